"""The machine as the plant sees it: drives grouped by supply, passive consumers, and the
adapters through which the sequencer drives it in closed loop."""
from __future__ import annotations

import math

import numpy as np

from ..air.demand import sonic_conductance
from ..physics.chamber import signed_mass_flow_kg_s, mass_to_nl
from ..physics.drive import drive_params
from ..physics.group import Group, Passive, Supply
from ..physics.strokes import throttle_to
from ..physics.units import PA_PER_BAR, bar_g_to_pa, celsius_to_k

NS = 1_000_000_000


class DriveAdapter:
    """One drive seen by the sequencer (the interface of the piecewise-linear
    ``CylinderPlant``), backed by its group's integration."""

    def __init__(self, group: Group, index: int, initial_extended: bool):
        self.group, self.index = group, index
        self.extend_cmd = initial_extended

    def command(self, t_ns: int, extend: bool) -> None:
        if extend == self.extend_cmd:
            return
        self.extend_cmd = extend
        self.group.command_valve(t_ns / NS, self.index, extend)

    def switches(self, t_ns: int) -> tuple[bool, bool]:
        return self.group.switches(self.index, t_ns / NS)

    def next_event_ns(self, after_ns: int) -> int | None:
        t = self.group.next_switch_after(self.index, after_ns / NS)
        if t is None:
            return None
        return max(after_ns + 1, math.ceil(t * NS - 1e-3))

    def forget_before(self, t_ns: int) -> None:
        pass


class PassiveAdapter:
    """A nozzle's valve: records when it is on (and tells its line's group)."""

    def __init__(self, group: Group | None = None, index: int = -1):
        self.group, self.index = group, index
        self.extend_cmd = False
        self.edges: list[tuple[float, bool]] = []

    def command(self, t_ns: int, on: bool) -> None:
        if on == self.extend_cmd:
            return
        self.extend_cmd = on
        self.edges.append((t_ns / NS, on))
        if self.group is not None:
            self.group.command_passive(t_ns / NS, self.index, on)

    def switches(self, t_ns: int) -> tuple[bool, bool]:
        return (False, False)

    def next_event_ns(self, after_ns: int) -> None:
        return None

    def forget_before(self, t_ns: int) -> None:
        pass


