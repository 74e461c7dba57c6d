"""A drive's physical parameters: what the machine file gives, and documented defaults for
what catalogues do not (docs/reference/physics.md: dynamic model).

Defaults (each overridable by the key named):

- **Flow paths** (``supply_C``/``exhaust_C`` with ``_b``, ``_m``, a number or [cap, rod]):
  the valve and the tube in series act like a sharp orifice of the tube's bore with an
  overall discharge coefficient of 0.6 (D2's orifice form), b = 0.3, m = 0.5. Without a
  tube the valve's orifice is taken as 0.2 x bore (2-12 mm), the usual valve size for a
  bore. A 4 mm tube gives C = 1.5e-8 m^3/(s Pa); the thesis measured 0.9-1.8e-8 for its
  4 mm circuits (docs/reference/physics.md: figures).
- **Dead volume**: the tube (valve to port) plus ``dead_volume_cm3`` inside the cylinder
  (default: 1 mm of stroke over the piston area, the ports and cushions).
- **Moving mass** (``moving_mass_kg``): an aluminium piston 0.4 x bore thick and a steel
  rod as long as the stroke plus a bore; the payload (``payload_kg``) adds to it, and
  ``mount_angle_deg`` (0 horizontal, 90 extending straight up) adds its weight's share.
- **Friction** (``friction_coulomb_n``, ``friction_static_n``, ``friction_viscous_ns_m``,
  ``stribeck_velocity_m_s``, each a number or [extending, retracting]: seals rub
  differently each way): Coulomb friction 4 % of the cap side's force at 6 bar gauge
  (seals of standard cylinders: 3-6 %), breakaway 1.5 x Coulomb, Stribeck velocity
  0.02 m/s, viscous friction equal to Coulomb at 1 m/s.
- **Spring** of a single-acting cylinder (``spring_n`` = [retracted, extended]): the force
  of 0.5 and 1.0 bar on the piston, so the cylinder needs about 1.2 bar gauge to extend.
- **Heat transfer** (``heat_transfer_w_m2k``): 30 W/(m^2 K) between the air and walls at
  ambient temperature, which gives the 0.3-3 s thermal time constants of docs/reference/physics.md
  section 7 for bores of 16-63 mm.
- **Valve**: switching delay ``switch_delay_s`` (machine file), an optional linear ramp of
  the flow areas over ``switch_ramp_s``, and the pressure wave's transit time L/c down each
  tube.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from .chamber import G_M_S2, tube_transit_s
from .flow import orifice_conductance
from .volumes import inner_dead_volumes_cm3, swept_areas_mm2

SLOT_PRESSURE_PA = 6e5          # the "6 bar" friction is stated at
ALUMINIUM_KG_M3, STEEL_KG_M3 = 2700.0, 7850.0


@dataclass(frozen=True)
class DriveParams:
    """One drive as the plant sees it (SI units). Chamber 1 is the cap end (filled to
    extend), chamber 2 the rod end."""
    name: str
    kind: str
    stroke_m: float
    area1_m2: float             # pressure on chamber 1 pushes out
    area2_m2: float             # pressure on chamber 2 pushes in
    rod_area_m2: float          # atmosphere on the rod's outer end pushes in
    dead1_m3: float
    dead2_m3: float
    tube1_m: float
    tube2_m: float
    wall1_m2: float             # tube wall area (the barrel's follows the stroke)
    wall2_m2: float
    bore_m: float
    C_supply: tuple[float, float]
    b_supply: tuple[float, float]
    m_supply: tuple[float, float]
    C_exhaust: tuple[float, float]
    b_exhaust: tuple[float, float]
    m_exhaust: tuple[float, float]
    mass_kg: float
    load_n: float               # constant force against extension (gravity)
    F_coulomb_n: tuple[float, float]    # (extending, retracting): seals differ by direction
    F_static_n: tuple[float, float]
    beta_ns_m: tuple[float, float]
    v_stribeck_m_s: tuple[float, float]
    spring_n: tuple[float, float]   # (at retracted, at extended), against extension
    vented2: bool               # single-acting: the rod end breathes atmosphere
    delay_s: float
    ramp_s: float
    heat_w_m2k: float
    check_valve: bool
    bistable: bool
    initial_extended: bool

    @property
    def transit_s(self) -> tuple[float, float]:
        return tube_transit_s(self.tube1_m), tube_transit_s(self.tube2_m)


def _pair(v, default):
    if v is None:
        return (default, default) if not isinstance(default, tuple) else default
    return tuple(v) if isinstance(v, (tuple, list)) else (v, v)


def default_path_conductance(consumer) -> float:
    """C of a drive's valve-and-tube path when not given (module note)."""
    d_mm = consumer.tube_id_mm or min(12.0, max(2.0, 0.2 * consumer.bore_mm))
    return orifice_conductance(d_mm, 0.6)


