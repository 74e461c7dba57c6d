"""Aligning a log to its prediction, fitting effects to some samples and scoring them on
others.

* :func:`align` finds a run's clock offset (and, unless the machine file gives the
  meter's response, a nuisance lag within the 0-0.6 s of thermal-mass meters): coarse by
  cross-correlating the changes of both series, fine by the correlation of the meter
  readings themselves.
* :func:`fit_effects` fits one or more effects jointly with bounded least squares
  (``scipy.optimize.least_squares``), standard errors from the Jacobian.
* :func:`folds` says which samples each fit may see: leave one run out, or with a single
  run alternate blocks of it, so that every figure called "held-out" comes from samples
  the fit never saw.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import PlcpredError
from .effects import NUISANCE_METER_TAU_S, Effect
from .io import MeasuredRun
from .model import MachineModel, ModelParams, RunModel


class DiagnosisError(PlcpredError):
    """Measured data that cannot be compared with the machine's prediction."""


@dataclass
class RunData:
    """A measured run tied to its prediction: the samples that fall within the predicted
    horizon, their intervals in prediction time, and their weights (seconds)."""
    run: MeasuredRun
    model: RunModel
    offset_s: float                 # logger clock at the prediction's time 0
    meter_tau_s: float
    correlation: float
    index: np.ndarray               # samples of ``run`` used
    start_s: np.ndarray             # prediction time
    end_s: np.ndarray
    measured_l_min: np.ndarray
    weight_s: np.ndarray = field(init=False)
    fitted_tau_s: float = 0.0        # the lag the alignment found (may exceed meter_tau_s)

    def __post_init__(self):
        self.weight_s = self.end_s - self.start_s

    def readings(self, params: ModelParams) -> np.ndarray:
        return self.model.readings(params, self.start_s, self.end_s)


def _intervals(run: MeasuredRun, offset_s: float, horizon_s: float):
    start = run.interval_starts_s() - offset_s
    end = run.time_s - offset_s
    keep = (start >= 0.0) & (end <= horizon_s)
    return np.flatnonzero(keep), start[keep], end[keep]


def _pearson(a: np.ndarray, b: np.ndarray) -> float:
    a = a - a.mean()
    b = b - b.mean()
    den = math.sqrt(float(a @ a) * float(b @ b))
    return float(a @ b) / den if den > 0 else 0.0


# lags tried when the meter's is not known; the baseline keeps at most the nuisance one
ALIGN_TAUS_S = (0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.8, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0,
                10.0)


