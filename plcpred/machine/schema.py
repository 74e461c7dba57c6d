"""Every key of the machine file, once: its table, the kind of value, its documentation
and, for numbers, its physical range. The reader takes the keys each table allows and
their ranges from here, ``sweep`` the numbers it may vary, ``init`` the keys it writes, and
``docs/reference/machine-file.md`` its key tables (``python -m plcpred.machine.schema``
writes them; a test checks that they agree)."""
from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

from ..physics.meter import REFERENCES
from ..physics.units import BAR_PER_PSI

TABLES = ("machine", "input", "consumer", "line", "meter", "calendar", "live")
# the kinds of value: a number, a number or [extend, retract] (or [cap, rod]), true/false,
# text, a whole number, a list of numbers, a program variable or address, one or two of
# them, a path (or a list of paths) relative to the file, an inline table
TYPES = ("number", "pair", "flag", "string", "integer", "numbers", "signal", "signals", "path",
         "paths", "table")


@dataclass(frozen=True)
class Row:
    """One row of a key table: keys documented together, their kind, default and meaning."""
    keys: tuple[str, ...]
    type: str
    default: str
    meaning: str


@dataclass(frozen=True)
class Section:
    """The keys of one table, or of one part of it, as the docs show them under
    ``heading``."""
    table: str
    heading: str
    rows: tuple[Row, ...]


