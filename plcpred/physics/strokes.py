"""Stroke times from the physics, and flow controls set to give a wanted stroke time.

``stroke_time_s = "auto"`` in a machine file asks for the time a drive needs from its
valve switching to reaching the far end, at the supply pressure with its load, starting
from rest: computed here by the plant (one extend, one retract). A stroke time given as
numbers is what the machine was commissioned to: the plant then turns the drive's
meter-out flow controls (the exhausting chamber's C) down until it takes that time, as a
commissioning engineer does, unless the file gives ``exhaust_C`` itself. Results are
cached per drive configuration.
"""
from __future__ import annotations

import dataclasses
import math

from . import group as _group
from .drive import drive_params
from .group import Group, PlantError, Supply
from .units import pa_to_bar_g

_CACHE: dict = {}      # keyed by the integrator too: the equality tests run both
SEARCH_STEPS = 12
MAX_THROTTLED_S = 20.0   # slower strokes than this are not set by flow controls
TIME_TOL_REL = 0.01


def _stroke(drive, extend: bool, supply_pa: float, atmosphere_pa: float, ambient_k: float,
            horizon: float = 60.0) -> float | None:
    """Seconds from the valve switching (flow reaching the chamber) to the end stop, or
    None when the drive does not get there within ``horizon`` (a minute)."""
    d = dataclasses.replace(drive, initial_extended=not extend, delay_s=0.0)
    g = Group([d], Supply(supply_pa, ambient_k), atmosphere_pa=atmosphere_pa,
              ambient_k=ambient_k, cache={})
    g.command_valve(0.0, 0, extend)
    t = 0.0
    while True:
        t_next = g.next_switch_after(0, t)
        if t_next is None or t_next > horizon:
            return None
        r, e = g.switches(0, t_next)
        if (e if extend else r):
            lag = d.transit_s[0 if extend else 1]
            return t_next - lag
        t = t_next


def stroke_times_s(drive, supply_pa: float, atmosphere_pa: float, ambient_k: float
                   ) -> tuple[float | None, float | None]:
    """(extend, retract) seconds from valve switch to end of stroke (see module note)."""
    key = ("times", _group.METHOD, drive, supply_pa, atmosphere_pa, ambient_k)
    if key not in _CACHE:
        _CACHE[key] = (_stroke(drive, True, supply_pa, atmosphere_pa, ambient_k),
                       _stroke(drive, False, supply_pa, atmosphere_pa, ambient_k))
    return _CACHE[key]


def throttle_to(drive, wanted_s: tuple[float, float], supply_pa: float,
                atmosphere_pa: float, ambient_k: float, explicit_exhaust=(False, False)):
    """``drive`` with its meter-out exhaust conductances lowered so that its strokes take
    ``wanted_s`` (extend, retract); a stroke that is already slower than wanted, or whose
    exhaust C the file gives, or slower than MAX_THROTTLED_S, stays as it is. Returns
    (drive, achieved times)."""
    key = ("throttle", _group.METHOD, drive, wanted_s, supply_pa, atmosphere_pa, ambient_k,
           explicit_exhaust)
    if key in _CACHE:
        return _CACHE[key]
    C = list(drive.C_exhaust)
    achieved = list(stroke_times_s(drive, supply_pa, atmosphere_pa, ambient_k))
    # extending exhausts the rod end (chamber 2); retracting exhausts the cap end (1);
    # a single-acting cylinder's spring stroke exhausts the cap end too
    for direction, chamber in ((0, 1), (1, 0)):
        if drive.vented2 and chamber == 1:
            continue
        if explicit_exhaust[chamber] or achieved[direction] is None or \
                achieved[direction] >= wanted_s[direction] or \
                wanted_s[direction] > MAX_THROTTLED_S:
            continue
        best = _search_log_c(drive, chamber, direction == 0, wanted_s[direction],
                             C[chamber], achieved[direction], supply_pa, atmosphere_pa,
                             ambient_k)
        if best is not None:
            C[chamber] = best[0]
            achieved[direction] = best[1]
    out = (dataclasses.replace(drive, C_exhaust=tuple(C)), tuple(achieved))
    _CACHE[key] = out
    return out


def _search_log_c(drive, chamber, extend, wanted_s, c0, t0, supply_pa, atmosphere_pa,
                  ambient_k):
    """(C, stroke time) of the exhaust conductance giving ``wanted_s``: secant steps on
    log t against log C (a metered-out stroke's time goes about as 1/C), kept inside a
    bracket that only shrinks."""
    def run(c):
        trial = list(drive.C_exhaust)
        trial[chamber] = c
        return _stroke(dataclasses.replace(drive, C_exhaust=tuple(trial)), extend,
                       supply_pa, atmosphere_pa, ambient_k, horizon=3.0 * wanted_s)

    lo, hi = (math.log(c0 * 1e-5), None), (math.log(c0), math.log(t0))   # (log C, log t)
    x_prev, y_prev = hi
    x = x_prev + (math.log(t0) - math.log(wanted_s))          # slope -1 to start
    best = None
    target = math.log(wanted_s)
    for _ in range(SEARCH_STEPS):
        x = min(max(x, lo[0]), hi[0])
        t = run(math.exp(x))
        if t is None:        # throttled so far it does not arrive: too low
            lo = (x, None)
            x = 0.5 * (x + hi[0])
            continue
        y = math.log(t)
        if best is None or abs(y - target) < abs(math.log(best[1]) - target):
            best = (math.exp(x), t)
        if abs(t - wanted_s) <= TIME_TOL_REL * wanted_s:
            break
        if y > target:
            lo = (x, y)
        else:
            hi = (x, y)
        slope = (y - y_prev) / (x - x_prev) if x != x_prev else -1.0
        if not slope < -0.05:
            slope = -1.0
        x_prev, y_prev = x, y
        x_new = x + (target - y) / slope
        if not lo[0] < x_new < hi[0]:
            x_new = 0.5 * (lo[0] + hi[0])
        x = x_new
    return best


def auto_stroke_times(consumer, supply_pa: float, atmosphere_pa: float, ambient_k: float
                      ) -> tuple[float, float]:
    """A machine file consumer's ``stroke_time_s = "auto"``: (extend, retract) seconds.
    Raises PlantError when the drive does not reach an end (load too high for the
    supply, a spring stronger than the pressure)."""
    times = stroke_times_s(drive_params(consumer), supply_pa, atmosphere_pa, ambient_k)
    for t, what in zip(times, ("extend", "retract")):
        if t is None:
            raise PlantError(f"the plant model says it does not {what} fully within a minute "
                             f"at {pa_to_bar_g(supply_pa, atmosphere_pa):g} bar(g) with its load")
    return times
