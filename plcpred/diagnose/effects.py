"""The unmodelled effects a diagnosis can name, each a physically bounded change of the
activation model's numbers (shaped after lmfit: a function plus parameter specs).

Each :class:`Effect` has parameters with a unit and bounds, ``apply`` (fitted values to a
changed :class:`~plcpred.diagnose.fit_model.ModelParams`), ``physical`` (the values as a user
reads them: a leak as NL/min and its sonic conductance C, a tube as metres, ...) and
``to_machine`` (the change written into a machine file in the model's own keys, so that
``plcpred predict`` on the fixed file carries it).

The vocabulary (design contract): ``leak passive_flow supply_pressure dead_volume
incomplete_exhaust shared_supply valve_delay stroke_time sensor_lag meter_gain``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..air.demand import sonic_conductance
from ..physics.flow import flow_nl_min
from ..physics.meter import REFERENCES, reference_factor
from ..physics.units import P0_PA, T0_K, bar_g_to_pa, celsius_to_k
from ..physics.volumes import held_air_nl, inner_dead_volumes_cm3, swept_areas_mm2
from .fit_model import MachineModel, ModelParams

# a diagnosed leak is written as an orifice-like restriction: ISO 6358 with b and m of a
# sharp-edged hole (choked at any supply above 0.9 bar gauge, so its flow is C-linear)
LEAK_B = 0.528
LEAK_M = 0.5
DEFAULT_TUBE_ID_MM = 4.0     # a diagnosed dead volume on a drive without tube data
MAX_METER_TAU_S = 10.0
# a cylinder's own dead volume (end caps, ports, cushions) up to this share of its swept
# volume, for an incomplete exhaust
MAX_INNER_DEAD_SHARE = 0.2
# an exhaust time constant below the machine file's smallest is written as off
MIN_WRITTEN_TAU_S = 1e-4
# a supply pressure this share away from the file's (gauge) is an unlikely verdict
MAX_SUPPLY_CHANGE = 0.5
# a dead volume fit that takes away more than this share of a drive's stated tube
MAX_TUBE_OVERSTATEMENT = 0.5
# a supply the log records may be fitted this far from the log's mean (a gauge's
# accuracy and a regulator's swing with the flow)
LOGGED_SUPPLY_TOLERANCE_BAR = 0.15
METER_LAG_FIT_MAX_S = 0.6   # thermal-mass meters respond in 0.1-0.6 s (docs/reference/physics.md: figures)

# What a healthy machine may show against its own file: a file's values are catalogue,
# drawing and commissioning figures, not measurements, so a fit that moves them no
# further than this names no fault (Effect.within_tolerance).
# A nozzle's conductance from a catalogue or an orifice and Cd: known to about 10 %, and
# the pressure at it a few per cent below the supply while it flows
PASSIVE_TOLERANCE_SHARE = 0.15
# stroke times are set at commissioning by eye and stopwatch: +/-10 %
STROKE_TOLERANCE_SHARE = 0.10
# a valve's switching time differs between units and with coil temperature by about
# 10 ms, and its spool takes 5-25 ms to open, which shifts the air by half of that
DELAY_TOLERANCE_S = 0.025
# a regulator's setting and its gauge: about 0.1 bar
SUPPLY_TOLERANCE_BAR = 0.1
# tubes are cut to length on site: a quarter either way, plus the volumes a file rarely
# gives: the cylinder's end caps, ports and cushions and the fittings, up to this much
# stroke's worth of bore beyond what the file says
TUBE_TOLERANCE_SHARE = 0.25
UNSTATED_DEAD_STROKE_MM = 2.0
# a hot fill and an exhaust cut short: a healthy stroke takes up to this share of D1 less
# than a settled one (the model-form band's bottom, diagnose.band)
HOT_FILL_SHARE = 0.08
# a thermal-mass meter reads within 1-3 % of reading
METER_GAIN_TOLERANCE = 0.03
# a meter's zero offset and the leaks every machine has at its fittings: 1 % of the flow
LEAK_TOLERANCE_SHARE = 0.01
# a line's own volume gives a little air back after each stroke on any machine
REFILL_TOLERANCE_FRACTION = 0.05


@dataclass
class Param:
    name: str
    unit: str
    lower: float
    upper: float
    init: float
    # values tried one parameter at a time before the least-squares fit, for parameters
    # whose fit is not convex (a shift or a time constant can lock onto the wrong edge)
    grid: tuple = ()
    # each value costs a sequencer run (a closed loop's timing, diagnose.timing): swept
    # on the grid and refined by golden section between grid neighbours, never by least
    # squares (the quantised value is piecewise constant)
    discrete: bool = False
    # each value a plant run (diagnose.through_plant): a fold chooses among the values
    # the fit on all samples ran rather than refining (which would run more)
    plant: bool = False
    # a discrete parameter of several drives also swept as one value for all of them
    joint: bool = True
    # the model's own accuracy, fitted beside an effect (diagnose.band): at a bound it
    # says nothing about the effect
    nuisance: bool = False


DELAY_GRID_S = tuple(np.round(np.arange(0.0, 0.51, 0.05), 3))
FACTOR_GRID = (0.25, 0.35, 0.5, 0.7, 1.0, 1.4, 2.0, 2.8, 4.0)
# a closed loop's grids are coarser (each value a sequencer run per log); golden section
# refines between neighbours
CLOSED_DELAY_GRID_S = (0.0, 0.03, 0.08, 0.16, 0.3, 0.5)
CLOSED_FACTOR_GRID = (0.5, 0.7, 1.0, 1.4, 2.0, 2.8, 4.0)
TAU_GRID_S = (0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0)


class Effect:
    name = ""
    title = ""
    expressible = True      # to_machine can write it in the machine file's keys
    through_plant = False   # its values are machine files run through the plant

    def params(self, mm: MachineModel, ctx: dict) -> list[Param]:
        raise NotImplementedError

    def applies(self, mm: MachineModel) -> bool:
        return True

    def apply(self, mm: MachineModel, p: ModelParams, theta) -> ModelParams:
        raise NotImplementedError

    def physical(self, mm: MachineModel, theta) -> dict:
        return {}

    def implausible(self, mm: MachineModel, theta) -> str | None:
        """Why fitted values ``theta`` are unlikely as a plant's truth, if they are (a
        verdict prefers an as-good effect whose values are not)."""
        return None

    def to_machine(self, mm: MachineModel, data: dict, theta) -> list[str]:
        """Change the machine file's TOML data in place; return what was changed."""
        return []

    def tolerance_box(self, mm: MachineModel, ctx: dict) -> list[tuple[float, float]] | None:
        """Per parameter, (low, high): the values within which the file's values move no
        further than a healthy machine's own differ from its file (catalogue
        conductances, stroke times set by eye, tubes cut on site); None for an effect
        no healthy machine shows."""
        return None

    def tolerance_reason(self, mm: MachineModel, theta, ctx: dict) -> str:
        """Why values ``theta`` within :meth:`tolerance_box` are no fault."""
        return "within a healthy machine's tolerance of its file"

    def within_tolerance(self, mm: MachineModel, theta, ctx: dict) -> str | None:
        """Where fitted values ``theta`` lie within :meth:`tolerance_box`, why; else
        None (a fault, or an effect no healthy machine shows)."""
        box = self.tolerance_box(mm, ctx)
        if box is None or not all(lo <= float(v) <= hi for v, (lo, hi) in zip(theta, box)):
            return None
        return self.tolerance_reason(mm, theta, ctx)

    def clipped_to_tolerance(self, mm: MachineModel, theta, ctx: dict) -> np.ndarray | None:
        """``theta`` with each value moved to the nearest within :meth:`tolerance_box`
        (None where the effect has none)."""
        box = self.tolerance_box(mm, ctx)
        if box is None:
            return None
        lo = np.array([low for low, _ in box], dtype=float)
        hi = np.array([high for _, high in box], dtype=float)
        return np.clip(np.asarray(theta, dtype=float), lo, hi)


