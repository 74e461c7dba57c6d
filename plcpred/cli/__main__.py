"""``python -m plcpred.cli``: the same as the ``plcpred`` command."""
import sys

from .main import main

sys.exit(main())
