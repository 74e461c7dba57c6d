"""Aligning a log to its prediction, fitting effects to some samples and scoring them on
others.

* :func:`align` finds a run's clock offset (and, unless the machine file gives the
  meter's response, a nuisance lag within the 0-0.6 s of thermal-mass meters): coarse by
  cross-correlating the changes of both series, fine by the correlation of the meter
  readings themselves.
* :func:`fit_effects` fits one or more effects jointly with bounded least squares
  (``scipy.optimize.least_squares``), standard errors from the Jacobian; a closed
  loop's timing (:mod:`~plcpred.diagnose.timing`) by grid and golden section.
* :func:`folds` says which samples each fit may see: leave one run out, or with a single
  run alternate blocks of it, so that every figure called "held-out" comes from samples
  the fit never saw.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import NamedTuple

import numpy as np

from ..physics.meter import cumulative_nl, first_order_lag
from .effects import METER_LAG_FIT_MAX_S, Effect, Param
from .errors import DiagnosisError
from .fit_model import MachineModel, ModelParams, RunModel
from .io import MeasuredRun, reading_starts

# samplers kept per run (a grid sweep's clocks, a fit's current and perturbed clock)
MAX_SAMPLERS = 64


@dataclass
class RunData:
    """A measured run tied to its prediction: the samples that fall within the predicted
    horizon, their intervals in prediction time, and their weights (seconds)."""
    run: MeasuredRun
    model: RunModel
    offset_s: float                 # logger clock at the prediction's time 0
    meter_tau_s: float
    fitted_tau_s: float             # the lag the alignment found (may exceed meter_tau_s)
    correlation: float
    start_s: np.ndarray             # prediction time
    end_s: np.ndarray
    measured_l_min: np.ndarray
    weight_s: np.ndarray = field(init=False)
    # resequenced predictions (timing effects in a closed loop): ModelParams.timing ->
    # (RunModel, its alignment's offset and meter lag minus this run's), made by
    # diagnose.timing
    variants: dict = field(default_factory=dict, repr=False)
    # what the alignment could not decide alone (another clock as good), for the report
    notes: list = field(default_factory=list, repr=False)

    def __post_init__(self):
        self.weight_s = self.end_s - self.start_s
        # what each reading averages of the meter's response (an instantaneous reading
        # still stands for its whole interval in weights and totals)
        self.read_start_s = reading_starts(self.run.sampling, self.start_s, self.end_s)
        # (timing, clock) -> IntervalSampler: the samples' cells at that clock
        self._samplers: dict = {}

    def readings(self, params: ModelParams) -> np.ndarray:
        """What the meter logs for this run's samples under ``params`` (RunModel.readings
        at the run's own or its timing variant's clock)."""
        if params.timing is None:
            rm, shift_s = self.model, 0.0
        else:
            rm, shift_s, lag_s = self.variants[params.timing]
            # the samples stay this run's; the variant's own alignment moves its clock and
            # its meter lag (the fit's timing_params move both further)
            if lag_s:
                params = dataclasses.replace(params, meter_tau_s=max(
                    0.0, params.meter_tau_s + lag_s))
        key = (params.timing, shift_s, params.clock_adjust_s)
        sampler = self._samplers.get(key)
        if sampler is None:
            if len(self._samplers) >= MAX_SAMPLERS:
                self._samplers.pop(next(iter(self._samplers)))
            sampler = rm.sampler(self.read_start_s - shift_s, self.end_s - shift_s,
                                 params.clock_adjust_s)
            self._samplers[key] = sampler
        return sampler(rm.metered_cumulative_nl(params))

    def forget_samplers(self, timing) -> None:
        """Drop the samplers of a timing variant that is no longer kept."""
        for key in [k for k in self._samplers if k[0] == timing]:
            del self._samplers[key]


def _common_samples(run: MeasuredRun, lo_s: float, hi_s: float,
                    horizon_s: float) -> np.ndarray:
    """Indices of the samples inside the prediction at every offset in [lo_s, hi_s]."""
    keep = (run.interval_starts_s() - hi_s >= 0.0) & (run.time_s - lo_s <= horizon_s)
    return np.flatnonzero(keep)


def _intervals(run: MeasuredRun, offset_s: float, horizon_s: float):
    """(indices, starts, ends in prediction time) of the samples inside the prediction
    at ``offset_s``."""
    idx = _common_samples(run, offset_s, offset_s, horizon_s)
    return idx, run.interval_starts_s()[idx] - offset_s, run.time_s[idx] - offset_s


def _pearson(a: np.ndarray, b: np.ndarray) -> float:
    a = a - a.mean()
    b = b - b.mean()
    den = math.sqrt(float(a @ a) * float(b @ b))
    return float(a @ b) / den if den > 0 else 0.0


CORRELATION_BLOCK = 1_000_000     # readings interpolated at once when aligning
# lags tried when the meter's is not known; the baseline keeps at most the nuisance one
ALIGN_TAUS_S = (0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.8, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0,
                10.0)


def align(run: MeasuredRun, rm: RunModel, params: ModelParams, window_s: float,
          meter_tau_s: float | None = None, offset_s: float | None = None,
          quick: bool = False, max_tau_s: float | None = None,
          near_s: float | None = None) -> RunData:
    """Tie ``run`` to its prediction ``rm``. The offset is the logger's clock reading at
    the prediction's time 0, searched within ``window_s`` of the log's first sample
    unless ``offset_s`` is given. The meter lag is ``meter_tau_s`` when the machine file
    gives it; else the lag and the offset that correlate best are searched together (a
    lag delays every reading, so the two trade off) and the run keeps the lag up to the
    0.6 s of a thermal-mass meter: a slower meter is the ``sensor_lag`` effect
    (``RunData.fitted_tau_s`` keeps what the search found). ``quick`` searches the
    fine offsets on a five times coarser grid and refines only the offset, and
    ``max_tau_s`` bounds the lags tried (a resequenced variant, aligned many times over,
    near what the nominal alignment found); ``near_s`` searches the offset only within a
    sampling interval or so of that one (another lag for an aligned run)."""
    taus = [meter_tau_s] if meter_tau_s is not None else [
        t for t in ALIGN_TAUS_S if max_tau_s is None or t <= max_tau_s]
    correlations = _Correlations(run, rm, params)
    if offset_s is None:
        found = _search_offset(correlations, taus, window_s, quick, near_s)
    else:
        found = _lag_at_offset(correlations, taus, offset_s)
    offset_s, fitted_tau = _refine_alignment(correlations, found, meter_tau_s, quick)
    tau = fitted_tau if meter_tau_s is not None else min(fitted_tau, METER_LAG_FIT_MAX_S)
    return _aligned_run(correlations, offset_s, tau, fitted_tau, found.notes)


class _Correlations:
    """The correlation of a run's readings with its prediction at clock offsets and a
    meter lag; the prediction's metered cumulative NL is kept per lag."""

    def __init__(self, run: MeasuredRun, rm: RunModel, params: ModelParams):
        self.run = run
        self.rm = rm
        self.params = params
        self.cells = rm.total_cells(params)
        self.lagged: dict[float, np.ndarray] = {}       # metered cumulative NL per lag

    def __call__(self, tau: float, offsets, span=None) -> np.ndarray | None:
        """Correlation of the readings with the log for each offset (over the samples
        valid for all offsets of ``span``, default ``offsets``: comparable values)."""
        run, rm = self.run, self.rm
        p = self.params.copy()
        p.meter_tau_s = tau
        lo_s, hi_s = span or (min(offsets), max(offsets))
        idx = _common_samples(run, lo_s, hi_s, rm.horizon_s)
        if len(idx) < 5:
            return None
        starts = run.reading_starts_s()[idx]
        ends = run.time_s[idx]
        meas = run.flow_l_min[idx]
        cum = self._metered(tau)
        # all offsets at once (in blocks of bounded size): one interpolation per block
        offs = np.asarray(offsets, dtype=float)
        b = meas - meas.mean()
        bb = float(b @ b)
        out = np.empty(len(offs))
        per_block = max(1, CORRELATION_BLOCK // len(idx))
        # a log whose readings follow one another (each starts where the one before
        # ended) shares its edges: the cumulative air is read once at each
        chained = len(starts) > 1 and bool(np.array_equal(starts[1:], ends[:-1]))
        bounds = np.concatenate([starts[:1], ends]) if chained else None
        for k in range(0, len(offs), per_block):
            o = offs[k:k + per_block, None]
            if chained:
                r = rm.chained_readings(p, bounds - o, cum)
            else:
                r = rm.readings(p, (starts - o).ravel(), (ends - o).ravel(),
                                cum_nl=cum).reshape(len(o), -1)
            a = r - r.mean(axis=1, keepdims=True)
            den = np.sqrt((a * a).sum(axis=1) * bb)
            out[k:k + per_block] = np.where(den > 0, (a @ b) / np.where(den > 0, den, 1.0),
                                            0.0)
        return out

    def _metered(self, tau: float) -> np.ndarray:
        """The prediction's metered cumulative NL with the meter lag ``tau`` (kept)."""
        cum = self.lagged.get(tau)
        if cum is None:
            p = self.params.copy()
            p.meter_tau_s = tau
            cum = self.lagged[tau] = self.rm.metered_cumulative_nl(p, self.cells)
        return cum

    def of_changes(self, tau: float, offset_s: float) -> tuple[float, int]:
        """(the correlation of the readings' changes from one to the next with the log's,
        readings used) at one offset, over the samples within the prediction there: a
        step in the log (a leak that opens) is one change among hundreds, where it
        lowers the readings' own correlation over the whole log."""
        run, rm = self.run, self.rm
        idx = _common_samples(run, offset_s, offset_s, rm.horizon_s)
        if len(idx) < 5:
            return -2.0, len(idx)
        r = rm.readings(self.params, run.reading_starts_s()[idx] - offset_s,
                        run.time_s[idx] - offset_s, cum_nl=self._metered(tau))
        return _pearson(np.diff(r), np.diff(run.flow_l_min[idx])), len(idx)

    def cost(self, tau: float, offset_s: float) -> float:
        """Minus the correlation at one offset (2 where too few samples overlap)."""
        c = self(tau, [offset_s])
        return 2.0 if c is None else -float(c[0])

    @property
    def grid_s(self) -> float:
        """The coarser of the log's sampling interval and the prediction's grid."""
        return max(self.run.interval_s, self.rm.dt_s)


class _Alignment(NamedTuple):
    """A clock offset and meter lag found by the search, the range the refinement may
    move the offset within, and what the report should say about it."""
    offset_s: float
    tau_s: float
    lo_s: float
    hi_s: float
    notes: list


def _search_offset(correlations: _Correlations, taus: list[float], window_s: float,
                   quick: bool, near_s: float | None) -> _Alignment:
    """The offset and lag that correlate best among the coarse candidates' fine offsets
    (or near ``near_s`` alone). A rival clock as good that uses more of the log is
    taken instead, and the report says so: a cycling machine correlates alike whole
    cycles later, and a clock that drops part of the log (the part before a leak
    opened, whose step lowers the whole log's correlation) must not win by dropping it."""
    run, rm = correlations.run, correlations.rm
    g = correlations.grid_s
    candidates = [near_s] if near_s is not None else _coarse_offsets(
        run, rm, correlations.cells, window_s)
    best, scored = _best_candidate(correlations, candidates, taus, quick)
    taken = best
    if len(scored) > 1 and run.sampling != "instant":
        taken = covering_alike(correlations, scored, best)
    rival = _covering_rival(run, rm, scored, taken, g)
    if rival is not None:
        taken = rival
    notes = []
    if taken is not best:
        used = len(_common_samples(run, best[1], best[1], rm.horizon_s))
        n = len(_common_samples(run, taken[1], taken[1], rm.horizon_s))
        notes.append(
            f"{run.name}: a clock {best[1] - taken[1]:+.1f} s from the one taken "
            f"correlates as well or better ({best[0]:.4f} against {taken[0]:.4f}) but "
            f"would use {used} of the log's readings instead of {n}: the one that uses "
            "more is taken; check it, or give --offset")
    offset_s = taken[1]
    return _Alignment(offset_s, taken[2], offset_s - g, offset_s + g, notes)


def _best_candidate(correlations: _Correlations, candidates: list[float],
                    taus: list[float], quick: bool) -> tuple[tuple, list[tuple]]:
    """(the best (correlation, offset, lag) over the candidates, each candidate's own
    best (correlation, offset))."""
    run, rm = correlations.run, correlations.rm
    g = correlations.grid_s
    best = (-2.0, candidates[0], taus[0])
    # every candidate is scored on the same samples, when enough of them are common
    common = (min(candidates) - 1.5 * g - max(taus), max(candidates) + 1.5 * g)
    n_common = len(_common_samples(run, common[0], common[1], rm.horizon_s))
    shared = common if n_common >= 0.75 * len(run.time_s) else None
    # instantaneous readings of a fast meter have narrow valleys of (offset, lag): a
    # grid step off, or a slightly longer lag a fraction of a second later, correlates
    # within a ten-thousandth of the right pair. So their offsets are searched on the
    # prediction's grid, and at each coarse offset the best lag wins outright (a smooth
    # valley of means is followed from the first lag by the refinement)
    instant = run.sampling == "instant"
    scored = []             # (correlation, offset) of each candidate's best
    for coarse in candidates:
        here, own = _fine_offsets(correlations, coarse, taus, shared, quick,
                                  (-2.0, coarse, taus[0]) if instant else best)
        scored.append(own)
        # the first candidate (the smallest shift) wins near-ties
        if not instant or here[0] > best[0] + 2e-3:
            best = here
    return best, scored


def _fine_offsets(correlations: _Correlations, coarse: float, taus: list[float],
                  shared: tuple | None, quick: bool, here: tuple) -> tuple[tuple, tuple]:
    """(``here`` (correlation, offset, lag) improved by the fine offsets around
    ``coarse`` at each lag, the best (correlation, offset, lag) among them alone)."""
    run, rm = correlations.run, correlations.rm
    g = correlations.grid_s
    instant = run.sampling == "instant"
    own = (-2.0, coarse, taus[0])
    for tau in taus:
        # a coarse offset may be late by up to the lag
        step = max(rm.dt_s, tau / 50.0, 0.0 if instant else g / (5.0 if quick else 25.0))
        span = (coarse - 1.5 * g - tau, coarse + 1.5 * g + step / 2)
        # interval means change smoothly with the offset, over a sampling interval:
        # their best offset on a grid five times finer than it lies within one step of
        # that grid's best, and only there is the fine grid read
        wide = step if instant else max(step, g / 5.0)
        fine = np.arange(span[0], span[1], wide)
        corr = correlations(tau, list(fine), shared)
        if corr is not None and wide > step:
            best = float(fine[int(np.argmax(corr))])
            fine = np.arange(max(span[0], best - wide), min(span[1], best + wide + step / 2),
                             step)
            corr = correlations(tau, list(fine), shared)
        if corr is None:
            continue
        k = int(np.argmax(corr))
        own = max(own, (float(corr[k]), float(fine[k]), tau))
        if corr[k] > here[0] + (0.0 if instant else 2e-3):
            here = (float(corr[k]), float(fine[k]), tau)
    return here, own


# candidate clocks whose readings' changes correlate this close to the best's are alike:
# the one that uses most of the log is taken
CHANGES_MARGIN = 0.01


def _uses_more(run: MeasuredRun, n: int, used: int) -> bool:
    """Do ``n`` readings use materially more of the log than ``used``?"""
    return n >= used + max(3, RIVAL_MORE_SHARE * len(run.time_s))


def covering_alike(correlations: _Correlations, scored: list[tuple], best: tuple
                    ) -> tuple:
    """Among the candidates' own best clocks, the one that uses most of the log of those
    whose readings' changes correlate with the log's as well as the best does
    (:meth:`_Correlations.of_changes`, within CHANGES_MARGIN); ``best`` where it is one
    of them (a clock that drops the log's start, where a leak had not yet opened, wins
    the readings' own correlation by dropping it)."""
    run, rm = correlations.run, correlations.rm
    used = len(_common_samples(run, best[1], best[1], rm.horizon_s))
    judged = [(*correlations.of_changes(tau, o), c, o, tau) for c, o, tau in scored]
    top = max(j[0] for j in judged)
    more = [j for j in judged if j[0] >= top - CHANGES_MARGIN and _uses_more(run, j[1], used)]
    if not more:
        return best
    _, _, c, o, tau = max(more, key=lambda j: (j[1], j[2]))
    return c, o, tau


def _covering_rival(run: MeasuredRun, rm: RunModel, scored: list[tuple], best: tuple,
                    g: float) -> tuple | None:
    """(correlation, offset, lag) of the candidate clock, more than a sampling interval
    or two from ``best``'s, that correlates within RIVAL_MARGIN of it and uses
    materially more of the log's readings (the one using most), or None. (Clocks whole
    cycles apart that use the whole log alike give the same diagnosis.)"""
    offset_s = best[1]
    used = len(_common_samples(run, offset_s, offset_s, rm.horizon_s))
    rivals = [(n, c, o, tau) for c, o, tau in scored if abs(o - offset_s) > 2.0 * g + 1.0
              and c >= best[0] - RIVAL_MARGIN
              and _uses_more(run, n := len(_common_samples(run, o, o, rm.horizon_s)), used)]
    if not rivals:
        return None
    _, c, o, tau = max(rivals)
    return c, o, tau


def _lag_at_offset(correlations: _Correlations, taus: list[float], offset_s: float
                   ) -> _Alignment:
    """The lag that correlates best at the given offset, which stays where it is."""
    corr = [correlations(tau, [offset_s]) for tau in taus]
    k = int(np.argmax([-2.0 if c is None else c[0] for c in corr]))
    return _Alignment(offset_s, taus[k], offset_s, offset_s, [])


def _refine_alignment(correlations: _Correlations, found: _Alignment,
                      meter_tau_s: float | None, quick: bool) -> tuple[float, float]:
    """(offset, lag) refined from the search's: the offset alone where the lag is known
    (or, ``quick``, kept at the best of the grid), else both together."""
    # scipy costs a third of a second to import: only the runs that need it pay
    from scipy.optimize import minimize, minimize_scalar

    offset_s, tau, lo_o, hi_o = found.offset_s, found.tau_s, found.lo_s, found.hi_s
    fitted_tau = tau
    if (meter_tau_s is not None or quick) and lo_o < hi_o:
        def offset_objective(o):
            return correlations.cost(tau, o)

        res = minimize_scalar(offset_objective, bounds=(lo_o, hi_o), method="bounded",
                              options={"xatol": correlations.rm.dt_s / 4, "maxiter": 40})
        if res.fun <= offset_objective(offset_s):
            offset_s = float(res.x)
    elif meter_tau_s is None:
        def objective(x):
            o = min(max(x[0], lo_o), hi_o)
            t = min(max(x[1], 0.0), ALIGN_TAUS_S[-1])
            return correlations.cost(t, o)

        dt_s = correlations.rm.dt_s
        x0 = [offset_s, tau]
        simplex = [x0, [offset_s + max(dt_s, correlations.grid_s / 10.0), tau],
                   [offset_s, tau + max(0.02, 0.1 * tau)]]
        res = minimize(objective, x0, method="Nelder-Mead",
                       options={"initial_simplex": simplex, "xatol": dt_s / 4,
                                "fatol": 1e-7, "maxfev": 120})
        if res.fun <= objective(x0):
            offset_s = min(max(float(res.x[0]), lo_o), hi_o)
            fitted_tau = min(max(float(res.x[1]), 0.0), ALIGN_TAUS_S[-1])
    return offset_s, fitted_tau


def _aligned_run(correlations: _Correlations, offset_s: float, tau: float,
                 fitted_tau: float, notes: list[str]) -> RunData:
    """The run's samples within the prediction at ``offset_s``, once the meter has
    settled, as a RunData with the meter lag ``tau``, and how well the log matches the
    machine at all (its correlation with the lag the search found)."""
    run, rm = correlations.run, correlations.rm
    idx, start, end = _intervals(run, offset_s, rm.horizon_s)
    # what the meter read before the machine started (air on or off, leaks settled or
    # not) is unknown: its first readings are left out until its lag has settled (a
    # thermal meter's longest lag when the one found is shorter: a coarse log cannot
    # tell)
    settled = start >= SETTLE_LAGS * max(fitted_tau, METER_LAG_FIT_MAX_S)
    if settled.sum() >= 5:
        idx, start, end = idx[settled], start[settled], end[settled]
    if len(idx) < 5:
        raise DiagnosisError(
            f"{run.name}: only {len(idx)} samples overlap the prediction at the clock "
            f"offset {offset_s:g} s; give the right one with --offset (the logger's time "
            "at the machine's start)")
    p_fit = correlations.params.copy()
    p_fit.meter_tau_s = fitted_tau
    rd = RunData(run, rm, float(offset_s), float(tau), float(fitted_tau), 0.0,
                 start, end, run.flow_l_min[idx])
    rd.notes = notes
    rd.correlation = _pearson(rm.readings(p_fit, rd.read_start_s, end, correlations.cells),
                              rd.measured_l_min)
    return rd


# another clock (more than a sampling interval or two away) this close in correlation
# to the one taken is as good: the report says so
RIVAL_MARGIN = 2e-3
RIVAL_MORE_SHARE = 0.05     # of the log's readings, more that a rival would use


SETTLE_LAGS = 3.0                  # a first-order meter is within 5 % after three lags
COARSE_TAUS_S = (0.0, 1.0, 3.0)    # lags the coarse search tries on the prediction
COARSE_CANDIDATES = 4
COARSE_MARGIN = 0.1                # other peaks are candidates if this close to the best


def _coarse_offsets(run: MeasuredRun, rm: RunModel, cells: np.ndarray,
                    window_s: float) -> list[float]:
    """Candidate offsets (within ``window_s`` of the first sample): where the changes of
    the log and of the prediction (lagged by each of COARSE_TAUS_S), both on a grid of the
    log's sampling interval, correlate best (Pearson over the overlap, at least half of
    the log). The best peaks, the smallest shift among near-equal ones first (a cycling
    machine correlates equally well a whole cycle later)."""
    # scipy costs a third of a second to import: only the runs that need it pay
    from scipy.signal import correlate

    g = max(run.interval_s, rm.dt_s)
    t_first = float(run.time_s[0])
    n_meas = int(run.span_s / g) + 1
    grid = t_first + np.arange(n_meas) * g
    dm = np.diff(np.interp(grid, run.time_s, run.flow_l_min))
    n_pred = int(rm.horizon_s / g)
    pe = np.arange(n_pred + 1) * g
    k_max = int(window_s / g)
    scores: dict[int, float] = {}
    flow = cells / rm.dt_s * 60.0
    n = len(dm)
    cx = np.concatenate([[0.0], np.cumsum(dm)])
    cxx = np.concatenate([[0.0], np.cumsum(dm * dm)])
    s_all = np.arange(-k_max, k_max + 1)
    # the log's sample i (at t_first + i g) averages the prediction's bin
    # [(i + s - 1) g, (i + s) g] when offset = t_first - s g; in differences, step i of
    # the log pairs with step i + s - 1 of the prediction
    i0 = np.maximum(0, 1 - s_all)
    for tau in COARSE_TAUS_S:
        lagged = first_order_lag(flow, rm.dt_s, tau) * rm.dt_s / 60.0
        cum = cumulative_nl(lagged)
        dp = np.diff(np.diff(np.interp(pe, rm.edges_s, cum)) / g)
        i1 = np.minimum(n, len(dp) - s_all + 1)
        ok = (i1 - i0) >= max(5, n // 2)
        if not ok.any():
            continue
        cy = np.concatenate([[0.0], np.cumsum(dp)])
        cyy = np.concatenate([[0.0], np.cumsum(dp * dp)])
        full = correlate(dp, dm, mode="full", method="fft")   # [k] = sum y[i+k-(n-1)] x[i]
        s_ok, a, b = s_all[ok], i0[ok], i1[ok]
        cross = full[s_ok - 1 + n - 1]
        cnt = (b - a).astype(float)
        sx, sxx = cx[b] - cx[a], cxx[b] - cxx[a]
        sy = cy[b + s_ok - 1] - cy[a + s_ok - 1]
        syy = cyy[b + s_ok - 1] - cyy[a + s_ok - 1]
        den = np.sqrt(np.clip((sxx - sx * sx / cnt) * (syy - sy * sy / cnt), 0.0, None))
        r = np.where(den > 0, (cross - sx * sy / cnt) / np.where(den > 0, den, 1.0), 0.0)
        for s, c in zip(s_ok.tolist(), r.tolist()):
            scores[s] = max(scores.get(s, -2.0), c)
    if not scores:
        return [t_first]
    shifts = np.array(sorted(scores))
    corrs = np.array([scores[s] for s in shifts])
    best = corrs.max()
    near = [int(s) for s, c in zip(shifts, corrs) if c >= best - 0.02]
    picks = [min(near, key=abs)]
    for k in np.argsort(-corrs):
        if len(picks) >= COARSE_CANDIDATES or corrs[k] < best - COARSE_MARGIN:
            break
        if all(abs(int(shifts[k]) - p) * g > 2.0 * g + 1.0 for p in picks):
            picks.append(int(shifts[k]))
    return [t_first - p * g for p in picks]


# ---------------------------------------------------------------------- fitting

@dataclass
class FitResult:
    effects: list[Effect]
    theta: np.ndarray
    stderr: np.ndarray
    names: list[str]
    units: list[str]
    params: list                    # per run: the fitted ModelParams
    cost: float
    n_samples: int
    success: bool
    message: str
    counts: list[int] = field(default_factory=list)   # parameters per effect

    def by_effect(self, theta=None):
        """(effect, its slice of ``theta``) for each effect, in order (``theta``: other
        values of the same parameters, default the fitted ones)."""
        return _by_effect(self.effects, self.counts, self.theta if theta is None else theta)

    @property
    def bic(self) -> float:
        n = max(self.n_samples, 1)
        rss = max(2.0 * self.cost, 1e-300)
        return n * math.log(rss / n) + len(self.theta) * math.log(n)


def _by_effect(effects, counts, theta):
    out, k = [], 0
    for e, n in zip(effects, counts):
        out.append((e, theta[k:k + n]))
        k += n
    return out


# the clock nuisance every fit may move: as far as a thermal meter's lag, which the
# alignment may have taken for a later clock (at 1 Hz the two look alike)
CLOCK_ADJUST_MAX_S = METER_LAG_FIT_MAX_S
CLOCK_GRID_S = tuple(np.round(np.arange(-CLOCK_ADJUST_MAX_S, CLOCK_ADJUST_MAX_S + 1e-9, 0.15), 3))


def fit_effects(effects: list[Effect], mm: MachineModel, rds: list[RunData],
                masks: list[np.ndarray], bases: list[ModelParams], ctx: dict,
                start: np.ndarray | None = None, hold_nuisances: bool = False
                ) -> FitResult:
    """Fit ``effects`` jointly to the samples ``masks[r]`` of each run (bounded least
    squares on the meter readings; each run keeps its own aligned base parameters).

    Every fit, the baseline's too (no effects), also refits a clock adjustment within
    CLOCK_ADJUST_MAX_S: the alignment found the offset with the nominal model, and an effect
    that moves air in time (a late valve on the largest drive) pulls it. Parameters with
    a grid (the meter's lag among them when it is fitted) are first swept one at a time,
    each value with every clock adjustment of CLOCK_GRID_S, so that a shift cannot lock
    onto the wrong edge; the one that explains most is kept, then the other effects'
    gridded parameters are swept at its clock. After least squares the clock grid is
    tried again, and least squares rerun from a better clock. Discrete parameters
    (a closed loop's timing, each value a sequencer run) are swept from the nominal
    timing, one drive or all of an effect's drives at a time, the best refined by golden
    section and then held while least squares fits the rest. ``start`` (the values of an
    earlier fit of the same effects, such as the fit on all samples before the folds')
    replaces the initial values and the sweep; its discrete values are refined near
    where they are. ``hold_nuisances`` keeps the start's clock and meter lag (the
    alternate blocks of one run)."""
    problem, u0 = _FitProblem.of(effects, mm, rds, masks, bases, ctx, start, hold_nuisances)
    if start is None:
        u0 = _sweep_timing(problem, u0)
        u0 = _sweep_gridded(problem, u0)
        res, u = _solve_from_best_clock(problem, u0)
    else:
        u0 = _refine_timing(problem, u0)
        res, u = problem.solve(u0)
        u = _blind_back_to_initial(problem, u)
    return _fit_result(problem, res, u)


def params_at(effects: list[Effect], mm: MachineModel, rds: list[RunData],
              bases: list[ModelParams], ctx: dict, theta: np.ndarray) -> list[ModelParams]:
    """Per run: ``bases`` with ``effects`` at ``theta`` (a :class:`FitResult`'s values,
    the clock adjustment and a fitted meter lag last), as a fit of them would give."""
    masks = [np.ones(len(rd.end_s), bool) for rd in rds]
    problem, _ = _FitProblem.of(effects, mm, rds, masks, bases, ctx, None, False)
    return problem.model_params(np.asarray(theta, dtype=float))


@dataclass
class _FitProblem:
    """What a fit varies and what it matches: the effects' parameters, then the clock
    adjustment (and the meter's lag where it is a nuisance), each in unit coordinates
    (``lo + u * span``), and the weighted residuals of the masked samples."""
    effects: list[Effect]
    mm: MachineModel
    rds: list[RunData]
    masks: list[np.ndarray]
    bases: list[ModelParams]
    sizes: list[int]                # parameters per effect
    flat: list[Param]               # every parameter, the clock (and lag) last
    lo: np.ndarray
    hi: np.ndarray
    span: np.ndarray
    lag_free: bool                  # the meter's lag is fitted (after the clock)
    timing_params: list[int]            # the clock (and lag) where they are not held
    held: np.ndarray                # neither swept nor fitted
    u_init: np.ndarray              # the parameters' initial values
    clock_grid_s: tuple             # the clock adjustments a sweep tries

    @classmethod
    def of(cls, effects: list[Effect], mm: MachineModel, rds: list[RunData],
           masks: list[np.ndarray], bases: list[ModelParams], ctx: dict,
           start: np.ndarray | None, hold_nuisances: bool
           ) -> tuple[_FitProblem, np.ndarray]:
        """(the problem, where the fit starts: ``start`` where given, else the initial
        values)."""
        sizes, flat, lag_free = _fit_parameters(effects, mm, ctx, bases)
        lo = np.array([p.lower for p in flat], dtype=float)
        hi = np.array([p.upper for p in flat], dtype=float)
        clock = sum(sizes)
        timing_params = [clock] + ([clock + 1] if lag_free else [])
        # the blocks of one run share its logger and meter: a fold keeps the clock and
        # lag that all its samples found (held: neither swept nor fitted). Half of a 20 s
        # log at 1 Hz, mostly idle, pins no clock, and one that drifts half a second puts
        # every held-out edge in the wrong sample
        held = np.zeros(len(flat), bool)
        if hold_nuisances and start is not None and len(start) == len(flat):
            held[timing_params] = True
            timing_params = []
        hi = np.where(hi > lo, hi, lo + 1e-9)
        x0 = np.clip(np.array([p.init for p in flat], dtype=float), lo, hi)
        span = hi - lo
        u_init = (x0 - lo) / span
        clock_grid_s = CLOCK_GRID_S
        if start is not None and len(start) == len(x0):
            x0 = np.clip(np.asarray(start, dtype=float), lo, hi)
            if hold_nuisances:
                clock_grid_s = (float(x0[clock]),)
        problem = cls(effects, mm, rds, masks, bases, sizes, flat, lo, hi, span, lag_free,
                      timing_params, held, u_init, clock_grid_s)
        return problem, (x0 - lo) / span

    @property
    def clock(self) -> int:
        """The clock adjustment's index (the meter's lag, where fitted, follows it)."""
        return sum(self.sizes)

    @property
    def discrete(self) -> np.ndarray:
        """Per parameter: is it discrete (each value a sequencer or plant run)?"""
        return np.array([p.discrete for p in self.flat])

    @property
    def free(self) -> np.ndarray:
        """The indices least squares fits: neither discrete nor held."""
        return np.flatnonzero(~self.discrete & ~self.held)

    @property
    def groups(self) -> list[list[int]]:
        """The parameters' indices, one list per effect."""
        return [list(range(k, k + n))
                for k, n in zip(np.cumsum([0] + self.sizes[:-1]), self.sizes)]

    @property
    def n_samples(self) -> int:
        """How many samples the fit sees."""
        return int(sum(int(m.sum()) for m in self.masks))

    def model_params(self, theta: np.ndarray) -> list[ModelParams]:
        """Per run: the base parameters with the effects at ``theta`` and its timing_params."""
        clock = self.clock
        out = []
        for base in self.bases:
            p = base
            for e, t in _by_effect(self.effects, self.sizes, theta):
                p = e.apply(self.mm, p, t)
            if p is base:           # effects return copies; the timing_params need one too
                p = base.copy()
            p.clock_adjust_s += float(theta[clock])
            if self.lag_free:
                p.meter_tau_s = float(theta[clock + 1])
            out.append(p)
        return out

    def residuals(self, u: np.ndarray) -> np.ndarray:
        """The masked samples' reading errors at ``u``, weighted by their seconds."""
        theta = self.lo + u * self.span
        out = []
        for rd, m, p in zip(self.rds, self.masks, self.model_params(theta)):
            if m.any():
                out.append((rd.readings(p)[m] - rd.measured_l_min[m])
                           * np.sqrt(rd.weight_s[m]))
        return np.concatenate(out) if out else np.zeros(1)

    def cost(self, u: np.ndarray) -> float:
        """The sum of the squared weighted residuals at ``u``."""
        r = self.residuals(u)
        return float(r @ r)

    def sweep(self, u_from: np.ndarray, ray: list[int], best: tuple,
              at_own_clock: bool = False) -> tuple:
        """``best`` (cost, u) improved by each grid value of ``ray``'s parameters, each
        with every clock adjustment of the clock grid (or ``u_from``'s own), from
        ``u_from``."""
        lo, hi, span, clock = self.lo, self.hi, self.span, self.clock
        clocks = [lo[clock] + u_from[clock] * span[clock]] if at_own_clock \
            else self.clock_grid_s
        for v in self.flat[ray[0]].grid:
            if not lo[ray[0]] <= v <= hi[ray[0]]:
                continue
            for c in clocks:
                u = u_from.copy()
                u[ray] = (v - lo[ray]) / span[ray]
                u[clock] = (c - lo[clock]) / span[clock]
                trial = self.cost(u)
                if trial < best[0]:
                    best = (trial, u)
        return best

    def profiled(self, u: np.ndarray) -> tuple[float, np.ndarray]:
        """(cost, u) with the clock and the meter's lag fitted for ``u``'s other
        values: a plant run's edges are its own, and a value compared at another value's
        clock loses to a worse one"""
        # scipy costs a third of a second to import: only the runs that need it pay
        from scipy.optimize import least_squares

        lo, span, clock, timing_params = self.lo, self.span, self.clock, self.timing_params
        best_c, best_u = min(((self.cost(v), v) for v in (
            _with(u, clock, (c - lo[clock]) / span[clock]) for c in self.clock_grid_s)),
            key=lambda x: x[0])
        if not timing_params:
            return best_c, best_u
        r = least_squares(lambda v: self.residuals(_with(best_u, timing_params, v)),
                          best_u[timing_params], bounds=(0.0, 1.0), diff_step=1e-4,
                          max_nfev=10 * len(timing_params))
        return (2.0 * r.cost, _with(best_u, timing_params, r.x)) if 2.0 * r.cost < best_c \
            else (best_c, best_u)

    def solve(self, u_from: np.ndarray):
        """(least squares' result, u) fitting the free parameters from ``u_from``'s
        values, the others held at them."""
        # scipy costs a third of a second to import: only the runs that need it pay
        from scipy.optimize import least_squares

        free = self.free
        if not len(free):       # a baseline fold with its timing_params held: nothing to fit
            r0 = self.residuals(u_from)
            return SimpleNamespace(x=np.zeros(0), cost=0.5 * float(r0 @ r0),
                                   jac=np.zeros((len(r0), 0)), success=True,
                                   message="nothing to fit"), u_from.copy()
        r = least_squares(lambda v: self.residuals(_with(u_from, free, v)), u_from[free],
                          bounds=(0.0, 1.0), diff_step=1e-4, x_scale=1.0,
                          max_nfev=40 * (len(free) + 1))
        u = u_from.copy()
        u[free] = r.x
        return r, u


def _fit_parameters(effects: list[Effect], mm: MachineModel, ctx: dict,
                    bases: list[ModelParams]) -> tuple[list[int], list[Param], bool]:
    """(parameters per effect, every parameter with the clock adjustment (and the
    meter's lag) last, whether the lag is fitted)."""
    specs = [e.params(mm, ctx) for e in effects]
    sizes = [len(s) for s in specs]
    flat = [p for s in specs for p in s]
    flat.append(Param("clock_adjust_s", "s", -CLOCK_ADJUST_MAX_S, CLOCK_ADJUST_MAX_S, 0.0))
    # the meter's lag, when the machine file does not give it, is a nuisance within a
    # thermal meter's range too (the alignment's estimate is pulled by the effect)
    lag_free = ctx.get("meter_tau_s") is None and not any(
        e.name == "sensor_lag" for e in effects)
    if lag_free:
        # swept with the clock: a log at 1 Hz barely tells a lag from a later clock,
        # and least squares from the alignment's pair stays in its valley
        flat.append(Param("meter_tau_s", "s", 0.0, METER_LAG_FIT_MAX_S,
                          float(np.mean([b.meter_tau_s for b in bases])),
                          tuple(np.linspace(0.0, METER_LAG_FIT_MAX_S, 5))))
    return sizes, flat, lag_free


def _sweep_timing(problem: _FitProblem, u0: np.ndarray) -> np.ndarray:
    """``u0`` with a closed loop's timing (the discrete parameters) swept: each drive
    alone, then the effect's drives together, from the nominal timing (swept one after
    the other, an early drive would take the whole gap just because it is swept
    first); the best ray is then refined."""
    flat, lo, span = problem.flat, problem.lo, problem.span
    rays = _discrete_rays(problem.groups, problem.discrete, [p.joint for p in flat])
    if not rays:
        return u0
    plant = flat[rays[0][0]].plant
    best, best_ray = problem.profiled(u0) if plant else (problem.cost(u0), u0), None
    for ray in rays:
        if plant:
            trial = _profiled_sweep(problem.profiled, u0, ray, flat[ray[0]], lo, span, best)
        else:
            trial = problem.sweep(u0, ray, best)
        if trial[0] < best[0]:
            best, best_ray = trial, ray
    u0 = best[1]
    if best_ray is not None:
        u0 = golden_refine(problem.cost, u0, best_ray, flat[best_ray[0]], lo, span,
                            profiled=problem.profiled if plant else None)
    return u0


def _refine_timing(problem: _FitProblem, u0: np.ndarray) -> np.ndarray:
    """``u0`` with a fold's own values of the discrete parameters, near the start's:
    an effect's drives moved alike together, else each alone."""
    flat, lo, span, discrete = problem.flat, problem.lo, problem.span, problem.discrete
    if not _discrete_rays(problem.groups, discrete, [p.joint for p in flat]):
        return u0
    for g in problem.groups:
        d = [j for j in g if discrete[j]]
        moved = [j for j in d if abs(u0[j] - problem.u_init[j]) > 1e-12]
        values = lo[moved] + u0[moved] * span[moved]
        together = len(moved) == len(d) > 1 and np.ptp(values) < 1e-9
        for ray in [moved] if together else [[j] for j in moved]:
            if flat[ray[0]].plant:
                # each value a plant run: the grid the fit on all samples ran, and
                # the value it found
                u0 = _profiled_sweep(problem.profiled, u0, ray, flat[ray[0]], lo, span,
                                     problem.profiled(u0))[1]
            else:
                u0 = golden_refine(problem.cost, u0, ray, flat[ray[0]], lo, span,
                                    narrow=True)
    return u0


def _sweep_gridded(problem: _FitProblem, u0: np.ndarray) -> np.ndarray:
    """``u0`` with the gridded parameters that are not discrete swept: first the one
    that alone explains most, with the clock (swept one after the other from the start,
    the first drive of a valve delay would take a gap that is another's), then the
    others one after the other from there at that clock (every drive later and the
    clock earlier look alike: noise would choose)."""
    gridded = [j for j, p in enumerate(problem.flat) if p.grid and not p.discrete]
    if not gridded:
        return u0
    alone = {j: problem.sweep(u0, [j], (problem.cost(u0), u0)) for j in gridded}
    first = min(gridded, key=lambda j: alone[j][0])
    best = alone[first]
    u0 = best[1]
    same = next((g for g in problem.groups if first in g), [first])
    for j in gridded:
        # the first one's siblings (the other drives of its effect) are left to
        # least squares from their neutral values: swept, they take up noise
        if j not in same:
            best = problem.sweep(u0, [j], best, at_own_clock=True)
            u0 = best[1]
    return u0


def _solve_from_best_clock(problem: _FitProblem, u0: np.ndarray):
    """(least squares' result, u) from ``u0``, run again from a better clock where the
    clock grid finds one once the other parameters are fitted.

    The sweep chose the clock (and the meter's lag) with the other parameters at their
    initial values (a leak still far from its size, a knife's flow half what it is).
    A lag left at a bound of its range (none, or the slowest thermal meter) was most
    likely traded for the clock against a wrong amplitude: then each lag of its grid is
    tried with the clock too."""
    res, u = problem.solve(u0)
    c0 = 2.0 * res.cost
    best = _best_clock(problem, u, c0)
    if best[0] < c0 * (1.0 - 1e-6):
        res2, u2 = problem.solve(best[1])
        if res2.cost < res.cost:
            res, u = res2, u2
    return res, u


def _best_clock(problem: _FitProblem, u: np.ndarray, cost: float) -> tuple:
    """(cost, u) of the best clock adjustment of CLOCK_GRID_S for ``u`` (and lag, where
    ``u``'s is at a bound of its range), or ``u`` itself at ``cost``."""
    lo, span, clock, flat = problem.lo, problem.span, problem.clock, problem.flat
    best = (cost, u)
    at_bound = problem.lag_free and (u[clock + 1] < 1e-6 or u[clock + 1] > 1.0 - 1e-6)
    lags = [None] + ([v for v in flat[clock + 1].grid] if at_bound else [])
    for c in CLOCK_GRID_S:
        for lag in lags:
            trial_u = u.copy()
            trial_u[clock] = (c - lo[clock]) / span[clock]
            if lag is not None:
                trial_u[clock + 1] = (lag - lo[clock + 1]) / span[clock + 1]
            trial = problem.cost(trial_u)
            if trial < best[0]:
                best = (trial, trial_u)
    return best


def _blind_back_to_initial(problem: _FitProblem, u: np.ndarray) -> np.ndarray:
    """``u`` with each effect parameter these samples say nothing about (a nozzle never
    on in them) back at its initial value: it must not keep what the start learnt from
    other samples. (The timing_params start where the alignment put them.) Blind means that
    moving it back changes none of these residuals; a small gradient is not enough (a
    valve delay between two grid cells has none)."""
    r0 = problem.residuals(u)
    free = problem.free
    for j in free[free < problem.clock]:
        if u[j] == problem.u_init[j]:
            continue
        trial = u.copy()
        trial[j] = problem.u_init[j]
        if np.array_equal(problem.residuals(trial), r0):
            u = trial
    return u


def _fit_result(problem: _FitProblem, res, u: np.ndarray) -> FitResult:
    """The fit at ``u``, standard errors of the free parameters from the Jacobian."""
    theta = problem.lo + u * problem.span
    n = problem.n_samples
    free = problem.free
    stderr = np.full(len(theta), math.nan)
    try:
        J = res.jac
        dof = max(1, n - len(theta))
        s2 = 2.0 * res.cost / dof
        cov = np.linalg.pinv(J.T @ J) * s2
        stderr[free] = np.sqrt(np.clip(np.diag(cov), 0.0, None)) * problem.span[free]
    except (ValueError, np.linalg.LinAlgError):
        pass
    flat = problem.flat
    return FitResult(problem.effects, theta, stderr, [p.name for p in flat],
                     [p.unit for p in flat], problem.model_params(theta), float(res.cost), n,
                     bool(res.success), str(res.message), problem.sizes)


GOLDEN_STEPS = 6
NARROW = 0.25          # a fold's refinement: this share of the way to the grid neighbours


def _discrete_rays(groups: list[list[int]], discrete: np.ndarray,
                   joint: list[bool]) -> list[list[int]]:
    """The directions a discrete sweep tries: each discrete parameter alone, and all of
    one effect's discrete parameters together (every valve slower by the same delay)
    where they are ``joint`` (one value means the same for each)."""
    rays = []
    for g in groups:
        d = [j for j in g if discrete[j]]
        rays += [[j] for j in d]
        if len(d) > 1 and all(joint[j] for j in d):
            rays.append(d)
    return rays


def _with(u: np.ndarray, idx, values) -> np.ndarray:
    out = u.copy()
    out[idx] = values
    return out


def _profiled_sweep(profiled, u0: np.ndarray, ray: list[int], param: Param, lo: np.ndarray,
                    span: np.ndarray, best: tuple) -> tuple:
    """``best`` (cost, u) improved by each grid value of the parameters ``ray`` (set
    to one value together) from ``u0``, each with its timing_params fitted (``profiled``)."""
    for v in param.grid:
        if param.lower <= v <= param.upper:
            trial = profiled(_with(u0, ray, np.clip((v - lo[ray]) / span[ray], 0.0, 1.0)))
            if trial[0] < best[0]:
                best = trial
    return best


def golden_refine(cost, u0: np.ndarray, ray: list[int], param: Param, lo: np.ndarray,
                   span: np.ndarray, narrow: bool = False, profiled=None) -> np.ndarray:
    """``u0`` with the parameters ``ray`` (set to one value together) refined by
    golden-section search between the grid values either side of their value (the
    bounds where the grid ends; with ``narrow``, NARROW of the way to them), the others
    held (or, with ``profiled``, u -> (cost, u), fitted for each value): for a discrete
    parameter each evaluation is a sequencer or plant run, so a few, not a gradient."""
    j = ray[0]
    v = lo[j] + u0[j] * span[j]
    grid = sorted(g for g in param.grid if param.lower <= g <= param.upper)
    a = max([g for g in grid if g < v - 1e-12], default=param.lower)
    b = min([g for g in grid if g > v + 1e-12], default=param.upper)
    if narrow:
        a, b = v - NARROW * (v - a), v + NARROW * (b - v)

    def at(x):
        u = u0.copy()
        u[ray] = np.clip((x - lo[ray]) / span[ray], 0.0, 1.0)
        return profiled(u) if profiled else (cost(u), u)

    ratio = (math.sqrt(5.0) - 1.0) / 2.0
    best = profiled(u0) if profiled else (cost(u0), u0)
    c, d = b - ratio * (b - a), a + ratio * (b - a)
    fc, fd = at(c), at(d)
    for _ in range(GOLDEN_STEPS - 2 if narrow else GOLDEN_STEPS):
        best = min((best, fc, fd), key=lambda x: x[0])
        if fc[0] < fd[0]:
            b, d, fd = d, c, fc
            c = b - ratio * (b - a)
            fc = at(c)
        else:
            a, c, fc = c, d, fd
            d = a + ratio * (b - a)
            fd = at(d)
    return min((best, fc, fd), key=lambda x: x[0])[1]


def folds(rds: list[RunData], period_s: float | None = None) -> list[list[np.ndarray]]:
    """Fit masks, one list (per run) per fold: leave one run out when there are several
    runs; with one run, alternate blocks (at least two cycles long when the cycle is
    known, at least ten samples, up to twenty blocks) fitted on the even blocks and
    scored on the odd ones, then the other way round."""
    if len(rds) >= 2:
        return [[np.full(len(rd.end_s), k != j) for k, rd in enumerate(rds)]
                for j in range(len(rds))]
    rd = rds[0]
    span = float(rd.end_s[-1] - rd.start_s[0])
    # blocks of at least two cycles (each holds every context of a cycling machine) and
    # ten samples; a one-off sequence gets short blocks so that its parts interleave
    block_s = max(2.0 * (period_s or 0.0), 10.0 * rd.run.interval_s, span / 20.0)
    n_blocks = int(np.clip(span // block_s, 2, 20))
    n_blocks += n_blocks % 2
    block = np.minimum(((rd.end_s - rd.start_s[0]) / span * n_blocks).astype(int),
                       n_blocks - 1)
    even = block % 2 == 0
    return [[even], [~even]]


@dataclass
class Score:
    measured_nl: float
    predicted_nl: float
    rmse_l_min: float
    n: int

    @property
    def error_pct(self) -> float:
        if self.measured_nl == 0:
            return math.nan
        return (self.predicted_nl - self.measured_nl) / self.measured_nl * 100.0

    @property
    def mse(self) -> float:
        return self.rmse_l_min ** 2


class _Tally:
    """Measured and predicted NL and squared error summed over samples of runs."""

    def __init__(self):
        self.meas = self.pred = self.sq = self.weight = 0.0
        self.n = 0

    def add(self, rd: RunData, params: ModelParams, mask: np.ndarray) -> None:
        if not mask.any():
            return
        r = rd.readings(params)[mask]
        w = rd.weight_s[mask]
        self.meas += float(rd.measured_l_min[mask] @ w) / 60.0
        self.pred += float(r @ w) / 60.0
        self.sq += float(((r - rd.measured_l_min[mask]) ** 2) @ w)
        self.weight += float(w.sum())
        self.n += int(mask.sum())

    def score(self) -> Score:
        rmse = math.sqrt(self.sq / self.weight) if self.weight else math.nan
        return Score(self.meas, self.pred, rmse, self.n)


def score(rds: list[RunData], params_per_run: list[ModelParams]) -> Score:
    """Measured and predicted NL and the RMSE of the readings over all samples."""
    tally = _Tally()
    for rd, p in zip(rds, params_per_run):
        tally.add(rd, p, np.ones(len(rd.end_s), bool))
    return tally.score()


def heldout(effects: list[Effect], mm: MachineModel, rds: list[RunData],
            bases: list[ModelParams], ctx: dict, fold_masks,
            start: np.ndarray | None = None) -> Score:
    """Fit on each fold's samples, score on the rest, pooled over the folds (with no
    effects: the baseline, its clock refitted, on the same samples)."""
    tally = _Tally()
    for masks in fold_masks:
        # alternate blocks of one run: the run's clock and meter, as every sample
        # found them
        params = fit_effects(effects, mm, rds, masks, bases, ctx, start,
                             hold_nuisances=len(rds) == 1).params
        for rd, m, p in zip(rds, masks, params):
            if not m.any():
                p = _own_clock(rd, p)
            tally.add(rd, p, ~m)
    return tally.score()


# how far a left-out run's clock may differ from the fitted runs': what two alignments
# disagree by, not a lag (at 1 Hz a wider reach lets the baseline take a slow meter's
# lag for a clock, and the sensor_lag effect goes unseen)
OWN_CLOCK_ADJUST_MAX_S = 0.1


def _own_clock(rd: RunData, params: ModelParams) -> ModelParams:
    """``params`` with the clock adjustment that fits run ``rd`` best (within
    OWN_CLOCK_ADJUST_MAX_S of the fitted one), the model itself unchanged: a run left out of a
    fit still has its own logger clock, which the alignment found with the nominal model
    (the same for every effect and the baseline)."""
    # scipy costs a third of a second to import: only the runs that need it pay
    from scipy.optimize import minimize_scalar

    def sq(adj):
        p = params.copy()
        p.clock_adjust_s = adj
        r = rd.readings(p) - rd.measured_l_min
        return float((r * r) @ rd.weight_s)

    a0 = params.clock_adjust_s
    res = minimize_scalar(sq, bounds=(a0 - OWN_CLOCK_ADJUST_MAX_S, a0 + OWN_CLOCK_ADJUST_MAX_S),
                          method="bounded", options={"xatol": 1e-3})
    out = params.copy()
    out.clock_adjust_s = float(res.x) if res.fun < sq(a0) else a0
    return out
