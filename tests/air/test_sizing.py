"""Sizing formulas on profiles with known answers, and the CI gate's exit codes."""
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import plcpred_in_process

from plcpred import predict
from plcpred.air import demand_profile
from plcpred.air.cycles import last_switch_s
from plcpred.air.demand import ConsumerModel
from plcpred.air.sizing import receiver_deficit, size
from plcpred.sequencer.timeline import Signal, Timeline

SAMPLES = Path(__file__).resolve().parents[2] / "samples"
RIG = SAMPLES / "prototype_rig" / "rig.toml"
S = 10**9


def square_wave(q_on=300.0, q_base=30.0, on_s=2.0, period_s=10.0, horizon_s=100.0):
    """A blower of q_on NL/min on for on_s every period_s, and a leak of q_base."""
    rows = [(0, 0, 0.0)]
    t = 1.0
    while t < horizon_s:
        rows += [(round(t * S), 0, 1.0), (round((t + on_s) * S), 0, 0.0)]
        t += period_s
    tl = Timeline([Signal("b", "output", "bool")], [r[0] for r in rows], [r[1] for r in rows],
                  [r[2] for r in rows], round(horizon_s * S))
    models = [ConsumerModel("blower", "nozzle", ["b"], "passive", flow_l_min=q_on),
              ConsumerModel("leak", "leak", [], "leak", flow_l_min=q_base)]
    return demand_profile(tl, models, 0.1)


def test_square_wave_design_flow_and_receiver_by_hand():
    prof = square_wave()
    s = size(prof, allowance=0.10, band_bar=0.5)
    mean = 30 + 300 * 2 / 10
    assert s.mean_l_min == pytest.approx(mean)
    assert s.design_flow_l_min == pytest.approx(mean * 1.1)
    # each blow drains (330 - 99) NL/min for 2 s; the 8 s between refill it completely
    deficit = (330 - mean * 1.1) * 2 / 60
    assert s.deficit_nl == pytest.approx(deficit)
    assert s.receiver_l == pytest.approx(deficit * 1.0 / 0.5)    # V = deficit * P0 / dP
    assert 1.0 <= s.deficit_at_s % 10 <= 3.0 + 1e-9
    assert s.peak_l_min == pytest.approx(330) and s.p95_l_min == pytest.approx(330)
    assert s.peak_1min_l_min == pytest.approx(mean, rel=0.02)


def test_deficit_accumulates_when_refilling_is_too_slow():
    # 60 s at 200 then 60 s at 0 against a supply of 150: deficit 50 NL/min for 1 min
    flow = np.r_[np.full(600, 200.0), np.zeros(600)]
    deficit, at_s, curve = receiver_deficit(flow, 0.1, 150.0)
    assert deficit == pytest.approx(50.0) and at_s == pytest.approx(60.0)
    assert curve[-1] == 0.0


def test_energy_cost_and_idle_share():
    prof = square_wave()
    s = size(prof, hours_per_year=2000, sec_kwh_per_nm3=0.12, price_per_kwh=0.2)
    energy = s.mean_l_min * 60 / 1000 * 0.12 * 2000
    assert s.energy_kwh_per_year == pytest.approx(energy)
    assert s.cost_per_year == pytest.approx(energy * 0.2)
    # no cylinder at all: everything is idle air, the blower's and the leak's
    assert s.idle_share == pytest.approx(1.0)
    assert s.passive_nl + s.leak_nl == pytest.approx(s.total_nl)
    assert s.idle_blowers_nl == pytest.approx(s.passive_nl)
    assert s.idle_leak_nl == pytest.approx(s.leak_nl)


def test_idle_share_counts_air_while_no_cylinder_moves():
    rows = [(0, 0, 0.0), (10 * S, 0, 1.0), (20 * S, 0, 0.0)]
    tl = Timeline([Signal("y", "output", "bool")], [r[0] for r in rows], [r[1] for r in rows],
                  [r[2] for r in rows], 40 * S)
    models = [ConsumerModel("cyl", "double_acting", ["y"], "active", extend_nl=1.0,
                            retract_nl=1.0, stroke_time_s=(1.0, 1.0)),
              ConsumerModel("leak", "leak", [], "leak", flow_l_min=6.0)]
    prof = demand_profile(tl, models, 0.1)
    s = size(prof)
    # leak 0.1 NL/s for 40 s = 4 NL, 0.2 NL of it while a stroke moves; strokes 2 NL
    assert s.idle_nl == pytest.approx(3.8)
    assert s.idle_share == pytest.approx(3.8 / 6.0)
    assert s.idle_leak_nl == pytest.approx(3.8) and s.idle_blowers_nl == 0.0
    # once the machine must have been still for 5 s, 2 x 5 s of leak are no longer idle
    assert size(prof, idle_after_s=5.0).idle_nl == pytest.approx(2.8)


def run(*args):
    return plcpred_in_process(*args)


