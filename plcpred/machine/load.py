"""The machine file (TOML): ties a PLC program's inputs and outputs to physical consumers,
switches and input schedules. Every key is documented in ``docs/reference/machine-file.md``.

``load_machine(path)`` reads and validates it. Problems are :class:`MachineError` naming
the file, the table and the key (``station.toml: consumer "clamp": stroke_mm must be > 0``);
harmless oddities are collected in ``Machine.warnings``.
"""
from __future__ import annotations

import difflib
import math
import stat as stat_module
import tomllib
from pathlib import Path

from ..parser import ProgramError, files
from ..parser.files import confined_to, env_roots, read_bytes, resolved
from ..physics.units import BAR_PER_PSI, P_ATM_KPA, PA_PER_BAR, ZERO_C_K
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
    METER_REFERENCES,
    METER_SAMPLINGS,
    PASSIVE_KEYS,
    PLANT_DRIVE_KEYS,
    RANGES,
    keys,
)

MAX_PULSES = 1_000_000
# factory compressed air is 6-10 bar(g), high-pressure networks up to 16: a larger number
# is most likely psi typed as bar (87 psi = 6 bar)
PLAUSIBLE_SUPPLY_BAR_G = 16.0


class _Reader:
    """Typed access to one TOML table, with errors that say where."""

    def __init__(self, file: str, where: str, table: dict, allowed: set[str]):
        self.file, self.where, self.table = file, where, table
        if not isinstance(table, dict):
            raise self.error(f"must be a table, not {type(table).__name__}")
        unknown = sorted(set(table) - allowed)
        if unknown:
            near = difflib.get_close_matches(unknown[0], sorted(allowed), n=1, cutoff=0.6)
            hint = f"did you mean '{near[0]}'? " if near else ""
            raise self.error(f"unknown key '{unknown[0]}' ({hint}known keys: "
                             f"{', '.join(sorted(allowed))})")

    def error(self, message: str) -> MachineError:
        return MachineError(self.file, self.where, message)

    def number(self, key, default=None, *, required=False, positive=False, nonneg=False):
        if key not in self.table:
            if required:
                raise self.error(f"missing required key '{key}'")
            return default
        return self._checked(key, self.table[key], positive, nonneg)

    def _checked(self, key, v, positive, nonneg) -> float:
        if isinstance(v, bool) or not isinstance(v, (int, float)) or (
                isinstance(v, int) and abs(v) > 1e300) or not math.isfinite(v):
            raise self.error(f"{key} must be a number, not {_shown(v)}")
        if positive and v <= 0:
            raise self.error(f"{key} must be > 0")
        if nonneg and v < 0:
            raise self.error(f"{key} must be >= 0")
        low, high = RANGES.get(key, (-math.inf, math.inf))
        if not low <= v <= high:
            raise self.error(f"{key} = {_shown(v)} is outside the physical range "
                             f"{low:g}..{high:g}")
        return float(v)

    def flag(self, key, default=False) -> bool:
        """A true/false key (TOML's booleans only: 1 or "yes" are errors)."""
        if key not in self.table:
            return default
        if not isinstance(self.table[key], bool):
            raise self.error(f"{key} must be true or false")
        return self.table[key]

    def string(self, key, default=None, *, required=False, choices=None):
        if key not in self.table:
            if required:
                raise self.error(f"missing required key '{key}'")
            return default
        v = self.table[key]
        if not isinstance(v, str) or not v:
            raise self.error(f"{key} must be a non-empty string, not {_shown(v)}")
        if len(v) > 1000 or not v.isprintable():
            raise self.error(f"{key} must be printable text of at most 1000 characters")
        if choices and v not in choices:
            raise self.error(f"{key} must be one of {', '.join(choices)}, not {v!r}")
        return v

    def pair(self, key, default, *, positive=False, nonneg=False):
        """A number used for both directions, or [first, second]."""
        if key not in self.table:
            return default
        v = self.table[key]
        values = v if isinstance(v, list) else [v, v]
        if len(values) != 2:
            raise self.error(f"{key} must be a number or a list of two numbers")
        return tuple(self._checked(key, x, positive, nonneg) for x in values)


