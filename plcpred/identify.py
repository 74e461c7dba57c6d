"""``plcpred identify flow``: the ISO 6358 parameters (C, b, m, a of D2) of a component
from test data.

Two kinds of data (a CSV, columns by name):

- **Steady flow**: upstream and downstream pressures and the flow through the component
  (``p_up_bar_g`` or ``p_up_bar`` (absolute) or ``p_up_kpa`` (absolute); the same for
  ``p_down``, default atmospheric; ``flow_l_min`` in normal litres per minute at ISO 8778;
  optional ``t_up_c``). Two methods:

  - ``improved`` (the thesis' method): C from the choked points (a regression of the
    flow on the upstream pressure through the origin over the points with r <= b), then
    b, m (and a, with ``--fit-a``) by bounded least squares on the flow ratio
    ``phi = q / (C P_u sqrt(T0/T_u))`` against the pressure ratio r, in relative terms
    (a meter's error is a share of its reading);
  - ``iso6358`` (ISO 6358:1989): m = 0.5, a = 1; C as above; b the mean over the
    subsonic points of ``b_i = (r - s)/(1 - s)``, ``s = sqrt(1 - phi^2)``.

- **Tank discharge or charge**: ``time_s`` and the tank's pressure (``p_bar_g``,
  ``p_bar`` or ``p_kpa``) for a tank of known volume (``--volume-l``) emptying through
  the component to atmosphere, or filling through it from ``--supply-bar-g``. The tank is
  taken isothermal (ISO 6358-2's tanks are filled with copper wool for that), so
  ``dP/dt = -/+ R T / V * qm(P)``; C, b, m are fitted by integrating this and least
  squares on the pressure curve, up to a pressure ratio of 0.98.

Confidence intervals are 95 %: 1.96 standard errors from the fit's Jacobian and residual
variance.
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

import numpy as np

from .datafile import FLOW_UNIT_SPELLINGS, PRESSURE_UNIT_SPELLINGS, DataLines
from .diagnose.io import FLOW_UNITS, PRESSURE_UNITS, column_unit
from .errors import PlcpredError
from .outputs.plotting import pyplot, save_fig
from .physics.flow import phi
from .physics.units import P_ATM_KPA, P_ATM_PA, PA_PER_BAR, R_J_KG_K, RHO0_KG_M3, T0_K, ZERO_C_K

Z95 = 1.96
R_FIT_MAX = 0.98       # tank curves: points nearer equilibrium than this are not fitted


class IdentifyError(PlcpredError):
    pass


class _OverBudget(Exception):
    """The tank model's evaluations ran past MAX_TANK_EVALUATIONS."""


# right-hand-side evaluations of one tank curve (a curve takes a few hundred; an absurd
# one, a C far too large for its time steps, would take without end)
MAX_TANK_EVALUATIONS = 100_000
VOLUME_L = (1e-4, 1e6)           # a test tank's volume, litres
MAX_PRESSURE_PA = 1e8            # 1000 bar


@dataclass
class FlowFit:
    """Identified D2 parameters with 95 % half-widths."""
    C: float
    b: float
    m: float
    a: float
    ci: dict = field(default_factory=dict)     # name -> half-width (95 %)
    method: str = "improved"
    n_points: int = 0
    rms: float = 0.0                            # residual RMS, in the data's unit
    rms_unit: str = "l/min"

    def as_dict(self) -> dict:
        return {"C": self.C, "b": self.b, "m": self.m, "a": self.a,
                "ci95": dict(self.ci), "method": self.method, "n_points": self.n_points,
                "rms": self.rms, "rms_unit": self.rms_unit}


# ---------------------------------------------------------------------- reading

@dataclass
class FlowData:
    p_up_pa: np.ndarray
    p_down_pa: np.ndarray
    flow_l_min: np.ndarray
    t_up_k: np.ndarray
    path: str = ""          # the file it was read from (for errors)


@dataclass
class TankData:
    time_s: np.ndarray
    p_pa: np.ndarray
    path: str = ""


def _pressure(row_get, stem, atm_pa, default=None):
    for suffix, to_pa in (("_bar_g", lambda v: v * PA_PER_BAR + atm_pa), ("_bar", lambda v: v * PA_PER_BAR),
                          ("_kpa", lambda v: v * 1e3)):
        v = row_get(stem + suffix)
        if v is not None:
            return to_pa(v)
    return default