SECTIONS = (
    Section('machine', '## `[machine]`', (
        Row(('name',), 'string', "the file's name",
            'shown in reports'),
        Row(('program',), 'path', 'required',
            ('the PLC program, relative to the machine file: an ST, `.seq`, PLCopen '
             'XML or TwinCAT object file, a TwinCAT `.plcproj`, or a folder holding a '
             'project (`"PLC/MyPlc/"`); it must be under the machine file\'s folder '
             '(see [Where programs and libraries may be](#where-programs-and-'
             'libraries-may-be))')),
        Row(('libraries',), 'paths', '`[]`',
            ('declarations of libraries the program uses, relative to the machine file'
             " (files or folders, as for `program`, under the machine file's folder "
             "too; at most 100); each one's name is its namespace (`MyLib.FB_X`). "
             'Stubs of common vendor libraries (Tc2_System, CODESYS Util, PLCopen '
             'motion) are built in')),
        Row(('scan_ms',), 'number', '10',
            "the PLC's scan time (0.01-60,000)"),
        Row(('supply_bar_g',), 'number', 'required',
            'the regulated supply pressure, gauge (0-100)'),
        Row(('atmosphere_kpa',), 'number', '101.325',
            'atmospheric pressure (50-120)'),
        Row(('ambient_c',), 'number', '20',
            "the air's and the walls' temperature (-60-150)"),
        Row(('cycle_signal',), 'signal', 'none',
            ('a program variable that marks each machine cycle or part: a BOOL counted'
             ' at each rising edge, or a counter counted at each increase '
             '(`nPartsDone`). `size` reports the air per cycle and the cycle time from'
             ' it, and `compare` gates air per cycle and the throughput. Without it, a'
             ' machine whose state repeats has as many cycles per repeating period as '
             'its least often switched valve switches on')),
        Row(('no_air',), 'signals', '`[]`',
            ('outputs of the program that switch no air (a lamp, a horn, a motor): named '
             'here, they draw no "drives no consumer" warning')),
    )),
    Section('input', '## `[[input]]`: inputs the world drives', (
        Row(('signal',), 'signal', 'required',
            'the input'),
        Row(('pulses_s',), 'numbers', 'none',
            'rising at each of these times (s)'),
        Row(('pulse_ms',), 'number', '200',
            'how long each pulse stays on'),
        Row(('period_s',), 'number', 'none',
            'or a periodic train (part arrivals) ...'),
        Row(('offset_s',), 'number', '0',
            '... whose first pulse comes at this time'),
        Row(('jitter_s',), 'number', '0',
            'random shift of each pulse, uniform within +/- this'),
        Row(('seed',), 'integer', '0',
            "the jitter's random seed (a whole number; runs repeat exactly)"),
        Row(('initial',), 'flag', 'false',
            'the value before the first pulse, and of an input with no schedule'),
    )),
    Section('consumer', '### Every consumer', (
        Row(('name',), 'string', 'required',
            'unique within the file'),
        Row(('kind',), 'string', 'required',
            'one of the kinds above'),
        Row(('valve',), 'signals', 'required (none for a `leak`)',
            'the output that switches it, or two for a bistable valve (below)'),
    )),
    Section('consumer', '### Cylinder-like consumers', (
        Row(('bore_mm',), 'number', 'required',
            'piston diameter'),
        Row(('rod_mm',), 'number', 'required for `double_acting`, `double_rod`; else 0',
            'rod diameter'),
        Row(('stroke_mm',), 'number', 'required',
            'stroke (for `semi_rotary` and `gripper`: the equivalent stroke)'),
        Row(('tube_id_mm',), 'number', '0',
            'inner diameter of the tubes from the valve'),
        Row(('tube_length_m',), 'pair', '0',
            'their length: a number, or [to cap end, to rod end]'),
        Row(('stroke_time_s',), 'pair', 'none',
            '[extend, retract] or one number, or `"auto"` (below)'),
        Row(('switch_delay_s',), 'number', '0',
            "the valve's switching delay"),
        Row(('switches',), 'table', 'none',
            '`{ retracted = "...", extended = "..." }`: the end switches the program reads'),
        Row(('initial',), 'string', '`"retracted"`',
            'or `"extended"`'),
        Row(('exhaust_tau_s',), 'number', 'off',
            ('activation-model option: a fill takes less by what its dead volume (the '
             "tube and the cylinder's own `dead_volume_cm3`) still holds above "
             'atmosphere, decaying with this time constant after the opposite stroke '
             'ended')),
        Row(('air_factor',), 'pair', '1',
            ("activation-model option: each fill's D1 air times this, [extend, retract] "
             "or one number: a calibration from flow logs (`diagnose --write-machine` "
             "writes it where the drive's strokes take less or more air than D1 books, "
             "as real strokes do by a few per cent); the physics plant ignores it")),
        Row(('partial_strokes',), 'flag', 'false',
            ('activation-model option (needs `stroke_time_s`): a stroke that the next '
             'edge cuts short (a pulse shorter than the stroke, a valve that chatters)'
             ' takes only the share of its swept volume the piston opened, and the '
             'chamber it leaves keeps the air of its swept share as a dead volume does'
             ' ([physics.md](physics.md#cylinders-air-per-valve-transition-d1): '
             'strokes cut short)')),
    )),
    Section('consumer', '### Nozzles and leaks', (
        Row(('C',), 'number', 'give `C` or `orifice_mm`',
            'sonic conductance, m^3/(s Pa)'),
        Row(('b',), 'number', 'required with `C`; 0.528 with an orifice',
            'critical pressure ratio (-1 < b < 1)'),
        Row(('m',), 'number', '0.5',
            'subsonic index'),
        Row(('a',), 'number', '1',
            'cracking pressure ratio (check valves), b < a <= 1'),
        Row(('orifice_mm', 'Cd'), 'number', '',
            'or an orifice and its discharge coefficient (Cd <= 1)'),
        Row(('pressure_bar_g',), 'number', 'the supply',
            'its own regulator (a leak may sit upstream, at the network)'),
        Row(('flow_model',), 'string', '`"iso6358"`',
            'or `"choked"`: the linear model (phi = 1)'),
    )),
    Section('consumer',
            '## Physics-plant keys (used by `plcpred emulate` and `"auto"` stroke times)', (
        Row(('payload_kg',), 'number', '0',
            'mass moved with the piston'),
        Row(('mount_angle_deg',), 'number', '0',
            '0 horizontal, 90 extending straight up, -90 straight down'),
        Row(('moving_mass_kg',), 'number', 'from the geometry',
            'piston and rod (an aluminium piston 0.4 x bore thick, a steel rod)'),
        Row(('supply_C', 'supply_b', 'supply_m'), 'pair',
            "the tube's bore as an orifice, Cd 0.6; b 0.3; m 0.5",
            'the supply-to-chamber paths: a number or [cap, rod]'),
        Row(('exhaust_C', 'exhaust_b', 'exhaust_m'), 'pair', 'as the supply paths',
            ('the chamber-to-exhaust paths; giving `exhaust_C` turns off the flow-'
             'control setting below')),
        Row(('check_valve',), 'flag', "false (or the line's `check_valves`)",
            'a check valve in the supply: a holding chamber cannot push air back'),
        Row(('friction_coulomb_n',), 'pair', "4 % of the cap side's force at 6 bar",
            'a number or [extending, retracting]'),
        Row(('friction_static_n',), 'pair', '1.5 x Coulomb',
            'breakaway friction (>= Coulomb)'),
        Row(('friction_viscous_ns_m',), 'pair', 'Coulomb per m/s',
            'viscous friction'),
        Row(('stribeck_velocity_m_s',), 'pair', '0.02',
            'the Stribeck velocity'),
        Row(('spring_n',), 'pair', '0.5 and 1.0 bar on the piston',
            'single-acting: spring force [retracted, extended]'),
        Row(('switch_ramp_s',), 'number', '0',
            'the valve opens its flow areas linearly over this time'),
        Row(('heat_transfer_w_m2k',), 'number', '30',
            'between the air and the walls'),
        Row(('dead_volume_cm3',), 'pair', '1 mm of stroke',
            ('inside the cylinder, beyond the tube: a number or [cap, rod]; the '
             'activation model uses it only for the air an incomplete exhaust keeps '
             '(`exhaust_tau_s`)')),
        Row(('line',), 'string', 'none',
            'the `[[line]]` it draws from (nozzles and leaks may name one too)'),
    )),
    Section('line', '### `[[line]]`: a supply line', (
        Row(('name',), 'string', 'required',
            'consumers name it in `line`'),
        Row(('volume_l',), 'number', '1',
            "the line's volume"),
        Row(('pressure_bar_g',), 'number', "the machine's `supply_bar_g`",
            "the regulator's set point"),
        Row(('network_bar_g',), 'number', 'set point + 1',
            'the pressure upstream of the regulator'),
        Row(('C', 'b', 'm'), 'number', '1e-7, 0.3, 0.5',
            "the regulator's flow path"),
        Row(('droop_bar',), 'number', '0.3',
            "the regulator's proportional band: the drop from no flow to wide open"),
        Row(('check_valves',), 'flag', 'false',
            'every drive on the line has a supply check valve'),
    )),
    Section('meter', '## `[meter]`: the flow meter of measured runs', (
        Row(('tau_s',), 'number', 'diagnose: fitted; emulate: 0.2',
            'first-order response time'),
        Row(('rate_hz',), 'number', 'emulate: 10',
            ('logging rate, each reading the mean over its interval (diagnose reads '
             "the log's own)")),
        Row(('reference',), 'string', '`"iso8778"`',
            'or `"din1343"` (0 °C, 101.325 kPa) or `"iso2533"` (15 °C, 101.325 kPa)'),
        Row(('noise_l_min',), 'number', '0',
            'emulate: Gaussian noise of the readings'),
        Row(('offset_l_min',), 'number', '0',
            'the reading at zero flow (diagnose subtracts it)'),
        Row(('full_scale_l_min',), 'number', 'none',
            'readings clip here (diagnose leaves them out)'),
        Row(('sampling',), 'string', '`"mean"`',
            ('`"mean"`: each reading is the mean of the meter\'s response over its '
             'logging interval (a meter\'s own logger); `"instant"`: the response at '
             "the moment it was read (a PLC or data logger polling the meter's "
             'analogue output)')),
        Row(('line',), 'string', 'none',
            "the meter sits after this line's regulator, not at the machine's drop"),
    )),
    Section('calendar', '## `[calendar]`: when the machine produces', (
        Row(('shifts_per_day',), 'number', '1',
            'shifts a day (with `hours_per_shift`, at most 24 h)'),
        Row(('hours_per_shift',), 'number', '8',
            'hours a shift'),
        Row(('days_per_week',), 'number', '5',
            'production days a week (0-7)'),
        Row(('weeks_per_year',), 'number', '52',
            'production weeks a year (0-53)'),
        Row(('production_share',), 'number', '1',
            'share of the scheduled hours the machine produces (0-1): availability'),
        Row(('idle_state',), 'string', '`"off"`',
            ('the machine outside production: `"off"` (valves de-energised, only leaks'
             ' use air) or `"program"` (as the program leaves it when nothing moves: '
             "leaks and blowers left on, at their rate over the run's idle time)")),
    )),
    Section('live', '## `[live]`: watching the running machine over OPC UA', (
        Row(('endpoint',), 'string', 'none',
            ('the OPC UA server of the PLC or gateway, `"opc.tcp://host:4840"` '
             "(`plcpred watch --endpoint` overrides it)")),
        Row(('node_template',), 'string', '`"ns=2;s={signal}"`',
            ('the node id of each signal, `{signal}` standing for its name in this '
             'file: `"ns=4;s=MAIN.{signal}"` on TwinCAT and CODESYS servers; '
             '`plcpred serve` uses the default')),
        Row(('nodes',), 'table', '`{}`',
            'node ids of single signals where the template does not fit: '
            '`{ qZ = "ns=4;s=GVL.qZ" }`'),
        Row(('meter_node',), 'string', 'the template with `flow_l_min`',
            "the flow meter's node (a number)"),
        Row(('meter_unit',), 'string', '`"l/min"`',
            'its unit: `"l/min"`, `"m3/h"`, `"l/s"`, `"m3/min"` or `"scfm"`'),
        Row(('meter_reference',), 'string', "`[meter]`'s, else `\"iso8778\"`",
            'its reference condition: `"iso8778"`, `"din1343"` or `"iso2533"`'),
        Row(('meter_tau_s',), 'number', "`[meter]`'s, else 0.2",
            "its response time: the prediction goes through it before it is compared"),
        Row(('pressure_node',), 'string', 'the template with `supply_bar_g`',
            'the supply pressure (bar gauge), recorded when the server has it'),
        Row(('cycle_signal',), 'signal', "`[machine]`'s",
            ('compared per cycle between its rising edges; without one, per window of '
             '`window_s`')),
        Row(('window_s',), 'number', '60',
            'the comparison window of a machine without a cycle signal (1-86,400)'),
        Row(('sampling_ms',), 'number', '0',
            "how often the server samples each node (0: as fast as it can)"),
        Row(('publishing_ms',), 'number', '100',
            'how often it sends what changed (10-60,000)'),
        Row(('rotate_s',), 'number', '3600',
            'a new pair of recorded files every so many seconds of machine time '
            '(60-86,400: hourly by default, 86400 daily)'),
        Row(('gap_alarm_percent',), 'number', '10',
            'alarm when measured differs from predicted by more than this ...'),
        Row(('gap_alarm_cycles',), 'integer', '3',
            '... for this many cycles (or windows) in a row'),
        Row(('idle_limit_l_min',), 'number', 'none',
            'alarm when the flow while the machine rests exceeds this (NL/min)'),
        Row(('learn_cycles',), 'integer', '10',
            ('judge the gap against a reference learned from this many first cycles (D1 '
             'scaled per consumer to what the healthy machine measured; 0: against D1 '
             'itself; 0-100,000)')),
        Row(('diagnose_every_s',), 'number', 'none',
            ('diagnose the last so many seconds of machine time every so many seconds, in '
             'a worker process while recording goes on (10-86,400: 900 is every 15 '
             'minutes)')),
        Row(('prometheus',), 'string', 'none',
            ('serve the comparison as Prometheus metrics at this port, on every interface '
             '(`9109`), or at `"HOST:PORT"` (`"127.0.0.1:9109"`); needs the '
             '`prometheus-client` package')),
        Row(('plot',), 'flag', 'false',
            ("draw the comparison per cycle (`comparison.png`, as in the [guide]"
             "(../guide/live.md#the-comparison-as-a-picture)) in the output folder when "
             "the watch ends")),
        Row(('security_policy',), 'string', '`"None"`',
            ('`"Basic256Sha256"`, `"Aes128_Sha256_RsaOaep"` or `"Aes256_Sha256_RsaPss"` '
             '(with `certificate` and `private_key`)')),
        Row(('security_mode',), 'string', '`"SignAndEncrypt"`',
            'or `"Sign"`'),
        Row(('certificate', 'private_key'), 'path', 'none',
            "the client's certificate and key (PEM or DER), relative to this file; "
            'never logged'),
        Row(('user',), 'string', 'none',
            'a user name to log in with ...'),
        Row(('password_env',), 'string', '`"PLCPRED_OPCUA_PASSWORD"`',
            '... and the environment variable that holds the password (never written '
            'in this file, never logged)'),
    )),

)

