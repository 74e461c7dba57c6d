"""B&R Automation Studio programs, as they are kept in a project's ``Logical`` folder.

A B&R program is a folder, not a POU: its ``.st`` files hold ``PROGRAM _INIT`` (run once
at start), ``PROGRAM _CYCLIC`` (run every cycle) and ``PROGRAM _EXIT``, and ACTIONs, each
action often in a file of its own; its ``.var`` files declare its variables (bare
``VAR ... END_VAR`` blocks), its ``.typ`` files its types and ``.fun`` files the
declarations of function blocks a library implements. A ``Global.var`` / ``Global.typ``
beside the program folders declares what they share.

:func:`load_bnr` reads such a folder into the IR plcpred runs: each program folder
becomes one PROGRAM named after the folder, whose body is its _INIT body, run on the
first scan only, then its _CYCLIC body (its _EXIT body never runs in a prediction);
its actions belong to it, called by name (``Blow;``); and a configuration runs every
program folder on one task, as the controller's cyclic task classes run them.
"""
from __future__ import annotations

import re
from pathlib import Path

from . import ir
from .errors import at
from .names import validate_names
from .st import parse_st

BNR_SUFFIXES = (".var", ".typ", ".fun")
_PHASES = ("_INIT", "_CYCLIC", "_EXIT")
_HOLDER = "__BNR_HOLDER"           # a POU the loose ACTIONs of a file are read into
_INIT_DONE = "_BNR_INIT_DONE"
_CYCLIC = re.compile(r"^\s*PROGRAM\s+_CYCLIC\b", re.I | re.M)
_COMMENTS = re.compile(r"\(\*.*?\*\)|//[^\n]*|/\*.*?\*/", re.S)
_ACTION_FIRST = re.compile(r"ACTION\s", re.I)


def has_cyclic(text: str) -> bool:
    """Whether an ST file holds a B&R ``PROGRAM _CYCLIC``."""
    return _CYCLIC.search(text) is not None


def is_bnr_folder(files: list[Path], read) -> bool:
    """Whether a folder's program files are a B&R project's: ``.var`` / ``.typ`` /
    ``.fun`` files, or a ``PROGRAM _CYCLIC``."""
    if any(f.suffix.lower() in BNR_SUFFIXES for f in files):
        return True
    return any(has_cyclic(read(f)) for f in files if f.suffix.lower() == ".st")


def _parse(path: Path, text: str) -> ir.Program:
    if path.suffix.lower() == ".st" and only_actions(text):
        # an action in a file of its own: read it as if written after a POU, on line 1
        return parse_st(f"PROGRAM {_HOLDER} END_PROGRAM " + text, str(path), dialect="bnr")
    return parse_st(text, str(path), dialect="bnr")


def only_actions(text: str) -> bool:
    """Whether the file starts (after comments) with an ACTION: B&R's action files."""
    return _ACTION_FIRST.match(_COMMENTS.sub(" ", text).lstrip()) is not None


def _program_name(folder: Path) -> str:
    """The PROGRAM a folder becomes: its name as an IEC identifier (ASCII letters, digits
    and underscores; anything else an underscore)."""
    name = "".join(ch if (ch.isascii() and ch.isalnum()) or ch == "_" else "_"
                   for ch in folder.name)
    if not name.strip("_") or name[0].isdigit():
        name = "P_" + name
    return name


def load_bnr(root: Path, files: list[Path], read) -> ir.Program:
    """The IR of the B&R program folders under ``root`` (module note)."""
    by_folder: dict[Path, list[ir.Program]] = {}
    for f in files:
        prog = _parse(f, read(f))
        by_folder.setdefault(f.parent, []).append(prog)
    out = ir.Program(source=str(root))
    programs = []
    for folder, progs in sorted(by_folder.items()):
        phases: dict[str, ir.Pou] = {}
        actions: list[ir.SfcAction] = []
        for p in progs:
            keep = []
            for pou in p.pous:
                key = pou.name.upper()
                if key in _PHASES and pou.kind == "PROGRAM":
                    if key in phases:
                        raise at(pou.pos, f"a second PROGRAM {pou.name} in {folder}")
                    phases[key] = pou
                    actions.extend(pou.actions)
                elif key == _HOLDER:
                    actions.extend(pou.actions)
                else:
                    keep.append(pou)
            p.pous = keep
            out = out.merge(p)
        if not phases:
            continue
        name = _program_name(folder)
        init = phases.get("_INIT")
        cyclic = phases.get("_CYCLIC")
        body: list = []
        pos = (cyclic or init).pos
        if init is not None and init.body:
            done = ir.Name(_INIT_DONE, pos=init.pos)
            body.append(ir.If([(ir.Unary("NOT", done, pos=init.pos),
                                [*init.body,
                                 ir.Assign(done, ir.Literal(True, "BOOL"), pos=init.pos)])],
                              pos=init.pos))
        if cyclic is not None:
            body.extend(cyclic.body)
        blocks = [b for ph in phases.values() for b in ph.var_blocks]
        blocks.append(ir.VarBlock("VAR", [ir.VarDecl(_INIT_DONE, ir.NamedType("BOOL"))]))
        pou = ir.Pou("PROGRAM", name, blocks, body, pos=pos)
        pou.actions = actions
        programs.append(pou)
    if not programs:
        return out
    out.pous.extend(programs)
    # the folder's bare VAR blocks (its .var files) are the programs' variables: kept as
    # global lists, which every program of the folder reads
    for g in out.globals:
        if g.block.kind == "VAR":
            g.block.kind = "VAR_GLOBAL"
    if not out.configurations and len(programs) > 1:
        task = ir.Task("Cyclic", {})
        out.configurations.append(ir.Configuration(
            "BnR", [], [ir.Resource("CPU", None, tasks=[task], programs=[
                ir.ProgramInstance(p.name, p.name, task.name) for p in programs])]))
    # what was put together here passes the same gate as what was parsed
    return validate_names(out)
