"""The physics of the virtual plant as plain functions (docs/reference/physics.md: restrictions,
dynamic model).

Pressures are absolute, in pascal; temperatures in kelvin; mass flows in kg/s; lengths in
metres; forces in newtons. Functions take floats: the group's right-hand side calls them
once per drive and chamber, which for the few drives of a group is faster than numpy on
tiny arrays.
"""
from __future__ import annotations

import math

from .units import GAMMA, P0_PA, R_J_KG_K, RHO0_KG_M3, T0_K

CP_J_KG_K = GAMMA * R_J_KG_K / (GAMMA - 1.0)
G_M_S2 = 9.80665
SOUND_M_S = 343.0          # speed of sound at 20 degC: the pressure wave's speed in a tube
# Near r = 1 the flow function of D2 falls as sqrt(1 - r): its slope is infinite, so the
# pressure equation would be infinitely stiff there. Above R_LAMINAR (pressures within
# 0.5 % of each other) the flow is taken linear in (1 - r), matching D2 at R_LAMINAR (the
# flow there is laminar anyway). It changes only how fast the last 0.5 % of a fill or an
# exhaust goes (by at most D2's flow at R_LAMINAR, about 12 % of choked for b = 0.3),
# not where it ends, so not how much air flows.
R_LAMINAR = 0.995


def phi_with_laminar_tail(r: float, b: float, m: float, a: float = 1.0) -> float:
    """(D2) the flow function of :func:`.flow.phi` for one ``r = P_d/P_u`` (0 <= r),
    with the laminar tail above ``R_LAMINAR * a`` (see module note). A scalar function of
    its own because the chambers' equations call it per step, where numpy's overhead on
    one value costs more than the arithmetic."""
    if r <= b:
        return 1.0
    if r >= a:
        return 0.0
    r_lam = R_LAMINAR * a
    x = (min(r, r_lam) - b) / (a - b)
    sub = (1.0 - x * x) ** m if x < 1.0 else 0.0
    return sub if r <= r_lam else sub * (a - r) / (a - r_lam)


def signed_mass_flow_kg_s(C: float, b: float, m: float, p_a_pa: float, t_a_k: float,
                          p_b_pa: float, t_b_k: float, a: float = 1.0) -> float:
    """(D2) mass flow from side a to side b through a restriction (C, b, m, a), negative
    when the air flows from b to a: ``qm = rho0 C P_u sqrt(T0/T_u) phi(P_d/P_u)`` with
    the upstream side whichever pressure is higher (:func:`.flow.mass_flow_kg_s` with
    the laminar tail, for one value)."""
    if p_a_pa >= p_b_pa:
        return RHO0_KG_M3 * C * p_a_pa * math.sqrt(T0_K / t_a_k) * phi_with_laminar_tail(
            p_b_pa / p_a_pa, b, m, a)
    return -RHO0_KG_M3 * C * p_b_pa * math.sqrt(T0_K / t_b_k) * phi_with_laminar_tail(
        p_a_pa / p_b_pa, b, m, a)


def chamber_rates(p_pa, t_k, v_m3, dv_m3_s, q_net_kg_s, h_in_w, q_heat_w):
    """(D4) pressure and temperature rates of a chamber of ideal gas:

    ``dP/dt = (gamma-1)/V (H + Q) - gamma P/V dV/dt`` with H the net enthalpy flow
    (cp * sum of inflows at their source temperature minus outflows at the chamber's) and
    Q the heat from the walls; D4 writes ``(gamma-1) cp = gamma R``. The temperature
    follows from ``m = PV/(RT)``: ``dT/dt = T (dP/P + dV/V - dm/m)``. The polytropic
    index is what comes out of this, not an input."""
    dp = (GAMMA - 1.0) / v_m3 * (h_in_w + q_heat_w) - GAMMA * p_pa / v_m3 * dv_m3_s
    mass_kg = p_pa * v_m3 / (R_J_KG_K * t_k)
    dt = t_k * (dp / p_pa + dv_m3_s / v_m3 - q_net_kg_s / mass_kg)
    return dp, dt


def friction_n(v_m_s: float, direction: float, F_coulomb_n: float, F_static_n: float,
               v_stribeck_m_s: float, beta_ns_m: float, delta: float = 2.0) -> float:
    """(docs/reference/physics.md: dynamic model, Stribeck) friction of a sliding piston against its
    motion: ``sgn(v) (F_c + (F_s - F_c) exp(-(|v|/v_s)^delta)) + beta v``; ``direction`` gives the
    sign while v passes through 0 at a breakaway."""
    return direction * (F_coulomb_n + (F_static_n - F_coulomb_n)
                        * math.exp(-(abs(v_m_s) / v_stribeck_m_s) ** delta)) + beta_ns_m * v_m_s


def mass_to_nl(mass_kg):
    """Normal litres (ISO 8778 reference, docs/reference/physics.md: reference conditions) of a
    mass of air."""
    return mass_kg / RHO0_KG_M3 * 1000.0


def nl_min_to_kg_s(flow_nl_min):
    return flow_nl_min / 60_000.0 * RHO0_KG_M3


def air_mass_kg(p_pa, v_m3, t_k):
    return p_pa * v_m3 / (R_J_KG_K * t_k)


def tube_transit_s(length_m: float) -> float:
    """The time a pressure wave needs to cross a tube (docs/reference/physics.md: dynamic
    model: L_t / c)."""
    return length_m / SOUND_M_S


def series_conductance(C1, b1, C2, b2):
    """(docs/reference/physics.md: restrictions, Eckersten) two restrictions in series:
    ``1/C^3 = 1/C1^3 + 1/C2^3``, ``1 - b = C^2 ((1 - b1)/C1^2 + (1 - b2)/C2^2)``."""
    C = (C1 ** -3 + C2 ** -3) ** (-1.0 / 3.0)
    b = 1.0 - C * C * ((1.0 - b1) / C1 ** 2 + (1.0 - b2) / C2 ** 2)
    return C, b


__all__ = ["CP_J_KG_K", "G_M_S2", "P0_PA", "R_LAMINAR", "SOUND_M_S", "air_mass_kg",
           "chamber_rates", "friction_n", "signed_mass_flow_kg_s", "mass_to_nl",
           "phi_with_laminar_tail",
           "series_conductance", "tube_transit_s"]