def _supply_pa(machine) -> float:
    return bar_g_to_pa(machine.supply_bar_g, machine.atmosphere_kpa)


def consumer_table(data: dict, name: str) -> dict:
    for t in data.get("consumer", []):
        if t.get("name") == name:
            return t
    raise KeyError(name)


def write_conductance(data: dict, consumer, C: float) -> None:
    """Give ``consumer`` (a nozzle or leak) the sonic conductance ``C`` in the machine
    file's ``data``, in place of its orifice and Cd; its b stays."""
    t = consumer_table(data, consumer.name)
    for key in ("orifice_mm", "Cd"):
        t.pop(key, None)
    t["C"] = float(f"{C:.6g}")
    t.setdefault("b", consumer.b)


class Leak(Effect):
    """An always-on flow the machine file does not have (a leak at a fitting, a pilot
    supply, a blow-off left open): ``flow_l_min`` NL/min at the supply."""
    name, title = "leak", "an unmodelled leak"

    def params(self, mm, ctx):
        return [Param("flow_l_min", "NL/min", 0.0, max(10.0, 5.0 * ctx["mean_l_min"]),
                      0.1 * ctx["mean_l_min"])]

    def apply(self, mm, p, theta):
        q = p.copy()
        q.extra_leak_l_min = p.extra_leak_l_min + float(theta[0])
        return q

    def tolerance_box(self, mm, ctx):
        return [(0.0, LEAK_TOLERANCE_SHARE * ctx["mean_l_min"])]

    def tolerance_reason(self, mm, theta, ctx):
        limit = LEAK_TOLERANCE_SHARE * ctx["mean_l_min"]
        return (f"{float(theta[0]):.2g} NL/min always on is within a meter's zero offset "
                f"and a healthy machine's fittings ({limit:.2g} NL/min)")

    def conductance(self, mm, flow_l_min: float) -> float:
        """(D2 inverted) the sonic conductance of a leak at the supply that flows
        ``flow_l_min``."""
        m = mm.machine
        per_unit = flow_nl_min(1.0, LEAK_B, LEAK_M, 1.0, _supply_pa(m),
                               m.atmosphere_kpa * 1000.0, celsius_to_k(m.ambient_c))
        return flow_l_min / float(per_unit) if per_unit > 0 else math.nan

    def physical(self, mm, theta):
        return {"flow_l_min": float(theta[0]), "C_m3_s_pa": self.conductance(mm, theta[0]),
                "b": LEAK_B, "m": LEAK_M}

    def to_machine(self, mm, data, theta):
        names = {t.get("name") for t in data.get("consumer", [])}
        name, k = "diagnosed leak", 2
        while name in names:
            name, k = f"diagnosed leak {k}", k + 1
        C = self.conductance(mm, theta[0])
        data.setdefault("consumer", []).append(
            {"name": name, "kind": "leak", "C": float(f"{C:.6g}"), "b": LEAK_B, "m": LEAK_M})
        return [f'added consumer "{name}" (leak, C = {C:.3g} m^3/(s Pa), '
                f'{theta[0]:.3g} NL/min)']


