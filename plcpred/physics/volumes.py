"""Free-air volume per stroke of an active consumer (docs/reference/physics.md D1a, D1b), stated at
the reference condition (section 1).

D1 gives the free air at atmospheric pressure: the swept volume plus the tube dead volume
between valve and port, filled isothermally to the absolute supply pressure,
``V_free = V_geom * P_s / P_atm``. At the reference condition (P0 = 100 kPa, T0 = 293.15 K)
the same air is ``V_ref = V_geom * (P_s / P0) * (T0 / T_s)``, with T_s the supply
temperature (the machine's ``ambient_c``). The thesis' per-stroke table uses P_atm instead
of P0, so its litres are ``P0 / P_atm`` (1.3 %) smaller than these normal litres.

Areas by kind (D1, "rodless and double-rod cylinders use the same area both ways"):

| kind | extend (cap side) | retract (rod side) |
|---|---|---|
| double_acting, single_acting | pi D^2/4 | pi (D^2 - d^2)/4 (single-acting: no air) |
| double_rod | pi (D^2 - d^2)/4 | pi (D^2 - d^2)/4 |
| rodless, semi_rotary, gripper | pi D^2/4 | pi D^2/4 (``stroke_mm``: the swept volume's stroke) |
"""
from __future__ import annotations

import math

from .units import P0_PA, T0_K


def swept_areas_mm2(kind: str, bore_mm: float, rod_mm: float = 0.0) -> tuple[float, float]:
    """(extend, retract) piston areas in mm^2."""
    full = math.pi * bore_mm ** 2 / 4.0
    annulus = math.pi * (bore_mm ** 2 - (rod_mm or 0.0) ** 2) / 4.0
    if kind == "double_rod":
        return annulus, annulus
    if kind in ("rodless", "semi_rotary", "gripper"):
        return full, full
    return full, annulus


def stroke_volume_nl(area_mm2: float, stroke_mm: float, tube_length_m: float,
                     tube_id_mm: float, supply_pa: float, supply_temp_k: float = T0_K) -> float:
    """(D1a/D1b) normal litres to fill one chamber and its tube from the valve:
    ``(s * A + L_t * pi d_t^2 / 4) * (P_s / P0) * (T0 / T_s)``."""
    swept_mm3 = area_mm2 * stroke_mm
    tube_mm3 = tube_length_m * 1000.0 * math.pi * tube_id_mm ** 2 / 4.0
    geom_l = (swept_mm3 + tube_mm3) * 1e-6
    return geom_l * (supply_pa / P0_PA) * (T0_K / supply_temp_k)


def consumer_stroke_volumes_nl(consumer, supply_pa: float, supply_temp_k: float = T0_K
                               ) -> tuple[float, float]:
    """(extend, retract) normal litres per stroke of a cylinder-like consumer of the
    machine file. A single-acting cylinder's spring stroke takes no air (D1)."""
    a_ext, a_ret = swept_areas_mm2(consumer.kind, consumer.bore_mm, consumer.rod_mm or 0.0)
    tube_id = consumer.tube_id_mm or 0.0
    l_cap, l_rod = consumer.tube_length_m
    v_ext = stroke_volume_nl(a_ext, consumer.stroke_mm, l_cap, tube_id, supply_pa,
                             supply_temp_k)
    if consumer.kind == "single_acting":
        return v_ext, 0.0
    v_ret = stroke_volume_nl(a_ret, consumer.stroke_mm, l_rod, tube_id, supply_pa,
                             supply_temp_k)
    return v_ext, v_ret


def swept_volumes_nl(consumer, supply_pa: float, atmosphere_pa: float,
                     supply_temp_k: float = T0_K) -> tuple[tuple, tuple]:
    """((cap, rod) D1 normal litres of the swept volumes alone, (cap, rod) the air they
    hold above atmosphere at supply): what a stroke cut short does not open, and what a
    chamber a cut stroke left open still holds (the ``partial_strokes`` option). A
    single-acting cylinder's spring side takes no air."""
    a_ext, a_ret = swept_areas_mm2(consumer.kind, consumer.bore_mm, consumer.rod_mm or 0.0)
    if consumer.kind == "single_acting":
        a_ret = 0.0
    d1 = tuple(stroke_volume_nl(a, consumer.stroke_mm, 0.0, 0.0, supply_pa, supply_temp_k)
               for a in (a_ext, a_ret))
    held = tuple(held_air_nl(a * consumer.stroke_mm / 1000.0, supply_pa, atmosphere_pa,
                             supply_temp_k) for a in (a_ext, a_ret))
    return d1, held


INNER_DEAD_STROKE_MM = 1.0   # a cylinder's own dead volume when not given: 1 mm of stroke


def inner_dead_volumes_cm3(consumer) -> tuple[float, float]:
    """(cap, rod) cm^3 of dead volume inside the cylinder, beyond its tube (end caps,
    ports, cushions): the machine file's ``dead_volume_cm3``, else each chamber's swept
    area times INNER_DEAD_STROKE_MM (the plant's rule too). D1 leaves it out."""
    given = (getattr(consumer, "plant", None) or {}).get("dead_volume_cm3")
    if given is not None:
        return tuple(given) if isinstance(given, (tuple, list)) else (given, given)
    a_ext, a_ret = swept_areas_mm2(consumer.kind, consumer.bore_mm, consumer.rod_mm or 0.0)
    return (a_ext * INNER_DEAD_STROKE_MM / 1000.0, a_ret * INNER_DEAD_STROKE_MM / 1000.0)


def held_air_nl(volume_cm3: float, supply_pa: float, atmosphere_pa: float,
                supply_temp_k: float = T0_K) -> float:
    """Normal litres a dead volume of ``volume_cm3`` at supply pressure holds above
    atmospheric pressure (docs/reference/physics.md: what D4 adds):
    ``V_dead * (P_s - P_atm) / P0 * T0 / T_s``."""
    return volume_cm3 * 1e-3 * (supply_pa - atmosphere_pa) / P0_PA * (T0_K / supply_temp_k)


def dead_fill_volumes_nl(consumer, supply_pa: float, atmosphere_pa: float,
                         supply_temp_k: float = T0_K) -> tuple[float, float]:
    """(cap, rod) normal litres that a chamber's dead volume (its tube from the valve and
    the cylinder's own dead volume, :func:`inner_dead_volumes_cm3`) holds above
    atmospheric pressure when it is at supply pressure (:func:`held_air_nl`): what an
    exhaust cut short leaves for the next fill (the ``exhaust_tau_s`` option of the air
    model)."""
    tube_id = consumer.tube_id_mm or 0.0
    area_mm2 = math.pi * tube_id ** 2 / 4.0
    inner_cm3 = inner_dead_volumes_cm3(consumer)
    return tuple(held_air_nl(length_m * area_mm2 + inner, supply_pa, atmosphere_pa,
                             supply_temp_k)
                 for length_m, inner in zip(consumer.tube_length_m, inner_cm3))
