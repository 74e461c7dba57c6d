"""Front ends that turn PLC programs into the typed IR of :mod:`plcpred.parser.ir`.

* :func:`parse_st` - IEC 61131-3 Structured Text (``.st``)
* :func:`load_program` - any supported file, chosen by extension
"""
from . import ir
from .errors import ProgramError, ProgramWarning
from .st import parse_st

__all__ = ["ir", "ProgramError", "ProgramWarning", "parse_st", "load_program"]


def load_program(path) -> "ir.Program":
    """Read and parse a program file: ``.st`` (also ``.iecst``, ``.txt``), ``.seq`` or
    PLCopen ``.xml``. Errors name the file, line and column."""
    from pathlib import Path

    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        text = p.read_text(encoding="latin-1")
    except OSError as e:
        raise ProgramError(f"cannot read file: {e.strerror}", str(path), 0, 0) from None
    suffix = p.suffix.lower()
    if suffix == ".seq":
        from .seq import parse_seq
        return parse_seq(text, str(path))
    if suffix == ".xml":
        from .plcopen import parse_plcopen
        return parse_plcopen(text, str(path))
    return parse_st(text, str(path))
