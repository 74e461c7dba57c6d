"""``emulate``: run a machine's program in closed loop with the physics plant and report
what a flow meter on it would log."""
from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass, field

import numpy as np

from ..machine import Machine, check_against_program
from ..physics.meter import interval_means_l_min
from ..sequencer import Sequencer, parse_horizon
from ..sequencer.timeline import HorizonError
from .flow_meter import MeterSettings, meter_readings
from .model import PlantModel
from .truth import load_real_machine

MAX_GRID_CELLS = 400_000
# the plant integrates every stroke of the horizon (about 20 s of work per emulated hour
# of a small station, more pieces held the longer it runs): a day is as far as a user
# waits for; longer questions are for predict and size, which repeat the cycle
MAX_EMULATE_HORIZON_S = 86_400.0
MAX_PLANT_ROWS = 200_000


@dataclass
class Emulation:
    """An emulated run: the real machine, its I/O, the plant's true flows and states,
    and the meter's log."""
    machine: object
    timeline: object
    plant: PlantModel
    horizon_s: float
    edges_s: np.ndarray                 # fine grid edges
    cumulative_nl: dict                 # series -> NL drawn by each edge
    measured_time_s: np.ndarray
    measured_flow_l_min: np.ndarray
    measured_supply_bar_g: np.ndarray
    meter: MeterSettings
    info: dict = field(default_factory=dict)

    def consumer_nl(self) -> dict[str, float]:
        """True normal litres per consumer over the horizon."""
        return {c.name: float(self.cumulative_nl[c.name][-1])
                for c in self.machine.consumers}

    @property
    def total_nl(self) -> float:
        """What the machine drew through the meter's point (all consumers, a line's drives
        through its regulator)."""
        return float(sum(self.cumulative_nl[n][-1] for n in self.plant.metered_names()))

    def true_total_cum_nl(self) -> np.ndarray:
        return sum(self.cumulative_nl[n] for n in self.plant.metered_names())

    def measured_nl(self) -> float:
        """The meter's readings integrated (at the meter's reference)."""
        return float(np.sum(self.measured_flow_l_min) / self.meter.rate_hz / 60.0)

    def plant_table(self):
        """(header, rows) of plant.csv: true flows (NL/min, ISO 8778) per consumer and in
        total, each drive's position and chamber pressures, on a grid of at most
        MAX_PLANT_ROWS rows."""
        dt = max(1e-3, self.horizon_s / MAX_PLANT_ROWS)
        n = max(1, int(round(self.horizon_s / dt)))
        edges = np.linspace(0.0, self.horizon_s, n + 1)
        mid = 0.5 * (edges[:-1] + edges[1:])
        cols, header = [edges[1:]], ["time_s"]
        total = np.zeros(n)
        names = self.plant.metered_names()
        for name, cum in self.cumulative_nl.items():
            flow = interval_means_l_min(cum, self.edges_s, edges[:-1], edges[1:])
            if name in names:
                total += flow
            cols.append(flow)
            header.append(f"{name}_l_min")
        cols.insert(1, total)
        header.insert(1, "total_l_min")
        sampled: dict = {}      # each group's states, sampled once for all its drives
        for c in self.machine.consumers:
            if c.is_cylinder:
                st = self.plant.drive_states(c.name, mid, sampled)
                for key, values in st.items():
                    cols.append(values)
                    header.append(f"{c.name}_{key}")
        return header, np.column_stack(cols)


def run_closed_loop(machine, program, horizon_s: float, compiled=None, on_time=None):
    """(plant, timeline): ``machine``'s program (parsed; ``compiled``: its compiled form)
    run against the physics plant over ``horizon_s``, untiled (the plant's end switches
    drive it), and the plant integrated to the horizon. ``on_time(t_ns)``: as
    :meth:`~plcpred.sequencer.Sequencer.run`."""

    plant = PlantModel(machine)
    timeline = Sequencer(program, machine, compiled=compiled, plant=plant).run(
        round(horizon_s * 1e9), tiling=False, on_time=on_time)
    plant.finish(horizon_s)
    return plant, timeline


def emulate(machine, horizon="60s", truth=None, seed: int | None = None,
            program=None, on_time=None) -> Emulation:
    """Run ``machine`` (a path or a loaded Machine; with ``truth``, a truth file applied
    to it) in closed loop with the physics plant over ``horizon``. ``on_time(t_ns)``
    hears of the simulated time reached as the run goes (a progress bar)."""

    wall0 = _time.perf_counter()
    if not isinstance(machine, Machine) or truth is not None:
        machine = load_real_machine(machine.path if isinstance(machine, Machine) else machine,
                                    truth)
    horizon_ns = parse_horizon(horizon)
    horizon_s = horizon_ns / 1e9
    if horizon_s > MAX_EMULATE_HORIZON_S:
        raise HorizonError(f"emulate runs the physics of every stroke and goes at most "
                           f"{MAX_EMULATE_HORIZON_S / 3600:g} h (asked for {horizon_s / 3600:g} h); "
                           "emulate a representative hour, and use predict or size for "
                           "long horizons")
    if program is None or not hasattr(program, "pous"):
        program = machine.read_program(program)
    check_against_program(machine, program)
    plant, timeline = run_closed_loop(machine, program, horizon_s, on_time=on_time)
    wall_run = _time.perf_counter() - wall0
    cells = max(1, min(MAX_GRID_CELLS, math.ceil(horizon_s / 1e-3)))
    edges = np.linspace(0.0, horizon_s, cells + 1)
    cumulative = plant.cumulative_nl(edges)
    meter = MeterSettings.from_machine(machine.meter)
    total = sum(cumulative[n] for n in plant.metered_names())
    rng = np.random.default_rng(seed)
    t_meter, flow = meter_readings(edges, total, meter, horizon_s, rng)
    supply = plant.line_pressure_bar_g(t_meter)
    info = {"wall_s": _time.perf_counter() - wall0, "wall_run_s": wall_run,
            "integrated_pieces": sum(g.integrated_pieces for g in plant.groups),
            "reused_pieces": sum(g.reused_pieces for g in plant.groups),
            "scans": timeline.info.get("scans")}
    return Emulation(machine, timeline, plant, horizon_s, edges, cumulative, t_meter, flow,
                     supply, meter, info)