def _shown(v) -> str:
    text = repr(v)
    return text if len(text) <= 60 else text[:57] + "..."


def _signal_name(r: _Reader, key: str, v) -> str:
    """A signal: a variable name, an address or NAME.bit, as printable short text."""
    if not isinstance(v, str) or not v or len(v) > 255 or not v.isprintable():
        raise r.error(f"{key} must be a signal name (a variable, %IX0.0 or WORD.3), "
                      f"not {_shown(v)}")
    return v


def _consumer(file: str, index: int, table: dict, warnings: list) -> Consumer:
    label = f'consumer "{table.get("name")}"' if isinstance(table, dict) and table.get(
        "name") else f"consumer #{index + 1}"
    r = _Reader(file, label, table, keys("consumer"))
    kind = r.string("kind", required=True, choices=KINDS)
    c = Consumer(r.string("name", required=True), kind)
    valve = table.get("valve")
    if valve is None:
        if kind != "leak":
            raise r.error("missing required key 'valve'")
    elif kind == "leak":
        raise r.error("a leak is always on and has no valve")
    elif isinstance(valve, str) and valve:
        c.valve = [_signal_name(r, "valve", valve)]
    elif (isinstance(valve, list) and len(valve) == 2
          and all(isinstance(v, str) and v for v in valve)):
        c.valve = [_signal_name(r, "valve", v) for v in valve]
    else:
        raise r.error("valve must be a signal name (monostable) or two (bistable), "
                      f"not {valve!r}")
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
                      f"({c.bore_mm:g})")
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
        raise r.error("switches must be { retracted = \"...\", extended = \"...\" }")
    c.switches = {k: _signal_name(r, f"switches.{k}", v) for k, v in sw.items()}
    c.initial = r.string("initial", "retracted", choices=("retracted", "extended"))
    c.exhaust_tau_s = r.number("exhaust_tau_s", positive=True)
    c.partial_strokes = r.flag("partial_strokes")
    if c.partial_strokes and c.stroke_time_s is None:
        raise r.error("partial_strokes needs stroke_time_s (how far a piston gets "
                      "before the next edge)")
    c.plant = _plant_keys(r, table, kind)
    for key in PASSIVE_KEYS:
        if key in table:
            raise r.error(f"'{key}' applies to nozzles and leaks, not to a {kind}")


def _passive_keys(r: _Reader, table: dict, c: Consumer) -> None:
    """A nozzle's or leak's restriction (C, b, m, a or an orifice) and regulator."""
    kind = c.kind
    for key in (*CYLINDER_KEYS, *PLANT_DRIVE_KEYS):
        if key in table:
            raise r.error(f"'{key}' applies to cylinders, not to a {kind}")
    c.C = r.number("C", positive=True)
    c.orifice_mm = r.number("orifice_mm", positive=True)
    c.Cd = r.number("Cd", positive=True)
    if c.C is None and c.orifice_mm is None:
        raise r.error("give the sonic conductance C (m^3/(s Pa)) or orifice_mm and Cd")
    if c.C is not None and c.orifice_mm is not None:
        raise r.error("give either C or orifice_mm, not both")
    if c.orifice_mm is not None and c.Cd is None:
        raise r.error("orifice_mm needs a discharge coefficient Cd")
    if c.Cd is not None and c.Cd > 1:
        raise r.error("Cd must be at most 1")
    c.b = r.number("b", 0.528 if c.C is None else None)  # ideal nozzle by default
    if c.b is None:
        raise r.error("missing required key 'b' (critical pressure ratio) with C")
    if not -1.0 < c.b < 1.0:
        raise r.error("b must lie between -1 and 1")
    c.m = r.number("m", 0.5, positive=True)
    c.a = r.number("a", 1.0, positive=True)
    if c.a <= c.b or c.a > 1.0:
        raise r.error("a (cracking pressure ratio) must be > b and <= 1")
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
        raise r.error("spring_n applies to single-acting cylinders")
    if "friction_static_n" in out and "friction_coulomb_n" in out and any(
            s < c for s, c in zip(out["friction_static_n"], out["friction_coulomb_n"])):
        raise r.error("friction_static_n must be >= friction_coulomb_n (breakaway is the "
                      "larger force)")
    return out


