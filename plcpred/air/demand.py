"""From a timeline to an air-demand profile: the activation/transition model
(docs/reference/physics.md section 2), kept as one rectangle of air per stroke or on-period
and read onto a regular time grid where asked (a repeating machine: one period's
rectangles, repeated).

* **Active consumers** (cylinders, semi-rotary drives, grippers) take their D1 volume on
  each change of their valve's effective command: rising (extend, cap end) or falling
  (retract, rod end) for a monostable valve; only rising for a single-acting cylinder; for
  a bistable valve a rising edge of a solenoid that changes the state (the last pulsed
  solenoid decides; both at once keep the state).
* **Passive consumers** (nozzles, air knives) flow at their D2 rate while their output is
  on; **leaks** always.

Shape of a stroke: nothing flows during the valve's switching delay
(docs/reference/physics.md: dynamic model: flow starts t_sw after the command); then
the volume is spread evenly (a rectangle) over the stroke time in that direction, while
the piston moves. Without a stroke time it is spread over the switching delay from the
edge, and without either it lands at the edge instant. Volumes are placed on the grid by integrating exactly, so each edge's total is
the same whatever the grid (air that would flow after the horizon is not counted).

Grid: cells ``[k dt, (k+1) dt)``; a cell's flow is its volume divided by ``dt`` (also for a
last, partial cell), so summing ``flow * dt`` gives the total exactly. Totals and peaks
come from the rectangles themselves, so they are the same at every ``dt``.

Matrix form (the thesis' formulation, :func:`activation_matrix`): ``A[i, j]`` the effective
state of device i at the end of cell j, ``Z = |A[:, j] - A[:, j-1]|`` split into rising and
falling parts; active air per cell ``Zx^T q_extend + Zr^T q_retract``, passive
``A^T qdot dt``. It equals the exact profile when no cell holds two edges of one device.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..errors import PlcpredError
from ..machine import CYLINDER_KINDS
from ..output import SHOWN_CONSUMERS, csv_column_name
from ..physics.flow import flow_nl_min, orifice_conductance
from ..physics.units import bar_g_to_pa, celsius_to_k
from ..physics.volumes import consumer_stroke_volumes_nl, dead_fill_volumes_nl, swept_volumes_nl
from ..sequencer.timeline import NS

if TYPE_CHECKING:  # pandas is imported where a DataFrame is built
    import pandas as pd


@dataclass
class ConsumerModel:
    """One consumer of the machine file with its air figures worked out."""
    name: str
    kind: str
    valve: list[str]
    role: str                         # "active" | "passive" | "leak"
    extend_nl: float = 0.0            # D1a per extend stroke
    retract_nl: float = 0.0           # D1b per retract stroke
    flow_l_min: float = 0.0           # D2 while on
    pressure_bar_g: float = 0.0
    delay_s: float = 0.0
    stroke_time_s: tuple[float, float] | None = None
    initial_extended: bool = False
    # incomplete exhaust (off unless the machine file gives exhaust_tau_s): the air a
    # chamber's dead volume holds above atmosphere when filled at supply, cap and rod end
    exhaust_tau_s: float | None = None
    dead_fill_nl: tuple[float, float] = (0.0, 0.0)
    # (cap, rod) D1 air of the swept volumes alone and what they hold above atmosphere:
    # what a stroke cut short does not take (partial_strokes)
    swept_nl: tuple[float, float] = (0.0, 0.0)
    swept_held_nl: tuple[float, float] = (0.0, 0.0)
    partial_strokes: bool = False     # option: strokes cut short by the next edge


def consumer_models(machine) -> list[ConsumerModel]:
    """D1 volumes and D2 flows of every consumer at the machine's supply (a nozzle's own
    regulator where it has one), with the supply at ``ambient_c``."""
    t_supply_k = celsius_to_k(machine.ambient_c)
    p_atm_pa = machine.atmosphere_kpa * 1000.0
    out = []
    for c in machine.consumers:
        if c.kind in CYLINDER_KINDS:
            p_pa = bar_g_to_pa(machine.supply_bar_g, machine.atmosphere_kpa)
            # D1a/D1b, times the file's calibration of each fill (air_factor)
            f_ext, f_ret = getattr(c, "air_factor", (1.0, 1.0))
            v_ext, v_ret = consumer_stroke_volumes_nl(c, p_pa, t_supply_k)
            v_ext, v_ret = v_ext * f_ext, v_ret * f_ret
            st = c.stroke_times()
            swept, swept_held = swept_volumes_nl(c, p_pa, p_atm_pa, t_supply_k)
            swept = (swept[0] * f_ext, swept[1] * f_ret)
            out.append(ConsumerModel(c.name, c.kind, list(c.valve), "active", v_ext, v_ret,
                                     pressure_bar_g=machine.supply_bar_g,
                                     delay_s=c.switch_delay_s, stroke_time_s=st,
                                     initial_extended=c.initial == "extended",
                                     exhaust_tau_s=getattr(c, "exhaust_tau_s", None),
                                     dead_fill_nl=dead_fill_volumes_nl(
                                         c, p_pa, p_atm_pa, t_supply_k),
                                     swept_nl=swept, swept_held_nl=swept_held,
                                     partial_strokes=c.partial_strokes))
        else:
            p_bar_g = c.pressure_bar_g if c.pressure_bar_g is not None else machine.supply_bar_g
            q = float(flow_nl_min(sonic_conductance(c), c.b, c.m, c.a, bar_g_to_pa(p_bar_g, machine.atmosphere_kpa),
                                  p_atm_pa, t_supply_k, c.flow_model))
            out.append(ConsumerModel(c.name, c.kind, list(c.valve),
                                     "leak" if c.kind == "leak" else "passive",
                                     flow_l_min=q, pressure_bar_g=p_bar_g))
    return out


def sonic_conductance(consumer) -> float:
    """A nozzle's or leak's C (m^3/(s Pa)): given, or from its orifice and Cd."""
    if consumer.C is not None:
        return consumer.C
    return orifice_conductance(consumer.orifice_mm, consumer.Cd)


# ---------------------------------------------------------------------- edges

_INT64_MAX = int(np.iinfo(np.int64).max)


class DemandError(PlcpredError, ValueError):
    """A timeline the air model cannot turn into a profile."""


def _signal(timeline, name: str, signal_map: dict | None, until_ns=None):
    """Edges of a machine file's signal (up to ``until_ns``): the timeline may know it by
    another name (an address resolved to its variable), recorded in ``timeline.info``."""
    if signal_map is None:
        signal_map = timeline.info.get("machine_signals", {})
    try:
        return timeline.edge_times_ns(signal_map.get(name, name), until_ns)
    except KeyError:
        if timeline.info.get("mode") != "recorded":
            raise                       # the sequencer's own timeline: a bug
        raise DemandError(f"{timeline.info.get('source', 'recorded I/O')}: no rows for "
                          f"the valve '{name}' (read_io_timeline with the machine holds "
                          "valves a trace lacks at their initial value)") from None


def valve_transitions(timeline, model: ConsumerModel, signal_map=None, until_ns=None):
    """(times_ns, extend) of the changes of a valve's effective command (up to
    ``until_ns``): ``extend`` is True for a change to extend. Starts from the cylinder's
    initial position."""
    init = model.initial_extended
    if len(model.valve) == 1:
        t, v = _signal(timeline, model.valve[0], signal_map, until_ns)
        state = v != 0
    else:
        codes_t, codes = [], []
        for sig, code in ((model.valve[0], 1), (model.valve[1], -1)):
            t, v = _signal(timeline, sig, signal_map, until_ns)
            on = v != 0
            rising = on & ~np.concatenate([[False], on[:-1]])
            codes_t.append(t[rising])
            codes.append(np.full(int(rising.sum()), code, dtype=np.int64))
        tt = np.concatenate(codes_t)
        cc = np.concatenate(codes)
        # pulses in the same scan add up: extend + retract = 0 keeps the state
        t, inv = np.unique(tt, return_inverse=True)
        net = np.bincount(inv, weights=cc, minlength=len(t))
        keep = net != 0
        t, state = t[keep], net[keep] > 0
    prev = np.concatenate([[init], state[:-1]]) if len(state) else state
    change = state != prev
    return t[change], state[change]


def passive_intervals(timeline, model: ConsumerModel, signal_map=None, until_ns=None):
    """(start_ns, end_ns) arrays of the periods a passive consumer's output is on (the
    last may end at the horizon; with ``until_ns``, the edges up to then)."""
    t, v = _signal(timeline, model.valve[0], signal_map, until_ns)
    on = v != 0
    prev = np.concatenate([[False], on[:-1]])
    starts = t[on & ~prev]
    ends = t[~on & prev]
    if len(ends) < len(starts):
        # a horizon beyond int64 nanoseconds (292 years: a timeline built by hand; no
        # command runs one) ends the interval as a float
        h = timeline.horizon_ns
        ends = np.concatenate([ends, [h if h <= _INT64_MAX else float(h)]])
    return starts, ends


# ---------------------------------------------------------------------- grid integration

def rectangles_cumulative_nl(points_s, start_s, duration_s, amount):
    """Sum over items of ``amount * clip((x - start) / duration, 0, 1)`` at ``points_s``:
    the cumulative volume of rectangles, exact at any point. A zero duration is a step
    counted from strictly after its start (so it lands in the cell that starts there)."""
    points_s = np.asarray(points_s, dtype=float)
    start_s = np.asarray(start_s, dtype=float)
    duration_s = np.asarray(duration_s, dtype=float)
    amount = np.asarray(amount, dtype=float)
    out = np.zeros(len(points_s))
    step = duration_s <= 0
    if step.any():
        order = np.argsort(start_s[step], kind="stable")
        ts = start_s[step][order]
        cum = np.concatenate([[0.0], np.cumsum(amount[step][order])])
        out += cum[np.searchsorted(ts, points_s, side="left")]
    ramp = ~step
    if ramp.any():
        rate = amount[ramp] / duration_s[ramp]
        bp = np.concatenate([start_s[ramp], start_s[ramp] + duration_s[ramp]])
        dslope = np.concatenate([rate, -rate])
        order = np.argsort(bp, kind="stable")
        bp, dslope = bp[order], dslope[order]
        slope = np.cumsum(dslope)                       # slope just after each breakpoint
        cum_at_bp = np.concatenate([[0.0], np.cumsum(slope[:-1] * np.diff(bp))])
        k = np.searchsorted(bp, points_s, side="right") - 1
        inside = k >= 0
        kk = np.clip(k, 0, None)
        out += np.where(inside, cum_at_bp[kk] + slope[kk] * (points_s - bp[kk]), 0.0)
    return out


def _periodic_cumulative(points_s, template, period_s: float) -> np.ndarray:
    """The cumulative volume at ``points_s`` of ``template`` (rectangles of one period)
    repeated every ``period_s`` without end: whole repetitions counted at once, only the
    few still filling at a point evaluated (a year of 4 s cycles costs no more than one)."""
    start, dur, vol = (np.asarray(x, dtype=float) for x in template)
    points_s = np.asarray(points_s, dtype=float)
    out = np.zeros(len(points_s))
    if not len(start):
        return out
    lo = float(start.min())
    hi = float((start + np.clip(dur, 0.0, None)).max())
    # repetitions j = 0, 1, ...: those with point - j p >= hi are complete
    n_full = np.clip(np.floor((points_s - hi) / period_s) + 1, 0, None)
    j_last = np.floor((points_s - lo) / period_s)
    out += n_full * float(vol.sum())
    for d in range(int(math.ceil((hi - lo) / period_s)) + 2):
        j = n_full + d
        ok = j <= j_last
        if not ok.any():
            break
        out[ok] += rectangles_cumulative_nl(points_s[ok] - j[ok] * period_s, start, dur, vol)
    return out


def residual_fill_nl(t_s, extend, delay_s: float, stroke_time_s, exhaust_tau_s: float,
                     dead_fill_nl) -> np.ndarray:
    """Air a fill does not take because its chamber has not finished exhausting
    (docs/reference/physics.md: what D4 adds, "incomplete exhaust"): a chamber starts exhausting when the
    opposite stroke has ended (its edge + delay + stroke time) and the air its dead volume
    holds above atmosphere decays as ``exp(-t / exhaust_tau_s)``; a fill at ``t`` after
    that start needs ``dead_fill_nl * exp(-t / tau)`` less (the whole of it if the opposite
    stroke has not ended). The first transition fills a chamber that has been empty."""
    t_s = np.asarray(t_s, dtype=float)
    extend = np.asarray(extend, dtype=bool)
    out = np.zeros(len(t_s))
    if len(t_s) < 2 or not exhaust_tau_s or exhaust_tau_s <= 0:
        return out
    st_ext, st_ret = stroke_time_s if stroke_time_s is not None else (0.0, 0.0)
    prev_end = t_s[:-1] + delay_s + np.where(extend[:-1], st_ext, st_ret)
    since = np.clip(t_s[1:] - prev_end, 0.0, None)
    held = np.where(extend[1:], dead_fill_nl[0], dead_fill_nl[1])
    out[1:] = held * np.exp(-since / exhaust_tau_s)
    return out


def stroke_cells(edges_s, t_s, extend, extend_nl: float, retract_nl: float,
                 delay_s: float = 0.0, stroke_time_s=None, exhaust_tau_s=None,
                 dead_fill_nl=(0.0, 0.0), swept_nl=None, swept_held_nl=None,
                 partial_strokes: bool = False) -> np.ndarray:
    """(D1, transition rule) normal litres per grid cell of one drive's strokes: each
    transition's volume spread evenly over its stroke time after its switching delay (see
    the module docstring), less the residual of an incomplete exhaust when
    ``exhaust_tau_s`` is given (:func:`residual_fill_nl`), strokes cut short by the next
    edge taking their share with ``partial_strokes`` (:func:`cut_stroke_volumes_nl`)."""
    return rectangles_cell_nl(edges_s, *stroke_rectangles(
        t_s, extend, extend_nl, retract_nl, delay_s, stroke_time_s, exhaust_tau_s,
        dead_fill_nl, swept_nl, swept_held_nl, partial_strokes))


# a stroke that ends within this of the next edge ends with it: a 0.6 s timer on a 0.6 s
# stroke is not cut, whatever the rounding of edge times summed over many cycles says
CUT_TOLERANCE_S = 1e-6


def stroke_cuts(t_s, extend, delay_s: float, stroke_time_s) -> np.ndarray:
    """Per transition: does the next one come before its stroke has ended (the valve
    reversed while the piston still moves)? Assumes each stroke starts from its end."""
    t_s = np.asarray(t_s, dtype=float)
    st = np.where(np.asarray(extend, dtype=bool), stroke_time_s[0], stroke_time_s[1])
    cut = np.zeros(len(t_s), bool)
    cut[:-1] = t_s[1:] < t_s[:-1] + st[:-1] - CUT_TOLERANCE_S
    return cut


def cut_stroke_volumes_nl(t_s, extend, extend_nl: float, retract_nl: float, delay_s: float,
                          stroke_time_s, exhaust_tau_s: float, dead_fill_nl, swept_nl,
                          swept_held_nl):
    """(NL, duration s) of each transition when strokes may be cut short (the
    ``partial_strokes`` option, docs/reference/physics.md: "strokes cut short"): the piston moves at
    its stroke's mean speed from a switching delay after the edge until its end stop or
    the next transition. A fill takes D1's dead-volume air plus the swept air of the share
    of the chamber the piston opened, less what the chamber still held: its dead volume's
    air and the air of the swept share the opposite (cut) stroke left in it, decaying as
    ``exp(-t / exhaust_tau_s)`` from the end of the opposite stroke's motion (nothing
    without ``exhaust_tau_s``: exhausts complete at once). With every stroke complete this
    is D1 less :func:`residual_fill_nl`. The loop runs per edge (each position depends on
    the last); only drives with a cut stroke take it."""
    n = len(t_s)
    times = np.asarray(t_s, dtype=float).tolist()       # Python floats: faster per item
    exts = np.asarray(extend, dtype=bool).tolist()
    d1 = (float(extend_nl), float(retract_nl))
    swept = (float(swept_nl[0]), float(swept_nl[1]))
    swept_held = (float(swept_held_nl[0]), float(swept_held_nl[1]))
    dead_held = (float(dead_fill_nl[0]), float(dead_fill_nl[1]))
    strokes = (float(stroke_time_s[0]), float(stroke_time_s[1]))
    vol = [0.0] * n
    dur = [0.0] * n
    y = 0.0 if (n and exts[0]) else 1.0            # share extended: starts at an end
    prev_end = -math.inf                           # the previous motion's end
    for i in range(n):
        e = 0 if exts[i] else 1
        start = times[i] + delay_s
        stroke_s = strokes[e]
        to_go = (1.0 - y) if e == 0 else y
        end = start + stroke_s * to_go
        if i + 1 < n:
            end = min(end, times[i + 1] + delay_s)
        moved = max(min(to_go, (end - start) / stroke_s) if stroke_s > 0 else to_go, 0.0)
        open_before = y if e == 0 else 1.0 - y     # the filled chamber's swept share
        y = y + moved if e == 0 else y - moved
        open_after = y if e == 0 else 1.0 - y
        held = 0.0
        if i > 0 and exhaust_tau_s:
            since = max(0.0, times[i] - prev_end)
            held = (dead_held[e] + swept_held[e] * open_before) * math.exp(
                -since / exhaust_tau_s)
        vol[i] = max(d1[e] - swept[e] * (1.0 - open_after) - held, 0.0)
        dur[i] = max(end - start, 0.0)
        prev_end = max(end, start)
    return np.array(vol), np.array(dur)


def stroke_rectangles(t_s, extend, extend_nl: float, retract_nl: float,
                      delay_s: float = 0.0, stroke_time_s=None, exhaust_tau_s=None,
                      dead_fill_nl=(0.0, 0.0), swept_nl=None, swept_held_nl=None,
                      partial_strokes: bool = False):
    """(D1, transition rule) each transition's (start s, duration s, NL): the air of
    :func:`stroke_cells` before it meets a grid (a duration of 0 is a step)."""
    t_s = np.asarray(t_s, dtype=float)
    extend = np.asarray(extend, dtype=bool)
    if (partial_strokes and stroke_time_s is not None and swept_nl is not None
            and stroke_cuts(t_s, extend, delay_s, stroke_time_s).any()):
        vol, dur = cut_stroke_volumes_nl(
            t_s, extend, extend_nl, retract_nl, delay_s, stroke_time_s, exhaust_tau_s,
            dead_fill_nl, swept_nl, swept_held_nl if swept_held_nl is not None else
            (0.0, 0.0))
        return t_s + delay_s, dur, vol
    vol = np.where(extend, extend_nl, retract_nl)
    if exhaust_tau_s:
        vol = np.clip(vol - residual_fill_nl(t_s, extend, delay_s, stroke_time_s,
                                             exhaust_tau_s, dead_fill_nl), 0.0, None)
    if stroke_time_s is not None:
        # the valve opens a switching delay after the edge; the chamber fills while the
        # piston moves (docs/reference/physics.md: dynamic model: flow starts t_sw after the command)
        start = t_s + delay_s
        dur = np.where(extend, stroke_time_s[0], stroke_time_s[1])
    else:
        start = t_s
        dur = np.full(len(t_s), float(delay_s))
    return start, dur, vol


def interval_cells(edges_s, starts_s, ends_s, flow_l_min: float) -> np.ndarray:
    """(D2 while on) normal litres per grid cell of a consumer flowing ``flow_l_min``
    over the given periods."""
    return rectangles_cell_nl(edges_s, *interval_rectangles(starts_s, ends_s, flow_l_min))


def interval_rectangles(starts_s, ends_s, flow_l_min: float):
    """(D2 while on) each period's (start s, duration s, NL)."""
    starts_s = np.asarray(starts_s, dtype=float)
    dur = np.asarray(ends_s, dtype=float) - starts_s
    return starts_s, dur, flow_l_min / 60.0 * dur