METER_REFERENCES = tuple(REFERENCES)
METER_SAMPLINGS = ("mean", "instant")
CALENDAR_IDLE_STATES = ("off", "program")
LIVE_METER_UNITS = ("l/min", "m3/h", "l/s", "m3/min", "scfm")
LIVE_SECURITY_POLICIES = ("None", "Basic256Sha256", "Aes128_Sha256_RsaOaep",
                          "Aes256_Sha256_RsaPss")
LIVE_SECURITY_MODES = ("Sign", "SignAndEncrypt")

# Physical ranges of every number in a machine file: (lowest, highest). Wider than any real
# machine, so they only catch typos, unit mix-ups and values that would overflow the
# arithmetic (a 1e300 s stroke, a 1e-300 s pulse). Bounds are inclusive unless the key is
# also required to be positive.
RANGES = {
    "scan_ms": (0.01, 60_000.0), "supply_bar_g": (0.0, 100.0),
    "atmosphere_kpa": (50.0, 120.0), "ambient_c": (-60.0, 150.0),
    # sizes a drive can have: the smallest pneumatic cylinders have 2.5 mm bores and
    # strokes of a few mm (5e-324 passed "> 0" and divided by zero in the plant)
    "bore_mm": (0.1, 2_000.0), "rod_mm": (0.0, 2_000.0), "stroke_mm": (0.01, 20_000.0),
    "tube_id_mm": (0.1, 200.0), "tube_length_m": (0.0, 1_000.0),
    "stroke_time_s": (1e-4, 3_600.0), "switch_delay_s": (0.0, 60.0),
    "pressure_bar_g": (0.0, 100.0), "C": (1e-15, 1e-3), "m": (0.0, 10.0), "a": (0.0, 1.0),
    "orifice_mm": (0.001, 1_000.0), "Cd": (0.0, 1.0),
    "pulse_ms": (1e-3, 1e9), "period_s": (1e-3, 1e8), "offset_s": (0.0, 1e9),
    "jitter_s": (0.0, 1e8), "pulses_s": (0.0, 1e9), "exhaust_tau_s": (1e-4, 60.0),
    "air_factor": (0.05, 20.0),
    "tau_s": (0.0, 600.0), "rate_hz": (1e-4, 1e5), "noise_l_min": (0.0, 1e7),
    "offset_l_min": (-1e6, 1e6), "full_scale_l_min": (0.0, 1e8),
    "payload_kg": (0.0, 1e5), "mount_angle_deg": (-90.0, 90.0), "moving_mass_kg": (0.0, 1e5),
    "supply_C": (1e-15, 1e-3), "exhaust_C": (1e-15, 1e-3), "supply_b": (-1.0, 0.99),
    "exhaust_b": (-1.0, 0.99), "supply_m": (0.05, 10.0), "exhaust_m": (0.05, 10.0),
    "friction_static_n": (0.0, 1e6), "friction_coulomb_n": (0.0, 1e6),
    "friction_viscous_ns_m": (0.0, 1e7), "stribeck_velocity_m_s": (1e-5, 10.0),
    "spring_n": (0.0, 1e6), "switch_ramp_s": (0.0, 10.0), "heat_transfer_w_m2k": (0.0, 1e4),
    "dead_volume_cm3": (0.0, 1e7), "volume_l": (1e-4, 1e6), "network_bar_g": (0.0, 100.0),
    "droop_bar": (1e-3, 50.0), "shifts_per_day": (0.0, 24.0), "hours_per_shift": (0.0, 24.0),
    "days_per_week": (0.0, 7.0), "weeks_per_year": (0.0, 53.0), "production_share": (0.0, 1.0),
}