# Limits of the data read (inputs are untrusted): points, and what each column may hold
# (wider than any test bench; they catch unit mix-ups and numbers that would overflow)
MAX_POINTS = 200_000
COLUMN_RANGES = {"flow_l_min": (-1e8, 1e8), "_bar_g": (-1.0, 1e3), "_bar": (0.0, 1e3),
                 "_kpa": (0.0, 1e5), "t_up_c": (-100.0, 500.0), "time_s": (-1e7, 1e7)}
TEMPERATURE_C = (-100.0, 500.0)


def _column_range(name: str) -> tuple[float, float] | None:
    if name in COLUMN_RANGES:
        return COLUMN_RANGES[name]
    for stem in ("p_up", "p_down", "p"):
        for suffix in ("_bar_g", "_bar", "_kpa"):
            if name == stem + suffix:
                return COLUMN_RANGES[suffix]
    return None


class DataColumns(NamedTuple):
    """Where test data hold their values when not under the default names: a header
    name or a 1-based number per column, and the units of the flow and the pressures
    (None: as the column's name gives it, else l/min and bar(g))."""
    time_col: object = None
    flow_col: object = None
    flow_unit: str | None = None
    p_up_col: object = None
    p_down_col: object = None
    pressure_col: object = None
    pressure_unit: str | None = None


def read_flow_data(path, atmosphere_kpa: float = P_ATM_KPA, temperature_c: float = 20.0,
                   columns: DataColumns | None = None):
    """Steady-flow or tank data from a CSV (see the module note; fields separated by
    ``,``, ``;`` or tabs, with ``;`` or tabs a decimal comma too; ``columns`` names
    columns the default names do not). Errors name the file, line and column. The file
    is read a line at a time: at most MAX_POINTS rows, each value of a known column
    within COLUMN_RANGES."""
    path = Path(path)
    atm = atmosphere_kpa * 1e3
    if not (math.isfinite(temperature_c) and
            TEMPERATURE_C[0] <= temperature_c <= TEMPERATURE_C[1]):
        raise IdentifyError(f"the temperature {temperature_c:g} C is outside "
                            f"{TEMPERATURE_C[0]:g} to {TEMPERATURE_C[1]:g} C")
    header, values = _read_rows(path, columns or DataColumns(), atmosphere_kpa)
    if "flow_l_min" in header:
        return _steady_flow(path, values, atm, temperature_c)
    if "time_s" in header:
        return _tank(path, values, atm)
    raise IdentifyError(f"{path}: columns {', '.join(header)}: expected steady-flow data "
                        "(p_up_bar_g, p_down_bar_g, flow_l_min) or a tank's pressure "
                        "(time_s, p_bar_g), or name the columns (--flow-col, --p-up-col, "
                        "--time-col, --pressure-col)")


class _Read(NamedTuple):
    """How one column of test data is read: the name the fit knows it by, the name its
    header gives, and value = cell * factor + offset."""
    key: str
    name: str
    factor: float = 1.0
    offset: float = 0.0


def _read_rows(path: Path, columns: DataColumns, atm_kpa: float
               ) -> tuple[list[str], list[tuple[int, dict]]]:
    """(the names the fit knows the columns by, (line, name -> value) of each data row):
    every value a finite number within its column's range."""
    plan: dict[int, _Read] | None = None
    decimal_comma, delimiter = False, ","
    values: list[tuple[int, dict]] = []
    with DataLines(path, IdentifyError) as lines:
        for k, line in enumerate(lines, start=1):
            if not line.strip() or line.lstrip().startswith("#"):
                continue
            if plan is None:
                delimiter = max((",", ";", "\t"), key=line.count)
                decimal_comma = delimiter != ","
            try:
                row = next(csv.reader([line], delimiter=delimiter))
            except csv.Error as e:
                raise IdentifyError(f"{path}:{k}: not CSV: {e}") from None
            if plan is None:
                plan = _column_plan(path, k, [h.strip() for h in row], columns, atm_kpa)
                continue
            if len(values) >= MAX_POINTS:
                raise IdentifyError(f"{path}:{k}: more than {MAX_POINTS:,} data rows")
            values.append((k, _row_values(path, k, row, plan, decimal_comma)))
    if plan is None or not values:
        raise IdentifyError(f"{path}: needs a header and data rows")
    return [r.key for r in plan.values()], values


