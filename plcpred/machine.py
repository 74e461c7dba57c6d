"""The machine file (TOML): ties a PLC program's inputs and outputs to physical consumers,
switches and input schedules. Contract: ``shared/design.md``, "Machine file".

``load_machine(path)`` reads and validates it. Problems are :class:`MachineError` naming
the file, the table and the key (``station.toml: consumer "clamp": stroke_mm must be > 0``);
harmless oddities are collected in ``Machine.warnings``.
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from .errors import PlcpredError

CYLINDER_KINDS = ("single_acting", "double_acting", "double_rod", "rodless", "semi_rotary",
                  "gripper")
PASSIVE_KINDS = ("nozzle", "leak")
KINDS = CYLINDER_KINDS + PASSIVE_KINDS
FLOW_MODELS = ("iso6358", "choked")
AUTO_SPEED_MM_S = 300.0  # stroke_time_s = "auto" until the plant model exists


class MachineError(PlcpredError):
    def __init__(self, file: str, where: str, message: str):
        super().__init__(message)
        self.file, self.where, self.message = file, where, message

    def __str__(self) -> str:
        return f"{self.file}: {self.where + ': ' if self.where else ''}{self.message}"

    def __reduce__(self):  # survives the trip back from a sweep's worker process
        return (type(self), (self.file, self.where, self.message))


@dataclass
class InputSchedule:
    """An external input: pulses at given times, or a periodic train (part arrivals)."""
    signal: str
    pulses_s: list[float] = field(default_factory=list)
    pulse_ms: float = 200.0
    period_s: float | None = None
    offset_s: float = 0.0
    jitter_s: float = 0.0
    seed: int | None = None
    initial: bool = False


@dataclass
class Consumer:
    name: str
    kind: str
    valve: list[str] = field(default_factory=list)  # [] (leak), [sol] (monostable), [a, b] bistable
    bore_mm: float | None = None
    rod_mm: float | None = None
    stroke_mm: float | None = None
    tube_id_mm: float | None = None
    tube_length_m: tuple[float, float] = (0.0, 0.0)  # valve to cap end, valve to rod end
    stroke_time_s: tuple[float, float] | str | None = None  # (extend, retract) or "auto"
    switch_delay_s: float = 0.0
    switches: dict[str, str] = field(default_factory=dict)  # retracted / extended -> signal
    initial: str = "retracted"
    pressure_bar_g: float | None = None
    C: float | None = None  # sonic conductance, m^3/(s Pa)
    b: float | None = None
    m: float | None = None
    a: float | None = None  # cracking pressure ratio
    orifice_mm: float | None = None
    Cd: float | None = None
    flow_model: str = "iso6358"
    exhaust_tau_s: float | None = None  # air-model option: incomplete exhaust (off)

    @property
    def is_cylinder(self) -> bool:
        return self.kind in CYLINDER_KINDS

    def stroke_times(self) -> tuple[float, float] | None:
        """(extend, retract) stroke times in s. ``"auto"`` asks the plant model, which
        does not exist yet: until it does, the stroke takes ``stroke_mm`` at
        AUTO_SPEED_MM_S (a mid-range piston speed between metered-out and free-running
        cylinders), and the machine warns about it."""
        if self.stroke_time_s == "auto":
            t = self.auto_stroke_times()
            return t if t[0] > 0 else None
        return self.stroke_time_s

    def auto_stroke_times(self) -> tuple[float, float]:
        """(extend, retract) of ``stroke_mm`` at AUTO_SPEED_MM_S."""
        t = (self.stroke_mm or 0.0) / AUTO_SPEED_MM_S
        return (t, t)

    @property
    def bistable(self) -> bool:
        return len(self.valve) == 2


@dataclass
class Meter:
    """The flow meter a measured run comes from (``[meter]``): what ``diagnose`` compares
    a prediction through, and what ``emulate`` imitates. All optional."""
    tau_s: float | None = None          # first-order response time
    rate_hz: float | None = None        # logging rate (readings averaged over 1/rate)
    reference: str = "iso8778"          # iso8778 | din1343 | iso2533
    noise_l_min: float = 0.0
    offset_l_min: float = 0.0           # reading at zero flow
    full_scale_l_min: float | None = None


@dataclass
class Machine:
    name: str
    path: Path
    program_path: Path
    scan_ms: float = 10.0
    supply_bar_g: float = 6.0
    atmosphere_kpa: float = 101.325
    ambient_c: float = 20.0
    signals: dict[str, str] = field(default_factory=dict)  # hardware address -> name
    inputs: list[InputSchedule] = field(default_factory=list)
    consumers: list[Consumer] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    meter: Meter | None = None

    def consumer(self, name: str) -> Consumer:
        for c in self.consumers:
            if c.name == name:
                return c
        raise KeyError(name)


_MACHINE_KEYS = {"name", "program", "scan_ms", "supply_bar_g", "atmosphere_kpa", "ambient_c"}
_INPUT_KEYS = {"signal", "pulses_s", "pulse_ms", "period_s", "offset_s", "jitter_s", "seed",
               "initial"}
_CONSUMER_KEYS = {"name", "kind", "valve", "bore_mm", "rod_mm", "stroke_mm", "tube_id_mm",
                  "tube_length_m", "stroke_time_s", "switch_delay_s", "switches", "initial",
                  "pressure_bar_g", "C", "b", "m", "a", "orifice_mm", "Cd", "flow_model",
                  "exhaust_tau_s"}
_METER_KEYS = {"tau_s", "rate_hz", "reference", "noise_l_min", "offset_l_min",
               "full_scale_l_min"}
METER_REFERENCES = ("iso8778", "din1343", "iso2533")


# Physical ranges of every number in a machine file: (lowest, highest). Wider than any real
# machine, so they only catch typos, unit mix-ups and values that would overflow the
# arithmetic (a 1e300 s stroke, a 1e-300 s pulse). Bounds are inclusive unless the key is
# also required to be positive.
RANGES = {
    "scan_ms": (0.01, 60_000.0), "supply_bar_g": (0.0, 100.0),
    "atmosphere_kpa": (50.0, 120.0), "ambient_c": (-60.0, 150.0),
    "bore_mm": (0.0, 2_000.0), "rod_mm": (0.0, 2_000.0), "stroke_mm": (0.0, 20_000.0),
    "tube_id_mm": (0.0, 200.0), "tube_length_m": (0.0, 1_000.0),
    "stroke_time_s": (1e-4, 3_600.0), "switch_delay_s": (0.0, 60.0),
    "pressure_bar_g": (0.0, 100.0), "C": (1e-15, 1e-3), "m": (0.0, 10.0), "a": (0.0, 1.0),
    "orifice_mm": (0.0, 1_000.0), "Cd": (0.0, 1.0),
    "pulse_ms": (1e-3, 1e9), "period_s": (1e-3, 1e8), "offset_s": (0.0, 1e9),
    "jitter_s": (0.0, 1e8), "pulses_s": (0.0, 1e9), "exhaust_tau_s": (1e-4, 60.0),
    "tau_s": (0.0, 600.0), "rate_hz": (1e-4, 1e5), "noise_l_min": (0.0, 1e7),
    "offset_l_min": (-1e6, 1e6), "full_scale_l_min": (0.0, 1e8),
}
MAX_PULSES = 1_000_000


class _Reader:
    """Typed access to one TOML table, with errors that say where."""

    def __init__(self, file: str, where: str, table: dict, allowed: set[str]):
        self.file, self.where, self.table = file, where, table
        if not isinstance(table, dict):
            raise self.error(f"must be a table, not {type(table).__name__}")
        unknown = sorted(set(table) - allowed)
        if unknown:
            raise self.error(f"unknown key '{unknown[0]}' (known keys: "
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
    r = _Reader(file, label, table, _CONSUMER_KEYS)
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
        c.bore_mm = r.number("bore_mm", required=True, positive=True)
        c.stroke_mm = r.number("stroke_mm", required=kind not in ("semi_rotary", "gripper"),
                               positive=True)
        if kind in ("semi_rotary", "gripper") and c.stroke_mm is None:
            raise r.error("missing required key 'stroke_mm' (for a semi-rotary drive or a "
                          "gripper: the equivalent stroke of its swept volume)")
        needs_rod = kind in ("double_acting", "double_rod", "single_acting")
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
            warnings.append(f"{file}: {label}: stroke_time_s = \"auto\" is estimated at "
                            f"{AUTO_SPEED_MM_S:g} mm/s until the plant model exists")
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
        for key in ("C", "b", "m", "a", "orifice_mm", "Cd", "pressure_bar_g", "flow_model"):
            if key in table:
                raise r.error(f"'{key}' applies to nozzles and leaks, not to a {kind}")
    else:
        for key in ("bore_mm", "rod_mm", "stroke_mm", "stroke_time_s", "switches",
                    "tube_length_m", "tube_id_mm", "switch_delay_s", "initial",
                    "exhaust_tau_s"):
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
    return c


def _input(file: str, index: int, table: dict) -> InputSchedule:
    label = f'input "{table.get("signal")}"' if isinstance(table, dict) and table.get(
        "signal") else f"input #{index + 1}"
    r = _Reader(file, label, table, _INPUT_KEYS)
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
    if "initial" in table:
        if not isinstance(table["initial"], bool):
            raise r.error("initial must be true or false")
        s.initial = table["initial"]
    if s.pulses_s and s.period_s is not None:
        raise r.error("give pulses_s or period_s, not both")
    if s.period_s is not None and s.pulse_ms / 1000.0 >= s.period_s:
        raise r.error("pulse_ms must be shorter than period_s")
    if s.period_s is not None and s.jitter_s * 2 >= s.period_s - s.pulse_ms / 1000.0:
        raise r.error("jitter_s is too large for period_s (pulses could overlap)")
    return s


def _meter(file: str, table: dict) -> Meter:
    r = _Reader(file, "[meter]", table, _METER_KEYS)
    return Meter(tau_s=r.number("tau_s", nonneg=True),
                 rate_hz=r.number("rate_hz", positive=True),
                 reference=r.string("reference", "iso8778", choices=METER_REFERENCES),
                 noise_l_min=r.number("noise_l_min", 0.0, nonneg=True),
                 offset_l_min=r.number("offset_l_min", 0.0),
                 full_scale_l_min=r.number("full_scale_l_min", positive=True))


def load_machine(path) -> Machine:
    """Read and validate a machine file. Raises :class:`MachineError`."""
    return machine_from_data(read_machine_data(path), path)


def read_machine_data(path) -> dict:
    """The machine file's TOML as a dict (not yet validated)."""
    path = Path(path)
    file = str(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as e:
        raise MachineError(file, "", f"cannot read file: {e.strerror}") from None
    except UnicodeDecodeError as e:
        raise MachineError(file, "", f"not UTF-8 text (byte {e.start}): TOML files are "
                                     "UTF-8") from None
    except RecursionError:
        raise MachineError(file, "", "not valid TOML: nested too deeply") from None
    except tomllib.TOMLDecodeError as e:
        raise MachineError(file, "", f"not valid TOML: {e}") from None
    return data


def machine_from_data(data: dict, path) -> Machine:
    """Validate a machine file's TOML data (as read, or with a sweep's settings applied:
    both go through the same checks). ``path`` is where it came from: the program path
    is relative to it and errors name it."""
    path = Path(path)
    file = str(path)
    unknown = sorted(set(data) - {"machine", "signals", "input", "consumer", "meter"})
    if unknown:
        raise MachineError(file, "", f"unknown table [{unknown[0]}] (known: [machine], "
                                     "[signals], [[input]], [[consumer]], [meter])")
    if "machine" not in data:
        raise MachineError(file, "", "missing the [machine] table")
    r = _Reader(file, "[machine]", data["machine"], _MACHINE_KEYS)
    program = r.string("program", required=True)
    machine = Machine(
        name=r.string("name", path.stem),
        path=path,
        program_path=(path.parent / program).resolve(),
        scan_ms=r.number("scan_ms", 10.0, positive=True),
        supply_bar_g=r.number("supply_bar_g", required=True, nonneg=True),
        atmosphere_kpa=r.number("atmosphere_kpa", 101.325, positive=True),
        ambient_c=r.number("ambient_c", 20.0),
    )
    if machine.ambient_c <= -273.15:
        raise r.error("ambient_c must be above absolute zero")
    if not machine.program_path.is_file():
        raise r.error(f"program file '{program}' not found (looked for "
                      f"{machine.program_path})")
    signals = data.get("signals", {})
    if not isinstance(signals, dict) or not all(
            isinstance(v, str) and v and len(v) <= 255 and v.isprintable()
            for v in signals.values()):
        raise MachineError(file, "[signals]", 'entries must look like "%IX0.0" = "PB1"')
    machine.signals = dict(signals)
    for key, what, builder, out in (("input", "[[input]]", _input, machine.inputs),
                                    ("consumer", "[[consumer]]", _consumer, machine.consumers)):
        tables = data.get(key, [])
        if not isinstance(tables, list):
            raise MachineError(file, what, f"write it as {what} (an array of tables)")
        for i, t in enumerate(tables):
            out.append(builder(file, i, t, machine.warnings) if key == "consumer"
                       else builder(file, i, t))
    if "meter" in data:
        machine.meter = _meter(file, data["meter"])
    seen = set()
    for c in machine.consumers:
        if c.name in seen:
            raise MachineError(file, f'consumer "{c.name}"', "name is used twice")
        seen.add(c.name)
    seen = set()
    for s in machine.inputs:
        if s.signal in seen:
            raise MachineError(file, f'input "{s.signal}"', "scheduled twice")
        seen.add(s.signal)
    return machine


def program_addresses(program) -> dict[str, str]:
    """Hardware address -> name of the variable declared AT it (``"%QX0.0" -> "Y_A"``), so
    a machine file may name a signal by its address without a [signals] entry."""
    out = {}
    blocks = [g.block for g in program.globals]
    blocks += [b for c in program.configurations for b in c.var_blocks]
    blocks += [b for c in program.configurations for r in c.resources for b in r.var_blocks]
    blocks += [b for p in program.pous if p.kind == "PROGRAM" for b in p.var_blocks]
    for b in blocks:
        for d in b.decls:
            if d.address and "*" not in d.address:
                out.setdefault(d.address.upper(), d.name)
    return out


def _program_io(program):
    """(all variable names, output names, names read anywhere) of a program, upper case."""
    from .parser.check import Checker

    names, outputs = set(), set()
    blocks = [g.block for g in program.globals]
    blocks += [b for c in program.configurations for b in c.var_blocks]
    blocks += [b for c in program.configurations for r in c.resources for b in r.var_blocks]
    for pou in program.pous:
        if pou.kind == "PROGRAM":
            blocks += pou.var_blocks
    for b in blocks:
        for d in b.decls:
            key = d.name.upper()
            names.add(key)
            if b.kind == "VAR_OUTPUT" or (d.address or "").startswith("%Q"):
                outputs.add(key)
    usage = Checker(program).run().program_usage
    return names, outputs, usage.read


def check_against_program(machine: Machine, program) -> list[str]:
    """Cross-check the machine's signals with the program's variables. Unknown signals are
    errors (raised); outputs that drive no consumer and switches the program never reads
    are returned (and added to ``machine.warnings``)."""
    file = str(machine.path)
    names, outputs, read = _program_io(program)
    by_address = program_addresses(program)
    by_address.update({addr.upper(): name for addr, name in machine.signals.items()})
    program_file = machine.program_path.name

    def resolve(signal: str) -> str:
        return by_address.get(signal.upper(), signal)

    def require(where: str, key: str, signal: str) -> str:
        name = resolve(signal)
        if name.upper() in used_addresses:
            return name.upper()  # an address the code uses directly
        base, dot, bit = name.rpartition(".")
        if dot and bit.isdigit() and base.upper() in names:
            name = base  # one bit of a WORD/BYTE variable
        if name.upper() not in names:
            raise MachineError(file, where, f"{key} '{signal}' is not a variable of "
                                            f"{program_file}")
        return name.upper()

    from .sequencer.compiler import names_in
    from .parser import ir
    used_addresses = {a.upper() for a in names_in(program, ir.DirectAddress, "address")}
    names |= used_addresses
    read = set(read) | used_addresses
    driven = set()
    warnings = []
    for c in machine.consumers:
        where = f'consumer "{c.name}"'
        for v in c.valve:
            driven.add(require(where, "valve", v))
        for role, sig in c.switches.items():
            name = require(where, f"switches.{role}", sig)
            if name not in read:
                warnings.append(f"{file}: {where}: switch '{sig}' is never read by "
                                f"{program_file}")
    for s in machine.inputs:
        require(f'input "{s.signal}"', "signal", s.signal)
    for out in sorted(outputs - driven):
        warnings.append(f"{file}: output '{out}' of {program_file} drives no consumer")
    machine.warnings.extend(warnings)
    return warnings