def with_onset(physical: dict, onsets: list[tuple[str, float | None, float]]) -> dict:
    """``physical`` with the first run's onset among ``onsets`` (name, onset in
    prediction time or None, the run's clock offset) where one was found: the run,
    the prediction's time and the logger's clock."""
    found = [(name, t, off) for name, t, off in onsets if t is not None]
    if found:
        name, t, off = found[0]
        physical.update({"onset_run": name, "onset_s": t, "onset_logger_s": t + off})
    return physical


class LeakFrom(Leak):
    """A leak (or a blower left on) that opens during the logs: each run's extra flow
    starts where its residual steps up (diagnose.onset), at its start in runs that have
    it throughout, never in runs before it. ``onsets``: per run (name, onset in
    prediction time or None, the run's clock offset) for the report."""
    title = "an unmodelled leak from a time on"

    def __init__(self, onsets: list[tuple[str, float | None, float]] = ()):
        self.onsets = list(onsets)

    def apply(self, mm, p, theta):
        q = super().apply(mm, p, theta)
        q.extra_leak_from_s = p.leak_onset_s
        return q

    def physical(self, mm, theta):
        return with_onset(super().physical(mm, theta), self.onsets)


class PassiveFlow(Effect):
    """Nozzles and air knives flowing other than their D2 model says (a wrong
    conductance, worn nozzles, the sonic assumption at low pressure): a factor on each
    nozzle's flow while on."""
    name, title = "passive_flow", "nozzles flowing other than modelled"

    def _nozzles(self, mm):
        return [k for k, row in enumerate(mm.passives) if mm.models[row].role == "passive"]

    def applies(self, mm):
        return bool(self._nozzles(mm))

    def params(self, mm, ctx):
        return [Param(f"{mm.models[mm.passives[k]].name}.factor", "", 0.1, 5.0, 1.0)
                for k in self._nozzles(mm)]

    def apply(self, mm, p, theta):
        q = p.copy()
        for k, f in zip(self._nozzles(mm), theta):
            q.passive_l_min[k] = p.passive_l_min[k] * f
        return q

    def tolerance_box(self, mm, ctx):
        return [(1.0 - PASSIVE_TOLERANCE_SHARE, 1.0 + PASSIVE_TOLERANCE_SHARE)] * len(
            self._nozzles(mm))

    def tolerance_reason(self, mm, theta, ctx):
        return (f"every nozzle within {PASSIVE_TOLERANCE_SHARE:.0%} of its rating "
                "(a catalogue's conductance, an orifice's Cd)")

    def _C(self, mm, k) -> float:
        return sonic_conductance(mm.machine.consumers[mm.passives[k]])

    def physical(self, mm, theta):
        out = {}
        for k, f in zip(self._nozzles(mm), theta):
            m = mm.models[mm.passives[k]]
            out[m.name] = {"factor": float(f), "flow_l_min": m.flow_l_min * float(f),
                           "C_m3_s_pa": self._C(mm, k) * float(f)}
        return out

    def to_machine(self, mm, data, theta):
        changes = []
        for k, f in zip(self._nozzles(mm), theta):
            if abs(f - 1.0) < 1e-3:
                continue
            m = mm.models[mm.passives[k]]
            C = self._C(mm, k) * float(f)
            write_conductance(data, mm.machine.consumers[mm.passives[k]], C)
            changes.append(f'consumer "{m.name}": C = {C:.3g} m^3/(s Pa) (x{f:.3g})')
        return changes


