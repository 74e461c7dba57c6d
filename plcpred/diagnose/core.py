"""The diagnosis of a sim-to-real gap, as one call: :func:`diagnose`.

1. Predict each measured run (the sequencer, or the run's recorded I/O trace) and align
   the log's clock to it (:func:`~plcpred.diagnose.fit.align`).
2. **Baseline**: measured vs predicted NL, error %, RMSE of the meter readings.
3. **Where**: the residual by context (:mod:`~plcpred.diagnose.locate`), named only where
   it stands out of the noise estimated from the data.
4. **Which effect**: every effect of the vocabulary fitted to the fit samples and scored
   on held-out samples (:func:`~plcpred.diagnose.fit.folds`); ranked by held-out RMSE,
   BIC breaking near-ties. Where end switches start the program's steps (a closed
   loop), ``stroke_time`` and ``valve_delay`` are also tried with the sequencer run
   again (:mod:`~plcpred.diagnose.timing`), and the better form on held-out samples
   stands for the effect. The verdict is the best effect when it beats the baseline on
   held-out samples by more than the noise allows and by a material share of the flow
   (:data:`MATERIAL_SHARE`, a thermal meter's accuracy), else ``none``.
5. **Combination**: from the verdict, effects are added one at a time while each still
   improves the held-out error by more than the noise allows, materially (up to three).

The nominal machine is also run through the physics plant (:func:`_dynamic_reference`).
The effects of no drive (leak, nozzle flow, meter lag) are fitted on D1 and beyond the
plant first. Where the plant explains a material part of the gap (what D1 leaves out by
design), alone or with each model's best effect of no drive, the drives' effects are
also fitted beyond it; a verdict that does not beat the reference is ``none``. Where
the plant beats D1 at all on held-out samples (or materially with those effects), its
runs are cheap enough, and no effect of no drive applied to D1 explains the log to the
noise, the effects that change how drives fill and move are also fitted through it:
the machine file changed by the effect, run through the plant
(:mod:`~plcpred.diagnose.through_plant`).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from datetime import datetime, timedelta
from typing import NamedTuple

import numpy as np

from ..air.demand import stroke_cuts
from ..errors import PlcpredError
from ..machine import Machine, as_machine
from ..plant.replay import closed_loop_total_cells_nl, replay_total_cells_nl
from ..progress import progress_or_off
from ..sequencer import compile_program, observed_names, unfold
from .band import ModelForm, WithinBand, band_pct, drive_factor_range, plant_factor_range
from .effects import (
    CLOSED_LOOP_EFFECTS,
    CUT_STROKE_EFFECTS,
    EFFECTS,
    METER_LAG_FIT_MAX_S,
    Effect,
    IncompleteExhaust,
    LeakFrom,
    StrokeTime,
    SupplyFrom,
    SupplyPressure,
)
from .errors import DiagnosisError
from .fit import FitResult, RunData, Score, align, fit_effects, folds, heldout, params_at, score
from .fit_model import MachineModel, RunModel, render_start_s
from .io import TIME_OF_DAY_FORMATS, MeasuredRun
from .locate import attribution, contexts, sample_contexts, step_contexts, windows
from .noise import flat_noise_l_min, noise_level_l_min
from .onset import step_onset
from .through_plant import MAX_VARIANT_PIECES, PLANT_FORMS, PlantVariants, variant_pieces
from .timing import Resequencer

MAX_COMBINATION = 3
# how much more error than the best open-loop effect an effect's open-loop forms may leave
# and still be fitted through the plant
PLANT_FORM_ERROR_RATIO = 3.0
# a held-out RMSE within this factor of the noise leaves nothing to explain
DOWN_TO_NOISE = 1.1
# effects that change no drive: where one of them, applied to D1, explains a log to its
# noise, the drives' physics (the plant) has nothing left to explain
NOT_OF_THE_DRIVES = ("leak", "passive_flow", "sensor_lag", "meter_gain")
MAX_CELLS_PER_RUN = 200_000
LONG_RUN_CELLS = 100_000
READING_CELLS = 10
# effects that scale the whole machine's air alike, as the model's own error does: a
# verdict among them needs the total to lie outside the model-form band as well as the
# flow to beat it. (A leak's flow in idle, one nozzle's or one drive's air have shapes of
# their own, which the flexed model, consumer by consumer, already had to match.)
VOLUME_EFFECTS = ("supply_pressure", "meter_gain")
# effects whose signature no scaling of the consumers' air makes (a flow while nothing
# switches, a slower meter): the band, which only scales, cannot stand in for them
SHAPE_EFFECTS = ("leak", "sensor_lag")
# a fitted value this close to a bound (share of the range) is at it: the effect wanted
# more than is physical, so it is not what happened
AT_BOUND_SHARE = 1e-3
# instantaneous readings are suggested where they leave at most this share of the logs'
# variance that interval means leave unexplained (healthy rigs logged either way leave
# a twentieth of the wrong way's)
INSTANT_HINT = 0.25
# units that do not fit: a log this many times the prediction (or a fraction of it)
SCALE_LIMIT = 20.0


@dataclass
class EffectResult:
    name: str
    title: str
    fit: FitResult
    fit_score: Score
    heldout_score: Score
    parameters: dict
    physical: dict
    # fitted on top of the plant's reference (what the plant draws beyond D1 added)
    beyond_plant: bool = False
    # a fitted value at a bound of its range (never a verdict: it wanted more than is
    # physical)
    at_bound: bool = False

    def summary(self) -> dict:
        return {"name": self.name, "title": self.title, "parameters": self.physical,
                "beyond_plant": self.beyond_plant, "at_bound": self.at_bound,
                "fitted": {k: {"value": float(v), "stderr": _num(s), "unit": u}
                           for k, v, s, u in zip(self.fit.names, self.fit.theta,
                                                 self.fit.stderr, self.fit.units)},
                "error_pct_after": _num(self.fit_score.error_pct),
                "rmse_l_min_after": _num(self.fit_score.rmse_l_min),
                "heldout_error_pct_after": _num(self.heldout_score.error_pct),
                "heldout_rmse_l_min_after": _num(self.heldout_score.rmse_l_min),
                "bic": _num(self.fit.bic)}


def _num(x):
    return None if x is None or not math.isfinite(float(x)) else float(x)


@dataclass
class Diagnosis:
    machine: object
    runs: list[RunData]
    baseline: Score
    baseline_heldout: Score
    noise_l_min: float
    contexts: list
    step_contexts: list
    locations: list[dict]
    effects: list[EffectResult]
    verdict: str
    combination: dict | None
    fold_kind: str
    warnings: list[str] = field(default_factory=list)
    fixed_machine: str | None = None
    bases: list = field(default_factory=list)       # per run: the aligned nominal model
    alternatives: list[str] = field(default_factory=list)   # as good as the verdict
    machine_model: MachineModel | None = None
    fit_context: dict = field(default_factory=dict)   # what the effects' fits were given
    # the nominal machine through the physics plant (no parameter; its timing_params
    # fitted), None where it was not made; whether it explains a real part of the gap
    # (then an effect must beat it too), and whether it explains the gap as well as the
    # best effects (then the verdict is none)
    reference: "EffectResult | None" = None
    on_plant: bool = False
    dynamics_explain: bool = False
    # the nominal model flexed within its own accuracy (diagnose.band), the band in
    # total air (low, high error_pct), and whether it explains what the effects did
    flexed: "EffectResult | None" = None
    band_pct: tuple = (0.0, 0.0)
    within_band: bool = False
    # why the best effects move the file's values no further than a healthy machine's
    # own differ from its file (then the verdict is none)
    within_tolerance: list = field(default_factory=list)
    # the meter's own noise (from flat stretches of the log, :func:`_meter_noise`), the
    # flat neighbours it rests on, and the held-out RMS error beyond it that the best
    # explanation leaves (NL/min)
    meter_noise_l_min: float = 0.0
    flat_pairs: int = 0
    left_l_min: float = 0.0
    # the residual by consumer, each by its own edges and phases (locate.attribution)
    attribution: list = field(default_factory=list)
    # the program the sequencer ran (parsed), or what ``diagnose`` was given to name it
    program: object = None
    # predict on the written corrected file against the logs (diagnose.corrected)
    file_check: object = None
    # where the verdict is none because the best effects stay within a healthy
    # machine's tolerance of its file: their combination (its values may be written)
    tolerated: dict | None = None

    def _onset(self) -> dict | None:
        """The verdict's onset, where it is an effect that starts during the logs."""
        if not self.combination or not self.effects:
            return None
        for e, _ in self.combination["fit"].by_effect():
            # (a form fitted with the model flexed within its band is its inner effect's)
            if isinstance(getattr(e, "inner", e), (LeakFrom, SupplyFrom)):
                found = self.combination["physical"]
                found = found.get(e.name, found) if isinstance(found, dict) else {}
                return found if "onset_s" in found else None
        return None

    def best_params(self):
        """Per run: the model parameters of the combination (which starts with the
        verdict), else the baseline's."""
        if self.combination:
            return self.combination["fit"].params
        return self.bases

    def summary(self) -> dict:
        b = self.baseline
        out = {
            "machine": self.machine.name,
            "baseline": {"measured_nl": b.measured_nl, "predicted_nl": b.predicted_nl,
                         "error_pct": _num(b.error_pct), "rmse_l_min": _num(b.rmse_l_min)},
            "runs": [{"name": rd.run.name, "offset_s": rd.offset_s,
                      "meter_tau_s": rd.meter_tau_s, "correlation": rd.correlation,
                      "samples": int(len(rd.end_s)),
                      "interval_s": rd.run.interval_s,
                      "sampling": rd.run.sampling or "mean",
                      "unlogged_s": rd.run.unlogged_s,
                      "supply_bar_g": _num(_logged_supply(rd.run)),
                      "source": "recorded I/O" if rd.model.timeline.info.get(
                          "mode") == "recorded" else "sequencer"} for rd in self.runs],
            "noise_l_min": self.noise_l_min,
            "meter_noise_l_min": self.meter_noise_l_min,
            "residual_left_l_min": self.left_l_min,
            "heldout": self.fold_kind,
            "contexts": [c.summary() for c in self.contexts],
            "locations": self.locations,
            "attribution": self.attribution,
            "effects": [e.summary() for e in self.effects],
            "verdict": self.verdict,
            "alternatives": self.alternatives,
            "combination": None if not self.combination else {
                "effects": self.combination["effects"],
                "heldout_error_pct_after": _num(self.combination["heldout"].error_pct),
                "heldout_rmse_l_min_after": _num(self.combination["heldout"].rmse_l_min),
                "error_pct_after": _num(self.combination["score"].error_pct),
                "parameters": self.combination["physical"],
                "beyond_plant": self.combination.get("beyond_plant", False)},
            "fixed_machine": self.fixed_machine,
            "fixed_machine_check": None if self.file_check is None
            else self.file_check.summary(),
            "warnings": self.warnings,
        }
        if self.reference is not None:
            r = self.reference
            out["dynamic_reference"] = {
                "error_pct": _num(r.fit_score.error_pct),
                "rmse_l_min": _num(r.fit_score.rmse_l_min),
                "heldout_error_pct": _num(r.heldout_score.error_pct),
                "heldout_rmse_l_min": _num(r.heldout_score.rmse_l_min),
                "explains_part_of_the_gap": self.on_plant,
                "explains_the_gap": self.dynamics_explain}
        if self.flexed is not None:
            out["model_form_band"] = {
                "low_pct": _num(self.band_pct[0]), "high_pct": _num(self.band_pct[1]),
                "heldout_rmse_l_min": _num(self.flexed.heldout_score.rmse_l_min),
                "around": "plant" if self.flexed.beyond_plant else "D1",
                "parameters": self.flexed.physical,
                "explains_the_gap": self.within_band}
        if self.within_tolerance:
            out["within_tolerance"] = list(self.within_tolerance)
        if self.step_contexts:
            out["step_contexts"] = [c.summary() for c in self.step_contexts]
        return out

    def report(self) -> str:
        """The readable report printed by ``plcpred diagnose``."""
        lines = [f"{self.machine.name}: {len(self.runs)} run"
                 f"{'s' if len(self.runs) != 1 else ''}, noise {self.noise_l_min:.2g} NL/min"]
        for rd in self.runs:
            lines += self._run_lines(rd)
        lines += self._where_lines()
        lines += self._effect_lines()
        lines += self._verdict_lines()
        return "\n".join(lines)

    def _run_lines(self, rd: RunData) -> list[str]:
        """The report's lines on one run: its log, alignment and what the log holds
        that the reader should know of (its supply pressure, spread times, gaps)."""
        src = rd.model.timeline.info.get("mode") == "recorded"
        way = "instantaneous" if rd.run.sampling == "instant" else "interval means"
        lines = [f"  {rd.run.name}: {len(rd.end_s)} samples every "
                 f"{rd.run.interval_s:g} s ({way}), clock offset {rd.offset_s:+.3f} s"
                 f"{clock_reading(rd.run, rd.offset_s)}, "
                 f"meter lag {rd.meter_tau_s:.2f} s, correlation {rd.correlation:.2f}"
                 f"{', edges from recorded I/O' if src else ''}"]
        logged = _logged_supply(rd.run)
        if logged is not None:
            said = self.machine.supply_bar_g
            lines.append(f"    supply pressure in the log: {logged:.2f} bar(g) on average"
                         + (f", the machine file says {said:g}: compare the verdict "
                            "supply_pressure below" if abs(logged - said) >
                            SUPPLY_NOTE_BAR else f" (machine file: {said:g})"))
        spread = rd.run.source.get("spread_rows")
        if spread:
            lines.append(f"    times stamped to the whole second: {spread} readings "
                         "spread evenly over their second")
        if rd.run.unlogged_s > 0.5 * rd.run.interval_s:
            lines.append(f"    gaps in the log: {rd.run.unlogged_s:.3g} s without a "
                         "reading; measured and predicted air both cover only the "
                         "logged intervals")
        return lines

    def _where_lines(self) -> list[str]:
        """The report's baseline and where the residual lies: by context, by consumer."""
        b = self.baseline
        lines = ["", f"baseline: measured {b.measured_nl:.2f} NL, predicted "
                     f"{b.predicted_nl:.2f} NL, error {b.error_pct:+.1f} %, RMSE "
                     f"{b.rmse_l_min:.2f} NL/min", "",
                 "where (residual = measured - predicted):"]
        for c in self.contexts[:8]:
            mark = "  <- stands out" if c.stands_out else ""
            lines.append(f"  {c.context:<28} {c.residual_nl:+9.3f} NL  "
                         f"({100 * c.share:+6.1f} % of the gap, +/- {c.uncertainty_nl:.3f})"
                         f"{mark}")
        if self.attribution:
            lines.append("by consumer (the residual fitted to each one's own predicted air):")
            for a in self.attribution[:4]:
                how = (f"{a['flow_l_min']:+.2f} NL/min" if a["consumer"] == "always on"
                       else f"{a['relative_pct']:+.0f} % of its predicted air")
                lines.append(f"  {a['consumer']:<28} {a['residual_nl']:+9.3f} NL  ({how})")
        return lines

    def _effect_lines(self) -> list[str]:
        """The report's table of effects: the baseline, each effect, and the nominal
        models an effect must beat (the plant's, the model flexed within its accuracy)."""
        b = self.baseline
        lines = ["", f"which effect (held-out: {self.fold_kind}):",
                 f"  {'effect':<20} {'error after':>11} {'held-out':>9} {'RMSE held-out':>14}"
                 "  parameters",
                 f"  {'(baseline)':<20} {b.error_pct:>+10.1f}% "
                 f"{self.baseline_heldout.error_pct:>+8.1f}% "
                 f"{self.baseline_heldout.rmse_l_min:>14.2f}"]
        # sorted by the column the verdict rests on (held-out RMSE)
        for e in sorted(self.effects, key=lambda e: e.heldout_score.rmse_l_min):
            note = "(at a bound of its range: not a verdict) " if e.at_bound else ""
            lines.append(f"  {e.name:<20} {e.fit_score.error_pct:>+10.1f}% "
                         f"{e.heldout_score.error_pct:>+8.1f}% "
                         f"{e.heldout_score.rmse_l_min:>14.2f}  {note}{_short(e.physical)}")
        around = " around the plant" if self.flexed is not None and self.flexed.beyond_plant \
            else ""
        for label, ref, text in (
                ("(plant, nominal)", self.reference,
                 "the machine file through the physics plant, no parameter"),
                ("(model accuracy)", self.flexed, f"the machine file flexed{around} within "
                 "the model's own accuracy: an effect must beat it")):
            if ref is not None:
                lines.append(f"  {label:<20} {ref.fit_score.error_pct:>+10.1f}% "
                             f"{ref.heldout_score.error_pct:>+8.1f}% "
                             f"{ref.heldout_score.rmse_l_min:>14.2f}  {text}")
        if self.on_plant:
            lines.append("  (the plant explains part of the gap that D1 leaves out by "
                         "design: an effect must beat it too)")
        return lines

    def _verdict_lines(self) -> list[str]:
        """The report's verdict: when a flow started, the noise and what is left beyond
        it, why the verdict is what it is, and the combination."""
        lines = ["", f"verdict: {self.verdict}"]
        onset = self._onset()
        if onset is not None:
            before = ("the supply the machine file says" if "supply_bar_g" in onset
                      else "the log shows no such flow")
            lines.append(f"  from {onset['onset_s']:.1f} s into {onset['onset_run']} on (its "
                         f"clock {onset['onset_logger_s']:.1f} s); before that {before}")
        lines.append(f"  meter noise {self.meter_noise_l_min:.2g} NL/min"
                     + (f" (from {self.flat_pairs} neighbouring readings where nothing "
                        "switches)" if self.flat_pairs else " (from the residual's "
                        "differences: the log has too few flat stretches)")
                     + f"; left beyond it on held-out samples: {self.left_l_min:.2g} NL/min "
                       "RMS")
        lines += self._verdict_reasons()
        if self.combination and len(self.combination["effects"]) > 1:
            c = self.combination
            lines.append(f"combination: {' + '.join(c['effects'])}: held-out error "
                         f"{c['heldout'].error_pct:+.1f} %, RMSE "
                         f"{c['heldout'].rmse_l_min:.2f} NL/min")
        return lines

    def _verdict_reasons(self) -> list[str]:
        """Why the verdict is unexplained or none, and what it cannot be told from."""
        b = self.baseline
        lines = []
        if self.verdict == "unexplained":
            where = ", ".join(c.context for c in self.contexts[:3] if c.stands_out) or \
                ", ".join(c.context for c in self.contexts[:2])
            who = ", ".join(f"{a['consumer']} {a['residual_nl']:+.2f} NL"
                            for a in self.attribution[:2])
            lines.append("  no effect in the library explains the gap: "
                         + (f"the best ({self.effects[0].name}) takes away less than half "
                            "of it; " if self.effects else "")
                         + f"it lies mostly in {where or 'no one context'}"
                         + (f" (by consumer: {who})" if who else ""))
        if self.verdict == "none" and self.flexed is not None:
            lo, hi = self.band_pct
            inside = lo <= b.error_pct <= hi
            lines.append(f"  {'within' if inside else 'outside'} the model's accuracy: error "
                         f"{b.error_pct:+.1f} % against a band of {lo:+.1f} to {hi:+.1f} % (a "
                         "healthy machine takes a few per cent less than D1 books, nozzles "
                         "flow within a few per cent of their rating)"
                         + (": what the effects explain, the band explains as well"
                            if self.within_band else "")
                         + ("; the machine file's own values, moved within their "
                            "tolerance, explain it (below)"
                            if not inside and self.within_tolerance else ""))
        if self.within_tolerance:
            lines.append("  the best effects move the file's values no further than a healthy "
                         "machine's own differ from its file, so no fault: "
                         + "; ".join(self.within_tolerance))
        if self.dynamics_explain:
            lines.append("  the nominal machine through the physics plant explains the gap "
                         "as well as any effect: it is what D1 leaves out by design (air "
                         "a tube holds at atmosphere, heat, exhausts cut short), no fault")
        if self.alternatives:
            lines.append(f"  as good on held-out samples (the data cannot tell them apart): "
                         f"{', '.join(self.alternatives)}")
        return lines


