"""The machine file (TOML): ties a PLC program's inputs and outputs to physical consumers,
switches and input schedules. Every key is documented in ``docs/reference/machine-file.md``.

``load_machine(path)`` reads and validates it. Problems are :class:`MachineError` naming
the file, the line, the table and the key (``station.toml:18: consumer "clamp": stroke_mm
must be > 0``; a mistyped name with the one meant); harmless oddities, and numbers outside
what real machines have (:data:`.schema.PLAUSIBLE`), are collected in
``Machine.warnings``.
"""
from __future__ import annotations

import difflib
import math
import re
import stat as stat_module
import tomllib
from dataclasses import dataclass
from pathlib import Path

from ..parser import ProgramError, files
from ..parser.files import confined_to, env_roots, read_bytes, resolved
from ..physics.units import P_ATM_KPA, PA_PER_BAR, ZERO_C_K
from .model import (
    FLOW_MODELS,
    HOURS_PER_YEAR,
    KINDS,
    Calendar,
    Consumer,
    InputSchedule,
    Line,
    Machine,
    MachineError,
    Meter,
)
from .schema import (
    CALENDAR_IDLE_STATES,
    CYLINDER_KEYS,
    LIVE_METER_UNITS,
    LIVE_SECURITY_MODES,
    LIVE_SECURITY_POLICIES,
    METER_REFERENCES,
    METER_SAMPLINGS,
    PASSIVE_KEYS,
    PLANT_DRIVE_KEYS,
    PLAUSIBLE,
    RANGES,
    keys,
)
from .where import line_of

MAX_PULSES = 1_000_000


def unknown_name(what: str, name: str, known) -> str:
    """``unknown key 'bor_mm'; did you mean 'bore_mm'?``, or every known name when none is
    close."""
    known = sorted(known)
    near = [k for k in known if k.lower() == name.lower()] or difflib.get_close_matches(
        name, known, n=1, cutoff=0.6)
    if near:
        return f"unknown {what} '{name}'; did you mean '{near[0]}'?"
    return f"unknown {what} '{name}' (known: {', '.join(known) or 'none'})"


@dataclass
class _Note:
    """A warning about one key (a value outside the plausible range), placed as an error
    is: its line is found once the whole file has been read."""
    where: str
    message: str
    table: str | None
    index: int | None
    key: str | None


class _Reader:
    """Typed access to one TOML table, with errors that say where: ``where`` as the user
    reads it, ``name`` and ``index`` the table for finding the line (a ``where`` of
    ``"[meter]"`` is the table ``meter``). Values outside their plausible range become
    warnings in ``notes``."""

    def __init__(self, file: str, where: str, table: dict, allowed: set[str], *,
                 name: str | None = None, index: int | None = None,
                 notes: list | None = None):
        self.file, self.where, self.table = file, where, table
        self.name = name if name is not None else where.strip("[]")
        self.index, self.notes = index, notes
        if not isinstance(table, dict):
            raise self.error(f"must be a table, not {type(table).__name__}")
        unknown = [k for k in table if k not in allowed]       # in the file's order
        if unknown:
            raise self.error(unknown_name("key", unknown[0], allowed), unknown[0])

    def error(self, message: str, key: str | None = None) -> MachineError:
        return MachineError(self.file, self.where, message, table=self.name,
                            index=self.index, key=key)

    def number(self, key, default=None, *, required=False, positive=False, nonneg=False):
        if key not in self.table:
            if required:
                raise self.error(f"missing required key '{key}'")
            return default
        return self._checked(key, self.table[key], positive, nonneg)

    def _checked(self, key, v, positive, nonneg) -> float:
        if isinstance(v, bool) or not isinstance(v, (int, float)) or (
                isinstance(v, int) and abs(v) > 1e300) or not math.isfinite(v):
            raise self.error(f"{key} must be a number, not {_shown(v)}", key)
        if positive and v <= 0:
            raise self.error(f"{key} must be > 0", key)
        if nonneg and v < 0:
            raise self.error(f"{key} must be >= 0", key)
        low, high = RANGES.get(key, (-math.inf, math.inf))
        if not low <= v <= high:
            raise self.error(f"{key} = {_shown(v)} is outside the physical range "
                             f"{low:g}..{high:g}", key)
        self._plausible(key, v)
        return float(v)

    def _plausible(self, key: str, v) -> None:
        """A warning when ``v`` is outside what real machines have (a unit mixed up)."""
        plausible = PLAUSIBLE.get(key)
        if plausible is None or self.notes is None or plausible.holds(v):
            return
        note = _Note(self.where, plausible.warning(key, v), self.name, self.index, key)
        if note not in self.notes:
            self.notes.append(note)

    def flag(self, key, default=False) -> bool:
        """A true/false key (TOML's booleans only: 1 or "yes" are errors)."""
        if key not in self.table:
            return default
        if not isinstance(self.table[key], bool):
            raise self.error(f"{key} must be true or false", key)
        return self.table[key]

    def string(self, key, default=None, *, required=False, choices=None):
        if key not in self.table:
            if required:
                raise self.error(f"missing required key '{key}'")
            return default
        v = self.table[key]
        if not isinstance(v, str) or not v:
            raise self.error(f"{key} must be a non-empty string, not {_shown(v)}", key)
        if len(v) > 1000 or not v.isprintable():
            raise self.error(f"{key} must be printable text of at most 1000 characters", key)
        if choices and v not in choices:
            near = difflib.get_close_matches(v, choices, n=1, cutoff=0.6)
            raise self.error(f"{key} must be one of {', '.join(choices)}, not {v!r}"
                             + (f"; did you mean '{near[0]}'?" if near else ""), key)
        return v

    def pair(self, key, default, *, positive=False, nonneg=False):
        """A number used for both directions, or [first, second]."""
        if key not in self.table:
            return default
        v = self.table[key]
        values = v if isinstance(v, list) else [v, v]
        if len(values) != 2:
            raise self.error(f"{key} must be a number or a list of two numbers", key)
        return tuple(self._checked(key, x, positive, nonneg) for x in values)


