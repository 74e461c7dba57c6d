"""Independent dynamic model of an electro-pneumatic machine (bench/indep).

Written from the physics notes (docs/reference/physics.md and the thesis figures it cites) (equations cited as D1, D2, D3, section 4 for the
chamber model, section 7 for what the dynamics add to D1), sharing no code with plcpred.
numpy only. It simulates, in one vectorised batch, any number of drives of any number of
runs (of any number of cases), so a 1 ms fixed step stays cheap:

* per drive two chambers (cap, rod), each lumped with its tube's dead volume and the
  cylinder's own internal dead volume; mass and internal energy as states (docs/reference/physics.md
  section 4: dP/dt = -gamma P/V dV/dt + gamma R T/V (qm_in - qm_out) + (gamma-1)/V Q),
  heat exchange with the walls of the cylinder and of the tube through separate heat
  transfer coefficients (the polytropic index is a result: between isothermal for a slow
  stroke in a thin tube and nearly adiabatic for a fast one in a large bore);
* four flow paths per drive by the extended ISO 6358 equation (D2), each the valve, the
  tube and (on the exhaust, for meter-out flow controls) a throttle in series by
  Eckersten's rule (docs/reference/physics.md, restrictions (D2)); a near-equilibrium linear patch (the last
  0.2 % of pressure ratio) keeps D2's infinite slope at r = 1 integrable;
* 5/2 (monostable or bistable) and 3/2 (single-acting) valves with a switching delay, a
  spool that travels over a ramp time with positive overlap (all ports shut for part of
  the travel), and the pressure wave's transit down each tube (L/c);
* the piston: (M_L + M_p) y'' = P1 A1 - P2 A2 - P_atm (A1 - A2) - F_f - F_L (section 4),
  Stribeck friction with breakaway, gravity by the mount angle, a spring for
  single-acting drives, end stops at 0 and s;
* the supply: ideal regulated pressure (optionally stepped in time), or a supply line of
  finite volume fed by a proportional regulator (drives without check valves then push
  air back into the line and are refilled: "shared supply"), or a regulator whose
  output pressure droops with the flow;
* nozzles, air knives and leaks as D2 restrictions to atmosphere (optionally behind their
  own regulator), switched through a valve with delay and ramp;
* the flow meter (first-order lag, mean-of-interval logging, noise, gain, reference
  condition, clock offset, time-stamp jitter) is `meter_log` below.

Linearly implicit (Rosenbrock-Euler) in every chamber pressure and the supply line
pressure; the piston's velocity update is implicit in the pneumatic spring. Mass is
conserved exactly: what the supply path delivers in a step is what the chamber gains.

`python bench/indep/physics.py --selfcheck` prints the validation ratios (settled stroke
against D1, steady nozzle against D2, short dwells, time-step convergence).
"""
from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass, field

import numpy as np

# ---- constants (docs/reference/physics.md, reference conditions (D3)) -------------------------------------------------
P0 = 100_000.0          # Pa, ISO 8778 reference pressure
T0 = 293.15             # K, ISO 8778 reference temperature
R_AIR = 287.05          # J/(kg K)
GAMMA = 1.4
CV = R_AIR / (GAMMA - 1.0)
CP = GAMMA * CV
# Normal density used to turn kg into normal litres. D2 in volume terms (q = C P ...,
# D3 q = qm / rho0) does not depend on it; for a chamber's mass the ideal-gas density at
# the reference (1.1884) makes P V / P0 (T0/T) exact, where 1.185 (ISO 8778's humid air)
# would read 0.3 % more. Used consistently for both.
RHO_N = P0 / (R_AIR * T0)
K_ORIFICE = math.sqrt(GAMMA / R_AIR * (2.0 / (GAMMA + 1.0)) ** ((GAMMA + 1.0) / (GAMMA - 1.0)))
G_ACC = 9.81
DIN1343_FACTOR = (P0 / 101_325.0) * (273.15 / T0)   # D3 conversion: ISO 8778 litres -> DIN 1343 litres (0.9196)
LIN_EPS = 0.002          # D2 linear patch: last 0.2 % of pressure ratio before r = 1


def c_orifice(d_mm: float, cd: float) -> float:
    """Sonic conductance of an orifice (docs/reference/physics.md, restrictions (D2), orifice form), m^3/(s Pa)."""
    area = math.pi * (d_mm * 1e-3) ** 2 / 4.0
    return cd * area * K_ORIFICE / (RHO_N * math.sqrt(T0))


def c_tube(d_mm: float, length_m: float, lam: float = 0.025, cd_inlet: float = 0.85) -> float:
    """Sonic conductance of a plain tube: its bore as an inlet orifice, reduced by wall
    friction as for a loss coefficient lam L/d in series (a Fanno-flow estimate). A 4 mm
    bore, 1 m tube gives about 1.0e-8, 6 m about 4.5e-9."""
    if d_mm <= 0 or length_m <= 0:
        return 1.0
    c0 = c_orifice(d_mm, cd_inlet)
    return c0 / math.sqrt(1.0 + 0.5 * lam * length_m / (d_mm * 1e-3))


def series(cs, bs):
    """Restrictions in series, Eckersten (docs/reference/physics.md, restrictions (D2)): 1/C^3 = sum 1/C_i^3,
    1 - b = C^2 sum (1 - b_i)/C_i^2."""
    cs = [float(c) for c in cs]
    inv = sum(1.0 / c ** 3 for c in cs)
    c = inv ** (-1.0 / 3.0)
    one_minus_b = c * c * sum((1.0 - b) / (ci * ci) for ci, b in zip(cs, bs))
    return c, float(min(max(1.0 - one_minus_b, -0.5), 0.9))


def d2_phi(r, b, m):
    """phi(r) of D2 (a = 1) with a linear patch over the last LIN_EPS of r, and its
    derivative dphi/dr. Vectorised; r may exceed 1 (then 0)."""
    r = np.asarray(r, dtype=float)
    b = np.broadcast_to(b, r.shape)
    m = np.broadcast_to(m, r.shape)
    r1 = 1.0 - LIN_EPS
    z1 = (r1 - b) / (1.0 - b)
    phi1 = np.power(np.maximum(1.0 - z1 * z1, 1e-300), m)
    rc = np.clip(r, b, r1)
    z = (rc - b) / (1.0 - b)
    base = np.maximum(1.0 - z * z, 1e-300)
    phi_sub = np.power(base, m)
    dphi_sub = m * np.power(base, m - 1.0) * (-2.0 * z / (1.0 - b))
    lin = r > r1
    phi = np.where(r <= b, 1.0, np.where(lin, phi1 * np.clip((1.0 - r) / LIN_EPS, 0.0, None), phi_sub))
    dphi = np.where(r <= b, 0.0, np.where(lin, np.where(r < 1.0, -phi1 / LIN_EPS, 0.0), dphi_sub))
    return phi, dphi


