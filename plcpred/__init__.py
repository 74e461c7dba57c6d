"""plcpred: predict the compressed-air demand of a machine from its PLC program.

Library first: the ``plcpred`` command is a thin layer over these calls.

* :func:`plcpred.parser.load_program` - parse ``.st``, ``.seq`` or PLCopen ``.xml`` into the IR
* :func:`plcpred.machine.load_machine` - read and validate a machine file (TOML)
* :func:`plcpred.unfold` - run a machine's program over a horizon into a Timeline
"""
__version__ = "0.1.0"

from .machine import load_machine  # noqa: E402
from .parser import load_program  # noqa: E402
from .sequencer import Timeline, unfold  # noqa: E402

__all__ = ["Timeline", "load_machine", "load_program", "unfold", "__version__"]