def drive_params(consumer, line_check_valves: bool = False) -> DriveParams:
    """A machine file's cylinder-like consumer as :class:`DriveParams`."""
    p = consumer.plant
    kind = consumer.kind
    bore_m = consumer.bore_mm / 1000.0
    rod_mm = consumer.rod_mm or 0.0
    a_ext_mm2, a_ret_mm2 = swept_areas_mm2(kind, consumer.bore_mm, rod_mm)
    area1, area2 = a_ext_mm2 * 1e-6, a_ret_mm2 * 1e-6
    rod_area = math.pi * (rod_mm / 1000.0) ** 2 / 4.0 if kind in (
        "double_acting", "single_acting") else 0.0
    stroke_m = consumer.stroke_mm / 1000.0
    tube_area = math.pi * ((consumer.tube_id_mm or 0.0) / 1000.0) ** 2 / 4.0
    l1, l2 = consumer.tube_length_m
    inner1, inner2 = (v * 1e-6 for v in inner_dead_volumes_cm3(consumer))
    c_default = default_path_conductance(consumer)
    mass = p.get("moving_mass_kg")
    if mass is None:
        mass = (ALUMINIUM_KG_M3 * math.pi * bore_m ** 2 / 4.0 * 0.4 * bore_m
                + STEEL_KG_M3 * rod_area * (stroke_m + bore_m))
        if kind in ("rodless", "semi_rotary", "gripper"):
            mass *= 3.0  # a carriage, vane or jaws instead of a rod
    mass += p.get("payload_kg", 0.0)
    load = mass * G_M_S2 * math.sin(math.radians(p.get("mount_angle_deg", 0.0)))
    fc = _pair(p.get("friction_coulomb_n"), 0.04 * area1 * SLOT_PRESSURE_PA)
    fs = _pair(p.get("friction_static_n"), tuple(1.5 * x for x in fc))
    fc = tuple(min(c, s) for c, s in zip(fc, fs))
    spring = (0.0, 0.0)
    if kind == "single_acting":
        spring = _pair(p.get("spring_n"), (0.5e5 * area1, 1.0e5 * area1))
    tube_id = (consumer.tube_id_mm or 0.0) / 1000.0
    return DriveParams(
        name=consumer.name, kind=kind, stroke_m=stroke_m,
        area1_m2=area1, area2_m2=area2, rod_area_m2=rod_area,
        dead1_m3=l1 * tube_area + inner1, dead2_m3=l2 * tube_area + inner2,
        tube1_m=l1, tube2_m=l2,
        # walls: the tube's, the piston and head faces, and the inner dead volume's as a
        # cube's (6 V^(2/3); only matters for a large one, a tank modelled as a drive)
        wall1_m2=math.pi * tube_id * l1 + 2 * area1 + 6 * inner1 ** (2 / 3),
        wall2_m2=math.pi * tube_id * l2 + 2 * area2 + 6 * inner2 ** (2 / 3),
        bore_m=bore_m,
        C_supply=_pair(p.get("supply_C"), c_default), b_supply=_pair(p.get("supply_b"), 0.3),
        m_supply=_pair(p.get("supply_m"), 0.5),
        C_exhaust=_pair(p.get("exhaust_C"), c_default),
        b_exhaust=_pair(p.get("exhaust_b"), 0.3), m_exhaust=_pair(p.get("exhaust_m"), 0.5),
        mass_kg=max(mass, 1e-3), load_n=load,
        F_coulomb_n=fc, F_static_n=fs,
        beta_ns_m=_pair(p.get("friction_viscous_ns_m"), tuple(x / 1.0 for x in fc)),
        v_stribeck_m_s=_pair(p.get("stribeck_velocity_m_s"), 0.02),
        spring_n=spring, vented2=kind == "single_acting",
        delay_s=consumer.switch_delay_s or 0.0, ramp_s=p.get("switch_ramp_s", 0.0),
        heat_w_m2k=p.get("heat_transfer_w_m2k", 30.0),
        check_valve=p.get("check_valve", line_check_valves),
        bistable=consumer.bistable, initial_extended=consumer.initial == "extended")