class SupplyPressure(Effect):
    """The machine runs at another supply pressure than its file says (a regulator set
    differently, a drooping network): D1 volumes scale with the absolute supply, nozzles
    and leaks follow D2 at their new upstream pressure."""
    name, title = "supply_pressure", "a different supply pressure"

    def _range(self, mm) -> tuple[float, float]:
        p = mm.machine.supply_bar_g
        return max(0.2, 0.4 * p), 1.6 * p + 1.0

    def params(self, mm, ctx):
        logged = ctx.get("logged_supply_bar_g")
        if logged is not None:
            # the log measured it: the fit may only move it by what a gauge and the
            # regulator's swing around its mean leave open, so that a verdict cannot
            # contradict the log (3.6 bar fitted where it read 5.0)
            lo, hi = self._range(mm)
            return [Param("supply_bar_g", "bar(g)", max(lo, logged - LOGGED_SUPPLY_TOLERANCE_BAR),
                          min(hi, logged + LOGGED_SUPPLY_TOLERANCE_BAR), logged)]
        return [Param("supply_bar_g", "bar(g)", *self._range(mm), mm.machine.supply_bar_g)]

    def tolerance_box(self, mm, ctx):
        p = mm.machine.supply_bar_g
        logged = ctx.get("logged_supply_bar_g")
        if logged is not None and abs(logged - p) > \
                SUPPLY_TOLERANCE_BAR + LOGGED_SUPPLY_TOLERANCE_BAR:
            return None         # the log reads a supply beyond it: no healthy value
        return [(p - SUPPLY_TOLERANCE_BAR, p + SUPPLY_TOLERANCE_BAR)]

    def tolerance_reason(self, mm, theta, ctx):
        shift = float(theta[0]) - mm.machine.supply_bar_g
        return (f"{shift:+.2f} bar from the file's supply is within a regulator's "
                "setting and its gauge")

    def apply(self, mm, p, theta):
        m = mm.machine
        q = p.copy()
        new_pa = bar_g_to_pa(float(theta[0]), m.atmosphere_kpa)
        ratio = new_pa / _supply_pa(m)                                   # D1: V ~ P_s
        q.extend_nl = p.extend_nl * ratio
        q.retract_nl = p.retract_nl * ratio
        q.swept_nl = p.swept_nl * ratio
        t_k = celsius_to_k(m.ambient_c)
        p_atm = m.atmosphere_kpa * 1000.0
        gauge_ratio = max(new_pa - p_atm, 0.0) / max(_supply_pa(m) - p_atm, 1.0)
        q.held_nl = p.held_nl * gauge_ratio          # what the chambers hold above P_atm
        q.swept_held_nl = p.swept_held_nl * gauge_ratio
        for k, row in enumerate(mm.passives):
            c = m.consumers[row]
            model = mm.models[row]
            if not model.flow_l_min:
                continue
            old_pa = bar_g_to_pa(model.pressure_bar_g, m.atmosphere_kpa)
            up_pa = new_pa if c.pressure_bar_g is None else min(
                new_pa, bar_g_to_pa(c.pressure_bar_g, m.atmosphere_kpa))
            args = (c.b, c.m, c.a)         # the loader fills in their defaults
            f_new = flow_nl_min(1.0, *args, up_pa, p_atm, t_k, c.flow_model)     # D2
            f_old = flow_nl_min(1.0, *args, old_pa, p_atm, t_k, c.flow_model)
            q.passive_l_min[k] = p.passive_l_min[k] * float(f_new) / float(f_old)
        return q

    def physical(self, mm, theta):
        return {"supply_bar_g": float(theta[0])}

    def implausible(self, mm, theta):
        # at a bound of its range the pressure did not explain the gap, it ran out; and
        # a regulator set half as much again (or half as little) as the file says is
        # less likely than an unmodelled consumer that the data cannot tell from it
        lo, hi = self._range(mm)
        p = mm.machine.supply_bar_g
        if not lo + 1e-3 * (hi - lo) < theta[0] < hi - 1e-3 * (hi - lo):
            return f"supply pressure at the bound of its range ({theta[0]:.3g} bar(g))"
        if abs(theta[0] - p) > MAX_SUPPLY_CHANGE * p:
            return f"supply pressure {theta[0]:.3g} bar(g) against the file's {p:g}"
        return None

    def to_machine(self, mm, data, theta):
        data["machine"]["supply_bar_g"] = round(float(theta[0]), 6)
        return [f"[machine] supply_bar_g = {theta[0]:.4g} (was "
                f"{mm.machine.supply_bar_g:g})"]


class SupplyFrom(SupplyPressure):
    """The supply changes during the logs (a network that sags during a shift, a
    regulator turned): from where the logs' own pressure column steps (diagnose.onset)
    the drives' D1 air and the nozzles' D2 flow follow the supply fitted after it, the
    file's before. ``onsets``: per run (name, onset in prediction time or None, the
    run's clock offset); ``after_bar_g``: the logs' mean supply after their steps."""
    title = "a supply pressure that changes from a time on"

    def __init__(self, onsets: list[tuple[str, float | None, float]] = (),
                 after_bar_g: float = 0.0):
        self.onsets = list(onsets)
        self.after_bar_g = after_bar_g

    def params(self, mm, ctx):
        lo, hi = self._range(mm)
        a = self.after_bar_g
        return [Param("supply_bar_g", "bar(g)", max(lo, a - LOGGED_SUPPLY_TOLERANCE_BAR),
                      min(hi, a + LOGGED_SUPPLY_TOLERANCE_BAR), a)]

    def tolerance_box(self, mm, ctx):
        p = mm.machine.supply_bar_g
        if abs(self.after_bar_g - p) > SUPPLY_TOLERANCE_BAR + LOGGED_SUPPLY_TOLERANCE_BAR:
            return None         # the log reads a supply beyond it: no healthy value
        return [(p - SUPPLY_TOLERANCE_BAR, p + SUPPLY_TOLERANCE_BAR)]

    def apply(self, mm, p, theta):
        # the ratios the whole run would take at the new supply, applied from the onset
        at_new = super().apply(mm, p, theta)
        q = p.copy()
        q.supply_from_s = p.supply_onset_s
        q.supply_d1_ratio = float(at_new.extend_nl.sum() / p.extend_nl.sum()) \
            if p.extend_nl.sum() > 0 else 1.0
        q.supply_passive_ratio = tuple(
            float(a / b) if b > 0 else 1.0 for a, b in zip(at_new.passive_l_min,
                                                           p.passive_l_min))
        return q

    def physical(self, mm, theta):
        return with_onset(super().physical(mm, theta), self.onsets)

    def to_machine(self, mm, data, theta):
        changes = super().to_machine(mm, data, theta)
        return [c + ": the supply the logs read after it changed" for c in changes]


def _tube_area_mm2(consumer) -> float:
    d = consumer.tube_id_mm or DEFAULT_TUBE_ID_MM
    return math.pi * d * d / 4.0


def tube_volumes_cm3(consumer) -> list[float]:
    """(cap, rod) cm^3 of the tubes the machine file states (none without a bore)."""
    if not consumer.tube_id_mm:
        return [0.0 for _ in consumer.tube_length_m]
    return [length * _tube_area_mm2(consumer) for length in consumer.tube_length_m]


