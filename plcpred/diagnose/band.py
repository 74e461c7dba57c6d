"""The model-form band: how far a healthy machine may legitimately differ from D1 and D2.

The activation model is exact for nothing real. A settled stroke takes D1 less the air
its dead volume already held at atmospheric pressure; a fill is not isothermal and
short dwells leave chambers hot and exhausts incomplete, so real strokes take a few per
cent less again; a nozzle's conductance is known to about ten per cent (docs/reference/physics.md,
"The dynamic model of a drive": a settled stroke takes a few per cent below D1, short dwells
less). A diagnosis that reads that error as a fault blames healthy machines, since any
free parameter absorbs a few per cent.

So the nominal model is allowed to flex within the band before any effect is credited:
:class:`ModelForm` is a nuisance "effect" with a parameter per chamber and per nozzle (where
within its band each chamber's fills lie, a factor on each nozzle and leak), fitted like the
clock and the meter's lag. An effect is a finding only where it beats the nominal model flexed
so, on held-out samples (:func:`~plcpred.diagnose.core.diagnose`), and :func:`band_pct` states
the band in total air for the report. Where the physics plant models a machine better than D1
(its held-out error is lower), the band is taken around the plant's air instead
(:func:`plant_factor_range`): the plant has the heat and the exhausts D1 leaves out, so what is
left to flex is narrower.
"""
from __future__ import annotations

import numpy as np

from ..air.demand import sonic_conductance
from .effects import (
    HOT_FILL_SHARE,
    PASSIVE_TOLERANCE_SHARE,
    Effect,
    Param,
    consumer_table,
    write_conductance,
)
from .fit_model import MachineModel, ModelParams

# a stroke may take this share of D1 more than a settled stroke (bore, stroke and tube
# lengths as built, a supply a little above the regulator's setting, the cylinder's own
# dead volume, which the file rarely gives)
DRIVE_ABOVE_SHARE = 0.04
# and this share less: an incomplete top-up after a hot fill and an exhaust cut short
# (settled strokes take about 0.96 x D1, short dwells and fast cycles less). Wider, it
# would hold a supply a bar low (14 % less air) for a healthy machine's
DRIVE_THERMAL_SHARE = HOT_FILL_SHARE
# a nozzle's or a leak's D2 flow either way (a worn or a blocked nozzle is 20 % and more)
PASSIVE_SHARE = PASSIVE_TOLERANCE_SHARE
# a stroke may take this share more or less than the physics plant's: the plant has the
# heat, the top-up and the exhaust that D1 leaves out, but not a real machine's heat
# transfer coefficients, spool ramps, friction and dimensions as built
PLANT_SHARE = 0.04
# a calibration factor this close to 1 is not written (a meter's own accuracy)
CALIBRATION_QUANTUM = 0.01


def drive_factor_range(mm: MachineModel, p: ModelParams) -> tuple[np.ndarray, np.ndarray]:
    """(low, high), each (drives, 2): the factors on each drive's extend and retract D1
    air within which a healthy drive's strokes lie. A settled stroke fills its swept
    volume, tube and the cylinder's own dead volume to supply from what they held, so
    it takes D1 (which counts the tube from zero and leaves the inner volume out) plus
    ``V_inner (P_s - P_atm)/P0 - V_tube P_atm/P0`` (section 7): that is where the band
    is centred. Hot fills and exhausts cut short take up to DRIVE_THERMAL_SHARE less,
    dimensions as built up to DRIVE_ABOVE_SHARE more."""
    d1 = np.stack([p.extend_nl, p.retract_nl], axis=1)
    tube_d1 = np.clip(d1 - p.swept_nl, 0.0, None)      # the tube's D1 air
    with np.errstate(invalid="ignore", divide="ignore"):
        # D1 less what a settled stroke takes, as a share of D1 (may be negative)
        settled = np.where(d1 > 0, (tube_d1 - p.held_nl) / d1, 0.0)
    centre = np.clip(1.0 - settled, 0.5, 1.5)
    return centre - DRIVE_THERMAL_SHARE, centre + DRIVE_ABOVE_SHARE


def plant_factor_range(mm: MachineModel) -> tuple[np.ndarray, np.ndarray]:
    """(low, high) as :func:`drive_factor_range`, for the plant's strokes: within
    PLANT_SHARE of what the plant draws (on top of the plant, a factor f on a stroke's
    D1 air adds (f - 1) x D1 to the plant's)."""
    n = len(mm.drives)
    return np.full((n, 2), 1.0 - PLANT_SHARE), np.full((n, 2), 1.0 + PLANT_SHARE)


