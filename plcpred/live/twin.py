"""What ``serve`` publishes: the machine's program run against the physics plant (as
``emulate`` runs it), read as the values of its signals, a flow meter and the supply
pressure at their times.

The closed loop runs from the machine's start to a horizon; a run's first seconds do not
depend on how long it goes on, so the server starts on a short run and moves on to
longer ones as the served time needs them, each time at the same values. Most machines
settle into a cycle: once a run's last periods repeat (every served signal's edges
shifted by one period, the metered air and the supply pressure the same to
:data:`REPEAT_TOL`), the values past it are that last period's, tiled (edges shifted by
whole periods, the meter's air added per period), and no longer run is made: a day
costs what the first minute did, in CPU and in memory. A period is trusted only where
the program's own prediction (the sequencer's open-loop run, which compares the
program's whole state) repeats too, and the checked stretch spans two of its periods: a
counter that changes the cycle only every hundred parts keeps the runs going until the
stretch spans it; a machine the prediction finds no period for (jittered inputs, a
counter running free, the clock read, a machine that comes to rest for good) is run in
ever longer runs to the horizon, as before.

With a truth file switched on at a time, the nominal and the real machine both run (each
tiled with its own period), and the served values leave the nominal run for the real one
at the first moment from then on when every served signal has the same value in both (at
once for a hidden leak: it changes no edge).

:meth:`Twin.process` runs all of this in a process of its own (a fresh interpreter: the
server's event loop is never starved by a closed-loop run); the server asks it for each
stretch of values (:class:`TwinProcess`)."""
from __future__ import annotations

import bisect
import copy
import math
import os
import pickle
import subprocess
import sys
import threading
import weakref

import numpy as np

from ..errors import PlcpredError
from ..machine import check_against_program
from ..plant import load_real_machine
from ..plant.emulate import MAX_EMULATE_HORIZON_S, run_closed_loop
from ..plant.flow_meter import MeterSettings, meter_readings
from ..sequencer import Sequencer, compile_program, observed_names
from ..sequencer.timeline import NS
from .settings import METER_NAME, PRESSURE_NAME, LiveError, machine_signals

FINE_DT_S = 1e-3           # the plant read on this grid for the meter (as emulate does)
FIRST_RUN_S = 20.0         # the first run's horizon: the server starts after it
RUN_GROWTH = 4.0           # each later run this much longer
# a run is tiled once its last REPEATS + 1 periods repeat (each the one before shifted by
# the period), as the plant's cells are repeated once a tiled timeline has settled
# (plcpred.plant.replay.SETTLE_PERIODS)
REPEATS = 3
REPEAT_TOL = 1e-6          # the metered air and supply pressure repeat to this (relative)
REST_PERIOD_S = 1.0        # the period tried for a machine whose signals no longer change
MAX_CHECK_CELLS = 20_000   # the air's repeat checked on at most this many cells
MAX_TABLE_CELLS = 1_000_000  # a tiled period's fine grid (1 ms for periods to 1000 s)