def _shown(v) -> str:
    text = repr(v)
    return text if len(text) <= 60 else text[:57] + "..."


def _signal_name(r: _Reader, key: str, v) -> str:
    """A signal: a variable name, an address or NAME.bit, as printable short text."""
    if not isinstance(v, str) or not v or len(v) > 255 or not v.isprintable():
        raise r.error(f"{key} must be a signal name (a variable, %IX0.0 or WORD.3), "
                      f"not {_shown(v)}", key.partition(".")[0])
    return v


def _consumer(file: str, index: int, table: dict, notes: list) -> Consumer:
    label = f'consumer "{table.get("name")}"' if isinstance(table, dict) and table.get(
        "name") else f"consumer #{index + 1}"
    r = _Reader(file, label, table, keys("consumer"), name="consumer", index=index,
                notes=notes)
    kind = r.string("kind", required=True, choices=KINDS)
    c = Consumer(r.string("name", required=True), kind)
    valve = table.get("valve")
    if valve is None:
        if kind != "leak":
            raise r.error("missing required key 'valve'")
    elif kind == "leak":
        raise r.error("a leak is always on and has no valve", "valve")
    elif isinstance(valve, str) and valve:
        c.valve = [_signal_name(r, "valve", valve)]
    elif (isinstance(valve, list) and len(valve) == 2
          and all(isinstance(v, str) and v for v in valve)):
        c.valve = [_signal_name(r, "valve", v) for v in valve]
    else:
        raise r.error("valve must be a signal name (monostable) or two (bistable), "
                      f"not {valve!r}", "valve")
    if c.is_cylinder:
        _cylinder_keys(r, table, c)
    else:
        _passive_keys(r, table, c)
    c.line = r.string("line")
    return c


def _cylinder_keys(r: _Reader, table: dict, c: Consumer) -> None:
    """A cylinder-like consumer's size, tubes, stroke times, switches and plant keys."""
    kind = c.kind
    c.bore_mm = r.number("bore_mm", required=True, positive=True)
    c.stroke_mm = r.number("stroke_mm", required=kind not in ("semi_rotary", "gripper"),
                           positive=True)
    if kind in ("semi_rotary", "gripper") and c.stroke_mm is None:
        raise r.error("missing required key 'stroke_mm' (for a semi-rotary drive or a "
                      "gripper: the equivalent stroke of its swept volume)")
    # a single-acting cylinder fills only its cap end: its rod does not matter to the air
    needs_rod = kind in ("double_acting", "double_rod")
    c.rod_mm = r.number("rod_mm", 0.0 if not needs_rod else None, required=needs_rod,
                        nonneg=True)
    if c.rod_mm is not None and c.rod_mm >= c.bore_mm:
        raise r.error(f"rod_mm ({c.rod_mm:g}) must be smaller than bore_mm "
                      f"({c.bore_mm:g})", "rod_mm")
    c.tube_id_mm = r.number("tube_id_mm", 0.0, nonneg=True)
    c.tube_length_m = r.pair("tube_length_m", (0.0, 0.0), nonneg=True)
    st = table.get("stroke_time_s")
    if st == "auto":
        c.stroke_time_s = "auto"
    else:
        c.stroke_time_s = r.pair("stroke_time_s", None, positive=True)
    c.switch_delay_s = r.number("switch_delay_s", 0.0, nonneg=True)
    sw = table.get("switches", {})
    if not isinstance(sw, dict) or set(sw) - {"retracted", "extended"} or not all(
            isinstance(v, str) and v for v in sw.values()):
        raise r.error("switches must be { retracted = \"...\", extended = \"...\" }",
                      "switches")
    c.switches = {k: _signal_name(r, f"switches.{k}", v) for k, v in sw.items()}
    c.initial = r.string("initial", "retracted", choices=("retracted", "extended"))
    c.exhaust_tau_s = r.number("exhaust_tau_s", positive=True)
    c.partial_strokes = r.flag("partial_strokes")
    c.air_factor = r.pair("air_factor", (1.0, 1.0), positive=True)
    if c.partial_strokes and c.stroke_time_s is None:
        raise r.error("partial_strokes needs stroke_time_s (how far a piston gets "
                      "before the next edge)", "partial_strokes")
    c.plant = _plant_keys(r, table, kind)
    for key in PASSIVE_KEYS:
        if key in table:
            raise r.error(f"'{key}' applies to nozzles and leaks, not to a {kind}", key)


