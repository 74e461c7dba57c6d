"""Compressor and receiver sizing from a demand profile (docs/reference/physics.md: energy).

* **Design flow** of the compressor: the mean demand plus an allowance (default 10 %).
  Compressors are sized for the average, receivers and lines for the peaks.
* **Receiver**: when demand exceeds the design flow the receiver supplies the difference
  and its pressure falls; when demand is below it the compressor refills it (never past
  full). The largest cumulative deficit over the horizon,
  ``max_t [D(t) - min_{s<=t} D(s)]`` with ``D(t) = integral (q - Q_design) dt``, sets the
  volume that keeps the pressure within the band dP: ``V = deficit_NL * P0 / dP``
  (normal litres are at P0 = 100 kPa).
* **Energy**: ``E = q_avg * SEC * hours / efficiency`` with the specific energy SEC in kWh per
  normal m^3; cost = E * price. (E2) With a production calendar the year's air is
  ``q_avg * hours + q_idle * (8760 h - hours)``: the supply stays pressurised, so leaks
  (and blowers the program leaves on, when the calendar says the machine stays on) run
  all year. SEC defaults to the isothermal work of compressing a normal
  m^3 from the atmosphere to the supply pressure over the compressor's isothermal
  efficiency (:func:`specific_energy_kwh_per_nm3`), 0.1 kWh/Nm^3 at 7 bar gauge (the
  published 0.30-0.35 kW per l/s), so that a lower supply pressure saves energy twice:
  less air (D1, D2) and less work per normal m^3.
* **Per cycle**: with a steady cycle (:mod:`~plcpred.air.cycles`) the cycle time and the
  air per cycle, which do not depend on the horizon.
* **Idle air**: air used while the machine waits: no cylinder is moving and, given the
  machine's outputs, they are in the state it waits in (every output off but those it
  never switches off, :func:`~plcpred.air.cycles.rest_mask`: blow-off within a cycle is
  productive, a blower the program leaves on while waiting is not), as a share of the
  total, split into leaks and blowers left on (the non-productive air of the published
  case study); with ``idle_after_s`` the machine must also have been still that long.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from ..machine import HOURS_PER_YEAR
from ..physics.units import CFM_M3_MIN, P0_PA, P_ATM_KPA, PA_PER_BAR
from .cycles import cycles_of, last_switch_s, rest_mask

DEFAULT_ALLOWANCE = 0.10
DEFAULT_BAND_BAR = 1.0
DEFAULT_SEC_KWH_NM3 = 0.1      # at 7 bar gauge, the published figure
# (E1) the isothermal efficiency that makes SEC(7 bar g) = DEFAULT_SEC_KWH_NM3 with the
# ISO 8778 normal m^3 (P0 = 100 kPa) and a 101.325 kPa atmosphere: 0.0574 / 0.1
ISOTHERMAL_EFFICIENCY = P0_PA * math.log(801.325 / 101.325) / 3.6e6 / DEFAULT_SEC_KWH_NM3
DEFAULT_HOURS = 4000.0      # two shifts, about 250 days
DEFAULT_PRICE = 0.15        # per kWh, in the user's currency
STOPS_EARLY = 0.8           # valves still after this share of the horizon: a warning


@dataclass
class Sizing:
    mean_l_min: float
    peak_l_min: float
    peak_1s_l_min: float
    peak_1min_l_min: float
    p95_l_min: float
    design_flow_l_min: float
    allowance: float
    deficit_nl: float
    deficit_at_s: float
    band_bar: float
    receiver_l: float
    energy_kwh_per_year: float
    cost_per_year: float
    hours_per_year: float
    sec_kwh_per_nm3: float
    price_per_kwh: float
    total_nl: float
    active_nl: float
    passive_nl: float
    leak_nl: float
    idle_nl: float
    idle_share: float
    horizon_s: float
    dt_s: float
    # the steady cycle (plcpred.air.cycles), None when the machine has none
    cycle_source: str | None = None
    cycle_s: float | None = None
    nl_per_cycle: float | None = None
    cycles_per_hour: float | None = None
    warnings: list = field(default_factory=list)
    currency: str = ""              # what the price and the cost are in (EUR, USD, ...)
    # a year as the machine file's [calendar] has it: hours_per_year are production hours,
    # and the rest of the 8,760 h the supply stays pressurised (leaks, blowers left on)
    idle_hours_per_year: float = 0.0
    idle_flow_l_min: float = 0.0
    air_nm3_per_year: float = 0.0
    # the idle air split: leaks, and nozzles / blowers left on while nothing moves
    idle_leak_nl: float = 0.0
    idle_blowers_nl: float = 0.0
    sec_basis: str = ""             # where the specific energy comes from

    def to_dict(self) -> dict:
        return asdict(self)


def specific_energy_kwh_per_nm3(supply_bar_g: float, atmosphere_kpa: float = P_ATM_KPA,
                                isothermal_efficiency: float = ISOTHERMAL_EFFICIENCY
                                ) -> float:
    """(E1) Specific energy of compressed air, kWh per normal m^3 (ISO 8778): the
    isothermal work of compressing it from the atmosphere to the supply pressure,
    ``P0 ln(p_supply / p_atm)`` per normal m^3 (intake at the reference temperature),
    over the compressor's isothermal efficiency (docs/reference/physics.md: energy)."""
    if isothermal_efficiency <= 0:
        raise ValueError("the isothermal efficiency must be positive")
    p_atm_pa = atmosphere_kpa * 1000.0
    p_supply_pa = p_atm_pa + supply_bar_g * PA_PER_BAR
    work_j_per_nm3 = P0_PA * math.log(p_supply_pa / p_atm_pa)
    return work_j_per_nm3 / 3.6e6 / isothermal_efficiency