def _short(physical: dict, depth: int = 0) -> str:
    parts = []
    for k, v in physical.items():
        if isinstance(v, dict):
            parts.append(f"{k}: {_short(v, depth + 1)}")
        elif isinstance(v, float):
            parts.append(f"{k}={v:.3g}")
        elif isinstance(v, list):
            parts.append(f"{k}=[{', '.join(f'{x:.3g}' for x in v)}]")
        else:
            parts.append(f"{k}={v}")
    text = ", ".join(parts)
    return text if depth or len(text) <= 90 else text[:87] + "..."


def _grid_dt(span_s: float, interval_s: float) -> float:
    """10 ms (fine for any meter's intervals and lag), doubled until the run has at most
    MAX_CELLS_PER_RUN cells, and further, while a reading still spans READING_CELLS
    cells, until it has at most LONG_RUN_CELLS: a long log's fits cost in proportion to
    its cells, and a reading averages what happened within it."""
    dt = 0.01
    while span_s / dt > MAX_CELLS_PER_RUN:
        dt *= 2.0
    while span_s / dt > LONG_RUN_CELLS and 2.0 * dt * READING_CELLS <= interval_s:
        dt *= 2.0
    return dt


def significant(base: Score, new: Score, noise_l_min: float) -> bool:
    """Does ``new`` beat ``base`` on held-out samples by more than noise allows? The
    mean-square error must fall by more than both 2 % of the baseline's and the
    fluctuation noise alone gives an MSE estimate (``3 sigma^2 sqrt(2/n)``)."""
    if not (math.isfinite(new.mse) and math.isfinite(base.mse)):
        return False
    n = max(new.n, 1)
    gain = base.mse - new.mse
    return gain > max(0.02 * base.mse, 3.0 * noise_l_min ** 2 * math.sqrt(2.0 / n))