def _passive_keys(r: _Reader, table: dict, c: Consumer) -> None:
    """A nozzle's or leak's restriction (C, b, m, a or an orifice) and regulator."""
    kind = c.kind
    for key in (*CYLINDER_KEYS, *PLANT_DRIVE_KEYS):
        if key in table:
            raise r.error(f"'{key}' applies to cylinders, not to a {kind}", key)
    c.C = r.number("C", positive=True)
    c.orifice_mm = r.number("orifice_mm", positive=True)
    c.Cd = r.number("Cd", positive=True)
    if c.C is None and c.orifice_mm is None:
        raise r.error("give the sonic conductance C (m^3/(s Pa)) or orifice_mm and Cd")
    if c.C is not None and c.orifice_mm is not None:
        raise r.error("give either C or orifice_mm, not both", "orifice_mm")
    if c.orifice_mm is not None and c.Cd is None:
        raise r.error("orifice_mm needs a discharge coefficient Cd", "orifice_mm")
    if c.Cd is not None and c.Cd > 1:
        raise r.error("Cd must be at most 1", "Cd")
    c.b = r.number("b", 0.528 if c.C is None else None)  # ideal nozzle by default
    if c.b is None:
        raise r.error("missing required key 'b' (critical pressure ratio) with C")
    if not -1.0 < c.b < 1.0:
        raise r.error("b must lie between -1 and 1", "b")
    c.m = r.number("m", 0.5, positive=True)
    c.a = r.number("a", 1.0, positive=True)
    if c.a <= c.b or c.a > 1.0:
        raise r.error("a (cracking pressure ratio) must be > b and <= 1", "a")
    c.pressure_bar_g = r.number("pressure_bar_g", nonneg=True)
    c.flow_model = r.string("flow_model", "iso6358", choices=FLOW_MODELS)


def _plant_keys(r: _Reader, table: dict, kind: str) -> dict:
    """The plant-only keys of a drive, checked (numbers in range, pairs as [cap, rod])."""
    out = {}
    for key, form in PLANT_DRIVE_KEYS.items():
        if key not in table:
            continue
        if form == "flag":
            out[key] = r.flag(key)
        elif form == "pair":
            out[key] = r.pair(key, None, positive=key.endswith("_C"), nonneg=True) \
                if not key.endswith("_b") else r.pair(key, None)
        else:   # the RANGES table bounds them; only the angle may be negative
            out[key] = r.number(key, nonneg=key != "mount_angle_deg")
    if "spring_n" in out and kind != "single_acting":
        raise r.error("spring_n applies to single-acting cylinders", "spring_n")
    if "friction_static_n" in out and "friction_coulomb_n" in out and any(
            s < c for s, c in zip(out["friction_static_n"], out["friction_coulomb_n"])):
        raise r.error("friction_static_n must be >= friction_coulomb_n (breakaway is the "
                      "larger force)", "friction_static_n")
    return out


