"""A log read far along a given clock is rendered over its own window, not from the
machine's start: the diagnosis' run model (:class:`RunModel` with ``start_s``) and the
plant's cells on a grid that starts late (a cycling machine's plant is integrated whole
periods earlier). Each windowed result is checked against the same quantity rendered
from the machine's start."""
import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from plcpred.diagnose.fit_model import RENDER_LEAD_S, MachineModel, RunModel, render_start_s
from plcpred.machine import as_machine
from plcpred.plant.replay import (
    SETTLE_PERIODS,
    closed_loop_total_cells_nl,
    replay_total_cells_nl,
)
from plcpred.sequencer import unfold

ROOT = Path(__file__).resolve().parents[2]
PICK = ROOT / "samples" / "pick_place.toml"
DT_S = 0.01


@pytest.fixture(scope="module")
def pick():
    machine = as_machine(PICK)
    return machine, MachineModel.of(machine), unfold(machine, 160.0)


def _params(mm: MachineModel):
    """The nominal numbers with every piece a window could cut wrong switched on: a
    refill, exhausts, strokes cut short, a meter lag, a clock adjustment and a leak that
    opens inside the window."""
    p = mm.nominal(meter_tau_s=0.4)
    p.refill_fraction, p.refill_tau_s = 0.2, 0.5
    p.exhaust_tau_s[:] = 0.05
    p.partial_strokes[:] = True
    p.extra_leak_l_min, p.extra_leak_from_s = 12.0, 131.3
    return dataclasses.replace(p, clock_adjust_s=0.27)


def test_a_window_renders_only_its_cells_and_the_same_readings(pick):
    _, mm, tl = pick
    full = RunModel(mm, tl, DT_S)
    start = render_start_s(125.0)
    window = RunModel(mm, tl, DT_S, start)
    assert start == pytest.approx(125.0 - RENDER_LEAD_S)
    assert window.start_s == pytest.approx(start) and window.edges_s[0] == window.start_s
    assert window.n_cells == math.ceil((tl.horizon_ns / 1e9 - start) / DT_S)
    assert full.n_cells - window.n_cells == round(start / DT_S)
    k0 = round(window.start_s / DT_S)
    params = _params(mm)
    assert np.allclose(window.edges_s, full.edges_s[k0:])
    # the same cells once the tails of what the window leaves out (a refill begun
    # before it, 0.5 s) have died away: the lead before the first reading covers them
    settled = round(20.0 / DT_S)
    assert np.allclose(window.total_cells(params)[settled:],
                       full.total_cells(params)[k0 + settled:], rtol=0, atol=1e-12)
    # readings of a log from 125 s on: a mean meter and instantaneous ones
    ends = np.arange(125.5, 159.0, 0.5)
    for starts in (ends - 0.5, ends - 0.01):
        assert np.allclose(window.readings(params, starts, ends),
                           full.readings(params, starts, ends), rtol=0, atol=1e-9)


def test_a_window_keeps_only_the_transitions_that_reach_into_it(pick):
    """Each evaluation costs what the window holds: a drive's transitions from the two
    before the window on (a stroke under way at its start), none past its end; and a
    recorded trace running on past what is read ends the grid at ``end_s``."""
    _, mm, tl = pick
    full = RunModel(mm, tl, DT_S)
    window = RunModel(mm, tl, DT_S, 100.0, end_s=130.0)
    assert window.horizon_s == 130.0 and window.edges_s[-1] == 130.0
    assert window.n_cells == round(30.0 / DT_S)
    for (t_full, _), (t_win, _) in zip(full.transitions, window.transitions):
        inside = t_full[(t_full >= 100.0) & (t_full <= 130.0)]
        assert 0 < len(inside) <= len(t_win) <= len(inside) + 3 < len(t_full) / 3
        assert t_win[0] < 100.0 and t_win[-1] >= inside[-1]
    params = _params(mm)
    params.extra_leak_from_s = 111.3
    k0, k1 = round(100.0 / DT_S), round(130.0 / DT_S)
    settled = round(10.0 / DT_S)
    assert np.allclose(window.total_cells(params)[settled:],
                       full.total_cells(params)[k0 + settled:k1], rtol=0, atol=1e-12)


def test_a_window_starts_on_whole_cells_within_the_horizon(pick):
    _, mm, tl = pick
    rm = RunModel(mm, tl, 0.02, 123.456)
    assert rm.start_s == pytest.approx(123.44) and rm.edges_s[-1] == tl.horizon_ns / 1e9
    assert RunModel(mm, tl, DT_S, 1e9).n_cells == 1
    assert RunModel(mm, tl, DT_S, -5.0).start_s == 0.0
    assert render_start_s(40.0) == 0.0


@pytest.mark.parametrize("closed_loop", [False, True])
def test_the_plant_on_a_late_grid_integrates_a_few_periods_only(pick, closed_loop):
    """Far along a tiled timeline the plant's cells are those of a grid whole periods
    earlier, and the plant integrates no more than it does for that grid."""
    machine, _, tl = pick
    period = tl.info["period_s"]
    settled = tl.info["tiled_from_s"] + SETTLE_PERIODS * period

    def cells(start_s: float, span_s: float, stats: dict) -> np.ndarray:
        edges = start_s + np.arange(round(span_s / DT_S) + 1) * DT_S
        if closed_loop:
            return closed_loop_total_cells_nl(machine, tl, edges, machine.read_program(),
                                              stats=stats)
        return replay_total_cells_nl(machine, tl, edges, stats)

    near, far = {}, {}
    whole = math.ceil(settled / period) * period
    c_near = cells(whole, period, near)
    c_far = cells(whole + 1000 * period, period, far)
    assert np.allclose(c_far, c_near, rtol=1e-9, atol=1e-12)
    # (from the machine's start to the far grid: a thousand periods of plant)
    assert far["pieces"] <= 1.2 * near["pieces"]


def test_a_log_far_along_a_given_clock_is_diagnosed_on_its_window():
    """A pick-and-place log at 35 days of machine time, given with ``--offset``: the
    diagnosis renders its window (and the meter's settling before it), not the 35 days
    from the machine's start (found by bench/fuzz.py: a log at 3,000,000 s with
    --offset 5 ran for minutes)."""
    from plcpred.diagnose import MeasuredRun, diagnose

    machine = as_machine(PICK)
    far_s = 3_000_000.0
    prediction = unfold(machine, 80.0)
    mm = MachineModel.of(machine)
    rm = RunModel(mm, prediction, DT_S)
    ends = np.arange(1.0, 80.0, 0.5)
    flow = rm.readings(mm.nominal(0.2), ends - 0.5, ends) + 4.0     # a 4 NL/min leak
    # the machine repeats every 4 s: the same readings a whole number of cycles later
    run = MeasuredRun("far.csv", ends + far_s + 5.0, flow)
    d = diagnose(machine, [run], offsets=[5.0], effects=["leak"], dynamic=False)
    model = d.runs[0].model
    assert model.start_s >= far_s - 200.0 and model.n_cells < 30_000
    assert d.verdict == "leak"
    assert d.effects[0].physical["flow_l_min"] == pytest.approx(4.0, rel=0.1)