# a good thermal-mass meter reads within about 1 % of reading (1-3 % is usual): an effect
# that explains less of the flow than that (RMS, beyond the noise) is not a finding
MATERIAL_SHARE = 0.01


def material(base: Score, new: Score, noise_l_min: float, mean_l_min: float) -> bool:
    """Does ``new`` explain a material part of the flow on held-out samples: does the
    RMS error beyond the noise fall by at least MATERIAL_SHARE of the mean flow?"""
    if not (math.isfinite(new.mse) and math.isfinite(base.mse)):
        return False
    before = math.sqrt(max(base.mse - noise_l_min ** 2, 0.0))
    after = math.sqrt(max(new.mse - noise_l_min ** 2, 0.0))
    return before - after >= MATERIAL_SHARE * mean_l_min


def diagnose(machine, runs: list[MeasuredRun], io=None, offsets=None,
             max_offset_s: float | None = None, effects=None,
             max_combination: int = MAX_COMBINATION, program=None,
             dynamic: bool = True, progress=None) -> Diagnosis:
    """Diagnose the gap between ``machine``'s prediction and measured ``runs``.

    ``io``: per run a recorded I/O :class:`~plcpred.sequencer.Timeline` (or None: the
    sequencer's); ``offsets``: per run the logger's clock at the machine's start (or
    None: aligned by correlation within ``max_offset_s``, default half the run up to
    120 s); ``effects``: names to try (default: all that apply); ``dynamic``: also score
    the nominal machine through the physics plant (:func:`_dynamic_reference`); where it
    explains part of the gap, each effect is also fitted beyond it, and the gap is
    ``none`` where it explains it as well as the best effects. ``progress``
    (:class:`~plcpred.progress.Progress`) shows the stage it is in."""
    progress = progress_or_off(progress)
    machine = as_machine(machine)
    warnings = list(machine.warnings)
    request = _checked_request(machine, runs, io, offsets, effects, warnings)
    progress.stage(f"predicting and aligning {len(runs)} log{'s' if len(runs) != 1 else ''}")
    aligned = _prepare_runs(machine, request, max_offset_s, program, warnings)
    g = _ground(machine, request, aligned, warnings)
    # the steps below lower judge.noise to what their best fits leave: each judges at
    # the noise known when it runs, so their order matters
    judge = _judge(g)
    progress.stage("the nominal machine" + (" through the physics plant" if dynamic else ""))
    nominal = _fit_nominal(g, dynamic)
    progress.stage(f"fitting {len(request.names)} effects")
    results = _fit_candidates(g, nominal, judge)
    progress.stage("ranking the effects and choosing the verdict")
    results = _rank_candidates(results, g, nominal, judge)
    exhaust = _exhaust_pairs(results, g, nominal, judge)
    where = _locate(g, judge.noise)
    results, verdict = _choose_verdict(results, exhaust, g, nominal, judge, max_combination)
    left = _judge_against_models(verdict, results, g, nominal, judge)
    return Diagnosis(machine, g.rds, g.base_score, nominal.heldout, judge.noise,
                     where.contexts, where.step_contexts, where.locations, results,
                     verdict.verdict, verdict.combination, g.fold_kind, warnings,
                     bases=g.bases, machine_model=g.mm, fit_context=g.ctx,
                     alternatives=verdict.alternatives,
                     reference=nominal.reference, on_plant=verdict.on_plant,
                     dynamics_explain=verdict.dynamics_explain, flexed=nominal.flexed,
                     band_pct=nominal.band, within_band=verdict.within_band,
                     within_tolerance=verdict.within_tolerance, tolerated=verdict.tolerated,
                     meter_noise_l_min=judge.meter_noise, flat_pairs=judge.flat_pairs,
                     left_l_min=left, attribution=where.attribution,
                     program=aligned.program)


class _Request(NamedTuple):
    """What :func:`diagnose` was asked, checked: one entry per run in each list."""
    runs: list[MeasuredRun]         # as the machine file's [meter] says to read them
    io: list                        # recorded I/O timelines (None: the sequencer's)
    offsets: list                   # the logger's clock at the machine's start, or None
    names: list[str]                # the effects to try


def _checked_request(machine: Machine, runs: list[MeasuredRun], io, offsets, effects,
                     warnings: list[str]) -> _Request:
    """The runs, I/O traces, offsets and effect names of a diagnosis, refused where they
    do not fit together or name an unknown effect."""
    if not runs:
        raise DiagnosisError("no measured runs given")
    io = list(io or [None] * len(runs))
    offsets = list(offsets or [None] * len(runs))
    if len(io) != len(runs) or len(offsets) != len(runs):
        raise DiagnosisError("give one --io (and one --offset) per measured run, or none")
    names = effects or list(EFFECTS)
    unknown = [n for n in names if n not in EFFECTS]
    if unknown:
        raise DiagnosisError(f"unknown effect {unknown[0]!r} (known: {', '.join(EFFECTS)})")
    runs = [_meter_corrected(run, machine.meter, warnings) for run in runs] \
        if machine.meter else list(runs)
    return _Request(runs, io, offsets, names)


@dataclass
class _Aligned:
    """The measured runs aligned to their predictions, and what made the predictions."""
    mm: MachineModel
    meter_tau: float | None         # the machine file's meter lag, if it gives one
    sequenced: bool                 # every prediction is the sequencer's (no --io)
    program: object                 # the program the sequencer runs (parsed once)
    compiled: object                # and compiled; None with recorded I/O
    rds: list[RunData] = field(default_factory=list)
    horizons: list[float] = field(default_factory=list)
    windows_s: list[float] = field(default_factory=list)    # the offset searched within
    period_s: float | None = None   # the machine's cycle, where the sequencer found one


def _prepare_runs(machine: Machine, request: _Request, max_offset_s: float | None,
                  program, warnings: list[str]) -> _Aligned:
    """Each run predicted (the sequencer, or its recorded I/O) and aligned to its
    prediction; where the logs do not say how they sample, a hint if instantaneous
    readings fit far better; where the meter's lag is not given, one lag for all."""
    mm = MachineModel.of(machine)
    meter_tau = machine.meter.tau_s if machine.meter and machine.meter.tau_s is not None \
        else None
    sequenced = all(tl is None for tl in request.io)
    if sequenced and not hasattr(program, "pous"):
        # parsed once for every unfold (timing effects run the sequencer again)
        program = machine.read_program(program)
    compiled = compile_program(program, observed_names(machine, program)) if sequenced \
        else None
    aligned = _Aligned(mm, meter_tau, sequenced, program, compiled)
    instants: list[RunData] = []    # the runs aligned as instantaneous readings
    for run, tl, off in zip(request.runs, request.io, request.offsets):
        instant = _align_run(machine, aligned, run, tl, off, max_offset_s, warnings)
        if instant is not None:
            instants.append(instant)
    if len(instants) == len(aligned.rds):
        _sampling_hint(aligned.rds, instants, warnings)
    if meter_tau is None:
        aligned.rds = _common_lag(aligned.rds, mm, aligned.windows_s, request.offsets)
    return aligned


def _align_run(machine: Machine, aligned: _Aligned, run: MeasuredRun, tl, off,
               max_offset_s: float | None, warnings: list[str]) -> RunData | None:
    """Add ``run`` aligned to its prediction to ``aligned``, checked against it; return
    it aligned as instantaneous readings too where it does not say how it samples."""
    window = _offset_window(run, max_offset_s, warnings)
    if off is None:
        horizon = run.span_s + window + 3.0
    else:
        horizon = max(1.0, float(run.time_s[-1]) - off + 1.0)
    aligned.horizons.append(horizon)
    aligned.windows_s.append(window)
    if tl is None:
        tl = _sequenced_timeline(machine, aligned, run, horizon)
    mm, meter_tau = aligned.mm, aligned.meter_tau
    # a log read far along a given clock is rendered over its own window (and the
    # meter's settling before it), not from the machine's start
    start_s = 0.0 if off is None else render_start_s(float(run.time_s[0]) - off)
    rm = RunModel(mm, tl, _grid_dt(tl.horizon_ns / 1e9 - start_s, run.interval_s),
                  start_s=start_s)
    rd = align(dataclasses.replace(run, sampling=run.sampling or "mean"), rm,
               mm.nominal(meter_tau or 0.0), window, meter_tau, off)
    _check_run(rd, rd.readings(mm.nominal(rd.meter_tau_s)), machine.name,
               off is not None, warnings)
    warnings += rd.notes
    _check_coverage(rd, warnings)
    aligned.rds.append(rd)
    if run.sampling is not None:
        return None
    # the instantaneous readings' clock lies within an interval of the means' (they
    # differ by where in its interval a reading stands): searched there alone
    return align(dataclasses.replace(run, sampling="instant"), rm,
                 mm.nominal(meter_tau or 0.0), window, meter_tau, off,
                 near_s=rd.offset_s if off is None else None)


def _offset_window(run: MeasuredRun, max_offset_s: float | None, warnings: list[str]
                   ) -> float:
    """How far from the log's first sample its clock offset is searched: ``max_offset_s``,
    by default half the run up to 120 s; never beyond the log's own length."""
    window = max_offset_s if max_offset_s is not None else min(
        120.0, max(2.0, 0.5 * run.span_s))
    if window > max(2.0, run.span_s):
        # an offset beyond the log's own length leaves no overlap to correlate, and
        # the search's grid grows with it (a window of 1e7 s would take 8 GB)
        warnings.append(f"--max-offset {window:g} s is longer than the log "
                        f"({run.span_s:g} s): searched within {max(2.0, run.span_s):g} s")
        window = max(2.0, run.span_s)
    return window


def _sequenced_timeline(machine: Machine, aligned: _Aligned, run: MeasuredRun,
                        horizon: float):
    """The sequencer's timeline of ``machine`` over ``horizon``; a log shorter than one
    cycle of it is refused."""
    tl = unfold(machine, horizon, program=aligned.program, compiled=aligned.compiled)
    if tl.info.get("period_s"):
        aligned.period_s = float(tl.info["period_s"])
        if run.span_s < aligned.period_s:
            raise DiagnosisError(
                f"{run.name}: the log covers {run.span_s:g} s, less than one cycle "
                f"of {machine.name} ({aligned.period_s:g} s)")
    return tl


class _SupplyStep(NamedTuple):
    """Where the logs' supply column steps: per run the onset (prediction time; 0: at
    the level after throughout, inf: before it or not logged), and the level after."""
    onsets: list[float]
    after_bar_g: float


@dataclass
class _Ground:
    """What every fit of a diagnosis works from: the aligned runs, each run's nominal
    model, the folds that keep samples out of a fit, and the fits' context."""
    machine: Machine
    mm: MachineModel
    rds: list[RunData]
    bases: list                     # per run: the nominal model (its meter lag, onset)
    residuals: list                 # per run: measured - predicted readings
    base_score: Score               # the nominal model on all samples, as aligned
    onsets: list[float] | None      # per run: where an always-on flow starts
    waiting: set[int]               # drives whose valve edges wait on the drives' timing
    names: list[str]                # the effects to try
    ctx: dict
    supply_logged_off: bool         # the logs' supply pressure is off the file's
    fold_masks: list
    fold_kind: str
    warnings: list[str]
    aligned: _Aligned
    supply_step: _SupplyStep | None = None  # where the logs' own supply column steps

    @property
    def plant_program(self):
        """The program the plant runs against (None: it follows the recorded edges)."""
        return self.aligned.program if self.aligned.compiled is not None else None


