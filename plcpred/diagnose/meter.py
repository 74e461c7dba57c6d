"""What a flow meter makes of a flow: its response lag and its logging intervals.

Comparing a prediction with a log means comparing like with like: the prediction's flow
on a fine grid goes through the meter's first-order response and is averaged over each
logged sample's interval, as a thermal-mass meter with a 1-2 Hz logger reports it
(docs/physics.md: figures: "the flow sensor acts as a low-pass filter"; section 7: meters lag
0.1-0.6 s).
"""
from __future__ import annotations

import math

import numpy as np


def first_order_lag(flow_l_min: np.ndarray, dt_s: float, tau_s: float,
                    from_rest: bool = False) -> np.ndarray:
    """A first-order sensor ``tau * dy/dt + y = x`` sampled on a grid of ``dt_s``, with
    the input held over each cell (exact for piecewise-constant input):
    ``y[n] = a y[n-1] + (1 - a) x[n]``, ``a = exp(-dt/tau)``. Starts settled at ``x[0]``
    (or at 0 with ``from_rest``)."""
    if not tau_s or tau_s <= 0 or len(flow_l_min) == 0:
        return flow_l_min
    from scipy.signal import lfilter

    a = math.exp(-dt_s / tau_s)
    x = np.asarray(flow_l_min, dtype=float)
    y, _ = lfilter([1.0 - a], [1.0, -a], x, zi=[0.0 if from_rest else a * x[0]])
    return y


def cumulative_nl(cell_nl: np.ndarray) -> np.ndarray:
    """Normal litres used by each grid edge (length cells + 1, starting at 0)."""
    return np.concatenate([[0.0], np.cumsum(cell_nl)])


def interval_means_l_min(cum_nl: np.ndarray, edges_s: np.ndarray, start_s: np.ndarray,
                         end_s: np.ndarray, dt_s: float | None = None) -> np.ndarray:
    """Mean flow (NL/min) over each ``[start, end]`` from the cumulative volume at the
    grid edges (linear within a cell, i.e. exact for cell-mean flows). Intervals must lie
    within the grid. ``dt_s``: the edges are ``k dt_s`` (the last may be short), which
    finds each time's cell by division instead of a search."""
    if dt_s is not None:
        return IntervalSampler(edges_s, start_s, end_s, dt_s)(cum_nl)
    c1 = np.interp(end_s, edges_s, cum_nl)
    c0 = np.interp(start_s, edges_s, cum_nl)
    return (c1 - c0) / (end_s - start_s) * 60.0


def _uniform_weights(x: np.ndarray, edges_s: np.ndarray, dt_s: float):
    """(cell, share of it) of each time ``x`` on edges ``k dt_s``: ``np.interp``'s
    weights, clamped at both ends."""
    i = np.clip((np.asarray(x) * (1.0 / dt_s)).astype(np.int64), 0, len(edges_s) - 2)
    e0 = edges_s[i]
    return i, np.clip((x - e0) / (edges_s[i + 1] - e0), 0.0, 1.0)


class IntervalSampler:
    """:func:`interval_means_l_min` for fixed intervals on a fixed uniform grid, with the
    cells and weights found once: a fit reads the same samples at the same clock for
    many model parameters. The function's uniform-grid case is this, made once."""

    def __init__(self, edges_s: np.ndarray, start_s: np.ndarray, end_s: np.ndarray,
                 dt_s: float):
        self.i0, self.f0 = _uniform_weights(start_s, edges_s, dt_s)
        self.i1, self.f1 = _uniform_weights(end_s, edges_s, dt_s)
        self.width_s = end_s - start_s

    def __call__(self, cum_nl: np.ndarray) -> np.ndarray:
        return (_at(cum_nl, self.i1, self.f1) - _at(cum_nl, self.i0, self.f0)) \
            / self.width_s * 60.0


def _at(y: np.ndarray, i: np.ndarray, f: np.ndarray) -> np.ndarray:
    y0 = y[i]
    return y0 + f * (y[i + 1] - y0)


def noise_level_l_min(residual_l_min: np.ndarray) -> float:
    """The measurement noise of a residual series, robustly: the median absolute
    deviation of its first differences (white noise of sigma gives differences of
    sigma*sqrt(2); steps at the few edges do not move a median), scaled to a standard
    deviation."""
    d = np.diff(np.asarray(residual_l_min, dtype=float))
    if len(d) < 2:
        return 0.0
    mad = np.median(np.abs(d - np.median(d)))
    return float(1.4826 * mad / math.sqrt(2.0))


# readings whose predicted neighbours agree to this share of the mean flow are "flat"
FLAT_SHARE = 0.02
MIN_FLAT_PAIRS = 12


def flat_noise_l_min(measured_l_min: np.ndarray, predicted_l_min: np.ndarray
                     ) -> tuple[float | None, int]:
    """(the meter's noise, readings it rests on) from what cannot be model error: the
    scatter between neighbouring readings where the prediction is flat (nothing
    switches, or only a constant flow runs), as :func:`noise_level_l_min` takes it (the
    median absolute difference, scaled to a standard deviation). A misfit of the model
    cannot raise it, where the differences of the residual carry every stroke the model
    places a little off. None where fewer than MIN_FLAT_PAIRS neighbours are flat."""
    m = np.asarray(measured_l_min, dtype=float)
    p = np.asarray(predicted_l_min, dtype=float)
    if len(m) < 3:
        return None, 0
    tol = FLAT_SHARE * max(float(np.mean(np.abs(p))), 1e-9)
    flat = np.abs(np.diff(p)) <= tol
    d = np.diff(m)[flat]
    if len(d) < MIN_FLAT_PAIRS:
        return None, int(len(d))
    mad = np.median(np.abs(d - np.median(d)))
    return float(1.4826 * mad / math.sqrt(2.0)), int(len(d))