class _Loop:
    """One machine's closed loop as served: a run from its start to ``run_s`` and, once
    that run ends in a repeating period, its last period tiled past it (``period_ns``)."""

    def __init__(self, machine, program, compiled, signals: list[str], horizon_s: float):
        self.machine, self.program, self.compiled = machine, program, compiled
        self.signals, self.horizon_s = signals, horizon_s
        self.plant = self.timeline = None
        self.run_s = 0.0
        self.run_ns = 0
        self.period_ns: int | None = None
        self.period_nl = 0.0       # the metered air of one period
        self._table = None         # (start s, step s, metered NL, supply bar g)
        self.edges: list[tuple[np.ndarray, np.ndarray]] = []   # per served signal
        self._predicted: tuple[float, int | None] | None = None   # (horizon s, period ns)

    # ------------------------------------------------------------------ runs
    @property
    def end_s(self) -> float:
        """How far the served values are known without another run."""
        return math.inf if self.period_ns is not None else self.run_s

    def next_horizon(self) -> float:
        h = FIRST_RUN_S if self.run_s <= 0 else self.run_s * RUN_GROWTH
        return min(h, self.horizon_s)

    def run(self, horizon_s: float) -> tuple:
        """(plant, timeline) of the closed loop to ``horizon_s`` (CPU-bound: touches
        nothing of this object's, so a worker thread may run it)."""
        return run_closed_loop(self.machine, self.program, horizon_s, self.compiled)

    def adopt(self, horizon_s: float, plant, timeline) -> None:
        """Serve from this run (dropping the one before) and look for its period."""
        self.plant, self.timeline = plant, timeline
        self.run_s, self.run_ns = float(horizon_s), round(horizon_s * NS)
        names = timeline.info.get("machine_signals", {})
        self.edges = [timeline.edge_times_ns(names.get(s, s)) for s in self.signals]
        self.period_ns = self._period_ns()
        self._table = None
        if self.period_ns is not None:
            self._tabulate()

    def _tabulate(self) -> None:
        """The run's last period on the fine grid (the metered air and the supply
        pressure), read past the run's end at the times that fall on it (the meter's
        grid does, for a period of whole milliseconds): a reading far along costs what
        one near the start does."""
        p_s = self.period_ns / NS
        cells = max(1, min(MAX_TABLE_CELLS, math.ceil(p_s / FINE_DT_S - 1e-6)))
        dt = p_s / cells
        times = (self.run_s - p_s) + dt * np.arange(cells + 1)
        cum = self._run_cum_nl(times)
        self.period_nl = float(self._run_cum_nl(np.array([self.run_s - p_s, self.run_s]))
                               @ np.array([-1.0, 1.0]))
        self._table = (self.run_s - p_s, dt, cum, self.plant.line_pressure_bar_g(times))

    def _period_ns(self) -> int | None:
        """The shortest period the run's last REPEATS + 1 periods repeat with, and that
        spans the program's own period (its prediction's) twice; None for none."""
        h = self.run_ns
        for p in self._candidates():
            window = (REPEATS + 1) * p
            if window >= h:
                break
            if not self._edges_repeat(p, h - window):
                continue
            predicted = self._predicted_ns()
            if predicted is None:
                return None        # the program's state is not known to repeat
            window = max(window, 2 * predicted)
            if window >= h:
                return None        # a longer run first
            if self._edges_repeat(p, h - window) and \
                    self._air_repeats(p, h - (REPEATS + 1) * p):
                return p
        return None

    def _candidates(self) -> list[int]:
        """Periods the run's edges allow, shortest first: from each signal's last edge
        back to its earlier edges to the same value, kept where every signal that
        changes within the last such period has its last edge one period earlier too
        (a period repeats every edge); and the rest period (nothing changes)."""
        h = self.run_ns
        limit = (h - 1) // (REPEATS + 1)
        parts = [np.array([round(REST_PERIOD_S * NS)], dtype=np.int64)]
        for t, v in self.edges:
            if len(t) > 2:
                same = t[1:-1][v[1:-1] == v[-1]]
                parts.append(t[-1] - same[same >= t[-1] - limit])
        out = np.unique(np.concatenate(parts))
        out = out[(out > 0) & (out <= limit)]
        for t, _ in self.edges:
            if len(t) > 1 and len(out):
                changes = t[-1] >= h - out          # within the last period
                before = t[-1] - out
                i = np.clip(np.searchsorted(t, before), 0, len(t) - 1)
                out = out[~changes | ((t[i] == before) & (i > 0))]
        return [int(p) for p in out]

    def _edges_repeat(self, p: int, lo: int) -> bool:
        """Does every served signal's value over [lo, run end) repeat after ``p``?"""
        h, lo = self.run_ns, max(lo, 1)
        for t, v in self.edges:
            i0, i1, j0, j1 = np.searchsorted(t, [lo, h - p, lo + p, h])
            if i1 - i0 != j1 - j0 or not (np.array_equal(t[i0:i1] + p, t[j0:j1])
                                          and np.array_equal(v[i0:i1], v[j0:j1])):
                return False
            at = np.searchsorted(t, [lo, lo + p], side="right") - 1
            if v[at[0]] != v[at[1]]:
                return False
        return True

    def _air_repeats(self, p: int, lo: int) -> bool:
        """Is the metered air over any stretch of [lo, run end) one period on the same
        (the air of a period the same from every start), and the supply pressure? (On
        at most MAX_CHECK_CELLS cells of the fine grid: a nozzle's air costs the plant
        its every switching by every time asked.)"""
        p_s, lo_s = p / NS, lo / NS
        span = self.run_s - p_s - lo_s
        cells = max(1, min(MAX_CHECK_CELLS, math.ceil(span / FINE_DT_S)))
        times = np.linspace(lo_s, lo_s + span, cells + 1)
        both = np.concatenate([times, times + p_s])
        cum = self._run_cum_nl(both)
        per = cum[cells + 1:] - cum[:cells + 1]
        if np.max(np.abs(per - per[0])) > REPEAT_TOL * max(abs(per[0]), 1e-3):
            return False
        supply = self.plant.line_pressure_bar_g(both)
        return bool(np.max(np.abs(supply[cells + 1:] - supply[:cells + 1]))
                    <= REPEAT_TOL * max(1.0, float(np.max(np.abs(supply)))))

    def _predicted_ns(self) -> int | None:
        """The period of the program's own prediction (the sequencer's tiling of its
        whole state, on the machine file's cylinder model) within this run's horizon;
        None where it finds none (jittered inputs, a clock read, a counter running
        free) or cannot run."""
        if self._predicted is not None and (self._predicted[1] is not None
                                            or self._predicted[0] >= self.run_s):
            return self._predicted[1]
        period = None
        if not self.compiled.reads_clock and \
                not any(s.jitter_s > 0 for s in self.machine.inputs):
            try:
                tl = Sequencer(self.program, self.machine,
                               compiled=self.compiled).run(self.run_ns)
                if tl.info.get("period_s"):
                    period = round(tl.info["period_s"] * NS)
            except PlcpredError:
                period = None
        self._predicted = (self.run_s, period)
        return period

    # ------------------------------------------------------------------ reading
    def _run_cum_nl(self, times_s: np.ndarray) -> np.ndarray:
        """The run's metered air by each time (within the run). The plant books a
        nozzle's air from its every switching at every time asked: it is asked with
        only the switchings within the times' span (a view of the plant), and the air
        by the span's start added, so a short span of a long run costs what its own
        switchings do."""
        times_s = np.asarray(times_s, dtype=float)
        if not len(times_s):
            return np.zeros(0)
        a, b = float(times_s.min()), float(times_s.max())
        view = _span_view(self.plant, a, b)
        if view is self.plant:
            return _metered(self.plant, times_s)
        inside = _metered(view, np.concatenate([[a], times_s]))
        return inside[1:] - inside[0] + _metered(self.plant, np.array([a]))[0]

    def _fold(self, times_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(time within the run, periods folded back) of each time: past the run's end,
        into its last period (at least one period back)."""
        times_s = np.asarray(times_s, dtype=float)
        if self.period_ns is None:
            return times_s, np.zeros(len(times_s))
        p_s = self.period_ns / NS
        past = times_s >= self.run_s
        k = np.where(past, np.maximum(1.0, np.floor((times_s - (self.run_s - p_s)) / p_s)),
                     0.0)
        return np.clip(times_s - k * p_s, 0.0, self.run_s), k

    def _from_table(self, folded: np.ndarray, column: int, exact) -> np.ndarray:
        """``column`` of the table at ``folded`` (times within the last period), where a
        time falls on its grid; ``exact(times)`` elsewhere."""
        t0, dt = self._table[0], self._table[1]
        table = self._table[column]
        x = (folded - t0) / dt
        i = np.rint(x)
        on = (np.abs(x - i) < 1e-6) & (i >= 0) & (i < len(table))
        out = np.empty(len(folded))
        out[on] = table[i[on].astype(np.int64)]
        if not on.all():
            out[~on] = exact(folded[~on])
        return out

    def _series(self, times_s: np.ndarray, column: int, exact, per_period: float = 0.0
                ) -> np.ndarray:
        """A series of the run at ``times_s``: ``exact(times)`` within the run, past its
        end the table's ``column`` at the time folded into the last period, plus
        ``per_period`` for each period folded back."""
        folded, k = self._fold(times_s)
        past = k > 0
        out = np.empty(len(folded))
        if (~past).any():
            out[~past] = exact(folded[~past])
        if past.any():
            out[past] = self._from_table(folded[past], column, exact)
            if per_period:
                out[past] += k[past] * per_period
        return out

    def cum_nl(self, times_s: np.ndarray) -> np.ndarray:
        """What the machine drew through the meter's point by each time (NL)."""
        return self._series(times_s, 2, self._run_cum_nl, self.period_nl)

    def supply_bar_g(self, times_s: np.ndarray) -> np.ndarray:
        return self._series(times_s, 3, self.plant.line_pressure_bar_g)

    def edges_between(self, k: int, lo: int, hi: int) -> tuple[np.ndarray, np.ndarray]:
        """(times ns, values) of served signal ``k``'s changes in [lo, hi)."""
        t, v = self.edges[k]
        h = self.run_ns
        m = (t >= lo) & (t < min(hi, h))
        if self.period_ns is None or hi <= h:
            return t[m], v[m]
        p = self.period_ns
        ref = (t >= h - p) & (t < h)
        tr, vr = t[ref], v[ref]
        first = max(1, (max(lo, h) - (h - p)) // p)
        last = (hi - 1 - (h - p)) // p
        reps = np.arange(first, last + 1, dtype=np.int64)
        tt = (tr[None, :] + reps[:, None] * p).ravel()
        vv = np.tile(vr, len(reps))
        keep = (tt >= max(lo, h)) & (tt < hi)
        return np.concatenate([t[m], tt[keep]]), np.concatenate([v[m], vv[keep]])

    def values_at(self, k: int, at_ns: np.ndarray) -> np.ndarray:
        """Served signal ``k``'s value at each time (ns)."""
        at_ns = np.asarray(at_ns, dtype=np.int64)
        if self.period_ns is not None:
            p, h = self.period_ns, self.run_ns
            fold = np.where(at_ns >= h, np.maximum(1, (at_ns - (h - p)) // p), 0)
            at_ns = at_ns - fold * p
        t, v = self.edges[k]
        return v[np.searchsorted(t, at_ns, side="right") - 1]


def _metered(plant, times_s: np.ndarray) -> np.ndarray:
    cumulative = plant.cumulative_nl(times_s)
    return sum(cumulative[n] for n in plant.metered_names())


def _span_view(plant, a: float, b: float):
    """``plant`` as seen over [a, b]: its nozzles switched only within the span (on at
    ``a`` if they were on then), its drives the same; ``plant`` itself where that drops
    no switching. Its air differs from the plant's by a constant over the span."""
    adapters, dropped = {}, False
    for name, adapter in plant.adapters.items():
        edges = getattr(adapter, "edges", None)
        if not edges:
            adapters[name] = adapter
            continue
        i = bisect.bisect_left(edges, (a, False))
        j = bisect.bisect_right(edges, (b, True))
        if i == 0 and j == len(edges):
            adapters[name] = adapter
            continue
        dropped = True
        clone = copy.copy(adapter)
        clone.edges = ([(a, True)] if i > 0 and edges[i - 1][1] else []) + edges[i:j]
        adapters[name] = clone
    if not dropped:
        return plant
    view = copy.copy(plant)
    view.adapters = adapters
    return view


class Twin:
    """The served machine: its signals (machine-file names, in :func:`machine_signals`
    order), then the meter and the supply pressure, as node indices."""

    def __init__(self, machine_path, horizon_s: float, truth=None, truth_at_s: float = 0.0,
                 seed: int | None = None, program=None):
        if not 0 < horizon_s <= MAX_EMULATE_HORIZON_S:
            raise LiveError(f"--horizon must be more than 0 s and at most "
                            f"{MAX_EMULATE_HORIZON_S / 3600:g} h (the physics plant's "
                            "longest run)")
        self.args = (machine_path, horizon_s, truth, truth_at_s, seed, program)
        self.horizon_s = float(horizon_s)
        self.nominal = load_real_machine(machine_path, None)
        self.real = load_real_machine(machine_path, truth) if truth is not None else None
        self.truth_at_s = float(truth_at_s or 0.0)
        if self.real is not None and self.truth_at_s <= 0:
            self.nominal, self.real = self.real, None      # the real machine from the start
        self.program = self.nominal.read_program(program)
        check_against_program(self.nominal, self.program)
        if self.real is not None:
            check_against_program(self.real, self.program)
        # compiled once for every run (a restarted server's first among them)
        self.compiled = compile_program(self.program, observed_names(self.nominal, self.program)
                                        | observed_names(self.real or self.nominal,
                                                         self.program))
        self.signals = machine_signals(self.nominal)
        self.names = self.signals + [METER_NAME, PRESSURE_NAME]
        self.meter_index, self.pressure_index = len(self.signals), len(self.signals) + 1
        self.meter = MeterSettings.from_machine((self.real or self.nominal).meter)
        self.rng = np.random.default_rng(seed)
        self._nominal, self._real = (
            _Loop(m, self.program, self.compiled, self.signals, self.horizon_s)
            if m is not None else None for m in (self.nominal, self.real))
        self._splice_s: float | None = None      # served from the real run from here on
        self._searched_s = self.truth_at_s       # no splice before this
        self.runs: list[tuple[str, float]] = []  # (which, horizon s) of every run made
        self._ahead = None          # a run made in a thread ahead of need (prefetch)
        self._asked_s = 0.0         # the furthest time values were asked for
        self._process = None

    # ------------------------------------------------------------------ runs
    def _cover(self, loop: _Loop, t_s: float) -> None:
        """Run ``loop`` on (longer runs, until it is tiled) until it covers ``t_s``."""
        while loop.end_s < t_s:
            h = loop.next_horizon()
            ahead = self._ahead
            if ahead is not None:
                # one run at a time (the runs share the compiled program)
                ahead[2].join()
            if ahead is not None and ahead[0] is loop and ahead[1] == h:
                self._ahead = None
                if "error" in ahead[3]:
                    raise ahead[3]["error"]
                plant, timeline = ahead[3]["run"]
            else:
                plant, timeline = loop.run(h)
            self.runs.append(("nominal" if loop is self._nominal else "real", h))
            loop.adopt(h, plant, timeline)

    def _ensure(self, t_s: float) -> None:
        """Every run the values up to ``t_s`` need made, and the splice searched to it."""
        t_s = min(t_s, self.horizon_s)
        self._asked_s = max(self._asked_s, t_s)
        self._cover(self._nominal, t_s if self._splice_s is None
                    else min(t_s, self._splice_s))
        if self._real is None or t_s <= self.truth_at_s:
            return
        self._cover(self._real, t_s)
        if self._splice_s is None and self._searched_s <= t_s:
            self._splice_s = self._find_splice(self._searched_s, t_s)
            self._searched_s = t_s

    def _covered_s(self) -> float:
        """How far the values are known without another run."""
        end = self._nominal.end_s
        if self._real is not None and self._real.run_s > 0:
            end = self._real.end_s if self._splice_s is not None else min(
                end, self._real.end_s)
        return end

    def prefetch(self) -> None:
        """Start the next run the served values will need in a thread (a machine that is
        not tiled: its next longer run, made while the current one is served)."""
        if self._ahead is not None and self._ahead[2].is_alive():
            return
        loop = None
        nominal, real = self._nominal, self._real
        if nominal.end_s < self.horizon_s and (self._splice_s is None
                                                or self._splice_s > nominal.end_s):
            loop = nominal
        elif real is not None and real.end_s < min(
                self.horizon_s, RUN_GROWTH * max(self._asked_s, self.truth_at_s)) \
                and RUN_GROWTH * self._asked_s >= self.truth_at_s:
            loop = real     # the real machine's runs once its time draws near
        if loop is None or (self._ahead is not None and self._ahead[0] is loop
                            and self._ahead[1] == loop.next_horizon()):
            return
        box: dict = {}

        def work() -> None:
            try:
                box["run"] = loop.run(h)
            except Exception as e:  # noqa: BLE001 - raised where the run is needed
                box["error"] = e

        h = loop.next_horizon()
        thread = threading.Thread(target=work, daemon=True, name="plcpred-twin-run")
        self._ahead = (loop, h, thread, box)
        thread.start()

    def _find_splice(self, from_s: float, to_s: float) -> float | None:
        """The first time in [max(truth_at, from), to] when every served signal has the
        same value in the nominal and the real machine; None for none."""
        lo = round(max(self.truth_at_s, from_s) * NS)
        hi = round(to_s * NS)
        loops = (self._nominal, self._real)
        parts = [np.array([lo], dtype=np.int64)]
        for loop in loops:
            for k in range(len(self.signals)):
                parts.append(loop.edges_between(k, lo, hi + 1)[0])
        candidates = np.unique(np.concatenate(parts))
        same = np.ones(len(candidates), bool)
        for k in range(len(self.signals)):
            same &= loops[0].values_at(k, candidates) == loops[1].values_at(k, candidates)
        hit = np.flatnonzero(same & (candidates <= hi))
        return float(candidates[hit[0]] / NS) if len(hit) else None

    def periods_s(self) -> dict[str, float | None]:
        """The period each machine's served values are tiled with (None: not tiled)."""
        out = {"nominal": self._nominal.period_ns}
        if self._real is not None:
            out["real"] = self._real.period_ns
        return {k: None if v is None else v / NS for k, v in out.items()}

    def status(self) -> dict:
        """What the twin has run: its runs, periods and where the real machine's values
        begin (for reports and the bench)."""
        return {"runs": list(self.runs), "periods_s": self.periods_s(),
                "splice_s": self._splice_s, "horizon_s": self.horizon_s}

    # ------------------------------------------------------------------ values
    def values_at(self, at_s: float) -> list:
        """Every node's value at ``at_s``: the signals', the meter's reading due then
        (its first at the machine's start) and the supply pressure."""
        period = 1.0 / self.meter.rate_hz
        self._ensure(at_s + period)
        at_ns = np.array([round(at_s * NS)])
        real = self._splice_s is not None and at_s >= self._splice_s
        loop = self._real if real else self._nominal
        values: list = [bool(loop.values_at(k, at_ns)[0]) for k in range(len(self.signals))]
        _, flow, supply = self._readings(at_s, at_s + period)
        return values + [float(flow[0]) if len(flow) else 0.0,
                         float(supply[0]) if len(supply) else
                         float(loop.supply_bar_g(np.array([min(at_s, self.horizon_s)]))[0])]

    def events(self, t0_s: float, t1_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(time ns, node index, value) of what changes in ``[t0_s, t1_s)``, sorted by
        time (signals before the meter at one time): the signals' edges and the meter's
        readings with the supply pressure at each."""
        self._ensure(t1_s)
        t_parts, i_parts, v_parts = [], [], []
        lo, hi = max(round(t0_s * NS), 1), round(t1_s * NS)
        cut = None if self._splice_s is None else round(self._splice_s * NS)
        for k in range(len(self.signals)):
            if cut is None:
                t, v = self._nominal.edges_between(k, lo, hi)
            else:
                tn, vn = self._nominal.edges_between(k, lo, min(hi, cut)) if lo < cut \
                    else (np.zeros(0, np.int64), np.zeros(0))
                tr, vr = self._real.edges_between(k, max(lo, cut), hi) if hi > cut \
                    else (np.zeros(0, np.int64), np.zeros(0))
                t, v = np.concatenate([tn, tr]), np.concatenate([vn, vr])
            t_parts.append(t)
            i_parts.append(np.full(len(t), k))
            v_parts.append(v.astype(float))
        times_s, flow, supply = self._readings(t0_s, t1_s)
        t_ns = np.round(times_s * NS).astype(np.int64)
        t_parts += [t_ns, t_ns]
        i_parts += [np.full(len(t_ns), self.meter_index), np.full(len(t_ns),
                                                                  self.pressure_index)]
        v_parts += [flow, supply]
        t_all, i_all = np.concatenate(t_parts), np.concatenate(i_parts)
        order = np.lexsort((i_all, t_all))
        return t_all[order], i_all[order], np.concatenate(v_parts)[order]

    def _readings(self, t0_s: float, t1_s: float):
        """(times s, flow as the meter reports it, supply bar g) of the meter's readings
        in ``[t0_s, t1_s)``: the plant's true flow through the meter's response, read on
        a fine grid from a lead-in of ten response times before ``t0_s``."""
        period = 1.0 / self.meter.rate_hz
        lead_s = max(1.0, 10.0 * self.meter.tau_s)
        start_s = max(0.0, np.floor((t0_s - lead_s) / period) * period)
        end_s = min(t1_s, self._covered_s(), self.horizon_s)
        if end_s <= start_s:
            return np.zeros(0), np.zeros(0), np.zeros(0)
        # the fine grid on whole multiples of FINE_DT_S whatever the window: two
        # renderings of one moment (a server's stretch, a check of it) then put the
        # plant's air into the same cells, and the meter's response agrees
        first = int(np.floor(start_s / FINE_DT_S + 1e-9))
        last = max(first + 1, int(np.ceil(end_s / FINE_DT_S - 1e-9)))
        edges = np.arange(first, last + 1) * FINE_DT_S
        edges[0], edges[-1] = start_s, end_s
        splice = self._splice_s
        if splice is None or splice > end_s:
            total = self._nominal.cum_nl(edges)
        elif splice <= start_s:
            total = self._real.cum_nl(edges)
        else:
            real = np.diff(self._real.cum_nl(edges))
            nominal = np.diff(self._nominal.cum_nl(edges))
            cell = np.where(edges[:-1] >= splice, real, nominal)
            total = np.concatenate([[0.0], np.cumsum(cell)])
        times, flow = meter_readings(edges - start_s, total - total[0], self.meter,
                                     end_s - start_s, self.rng)
        times = times + start_s
        keep = (times >= t0_s - 1e-9) & (times < t1_s - 1e-9)
        times, flow = times[keep], flow[keep]
        if splice is None or splice > end_s:
            supply = self._nominal.supply_bar_g(times)
        else:
            supply = self._real.supply_bar_g(times)
            before = times < splice
            if before.any():
                supply[before] = self._nominal.supply_bar_g(times[before])
        return times, flow, supply

    # ------------------------------------------------------------------ its process
    def process(self) -> TwinProcess:
        """This twin run in a process of its own (started on first use, then kept for
        a restarted server): the server's event loop stays free of closed-loop runs."""
        if self._process is None or not self._process.alive():
            self._process = TwinProcess(self.args)
        return self._process


# ---------------------------------------------------------------------- the process
def _main() -> None:
    """The twin's process (its sys.path read first): reads its twin's arguments, then
    (method, arguments) requests, from stdin and answers each with ("ok", result) or ("error", exception) on the
    stdout it started with (pickled), making the next run ahead of need between
    requests. Ends when stdin does (the server is gone) or on None."""
    requests = sys.stdin.buffer
    replies = os.fdopen(os.dup(sys.stdout.fileno()), "wb")
    os.dup2(sys.stderr.fileno(), sys.stdout.fileno())   # a print must not break a reply
    sys.stdout = sys.stderr
    twin, args = None, None
    while True:
        try:
            request = pickle.load(requests)
        except (EOFError, OSError, pickle.UnpicklingError):
            return
        if request is None:
            return
        if args is None:
            args = request
            continue
        name, call_args = request
        try:
            if twin is None:
                twin = Twin(*args)
            reply = ("ok", getattr(twin, name)(*call_args))
        except Exception as e:  # noqa: BLE001 - handed to the server
            reply = ("error", e)
        try:
            data = pickle.dumps(reply, protocol=pickle.HIGHEST_PROTOCOL)
        except Exception:  # noqa: BLE001 - an exception that does not pickle
            data = pickle.dumps(("error", LiveError(f"{type(reply[1]).__name__}: "
                                                    f"{reply[1]}")))
        try:
            replies.write(data)
            replies.flush()
        except OSError:
            return
        if twin is not None and reply[0] == "ok":
            twin.prefetch()


class TwinProcess:
    """A :class:`Twin` (made again from its arguments) in a process of its own, asked one
    request at a time; it ends with its twin, or when the server's process does. (A
    fresh interpreter, not multiprocessing's: a script that serves without a
    ``__main__`` guard is not run again in it.)"""

    def __init__(self, args):

        # the child sees the modules this process does: its sys.path first
        boot = ("import pickle, sys; sys.path[:] = pickle.load(sys.stdin.buffer); "
                "from plcpred.live.twin import _main; _main()")
        self.proc = subprocess.Popen([sys.executable, "-c", boot], stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE)
        self._lock = threading.Lock()
        self._send(list(sys.path))
        self._send(args)
        self._finalizer = weakref.finalize(self, _stop, self.proc)

    @property
    def pid(self) -> int:
        return self.proc.pid

    def alive(self) -> bool:
        return self.proc.poll() is None

    def _send(self, obj) -> None:
        self.proc.stdin.write(pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL))
        self.proc.stdin.flush()

    def call(self, name: str, *args):
        """``twin.name(*args)`` in the process (blocking: for a worker thread)."""
        with self._lock:
            try:
                self._send((name, args))
                status, result = pickle.load(self.proc.stdout)
            except (EOFError, OSError, ValueError, pickle.UnpicklingError) as e:
                raise LiveError(f"the twin's process ended "
                                f"({e or 'no reply'}; exit code {self.proc.poll()})") from None
        if status == "error":
            raise result
        return result

    def close(self) -> None:
        self._finalizer()


def _stop(proc) -> None:
    try:
        proc.stdin.close()          # the process ends at the end of its requests
    except OSError:
        pass
    try:
        proc.wait(timeout=2)
    except Exception:  # noqa: BLE001 - busy with a run: ended
        proc.kill()
        proc.wait(timeout=2)
    if proc.stdout is not None:
        proc.stdout.close()