def _ground(machine: Machine, request: _Request, aligned: _Aligned,
            warnings: list[str]) -> _Ground:
    """The nominal model of each aligned run, with the onset of an always-on flow where
    the residual steps up, the folds, and the context every fit shares."""
    mm, rds = aligned.mm, aligned.rds
    bases: list = []
    residuals: list = []
    for rd in rds:
        base = mm.nominal(rd.meter_tau_s)
        bases.append(base)
        residuals.append(rd.measured_l_min - rd.readings(base))
    waiting = _waiting_drives(aligned, request)
    base_score = score(rds, bases)
    onsets = _leak_onsets(rds, residuals, aligned.period_s)
    if onsets is not None:
        bases = [dataclasses.replace(b, leak_onset_s=t) for b, t in zip(bases, onsets)]
    supply_step = _supply_onsets(rds, aligned.period_s)
    if supply_step is not None:
        bases = [dataclasses.replace(b, supply_onset_s=t)
                 for b, t in zip(bases, supply_step.onsets)]
    fold_masks = folds(rds, aligned.period_s)
    fold_kind = ("leave one run out" if len(rds) >= 2
                 else "alternate blocks of the run (fit on one half, scored on the other)")
    ctx = {"mean_l_min": max(base_score.measured_nl, 1e-9) * 60.0 / max(
        sum(float(rd.weight_s.sum()) for rd in rds), 1e-9),
        "meter_tau_s": aligned.meter_tau,
        "fitted_tau_s": max(rd.fitted_tau_s for rd in rds),
        "logged_supply_bar_g": _logged_supply_all(rds)}
    return _Ground(machine, mm, rds, bases, residuals, base_score, onsets, waiting,
                   request.names, ctx, _supply_logged_off(ctx["logged_supply_bar_g"], machine),
                   fold_masks, fold_kind, warnings, aligned, supply_step)


def _waiting_drives(aligned: _Aligned, request: _Request) -> set[int]:
    """The drives whose valve edges wait on the drives' timing (a closed loop), where
    a timing effect is to be tried on the sequencer's runs; where there are any, the
    machine model gets the resequencer that runs the program again for them."""
    mm = aligned.mm
    if not (mm.drives and aligned.sequenced and set(CLOSED_LOOP_EFFECTS) & set(request.names)):
        return set()
    reseq = Resequencer(mm, aligned.rds, aligned.horizons, aligned.windows_s,
                        request.offsets, aligned.program, aligned.meter_tau)
    reseq.compiled = aligned.compiled
    waiting = reseq.waiting_drives()
    if waiting:
        mm.resequencer = reseq
    return waiting


@dataclass
class _Judge:
    """Whether a held-out score beats another by more than the noise allows and by a
    material share of the flow. The noise is the one known when asked: as the fits go,
    it falls to what the best of them leaves."""
    noise: float                    # NL/min
    mean_l_min: float
    meter_noise: float              # the meter's own, from flat stretches of the logs
    flat_pairs: int                 # the flat neighbours it rests on (0: the noise's)

    def finding(self, base: Score, new: Score) -> bool:
        """Does ``new`` beat ``base`` as a verdict must (:func:`significant`,
        :func:`material`)?"""
        return significant(base, new, self.noise) and material(base, new, self.noise,
                                                               self.mean_l_min)

    def beyond_accuracy(self, base: Score, new: Score) -> bool:
        """:meth:`finding` at the meter's own noise where the log's flat stretches tell
        it (no fit lowers it: the misfit a fit leaves is what the model's accuracy may
        leave too). A log without them has only the residual's differences, which carry
        every stroke the model places off (at 1 Hz, a timer-driven rig's are several
        times the meter's noise), and is judged at the noise the verdict was."""
        at = self.meter_noise if self.flat_pairs else self.noise
        return significant(base, new, at) and material(base, new, at, self.mean_l_min)


def _judge(g: _Ground) -> _Judge:
    """The judge at the noise of the residual's differences before any fit, and the
    meter's own noise."""
    noise = float(np.median([noise_level_l_min(r) for r in g.residuals]))
    meter_noise, flat_pairs = _meter_noise(g.rds, g.bases, noise)
    return _Judge(noise, g.ctx["mean_l_min"], meter_noise, flat_pairs)


@dataclass
class _Nominal:
    """The nominal models an effect must beat on held-out samples."""
    fit: FitResult                  # D1, its clock and meter lag fitted on all samples
    heldout: Score                  # D1 on held-out samples
    flexed: EffectResult | None     # D1 flexed within its own accuracy (diagnose.band)
    band: tuple[float, float]       # that accuracy in total air (low, high error_pct)
    reference: EffectResult | None  # the machine file through the physics plant
    reference_cost: dict            # what the reference's plant runs cost


def _fit_nominal(g: _Ground, dynamic: bool) -> _Nominal:
    """D1 with its timing_params (clock, meter lag) fitted as every effect's are: on all
    samples, then each fold from there; D1 flexed within its own accuracy, what a healthy
    machine may do; and, where asked, the machine file through the physics plant."""
    mm, rds, bases, ctx = g.mm, g.rds, g.bases, g.ctx
    base_all = fit_effects([], mm, rds, [np.ones(len(rd.end_s), bool) for rd in rds],
                           bases, ctx)
    base_heldout = heldout([], mm, rds, bases, ctx, g.fold_masks, start=base_all.theta)
    flexed = _evaluate([ModelForm(drive_factor_range(mm, bases[0]))], mm, rds, bases,
                       ctx, g.fold_masks) if mm.models else None
    band = _band(mm, rds, bases)
    reference_cost: dict = {}
    reference = _dynamic_reference(g.machine, mm, rds, bases, ctx, g.fold_masks,
                                   g.warnings, g.plant_program, g.aligned.compiled,
                                   reference_cost) \
        if dynamic and mm.drives else None
    if reference is not None and flexed is not None:
        flexed = _flexed_on_plant(flexed, mm, rds, bases, ctx, g.fold_masks)
    return _Nominal(base_all, base_heldout, flexed, band, reference, reference_cost)


def _flexed_on_plant(flexed: EffectResult, mm, rds, bases, ctx, fold_masks
                     ) -> EffectResult:
    """The better on held-out samples of ``flexed`` (D1 flexed within its band) and
    the plant's reference flexed within the same accuracy: where the plant models a
    machine's strokes better than D1 (long tubes, fills that do not settle), a healthy
    machine's error is the plant's own, not D1's, and an effect must beat that."""
    on_plant = _evaluate([ModelForm(plant_factor_range(mm))], mm, rds, _plant_bases(bases),
                         ctx, fold_masks)
    if on_plant.heldout_score.rmse_l_min < flexed.heldout_score.rmse_l_min:
        on_plant.beyond_plant = True
        return on_plant
    return flexed


def _effect_forms(g: _Ground) -> dict[str, list[Effect]]:
    """Per effect name, the forms of it to fit: applied to the predicted edges, with the
    program waiting on the drives (every later edge moved), with strokes cut short, and
    a leak from its onset; whichever holds on held-out samples stands for the effect."""
    mm = g.mm
    cut_drives = _cut_drives(mm, g.rds)
    cut = bool(cut_drives)
    # a slower stroke on a drive whose strokes all complete may be cut short by an edge
    # that does not wait for it (a valve on a timer); where the program waits on the
    # drive (its edges move with the strokes) the edge comes after the slower stroke
    uncut = tuple(k for k, m in enumerate(mm.drive_models())
                  if m.stroke_time_s and k not in cut_drives | g.waiting)
    slowed = {StrokeTime.name: StrokeTime(partial_drives=uncut)} if uncut else {}
    forms = {name: [e for e in (EFFECTS[name], CLOSED_LOOP_EFFECTS.get(name),
                                CUT_STROKE_EFFECTS.get(name) if cut else None,
                                slowed.get(name))
                    if e is not None and e.applies(mm)] for name in g.names}
    if g.supply_logged_off and forms.get(SupplyPressure.name):
        # the log reads the supply: D1's own error must not pull the fit off that reading
        forms[SupplyPressure.name].append(WithinBand(EFFECTS[SupplyPressure.name]))
    if g.supply_step is not None and forms.get(SupplyPressure.name):
        # the log reads the supply's step: D1's own error must not pull the fit off it
        stepped = SupplyFrom([(rd.run.name, t if 0.0 < t < math.inf else None, rd.offset_s)
                              for rd, t in zip(g.rds, g.supply_step.onsets)],
                             g.supply_step.after_bar_g)
        forms[SupplyPressure.name] += [stepped, WithinBand(stepped)]
    if g.onsets is not None and "leak" in forms:
        forms["leak"].append(LeakFrom([(rd.run.name, t if 0.0 < t < math.inf else None,
                                        rd.offset_s) for rd, t in zip(g.rds, g.onsets)]))
    return forms


@dataclass
class _Candidates:
    """Each effect's forms, and the fits of them so far."""
    g: _Ground
    forms: dict[str, list[Effect]]
    tried: dict[str, list[EffectResult]]
    plant_bases: list               # the nominal models on top of the plant's reference

    def fit_forms(self, name: str, beyond: bool) -> None:
        """Fit each form of effect ``name`` on D1, or ``beyond`` on top of the plant's
        reference: open-loop forms only there (a resequenced run has no plant run of its
        own)."""
        g = self.g
        bases = self.plant_bases if beyond else g.bases
        self.tried[name] += [_evaluate([e], g.mm, g.rds, bases, g.ctx, g.fold_masks)
                             for e in self.forms[name]
                             if not beyond or e is not CLOSED_LOOP_EFFECTS.get(name)]

    def best_heldout(self, nominal: Score, beyond: bool) -> Score:
        """A nominal model's held-out score, or its best effect's so far."""
        return min([nominal] + [e.heldout_score for t in self.tried.values() for e in t
                                if e.beyond_plant == beyond], key=lambda x: x.rmse_l_min)

    def best(self) -> list[EffectResult]:
        """Each effect's best form on held-out samples, the best first."""
        results = [min(t, key=lambda e: e.heldout_score.rmse_l_min)
                   for t in self.tried.values() if t]
        results.sort(key=lambda e: e.heldout_score.rmse_l_min)
        return results


