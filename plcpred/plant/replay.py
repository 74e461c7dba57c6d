"""The physics plant driven open loop by an I/O timeline.

``emulate`` runs the program against the plant, so the plant's end switches move the
program's edges. :func:`replay` takes the edges as given (a prediction's, or a recorded
trace's) and only asks what air the machine draws when its valves switch then: the
dynamic model (D4, docs/reference/physics.md) on the air model's own valve edges. The diagnosis
uses it, or the program run against the plant without a meter
(:func:`closed_loop_total_cells_nl`), as the nominal machine's dynamic reference (what
D1 leaves out by design: the air a tube still holds at atmospheric pressure, heat,
exhausts and strokes cut short).
"""
from __future__ import annotations

import math

import numpy as np

from ..air.demand import consumer_models, passive_intervals, valve_transitions
from .emulate import run_closed_loop
from .model import PlantModel


def replay(machine, timeline, horizon_s: float | None = None) -> PlantModel:
    """The plant of ``machine`` with every valve switched when ``timeline`` switches it
    (the air model's mapping of signals to valves: single and double solenoids, a
    consumer's initial position), integrated to ``horizon_s`` (default the timeline's).
    Read it with :meth:`PlantModel.cumulative_nl` and :meth:`PlantModel.metered_names`.

    Raises :class:`~plcpred.physics.group.PlantError` where the plant cannot integrate."""
    horizon_s = timeline.horizon_ns / 1e9 if horizon_s is None else float(horizon_s)
    plant = PlantModel(machine)
    signal_map = timeline.info.get("machine_signals", {})
    commands: list[tuple[int, int, object, bool]] = []   # (t ns, order, adapter, on)
    for consumer, model in zip(machine.consumers, consumer_models(machine)):
        if model.role == "leak" or not model.valve:
            continue
        adapter = plant.adapter(consumer)
        if model.role == "active":
            t_ns, extend = valve_transitions(timeline, model, signal_map)
            commands += [(int(t), len(commands) + i, adapter, bool(e))
                         for i, (t, e) in enumerate(zip(t_ns, extend))]
        else:
            starts, ends = passive_intervals(timeline, model, signal_map)
            for s, e in zip(starts, ends):
                commands.append((int(s), len(commands), adapter, True))
                commands.append((int(e), len(commands), adapter, False))
    # a group takes its commands in time order (several drives may share one)
    commands.sort(key=lambda c: (c[0], c[1]))
    limit_ns = round(horizon_s * 1e9)
    for t_ns, _, adapter, on in commands:
        if t_ns <= limit_ns:
            adapter.command(t_ns, on)
    plant.finish(horizon_s)
    return plant


# periods the plant runs past the start of a repeating timeline before its cells are
# repeated: a chamber's temperature and a line's pressure settle within a cycle or two
SETTLE_PERIODS = 3


def _stop_cell(timeline, edges_s: np.ndarray) -> tuple[int, int, float]:
    """(cells to integrate, period in cells, shift s): all of them, or where a timeline
    that repeats one period from some time on (the sequencer's tiling) has repeated
    SETTLE_PERIODS times, when the period is a whole number of cells. A grid that
    starts later than that is integrated whole periods earlier (``shift``: what to
    take from its edges), where the plant draws the same: a log's window far along a
    cycling machine costs the plant no more than one near its start."""
    n = len(edges_s) - 1
    if timeline is None:
        return n, 0, 0.0
    info = timeline.info
    period_s, tiled_s = info.get("period_s"), info.get("tiled_from_s")
    if period_s and tiled_s is not None and n > 1:
        # (far along, neighbouring edges differ by the step only to their magnitude's
        # rounding: the step from the whole grid)
        dt_s = float(edges_s[1] - edges_s[0]) if not edges_s[0] or n < 3 \
            else float(edges_s[n - 1] - edges_s[0]) / (n - 1)
        period_cells = round(period_s / dt_s)
        if period_cells and abs(period_s / dt_s - period_cells) < 1e-6:
            settled_s = tiled_s + SETTLE_PERIODS * period_s
            shift_s = max(0, math.floor((float(edges_s[0]) - settled_s) / period_s)) \
                * period_s
            stop = max(int(np.ceil((settled_s - (float(edges_s[0]) - shift_s)) / dt_s)),
                       period_cells)
            return (stop, period_cells, shift_s) if stop < n else (n, 0, shift_s)
    return n, 0, 0.0