class DeadVolume(Effect):
    """More (or less) volume between valve and piston than the file says (a longer tube,
    a fitting, a manifold; D1 also counts a dead volume's air from zero, docs/reference/physics.md
    section 7): ``extra_cm3`` per drive, filled to supply on every stroke."""
    name, title = "dead_volume", "a different dead volume (tube length)"

    def applies(self, mm):
        return bool(mm.drives)

    def params(self, mm, ctx):
        out = []
        for row in mm.drives:
            c = mm.machine.consumers[row]
            tube_cm3 = min(tube_volumes_cm3(c))
            swept_cm3 = math.pi * c.bore_mm ** 2 / 4.0 * (c.stroke_mm or 0.0) / 1000.0
            out.append(Param(f"{c.name}.extra_cm3", "cm^3", -tube_cm3,
                             max(20.0, 2.0 * swept_cm3), 0.0))
        return out

    def implausible(self, mm, theta):
        # tube lengths are measured with a tape: a file that overstates a drive's tube
        # by more than half is less likely than air its fills do not take (an exhaust
        # cut short, a lower supply), which reduce a fill just the same
        for row, v in zip(mm.drives, theta):
            c = mm.machine.consumers[row]
            tube_cm3 = min(tube_volumes_cm3(c))
            if tube_cm3 > 0 and v < -MAX_TUBE_OVERSTATEMENT * tube_cm3:
                return (f'{c.name}: {-v:.3g} cm^3 less than its {tube_cm3:.3g} cm^3 of '
                        "tube")
        return None

    def tolerance_box(self, mm, ctx):
        box = []
        nominal = mm.nominal()
        nl_per_cm3 = self._nl_per_cm3(mm)
        atm_share = mm.machine.atmosphere_kpa * 1e3 / _supply_pa(mm.machine)
        for k, row in enumerate(mm.drives):
            c = mm.machine.consumers[row]
            bore_mm2 = max(swept_areas_mm2(c.kind, c.bore_mm, c.rod_mm or 0.0))
            tube_cm3 = min(tube_volumes_cm3(c))
            allowed = (TUBE_TOLERANCE_SHARE * tube_cm3 + max(inner_dead_volumes_cm3(c))
                       + bore_mm2 * UNSTATED_DEAD_STROKE_MM / 1000.0)
            # less volume than the file says goes as far as D1's own excess a healthy
            # drive shows: the tube's air counted from zero where a real fill starts at
            # atmosphere (D1, section 7), and a hot fill's shortfall
            fills_nl = nominal.extend_nl[k] if mm.models[row].kind == "single_acting" \
                else min(nominal.extend_nl[k], nominal.retract_nl[k])
            below = allowed + atm_share * tube_cm3 + HOT_FILL_SHARE * fills_nl / nl_per_cm3
            box.append((-below, allowed))
        return box

    def tolerance_reason(self, mm, theta, ctx):
        return (f"every drive's dead volume within {TUBE_TOLERANCE_SHARE:.0%} of its tubes "
                "and a few mm of its bore (tubes cut on site, end caps and fittings), or "
                "less by what D1 books beyond a healthy fill")

    def _nl_per_cm3(self, mm) -> float:
        m = mm.machine                                  # D1: V * P_s/P0 * T0/T_s
        return 1e-3 * _supply_pa(m) / P0_PA * T0_K / celsius_to_k(m.ambient_c)

    def apply(self, mm, p, theta):
        q = p.copy()
        extra = np.asarray(theta, dtype=float) * self._nl_per_cm3(mm)
        q.extend_nl = np.clip(p.extend_nl + extra, 0.0, None)
        single = np.array([mm.models[r].kind == "single_acting" for r in mm.drives])
        q.retract_nl = np.where(single, p.retract_nl, np.clip(p.retract_nl + extra, 0.0,
                                                              None))
        # a longer tube also holds more air when an exhaust is cut short (only the
        # exhaust options read it)
        m = mm.machine
        held = held_air_nl(np.asarray(theta, dtype=float), _supply_pa(m),
                           m.atmosphere_kpa * 1000.0, celsius_to_k(m.ambient_c))
        q.held_nl = np.clip(p.held_nl + held[:, None] * np.stack(
            [np.ones(len(single)), ~single], axis=1), 0.0, None)
        return q

    def physical(self, mm, theta):
        out = {}
        for row, v in zip(mm.drives, theta):
            c = mm.machine.consumers[row]
            out[c.name] = {"extra_cm3": float(v),
                           "extra_tube_m": float(v) / _tube_area_mm2(c),  # cm3/mm2 = m
                           "tube_id_mm": c.tube_id_mm or DEFAULT_TUBE_ID_MM}
        return out

    def to_machine(self, mm, data, theta):
        changes = []
        for row, v in zip(mm.drives, theta):
            if abs(v) < 0.05:
                continue
            c = mm.machine.consumers[row]
            dl = float(v) * 1000.0 / _tube_area_mm2(c) / 1000.0     # m
            t = consumer_table(data, c.name)
            if not c.tube_id_mm:
                t["tube_id_mm"] = DEFAULT_TUBE_ID_MM
            lengths = [max(0.0, round(x + dl, 6)) for x in c.tube_length_m]
            t["tube_length_m"] = lengths
            changes.append(f'consumer "{c.name}": tube_length_m = {lengths} '
                           f"({v:+.3g} cm^3 per chamber)")
        return changes


