"""Reading one program file, or a project's files, into the IR: the format chosen by
what a file holds and its name (ST, ``.seq``, PLCopen XML, TwinCAT objects and projects,
B&R folders), without the vendor libraries a program uses (:mod:`.libraries` adds them)."""
from __future__ import annotations

import re
from functools import reduce
from pathlib import Path

from . import ir, twincat
from .beremiz_project import confnode_globals, is_beremiz_project
from .bnr import BNR_SUFFIXES, has_cyclic, is_bnr_folder, load_bnr, only_actions
from .errors import ProgramError, ProgramFileError
from .files import confined_to, env_roots, listing, resolved
from .names import validate_names
from .notes import missing_pragma, reference_pragma
from .plcopen import parse_plcopen
from .seq import parse_seq
from .st import parse_st

DIALECTS = ("auto", "iec", "bnr")


def read_program(path, dialect: str = "auto", allowed_roots=None) -> ir.Program:
    """The program in ``path`` (a file, a ``.plcproj`` or a folder) as the IR, read only
    from under ``allowed_roots`` (None: the program's own folder and the folders
    ``PLCPRED_ALLOW_ROOTS`` allows); see :func:`plcpred.parser.load_program`."""
    if dialect not in DIALECTS:
        raise ValueError(f"dialect must be one of {', '.join(DIALECTS)}, not {dialect!r}")
    p = Path(path)
    roots = allowed_roots
    if roots is None:
        own = resolved(p)
        roots = (own if p.is_dir() else own.parent,) + env_roots()
    with confined_to(roots):
        return read_file(p, dialect)


def read_file(path, dialect: str = "auto") -> ir.Program:
    """One file or project, read within the roots the caller has confined reading to."""
    p = Path(path)
    if p.is_dir() or p.suffix.lower() == ".plcproj":
        missing: list = []
        files = twincat.project_files(p, missing)
        if not files:
            raise ProgramError("none of the files the project lists is there", str(p), 0, 0)
        if p.is_dir() and (dialect == "bnr" or (
                dialect == "auto" and is_bnr_folder(files, twincat.read_source))):
            # B&R Automation Studio: program folders, .var/.typ/.fun (see .bnr)
            return load_bnr(p, files, twincat.read_source)
        merged = reduce(ir.Program.merge, [read_file(f, dialect) for f in files])
        merged.source = str(path)
        # kept for naming the libraries a check misses (see check.Checker.missing)
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
        folder = p.parent
        files = [f for f in listing(folder, depth=0)
                 if f.suffix.lower() in BNR_SUFFIXES + (".st",)]
        return load_bnr(folder, files, twincat.read_source)
    kind = _sniff(text) or p.suffix.lower()
    if kind == ".seq":
        return parse_seq(text, str(path))
    if kind == ".xml":
        program = parse_plcopen(text, str(path))
        if is_beremiz_project(p.parent):
            program.globals += confnode_globals(p.parent)
            validate_names(program)
        return program
    if kind in twincat.OBJECT_SUFFIXES:
        return twincat.parse_twincat(text, str(path))
    if kind == "machine":
        raise ProgramFileError("this is a machine file (TOML), not a PLC program: give it "
                               "to predict, timeline, size, compare, sweep or diagnose, "
                               "which read the program it names", str(path), 1, 1)
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
