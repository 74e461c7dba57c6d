"""Front ends that turn PLC programs into the typed IR of :mod:`plcpred.parser.ir`.

* :func:`parse_st` - IEC 61131-3 Structured Text (``.st``)
* :func:`load_program` - any supported file or TwinCAT project, chosen by content and
  extension (:mod:`.read`), with what it uses from vendor libraries (:mod:`.libraries`)
"""
from . import ir
from .errors import ProgramError, ProgramFileError, ProgramWarning
from .libraries import library_program
from .read import DIALECTS, read_program
from .st import parse_st

__all__ = ["ir", "ProgramError", "ProgramFileError", "ProgramWarning", "parse_st", "load_program", "DIALECTS"]


def load_program(path, libraries: bool = True, lib_dirs=(), dialect: str = "auto",
                 allowed_roots=None) -> "ir.Program":
    """Read and parse a program: an ST file (``.st``, also ``.iecst``, ``.txt``), a
    ``.seq`` chart, a PLCopen ``.xml`` export, a TwinCAT 3 object file (``.TcPOU``,
    ``.TcGVL``, ``.TcDUT``, ``.TcIO``, ``.TcTTO``), or a whole project: a TwinCAT
    ``.plcproj`` or a folder. A file is read by what it holds when its name says
    otherwise (a ``.TcPOU`` saved as ``.st``). Errors name the file, line and column.

    With ``libraries``, what the program uses from vendor libraries (the shipped stubs,
    and declarations under ``lib_dirs``) is added to it (see :mod:`.libraries`).
    ``dialect`` settles what vendors read differently: "auto" tells a B&R Automation
    Studio program by its files (``.var``/``.typ``/``.fun``, ``PROGRAM _CYCLIC``), "bnr"
    reads ST the B&R way (``Act;`` calls an action), "iec" never does.

    Files are read only from under ``allowed_roots`` (folders; a machine file's, see
    :mod:`.files`): the program, what its project lists, the libraries. None (a path the
    user gave on the command line): from under the program's own folder (the folder
    itself, or the one holding the file), each library from under its own, and the
    folders ``PLCPRED_ALLOW_ROOTS`` allows (--allow-root). Only regular files of at most
    :data:`.files.MAX_FILE_BYTES` are read."""
    program = read_program(path, dialect, allowed_roots)
    if not libraries:
        return program
    return program.merge(library_program([program], lib_dirs, allowed_roots=allowed_roots))
