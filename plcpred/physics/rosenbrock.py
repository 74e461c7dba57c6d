"""A linearly implicit integrator for the plant's pieces: ROS34PW2, a Rosenbrock-W method.

The plant's equations (docs/reference/physics.md: dynamic model, D2 and D4) are stiff where a
chamber is nearly full or empty (its pressure follows the supply within milliseconds while
its temperature relaxes over seconds) and not stiff while a piston moves. A Rosenbrock
method takes each step with one linear solve per stage instead of Newton iterations; a
*W*-method keeps its order with any approximation of the Jacobian, so one Jacobian
(by finite differences of the right-hand side) serves many steps and is renewed only when a
step fails or the step size has moved far from the one it was factored for.

Method: ROS34PW2 of Rang and Angermann (BIT 45 (2005) 761-787), 4 stages, order 3 with an
embedded order-2 estimate, L-stable and stiffly accurate, written in the transformed form
of Hairer and Wanner (Solving ODEs II, section IV.7, (7.17)-(7.18)): with
``G = I/(h gamma) - J``, ``G u_i = f(y0 + sum_j a_ij u_j) + sum_j (c_ij/h) u_j``,
``y1 = y0 + sum_i m_i u_i``. The dense output is the cubic Hermite interpolant of each step
(states and right-hand sides at both ends), which the events are located on.

Only numpy: scipy's integrate package takes a third of a second to import, longer than
most emulations take to integrate.
"""
from __future__ import annotations

import math

import numpy as np

# ROS34PW2 in Hairer's form: alpha (A), gamma (Gam, lower triangular with gamma on the
# diagonal), b and the embedded bhat.
_GAMMA = 4.3586652150845900e-01
_A = np.array([[0.0, 0.0, 0.0, 0.0],
               [8.7173304301691801e-01, 0.0, 0.0, 0.0],
               [8.4457060015369423e-01, -1.1299064236397981e-01, 0.0, 0.0],
               [0.0, 0.0, 1.0, 0.0]])
_GAM = np.array([[_GAMMA, 0.0, 0.0, 0.0],
                 [-8.7173304301691801e-01, _GAMMA, 0.0, 0.0],
                 [-9.0338057013044082e-01, 5.4180672388095326e-02, _GAMMA, 0.0],
                 [2.4212380706095346e-01, -1.2232505839045147e+00, 5.4526025533510214e-01,
                  _GAMMA]])
_B = np.array([2.4212380706095346e-01, -1.2232505839045147e+00, 1.5452602553351023e+00,
               4.3586652150845900e-01])
_BHAT = np.array([3.7810903145819369e-01, -9.6042292212423178e-02, 5.0000000000000000e-01,
                  2.1793326075422950e-01])
# the transformed coefficients (Hairer and Wanner (7.18))
_GINV = np.linalg.inv(_GAM)
TA = np.tril(_A @ _GINV, -1)          # a_ij: stage states from earlier u_j
TC = np.tril(np.diag(1.0 / np.diag(_GAM)) - _GINV, -1)   # c_ij: (c_ij / h) u_j added to f
TM = _B @ _GINV                       # y1 = y0 + sum m_i u_i
TE = (_B - _BHAT) @ _GINV             # the error estimate
STAGE_T = _A.sum(axis=1)              # stage times (fractions of h)
ORDER_EST = 3.0                       # the estimate's error goes as h^3

STATS = {"jac": 0, "inv": 0, "rej": 0}   # work done (Jacobians, inversions, rejected steps)
SAFETY, FAC_MIN, FAC_MAX = 0.9, 0.2, 6.0
START_RETRIES = 4   # shorter steps tried before an event is taken where it starts
HOLD_MAX = 1.2     # step-size gains below this keep h (and G)
JAC_MAX_AGE = 10    # accepted steps one Jacobian serves at most


class OverBudget(Exception):
    """More right-hand-side evaluations than the caller allowed."""


class StepFailure(ArithmeticError):
    """The step size fell below what the clock resolves (equations too stiff or broken)."""


