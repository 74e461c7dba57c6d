"""Drives that share one supply, integrated together between discrete events.

A group is either one drive on the ideal supply (the machine's regulated pressure, no dynamics), or
every drive and passive consumer on one ``[[line]]``: a volume fed by a regulator, through which the
drives exchange air (docs/reference/physics.md: what D4 adds, shared supply).

The state is integrated by :mod:`.rosenbrock` (ROS34PW2, a linearly implicit method with
a finite-difference Jacobian kept over steps: the equations are stiff when chambers are
nearly full, not stiff while pistons move; scipy's LSODA, the reference it replaced, stays
behind ``METHOD = "lsoda"`` for the equality tests) in *pieces*: a piece ends at the next
discrete event (a valve
reaching a chamber, a piston breaking away, reaching an end stop or stopping, the group
settling). Within a piece every drive is either stuck (v = 0) or sliding one way, so the
right-hand side is smooth. Pieces are kept with their dense output, so that

- the sequencer can look ahead for the next end-switch edge and later take back what it
  integrated past a new valve command (``truncate``),
- outputs are sampled afterwards on any grid,
- a piece that starts from a state met before (the same to 7 digits, the same valves and
  modes) is reused instead of integrated again: a cycling machine integrates its first
  cycles and replays the rest.

Once a group settles (pistons at rest, chambers within 0.05 % of their target pressure and
0.5 K of ambient) it is snapped to its final state and stays there without integration
until the next command; the air the snap adds is booked where it would have flowed.
"""
from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from ..errors import PlcpredError
from . import rosenbrock
from .chamber import (
    CP_J_KG_K,
    R_J_KG_K,
    air_mass_kg,
    chamber_rates,
    friction_n,
    signed_mass_flow_kg_s,
)
from .units import P_ATM_PA, PA_PER_BAR

# "rosenbrock" (ROS34PW2, numpy only) or "lsoda" (scipy's LSODA at rtol 1e-6, the
# reference the equality tests compare with). The Rosenbrock path's tolerances: relative,
# and factors on LSODA's absolute ones (1 Pa, 1 mK, 10 nm, 1 um/s, 1e-11 kg), i.e. 10 Pa,
# 10 mK, 0.1 um, 100 um/s and 1e-9 kg. Air and edge timelines then agree with LSODA within
# 0.05 % and to the scan on the samples (tests/plant/test_integrator.py). Pressures looser
# than 10 Pa let a filling chamber overshoot its supply by the error, and a piston
# breaking away there stopped and broke away again without end (the rig at 2.5 bar(g)).
METHOD = "rosenbrock"
LSODA_RTOL = 1e-6
RTOL = 1e-4
ATOL_FACTOR = 10.0
ATOL_FACTOR_V = 100.0      # pistons' velocities
ATOL_FACTOR_MASS = 100.0   # the masses drawn (they feed nothing back)

MAX_PIECE_S = 30.0
SETTLE_P_REL = 5e-4
SETTLE_T_K = 0.5
POS_EPS_M = 1e-7
CACHE_LIMIT = 50_000
LOOKAHEAD_S = 600.0       # a switch that has not changed by then is taken as never
TIME_EPS_S = 1e-10        # switch times are compared with the sequencer's whole ns


MAX_TINY_PIECES = 10_000  # consecutive pieces shorter than a microsecond: chattering
MAX_PIECES = 1_000_000    # per group held in memory (about 0.3 KB each)
# right-hand-side evaluations of one piece, for one drive (a group of n drives may take
# 1/n of it, at least a tenth): a real piece takes a few hundred, at most 2,000 in the
# samples; equations too stiff for any step (a regulator's C of 1e-4 into a 1 l line)
# would take without end while the solver's memory grows. About 4 s of work.
MAX_PIECE_EVALUATIONS = 200_000
STIFF_TAU_S = 1e-5        # a time constant below this is named as the likely cause


class PlantError(PlcpredError):
    """The plant cannot integrate a machine (parameters far outside what moves)."""


class _OverBudget(Exception):
    """A piece's right-hand-side evaluations ran past its budget."""


class _DriveConsts(NamedTuple):
    """One drive's constants as the right-hand side reads them (SI units); the friction
    fields are (extending, retracting) pairs."""
    area1: float
    area2: float
    rod_area: float
    load: float
    spring0: float
    spring_rate: float
    Cs1: float
    bs1: float
    ms1: float
    Cs2: float
    bs2: float
    ms2: float
    Ce1: float
    be1: float
    me1: float
    Ce2: float
    be2: float
    me2: float
    stroke: float
    dead1: float
    dead2: float
    wall1: float
    wall2: float
    heat: float
    vented2: bool
    check: bool
    pi_bore: float
    F_coulomb: tuple
    F_static: tuple
    v_stribeck: tuple
    beta: tuple
    mass: float


@dataclass
class Supply:
    """The ideal supply (``line is None``) or a line's regulator and volume."""
    pressure_pa: float                 # set point (ideal: the supply itself)
    temperature_k: float
    line: str | None = None
    volume_m3: float = 0.0
    network_pa: float = 0.0
    C: float = 1e-7
    b: float = 0.3
    m: float = 0.5
    droop_pa: float = 3e4


@dataclass
class Passive:
    """A nozzle or leak on a line (its flow depends on the line pressure)."""
    name: str
    C: float
    b: float
    m: float
    a: float
    always_on: bool
    pressure_pa: float | None = None   # own regulator below the line, if any


@dataclass
class Control:
    """The discrete state of a group: valve openings, motion modes, pending changes."""
    # per drive and chamber: supply-open fraction u(t) = clip(u0 + slope (t - t_ref))
    u0: np.ndarray
    slope: np.ndarray
    t_ref: np.ndarray
    ramp_end: np.ndarray
    moving: np.ndarray
    direction: np.ndarray
    on: np.ndarray                     # passive consumers on the line
    pending: list = field(default_factory=list)   # sorted (t, seq, kind, i, j, value)
    at_rest: bool = False

    def copy(self) -> "Control":
        return Control(self.u0.copy(), self.slope.copy(), self.t_ref.copy(),
                       self.ramp_end.copy(), self.moving.copy(), self.direction.copy(),
                       self.on.copy(), list(self.pending), self.at_rest)

    def u_at(self, t: float) -> np.ndarray:
        return np.clip(self.u0 + self.slope * (t - self.t_ref), 0.0, 1.0)