def _line(file: str, index: int, table: dict, notes: list) -> Line:
    label = f'line "{table.get("name")}"' if isinstance(table, dict) and table.get(
        "name") else f"line #{index + 1}"
    r = _Reader(file, label, table, keys("line"), name="line", index=index, notes=notes)
    line = Line(r.string("name", required=True),
                volume_l=r.number("volume_l", 1.0, positive=True),
                pressure_bar_g=r.number("pressure_bar_g", nonneg=True),
                network_bar_g=r.number("network_bar_g", nonneg=True),
                C=r.number("C", positive=True), b=r.number("b", 0.3),
                m=r.number("m", 0.5, positive=True),
                droop_bar=r.number("droop_bar", 0.3, positive=True))
    if not -1.0 < line.b < 1.0:
        raise r.error("b must lie between -1 and 1", "b")
    line.check_valves = r.flag("check_valves", line.check_valves)
    return line


def _input(file: str, index: int, table: dict, notes: list) -> InputSchedule:
    label = f'input "{table.get("signal")}"' if isinstance(table, dict) and table.get(
        "signal") else f"input #{index + 1}"
    r = _Reader(file, label, table, keys("input"), name="input", index=index, notes=notes)
    s = InputSchedule(_signal_name(r, "signal", r.string("signal", required=True)))
    pulses = table.get("pulses_s", [])
    if not isinstance(pulses, list) or len(pulses) > MAX_PULSES:
        raise r.error(f"pulses_s must be a list of at most {MAX_PULSES:,} times", "pulses_s")
    s.pulses_s = sorted(r._checked("pulses_s", p, False, True) for p in pulses)
    s.pulse_ms = r.number("pulse_ms", 200.0, positive=True)
    s.period_s = r.number("period_s", positive=True)
    s.offset_s = r.number("offset_s", 0.0, nonneg=True)
    s.jitter_s = r.number("jitter_s", 0.0, nonneg=True)
    if "seed" in table:
        if not isinstance(table["seed"], int) or isinstance(table["seed"], bool) or not (
                0 <= table["seed"] < 2**63):
            raise r.error("seed must be a whole number 0..2^63-1", "seed")
        s.seed = table["seed"]
    s.initial = r.flag("initial", s.initial)
    if s.pulses_s and s.period_s is not None:
        raise r.error("give pulses_s or period_s, not both", "period_s")
    if s.period_s is not None and s.pulse_ms / 1000.0 >= s.period_s:
        raise r.error("pulse_ms must be shorter than period_s", "pulse_ms")
    if s.period_s is not None and s.jitter_s * 2 >= s.period_s - s.pulse_ms / 1000.0:
        raise r.error("jitter_s is too large for period_s (pulses could overlap)", "jitter_s")
    return s


def _meter(file: str, table: dict, notes: list) -> Meter:
    r = _Reader(file, "[meter]", table, keys("meter"), notes=notes)
    return Meter(tau_s=r.number("tau_s", nonneg=True),
                 rate_hz=r.number("rate_hz", positive=True),
                 reference=r.string("reference", "iso8778", choices=METER_REFERENCES),
                 noise_l_min=r.number("noise_l_min", 0.0, nonneg=True),
                 offset_l_min=r.number("offset_l_min", 0.0),
                 full_scale_l_min=r.number("full_scale_l_min", positive=True),
                 line=r.string("line"),
                 sampling=r.string("sampling", choices=METER_SAMPLINGS))


def _calendar(file: str, table: dict, notes: list) -> Calendar:
    r = _Reader(file, "[calendar]", table, keys("calendar"), notes=notes)
    c = Calendar(shifts_per_day=r.number("shifts_per_day", 1.0, nonneg=True),
                 hours_per_shift=r.number("hours_per_shift", 8.0, nonneg=True),
                 days_per_week=r.number("days_per_week", 5.0, nonneg=True),
                 weeks_per_year=r.number("weeks_per_year", 52.0, nonneg=True),
                 production_share=r.number("production_share", 1.0, nonneg=True),
                 idle_state=r.string("idle_state", "off", choices=CALENDAR_IDLE_STATES))
    day_h = c.shifts_per_day * c.hours_per_shift
    if day_h > 24.0:
        raise r.error(f"shifts_per_day x hours_per_shift is {day_h:g} h, more than a day")
    if c.production_hours > HOURS_PER_YEAR:
        raise r.error(f"the calendar's {c.production_hours:g} production hours do not fit "
                      f"in a year ({HOURS_PER_YEAR:g} h)")
    return c


