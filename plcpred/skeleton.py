"""``plcpred init``: a commented machine file to start from, written from a program's I/O.

The program says which signals it reads and writes and how often its task runs; it cannot
say what drives its inputs or which air consumer each output switches. So the file it
writes loads and runs as it is (the program alone, nothing scheduled), and lists every
input as an ``[[input]]`` and every BOOL output as a ``[[consumer]]`` to uncomment and
fill in, with the keys each needs (see docs/reference/machine-file.md).
"""
from __future__ import annotations

import datetime
import os
from dataclasses import dataclass
from pathlib import Path

from .parser import ir

DEFAULT_SCAN_MS = 10.0
DEFAULT_SUPPLY_BAR_G = 6.0
# words that name an end-position sensor in common naming conventions
_SWITCH_WORDS = ("home", "work", "ext", "ret", "out", "in_pos", "up", "down", "open",
                 "closed", "end", "pos")


@dataclass
class Signal:
    name: str          # as declared
    type_name: str     # BOOL, WORD, ...
    address: str       # %IX0.0, or "" for a VAR_INPUT / VAR_OUTPUT of a PROGRAM


def program_signals(program: ir.Program) -> tuple[list[Signal], list[Signal]]:
    """(inputs, outputs) of a program: its located variables (%I, %Q) and the
    VAR_INPUT / VAR_OUTPUT of its PROGRAMs, in declaration order, each once."""
    blocks = [g.block for g in program.globals]
    blocks += [b for c in program.configurations for b in c.var_blocks]
    blocks += [b for c in program.configurations for r in c.resources for b in r.var_blocks]
    blocks += [b for p in program.pous if p.kind == "PROGRAM" for b in p.var_blocks]
    inputs, outputs, seen = [], [], set()
    for b in blocks:
        for d in b.decls:
            addr = (d.address or "").upper()
            is_in = addr.startswith("%I") or (b.kind == "VAR_INPUT" and not addr)
            is_out = addr.startswith("%Q") or (b.kind == "VAR_OUTPUT" and not addr)
            if not (is_in or is_out) or d.name.upper() in seen or "*" in addr:
                continue
            seen.add(d.name.upper())
            type_name = d.type.name if isinstance(d.type, ir.NamedType) else "?"
            (inputs if is_in else outputs).append(Signal(d.name, type_name.upper(), addr))
    return inputs, outputs


def task_scan_ms(program: ir.Program) -> float | None:
    """The interval of the program's first task with one, in ms (None without a task)."""
    for c in program.configurations:
        for r in c.resources:
            for t in r.tasks:
                if t.interval_ns is not None:
                    return t.interval_ns / 1e6
    return None


def _toml_string(text: str) -> str:
    """A TOML basic string: quotes and backslashes escaped, and control characters (a
    file name may hold a newline) as \\uXXXX, so no text can end the string."""
    out = []
    for ch in text:
        if ch in ('"', "\\"):
            out.append("\\" + ch)
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04X}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def _looks_like_switch(name: str) -> bool:
    low = name.lower()
    return any(w in low for w in _SWITCH_WORDS)


_INPUTS_HEAD = [
    "# ---------------------------------------------------------------- inputs",
    "# Inputs the outside world drives (a start button, a part sensor): give each a",
    "# schedule. End switches of cylinders are answered by the consumer's",
    "# `switches` instead (marked below); leave those out here.",
]
_CONSUMERS_HEAD = [
    "# ---------------------------------------------------------------- consumers",
    "# One per output that switches air. A cylinder (double_acting, single_acting,",
    "# rodless, ...) uses air on each stroke; a nozzle, air knife or blow-off while",
    "# its output is TRUE. Delete the blocks of outputs that drive no air.",
]


def _input_block(s: Signal) -> list[str]:
    hint = "  (an end switch? see `switches` below)" if _looks_like_switch(s.name) else ""
    return [f"# {s.name}{_at(s)}{hint}", "# [[input]]", f"# signal = {_toml_string(s.name)}",
            "# period_s = 10.0       # FILL IN: every how many seconds it comes",
            "# offset_s = 0.5        # first time",
            "# pulse_ms = 200        # how long it stays TRUE"]


def _consumer_block(s: Signal) -> list[str]:
    return [f"# {s.name}{_at(s)}", "# [[consumer]]", f"# name = {_toml_string(s.name)}",
            "# kind = \"double_acting\"   # or single_acting, rodless, nozzle, ...",
            f"# valve = {_toml_string(s.name)}",
            "# bore_mm = 32", "# rod_mm = 12", "# stroke_mm = 100",
            "# tube_id_mm = 4", "# tube_length_m = [1.0, 1.0]",
            "# stroke_time_s = [0.5, 0.5]   # extend, retract",
            "# switches = { retracted = \"...\", extended = \"...\" }",
            "#   (a nozzle instead: kind = \"nozzle\", orifice_mm = 1.5, Cd = 0.8)"]


