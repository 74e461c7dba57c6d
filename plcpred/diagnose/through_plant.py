"""Effects fitted through the physics plant: the machine file changed as the effect says
(a supply pressure, a tube, a valve's delay, a stroke time) and run through the plant.

An effect's open-loop form (:mod:`~plcpred.diagnose.effects`) changes D1's numbers: a
longer tube adds its volume to every stroke. On a real machine a longer tube also fills
more slowly, so the stroke arrives later, the program's next step starts later, and an
exhaust at speed keeps more of the tube's air; a lower supply slows every stroke. Where
the plant is the better nominal model of the machine (its reference beats D1 on held-out
samples), those shapes decide which effect it is. :class:`ThroughPlant` wraps an effect
so that its values are written into the machine file with the effect's own
``to_machine`` (the form ``--write-machine`` writes) and that machine is run through the
plant (the program against it for sequencer runs, the recorded edges for ``--io`` runs);
:class:`PlantVariants` makes and keeps those runs.

Each value costs a plant run, so the parameters are discrete (diagnose.fit sweeps a
coarse grid one drive at a time and all together, refines the best by golden section,
and lets each fold choose among the values already run), quantised so that evaluations
share runs.
"""
from __future__ import annotations

import copy
import dataclasses
from collections import OrderedDict

import numpy as np

from ..errors import PlcpredError
from ..machine import machine_from_data, read_machine_data
from ..physics.volumes import inner_dead_volumes_cm3
from ..plant.replay import shared_run_cells_nl
from .effects import (
    CLOSED_DELAY_GRID_S,
    CLOSED_FACTOR_GRID,
    DeadVolume,
    Effect,
    Param,
    StrokeTime,
    SupplyPressure,
    ValveDelay,
    tube_volumes_cm3,
)
from .timing import KEPT_CELLS, quantise_delay, quantise_factor

SUPPLY_QUANTUM_BAR = 0.01
SUPPLY_GRID = (0.7, 0.85, 1.15, 1.3)            # times the file's gauge pressure
DEAD_VOLUME_GRID = (-0.5, 0.5, 1.5, 3.0)        # times a drive's known dead volume
DEAD_VOLUME_QUANTUM = 0.02                      # of a drive's known dead volume
MIN_DEAD_VOLUME_CM3 = 2.0
# what one value may cost, in the plant's integration pieces (a piece is one stretch
# between valve commands or switch events; about 1-2 ms of CPU each). A value is one
# plant run to the longest log's end (a variant's cycle is its own, so the prediction's
# tiling does not hold for it; every sequencer log reads the same run), and a fit runs
# some 30-60 values: 800 pieces keep it near a minute. Two 40 s logs of the sample
# machines cost 40-440 (the pick-and-place station 435); of the rig's sequence 2
# (drive C at 50 cycles a minute) 880; an hour of pick-and-place about 25,000.
MAX_VARIANT_PIECES = 800
# and what one effect may cost in all (the pick-and-place station's slower strokes,
# two 40 s logs: about 24,000): past it, the effect is not fitted through the plant
MAX_EFFECT_PIECES = 30_000


def _run_key(rd, replayed: bool):
    """Runs with the same key share one plant run, to the longest's horizon: every
    sequencer run (the program from its start against the variant), and replayed
    (recorded) edges of one timeline."""
    return id(rd.model.timeline) if replayed else None


def variant_pieces(reference_cost: dict, rds, replayed: bool = False) -> float:
    """About how many integration pieces one variant of ``rds`` costs: the reference's
    pieces per integrated machine second (``reference_cost``, counted by the plant's
    replay functions) times the seconds a variant integrates."""
    per_s = reference_cost.get("pieces", 0) / max(reference_cost.get("machine_s", 0.0), 1e-9)
    longest: dict = {}
    for rd in rds:
        key = _run_key(rd, replayed)
        longest[key] = max(longest.get(key, 0.0), rd.model.horizon_s)
    return per_s * sum(longest.values())