def test_size_writes_the_reports(tmp_path):
    r = run("size", RIG, "--horizon", "20s", "--out", tmp_path, "--allowance", "15%")
    assert r.returncode == 0, r.stderr
    data = json.loads((tmp_path / "sizing.json").read_text())
    for key in ("mean_l_min", "peak_l_min", "design_flow_l_min", "receiver_l",
                "energy_kwh_per_year", "cost_per_year", "idle_share"):
        assert key in data
    assert data["design_flow_l_min"] == pytest.approx(data["mean_l_min"] * 1.15)
    html = (tmp_path / "sizing.html").read_text()
    assert "data:image/png;base64," in html and "<table>" in html
    assert "receiver" in (tmp_path / "sizing.md").read_text()


def test_compare_exit_codes(tmp_path):
    same = run("compare", RIG, "--horizon", "20s", "--program-new",
               SAMPLES / "prototype_rig" / "rig.seq")
    assert same.returncode == 0, same.stderr
    more = run("compare", RIG, SAMPLES / "prototype_rig" / "rig_seq2.toml", "--horizon", "30s",
               "--max-increase", "2%")
    assert more.returncode == 1 and "FAIL" in more.stdout
    loose = run("compare", RIG, SAMPLES / "prototype_rig" / "rig_seq2.toml", "--horizon",
                "30s", "--max-increase", "100NL", "--json", "-")
    assert loose.returncode == 0
    data = json.loads(loose.stdout)
    assert data["within_allowance"] and data["delta_nl"] > 0
    assert sum(c["delta_nl"] for c in data["consumers"]) == pytest.approx(data["delta_nl"])
    missing = run("compare", RIG, tmp_path / "nothere.toml", "--horizon", "10s")
    assert missing.returncode == 2 and "Traceback" not in missing.stderr
    bad = run("compare", RIG, "--horizon", "10s", "--max-increase", "lots")
    assert bad.returncode == 2


def test_a_machine_without_consumers_still_reports(tmp_path):
    (tmp_path / "p.st").write_text("PROGRAM P VAR_OUTPUT y : BOOL; END_VAR y := TRUE; "
                                   "END_PROGRAM")
    (tmp_path / "m.toml").write_text('[machine]\nprogram = "p.st"\nsupply_bar_g = 6\n')
    r = run("size", tmp_path / "m.toml", "--horizon", "5s", "--out", tmp_path / "o")
    assert r.returncode == 0, r.stderr
    data = json.loads((tmp_path / "o" / "sizing.json").read_text())
    assert data["total_nl"] == 0 and data["receiver_l"] == 0 and data["idle_share"] == 0


PUSHER = """[[consumer]]
name = "pusher"
kind = "double_acting"
bore_mm = 32
rod_mm = 12
stroke_mm = 80
valve = "qPush"
"""


def test_compare_fails_a_new_machine_that_never_moves(tmp_path):
    """The E-stop nobody schedules: NEW uses far less air because it never runs. The gate
    fails it with its own exit code (4) and names the input."""
    (tmp_path / "p.st").write_text("""PROGRAM P
VAR_INPUT I_ESTOP_OK : BOOL; xPart : BOOL; END_VAR
VAR_OUTPUT qPush : BOOL; END_VAR
qPush := I_ESTOP_OK AND xPart;
END_PROGRAM""")
    base = """[machine]
program = "p.st"
supply_bar_g = 6
[[input]]
signal = "xPart"
period_s = 2.0
pulse_ms = 500
{estop}
""" + PUSHER
    (tmp_path / "base.toml").write_text(base.format(
        estop='[[input]]\nsignal = "I_ESTOP_OK"\ninitial = true'))
    (tmp_path / "new.toml").write_text(base.format(estop=""))
    r = run("compare", tmp_path / "base.toml", tmp_path / "new.toml", "--horizon", "20s",
            "--max-increase", "2%")
    assert r.returncode == 4, r.stdout + r.stderr
    assert "NEW never moves" in r.stdout and "I_ESTOP_OK" in r.stdout
    js = run("compare", tmp_path / "base.toml", tmp_path / "new.toml", "--horizon", "20s",
             "--json", "-")
    data = json.loads(js.stdout)
    assert js.returncode == 4 and data["new_moves"] is False and data["passes"] is False
    ok = run("compare", tmp_path / "base.toml", tmp_path / "base.toml", "--horizon", "20s")
    assert ok.returncode == 0


# ---------------------------------------------------------------------- cycles

PICK = SAMPLES / "pick_place.toml"


def _pick_place_variant(tmp_path, name, old, new):
    """pick_place.toml with one line changed, its program found from tmp_path."""
    text = PICK.read_text().replace('program = "codesys_pick_place.st"',
                                    f'program = "{(SAMPLES / "codesys_pick_place.st")}"')
    assert old in text
    path = tmp_path / name
    path.write_text(text.replace(old, new))
    return path