class HermiteDense:
    """The solution between accepted steps as cubic Hermite pieces; ``sol(rel)`` gives
    states as scipy's dense outputs do: shape (n,) for a scalar time, (n, m) for m times.

    ``monotone``: columns (accumulated quantities such as the air drawn) whose pieces
    are kept monotone where the step's data are (Fritsch and Carlson's limit on the end
    slopes, SIAM J. Numer. Anal. 17 (1980) 238): a drawn mass that only grows over a
    step must not dip between its ends."""

    def __init__(self, ts: np.ndarray, ys: np.ndarray, fs: np.ndarray,
                 monotone: np.ndarray | None = None):
        self.ts, self.ys = ts, ys
        f0, f1 = fs[:-1].copy(), fs[1:].copy()
        if monotone is not None and np.any(monotone) and len(ts) > 1:
            h = np.diff(ts)[:, None]
            d = (ys[1:, monotone] - ys[:-1, monotone]) / h
            a0, a1 = f0[:, monotone], f1[:, monotone]
            with np.errstate(divide="ignore", invalid="ignore"):
                r0, r1 = a0 / d, a1 / d
                norm = np.sqrt(r0 * r0 + r1 * r1)
                shrink = np.where((d != 0) & (r0 >= 0) & (r1 >= 0) & (norm > 3.0),
                                  3.0 / norm, 1.0)
            flat = d == 0.0
            f0[:, monotone] = np.where(flat, 0.0, a0 * shrink)
            f1[:, monotone] = np.where(flat, 0.0, a1 * shrink)
        self.f0, self.f1 = f0, f1

    def __call__(self, rel, cols=None):
        """States at relative times ``rel``; ``cols``: only these states (indices)."""
        scalar = np.ndim(rel) == 0
        t = np.atleast_1d(np.asarray(rel, dtype=float))
        ts = self.ts
        ys, f0, f1 = (self.ys, self.f0, self.f1) if cols is None else (
            self.ys[:, cols], self.f0[:, cols], self.f1[:, cols])
        if len(ts) < 2:
            out = np.repeat(ys[:1], len(t), axis=0)
        else:
            k = np.clip(np.searchsorted(ts, t, side="right") - 1, 0, len(ts) - 2)
            h = (ts[k + 1] - ts[k])[:, None]
            s = (t - ts[k])[:, None] / h
            s2 = s * s
            s3 = s2 * s
            out = ((2 * s3 - 3 * s2 + 1) * ys[k] + (s3 - 2 * s2 + s) * h * f0[k]
                   + (-2 * s3 + 3 * s2) * ys[k + 1] + (s3 - s2) * h * f1[k])
        return out[0] if scalar else out.T


def _hermite_at(t, t0, h, y0, y1, f0, f1):
    s = (t - t0) / h
    s2 = s * s
    s3 = s2 * s
    return ((2 * s3 - 3 * s2 + 1) * y0 + (s3 - 2 * s2 + s) * h * f0
            + (-2 * s3 + 3 * s2) * y1 + (s3 - s2) * h * f1)


def _locate(event, t0, h, y0, y1, f0, f1, g0, g1):
    """The time in (t0, t0 + h] where ``event`` crosses zero on the step's interpolant
    (Illinois false position, to a few ulps of the clock)."""
    a, b, ga, gb = t0, t0 + h, g0, g1
    side = 0
    tol = 4.0 * np.spacing(max(abs(b), 1e-3))
    for _ in range(80):
        if b - a <= tol:
            break
        t = (a * gb - b * ga) / (gb - ga) if gb != ga else 0.5 * (a + b)
        if not a < t < b:
            t = 0.5 * (a + b)
        g = event(t, _hermite_at(t, t0, h, y0, y1, f0, f1))
        if (g > 0) == (ga > 0) and g != 0.0:
            a, ga = t, g
            if side == -1:
                gb *= 0.5
            side = -1
        else:
            b, gb = t, g
            if side == 1:
                ga *= 0.5
            side = 1
    return b