class IncompleteExhaust(Effect):
    """Chambers refilled before they have exhausted (high cycle rates, a throttled
    exhaust): each fill takes less by what the chamber's dead volume (its tube and the
    cylinder's own end volume) still holds, decaying with the exhaust time constant (the
    air model's ``exhaust_tau_s`` option). Per drive the time constant and the
    cylinder's own dead volume (``dead_volume_cm3``: a machine file rarely knows it, and
    it sets how much an exhaust cut short can keep)."""
    name, title = "incomplete_exhaust", "chambers not fully exhausted"

    def __init__(self, partial: bool = False):
        # the form for valves reversed before their drive arrived: strokes cut short
        # take the share the piston covered (the air model's partial_strokes option)
        self.partial = partial
        if partial:
            self.title = "chambers not fully exhausted, strokes cut short"

    def applies(self, mm):
        return bool(mm.drives)

    def _timed(self, mm) -> list[int]:
        return [k for k, row in enumerate(mm.drives) if mm.models[row].stroke_time_s]

    def _inner(self, mm, k) -> tuple[float, float]:
        return inner_dead_volumes_cm3(mm.machine.consumers[mm.drives[k]])

    def params(self, mm, ctx):
        out = []
        for k, row in enumerate(mm.drives):
            c = mm.machine.consumers[row]
            name = mm.models[row].name
            inner = self._inner(mm, k)
            swept_cm3 = math.pi * c.bore_mm ** 2 / 4.0 * (c.stroke_mm or 0.0) / 1000.0
            top_cm3 = max(5.0, MAX_INNER_DEAD_SHARE * swept_cm3, *inner)
            # the volume is swept first: with the file's small one, the time constant
            # would run to its bound to keep enough air, and least squares stays there
            out += [Param(f"{name}.dead_volume_cm3", "cm^3", 0.0, top_cm3,
                          float(np.mean(inner)),
                          tuple(top_cm3 * f for f in (0.0, 0.1, 0.25, 0.5, 1.0))),
                    # 0 is off (the nominal model): where a fit of samples that say
                    # nothing about a drive leaves it
                    Param(f"{name}.exhaust_tau_s", "s", 0.0, 5.0, 0.0, TAU_GRID_S)]
        return out

    def apply(self, mm, p, theta):
        q = p.copy()
        m = mm.machine
        state = (_supply_pa(m), m.atmosphere_kpa * 1000.0, celsius_to_k(m.ambient_c))
        for k, row in enumerate(mm.drives):
            inner, tau = theta[2 * k], theta[2 * k + 1]
            q.exhaust_tau_s[k] = float(tau)
            q.held_nl[k] = [held_air_nl(t + float(inner), *state)     # the air it keeps
                            for t in tube_volumes_cm3(m.consumers[row])]
        if self.partial:
            q.partial_strokes[self._timed(mm)] = True
        return q

    def physical(self, mm, theta):
        out = {mm.models[r].name: {"exhaust_tau_s": float(theta[2 * k + 1]),
                                   "dead_volume_cm3": float(theta[2 * k])}
               for k, r in enumerate(mm.drives)}
        for k in self._timed(mm) if self.partial else ():
            out[mm.models[mm.drives[k]].name]["partial_strokes"] = True
        return out

    def to_machine(self, mm, data, theta):
        changes = []
        timed = set(self._timed(mm)) if self.partial else set()
        for k, r in enumerate(mm.drives):
            inner, tau = float(theta[2 * k]), float(theta[2 * k + 1])
            name = mm.models[r].name
            if k in timed:
                consumer_table(data, name)["partial_strokes"] = True
                changes.append(f'consumer "{name}": partial_strokes = true')
            if tau < MIN_WRITTEN_TAU_S:
                continue            # off: the drive's exhausts are complete
            t = consumer_table(data, name)
            t["exhaust_tau_s"] = float(f"{tau:.6g}")
            change = f'consumer "{name}": exhaust_tau_s = {tau:.3g}'
            if max(abs(inner - v) for v in self._inner(mm, k)) > 0.05:
                t["dead_volume_cm3"] = round(inner, 3)
                change += f", dead_volume_cm3 = {inner:.3g}"
            changes.append(change)
        return changes


class SharedSupply(Effect):
    expressible = False     # the air model has no shared-line option yet

    """Drives on one supply line without check valves: holding neighbours give air back
    to the line while a drive fills and take it again afterwards (docs/reference/physics.md: what D4 adds),
    so a share of each stroke's air arrives later, as a refill with a time constant."""
    name, title = "shared_supply", "drives refilling each other on a shared line"

    def applies(self, mm):
        return len(mm.drives) >= 2

    def params(self, mm, ctx):
        return [Param("refill_fraction", "", 0.0, 0.6, 0.1, (0.05, 0.15, 0.3, 0.45)),
                Param("refill_tau_s", "s", 0.02, 3.0, 0.3, (0.05, 0.1, 0.2, 0.4, 0.8, 1.5))]

    def apply(self, mm, p, theta):
        q = p.copy()
        q.refill_fraction, q.refill_tau_s = float(theta[0]), float(theta[1])
        return q

    def tolerance_box(self, mm, ctx):
        return [(0.0, REFILL_TOLERANCE_FRACTION), (-math.inf, math.inf)]

    def tolerance_reason(self, mm, theta, ctx):
        return (f"{float(theta[0]):.0%} of each stroke refilled later is what any "
                "supply line's own volume gives back")

    def physical(self, mm, theta):
        return {"refill_fraction": float(theta[0]), "refill_tau_s": float(theta[1])}


class _Timing(Effect):
    """A timing effect applied to the predicted edges, or (``closed_loop``) with the
    program run again so that every later edge moves too (diagnose.timing)."""

    def __init__(self, closed_loop: bool = False):
        self.closed_loop = closed_loop
        if closed_loop:
            self.title += " (the program waiting on them)"

    def applies(self, mm):
        return bool(mm.drives) and (mm.resequencer is not None or not self.closed_loop)

    def _resequenced(self, mm, p: ModelParams, q: ModelParams, **change) -> list[tuple]:
        """Point ``q`` at the run with ``p``'s timing changed by ``change`` (factors= or
        delays=, made if new); the quantised (factor, extra delay) of each drive."""
        q.timing = mm.resequencer.key(start=p.timing, **change)
        mm.resequencer.ensure(q.timing)
        return list(q.timing or mm.resequencer.neutral)


