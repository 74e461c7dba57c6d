"""``plcpred init``: a commented machine file to start from, written from a program's I/O.

The program says which signals it reads and writes and how often its task runs; it cannot
say what drives its inputs or which air consumer each output switches. So the file it
writes loads and runs as it is (the program alone, nothing scheduled), and lists every
input as an ``[[input]]`` and every BOOL output as a ``[[consumer]]`` to uncomment and
fill in, with the keys each needs (see docs/reference/machine-file.md). An input whose
name reads as an end switch of the drive an output's name names (``A_RET`` of ``Y_A``,
``xZUp`` of ``qZ``, ``bClampWork`` of ``bClampValve``) is put in that consumer's
``switches`` instead, when the program reads it.
"""
from __future__ import annotations

import datetime
import os
import re
from dataclasses import dataclass
from pathlib import Path

from .parser import ir
from .parser.check import Checker

DEFAULT_SCAN_MS = 10.0
DEFAULT_SUPPLY_BAR_G = 6.0
# the last word of an end switch's name and the end it reports, in common naming
# conventions (English and German; a vertical drive's "up" is its rest position, a
# gripper's or clamp's "closed" its working one)
_RETRACTED_WORDS = ("ret", "retr", "retracted", "home", "back", "up", "open", "opened", "in",
                    "rear", "rest", "eingefahren", "oben", "hinten", "offen", "grund")
_EXTENDED_WORDS = ("ext", "extd", "extended", "work", "out", "front", "down", "closed",
                   "close", "end", "ausgefahren", "unten", "vorne", "vorn", "geschlossen",
                   "fwd", "forward")
_END_OF = {w: "retracted" for w in _RETRACTED_WORDS} | {w: "extended" for w in _EXTENDED_WORDS}
# a first word that only says what kind of signal it is (IEC/CODESYS prefixes x, b, q, i,
# o; Y for a valve solenoid, S and B for sensors on schematics) and a last word that
# says "valve"
_PREFIXES = ("x", "b", "q", "i", "o", "y", "s", "di", "do")
_VALVE_WORDS = ("valve", "vlv", "ventil", "sol", "solenoid", "coil", "cmd", "y")
# Festo/DIN schematic names: sensors 1B1/1S1 (retracted) and 1B2/1S2 (extended) of
# drive 1A, its solenoid 1Y1 (or 1M1)
_SCHEMATIC_SENSOR = re.compile(r"(\d+)[BS]([12])", re.ASCII)
_SCHEMATIC_VALVE = re.compile(r"(\d+)[YM]1", re.ASCII)
_HUNGARIAN = re.compile(r"^[a-z]{1,2}(?=[A-Z])", re.ASCII)
_WORD = re.compile(r"[A-Z]+(?=[A-Z][a-z])|[A-Z]?[a-z]+|[A-Z]+|\d+", re.ASCII)


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
            if not (is_in or is_out) or d.name.upper() in seen:
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


def _words(name: str) -> list[str]:
    """The words of a signal name, lower case, without a type prefix in lower case
    (``x``, ``b``, ``q``, ``fb`` before a capital): split at ``_``, between a lower and an
    upper case letter, and before the last capital of a run (``xZDown`` -> z, down)."""
    name = _HUNGARIAN.sub("", name)
    return [w.lower() for part in re.split(r"[^A-Za-z0-9]+", name) for w in _WORD.findall(part)]


def _stem(words: list[str], drop_last=()) -> list[str]:
    """``words`` without a leading type prefix (``Y_A``, ``S_A_RET``; when more follow)
    and a trailing word of ``drop_last`` (when more precede)."""
    if len(words) > 1 and words[0] in _PREFIXES:
        words = words[1:]
    if len(words) > 1 and words[-1] in drop_last:
        words = words[:-1]
    return words


def _switch_end(name: str) -> tuple[str, str] | None:
    """(the drive's stem, "retracted" or "extended") when ``name`` reads as an end switch:
    its last word names an end position (``A_RET``, ``xZUp``, ``bClampWork``,
    ``ejector_home``); the stem is "" for a name that is nothing but the end
    (``xExtended``)."""
    words = _words(name)
    if not words or words[-1] not in _END_OF:
        return None
    return "".join(_stem(words[:-1])), _END_OF[words[-1]]


def _looks_like_switch(name: str) -> bool:
    """Whether the name reads as an end switch's, "in" and "out" aside (``part_in``)."""
    words = _words(name)
    return (_switch_end(name) is not None and words[-1] not in ("in", "out")) \
        or _SCHEMATIC_SENSOR.fullmatch(name) is not None