def align(run: MeasuredRun, rm: RunModel, params: ModelParams, window_s: float,
          meter_tau_s: float | None = None, offset_s: float | None = None) -> RunData:
    """Tie ``run`` to its prediction ``rm``. The offset is the logger's clock reading at
    the prediction's time 0, searched within ``window_s`` of the log's first sample
    unless ``offset_s`` is given. The meter lag is ``meter_tau_s`` when the machine file
    gives it; else the lag and the offset that correlate best are searched together (a
    lag delays every reading, so the two trade off) and the run keeps the lag up to the
    0.6 s of a thermal-mass meter: a slower meter is the ``sensor_lag`` effect
    (``RunData.fitted_tau_s`` keeps what the search found)."""
    from scipy.optimize import minimize

    taus = [meter_tau_s] if meter_tau_s is not None else list(ALIGN_TAUS_S)
    cells = rm.total_cells(params)

    def correlations(tau, offsets):
        """Correlation of the readings with the log for each offset (over the samples
        valid for all of them)."""
        p = params.copy()
        p.meter_tau_s = tau
        idx = np.intersect1d(_intervals(run, max(offsets), rm.horizon_s)[0],
                             _intervals(run, min(offsets), rm.horizon_s)[0])
        if len(idx) < 5:
            return None
        starts = run.interval_starts_s()[idx]
        ends = run.time_s[idx]
        meas = run.flow_l_min[idx]
        return np.array([_pearson(rm.readings(p, starts - o, ends - o, cells), meas)
                         for o in offsets])

    g = max(run.interval_s, rm.dt_s)
    if offset_s is None:
        coarse = _coarse_offset(run, rm, cells, window_s)
        best = (-2.0, coarse, taus[0])
        for tau in taus:
            # the lag-free coarse offset is late by about the lag
            step = max(rm.dt_s, g / 25.0, tau / 50.0)
            fine = np.arange(coarse - 1.5 * g - tau, coarse + 1.5 * g + step / 2, step)
            corr = correlations(tau, list(fine))
            if corr is None:
                continue
            k = int(np.argmax(corr))
            if corr[k] > best[0] + 1e-9:
                best = (float(corr[k]), float(fine[k]), tau)
        _, offset_s, tau = best
        lo_o, hi_o = offset_s - g, offset_s + g
    else:
        corr = [correlations(tau, [offset_s]) for tau in taus]
        k = int(np.argmax([-2.0 if c is None else c[0] for c in corr]))
        tau = taus[k]
        lo_o = hi_o = offset_s
    fitted_tau = tau
    if meter_tau_s is None or lo_o < hi_o:
        # continuous refinement of (offset, lag)
        tau_free = meter_tau_s is None

        def objective(x):
            o = min(max(x[0], lo_o), hi_o)
            t = min(max(x[1], 0.0), ALIGN_TAUS_S[-1]) if tau_free else tau
            c = correlations(t, [o])
            return 2.0 if c is None else -float(c[0])

        x0 = [offset_s, tau]
        simplex = [x0, [offset_s + max(rm.dt_s, g / 10.0), tau],
                   [offset_s, tau + max(0.02, 0.1 * tau)]]
        res = minimize(objective, x0, method="Nelder-Mead",
                       options={"initial_simplex": simplex, "xatol": rm.dt_s / 4,
                                "fatol": 1e-7, "maxfev": 120})
        if res.fun <= objective(x0):
            offset_s = min(max(float(res.x[0]), lo_o), hi_o)
            if tau_free:
                fitted_tau = min(max(float(res.x[1]), 0.0), ALIGN_TAUS_S[-1])
    tau = fitted_tau if meter_tau_s is not None else min(fitted_tau, NUISANCE_METER_TAU_S)
    p = params.copy()
    p.meter_tau_s = tau
    idx, start, end = _intervals(run, offset_s, rm.horizon_s)
    if len(idx) < 5:
        raise DiagnosisError(
            f"{run.name}: only {len(idx)} samples overlap the prediction at the clock "
            f"offset {offset_s:g} s; give the right one with --offset (the logger's time "
            "at the machine's start)")
    corr_best = _pearson(rm.readings(p, start, end, cells), run.flow_l_min[idx])
    rd = RunData(run, rm, float(offset_s), float(tau), float(corr_best), idx, start, end,
                 run.flow_l_min[idx])
    rd.fitted_tau_s = float(fitted_tau)
    return rd


