"""Effects that come and go: where in a log an always-on flow starts (a leak opening, a
blower left on from some time).

A fault that begins during a log shows as a step in the residual (measured less
predicted): its level before the step and after differ by the new flow. The residual of
a healthy machine also wanders (strokes placed a little off, the model's shape error),
but cycle by cycle alike, so the step is sought in the residual's means over blocks of
whole cycles (or of MIN_BLOCK_S without a cycle), and must stand out of their scatter
(:data:`MIN_Z`) by a material share of the flow (:data:`MIN_STEP_SHARE`), with at least
:data:`MIN_SIDE_SHARE` of the log on either side. The criterion is a two-sample
t-statistic on the block means at the best single split (binary segmentation's first
step); the split is then refined reading by reading within the blocks next to it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

MIN_Z = 6.0               # block means are correlated: a strict threshold
MIN_STEP_SHARE = 0.03     # of the mean flow (a good meter's accuracy is 1 %)
MIN_SIDE_SHARE = 0.1      # of the log on either side of the step
MIN_BLOCK_S = 5.0
MIN_BLOCKS = 8


@dataclass
class Onset:
    """A step in a run's residual: at ``time_s`` (prediction time) by ``step_l_min``."""
    time_s: float
    step_l_min: float
    before_l_min: float
    after_l_min: float
    z: float


def _blocks(end_s: np.ndarray, block_s: float) -> np.ndarray:
    return np.floor((end_s - end_s[0]) / block_s).astype(np.int64)


def step_onset(end_s: np.ndarray, residual_l_min: np.ndarray, weight_s: np.ndarray,
               mean_l_min: float, period_s: float | None = None) -> Onset | None:
    """The one step in ``residual_l_min`` (readings ending at ``end_s``) that stands
    out as the module says, or None."""
    end_s = np.asarray(end_s, dtype=float)
    r = np.asarray(residual_l_min, dtype=float)
    w = np.asarray(weight_s, dtype=float)
    if len(r) < 4 * MIN_BLOCKS:
        return None
    span_s = float(end_s[-1] - end_s[0])
    block_s = max(MIN_BLOCK_S, period_s or 0.0)
    if period_s:
        block_s = period_s * math.ceil(MIN_BLOCK_S / period_s)
    if span_s / block_s < MIN_BLOCKS:
        block_s = span_s / MIN_BLOCKS
    b = _blocks(end_s, block_s)
    n_blocks = int(b[-1]) + 1
    sw = np.bincount(b, weights=w, minlength=n_blocks)
    keep = sw > 0
    means = np.bincount(b, weights=w * r, minlength=n_blocks)[keep] / sw[keep]
    starts = np.flatnonzero(keep)
    n = len(means)
    lo = max(2, int(math.ceil(MIN_SIDE_SHARE * n)))
    best = None
    for k in range(lo, n - lo + 1):
        left, right = means[:k], means[k:]
        d = float(right.mean() - left.mean())
        resid = np.concatenate([left - left.mean(), right - right.mean()])
        s = float(np.sqrt(resid @ resid / max(n - 2, 1)))
        z = abs(d) / max(s * math.sqrt(1.0 / len(left) + 1.0 / len(right)), 1e-12)
        if best is None or z > best[0]:
            best = (z, k, d)
    if best is None:
        return None
    z, k, d = best
    if z < MIN_Z or abs(d) < MIN_STEP_SHARE * mean_l_min:
        return None
    # the reading where the level changes, within the blocks on either side of the split
    first = int(np.searchsorted(b, starts[max(k - 1, 0)]))
    last = int(np.searchsorted(b, starts[min(k, n - 1)] + 1))
    before = float(np.average(r[:first], weights=w[:first])) if first > 0 else 0.0
    after = float(np.average(r[last:], weights=w[last:])) if last < len(r) else 0.0
    cut = first
    best_cost = math.inf
    for i in range(first, max(last, first + 1)):
        seg = r[first:last]
        j = i - first
        cost = float(np.sum((seg[:j] - before) ** 2) + np.sum((seg[j:] - after) ** 2))
        if cost < best_cost:
            best_cost, cut = cost, i
    time_s = float(end_s[cut] - w[cut]) if cut < len(end_s) else float(end_s[-1])
    return Onset(time_s, after - before, before, after, z)
