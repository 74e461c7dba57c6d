"""Timing effects in a closed loop: the sequencer run again with other drive timing.

When end switches start the program's next step, a slower stroke or a later valve
moves every later edge and the cycle itself grows, so a timing effect cannot be applied
to the predicted edges (a 2.4x slower feed stroke on a 5 s cycle puts the prediction a
whole cycle out within a minute of log). :class:`Resequencer` runs the machine's program
again with the drives' stroke times scaled and switching delays added, ties each run's log
to the new prediction (its own clock alignment: the nominal one was found against the
wrong cycle) and keeps the result as a variant of the run
(:attr:`~plcpred.diagnose.fit.RunData.variants`, with its offset and meter lag relative
to the run's), which the fit selects through
:attr:`~plcpred.diagnose.fit_model.ModelParams.timing`. Variants are keyed by quantised
timing (1 % of a stroke time, 1 ms of delay) so that a fit's evaluations share them.
"""
from __future__ import annotations

import dataclasses
import math
from collections import OrderedDict

import numpy as np

from ..sequencer import compile_program, observed_names, unfold
from .effects import METER_LAG_FIT_MAX_S
from .fit import DiagnosisError, align
from .fit_model import MachineModel, RunModel
from .io import MeasuredRun

FACTOR_QUANTUM = 0.01          # in ln(factor): 1 % steps of a stroke time
DELAY_QUANTUM_S = 0.001
KEPT_CELLS = 8_000_000         # grid cells of all runs' variants held at once
PROBE_FACTOR = 1.5             # the timing change that tells a closed loop from timers
# a variant is aligned on the log's first ALIGN_SPAN_WINDOWS offset windows (at least
# ALIGN_SPAN_MIN_S): an hour's log aligns no better than its first minutes, at ten
# times the cost
ALIGN_SPAN_WINDOWS = 4.0
ALIGN_SPAN_MIN_S = 300.0


def quantise_factor(f: float) -> float:
    return float(math.exp(round(math.log(max(f, 1e-6)) / FACTOR_QUANTUM) * FACTOR_QUANTUM))


def quantise_delay(d: float) -> float:
    return round(round(d / DELAY_QUANTUM_S) * DELAY_QUANTUM_S, 6)