# [live] (plcpred watch): read here so that every command refuses a mistake in it; kept
# as a dict of the keys given, which plcpred.live completes with its defaults
def _live(file: str, table: dict, path: Path) -> dict:
    r = _Reader(file, "[live]", table, keys("live"))
    given = {
        "endpoint": r.string("endpoint"), "node_template": r.string("node_template"),
        "meter_node": r.string("meter_node"), "pressure_node": r.string("pressure_node"),
        "cycle_signal": r.string("cycle_signal"), "user": r.string("user"),
        "password_env": r.string("password_env"),
        "meter_unit": r.string("meter_unit", choices=LIVE_METER_UNITS),
        "meter_reference": r.string("meter_reference", choices=METER_REFERENCES),
        "security_policy": r.string("security_policy", choices=LIVE_SECURITY_POLICIES),
        "security_mode": r.string("security_mode", choices=LIVE_SECURITY_MODES),
        "window_s": r.number("window_s", nonneg=True),
        "sampling_ms": r.number("sampling_ms", nonneg=True),
        "publishing_ms": r.number("publishing_ms", nonneg=True),
        "rotate_s": r.number("rotate_s", nonneg=True),
        "meter_tau_s": r.number("meter_tau_s", nonneg=True),
        "gap_alarm_percent": r.number("gap_alarm_percent", nonneg=True),
        "gap_alarm_cycles": r.number("gap_alarm_cycles", nonneg=True),
        "idle_limit_l_min": r.number("idle_limit_l_min", nonneg=True),
        "learn_cycles": r.number("learn_cycles", nonneg=True),
        "diagnose_every_s": r.number("diagnose_every_s", nonneg=True),
        "prometheus": _metrics_address(r, table.get("prometheus")),
        "plot": r.flag("plot", None)}
    out = {k: v for k, v in given.items() if v is not None}
    for key in ("gap_alarm_cycles", "learn_cycles"):
        if key in out and out[key] != int(out[key]):
            raise r.error(f"{key} must be a whole number, not {out[key]:g}", key)
    # read when watch connects: paths, never the keys themselves
    for key, value in (("certificate", r.string("certificate")),
                       ("private_key", r.string("private_key"))):
        if value is not None:
            out[key] = str(path.parent / value)
    nodes = table.get("nodes", {})
    if not isinstance(nodes, dict) or not all(
            isinstance(v, str) and v and v.isprintable() and len(v) <= 1000
            for v in nodes.values()):
        raise r.error('nodes must be a table of signal = "node id" (non-empty text)')
    out["nodes"] = dict(nodes)
    template = out.get("node_template", "{signal}")
    if "{signal}" not in template or template.replace("{signal}", "").count("{") \
            or template.replace("{signal}", "").count("}"):
        raise r.error('node_template must hold {signal} once and no other braces, as in '
                      '"ns=4;s=MAIN.{signal}"')
    if out.get("security_policy", "None") != "None" and not (
            "certificate" in out and "private_key" in out):
        raise r.error(f"security_policy {out['security_policy']} needs certificate and "
                      "private_key")
    return out


_METRICS_ADDRESS = re.compile(r"(?:(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.-]+):)?(\d{1,5})")


def _metrics_address(r: _Reader, v) -> str | None:
    """[live] prometheus: a port (a number or text) or "HOST:PORT", as text."""
    if v is None:
        return None
    text = str(v) if isinstance(v, int) and not isinstance(v, bool) else v
    m = _METRICS_ADDRESS.fullmatch(text) if isinstance(text, str) else None
    if m is None or not 0 < int(m.group(2)) < 65536:
        raise r.error('prometheus must be a port (9109) or "HOST:PORT" ("127.0.0.1:9109"), '
                      f"not {_shown(v)}", "prometheus")
    return text


_PROGRAM_SUFFIXES = {".st", ".iecst", ".seq", ".xml", ".tcpou", ".tcgvl", ".tcdut", ".tcio",
                     ".tctto", ".plcproj"}


def as_machine(machine) -> Machine:
    """``machine`` itself when it is a loaded :class:`Machine`, else the machine file at
    that path, loaded: what every entry point that takes either does first."""
    return machine if isinstance(machine, Machine) else load_machine(machine)


def load_machine(path, allowed_roots=None) -> Machine:
    """Read and validate a machine file. Raises :class:`MachineError`. Its program and
    libraries must be under its folder, or one of ``allowed_roots`` (see
    :func:`machine_roots`)."""
    return machine_from_data(read_machine_data(path), path, allowed_roots)


MAX_MACHINE_BYTES = 16_000_000    # a machine file (a few kB in practice)


def machine_roots(path, allowed_roots=None) -> tuple[Path, ...]:
    """The folders a machine file's program and libraries may be in: the file's own
    folder, the ``allowed_roots`` given (a command line's ``--allow-root``), and those of
    the ``PLCPRED_ALLOW_ROOTS`` environment variable (os.pathsep-separated)."""
    roots = [resolved(Path(path).parent)]
    roots += [resolved(Path(r)) for r in allowed_roots or ()]
    roots += env_roots()
    return tuple(dict.fromkeys(roots))


