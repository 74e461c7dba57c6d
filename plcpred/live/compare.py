"""The live comparison: per machine cycle (between rising edges of its cycle signal) or
per window, the air the model predicts from the recorded valve edges (the activation
model of :mod:`plcpred.air` on the real I/O, through the meter's first-order response
like the readings) against the air the meter read, the flow while the machine rests, a
rolling gap and the alarms. The alarms judge the gap to the reference learned from the
first cycles (:mod:`.reference`), D1's own gap is reported beside it.

It holds only the edges and readings of the last stretch it compares (a lookback for
the strokes still running at a cycle's start, and the cycle): memory stays bounded
however long it runs. Pure arithmetic on what it is fed: no I/O."""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

import numpy as np

from ..air import consumer_models, demand_profile
from ..air.demand import DemandSteps
from ..physics.meter import cumulative_nl, first_order_lag
from ..sequencer.timeline import NS, Signal, Timeline
from .reference import LearnedReference

GRID_DT_S = 0.01
ROLLING_CYCLES = 10
MAX_LOOKBACK_S = 30.0
MAX_CYCLE_FACTOR = 10        # a cycle longer than this many windows is compared as windows


@dataclass
class CycleResult:
    number: int
    start_ns: int
    end_ns: int
    measured_nl: float
    predicted_nl: float
    idle_l_min: float | None          # measured flow while resting (None: no rest)
    idle_predicted_l_min: float | None
    rolling_gap: float | None         # against the reference over the last cycles
    by_consumer: np.ndarray | None = None   # D1's NL per consumer (``models`` order)
    reference_nl: float | None = None       # the learned reference's (None: learning)
    reference: str = "D1"                   # what the reference is (its label)
    learned_now: bool = False               # the reference was learned with this cycle

    @property
    def gap(self) -> float | None:
        """Measured against D1."""
        return _gap(self.measured_nl, self.predicted_nl)

    @property
    def reference_gap(self) -> float | None:
        """Measured against the learned reference (the one alarms judge)."""
        return _gap(self.measured_nl, self.reference_nl)

    @property
    def duration_s(self) -> float:
        return (self.end_ns - self.start_ns) / NS


def _gap(measured: float, expected: float | None) -> float | None:
    return (measured - expected) / expected if expected is not None and expected > 0 \
        else None


@dataclass
class _Alarm:
    streak: list = field(default_factory=list)     # cycles in a row beyond the limit
    raised_ns: int | None = None