def test_per_cycle_sizing_does_not_depend_on_the_horizon():
    from plcpred.air import predict
    from plcpred.air.cycles import cycles_of

    figures = []
    for horizon in ("1h", "24h"):
        p = predict(PICK, horizon)
        c = cycles_of(p.machine, p.timeline, p.profile)
        s = size(p.profile, cycles=c)
        figures.append((s.cycle_s, s.nl_per_cycle, c.count))
    (c1, nl1, _n1), (c24, nl24, n24) = figures
    assert c1 == c24 == 4.0                       # the repeating state's period
    assert nl1 == pytest.approx(nl24, rel=1e-6)
    # and it is the air of one cycle: the mean flow times the cycle, once start-up is past
    assert nl24 * n24 == pytest.approx(p.profile.total_nl, rel=1e-3)


def test_compare_fails_a_throughput_drop(tmp_path):
    """A much slower X slide (a flow control turned down): the station can no longer take
    a part every 4 s, so NEW uses less air per hour. The per-hour gate would pass it; the
    throughput gate fails it (exit 5), and air is compared per part."""
    slow = _pick_place_variant(tmp_path, "slow.toml", "stroke_time_s = [0.45, 0.45]",
                               "stroke_time_s = [2.0, 2.0]")
    r = run("compare", PICK, slow, "--horizon", "10min", "--json", "-")
    assert r.returncode == 5, r.stdout + r.stderr
    data = json.loads(r.stdout)
    base, new = data["cycles"]["base"], data["cycles"]["new"]
    assert data["per"] == "cycle"
    assert base["cycle_s"] == 4.0                  # a part every 4 s
    # parts still come every 4 s; the slow station misses some: its state repeats only
    # after several arrivals, several parts per period
    assert new["cycle_s"] > 4.5 and "per period of valve" in new["source"]
    assert data["throughput_drop_pct"] == pytest.approx(
        (1 - base["cycle_s"] / new["cycle_s"]) * 100)
    # the same strokes per part; only the leak runs longer per part
    assert 0 < data["delta_pct"] < 10 and not data["passes"]
    text = run("compare", PICK, slow, "--horizon", "10min")
    assert "FAIL: throughput" in text.stdout and "--max-throughput-drop" in text.stdout
    assert run("compare", PICK, slow, "--horizon", "10min", "--max-throughput-drop", "30%",
               "--max-increase", "10%").returncode == 0
    assert run("compare", PICK, slow, "--horizon", "10min", "--max-throughput-drop",
               "lots").returncode == 2


def test_cycle_signal_counts_a_counter(tmp_path):
    (tmp_path / "p.st").write_text("""PROGRAM P
VAR_INPUT xPart : BOOL; END_VAR
VAR_OUTPUT qPush : BOOL; nParts : INT; END_VAR
VAR edge : R_TRIG; END_VAR
edge(CLK := xPart);
IF edge.Q THEN nParts := nParts + 1; END_IF
qPush := xPart;
END_PROGRAM""")
    machine = """[machine]
program = "p.st"
supply_bar_g = 6
cycle_signal = "{signal}"
[[input]]
signal = "xPart"
period_s = 2.5
offset_s = 0.5
pulse_ms = 500
""" + PUSHER
    (tmp_path / "m.toml").write_text(machine.format(signal="nParts"))
    r = run("size", tmp_path / "m.toml", "--horizon", "60s", "--out", tmp_path / "o")
    assert r.returncode == 0, r.stderr
    data = json.loads((tmp_path / "o" / "sizing.json").read_text())
    assert data["cycle_s"] == pytest.approx(2.5) and data["cycle_source"] == 'signal "nParts"'
    # one extend and one retract of the pusher per part (D1 both ways, no leak)
    per_part = data["active_nl"] / 24                  # 24 parts in 60 s
    assert data["nl_per_cycle"] == pytest.approx(per_part, rel=1e-6)
    (tmp_path / "bad.toml").write_text(machine.format(signal="nothing"))
    bad = run("size", tmp_path / "bad.toml", "--horizon", "10s", "--out", tmp_path / "o2")
    assert bad.returncode in (1, 2) and "cycle_signal" in bad.stderr
    assert "[machine]" in bad.stderr and "Traceback" not in bad.stderr


# ---------------------------------------------------------------------- exact peaks

def test_square_wave_peaks_by_hand():
    prof = square_wave(horizon_s=100.0)
    assert prof.peak_l_min() == pytest.approx(330.0)          # blower and leak together
    assert prof.peak_l_min(1.0) == pytest.approx(330.0)
    # any 60 s holds six 2 s blows at most: 30 + 300 * 12 / 60
    assert prof.peak_l_min(60.0) == pytest.approx(90.0)
    # a 5 s window holds one whole blow: 30 + 300 * 2 / 5
    assert prof.peak_l_min(5.0) == pytest.approx(150.0)