def d2_massflow(C, b, m, pu, pd, tu):
    """D2 mass flow (kg/s) from pu to pd (one direction, pu >= pd assumed) and its partial
    derivatives d/dpu, d/dpd."""
    r = pd / pu
    phi, dphi = d2_phi(r, b, m)
    k = RHO_N * C * np.sqrt(T0 / tu)
    q = k * pu * phi
    dq_dpd = k * dphi
    dq_dpu = k * (phi - r * dphi)
    return q, dq_dpu, dq_dpd


def d2_secant(C, b, m, pa, pb, ta, tb, allow_reverse=True):
    """Signed D2 mass flow from node a to node b (either way) and its secant conductance
    G >= 0, q = G (pa - pb). The implicit step uses the secant, not the tangent: a choked
    flow extrapolated along its tangent would carry a chamber past the pressure it flows
    towards; with the secant the new pressure stays between the old one and those of the
    nodes the chamber is open to (in the linear patch the two are the same)."""
    fwd = pa >= pb
    pu = np.where(fwd, pa, pb)
    pd = np.where(fwd, pb, pa)
    tu = np.where(fwd, ta, tb)
    phi, _ = d2_phi(pd / pu, b, m)
    k = RHO_N * C * np.sqrt(T0 / tu)
    qabs = k * pu * phi
    dp = pu - pd
    z1 = (1.0 - LIN_EPS - b) / (1.0 - b)
    g_lin = k * np.power(np.maximum(1.0 - z1 * z1, 1e-300), m) / LIN_EPS
    G = np.where(dp > 1e-9 * pu, qabs / np.maximum(dp, 1e-300), g_lin)
    q = np.where(fwd, qabs, -qabs)
    if allow_reverse is not True:
        ok = fwd | np.asarray(allow_reverse)
        q = np.where(ok, q, 0.0)
        G = np.where(ok, G, 0.0)
    return q, G


class _Paths:
    """D2 with the secant conductance (as d2_secant) for fixed arrays of b, m: what does
    not change from step to step is computed once (the integrator's hot loop)."""

    def __init__(self, b, m):
        self.b = np.asarray(b, dtype=float)
        self.m = np.asarray(m, dtype=float)
        self.inv1b = 1.0 / (1.0 - self.b)
        self.r1 = 1.0 - LIN_EPS
        self.z1 = (self.r1 - self.b) * self.inv1b
        self.phi1 = np.power(np.maximum(1.0 - self.z1 * self.z1, 1e-300), self.m)
        self.glin = self.phi1 / LIN_EPS

    def flow(self, C, pa, pb, ta, tb, reverse_ok=None):
        fwd = pa >= pb
        pu = np.where(fwd, pa, pb)
        pd = (pa + pb) - pu
        r = pd / pu
        z = np.minimum(np.maximum((r - self.b) * self.inv1b, 0.0), self.z1)
        phi = np.power(1.0 - z * z, self.m)
        phi = np.where(r > self.r1, self.glin * (1.0 - r), phi)
        k = (RHO_N * np.sqrt(T0)) * C / np.sqrt(np.where(fwd, ta, tb))
        dp = pu - pd
        qabs = k * pu * phi
        G = np.where(dp > 1e-9 * pu, qabs / np.maximum(dp, 1e-300), k * self.glin)
        q = np.where(fwd, qabs, -qabs)
        if reverse_ok is not None:
            ok = fwd | reverse_ok
            q = np.where(ok, q, 0.0)
            G = np.where(ok, G, 0.0)
        return q, G


def _clip(x, lo, hi):
    return np.minimum(np.maximum(x, lo), hi)


def d1_stroke_nl(bore_mm, rod_mm, stroke_mm, tube_id_mm, tube_len_m, p_supply_abs, t_supply_k,
                 kind="double_acting", direction="extend"):
    """D1a/D1b at the ISO 8778 reference (D3): (swept + tube) * P_s/P0 * T0/T_s, NL."""
    a_full = math.pi * (bore_mm * 1e-3) ** 2 / 4.0
    a_rod = math.pi * (rod_mm * 1e-3) ** 2 / 4.0
    if kind in ("rodless", "semi_rotary", "gripper"):
        area = a_full
    elif kind == "double_rod":
        area = a_full - a_rod
    elif direction == "extend":
        area = a_full
    else:
        area = a_full - a_rod
    if kind == "single_acting" and direction != "extend":
        return 0.0
    v = area * stroke_mm * 1e-3 + tube_len_m * math.pi * (tube_id_mm * 1e-3) ** 2 / 4.0
    return v * p_supply_abs / P0 * T0 / t_supply_k * 1000.0


# ---- specifications ------------------------------------------------------------------

@dataclass
class DriveSpec:
    name: str
    kind: str                      # double_acting, single_acting, double_rod, rodless, semi_rotary, gripper
    bore_mm: float
    rod_mm: float
    stroke_mm: float
    tube_id_mm: float
    tube_len_m: tuple              # (cap, rod)
    dead_len_mm: tuple = (2.5, 2.5)       # cylinder's own dead volume as mm of its bore, per chamber
    # valve and circuit
    c_valve: float = 1.5e-8        # valve's port-to-port conductance (each of the four paths)
    b_valve: float = 0.3
    m_valve: float = 0.5
    c_throttle: tuple = (None, None)     # meter-out throttle on the exhaust of (cap, rod); None = open
    c_meter_in: float | None = None      # single-acting: a meter-in throttle on the supply
    tube_lambda: float = 0.025
    overlap: float = 0.2           # share of the spool's travel (its middle) with all ports shut
    ramp_s: float = 0.012          # spool travel time
    delay_s: float = 0.015         # switching delay (command to spool moving)
    wave_c: float = 343.0          # pressure wave speed in the tubes
    check_valve: bool = False      # supply check valve (a holding chamber cannot push back)
    # thermal
    h_cyl: float = 30.0            # W/(m^2 K), air to cylinder walls
    h_tube: float = 60.0           # W/(m^2 K), air to tube walls
    # mechanics
    payload_kg: float = 0.0
    moving_mass_kg: float | None = None
    mount_angle_deg: float = 0.0
    f_coulomb: tuple = (None, None)      # N, (extending, retracting); None: 5 % of the cap force at 6 bar
    static_ratio: float = 1.4
    viscous_ns_m: float | None = None
    stribeck_v: float = 0.02
    damping_ratio: float = 0.5     # seals' viscous damping at least this share of critical on the air spring
    f_load: float = 0.0            # constant external load against extension, N
    spring_bar: tuple = (0.5, 1.1) # single-acting spring, as bar on the piston (retracted, extended)
    initial: str = "retracted"
    # valve command edges: list of (t_command, state 0/1) (state 1 = extend)
    edges: list = field(default_factory=list)

    # derived geometry
    def areas(self):
        a_full = math.pi * (self.bore_mm * 1e-3) ** 2 / 4.0
        a_rod = math.pi * (self.rod_mm * 1e-3) ** 2 / 4.0
        if self.kind in ("rodless", "semi_rotary", "gripper"):
            return a_full, a_full
        if self.kind == "double_rod":
            return a_full - a_rod, a_full - a_rod
        if self.kind == "single_acting":
            return a_full, a_full        # rod side vented: force (P1 - P_atm) A1
        return a_full, a_full - a_rod

    def mass(self):
        if self.moving_mass_kg is not None:
            return self.moving_mass_kg + self.payload_kg
        d = self.bore_mm * 1e-3
        a_full = math.pi * d * d / 4.0
        piston = 2700.0 * a_full * 0.45 * d + 0.01
        rod = 7850.0 * math.pi * (self.rod_mm * 1e-3) ** 2 / 4.0 * (self.stroke_mm * 1e-3 + 0.04)
        if self.kind == "rodless":
            piston += 0.25 + 8.0 * a_full        # carriage
        if self.kind == "gripper":
            piston += 0.04                        # jaws
        if self.kind == "semi_rotary":
            piston += 0.10                        # vane, shaft and lever as equivalent mass
        return piston + rod + self.payload_kg


