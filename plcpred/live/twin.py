"""What ``serve`` publishes: the machine's program run against the physics plant (as
``emulate`` runs it), read as the values of its signals, a flow meter and the supply
pressure at their times.

The closed loop runs from the machine's start to a horizon; a run's first seconds do not
depend on how long it goes on, so the server starts on a short run and moves on to
longer ones as they finish (:meth:`Twin.run`), each time at the same values. With a truth
file switched on at a time, the nominal and the real machine both run, and the served
values leave the nominal run for the real one at the first moment from then on when
every served signal has the same value in both (at once for a hidden leak: it changes no
edge)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..machine import check_against_program
from ..plant import load_real_machine
from ..plant.emulate import MAX_EMULATE_HORIZON_S, run_closed_loop
from ..plant.flow_meter import MeterSettings, meter_readings
from ..sequencer import compile_program, observed_names
from ..sequencer.timeline import NS
from .settings import METER_NAME, PRESSURE_NAME, LiveError, machine_signals

FINE_DT_S = 1e-3           # the plant read on this grid for the meter (as emulate does)
FIRST_RUN_S = 20.0         # the first run's horizon: the server starts after it
RUN_GROWTH = 4.0           # each later run this much longer


@dataclass
class TwinRun:
    """One closed-loop run (and, with a truth file switched on later, the real
    machine's too) up to ``horizon_s``."""
    horizon_s: float
    nominal: tuple          # (plant, timeline)
    real: tuple | None
    splice_s: float | None  # served from the real run from here on (None: never)


class Twin:
    """The served machine: its signals (machine-file names, in :func:`machine_signals`
    order), then the meter and the supply pressure, as node indices."""

    def __init__(self, machine_path, horizon_s: float, truth=None, truth_at_s: float = 0.0,
                 seed: int | None = None, program=None):
        if not 0 < horizon_s <= MAX_EMULATE_HORIZON_S:
            raise LiveError(f"--horizon must be more than 0 s and at most "
                            f"{MAX_EMULATE_HORIZON_S / 3600:g} h (the physics plant's "
                            "longest run)")
        self.horizon_s = float(horizon_s)
        self.nominal = load_real_machine(machine_path, None)
        self.real = load_real_machine(machine_path, truth) if truth is not None else None
        self.truth_at_s = float(truth_at_s or 0.0)
        if self.real is not None and self.truth_at_s <= 0:
            self.nominal, self.real = self.real, None      # the real machine from the start
        self.program = self.nominal.read_program(program)
        check_against_program(self.nominal, self.program)
        if self.real is not None:
            check_against_program(self.real, self.program)
        # compiled once for every run (a restarted server's first among them)
        self.compiled = compile_program(self.program, observed_names(self.nominal, self.program)
                                        | observed_names(self.real or self.nominal,
                                                         self.program))
        self.signals = machine_signals(self.nominal)
        self.names = self.signals + [METER_NAME, PRESSURE_NAME]
        self.meter_index, self.pressure_index = len(self.signals), len(self.signals) + 1
        self.meter = MeterSettings.from_machine((self.real or self.nominal).meter)
        self.rng = np.random.default_rng(seed)

    # ------------------------------------------------------------------ runs
    def run_horizons(self) -> list[float]:
        """The horizons of the runs the server goes through, the last the whole."""
        out, h = [], min(FIRST_RUN_S, self.horizon_s)
        while h < self.horizon_s:
            out.append(h)
            h *= RUN_GROWTH
        return out + [self.horizon_s]

    def run(self, horizon_s: float) -> TwinRun:
        """The closed loop (CPU-bound: for a worker thread) up to ``horizon_s``."""
        nominal = run_closed_loop(self.nominal, self.program, horizon_s, self.compiled)
        if self.real is None or self.truth_at_s >= horizon_s:
            return TwinRun(horizon_s, nominal, None, None)
        real = run_closed_loop(self.real, self.program, horizon_s, self.compiled)
        return TwinRun(horizon_s, nominal, real, self._splice_s(nominal[1], real[1],
                                                                horizon_s))

    def _edges(self, timeline, signal: str) -> tuple[np.ndarray, np.ndarray]:
        name = timeline.info.get("machine_signals", {}).get(signal, signal)
        return timeline.edge_times_ns(name)

    def _splice_s(self, a, b, horizon_s: float) -> float | None:
        """The first time from ``truth_at_s`` on when every served signal has the same
        value in timelines ``a`` and ``b``."""
        at_ns = round(self.truth_at_s * NS)
        series = [(self._edges(a, s), self._edges(b, s)) for s in self.signals]
        candidates = np.unique(np.concatenate(
            [[at_ns]] + [t[t >= at_ns] for pair in series for t, _ in pair]))
        same = np.ones(len(candidates), bool)
        for (ta, va), (tb, vb) in series:
            value_a = va[np.searchsorted(ta, candidates, side="right") - 1]
            value_b = vb[np.searchsorted(tb, candidates, side="right") - 1]
            same &= value_a == value_b
        hit = np.flatnonzero(same & (candidates <= round(horizon_s * NS)))
        return float(candidates[hit[0]] / NS) if len(hit) else None

    # ------------------------------------------------------------------ values
    def values_at(self, run: TwinRun, at_s: float) -> list:
        """Every node's value at ``at_s``: the signals', the meter's reading due then
        (its first at the machine's start) and the supply pressure."""
        at_ns = round(at_s * NS)
        values: list = []
        for s in self.signals:
            t, v = self._edges(run.nominal[1], s)
            if run.splice_s is not None and at_s >= run.splice_s:
                t, v = self._edges(run.real[1], s)
            values.append(bool(v[np.searchsorted(t, at_ns, side="right") - 1]))
        period = 1.0 / self.meter.rate_hz
        _, flow, supply = self._readings(run, at_s, at_s + period)
        return values + [float(flow[0]) if len(flow) else 0.0,
                         float(supply[0]) if len(supply) else
                         float(run.nominal[0].line_pressure_bar_g(np.zeros(1))[0])]

    def events(self, run: TwinRun, t0_s: float, t1_s: float
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(time ns, node index, value) of what changes in ``[t0_s, t1_s)``, sorted by
        time (signals before the meter at one time): the signals' edges and the meter's
        readings with the supply pressure at each."""
        t_parts, i_parts, v_parts = [], [], []
        lo, hi = round(t0_s * NS), round(t1_s * NS)
        for k, s in enumerate(self.signals):
            t, v = self._edges(run.nominal[1], s)
            if run.splice_s is not None:
                cut = round(run.splice_s * NS)
                tr, vr = self._edges(run.real[1], s)
                keep = t < cut
                t, v = np.concatenate([t[keep], tr[tr >= cut]]), np.concatenate(
                    [v[keep], vr[tr >= cut]])
            m = (t >= max(lo, 1)) & (t < hi)
            t_parts.append(t[m])
            i_parts.append(np.full(int(m.sum()), k))
            v_parts.append(v[m].astype(float))
        times_s, flow, supply = self._readings(run, t0_s, t1_s)
        t_ns = np.round(times_s * NS).astype(np.int64)
        t_parts += [t_ns, t_ns]
        i_parts += [np.full(len(t_ns), self.meter_index), np.full(len(t_ns),
                                                                  self.pressure_index)]
        v_parts += [flow, supply]
        t_all, i_all = np.concatenate(t_parts), np.concatenate(i_parts)
        order = np.lexsort((i_all, t_all))
        return t_all[order], i_all[order], np.concatenate(v_parts)[order]

    def _readings(self, run: TwinRun, t0_s: float, t1_s: float):
        """(times s, flow as the meter reports it, supply bar g) of the meter's readings
        in ``[t0_s, t1_s)``: the plant's true flow through the meter's response, read on
        a fine grid from a lead-in of ten response times before ``t0_s``."""
        period = 1.0 / self.meter.rate_hz
        lead_s = max(1.0, 10.0 * self.meter.tau_s)
        start_s = max(0.0, np.floor((t0_s - lead_s) / period) * period)
        end_s = min(t1_s, run.horizon_s)
        if end_s <= start_s:
            return np.zeros(0), np.zeros(0), np.zeros(0)
        cells = max(1, int(np.ceil((end_s - start_s) / FINE_DT_S)))
        edges = np.linspace(start_s, end_s, cells + 1)
        total = self._total_cum_nl(run.nominal[0], edges)
        if run.splice_s is not None:
            real = np.diff(self._total_cum_nl(run.real[0], edges))
            cell = np.where(edges[:-1] >= run.splice_s, real, np.diff(total))
            total = np.concatenate([[0.0], np.cumsum(cell)])
        times, flow = meter_readings(edges - start_s, total - total[0], self.meter,
                                     end_s - start_s, self.rng)
        times = times + start_s
        keep = (times >= t0_s - 1e-9) & (times < t1_s - 1e-9)
        times, flow = times[keep], flow[keep]
        supply = run.nominal[0].line_pressure_bar_g(times)
        if run.splice_s is not None:
            after = times >= run.splice_s
            if after.any():
                supply[after] = run.real[0].line_pressure_bar_g(times[after])
        return times, flow, supply

    @staticmethod
    def _total_cum_nl(plant, edges: np.ndarray) -> np.ndarray:
        cumulative = plant.cumulative_nl(edges)
        return sum(cumulative[n] for n in plant.metered_names())