class Resequencer:
    """Per drive (in ``MachineModel.drives`` order) a stroke-time factor and an extra
    switching delay; :meth:`ensure` makes each run's variant for one such timing."""

    def __init__(self, mm, rds, horizons_s, windows_s, offsets, program, meter_tau_s):
        self.mm = mm
        self.meter_tau_s = meter_tau_s
        self.rds = rds
        self.horizons_s = horizons_s
        self.windows_s = windows_s
        self.offsets = offsets
        self.program = program
        self.drive_consumers = [mm.machine.consumer(mm.models[r].name) for r in mm.drives]
        self.made = 0                   # variants made so far (each a sequencer run per run)
        self.compiled = None            # the program compiled, on the first variant
        self._kept: OrderedDict = OrderedDict()
        self.neutral = tuple((1.0, 0.0) for _ in mm.drives)

    def key(self, factors=None, delays=None, start=None) -> tuple:
        """The quantised timing ``start`` (default: neutral) with ``factors`` and/or
        ``delays`` replaced; None when that is the nominal timing."""
        old = start or self.neutral
        f = [a for a, _ in old] if factors is None else [quantise_factor(x) for x in factors]
        d = [b for _, b in old] if delays is None else [quantise_delay(x) for x in delays]
        key = tuple(zip(f, d))
        return None if key == self.neutral else key

    def machine(self, key):
        """The machine with ``key``'s timing (stroke times scaled, delays added)."""
        machine = self.mm.machine
        changed = {}
        for c, (f, d) in zip(self.drive_consumers, key):
            st = c.stroke_times()
            if st is None:
                continue
            changed[c.name] = dataclasses.replace(
                c, stroke_time_s=(st[0] * f, st[1] * f),
                switch_delay_s=max(0.0, c.switch_delay_s + d))
        return dataclasses.replace(
            machine, consumers=[changed.get(c.name, c) for c in machine.consumers],
            warnings=[])

    def ensure(self, key) -> None:
        """Give every run its variant for ``key`` (None: the nominal timing, nothing to
        make). The least recently used variants are dropped beyond KEPT_CELLS."""
        if key is None:
            return
        if key in self._kept:
            self._kept.move_to_end(key)
            return

        self.made += 1
        if self.compiled is None:       # once: every variant runs the same program
            self.compiled = compile_program(self.program,
                                            observed_names(self.machine(key), self.program))
        machine = self.machine(key)
        mm = MachineModel.of(machine)
        for rd, horizon, window, off in zip(self.rds, self.horizons_s, self.windows_s,
                                            self.offsets):
            tl = unfold(machine, horizon, program=self.program, compiled=self.compiled)
            rm = RunModel(mm, tl, rd.model.dt_s, start_s=rd.model.start_s)
            shift = lag = 0.0
            if off is None and _edges_moved_s(rd.model, rm, float(rd.end_s[-1])) > rm.dt_s:
                # the nominal alignment matched a cycle of the wrong length: the variant
                # is aligned as the nominal run was, by the same search
                try:
                    # the lag searched again too (unless the file gives it): it trades
                    # off against the offset, and the nominal search stretched it to
                    # bridge the wrong cycle
                    other = align(_head(rd.run, ALIGN_SPAN_WINDOWS * window), rm,
                                  mm.nominal(rd.fitted_tau_s), window,
                                  self.meter_tau_s, None, quick=True,
                                  max_tau_s=max(METER_LAG_FIT_MAX_S, rd.fitted_tau_s))
                    shift = other.offset_s - rd.offset_s
                    lag = other.meter_tau_s - rd.meter_tau_s
                except DiagnosisError:
                    pass
            rd.variants[key] = (rm, shift, lag)
        self._kept[key] = True
        cells = sum(rd.model.n_cells for rd in self.rds)
        while len(self._kept) > max(8, KEPT_CELLS // max(cells, 1)):
            old, _ = self._kept.popitem(last=False)
            for rd in self.rds:
                rd.variants.pop(old, None)
                rd.forget_samplers(old)

    def waiting_drives(self) -> set[int]:
        """The drives (indices into mm.drives) whose valve edges wait on the drives' timing:
        with every stroke PROBE_FACTOR slower and every valve 50 ms later, do its valve
        transitions in the first run differ from the nominal ones?"""
        probe = self.key(factors=[PROBE_FACTOR] * len(self.neutral),
                         delays=[0.05] * len(self.neutral))
        self.ensure(probe)
        rd = self.rds[0]
        return {k for k, (t0, t1) in enumerate(zip(rd.model.transitions,
                                                   rd.variants[probe][0].transitions))
                if _times_moved_s(t0[0], t1[0], rd.model.horizon_s) > 1e-3}


def _edges_moved_s(nominal, variant, until_s: float) -> float:
    """How far the variant moves the valve edges of the nominal run (RunModels), edge by
    edge in order, up to ``until_s`` (the run's last sample)."""
    return max((_times_moved_s(t0, t1, until_s) for (t0, _), (t1, _) in
                zip(nominal.transitions, variant.transitions)), default=0.0)


def _times_moved_s(t0, t1, until_s: float) -> float:
    """How far one drive's edge times ``t1`` move from the nominal ``t0``."""
    t0, t1 = t0[t0 <= until_s], t1[t1 <= until_s]
    n = min(len(t0), len(t1))
    moved = float(np.max(np.abs(t1[:n] - t0[:n]))) if n else 0.0
    if len(t0) != len(t1):
        moved = max(moved, until_s - float(min(t0[n:].min(initial=until_s),
                                               t1[n:].min(initial=until_s))))
    return moved


def _head(run, span_s: float):
    """The first ``span_s`` (at least ALIGN_SPAN_MIN_S) of a measured run."""

    end = run.time_s[0] + max(span_s, ALIGN_SPAN_MIN_S)
    n = int(np.searchsorted(run.time_s, end, side="right"))
    # a sparse log (readings 1,000 s apart) holds too few readings in its head to have
    # an interval: then the whole log is the head
    if n >= len(run.time_s) or n < 3:
        return run
    return MeasuredRun(run.name, run.time_s[:n], run.flow_l_min[:n], sampling=run.sampling)