def _contained_path(r: _Reader, key: str, value: str, path: Path, roots) -> Path:
    """The path ``value`` of ``key`` (relative to the machine file's folder) resolved,
    when it is a regular file (at most MAX_FILE_BYTES) or a folder under ``roots``; else
    a MachineError naming the key (and the path, never what the file holds)."""
    shown = value if len(value) <= 200 else value[:200] + "..."
    what = "program file" if key == "program" else "library"
    if "\0" in value:
        raise r.error(f"{key}: '{shown}' is not a path (it holds a NUL character)", key)
    target = files.resolved(path.parent / value)
    if not files.is_under(target, roots):
        raise r.error(f"{key}: " + files.outside_message(value, roots), key)
    try:
        st = target.stat()
    except (OSError, ValueError):
        raise r.error(f"{what} '{shown}' not found (looked for {target})", key) from None
    if stat_module.S_ISDIR(st.st_mode):
        return target
    if not stat_module.S_ISREG(st.st_mode):
        raise r.error(f"{key}: '{shown}' is not a regular file or a folder (a device, a "
                      "pipe or a socket): plcpred reads programs and libraries from files", key)
    if st.st_size > files.MAX_FILE_BYTES:
        raise r.error(f"{key}: '{shown}' is {files.size_text(st.st_size)}; plcpred reads "
                      f"files of at most {files.size_text(files.MAX_FILE_BYTES)}", key)
    return target


def read_machine_data(path) -> dict:
    """The machine file's TOML as a dict (not yet validated)."""
    path = Path(path)
    file = str(path)
    if path.is_dir() or path.suffix.lower() in _PROGRAM_SUFFIXES:
        raise MachineError(file, "", "this is a PLC program, not a machine file: commands that "
                                     "run a machine take its TOML machine file, which names "
                                     "the program (program = \"...\"); `plcpred check` reads "
                                     "programs")
    try:
        with _anywhere():
            raw = read_bytes(path, MAX_MACHINE_BYTES)   # a regular file, bounded
    except ProgramError as e:
        raise MachineError(file, "", e.message) from None
    return parse_toml(raw, file)


# tomllib's place of a syntax error, at the end of its message
_TOML_AT = re.compile(r"\s*\(at line (\d+), column (\d+)\)$")


def parse_toml(raw: bytes, file: str) -> dict:
    """A machine file's bytes as TOML data; errors at their line and column."""
    try:
        # newlines as a text file reads them (\r\n and \r as \n)
        return tomllib.loads(raw.decode("utf-8").replace("\r\n", "\n").replace("\r", "\n"))
    except UnicodeDecodeError as e:
        line = raw.count(b"\n", 0, e.start) + 1
        column = e.start - raw.rfind(b"\n", 0, e.start)
        raise MachineError(file, "", f"not UTF-8 text (byte {e.start}): TOML files are "
                                     "UTF-8", line=line, column=column) from None
    except RecursionError:
        raise MachineError(file, "", "not valid TOML: nested too deeply") from None
    except tomllib.TOMLDecodeError as e:
        message = str(e)
        at = _TOML_AT.search(message)
        if at is None:
            raise MachineError(file, "", f"not valid TOML: {message}") from None
        raise MachineError(file, "", f"not valid TOML: {message[:at.start()]}",
                           line=int(at.group(1)), column=int(at.group(2))) from None


def _anywhere():
    """The machine file itself is named by the user: read from wherever it is."""
    return confined_to(None)


def machine_from_data(data: dict, path, allowed_roots=None) -> Machine:
    """Validate a machine file's TOML data (as read, or with a sweep's settings applied:
    both go through the same checks). ``path`` is where it came from: the program path
    is relative to it and errors name it. The program and libraries must be regular
    files or folders under the file's folder or ``allowed_roots`` (:func:`machine_roots`),
    reached without leaving them through ``..`` or a symbolic link."""
    path = Path(path)
    notes: list[_Note] = []
    try:
        machine = _validated(data, path, allowed_roots, notes)
    except MachineError as e:
        raise locate_error(e, path, data)
    text = _source_text(path, data)[0] if notes else None
    machine.warnings[:0] = [_placed(n, str(path), text) for n in notes]
    return machine