@dataclass(frozen=True)
class CompressorSheet:
    """(E1) What a compressor's data sheet says of its energy: the specific package input
    power at full load (CAGI data sheets give kW per 100 cfm, ISO 1217 ones kW per m^3/min
    of free air delivered, both at an intake of 100 kPa and 20 degC, as the ISO 8778
    normal m^3 is) and the full-load pressure it is rated at. Read as an isothermal
    efficiency (the isothermal work of E1 at the rated pressure over the sheet's energy
    per m^3), it gives the specific energy at any supply pressure along E1's curve."""
    kw_per_m3_min: float
    rated_bar_g: float = 7.0

    def __post_init__(self):
        if not 0 < self.kw_per_m3_min < math.inf:
            raise ValueError(f"a compressor's specific power must be > 0 kW per m^3/min, "
                             f"not {self.kw_per_m3_min:g}")
        if not 0 < self.rated_bar_g < math.inf:
            raise ValueError(f"a compressor's rated pressure (--compressor-bar) must be "
                             f"above 0 bar gauge, not {self.rated_bar_g:g}")

    @classmethod
    def from_kw_per_100cfm(cls, kw_per_100cfm: float, rated_bar_g: float = 7.0):
        return cls(kw_per_100cfm / (100.0 * CFM_M3_MIN), rated_bar_g)

    def isothermal_efficiency(self, atmosphere_kpa: float = P_ATM_KPA) -> float:
        sheet_kwh_per_nm3 = self.kw_per_m3_min / 60.0          # kW per m^3/min
        return specific_energy_kwh_per_nm3(self.rated_bar_g, atmosphere_kpa, 1.0) \
            / sheet_kwh_per_nm3

    def sec_kwh_per_nm3(self, supply_bar_g: float, atmosphere_kpa: float = P_ATM_KPA
                        ) -> float:
        return specific_energy_kwh_per_nm3(supply_bar_g, atmosphere_kpa,
                                           self.isothermal_efficiency(atmosphere_kpa))

    def describe(self, atmosphere_kpa: float = P_ATM_KPA) -> str:
        return (f"the compressor's data sheet: {self.kw_per_m3_min:.3g} kW per m³/min "
                f"({self.kw_per_m3_min * 100.0 * CFM_M3_MIN:.3g} kW per 100 cfm) at "
                f"{self.rated_bar_g:g} bar(g), "
                f"{100 * self.isothermal_efficiency(atmosphere_kpa):.1f} % isothermal "
                "efficiency, along E1 to the supply pressure")


DEFICIT_TIE_NL = 1e-6          # deficits closer than a microlitre are the same one


def receiver_deficit(flow_l_min, dt_s: float, design_flow_l_min: float):
    """(largest deficit in NL, time in s at which it first occurs, deficit curve at the
    end of each cell) of demand over a constant supply (a Lindley recursion,
    vectorised). A repeating machine reaches the same deficit every cycle, and the sum's
    rounding makes one of them larger by 1e-12 NL: the first cycle within a microlitre
    of the largest is the one named, whatever order the cells were added in."""
    net_nl = (np.asarray(flow_l_min, dtype=float) - design_flow_l_min) * dt_s / 60.0
    d = np.concatenate([[0.0], np.cumsum(net_nl)])
    deficit = d - np.minimum.accumulate(d)
    largest = float(deficit.max())
    k = int(np.argmax(deficit >= largest - DEFICIT_TIE_NL))
    return largest, round(k * dt_s, 9), deficit[1:]


