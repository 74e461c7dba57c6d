"""What a real flow meter reports of a true flow (docs/reference/physics.md: figures, what D4 adds):
its reference condition, first-order response, logging intervals (each reading the mean over its
interval, or with ``sampling = "instant"`` the response at the reading's time), noise, zero offset
and full-scale clipping."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..physics.meter import cumulative_nl, first_order_lag, interval_means_l_min, reference_factor

DEFAULT_TAU_S = 0.2      # a thermal-mass meter's response (0.1-0.6 s)
DEFAULT_RATE_HZ = 10.0


@dataclass
class MeterSettings:
    tau_s: float = DEFAULT_TAU_S
    rate_hz: float = DEFAULT_RATE_HZ
    reference: str = "iso8778"
    noise_l_min: float = 0.0
    offset_l_min: float = 0.0
    full_scale_l_min: float | None = None
    sampling: str = "mean"          # "mean" over the interval | "instant" at its end

    @classmethod
    def from_machine(cls, meter) -> "MeterSettings":
        """The machine file's ``[meter]`` with this module's defaults for what it leaves
        out."""
        if meter is None:
            return cls()
        return cls(tau_s=DEFAULT_TAU_S if meter.tau_s is None else meter.tau_s,
                   rate_hz=meter.rate_hz or DEFAULT_RATE_HZ, reference=meter.reference,
                   noise_l_min=meter.noise_l_min, offset_l_min=meter.offset_l_min,
                   full_scale_l_min=meter.full_scale_l_min,
                   sampling=meter.sampling or "mean")


def meter_readings(edges_s: np.ndarray, cum_nl: np.ndarray, settings: MeterSettings,
                   horizon_s: float, rng: np.random.Generator | None = None):
    """(times, readings in l/min at the meter's reference) of a true flow given as its
    cumulative ISO 8778 normal litres at the fine grid's edges.

    The flow of each fine cell (its mean) goes through the first-order response (exact
    for piecewise-constant input), each reading is the mean of the response over its
    logging interval ending at its time stamp (``instant``: the response in the fine cell
    that holds the time stamp, as a logger polling the meter's analogue output reads it),
    then converted to the meter's reference (V_ref2 = V_ref1 (P1/P2)(T2/T1),
    docs/reference/physics.md: reference conditions), offset, noise and clipping."""
    dt = np.diff(edges_s)
    cell_flow = np.diff(cum_nl) / dt * 60.0
    lagged = first_order_lag(cell_flow, float(np.median(dt)), settings.tau_s)
    period = 1.0 / settings.rate_hz
    times = np.arange(period, horizon_s + 1e-9, period)
    if settings.sampling == "instant":
        # the response is held over each fine cell: the cell's value at the time stamp
        cell = np.clip(np.searchsorted(edges_s, times, side="left") - 1, 0, len(dt) - 1)
        flow = lagged[cell]
    else:
        flow = interval_means_l_min(cumulative_nl(lagged * dt / 60.0), edges_s,
                                    times - period, times)
    flow = flow / reference_factor(settings.reference)
    if settings.noise_l_min > 0:
        rng = rng or np.random.default_rng()
        flow = flow + rng.normal(0.0, settings.noise_l_min, len(flow))
    flow = flow + settings.offset_l_min
    if settings.full_scale_l_min is not None:
        flow = np.minimum(flow, settings.full_scale_l_min)
    return times, flow
