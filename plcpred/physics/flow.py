"""Flow through restrictions: the extended ISO 6358 equation (docs/reference/physics.md D2), the
volumetric flow at the reference condition (D3) and the orifice form for nozzles whose
sonic conductance is not known.

Pressures here are absolute, in pascal, unless a name says otherwise; the reference
condition (ISO 8778) is in :mod:`.units`.
"""
from __future__ import annotations

import math

import numpy as np

from .units import GAMMA, R_J_KG_K, RHO0_KG_M3, T0_K

# sqrt(gamma/R * (2/(gamma+1))^((gamma+1)/(gamma-1))), the choked orifice constant
_ORIFICE_K = math.sqrt(GAMMA / R_J_KG_K * (2 / (GAMMA + 1)) ** ((GAMMA + 1) / (GAMMA - 1)))


def phi(pressure_ratio, b: float, m: float = 0.5, a: float = 1.0):
    """The flow function of D2 for ``r = P_d / P_u``: 1 when choked (r <= b),
    ``[1 - ((r - b)/(a - b))^2]^m`` for b < r < a, 0 from the cracking ratio a on."""
    r = np.asarray(pressure_ratio, dtype=float)
    x = np.clip((r - b) / (a - b), 0.0, 1.0)
    out = np.where(r <= b, 1.0, (1.0 - x * x) ** m)
    out = np.where(r >= a, 0.0, out)
    return out if out.ndim else float(out)


def mass_flow_kg_s(C_m3_s_pa: float, b: float, m: float, a: float, p_up_pa, p_down_pa,
                   t_up_k: float = T0_K, flow_model: str = "iso6358"):
    """(D2) ``qm = rho0 * C * P_u * sqrt(T0/T_u) * phi(P_d/P_u)``; with
    ``flow_model="choked"`` phi = 1 (the linear model)."""
    p_up = np.asarray(p_up_pa, dtype=float)
    f = 1.0 if flow_model == "choked" else phi(np.asarray(p_down_pa) / p_up, b, m, a)
    return RHO0_KG_M3 * C_m3_s_pa * p_up * math.sqrt(T0_K / t_up_k) * f


def flow_nl_min(C_m3_s_pa: float, b: float, m: float, a: float, p_up_pa, p_down_pa,
                t_up_k: float = T0_K, flow_model: str = "iso6358"):
    """(D2, D3) volumetric flow at the reference condition, normal litres per minute:
    ``q = qm / rho0``."""
    qm = mass_flow_kg_s(C_m3_s_pa, b, m, a, p_up_pa, p_down_pa, t_up_k, flow_model)
    return qm / RHO0_KG_M3 * 60_000.0


def orifice_conductance(orifice_mm: float, Cd: float) -> float:
    """The sonic conductance (m^3/(s Pa)) equivalent to a sharp orifice of diameter ``orifice_mm``
    and discharge coefficient ``Cd`` (docs/reference/physics.md: restrictions, orifice form: ``qm =
    Cd * A * P_u / sqrt(T_u) * K``; matching D2 when choked gives ``C = Cd * A * K / (rho0 *
    sqrt(T0))``)."""
    area_m2 = math.pi * (orifice_mm / 1000.0) ** 2 / 4.0
    return Cd * area_m2 * _ORIFICE_K / (RHO0_KG_M3 * math.sqrt(T0_K))
