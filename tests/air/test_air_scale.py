"""Demand of wide machines: the profile kept per stroke, read on any grid and in
stretches, and the outputs that group consumers beyond the largest few."""
import csv
import json
import subprocess
import sys

import numpy as np
import pytest

from plcpred.air import default_dt, predict
from plcpred.air.demand import rectangles_cumulative_nl
from plcpred.air.predict import csv_columns
from plcpred.outputs.files import write_demand_csv

N_VALVES = 17


def wide_machine(tmp_path, n=N_VALVES, period_ms=700):
    """``n`` cylinders of different bores, each toggled by its own timer (cylinder k every
    ``period_ms + 37 k`` ms), a nozzle on while cylinder 0 is out, and a leak."""
    decl = ["PROGRAM Wide", "VAR"] + [f"  q{k} : BOOL; t{k} : TON;" for k in range(n)] + [
        "  qBlow : BOOL;", "END_VAR"]
    body = []
    for k in range(n):
        body += [f"t{k}(IN := NOT t{k}.Q, PT := T#{period_ms + 37 * k}MS);",
                 f"IF t{k}.Q THEN q{k} := NOT q{k}; END_IF"]
    body.append("qBlow := q0;")
    (tmp_path / "wide.st").write_text("\n".join(decl + body + ["END_PROGRAM", ""]))
    toml = ['[machine]', 'name = "wide"', 'program = "wide.st"', "scan_ms = 5",
            "supply_bar_g = 6.0"]
    for k in range(n):
        toml += ["", "[[consumer]]", f'name = "cyl {k}"', 'kind = "double_acting"',
                 f"bore_mm = {12 + 4 * k}", f"rod_mm = {4 + k}", "stroke_mm = 100",
                 f'valve = "q{k}"', "stroke_time_s = [0.21, 0.17]", "switch_delay_s = 0.01"]
    toml += ["", "[[consumer]]", 'name = "blow"', 'kind = "nozzle"', 'valve = "qBlow"',
             "orifice_mm = 1.2", "Cd = 0.8",
             "", "[[consumer]]", 'name = "leak"', 'kind = "leak"', "orifice_mm = 0.5", "Cd = 0.6"]
    path = tmp_path / "wide.toml"
    path.write_text("\n".join(toml) + "\n")
    return path


def read_csv(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], np.array(rows[1:], dtype=float)


def test_totals_are_the_same_at_every_grid_and_equal_the_grid_sums(tmp_path):
    m = wide_machine(tmp_path)
    r = predict(m, "20s", dt=0.01)
    base = r.profile.consumer_nl.copy()
    for dt in (0.003, 0.05, 0.7, 3.0):
        other = predict(m, "20s", dt=dt).profile
        assert np.array_equal(other.consumer_nl, base)          # from the strokes, not cells
        assert other.cell_nl.sum(axis=1) == pytest.approx(base, rel=1e-9, abs=1e-12)
        assert other.total_cell_nl.sum() == pytest.approx(base.sum(), rel=1e-12)


def test_csv_written_in_stretches_equals_the_exact_cumulative_on_the_whole_grid(tmp_path):
    m = wide_machine(tmp_path)
    prof = predict(m, "25s", dt=0.01).profile            # 2,500 cells
    write_demand_csv(prof, tmp_path / "all.csv", shown=None, values_per_write=1)   # 1,000-row stretches
    header, body = read_csv(tmp_path / "all.csv")
    assert header[2:] == [f"cyl_{k}_l_min" for k in range(N_VALVES)] + ["blow_l_min", "leak_l_min"]
    assert len(body) == 2500 and body[:, 0] == pytest.approx(np.arange(2500) * 0.01)
    edges = prof.edges_s
    for i, rect in enumerate(prof.rects):
        # each column against the differences of the exact cumulative volume, written
        # independently of the stretch-by-stretch placement
        expected = np.diff(rectangles_cumulative_nl(edges, *rect)) / 0.01 * 60
        assert body[:, 2 + i] == pytest.approx(expected, abs=2e-6), prof.names[i]
    assert body[:, 1] == pytest.approx(body[:, 2:].sum(axis=1), abs=1e-4)