def _validated(data: dict, path: Path, allowed_roots, notes: list) -> Machine:
    """The machine of ``data``; warnings about single keys go to ``notes``."""
    file = str(path)
    _check_table_names(data, file)
    machine = _machine_table(data["machine"], path, machine_roots(path, allowed_roots),
                             notes)
    machine.signals = _signals_table(data.get("signals", {}), file)
    for key, what, builder, out in (("input", "[[input]]", _input, machine.inputs),
                                    ("consumer", "[[consumer]]", _consumer, machine.consumers),
                                    ("line", "[[line]]", _line, machine.lines)):
        tables = data.get(key, [])
        if not isinstance(tables, list):
            raise MachineError(file, what, f"write it as {what} (an array of tables)",
                               table=key)
        for i, t in enumerate(tables):
            out.append(builder(file, i, t, notes))
    if "meter" in data:
        machine.meter = _meter(file, data["meter"], notes)
    if "calendar" in data:
        machine.calendar = _calendar(file, data["calendar"], notes)
    if "live" in data:
        machine.live = _live(file, data["live"], path)
    _check_names(machine, file)
    _check_supply(machine, file, notes)
    return machine


def _source_text(path: Path, data: dict | None = None) -> tuple[str | None, dict | None]:
    """(the text of the machine file at ``path``, its data) when it holds ``data`` (any
    data when None): then its lines are where ``data``'s keys stand. (None, None) when it
    cannot be read or holds something else (a sweep's settings, a truth file merged)."""
    try:
        with _anywhere():
            raw = read_bytes(path, MAX_MACHINE_BYTES)
        text = raw.decode("utf-8")
        parsed = tomllib.loads(text.replace("\r\n", "\n").replace("\r", "\n"))
    except (ProgramError, UnicodeDecodeError, RecursionError, tomllib.TOMLDecodeError,
            OSError, ValueError):
        return None, None
    if data is not None and parsed != data:
        return None, None
    return text, parsed


_WHERE = re.compile(r'(consumer|line|input) "(.*)"$')


def error_place(e: MachineError, data) -> tuple[str | None, int | None, str | None]:
    """(table, index, key) of an error; from its ``where`` (``consumer "clamp"``) when it
    was raised without them."""
    if e.table is not None:
        return e.table, e.index, e.key
    named = _WHERE.match(e.where)
    if named and isinstance(data, dict) and isinstance(data.get(named.group(1)), list):
        table, name = named.groups()
        ident = "signal" if table == "input" else "name"
        for i, t in enumerate(data[table]):
            if isinstance(t, dict) and t.get(ident) == name:
                return table, i, e.key
    if e.where.startswith("[") and not e.where.startswith("[["):
        return e.where.strip("[]"), None, e.key
    return None, None, None


def locate_error(e: MachineError, path, data: dict | None = None,
                 holding: str | None = None) -> MachineError:
    """``e`` with the line where its table and key stand in the file at ``path`` (when
    ``e`` names that file, has no line yet, the file holds ``data`` and that line holds
    the text ``holding``)."""
    if e.line is not None or e.file != str(path):
        return e
    text, parsed = _source_text(Path(path), data)
    if text is not None:
        line = line_of(text, *error_place(e, parsed))
        lines = text.replace("\r\n", "\n").replace("\r", "\n").split("\n")
        if line is not None and (holding is None or holding in lines[line - 1]):
            e.line = line
    return e


def _placed(note: _Note, file: str, text: str | None) -> str:
    """A warning as an error would read, at its line when ``text`` is the file's."""
    line = line_of(text, note.table, note.index, note.key) if text is not None else None
    return str(MachineError(file, note.where, note.message, line=line))


KNOWN_TABLES = ("machine", "signals", "input", "consumer", "meter", "line", "calendar",
                "live")


def _check_table_names(data: dict, file: str) -> None:
    """Only tables a machine file has, and a [machine] among them."""
    unknown = [k for k in data if k not in KNOWN_TABLES]       # in the file's order
    if unknown:
        raise MachineError(file, "", unknown_name("table", unknown[0], KNOWN_TABLES),
                           table=unknown[0])
    if "machine" not in data:
        raise MachineError(file, "", "missing the [machine] table")