def _coarse_offset(run: MeasuredRun, rm: RunModel, cells: np.ndarray,
                   window_s: float) -> float:
    """The offset (within ``window_s`` of the first sample) at which the changes of the
    log and of the prediction, both on a grid of the log's sampling interval, correlate
    best (Pearson over the overlap, at least half of the log)."""
    g = max(run.interval_s, rm.dt_s)
    t_first = float(run.time_s[0])
    n_meas = int(run.span_s / g) + 1
    grid = t_first + np.arange(n_meas) * g
    meas = np.interp(grid, run.time_s, run.flow_l_min)
    n_pred = int(rm.horizon_s / g)
    from .meter import cumulative_nl

    cum = cumulative_nl(cells)
    pe = np.arange(n_pred + 1) * g
    pred = np.diff(np.interp(pe, rm.edges_s, cum)) / g
    dm = np.diff(meas)
    dp = np.diff(pred)
    k_max = int(window_s / g)
    shifts, corrs = [], []
    for s in range(-k_max, k_max + 1):
        # the log's sample i (at t_first + i g) averages the prediction's bin
        # [(i + s - 1) g, (i + s) g] when offset = t_first - s g; in differences, step i
        # of the log pairs with step i + s - 1 of the prediction
        i0 = max(0, 1 - s)
        i1 = min(len(dm), len(dp) - s + 1)
        if i1 - i0 < max(5, len(dm) // 2):
            continue
        shifts.append(s)
        corrs.append(_pearson(dm[i0:i1], dp[i0 + s - 1:i1 + s - 1]))
    if not shifts:
        return t_first
    corrs = np.array(corrs)
    # a cycling machine correlates equally well a whole cycle later: among the peaks
    # within 0.02 of the best, the smallest shift (the log starting with the machine)
    near = [s for s, c in zip(shifts, corrs) if c >= corrs.max() - 0.02]
    return t_first - min(near, key=abs) * g


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

    @property
    def bic(self) -> float:
        n = max(self.n_samples, 1)
        rss = max(2.0 * self.cost, 1e-300)
        return n * math.log(rss / n) + len(self.theta) * math.log(n)


def _apply(effects, mm, base: ModelParams, theta, sizes):
    p = base
    k = 0
    for e, n in zip(effects, sizes):
        p = e.apply(mm, p, theta[k:k + n])
        k += n
    return p


def fit_effects(effects: list[Effect], mm: MachineModel, rds: list[RunData],
                masks: list[np.ndarray], bases: list[ModelParams], ctx: dict) -> FitResult:
    """Fit ``effects`` jointly to the samples ``masks[r]`` of each run (bounded least
    squares on the meter readings; each run keeps its own aligned base parameters)."""
    from scipy.optimize import least_squares

    specs = [e.params(mm, ctx) for e in effects]
    sizes = [len(s) for s in specs]
    flat = [p for s in specs for p in s]
    lo = np.array([p.lower for p in flat], dtype=float)
    hi = np.array([p.upper for p in flat], dtype=float)
    hi = np.where(hi > lo, hi, lo + 1e-9)
    x0 = np.clip(np.array([p.init for p in flat], dtype=float), lo, hi)
    span = hi - lo
    n = int(sum(int(m.sum()) for m in masks))

    def residuals(u):
        theta = lo + u * span
        out = []
        for rd, m, base in zip(rds, masks, bases):
            if not m.any():
                continue
            p = _apply(effects, mm, base, theta, sizes)
            out.append((rd.readings(p)[m] - rd.measured_l_min[m]) * np.sqrt(rd.weight_s[m]))
        return np.concatenate(out) if out else np.zeros(1)

    if not flat:
        r = residuals(np.zeros(0))
        return FitResult(effects, np.zeros(0), np.zeros(0), [], [], bases, 0.5 * float(r @ r),
                         n, True, "nothing to fit", sizes)
    u0 = (x0 - lo) / span
    res = least_squares(residuals, u0, bounds=(0.0, 1.0), diff_step=1e-4, x_scale=1.0,
                        max_nfev=40 * (len(flat) + 1))
    theta = lo + res.x * span
    stderr = np.full(len(theta), math.nan)
    try:
        J = res.jac
        dof = max(1, n - len(theta))
        s2 = 2.0 * res.cost / dof
        cov = np.linalg.pinv(J.T @ J) * s2
        stderr = np.sqrt(np.clip(np.diag(cov), 0.0, None)) * span
    except (ValueError, np.linalg.LinAlgError):
        pass
    params = [_apply(effects, mm, base, theta, sizes) for base in bases]
    return FitResult(effects, theta, stderr, [p.name for p in flat], [p.unit for p in flat],
                     params, float(res.cost), n, bool(res.success), str(res.message), sizes)


def folds(rds: list[RunData], period_s: float | None = None) -> list[list[np.ndarray]]:
    """Fit masks, one list (per run) per fold: leave one run out when there are several
    runs; with one run, alternate blocks (at least two cycles long when the cycle is
    known, at least ten samples, up to twenty blocks) fitted on the even blocks and scored on the odd ones, then
    the other way round."""
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


def score(rds: list[RunData], params_per_run: list[ModelParams],
          masks: list[np.ndarray] | None = None) -> Score:
    """Measured and predicted NL and the RMSE of the readings over the masked samples."""
    tally = _Tally()
    for k, (rd, p) in enumerate(zip(rds, params_per_run)):
        tally.add(rd, p, np.ones(len(rd.end_s), bool) if masks is None else masks[k])
    return tally.score()


def heldout(effects: list[Effect], mm: MachineModel, rds: list[RunData],
            bases: list[ModelParams], ctx: dict, fold_masks) -> Score:
    """Fit on each fold's samples, score on the rest, pooled over the folds (with no
    effects: the baseline on the same samples)."""
    tally = _Tally()
    for masks in fold_masks:
        params = fit_effects(effects, mm, rds, masks, bases, ctx).params if effects \
            else bases
        for rd, m, p in zip(rds, masks, params):
            tally.add(rd, p, ~m)
    return tally.score()