@dataclass(slots=True)
class Piece:
    t0: float
    t1: float
    x0: np.ndarray          # state at t0 (cumulative masses absolute)
    sol: object             # dense output over relative time, or None for a rest piece
    control: Control | None  # at t0; dropped once no command can come before t1
    rest_rates: np.ndarray | None = None   # d(state)/dt while at rest (cumulative masses)

    def state(self, t):
        """States at times ``t`` (array) within the piece, shape (len(t), n_state)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        if self.sol is None:
            return self.x0[None, :] + (t - self.t0)[:, None] * self.rest_rates[None, :]
        rel = np.clip(t - self.t0, 0.0, self.sol.t_max)
        y = np.atleast_2d(self.sol(rel)).T
        out = y.copy()
        out[:, self.sol.cum] += self.x0[self.sol.cum]
        out[:, ~self.sol.cum] += (self.x0 - self.sol.x_start)[~self.sol.cum]
        return out

    def end_state(self) -> np.ndarray:
        """The state at ``t1`` of a piece that ends where its solution does (the
        solution's last value is kept with it: a reused piece needs no interpolation)."""
        d = self.sol
        return d.end + np.where(d.cum, self.x0, self.x0 - d.x_start)


class _Dense:
    """The solver's dense output with what a reused piece needs."""

    def __init__(self, fn, t_max, x_start, cum):
        self.fn, self.t_max, self.x_start, self.cum = fn, t_max, x_start, cum
        self.end = np.asarray(fn(t_max), dtype=float)     # relative to x_start

    def __call__(self, rel, cols=None):
        if cols is None:
            return self.fn(rel)
        if isinstance(self.fn, rosenbrock.HermiteDense):
            return self.fn(rel, cols)
        return self.fn(rel)[cols]


class Group:
    """Drives on one supply. Times are float seconds; ``t`` is how far it is integrated."""

    def __init__(self, drives, supply: Supply, passives=(), atmosphere_pa=P_ATM_PA,
                 ambient_k=293.15, cache: dict | None = None):
        self.drives = list(drives)
        self.supply = supply
        self.passives = list(passives)
        self.p_atm, self.t_amb = atmosphere_pa, ambient_k
        n, k = len(self.drives), len(self.passives)
        self.n, self.k = n, k
        self.has_line = supply.line is not None
        self._arrays()
        # state: P1 P2 T1 T2 y v M (n each) [+ P_line, M_regulator, M_passive (k)]
        self.size = 7 * n + ((2 + k) if self.has_line else 0)
        cum = np.zeros(self.size, dtype=bool)
        cum[6 * n:7 * n] = True
        if self.has_line:
            cum[7 * n + 1:] = True
        self.cum = cum
        x = np.zeros(self.size)
        ext = np.array([d.initial_extended for d in self.drives], dtype=bool)
        p_sup = supply.pressure_pa
        x[0:n] = np.where(ext, p_sup, self.p_atm)
        x[n:2 * n] = np.where(ext | self.vented2, self.p_atm, p_sup)
        x[2 * n:4 * n] = ambient_k
        x[4 * n:5 * n] = np.where(ext, self.stroke, 0.0)
        if self.has_line:
            x[7 * n] = p_sup
        u = np.where(ext, 1.0, 0.0)
        u = np.stack([u, 1.0 - u], axis=1)           # (n, 2): chamber 1, chamber 2
        u[self.vented2, 1] = 0.0
        self.control = Control(u, np.zeros((n, 2)), np.zeros((n, 2)), np.zeros((n, 2)),
                               np.zeros(n, dtype=bool), np.zeros(n),
                               np.array([p.always_on for p in self.passives], dtype=bool))
        self.t = 0.0
        self.x = x
        self.pieces: list[Piece] = []
        # per drive: times and (retracted, extended) of each switch change
        self.switch_times: list[list[float]] = [[] for _ in range(n)]
        self.switch_states: list[list[tuple[bool, bool]]] = [[] for _ in range(n)]
        self._switch_now = [self._switch_state(i, x) for i in range(n)]
        self._switch_initial = list(self._switch_now)
        self._seq = 0
        self.cache = cache if cache is not None else {}
        # a shared cache must never hand one group's piece to another
        self._ident = repr((self.drives, self.supply, self.passives, atmosphere_pa,
                            ambient_k))
        self.integrated_pieces = 0
        # the Rosenbrock path's factors on the absolute tolerances (see ATOL_FACTOR)
        self._atol_factors = np.full(self.size, ATOL_FACTOR)
        self._atol_factors[5 * n:6 * n] = ATOL_FACTOR_V
        self._atol_factors[cum] = ATOL_FACTOR_MASS
        self._tiny = 0
        self._settled_upto = 0      # pieces before this index have dropped their control
        self.reused_pieces = 0
        if self.has_line:
            x[7 * n] = self._line_equilibrium(self.control.on)
        self._settle_or_start()

    # ------------------------------------------------------------------ parameters
    def _arrays(self):
        d = self.drives
        f = lambda attr: np.array([getattr(x, attr) for x in d], dtype=float)  # noqa: E731
        pair = lambda attr: np.array([getattr(x, attr) for x in d],  # noqa: E731
                                     dtype=float).reshape(-1, 2)
        # arrays for the vectorised bookkeeping (settling, snapping, breakaway)
        self.stroke = f("stroke_m")
        self.A1, self.A2 = f("area1_m2"), f("area2_m2")
        self.dead1, self.dead2 = f("dead1_m3"), f("dead2_m3")
        self.Fs = pair("F_static_n")           # (n, 2): extending, retracting
        self.vented2 = np.array([x.vented2 for x in d], dtype=bool)
        self.check = np.array([x.check_valve for x in d], dtype=bool)
        # per drive, as plain floats (the right-hand side's loop reads these)
        self._par = [_DriveConsts(
                      dr.area1_m2, dr.area2_m2, dr.rod_area_m2, dr.load_n, dr.spring_n[0],
                      (dr.spring_n[1] - dr.spring_n[0]) / dr.stroke_m,
                      dr.C_supply[0], dr.b_supply[0], dr.m_supply[0],
                      dr.C_supply[1], dr.b_supply[1], dr.m_supply[1],
                      dr.C_exhaust[0], dr.b_exhaust[0], dr.m_exhaust[0],
                      dr.C_exhaust[1], dr.b_exhaust[1], dr.m_exhaust[1],
                      dr.stroke_m, dr.dead1_m3, dr.dead2_m3, dr.wall1_m2, dr.wall2_m2,
                      dr.heat_w_m2k, dr.vented2, dr.check_valve, math.pi * dr.bore_m,
                      dr.F_coulomb_n, dr.F_static_n, dr.v_stribeck_m_s, dr.beta_ns_m,
                      dr.mass_kg) for dr in d]
        if self.passives:
            self.pC = np.array([p.C for p in self.passives])
            self.pb = np.array([p.b for p in self.passives])
            self.pm = np.array([p.m for p in self.passives])
            self.pa = np.array([p.a for p in self.passives])
            self.p_own = np.array([p.pressure_pa or np.inf for p in self.passives])

    # ------------------------------------------------------------------ physics
    def _force(self, i: int, p1: float, p2: float, y: float) -> float:
        """(docs/reference/physics.md: dynamic model, motion) the pressure, atmosphere, load and
        spring forces on drive i's piston, + extending."""
        P = self._par[i]
        return (p1 * P.area1 - p2 * P.area2 - self.p_atm * P.rod_area - P.load
                - (P.spring0 + P.spring_rate * y))

    def _passive_flows(self, p_line, on):
        return np.array([signed_mass_flow_kg_s(self.pC[j], self.pb[j], self.pm[j],
                                        min(p_line, self.p_own[j]), self.t_amb,
                                        self.p_atm, self.t_amb, self.pa[j]) if on[j] else 0.0
                         for j in range(self.k)])

    def _regulator(self, p_line):
        s = self.supply
        opening = min(max((s.pressure_pa - p_line) / s.droop_pa, 0.0), 1.0)
        if opening <= 0.0:
            return 0.0
        q = opening * signed_mass_flow_kg_s(s.C, s.b, s.m, s.network_pa, s.temperature_k, p_line,
                                     s.temperature_k)
        return max(q, 0.0)   # a regulator does not feed the network back

    def _path_flows(self, i, u1, u2, p_sup, t_sup, p1, t1, p2, t2):
        """Mass flows (kg/s) of drive i: supply->1, 1->exhaust, supply->2, 2->exhaust."""
        P = self._par[i]
        p_atm, t_amb = self.p_atm, self.t_amb
        qs1 = u1 * signed_mass_flow_kg_s(P.Cs1, P.bs1, P.ms1, p_sup, t_sup, p1, t1) \
            if u1 > 0 else 0.0
        qe1 = (1.0 - u1) * signed_mass_flow_kg_s(P.Ce1, P.be1, P.me1, p1, t1, p_atm, t_amb) \
            if u1 < 1 else 0.0
        if P.vented2:   # vented rod end
            qs2 = qe2 = 0.0
        else:
            qs2 = u2 * signed_mass_flow_kg_s(P.Cs2, P.bs2, P.ms2, p_sup, t_sup, p2, t2) \
                if u2 > 0 else 0.0
            qe2 = (1.0 - u2) * signed_mass_flow_kg_s(P.Ce2, P.be2, P.me2, p2, t2, p_atm, t_amb) \
                if u2 < 1 else 0.0
        if P.check:   # supply check valve
            qs1, qs2 = max(qs1, 0.0), max(qs2, 0.0)
        return qs1, qe1, qs2, qe2

    def rhs(self, t, x, control: Control, u=None, modes=None):
        """d(state)/dt; ``u``: the valves' openings when they are constant over a piece
        (they are unless a valve ramps), ``modes``: (moving, direction) as lists, so
        that each call neither recomputes them nor does arithmetic on numpy scalars."""
        n = self.n
        xs = x.tolist()
        t_sup, t_amb = self.supply.temperature_k, self.t_amb
        p_sup = xs[7 * n] if self.has_line else self.supply.pressure_pa
        if u is None:
            u = control.u_at(t).tolist()
        moving, direction = modes if modes is not None else (control.moving.tolist(),
                                                             control.direction.tolist())
        out = [0.0] * self.size
        drawn = 0.0
        for i in range(n):
            P = self._par[i]
            p1, p2, t1, t2 = xs[i], xs[n + i], xs[2 * n + i], xs[3 * n + i]
            y, v = xs[4 * n + i], xs[5 * n + i]
            qs1, qe1, qs2, qe2 = self._path_flows(i, u[i][0], u[i][1], p_sup, t_sup,
                                                  p1, t1, p2, t2)
            vel = v if moving[i] else 0.0
            stroke = P.stroke
            v1 = P.dead1 + P.area1 * y
            v2 = P.dead2 + P.area2 * (stroke - y)
            # D4: enthalpy of what flows in at its source's temperature, out at the chamber's
            h1 = CP_J_KG_K * (qs1 * (t_sup if qs1 > 0 else t1) - qe1 * (t1 if qe1 > 0 else t_amb))
            heat1 = P.heat * (P.wall1 + P.pi_bore * y) * (t_amb - t1)
            dp1, dt1 = chamber_rates(p1, t1, v1, P.area1 * vel, qs1 - qe1, h1, heat1)
            if P.vented2:
                dp2 = dt2 = 0.0
            else:
                h2 = CP_J_KG_K * (qs2 * (t_sup if qs2 > 0 else t2)
                                  - qe2 * (t2 if qe2 > 0 else t_amb))
                heat2 = P.heat * (P.wall2 + P.pi_bore * (stroke - y)) * (t_amb - t2)
                dp2, dt2 = chamber_rates(p2, t2, v2, -P.area2 * vel, qs2 - qe2, h2, heat2)
            if moving[i]:
                force = self._force(i, p1, p2, y)
                k = 0 if direction[i] > 0 else 1
                fr = friction_n(v, direction[i], P.F_coulomb[k], P.F_static[k],
                                P.v_stribeck[k], P.beta[k])
                acc = (force - fr) / P.mass
            else:
                acc = 0.0
            out[i], out[n + i], out[2 * n + i], out[3 * n + i] = dp1, dp2, dt1, dt2
            out[4 * n + i], out[5 * n + i], out[6 * n + i] = vel, acc, qs1 + qs2
            drawn += qs1 + qs2
        if self.has_line:
            p_line = xs[7 * n]
            q_reg = self._regulator(p_line)
            q_pass = self._passive_flows(p_line, control.on) if self.k else np.zeros(0)
            # the line: isothermal volume (a long metal pipe at ambient)
            out[7 * n] = R_J_KG_K * t_sup / self.supply.volume_m3 * (
                q_reg - drawn - float(q_pass.sum()))
            out[7 * n + 1] = q_reg
            out[7 * n + 2:] = q_pass.tolist()
        return np.array(out)

    def piece_rhs(self, control: Control, t0: float):
        """:meth:`rhs` for one piece as a closure ``f(tr, x)`` of the time ``tr`` from
        ``t0``: the same equations (D2, D4, the motion of docs/reference/physics.md), with
        each drive's constants, valve openings and motion mode bound once, since the
        integrator calls it a few thousand times per piece. A valve ramp or a line
        (the supply follows the state) goes through :meth:`rhs`."""
        if np.any(control.slope != 0.0) or self.has_line:
            u = None if np.any(control.slope != 0.0) else control.u_at(t0).tolist()
            modes = (control.moving.tolist(), control.direction.tolist())
            rhs = self.rhs
            return lambda tr, x: rhs(t0 + tr, x, control, u, modes)
        n, size = self.n, self.size
        t_sup, t_amb, p_atm = self.supply.temperature_k, self.t_amb, self.p_atm
        p_sup = self.supply.pressure_pa
        flow = signed_mass_flow_kg_s
        rates = chamber_rates
        u = control.u_at(t0).tolist()
        drives = []
        for i in range(n):
            P = self._par[i]
            moving = bool(control.moving[i])
            d = float(control.direction[i])
            k = 0 if d > 0 else 1
            u1, u2 = u[i]
            drives.append((
                i, P, u1, u2, moving, d, P.F_coulomb[k], P.F_static[k], P.v_stribeck[k],
                P.beta[k], P.vented2, P.check,
                P.rod_area * p_atm + P.load + P.spring0))
        cp = CP_J_KG_K

        def f(tr, x):
            xs = x.tolist()
            out = [0.0] * size
            for (i, P, u1, u2, moving, d, fc, fs, vs, beta, vented2, check,
                 const_force) in drives:
                p1, p2, t1, t2 = xs[i], xs[n + i], xs[2 * n + i], xs[3 * n + i]
                y, v = xs[4 * n + i], xs[5 * n + i]
                # the four paths of the valve (as _path_flows)
                qs1 = u1 * flow(P.Cs1, P.bs1, P.ms1, p_sup, t_sup, p1, t1) if u1 > 0 else 0.0
                qe1 = (1.0 - u1) * flow(P.Ce1, P.be1, P.me1, p1, t1, p_atm, t_amb) \
                    if u1 < 1 else 0.0
                if vented2:
                    qs2 = qe2 = 0.0
                else:
                    qs2 = u2 * flow(P.Cs2, P.bs2, P.ms2, p_sup, t_sup, p2, t2) \
                        if u2 > 0 else 0.0
                    qe2 = (1.0 - u2) * flow(P.Ce2, P.be2, P.me2, p2, t2, p_atm, t_amb) \
                        if u2 < 1 else 0.0
                if check:
                    qs1, qs2 = max(qs1, 0.0), max(qs2, 0.0)
                vel = v if moving else 0.0
                stroke = P.stroke
                # D4: enthalpy in at the source's temperature, out at the chamber's
                h1 = cp * (qs1 * (t_sup if qs1 > 0 else t1) - qe1 * (t1 if qe1 > 0 else t_amb))
                heat1 = P.heat * (P.wall1 + P.pi_bore * y) * (t_amb - t1)
                dp1, dt1 = rates(p1, t1, P.dead1 + P.area1 * y, P.area1 * vel, qs1 - qe1,
                                 h1, heat1)
                if vented2:
                    dp2 = dt2 = 0.0
                else:
                    h2 = cp * (qs2 * (t_sup if qs2 > 0 else t2)
                               - qe2 * (t2 if qe2 > 0 else t_amb))
                    heat2 = P.heat * (P.wall2 + P.pi_bore * (stroke - y)) * (t_amb - t2)
                    dp2, dt2 = rates(p2, t2, P.dead2 + P.area2 * (stroke - y),
                                     -P.area2 * vel, qs2 - qe2, h2, heat2)
                if moving:
                    force = p1 * P.area1 - p2 * P.area2 - const_force - P.spring_rate * y
                    # Stribeck friction (friction_n), the direction fixed over the piece
                    fr = d * (fc + (fs - fc) * math.exp(-(abs(v) / vs) ** 2.0)) + beta * v
                    acc = (force - fr) / P.mass
                else:
                    acc = 0.0
                out[i], out[n + i], out[2 * n + i], out[3 * n + i] = dp1, dp2, dt1, dt2
                out[4 * n + i], out[5 * n + i], out[6 * n + i] = vel, acc, qs1 + qs2
            return np.array(out)
        return f

    # ------------------------------------------------------------------ modes and events
    def _switch_state(self, i, x) -> tuple[bool, bool]:
        y = x[4 * self.n + i]
        still = not self.control.moving[i]
        return (bool(still and y <= POS_EPS_M), bool(still and y >= self.stroke[i] - POS_EPS_M))

    def _push(self, i, force, y):
        """How far the force on drive i exceeds breakaway towards a free direction (> 0:
        it starts moving), with each direction's static friction."""
        out = force - self.Fs[i, 0] if y < self.stroke[i] - POS_EPS_M else -np.inf
        if y > POS_EPS_M:
            out = max(out, -force - self.Fs[i, 1])
        return out

    def _update_modes(self, t, x) -> None:
        """Stops, stops and breakaways at ``t``; logs switch changes."""
        n = self.n
        c = self.control
        for _ in range(3):
            changed = False
            force = [self._force(i, x[i], x[n + i], x[4 * n + i]) for i in range(n)]
            for i in range(n):
                yi, vi = x[4 * n + i], x[5 * n + i]
                if c.moving[i]:
                    d = c.direction[i]
                    if (d > 0 and yi >= self.stroke[i] - POS_EPS_M) or (d < 0 and yi <= POS_EPS_M):
                        x[4 * n + i] = self.stroke[i] if d > 0 else 0.0
                        x[5 * n + i] = 0.0
                        c.moving[i] = False
                        changed = True
                    elif vi * d <= 1e-9:
                        x[5 * n + i] = 0.0
                        c.moving[i] = False
                        changed = True
                if not c.moving[i] and self._push(i, force[i], x[4 * n + i]) > \
                        -1e-9 * self.Fs[i].max() + 1e-12:
                    c.moving[i] = True
                    c.direction[i] = 1.0 if force[i] > 0 else -1.0
                    x[5 * n + i] = 0.0
                    changed = True
            if not changed:
                break
        for i in range(n):
            s = self._switch_state(i, x)
            if s != self._switch_now[i]:
                self._switch_now[i] = s
                self.switch_times[i].append(t)
                self.switch_states[i].append(s)

    def _targets(self, x, control: Control):
        """Pressures the chambers settle to and the line's equilibrium, or None while a
        valve moves."""
        u = control.u0
        if np.any(control.slope != 0.0) or np.any((u != 0.0) & (u != 1.0)):
            return None
        n = self.n
        p_sup = self._line_equilibrium(control.on) if self.has_line else self.supply.pressure_pa
        p1, p2 = x[0:n], x[n:2 * n]
        t1 = np.where(u[:, 0] == 1.0, p_sup, self.p_atm)
        t2 = np.where(u[:, 1] == 1.0, p_sup, self.p_atm)
        # a check valve holds a chamber above a sagging supply
        t1 = np.where(self.check & (u[:, 0] == 1.0) & (p1 > p_sup), p1, t1)
        t2 = np.where(self.check & (u[:, 1] == 1.0) & (p2 > p_sup), p2, t2)
        t2 = np.where(self.vented2, self.p_atm, t2)
        return t1, t2, p_sup

    def _deviation(self, x, targets) -> float:
        n = self.n
        t1, t2, p_sup = targets
        dev = max(np.max(np.abs(x[0:n] - t1) / t1, initial=0.0),
                  np.max(np.abs(x[n:2 * n] - t2) / t2, initial=0.0)) / SETTLE_P_REL
        dev = max(dev, np.max(np.abs(x[2 * n:4 * n] - self.t_amb), initial=0.0) / SETTLE_T_K)
        if self.has_line:
            dev = max(dev, abs(x[7 * n] - p_sup) / p_sup / SETTLE_P_REL)
        return float(dev)

    def _settle_event(self, targets):
        """:meth:`_deviation` - 1 against targets fixed over a piece (no check valve can
        hold a chamber above them), in plain floats: it is evaluated after every step."""
        n = self.n
        t1, t2, p_sup = targets
        pairs = [(i, p, 1.0 / p) for i, p in enumerate(t1.tolist())]
        pairs += [(n + i, p, 1.0 / p) for i, p in enumerate(t2.tolist())]
        temps = range(2 * n, 4 * n)
        t_amb = self.t_amb
        line = 7 * n if self.has_line else None
        inv_p, inv_t = 1.0 / SETTLE_P_REL, 1.0 / SETTLE_T_K

        def settle(tr, x):
            xs = x.tolist()
            dev_p = max((abs(xs[k] - p) * inv for k, p, inv in pairs), default=0.0)
            if line is not None:
                dev_p = max(dev_p, abs(xs[line] - p_sup) / p_sup)
            dev_t = max((abs(xs[k] - t_amb) for k in temps), default=0.0)
            return max(dev_p * inv_p, dev_t * inv_t) - 1.0
        return settle

    def _line_equilibrium(self, on) -> float:
        """The line pressure at which the regulator feeds exactly the passive flows."""
        if not self.has_line:
            return self.supply.pressure_pa
        def gap(p):
            q = self._passive_flows(p, on).sum() if self.k else 0.0
            return self._regulator(p) - q
        lo, hi = self.p_atm * 1.0001, self.supply.pressure_pa
        if gap(hi) >= 0.0 or gap(lo) <= 0.0:
            return hi if gap(hi) >= 0.0 else lo
        # the gap falls with the line pressure (the regulator closes, the nozzles draw
        # more): bisection to a millipascal, about 30 halvings
        while hi - lo > 1e-3:
            mid = 0.5 * (lo + hi)
            if gap(mid) > 0.0:
                lo = mid
            else:
                hi = mid
        return 0.5 * (lo + hi)

    def _snap(self, x, targets) -> None:
        """Put a settled group in its final state; book the air the snap moves."""
        n = self.n
        t1, t2, p_sup = targets
        c = self.control
        v1 = self.dead1 + self.A1 * x[4 * n:5 * n]
        v2 = self.dead2 + self.A2 * (self.stroke - x[4 * n:5 * n])
        dm1 = air_mass_kg(t1, v1, self.t_amb) - air_mass_kg(x[0:n], v1, x[2 * n:3 * n])
        dm2 = air_mass_kg(t2, v2, self.t_amb) - air_mass_kg(x[n:2 * n], v2, x[3 * n:4 * n])
        dm2 = np.where(self.vented2, 0.0, dm2)
        from_supply = dm1 * (c.u0[:, 0] == 1.0) + dm2 * (c.u0[:, 1] == 1.0)
        x[6 * n:7 * n] += from_supply
        x[0:n], x[n:2 * n] = t1, np.where(self.vented2, self.p_atm, t2)
        x[2 * n:4 * n] = self.t_amb
        x[5 * n:6 * n] = 0.0
        if self.has_line:
            dm_line = (p_sup - x[7 * n]) * self.supply.volume_m3 / (
                R_J_KG_K * self.supply.temperature_k)
            x[7 * n + 1] += dm_line + from_supply.sum()
            x[7 * n] = p_sup

    def _rest_rates(self):
        rates = np.zeros(self.size)
        if self.has_line and self.k:
            q = self._passive_flows(self.x[7 * self.n], self.control.on)
            rates[7 * self.n + 1] = q.sum()
            rates[7 * self.n + 2:] = q
        return rates

    # ------------------------------------------------------------------ control
    def _apply_pending(self, t) -> None:
        c = self.control
        # float times: a change due within TIME_EPS_S is due now (two sums of the same
        # times may differ in the last bit)
        while c.pending and c.pending[0][0] <= t + TIME_EPS_S:
            tc, _, kind, i, j, value = c.pending.pop(0)
            if kind == "valve":
                now = c.u_at(tc)[i, j]
                ramp = self.drives[i].ramp_s
                c.u0[i, j], c.t_ref[i, j] = now, tc
                if ramp > 0.0 and now != value:
                    c.slope[i, j] = (value - now) / ramp
                    c.ramp_end[i, j] = tc + ramp * abs(value - now)
                else:
                    c.u0[i, j], c.slope[i, j], c.ramp_end[i, j] = value, 0.0, tc
            else:
                c.on[i] = bool(value)
            c.at_rest = False
        # a finished ramp becomes a constant opening
        done = (c.slope != 0.0) & (c.ramp_end <= t)
        if np.any(done):
            c.u0[done] = np.clip(c.u0[done] + c.slope[done] * (c.ramp_end[done]
                                                               - c.t_ref[done]), 0.0, 1.0)
            c.u0[done] = np.round(c.u0[done])
            c.slope[done] = 0.0

    def _next_boundary(self) -> float:
        c = self.control
        tb = self.t + MAX_PIECE_S
        if c.pending:
            tb = min(tb, c.pending[0][0])
        ramps = c.ramp_end[(c.slope != 0.0) & (c.ramp_end > self.t)]
        if ramps.size:
            tb = min(tb, float(ramps.min()))
        return tb

    def _settle_or_start(self) -> None:
        """At the frontier: apply what is due, update modes, check for rest."""
        self._apply_pending(self.t)
        self._update_modes(self.t, self.x)
        c = self.control
        if not np.any(c.moving):
            targets = self._targets(self.x, c)
            if targets is not None and self._deviation(self.x, targets) <= 1.0 + 1e-6:
                self._snap(self.x, targets)
                c.at_rest = True

    def command_valve(self, t: float, i: int, extend: bool) -> None:
        """Drive i's valve is commanded to extend (or retract) at ``t``; each chamber sees
        it after the switching delay and the pressure wave's transit down its tube."""
        self._move_frontier(t)
        d = self.drives[i]
        tr1, tr2 = d.transit_s
        self._schedule(t + d.delay_s + tr1, "valve", i, 0, 1.0 if extend else 0.0)
        if not self.vented2[i]:
            self._schedule(t + d.delay_s + tr2, "valve", i, 1, 0.0 if extend else 1.0)
        self._settle_or_start()

    def command_passive(self, t: float, j: int, on: bool) -> None:
        self._move_frontier(t)
        self._schedule(t, "passive", j, 0, 1.0 if on else 0.0)
        self._settle_or_start()

    def _schedule(self, t, kind, i, j, value):
        self._seq += 1
        bisect.insort(self.control.pending, (t, self._seq, kind, i, j, value))
        self.control.at_rest = False

    def _move_frontier(self, t: float) -> None:
        if self.t < t:
            self.advance(t)
        # advancing integrates whole pieces (to a boundary or an event), often past t
        if self.t > t:
            self.truncate(t)
        # commands only come later than this one: pieces that end by now are never
        # truncated into again, so their control state (most of their memory) can go
        k = self._settled_upto
        while k < len(self.pieces) and self.pieces[k].t1 <= t:
            self.pieces[k].control = None
            k += 1
        self._settled_upto = k

    def truncate(self, t: float) -> None:
        """Forget what was integrated after ``t`` (a command came before it)."""
        while self.pieces and self.pieces[-1].t0 > t:
            self.pieces.pop()
        if self.pieces and self.pieces[-1].t1 > t:
            last = self.pieces[-1]
            self.x = last.state([t])[0]
            self.control = last.control.copy()
            if t > last.t0:
                last.t1 = t
            else:
                self.pieces.pop()
        self.t = t
        for i in range(self.n):
            times, states = self.switch_times[i], self.switch_states[i]
            while times and times[-1] > t:
                times.pop()
                states.pop()
            self._switch_now[i] = states[-1] if states else self._switch_initial[i]

    # ------------------------------------------------------------------ integration
    def advance(self, t_target: float) -> None:
        while self.t < t_target:
            self._step(t_target)

    def _step(self, t_target: float) -> None:
        c = self.control
        tb = self._next_boundary()
        if c.at_rest:
            t1 = min(tb, t_target) if c.pending else t_target
            last = self.pieces[-1] if self.pieces else None
            if last is not None and last.sol is None and last.t1 == self.t \
                    and last.control is not None and last.control.at_rest \
                    and _same(last.control, c):
                last.t1 = t1
            else:
                self.pieces.append(Piece(self.t, t1, self.x.copy(), None, c.copy(),
                                         self._rest_rates()))
            self.x = self.x + (t1 - self.t) * self.pieces[-1].rest_rates
            self.t = t1
            if t1 >= tb:
                self._settle_or_start()
            return
        if tb - self.t <= TIME_EPS_S:
            self.t = max(self.t, tb)
            self._settle_or_start()
            return
        piece, x_end, t_end = self._integrate(tb)
        self._tiny = self._tiny + 1 if t_end - self.t < 1e-6 else 0
        if self._tiny > MAX_TINY_PIECES:
            raise PlantError(f"the plant cannot integrate drive(s) {self._names()} at "
                             f"{self.t:.6g} s: events follow each other without end (check "
                             "friction, mass and load for values far outside real drives)")
        if len(self.pieces) >= MAX_PIECES:
            raise PlantError(f"drive(s) {self._names()}: more than {MAX_PIECES:,} integration "
                             f"pieces by {self.t:.6g} s; emulate a shorter horizon (the "
                             "physics plant keeps every piece for its outputs)")
        self.pieces.append(piece)
        self.x, self.t = x_end, t_end
        self._settle_or_start()

    def _key(self, tb):
        c = self.control
        n = self.n
        x = self.x
        q = np.concatenate([np.round(x[0:2 * n], 1), np.round(x[2 * n:4 * n], 4),
                            np.round(x[4 * n:5 * n], 8), np.round(x[5 * n:6 * n], 6),
                            np.round(x[7 * n:7 * n + 1], 1) if self.has_line else []])
        return (self._ident, q.tobytes(), c.u0.tobytes(), c.slope.tobytes(),
                np.round(c.t_ref - self.t, 9).tobytes(), c.moving.tobytes(),
                c.direction.tobytes(), c.on.tobytes(), round(tb - self.t, 9))

    def _integrate(self, tb):
        t0 = self.t
        c = self.control
        key = self._key(tb)
        hit = self.cache.get(key)
        if hit is None:
            hit = self._solve(tb)
            if len(self.cache) < CACHE_LIMIT:
                self.cache[key] = hit
            self.integrated_pieces += 1
        else:
            self.reused_pieces += 1
        dense, t_len = hit
        piece = Piece(t0, t0 + t_len, self.x.copy(), dense, c.copy())
        x_end = piece.end_state()
        return piece, x_end, t0 + t_len

    def _solve(self, tb):
        """Integrate from the frontier to ``tb`` or the first event; relative time."""
        t0 = self.t
        c = self.control.copy()
        n = self.n
        x0 = self.x.copy()
        x0[self.cum] = 0.0
        budget = max(MAX_PIECE_EVALUATIONS // max(1, n), MAX_PIECE_EVALUATIONS // 10)
        calls = [0]
        rhs = self.piece_rhs(c, t0)

        def f(tr, x):
            calls[0] += 1
            if calls[0] > budget:
                raise _OverBudget()
            return rhs(tr, x)

        events = []
        for i in range(n):
            if c.moving[i]:
                d = c.direction[i]
                stop = (lambda tr, x, i=i: x[4 * n + i] - self.stroke[i]) if d > 0 else (
                    lambda tr, x, i=i: x[4 * n + i])
                stop.terminal, stop.direction = True, (1 if d > 0 else -1)
                halt = lambda tr, x, i=i: x[5 * n + i]  # noqa: E731
                halt.terminal, halt.direction = True, (-1 if d > 0 else 1)
                events += [stop, halt]
            else:
                def breakaway(tr, x, i=i):
                    y = x[4 * n + i]
                    return self._push(i, self._force(i, x[i], x[n + i], y), y)
                breakaway.terminal, breakaway.direction = True, 1
                events.append(breakaway)
        if not np.any(c.moving):
            targets = self._targets(x0, c)
            if targets is not None:
                if np.any(self.check):      # targets follow the chambers (check valves)
                    def settle(tr, x):
                        xt = x.copy()
                        return self._deviation(xt, self._targets(xt, c)) - 1.0
                else:
                    settle = self._settle_event(targets)
                settle.terminal, settle.direction = True, -1
                events.append(settle)
        atol = np.concatenate([np.full(2 * n, 1.0), np.full(2 * n, 1e-3), np.full(n, 1e-8),
                               np.full(n, 1e-6), np.full(n, 1e-11),
                               np.concatenate([[1.0], np.full(1 + self.k, 1e-11)])
                               if self.has_line else []])
        span = tb - t0
        if METHOD == "lsoda":
            t_len, sol_fn = self._solve_lsoda(f, span, x0, events, atol, t0, budget)
        else:
            try:
                sol_fn, t_len, _ = rosenbrock.solve(
                    f, span, x0, RTOL, atol * self._atol_factors, events,
                    first_step=min(1e-5, span), free=~self.cum)
            except _OverBudget:
                raise PlantError(self._too_stiff(t0, budget)) from None
            except (ArithmeticError, ValueError, np.linalg.LinAlgError) as e:
                raise PlantError(f"the plant cannot integrate drive(s) {self._names()} from "
                                 f"{t0:.6g} s ({type(e).__name__}: {e}); check sizes, "
                                 "conductances and loads for values far outside real drives"
                                 ) from None
        # an event at the very start: move on by at least a few of the clock's own
        # steps, or late in a long run (4,100 s on) the piece adds nothing to the clock
        # and the same event is found again without end
        min_len_s = max(1e-9, 8.0 * float(np.spacing(t0)))
        if t_len < min_len_s:
            t_len = min(min_len_s, span)
        dense = _Dense(sol_fn, t_len, x0, self.cum)
        return dense, t_len

    def _solve_lsoda(self, f, span, x0, events, atol, t0, budget):
        """The reference integration (scipy's LSODA), kept for the equality tests:
        (length, dense output)."""
        # scipy costs a third of a second to import: only this reference path pays it
        from scipy.integrate import solve_ivp
        try:
            sol = solve_ivp(f, (0.0, span), x0, method="LSODA", dense_output=True,
                            events=events or None, rtol=LSODA_RTOL, atol=atol,
                            first_step=min(1e-5, span))
        except _OverBudget:
            raise PlantError(self._too_stiff(t0, budget)) from None
        except (ArithmeticError, ValueError) as e:
            raise PlantError(f"the plant cannot integrate drive(s) {self._names()} from "
                             f"{t0:.6g} s ({type(e).__name__}: {e}); check sizes, "
                             "conductances and loads for values far outside real drives"
                             ) from None
        if sol.status < 0:
            raise PlantError(f"the plant cannot integrate drive(s) {self._names()} from "
                             f"{t0:.6g} s: {sol.message}")
        return float(sol.t[-1]), sol.sol

    def _names(self) -> str:
        return ", ".join(f'"{d.name}"' for d in self.drives) or "(none)"

    def _time_constants(self) -> list[tuple[float, str]]:
        """(seconds, what to change) of the fastest processes of the group's equations:
        the line's regulator refilling its volume, and each chamber filling or
        emptying its dead volume through its supply and exhaust paths."""
        rt0 = R_J_KG_K * self.t_amb * 1.185         # (Pa m^3 / kg) * kg/m^3 at ISO 8778
        out = []
        s = self.supply
        if self.has_line and s.C > 0 and s.network_pa > 0:
            tau = s.volume_m3 * s.droop_pa / (rt0 * s.C * s.network_pa)
            out.append((tau, f'[[line]] "{s.line}": its regulator (C = {s.C:.3g} '
                             f'm^3/(s Pa), droop_bar = {s.droop_pa / PA_PER_BAR:g}) refills its '
                             f'volume_l = {s.volume_m3 * 1e3:g} in about {tau:.2g} s; '
                             "regulators have C of 1e-8 to 1e-6, lines hold 0.01 to 100 l"))
        for d in self.drives:
            for j, dead in enumerate((d.dead1_m3, d.dead2_m3)):
                C = max(d.C_supply[j], d.C_exhaust[j])
                if C > 0 and dead > 0:
                    tau = dead / (rt0 * C)
                    out.append((tau, f'consumer "{d.name}": its {("cap", "rod")[j]} end '
                                     f"({dead * 1e6:.3g} cm^3 dead volume) fills through C "
                                     f"= {C:.3g} m^3/(s Pa) in about {tau:.2g} s (check "
                                     "supply_C, exhaust_C and dead_volume_cm3)"))
        return sorted(out)

    def _too_stiff(self, t0: float, budget: int) -> str:
        what = (f'line "{self.supply.line}" (drives {self._names()})' if self.has_line
                else f"drive(s) {self._names()}")
        fast = [msg for tau, msg in self._time_constants()[:2] if tau < STIFF_TAU_S]
        cause = ("; the fastest: " + "; ".join(fast)) if fast else (
            "; check the conductances (C), volumes and droop of the line and drives for "
            "values far outside real ones")
        return (f"the plant cannot integrate {what} from {t0:.6g} s: more than "
                f"{budget:,} evaluations of its equations between two events, which are "
                f"too stiff{cause}")

    # ------------------------------------------------------------------ queries
    def switches(self, i: int, t: float) -> tuple[bool, bool]:
        if self.t < t:
            self.advance(t)
        k = bisect.bisect_right(self.switch_times[i], t + TIME_EPS_S)
        return self.switch_states[i][k - 1] if k else self._switch_initial[i]

    def next_switch_after(self, i: int, t: float) -> float | None:
        """The first time > ``t`` at which drive i's switches change, integrating ahead
        as far as needed (LOOKAHEAD_S at most), or None."""
        if self.t < t:
            self.advance(t)
        limit = t + LOOKAHEAD_S
        while True:
            times = self.switch_times[i]
            k = bisect.bisect_right(times, t + TIME_EPS_S)
            if k < len(times):
                return times[k]
            c = self.control
            if (c.at_rest and not c.pending) or self.t >= limit:
                return None
            self._step(math.inf)

    def state_at(self, times_s: np.ndarray, cols=None) -> np.ndarray:
        """States on a grid of times within [0, t] (rows), from the pieces; ``cols``:
        only these states (indices; the outputs each need a few of a group's 7 per
        drive). Pieces that share one dense solution (reused ones) are evaluated in one
        call."""
        times_s = np.asarray(times_s, dtype=float)
        cols = np.arange(self.size) if cols is None else np.asarray(cols, dtype=int)
        pieces = self.pieces
        starts = np.array([p.t0 for p in pieces])
        idx = np.clip(np.searchsorted(starts, times_s, side="right") - 1, 0, len(pieces) - 1)
        base = np.empty((len(pieces), len(cols)))     # what each piece adds to its solution
        rates = np.zeros((len(pieces), len(cols)))
        dense_of = np.full(len(pieces), -1)
        denses: dict[int, int] = {}
        dense_list = []
        cum = self.cum[cols]
        for k, p in enumerate(pieces):
            x0 = p.x0[cols]
            if p.sol is None:
                base[k] = x0
                rates[k] = p.rest_rates[cols]
            else:
                base[k] = np.where(cum, x0, x0 - p.sol.x_start[cols])
                j = denses.setdefault(id(p.sol), len(dense_list))
                if j == len(dense_list):
                    dense_list.append(p.sol)
                dense_of[k] = j
        rel = times_s - starts[idx]
        out = base[idx]
        drawing = np.any(rates != 0.0, axis=1)[idx]     # rest pieces that draw air
        if np.any(drawing):
            out[drawing] += rel[drawing, None] * rates[idx[drawing]]
        # each dense solution's times, found by one sort instead of a scan per solution
        which = dense_of[idx]
        order = np.argsort(which, kind="stable")
        bounds = np.searchsorted(which[order], np.arange(-1, len(dense_list) + 1))
        for j, dense in enumerate(dense_list):
            sel = order[bounds[j + 1]:bounds[j + 2]]
            if len(sel):
                out[sel] += np.atleast_2d(dense(np.clip(rel[sel], 0.0, dense.t_max),
                                                cols)).T
        return out


def _same(a: Control, b: Control) -> bool:
    return (np.array_equal(a.u0, b.u0) and np.array_equal(a.on, b.on)
            and not a.pending and not b.pending)
