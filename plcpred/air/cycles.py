"""Machine cycles in a timeline: what "per cycle" and "throughput" mean for the gate and
for sizing.

A cycle is counted at each rising edge (a BOOL) or each increase (a counter) of the
signal the machine file names as ``[machine] cycle_signal``; without one, a machine whose
state repeats (a tiled timeline) has as many cycles in each repeating period as the valve
that switches on least often switches on in it (every drive moves once or more per
cycle; a machine fed faster than it works repeats only after several). The steady
figures come from whole cycles only: air per cycle is the air between the first and the
last cycle boundary divided by the cycles between them, so a start-up sequence or a
horizon that ends mid-cycle does not enter them, and they do not depend on the horizon.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..sequencer.timeline import NS, Timeline


@dataclass
class Cycles:
    source: str                 # 'signal "NAME"' or "repeating state"
    count: int                  # cycle boundaries within the horizon
    cycle_s: float | None       # steady cycle time (None: fewer than two boundaries)
    nl_per_cycle: float | None  # steady air per cycle, NL

    @property
    def per_hour(self) -> float | None:
        return 3600.0 / self.cycle_s if self.cycle_s else None

    def to_dict(self) -> dict:
        return {"source": self.source, "count": self.count, "cycle_s": self.cycle_s,
                "nl_per_cycle": self.nl_per_cycle, "cycles_per_hour": self.per_hour}


def _executed_edges(timeline, signal: str):
    """(times ns, values) of a machine file's signal over the executed part of the run
    (the timeline may know it by another name, recorded in its info)."""
    name = timeline.info.get("machine_signals", {}).get(signal, signal)
    return timeline.executed_edge_times_ns(name)


def _boundaries(t_ns: np.ndarray, v: np.ndarray, before: float) -> np.ndarray:
    """Times at which the signal rises (BOOL) or counts up (a counter), given its
    edges and its value before the first of them."""
    prev = np.concatenate([[before], v[:-1]])
    return t_ns[v > prev] if len(v) else t_ns


def cycles_of(machine, timeline, profile) -> Cycles | None:
    """The cycles of a predicted run (None: no cycle signal and no repeating state)."""
    def nl_between(a_s: float, b_s: float) -> float:
        """Air between two times, exact (the demand before the grid)."""
        a, b = profile.cumulative_nl_at([a_s, b_s])
        return float(b - a)

    horizon_ns = timeline.horizon_ns
    signal = machine.cycle_signal
    if signal:
        t, v = _executed_edges(timeline, signal)
        # the first row is the initial value, not a change
        b = _boundaries(t[1:], v[1:], float(v[0])) if len(v) else t
        source = f'signal "{signal}"'
        if timeline.tiled is None:
            return _steady(source, b / NS, nl_between)
        t1, t2 = timeline.tiled
        period = (b > t1) & (b <= t2)
        per_tile = int(period.sum())
        if per_tile == 0:
            return Cycles(source, len(b), None, None)
        reps = np.floor((horizon_ns - b[period]) / (t2 - t1)).astype(np.int64)
        count = len(b) + int(np.clip(reps, 0, None).sum())
        return _tiled(source, count, timeline, per_tile, nl_between)
    if timeline.tiled is not None:
        t1, t2 = timeline.tiled
        per_tile, valve = _moves_per_period(machine, timeline)
        source = "repeating state" + (f" ({per_tile} per period of valve '{valve}')"
                                      if per_tile > 1 else "")
        return _tiled(source, int((horizon_ns - t1) // (t2 - t1)) * per_tile, timeline,
                      per_tile, nl_between)
    return None


def _moves_per_period(machine, timeline) -> tuple[int, str | None]:
    """Cycles in one repeating period: how often the valve that switches on least often
    (but at least once) does so in it, since each drive of a machine moves at least once
    per cycle (a period of a machine fed faster than it works holds several)."""
    t1, t2 = timeline.tiled
    best = (1, None)
    for c in machine.consumers:
        for v in c.valve:
            t, val = _executed_edges(timeline, v)
            if len(val) < 2:
                continue
            rises = _boundaries(t[1:], val[1:], float(val[0]))
            n = int(((rises > t1) & (rises <= t2)).sum())
            if n and (best[1] is None or n < best[0]):
                best = (n, v)
    return best


def _tiled(source: str, count: int, timeline, per_tile: int, nl_between) -> Cycles:
    """A tiled run's steady cycle: the period holds ``per_tile`` cycles; the air is taken
    over every whole period in the horizon (on a grid, whose cells do not line up with
    the periods, the part-cells at both ends then weigh nothing)."""
    t1, t2 = timeline.tiled
    whole = max(1, int((timeline.horizon_ns - t1) // (t2 - t1)))
    air = nl_between(t1 / NS, (t1 + whole * (t2 - t1)) / NS)
    return Cycles(source, count, (t2 - t1) / NS / per_tile, air / whole / per_tile)


def _steady(source: str, b_s: np.ndarray, nl_between) -> Cycles:
    n = len(b_s)
    if n < 2:
        return Cycles(source, n, None, None)
    return Cycles(source, n, float(b_s[-1] - b_s[0]) / (n - 1),
                  nl_between(float(b_s[0]), float(b_s[-1])) / (n - 1))


def last_switch_s(machine, timeline) -> float | None:
    """When a consumer's valve last switches in the run (None: a repeating run, whose
    valves keep switching to the horizon; 0 when none ever does)."""
    if timeline.tiled is not None:
        return None
    last = 0.0
    for c in machine.consumers:
        for v in c.valve:
            t, _ = _executed_edges(timeline, v)
            if len(t) > 1:          # the first row is the initial value
                last = max(last, float(t[-1]) / NS)
    return last


def arrival_period_s(machine, timeline) -> float | None:
    """A run that does not repeat (jittered arrivals) still cycles with its inputs: the
    longest period of a periodic input schedule, for binning its plots in whole cycles
    (None for a repeating run: its own period is known)."""
    if timeline.tiled is not None:
        return None
    periods = [s.period_s for s in machine.inputs if s.period_s]
    return max(periods) if periods else None


def rest_mask(machine, timeline, profile) -> np.ndarray | None:
    """Grid cells in which the machine's valve outputs are in its *waiting state*
    (:func:`rest_spells_ns`). None when no consumer has a valve. A repeating run is read
    for one period: the time waited up to each grid edge is the start-up's, whole
    periods', and the part of a period's (never every spell to the horizon, which for 10
    years of a fast machine is gigabytes)."""
    pieces = _rest_pieces(machine, timeline)
    if pieces is None:
        return None
    (a0, b0), (a, b), t1, p = pieces
    e_ns = np.asarray(profile.edges_s, dtype=float) * NS
    if p is None:
        waited = _waited(a0, b0, e_ns)
    else:
        waited = _waited(a0, b0, np.minimum(e_ns, t1))
        later = e_ns > t1
        n, r = np.divmod(e_ns[later] - t1, p)
        waited[later] += n * float(np.sum(b - a)) + _waited(a - t1, b - t1, r)
    return np.diff(waited) >= np.diff(e_ns) * (1.0 - 1e-9)


def _waited(a, b, t) -> np.ndarray:
    """Time spent in the spells [a, b) (in order, not overlapping) up to each of ``t``."""
    if len(a) == 0:
        return np.zeros(len(t))
    x = np.column_stack([a, b]).ravel().astype(float)
    c = np.column_stack([np.concatenate([[0.0], np.cumsum(b - a)[:-1]]),
                         np.cumsum(b - a)]).ravel().astype(float)
    return np.interp(t, x, c, left=0.0, right=float(c[-1]))


def _rest_pieces(machine, timeline):
    """((start-up spells), (one period's spells), period start, period) in ns, the period
    None for a run that does not repeat (its spells are then the start-up's, to the
    horizon); None when no consumer has a valve."""
    signals = list(dict.fromkeys(v for c in machine.consumers for v in c.valve))
    if not signals:
        return None
    edges = [_executed_edges(timeline, s) for s in signals]
    t1, t2 = timeline.tiled if timeline.tiled is not None else (0, timeline.horizon_ns)
    times, states = _output_states(edges, t1, t2)
    lasting = np.diff(times) > 0
    waiting = np.logical_and.reduce(states[lasting], axis=0)
    resting = (states == waiting[None, :]).all(axis=1) & lasting
    a, b = times[:-1][resting], times[1:][resting]
    if timeline.tiled is None:
        return (a, b), (a[:0], b[:0]), timeline.horizon_ns, None
    a0 = b0 = a[:0]
    if t1 > 0:
        times0, states0 = _output_states(edges, 0, t1)
        rest0 = (states0 == waiting[None, :]).all(axis=1)
        a0, b0 = times0[:-1][rest0], times0[1:][rest0]
    return (a0, b0), (a, b), t1, t2 - t1


def rest_spells_ns(machine, timeline) -> tuple[np.ndarray, np.ndarray] | None:
    """(starts, ends) in ns, in order, of the spells in which the machine's valve outputs
    are in its *waiting state*: every output off but those that are on throughout (over
    one repeating period of a tiled run, else over the run). A machine waits with
    everything off, or with what its program never switches off (a blower left on is
    then idle air while it waits, and productive blow-off in a cycle is not); a machine
    that never rests (a blow-off line with parts always in it) never waits. None when no
    consumer has a valve."""
    pieces = _rest_pieces(machine, timeline)
    if pieces is None:
        return None
    (a0, b0), (a, b), t1, p = pieces
    if p is not None:
        # the period's spells repeat to the horizon; the start-up has its own
        reps = np.arange(int((timeline.horizon_ns - t1) // p) + 1, dtype=np.int64) * p
        a = np.concatenate([a0, (a[None, :] + reps[:, None]).ravel()])
        b = np.concatenate([b0, (b[None, :] + reps[:, None]).ravel()])
    else:
        a, b = a0, b0
    a = np.clip(a, 0, timeline.horizon_ns)
    b = np.clip(b, 0, timeline.horizon_ns)
    order = np.argsort(a, kind="stable")
    return a[order], b[order]


def blowing_only_in_cycle(machine, timeline) -> Timeline:
    """``timeline`` with every nozzle's valve closed while the machine waits
    (:func:`rest_spells_ns`): the saving measure "blow-off only in cycle" of compressed-air
    audits (a blower's valve interlocked with the cycle). The program is not run again:
    what it reads of those outputs is as before."""
    spells = rest_spells_ns(machine, timeline)
    if spells is None:
        return timeline
    a, b = spells
    names = timeline.info.get("machine_signals", {})
    index = {n.upper(): i for i, n in enumerate(timeline.names)}
    nozzles = {index[names.get(v, v).upper()] for c in machine.consumers
               if c.kind == "nozzle" for v in c.valve if names.get(v, v).upper() in index}
    t, s, v = timeline.time_ns, timeline.signal_idx, timeline.values
    keep = ~np.isin(s, list(nozzles))
    parts_t, parts_s, parts_v = [t[keep]], [s[keep]], [v[keep]]
    for i in sorted(nozzles):
        ti, vi = t[s == i], v[s == i]
        at = np.unique(np.concatenate([ti, a, b, [0]]))
        at = at[at <= timeline.horizon_ns]
        on = _on_at(ti, vi, at)
        j = np.searchsorted(a, at, side="right") - 1
        waiting = (j >= 0) & (at < b[np.clip(j, 0, None)])
        value = (on & ~waiting).astype(float)
        changed = np.concatenate([[True], value[1:] != value[:-1]])
        parts_t.append(at[changed])
        parts_s.append(np.full(int(changed.sum()), i, dtype=np.int32))
        parts_v.append(value[changed])
    t2, s2, v2 = (np.concatenate(x) for x in (parts_t, parts_s, parts_v))
    order = np.argsort(t2, kind="stable")
    info = dict(timeline.info, measure="blow-off only in cycle")
    return Timeline(timeline.signals, t2[order], s2[order], v2[order], timeline.horizon_ns,
                    info, max_changes=timeline.max_changes)


def _output_states(edges, lo: int, hi: int) -> tuple[np.ndarray, np.ndarray]:
    """(times ns, states): the times in [lo, hi] at which any of the signals whose
    ``edges`` are given changes (with lo and hi), and every signal's value (TRUE or not)
    from each of them to the next."""
    times = np.unique(np.concatenate([[lo, hi]] + [t[(t > lo) & (t < hi)] for t, _ in edges]))
    starts = times[:-1]
    states = np.empty((len(starts), len(edges)), dtype=bool)
    for j, (t, v) in enumerate(edges):
        states[:, j] = _on_at(t, v, starts)
    return times, states


def _on_at(t_ns: np.ndarray, v: np.ndarray, at_ns: np.ndarray) -> np.ndarray:
    """Whether a signal with edges (``t_ns``, ``v``) is TRUE (not 0) at each of ``at_ns``
    (FALSE before its first edge)."""
    k = np.searchsorted(t_ns, at_ns, side="right") - 1
    return np.where(k >= 0, v[np.clip(k, 0, None)] != 0, False)