def _fit_candidates(g: _Ground, nominal: _Nominal, judge: _Judge) -> list[EffectResult]:
    """Every effect fitted on D1, and on top of the plant where the plant explains a
    material part of the gap, and through the plant where that may pay; each effect's
    best form on held-out samples, the best first."""
    names, reference = g.names, nominal.reference
    candidates = _Candidates(g, _effect_forms(g), {name: [] for name in names},
                             _plant_bases(g.bases))
    # the effects of no drive (a leak, a nozzle's flow, the meter) first, each fitted on
    # D1 and on the plant's reference: which of the two is the better nominal model of
    # the drives is best seen with them fitted, since a fault that adds air (a stronger
    # nozzle) hides D1's own excess behind it
    for name in names:
        if name in NOT_OF_THE_DRIVES:
            candidates.fit_forms(name, False)
            if reference is not None:
                candidates.fit_forms(name, True)
    on_reference = _plant_explains_part(candidates, nominal, judge)
    if (reference is not None and g.machine.path is not None
            and (reference.heldout_score.rmse_l_min < nominal.heldout.rmse_l_min
                 or on_reference)):
        _make_plant_variants(g, nominal)
    for name in names:
        if name not in NOT_OF_THE_DRIVES:
            candidates.fit_forms(name, False)
            if on_reference:
                candidates.fit_forms(name, True)
    if g.mm.plant_variants is not None and not _explained_on_d1(candidates.tried,
                                                                judge.noise):
        _fit_through_plant(candidates, reference)
    return candidates.best()


def _plant_explains_part(candidates: _Candidates, nominal: _Nominal, judge: _Judge
                         ) -> bool:
    """Does the plant explain a material part of the gap, alone or with each nominal
    model's best effect of no drive? Then the drives' effects are also fitted on top
    of it. The test is the verdict's, at the noise known before any fit (the fits lower
    it later)."""
    reference = nominal.reference
    if reference is None:
        return False
    d1_side = candidates.best_heldout(nominal.heldout, False)
    plant_side = candidates.best_heldout(reference.heldout_score, True)
    return judge.finding(nominal.heldout, reference.heldout_score) or judge.finding(
        d1_side, plant_side)


def _make_plant_variants(g: _Ground, nominal: _Nominal) -> None:
    """The plant is the better nominal model of this machine, if only by a little (a
    fault it misses as much as D1 does hides how much else it explains): the effects
    that change how its drives fill and move are also fitted through it, each value a
    plant run of the whole log (a variant's cycle is its own), so only where that costs
    few integration pieces: the reference's per machine second. Else a warning says
    why not."""
    compiled = g.aligned.compiled
    pieces = variant_pieces(nominal.reference_cost, g.rds, replayed=compiled is None)
    if pieces <= MAX_VARIANT_PIECES:
        try:
            g.mm.plant_variants = PlantVariants(g.machine, g.mm, g.rds, g.bases,
                                                g.plant_program, compiled)
        except PlcpredError as e:
            g.warnings.append(f"effects not fitted through the physics plant: {e}")
    else:
        g.warnings.append(
            f"effects not fitted through the physics plant: each value would cost "
            f"about {pieces:,.0f} integration pieces (the limit is "
            f"{MAX_VARIANT_PIECES:,}); a shorter log, or fewer fast-cycling drives, "
            f"fits them so")


def _explained_on_d1(tried: dict[str, list[EffectResult]], noise: float) -> bool:
    """Does an effect of no drive (a leak, a nozzle's flow, the meter), applied to D1,
    explain the log to its noise? Then the drives' physics (the plant) has nothing left
    to explain. (Not so an effect of the drives: a lower supply or an exhaust applied to
    D1 fits the sorter's longer tubes to the noise, what its fills cut short do to them;
    nor one fitted beyond the plant: a leak on the plant comes near the noise on a clamp
    station's slower valves, which the plant's variants then fit to it.) No noise
    exceeds what the best open-loop fit on D1 leaves: the differences of the residual that
    estimate it before any fit also carry a fault's own signal."""
    open_loop = [(name, e) for name, t in tried.items() for e in t if not e.beyond_plant]
    floor = min([noise] + [e.fit_score.rmse_l_min for _, e in open_loop])
    return any(e.heldout_score.rmse_l_min <= DOWN_TO_NOISE * floor
               for name, e in open_loop if name in NOT_OF_THE_DRIVES)


def _fit_through_plant(candidates: _Candidates, reference: EffectResult) -> None:
    """The effects through the plant, each value a plant run. A plant form is its
    open-loop form plus the drives' dynamics (a fill's pace moves the strokes, and with
    them the program), so where it wins its open-loop forms come near the best open-loop
    error: an effect whose open-loop forms all leave more than PLANT_FORM_ERROR_RATIO times it
    is not run through the plant."""
    g, tried = candidates.g, candidates.tried
    reach = PLANT_FORM_ERROR_RATIO * min((e.heldout_score.rmse_l_min
                                    for t in tried.values() for e in t),
                                   default=float("inf"))
    for name in g.names:
        if (name in PLANT_FORMS and PLANT_FORMS[name].applies(g.mm)
                and (not tried[name] or any(e.heldout_score.rmse_l_min <= reach
                                            for e in tried[name]))):
            try:
                # from the reference's clock and meter lag: a sweep of plant runs
                # holds them while it chooses, and the alignment's are D1's
                tried[name].append(_evaluate([PLANT_FORMS[name]], g.mm, g.rds,
                                             reference.fit.params, g.ctx, g.fold_masks))
            except PlcpredError as e:
                g.warnings.append(f"{name} not fitted through the plant: {e}")


def _rank_candidates(results: list[EffectResult], g: _Ground, nominal: _Nominal,
                     judge: _Judge) -> list[EffectResult]:
    """The effects ranked for the verdict: the baseline fitted again from a better
    clock and lag an effect found, the noise lowered to what the best fit leaves, ties
    broken by parsimony and plausibility, and a supply the logs' pressure shows off
    first among equals."""
    better = baseline_from_effects(nominal.fit, results + [nominal.reference] * (
        nominal.reference is not None), g.mm, g.rds, g.bases, g.ctx)
    if better is not None:
        nominal.fit = better
        nominal.heldout = heldout([], g.mm, g.rds, g.bases, g.ctx, g.fold_masks,
                                  start=better.theta)
    # differences of the residual overstate the noise when the log is too coarse for
    # the strokes (1 Hz against 0.2 s strokes); no noise can exceed what the best fit
    # leaves
    if results:
        judge.noise = min(judge.noise, min(e.fit_score.rmse_l_min for e in results))
    results = tie_break(results, judge.noise, g.mm)
    return _logged_supply_first(results, judge.noise, g.supply_logged_off)


class _Exhaust(NamedTuple):
    """An incomplete exhaust among the effects, and each other effect fitted with it."""
    exhaust: EffectResult | None
    first_implausible: bool         # the first effect's values are no plant's
    pairs: list[EffectResult]


def _exhaust_pairs(results: list[EffectResult], g: _Ground, nominal: _Nominal,
                   judge: _Judge) -> _Exhaust:
    """Where an incomplete exhaust comes first, or explains part of the gap behind a
    first whose values no plant has (a drive with most of its tube gone: what an
    exhaust cut short does to a fill), every other effect fitted with it
    (:func:`_with_exhaust`)."""
    exhaust = next((e for e in results if e.name == IncompleteExhaust.name), None)
    first_implausible = bool(results) and _implausible(results[0], g.mm) is not None
    pairs = []
    if exhaust is not None and (exhaust is results[0] or (
            first_implausible and judge.finding(nominal.heldout, exhaust.heldout_score))):
        pairs = _with_exhaust(exhaust, results, g.mm, g.rds, _bases_of(exhaust, g.bases),
                              g.ctx, g.fold_masks, g.warnings)
        if pairs:
            # an exhaust's mismatch with D1 (a sorter's chatter) left in every single
            # fit inflates the noise; the pairs say how little is left
            judge.noise = min(judge.noise, min(p.fit_score.rmse_l_min for p in pairs))
    return _Exhaust(exhaust, first_implausible, pairs)


class _Where(NamedTuple):
    """Where the residual lies: by context, by step, in time, by consumer."""
    contexts: list
    step_contexts: list
    locations: list[dict]
    attribution: list


def _locate(g: _Ground, noise: float) -> _Where:
    """The residual by context (named where it stands out of ``noise``), its windows
    in those contexts, by consumer, and by the program's steps where every run has
    them."""
    labels = [sample_contexts(rd, p) for rd, p in zip(g.rds, g.bases)]
    weights = [rd.weight_s for rd in g.rds]
    ctx_list = contexts(labels, g.residuals, weights, noise)
    named = {c.context for c in ctx_list if c.stands_out}
    locations = []
    for rd, lab, r in zip(g.rds, labels, g.residuals):
        locations += windows(rd, lab, r, noise, named)
    locations.sort(key=lambda x: -abs(x["residual_nl"]))
    by_consumer = attribution(g.rds, g.bases, g.residuals)
    steps = [step_contexts(rd) for rd in g.rds]
    step_list = contexts(steps, g.residuals, weights, noise) if all(
        s is not None for s in steps) else []
    return _Where(ctx_list, step_list, locations, by_consumer)


@dataclass
class _Verdict:
    """The verdict, the combination of effects that starts with it, and why."""
    verdict: str = "none"
    combination: dict | None = None
    alternatives: list[str] = field(default_factory=list)
    on_plant: bool = False          # the plant explains a real part of the gap
    within_band: bool = False       # the model's own accuracy explains it as well
    # why the effects' values lie within a healthy machine's tolerance of its file
    within_tolerance: list[str] = field(default_factory=list)
    # the combination those values come from (diagnose.corrected may write them)
    tolerated: dict | None = None
    dynamics_explain: bool = False  # the plant explains it as well as the effects

    def no_fault(self) -> None:
        """No fault after all: the effects stay ranked in the report."""
        self.verdict, self.combination, self.alternatives = "none", None, []


def _choose_verdict(results: list[EffectResult], exhaust: _Exhaust, g: _Ground,
                    nominal: _Nominal, judge: _Judge, max_combination: int
                    ) -> tuple[list[EffectResult], _Verdict]:
    """(the effects, those at a bound of their range last; the verdict): the first
    effect where it beats D1 by more than the noise allows and materially, with the
    effects added to it one at a time while each still does."""
    reference = nominal.reference
    # the plant explains a real part of the gap (D1's own limits): then no noise exceeds
    # what it leaves, and an effect must beat it too
    on_plant = reference is not None and judge.finding(nominal.heldout,
                                                       reference.heldout_score)
    if on_plant:
        judge.noise = min(judge.noise, reference.fit_score.rmse_l_min)
    # a value at its bound wanted more than is physical: it never wins, however well
    # it fits (ranked after those within their bounds)
    for e in results:
        e.at_bound = _at_bound(e, g.mm, g.ctx, g.rds, g.bases)
    results = [e for e in results if not e.at_bound] + [e for e in results if e.at_bound]
    verdict = _Verdict(on_plant=on_plant)
    if results and judge.finding(nominal.heldout, results[0].heldout_score) \
            and not results[0].at_bound:
        best = _first_verdict(verdict, results, exhaust, g, nominal, judge)
        best = _combine(best, results, g, nominal, judge, max_combination)
        verdict.combination = {"effects": [e.name for e in best.fit.effects],
                               "fit": best.fit, "heldout": best.heldout_score,
                               "score": best.fit_score, "physical": best.physical,
                               "beyond_plant": best.beyond_plant}
    return results, verdict


