"""What a flow meter makes of a flow: its response lag and its logging intervals.

Comparing a prediction with a log means comparing like with like: the prediction's flow on a fine
grid goes through the meter's first-order response and is averaged over each logged sample's
interval, as a thermal-mass meter with a 1-2 Hz logger reports it (docs/reference/physics.md:
figures: "the flow sensor acts as a low-pass filter"; section 7: meters lag 0.1-0.6 s).
"""
from __future__ import annotations

import math

import numpy as np

from .units import P0_PA, P_ATM_PA, T0_K, ZERO_C_K

# the reference conditions a meter's normal litres may be given at: (pressure Pa, K)
REFERENCES = {"iso8778": (P0_PA, T0_K), "din1343": (P_ATM_PA, ZERO_C_K),
              "iso2533": (P_ATM_PA, 288.15)}


def reference_factor(reference: str) -> float:
    """Multiplier from normal litres at ``reference`` to ISO 8778 normal litres
    (D3): ``(P_ref / P0) * (T0 / T_ref)``; DIN 1343 litres are 8.7 % more ISO 8778
    litres. Raises ValueError naming the known references."""
    try:
        p_pa, t_k = REFERENCES[reference]
    except KeyError:
        raise ValueError(f"unknown reference {reference!r} (known: "
                         f"{', '.join(REFERENCES)})") from None
    return (p_pa / P0_PA) * (T0_K / t_k)


def first_order_lag(flow_l_min: np.ndarray, dt_s: float, tau_s: float,
                    from_rest: bool = False) -> np.ndarray:
    """A first-order sensor ``tau * dy/dt + y = x`` sampled on a grid of ``dt_s``, with
    the input held over each cell (exact for piecewise-constant input):
    ``y[n] = a y[n-1] + (1 - a) x[n]``, ``a = exp(-dt/tau)``. Starts settled at ``x[0]``
    (or at 0 with ``from_rest``).

    The recursion is solved by doubling (``y[n] += a^s y[n-s]`` for s = 1, 2, 4, ...),
    log2(n) passes of numpy: within 1e-14 of the sequential filter relative to the
    largest value, as fast as scipy's ``lfilter`` and without its 0.3 s import."""
    if not tau_s or tau_s <= 0 or len(flow_l_min) == 0:
        return flow_l_min
    a = math.exp(-dt_s / tau_s)
    x = np.asarray(flow_l_min, dtype=float)
    y = (1.0 - a) * x
    if not from_rest:
        y[0] += a * x[0]
    # after pass k, y[n] holds the recursion's terms of x[n - 2^k + 1 .. n]
    factor, shift, n = a, 1, len(y)
    while shift < n and factor > 0.0:
        y[shift:] += factor * y[:-shift]
        factor *= factor
        shift *= 2
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


def chained_interval_means_l_min(cum_nl: np.ndarray, edges_s: np.ndarray,
                                 bounds_s: np.ndarray, dt_s: float) -> np.ndarray:
    """:func:`interval_means_l_min` of intervals that follow one another: each row of
    ``bounds_s`` holds the boundaries of one chain (``n + 1`` for ``n`` intervals) on the
    uniform grid ``edges_s``. Each shared boundary is read once; the values are the
    function's, to the last bit."""
    b = np.asarray(bounds_s, dtype=float)
    i, f = _uniform_weights(b.ravel(), edges_s, dt_s)
    c = _at(cum_nl, i, f).reshape(b.shape)
    return (c[..., 1:] - c[..., :-1]) / (b[..., 1:] - b[..., :-1]) * 60.0


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