class PlantModel:
    """Every consumer of a (real) machine file as physics: one :class:`Group` per drive
    on the ideal supply and one per ``[[line]]``."""

    def __init__(self, machine):
        self.machine = machine
        self.atm_pa = machine.atmosphere_kpa * 1000.0
        self.ambient_k = celsius_to_k(machine.ambient_c)
        self.supply_pa = bar_g_to_pa(machine.supply_bar_g, machine.atmosphere_kpa)
        self.cache: dict = {}
        self.groups: list[Group] = []
        self.where: dict[str, tuple[Group | None, int]] = {}
        lines = {ln.name: ln for ln in machine.lines}
        on_line: dict[str, tuple[list, list]] = {name: ([], []) for name in lines}
        for c in machine.consumers:
            if c.line is not None:
                (on_line[c.line][0] if c.is_cylinder else on_line[c.line][1]).append(c)
            elif c.is_cylinder:
                g = Group([self._drive(c)], Supply(self.supply_pa, self.ambient_k),
                          atmosphere_pa=self.atm_pa, ambient_k=self.ambient_k,
                          cache=self.cache)
                self.groups.append(g)
                self.where[c.name] = (g, 0)
        for name, (drives, passives) in on_line.items():
            if not drives and not passives:
                continue
            ln = lines[name]
            set_pa = bar_g_to_pa(ln.pressure_bar_g if ln.pressure_bar_g is not None
                                 else machine.supply_bar_g, machine.atmosphere_kpa)
            net_pa = bar_g_to_pa(ln.network_bar_g, machine.atmosphere_kpa) \
                if ln.network_bar_g is not None else set_pa + 1e5
            supply = Supply(set_pa, self.ambient_k, line=name,
                            volume_m3=ln.volume_l / 1000.0, network_pa=net_pa,
                            C=ln.C if ln.C is not None else 1e-7, b=ln.b, m=ln.m,
                            droop_pa=ln.droop_bar * PA_PER_BAR)
            plist = [Passive(c.name, sonic_conductance(c), c.b, c.m, c.a or 1.0,
                             c.kind == "leak",
                             bar_g_to_pa(c.pressure_bar_g, machine.atmosphere_kpa)
                             if c.pressure_bar_g is not None else None) for c in passives]
            g = Group([self._drive(c, ln.check_valves) for c in drives], supply, plist,
                      atmosphere_pa=self.atm_pa, ambient_k=self.ambient_k, cache=self.cache)
            self.groups.append(g)
            for i, c in enumerate(drives):
                self.where[c.name] = (g, i)
            for j, c in enumerate(passives):
                self.where[c.name] = (g, 7 * len(drives) + 2 + j)
        self.adapters: dict[str, object] = {}

    def _drive(self, c, line_check_valves: bool = False):
        """A drive's parameters; with stroke times in the file, its flow controls set to
        give them (see :mod:`.strokes`)."""
        d = drive_params(c, line_check_valves)
        if isinstance(c.stroke_time_s, tuple):
            explicit = "exhaust_C" in c.plant
            d, _ = throttle_to(d, c.stroke_time_s, self.supply_pa, self.atm_pa,
                               self.ambient_k, (explicit, explicit))
        return d

    def adapter(self, consumer):
        """What the sequencer drives for a consumer with a valve."""
        group, index = self.where.get(consumer.name, (None, -1))
        if consumer.is_cylinder:
            a = DriveAdapter(group, index, consumer.initial == "extended")
        elif group is not None:
            a = PassiveAdapter(group, index - 7 * group.n - 2)
        else:
            a = PassiveAdapter()
        self.adapters[consumer.name] = a
        return a

    def finish(self, horizon_s: float) -> None:
        """Integrate every group to the horizon (after the sequencer has run)."""
        for g in self.groups:
            g.advance(horizon_s)

    # ------------------------------------------------------------------ outputs
    def cumulative_nl(self, edges_s: np.ndarray) -> dict[str, np.ndarray]:
        """Normal litres each consumer has drawn from its supply by each time (for a drive
        on a line: from the line; the line's regulator appears as ``line:<name>``)."""
        out: dict[str, np.ndarray] = {}
        # only the drawn masses are sampled: each group's columns 6n.. (its drives'),
        # and on a line the regulator's and its passives'
        states = {}
        for g in self.groups:
            cols = list(range(6 * g.n, g.size if g.has_line else 7 * g.n))
            states[id(g)] = (g.state_at(edges_s, cols), 6 * g.n)
        for c in self.machine.consumers:
            group, index = self.where.get(c.name, (None, -1))
            if group is not None:
                x, first = states[id(group)]
                col = 6 * group.n + index if c.is_cylinder else index
                out[c.name] = mass_to_nl(x[:, col - first])
            else:
                out[c.name] = mass_to_nl(self._passive_mass_kg(c, edges_s))
        for g in self.groups:
            if g.has_line:
                x, first = states[id(g)]
                out[f"line:{g.supply.line}"] = mass_to_nl(x[:, 7 * g.n + 1 - first])
        for ln in self.machine.lines:       # a line nobody draws from
            out.setdefault(f"line:{ln.name}", np.zeros(len(edges_s)))
        return out

    def passive_flow_kg_s(self, c) -> float:
        """(D2, full phi) a nozzle's or leak's flow at its own pressure or the supply. A
        nozzle's regulator cannot raise the supply; a leak's pressure may lie above it (a
        leak upstream of the machine's regulator sees the network)."""
        p_up = self.supply_pa
        if c.pressure_bar_g is not None:
            own = bar_g_to_pa(c.pressure_bar_g, self.machine.atmosphere_kpa)
            p_up = own if c.kind == "leak" else min(p_up, own)
        return float(signed_mass_flow_kg_s(sonic_conductance(c), c.b, c.m, p_up, self.ambient_k,
                                    self.atm_pa, self.ambient_k, c.a or 1.0))

    def _passive_mass_kg(self, c, edges_s):
        q = self.passive_flow_kg_s(c)
        if c.kind == "leak":
            return q * edges_s
        on_time = np.zeros_like(edges_s)
        edges = getattr(self.adapters.get(c.name), "edges", [])
        t_on = None
        for t, on in edges:
            if on:
                t_on = t
            elif t_on is not None:
                on_time += np.clip(edges_s - t_on, 0.0, t - t_on)
                t_on = None
        if t_on is not None:
            on_time += np.clip(edges_s - t_on, 0.0, None)
        return q * on_time

    def metered_names(self) -> list[str]:
        """The series whose sum the machine's flow meter sees: at the machine drop
        (default) everything, a line's drives through its regulator; on a line
        (``[meter] line``) that line's regulator flow."""
        meter = self.machine.meter
        if meter is not None and meter.line is not None:
            return [f"line:{meter.line}"]
        names = [c.name for c in self.machine.consumers if c.line is None]
        names += [f"line:{g.supply.line}" for g in self.groups if g.has_line]
        return names

    def drive_states(self, name: str, times_s: np.ndarray,
                     group_states: dict | None = None) -> dict[str, np.ndarray]:
        """Position (mm) and chamber pressures (bar gauge) of a drive on a grid.
        ``group_states``: id(group) -> its states on that grid, to sample each group once
        when asking for several drives."""
        g, i = self.where[name]
        if group_states is None:
            group_states = {}
        n = g.n
        if id(g) not in group_states:
            # pressures and positions only: columns 0..2n and 4n..5n
            cols = list(range(2 * n)) + list(range(4 * n, 5 * n))
            group_states[id(g)] = g.state_at(times_s, cols)
        x = group_states[id(g)]
        to_bar_g = lambda p: (p - self.atm_pa) / PA_PER_BAR  # noqa: E731
        return {"position_mm": x[:, 2 * n + i] * 1000.0, "p_cap_bar_g": to_bar_g(x[:, i]),
                "p_rod_bar_g": to_bar_g(x[:, n + i])}

    def line_pressure_bar_g(self, times_s: np.ndarray) -> np.ndarray:
        """The supply pressure the meter's neighbourhood sees: its line's pressure (the
        first line's when it sits at the drop), or the machine's regulated supply."""
        meter = self.machine.meter
        wanted = meter.line if meter is not None else None
        for g in self.groups:
            if g.has_line and wanted in (None, g.supply.line):
                return (g.state_at(times_s, [7 * g.n])[:, 0] - self.atm_pa) / PA_PER_BAR
        return np.full(len(times_s), self.machine.supply_bar_g)