def test_peaks_are_the_same_at_every_dt():
    from plcpred.air import predict

    figures = []
    for dt in (0.002, 0.05, 0.3):
        prof = predict(PICK, "30s", dt=dt).profile
        figures.append((prof.peak_l_min(), prof.peak_l_min(1.0), prof.peak_l_min(10.0)))
        # the grid can only average the exact demand down
        assert prof.grid_peak_l_min() <= prof.peak_l_min() + 1e-9
        assert prof.steps.cumulative_nl(prof.horizon_s) == pytest.approx(prof.total_nl,
                                                                         rel=1e-9)
    for f in figures[1:]:
        assert f == pytest.approx(figures[0], rel=1e-12)
    fine = predict(PICK, "30s", dt=0.001).profile
    # a 1 ms grid's 1 s windows come within a cell's air of the exact one
    assert fine.grid_peak_l_min(1.0) == pytest.approx(figures[0][1], rel=5e-3)
    assert fine.grid_peak_l_min(1.0) <= figures[0][1] + 1e-9


def test_sizing_warns_of_a_machine_that_stops_early(tmp_path):
    # the rig runs its one sequence in about 8 s, then stands still
    r = run("size", RIG, "--horizon", "60s", "--out", tmp_path / "rig")
    assert r.returncode == 0, r.stderr
    data = json.loads((tmp_path / "rig" / "sizing.json").read_text())
    assert len(data["warnings"]) == 1 and "last switch at 8.26 s of the 60 s" in r.stderr
    assert "cycle_signal" in data["warnings"][0] and data["cycle_s"] is None
    assert "Warning" in (tmp_path / "rig" / "sizing.md").read_text()
    # a cycling machine keeps switching to the end of any horizon
    r = run("size", PICK, "--horizon", "60s", "--out", tmp_path / "pick")
    assert json.loads((tmp_path / "pick" / "sizing.json").read_text())["warnings"] == []


# ---------------------------------------------------------------------- energy

def test_specific_energy_rises_with_pressure_as_isothermal_work():
    from plcpred.air.sizing import DEFAULT_SEC_KWH_NM3, specific_energy_kwh_per_nm3

    # the published figure at 7 bar gauge (0.30-0.35 kW per l/s = about 0.1 kWh/Nm^3)
    assert specific_energy_kwh_per_nm3(7.0) == pytest.approx(DEFAULT_SEC_KWH_NM3, rel=1e-9)
    assert 0.30 / 3.6 <= specific_energy_kwh_per_nm3(7.0) <= 0.35 / 3.6 * 1.1
    # isothermal work: P0 ln(p/p_atm) per normal m^3, so 4 bar g costs ln(5.01/1.01)/ln(8.01/1.01)
    ratio = math.log(501.325 / 101.325) / math.log(801.325 / 101.325)
    assert specific_energy_kwh_per_nm3(4.0) / specific_energy_kwh_per_nm3(7.0) == \
        pytest.approx(ratio, rel=1e-12)
    assert specific_energy_kwh_per_nm3(0.0) == 0.0


def test_size_takes_the_energy_from_the_supply_pressure(tmp_path):
    # the rig runs at 3.987 bar gauge: each normal m^3 costs less than at 7 bar
    r = run("size", RIG, "--horizon", "20s", "--out", tmp_path / "a")
    data = json.loads((tmp_path / "a" / "sizing.json").read_text())
    from plcpred.air.sizing import specific_energy_kwh_per_nm3
    assert data["sec_kwh_per_nm3"] == pytest.approx(specific_energy_kwh_per_nm3(3.987),
                                                    rel=1e-3)
    assert data["energy_kwh_per_year"] == pytest.approx(
        data["mean_l_min"] * 60 / 1000 * data["sec_kwh_per_nm3"] * 4000, rel=1e-9)
    r = run("size", RIG, "--horizon", "20s", "--out", tmp_path / "b", "--sec", "0.1")
    assert r.returncode == 0
    assert json.loads((tmp_path / "b" / "sizing.json").read_text())["sec_kwh_per_nm3"] == 0.1