class ValveDelay(_Timing):
    """Valves switching later (or earlier) than the file says: ``delay_s`` added to each
    drive's switching delay."""
    name, title = "valve_delay", "different valve switching delays"

    def params(self, mm, ctx):
        return [Param(f"{mm.models[r].name}.extra_delay_s", "s", -mm.models[r].delay_s, 0.5,
                      0.0, CLOSED_DELAY_GRID_S if self.closed_loop else DELAY_GRID_S,
                      discrete=self.closed_loop)
                for r in mm.drives]

    def apply(self, mm, p, theta):
        q = p.copy()
        if self.closed_loop:
            theta = [d for _, d in self._resequenced(mm, p, q, delays=theta)]
        q.delay_s = np.clip(p.delay_s + np.asarray(theta, dtype=float), 0.0, None)
        return q

    def tolerance_box(self, mm, ctx):
        return [(-DELAY_TOLERANCE_S, DELAY_TOLERANCE_S)] * len(mm.drives)

    def tolerance_reason(self, mm, theta, ctx):
        return (f"every valve within {DELAY_TOLERANCE_S * 1000:.0f} ms of the file's "
                "switching time (units and coil temperatures differ)")

    def physical(self, mm, theta):
        return {mm.models[r].name: {"switch_delay_s": mm.models[r].delay_s + float(d)}
                for r, d in zip(mm.drives, theta)}

    def to_machine(self, mm, data, theta):
        changes = []
        for r, d in zip(mm.drives, theta):
            if abs(d) < 1e-4:
                continue
            m = mm.models[r]
            new = round(max(0.0, m.delay_s + float(d)), 6)
            consumer_table(data, m.name)["switch_delay_s"] = new
            changes.append(f'consumer "{m.name}": switch_delay_s = {new:g}')
        return changes


class StrokeTime(_Timing):
    """Strokes faster or slower than the file says (a flow control turned, a payload): a factor on
    each drive's stroke times. Air per stroke stays (docs/reference/physics.md: what D4 adds); its
    shape in time changes."""
    name, title = "stroke_time", "different stroke times"

    def __init__(self, closed_loop: bool = False, partial_drives: tuple[int, ...] = ()):
        super().__init__(closed_loop)
        # the form for a slower stroke that the next edge now reverses before it arrives
        # (a valve on a timer): such a stroke takes the share of its swept air the piston
        # covered (the air model's partial_strokes option). Only for drives whose strokes
        # all complete at the file's times (``partial_drives``, indices into mm.drives):
        # on the others the option would change the air at any factor, which is the
        # exhaust's form for strokes cut short, not a stroke time
        self.partial_drives = tuple(partial_drives)
        if self.partial_drives:
            self.title += ", strokes cut short"

    def _reference(self, mm, k):
        m = mm.models[mm.drives[k]]
        if m.stroke_time_s is not None:
            return m.stroke_time_s
        return mm.machine.consumers[mm.drives[k]].auto_stroke_times()

    def params(self, mm, ctx):
        return [Param(f"{mm.models[r].name}.factor", "", 0.2, 5.0, 1.0,
                      CLOSED_FACTOR_GRID if self.closed_loop else FACTOR_GRID,
                      discrete=self.closed_loop) for r in mm.drives]

    def apply(self, mm, p, theta):
        q = p.copy()
        if self.closed_loop:
            theta = [f for f, _ in self._resequenced(mm, p, q, factors=theta)]
        for k, f in enumerate(theta):
            ext, ret = self._reference(mm, k)
            q.stroke_ext_s[k] = ext * float(f)
            q.stroke_ret_s[k] = ret * float(f)
        if self.partial_drives:
            rows = list(self.partial_drives)
            q.partial_strokes[rows] = True      # a stroke that is not cut takes D1
            q.exhaust_tau_s[rows] = np.maximum(q.exhaust_tau_s[rows],
                                               self._throttled_tau_s(mm, theta)[rows])
        return q

    def tolerance_box(self, mm, ctx):
        return [(1.0 - STROKE_TOLERANCE_SHARE, 1.0 + STROKE_TOLERANCE_SHARE)] * len(mm.drives)

    def tolerance_reason(self, mm, theta, ctx):
        return (f"every stroke time within {STROKE_TOLERANCE_SHARE:.0%} of the file's "
                "(set at commissioning by eye)")

    def _throttled_tau_s(self, mm, theta) -> np.ndarray:
        """The exhaust time constant a slower stroke brings: strokes are slowed by the
        meter-out flow control, which throttles the exhausting chamber too, so that it
        empties on about the time the stroke gained (0 at the file's stroke time: the
        nominal model). A chamber reversed mid-stroke then keeps its air, as the plant's
        does, rather than being refilled from atmosphere."""
        out = np.zeros(len(theta))
        for k, f in enumerate(theta):
            out[k] = max(0.0, (float(f) - 1.0) * float(np.mean(self._reference(mm, k))))
        return out

    def physical(self, mm, theta):
        out = {}
        for k, f in enumerate(theta):
            ext, ret = self._reference(mm, k)
            out[mm.models[mm.drives[k]].name] = {"factor": float(f),
                                                 "stroke_time_s": [ext * f, ret * f]}
        taus = self._throttled_tau_s(mm, theta)
        for k in self.partial_drives:
            if abs(theta[k] - 1.0) >= 1e-3:
                out[mm.models[mm.drives[k]].name]["partial_strokes"] = True
            if taus[k] > 0:
                out[mm.models[mm.drives[k]].name]["exhaust_tau_s"] = float(taus[k])
        return out

    def to_machine(self, mm, data, theta):
        changes = []
        taus = self._throttled_tau_s(mm, theta)
        for k, f in enumerate(theta):
            if abs(f - 1.0) < 1e-3:
                continue
            ext, ret = self._reference(mm, k)
            new = [round(max(1e-4, ext * float(f)), 6), round(max(1e-4, ret * float(f)), 6)]
            name = mm.models[mm.drives[k]].name
            t = consumer_table(data, name)
            t["stroke_time_s"] = new
            changes.append(f'consumer "{name}": stroke_time_s = {new}')
            if k in self.partial_drives:
                t["partial_strokes"] = True
                change = f'consumer "{name}": partial_strokes = true'
                tau = float(taus[k])
                if tau > max(MIN_WRITTEN_TAU_S, mm.models[mm.drives[k]].exhaust_tau_s or 0.0):
                    t["exhaust_tau_s"] = float(f"{tau:.6g}")
                    change += f", exhaust_tau_s = {tau:.3g}"
                changes.append(change)
        return changes


