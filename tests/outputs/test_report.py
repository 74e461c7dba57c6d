"""The plots and the diagnosis report say what the data say: checked through the arrays
they draw (the small helpers of plcpred.outputs' plot modules), not through pixels."""
import copy
import dataclasses
import itertools
import re
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import SAMPLES

from plcpred.air import predict
from plcpred.air.sizing import receiver_deficit, size_prediction
from plcpred.diagnose import diagnose, read_measured
from plcpred.machine import load_machine, machine_from_data, read_machine_data
from plcpred.outputs.diagnosis_report import (
    SIGN_NOTE,
    diagnosis_conclusion,
    diagnosis_html,
    gap_cost,
    how_sure_rows,
    logger_axis,
    plot_diagnosis,
)
from plcpred.outputs.emulation_plot import (
    emulation_view,
    plot_emulation,
    predicted_flow_l_min,
    time_bins_mean,
    zoom_window,
)
from plcpred.outputs.plotting import envelope
from plcpred.outputs.sizing_report import plot_sizing, sizing_windows, window_layers
from plcpred.plant import emulate

PICK_PLACE = SAMPLES / "pick_place.toml"
SORTER = SAMPLES / "sorter.toml"
RIG = SAMPLES / "prototype_rig" / "rig.toml"
RIG_NOLEAK = SAMPLES / "prototype_rig" / "rig_noleak.toml"


@pytest.fixture(scope="module")
def pick_place_emulated():
    """Three 4 s cycles of the pick-and-place in the plant, and their prediction."""
    em = emulate(PICK_PLACE, "12s", seed=1)
    return em, predict(load_machine(PICK_PLACE), em.horizon_s).profile


@pytest.fixture(scope="module")
def rig_diagnosis():
    """The rig's logged leak, diagnosed quickly (two effects, no plant)."""
    runs = [read_measured(SAMPLES / "prototype_rig" / "seq1_measured.csv")]
    return diagnose(load_machine(RIG_NOLEAK), runs, effects=["leak", "meter_gain"],
                    dynamic=False)


# ------------------------------------------------------------------------ emulate.png

def test_envelope_keeps_a_drives_full_stroke(pick_place_emulated):
    """A bin's mean of the X slide's position is a place it never stands; the band's top
    is its stroke, in the plot's bins and in bins of a whole cycle alike."""
    em, pred = pick_place_emulated
    v = emulation_view(em, predicted=pred)
    x = v.series("X slide_position_mm")
    assert v.k > 1
    assert v.horizon(x).hi.max() == pytest.approx(x.max())
    assert x.max() == pytest.approx(200.0, abs=1.0)
    per_cycle = envelope(v.rows[:, 0], x, round(4.0 / v.dt_s))
    assert per_cycle.hi[:3] == pytest.approx([200.0] * 3, abs=1.0)
    assert per_cycle.mean.max() < 120.0         # what the old plot drew as the stroke


def test_zoom_spans_one_cycle_from_its_first_stroke(pick_place_emulated):
    em, pred = pick_place_emulated
    v = emulation_view(em, predicted=pred)
    assert v.period_s == pytest.approx(4.0)
    a, b = v.zoom
    assert b - a == pytest.approx(4.0)
    assert em.horizon_s - 8.0 <= a and b <= em.horizon_s + 1e-9
    sel = v.in_zoom()
    total = v.series("total_l_min")[sel]
    # it starts quiet (only the leak) and holds the X slide's whole stroke
    assert total[0] <= total.min() + 0.05 * (np.percentile(total, 95) - total.min())
    assert v.series("X slide_position_mm")[sel].max() == pytest.approx(200.0, abs=1.0)


def test_zoom_window_on_a_known_cycle():
    """Pulses from 1.0 to 1.5 s of every 4 s: the window opens just before one."""
    t = np.arange(0.0, 20.0, 0.01)
    flow = 3.0 + 100.0 * ((t % 4.0 >= 1.0) & (t % 4.0 < 1.5))
    a, b = zoom_window(t, flow, 20.0, 4.0)
    assert (a, b) == pytest.approx((12.8, 16.8), abs=0.02)
    assert zoom_window(t, flow, 20.0, 12.0) is None      # not two periods
    assert zoom_window(t, flow, 20.0, None) is None      # no cycle