@dataclass
class RestrictionSpec:
    """A nozzle (switched by its valve), an air knife or a leak (always on)."""
    name: str
    C: float
    b: float = 0.528
    m: float = 0.5
    p_reg_abs: float | None = None       # its own regulator (absolute Pa); None = the supply
    edges: list | None = None            # valve edges (t, state); None = always on (a leak)
    delay_s: float = 0.012
    ramp_s: float = 0.010
    onset_s: float | None = None         # a leak that opens (over 0.5 s) at this time
    stuck_on_from: float | None = None   # a valve stuck open from this time


@dataclass
class SupplySpec:
    p_set_abs: float                     # regulated pressure at no flow, Pa abs
    schedule: list = field(default_factory=list)   # [(t, p_set_abs)]: one step, ramped over 1 s
    mode: str = "ideal"                  # ideal | line | droop
    line_volume_l: float = 0.5
    reg_C: float = 6e-8
    reg_b: float = 0.3
    reg_m: float = 0.5
    reg_band_pa: float = 30_000.0
    network_abs: float | None = None
    droop_pa_per_nl_min: float = 0.0     # droop mode: pressure lost per NL/min of flow
    droop_tau_s: float = 0.15


@dataclass
class RunSpec:
    t_end: float
    supply: SupplySpec
    drives: list
    restrictions: list
    p_atm: float = 101_325.0
    t_amb: float = 293.15               # walls and atmosphere
    t_sup: float = 293.15               # supply air
    bin_s: float = 0.01


# ---- the batch integrator ---------------------------------------------------------------

def _edge_table(lists, pad_time=np.inf):
    n = len(lists)
    emax = max([len(x) for x in lists] + [0]) + 1
    tt = np.full((n, emax), pad_time)
    uu = np.zeros((n, emax))
    for i, lst in enumerate(lists):
        for j, (t, u) in enumerate(lst):
            tt[i, j] = t
            uu[i, j] = u
    return tt, uu


class _Edges:
    """Per-element sorted event times; `advance(t)` applies all events up to t."""

    def __init__(self, lists, init):
        self.t, self.u = _edge_table(lists)
        self.n = len(lists)
        self.ptr = np.zeros(self.n, dtype=int)
        self.state = np.asarray(init, dtype=float).copy()
        self.ar = np.arange(self.n)
        self.next_t = self.t[:, 0].copy() if self.n else np.zeros(0)
        self.min_next = self.next_t.min() if self.n else np.inf

    def advance(self, t):
        if self.min_next > t:
            return None
        changed = np.zeros(self.n, dtype=bool)
        while True:
            hit = self.next_t <= t
            if not hit.any():
                break
            idx = self.ar[hit]
            self.state[idx] = self.u[idx, self.ptr[idx]]
            self.ptr[idx] += 1
            self.next_t[idx] = self.t[idx, self.ptr[idx]]
            changed[idx] = True
        self.min_next = self.next_t.min()
        return changed