def idle_mask(profile, idle_after_s: float = 0.0) -> np.ndarray:
    """Cells in which no cylinder moves (and, with ``idle_after_s``, none has moved for
    that long before)."""
    active = [i for i, r in enumerate(profile.roles) if r == "active"]
    if active:
        vol = profile.cells_nl(active)
        # the merged rates cancel to rounding noise, not to zero, where strokes end
        moving = vol > 1e-9 * max(float(vol.max()), 1e-300)
    else:
        moving = np.zeros(profile.n_cells, dtype=bool)
    if idle_after_s > 0 and moving.any():
        # idle once k whole cells have passed since the last one with movement
        k = max(1, int(round(idle_after_s / profile.dt_s)))
        c = np.concatenate([[0], np.cumsum(moving)])
        recent = c[1:] - c[np.maximum(np.arange(1, len(c)) - (k + 1), 0)]
        return recent == 0
    return ~moving


def size(profile, allowance: float = DEFAULT_ALLOWANCE, band_bar: float = DEFAULT_BAND_BAR,
         hours_per_year: float = DEFAULT_HOURS, sec_kwh_per_nm3: float | None = None,
         price_per_kwh: float = DEFAULT_PRICE, efficiency: float = 1.0,
         idle_after_s: float = 0.0, cycles=None, last_switch_s: float | None = None,
         supply: tuple[float, float] | None = None, calendar=None,
         waiting=None, compressor: CompressorSheet | None = None) -> Sizing:
    """Size the supply for ``profile`` (module note); ``cycles`` (a
    :class:`~plcpred.air.cycles.Cycles`) adds the steady cycle's figures, and
    ``last_switch_s`` (when the valves last switch) warns of a machine that stops long
    before the horizon ends. ``sec_kwh_per_nm3`` None: from ``supply`` (supply bar
    gauge, atmosphere kPa) by E1, without it DEFAULT_SEC_KWH_NM3. With a ``calendar``
    (:class:`~plcpred.machine.Calendar`) the machine produces for ``hours_per_year`` and
    stands for the rest of the 8,760 h with the supply on: its leaks flow, and with
    ``idle_state = "program"`` the blowers the program leaves on when nothing moves
    (their rate over the run's idle time) (E2). ``waiting`` (a cell mask,
    :func:`~plcpred.air.cycles.rest_mask`) narrows idle to the cells in which the
    machine's outputs are as it waits: productive blow-off in a cycle is not idle air.
    A ``compressor`` data sheet (:class:`CompressorSheet`) sets E1's efficiency
    instead of the default one; ``sec_kwh_per_nm3`` overrides both."""
    warnings = []
    sec_kwh_per_nm3, sec_basis = _specific_energy(sec_kwh_per_nm3, supply, compressor,
                                                  warnings)
    if allowance < 0 or band_bar <= 0 or hours_per_year < 0 or sec_kwh_per_nm3 < 0 \
            or efficiency <= 0:
        raise ValueError("allowance, hours and specific energy must be >= 0, the pressure "
                         "band and efficiency > 0")
    total = profile.total_flow_l_min
    mean = profile.mean_l_min
    design = mean * (1.0 + allowance)
    deficit, at_s, _ = receiver_deficit(total, profile.dt_s, design)
    receiver_l = deficit * P0_PA / (band_bar * PA_PER_BAR)
    split = profile.by_role_nl()
    idle = idle_mask(profile, idle_after_s)
    if waiting is not None:
        idle = idle & waiting
    idle_by_consumer = profile.consumer_nl_within(idle)
    idle_nl = float(idle_by_consumer.sum())
    roles = np.array(profile.roles)
    idle_blowers_nl = float(idle_by_consumer[roles == "passive"].sum())
    idle_hours, idle_flow = _idle_year(profile, calendar, hours_per_year, idle, split["leak"],
                                       idle_blowers_nl)
    # (E2) annual air: production hours at the mean, idle hours at the idle flow
    air_nm3 = (mean * hours_per_year + idle_flow * idle_hours) * 60.0 / 1000.0
    energy = air_nm3 * sec_kwh_per_nm3 / efficiency
    if last_switch_s is not None and last_switch_s < STOPS_EARLY * profile.horizon_s:
        warnings.append(
            f"the valves last switch at {last_switch_s:g} s of the {profile.horizon_s:g} s "
            "horizon: the mean, the design flow (and with it the receiver), the energy and "
            "the idle share are averaged over a machine standing still for the rest (the "
            f"peaks are not); size over about {last_switch_s:g} s, or name a cycle "
            "([machine] cycle_signal) for per-cycle figures")
    return Sizing(
        mean_l_min=mean, peak_l_min=profile.peak_l_min(),
        peak_1s_l_min=profile.peak_l_min(1.0), peak_1min_l_min=profile.peak_l_min(60.0),
        p95_l_min=float(np.percentile(total, 95)), design_flow_l_min=design,
        allowance=allowance, deficit_nl=deficit, deficit_at_s=at_s, band_bar=band_bar,
        receiver_l=receiver_l, energy_kwh_per_year=energy,
        cost_per_year=energy * price_per_kwh, hours_per_year=hours_per_year,
        sec_kwh_per_nm3=sec_kwh_per_nm3, sec_basis=sec_basis, price_per_kwh=price_per_kwh,
        total_nl=profile.total_nl, active_nl=split["active"], passive_nl=split["passive"],
        leak_nl=split["leak"], idle_nl=idle_nl,
        idle_share=idle_nl / profile.total_nl if profile.total_nl > 0 else 0.0,
        idle_leak_nl=float(idle_by_consumer[roles == "leak"].sum()),
        idle_blowers_nl=idle_blowers_nl, idle_hours_per_year=idle_hours,
        idle_flow_l_min=idle_flow, air_nm3_per_year=air_nm3,
        horizon_s=profile.horizon_s, dt_s=profile.dt_s,
        **({} if cycles is None or cycles.cycle_s is None else {
            "cycle_source": cycles.source, "cycle_s": cycles.cycle_s,
            "nl_per_cycle": cycles.nl_per_cycle, "cycles_per_hour": cycles.per_hour}),
        warnings=warnings)