def test_prediction_overlaid_is_the_predictions_air(pick_place_emulated):
    em, pred = pick_place_emulated
    v = emulation_view(em, predicted=pred)
    assert np.sum(v.predicted_l_min) * v.dt_s / 60.0 == pytest.approx(pred.total_nl, rel=1e-6)
    edges = np.linspace(0.0, em.horizon_s, 7)
    flow = predicted_flow_l_min(pred, edges)
    assert np.sum(flow * np.diff(edges) / 60.0) == pytest.approx(pred.total_nl, rel=1e-9)


def test_meter_means_per_bin():
    t, mean = time_bins_mean([0.1, 0.2, 1.1, 2.5, 2.6], [1.0, 3.0, 5.0, 7.0, 9.0], 1.0, 4.0)
    assert list(t) == [0.0, 1.0, 2.0, 3.0]
    assert list(mean[:3]) == [2.0, 5.0, 8.0] and np.isnan(mean[3])


def test_emulation_plot_is_written(pick_place_emulated, tmp_path):
    em, pred = pick_place_emulated
    plot_emulation(em, tmp_path / "e.png", predicted=pred)
    assert (tmp_path / "e.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


# ------------------------------------------------------------------------- sizing.png

@pytest.fixture(scope="module")
def pick_place_sized():
    r = predict(load_machine(PICK_PLACE), "61s")
    return r.profile, size_prediction(r)


def _deficit(profile, s):
    return receiver_deficit(profile.total_flow_l_min, profile.dt_s, s.design_flow_l_min)[2]


def test_air_per_cycle_adds_up_to_the_total(pick_place_sized):
    profile, s = pick_place_sized
    w = sizing_windows(profile, s, _deficit(profile, s), k=1)
    assert w.what == "cycle" and w.width_s == pytest.approx(s.cycle_s)
    assert w.total_nl == pytest.approx(profile.total_nl, rel=1e-9)
    assert (w.n, w.n_whole) == (16, 15)                 # 61 s: 15 cycles and a second
    cut_nl = np.diff(profile.cumulative_nl_at([60.0, 61.0]))[0]
    assert w.env.mean.sum() + cut_nl == pytest.approx(profile.total_nl, rel=1e-9)
    # a steady machine: every whole cycle takes the steady air per cycle
    assert w.env.mean[1:] == pytest.approx(s.nl_per_cycle, rel=1e-3)
    # the receiver is sized on the largest deficit of any cycle, each cycle counted once
    assert w.deficit_max_nl == pytest.approx(s.deficit_nl, rel=1e-9)
    assert w.deficit_counts.sum() == 16


def test_a_machine_without_a_cycle_is_cut_in_windows():
    r = predict(load_machine(RIG), "20s")
    s = size_prediction(r)
    w = sizing_windows(r.profile, s, _deficit(r.profile, s))
    assert w.what == "window" and w.n == w.n_whole == 20
    assert w.total_nl == pytest.approx(r.profile.total_nl, rel=1e-9)
    assert w.deficit_max_nl == pytest.approx(s.deficit_nl, rel=1e-9)


def _windows_one_by_one(profile, s, deficit, width):
    """What the sizing plot draws, from every window's own numbers (as it was drawn
    before the windows were reduced in chunks): starts, values and whether whole, each
    one's largest deficit, and the histogram's bins."""
    horizon = profile.horizon_s
    edges = np.append(np.arange(0.0, horizon - 1e-9 * horizon, width), horizon)
    nl = np.diff(profile.cumulative_nl_at(edges))
    whole = np.diff(edges) >= width * (1 - 1e-6)
    cell_end = profile.edges_s[1:]
    largest = []
    for a, b in itertools.pairwise(edges):
        # the cells whose end lies in the window, or the one that holds it
        lo = min(np.searchsorted(cell_end, a, side="right"), len(deficit) - 1)
        hi = len(deficit) if b == horizon else np.searchsorted(cell_end, b, side="right")
        largest.append(deficit[lo:max(hi, lo + 1)].max())
    largest = np.array(largest)
    top = max(largest.max(), s.deficit_nl, 1e-9)
    return edges[:-1], nl, whole, largest, np.linspace(0.0, top * 1.05, 43)


def _jittered_sorter(dt_s):
    """The sorter with parts that come up to 0.1 s early or late (every 1.2 s, every
    third metal): windows of 4 s or a minute hold different parts, no two alike."""
    data = read_machine_data(SORTER)
    for t in data["input"]:
        t["jitter_s"] = 0.1
    r = predict(machine_from_data(data, SORTER), "1203s", dt=dt_s)
    return r.profile, size_prediction(r)


@pytest.mark.parametrize("dt_s", [None, 10.0])      # cells shorter and longer than a window
@pytest.mark.parametrize("cycle_s,k", [(4.0, 7), (None, 3)])    # 4 s windows, minutes
def test_windows_reduced_in_chunks_draw_what_the_windows_one_by_one_do(dt_s, cycle_s, k):
    profile, s = _jittered_sorter(dt_s)
    assert s.cycle_s is None                # jittered: sized without a steady cycle
    s = dataclasses.replace(s, cycle_s=cycle_s)
    deficit = _deficit(profile, s)
    width = cycle_s or 60.0
    start, nl, whole, largest, hist_bins = _windows_one_by_one(profile, s, deficit, width)
    values = nl[whole] if cycle_s else nl[whole] / width * 60.0
    env = envelope(start[whole], values, k)
    # the case the chunks must get right: windows that differ, a last one cut, groups
    # of k with a shorter last one, deficits spread over the histogram
    assert not whole[-1] and whole[:-1].all() and whole.sum() % k
    assert values.max() > 1.05 * values.min()
    assert np.count_nonzero(np.histogram(largest, hist_bins)[0]) > 3
    for chunk in (None, 5 * k + 1, 1):                  # one chunk, several, a group each
        w = sizing_windows(profile, s, deficit, k=k, chunk=chunk)
        assert (w.what, w.width_s, w.k) == ("cycle" if cycle_s else "minute", width, k)
        assert (w.n, w.n_whole) == (len(nl), whole.sum())
        assert np.array_equal(w.env.t_s, env.t_s)
        for got, expected in ((w.env.lo, env.lo), (w.env.mean, env.mean),
                              (w.env.hi, env.hi)):
            assert np.array_equal(got, expected), chunk
        assert (w.least, w.greatest) == (values.min(), values.max())
        assert w.mean == pytest.approx(values.mean(), rel=1e-12)
        assert w.total_nl == pytest.approx(nl.sum(), rel=1e-12)
        assert w.deficit_max_nl == largest.max()
        assert np.array_equal(w.deficit_bins_nl, hist_bins)
        assert np.array_equal(w.deficit_counts, np.histogram(largest, hist_bins)[0])
        whole_edges = np.append(start[whole], start[whole][-1] + width)
        assert np.array_equal(w.groups_s, np.append(whole_edges[::k], whole_edges[-1]))
    # in one chunk, the mean is the windows' mean to the last bit
    w = sizing_windows(profile, s, deficit, k=k)
    assert w.mean == values.mean()


def test_sizing_plot_is_written(pick_place_sized, tmp_path):
    profile, s = pick_place_sized
    plot_sizing(profile, s, tmp_path / "s.png", title="<b>$x$</b>")
    assert (tmp_path / "s.png").stat().st_size > 10_000


# ---------------------------------------------------------------------- diagnose.html

def _text(page: str) -> str:
    """The page without its tags and embedded pictures."""
    return re.sub(r"<[^>]+>", " ", re.sub(r"src='data:[^']*'", "", page))


def test_html_opens_with_the_conclusion(rig_diagnosis):
    d = rig_diagnosis
    page = diagnosis_html(d, None, figures={})
    body = page[page.index("<body>"):]
    first = re.search(r"<p[^>]*>(.*?)</p>", body, re.DOTALL)
    assert "class='conclusion'" in first.group(0)
    assert "leak of about 9.9 NL/min" in first.group(1)
    assert "kWh" in first.group(1)
    assert body.index("conclusion") < body.index("How sure") < body.index("<pre>")


def test_html_holds_the_held_out_figures_signed_one_way(rig_diagnosis):
    d = rig_diagnosis
    text = _text(diagnosis_html(d, None, figures={}))
    before, after = d.baseline_heldout, d.combination["heldout"]
    assert d.baseline.measured_nl > d.baseline.predicted_nl
    # measured - predicted: the meter reads more, so the gap is positive
    assert f"+{-before.error_pct:.1f} %" in text
    assert f"{before.rmse_l_min:.2f} NL/min" in text and f"{after.rmse_l_min:.2f} NL/min" in text
    assert SIGN_NOTE in text
    rows = dict(how_sure_rows(d))
    assert "95 %" in rows["fitted flow_l_min"]


def test_html_escapes_what_comes_from_files(rig_diagnosis):
    d = copy.copy(rig_diagnosis)
    d.machine = copy.copy(d.machine)
    d.machine.name = "<script>alert(1)</script>"
    page = diagnosis_html(d, b"not a png", figures={})
    assert "<script>" not in page
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in page


def test_the_logger_clock_is_named(rig_diagnosis):
    rd = rig_diagnosis.runs[0]
    t, origin, label = logger_axis(rd)
    assert origin == 0.0 and t == pytest.approx(rd.end_s + rd.offset_s)
    assert "logger's clock" in label and "time_s" in label


def test_a_leak_costs_what_its_air_does(rig_diagnosis):
    machine = rig_diagnosis.machine
    c = gap_cost(machine, 10.0, always_on=True)
    assert machine.calendar is None and c.hours == 4000.0
    assert c.nm3 == pytest.approx(10.0 * 60 * 4000 / 1000)
    assert c.kwh == pytest.approx(c.nm3 * c.sec_kwh_per_nm3)
    assert c.cost == pytest.approx(c.kwh * c.price)
    text, cost = diagnosis_conclusion(rig_diagnosis)
    assert f"{cost.kwh:,.0f} kWh" in text


def test_diagnosis_pictures(rig_diagnosis, tmp_path):
    plot_diagnosis(rig_diagnosis, tmp_path / "d.png")
    page = diagnosis_html(rig_diagnosis, (tmp_path / "d.png").read_bytes())
    assert page.count("data:image/png;base64,") == 3


def test_air_per_cycle_by_consumer_adds_up(pick_place_sized):
    profile, s = pick_place_sized
    deficit = _deficit(profile, s)
    w = sizing_windows(profile, s, deficit, k=1)
    groups, _, stacks = window_layers(profile, w)
    assert len(groups) == w.n_whole + 1
    assert stacks.sum(axis=0) == pytest.approx(w.env.mean, rel=1e-9)
    w4 = sizing_windows(profile, s, deficit, k=4)
    grouped = window_layers(profile, w4)[2].sum(axis=0)    # mean per cycle of 4
    assert len(grouped) == 4                                # 15 cycles: 4, 4, 4, 3
    assert grouped == pytest.approx(w4.env.mean, rel=1e-9)
    assert grouped[0] == pytest.approx(w.env.mean[:4].mean(), rel=1e-9)
    assert grouped[-1] == pytest.approx(w.env.mean[12:].mean(), rel=1e-9)


def test_a_date_time_clock_is_shown_from_its_first_reading():
    """A log stamped with dates: its clock in seconds since 1970 would read 1.7e9 s."""
    run = SimpleNamespace(source={"time_format": "%Y-%m-%d %H:%M:%S", "time_column": "Zeit"})
    start = 1_700_000_000.0                         # 2023-11-14 22:13:20
    rd = SimpleNamespace(run=run, offset_s=start, end_s=np.array([1.0, 2.0, 3.0]),
                         weight_s=np.array([1.0, 1.0, 1.0]))
    t, origin, label = logger_axis(rd)
    assert origin == start and list(t) == [1.0, 2.0, 3.0]
    assert "2023-11-14 22:13:20" in label and "'Zeit'" in label


@pytest.mark.parametrize("verdict", ["none", "unexplained", "meter_gain"])
def test_every_verdict_reads(rig_diagnosis, verdict):
    d = copy.copy(rig_diagnosis)
    d.verdict = verdict
    d.combination = None if verdict != "meter_gain" else d.combination
    text, cost = diagnosis_conclusion(d)
    assert text.startswith("The meter reads 6.99 NL more")
    if verdict == "none":
        assert "no fault" in text and cost is None
    elif verdict == "unexplained":
        assert "idle" in text and cost is None
    else:
        assert "flow meter reading high or low" in text and cost.kwh > 0
    assert "How sure" in diagnosis_html(d, None, figures={})


def test_rows_written_in_blocks_are_savetxts_bytes():
    import io

    from plcpred.outputs.files import ROWS_PER_WRITE, write_rows
    rng = np.random.default_rng(5)
    rows = rng.normal(0.0, 1e3, (2 * ROWS_PER_WRITE + 17, 5))
    rows[3, 1], rows[4, 2], rows[5, 0] = np.nan, np.inf, -0.0
    rows[6] = [1e-9, 1e12, -123456789.0, 0.5, 7.0]
    for fmt in ("%.6g", "%.4f"):
        want, got = io.StringIO(), io.StringIO()
        np.savetxt(want, rows, fmt=fmt, delimiter=",")
        write_rows(got, rows, fmt)
        assert got.getvalue() == want.getvalue(), fmt
    empty = io.StringIO()
    write_rows(empty, np.zeros((0, 3)), "%.4f")
    assert empty.getvalue() == ""