def _at(s: Signal) -> str:
    return f" at {s.address}" if s.address else ""


def _blocks(head: list[str], signals: list[Signal], block) -> list[str]:
    """A section: its heading, then one commented block per signal."""
    if not signals:
        return []
    out = list(head)
    for s in signals:
        out += ["", *block(s)]
    return out + [""]


def machine_skeleton(program: ir.Program, program_path: Path, out_path: Path | None,
                     today: datetime.date | None = None) -> str:
    """The text of a machine file for ``program`` (read from ``program_path``), to be
    written at ``out_path`` (the program is named relative to it; None: the current
    folder)."""
    inputs, outputs = program_signals(program)
    folder = (out_path.parent if out_path is not None else Path.cwd()).resolve()
    try:
        rel = os.path.relpath(program_path.resolve(), folder)
    except ValueError:          # another drive (Windows)
        rel = str(program_path.resolve())
    rel = rel.replace(os.sep, "/")
    if program_path.is_dir() and not rel.endswith("/"):
        rel += "/"
    programs = [p.name for p in program.pous if p.kind == "PROGRAM"]
    name = programs[0] if len(programs) == 1 else program_path.stem
    scan = task_scan_ms(program)
    day = (today or datetime.date.today()).isoformat()
    lines = [
        f"# Machine file for {_toml_string(program_path.name)[1:-1]}, written by "
        f"`plcpred init` on {day}.",
        "# It loads and runs as it is (the program alone, nothing scheduled). Fill in what",
        "# the program cannot tell: what drives its inputs and which air consumer each",
        "# output switches (uncomment and complete the blocks below). Every key, with its",
        "# units and an example per consumer kind: docs/reference/machine-file.md.",
        "",
        "[machine]",
        f"name = {_toml_string(name)}",
        f"program = {_toml_string(rel)}",
        f"scan_ms = {scan if scan is not None else DEFAULT_SCAN_MS:g}"
        + ("                # the program's task interval" if scan is not None else
           "                # FILL IN: the PLC task's cycle (no task in the program)"),
        f"supply_bar_g = {DEFAULT_SUPPLY_BAR_G:g}            "
        "# FILL IN: the supply pressure at the machine",
        "",
    ]
    lines += _blocks(_INPUTS_HEAD, [s for s in inputs if s.type_name == "BOOL"], _input_block)
    other_in = [s for s in inputs if s.type_name != "BOOL"]
    if other_in:
        lines.append("# Other inputs (kept at their initial values unless scheduled): "
                     + ", ".join(f"{s.name} ({s.type_name})" for s in other_in))
        lines.append("")
    lines += _blocks(_CONSUMERS_HEAD, [s for s in outputs if s.type_name == "BOOL"],
                     _consumer_block)
    other_out = [s for s in outputs if s.type_name != "BOOL"]
    if other_out:
        lines.append("# Other outputs: " + ", ".join(f"{s.name} ({s.type_name})"
                                                    for s in other_out)
                     + "; a bit of a WORD output drives a valve as valve = \"NAME.3\".")
        lines.append("")
    if not inputs and not outputs:
        lines += ["# The program declares no located variables (%I, %Q) and its PROGRAMs",
                  "# no VAR_INPUT / VAR_OUTPUT: name any of its variables as a signal.", ""]
    arrays = bool_arrays(program)
    if arrays:
        lines.append("# BOOL arrays (valves and switches of many drives): name an element as "
                     "a signal,")
        lines += [f"#   {name}: {dims} -> {name}[{first}]" for name, dims, first in arrays]
        lines.append("")
    return "\n".join(lines)


def bool_arrays(program: ir.Program) -> list[tuple[str, str, str]]:
    """(name, ``ARRAY[..] OF BOOL`` text, first element's index text) of the BOOL arrays
    a program's globals and PROGRAMs declare (with literal bounds), in declaration
    order."""
    blocks = [g.block for g in program.globals]
    blocks += [b for p in program.pous if p.kind == "PROGRAM" for b in p.var_blocks]
    out = []
    for b in blocks:
        for d in b.decls:
            t = d.type
            if not isinstance(t, ir.ArrayType) or not isinstance(t.element, ir.NamedType) \
                    or t.element.name.upper() != "BOOL":
                continue
            bounds = [(lo.value, hi.value) for lo, hi in t.dims
                      if isinstance(lo, ir.Literal) and isinstance(hi, ir.Literal)]
            if len(bounds) != len(t.dims):
                continue
            dims = ", ".join(f"{lo}..{hi}" for lo, hi in bounds)
            out.append((d.name, f"ARRAY[{dims}] OF BOOL", ", ".join(str(lo) for lo, _ in bounds)))
    return out