# [live]'s numbers (plcpred watch)
RANGES.update({"window_s": (1.0, 86_400.0), "sampling_ms": (0.0, 60_000.0),
               "publishing_ms": (10.0, 60_000.0), "rotate_s": (60.0, 86_400.0),
               "meter_tau_s": (0.0, 600.0), "gap_alarm_percent": (0.1, 1_000.0),
               "gap_alarm_cycles": (1.0, 10_000.0), "idle_limit_l_min": (0.0, 1e8),
               "learn_cycles": (0.0, 100_000.0), "diagnose_every_s": (10.0, 86_400.0)})


@dataclass(frozen=True)
class Plausible:
    """Where the numbers of real machines lie. Outside it (but inside :data:`RANGES`) a
    value is more likely a unit mixed up than a machine: a warning, with the likely mix-up
    (``low_hint``, ``high_hint``: format strings of the value ``v`` and its readings in
    other units)."""
    low: float
    high: float
    unit: str
    high_hint: str = ""
    low_hint: str = ""

    def holds(self, v: float) -> bool:
        return self.low <= v <= self.high

    @property
    def span(self) -> str:
        return f"{self.low:g}{' to ' if self.low < 0 else '-'}{self.high:g} {self.unit}"

    def warning(self, key: str, v: float) -> str:
        hint = self.high_hint if v > self.high else self.low_hint
        text = f"{key} = {v:g} {self.unit} is outside the plausible {self.span}"
        if hint:
            text += "; " + hint.format(v=v, psi_as_bar=v * BAR_PER_PSI, per_1000=v / 1000,
                                       times_10=v * 10, times_1000=v * 1000,
                                       fahrenheit_as_c=(v - 32) / 1.8)
        return text