def _specific_energy(sec_kwh_per_nm3, supply, compressor, warnings: list
                     ) -> tuple[float, str]:
    """(E1) the energy per normal m^3 and what it rests on: as given, from a compressor's
    data sheet at the supply, isothermal compression to the supply over the default
    efficiency, or the published figure when the supply is not known."""
    if sec_kwh_per_nm3 is not None:
        return sec_kwh_per_nm3, "given (--sec)"
    if supply is None:
        return DEFAULT_SEC_KWH_NM3, "the published figure at 7 bar(g)"
    if compressor is not None:
        if supply[0] > compressor.rated_bar_g:
            warnings.append(f"the supply ({supply[0]:g} bar(g)) is above the pressure the "
                            f"compressor is rated at ({compressor.rated_bar_g:g} bar(g)): "
                            "its energy there is extrapolated along E1")
        return compressor.sec_kwh_per_nm3(*supply), compressor.describe(supply[1])
    return specific_energy_kwh_per_nm3(*supply), (
        "isothermal compression to the supply pressure over "
        f"{100 * ISOTHERMAL_EFFICIENCY:.1f} % efficiency (E1)")


def _idle_year(profile, calendar, hours_per_year: float, idle, leak_nl: float,
               idle_blowers_nl: float) -> tuple[float, float]:
    """(E2) the hours a year the machine stands with the supply on, and its flow then
    (NL/min): its leaks, and with ``idle_state = "program"`` the blowers the program
    leaves on when nothing moves (their rate over the run's idle cells ``idle``)."""
    if calendar is None:
        return 0.0, 0.0
    if hours_per_year > HOURS_PER_YEAR:
        raise ValueError(f"{hours_per_year:g} production hours do not fit in a year "
                         f"({HOURS_PER_YEAR:g} h)")
    idle_flow = leak_nl / profile.horizon_s * 60.0          # leaks: always
    idle_s = float(np.diff(profile.edges_s)[idle].sum())
    if calendar.idle_state == "program" and idle_s > 0:
        idle_flow += idle_blowers_nl / idle_s * 60.0
    return HOURS_PER_YEAR - hours_per_year, idle_flow


def production_hours(machine, hours: float | None) -> float:
    """The hours a year the machine produces: ``hours`` when given, else its
    [calendar]'s, else DEFAULT_HOURS."""
    if hours is not None:
        return hours
    return machine.calendar.production_hours if machine.calendar else DEFAULT_HOURS


def size_prediction(result, hours: float | None = None, **options) -> Sizing:
    """:func:`size` for a :class:`~plcpred.air.predict.Prediction`, with what its machine
    and timeline say: the production hours (``hours``, else the [calendar]'s), the
    calendar, the supply, the waiting state (idle air), the steady cycle and when the
    valves last switch. ``options`` go to :func:`size` (allowance, band, price, ...).
    ``plcpred size`` and every ``sweep`` scenario count a year through this one call."""

    m, tl, profile = result.machine, result.timeline, result.profile
    return size(profile, hours_per_year=production_hours(m, hours), calendar=m.calendar,
                waiting=rest_mask(m, tl, profile), cycles=cycles_of(m, tl, profile),
                last_switch_s=last_switch_s(m, tl), supply=(m.supply_bar_g, m.atmosphere_kpa),
                **options)