def solve(fun, span: float, x0: np.ndarray, rtol: float, atol: np.ndarray,
          events=(), first_step: float = 1e-5, free: np.ndarray | None = None,
          max_evaluations: int | None = None):
    """Integrate ``x' = fun(t, x)`` over relative time [0, span] from ``x0``, stopping at
    the first terminal event (a callable ``g(t, x)`` with ``direction`` +1, -1 or 0: the
    crossing counted, as scipy's ``solve_ivp`` does).

    ``free``: the states the right-hand side depends on (the Jacobian's columns; states
    that only accumulate, such as drawn masses, are left out). Returns
    ``(dense, t_end, evaluations)``; raises :class:`OverBudget` past ``max_evaluations``
    and :class:`StepFailure` when no step size down to the clock's resolution passes."""
    x = np.array(x0, dtype=float)
    n = len(x)
    cols = np.flatnonzero(free) if free is not None else np.arange(n)
    acc_rows = np.flatnonzero(~np.asarray(free, dtype=bool)) if free is not None else []
    budget = max_evaluations if max_evaluations is not None else 1 << 62
    jac_step = 1.5e-8 * np.maximum(atol / rtol, 0.0)
    directions = [getattr(ev, "direction", 0) for ev in events]
    evals = 0
    eye = np.eye(n)
    t = 0.0
    f = fun(t, x)
    evals += 1
    ts, ys, fs = [0.0], [x], [f]
    g_prev = [ev(t, x) for ev in events]
    h = min(first_step, span)
    J = None
    age = 0
    h_jac = 0.0
    G_inv = None
    U = np.zeros((4, n))        # the stages' u_i, rows
    retries = 0
    h_min = 16.0 * np.spacing(max(span, 1.0))
    while t < span:
        if span - t < 1.1 * h:     # land on the end exactly
            h = span - t
        if J is None or age >= JAC_MAX_AGE:
            J = np.zeros((n, n))
            steps = np.maximum(1.5e-8 * np.abs(x), jac_step)
            for j in cols:
                xp = x.copy()
                xp[j] += steps[j]
                J[:, j] = (fun(t, xp) - f) / steps[j]
            # the accumulated states are left out of the implicit part: each step then
            # adds the method's own quadrature of their rates, not a share of the
            # other states' corrections
            J[acc_rows] = 0.0
            evals += len(cols)
            STATS["jac"] += 1
            h_jac = 0.0
            age = 0
        # the Jacobian is kept over steps (a W-method keeps its order with any), but G is
        # inverted for each new h: shifting a kept G's diagonal instead would change
        # the Jacobian as much as the stiff rates themselves
        if h != h_jac:
            G_inv = np.linalg.inv(eye / (h * _GAMMA) - J)
            STATS["inv"] += 1
            h_jac = h
        ch = TC / h
        try:
            U[0] = G_inv @ f
            for i in (1, 2, 3):
                fi = fun(t + STAGE_T[i] * h, x + TA[i, :i] @ U[:i])
                U[i] = G_inv @ (fi + ch[i, :i] @ U[:i])
            evals += 3
            x_new = x + TM @ U
            err_vec = (TE @ U) / (atol + rtol * np.maximum(np.abs(x), np.abs(x_new)))
            err = math.sqrt(float(err_vec @ err_vec) / n)
        except (ArithmeticError, ValueError):
            # a stage left the physical states (a negative pressure or temperature):
            # the step was too long
            evals += 3
            err = math.inf
        if evals > budget:
            raise OverBudget()
        if err <= 1.0:
            try:
                f_new = fun(t + h, x_new)
            except (ArithmeticError, ValueError):
                err = math.inf
            evals += 1
        if not err <= 1.0:          # rejected (or not finite)
            STATS["rej"] += 1
            if not math.isfinite(err):
                h *= 0.25
            else:
                h *= max(FAC_MIN, SAFETY * err ** (-1.0 / ORDER_EST))
            if age > 0:     # a Jacobian of this very state is as good as it gets
                J = None
            if h < h_min:
                raise StepFailure(f"step size {h:.3g} s at {t:.6g} s into the piece")
            continue
        t_new = t + h
        hit = None
        at_start = False
        if events:
            g_new = [ev(t_new, x_new) for ev in events]
            for k, ev in enumerate(events):
                g0, g1, d = g_prev[k], g_new[k], directions[k]
                # as scipy counts them: a rise includes g0 = 0, a fall too
                if (g0 <= 0 <= g1 and d >= 0) or (g0 >= 0 >= g1 and d <= 0):
                    if g0 == 0.0:
                        at_start = True
                        tk = t
                    else:
                        tk = _locate(ev, t, h, x, x_new, f, f_new, g0, g1)
                    if hit is None or tk < hit:
                        hit = tk
        else:
            g_new = g_prev
        if at_start and hit == t and retries < START_RETRIES:
            # an event function that starts at zero (a piston that has just broken
            # away, v = 0) and leaves it the wrong way over a step may only show the
            # step's error: a shorter step tells that from a true crossing
            retries += 1
            h *= 0.1
            continue
        retries = 0
        if hit is not None:
            if hit <= t:        # the event sat at the step's start
                break
            x_hit = _hermite_at(hit, t, h, x, x_new, f, f_new)
            f_hit = fun(hit, x_hit)
            evals += 1
            ts.append(hit)
            ys.append(x_hit)
            fs.append(f_hit)
            t = hit
            break
        ts.append(t_new)
        ys.append(x_new)
        fs.append(f_new)
        t, x, f, g_prev = t_new, x_new, f_new, g_new
        age += 1
        fac = SAFETY * err ** (-1.0 / ORDER_EST) if err > 0 else FAC_MAX
        if not 1.0 <= fac <= HOLD_MAX:   # a small gain is not worth a new G
            h *= min(FAC_MAX, max(FAC_MIN, fac))
    dense = HermiteDense(np.array(ts), np.array(ys), np.array(fs),
                         None if free is None else ~np.asarray(free, dtype=bool))
    return dense, t, evals