class SensorLag(Effect):
    """The meter responds more slowly than assumed (a first-order lag of ``tau_s``;
    thermal-mass meters are 0.1-0.6 s, some much slower). The clock alignment already
    searched lag and offset together; this effect lets the lag go beyond a thermal
    meter's (or away from the machine file's ``[meter] tau_s``)."""
    name, title = "sensor_lag", "a slower flow meter"

    def params(self, mm, ctx):
        return [Param("tau_s", "s", 0.0, MAX_METER_TAU_S,
                      max(ctx["fitted_tau_s"], ctx["meter_tau_s"] or 0.0),
                      (0.3, 0.6, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0))]

    def apply(self, mm, p, theta):
        q = p.copy()
        q.meter_tau_s = float(theta[0])
        return q

    def physical(self, mm, theta):
        return {"tau_s": float(theta[0])}

    def tolerance_box(self, mm, ctx):
        return [(0.0, METER_LAG_FIT_MAX_S)]

    def tolerance_reason(self, mm, theta, ctx):
        return f"a meter lag of {float(theta[0]):.2g} s is a thermal-mass meter's own"

    def to_machine(self, mm, data, theta):
        data.setdefault("meter", {})["tau_s"] = round(float(theta[0]), 6)
        return [f"[meter] tau_s = {theta[0]:.3g}"]


class MeterGain(Effect):
    """The meter reads a fixed share more or less than the air through it: a meter out
    of calibration, or one that reports normal litres at another reference (a DIN 1343
    meter reads ISO 8778 air 8 % low; docs/reference/physics.md). Every reading scales alike,
    whatever consumer draws it, which no consumer's effect does."""
    name, title = "meter_gain", "a flow meter reading high or low"

    def params(self, mm, ctx):
        return [Param("gain", "", MIN_METER_GAIN, MAX_METER_GAIN, 1.0)]

    def apply(self, mm, p, theta):
        q = p.copy()
        q.meter_gain = p.meter_gain * float(theta[0])
        return q

    def tolerance_box(self, mm, ctx):
        return [(1.0 - METER_GAIN_TOLERANCE, 1.0 + METER_GAIN_TOLERANCE)]

    def tolerance_reason(self, mm, theta, ctx):
        return (f"a meter gain of {float(theta[0]):.3f} is within a thermal-mass "
                f"meter's accuracy ({METER_GAIN_TOLERANCE:.0%} of reading)")

    def physical(self, mm, theta):
        out = {"gain": float(theta[0])}
        reference = _reference_of(float(theta[0]))
        if reference:
            out["reference"] = reference
        return out

    def to_machine(self, mm, data, theta):
        gain = float(theta[0])
        reference = _reference_of(gain)
        if reference:
            data.setdefault("meter", {})["reference"] = reference
            return [f'[meter] reference = "{reference}" (the meter reads {gain:.3f}x '
                    "ISO 8778 air)"]
        return []


MIN_METER_GAIN, MAX_METER_GAIN = 0.7, 1.4
# a gain this close to another reference's ratio is read as that reference
REFERENCE_MATCH = 0.015


def _reference_of(gain: float) -> str | None:
    """The normal-litre reference a meter reading ``gain`` x ISO 8778 litres reports
    in, if one is that close (DIN 1343, ISO 2533)."""
    for name in REFERENCES:
        if name != "iso8778" and abs(gain * reference_factor(name) - 1.0) < REFERENCE_MATCH:
            return name
    return None


EFFECTS: dict[str, Effect] = {e.name: e for e in (
    Leak(), PassiveFlow(), SupplyPressure(), DeadVolume(), IncompleteExhaust(),
    SharedSupply(), ValveDelay(), StrokeTime(), SensorLag(), MeterGain())}
VOCABULARY = ("none",) + tuple(EFFECTS)
# the same effects where end switches start the program's next steps, so that a timing
# change moves every later edge (diagnose.timing runs the sequencer again); tried
# beside the forms above when the machine's runs come from the sequencer
CLOSED_LOOP_EFFECTS: dict[str, Effect] = {e.name: e for e in (
    ValveDelay(closed_loop=True), StrokeTime(closed_loop=True))}
# the form tried beside the above where a run's valves reverse before their drive arrived
CUT_STROKE_EFFECTS: dict[str, Effect] = {e.name: e for e in (IncompleteExhaust(partial=True),)}
# and StrokeTime(partial_drives=...), a slower stroke cut short by an edge that does not
# wait for it: diagnose makes it for each diagnosis, since which drives' strokes all
# complete and which drives the program waits on depend on the runs
