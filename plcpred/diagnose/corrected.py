"""The corrected machine file (``diagnose --write-machine``), checked the way the user
will use it.

The diagnosis judges its effects on the logs' own timelines: the recorded I/O, or the
program run again where timing matters. The user runs ``plcpred predict`` on the file,
where the program runs from the file's input schedule and every value written changes
what it does: a valve delay the program waits on slows each cycle, a delay past a
watchdog stops the machine. So before the file is written, ``predict`` is run on it over
the logs' windows and its air is compared with what the logs measured, and with what it
books on the nominal file (:class:`FileCheck`).

Of the files that carry the verdict's effects with and without the calibration
(:func:`calibration`), the calibration alone, none of them, and (for a verdict of none
because the best effects stay within a healthy machine's tolerance of the file) those
effects' values within that tolerance, the one that comes
nearest the logs' air is written, the verdict's own preferred where it is within
:data:`CLOSE_PCT` of the nearest; what is left out is said in the file's header, the
report and the JSON. Values fitted through the physics plant are always written: they
are meant to be run through it (``emulate``), so predict cannot judge them, only the
calibration on top of them. An effect fitted beyond the plant's reference is judged
like any other: where D1's own excess books as much air as the effect, the file without
it predicts the logs better, and its header says the effect was left out.
"""
from __future__ import annotations

import copy
import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..air.demand import consumer_models, demand_profile
from ..errors import PlcpredError
from ..machine import machine_from_data, read_machine_data, save_machine
from ..sequencer import unfold
from .band import ModelForm, drive_factor_range
from .core import Diagnosis
from .fit import fit_effects
from .fit_model import lagged_cumulative_nl

# percentage points of the logs' air by which another file must come nearer them than
# the verdict's for the verdict's file not to be written: the share by which the
# program's own input schedule and the logged machine's parts may differ over two logs
CLOSE_PCT = 1.0
# the grid on which the check meters its demand (a tenth of the shortest lag of a
# thermal meter; the strokes' air is summed exactly into each cell)
CHECK_DT_S = 0.01


@dataclass(frozen=True)
class FileCheck:
    """``predict``'s air over the logs' readings: on the nominal file and on the written
    one, against what the logs measured (normal litres, all runs together)."""
    measured_nl: float
    nominal_nl: float | None        # None: the program does not run on it
    written_nl: float | None
    left_out: tuple[str, ...] = ()  # what the diagnosis found that the file does not carry

    @staticmethod
    def _pct(predicted_nl: float | None, measured_nl: float) -> float | None:
        if predicted_nl is None or not measured_nl > 0:
            return None
        return 100.0 * (predicted_nl - measured_nl) / measured_nl

    @property
    def nominal_error_pct(self) -> float | None:
        return self._pct(self.nominal_nl, self.measured_nl)

    @property
    def written_error_pct(self) -> float | None:
        return self._pct(self.written_nl, self.measured_nl)

    def text(self) -> str:
        """One line for the report: what predict books on the file against the logs."""
        if self.written_nl is None:
            return "predict on the corrected file: the program does not run on it"
        line = (f"predict on the corrected file: {self.written_nl:.1f} NL against "
                f"{self.measured_nl:.1f} NL measured over the logs "
                f"({self.written_error_pct:+.1f} %")
        if self.nominal_nl is not None:
            line += f"; on the machine file {self.nominal_error_pct:+.1f} %"
        return line + ")"

    def summary(self) -> dict:
        return {"measured_nl": self.measured_nl, "nominal_nl": self.nominal_nl,
                "written_nl": self.written_nl,
                "nominal_error_pct": self.nominal_error_pct,
                "written_error_pct": self.written_error_pct,
                "left_out": list(self.left_out)}


@dataclass
class _Candidate:
    """One way to write the file: its data and the header lines that say what it holds."""
    data: dict
    changes: list
    calibrated: list
    skipped: list
    with_effects: bool
    predicted_nl: float | None = None