def test_a_compressor_data_sheet_sets_the_energy_along_the_pressure_curve(tmp_path):
    from plcpred.air.sizing import CompressorSheet

    # CAGI: 16.5 kW per 100 cfm at 7 bar(g); 100 cfm = 2.8317 m^3/min of free air, so at its
    # rated pressure a normal m^3 costs 16.5 / (2.8317 * 60) kWh, whatever the curve says
    sheet = CompressorSheet.from_kw_per_100cfm(16.5, 7.0)
    at_rated = 16.5 / (100 * 0.028316846592 * 60)
    assert sheet.sec_kwh_per_nm3(7.0) == pytest.approx(at_rated, rel=1e-12)
    assert at_rated == pytest.approx(0.0971, abs=1e-4)
    # isothermal work over the sheet's energy: 0.0574 / 0.0971
    assert sheet.isothermal_efficiency() == pytest.approx(0.05744 / 0.09711, rel=1e-3)
    # below its rated pressure it costs what the isothermal work saves (E1)
    ratio = math.log(501.325 / 101.325) / math.log(801.325 / 101.325)
    assert sheet.sec_kwh_per_nm3(4.0) == pytest.approx(at_rated * ratio, rel=1e-12)
    # the same compressor in ISO 1217 units: kW per m^3/min
    assert CompressorSheet(16.5 / 2.8316846592).sec_kwh_per_nm3(4.0) == pytest.approx(
        sheet.sec_kwh_per_nm3(4.0), rel=1e-12)

    # the rig runs at 3.987 bar(g), below the sheet's 7: less than the sheet's figure
    r = run("size", RIG, "--horizon", "20s", "--out", tmp_path / "a",
            "--compressor-power", "16.5kW/100cfm")
    assert r.returncode == 0, r.stderr
    data = json.loads((tmp_path / "a" / "sizing.json").read_text())
    assert data["sec_kwh_per_nm3"] == pytest.approx(sheet.sec_kwh_per_nm3(3.987), rel=1e-3)
    assert "data sheet" in data["sec_basis"]
    assert "59.1 % isothermal efficiency" in (tmp_path / "a" / "sizing.md").read_text()
    # rated below the supply: extrapolated, and said so
    r = run("size", RIG, "--horizon", "20s", "--out", tmp_path / "b",
            "--compressor-power", "5.8kW/(m3/min)", "--compressor-bar", "3")
    assert r.returncode == 0 and "above the pressure the compressor is rated at" in r.stderr
    for bad in (["--compressor-power", "16kW"], ["--compressor-power", "0kW/100cfm"],
                ["--compressor-power", "16.5kW/100cfm", "--sec", "0.1"]):
        r = run("size", RIG, "--horizon", "20s", "--out", tmp_path / "c", *bad)
        assert r.returncode == 2 and "compressor-power" in r.stderr, bad
        assert not (tmp_path / "c").exists()
    # a sweep over the supply pressure counts each scenario with the same compressor
    r = run("sweep", PICK, "--horizon", "20s", "--set", "supply_bar_g=5,6", "--workers", "1",
            "--compressor-power", "16.5kW/100cfm", "--out", tmp_path / "s")
    assert r.returncode == 0, r.stderr
    import csv
    for row in csv.DictReader((tmp_path / "s" / "sweep.csv").open()):
        sec = sheet.sec_kwh_per_nm3(float(row["supply_bar_g"]))
        assert float(row["energy_kwh_per_year"]) == pytest.approx(
            float(row["air_nm3_per_year"]) * sec, rel=1e-9)


def test_currency_is_shown_with_the_cost(tmp_path):
    r = run("size", PICK, "--horizon", "20s", "--out", tmp_path / "a", "--price", "0.2",
            "--currency", "EUR")
    assert r.returncode == 0, r.stderr
    assert " EUR/year" in r.stdout
    data = json.loads((tmp_path / "a" / "sizing.json").read_text())
    assert data["currency"] == "EUR"
    assert data["cost_per_year"] == pytest.approx(data["energy_kwh_per_year"] * 0.2)
    assert "0.2 EUR per kWh" in (tmp_path / "a" / "sizing.md").read_text()
    bad = run("size", PICK, "--horizon", "20s", "--out", tmp_path / "b", "--currency",
              "<script>")
    assert bad.returncode == 2 and "currency" in bad.stderr


def test_the_report_says_what_the_sizing_rests_on(tmp_path):
    r = run("size", PICK, "--horizon", "20s", "--out", tmp_path / "a")
    assert r.returncode == 0, r.stderr
    md = (tmp_path / "a" / "sizing.md").read_text()
    assumptions = md[md.index("| assumption | value |"):]
    assert "| supply pressure | 6 bar(g), atmosphere 101.325 kPa |" in assumptions
    assert "isothermal compression to the supply pressure" in assumptions
    assert "| operating hours per year | 4000 h |" in assumptions
    assert "pick_place.toml" in assumptions and "codesys_pick_place.st" in assumptions
    assert "(at 0.15 per kWh)" in md          # no currency: no gap where it would be
    r = run("size", PICK, "--horizon", "20s", "--out", tmp_path / "b", "--sec", "0.12")
    md = (tmp_path / "b" / "sizing.md").read_text()
    assert "| specific energy | 0.12 kWh/Nm³, given (--sec) |" in md


def test_long_horizon_plots_bin_whole_cycles():
    from plcpred.outputs.plotting import MAX_CYCLES_DRAWN, whole_periods
    # a 4 s cycle on a 10 ms grid over an hour: 900 cycles, bins of 120 cells would cut
    # cycles in drifting places; they become one whole cycle (400 cells) or more
    assert whole_periods(120, 4.0, 0.01, 360_000) == 400
    assert whole_periods(1000, 4.0, 0.01, 360_000) == 1200
    # few cycles on the axis: drawn as they are
    cells = int(MAX_CYCLES_DRAWN * 400)
    assert whole_periods(20, 4.0, 0.01, cells) == 20
    assert whole_periods(20, None, 0.01, 360_000) == 20