def test_groups_read_in_pieces_equal_the_exact_cumulative(tmp_path, monkeypatch):
    # a group of consumers is read without merging its rectangles, and in pieces of
    # the grid when it holds many: each cell against the exact cumulative of them all
    from plcpred.air import demand

    prof = predict(wide_machine(tmp_path), "30s", dt=0.01).profile
    edges = prof.edges_s
    which = [0, 3, 5, 16, 18]                     # cylinders, the leak
    rects = [np.concatenate([prof.rects[i][k] for i in which]) for k in range(3)]
    expected = np.diff(rectangles_cumulative_nl(edges, *rects))
    whole = prof.cells_nl(which)
    monkeypatch.setattr(demand, "CELL_ITEMS", 7)    # a piece per 7 rectangles
    pieces = prof.cells_nl(which)
    assert whole == pytest.approx(expected, abs=1e-12)
    assert pieces == pytest.approx(expected, abs=1e-12)
    assert prof.cells_nl([4], edges[100:2001:3]) == pytest.approx(
        np.diff(rectangles_cumulative_nl(edges[100:2001:3], *prof.rects[4])), abs=1e-12)


def test_a_wide_machine_shows_its_largest_users_and_other(tmp_path):
    m = wide_machine(tmp_path)
    prof = predict(m, "20s", dt=0.01).profile
    write_demand_csv(prof, tmp_path / "d.csv", shown=5)
    header, body = read_csv(tmp_path / "d.csv")
    top = sorted(np.argsort(-prof.consumer_nl)[:5].tolist())
    assert header == ["time_s", "total_l_min"] + [
        prof.names[i].replace(" ", "_") + "_l_min" for i in top] + ["other_l_min"]
    assert body[:, 1] == pytest.approx(body[:, 2:].sum(axis=1), abs=1e-4)
    rest = [i for i in range(len(prof.names)) if i not in top]
    assert (body[:, -1] * 0.01 / 60).sum() == pytest.approx(prof.consumer_nl[rest].sum(),
                                                            rel=1e-6)
    # the largest bores use the most air: the shown ones are the last cylinders
    assert set(top) >= {N_VALVES - 1, N_VALVES - 2}
    # one more consumer than shown is shown rather than called "other"
    assert [g[0] for g in prof.groups(len(prof.names) - 1)] == prof.names


def test_idle_air_within_cells_equals_the_dense_sum(tmp_path):
    prof = predict(wide_machine(tmp_path), "15s", dt=0.02).profile
    rng = np.random.default_rng(4)
    mask = rng.random(prof.n_cells) < 0.3
    assert prof.consumer_nl_within(mask) == pytest.approx(prof.cell_nl[:, mask].sum(axis=1),
                                                          rel=1e-9, abs=1e-12)
    assert prof.consumer_nl_within(np.zeros(prof.n_cells, bool)).sum() == 0.0


def test_the_default_grid_counts_the_columns_written():
    assert csv_columns(5) == 7 and csv_columns(13) == 15 and csv_columns(200) == 15
    assert csv_columns(200, None) == 202
    assert default_dt(3600, columns=csv_columns(200)) == 0.01
    dt = default_dt(3600, columns=csv_columns(200, None))
    assert 3600 / dt * 202 <= 6_000_000 and dt > 0.1