def rectangles_cell_nl(edges_s, start_s, duration_s, amount) -> np.ndarray:
    """The volume of each grid cell under the same rectangles (and steps) as
    :func:`rectangles_cumulative_nl`, i.e.
    ``np.diff(rectangles_cumulative_nl(edges_s, ...))``, in time linear in cells plus items: each rectangle's rate is switched on and off at its two
    breakpoints, a cell takes the rate in force over its whole width plus the part of
    each breakpoint inside it."""
    edges_s = np.asarray(edges_s, dtype=float)
    start_s = np.asarray(start_s, dtype=float)
    duration_s = np.asarray(duration_s, dtype=float)
    amount = np.asarray(amount, dtype=float)
    n = len(edges_s) - 1
    out = np.zeros(n)
    step = duration_s <= 0
    if step.any():
        k = np.searchsorted(edges_s, start_s[step], side="right") - 1
        ok = (k >= 0) & (k < n)
        out += np.bincount(k[ok], weights=amount[step][ok], minlength=n)
    ramp = ~step
    if ramp.any():
        rate = amount[ramp] / duration_s[ramp]
        bp = np.concatenate([start_s[ramp], start_s[ramp] + duration_s[ramp]])
        change = np.concatenate([rate, -rate])
        k = np.searchsorted(edges_s, bp, side="right") - 1
        inside = (k >= 0) & (k < n)
        before = k < 0                      # in force from the first cell on
        # (astype: bincount of nothing is an integer array, which would drop the rate)
        full = np.bincount(k[inside] + 1, weights=change[inside],
                           minlength=n + 1).astype(float)
        full[0] += change[before].sum()
        rate_full = np.cumsum(full)[:n]
        part = np.bincount(k[inside], weights=change[inside] * (
            edges_s[k[inside] + 1] - bp[inside]), minlength=n)
        out += rate_full * np.diff(edges_s) + part
    return out