def simulate(runs: list[RunSpec], dt: float = 1e-3, record_edges: bool = True, progress=None, trace=None):
    """Integrate all runs together. Returns one dict per run:
    'flow_nl' (NL per bin, at the meter's place), 'p_supply' (mean supply/line pressure
    per bin, Pa abs), 'bin_s', and per drive 'edge_air_nl' (air drawn from the supply
    between a drive's effective valve edges, per edge, index 0 = before the first edge),
    'reach' (time the piston reached the end of each stroke, per edge, nan if never),
    'drive_air_nl' (total), 'restr_air_nl' (per restriction, total)."""
    nr = len(runs)
    t_end = max(r.t_end for r in runs)
    nsteps = int(math.ceil(t_end / dt - 1e-9))
    # --- flatten drives
    drv = [(ri, d) for ri, r in enumerate(runs) for d in r.drives]
    nd = len(drv)
    run_of_d = np.array([ri for ri, _ in drv], dtype=int)
    p_atm_r = np.array([r.p_atm for r in runs])
    t_amb_r = np.array([r.t_amb for r in runs])
    t_sup_r = np.array([r.t_sup for r in runs])

    A1 = np.zeros(nd); A2 = np.zeros(nd); S = np.zeros(nd); M = np.zeros(nd)
    V01 = np.zeros(nd); V02 = np.zeros(nd)
    Aw_t1 = np.zeros(nd); Aw_t2 = np.zeros(nd)
    perim = np.zeros(nd)
    h_cyl = np.zeros(nd); h_tube = np.zeros(nd)
    Cs = np.zeros((2, nd)); bs = np.zeros((2, nd)); ms = np.zeros((2, nd))
    Ce = np.zeros((2, nd)); be = np.zeros((2, nd)); me = np.zeros((2, nd))
    vent2 = np.zeros(nd, dtype=bool)
    check = np.zeros(nd, dtype=bool)
    ov = np.zeros(nd); ramp = np.zeros(nd)
    Fc_ext = np.zeros(nd); Fc_ret = np.zeros(nd); Fs_ratio = np.zeros(nd); beta = np.zeros(nd); vs = np.zeros(nd)
    Fg = np.zeros(nd); Fl = np.zeros(nd); Fsp0 = np.zeros(nd); Fsp1 = np.zeros(nd)
    y = np.zeros(nd); v = np.zeros(nd)
    drive_lists = []; cap_lists = []; rod_lists = []
    init_state = np.zeros(nd)
    for i, (ri, d) in enumerate(drv):
        r = runs[ri]
        a1, a2 = d.areas()
        A1[i], A2[i] = a1, a2
        S[i] = d.stroke_mm * 1e-3
        M[i] = d.mass()
        lt1, lt2 = d.tube_len_m
        at = math.pi * (d.tube_id_mm * 1e-3) ** 2 / 4.0
        V01[i] = a1 * d.dead_len_mm[0] * 1e-3 + lt1 * at
        V02[i] = a2 * d.dead_len_mm[1] * 1e-3 + lt2 * at
        Aw_t1[i] = math.pi * d.tube_id_mm * 1e-3 * lt1
        Aw_t2[i] = math.pi * d.tube_id_mm * 1e-3 * lt2
        perim[i] = math.pi * d.bore_mm * 1e-3
        h_cyl[i] = d.h_cyl; h_tube[i] = d.h_tube
        for k, lt in enumerate((lt1, lt2)):
            ct = c_tube(d.tube_id_mm, lt, d.tube_lambda) if lt > 0 else None
            parts_s = [(d.c_valve, d.b_valve)] + ([(ct, 0.45)] if ct else [])
            if d.kind == "single_acting" and k == 0 and d.c_meter_in:
                parts_s.append((d.c_meter_in, 0.3))
            c_s, b_s = series([p[0] for p in parts_s], [p[1] for p in parts_s])
            parts_e = [(d.c_valve * 1.15, d.b_valve)] + ([(ct, 0.45)] if ct else [])
            if d.c_throttle[k]:
                parts_e.append((d.c_throttle[k], 0.3))
            c_e, b_e = series([p[0] for p in parts_e], [p[1] for p in parts_e])
            Cs[k, i], bs[k, i], ms[k, i] = c_s, b_s, d.m_valve
            Ce[k, i], be[k, i], me[k, i] = c_e, b_e, d.m_valve
        if d.kind == "single_acting":
            vent2[i] = True
            Cs[1, i] = 0.0
            Ce[1, i] = 2e-7; be[1, i] = 0.3; me[1, i] = 0.5
            V02[i] = a2 * 0.02                       # breather side: open to atmosphere
        check[i] = d.check_valve
        ov[i] = d.overlap; ramp[i] = max(d.ramp_s, 1e-4)
        fcap6 = a1 * 6e5
        fce, fcr = d.f_coulomb
        Fc_ext[i] = fce if fce is not None else 0.05 * fcap6
        Fc_ret[i] = fcr if fcr is not None else Fc_ext[i]
        Fs_ratio[i] = d.static_ratio
        beta[i] = d.viscous_ns_m if d.viscous_ns_m is not None else Fc_ext[i] / 0.5
        vs[i] = d.stribeck_v
        # a floor on the viscous damping: a share of critical damping of the piston on the
        # air spring of a half-stroke chamber at 6 bar (lip seals and the air's own losses;
        # without it a light piston on a throttled spring return chatters in stick-slip)
        k_ref = GAMMA * 7e5 * a1 * a1 / (V01[i] + a1 * S[i] / 2.0)
        beta[i] = max(beta[i], d.damping_ratio * 2.0 * math.sqrt(k_ref * M[i]))
        Fg[i] = M[i] * G_ACC * math.sin(math.radians(d.mount_angle_deg))
        Fl[i] = d.f_load
        if d.kind == "single_acting":
            Fsp0[i] = d.spring_bar[0] * 1e5 * a1
            Fsp1[i] = d.spring_bar[1] * 1e5 * a1
        init_state[i] = 1.0 if d.initial == "extended" else 0.0
        y[i] = S[i] * init_state[i]
        ed = sorted(d.edges)
        # valve edges: effective at command + switching delay; each chamber's port also
        # waits for the pressure wave down its tube (docs/reference/physics.md, the dynamic model (D4))
        de = [(t + d.delay_s, u) for t, u in ed]
        drive_lists.append(de)
        cap_lists.append([(t + lt1 / d.wave_c, u) for t, u in de])
        rod_lists.append([(t + lt2 / d.wave_c, u) for t, u in de])

    drive_ev = _Edges(drive_lists, init_state)
    cap_ev = _Edges(cap_lists, init_state)
    rod_ev = _Edges(rod_lists, init_state)
    x_cap = init_state.copy(); x_rod = init_state.copy()     # spool positions seen by each port

    # chambers stacked: [cap..., rod...]
    A = np.concatenate([A1, A2])
    Vd = np.concatenate([V01, V02])
    Awt = np.concatenate([Aw_t1, Aw_t2])
    perim2 = np.concatenate([perim, perim])
    h_c2 = np.concatenate([h_cyl, h_cyl]); h_t2 = np.concatenate([h_tube, h_tube])
    Cs2 = Cs.reshape(-1); bs2 = bs.reshape(-1); ms2 = ms.reshape(-1)
    Ce2 = Ce.reshape(-1); be2 = be.reshape(-1); me2 = me.reshape(-1)
    run_c = np.concatenate([run_of_d, run_of_d])
    vent_c = np.concatenate([np.zeros(nd, dtype=bool), vent2])
    check_c = np.concatenate([check, check])
    ov2 = np.concatenate([ov, ov])
    patm_c = p_atm_r[run_c]; tamb_c = t_amb_r[run_c]; tsup_c = t_sup_r[run_c]

    # --- supplies
    sp = [r.supply for r in runs]
    mode_line = np.array([s.mode == "line" for s in sp])
    mode_droop = np.array([s.mode == "droop" for s in sp])
    p_set0 = np.array([s.p_set_abs for s in sp])
    # at most one scheduled step per run (a supply that drops at an onset), ramped over 1 s
    sched_t = np.array([s.schedule[0][0] if s.schedule else np.inf for s in sp])
    sched_p = np.array([s.schedule[0][1] if s.schedule else s.p_set_abs for s in sp])
    V_line = np.array([s.line_volume_l * 1e-3 for s in sp])
    reg_C = np.array([s.reg_C for s in sp]); reg_b = np.array([s.reg_b for s in sp]); reg_m = np.array([s.reg_m for s in sp])
    reg_band = np.array([s.reg_band_pa for s in sp])
    p_net = np.array([s.network_abs if s.network_abs else s.p_set_abs + 1.5e5 for s in sp])
    droop_k = np.array([s.droop_pa_per_nl_min for s in sp])
    droop_tau = np.array([s.droop_tau_s for s in sp])
    q_lag = np.zeros(nr)                      # droop: lagged flow, NL/min
    p_line = p_set0.copy()

    # initial chamber states: the holding chamber at supply, the other at atmosphere
    Vc = Vd + A * np.concatenate([y, S - y])
    ext0 = np.concatenate([init_state, 1.0 - init_state])
    p_c = np.where(ext0 > 0.5, p_set0[run_c], patm_c)
    p_c = np.where(vent_c, patm_c, p_c)
    Tc = tamb_c.copy()
    mc = p_c * Vc / (R_AIR * Tc)

    # --- restrictions
    rs = [(ri, x) for ri, r in enumerate(runs) for x in r.restrictions]
    nn = len(rs)
    run_n = np.array([ri for ri, _ in rs], dtype=int)
    Cn = np.array([x.C for _, x in rs]); bn = np.array([x.b for _, x in rs]); mn = np.array([x.m for _, x in rs])
    preg_n = np.array([x.p_reg_abs if x.p_reg_abs else np.inf for _, x in rs])
    always = np.array([x.edges is None for _, x in rs], dtype=bool)
    n_lists = []
    for _, x in rs:
        lst = []
        if x.edges is not None:
            lst = [(t + x.delay_s, u) for t, u in sorted(x.edges)]
        n_lists.append(lst)
    noz_ev = _Edges(n_lists, np.zeros(nn))
    x_n = np.zeros(nn)
    ramp_n = np.array([max(x.ramp_s, 1e-4) for _, x in rs])
    onset_n = np.array([x.onset_s if x.onset_s is not None else -1.0 for _, x in rs])
    stuck_n = np.array([x.stuck_on_from if x.stuck_on_from is not None else np.inf for _, x in rs])
    patm_n = p_atm_r[run_n] if nn else np.zeros(0)
    tsup_n = t_sup_r[run_n] if nn else np.zeros(0)

    # --- recording
    bin_s = runs[0].bin_s
    nbins = int(math.ceil(t_end / bin_s)) + 1
    flow_bins = np.zeros((nr, nbins))
    psup_bins = np.zeros((nr, nbins))
    steps_per_bin = bin_s / dt
    emax = drive_ev.t.shape[1]
    edge_air = np.zeros(nd * emax)
    reach = np.full((nd, emax), np.nan)
    restr_air = np.zeros(nn)
    drive_air = np.zeros(nd)
    drive_back = np.zeros(nd)

    ar_d = np.arange(nd)
    path_s = _Paths(bs2, ms2)
    path_e = _Paths(be2, me2)
    path_n = _Paths(bn, mn)
    step_x = dt / ramp
    step_n = dt / ramp_n if nn else None
    half = 0.5 - 0.5 * ov2
    inv_half = 1.0 / half
    exp = np.exp
    t = 0.0
    for step in range(nsteps):
        t = step * dt
        # supply set points (scheduled steps ramped over 1 s)
        p_set = p_set0 + (sched_p - p_set0) * _clip((t - sched_t) / 1.0, 0.0, 1.0)
        # ---- valves
        drive_ev.advance(t)
        cap_ev.advance(t)
        rod_ev.advance(t)
        x_cap += _clip(cap_ev.state - x_cap, -step_x, step_x)
        x_rod += _clip(rod_ev.state - x_rod, -step_x, step_x)
        press = np.concatenate([x_cap, 1.0 - x_rod])     # 1: the chamber is on supply
        # positive overlap: over the middle `ov` of the travel every port of the chamber is shut
        s_open = _clip((press - (1.0 - half)) * inv_half, 0.0, 1.0)
        e_open = _clip((half - press) * inv_half, 0.0, 1.0)
        s_open = np.where(vent_c, 0.0, s_open)
        e_open = np.where(vent_c, 1.0, e_open)
        if nn:
            noz_ev.advance(t)
            want = np.where(always, 1.0, noz_ev.state)
            want = np.where(t >= stuck_n, 1.0, want)
            x_n += _clip(want - x_n, -step_n, step_n)
            open_n = np.where(always & (onset_n >= 0), _clip((t - onset_n) / 0.5, 0.0, 1.0),
                              np.where(always, 1.0, x_n))
        # ---- supply pressure seen by the consumers
        p_up_r = np.where(mode_line, p_line, np.where(mode_droop, p_set - droop_k * q_lag, p_set))
        p_up = p_up_r[run_c]
        # ---- chamber flows (kg/s, + into the chamber)
        Vc = Vd + A * np.concatenate([y, S - y])
        p_c = mc * R_AIR * Tc / Vc
        Cs_eff = Cs2 * s_open
        Ce_eff = Ce2 * e_open
        qs, Gs = path_s.flow(Cs_eff, p_up, p_c, tsup_c, Tc, reverse_ok=~check_c)
        dqs_dup = Gs
        dqs_dpc = -Gs
        qe, Ge = path_e.flow(Ce_eff, p_c, patm_c, Tc, tamb_c)
        dqe_dpc = Ge
        # qe: + out of the chamber. Energy carried: inflow at the source's temperature
        ts_in = np.where(qs >= 0, tsup_c, Tc)
        te_in = np.where(qe >= 0, Tc, tamb_c)
        a_s = GAMMA * R_AIR * ts_in / Vc
        a_e = GAMMA * R_AIR * te_in / Vc
        g = a_s * qs - a_e * qe
        gp = a_s * dqs_dpc - a_e * dqe_dpc
        gL = a_s * dqs_dup
        denom = 1.0 - dt * gp
        alpha = dt * g / denom
        betaL = dt * gL / denom
        # ---- restrictions at their pressures
        if nn:
            p_up_n = p_up_r[run_n]
            regulated = preg_n < p_up_n
            pn = np.minimum(preg_n, p_up_n)
            qn, Gn = path_n.flow(Cn * np.maximum(open_n, 0.0), pn, patm_n, tsup_n, tsup_n)
            dqn_dpu = np.where(regulated | (open_n <= 0), 0.0, Gn)
        # ---- supply line pressure (linearly implicit, Schur complement over its chambers)
        dPL = np.zeros(nr)
        q_reg_eff = np.zeros(nr)
        if mode_line.any():
            xr = _clip((p_set - p_line) / reg_band, 0.0, 1.0)
            dxr = np.where((xr > 0) & (xr < 1), -1.0 / reg_band, 0.0)
            qr, dqr_du, dqr_dd = d2_massflow(reg_C, reg_b, reg_m, p_net, np.minimum(p_line, p_net * 0.9999), t_sup_r)
            # qr is per unit opening: q = x * qr
            q_reg = xr * qr
            dq_reg = dxr * qr + xr * dqr_dd
            # chambers: flow out of the line = qs; d(qs)/dPL total = dqs_dup + dqs_dpc * betaL
            w_out = np.bincount(run_c, weights=qs + dqs_dpc * alpha, minlength=nr).astype(float)
            w_slope = np.bincount(run_c, weights=dqs_dup + dqs_dpc * betaL, minlength=nr).astype(float)
            if nn:
                w_out += np.bincount(run_n, weights=qn, minlength=nr)
                w_slope += np.bincount(run_n, weights=dqn_dpu, minlength=nr)
            cap_l = V_line / (R_AIR * t_sup_r * dt)
            dPL = np.where(mode_line, (q_reg - w_out) / (cap_l - dq_reg + w_slope), 0.0)
            q_reg_eff = np.where(mode_line, q_reg + dq_reg * dPL, 0.0)
        dP = alpha + betaL * dPL[run_c]
        qs_eff = qs + dqs_dpc * dP + dqs_dup * dPL[run_c]
        qe_eff = qe + dqe_dpc * dP
        if nn:
            qn_eff = qn + dqn_dpu * dPL[run_n]
        # ---- mass and energy
        dm = dt * (qs_eff - qe_eff)
        U = mc * CV * Tc + dt * CP * (ts_in * qs_eff - te_in * qe_eff)
        mc = np.maximum(mc + dm, 1e-12)
        Tc = _clip(U / (mc * CV), 150.0, 600.0)
        # heat exchange with the walls: cylinder barrel (wetted length) and tube
        wet = np.concatenate([y, S - y])
        Acyl = perim2 * (wet + 0.005) + 2.0 * A
        G = h_c2 * Acyl + h_t2 * Awt
        Tc = tamb_c + (Tc - tamb_c) * exp(-dt * G / (mc * CV))
        p_c = mc * R_AIR * Tc / Vc
        # ---- piston
        P1 = p_c[:nd]; P2 = p_c[nd:]
        patm_d = p_atm_r[run_of_d]
        Fp = P1 * A1 - P2 * A2 - patm_d * (A1 - A2)
        Fspring = Fsp0 + (Fsp1 - Fsp0) * (y / S)
        Fnet = Fp - Fg - Fl - Fspring
        V1 = Vc[:nd]; V2 = Vc[nd:]
        kspr = GAMMA * (P1 * A1 * A1 / V1 + P2 * A2 * A2 / V2)
        moving = v != 0.0
        dirn = np.where(moving, np.sign(v), np.sign(Fnet))
        Fc = np.where(dirn > 0, Fc_ext, Fc_ret)
        Fstat = Fc * Fs_ratio
        Ff = dirn * (Fc + (Fstat - Fc) * exp(-(np.abs(v) / vs) ** 2))
        breakaway = np.abs(Fnet) > Fstat
        # no breakaway into an end stop
        breakaway &= ~((y >= S) & (Fnet > 0)) & ~((y <= 0.0) & (Fnet < 0))
        go = moving | breakaway
        vn = (v + dt * (Fnet - Ff) / M) / (1.0 + dt * beta / M + dt * dt * kspr / M)
        vn = np.where(go, vn, 0.0)
        vn = np.where(moving & (np.sign(vn) != np.sign(v)), 0.0, vn)
        yn = y + dt * vn
        hit_hi = yn >= S
        hit_lo = yn <= 0.0
        yn = _clip(yn, 0.0, S)
        vn = np.where(hit_hi | hit_lo, 0.0, vn)
        # volume change: isentropic for the step's motion
        Vn = Vd + A * np.concatenate([yn, S - yn])
        Tc = Tc * (Vc / Vn) ** (GAMMA - 1.0)
        y, v = yn, vn
        # ---- recording
        q_sup_d = qs_eff[:nd] + qs_eff[nd:]
        if record_edges:
            flat = ar_d * emax + drive_ev.ptr
            edge_air[flat] += q_sup_d * dt
            st = drive_ev.state
            k = np.maximum(drive_ev.ptr - 1, 0)
            has_edge = drive_ev.ptr > 0
            done_ext = has_edge & (st > 0.5) & (y >= 0.99 * S) & np.isnan(reach[ar_d, k])
            done_ret = has_edge & (st < 0.5) & (y <= 0.01 * S) & np.isnan(reach[ar_d, k])
            dn = done_ext | done_ret
            if dn.any():
                reach[ar_d[dn], k[dn]] = t + dt
        drive_air += q_sup_d * dt
        drive_back -= np.minimum(q_sup_d, 0.0) * dt
        qtot = np.bincount(run_c, weights=qs_eff, minlength=nr).astype(float)
        if nn:
            qtot += np.bincount(run_n, weights=qn_eff, minlength=nr)
            restr_air += qn_eff * dt
        q_meter = np.where(mode_line, q_reg_eff, qtot)
        b = int((t + 0.5 * dt) / bin_s)
        flow_bins[:, b] += q_meter * dt
        psup_bins[:, b] += p_up_r / steps_per_bin
        if mode_line.any():
            p_line = p_line + dPL
        if mode_droop.any():
            q_nl_min = q_meter / RHO_N * 60_000.0
            q_lag = q_lag + (q_nl_min - q_lag) * (dt / droop_tau)
        if trace is not None:
            trace.append((t + dt, y.copy(), v.copy(), p_c.copy()))
        if progress and step % 20000 == 0:
            progress(step, nsteps)
    simulate.last_state = {"m": mc, "T": Tc, "p": mc * R_AIR * Tc / (Vd + A * np.concatenate([y, S - y])),
                           "y": y, "V": Vd + A * np.concatenate([y, S - y])}

    out = []
    to_nl = 1000.0 / RHO_N
    di = 0; ni = 0
    for ri, r in enumerate(runs):
        nb = int(math.ceil(r.t_end / bin_s))
        res = {"flow_nl": flow_bins[ri, :nb] * to_nl, "p_supply": psup_bins[ri, :nb], "bin_s": bin_s,
               "drives": [], "restr_air_nl": []}
        for d in r.drives:
            ne = len(d.edges)
            res["drives"].append({
                "name": d.name,
                "edge_air_nl": edge_air[di * emax: di * emax + ne + 1] * to_nl,
                "reach": reach[di, :ne].copy(),
                "air_nl": drive_air[di] * to_nl,
                "pushed_back_nl": drive_back[di] * to_nl,
            })
            di += 1
        for x in r.restrictions:
            res["restr_air_nl"].append((x.name, restr_air[ni] * to_nl))
            ni += 1
        out.append(res)
    return out