def _first_verdict(verdict: _Verdict, results: list[EffectResult], exhaust: _Exhaust,
                   g: _Ground, nominal: _Nominal, judge: _Judge) -> EffectResult:
    """Name the first effect in ``verdict``, with the effects the held-out samples
    cannot tell from it (a dead volume and an incomplete exhaust when every dwell is the
    same); or, past the exhaust every fast machine shows, the fault beyond it, else the
    exhaust. Returns the fit the combination starts from."""
    first = results[0]
    verdict.verdict = first.name
    verdict.alternatives = [e.name for e in results[1:]
                            if judge.finding(nominal.heldout, e.heldout_score)
                            and not significant(e.heldout_score, first.heldout_score,
                                                judge.noise)]
    pairs = exhaust.pairs
    # the exhaust first, or an implausible first
    past = bool(pairs) and (verdict.verdict == IncompleteExhaust.name or (
        exhaust.first_implausible and judge.finding(nominal.heldout,
                                                    exhaust.exhaust.heldout_score)))
    beyond = [p for p in pairs if judge.finding(exhaust.exhaust.heldout_score,
                                                p.heldout_score)
              and _implausible(p, g.mm) is None]
    if past and beyond:
        # the fault lies beyond the exhaust every fast machine shows (_with_exhaust):
        # it is the verdict, and the combination starts from the pair
        best = min(beyond, key=lambda p: p.heldout_score.rmse_l_min)
        verdict.verdict, verdict.alternatives = best.fit.effects[-1].name, []
        return best
    if past and verdict.verdict != IncompleteExhaust.name:
        verdict.verdict, verdict.alternatives = exhaust.exhaust.name, []
        return exhaust.exhaust
    return first


def _combine(best: EffectResult, results: list[EffectResult], g: _Ground,
             nominal: _Nominal, judge: _Judge, max_combination: int) -> EffectResult:
    """``best`` with the other effects that beat D1 added one at a time, the one that
    helps most each time, while each still improves the held-out error by more than
    the noise allows, materially (up to ``max_combination`` effects)."""
    chosen = list(best.fit.effects)
    candidates = [e for e in results
                  if judge.finding(nominal.heldout, e.heldout_score)
                  and e.name not in {c.name for c in chosen}]
    # nothing is left to explain once the held-out error is down to the noise
    while (len(chosen) < max_combination and candidates
           and best.heldout_score.rmse_l_min > DOWN_TO_NOISE * judge.noise):
        trials = [_evaluate_or_warn(chosen + list(c.fit.effects), g.mm, g.rds,
                                    _bases_of(best, g.bases), g.ctx, g.fold_masks,
                                    g.warnings)
                  for c in candidates]
        trials = [t for t in trials if t is not None]
        trial = min(trials, key=lambda e: e.heldout_score.rmse_l_min, default=None)
        if trial is None or not judge.finding(best.heldout_score, trial.heldout_score):
            break
        best = trial
        chosen = list(trial.fit.effects)
        candidates = [c for c in candidates if c.name not in {e.name for e in chosen}]
    return best


def _judge_against_models(verdict: _Verdict, results: list[EffectResult], g: _Ground,
                          nominal: _Nominal, judge: _Judge) -> float:
    """The verdict held against what needs no fault: none where the nominal model
    flexed within its own accuracy, or the machine file through the plant, explains the
    gap as well; unexplained where a material residual is left that the effects do not
    explain. Returns the held-out error beyond the meter's noise that is left."""
    if verdict.combination is not None and not _beats_band(
            verdict.verdict, verdict.combination, nominal.flexed, nominal.band,
            g.base_score, judge.beyond_accuracy, g.supply_logged_off):
        # what the effects explain, the nominal model flexed within its own accuracy
        # explains as well (or the total lies within the band): no fault
        verdict.within_band = True
        verdict.no_fault()
    # what is left is judged after the best explanation: a fault's, one within the
    # file's tolerance, else the file flexed within the model's accuracy
    explanation = verdict.combination
    if (verdict.combination is not None and verdict.on_plant
            and not judge.finding(nominal.reference.heldout_score,
                                  verdict.combination["heldout"])):
        # the machine file, modelled dynamically, explains the gap as well as the best
        # effects do: D1's own limits, no fault (the effects stay ranked in the report)
        verdict.dynamics_explain = True
        verdict.no_fault()
    if verdict.combination is not None:
        why = _within_tolerance(verdict, results, g, nominal, judge)
        if why:
            # the effects only move the file's values as far as a healthy machine's
            # own differ from its file: no fault, and the report says how far
            verdict.within_tolerance = why
            verdict.tolerated = verdict.combination
            verdict.no_fault()
    left = _left_over(explanation, nominal.flexed, nominal.heldout, judge.meter_noise)
    # with no fault named and the total within the band, what is left is the shape of
    # the model's own error (air a stroke takes later or sooner than D1 books it), which
    # a healthy machine shows as well
    healthy_total = verdict.combination is None and \
        nominal.band[0] <= g.base_score.error_pct <= nominal.band[1]
    if _unexplained_gap(left, explanation, nominal.flexed, nominal.heldout,
                        judge.meter_noise, g.ctx["mean_l_min"]) \
            and not verdict.dynamics_explain and not healthy_total:
        verdict.verdict = "unexplained"
    return left


# a residual beyond the meter's noise of at least this share of the mean flow (RMS) is
# material: more than a good meter's accuracy and the model's shape error on strokes
UNEXPLAINED_SHARE = 0.05
# and the best explanation must take at least this share of the gap beyond the noise
# away, else the gap is unexplained rather than that effect
EXPLAINED_SHARE = 0.5


def _leak_onsets(rds: list[RunData], residuals: list, period_s: float | None
                 ) -> list[float] | None:
    """Per run where an always-on flow starts (diagnose.onset): the step's time in a
    run whose residual steps up, 0 in a run whose residual sits at the level after the
    steps (the flow runs throughout), infinity in one at the level before (it has not
    started); None where no run's residual steps up."""
    flow = sum(float(rd.measured_l_min @ rd.weight_s) for rd in rds)
    mean_l_min = flow / max(sum(float(rd.weight_s.sum()) for rd in rds), 1e-9)
    steps = [step_onset(rd.end_s, r, rd.weight_s, mean_l_min, period_s)
             for rd, r in zip(rds, residuals)]
    up = [o for o in steps if o is not None and o.step_l_min > 0]
    if not up:
        return None
    before = float(np.mean([o.before_l_min for o in up]))
    after = float(np.mean([o.after_l_min for o in up]))
    out = []
    for rd, r, o in zip(rds, residuals, steps):
        if o is not None and o.step_l_min > 0:
            out.append(o.time_s)
            continue
        level = float(np.average(r, weights=rd.weight_s))
        out.append(0.0 if abs(level - after) < abs(level - before) else math.inf)
    return out


def _supply_onsets(rds: list[RunData], period_s: float | None) -> _SupplyStep | None:
    """Where the supply the logs record steps (diagnose.onset on their pressure
    column: a step of at least its MIN_STEP_SHARE of the level, standing out of the
    column's own scatter); None where no run's does."""
    steps = []
    for rd in rds:
        p = rd.run.supply_bar_g
        ok = np.isfinite(p) if p is not None else None
        if ok is None or ok.sum() < 2:
            steps.append((None, None))
            continue
        # readings in prediction time, each standing for its interval
        end_s = rd.run.time_s[ok] - rd.offset_s
        weight_s = np.full(len(end_s), rd.run.interval_s)
        level = float(np.mean(p[ok]))
        steps.append((step_onset(end_s, p[ok], weight_s, abs(level), period_s), level))
    found = [o for o, _ in steps if o is not None]
    if not found:
        return None
    before = float(np.mean([o.before_l_min for o in found]))
    after = float(np.mean([o.after_l_min for o in found]))
    onsets = []
    for o, level in steps:
        if o is not None:
            onsets.append(max(o.time_s, 0.0))
        elif level is not None and abs(level - after) < abs(level - before):
            onsets.append(0.0)
        else:
            onsets.append(math.inf)
    return _SupplyStep(onsets, after)


def _meter_noise(rds: list[RunData], bases: list, fallback: float) -> tuple[float, int]:
    """(the meter's noise, flat neighbours it rests on) over all runs
    (:func:`meter.flat_noise_l_min`), else ``fallback`` (differences of the residual)."""
    found = [flat_noise_l_min(rd.measured_l_min, rd.readings(b)) for rd, b in zip(rds, bases)]
    known = [(v, n) for v, n in found if v is not None]
    if not known:
        return fallback, 0
    return float(np.median([v for v, _ in known])), sum(n for _, n in known)


def _beyond(score_: Score, noise: float) -> float:
    """RMS error beyond the noise (NL/min)."""
    return math.sqrt(max(score_.mse - noise ** 2, 0.0))


def _left_over(combination: dict | None, flexed, base_heldout: Score,
               meter_noise: float) -> float:
    """The held-out RMS error beyond the meter's noise that the best explanation
    leaves: the verdict's combination, else the nominal model flexed within its band."""
    if combination is not None:
        return _beyond(combination["heldout"], meter_noise)
    return _beyond(flexed.heldout_score if flexed is not None else base_heldout,
                   meter_noise)


def _unexplained_gap(left: float, combination: dict | None, flexed, base_heldout: Score,
                     meter_noise: float, mean_l_min: float) -> bool:
    """Is a material residual left that the library does not explain: more than
    UNEXPLAINED_SHARE of the mean flow beyond the meter's noise, after an explanation
    that took less than EXPLAINED_SHARE of the gap away (or none at all)?"""
    if left <= UNEXPLAINED_SHARE * mean_l_min:
        return False
    if combination is None:
        return True
    before = _beyond(flexed.heldout_score if flexed is not None else base_heldout,
                     meter_noise)
    return before <= 0 or 1.0 - left / before < EXPLAINED_SHARE


def _band(mm: MachineModel, rds: list[RunData], bases: list) -> tuple[float, float]:
    """The model-form band in total air over all runs (:func:`band.band_pct`) from
    the air each run's nominal prediction books on drives and on nozzles and leaks."""
    drive_nl = passive_nl = 0.0
    for rd, base in zip(rds, bases):
        cells = rd.model.consumer_cells(base)
        drive_nl += float(cells[mm.drives].sum()) if mm.drives else 0.0
        passive_nl += float(cells[mm.passives].sum()) if mm.passives else 0.0
    return band_pct(mm, bases[0], drive_nl, passive_nl)


def _within_tolerance(verdict: _Verdict, results: list[EffectResult], g: _Ground,
                      nominal: _Nominal, judge: _Judge) -> list[str]:
    """Why the verdict's effects lie within a healthy machine's tolerance of its file
    (:meth:`Effect.within_tolerance`); empty where they name a fault. An effect added
    to a verdict within tolerance is a fault only where it is one on its own: a
    finding, within its bounds, that beats the file flexed within its own accuracy."""
    why, rest = [], []
    for e, theta in verdict.combination["fit"].by_effect():
        reason = e.within_tolerance(g.mm, theta, g.ctx)
        if reason is None:
            rest.append(e.name)
        else:
            why.append(f"{e.name}: {reason}")
    if rest and _as_good_within_tolerance(verdict.combination, g, judge):
        return [f"{name}: moved to the edge of a healthy machine's tolerance of its file, "
                "it explains the logs as well" for name in rest] + why
    if not why or verdict.verdict in rest:
        return []
    against = nominal.flexed.heldout_score if nominal.flexed is not None else nominal.heldout
    alone = [r for r in results if r.name in rest and not r.at_bound
             and judge.finding(against, r.heldout_score)]
    return [] if alone else why


