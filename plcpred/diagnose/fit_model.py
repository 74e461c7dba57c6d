"""The activation model taken apart so that an effect can change one piece of it.

:class:`ModelParams` holds the numbers the activation/transition model runs on (each
drive's D1 volumes, switching delay and stroke times, each nozzle's and leak's D2 flow) plus
what the diagnosis adds (an extra leak flow, a drive's exhaust time constant, the meter's
lag and a clock correction). An effect is a function from its fitted parameters to a
changed copy of these numbers (:mod:`~plcpred.diagnose.effects`); :class:`RunModel` turns
any such copy into what the meter would have logged for one run.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from ..air.demand import (
    ConsumerModel,
    consumer_models,
    grid_edges_s,
    interval_cells,
    passive_intervals,
    stroke_cells,
    valve_transitions,
)
from ..physics.meter import (
    IntervalSampler,
    chained_interval_means_l_min,
    first_order_lag,
    interval_means_l_min,
)
from ..sequencer.timeline import NS
from .errors import DiagnosisError

# metered cumulative NL kept per run model (each a float per grid cell: 2.9 MB an hour)
METERED_KEPT = 12


def lagged_cumulative_nl(cells_nl: np.ndarray, dt_s: float, tau_s: float) -> np.ndarray:
    """:func:`~plcpred.physics.meter.cumulative_nl` of the cells through
    :func:`~plcpred.physics.meter.first_order_lag` (settled at the first cell), the same
    values to rounding. A fit meters its model thousands of times: here the lag is one
    pass of scipy's ``lfilter`` (the diagnosis imports scipy anyway) and the sum is
    written in place, about half the time of the two functions."""
    out = np.empty(len(cells_nl) + 1)
    out[0] = 0.0
    if tau_s and tau_s > 0 and len(cells_nl):
        # scipy costs a third of a second to import: the diagnosis' fits need it anyway
        from scipy.signal import lfilter

        a = math.exp(-dt_s / tau_s)
        cells_nl, _ = lfilter([1.0 - a], [1.0, -a], cells_nl, zi=[a * cells_nl[0]])
    np.cumsum(cells_nl, out=out[1:])
    return out

@dataclass
class ModelParams:
    """The numbers an effect may change (per drive: in the order of
    ``MachineModel.drives``; per passive consumer: ``MachineModel.passives``)."""
    extend_nl: np.ndarray
    retract_nl: np.ndarray
    delay_s: np.ndarray
    stroke_ext_s: np.ndarray          # NaN: no stroke time (the volume lands in the delay)
    stroke_ret_s: np.ndarray
    exhaust_tau_s: np.ndarray         # 0: chambers fully exhausted (D1)
    # (drives, 2): the air the cap and rod dead volumes hold above atmosphere at supply
    # (what an exhaust cut short keeps)
    held_nl: np.ndarray
    # (drives, 2): cap and rod swept volumes' D1 air and the air they hold above
    # atmosphere at supply (what a stroke cut short does not open, or leaves full)
    swept_nl: np.ndarray
    swept_held_nl: np.ndarray
    partial_strokes: np.ndarray       # bool per drive: strokes cut short take their share
    passive_l_min: np.ndarray         # D2 flow while on (nozzles) or always (leaks)
    extra_leak_l_min: float = 0.0     # an always-on flow the machine file does not have
    # from this time on (prediction time; inf: not in this run): a leak that opens
    # during the log. ``leak_onset_s`` is where the run's residual steps up, if it does
    # (diagnose.onset), for an effect to take as its start
    extra_leak_from_s: float = 0.0
    leak_onset_s: float = 0.0
    # from this time on (prediction time; inf: never in this run) the machine runs at
    # another supply: the drives' cells times ``supply_d1_ratio`` (D1: air ~ absolute
    # supply), each passive's times its entry of ``supply_passive_ratio`` (D2).
    # ``supply_onset_s`` is where the run's logged supply steps (diagnose.onset), for
    # an effect to take as its start
    supply_from_s: float = math.inf
    supply_d1_ratio: float = 1.0
    supply_passive_ratio: tuple = ()
    supply_onset_s: float = math.inf
    refill_fraction: float = 0.0      # shared supply: share of each stroke refilled later
    refill_tau_s: float = 0.0
    meter_tau_s: float = 0.0
    meter_gain: float = 1.0           # the meter reads this times the air through it
    clock_adjust_s: float = 0.0       # added to the run's aligned offset
    # a resequenced run's key (diagnose.timing: per drive a stroke factor and an extra
    # delay), None: the run's own prediction
    timing: tuple | None = None
    # add what the physics plant draws beyond D1 on the run's nominal edges
    # (RunModel.dynamic_cells): the nominal machine's dynamic reference
    dynamic: bool = False
    # with ``dynamic``: the plant's air for the machine file changed by effects
    # (diagnose.through_plant: RunModel.variant_cells) instead of the nominal file's
    variant: tuple = ()

    def copy(self) -> ModelParams:
        """A copy whose arrays an effect may change (called for every evaluation of a
        fit, so field by field rather than ``copy.deepcopy``)."""
        return dataclasses.replace(self, **{f: getattr(self, f).copy() for f in _ARRAYS})


_ARRAYS = ("extend_nl", "retract_nl", "delay_s", "stroke_ext_s", "stroke_ret_s",
           "exhaust_tau_s", "held_nl", "swept_nl", "swept_held_nl", "partial_strokes",
           "passive_l_min")


@dataclass
class MachineModel:
    """A machine's consumers as the diagnosis sees them."""
    machine: object
    models: list[ConsumerModel]
    drives: list[int] = field(default_factory=list)     # rows of active consumers
    passives: list[int] = field(default_factory=list)   # rows of nozzles and leaks
    # set when the runs come from the sequencer and the drives' timing moves the valve
    # edges (a closed loop): timing effects then run the sequencer again
    resequencer: object = None
    # the plant runs of machine files changed by effects (diagnose.through_plant)
    plant_variants: object = None

    @classmethod
    def of(cls, machine) -> MachineModel:
        models = consumer_models(machine)
        meter = machine.meter
        if meter is not None and meter.line is not None:
            # the meter sits on one line: it sees only the consumers on that line
            models = [m for m, c in zip(models, machine.consumers) if c.line == meter.line]
            if not models:
                raise DiagnosisError(f"{machine.path}: [meter] line '{meter.line}' feeds no "
                                     "consumer: nothing the meter sees can be predicted")
        return cls(machine, models, [i for i, m in enumerate(models) if m.role == "active"],
                   [i for i, m in enumerate(models) if m.role != "active"])

    def nominal(self, meter_tau_s: float = 0.0) -> ModelParams:
        d = [self.models[i] for i in self.drives]
        p = [self.models[i] for i in self.passives]
        st = [m.stroke_time_s or (np.nan, np.nan) for m in d]
        return ModelParams(
            extend_nl=np.array([m.extend_nl for m in d], dtype=float),
            retract_nl=np.array([m.retract_nl for m in d], dtype=float),
            delay_s=np.array([m.delay_s for m in d], dtype=float),
            stroke_ext_s=np.array([s[0] for s in st], dtype=float),
            stroke_ret_s=np.array([s[1] for s in st], dtype=float),
            exhaust_tau_s=np.array([m.exhaust_tau_s or 0.0 for m in d], dtype=float),
            held_nl=np.array([m.dead_fill_nl for m in d], dtype=float).reshape(-1, 2),
            swept_nl=np.array([m.swept_nl for m in d], dtype=float).reshape(-1, 2),
            swept_held_nl=np.array([m.swept_held_nl for m in d], dtype=float).reshape(-1, 2),
            partial_strokes=np.array([m.partial_strokes for m in d], dtype=bool),
            passive_l_min=np.array([m.flow_l_min for m in p], dtype=float),
            meter_tau_s=meter_tau_s)

    def drive_models(self) -> list[ConsumerModel]:
        return [self.models[i] for i in self.drives]

    def passive_models(self) -> list[ConsumerModel]:
        return [self.models[i] for i in self.passives]


