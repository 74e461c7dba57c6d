"""Where in the cycle a residual lies: each logged sample gets the context the prediction
gives it (a drive's strokes, a nozzle on, idle), and a context is named only when its
residual stands out of the noise.

A sample's context is the consumer with the most predicted air in the sample's interval
(cylinders by their strokes, nozzles while on; leaks are always on and never a context);
a sample with no stroke and no nozzle (or only the fringe of one: less than 2 % of the
largest air a consumer takes in one sample) is ``idle``. For SFC programs each sample also has
the step active at its midpoint.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..physics.meter import cumulative_nl
from ..sequencer.timeline import NS

IDLE = "idle"
IDLE_SHARE = 0.02
STANDS_OUT_SIGMA = 3.0


@dataclass
class Context:
    context: str
    residual_nl: float
    share: float            # of the gross gap (sum of |residual| over contexts), signed
    samples: int
    duration_s: float
    uncertainty_nl: float   # one standard deviation of the residual from noise alone
    stands_out: bool

    def summary(self) -> dict:
        return {"context": self.context, "residual_nl": self.residual_nl,
                "share": self.share, "samples": self.samples, "duration_s": self.duration_s,
                "uncertainty_nl": self.uncertainty_nl, "stands_out": self.stands_out}


def sample_contexts(rd, params) -> np.ndarray:
    """The context label of each of the run's samples (see the module docstring)."""
    rm = rd.model
    cells = rm.consumer_cells(params)[:-1]
    labels = []
    vols = []
    for row, m in enumerate(rm.mm.models):
        if m.role == "leak":
            continue
        cum = cumulative_nl(cells[row])
        vols.append(np.interp(rd.end_s, rm.edges_s, cum)
                    - np.interp(rd.start_s, rm.edges_s, cum))
        labels.append(f"{m.name} strokes" if m.role == "active" else f"{m.name} on")
    if not vols:
        return np.full(len(rd.end_s), IDLE, dtype=object)
    v = np.vstack(vols)
    k = np.argmax(v, axis=0)
    out = np.array(labels, dtype=object)[k]
    # a reading that only touches a stroke (its air spread over the grid cell the
    # reading's edge falls in) is idle: the threshold is a share of the largest air any
    # consumer takes in one reading, so that the labels do not depend on the grid
    out[v.max(axis=0) <= max(IDLE_SHARE * float(v.max()), 1e-9)] = IDLE
    return out


def step_contexts(rd) -> np.ndarray | None:
    """The SFC step active at each sample's midpoint (``step NAME``), or None when the
    program has no steps."""
    tl = rd.model.timeline
    steps = [s.name for s in tl.signals if s.kind == "step"]
    if not steps:
        return None
    mid_ns = np.round((rd.start_s + rd.end_s) / 2.0 * NS).astype(np.int64)
    out = np.full(len(mid_ns), "no step", dtype=object)
    for name in steps:
        t, v = tl.edge_times_ns(name)
        k = np.searchsorted(t, mid_ns, side="right") - 1
        active = (k >= 0) & (v[np.clip(k, 0, None)] != 0)
        out[active] = f"step {name}"
    return out


def contexts(labels_per_run, residual_per_run, weight_per_run, noise_l_min: float
             ) -> list[Context]:
    """Residual NL (measured - predicted) per context over all runs, its signed share of
    the gross gap, and its noise uncertainty ``sigma * sqrt(sum w^2) / 60``; sorted by
    the size of the residual."""
    labels = np.concatenate(labels_per_run)
    r = np.concatenate(residual_per_run)
    w = np.concatenate(weight_per_run)
    out = []
    per = {}
    for c in sorted(set(labels.tolist())):
        m = labels == c
        per[c] = (m, float(r[m] @ w[m]) / 60.0)
    # shares of the gross gap: contexts of opposite sign do not cancel into a tiny total
    gross = sum(abs(res) for _, res in per.values())
    for c, (m, res) in per.items():
        unc = noise_l_min * math.sqrt(float(w[m] @ w[m])) / 60.0
        out.append(Context(c, res, res / gross if gross else 0.0, int(m.sum()),
                           float(w[m].sum()), unc,
                           abs(res) > STANDS_OUT_SIGMA * max(unc, 1e-12)))
    out.sort(key=lambda c: -abs(c.residual_nl))
    return out