def _column_plan(path, line: int, header: list[str], columns: DataColumns, atm_kpa: float
                 ) -> dict[int, _Read]:
    """Column index -> how it is read: the columns ``columns`` names, then those under
    the default names (p_up_bar_g, flow_l_min, time_s, ...) that they leave."""
    named: dict[int, _Read] = {}
    flow_unit = columns.flow_unit
    for col, key in ((columns.flow_col, "flow_l_min"), (columns.time_col, "time_s")):
        if col is None:
            continue
        i = _named_column(path, line, header, col, key)
        factor = 1.0
        if key == "flow_l_min":
            said = column_unit(header[i], FLOW_UNIT_SPELLINGS)
            factor = FLOW_UNITS[flow_unit or said or "l/min"]
        named[i] = _Read(key, header[i], factor)
    for col, stem in ((columns.p_up_col, "p_up"), (columns.p_down_col, "p_down"),
                      (columns.pressure_col, "p")):
        if col is not None:
            i = _named_column(path, line, header, col, f"{stem}_kpa")
            unit = columns.pressure_unit or column_unit(header[i], PRESSURE_UNIT_SPELLINGS) \
                or "bar"
            bar_per_unit, absolute = PRESSURE_UNITS[unit]
            # read as kPa absolute, the default names' own unit
            named[i] = _Read(f"{stem}_kpa", header[i], bar_per_unit * 100.0,
                             0.0 if absolute else atm_kpa)
    taken = {r.key.rpartition("_")[0] if r.key.endswith("_kpa") else r.key
             for r in named.values()}
    plan = dict(named)
    for i, h in enumerate(header):
        key = h.lower()
        stem = next((s for s in ("p_up", "p_down", "p") for u in ("_bar_g", "_bar", "_kpa")
                     if key == s + u), None)
        if i in plan or (stem or key) in taken:
            continue
        if stem is not None or key in ("flow_l_min", "time_s", "t_up_c"):
            plan[i] = _Read(key, h)
    return plan


def _named_column(path, line: int, header: list[str], wanted, what: str) -> int:
    """The index of the column ``wanted`` names (a header name or a 1-based number)."""
    text = str(wanted).strip()
    if text.isascii() and text.isdigit():
        if not 1 <= int(text) <= len(header):
            raise IdentifyError(f"{path}:{line}: column {text} for {what}: the header has "
                                f"{len(header)} columns ({', '.join(header)})")
        return int(text) - 1
    lower = [h.lower() for h in header]
    if text.lower() not in lower:
        raise IdentifyError(f"{path}:{line}: no column {text!r} for {what} (columns: "
                            f"{', '.join(header)})")
    return lower.index(text.lower())


def _row_values(path, k: int, row: list[str], plan: dict[int, _Read],
                decimal_comma: bool) -> dict:
    parsed = {}
    for i, how in plan.items():
        if i >= len(row) or not row[i].strip():
            continue
        cell = row[i].strip()
        try:
            v = float(cell.replace(",", ".") if decimal_comma else cell)
        except ValueError:
            raise IdentifyError(f"{path}:{k}:{i + 1}: {how.name}: not a number: "
                                f"{row[i][:40]!r}") from None
        if not math.isfinite(v):
            raise IdentifyError(f"{path}:{k}:{i + 1}: {how.name}: not a finite number")
        v = v * how.factor + how.offset
        lo_hi = _column_range(how.key)
        if lo_hi is not None and not lo_hi[0] <= v <= lo_hi[1]:
            raise IdentifyError(f"{path}:{k}:{i + 1}: {how.name}: {cell[:40]} "
                                f"is outside {_in_unit(lo_hi, how)} (a unit mix-up?)")
        parsed[how.key] = v
    return parsed


def _in_unit(lo_hi: tuple[float, float], how: _Read) -> str:
    """A column's range in the unit of its cells."""
    lo, hi = ((x - how.offset) / how.factor for x in lo_hi)
    return f"{lo:g} to {hi:g}"