# ---- stroke tests and commissioning --------------------------------------------------------

def _clone(d: DriveSpec, **kw) -> DriveSpec:
    import copy
    e = copy.copy(d)
    for k, val in kw.items():
        setattr(e, k, val)
    return e


def stroke_times(items, dt=1e-3, settle=None):
    """items: list of (DriveSpec, p_set_abs, p_atm, t_amb). Each drive strokes from its
    settled initial position (retracted) out, settles, and back. Returns a list of
    (t_extend, t_retract) from the valve's switching (command + delay) to arrival within
    1 % of the end; nan if it never arrives. All drives in one batch."""
    runs = []
    holds = []
    for d, p_set, p_atm, t_amb in items:
        hold = settle if settle else 3.0
        holds.append(hold)
        dd = _clone(d, edges=[(0.05, 1), (0.05 + hold, 0)], initial="retracted")
        runs.append(RunSpec(t_end=0.05 + 2 * hold, supply=SupplySpec(p_set_abs=p_set), drives=[dd],
                            restrictions=[], p_atm=p_atm, t_amb=t_amb, t_sup=t_amb, bin_s=0.05))
    res = simulate(runs, dt=dt)
    out = []
    for (d, *_), r, hold in zip(items, res, holds):
        reach = r["drives"][0]["reach"]
        t0 = 0.05 + d.delay_s
        out.append((reach[0] - t0, reach[1] - (t0 + hold)))
    return out