class PlantVariants:
    """The plant's air per run for machine files changed by effects. A variant is a
    tuple of (effect name, quantised values) pairs, applied in order with the effects'
    ``to_machine`` to the nominal file's data; :meth:`ensure` sets each run's
    :attr:`~plcpred.diagnose.fit_model.RunModel.variant_cells` (the plant's cells less the
    nominal D1 cells, as the reference's are) for it."""

    def __init__(self, machine, mm, rds, bases, program=None, compiled=None):
        self.machine = machine
        self.mm = mm
        self.rds = rds
        self.program = program
        self.compiled = compiled
        self.data = read_machine_data(machine.path)
        if dataclasses.replace(machine_from_data(self.data, machine.path), warnings=[]) \
                != dataclasses.replace(machine, warnings=[]):
            # a variant is the file changed by an effect: a machine changed in memory
            # after loading would lose its changes
            raise PlcpredError(f"{machine.path.name}: the machine differs from its file")
        self.made = 0
        # integration pieces the plant ran, per effect (the last of a variant's)
        self.pieces: dict[str, int] = {}
        self._kept: OrderedDict = OrderedDict()
        self._d1 = [rd.model.total_cells(dataclasses.replace(b, dynamic=False, variant=()))
                    for rd, b in zip(rds, bases)]

    def machine_of(self, variant):
        data = copy.deepcopy(self.data)
        for name, values in variant:
            PLANT_FORMS[name].inner.to_machine(self.mm, data, np.asarray(values, float))
        return machine_from_data(data, self.machine.path)

    def ensure(self, variant: tuple) -> None:
        """Give every run its cells for ``variant`` (``()``: the nominal machine, which
        the reference made). Raises PlcpredError where the plant cannot run it."""
        if not variant:
            return
        if variant in self._kept:
            self._kept.move_to_end(variant)
            return

        effect = variant[-1][0]
        spent = self.pieces.get(effect, 0)
        if spent >= MAX_EFFECT_PIECES:
            raise PlcpredError(f"its budget of {MAX_EFFECT_PIECES:,} integration pieces "
                               f"in the plant is spent ({self.made} values run)")
        self.made += 1
        machine = self.machine_of(variant)
        replayed = self.program is None
        shared: dict = {}
        for rd, d1 in zip(self.rds, self._d1):
            shared.setdefault(_run_key(rd, replayed), []).append((rd, d1))
        stats: dict = {}
        for runs in shared.values():
            # the variant's own cycle: its period is not the prediction's
            cells = shared_run_cells_nl(machine, [rd.model.edges_s for rd, _ in runs],
                                        runs[0][0].model.timeline, self.program,
                                        self.compiled, stats)
            for (rd, d1), c in zip(runs, cells):
                rd.model.variant_cells[variant] = c - d1
        self.pieces[effect] = spent + stats.get("pieces", 0)
        self._kept[variant] = True
        cells = sum(rd.model.n_cells for rd in self.rds)
        while len(self._kept) > max(8, KEPT_CELLS // max(cells, 1)):
            old, _ = self._kept.popitem(last=False)
            for rd in self.rds:
                rd.model.variant_cells.pop(old, None)


class ThroughPlant(Effect):
    """``inner`` with its values written into the machine file and run through the
    plant (:mod:`~plcpred.diagnose.through_plant`): its parameters, units, physical
    values and machine-file changes are ``inner``'s."""

    joint = True        # the drives' values also swept as one (every valve later)
    through_plant = True

    def __init__(self, inner: Effect):
        self.inner = inner
        self.name = inner.name
        self.title = inner.title + " (through the plant)"

    def applies(self, mm):
        return mm.plant_variants is not None and self.inner.applies(mm)

    def grid(self, mm, k: int, param: Param) -> tuple:
        return param.grid

    def quantise(self, mm, theta) -> tuple:
        raise NotImplementedError

    def params(self, mm, ctx):
        out = []
        for k, p in enumerate(self.inner.params(mm, ctx)):
            out.append(dataclasses.replace(p, grid=self.grid(mm, k, p), discrete=True,
                                           plant=True, joint=self.joint))
        return out

    def apply(self, mm, p, theta):
        values = self.quantise(mm, theta)
        q = p.copy()
        q.dynamic = True
        q.variant = tuple(x for x in p.variant if x[0] != self.name)
        if any(abs(v - n) > 1e-12 for v, n in zip(values, self.neutral(mm))):
            q.variant += ((self.name, values),)
        mm.plant_variants.ensure(q.variant)
        return q

    def neutral(self, mm) -> tuple:
        # the file's own values (these effects' parameters do not read the context)
        return self.quantise(mm, [p.init for p in self.inner.params(mm, {})])

    def physical(self, mm, theta):
        return self.inner.physical(mm, self.quantise(mm, theta))

    def implausible(self, mm, theta):
        return self.inner.implausible(mm, self.quantise(mm, theta))

    def within_tolerance(self, mm, theta, ctx):
        return self.inner.within_tolerance(mm, self.quantise(mm, theta), ctx)

    def tolerance_box(self, mm, ctx):
        return self.inner.tolerance_box(mm, ctx)

    def to_machine(self, mm, data, theta):
        return self.inner.to_machine(mm, data, np.asarray(self.quantise(mm, theta)))


class _SupplyThroughPlant(ThroughPlant):
    def grid(self, mm, k, param):
        p = mm.machine.supply_bar_g
        return tuple(round(p * f, 2) for f in SUPPLY_GRID)

    def quantise(self, mm, theta):
        return (round(round(float(theta[0]) / SUPPLY_QUANTUM_BAR) * SUPPLY_QUANTUM_BAR, 4),)


def _known_dead_cm3(mm, k: int) -> float:
    c = mm.machine.consumers[mm.drives[k]]
    known = min(tube_volumes_cm3(c)) + float(np.mean(inner_dead_volumes_cm3(c)))
    return max(MIN_DEAD_VOLUME_CM3, known)


class _DeadVolumeThroughPlant(ThroughPlant):
    joint = False       # cm^3 of different drives: not one value for all

    def grid(self, mm, k, param):
        v = _known_dead_cm3(mm, k)
        return tuple(round(v * f, 3) for f in DEAD_VOLUME_GRID)

    def quantise(self, mm, theta):
        out = []
        for k, v in enumerate(theta):
            q = DEAD_VOLUME_QUANTUM * _known_dead_cm3(mm, k)
            out.append(round(round(float(v) / q) * q, 4))
        return tuple(out)


class _DelayThroughPlant(ThroughPlant):
    def grid(self, mm, k, param):
        return CLOSED_DELAY_GRID_S

    def quantise(self, mm, theta):
        return tuple(quantise_delay(float(d)) for d in theta)


class _StrokeThroughPlant(ThroughPlant):
    def grid(self, mm, k, param):
        return CLOSED_FACTOR_GRID

    def quantise(self, mm, theta):
        return tuple(round(quantise_factor(float(f)), 6) for f in theta)


PLANT_FORMS: dict[str, ThroughPlant] = {e.name: e for e in (
    _SupplyThroughPlant(SupplyPressure()), _DeadVolumeThroughPlant(DeadVolume()),
    _DelayThroughPlant(ValveDelay()), _StrokeThroughPlant(StrokeTime()))}