# prediction time a run's grid keeps before the first time it is read at: ten lags of the
# slowest meter a fit tries (effects.MAX_METER_TAU_S), so that a lag started settled at
# the grid's first cell has forgotten that start (e^-10), and more than any clock
# adjustment or refill tail
RENDER_LEAD_S = 100.0


def render_start_s(first_read_s: float) -> float:
    """Where a run's grid may start when nothing before ``first_read_s`` (prediction
    time: the log's first reading at a given clock) is read: RENDER_LEAD_S before it."""
    return max(0.0, first_read_s - RENDER_LEAD_S)


def window_start_cell(start_s: float, horizon_s: float, dt_s: float) -> int:
    """The grid cell ``start_s`` falls in (runs with the same grid step and horizon then
    share edges or differ by whole cells), within the horizon."""
    return max(0, math.floor(max(0.0, min(start_s, horizon_s - dt_s)) / dt_s + 1e-9))


def window_edges_s(start_cell: int, horizon_s: float, dt_s: float) -> np.ndarray:
    """Edges every ``dt_s`` from cell ``start_cell`` to ``horizon_s`` (the last cell may
    be short): those of :func:`~plcpred.air.demand.grid_edges_s` from that cell on."""
    if not start_cell:
        return grid_edges_s(horizon_s, dt_s)
    n = max(1, math.ceil(horizon_s / dt_s - 1e-9) - start_cell)
    edges = np.arange(start_cell, start_cell + n + 1, dtype=float) * dt_s
    edges[-1] = min(edges[-1], horizon_s)
    return edges