def windows(rd, labels, residual, noise_l_min: float, named: set[str],
            limit: int = 50) -> list[dict]:
    """Runs of consecutive samples with one context among ``named`` (the contexts that
    stand out), on the logger's clock, largest residual first."""
    out = []
    if not len(labels):
        return out
    change = np.flatnonzero(labels[1:] != labels[:-1]) + 1
    bounds = np.concatenate([[0], change, [len(labels)]])
    for a, b in zip(bounds[:-1], bounds[1:]):
        c = labels[a]
        if c not in named:
            continue
        w = rd.weight_s[a:b]
        res = float(residual[a:b] @ w) / 60.0
        out.append({"run": rd.run.name, "start_s": float(rd.start_s[a] + rd.offset_s),
                    "end_s": float(rd.end_s[b - 1] + rd.offset_s), "context": c,
                    "residual_nl": res})
    out.sort(key=lambda x: -abs(x["residual_nl"]))
    return out[:limit]


ALWAYS_ON = "always on"
NUDGE_S = 0.02          # the clock and lag change whose effect is taken out
RIDGE_SHARE = 1e-4      # of the scaled columns' mean square: keeps collinear ones finite


def attribution(rds, params_per_run, residual_per_run) -> list[dict]:
    """The residual attributed to consumers by their own edges and phases: a weighted
    least-squares fit of the residual readings to each consumer's own predicted
    readings (through the meter) and a constant (an always-on flow),
    ``r = sum_c beta_c v_c + gamma``. A consumer's share is ``beta_c`` times its
    predicted air, so a nozzle that runs while a drive strokes takes the blame only as
    far as its own on and off explain the residual, not for having the most air in a
    reading. Sorted by the size of the attributed air (NL)."""
    names, cols, ys, ws = None, [], [], []
    for rd, p, r in zip(rds, params_per_run, residual_per_run):
        rm = rd.model
        cells = rm.consumer_cells(p)[:-1]
        rows = [k for k, m in enumerate(rm.mm.models) if m.role != "leak"]
        names = [rm.mm.models[k].name for k in rows]
        # and, attributed to no one, how the readings change with a slightly later clock
        # and a slightly slower meter: an alignment a little off (pulled by the fault
        # itself) leaves residual at every edge, which would land on the drives
        total = cells.sum(axis=0)
        now = rm.readings(p, rd.read_start_s, rd.end_s, total_cells=total)
        later = rm.readings(p, rd.read_start_s - NUDGE_S, rd.end_s - NUDGE_S,
                            total_cells=total)
        slower = rm.readings(dataclasses.replace(p, meter_tau_s=p.meter_tau_s + NUDGE_S),
                             rd.read_start_s, rd.end_s, total_cells=total)
        cols.append(np.column_stack(
            [rm.readings(p, rd.read_start_s, rd.end_s, total_cells=cells[k]) for k in rows]
            + [np.ones(len(rd.end_s)), later - now, slower - now]))
        ys.append(np.asarray(r, dtype=float))
        ws.append(rd.weight_s)
    if names is None:
        return []
    x, y, w = np.vstack(cols), np.concatenate(ys), np.concatenate(ws)
    sw = np.sqrt(w)
    a = x * sw[:, None]
    # each column on its own scale (a consumer's NL/min against the constant's 1), so
    # that the ridge holds back each alike
    scale = np.sqrt((a * a).mean(axis=0))
    scale[scale <= 0] = 1.0
    a = a / scale
    gram = a.T @ a
    ridge = RIDGE_SHARE * float(np.trace(gram)) / max(len(gram), 1)
    beta = np.linalg.solve(gram + ridge * np.eye(len(gram)), a.T @ (y * sw)) / scale
    predicted_nl = (x * w[:, None]).sum(axis=0) / 60.0
    n = len(names)
    out = [{"consumer": name, "residual_nl": float(b * v), "relative_pct": float(100.0 * b)}
           for name, b, v in zip(names, beta[:n], predicted_nl[:n]) if v > 0]
    out.append({"consumer": ALWAYS_ON, "residual_nl": float(beta[n] * predicted_nl[n]),
                "flow_l_min": float(beta[n])})
    out.sort(key=lambda d: -abs(d["residual_nl"]))
    return out