def _as_good_within_tolerance(combination: dict, g: _Ground, judge: _Judge) -> bool:
    """Do the combination's values, each moved to the nearest a healthy machine's
    tolerance of its file allows (:meth:`Effect.clipped_to_tolerance`), explain the logs
    as well, the values beyond it no finding? A fit whose objective is flat beyond the
    tolerance (a stroke time that only has to end before a sensor drops) lands anywhere
    on that flat; the least departure from the file that explains the logs is what a
    healthy machine claims."""
    fit: FitResult = combination["fit"]
    clipped = [e.clipped_to_tolerance(g.mm, part, g.ctx) for e, part in fit.by_effect()]
    if any(c is None for c in clipped):
        return False                # an effect no healthy machine shows
    # the clock adjustment and a fitted meter lag follow the effects' values
    theta = np.concatenate(clipped + [np.asarray(fit.theta[sum(fit.counts):], float)])
    bases = _plant_bases(g.bases) if combination.get("beyond_plant") else g.bases
    try:
        params = params_at(fit.effects, g.mm, g.rds, bases, g.ctx, theta)
    except PlcpredError:
        return False                # the plant or the sequencer cannot run those values
    return not judge.finding(score(g.rds, params), combination["score"])


def _beats_band(verdict: str, combination: dict, flexed: "EffectResult | None",
                band: tuple[float, float], base: Score, finding, supply_logged_off: bool
                ) -> bool:
    """Does the combination explain more than the model's own accuracy can: beat the
    nominal model flexed within the band on held-out samples, and, where the verdict
    scales the whole machine's air (VOLUME_EFFECTS), with the total outside the band?
    A supply the log's own pressure column shows off the file's is a reading, not a fit:
    it needs no band."""
    if flexed is None or verdict in SHAPE_EFFECTS or (
            verdict == "supply_pressure" and supply_logged_off):
        return True
    if not finding(flexed.heldout_score, combination["heldout"]):
        return False
    return not (verdict in VOLUME_EFFECTS and band[0] <= base.error_pct <= band[1])


def _logged_supply_first(results: list[EffectResult], noise: float, logged_off: bool
                         ) -> list[EffectResult]:
    """Where the logs' own pressure column shows the supply off the file's, a supply
    fitted to that reading goes first among effects the held-out samples cannot tell
    from the first (a meter reading low scales every flow alike, as a lower supply
    does): the log says which it is."""
    supply = next((e for e in results if e.name == "supply_pressure"), None)
    if not logged_off or supply is None or supply is results[0] or supply.at_bound:
        return results
    if significant(supply.heldout_score, results[0].heldout_score, noise):
        return results
    return [supply] + [e for e in results if e is not supply]


def _supply_logged_off(logged_bar_g: float | None, machine) -> bool:
    """Does the logs' mean supply pressure (:func:`_logged_supply_all`) differ from the
    machine file's by more than a gauge's reading error and a regulator's swing?"""
    return logged_bar_g is not None and abs(logged_bar_g - machine.supply_bar_g) > \
        SUPPLY_NOTE_BAR


def _at_bound(result: EffectResult, mm, ctx: dict, rds: list[RunData], bases: list
              ) -> bool:
    """Does any of ``result``'s effect parameters (not the clock or the meter's lag) sit
    at a bound of its range, other than a bound of zero (a leak, a lag or an extra
    volume of none: that part of the effect is off), where it matters: the fit on all
    samples is materially worse with it back at its initial value? It wanted more than
    is physical there. (A drive whose strokes the log cannot resolve lets its factor
    drift to a bound without changing anything.)"""
    theta = np.array(result.fit.theta, dtype=float)
    k = 0
    for e, part in result.fit.by_effect():
        if e.name == SupplyPressure.name and _supply_logged_off(
                ctx.get("logged_supply_bar_g"), mm.machine):
            # the log reads a supply off the file's: the bounds are that reading and a
            # gauge's error, not what is physical, and the reading is the finding
            k += len(part)
            continue
        for j, spec in enumerate(e.params(mm, ctx)):
            value = float(part[j]) if j < len(part) else math.nan
            near = AT_BOUND_SHARE * (spec.upper - spec.lower)
            if near > 0 and not spec.nuisance and any(bound != 0.0 and abs(value - bound) < near
                                for bound in (spec.lower, spec.upper)):
                back = theta.copy()
                back[k + j] = spec.init
                if _matters(result, back, mm, rds, _bases_of(result, bases)):
                    return True
        k += len(part)
    return False


# a parameter matters where setting it back raises the all-sample RMSE by this share
MATTERS_SHARE = 0.01


def _matters(result: EffectResult, theta: np.ndarray, mm, rds: list[RunData],
             bases: list) -> bool:
    """Is the fit with ``theta`` (the result's values with one changed) materially worse
    than the result's own on all samples, at the result's clock and meter lag?"""
    params = []
    for base, fitted in zip(bases, result.fit.params):
        p = base
        for e, t in result.fit.by_effect(theta):
            p = e.apply(mm, p, t)
        p = dataclasses.replace(p, clock_adjust_s=fitted.clock_adjust_s,
                                meter_tau_s=fitted.meter_tau_s)
        params.append(p)
    try:
        worse = score(rds, params).rmse_l_min
    except PlcpredError:
        return True
    return worse > (1.0 + MATTERS_SHARE) * result.fit_score.rmse_l_min


def _dynamic_reference(machine, mm, rds, bases, ctx, fold_masks, warnings: list[str],
                       program=None, compiled=None, stats: dict | None = None
                       ) -> EffectResult | None:
    """The nominal machine file through the physics plant, its clock and meter lag
    fitted as the baseline's are, scored on the same held-out samples: what the machine
    draws with nothing wrong once what D1 leaves out by design is in (docs/reference/physics.md:
    the air a tube still holds at atmosphere, heat, exhausts and strokes cut short at
    speed). With the sequencer's runs (``program`` given) the program runs against the
    plant, whose end switches move the edges it waits on, as on the machine
    (:func:`~plcpred.plant.replay.closed_loop_total_cells_nl`); with recorded I/O the
    plant follows the recorded edges (:func:`~plcpred.plant.replay.replay`). Each run's
    :attr:`RunModel.dynamic_cells` is set to the plant's cells less the nominal D1
    cells. None (with a warning) where the plant cannot run the machine. ``stats`` (a
    dict) counts what its plant runs cost (integration pieces, machine seconds)."""

    made: dict[tuple, np.ndarray] = {}      # runs with the same edges: one plant run
    for rd, base in zip(rds, bases):
        rm = rd.model
        key = (rm.horizon_s, len(rm.edges_s),
               tuple(t.tobytes() + e.tobytes() for t, e in rm.transitions),
               rm.unit_cells.tobytes())
        try:
            plant_cells = made.get(key)
            if plant_cells is None:
                if program is not None:
                    plant_cells = closed_loop_total_cells_nl(machine, rm.timeline,
                                                             rm.edges_s, program, compiled,
                                                             stats)
                else:
                    plant_cells = replay_total_cells_nl(machine, rm.timeline, rm.edges_s,
                                                        stats)
                made[key] = plant_cells
        except PlcpredError as e:
            warnings.append(f"no dynamic reference: {e}")
            for r in rds:
                r.model.dynamic_cells = None
            return None
        nominal = dataclasses.replace(base, dynamic=False)
        rm.dynamic_cells = plant_cells - rm.total_cells(nominal)
    result = _evaluate([], mm, rds, _plant_bases(bases), ctx, fold_masks)
    result.name, result.title = "plant", "the machine file through the physics plant"
    return result


def _cut_drives(mm, rds) -> set[int]:
    """The drives (indices into mm.drives) whose valve some run reverses before the drive
    has arrived (a pulse shorter than the stroke, a valve that chatters), where the file
    books their strokes whole."""
    out = set()
    for k, m in enumerate(mm.drive_models()):
        if m.stroke_time_s and not m.partial_strokes:
            for rd in rds:
                t_s, ext = rd.model.transitions[k]
                if stroke_cuts(t_s, ext, m.delay_s, m.stroke_time_s).any():
                    out.add(k)
                    break
    return out


def _with_exhaust(exhaust: EffectResult, results: list[EffectResult], mm, rds, bases, ctx,
                  fold_masks, warnings: list[str]) -> list[EffectResult]:
    """Each other effect of ``results`` fitted together with an incomplete exhaust that
    explains part of the gap (``exhaust``).

    An exhaust cut short (and a stroke cut short, which the effect's other form adds) is
    no fault: it is D1's own limit, there on any machine that cycles fast or reverses a
    valve before its drive arrives (docs/reference/physics.md).
    A fault on such a machine (a slow meter, another supply) shows as a smaller gap on
    top of it, which the single effects cannot rank: the exhaust takes the larger share
    whatever else is wrong, or another effect that mimics both takes the first place.
    The verdict names the pair's other effect when the pair beats the exhaust alone on
    held-out samples by more than the noise."""
    pairs = [_evaluate_or_warn(list(exhaust.fit.effects) + list(e.fit.effects), mm, rds,
                               bases, ctx, fold_masks, warnings)
             for e in results if e.name != exhaust.name]
    return [p for p in pairs if p is not None]


def _evaluate_or_warn(effects: list[Effect], mm, rds, bases, ctx, fold_masks,
                      warnings: list[str]) -> EffectResult | None:
    """:func:`_evaluate`, or None with a warning where the plant cannot run a
    combination with a plant form (its budget of integration pieces spent): the
    combination goes untried, the diagnosis goes on without it."""
    try:
        return _evaluate(effects, mm, rds, bases, ctx, fold_masks)
    except PlcpredError as e:
        warnings.append(f"{' + '.join(x.name for x in effects)} not fitted: {e}")
        return None


def _plant_bases(bases: list) -> list:
    """The nominal models with the plant's air beyond D1 added (ModelParams.dynamic)."""
    return [dataclasses.replace(b, dynamic=True) for b in bases]


def _bases_of(result: EffectResult, bases: list) -> list:
    """The nominal models ``result`` was fitted from: D1's, or on top of the plant."""
    return _plant_bases(bases) if result.beyond_plant else bases


def _through_plant(effects: list[Effect]) -> bool:
    """Were any of ``effects`` fitted as machine files run through the plant?"""
    return any(e.through_plant for e in effects)