def commission(items, targets, dt=1e-3, iters=14):
    """Turn each drive's meter-out flow controls (the exhaust throttles; for a
    single-acting drive a meter-in throttle on the supply for its powered stroke) down
    until its strokes take the target times (extend, retract); a target of None leaves
    that direction open. Returns a list of DriveSpec copies with the throttles set and a
    list of the stroke times reached. Bisection on log10(C) over all drives at once."""
    n = len(items)
    lo = np.full((n, 2), -11.0)
    hi = np.full((n, 2), -6.3)
    drives = [it[0] for it in items]

    def with_throttle(d, le, lr):
        if d.kind == "single_acting":
            return _clone(d, c_meter_in=(10 ** le) if le is not None else None,
                          c_throttle=(10 ** lr if lr is not None else None, None))
        return _clone(d, c_throttle=(10 ** lr if lr is not None else None, 10 ** le if le is not None else None))

    tg = np.array([[np.nan if x is None else x for x in (tt if tt is not None else (None, None))] for tt in targets],
                  dtype=float)
    hold = 3.0      # the same test as stroke_times(): a drive's retract depends on how full the hold left it
    for _ in range(iters):
        mid = 0.5 * (lo + hi)
        cur = [with_throttle(d, None if np.isnan(tg[i, 0]) else mid[i, 0], None if np.isnan(tg[i, 1]) else mid[i, 1])
               for i, d in enumerate(drives)]
        st = stroke_times([(c,) + tuple(items[i][1:]) for i, c in enumerate(cur)], dt=dt, settle=hold)
        st = np.array(st, dtype=float)
        slow = np.where(np.isnan(st), True, st > tg)      # too slow: open the throttle (raise C)
        lo = np.where(slow, mid, lo)
        hi = np.where(slow, hi, mid)
    final = 0.5 * (lo + hi)
    out = [with_throttle(d, None if np.isnan(tg[i, 0]) else final[i, 0], None if np.isnan(tg[i, 1]) else final[i, 1])
           for i, d in enumerate(drives)]
    st = stroke_times([(c,) + tuple(items[i][1:]) for i, c in enumerate(out)], dt=dt, settle=hold)
    return out, st