def _with_calendar(tmp_path, calendar: str):
    program = (PICK.parent / "codesys_pick_place.st").as_posix()
    text = PICK.read_text().replace('program = "codesys_pick_place.st"',
                                    f'program = "{program}"')
    path = tmp_path / "pick_cal.toml"
    path.write_text(text + "\n[calendar]\n" + calendar)
    return path


def test_a_production_calendar_counts_leaks_all_year(tmp_path):
    """(E2) by hand: 2 x 8 h x 5 days x 50 weeks x 0.9 = 3,600 h producing at the mean;
    the other 5,160 h the supply stays on and the leak (pick_place's fittings) flows."""
    machine = _with_calendar(tmp_path, "shifts_per_day = 2\nhours_per_shift = 8\n"
                                       "days_per_week = 5\nweeks_per_year = 50\n"
                                       "production_share = 0.9\n")
    r = run("size", machine, "--horizon", "60s", "--out", tmp_path / "a")
    assert r.returncode == 0, r.stderr
    d = json.loads((tmp_path / "a" / "sizing.json").read_text())
    leak = next(c for c in d["consumers"].values() if c["role"] == "leak")
    leak_l_min = leak["total_nl"] / 60.0 * 60.0
    assert d["hours_per_year"] == pytest.approx(3600.0)
    assert d["idle_hours_per_year"] == pytest.approx(5160.0)
    assert d["idle_flow_l_min"] == pytest.approx(leak_l_min, rel=1e-9)
    air = (d["mean_l_min"] * 3600 + leak_l_min * 5160) * 60 / 1000
    assert d["air_nm3_per_year"] == pytest.approx(air, rel=1e-9)
    assert d["energy_kwh_per_year"] == pytest.approx(air * d["sec_kwh_per_nm3"], rel=1e-9)
    assert "5,160 h standing" in (tmp_path / "a" / "sizing.md").read_text()
    # --hours still sets the production hours; the rest of the year stands
    r = run("size", machine, "--horizon", "60s", "--out", tmp_path / "b", "--hours", "8000")
    d = json.loads((tmp_path / "b" / "sizing.json").read_text())
    assert (d["hours_per_year"], d["idle_hours_per_year"]) == (8000.0, 760.0)
    # without a calendar, as before: the year is the production hours
    r = run("size", PICK, "--horizon", "60s", "--out", tmp_path / "c")
    d = json.loads((tmp_path / "c" / "sizing.json").read_text())
    assert (d["hours_per_year"], d["idle_hours_per_year"]) == (4000.0, 0.0)
    assert d["air_nm3_per_year"] == pytest.approx(d["mean_l_min"] * 4000 * 60 / 1000)


def test_a_calendar_that_does_not_fit_is_named(tmp_path):
    machine = _with_calendar(tmp_path, "shifts_per_day = 3\nhours_per_shift = 9\n")
    r = run("size", machine, "--horizon", "10s", "--out", tmp_path / "a")
    assert r.returncode == 2 and "[calendar]" in r.stderr and "more than a day" in r.stderr
    machine = _with_calendar(tmp_path, "shifts_per_day = 3\nhours_per_shift = 8\n"
                                       "days_per_week = 7\nweeks_per_year = 53\n")
    r = run("size", machine, "--horizon", "10s", "--out", tmp_path / "c")
    assert r.returncode == 2 and "do not fit in a year" in r.stderr
    machine = _with_calendar(tmp_path, "idle_state = \"sometimes\"\n")
    r = run("size", machine, "--horizon", "10s", "--out", tmp_path / "b")
    assert r.returncode == 2 and "idle_state" in r.stderr and "Traceback" not in r.stderr


def test_sweep_counts_energy_and_cost_with_the_same_options(tmp_path):
    r = run("sweep", PICK, "--horizon", "20s", "--set", "supply_bar_g=5,6", "--workers", "1",
            "--hours", "2000", "--price", "0.3", "--currency", "EUR", "--out", tmp_path / "s")
    assert r.returncode == 0, r.stderr
    assert "cost_per_year_EUR" in r.stdout
    import csv
    rows = list(csv.DictReader((tmp_path / "s" / "sweep.csv").open()))
    for row in rows:
        mean = float(row["mean_l_min"])
        assert float(row["air_nm3_per_year"]) == pytest.approx(mean * 2000 * 60 / 1000)
        assert float(row["cost_per_year"]) == pytest.approx(
            float(row["energy_kwh_per_year"]) * 0.3)
    # a lower supply saves twice: less air and less work per normal m^3 (E1)
    e5, e6 = (float(r_["energy_kwh_per_year"]) for r_ in rows)
    m5, m6 = (float(r_["mean_l_min"]) for r_ in rows)
    assert e5 / e6 < m5 / m6