def write_fixed_machine(d: Diagnosis, path) -> list[str]:
    """Write ``d.machine``'s file with the combination's effects (the verdict first) in
    the machine file's own keys and the model's accuracy as the logs show it
    (:func:`calibration`), so that ``plcpred predict`` on it carries them; or, where
    ``predict`` on that file comes materially further from the logs' air than on one
    without them, the nearer file, saying what it leaves out. Sets ``d.fixed_machine``
    and ``d.file_check``; returns what was changed. The file is checked by loading it
    before it is renamed into place."""
    path = Path(path)
    candidates = _candidates(d)
    measured_nl, windows = _windows(d)
    # parsed once for every candidate's run
    program = d.program if hasattr(d.program, "pous") else d.machine.read_program(d.program)
    for c in candidates:
        c.predicted_nl = _predicted_nl(d, c.data, windows, program)
    # the machine file as it is: the last candidate unless only the verdict's count
    unchanged = next((c for c in candidates if not (c.with_effects or c.calibrated)), None)
    nominal_nl = unchanged.predicted_nl if unchanged is not None else _predicted_nl(
        d, read_machine_data(d.machine.path), windows, program)
    chosen = _nearest(candidates, measured_nl)
    left_out = _left_out(d, chosen, candidates[0], measured_nl)
    header = _header(d, chosen, left_out)
    save_machine(chosen.data, d.machine, path, "\n".join(header), by="plcpred diagnose")
    d.fixed_machine = str(path)
    d.file_check = FileCheck(measured_nl, nominal_nl, chosen.predicted_nl, tuple(left_out))
    return chosen.changes


def _candidates(d: Diagnosis) -> list[_Candidate]:
    """The files the diagnosis could write, the verdict's own first: its effects with the
    calibration, its effects alone, the calibration alone, nothing changed; for a
    verdict of none within tolerance, last, the tolerated values."""
    out = []
    # values fitted through the plant are meant to be run through it (emulate): predict
    # (D1) cannot judge them, only the calibration on top of them
    kinds = (True,) if d.combination and _through_plant(d) else \
        (True, False) if d.combination else (False,)
    for with_effects in kinds:
        data = read_machine_data(d.machine.path)
        changes, skipped = _effect_changes(d, data) if with_effects else ([], [])
        plain = copy.deepcopy(data)
        calibrated = calibration(d, data, with_effects)
        if calibrated:
            out.append(_Candidate(data, changes, calibrated, skipped,
                                  with_effects))
        out.append(_Candidate(plain, changes, [], skipped, with_effects))
    if d.combination is None and d.tolerated is not None:
        data = read_machine_data(d.machine.path)
        changes = _tolerated_changes(d, data)
        if changes:
            out.append(_Candidate(data, changes, [], [], True))
    return out


def _tolerated_changes(d: Diagnosis, data: dict) -> list[str]:
    """Write into ``data`` the values of the effects that a verdict of none found within
    a healthy machine's tolerance of its file, each moved to the nearest that tolerance
    allows: the file's catalogue values corrected, no fault (a stroke time a tenth off
    can decide whether the program catches every part)."""
    changes: list[str] = []
    for e, theta in d.tolerated["fit"].by_effect():
        clipped = e.clipped_to_tolerance(d.machine_model, theta, d.fit_context)
        if e.expressible and clipped is not None:
            changes += [f"{c} (within a healthy machine's tolerance of its file)"
                        for c in e.to_machine(d.machine_model, data, clipped)]
    return changes


def _effect_changes(d: Diagnosis, data: dict) -> tuple[list[str], list[str]]:
    """Write the combination's effects into ``data``: (what changed, the effects the air
    model cannot express)."""
    changes: list[str] = []
    skipped: list[str] = []
    for e, theta in d.combination["fit"].by_effect():
        if not e.expressible:
            skipped.append(e.name)
            continue
        changes += e.to_machine(d.machine_model, data, theta)
    return changes, skipped


def calibration(d: Diagnosis, data: dict, with_effects: bool = True) -> list[str]:
    """Write into ``data`` the model's own accuracy as the logs show it, on top of the
    verdict's effects (``with_effects``) or of the nominal machine: the nominal model
    flexed within its band (:class:`~plcpred.diagnose.band.ModelForm`), fitted on every
    sample, as each drive's ``air_factor`` and each nozzle's and leak's C. A healthy
    machine's strokes take a few per cent less than D1 books; without this, ``predict``
    on the corrected file keeps that error however right the verdict. Not where an
    effect was fitted through the plant (its air is in no D1 figure the fit could start
    from)."""
    mm = d.machine_model
    if mm is None or not mm.models or not d.runs or (
            with_effects and d.combination and _through_plant(d)):
        return []
    start = d.combination["fit"].params if with_effects and d.combination else d.bases
    # what predict on the corrected file books: D1 with the effects, no plant
    bases = [dataclasses.replace(p, dynamic=False, variant=()) for p in start]
    flex = ModelForm(drive_factor_range(mm, bases[0]))
    masks = [np.ones(len(rd.end_s), bool) for rd in d.runs]
    fit = fit_effects([flex], mm, d.runs, masks, bases, d.fit_context)
    (_, theta), = fit.by_effect()
    return flex.to_machine(mm, data, theta)