class ModelForm(Effect):
    """The nominal model flexed within the band (a nuisance, never a verdict): each
    drive's chambers anywhere within its band, each nozzle and leak within
    PASSIVE_SHARE of its rating. Chamber by chamber, since heat, dwell and tubing differ
    between drives and between a drive's two fills, and a catalogue's conductance errs
    for each nozzle on its own. ``factor_range`` (default :func:`drive_factor_range`):
    the band on D1's air, or :func:`plant_factor_range` on top of the plant's."""
    name, title = "model_form", "the activation model's own accuracy"
    expressible = False

    def __init__(self, factor_range: tuple[np.ndarray, np.ndarray] | None = None):
        self.factor_range = factor_range

    def params(self, mm, ctx):
        # per drive and direction 0: its strokes at the band's top, 1: at its bottom.
        # Each chamber on its own: the dwell before a chamber's next fill, which decides
        # how far it exhausted and cooled, differs between the two
        out = [Param(f"{mm.models[r].name}.{way}_shortfall", "share of the band", 0.0, 1.0,
                     0.5, (0.0, 0.5, 1.0), nuisance=True)
               for r in mm.drives for way in ("extend", "retract")]
        out += [Param(f"{mm.models[r].name}.factor", "", 1.0 - PASSIVE_SHARE,
                      1.0 + PASSIVE_SHARE, 1.0, nuisance=True) for r in mm.passives]
        return out

    @staticmethod
    def count(mm: MachineModel) -> int:
        """How many parameters :meth:`params` gives."""
        return 2 * len(mm.drives) + len(mm.passives)

    def apply(self, mm, p, theta):
        q = p.copy()
        n = 2 * len(mm.drives)
        if n:
            low, high = self.factor_range if self.factor_range is not None else \
                drive_factor_range(mm, p)
            s = np.asarray(theta[:n], dtype=float).reshape(-1, 2)
            factor = high - s * (high - low)
            q.extend_nl = p.extend_nl * factor[:, 0]
            q.retract_nl = p.retract_nl * factor[:, 1]
            q.swept_nl = p.swept_nl * factor
        if mm.passives:
            q.passive_l_min = p.passive_l_min * np.asarray(theta[n:], dtype=float)
        return q

    def physical(self, mm, theta):
        return dict(zip([p.name for p in self.params(mm, {})], map(float, theta)))

    def to_machine(self, mm, data, theta):
        """The flexed model as a calibration of the file: each drive's ``air_factor``
        (extend, retract) times the factor its fills were flexed by, each nozzle's and
        leak's C times its factor. Needs ``factor_range`` (the band of the bases the
        fit started from). Factors within CALIBRATION_QUANTUM of 1 are left out."""
        changes = []
        n = 2 * len(mm.drives)
        if n and self.factor_range is not None:
            low, high = self.factor_range
            s = np.asarray(theta[:n], dtype=float).reshape(-1, 2)
            factors = high - s * (high - low)
            for row, f in zip(mm.drives, factors):
                if np.all(np.abs(f - 1.0) < CALIBRATION_QUANTUM):
                    continue
                c = mm.machine.consumers[row]
                new = [round(float(a * b), 3) for a, b in zip(c.air_factor, f)]
                consumer_table(data, c.name)["air_factor"] = new
                changes.append(f'consumer "{c.name}": air_factor = {new} (calibrated: '
                               "its fills take that share of D1)")
        for row, f in zip(mm.passives, theta[n:]):
            if abs(float(f) - 1.0) < CALIBRATION_QUANTUM:
                continue
            c = mm.machine.consumers[row]
            C = sonic_conductance(c) * float(f)
            write_conductance(data, c, C)
            changes.append(f'consumer "{c.name}": C = {C:.3g} m^3/(s Pa) (calibrated: '
                           f"x{float(f):.3g})")
        return changes


def band_pct(mm: MachineModel, p: ModelParams, drive_nl: float, passive_nl: float
             ) -> tuple[float, float]:
    """(low, high): the error in total air, in per cent as ``error_pct`` counts it
    (predicted - measured over measured), that a healthy machine may show, for a run
    whose prediction books ``drive_nl`` on its drives and ``passive_nl`` on its nozzles
    and leaks (the drives' factors averaged)."""
    if drive_nl + passive_nl <= 0:
        return 0.0, 0.0
    low_f = high_f = 1.0
    if mm.drives:
        low, high = drive_factor_range(mm, p)
        low_f, high_f = float(np.mean(low)), float(np.mean(high))
    least = low_f * drive_nl + (1.0 - PASSIVE_SHARE) * passive_nl     # measured at least
    most = high_f * drive_nl + (1.0 + PASSIVE_SHARE) * passive_nl
    predicted = drive_nl + passive_nl
    return 100.0 * (predicted - most) / most, 100.0 * (predicted - least) / least


class WithinBand(Effect):
    """``inner`` fitted together with the nominal model flexed within its band
    (:class:`ModelForm`): the effect's values are then what the logs say beyond the
    model's own accuracy. Used where a reading fixes the effect's size (a supply the log's
    pressure column reads), which D1's own error would otherwise pull off that reading.
    Everything but the fit is ``inner``'s."""

    def __init__(self, inner: Effect, factor_range=None):
        self.inner = inner
        self.flex = ModelForm(factor_range)
        self.name = inner.name
        self.title = inner.title + " (the model flexed within its accuracy)"
        self.expressible = inner.expressible
        self.through_plant = inner.through_plant

    def _own(self, mm, theta):
        return theta[:len(theta) - ModelForm.count(mm)]

    def applies(self, mm):
        return self.inner.applies(mm)

    def params(self, mm, ctx):
        return self.inner.params(mm, ctx) + self.flex.params(mm, ctx)

    def apply(self, mm, p, theta):
        n = len(theta) - ModelForm.count(mm)
        return self.flex.apply(mm, self.inner.apply(mm, p, theta[:n]), theta[n:])

    def physical(self, mm, theta):
        return self.inner.physical(mm, self._own(mm, theta))

    def implausible(self, mm, theta):
        return self.inner.implausible(mm, self._own(mm, theta))

    def to_machine(self, mm, data, theta):
        return self.inner.to_machine(mm, data, self._own(mm, theta))

    def tolerance_box(self, mm, ctx):
        box = self.inner.tolerance_box(mm, ctx)
        return None if box is None else box + [(-np.inf, np.inf)] * ModelForm.count(mm)

    def tolerance_reason(self, mm, theta, ctx):
        return self.inner.tolerance_reason(mm, self._own(mm, theta), ctx)