_PSI = "psi typed as bar? {v:g} psi is {psi_as_bar:.2f} bar(g)"
_MS_AS_S = "ms typed as s? {v:g} ms is {per_1000:g} s"

# the plausible values of the keys most often typed in a wrong unit
PLAUSIBLE = {
    "supply_bar_g": Plausible(1.0, 16.0, "bar(g)", _PSI),
    "pressure_bar_g": Plausible(0.0, 16.0, "bar(g)", _PSI),
    "network_bar_g": Plausible(0.0, 16.0, "bar(g)", _PSI),
    "ambient_c": Plausible(-30.0, 60.0, "°C", "°F typed as °C? {v:g} °F is "
                                               "{fahrenheit_as_c:.0f} °C"),
    "scan_ms": Plausible(0.25, 1000.0, "ms", low_hint="s typed as ms? {v:g} s is "
                                                      "{times_1000:g} ms"),
    "bore_mm": Plausible(2.5, 320.0, "mm", low_hint="cm typed as mm? {v:g} cm is "
                                                    "{times_10:g} mm"),
    "stroke_mm": Plausible(1.0, 6000.0, "mm", low_hint="cm typed as mm? {v:g} cm is "
                                                       "{times_10:g} mm"),
    "tube_id_mm": Plausible(1.0, 25.0, "mm", low_hint="cm typed as mm? {v:g} cm is "
                                                      "{times_10:g} mm"),
    "tube_length_m": Plausible(0.0, 30.0, "m", "mm typed as m? {v:g} mm is {per_1000:g} m"),
    "stroke_time_s": Plausible(0.005, 30.0, "s", _MS_AS_S),
    "switch_delay_s": Plausible(0.0, 0.5, "s", _MS_AS_S),
    "exhaust_tau_s": Plausible(0.001, 5.0, "s", _MS_AS_S),
    "orifice_mm": Plausible(0.05, 25.0, "mm"),
    "tau_s": Plausible(0.0, 30.0, "s", _MS_AS_S),
}