def _steady_flow(path, values, atm: float, temperature_c: float) -> FlowData:
    pu, pd, q, tk = [], [], [], []
    for k, v in values:
        p_up = _pressure(v.get, "p_up", atm)
        if p_up is None or "flow_l_min" not in v:
            raise IdentifyError(f"{path}:{k}: needs p_up_bar_g (or p_up_bar, "
                                "p_up_kpa) and flow_l_min")
        p_down = _pressure(v.get, "p_down", atm, default=atm)
        if p_up <= 0 or p_down <= 0:
            raise IdentifyError(f"{path}:{k}: pressures must be above absolute zero")
        pu.append(p_up)
        pd.append(p_down)
        q.append(v["flow_l_min"])
        tk.append(v.get("t_up_c", temperature_c) + ZERO_C_K)
    return FlowData(*(np.array(x) for x in (pu, pd, q, tk)), path=str(path))


def _tank(path, values, atm: float) -> TankData:
    t, p = [], []
    for k, v in values:
        pk = _pressure(v.get, "p", atm)
        if pk is None or "time_s" not in v:
            raise IdentifyError(f"{path}:{k}: needs time_s and p_bar_g (or p_bar, p_kpa)")
        if pk <= 0:
            raise IdentifyError(f"{path}:{k}: the pressure must be above absolute zero")
        t.append(v["time_s"])
        p.append(pk)
    t, p = np.array(t), np.array(p)
    if np.any(np.diff(t) <= 0):
        raise IdentifyError(f"{path}: time_s must increase")
    return TankData(t, p, path=str(path))



# what an identified component may be (the machine file's ranges for a nozzle or leak)
C_RANGE = (1e-15, 1e-3)          # m^3/(s Pa)


def _source(data, what: str) -> str:
    return f"{data.path}: {what}" if getattr(data, "path", "") else what


def _checked(fit: FlowFit, what: str, check: str = "the flow and pressure units") -> FlowFit:
    """``fit`` if its parameters are finite and a component can have them, else an
    IdentifyError saying the data do not describe one."""
    values = {"C": fit.C, "b": fit.b, "m": fit.m, "a": fit.a, "rms": fit.rms}
    bad = [k for k, v in values.items() if not math.isfinite(v)]
    if bad:
        raise IdentifyError(f"{what}: the fit gives no finite {', '.join(bad)}: the data do "
                            f"not describe a pneumatic component (check {check})")
    if not C_RANGE[0] <= fit.C <= C_RANGE[1]:
        raise IdentifyError(f"{what}: the fitted C of {fit.C:.3g} m^3/(s Pa) is outside "
                            f"{C_RANGE[0]:g} to {C_RANGE[1]:g}, what a machine file takes: "
                            f"check {check}")
    if not (-1.0 < fit.b < 1.0 and 0.0 < fit.m <= 10.0 and 0.0 < fit.a <= 1.0):
        raise IdentifyError(f"{what}: the fitted b {fit.b:.3g}, m {fit.m:.3g}, a "
                            f"{fit.a:.3g} are outside -1 < b < 1, 0 < m <= 10, 0 < a <= 1: "
                            f"the data do not describe a pneumatic component (check {check})")
    return fit


# ---------------------------------------------------------------------- steady flow

def _ci(jac, resid, n_params):
    """95 % half-widths from a least-squares Jacobian and residuals."""
    dof = max(1, len(resid) - n_params)
    s2 = float(resid @ resid) / dof
    try:
        cov = np.linalg.inv(jac.T @ jac) * s2
    except np.linalg.LinAlgError:
        return [math.inf] * n_params
    return [Z95 * math.sqrt(max(v, 0.0)) for v in np.diag(cov)]


def _choked_c(k_vals, weights, r, b):
    """C from the points with r <= b: weighted regression through the origin, i.e. the
    mean of q/(P_u sqrt(T0/T_u)) weighted by P_u^2; with its 95 % half-width."""
    sel = r <= b
    if sel.sum() < 2:
        return None
    w = weights[sel]
    c = float(np.sum(w * k_vals[sel]) / np.sum(w))
    resid = (k_vals[sel] - c) * np.sqrt(w)
    se = math.sqrt(float(resid @ resid) / max(1, sel.sum() - 1) / float(np.sum(w)))
    return c, Z95 * se