class LiveComparison:
    """Fed edges and readings in time order (absolute ns); gives a :class:`CycleResult`
    for each cycle or window once the readings cover its end."""

    def __init__(self, machine, settings):
        self.machine, self.settings = machine, settings
        self.models = consumer_models(machine)
        # kept over reconnects and new segments: the machine is the same
        self.reference = LearnedReference([m.name for m in self.models],
                                          int(getattr(settings, "learn_cycles", 0) or 0))
        self.valves = list(dict.fromkeys(v for m in self.models for v in m.valve))
        self.rest_value = self._rest_values()
        self.tau_s = float(settings.meter_tau_s or 0.0)
        slowest = max([m.delay_s + max(m.stroke_time_s or (0.0,)) for m in self.models
                       if m.role == "active"] + [0.0])
        self.lookback_ns = round(min(MAX_LOOKBACK_S, slowest + 5 * self.tau_s + 1.0) * NS)
        self.settle_ns = round((slowest + 3 * self.tau_s + 0.1) * NS)
        self.cycle_signal = settings.cycle_signal
        self.window_ns = round(settings.window_s * NS)
        self.reset()
        self.results: deque = deque(maxlen=ROLLING_CYCLES)
        self.count = 0
        self.gap_alarm, self.idle_alarm = _Alarm(), _Alarm()

    def _rest_values(self) -> dict[str, float]:
        """A valve's value where nothing was recorded: off, or on for the single solenoid
        of a cylinder that starts extended (as ``diagnose --io`` holds it)."""
        out = {}
        for m in self.models:
            for v in m.valve:
                out.setdefault(v, 1.0 if (m.role == "active" and len(m.valve) == 1
                                          and m.initial_extended) else 0.0)
        return out

    def reset(self, origin_ns: int | None = None) -> None:
        """Forget everything (a new segment after a gap: nothing spans it)."""
        self.state = dict(self.rest_value)
        self.base_ns = origin_ns               # edges kept from here, ``base`` the state then
        self.base = dict(self.state)
        self.edges: deque = deque()            # (t ns, valve, value)
        self.readings: deque = deque()         # (t ns, NL/min)
        # what flowed before the origin (strokes under way, the meter's response) is
        # unknown: a cycle or window is compared from a lookback after it on
        self.first_ns = None if origin_ns is None else origin_ns + self.lookback_ns
        # the open cycle's start (with a cycle signal: its first rising edge, the
        # stretch before it is no whole cycle)
        self.boundary_ns = self.first_ns if self.cycle_signal is None else None
        self.pending: deque = deque()          # cycles ended, waiting for their readings
        self.cycle_value = None
        self.reading_period_ns = None

    # ------------------------------------------------------------------ input
    def edge(self, t_ns: int, signal: str, value: float) -> None:
        if self.base_ns is None:
            self.reset(t_ns)
        if signal in self.state:
            self.edges.append((t_ns, signal, value))
            self.state[signal] = value
        if self.cycle_signal is not None and signal == self.cycle_signal:
            rising = self.cycle_value is not None and value > self.cycle_value
            self.cycle_value = value
            if rising:
                self._boundary(t_ns)

    def snapshot(self, states: dict[str, float]) -> None:
        """Values known at a segment's start."""
        for s, v in states.items():
            if s in self.state:
                self.state[s] = self.base[s] = v
            if s == self.cycle_signal:
                self.cycle_value = v

    def reading(self, t_ns: int, flow_l_min: float) -> list[CycleResult]:
        """A meter reading (NL/min at ISO 8778, the mean since the reading before); the
        cycles it completes."""
        if self.base_ns is None:
            self.reset(t_ns)
        if self.readings:
            gap = t_ns - self.readings[-1][0]
            if self.reading_period_ns is None or gap < self.reading_period_ns:
                self.reading_period_ns = gap
        self.readings.append((t_ns, flow_l_min))
        if self.boundary_ns is not None and self.cycle_signal is None:
            while t_ns >= self.boundary_ns + self.window_ns:
                self._boundary(self.boundary_ns + self.window_ns)
        elif self.boundary_ns is not None and \
                t_ns >= self.boundary_ns + MAX_CYCLE_FACTOR * self.window_ns:
            self._boundary(t_ns)                # a machine that stopped cycling
        out = []
        while self.pending and self.pending[0][1] <= t_ns:
            a, b = self.pending.popleft()
            out.append(self._compare(a, b))
        self._forget()
        return out

    def _boundary(self, t_ns: int) -> None:
        if self.boundary_ns is not None and t_ns > self.boundary_ns >= self.first_ns:
            self.pending.append((self.boundary_ns, t_ns))
        self.boundary_ns = t_ns

    def _forget(self) -> None:
        """Drop what no cycle still to compare needs (bounded memory)."""
        keep_from = (self.pending[0][0] if self.pending else self.boundary_ns or 0) \
            - self.lookback_ns
        while self.edges and self.edges[0][0] < keep_from:
            t, s, v = self.edges.popleft()
            self.base[s] = v
            self.base_ns = t
        while len(self.readings) > 2 and self.readings[1][0] < keep_from:
            self.readings.popleft()

    # ------------------------------------------------------------------ comparing
    def _compare(self, a_ns: int, b_ns: int) -> CycleResult:
        start_ns = max(a_ns - self.lookback_ns, self.base_ns if self.base_ns is not None
                       else a_ns)
        grid = np.arange(start_ns, b_ns + 1, round(GRID_DT_S * NS), dtype=np.int64)
        if grid[-1] != b_ns:
            grid = np.append(grid, b_ns)
        by_consumer_cum = self._predicted_cum_nl(start_ns, b_ns, grid)
        predicted_cum = by_consumer_cum.sum(axis=0)
        measured_cum, covered = self._measured_cum_nl(grid)
        ia, ib = int(np.searchsorted(grid, a_ns)), len(grid) - 1
        measured = float(measured_cum[ib] - measured_cum[ia])
        by_consumer = by_consumer_cum[:, ib] - by_consumer_cum[:, ia]
        idle, idle_pred = self._idle(grid, ia, measured_cum, predicted_cum, covered)
        self.count += 1
        ref = self.reference
        learned_now = ref.add(self.count, by_consumer, measured)
        result = CycleResult(self.count, a_ns, b_ns, measured, float(by_consumer.sum()), idle,
                             idle_pred, None, by_consumer, ref.expected_nl(by_consumer),
                             ref.label(), learned_now)
        if result.reference_nl is not None:
            self.results.append(result)
            m = sum(r.measured_nl for r in self.results)
            e = sum(r.reference_nl for r in self.results)
            result.rolling_gap = _gap(m, e)
        return result

    def _predicted_cum_nl(self, start_ns: int, end_ns: int, grid: np.ndarray) -> np.ndarray:
        """Per consumer (rows in ``self.models`` order) the model's air (NL) by each grid
        time from the valves' states at ``start_ns`` and the edges since, through the
        meter's response (linear: each consumer's share passes it on its own)."""
        names = self.valves
        index = {n: i for i, n in enumerate(names)}
        state = dict(self.base)
        rows = [(t, s, v) for t, s, v in self.edges if t <= start_ns]
        for _, s, v in rows:
            state[s] = v
        later = [(t - start_ns, index[s], v) for t, s, v in self.edges
                 if start_ns < t <= end_ns]
        t_ns = [0] * len(names) + [r[0] for r in later]
        sig = list(range(len(names))) + [r[1] for r in later]
        val = [state[n] for n in names] + [r[2] for r in later]
        horizon_ns = max(end_ns - start_ns, 1)
        timeline = Timeline([Signal(n, "output", "bool") for n in names], t_ns, sig, val,
                            horizon_ns, info={"mode": "recorded", "source": "watched I/O"})
        profile = demand_profile(timeline, self.models, GRID_DT_S)
        at_s = (grid - start_ns) / NS
        dt = np.diff(grid) / NS
        out = np.zeros((len(self.models), len(grid)))
        for k, rect in enumerate(profile.rects):
            if rect is None or not len(rect[0]):
                continue
            cells = np.diff(DemandSteps.of([rect], horizon_ns / NS).cumulative_nl(at_s))
            flow = np.divide(cells, dt, out=np.zeros_like(cells), where=dt > 0) * 60.0
            out[k] = cumulative_nl(first_order_lag(flow, GRID_DT_S, self.tau_s) * dt / 60.0)
        return out

    def _measured_cum_nl(self, grid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The meter's air (NL) by each grid time (each reading the mean flow since the
        one before), and which grid cells the readings cover."""
        t = np.array([r[0] for r in self.readings], dtype=np.int64)
        q = np.array([r[1] for r in self.readings])
        period = self.reading_period_ns or 0
        starts = np.concatenate([[t[0] - period], t[:-1]])
        cum_t = np.concatenate([[starts[0]], t])
        cum_v = cumulative_nl(q * (t - starts) / NS / 60.0)
        cum = np.interp(grid, cum_t, cum_v)
        covered = (grid[:-1] >= cum_t[0]) & (grid[1:] <= cum_t[-1])
        return cum, covered

    def _idle(self, grid, ia, measured_cum, predicted_cum, covered):
        """Mean measured and predicted flow (NL/min) over the cycle's cells at rest: no
        valve edge in the settling time before (strokes, the meter's response)."""
        edge_t = np.array([t for t, _, _ in self.edges], dtype=np.int64)
        cells = np.arange(ia, len(grid) - 1)
        if not len(cells):
            return None, None
        starts = grid[cells]
        last = np.searchsorted(edge_t, grid[cells + 1], side="right") - 1
        prev = np.where(last >= 0, edge_t[np.clip(last, 0, None)], np.iinfo(np.int64).min)
        rest = (starts - prev >= self.settle_ns) & covered[cells]
        if self.base_ns is not None:
            rest &= starts - self.base_ns >= self.settle_ns
        if not rest.any():
            return None, None
        dt_min = (grid[cells + 1] - grid[cells])[rest].sum() / NS / 60.0
        m = np.diff(measured_cum)[cells][rest].sum() / dt_min
        p = np.diff(predicted_cum)[cells][rest].sum() / dt_min
        return float(m), float(p)

    # ------------------------------------------------------------------ alarms
    def alarms(self, result: CycleResult) -> list[dict]:
        """Alarm events this cycle raises or clears: the gap to the reference beyond the
        threshold for ``gap_alarm_cycles`` cycles in a row (none while it is learned),
        the idle flow beyond its limit. Each raised alarm gives the time it began (the
        first cycle of its streak)."""
        s = self.settings
        out = []
        gap = result.reference_gap
        beyond = gap is not None and abs(gap) * 100.0 > s.gap_alarm_percent
        out += self._track(self.gap_alarm, beyond, result, s.gap_alarm_cycles, "gap",
                           {"gap_percent": None if gap is None else 100.0 * gap,
                            "limit_percent": s.gap_alarm_percent,
                            "reference": result.reference})
        if s.idle_limit_l_min is not None and result.idle_l_min is not None:
            out += self._track(self.idle_alarm, result.idle_l_min > s.idle_limit_l_min,
                               result, 1, "idle_flow",
                               {"idle_l_min": result.idle_l_min,
                                "limit_l_min": s.idle_limit_l_min})
        return out

    @staticmethod
    def _track(alarm: _Alarm, beyond: bool, result: CycleResult, needed: int, kind: str,
               data: dict) -> list[dict]:
        if not beyond:
            alarm.streak.clear()
            if alarm.raised_ns is not None:
                alarm.raised_ns = None
                return [{"alarm": kind, "state": "cleared", "at_ns": result.start_ns, **data}]
            return []
        alarm.streak.append(result.start_ns)
        del alarm.streak[:-needed]
        if alarm.raised_ns is None and len(alarm.streak) >= needed:
            alarm.raised_ns = alarm.streak[0]
            return [{"alarm": kind, "state": "raised", "began_ns": alarm.raised_ns,
                     "cycle": result.number, **data}]
        return []