def plausible_markdown() -> str:
    """The table of :data:`PLAUSIBLE` as the docs show it."""
    lines = ["| key | plausible | outside it, likely |", "|---|---|---|"]
    for key, p in PLAUSIBLE.items():
        hints = [h.split("?")[0] + "?" for h in (p.low_hint, p.high_hint) if h]
        lines.append(f"| `{key}` | {p.span} | "
                     f"{'; '.join(hints) or 'a typo'} |")
    return "\n".join(lines)


def keys(table: str) -> set[str]:
    """The keys ``table`` (``"consumer"``, ...) allows."""
    return {k for s in SECTIONS if s.table == table for row in s.rows for k in row.keys}


def key_types(table: str, plant: bool = True) -> dict[str, str]:
    """Each key of ``table`` with its kind of value (without ``plant``: leaving out the
    keys only the physics plant reads)."""
    return {k: row.type for s in SECTIONS if s.table == table
            and (plant or not is_plant_section(s)) for row in s.rows for k in row.keys}


def section_keys(heading: str) -> tuple[str, ...]:
    """The keys of the section under ``heading``, in the docs' order."""
    section = next(s for s in SECTIONS if s.heading == heading)
    return tuple(k for row in section.rows for k in row.keys)


CYLINDER_KEYS = section_keys("### Cylinder-like consumers")
PASSIVE_KEYS = section_keys("### Nozzles and leaks")