def identify_steady(data: FlowData, method: str = "improved", fit_a: bool = False
                    ) -> FlowFit:
    """C, b, m (a) from steady-flow points (see the module note)."""
    # scipy costs a third of a second to import: only the runs that need it pay
    from scipy.optimize import least_squares

    n = len(data.flow_l_min)
    if n < 4:
        raise IdentifyError(f"steady-flow data needs at least 4 points, not {n}")
    forward = data.p_up_pa > data.p_down_pa
    if not np.all(forward):
        raise IdentifyError("every point needs the upstream pressure above the downstream")
    r = data.p_down_pa / data.p_up_pa
    scale = data.p_up_pa * np.sqrt(T0_K / data.t_up_k)            # q = C * scale * phi
    q_m3_s = data.flow_l_min / 60_000.0
    k_vals = q_m3_s / scale                                       # C * phi per point
    weights = scale ** 2
    c0 = float(np.max(k_vals))
    if c0 <= 0:
        raise IdentifyError("no positive flow in the data")
    # a joint fit first, for where the choked points end
    lo = [c0 * 0.5, -0.5, 0.1] + ([0.5] if fit_a else [])
    hi = [c0 * 2.0, 0.95, 3.0] + ([1.0] if fit_a else [])
    x0 = [c0, min(0.3, float(np.median(r))), 0.5] + ([0.999] if fit_a else [])

    def model(x, rr, sc):
        a = x[3] if fit_a else 1.0
        return x[0] * sc * phi(rr, x[1], x[2], max(a, x[1] + 1e-3))

    joint = least_squares(lambda x: (model(x, r, scale) - q_m3_s) / c0 / scale.mean(),
                          x0, bounds=(lo, hi), x_scale=[c0, 0.1, 0.1] + ([0.01] if fit_a else []))
    b_joint = float(joint.x[1])
    choked = _choked_c(k_vals, weights, r, b_joint)
    if choked is None:      # no point choked: C from the joint fit
        C, C_ci = float(joint.x[0]), _ci(joint.jac, joint.fun, len(x0))[0]
    else:
        C, C_ci = choked
    phi_meas = k_vals / C
    if method == "iso6358":
        sub = (r > b_joint) & (phi_meas < 0.999) & (phi_meas > 0.05)
        if sub.sum() < 1:
            raise IdentifyError("the ISO 6358 method needs subsonic points (pressure ratios "
                                "above the critical one)")
        s = np.sqrt(1.0 - np.minimum(phi_meas[sub], 1.0) ** 2)
        b_i = (r[sub] - s) / (1.0 - s)
        b = float(np.mean(b_i))
        b_ci = Z95 * float(np.std(b_i, ddof=1)) / math.sqrt(sub.sum()) if sub.sum() > 1 \
            else math.inf
        fitted = C * scale * phi(r, b, 0.5)
        rms = float(np.sqrt(np.mean((fitted - q_m3_s) ** 2))) * 60_000.0
        return _checked(FlowFit(C, b, 0.5, 1.0, {"C": C_ci, "b": b_ci}, "iso6358", n, rms),
                        _source(data, "steady flow (iso6358)"))
    # improved: b, m (a) on the flow ratio against the pressure ratio
    lo2 = [-0.5, 0.1] + ([0.5] if fit_a else [])
    hi2 = [0.95, 3.0] + ([1.0] if fit_a else [])
    x02 = [min(max(b_joint, -0.49), 0.94), min(max(float(joint.x[2]), 0.11), 2.9)] + \
        ([float(joint.x[3])] if fit_a else [])

    # relative residuals: a meter's error is a share of its reading, so the small flows
    # near r = 1 are as precise, relatively, as the choked ones
    use = phi_meas > 0.02

    def resid2(x):
        a = x[2] if fit_a else 1.0
        return phi(r[use], x[0], x[1], max(a, x[0] + 1e-3)) / phi_meas[use] - 1.0
    fit = least_squares(resid2, x02, bounds=(lo2, hi2))
    ci = _ci(fit.jac, fit.fun, len(x02))
    b, m = float(fit.x[0]), float(fit.x[1])
    a = float(fit.x[2]) if fit_a else 1.0
    fitted = C * scale * phi(r, b, m, a)
    rms = float(np.sqrt(np.mean((fitted - q_m3_s) ** 2))) * 60_000.0
    out = {"C": C_ci, "b": ci[0], "m": ci[1]}
    if fit_a:
        out["a"] = ci[2]
    return _checked(FlowFit(C, b, m, a, out, "improved", n, rms),
                    _source(data, "steady flow"))


