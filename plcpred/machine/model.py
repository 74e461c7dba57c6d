"""What a machine file describes, as data: the machine, its consumers, input schedules,
supply lines, meter and calendar (read by :mod:`.load`, written by :mod:`.save`)."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from ..errors import PlcpredError
from ..parser import load_program
from ..parser.files import resolved
from ..physics.group import PlantError
from ..physics.strokes import auto_stroke_times
from ..physics.units import P_ATM_KPA, P_ATM_PA, PA_PER_BAR, T0_K

CYLINDER_KINDS = ("single_acting", "double_acting", "double_rod", "rodless", "semi_rotary",
                  "gripper")
PASSIVE_KINDS = ("nozzle", "leak")
KINDS = CYLINDER_KINDS + PASSIVE_KINDS
FLOW_MODELS = ("iso6358", "choked")


class MachineError(PlcpredError):
    """A problem in a machine (or truth) file: the file, ``where`` in it as the user reads
    it (``consumer "clamp"``, ``[machine]``) and the message. ``table``, ``index`` (of an
    array of tables) and ``key`` say where for a program: the loader finds the ``line``
    (and a TOML syntax error its ``column``) from them."""

    def __init__(self, file: str, where: str, message: str, *, table: str | None = None,
                 index: int | None = None, key: str | None = None, line: int | None = None,
                 column: int | None = None):
        super().__init__(message)
        self.file, self.where, self.message = file, where, message
        self.table, self.index, self.key = table, index, key
        self.line, self.column = line, column

    def __str__(self) -> str:
        at = "".join(f":{n}" for n in (self.line, self.column) if n is not None)
        return f"{self.file}{at}: {self.where + ': ' if self.where else ''}{self.message}"

    def __reduce__(self):  # survives the trip back from a sweep's worker process
        return (_machine_error, (self.file, self.where, self.message, self.table,
                                 self.index, self.key, self.line, self.column))


def _machine_error(file, where, message, table, index, key, line, column) -> MachineError:
    return MachineError(file, where, message, table=table, index=index, key=key, line=line,
                        column=column)


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
    partial_strokes: bool = False       # air-model option: strokes cut short (off)
    # air-model option: D1's air of each fill (extend, retract) times this (a calibration)
    air_factor: tuple[float, float] = (1.0, 1.0)
    line: str | None = None             # the [[line]] it hangs on (plant only)
    # (supply Pa, atmosphere Pa, ambient K, file) for stroke times from the plant
    supply_context: tuple = (6.0 * PA_PER_BAR + P_ATM_PA, P_ATM_PA, T0_K, "")
    plant: dict = field(default_factory=dict)  # plant-only keys (emulate), validated

    @property
    def is_cylinder(self) -> bool:
        return self.kind in CYLINDER_KINDS

    def stroke_times(self) -> tuple[float, float] | None:
        """(extend, retract) stroke times in s; ``"auto"`` asks the physics plant."""
        if self.stroke_time_s == "auto":
            return self.auto_stroke_times()
        return self.stroke_time_s

    def auto_stroke_times(self) -> tuple[float, float]:
        """(extend, retract) seconds from valve switch to end of stroke, by the physics
        plant at the machine's supply pressure with this drive's load and circuit
        (:mod:`plcpred.physics.strokes`; cached per configuration)."""
        *conditions, file = self.supply_context
        try:
            return auto_stroke_times(self, *conditions)
        except PlantError as e:
            raise MachineError(file, f'consumer "{self.name}"',
                               f'stroke_time_s = "auto": {e}') from None

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
    line: str | None = None             # on one [[line]] (after its regulator); default: the drop
    # what a reading is: "mean" (the response averaged over its logging interval, as a
    # meter's own logger reports) or "instant" (the response when it was read, as a PLC
    # polling the meter's analogue output does); None: not said (read as "mean")
    sampling: str | None = None


@dataclass
class Line:
    """A supply line (``[[line]]``, plant only): a regulator from the network into a
    volume that the consumers naming it draw from."""
    name: str
    volume_l: float = 1.0
    pressure_bar_g: float | None = None   # regulator set point (default: the machine's)
    network_bar_g: float | None = None    # upstream of the regulator (default set + 1 bar)
    C: float | None = None                # regulator's sonic conductance (default: ample)
    b: float = 0.3
    m: float = 0.5
    droop_bar: float = 0.3                # pressure drop from no flow to wide open
    check_valves: bool = False            # every drive on the line has a supply check valve


HOURS_PER_YEAR = 8760.0


@dataclass
class Calendar:
    """When the machine produces (``[calendar]``), for annual air, energy and cost: the
    supply stays pressurised all year, so leaks count for 8,760 h."""
    shifts_per_day: float = 1.0
    hours_per_shift: float = 8.0
    days_per_week: float = 5.0
    weeks_per_year: float = 52.0
    production_share: float = 1.0     # of the scheduled hours, the share it produces
    idle_state: str = "off"           # outside production: "off" (valves de-energised:
    #                                   leaks only) or "program" (as the program leaves it
    #                                   when nothing moves: leaks and blowers left on)

    @property
    def production_hours(self) -> float:
        return (self.shifts_per_day * self.hours_per_shift * self.days_per_week
                * self.weeks_per_year * self.production_share)


@dataclass
class Machine:
    name: str
    path: Path
    program_path: Path
    scan_ms: float = 10.0
    supply_bar_g: float = 6.0
    atmosphere_kpa: float = P_ATM_KPA
    ambient_c: float = 20.0
    signals: dict[str, str] = field(default_factory=dict)  # hardware address -> name
    inputs: list[InputSchedule] = field(default_factory=list)
    consumers: list[Consumer] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    meter: Meter | None = None
    calendar: Calendar | None = None
    lines: list[Line] = field(default_factory=list)
    # a BOOL that rises (or a counter that counts up) once per machine cycle or part
    cycle_signal: str | None = None
    # outputs that switch no air (a lamp, a motor): no "drives no consumer" warning
    no_air: list[str] = field(default_factory=list)
    # declarations of vendor libraries the program uses (files or folders)
    library_paths: list[Path] = field(default_factory=list)
    # the folders its program and libraries may be read from: the machine file's, and
    # those the user allows (--allow-root); () for a machine made in code: the program's
    # own folder
    allowed_roots: tuple = ()

    def read_program(self, path=None):
        """The machine's program (or the one at ``path``, which the user names: its
        folder may be read too), with what it uses from its libraries."""
        roots = tuple(self.allowed_roots) or None
        if path is not None and roots is not None:
            own = resolved(Path(path))
            roots += (own if own.is_dir() else own.parent,)
        return load_program(self.program_path if path is None else path,
                            lib_dirs=self.library_paths, allowed_roots=roots)

    def consumer(self, name: str) -> Consumer:
        for c in self.consumers:
            if c.name == name:
                return c
        raise KeyError(name)