def grid_edges_s(horizon_s: float, dt_s: float) -> np.ndarray:
    n = max(1, int(math.ceil(horizon_s / dt_s - 1e-9)))
    edges = np.arange(n + 1, dtype=float) * dt_s
    edges[-1] = min(edges[-1], horizon_s)
    return edges


# ---------------------------------------------------------------------- exact peaks

@dataclass
class DemandSteps:
    """The total demand as the model has it before any grid: a piecewise-constant rate
    (the strokes' and nozzles' rectangles) plus steps (strokes with no duration), as
    breakpoint times, the rate after each (NL/s) and the cumulative NL at each
    (right-continuous). Peaks from it do not depend on the output grid."""
    times_s: np.ndarray
    rate_nl_s: np.ndarray
    cum_nl: np.ndarray
    horizon_s: float
    n_steps: int = 0          # strokes with no duration (no rate: left out of peaks)
    start_s: float = 0.0      # the stretch [start_s, horizon_s] it covers (the air before
    #                           start_s is not in cum_nl: a block of a longer run)

    @classmethod
    def of(cls, rects, horizon_s: float, start_s: float = 0.0) -> "DemandSteps":
        # written to hold few arrays of all breakpoints at once: a week of a fast machine
        # has millions of them
        start = np.concatenate([r[0] for r in rects]) if rects else np.zeros(0)
        dur = np.concatenate([r[1] for r in rects]) if rects else np.zeros(0)
        vol = np.concatenate([r[2] for r in rects]) if rects else np.zeros(0)
        ramp = dur > 0
        n_ramp, n_step = int(ramp.sum()), int((~ramp).sum())
        rate = vol[ramp] / dur[ramp]
        t = np.concatenate([start[ramp], start[ramp] + dur[ramp], start[~ramp]])
        d_rate = np.concatenate([rate, -rate, np.zeros(n_step)])
        jump = np.concatenate([np.zeros(2 * n_ramp), vol[~ramp]]) if n_step else None
        del start, dur, vol, rate, ramp
        order = np.argsort(t, kind="stable")
        t = t[order]
        d_rate = d_rate[order]
        if jump is not None:
            jump = jump[order]
        del order
        if not len(t):
            return cls(t, t, t, float(horizon_s), n_step, float(start_s))
        # one breakpoint per distinct time (t is sorted)
        first = np.flatnonzero(np.concatenate([[True], t[1:] != t[:-1]]))
        times = t[first]
        del t
        rate_after = np.cumsum(d_rate)[np.r_[first[1:], len(d_rate)] - 1]
        del d_rate
        jumps = np.add.reduceat(jump, first) if jump is not None else 0.0
        gaps = np.diff(times, prepend=times[:1])
        rate_before = np.concatenate([[0.0], rate_after[:-1]])
        cum = np.cumsum(rate_before * gaps + jumps)
        return cls(times, np.clip(rate_after, 0.0, None), cum, float(horizon_s), n_step,
                   float(start_s))

    def cumulative_nl(self, at_s) -> np.ndarray:
        """NL used by each time (steps at a time counted in)."""
        at_s = np.asarray(at_s, dtype=float)
        k = np.searchsorted(self.times_s, at_s, side="right") - 1
        kk = np.clip(k, 0, None)
        if not len(self.times_s):
            return np.zeros_like(at_s)
        return np.where(k >= 0, self.cum_nl[kk] + self.rate_nl_s[kk]
                        * (at_s - self.times_s[kk]), 0.0)

    def peak_l_min(self, window_s: float | None = None) -> float:
        """The highest instantaneous demand (steps left out: they have no rate), or the
        highest mean over any window of ``window_s`` within ``[start_s, horizon_s]`` (a
        window's mean is largest with one of its ends on a breakpoint)."""
        # the breakpoints before the horizon: a prefix (times are sorted), taken as a
        # view, not a copy (a week of a machine that never repeats has millions)
        inside = int(np.searchsorted(self.times_s, self.horizon_s, side="left"))
        if not window_s:
            return float(self.rate_nl_s[:inside].max(initial=0.0)) * 60.0
        w = min(float(window_s), self.horizon_s)
        first_end = self.start_s + w
        b = self.times_s[:inside]
        best = 0.0
        for a in range(0, len(b) + 1, 250_000):         # in blocks: bounded memory
            part = b[a:a + 250_000]
            ends = np.concatenate([part, part + w]
                                  + ([[first_end, self.horizon_s]] if not a else []))
            ends = ends[(ends >= first_end - 1e-12) & (ends <= self.horizon_s + 1e-12)]
            gain = self.cumulative_nl(ends) - self.cumulative_nl(ends - w)
            best = max(best, float(gain.max(initial=0.0)))
        return best / w * 60.0