class RunModel:
    """One run's events (from the sequencer or a recorded I/O trace) on a fine grid, and
    the meter readings any :class:`ModelParams` gives for the run's samples.

    The grid covers the prediction from ``start_s`` (0: the machine's start) to its
    horizon (or ``end_s``): a log read far along a given clock is rendered over its own
    window, not from the machine's start. A drive's transitions are kept from the two
    before the window on (a stroke under way at its start, the edge the first fill
    depends on), a nozzle's periods that reach into it, a leak all along."""

    def __init__(self, mm: MachineModel, timeline, dt_s: float, start_s: float = 0.0,
                 end_s: float | None = None):
        self.mm = mm
        self.timeline = timeline
        # (a recorded trace may run on far past what is read: ``end_s`` ends the grid;
        # within a microsecond of the timeline's end, its own end stands)
        self.horizon_s = timeline.horizon_ns / NS
        if end_s is not None and end_s < self.horizon_s - 1e-6:
            self.horizon_s = float(end_s)
        self.dt_s = dt_s
        self.start_cell = window_start_cell(start_s, self.horizon_s, dt_s)
        self.edges_s = window_edges_s(self.start_cell, self.horizon_s, dt_s)
        self.start_s = float(self.edges_s[0])
        self.n_cells = len(self.edges_s) - 1
        # the edges from the grid's first: the uniform sampler finds cells by division
        self._sampled_edges_s = self.edges_s - self.start_s if self.start_s else self.edges_s
        signal_map = timeline.info.get("machine_signals", {})
        # each evaluation costs what the grid's window holds, however long the run
        self.transitions = []
        for m in mm.drive_models():
            t_ns, ext = valve_transitions(timeline, m, signal_map)
            t_s = t_ns / NS
            a = max(0, int(np.searchsorted(t_s, self.start_s)) - 2)
            b = int(np.searchsorted(t_s, self.horizon_s, side="right")) + 1
            self.transitions.append((t_s[a:b], ext[a:b]))
        # a passive consumer's cells per NL/min of flow (its cells scale with the flow)
        self.unit_cells = np.zeros((len(mm.passives), self.n_cells))
        for k, m in enumerate(mm.passive_models()):
            if m.role == "leak":
                s, e = np.array([0.0]), np.array([self.horizon_s])
            else:
                s_ns, e_ns = passive_intervals(timeline, m, signal_map)
                s, e = s_ns / NS, e_ns / NS
                keep = (e >= self.start_s) & (s <= self.horizon_s)
                s, e = s[keep], e[keep]
            self.unit_cells[k] = interval_cells(self.edges_s, s, e, 1.0)
        self.leak_unit = interval_cells(self.edges_s, [0.0], [self.horizon_s], 1.0)
        self._leak_from: dict[float, np.ndarray] = {}
        self._drive_cache: dict[tuple, np.ndarray] = {}
        self._metered: dict[tuple, tuple] = {}
        # NL per cell the physics plant draws beyond the nominal D1 model on these edges
        # (set by the diagnosis; used where ModelParams.dynamic)
        self.dynamic_cells: np.ndarray | None = None
        # the same for machine files changed by effects (diagnose.through_plant)
        self.variant_cells: dict[tuple, np.ndarray] = {}

    # ------------------------------------------------------------------ cells
    @staticmethod
    def _drive_key(params: ModelParams, k: int) -> tuple:
        """What drive ``k``'s cells depend on."""
        return (k, params.extend_nl[k], params.retract_nl[k], params.delay_s[k],
                (params.stroke_ext_s[k], params.stroke_ret_s[k]), params.exhaust_tau_s[k],
                tuple(params.held_nl[k]), tuple(params.swept_nl[k]),
                tuple(params.swept_held_nl[k]), bool(params.partial_strokes[k]),
                params.refill_fraction, params.refill_tau_s)

    def drive_cells(self, params: ModelParams, k: int) -> np.ndarray:
        """NL per cell of drive ``k`` under ``params`` (cached: most evaluations change
        one drive at most)."""
        st = (params.stroke_ext_s[k], params.stroke_ret_s[k])
        key = self._drive_key(params, k)
        cells = self._drive_cache.get(key)
        if cells is None:
            if len(self._drive_cache) > 256:
                self._drive_cache.clear()
            t_s, ext = self.transitions[k]
            stroke = None if np.isnan(st[0]) else (float(st[0]), float(st[1]))
            share = 1.0 - params.refill_fraction
            cells = stroke_cells(self.edges_s, t_s, ext, share * params.extend_nl[k],
                                 share * params.retract_nl[k], float(params.delay_s[k]),
                                 stroke, float(params.exhaust_tau_s[k]) or None,
                                 tuple(params.held_nl[k]), tuple(share * params.swept_nl[k]),
                                 tuple(params.swept_held_nl[k]),
                                 bool(params.partial_strokes[k]))
            if params.refill_fraction > 0:
                cells = cells + self._refill_cells(params, k, stroke)
            self._drive_cache[key] = cells
        return cells

    def _refill_cells(self, params: ModelParams, k: int, stroke) -> np.ndarray:
        """Shared supply: the share of each stroke's air that neighbours give back to the
        line and take again afterwards, flowing as ``exp(-t/tau)`` from the stroke's end."""
        t_s, ext = self.transitions[k]
        vol = params.refill_fraction * np.where(ext, params.extend_nl[k],
                                                params.retract_nl[k])
        end = t_s + params.delay_s[k] + (0.0 if stroke is None else
                                         np.where(ext, stroke[0], stroke[1]))
        # the refill as a first-order response to the volume given back at each stroke
        # end (the same filter as the meter's, volume preserved)
        k_cell = (end / self.dt_s).astype(np.int64)
        keep = (k_cell >= self.start_cell) & (end < self.horizon_s)
        k_cell = np.clip(k_cell - self.start_cell, 0, self.n_cells - 1)
        impulses = np.bincount(k_cell[keep], weights=vol[keep], minlength=self.n_cells)
        return first_order_lag(impulses, self.dt_s, max(params.refill_tau_s, 1e-3),
                               from_rest=True)

    def consumer_cells(self, params: ModelParams) -> np.ndarray:
        """NL per cell per consumer (rows as the machine's consumers), plus a last row for
        the diagnosis' extra leak."""
        out = np.zeros((len(self.mm.models) + 1, self.n_cells))
        for k, row in enumerate(self.mm.drives):
            out[row] = self.drive_cells(params, k)
        for k, row in enumerate(self.mm.passives):
            out[row] = self.unit_cells[k] * params.passive_l_min[k]
        cut = self._supply_cut(params)
        if cut is not None:
            out[self.mm.drives, cut:] *= params.supply_d1_ratio
            for k, row in enumerate(self.mm.passives):
                out[row, cut:] *= params.supply_passive_ratio[k]
        out[-1] = self._leak_cells(params)
        return out

    def _supply_cut(self, params: ModelParams) -> int | None:
        """The first cell at the changed supply (None: the file's throughout)."""
        if params.supply_from_s >= self.horizon_s:
            return None
        return int(np.clip(math.ceil((params.supply_from_s - self.start_s) / self.dt_s
                                     - 1e-9), 0, self.n_cells))

    def _leak_cells(self, params: ModelParams) -> np.ndarray:
        """The diagnosis' extra leak per cell, from ``extra_leak_from_s`` on."""
        if not params.extra_leak_l_min:
            return np.zeros(self.n_cells)
        start = params.extra_leak_from_s
        if start <= 0.0:
            return self.leak_unit * params.extra_leak_l_min
        if start >= self.horizon_s:
            return np.zeros(self.n_cells)
        unit = self._leak_from.get(start)
        if unit is None:
            unit = interval_cells(self.edges_s, [start], [self.horizon_s], 1.0)
            self._leak_from = {start: unit}
        return unit * params.extra_leak_l_min

    def total_cells(self, params: ModelParams) -> np.ndarray:
        total = self._leak_cells(params)
        cut = self._supply_cut(params)
        if len(self.mm.passives):
            passive = params.passive_l_min @ self.unit_cells
            if cut is not None:
                ratio = np.asarray(params.supply_passive_ratio, dtype=float)
                passive[cut:] = (params.passive_l_min * ratio) @ self.unit_cells[:, cut:]
            total = total + passive
        if cut is None:
            for k in range(len(self.mm.drives)):
                total = total + self.drive_cells(params, k)
        else:
            drives = np.zeros(self.n_cells)
            for k in range(len(self.mm.drives)):
                drives += self.drive_cells(params, k)
            drives[cut:] *= params.supply_d1_ratio
            total = total + drives
        if params.dynamic:
            extra = self.variant_cells[params.variant] if params.variant \
                else self.dynamic_cells
            if extra is not None:
                total = total + extra
        return total

    # ------------------------------------------------------------------ readings
    def metered_cumulative_nl(self, params: ModelParams,
                              total_cells: np.ndarray | None = None) -> np.ndarray:
        """Normal litres through the meter (its lag applied) by each grid edge.

        Kept for the last few parameter sets that give different cells or lags: a fit's
        Jacobian moves the clock (which only shifts the readings) and the parameters of
        other runs, and about two evaluations in three meter cells already metered."""
        key = None
        if total_cells is None:
            key = self._metered_key(params)
            hit = self._metered.get(key)
            if hit is not None and hit[0] is self.dynamic_cells \
                    and hit[1] is self.variant_cells.get(params.variant):
                cum = hit[2]
                return cum if params.meter_gain == 1.0 else cum * params.meter_gain
        cells = self.total_cells(params) if total_cells is None else total_cells
        cum = lagged_cumulative_nl(cells, self.dt_s, params.meter_tau_s)
        if key is not None:
            cum.flags.writeable = False          # shared by later evaluations
            if len(self._metered) >= METERED_KEPT:
                self._metered.pop(next(iter(self._metered)))
            self._metered[key] = (self.dynamic_cells,
                                  self.variant_cells.get(params.variant), cum)
        return cum if params.meter_gain == 1.0 else cum * params.meter_gain

    def _metered_key(self, params: ModelParams) -> tuple:
        """What the metered cumulative NL depends on but the meter's gain (the dynamic
        reference's arrays are checked by identity beside it)."""
        return (tuple(self._drive_key(params, k) for k in range(len(self.mm.drives))),
                tuple(params.passive_l_min), params.extra_leak_l_min,
                params.extra_leak_from_s, params.supply_from_s, params.supply_d1_ratio,
                params.supply_passive_ratio, params.dynamic, params.variant,
                params.meter_tau_s)

    def readings(self, params: ModelParams, start_s: np.ndarray, end_s: np.ndarray,
                 total_cells: np.ndarray | None = None,
                 cum_nl: np.ndarray | None = None) -> np.ndarray:
        """What the meter logs (NL/min) over each ``[start, end]`` of the run's prediction
        time: the total flow through the meter's lag, averaged over the interval."""
        if cum_nl is None:
            cum_nl = self.metered_cumulative_nl(params, total_cells)
        shift = params.clock_adjust_s + self.start_s
        return interval_means_l_min(cum_nl, self._sampled_edges_s, start_s - shift,
                                    end_s - shift, self.dt_s)

    def sampler(self, start_s: np.ndarray, end_s: np.ndarray,
                clock_adjust_s: float = 0.0) -> IntervalSampler:
        """What :meth:`readings` reads of the metered cumulative NL for these intervals
        at this clock, found once (its cells and weights on the run's own grid)."""
        shift = clock_adjust_s + self.start_s
        return IntervalSampler(self._sampled_edges_s, start_s - shift, end_s - shift,
                               self.dt_s)

    def chained_readings(self, params: ModelParams, bounds_s: np.ndarray,
                         cum_nl: np.ndarray) -> np.ndarray:
        """:meth:`readings` of intervals that follow one another, a chain per row of
        ``bounds_s`` (each row's ``n + 1`` boundaries in the run's prediction time):
        the same values, each shared boundary read once."""
        shift = params.clock_adjust_s + self.start_s
        return chained_interval_means_l_min(cum_nl, self._sampled_edges_s,
                                            bounds_s - shift, self.dt_s)
