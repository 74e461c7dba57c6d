"""Units and reference conditions: the one place their numbers are written.

Normal litres are ISO 8778 ("ANR") litres: air at T0 = 293.15 K and P0 = 100 kPa, rho0 =
1.185 kg/m^3 (docs/reference/physics.md: reference conditions). The standard atmosphere
(101.325 kPa) is the default ambient pressure; gauge pressures are above it.
"""
from __future__ import annotations

T0_K = 293.15               # ISO 8778 reference temperature
P0_PA = 100_000.0           # ISO 8778 reference pressure
RHO0_KG_M3 = 1.185          # air at the reference condition
R_J_KG_K = 287.05           # specific gas constant of air
GAMMA = 1.4                 # ratio of specific heats of air
P_ATM_PA = 101_325.0        # the standard atmosphere
P_ATM_KPA = P_ATM_PA / 1e3
PA_PER_BAR = 100_000.0
ZERO_C_K = 273.15
CFM_M3_MIN = 0.028316846592          # one cubic foot per minute, in m^3/min
BAR_PER_PSI = 0.0689476


def bar_g_to_pa(p_bar_g: float, atmosphere_kpa: float = P_ATM_KPA) -> float:
    """Absolute pressure (Pa) of a gauge pressure in bar over ``atmosphere_kpa``."""
    return p_bar_g * PA_PER_BAR + atmosphere_kpa * 1e3


def pa_to_bar_g(p_pa, atmosphere_pa: float = P_ATM_PA):
    """Gauge pressure in bar of an absolute pressure (Pa)."""
    return (p_pa - atmosphere_pa) / PA_PER_BAR


def celsius_to_k(t_c: float) -> float:
    return t_c + ZERO_C_K