# ---------------------------------------------------------------------- the profile


# rectangles merged at once for the peaks (about 150 bytes each while merged)
PEAK_BLOCK_RECTS = 200_000


def shows_every_consumer(n_consumers: int, shown: int | None) -> bool:
    """Whether the outputs show each of ``n_consumers`` one by one: ``shown`` is None
    (all), or there are at most ``shown + 1`` (an "other" of one would hide a name)."""
    return shown is None or n_consumers <= shown + 1


class _Series:
    """The rectangles of one or more consumers merged and sorted by start, so that the
    volumes of any stretch of the grid need only the rectangles that reach into it."""

    def __init__(self, rects):
        if len(rects) == 1:
            start, dur, vol = (np.asarray(x, dtype=float) for x in rects[0])
        else:
            start, dur, vol = (np.concatenate([np.asarray(r[k], dtype=float) for r in rects])
                               if rects else np.zeros(0) for k in range(3))
        if len(start) > 1 and not np.all(start[1:] >= start[:-1]):
            order = np.argsort(start, kind="stable")
            start, dur, vol = start[order], dur[order], vol[order]
        # one consumer's rectangles come sorted and are used as they are (no copy)
        self.start_s, self.duration_s, self.nl = start, dur, vol
        # the latest end so far: every item before the first with reach >= t ends before t
        self.reach_s = np.maximum.accumulate(start + np.clip(dur, 0, None)) \
            if len(start) else start

    @property
    def rects(self) -> tuple:
        """(start_s, duration_s, nl) of all the rectangles."""
        return self.start_s, self.duration_s, self.nl

    def clipped(self, lo_s: float, hi_s: float) -> tuple:
        """(start_s, duration_s, nl) of the air that flows within ``[lo_s, hi_s]``: the
        rectangles cut at both ends (their volume in proportion, the rate unchanged)
        and the steps at times within it."""
        start, dur, nl = self.reaching(lo_s, hi_s)
        a = np.maximum(start, lo_s)
        cut = np.minimum(start + dur, hi_s) - a
        ramp = dur > 0
        keep = np.where(ramp, cut > 0, start >= lo_s)
        share = np.divide(cut, dur, out=np.ones_like(cut), where=ramp)
        return a[keep], np.where(ramp, cut, 0.0)[keep], (nl * share)[keep]

    def reaching(self, lo_s: float, hi_s: float) -> tuple:
        """(start_s, duration_s, nl) of the rectangles that reach into ``[lo_s, hi_s]``
        (views: a stretch of the sorted arrays)."""
        lo = int(np.searchsorted(self.reach_s, lo_s, side="left"))
        hi = int(np.searchsorted(self.start_s, hi_s, side="right"))
        return self.start_s[lo:hi], self.duration_s[lo:hi], self.nl[lo:hi]

    def cells_nl(self, edges_s) -> np.ndarray:
        """Normal litres in each cell of ``edges_s`` (any stretch of any grid)."""
        return _cells_in_pieces(edges_s, [self])