def _line(file: str, index: int, table: dict) -> Line:
    label = f'line "{table.get("name")}"' if isinstance(table, dict) and table.get(
        "name") else f"line #{index + 1}"
    r = _Reader(file, label, table, keys("line"))
    line = Line(r.string("name", required=True),
                volume_l=r.number("volume_l", 1.0, positive=True),
                pressure_bar_g=r.number("pressure_bar_g", nonneg=True),
                network_bar_g=r.number("network_bar_g", nonneg=True),
                C=r.number("C", positive=True), b=r.number("b", 0.3),
                m=r.number("m", 0.5, positive=True),
                droop_bar=r.number("droop_bar", 0.3, positive=True))
    if not -1.0 < line.b < 1.0:
        raise r.error("b must lie between -1 and 1")
    line.check_valves = r.flag("check_valves", line.check_valves)
    return line


def _input(file: str, index: int, table: dict) -> InputSchedule:
    label = f'input "{table.get("signal")}"' if isinstance(table, dict) and table.get(
        "signal") else f"input #{index + 1}"
    r = _Reader(file, label, table, keys("input"))
    s = InputSchedule(_signal_name(r, "signal", r.string("signal", required=True)))
    pulses = table.get("pulses_s", [])
    if not isinstance(pulses, list) or len(pulses) > MAX_PULSES:
        raise r.error(f"pulses_s must be a list of at most {MAX_PULSES:,} times")
    s.pulses_s = sorted(r._checked("pulses_s", p, False, True) for p in pulses)
    s.pulse_ms = r.number("pulse_ms", 200.0, positive=True)
    s.period_s = r.number("period_s", positive=True)
    s.offset_s = r.number("offset_s", 0.0, nonneg=True)
    s.jitter_s = r.number("jitter_s", 0.0, nonneg=True)
    if "seed" in table:
        if not isinstance(table["seed"], int) or isinstance(table["seed"], bool) or not (
                0 <= table["seed"] < 2**63):
            raise r.error("seed must be a whole number 0..2^63-1")
        s.seed = table["seed"]
    s.initial = r.flag("initial", s.initial)
    if s.pulses_s and s.period_s is not None:
        raise r.error("give pulses_s or period_s, not both")
    if s.period_s is not None and s.pulse_ms / 1000.0 >= s.period_s:
        raise r.error("pulse_ms must be shorter than period_s")
    if s.period_s is not None and s.jitter_s * 2 >= s.period_s - s.pulse_ms / 1000.0:
        raise r.error("jitter_s is too large for period_s (pulses could overlap)")
    return s


def _meter(file: str, table: dict) -> Meter:
    r = _Reader(file, "[meter]", table, keys("meter"))
    return Meter(tau_s=r.number("tau_s", nonneg=True),
                 rate_hz=r.number("rate_hz", positive=True),
                 reference=r.string("reference", "iso8778", choices=METER_REFERENCES),
                 noise_l_min=r.number("noise_l_min", 0.0, nonneg=True),
                 offset_l_min=r.number("offset_l_min", 0.0),
                 full_scale_l_min=r.number("full_scale_l_min", positive=True),
                 line=r.string("line"),
                 sampling=r.string("sampling", choices=METER_SAMPLINGS))


def _calendar(file: str, table: dict) -> Calendar:
    r = _Reader(file, "[calendar]", table, keys("calendar"))
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


