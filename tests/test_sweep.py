"""What-if sweeps: results equal single predictions, and the Dask engine (on a real
LocalCluster) equals the local one."""
import subprocess
import sys
from pathlib import Path

import pytest

from plcpred import predict
from plcpred.machine import load_machine, read_machine_data
from plcpred.parser import load_program
from plcpred.sweep import SweepError, apply_settings, parse_setting, scenarios, sweep

SAMPLES = Path(__file__).resolve().parent.parent / "samples"
RIG = SAMPLES / "prototype_rig" / "rig.toml"
SETTINGS = ["supply_bar_g=3,5", "air knives.pressure_bar_g=2,3.5", "program.BLOW_TIME=T#2s,T#3s",
            "A.stroke_time_s=0.3/0.2"]


def test_cartesian_product():
    combos = scenarios([parse_setting(s) for s in SETTINGS])
    assert len(combos) == 8
    assert combos[0] == {"supply_bar_g": "3", "air knives.pressure_bar_g": "2",
                         "program.BLOW_TIME": "T#2s", "A.stroke_time_s": "0.3/0.2"}


def test_sweep_rows_equal_single_predictions():
    rows = sweep(RIG, [parse_setting(s) for s in SETTINGS[:3]], 20.0, 0.05, workers=2)
    assert len(rows) == 8
    base = load_machine(RIG)
    program = load_program(base.program_path)
    for row in rows[::3]:
        sc = {k: row[k] for k in ("supply_bar_g", "air knives.pressure_bar_g",
                                  "program.BLOW_TIME")}
        m, p = apply_settings(read_machine_data(RIG), RIG, program, sc)
        single = predict(m, 20.0, dt=0.05, program=p).profile
        assert row["total_nl"] == single.total_nl
        assert row["air knives_nl"] == pytest.approx(
            single.consumer_nl[single.names.index("air knives")])
    # the settings really act: a longer blow and a higher knife pressure use more air
    by = {(r["air knives.pressure_bar_g"], r["program.BLOW_TIME"], r["supply_bar_g"]):
          r["total_nl"] for r in rows}
    assert by[("2", "T#3s", "3")] > by[("2", "T#2s", "3")]
    assert by[("3.5", "T#2s", "3")] > by[("2", "T#2s", "3")]
    assert by[("2", "T#2s", "5")] > by[("2", "T#2s", "3")]     # leak and cylinders


def test_dask_engine_on_a_local_cluster_equals_the_local_engine():
    distributed = pytest.importorskip("dask.distributed")
    settings = [parse_setting(s) for s in SETTINGS[:2]]
    local = sweep(RIG, settings, 15.0, 0.05, workers=1)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        remote = sweep(RIG, settings, 15.0, 0.05, engine="dask", scheduler=cluster.scheduler_address)
    assert remote == local


@pytest.mark.parametrize("bad,message", [("nobody.C=1", "no consumer"),
                                         ("program.NOPE=T#1s", "no variable"),
                                         ("supply_bar_g=lots", "not a number"),
                                         ("A.colour=red", "cannot sweep")])
def test_bad_settings_are_named(bad, message):
    with pytest.raises(SweepError, match=message):
        sweep(RIG, [parse_setting(bad)], 5.0)