class _Group:
    """Several consumers read together without merging their rectangles: each member's
    own sorted rectangles are cut to the stretch asked for, so that the memory follows
    the stretch, not the run (the "other" of a wide machine over a day that never
    repeats is millions of rectangles)."""

    def __init__(self, members: list[_Series]):
        self.members = members

    def cells_nl(self, edges_s) -> np.ndarray:
        """Normal litres in each cell of ``edges_s`` (any stretch of any grid)."""
        return _cells_in_pieces(edges_s, self.members)


# rectangles placed on a grid at once (about 100 bytes each while placed)
CELL_ITEMS = 250_000


def _cells_in_pieces(edges_s, members: list) -> np.ndarray:
    """The cells of ``edges_s`` under the rectangles of ``members`` (series) together,
    worked out in pieces of the grid that each hold at most about ``CELL_ITEMS``
    rectangles (a cell's air depends only on the rectangles that reach into it)."""
    edges_s = np.asarray(edges_s, dtype=float)

    def volumes(e):
        parts = [m.reaching(e[0], e[-1]) for m in members]
        if not parts:
            return np.zeros(len(e) - 1)
        if len(parts) == 1:
            return rectangles_cell_nl(e, *parts[0])
        return rectangles_cell_nl(e, *(np.concatenate([p[k] for p in parts]) for k in range(3)))

    n_cells = len(edges_s) - 1
    items = sum(len(m.reaching(edges_s[0], edges_s[-1])[0]) for m in members)
    pieces = min(n_cells, -(-items // CELL_ITEMS))
    if pieces <= 1:
        return volumes(edges_s)
    cuts = np.linspace(0, n_cells, pieces + 1).astype(int)
    return np.concatenate([volumes(edges_s[a:b + 1]) for a, b in zip(cuts[:-1], cuts[1:])])


@dataclass
class DemandProfile:
    """Air demand of each consumer, kept as the model has it (per consumer, each stroke's
    or on-period's rectangle: start, duration, NL) and read on a regular grid of ``dt_s``
    only where asked: per-consumer totals are exact sums of the rectangles, the total
    flow is one pass over all of them, and per-consumer cells are worked out stretch by
    stretch (``demand.csv``) or on a coarser grid (the plot), so memory grows with the
    number of strokes and cells, not with consumers x cells."""
    names: list[str]
    roles: list[str]
    rects: list                         # per consumer: (start_s, duration_s, nl) arrays
    dt_s: float
    horizon_s: float
    strokes: dict = field(default_factory=dict)   # name -> (extend, retract) counts
    # name -> strokes the next edge cut short (drives with stroke times; D1 books them in
    # full unless the drive has partial_strokes)
    cut_strokes: dict = field(default_factory=dict)
    models: list = field(default_factory=list)
    # a machine that repeats: per consumer the rectangles of one period (those whose
    # edge lies in (t2, t2 + period]), repeated every period_s up to the horizon on top
    # of ``rects`` (the edges up to t2); the profile then costs one period at any horizon
    templates: list | None = None
    period_s: float | None = None

    @property
    def steps(self) -> DemandSteps:
        """The exact total demand over the whole horizon (breakpoints, rates,
        cumulative). For a repeating machine this holds every repetition: the profile's
        own peaks need a few (:meth:`peak_l_min`)."""
        return DemandSteps.of(self._rects_over(self.horizon_s), self.horizon_s)

    @property
    def has_steps(self) -> bool:
        """Whether some stroke has no duration (a volume without a rate, which the
        instantaneous peak leaves out)."""
        return any(r is not None and bool(np.any(np.asarray(r[1]) <= 0))
                   for r in list(self.rects) + list(self.templates or ()))

    def _cover_s(self, window_s: float) -> float:
        """The end of a stretch from 0 that holds every distinct window of ``window_s``
        (the whole horizon unless the machine repeats)."""
        if self.templates is None:
            return self.horizon_s
        # the demand repeats from t1 = (the last base stroke's end, the template's end
        # less a period) on, so every window of window_s has an equal one that starts
        # within [t1, t1 + period)
        p = self.period_s
        # a base rectangle that lasts to the horizon (a leak, an output left on) is a
        # constant rate from its start on
        ends = []
        for r in self.rects:
            if len(r[0]):
                end = r[0] + np.clip(r[1], 0, None)
                ends.append(float(np.max(np.where(end >= self.horizon_s, r[0], end))))
        hi = max([float((tm[0] + np.clip(tm[1], 0, None)).max())
                  for tm in self.templates if tm is not None and len(tm[0])] + [0.0])
        t1 = max(ends + [hi - p, 0.0])
        return min(self.horizon_s, t1 + p + float(window_s or 0.0))

    def _rects_over(self, cover_s: float) -> list:
        """Per consumer, the rectangles up to ``cover_s`` (a repeating machine's
        repetitions up to then) as (start_s, duration_s, nl) sorted by start."""
        rects = list(self.rects)
        p = self.period_s
        for i, tm in enumerate(self.templates or ()):
            if tm is not None and len(tm[0]):
                k = np.arange(int(max(0.0, (cover_s - tm[0].min()) // p)) + 1) * p
                reps = _Series([((tm[0][None, :] + k[:, None]).ravel(),
                                 np.tile(tm[1], len(k)), np.tile(tm[2], len(k)))])
                rects[i] = _Series([rects[i], reps.rects]).rects
        return rects

    @functools.cached_property
    def edges_s(self) -> np.ndarray:
        return grid_edges_s(self.horizon_s, self.dt_s)

    @property
    def n_cells(self) -> int:
        return len(self.edges_s) - 1

    @property
    def time_s(self) -> np.ndarray:
        """Start of each cell."""
        return self.edges_s[:-1]

    def series(self, which) -> _Series:
        """The merged rectangles of the consumers at indices ``which``."""
        return _Series([self.rects[i] for i in which])

    def cumulative_nl_at(self, at_s, which=None) -> np.ndarray:
        """Normal litres the consumers at indices ``which`` (default all) have used by
        each time, exact (air that would flow after the horizon is not counted)."""
        return self._cumulative_of(range(len(self.names)) if which is None else which)(at_s)

    def _cumulative_of(self, which):
        """A function of times giving the cumulative normal litres of the consumers at
        indices ``which``, their rectangles (and templates) merged once."""
        base = self.series(which)
        tmpl = [self.templates[i] for i in which if self.templates is not None
                and self.templates[i] is not None]
        template = _Series(tmpl) if tmpl else None

        def cumulative(at_s):
            at_s = np.minimum(np.asarray(at_s, dtype=float), self.horizon_s)
            flat = at_s.ravel()
            out = rectangles_cumulative_nl(flat, *base.rects)
            if template is not None:
                out += _periodic_cumulative(flat, template.rects, self.period_s)
            return out.reshape(at_s.shape)
        return cumulative

    def _member(self, i: int) -> _Series:
        """Consumer ``i``'s rectangles as a series (made once)."""
        members = self.__dict__.setdefault("_members", {})
        if i not in members:
            members[i] = _Series([self.rects[i]])
        return members[i]

    def cells_of(self, which):
        """A function of grid edges giving the normal litres per cell of the consumers at
        indices ``which`` (each consumer's rectangles cut to the stretch asked for)."""
        if self.templates is None:
            which = list(which)
            if len(which) == 1:
                return self._member(which[0]).cells_nl
            return _Group([self._member(i) for i in which]).cells_nl
        cumulative = self._cumulative_of(which)
        return lambda edges_s: np.diff(cumulative(edges_s))

    def cells_nl(self, which=None, edges_s=None) -> np.ndarray:
        """Normal litres per cell of the consumers at indices ``which`` together (default
        all) on ``edges_s`` (default the profile's grid)."""
        which = range(len(self.names)) if which is None else which
        return self.cells_of(which)(self.edges_s if edges_s is None else edges_s)

    @functools.cached_property
    def total_cell_nl(self) -> np.ndarray:
        """Normal litres per cell, all consumers."""
        return self.cells_nl()

    @functools.cached_property
    def cell_nl(self) -> np.ndarray:
        """Per-consumer normal litres per cell (consumers x cells): dense, for studies of a
        few consumers; the outputs never build it."""
        out = np.zeros((len(self.names), self.n_cells))
        for i in range(len(self.names)):
            out[i] = self.cells_nl([i])
        return out

    @property
    def flow_l_min(self) -> np.ndarray:
        """Per-consumer mean flow in each cell, NL/min (consumers x cells, dense)."""
        return self.cell_nl / self.dt_s * 60.0

    @property
    def total_flow_l_min(self) -> np.ndarray:
        return self.total_cell_nl / self.dt_s * 60.0

    @functools.cached_property
    def consumer_nl(self) -> np.ndarray:
        """Per-consumer totals over the horizon, from the rectangles (the same at every
        ``dt``)."""
        return np.array([float(self.cumulative_nl_at([self.horizon_s], [i])[0])
                         for i in range(len(self.names))], dtype=float)

    @property
    def active_nl(self) -> np.ndarray:
        return np.where(np.array(self.roles) == "active", self.consumer_nl, 0.0)

    @property
    def passive_nl(self) -> np.ndarray:
        return np.where(np.array(self.roles) == "active", 0.0, self.consumer_nl)

    @property
    def total_nl(self) -> float:
        return float(self.consumer_nl.sum())

    @property
    def mean_l_min(self) -> float:
        return self.total_nl / self.horizon_s * 60.0

    def peak_l_min(self, window_s: float | None = None,
                   block_rects: int = PEAK_BLOCK_RECTS) -> float:
        """The highest instantaneous demand, or the highest mean over any window of
        ``window_s``: exact (:class:`DemandSteps`, the same at every ``dt``).

        Worked out in blocks of time holding about ``block_rects`` rectangles, each
        block reaching ``window_s`` into the next so that every window lies wholly in
        one: a week of a machine that never repeats has millions of breakpoints, and
        all of them merged at once would take more memory than the run itself."""
        cache = self.__dict__.setdefault("_peak_cache", {})
        key = (float(window_s or 0.0), block_rects)
        if key not in cache:
            cover = self._cover_s(window_s or 0.0)
            # a run that does not repeat: the consumers' own series, as the grid reads them
            series = [self._member(i) for i, r in enumerate(self.rects) if len(r[0])] \
                if self.templates is None else \
                [_Series([r]) for r in self._rects_over(cover) if len(r[0])]
            n = sum(len(x.start_s) for x in series)
            bounds = np.linspace(0.0, cover, max(1, -(-n // max(1, block_rects))) + 1)
            w = min(float(window_s), cover) if window_s else 0.0
            best = 0.0
            for lo, nxt in zip(bounds[:-1], bounds[1:]):
                hi = cover if nxt >= bounds[-1] else min(cover, float(nxt) + w)
                if window_s and float(lo) + w > hi:
                    continue
                block = DemandSteps.of([x.clipped(float(lo), hi) for x in series], hi,
                                       start_s=float(lo))
                best = max(best, block.peak_l_min(w if window_s else None))
            cache[key] = best
        return cache[key]

    def grid_peak_l_min(self, window_s: float | None = None) -> float:
        """The highest total flow of a grid cell, or mean over ``window_s`` in whole
        cells (what a plot of the grid shows)."""
        return float(np.max(self.moving_average_l_min(window_s))) if window_s else float(
            np.max(self.total_flow_l_min))

    def moving_average_l_min(self, window_s: float) -> np.ndarray:
        """Total flow averaged over the trailing ``window_s`` (whole cells; windows that
        would start before 0 are left out)."""
        k = max(1, int(round(window_s / self.dt_s)))
        total = self.total_cell_nl
        if k >= len(total):
            return np.array([total.sum() / (len(total) * self.dt_s) * 60.0])
        c = np.concatenate([[0.0], np.cumsum(total)])
        return (c[k:] - c[:-k]) / (k * self.dt_s) * 60.0

    def cumulative_nl(self) -> np.ndarray:
        """Normal litres used by the end of each cell."""
        return np.cumsum(self.total_cell_nl)

    def consumer_nl_within(self, cell_mask) -> np.ndarray:
        """Per-consumer normal litres in the cells where ``cell_mask`` is true."""
        mask = np.asarray(cell_mask, dtype=bool)
        d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
        starts = self.edges_s[np.flatnonzero(d == 1)]
        stops = self.edges_s[np.flatnonzero(d == -1)]
        out = np.zeros(len(self.names))
        if not len(starts):
            return out
        for i in range(len(self.names)):
            cum = self.cumulative_nl_at(np.concatenate([starts, stops]), [i])
            out[i] = float(np.sum(cum[len(starts):] - cum[:len(starts)]))
        return out

    def by_role_nl(self) -> dict:
        out = {"active": 0.0, "passive": 0.0, "leak": 0.0}
        for role, v in zip(self.roles, self.consumer_nl):
            out[role] += float(v)
        return out

    def groups(self, shown: int | None = SHOWN_CONSUMERS) -> list[tuple[str, list[int]]]:
        """(label, consumer indices) of what the outputs show one by one: every consumer
        in machine-file order when there are at most ``shown + 1`` (or ``shown`` is None),
        else the ``shown`` largest users in machine-file order and "other" for the rest
        (the only group of more than one)."""
        n = len(self.names)
        if shows_every_consumer(n, shown):
            return [(name, [i]) for i, name in enumerate(self.names)]
        top = sorted(np.argsort(-self.consumer_nl, kind="stable")[:shown].tolist())
        rest = sorted(set(range(n)) - set(top))
        return [(self.names[i], [i]) for i in top] + [(f"other ({len(rest)})", rest)]

    def to_frame(self, consumers: bool = True) -> pd.DataFrame:
        """The demand on the profile's grid as a pandas DataFrame: indexed by ``time_s``
        (the start of each cell of ``dt_s``), a ``total_l_min`` column and, unless
        ``consumers`` is false, one ``<consumer>_l_min`` column per consumer in
        machine-file order, named as in ``demand.csv`` (letters, digits and ``_-.``,
        anything else ``_``); each is the mean flow in NL/min over the cell. Every
        consumer's column is dense (consumers x cells floats): for a long horizon on a
        fine grid, predict with a coarser ``dt`` or ask for the total alone."""
        # pandas is imported here: it is heavy (half a second), and most runs never need it
        import pandas as pd

        data = {"total_l_min": self.total_flow_l_min}
        if consumers:
            flows = self.flow_l_min
            for i, name in enumerate(self.names):
                column = csv_column_name(name) + "_l_min"
                while column in data:                   # two names the same once cleaned
                    column = column[:-len("_l_min")] + "_" + "_l_min"
                data[column] = flows[i]
        return pd.DataFrame(data, index=pd.Index(self.time_s, name="time_s"))

    # ------------------------------------------------------------------ files
    def summary(self) -> dict:
        consumers = {}
        active, passive = self.active_nl, self.passive_nl
        for i, (name, role) in enumerate(zip(self.names, self.roles)):
            entry = {"total_nl": float(self.consumer_nl[i]),
                     "active_nl": float(active[i]),
                     "passive_nl": float(passive[i]), "role": role}
            m = self.models[i] if i < len(self.models) else None
            if m is not None:
                entry["kind"] = m.kind
            if name in self.strokes:
                entry["strokes"] = {"extend": int(self.strokes[name][0]),
                                    "retract": int(self.strokes[name][1])}
            if m is not None and role == "active":
                entry["extend_nl_per_stroke"] = m.extend_nl
                entry["retract_nl_per_stroke"] = m.retract_nl
            elif m is not None:
                entry["flow_l_min_while_on"] = m.flow_l_min
            consumers[name] = entry
        split = self.by_role_nl()
        return {"total_nl": self.total_nl, "mean_l_min": self.mean_l_min,
                "peak_l_min": self.peak_l_min(), "peak_1s_l_min": self.peak_l_min(1.0),
                "horizon_s": self.horizon_s, "dt_s": self.dt_s,
                "active_nl": split["active"], "passive_nl": split["passive"],
                "leak_nl": split["leak"], "consumers": consumers}


def demand_profile(timeline, models: list[ConsumerModel], dt_s: float = 0.01,
                   signal_map=None) -> DemandProfile:
    """Every consumer's air as rectangles (see the module docstring), read on a grid of
    ``dt_s``. A timeline that repeats (tiled) is read up to two periods past its first
    repetition: the rectangles of the edges up to t2 and one period's template, which
    the profile repeats to the horizon (so ten years cost what two periods do)."""
    if dt_s <= 0:
        raise ValueError("dt must be positive")
    horizon_ns = timeline.horizon_ns
    horizon_s = horizon_ns / NS
    until_ns = t2 = p = None
    if timeline.tiled is not None:
        t1, t2 = timeline.tiled
        p = t2 - t1
        if horizon_ns > t2 + 2 * p:
            until_ns = t2 + 2 * p
    strokes, cut_strokes, rects, templates = {}, {}, [], []

    def split(origin_ns, rect):
        """(base, template, repetitions of each template item within the horizon)."""
        base = origin_ns <= t2
        tmpl = (origin_ns > t2) & (origin_ns <= t2 + p)
        # (horizon - origin) // p + 1 in exact integers: the horizon may lie beyond what
        # int64 nanoseconds hold (292 years), an item's offset in its period never does
        whole, rest = divmod(horizon_ns - t2, p)
        if whole > _INT64_MAX // 4:
            raise DemandError(f"a horizon of {horizon_s:.3g} s repeats the machine's "
                              f"{p / NS:g} s cycle more often than the air model counts "
                              "(plcpred runs 10 years at most)")
        reps = whole + 1 - (origin_ns[tmpl] - t2 > rest).astype(np.int64)
        return (tuple(np.asarray(x)[base] for x in rect),
                tuple(np.asarray(x)[tmpl] for x in rect), base, tmpl, reps)

    for m in models:
        template = None
        if m.role == "active":
            t_ns, ext = valve_transitions(timeline, m, signal_map, until_ns)
            rect = stroke_rectangles(t_ns / NS, ext, m.extend_nl, m.retract_nl, m.delay_s,
                                     m.stroke_time_s, m.exhaust_tau_s, m.dead_fill_nl,
                                     m.swept_nl, m.swept_held_nl, m.partial_strokes)
            cut = (stroke_cuts(t_ns / NS, ext, m.delay_s, m.stroke_time_s)
                   if m.stroke_time_s else np.zeros(len(t_ns), bool))
            if until_ns is None:
                strokes[m.name] = (int(ext.sum()), int((~ext).sum()))
                cut_strokes[m.name] = int(cut.sum())
            else:
                rect, template, base, tmpl, reps = split(t_ns, rect)
                e = ext[tmpl]
                strokes[m.name] = (int(ext[base].sum() + reps[e].sum()),
                                   int((~ext[base]).sum() + reps[~e].sum()))
                cut_strokes[m.name] = int(cut[base].sum() + reps[cut[tmpl]].sum())
        elif m.role == "leak":
            rect = interval_rectangles(np.array([0.0]), np.array([horizon_s]), m.flow_l_min)
        else:
            # an output still on at the end of the edges read is on to the horizon
            s_ns, e_ns = passive_intervals(timeline, m, signal_map, until_ns)
            rect = interval_rectangles(s_ns / NS, e_ns / NS, m.flow_l_min)
            if until_ns is not None:
                rect, template, *_ = split(s_ns, rect)
        rects.append(rect)
        templates.append(template)
    periodic = until_ns is not None
    return DemandProfile([m.name for m in models], [m.role for m in models], rects, dt_s,
                         horizon_s, strokes, cut_strokes, list(models),
                         templates if periodic else None, p / NS if periodic else None)


def activation_matrix(timeline, models: list[ConsumerModel], dt_s: float, signal_map=None):
    """(A, Zx, Zr): effective states at the end of each cell (devices x cells) and their
    rising and falling transitions (see the module docstring)."""
    horizon_s = timeline.horizon_ns / NS
    edges = grid_edges_s(horizon_s, dt_s)
    ends_ns = np.round(edges[1:] * NS).astype(np.int64)
    A = np.zeros((len(models), len(ends_ns)))
    A0 = np.zeros(len(models))
    for i, m in enumerate(models):
        if m.role == "leak":
            A[i] = 1.0
            A0[i] = 1.0
            continue
        if m.role == "active":
            t, ext = valve_transitions(timeline, m, signal_map)
            states = np.concatenate([[m.initial_extended], ext]).astype(float)
            A0[i] = float(m.initial_extended)
        else:
            t, v = _signal(timeline, m.valve[0], signal_map)
            states = np.concatenate([[0.0], (v != 0).astype(float)])
        k = np.searchsorted(t, ends_ns, side="left")   # edges strictly before the cell end
        A[i] = states[k]
    prev = np.concatenate([A0[:, None], A[:, :-1]], axis=1)
    Zx = np.clip(A - prev, 0, None)
    Zr = np.clip(prev - A, 0, None)
    return A, Zx, Zr