def test_cli_consumers_option(tmp_path):
    m = wide_machine(tmp_path)
    out = tmp_path / "o"
    r = subprocess.run([sys.executable, "-m", "plcpred", "predict", str(m), "--horizon", "10s",
                        "--out", str(out), "--consumers", "3"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    header, body = read_csv(out / "demand.csv")
    assert len(header) == 2 + 3 + 1 and header[-1] == "other_l_min"
    summary = json.loads((out / "summary.json").read_text())
    assert len(summary["consumers"]) == N_VALVES + 2          # the summary keeps every one
    assert (body[:, 1] * 0.01 / 60).sum() == pytest.approx(summary["total_nl"], rel=1e-6)
    r = subprocess.run([sys.executable, "-m", "plcpred", "predict", str(m), "--horizon", "10s",
                        "--out", str(out), "--consumers", "none"], capture_output=True, text=True)
    assert r.returncode == 2 and "--consumers" in r.stderr and "Traceback" not in r.stderr


def test_a_tiled_timeline_gives_each_signal_its_edges_without_building_the_whole():
    from pathlib import Path

    from plcpred import load_machine, unfold
    pick = Path(__file__).resolve().parents[2] / "samples" / "pick_place.toml"
    lazy = unfold(load_machine(pick), "2h")
    built = unfold(load_machine(pick), "2h")
    assert lazy.tiled is not None
    for name in lazy.names:
        t, v = lazy.edge_times_ns(name)
        m = built.signal_idx == built.names.index(name)
        assert np.array_equal(t, built.time_ns[m]) and np.array_equal(v, built.values[m]), name
    assert lazy._full is None                      # nothing was built for the lazy one


def test_demand_csv_times_are_exact_decimals_at_any_horizon():
    from plcpred.outputs.files import csv_rows
    text = csv_rows(8_639_998, 10_000_000, np.array([[1.0, 2.5], [1.0, 2.5]]))
    assert text == "86399.98,1.000000,2.500000\n86399.99,1.000000,2.500000\n"
    text = csv_rows(0, 250_000_000, np.array([[-1e-12], [1 / 3], [0.0], [1 / 3]]))
    assert text == "0,0.000000\n0.25,0.333333\n0.5,0.000000\n0.75,0.333333\n"


SAMPLES = __import__("pathlib").Path(__file__).resolve().parents[2] / "samples"


@pytest.mark.parametrize("name", ["pick_place", "sorter", "press"])
def test_a_repeating_machine_read_as_one_period_equals_the_full_run(name):
    from plcpred import load_machine, unfold
    from plcpred.air import consumer_models, demand_profile
    m = load_machine(SAMPLES / f"{name}.toml")
    tiled, full = unfold(m, "7min"), unfold(m, "7min", tiling=False)
    models = consumer_models(m)
    for dt in (0.01, 0.37):
        a, b = demand_profile(tiled, models, dt), demand_profile(full, models, dt)
        assert a.templates is not None and b.templates is None
        assert a.strokes == b.strokes
        assert a.consumer_nl == pytest.approx(b.consumer_nl, rel=1e-10)
        assert a.total_cell_nl == pytest.approx(b.total_cell_nl, abs=1e-9)
        for w in (None, 1.0, 60.0):
            assert a.peak_l_min(w) == pytest.approx(b.peak_l_min(w), rel=1e-10)
        at = np.random.default_rng(2).uniform(0, 420, 50)
        assert a.cumulative_nl_at(at) == pytest.approx(b.cumulative_nl_at(at), rel=1e-10)
        busy = b.total_cell_nl > 0.5 * b.total_cell_nl.mean()
        assert a.consumer_nl_within(busy) == pytest.approx(b.consumer_nl_within(busy), rel=1e-9)


def test_ten_years_of_a_cycling_machine_cost_what_two_periods_do():
    from plcpred import load_machine, unfold
    from plcpred.air import consumer_models, demand_profile
    m = load_machine(SAMPLES / "pick_place.toml")
    day, years = unfold(m, "1d"), unfold(m, "3650d")
    models = consumer_models(m)
    a = demand_profile(day, models, 1.0)
    b = demand_profile(years, models, default_dt(3650 * 86400))
    assert years._full is None                    # the timeline was never built
    # the machine repeats every period: strokes and air grow with the horizon, and the
    # mean flow is the day's (a stroke or two cut by the horizon differ)
    for name, (ext, ret) in a.strokes.items():
        assert b.strokes[name][0] == pytest.approx(ext * 3650, abs=3650)
    assert b.mean_l_min == pytest.approx(a.mean_l_min, rel=1e-4)
    assert b.peak_l_min() == pytest.approx(a.peak_l_min(), rel=1e-12)
    assert b.total_cell_nl.sum() == pytest.approx(b.total_nl, rel=1e-9)


def test_a_run_that_does_not_repeat_is_plotted_in_whole_arrival_periods(tmp_path,
                                                                        monkeypatch):
    # jittered arrivals never tile; bins of a fixed length over a 4 s cycle would draw
    # a moire, bins of the arrival period average one part each
    from plcpred.machine import machine_from_data, read_machine_data
    from plcpred.outputs import demand_plot
    from plcpred.outputs.files import write_prediction
    path = SAMPLES / "pick_place.toml"
    data = read_machine_data(path)
    for t in data["input"]:
        if "period_s" in t:
            t["jitter_s"] = 0.1
    jittered = predict(machine_from_data(data, path), "2h")
    tiled = predict(machine_from_data(read_machine_data(path), path), "2h")
    assert jittered.timeline.tiled is None and tiled.timeline.tiled is not None
    period = max(t["period_s"] for t in data["input"] if "period_s" in t)
    from plcpred.air.cycles import arrival_period_s
    assert arrival_period_s(jittered.machine, jittered.timeline) == period
    assert arrival_period_s(tiled.machine, tiled.timeline) is None
    widths = []
    real = demand_plot.whole_periods
    monkeypatch.setattr(demand_plot, "whole_periods",
                        lambda *a: widths.append(real(*a)) or widths[-1])
    write_prediction(jittered, tmp_path, plot=True)
    cells = round(period / jittered.profile.dt_s)
    assert widths and widths[0] % cells == 0
    # the sizing report's demand plot (drawn last) is binned the same way
    from plcpred.air.sizing import size_prediction
    (tmp_path / "size").mkdir()
    from plcpred.outputs.sizing_report import write_sizing_report
    write_sizing_report(jittered, size_prediction(jittered), tmp_path / "size")
    assert widths[-1] == widths[0]