def test_cli_sweep_is_quiet_off_a_terminal_and_writes_csv(tmp_path):
    r = subprocess.run(check=False, args=[sys.executable, "-m", "plcpred.cli", "sweep", str(RIG), "--set",
                        "supply_bar_g=3,4", "--horizon", "10s", "--out", str(tmp_path)],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert r.stderr == ""
    lines = (tmp_path / "sweep.csv").read_text().splitlines()
    assert len(lines) == 3 and lines[0].startswith("supply_bar_g,total_nl")
    r = subprocess.run(check=False, args=[sys.executable, "-m", "plcpred.cli", "sweep", str(RIG), "--set",
                        "supply_bar_g=3", "--horizon", "10s", "--engine", "dask"],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "--scheduler" in r.stderr


def test_errors_survive_the_trip_from_a_worker_process():
    import pickle

    from plcpred.machine import MachineError
    from plcpred.parser import ProgramError
    from plcpred.sequencer import CompileError, ExecutionError, Watchdog
    for e in (MachineError("m.toml", 'consumer "c"', "bad"), ProgramError("x", "p.st", 3, 4),
              CompileError("y", "p.st", 5, 6), ExecutionError("z", "p.st", 7, 8),
              Watchdog("w", "p.st", 9, 1)):
        back = pickle.loads(pickle.dumps(e))
        assert type(back) is type(e) and str(back) == str(e)


@pytest.mark.parametrize("setting, message", [
    ("A.bore_mm=-5", "bore_mm must be > 0"), ("supply_bar_g=nan", "supply_bar_g must be a number"),
    ("A.bore_mm=1e400", "must be a number"), ("A.stroke_time_s=1e-300", "physical range"),
    ("supply_bar_g=500", "physical range"), ("scan_ms=0", "scan_ms must be > 0")])
def test_swept_values_go_through_the_loaders_checks(setting, message):
    with pytest.raises(SweepError, match=message):
        sweep(RIG, [parse_setting(setting)], 1.0, workers=1)


def test_a_batch_gives_the_rows_of_its_scenarios_in_order():
    from plcpred.sweep import parse_setting, run_batch, run_scenario, scenarios
    combos = scenarios([parse_setting("supply_bar_g=3,5,6")])
    args = [(str(RIG), sc, 5.0, 0.05, None) for sc in combos]
    rows = run_batch(args)
    assert [r["supply_bar_g"] for r in rows] == ["3", "5", "6"]
    assert rows == [run_scenario(*a) for a in args]
    assert rows[0]["total_nl"] < rows[2]["total_nl"]     # more pressure, more air


@pytest.mark.parametrize("n, threads", [(64, 2), (1, 4), (7, 2), (500, 16), (3, 1)])
def test_guided_batches_cover_every_scenario_once_in_falling_sizes(n, threads):
    from plcpred.sweep import guided_batches
    batches = guided_batches(n, threads)
    assert [k for b in batches for k in b] == list(range(n))
    sizes = [len(b) for b in batches]
    assert sizes == sorted(sizes, reverse=True) and sizes[-1] == 1
    # the first batch is a (2 * threads)-th of the work, not all of it
    assert sizes[0] == max(1, n // (2 * threads))


def test_the_dask_worker_settings_are_known_to_dask():
    dask = pytest.importorskip("dask")
    pytest.importorskip("dask.distributed")
    from plcpred.sweep import DASK_WORKER_CONFIG
    for key, value in DASK_WORKER_CONFIG.items():
        assert dask.config.get(key) is not None, key       # a key Dask has (no typo)
        with dask.config.set({key: value}):
            assert dask.config.get(key) == value


def test_the_allocator_setting_applies_once_on_glibc():
    import platform

    from plcpred.memory import use_large_malloc_thresholds
    if platform.system() != "Linux" or platform.libc_ver()[0] != "glibc":
        pytest.skip("glibc only")
    assert use_large_malloc_thresholds() is True
    assert use_large_malloc_thresholds() is True          # once; then a no-op


def test_saving_measures_repair_leaks_and_lower_the_supply():
    from plcpred.sweep import measure_setting
    settings = [measure_setting("leaks=-30%"), measure_setting("pressure=-1bar")]
    assert [s.values for s in settings] == [["0%", "-30%"], ["0bar", "-1bar"]]
    rows = sweep(RIG, settings, 20.0, 0.05, workers=1)
    by = {(r["measure.leaks"], r["measure.pressure"]): r for r in rows}
    leak = next(c.name for c in load_machine(RIG).consumers if c.kind == "leak")
    base, fixed = by[("0%", "0bar")], by[("-30%", "0bar")]
    # a leak's flow is proportional to its conductance: 30 % of it repaired
    assert fixed[f"{leak}_nl"] == pytest.approx(0.7 * base[f"{leak}_nl"], rel=1e-9)
    assert fixed["total_nl"] == pytest.approx(
        base["total_nl"] - 0.3 * base[f"{leak}_nl"], rel=1e-9)
    # one bar less is the machine at one bar less, and regulators above it give the supply
    seq2 = SAMPLES / "prototype_rig" / "rig_seq2.toml"      # knives regulated to 2 bar g
    m, _ = apply_settings(read_machine_data(seq2), seq2,
                          load_program(load_machine(seq2).program_path),
                          {"measure.pressure": "-3"})
    assert m.supply_bar_g == pytest.approx(load_machine(seq2).supply_bar_g - 3)
    knives = [c for c in m.consumers if c.pressure_bar_g is not None]
    assert knives and all(c.pressure_bar_g == pytest.approx(m.supply_bar_g) for c in knives)
    data = read_machine_data(RIG)
    program = load_program(load_machine(RIG).program_path)
    lower = by[("0%", "-1bar")]
    (same,) = sweep(RIG, [parse_setting(f"supply_bar_g={load_machine(RIG).supply_bar_g - 1}")],
                    20.0, 0.05, workers=1)
    assert lower["total_nl"] == pytest.approx(same["total_nl"], rel=1e-12)
    with pytest.raises(SweepError, match="measures are leaks, pressure, blowoff"):
        measure_setting("valves=-1")
    with pytest.raises(SweepError, match="from 0% to -100%"):
        apply_settings(data, RIG, program, {"measure.leaks": "+20%"})


BLOWER_LEFT_ON = """PROGRAM Station
VAR_INPUT part, cyl_out : BOOL; END_VAR
VAR_OUTPUT valve, blower : BOOL; END_VAR
VAR trig : R_TRIG; hold : TON; END_VAR
blower := TRUE;                       (* nobody switches it off *)
trig(CLK := part);
IF trig.Q THEN valve := TRUE; END_IF
hold(IN := cyl_out, PT := T#300ms);
IF hold.Q THEN valve := FALSE; END_IF
END_PROGRAM
"""


def _blower_station(tmp_path, program=BLOWER_LEFT_ON, more=""):
    """A cylinder cycling on parts every 2 s and a blower its program never switches
    off; ``more`` adds tables (a [calendar], consumers)."""
    (tmp_path / "station.st").write_text(program)
    (tmp_path / "station.toml").write_text("""[machine]
name = "blower left on"
program = "station.st"
scan_ms = 10
supply_bar_g = 6.0

[[input]]
signal = "part"
period_s = 2.0
offset_s = 0.5
pulse_ms = 100

[[consumer]]
name = "cyl"
kind = "double_acting"
bore_mm = 32
rod_mm = 12
stroke_mm = 100
valve = "valve"
stroke_time_s = [0.2, 0.2]
switches = { extended = "cyl_out" }

[[consumer]]
name = "blower"
kind = "nozzle"
valve = "blower"
orifice_mm = 1.5
Cd = 0.8
""" + more)


def test_blowing_only_in_cycle_closes_the_nozzles_while_the_machine_waits(tmp_path):
    _blower_station(tmp_path)
    from plcpred.sweep import measure_setting
    path = tmp_path / "station.toml"
    rows = sweep(path, [measure_setting("blowoff=cycle")], 20.0, 0.01, workers=1)
    by = {r["measure.blowoff"]: r for r in rows}
    # as the program says the blower is on for the whole 20 s; as the measure says only
    # while a cycle runs: while the valve is on (the waiting state is valve off, blower
    # on), worked out here from the timeline's valve intervals
    tl = predict(load_machine(path), 20.0, dt=0.01).timeline
    on = tl.intervals("valve")
    on_s = float((on["end_s"].clip(upper=20.0) - on["start_s"]).sum())
    q_l_min = by["always"]["blower_nl"] / 20.0 * 60.0      # on throughout
    assert by["cycle"]["blower_nl"] == pytest.approx(q_l_min * on_s / 60.0, rel=1e-6)
    assert 4.0 < on_s < 6.0                       # ten parts, about half a second each
    assert by["cycle"]["cyl_nl"] == pytest.approx(by["always"]["cyl_nl"], rel=1e-12)
    data = read_machine_data(path)
    with pytest.raises(SweepError, match="'always'"):
        apply_settings(data, path, None, {"measure.blowoff": "never"})
    data["consumer"] = [c for c in data["consumer"] if c["kind"] != "nozzle"]
    with pytest.raises(SweepError, match="no nozzle"):
        apply_settings(data, path, None, {"measure.blowoff": "cycle"})


def test_a_sweep_counts_the_year_as_size_does(tmp_path):
    # one path from a prediction to a year's air: the calendar, and idle air taken in the
    # state the machine waits in (the blower left on, not the blow-off while the
    # cylinder holds out), the same in size and in sweep
    from plcpred.air.sizing import size_prediction
    _blower_station(tmp_path, BLOWER_LEFT_ON.replace(
        "valve, blower : BOOL;", "valve, blower, blow : BOOL;").replace(
        "END_PROGRAM", "blow := valve AND cyl_out;\nEND_PROGRAM"), more="""
[calendar]
shifts_per_day = 2
idle_state = "program"

[[consumer]]
name = "blow-off"
kind = "nozzle"
valve = "blow"
orifice_mm = 3.0
Cd = 0.8
""")
    path = tmp_path / "station.toml"
    (row,) = sweep(path, [parse_setting("supply_bar_g=6")], 20.0, 0.01, workers=1)
    s = size_prediction(predict(load_machine(path), 20.0, dt=0.01))
    assert s.idle_hours_per_year > 0 and s.idle_flow_l_min > 0
    for key in ("air_nm3_per_year", "energy_kwh_per_year", "cost_per_year"):
        assert row[key] == pytest.approx(getattr(s, key), rel=1e-12), key


def test_a_process_parses_a_program_once_and_again_when_it_changes(tmp_path):
    import os
    import shutil

    from plcpred import sweep as sweep_module
    from plcpred.sweep import run_scenario
    rig = tmp_path / "rig.toml"
    shutil.copy(RIG, rig)
    shutil.copy(RIG.parent / "rig.st", tmp_path / "rig.st")
    sweep_module._PROGRAMS.clear()
    plain = run_scenario(str(rig), {}, 20.0, 0.05)
    # a setting that changes the program works on a copy: the cached IR stays as read
    longer = run_scenario(str(rig), {"program.BLOW_TIME": "T#6s"}, 20.0, 0.05)
    assert longer["total_nl"] > plain["total_nl"]
    assert run_scenario(str(rig), {}, 20.0, 0.05) == plain
    assert len(sweep_module._PROGRAMS) == 1
    # the file changed (the knives blow as long as the setting made them): parsed again
    text = (tmp_path / "rig.st").read_text()
    assert "BLOW_TIME : TIME := T#3700ms;" in text
    (tmp_path / "rig.st").write_text(text.replace("BLOW_TIME : TIME := T#3700ms;",
                                                  "BLOW_TIME : TIME := T#6s;"))
    st = (tmp_path / "rig.st").stat()
    os.utime(tmp_path / "rig.st", ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
    changed = run_scenario(str(rig), {}, 20.0, 0.05)
    assert changed["total_nl"] == pytest.approx(longer["total_nl"])
    assert len(sweep_module._PROGRAMS) == 2


def test_too_many_scenarios_fail_before_any_work():
    settings = [parse_setting("supply_bar_g=" + ",".join(str(3 + k / 1000) for k in range(1000))),
                parse_setting("A.stroke_time_s=" + ",".join(f"0.{k + 1}/0.2" for k in range(50)))]
    with pytest.raises(SweepError, match=r"50,000 scenarios \(1000 x 50\) is more than "
                                         r"--max-scenarios 10,000"):
        sweep(RIG, settings, 20.0, 0.05)
    with pytest.raises(SweepError, match="more than --max-scenarios 3"):
        sweep(RIG, [parse_setting("supply_bar_g=3,4,5,6")], 1.0, max_scenarios=3)


def test_dask_workers_started_elsewhere_find_a_relative_machine_path(tmp_path, monkeypatch):
    """The cluster's workers run in the folder they were started in; a sweep given a
    path relative to the caller's folder still reaches them (it was an error)."""
    distributed = pytest.importorskip("dask.distributed")
    monkeypatch.chdir(tmp_path)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        monkeypatch.chdir(SAMPLES)
        rows = sweep(Path("prototype_rig") / "rig.toml", [parse_setting("supply_bar_g=3,5")],
                     5.0, 0.05, engine="dask", scheduler=cluster.scheduler_address)
    assert [r["supply_bar_g"] for r in rows] == ["3", "5"]
    assert rows[1]["total_nl"] > rows[0]["total_nl"]


def test_a_sweep_shows_each_scenarios_cycle_and_warns_as_size_does(tmp_path, capsys):
    """Cycles per hour and NL per cycle per scenario (a scenario that takes more air per
    part shows it at the same throughput), as size gives them; and size's warning that
    the machine stands still for most of the horizon."""
    from plcpred.air.sizing import size_prediction
    from plcpred.cli import main
    pick = SAMPLES / "pick_place.toml"
    rows = sweep(pick, [parse_setting("supply_bar_g=5,6")], 30.0, workers=1)
    machine = load_machine(pick)
    for row, supply in zip(rows, (5.0, 6.0)):
        machine.supply_bar_g = supply
        s = size_prediction(predict(machine, 30.0))
        assert row["cycles_per_hour"] == pytest.approx(s.cycles_per_hour) == 900.0
        assert row["nl_per_cycle"] == pytest.approx(s.nl_per_cycle, rel=1e-12)
        assert row["warnings"] == []
    assert rows[1]["nl_per_cycle"] > 1.1 * rows[0]["nl_per_cycle"]
    assert main(["sweep", str(pick), "--set", "supply_bar_g=5,6", "--horizon", "30s",
                 "--workers", "1", "--out", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].split()[4:6] == ["cycles_per_hour", "nl_per_cycle"]
    assert out[2].split()[4:6] == ["900.00", f"{rows[0]['nl_per_cycle']:.2f}"]
    csv_head = (tmp_path / "o" / "sweep.csv").read_text().splitlines()[0].split(",")
    assert "nl_per_cycle" in csv_head and "warnings" not in csv_head
    # the rig runs its sequence once: it stands still after 8 s of 60
    assert main(["sweep", str(RIG), "--set", "supply_bar_g=4,5", "--horizon", "60s",
                 "--workers", "1"]) == 0
    captured = capsys.readouterr()
    assert captured.err.count("warning:") == 1
    assert "warning: every scenario: the valves last switch at 8.26 s of the 60 s " \
           "horizon" in captured.err
    assert captured.out.splitlines()[2].split()[4:6] == ["-", "-"]