def test_idle_air_is_air_while_the_machine_waits(tmp_path):
    """The rig blows its knives while its cylinders stand still in the sequence: that is
    productive blow-off, not idle air (it counted 86 % as idle when idle meant 'no
    cylinder moving'). Its waiting state is everything off: the leak before the start
    press and after the sequence is idle. A blower the program never switches off is
    left on: while the machine waits, its air is idle air."""
    from plcpred.air.cycles import rest_mask
    rig = predict(RIG, 20.0)
    s = size(rig.profile, waiting=rest_mask(rig.machine, rig.timeline, rig.profile))
    assert s.idle_blowers_nl == 0.0 and s.passive_nl > 0
    leak_l_min = s.leak_nl / 20.0 * 60.0
    # waiting: before the start press (0.5 s) and after the last valve switches
    quiet_s = 0.5 + 20.0 - last_switch_s(rig.machine, rig.timeline)
    assert s.idle_leak_nl == pytest.approx(leak_l_min * quiet_s / 60.0, rel=0.02)
    assert size(rig.profile).idle_share > 0.8            # the old, cylinder-only idea
    # a part every 4 s: the clamp closes for 1 s (strokes 0.2 s each way); the blower
    # stays on: it is left on for the 4 - 1 - 0.2 s of each cycle the machine waits
    (tmp_path / "p.st").write_text(
        "PROGRAM P\nVAR go AT %IX0.0 : BOOL; clamp AT %QX0.0 : BOOL; blow AT %QX0.1 : BOOL;"
        " t : TP; END_VAR\nt(IN := go, PT := T#1s);\nclamp := t.Q;\nblow := TRUE;\n"
        "END_PROGRAM\n")
    (tmp_path / "m.toml").write_text(
        '[machine]\nname = "m"\nprogram = "p.st"\nscan_ms = 10\nsupply_bar_g = 6\n'
        '[[input]]\nsignal = "go"\nperiod_s = 4\noffset_s = 0.5\npulse_ms = 100\n'
        '[[consumer]]\nname = "clamp"\nkind = "double_acting"\nbore_mm = 32\nrod_mm = 12\n'
        'stroke_mm = 50\nvalve = "clamp"\nstroke_time_s = [0.2, 0.2]\n'
        '[[consumer]]\nname = "blower"\nkind = "nozzle"\nvalve = "blow"\norifice_mm = 1\n'
        'Cd = 0.8\n')
    m = predict(tmp_path / "m.toml", 400.0)
    b = size(m.profile, waiting=rest_mask(m.machine, m.timeline, m.profile))
    blower = float(m.profile.consumer_nl[m.profile.names.index("blower")])
    assert b.idle_blowers_nl / blower == pytest.approx((4.0 - 1.0 - 0.2) / 4.0, abs=0.01)


def test_peaks_in_blocks_are_the_peaks_of_the_whole_run():
    # a run that never repeats is worked out in blocks of time; every block must see
    # each window whole, also those across a block's end, and strokes without duration
    from plcpred.air.demand import DemandProfile

    rng = np.random.default_rng(3)
    horizon = 400.0
    rects = []
    for _ in range(4):
        # times in eighths of a second: a window's ends then land exactly on breakpoints
        start = np.sort(rng.integers(0, 8 * 400, 250)) / 8.0
        dur = np.where(rng.random(250) < 0.2, 0.0, rng.integers(1, 24, 250) / 8.0)
        rects.append((start, dur, rng.uniform(0.1, 2.0, 250)))
    rects.append((np.array([0.0]), np.array([horizon]), np.array([horizon * 0.5])))
    prof = DemandProfile(names=list("abcdL"), roles=["active"] * 4 + ["leak"], rects=rects,
                         dt_s=0.1, horizon_s=horizon)
    # by hand, without the steps (a window's air is then continuous in its position):
    # the rate just after each breakpoint, and each window with an end on a breakpoint,
    # from the plain cumulative sums
    ramps = [tuple(x[r[1] > 0] for x in r) for r in rects]
    smooth = DemandProfile(names=list("abcdL"), roles=["active"] * 4 + ["leak"],
                           rects=ramps, dt_s=0.1, horizon_s=horizon)
    starts, durs, vols = (np.concatenate([r[k] for r in ramps]) for k in range(3))
    points = np.unique(np.concatenate([starts, starts + durs]))
    points = points[points < horizon]
    covering = (starts[None, :] <= points[:, None]) & (points[:, None] < (starts + durs)[None, :])
    rate = covering @ (vols / durs)
    assert smooth.peak_l_min() == pytest.approx(rate.max() * 60, rel=1e-12)
    assert prof.peak_l_min() == pytest.approx(rate.max() * 60, rel=1e-12)  # steps: no rate
    for w in (0.125, 1.0, 7.25, 60.0):
        ends = np.concatenate([points, points + w, [w, horizon]])
        ends = ends[(ends >= w) & (ends <= horizon)]
        gain = smooth.cumulative_nl_at(ends) - smooth.cumulative_nl_at(ends - w)
        for block in (10**9, 1, 17, 300):
            assert smooth.peak_l_min(w, block_rects=block) == pytest.approx(
                gain.max() / w * 60, rel=1e-12)
    for w in (None, 0.125, 1.0, 7.3, 60.0, 399.0, 800.0):
        whole = prof.peak_l_min(w, block_rects=10**9)
        for block in (1, 17, 300):
            assert prof.peak_l_min(w, block_rects=block) == pytest.approx(whole, rel=1e-12)
    # a repeating machine: its stretch of distinct windows, in blocks too
    from plcpred.air import predict
    tiled = predict(PICK, "1h").profile
    assert tiled.templates is not None
    for w in (None, 1.0, 60.0):
        assert tiled.peak_l_min(w, block_rects=5) == pytest.approx(
            tiled.peak_l_min(w), rel=1e-12)


