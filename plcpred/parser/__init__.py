"""Front ends that turn PLC programs into the typed IR of :mod:`plcpred.parser.ir`.

* :func:`parse_st` - IEC 61131-3 Structured Text (``.st``)
* :func:`load_program` - any supported file or TwinCAT project, chosen by content and extension
"""
import re

from . import ir
from .errors import ProgramError, ProgramWarning
from .st import parse_st

__all__ = ["ir", "ProgramError", "ProgramWarning", "parse_st", "load_program"]


DIALECTS = ("auto", "iec", "bnr")


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
    from pathlib import Path

    from .files import confined_to, env_roots, resolved
    if dialect not in DIALECTS:
        raise ValueError(f"dialect must be one of {', '.join(DIALECTS)}, not {dialect!r}")
    p = Path(path)
    roots = allowed_roots
    if roots is None:
        own = resolved(p)
        roots = (own if p.is_dir() else own.parent,) + env_roots()
    with confined_to(roots):
        program = _load(p, dialect)
    if not libraries:
        return program
    from .libraries import library_program
    return program.merge(library_program([program], lib_dirs, allowed_roots=allowed_roots))


def _load(path, dialect: str = "auto") -> "ir.Program":
    from pathlib import Path

    from . import twincat

    from .bnr import BNR_SUFFIXES, has_cyclic, is_bnr_folder, load_bnr, only_actions

    p = Path(path)
    if p.is_dir() or p.suffix.lower() == ".plcproj":
        from functools import reduce
        missing: list = []
        files = twincat.project_files(p, missing)
        if not files:
            raise ProgramError("none of the files the project lists is there", str(p), 0, 0)
        if p.is_dir() and (dialect == "bnr" or (
                dialect == "auto" and is_bnr_folder(files, twincat.read_source))):
            # B&R Automation Studio: program folders, .var/.typ/.fun (see .bnr)
            return load_bnr(p, files, twincat.read_source)
        merged = reduce(ir.Program.merge, [_load(f, dialect) for f in files])
        merged.source = str(path)
        # kept for naming the libraries a check misses (see check.Checker.missing)
        from .libraries import missing_pragma, reference_pragma
        merged.pragmas += [(reference_pragma(name), ir.Pos(str(path), 0, 0))
                           for name in twincat.project_references(p)]
        merged.pragmas += [(missing_pragma(include), pos) for include, pos in missing]
        return merged
    text = twincat.read_source(p)
    suffix = p.suffix.lower()
    part_of_folder = suffix in BNR_SUFFIXES or (suffix == ".st" and (
        has_cyclic(text) or (dialect == "bnr" and only_actions(text))))
    if dialect != "iec" and part_of_folder:
        # one file of a B&R program: the program is its folder
        from .files import listing
        folder = p.parent
        files = [f for f in listing(folder, depth=0)
                 if f.suffix.lower() in BNR_SUFFIXES + (".st",)]
        return load_bnr(folder, files, twincat.read_source)
    kind = _sniff(text) or p.suffix.lower()
    if kind == ".seq":
        from .seq import parse_seq
        return parse_seq(text, str(path))
    if kind == ".xml":
        from .plcopen import parse_plcopen
        program = parse_plcopen(text, str(path))
        from .beremiz_project import confnode_globals, is_beremiz_project
        if is_beremiz_project(p.parent):
            from .names import validate_names
            program.globals += confnode_globals(p.parent)
            validate_names(program)
        return program
    if kind in twincat.OBJECT_SUFFIXES:
        return twincat.parse_twincat(text, str(path))
    if kind == "machine":
        raise ProgramError("this is a machine file (TOML), not a PLC program: give it to "
                           "predict, timeline, size, compare, sweep or diagnose, which read "
                           "the program it names", str(path), 1, 1)
    return parse_st(text, str(path), dialect="bnr" if dialect == "bnr" else "iec")


_XML_ROOT = re.compile(r"\s*(?:<\?xml[^>]*\?>\s*)?(?:<!--[\s\S]*?-->\s*)*<(?:\w+:)?(\w+)")
_MACHINE_TABLE = re.compile(r"^\s*\[machine\]\s*$", re.M)


def _sniff(text: str) -> str | None:
    """What a file holds when its content says so: an XML root element we know, or a
    machine file's ``[machine]`` table."""
    head = text[:4096]
    m = _XML_ROOT.match(head)
    if m:
        return {"TcPlcObject": ".tcpou", "project": ".xml"}.get(m.group(1))
    return "machine" if _MACHINE_TABLE.search(head) else None
