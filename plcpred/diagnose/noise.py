"""How noisy a flow meter's readings are: the scale the diagnosis judges a gap against."""
from __future__ import annotations

import math

import numpy as np


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
