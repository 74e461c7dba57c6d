"""plcpred: predict the compressed-air demand of a machine from its PLC program.

Library first: the ``plcpred`` command is a thin layer over these calls.

* :func:`plcpred.parser.load_program` - parse ``.st``, ``.seq`` or PLCopen ``.xml`` into the IR
"""
__version__ = "0.1.0"

from .parser import load_program  # noqa: E402

__all__ = ["load_program", "__version__"]