def is_plant_section(section: Section) -> bool:
    return section.heading.startswith("## Physics-plant")


# the plant-only keys of a drive (emulate; the activation model ignores them) -> kind
PLANT_DRIVE_KEYS = {k: row.type for s in SECTIONS if is_plant_section(s)
                    for row in s.rows for k in row.keys if k != "line"}


def markdown(section: Section) -> str:
    """The section's key table as the docs show it."""
    lines = ["| key | default | meaning |", "|---|---|---|"]
    for row in section.rows:
        keys_text = ", ".join(f"`{k}`" for k in row.keys)
        lines.append(f"| {keys_text} | {row.default} | {row.meaning} |".replace("|  |", "| |"))
    return "\n".join(lines)


PLAUSIBLE_HEADING = "### Values that draw a warning"


def with_tables(doc: str) -> str:
    """``doc`` (the machine-file reference) with each section's key table, and the table
    of plausible values, written anew after its heading (the first table that follows
    it)."""
    lines = doc.split("\n")
    tables = [(s.heading, markdown(s)) for s in SECTIONS]
    tables.append((PLAUSIBLE_HEADING, plausible_markdown()))
    for heading, table in tables:
        start = lines.index(heading)
        head = table.split("\n")[0]
        first = next(i for i in range(start, len(lines)) if lines[i].strip() == head)
        end = first
        while end < len(lines) and lines[end].startswith("|"):
            end += 1
        lines[first:end] = table.split("\n")
    return "\n".join(lines)


DOC = Path(__file__).resolve().parent.parent.parent / "docs" / "reference" / "machine-file.md"


def main() -> int:
    """``python -m plcpred.machine.schema``: write the key tables of the machine-file
    reference from :data:`SECTIONS`."""
    if not DOC.exists():
        print(f"{DOC} not found (run from a source checkout)", file=sys.stderr)
        return 2
    DOC.write_text(with_tables(DOC.read_text()))
    print(f"wrote the key tables of {DOC}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