# ---- the flow meter ---------------------------------------------------------------------------

def meter_log(flow_nl, bin_s, rng, *, t_start, t_len, rate_hz, tau_s, noise_frac, gain=1.0,
              reference="iso8778", clock_offset=0.0, jitter_frac=0.0, p_supply=None,
              p_atm=101_325.0, p_noise_bar=0.01, sampling="mean"):
    """A thermal-mass flow meter and its logger.

    flow_nl: air per bin (NL at ISO 8778, D3) on the machine clock. The meter responds as a
    first-order lag tau_s (exact for piecewise-constant input), each reading is the mean
    of the response over its logging interval (or the value at the reading's time with
    sampling="instant"), multiplied by gain, converted to the meter's reference (DIN 1343
    reads 0.92 as many litres, D3), plus Gaussian noise of noise_frac times the mean flow.
    Time stamps: logger clock = machine time + clock_offset, each stamp off by a uniform
    jitter of +-jitter_frac of an interval. Returns (times, flow_l_min, supply_bar_g or
    None, true_nl) where true_nl is the air through the meter over the logged window."""
    q = flow_nl / bin_s * 60.0                 # NL/min per bin
    a = math.exp(-bin_s / tau_s) if tau_s > 0 else 0.0
    # y_{k+1} = a y_k + (1 - a) q_k, and the bin's mean response (exact integral)
    yk = np.empty(len(q) + 1)
    yk[0] = q[0]
    try:
        from scipy.signal import lfilter
        yk[1:] = lfilter([1.0 - a], [1.0, -a], q, zi=[a * q[0]])[0]
    except Exception:  # pragma: no cover
        for k in range(len(q)):
            yk[k + 1] = a * yk[k] + (1.0 - a) * q[k]
    if tau_s > 0:
        mean_bin = q + (yk[:-1] - q) * (tau_s / bin_s) * (1.0 - a)
    else:
        mean_bin = q
    per = 1.0 / rate_hz
    n = int(math.floor(t_len * rate_hz + 1e-9))
    t_read = t_start + per * np.arange(1, n + 1)     # machine time of each reading (end of its interval)
    cum = np.concatenate([[0.0], np.cumsum(mean_bin) * bin_s])   # NL/min * s
    tb = np.arange(len(cum)) * bin_s
    c_end = np.interp(t_read, tb, cum)
    c_beg = np.interp(t_read - per, tb, cum)
    if sampling == "mean":
        reading = (c_end - c_beg) / per
    else:
        reading = np.interp(t_read, tb[1:], yk[1:])
    factor = gain * (DIN1343_FACTOR if reference == "din1343" else 1.0)
    reading = reading * factor
    true_cum = np.concatenate([[0.0], np.cumsum(q) * bin_s])
    true_nl = (np.interp(t_start + t_len, tb, true_cum) - np.interp(t_start, tb, true_cum)) / 60.0
    mean_flow = max(float(np.mean(reading)), 1e-6)
    reading = reading + rng.normal(0.0, noise_frac * mean_flow, size=n)
    reading = np.maximum(reading, 0.0)
    stamps = t_read + clock_offset + rng.uniform(-jitter_frac, jitter_frac, size=n) * per
    sup = None
    if p_supply is not None:
        cp = np.concatenate([[0.0], np.cumsum(p_supply) * bin_s])
        pbar = (np.interp(t_read, tb, cp) - np.interp(t_read - per, tb, cp)) / per
        sup = (pbar - p_atm) / 1e5 + rng.normal(0.0, p_noise_bar, size=n)
    return stamps, reading, sup, true_nl


# ---- self-check -------------------------------------------------------------------------------