def _contained_path(r: "_Reader", key: str, value: str, path: Path, roots) -> Path:
    """The path ``value`` of ``key`` (relative to the machine file's folder) resolved,
    when it is a regular file (at most MAX_FILE_BYTES) or a folder under ``roots``; else
    a MachineError naming the key (and the path, never what the file holds)."""
    shown = value if len(value) <= 200 else value[:200] + "..."
    what = "program file" if key == "program" else "library"
    if "\0" in value:
        raise r.error(f"{key}: '{shown}' is not a path (it holds a NUL character)")
    target = files.resolved(path.parent / value)
    if not files.is_under(target, roots):
        raise r.error(f"{key}: " + files.outside_message(value, roots))
    try:
        st = target.stat()
    except (OSError, ValueError):
        raise r.error(f"{what} '{shown}' not found (looked for {target})") from None
    if stat_module.S_ISDIR(st.st_mode):
        return target
    if not stat_module.S_ISREG(st.st_mode):
        raise r.error(f"{key}: '{shown}' is not a regular file or a folder (a device, a "
                      "pipe or a socket): plcpred reads programs and libraries from files")
    if st.st_size > files.MAX_FILE_BYTES:
        raise r.error(f"{key}: '{shown}' is {files.size_text(st.st_size)}; plcpred reads "
                      f"files of at most {files.size_text(files.MAX_FILE_BYTES)}")
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
        # newlines as a text file reads them (\r\n and \r as \n)
        data = tomllib.loads(raw.decode("utf-8").replace("\r\n", "\n").replace("\r", "\n"))
    except ProgramError as e:
        raise MachineError(file, "", e.message) from None
    except UnicodeDecodeError as e:
        raise MachineError(file, "", f"not UTF-8 text (byte {e.start}): TOML files are "
                                     "UTF-8") from None
    except RecursionError:
        raise MachineError(file, "", "not valid TOML: nested too deeply") from None
    except tomllib.TOMLDecodeError as e:
        raise MachineError(file, "", f"not valid TOML: {e}") from None
    return data


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
    file = str(path)
    _check_table_names(data, file)
    machine = _machine_table(data["machine"], path, machine_roots(path, allowed_roots))
    machine.signals = _signals_table(data.get("signals", {}), file)
    for key, what, builder, out in (("input", "[[input]]", _input, machine.inputs),
                                    ("consumer", "[[consumer]]", _consumer, machine.consumers),
                                    ("line", "[[line]]", _line, machine.lines)):
        tables = data.get(key, [])
        if not isinstance(tables, list):
            raise MachineError(file, what, f"write it as {what} (an array of tables)")
        for i, t in enumerate(tables):
            out.append(builder(file, i, t, machine.warnings) if key == "consumer"
                       else builder(file, i, t))
    if "meter" in data:
        machine.meter = _meter(file, data["meter"])
    if "calendar" in data:
        machine.calendar = _calendar(file, data["calendar"])
    _check_names(machine, file)
    _check_supply(machine, file)
    return machine


KNOWN_TABLES = ("machine", "signals", "input", "consumer", "meter", "line", "calendar")


def _check_table_names(data: dict, file: str) -> None:
    """Only tables a machine file has, and a [machine] among them."""
    unknown = sorted(set(data) - set(KNOWN_TABLES))
    if unknown:
        near = difflib.get_close_matches(unknown[0], KNOWN_TABLES, n=1, cutoff=0.6)
        raise MachineError(file, "", f"unknown table [{unknown[0]}] ("
                                     + (f"did you mean [{near[0]}]? " if near else "")
                                     + "known: [machine], [signals], [[input]], "
                                       "[[consumer]], [[line]], [meter], [calendar])")
    if "machine" not in data:
        raise MachineError(file, "", "missing the [machine] table")