def _evaluate(effects: list[Effect], mm, rds, bases, ctx, fold_masks) -> EffectResult:
    all_masks = [np.ones(len(rd.end_s), bool) for rd in rds]
    fit = fit_effects(effects, mm, rds, all_masks, bases, ctx)
    fit_score = score(rds, fit.params)
    # the folds start from the fit on all samples (their sweep would find the same
    # basin; the held-out samples still never shape the fold's own fit)
    held = heldout(effects, mm, rds, bases, ctx, fold_masks, start=fit.theta)
    physical = {}
    for e, theta in fit.by_effect():
        ph = e.physical(mm, theta)
        physical.update(ph if len(effects) == 1 else {e.name: ph})
    name = "+".join(e.name for e in effects)
    beyond = bool(bases) and bases[0].dynamic
    title = " + ".join(e.title for e in effects) + (
        " (beyond the plant)" if beyond and not _through_plant(effects) else "")
    return EffectResult(name, title, fit, fit_score, held,
                        dict(zip(fit.names, map(float, fit.theta))), physical, beyond)


def tie_break(results: list[EffectResult], noise: float, mm) -> list[EffectResult]:
    """Among effects whose held-out error is as good as the best's (within one standard
    deviation of what noise does to a held-out MSE, or 1 % of RMSE), the one with the
    fewest parameters goes first (the lowest BIC among equals). Then, when the first's
    fitted values are implausible as a plant's truth (:meth:`Effect.implausible`), the
    best plausible effect that the held-out samples cannot tell from it goes first."""
    if len(results) < 2:
        return results
    best = results[0].heldout_score
    # within one standard deviation of what noise alone does to a held-out MSE (or
    # 1 % of RMSE): the data do not prefer the better one, parsimony does
    near = [e for e in results if e.heldout_score.mse - best.mse <= max(
        0.0201 * best.mse, noise ** 2 * math.sqrt(2.0 / max(e.heldout_score.n, 1)))]
    rest = [e for e in results if e not in near]
    near.sort(key=lambda e: (sum(e.fit.counts), e.fit.bic))
    results = near + rest
    first = results[0]
    if _implausible(first, mm) is None:
        return results
    for e in results[1:]:
        if significant(e.heldout_score, first.heldout_score, noise):
            break           # sorted by held-out RMSE: the rest are worse still
        if _implausible(e, mm) is None:
            return [e] + [x for x in results if x is not e]
    return results


def _implausible(result: EffectResult, mm) -> str | None:
    for e, theta in result.fit.by_effect():
        why = e.implausible(mm, theta)
        if why:
            return why
    return None


def baseline_from_effects(base_all: FitResult, fitted: list[EffectResult], mm, rds,
                           bases, ctx) -> FitResult | None:
    """The baseline fitted again from each clock adjustment and meter lag that an
    effect's fit ended at, where one fits all samples better than its own did; else
    None.

    The clock and the lag have valleys of their own (a lag and a later clock look
    alike; with instantaneous readings the valleys are narrow), and the baseline's sweep
    can end in a shallower one than an effect's path through its own parameters finds.
    The effect would then be credited with the clock's improvement: a knife's flow
    factor of 1.003 "explained" a healthy rig logged at 1 Hz (held out 0.52 NL/min
    against the baseline's 0.63, with its clock 0.3 s earlier and its lag 0.44 s
    against 0.29 s)."""
    names = list(base_all.names)
    starts = []
    for e in fitted:
        found = dict(zip(e.fit.names, map(float, e.fit.theta)))
        if not all(n in found for n in names):
            continue            # the sensor_lag effect has no lag nuisance
        start = np.array([found[n] for n in names])
        if not any(np.allclose(start, s, atol=1e-3) for s in starts + [base_all.theta]):
            starts.append(start)
    best = None
    for start in starts:
        fit = fit_effects([], mm, rds, [np.ones(len(rd.end_s), bool) for rd in rds],
                          bases, ctx, start=start)
        if fit.cost < (best or base_all).cost * (1.0 - 1e-6):
            best = fit
    return best


def _sampling_hint(rds: list[RunData], instants: list[RunData], warnings: list[str]) -> None:
    """Say so where logs read as interval means (what a meter's own logger reports, and
    the default) fit instantaneous readings far better (a PLC polling the meter's
    analogue output: at 1 Hz behind a fast meter most strokes fall between two readings,
    and read as means such a log looks like a fault of the drives). Only a hint: a fault
    the nominal model lacks can tilt the comparison either way (an emulated clamp
    station logged as means at 1 Hz, its drill feed's tubes 2.3x longer, left a twelfth
    as much unexplained read instantaneously), so the user says which (``--sampling``,
    ``[meter] sampling``)."""
    as_means, as_instants = _unexplained(rds), _unexplained(instants)
    if as_instants < INSTANT_HINT * as_means:
        warnings.append(
            f"the logs fit instantaneous readings better than interval means ({as_instants:.2g} "
            f"against {as_means:.2g} readings' worth of their variance left unexplained): if "
            "a PLC or logger polls the meter's output, give --sampling instant (or [meter] "
            "sampling = \"instant\")")


def _unexplained(rds: list[RunData]) -> float:
    """Readings' worth of the logs' variance the nominal alignments leave unexplained."""
    return sum(len(rd.end_s) * (1.0 - max(rd.correlation, 0.0) ** 2) for rd in rds)


def _common_lag(rds: list[RunData], mm, windows_s: list[float], offsets: list) -> list:
    """The runs as one meter logged them all: with one lag.

    At 1 Hz a lag and a later clock look alike, so each run's own alignment can trade
    one for the other its own way: two logs of a healthy rig came out 0.4 s of lag apart
    with their clocks 0.3 s apart the other way. A fit moves one clock adjustment and one
    lag for all runs and cannot follow both, and a run left out then lands its edges in
    the wrong readings (held out 6.2 NL/min against 0.5 of noise, named stroke_time).
    So where the lags differ (all within a thermal meter's), each run is aligned again at
    each run's lag, its offset searched near the one it had (the same reading time, less
    the lags' difference), and the lag that leaves the least of the logs' variance
    unexplained over all runs is every run's."""
    taus = sorted({round(rd.meter_tau_s, 2) for rd in rds})
    if len(taus) < 2 or max(rd.fitted_tau_s for rd in rds) > METER_LAG_FIT_MAX_S:
        return rds
    best = None
    for tau in taus:
        again = [align(rd.run, rd.model, mm.nominal(tau), w, tau, off,
                       near_s=None if off is not None else rd.offset_s + rd.meter_tau_s - tau)
                 for rd, w, off in zip(rds, windows_s, offsets)]
        if best is None or _unexplained(again) < _unexplained(best):
            best = again
    for new, old in zip(best, rds):
        new.fitted_tau_s = old.fitted_tau_s
    return best


def _meter_corrected(run: MeasuredRun, meter, warnings: list[str]) -> MeasuredRun:
    """A run as the machine file's ``[meter]`` says to read it: its zero offset taken
    off, and readings at full scale (clipped, so they say only "at least this much")
    left out as if the logger had missed them."""
    flow = run.flow_l_min - (meter.offset_l_min or 0.0)
    keep = np.ones(len(flow), bool)
    if meter.full_scale_l_min:
        keep = run.flow_l_min < 0.999 * meter.full_scale_l_min
        if not keep.all():
            warnings.append(f"{run.name}: {int((~keep).sum())} readings at the meter's full "
                            f"scale ({meter.full_scale_l_min:g} NL/min) left out")
    if keep.sum() < 3:
        raise DiagnosisError(f"{run.name}: (almost) every reading is at the meter's full "
                             "scale")
    return MeasuredRun(run.name, run.time_s[keep], flow[keep], None if run.supply_bar_g is
                       None else run.supply_bar_g[keep], dict(run.source),
                       run.sampling or meter.sampling)


# a log of which the alignment uses less than this share is pointed out
COVERAGE_SHARE = 0.9


def _check_coverage(rd: RunData, warnings: list[str]) -> None:
    """Say so where the alignment leaves a material part of the log unused (a clock
    that slipped by whole cycles drops the readings before the prediction's start)."""
    total = len(rd.run.time_s)
    used = len(rd.end_s)
    if total and used < COVERAGE_SHARE * total:
        warnings.append(f"{rd.run.name}: only {used} of {total} readings fall within the "
                        f"prediction at the clock offset {rd.offset_s:+.3f} s (the rest "
                        "before the machine's start or after the horizon); if the machine "
                        "ran all through the log, give its clock with --offset")


def _check_run(rd: RunData, pred: np.ndarray, machine_name: str, given_offset: bool,
               warnings: list[str]) -> None:
    """Units, flow and likeness of a run against its nominal readings ``pred``."""
    run = rd.run
    meas_mean = float(rd.measured_l_min @ rd.weight_s) / float(rd.weight_s.sum())
    pred_mean = float(pred @ rd.weight_s) / float(rd.weight_s.sum())
    if pred_mean > 0 and meas_mean > 0:
        ratio = meas_mean / pred_mean
        if ratio > SCALE_LIMIT or ratio < 1.0 / SCALE_LIMIT:
            raise DiagnosisError(
                f"{run.name}: the measured flow averages {meas_mean:.4g} NL/min, "
                f"{ratio:.3g} times the prediction ({pred_mean:.4g} NL/min): check "
                "--flow-unit (l/min, m3/h, l/s, scfm) and --reference")
    if meas_mean <= 0:
        raise DiagnosisError(f"{run.name}: the log shows no flow (mean "
                             f"{meas_mean:.3g} NL/min)")
    if rd.correlation < 0.2 and np.std(pred) > 0:
        text = (f"{run.name}: the log does not look like {machine_name}'s prediction "
                f"(best correlation {rd.correlation:.2f}); is it a run of this machine?")
        if given_offset:
            warnings.append(text)
        else:
            raise DiagnosisError(text + " If it is, give the clock offset with --offset")


def clock_reading(run, offset_s: float) -> str:
    """Where the prediction's t = 0 falls on a log whose times are date-times or times
    of day (its offset in seconds since 1970 or midnight says little to a reader)."""
    fmt = run.source.get("time_format", "seconds")
    if fmt == "seconds" or not math.isfinite(offset_s):
        return ""
    try:
        at = datetime(1970, 1, 1) + timedelta(seconds=offset_s)
    except OverflowError:
        return ""
    day = "" if fmt in TIME_OF_DAY_FORMATS else "%Y-%m-%d "
    text = at.strftime(day + "%H:%M:%S.%f")[:-3]
    return f" (the prediction's t = 0 at {text} on the log's clock)"


SUPPLY_NOTE_BAR = 0.2   # a logged supply this far from the machine file's is pointed out


def _logged_supply_all(rds: list[RunData]) -> float | None:
    """The mean supply pressure the logs record, weighted by their readings; None
    unless every run records one."""
    means = [(_logged_supply(rd.run), len(rd.run.time_s)) for rd in rds]
    if not means or any(m is None for m, _ in means):
        return None
    return float(sum(m * n for m, n in means) / sum(n for _, n in means))


def _logged_supply(run) -> float | None:
    """The mean supply pressure a log records (its supply_bar_g column), None without."""
    p = run.supply_bar_g
    if p is None:
        return None
    p = p[np.isfinite(p)]
    return float(np.mean(p)) if len(p) else None