def _count(stats: dict | None, plant, horizon_s: float) -> None:
    """Add a run's integration pieces and integrated seconds to ``stats`` (what a plant
    run of this machine costs, counted the same on every computer)."""
    if stats is not None:
        stats["pieces"] = stats.get("pieces", 0) + sum(len(g.pieces) for g in plant.groups)
        stats["machine_s"] = stats.get("machine_s", 0.0) + horizon_s


def _metered_cells(plant, edges_s, n: int, period_cells: int) -> np.ndarray:
    cumulative = plant.cumulative_nl(edges_s)
    cells = np.diff(sum(cumulative[name] for name in plant.metered_names()))
    if len(cells) < n:
        cells = np.concatenate([cells, np.resize(cells[len(cells) - period_cells:],
                                                 n - len(cells))])
    return cells


def replay_total_cells_nl(machine, timeline, edges_s: np.ndarray,
                          stats: dict | None = None) -> np.ndarray:
    """Normal litres per grid cell (between ``edges_s``, uniform) through the machine's
    meter point when the plant is driven by ``timeline`` (:func:`replay`). A timeline
    that repeats one period from some time on (the sequencer's tiling) is run
    SETTLE_PERIODS periods past that time and its cells repeated from there, when the
    period is a whole number of cells: an hour's log costs a minute of plant. ``stats``
    (a dict) counts the run's cost (:func:`_count`)."""
    edges_s = np.asarray(edges_s, dtype=float)
    stop, period_cells, shift_s = _stop_cell(timeline, edges_s)
    run_edges_s = edges_s[:stop + 1] - shift_s
    plant = replay(machine, timeline, float(run_edges_s[-1]))
    _count(stats, plant, float(run_edges_s[-1] - run_edges_s[0]))
    return _metered_cells(plant, run_edges_s, len(edges_s) - 1, period_cells)


def closed_loop_total_cells_nl(machine, timeline, edges_s: np.ndarray, program,
                               compiled=None, stats: dict | None = None) -> np.ndarray:
    """As :func:`replay_total_cells_nl`, but with the program running against the plant
    (as ``emulate`` does, without a meter): its end switches move the edges where the
    program waits on them. ``timeline`` is the sequencer's own prediction, for its
    period (None: the whole horizon is run, for a machine whose cycle is not the
    prediction's); ``program`` the parsed program (``compiled``: its compiled form)."""

    edges_s = np.asarray(edges_s, dtype=float)
    stop, period_cells, shift_s = _stop_cell(timeline, edges_s)
    run_edges_s = edges_s[:stop + 1] - shift_s
    plant, _ = run_closed_loop(machine, program, float(run_edges_s[-1]), compiled)
    _count(stats, plant, float(run_edges_s[-1] - run_edges_s[0]))
    return _metered_cells(plant, run_edges_s, len(edges_s) - 1, period_cells)


def shared_run_cells_nl(machine, edges_s: list[np.ndarray], timeline=None, program=None,
                        compiled=None, stats: dict | None = None) -> list[np.ndarray]:
    """Normal litres per cell through the meter point for each grid of ``edges_s`` (each
    from the run's start or later on), from one plant run to the longest: driven by
    ``timeline``'s edges (:func:`replay`), or with ``program`` given, the program run
    against the plant from its start (a run's first seconds do not depend on how long it
    goes on). Nothing is tiled: the machine's cycle need not be any prediction's.
    ``stats`` counts the run's cost (:func:`_count`)."""

    edges_s = [np.asarray(e, dtype=float) for e in edges_s]
    horizon_s = max(float(e[-1]) for e in edges_s)
    if program is not None:
        plant, _ = run_closed_loop(machine, program, horizon_s, compiled)
    else:
        plant = replay(machine, timeline, horizon_s)
    _count(stats, plant, horizon_s - min(float(e[0]) for e in edges_s))
    return [_metered_cells(plant, e, len(e) - 1, 0) for e in edges_s]