def _machine_table(table: dict, path: Path, roots) -> Machine:
    """The [machine] table: the program and libraries (under ``roots``), the scan, the
    supply and the ambient conditions, the cycle signal."""
    file = str(path)
    r = _Reader(file, "[machine]", table, keys("machine"))
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
    if machine.ambient_c <= -ZERO_C_K:
        raise r.error("ambient_c must be above absolute zero")
    libraries = table.get("libraries", [])
    if not isinstance(libraries, list) or not all(isinstance(x, str) and x for x in libraries):
        raise r.error('libraries must be a list of paths, like ["libs/MyLib/"]')
    if len(libraries) > 100:
        raise r.error(f"libraries: {len(libraries)} of them; at most 100")
    for lib in libraries:
        machine.library_paths.append(_contained_path(r, "libraries", lib, path, roots))
    return machine


def _signals_table(signals, file: str) -> dict:
    """[signals]: hardware addresses named (``"%IX0.0" = "PB1"``)."""
    if not isinstance(signals, dict) or not all(
            isinstance(v, str) and v and len(v) <= 255 and v.isprintable()
            for v in signals.values()):
        raise MachineError(file, "[signals]", 'entries must look like "%IX0.0" = "PB1"')
    return dict(signals)


def _check_names(machine: Machine, file: str) -> None:
    """Consumer and line names each used once, every line a consumer or the meter names
    declared, every input scheduled once."""
    seen = set()
    for c in machine.consumers:
        if c.name in seen:
            raise MachineError(file, f'consumer "{c.name}"', "name is used twice")
        seen.add(c.name)
    lines = {ln.name for ln in machine.lines}
    if len(lines) != len(machine.lines):
        raise MachineError(file, "[[line]]", "a line name is used twice")
    for c in machine.consumers:
        if c.line is not None and c.line not in lines:
            known = ", ".join(sorted(lines)) or "none"
            raise MachineError(file, f'consumer "{c.name}"', f"line '{c.line}' is not a "
                               f"[[line]] of the file (lines: {known})")
    if machine.meter is not None and machine.meter.line is not None and \
            machine.meter.line not in lines:
        raise MachineError(file, "[meter]", f"line '{machine.meter.line}' is not a [[line]] "
                           f"of the file (lines: {', '.join(sorted(lines)) or 'none'})")
    seen = set()
    for s in machine.inputs:
        if s.signal in seen:
            raise MachineError(file, f'input "{s.signal}"', "scheduled twice")
        seen.add(s.signal)


def _check_supply(machine: Machine, file: str) -> None:
    """The supply against what factory air runs at and what each consumer needs: a warning
    for psi typed as bar and for a nozzle regulated above the supply; each drive's
    ``"auto"`` stroke times computed now, so that a drive the supply cannot move is an
    error naming it."""
    if machine.supply_bar_g > PLAUSIBLE_SUPPLY_BAR_G:
        machine.warnings.append(
            f"{file}: [machine]: supply_bar_g = {machine.supply_bar_g:g} is above what "
            f"factory air runs at (up to {PLAUSIBLE_SUPPLY_BAR_G:g} bar(g)); if it is in "
            f"psi, that is {machine.supply_bar_g * BAR_PER_PSI:.2f} bar(g)")
    supply_context = ((machine.supply_bar_g * PA_PER_BAR + machine.atmosphere_kpa * 1e3),
                      machine.atmosphere_kpa * 1e3, machine.ambient_c + ZERO_C_K, file)
    for c in machine.consumers:
        c.supply_context = supply_context
        if c.stroke_time_s == "auto":
            c.auto_stroke_times()   # fails here, naming the drive, if it cannot move
        if c.kind == "nozzle" and c.pressure_bar_g is not None and \
                c.pressure_bar_g > machine.supply_bar_g:
            machine.warnings.append(
                f'{file}: consumer "{c.name}": pressure_bar_g = {c.pressure_bar_g:g} is above '
                f"supply_bar_g = {machine.supply_bar_g:g}; a regulator cannot raise its "
                "supply (predict takes the nozzle's pressure as given, emulate the supply)")