def test_the_waiting_cells_of_a_repeating_run_are_read_from_one_period():
    """rest_mask folds the period instead of listing every spell to the horizon (10 years
    of the ld_ejector took 1.5 GB): the same cells as the spells listed one by one."""
    import numpy as np

    from plcpred import load_machine, predict
    from plcpred.air.cycles import rest_mask, rest_spells_ns
    from plcpred.air.demand import DemandSteps
    from plcpred.sequencer.timeline import NS
    for name in ("ld_ejector.toml", "sorter.toml", "clamp_station.toml"):
        m = load_machine(SAMPLES / name)
        r = predict(m, "1h")
        assert r.timeline.tiled is not None
        a, b = (x / NS for x in rest_spells_ns(m, r.timeline))
        listed = DemandSteps.of([(a, b - a, b - a)], r.profile.horizon_s)
        e = r.profile.edges_s
        expected = np.diff(listed.cumulative_nl(e)) >= np.diff(e) * (1 - 1e-9)
        got = rest_mask(m, r.timeline, r.profile)
        assert expected.any() and np.array_equal(got, expected), name


def test_sizing_ten_years_of_a_fast_machine(tmp_path):
    """79 million cycles of 4 s: the sizing plot reduces them a chunk at a time (held
    one by one they took 9.5 GB); the child reports its own peak resident memory."""
    resource = pytest.importorskip("resource")
    argv = ["plcpred", "size", str(SAMPLES / "ld_ejector.toml"), "--horizon", "3650d",
            "--out", str(tmp_path / "o")]
    child = ("import atexit, resource, runpy, sys\n"
             "atexit.register(lambda: print('peak_rss', resource.getrusage("
             "resource.RUSAGE_SELF).ru_maxrss, file=sys.stderr))\n"
             f"sys.argv = {argv!r}\n"
             "runpy.run_module('plcpred', run_name='__main__', alter_sys=True)\n")

    def limit_memory():             # in the child: past 1.5 GB it fails, not the machine
        resource.setrlimit(resource.RLIMIT_AS, (1_500_000_000, 1_500_000_000))

    r = subprocess.run(check=False, args=[sys.executable, "-c", child],
                       capture_output=True, text=True, timeout=120,
                       preexec_fn=limit_memory if sys.platform == "linux" else None)
    assert r.returncode == 0, r.stderr
    assert json.loads((tmp_path / "o" / "sizing.json").read_text())["cycle_s"] == 4.0
    peak = int(r.stderr.rsplit("peak_rss", 1)[1].split()[0])
    peak_mb = peak / 2**20 if sys.platform == "darwin" else peak / 2**10   # bytes, KiB
    assert peak_mb < 600, peak_mb


@pytest.mark.parametrize("option,value", [("--allowance", "abc"), ("--band", "1xbar")])
def test_unreadable_size_options_name_themselves(tmp_path, option, value):
    r = subprocess.run(check=False, args=[sys.executable, "-m", "plcpred", "size", str(SAMPLES / "press.toml"),
                        "--horizon", "10s", "--out", str(tmp_path / "o"), option, value],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and f"{option}: cannot read '{value}'" in r.stderr, r.stderr


def test_compare_json_takes_a_path_like_every_other_command(tmp_path, capsys):
    """One convention: --json PATH writes the file (the table still on stdout); --json -
    prints the JSON alone on stdout and the table on stderr; --json needs its PATH."""
    from plcpred.cli import main
    press = SAMPLES / "press.toml"
    out = tmp_path / "cmp.json"
    code = main(["compare", str(press), str(press), "--horizon", "10s", "--json", str(out)])
    printed = capsys.readouterr().out
    assert code == 0 and out.exists()
    assert json.loads(out.read_text())["within_allowance"] is True
    assert printed.startswith("air use over 10 s") and "ok: new uses" in printed
    assert main(["compare", str(press), str(press), "--horizon", "10s", "--json", "-"]) == 0
    captured = capsys.readouterr()
    assert json.loads(captured.out)["within_allowance"] is True
    assert "ok: new uses" in captured.err
    with pytest.raises(SystemExit) as exit_:
        main(["compare", str(press), str(press), "--horizon", "10s", "--json"])
    assert exit_.value.code == 2
    assert "--json: expected one argument" in capsys.readouterr().err
    assert main(["compare", str(press), str(press), "--horizon", "10s", "--json",
                 str(tmp_path)]) == 2