def _machine_table(table: dict, path: Path, roots, notes: list) -> Machine:
    """The [machine] table: the program and libraries (under ``roots``), the scan, the
    supply and the ambient conditions, the cycle signal."""
    file = str(path)
    r = _Reader(file, "[machine]", table, keys("machine"), notes=notes)
    program = r.string("program", required=True)
    machine = Machine(
        name=r.string("name", path.stem),
        path=path,
        program_path=_contained_path(r, "program", program, path, roots),
        allowed_roots=roots,
        scan_ms=r.number("scan_ms", 10.0, positive=True),
        supply_bar_g=r.number("supply_bar_g", required=True, nonneg=True),
        atmosphere_kpa=r.number("atmosphere_kpa", P_ATM_KPA, positive=True),
        ambient_c=r.number("ambient_c", 20.0),
    )
    if "cycle_signal" in table:
        machine.cycle_signal = _signal_name(r, "cycle_signal", table["cycle_signal"])
    no_air = table.get("no_air", [])
    if not isinstance(no_air, list) or len(no_air) > 100_000:
        raise r.error('no_air must be a list of outputs, like ["qLamp"]', "no_air")
    machine.no_air = [_signal_name(r, "no_air", v) for v in no_air]
    if machine.ambient_c <= -ZERO_C_K:
        raise r.error("ambient_c must be above absolute zero", "ambient_c")
    libraries = table.get("libraries", [])
    if not isinstance(libraries, list) or not all(isinstance(x, str) and x for x in libraries):
        raise r.error('libraries must be a list of paths, like ["libs/MyLib/"]', "libraries")
    if len(libraries) > 100:
        raise r.error(f"libraries: {len(libraries)} of them; at most 100", "libraries")
    for lib in libraries:
        machine.library_paths.append(_contained_path(r, "libraries", lib, path, roots))
    return machine


def _signals_table(signals, file: str) -> dict:
    """[signals]: hardware addresses named (``"%IX0.0" = "PB1"``)."""
    if not isinstance(signals, dict):
        raise MachineError(file, "[signals]", 'entries must look like "%IX0.0" = "PB1"',
                           table="signals")
    for k, v in signals.items():
        if not (isinstance(v, str) and v and len(v) <= 255 and v.isprintable()):
            raise MachineError(file, "[signals]", 'entries must look like "%IX0.0" = "PB1"',
                               table="signals", key=k)
    return dict(signals)


def _check_names(machine: Machine, file: str) -> None:
    """Consumer and line names each used once, every line a consumer or the meter names
    declared, every input scheduled once."""
    seen = set()
    for i, c in enumerate(machine.consumers):
        if c.name in seen:
            raise MachineError(file, f'consumer "{c.name}"', "name is used twice",
                               table="consumer", index=i, key="name")
        seen.add(c.name)
    lines = set()
    for i, ln in enumerate(machine.lines):
        if ln.name in lines:
            raise MachineError(file, f'line "{ln.name}"', "name is used twice", table="line",
                               index=i, key="name")
        lines.add(ln.name)
    for i, c in enumerate(machine.consumers):
        if c.line is not None and c.line not in lines:
            raise MachineError(file, f'consumer "{c.name}"', _no_line(c.line, lines),
                               table="consumer", index=i, key="line")
    if machine.meter is not None and machine.meter.line is not None and \
            machine.meter.line not in lines:
        raise MachineError(file, "[meter]", _no_line(machine.meter.line, lines),
                           table="meter", key="line")
    seen = set()
    for i, s in enumerate(machine.inputs):
        if s.signal in seen:
            raise MachineError(file, f'input "{s.signal}"', "scheduled twice", table="input",
                               index=i, key="signal")
        seen.add(s.signal)


def _no_line(name: str, lines: set[str]) -> str:
    near = difflib.get_close_matches(name, sorted(lines), n=1, cutoff=0.6)
    return (f"line '{name}' is not a [[line]] of the file"
            + (f"; did you mean '{near[0]}'?" if near else
               f" (lines: {', '.join(sorted(lines)) or 'none'})"))


def _check_supply(machine: Machine, file: str, notes: list) -> None:
    """The supply against what each consumer needs: a warning for a nozzle regulated above
    the supply; each drive's ``"auto"`` stroke times computed now, so that a drive the
    supply cannot move is an error naming it."""
    supply_context = ((machine.supply_bar_g * PA_PER_BAR + machine.atmosphere_kpa * 1e3),
                      machine.atmosphere_kpa * 1e3, machine.ambient_c + ZERO_C_K, file)
    for i, c in enumerate(machine.consumers):
        c.supply_context = supply_context
        if c.stroke_time_s == "auto":
            try:
                c.auto_stroke_times()   # fails here, naming the drive, if it cannot move
            except MachineError as e:
                e.table, e.index, e.key = "consumer", i, "stroke_time_s"
                raise
        if c.kind == "nozzle" and c.pressure_bar_g is not None and \
                c.pressure_bar_g > machine.supply_bar_g:
            notes.append(_Note(
                f'consumer "{c.name}"', f"pressure_bar_g = {c.pressure_bar_g:g} is above "
                f"supply_bar_g = {machine.supply_bar_g:g}; a regulator cannot raise its "
                "supply (predict takes the nozzle's pressure as given, emulate the supply)",
                "consumer", i, "pressure_bar_g"))