def _selfcheck():
    p_atm = 101_325.0
    p_s = p_atm + 6e5
    T = 293.15
    print("independent physics self-check (bench/indep/physics.py)")
    print(f"  supply 6 bar(g) = {p_s/1e5:.4f} bar abs, T {T} K, normal density {RHO_N:.4f} kg/m^3")

    # 1. nozzle, steady: D2 exactly
    cn = c_orifice(1.5, 0.8)
    noz = RestrictionSpec("n", C=cn, b=0.528, m=0.5, edges=[(0.5, 1), (4.5, 0)], delay_s=0.012, ramp_s=0.01)
    noz2 = RestrictionSpec("knife", C=5e-9, b=0.25, m=0.5, p_reg_abs=p_atm + 3e5, edges=[(0.5, 1), (4.5, 0)])
    leak = RestrictionSpec("leak", C=8e-10, b=0.15, m=0.7, edges=None)
    runs = [RunSpec(t_end=5.0, supply=SupplySpec(p_set_abs=p_s), drives=[], restrictions=[x], p_atm=p_atm)
            for x in (noz, noz2, leak)]
    res = simulate(runs)
    for x, r, p_up in zip((noz, noz2, leak), res, (p_s, p_atm + 3e5, p_s)):
        q = r["flow_nl"] / r["bin_s"] * 60.0
        steady = q[int(2.0 / 0.01):int(4.0 / 0.01)].mean()
        phi, _ = d2_phi(np.array(p_atm / p_up), x.b, x.m)
        d2 = x.C * p_up * float(phi) * 60_000.0        # D2 + D3, NL/min
        print(f"  nozzle '{x.name}': steady {steady:8.3f} NL/min, D2 {d2:8.3f}, ratio {steady/d2:.5f}")

    # 2. settled slow strokes against D1
    print("  settled strokes (10 s dwell) against D1 (swept + tube at the supply, D1a/D1b + D3):")
    cases = [
        DriveSpec("32x100, 1.5 m tube", "double_acting", 32, 12, 100, 4, (1.5, 1.5)),
        DriveSpec("50x25, 6 m tube", "double_acting", 50, 20, 25, 4, (6.0, 6.0)),
        DriveSpec("20x50, 1 m tube", "double_acting", 20, 8, 50, 4, (1.0, 1.0)),
        DriveSpec("rodless 25x200", "rodless", 25, 0, 200, 4, (1.5, 1.5)),
        DriveSpec("single-acting 20x40", "single_acting", 20, 8, 40, 4, (0.8, 0.0)),
    ]
    runs = []
    for d in cases:
        d.edges = [(0.5, 1), (10.5, 0)]
        runs.append(RunSpec(t_end=20.5, supply=SupplySpec(p_set_abs=p_s), drives=[d], restrictions=[], p_atm=p_atm))
    res = simulate(runs)
    for d, r in zip(cases, res):
        ea = r["drives"][0]["edge_air_nl"]
        for k, direction in ((1, "extend"), (2, "retract")):
            d1 = d1_stroke_nl(d.bore_mm, d.rod_mm, d.stroke_mm, d.tube_id_mm, d.tube_len_m[k - 1], p_s, T,
                              d.kind, direction)
            if d1 <= 0:
                continue
            a1, a2 = d.areas()
            area = a1 if k == 1 else a2
            at = math.pi * (d.tube_id_mm * 1e-3) ** 2 / 4
            vt = d.tube_len_m[k - 1] * at
            vint = area * d.dead_len_mm[k - 1] * 1e-3
            expect = d1 - (vt + vint) * p_atm / P0 * 1000 + vint * p_s / P0 * 1000
            st = r["drives"][0]["reach"][k - 1] - (0.5 + (k - 1) * 10 + d.delay_s)
            print(f"    {d.name:22s} {direction:7s}: {ea[k]:.4f} NL, D1 {d1:.4f}, ratio {ea[k]/d1:.3f}"
                  f" (section 7: {expect/d1:.3f}), stroke {st*1000:.0f} ms")

    # 3. short dwells: incomplete exhaust and top-up
    print("  the same 32x100 drive cycled with short dwells (air per cycle / D1 per cycle):")
    d = cases[0]
    d1c = sum(d1_stroke_nl(32, 12, 100, 4, 1.5, p_s, T, "double_acting", x) for x in ("extend", "retract"))
    runs = []
    dwells = (0.25, 0.4, 0.7, 1.5, 4.0)
    for dw in dwells:
        dd = _clone(d, edges=[])
        tt = 0.5
        edges = []
        for _ in range(6):
            edges += [(tt, 1), (tt + dw, 0)]
            tt += 2 * dw
        dd.edges = edges
        runs.append(RunSpec(t_end=tt + 0.1, supply=SupplySpec(p_set_abs=p_s), drives=[dd], restrictions=[], p_atm=p_atm))
    res = simulate(runs)
    for dw, r in zip(dwells, res):
        ea = r["drives"][0]["edge_air_nl"]
        cyc = ea[5:11].sum() / 3.0
        print(f"    dwell {dw:4.2f} s: {cyc:.4f} NL per cycle, ratio {cyc/d1c:.3f}")

    # 4. heat transfer: the same drive with slow and fast thermal exchange, and a short dwell
    print("  heat transfer (air of the extend stroke, 0.4 s dwell, against 10 s dwell):")
    for h in (10.0, 30.0, 100.0):
        rr = []
        for dw in (0.4, 10.0):
            dd = _clone(d, h_cyl=h, h_tube=2 * h, edges=[(0.5, 1), (0.5 + dw, 0)])
            rr.append(RunSpec(t_end=0.6 + dw, supply=SupplySpec(p_set_abs=p_s), drives=[dd], restrictions=[], p_atm=p_atm))
        res = simulate(rr)
        a = [x["drives"][0]["edge_air_nl"][1] for x in res]
        print(f"    h {h:5.1f} W/m2K: {a[0]:.4f} / {a[1]:.4f} NL = {a[0]/a[1]:.3f}")

    # 5. time-step convergence
    print("  time step (32x100 extend: air NL, stroke ms):")
    for dt in (2e-3, 1e-3, 0.5e-3, 0.25e-3):
        dd = _clone(d, edges=[(0.5, 1), (3.5, 0)], c_throttle=(3e-9, 3e-9))
        r = simulate([RunSpec(t_end=6.5, supply=SupplySpec(p_set_abs=p_s), drives=[dd], restrictions=[], p_atm=p_atm)], dt=dt)[0]
        st = (r["drives"][0]["reach"][0] - 0.5 - d.delay_s) * 1000
        print(f"    dt {dt*1000:5.2f} ms: extend {r['drives'][0]['edge_air_nl'][1]:.4f} NL, stroke {st:.1f} ms")

    # 6. shared supply: the same two drives with and without a line
    print("  shared supply (two drives, the second holding while the first strokes):")
    a = DriveSpec("A", "double_acting", 50, 20, 100, 4, (1.5, 1.5), edges=[(1.0, 1), (3.0, 0), (5.0, 1), (7.0, 0)])
    bdr = DriveSpec("B", "double_acting", 40, 16, 50, 4, (1.5, 1.5), initial="extended", edges=[])
    res = []
    for mode in ("ideal", "line"):
        sp = SupplySpec(p_set_abs=p_s, mode=mode, line_volume_l=0.1, reg_C=6e-9)
        res.append(simulate([RunSpec(t_end=9.0, supply=sp, drives=[_clone(a), _clone(bdr)], restrictions=[], p_atm=p_atm)])[0])
    for mode, r in zip(("ideal", "line"), res):
        q = r["flow_nl"] / r["bin_s"] * 60
        print(f"    {mode:5s}: total {r['flow_nl'].sum():.4f} NL, peak {q.max():6.1f} NL/min,"
              f" min supply {r['p_supply'].min()/1e5 - p_atm/1e5:.2f} bar(g), A extend reached at"
              f" {r['drives'][0]['reach'][0]:.3f} s, B pushed back {r['drives'][1]['pushed_back_nl']:.4f} NL"
              f" and took {r['drives'][1]['air_nl'] + r['drives'][1]['pushed_back_nl']:.4f} NL again")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--selfcheck", action="store_true", help="print the validation ratios")
    args = ap.parse_args(argv)
    if args.selfcheck:
        _selfcheck()
        return 0
    ap.print_help()
    return 0


if __name__ == "__main__":
    sys.exit(main())