# ---------------------------------------------------------------------- tank

def tank_pressure_pa(time_s, p_start_pa, C, b, m, volume_m3, mode="discharge",
                     supply_pa=None, atmosphere_pa=P_ATM_PA, temperature_k=T0_K, a=1.0):
    """An isothermal tank's pressure emptying through (C, b, m) to atmosphere, or filling
    from ``supply_pa``: ``dP/dt = -/+ (R T / V) rho0 C P_u sqrt(T0/T) phi(P_d/P_u)``."""
    # scipy costs a third of a second to import: only the runs that need it pay
    from scipy.integrate import solve_ivp

    k = R_J_KG_K * temperature_k / volume_m3 * RHO0_KG_M3 * C * math.sqrt(T0_K / temperature_k)
    calls = [0]

    def rate(t, p):
        calls[0] += 1
        if calls[0] > MAX_TANK_EVALUATIONS:
            raise _OverBudget()
        if mode == "discharge":
            r = atmosphere_pa / p[0]
            return [-k * p[0] * float(phi(r, b, m, a))] if r < 1 else [0.0]
        r = p[0] / supply_pa
        return [k * supply_pa * float(phi(r, b, m, a))] if r < 1 else [0.0]
    t = np.asarray(time_s, dtype=float)
    try:
        sol = solve_ivp(rate, (t[0], t[-1]), [p_start_pa], t_eval=t, method="LSODA",
                        rtol=1e-8, atol=1.0)
    except _OverBudget:
        raise IdentifyError(
            f"the tank model needs more than {MAX_TANK_EVALUATIONS:,} steps for this curve "
            f"(C {C:.3g} m^3/(s Pa) emptying {volume_m3 * 1000:g} l over "
            f"{t[-1] - t[0]:.3g} s): check time_s (seconds), the pressures' unit and "
            "--volume-l") from None
    if sol.status < 0 or sol.y.shape[1] != len(t):
        raise IdentifyError(f"the tank model cannot follow this curve ({sol.message}): "
                            "check time_s (seconds), the pressures' unit and --volume-l")
    return sol.y[0]


