"""plcpred: predict the compressed-air demand of a machine from its PLC program.

Library first: the ``plcpred`` command is a thin layer over these calls.

* :func:`plcpred.parser.load_program` - parse ``.st``, ``.seq`` or PLCopen ``.xml`` into the IR
* :func:`plcpred.machine.load_machine` - read and validate a machine file (TOML)
* :func:`plcpred.unfold` - run a machine's program over a horizon into a Timeline
* :func:`plcpred.predict` - timeline and air-demand profile of a machine
"""
__version__ = "0.1.0"

from .lazy import lazy_attributes

# imported on first use (PEP 562), so that ``plcpred --help`` and the CLI's argument
# errors do not wait for numpy, the parser and the sequencer
_LAZY = {"load_machine": ".machine", "load_program": ".parser", "Timeline": ".sequencer",
         "unfold": ".sequencer", "DemandProfile": ".air", "predict": ".air"}

__all__ = ["DemandProfile", "Timeline", "load_machine", "load_program", "predict", "unfold",
           "__version__"]


__getattr__, __dir__ = lazy_attributes(__name__, _LAZY)