def _through_plant(d: Diagnosis) -> bool:
    return any(e.through_plant for e in d.combination["fit"].effects)


def _windows(d: Diagnosis) -> tuple[float, list[tuple[np.ndarray, np.ndarray, float]]]:
    """The logs' measured normal litres over their readings, and per run the readings'
    (start, end) in prediction time and the meter's lag."""
    measured_nl = sum(float(np.sum(rd.measured_l_min * rd.weight_s)) for rd in d.runs) / 60.0
    return measured_nl, [(rd.start_s, rd.end_s, rd.meter_tau_s) for rd in d.runs]


def _predicted_nl(d: Diagnosis, data: dict, windows, program) -> float | None:
    """What ``predict`` books on the machine file ``data`` over ``windows`` (normal
    litres) as each run's meter reads it, ``program`` run from the file's own inputs;
    None where it does not run."""
    try:
        machine = machine_from_data(data, d.machine.path, d.machine.allowed_roots)
        horizon_s = max(float(end[-1]) for _, end, _ in windows if len(end)) + CHECK_DT_S
        timeline = unfold(machine, horizon_s, program=program)
        profile = demand_profile(timeline, consumer_models(machine), CHECK_DT_S)
    except PlcpredError:
        return None
    # through each run's meter: its lag carries the air of strokes just before a
    # reading into it, as it did for the logs
    edges_s = np.arange(math.ceil(horizon_s / CHECK_DT_S) + 1) * CHECK_DT_S
    cells_nl = np.diff(profile.cumulative_nl_at(edges_s))
    total_nl = 0.0
    for start, end, tau_s in windows:
        if len(end):
            metered = lagged_cumulative_nl(cells_nl, CHECK_DT_S, tau_s)
            total_nl += float(np.sum(np.interp(end, edges_s, metered)
                                     - np.interp(start, edges_s, metered)))
    return total_nl


def _error(c: _Candidate, measured_nl: float) -> float:
    if c.predicted_nl is None or not measured_nl > 0:
        return math.inf
    return abs(100.0 * (c.predicted_nl - measured_nl) / measured_nl)


def _nearest(candidates: list[_Candidate], measured_nl: float) -> _Candidate:
    """The first of ``candidates`` (they come in the order they are preferred) within
    CLOSE_PCT of the one nearest the logs' air; the first where none runs."""
    best = min(_error(c, measured_nl) for c in candidates)
    if not math.isfinite(best):
        return candidates[0]
    return next(c for c in candidates if _error(c, measured_nl) <= best + CLOSE_PCT)


def _left_out(d: Diagnosis, chosen: _Candidate, preferred: _Candidate, measured_nl: float
              ) -> list[str]:
    """What the written file leaves out of the preferred one, and why."""
    if chosen is preferred:
        return []

    def booked(c: _Candidate) -> str:
        return "the program does not run" if c.predicted_nl is None \
            else f"predict books {c.predicted_nl:.1f} NL"
    why = (f"with it {booked(preferred)}, as written {booked(chosen)}, against "
           f"{measured_nl:.1f} NL measured")
    out = []
    if preferred.with_effects and not chosen.with_effects:
        out.append(f"{' + '.join(d.combination['effects'])} (as the diagnosis fitted it): {why}")
    if preferred.calibrated and not chosen.calibrated:
        out.append(f"the calibration: {why}")
    return out


def _header(d: Diagnosis, chosen: _Candidate, left_out: list[str]) -> list[str]:
    machine = d.machine
    header = [f"{machine.name}, corrected by plcpred diagnose from {machine.path.name}",
              f"verdict: {d.verdict}"]
    header += [f"changed: {c}" for c in chosen.changes] or ["changed: nothing"]
    header += [f"calibrated: {c}" for c in chosen.calibrated]
    header += [f"not written (the air model cannot express it yet): {s}"
               for s in chosen.skipped]
    header += [f"not written: {s}" for s in left_out]
    if chosen.with_effects and d.combination and d.combination.get("beyond_plant") \
            and chosen.changes:
        header.append(("fitted through the physics plant (this file run through it)"
                       if _through_plant(d) else
                       "fitted beyond the physics plant's reference of the nominal machine")
                      + ": predict (D1) on this file also books what D1 leaves out by design")
    return header