def identify_tank(data: TankData, volume_l: float, mode: str = "discharge",
                  supply_pa: float | None = None, atmosphere_pa: float = P_ATM_PA,
                  temperature_k: float = T0_K) -> FlowFit:
    """C, b, m from a tank's pressure curve (see the module note)."""
    # scipy costs a third of a second to import: only the runs that need it pay
    from scipy.optimize import least_squares

    if mode not in ("discharge", "charge"):
        raise IdentifyError("mode must be discharge or charge")
    if mode == "charge" and supply_pa is None:
        raise IdentifyError("a charge needs the supply pressure (--supply-bar-g)")
    if len(data.time_s) < 6:
        raise IdentifyError("a tank curve needs at least 6 points")
    if not (math.isfinite(volume_l) and VOLUME_L[0] <= volume_l <= VOLUME_L[1]):
        raise IdentifyError(f"the tank's volume {volume_l:g} l is outside {VOLUME_L[0]:g} "
                            f"to {VOLUME_L[1]:g} l")
    if supply_pa is not None and not (math.isfinite(supply_pa)
                                      and atmosphere_pa < supply_pa <= MAX_PRESSURE_PA):
        raise IdentifyError(f"the supply of {(supply_pa - atmosphere_pa) / PA_PER_BAR:g} bar(g) "
                            "must lie above atmospheric and at most "
                            f"{(MAX_PRESSURE_PA - atmosphere_pa) / PA_PER_BAR:g} bar(g)")
    if not (math.isfinite(temperature_k) and 173.15 <= temperature_k <= 773.15):
        raise IdentifyError(f"the temperature {temperature_k - ZERO_C_K:g} C is outside "
                            "-100 to 500 C")
    v = volume_l / 1000.0
    p = data.p_pa
    # a first C from the start of the curve (choked there in a discharge from high pressure)
    dp0 = abs(p[1] - p[0]) / (data.time_s[1] - data.time_s[0])
    p_up0 = p[0] if mode == "discharge" else supply_pa
    c0 = dp0 * v / (R_J_KG_K * temperature_k * RHO0_KG_M3 * p_up0)
    if not (math.isfinite(c0) and C_RANGE[0] <= c0 <= C_RANGE[1]):
        raise IdentifyError(
            f"the curve's first step ({(p[1] - p[0]) / PA_PER_BAR:.3g} bar in "
            f"{data.time_s[1] - data.time_s[0]:.3g} s from a {volume_l:g} l tank) needs a C "
            f"of {c0:.3g} m^3/(s Pa), outside {C_RANGE[0]:g} to {C_RANGE[1]:g}: check "
            "time_s (seconds), the pressures' unit and --volume-l")
    span = float(np.ptp(p)) or 1.0
    # the last 2 % of the way to equilibrium is left out of the fit: there the flow is tiny,
    # laminar rather than D2, and a pressure sensor's offset or the tank's last cooling
    # weigh more than the component
    r = atmosphere_pa / p if mode == "discharge" else p / supply_pa
    use = r < R_FIT_MAX
    if use.sum() < 6:
        raise IdentifyError("a tank curve needs at least 6 points with the pressure ratio "
                            f"below {R_FIT_MAX}")

    def resid(x):
        model = tank_pressure_pa(data.time_s, p[0], x[0] * c0, x[1], x[2], v, mode,
                                 supply_pa, atmosphere_pa, temperature_k)
        return (model - p)[use] / span

    fit = least_squares(resid, [1.0, 0.3, 0.5], bounds=([0.1, -0.5, 0.1], [10.0, 0.95, 3.0]),
                        diff_step=1e-4)
    ci = _ci(fit.jac, fit.fun, 3)
    rms = float(np.sqrt(np.mean(fit.fun ** 2))) * span / PA_PER_BAR
    return _checked(FlowFit(float(fit.x[0] * c0), float(fit.x[1]), float(fit.x[2]), 1.0,
                            {"C": ci[0] * c0, "b": ci[1], "m": ci[2]}, f"tank {mode}",
                            len(p), rms, "bar"), _source(data, f"tank {mode}"),
                    "time_s (seconds), the pressures' unit and --volume-l")


def plot_fit(data, fit: FlowFit, path, volume_l=None, mode="discharge", supply_pa=None,
             atmosphere_pa=P_ATM_PA, temperature_k=T0_K) -> None:
    """The fit plot: the flow ratio against the pressure ratio (steady flow), or the
    tank's pressure against time, with the fitted curve."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.5), constrained_layout=True)
    if isinstance(data, FlowData):
        r = data.p_down_pa / data.p_up_pa
        phi_data = data.flow_l_min / 60_000.0 / (fit.C * data.p_up_pa
                                                 * np.sqrt(T0_K / data.t_up_k))
        rr = np.linspace(0, 1, 400)
        ax.plot(r, phi_data, "o", ms=3, color="black", label="data")
        ax.plot(rr, phi(rr, fit.b, fit.m, fit.a), color="tab:red",
                label=f"D2: b {fit.b:.3f}, m {fit.m:.3f}")
        ax.set_xlabel("pressure ratio P_d / P_u")
        ax.set_ylabel("flow ratio q / (C P_u)")
    else:
        model = tank_pressure_pa(data.time_s, data.p_pa[0], fit.C, fit.b, fit.m,
                                 volume_l / 1000.0, mode, supply_pa, atmosphere_pa,
                                 temperature_k)
        ax.plot(data.time_s, data.p_pa / PA_PER_BAR, "o", ms=3, color="black", label="data")
        ax.plot(data.time_s, model / PA_PER_BAR, color="tab:red", label="fit")
        ax.set_xlabel("time, s")
        ax.set_ylabel("tank pressure, bar (absolute)")
    ax.set_title(f"{fit.method}: C {fit.C:.3e} m^3/(s Pa), b {fit.b:.3f}, m {fit.m:.3f}",
                 fontsize=10)
    ax.legend()
    save_fig(fig, path)


__all__ = ["FlowData", "FlowFit", "IdentifyError", "TankData", "identify_steady",
           "identify_tank", "plot_fit", "read_flow_data", "tank_pressure_pa"]