def end_switches(inputs: list[Signal], outputs: list[Signal]) -> dict[str, dict[str, str]]:
    """Output name -> {"retracted": input, "extended": input}: the BOOL inputs whose names
    read as the end switches of the drive a BOOL output's name names (``Y_A``: ``A_RET``,
    ``A_EXT``; ``qZ``: ``xZUp``, ``xZDown``; ``bClampValve``: ``bClampHome``,
    ``bClampWork``; ``eject_valve``: ``ejector_out``; ``1Y1``: ``1B1``, ``1B2``). A
    switch whose name fits two outputs equally well, or an end two switches claim, is
    left out: the file says it, not a guess."""
    outs = [s for s in outputs if s.type_name == "BOOL"]
    stems = {s.name: "".join(_stem(_words(s.name), _VALVE_WORDS)) for s in outs}
    claims: dict[tuple[str, str], list[str]] = {}
    for s in inputs:
        if s.type_name != "BOOL":
            continue
        m = _SCHEMATIC_SENSOR.fullmatch(s.name)
        if m:
            end = "retracted" if m.group(2) == "1" else "extended"
            fits = [o.name for o in outs if (v := _SCHEMATIC_VALVE.fullmatch(o.name))
                    and v.group(1) == m.group(1)]
        else:
            found = _switch_end(s.name)
            if found is None:
                continue
            stem, end = found
            fits = _fitting_outputs(stem, stems) if stem else [o.name for o in outs]
        if len(fits) == 1:
            claims.setdefault((fits[0], end), []).append(s.name)
    out: dict[str, dict[str, str]] = {}
    for (valve, end), names in claims.items():
        if len(names) == 1:
            out.setdefault(valve, {})[end] = names[0]
    return {o.name: dict(sorted(out[o.name].items(), key=lambda kv: kv[0] != "retracted"))
            for o in outs if o.name in out}


def _fitting_outputs(stem: str, stems: dict[str, str]) -> list[str]:
    """The outputs whose stem is ``stem``, else the one whose stem and ``stem`` begin one
    with the other (``eject``, ``ejector``; three letters at least) most closely."""
    exact = [name for name, s in stems.items() if s == stem]
    if exact:
        return exact
    near = [(abs(len(s) - len(stem)), name) for name, s in stems.items()
            if min(len(s), len(stem)) >= 3 and (s.startswith(stem) or stem.startswith(s))]
    best = min((d for d, _ in near), default=None)
    return [name for d, name in near if d == best]


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


def _input_block(s: Signal, switch_of: dict[str, tuple[str, str, bool]]) -> list[str]:
    if s.name in switch_of:
        valve, end, read = switch_of[s.name]
        if read:
            return [(f"# {s.name}{_at(s)}: the {end} end switch of {valve} (in its "
                     "`switches` below)")]
        return [(f"# {s.name}{_at(s)}: the {end} end switch of {valve} by its name, never "
                 "read by the program (nothing to fill in)")]
    hint = "  (an end switch? see `switches` below)" if _looks_like_switch(s.name) else ""
    return [f"# {s.name}{_at(s)}{hint}", "# [[input]]", f"# signal = {_toml_string(s.name)}",
            "# period_s = 10.0       # FILL IN: every how many seconds it comes",
            "# offset_s = 0.5        # first time",
            "# pulse_ms = 200        # how long it stays TRUE"]


def _consumer_block(s: Signal, switches: dict[str, dict[str, str]]) -> list[str]:
    found = switches.get(s.name)
    if found:
        pairs = ", ".join(f"{end} = {_toml_string(name)}" for end, name in found.items())
        switch_line = f"# switches = {{ {pairs} }}   # found by their names"
    else:
        switch_line = "# switches = { retracted = \"...\", extended = \"...\" }"
    return [f"# {s.name}{_at(s)}", "# [[consumer]]", f"# name = {_toml_string(s.name)}",
            "# kind = \"double_acting\"   # or single_acting, rodless, nozzle, ...",
            f"# valve = {_toml_string(s.name)}",
            "# bore_mm = 32", "# rod_mm = 12", "# stroke_mm = 100",
            "# tube_id_mm = 4", "# tube_length_m = [1.0, 1.0]",
            "# stroke_time_s = [0.5, 0.5]   # extend, retract",
            switch_line,
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
    # a switch the program never reads is left out of `switches` (it would draw a warning)
    read = Checker(program).run().program_usage.read
    named = end_switches(inputs, outputs)
    switch_of = {name: (valve, end, name.upper() in read) for valve, found in named.items()
                 for end, name in found.items()}
    switches = {valve: kept for valve, found in named.items()
                if (kept := {e: n for e, n in found.items() if n.upper() in read})}
    lines += _blocks(_INPUTS_HEAD, [s for s in inputs if s.type_name == "BOOL"],
                     lambda s: _input_block(s, switch_of))
    other_in = [s for s in inputs if s.type_name != "BOOL"]
    if other_in:
        lines.append("# Other inputs (kept at their initial values unless scheduled): "
                     + ", ".join(f"{s.name} ({s.type_name})" for s in other_in))
        lines.append("")
    lines += _blocks(_CONSUMERS_HEAD, [s for s in outputs if s.type_name == "BOOL"],
                     lambda s: _consumer_block(s, switches))
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
