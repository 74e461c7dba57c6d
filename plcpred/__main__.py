"""``python -m plcpred``: the same as the ``plcpred`` command."""
import sys

from .cli import main

sys.exit(main())
