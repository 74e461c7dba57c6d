"""plcpred: predict the compressed-air demand of a machine from its PLC program.

Library first: the ``plcpred`` command is a thin layer over these calls.

* :func:`plcpred.parser.load_program` - parse ``.st``, ``.seq`` or PLCopen ``.xml`` into the IR
* :func:`plcpred.machine.load_machine` - read and validate a machine file (TOML)
* :func:`plcpred.unfold` - run a machine's program over a horizon into a Timeline
* :func:`plcpred.predict` - timeline and air-demand profile of a machine
"""
__version__ = "0.1.0"

from .machine import load_machine  # noqa: E402
from .parser import load_program  # noqa: E402
from .sequencer import Timeline, unfold  # noqa: E402
from .air import DemandProfile, predict  # noqa: E402

__all__ = ["DemandProfile", "Timeline", "load_machine", "load_program", "predict", "unfold",
           "__version__"]
