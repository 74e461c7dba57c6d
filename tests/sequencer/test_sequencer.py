"""The executor as a whole: event jumps equal scan stepping (on every sample and on
generated programs), tiling equals a full run, the plant and schedules drive the inputs,
and timeline.csv follows the contract."""
import csv
import random
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from plcpred import unfold
from plcpred.machine import Consumer, InputSchedule, Machine, load_machine
from plcpred.parser import parse_st
from plcpred.sequencer import Sequencer, parse_horizon

SAMPLES = Path(__file__).resolve().parents[2] / "samples"
MACHINES = sorted(SAMPLES.glob("*.toml")) + sorted((SAMPLES / "prototype_rig").glob("*.toml"))


@pytest.mark.parametrize("path", MACHINES, ids=lambda p: p.stem)
def test_event_driven_equals_scan_stepping_on_every_sample(path):
    machine = load_machine(path)
    fast = unfold(machine, "40s", tiling=False)
    ref = unfold(machine, "40s", scan_stepping=True)
    assert fast == ref
    assert fast.info["scans"] <= ref.info["scans"]
    assert len(fast.time_ns) > len(fast.signals)   # something happened


@pytest.mark.parametrize("path", MACHINES, ids=lambda p: p.stem)
def test_tiling_equals_a_full_run(path):
    machine = load_machine(path)
    tiled = unfold(machine, "3m")
    full = unfold(machine, "3m", tiling=False)
    assert tiled == full


def test_cycling_samples_tile():
    tl = unfold(SAMPLES / "pick_place.toml", "10m")
    assert tl.info["period_s"] == pytest.approx(4.0)
    assert tl.count_rising("qZ") == 150          # one pick per part, parts every 4 s


@pytest.mark.parametrize("program", ["rig.seq", "rig.xml"])
def test_rig_chart_gives_the_same_valve_timeline_as_the_st_program(program):
    machine = load_machine(SAMPLES / "prototype_rig" / "rig.toml")
    st = unfold(machine, "30s")
    chart = unfold(machine, "30s", program=SAMPLES / "prototype_rig" / program)
    for sig in ("Y_A", "Y_B", "Y_C", "Y_KNIVES", "A_EXT", "C_RET"):
        t1, v1 = st.edge_times_ns(sig)
        t2, v2 = chart.edge_times_ns(sig)
        assert np.array_equal(t1, t2) and np.array_equal(v1, v2), sig


def test_rig_sequence_2_chart_and_st_agree():
    machine = load_machine(SAMPLES / "prototype_rig" / "rig_seq2.toml")
    st = unfold(machine, "62s")
    chart = unfold(machine, "62s", program=SAMPLES / "prototype_rig" / "rig_seq2.seq")
    for sig in ("Y_A", "Y_B", "Y_C", "Y_KNIVES"):
        assert np.array_equal(st.edge_times_ns(sig)[0], chart.edge_times_ns(sig)[0]), sig
    assert st.count_rising("Y_A") == 30 and st.count_rising("Y_C") == 50


def test_rig_sequence_1_timing_follows_the_plant_model():
    tl = unfold(SAMPLES / "prototype_rig" / "rig.toml", "30s")
    # PB1 at 0.5 s; A: 15 ms switching delay + 0.40 s stroke -> A_EXT at 0.915 s, seen at
    # the 0.92 s scan; B 300 ms later; knives blow 10 s
    assert tl.edges("Y_A")["time_s"].tolist() == [0, 0.5, 4.56]
    assert tl.edges("A_RET")["time_s"].tolist() == [0, 0.52, 4.83]
    assert tl.edges("A_EXT")["time_s"].tolist() == [0, 0.92, 4.58]
    assert tl.edges("Y_B")["time_s"].tolist() == [0, 1.22, 4.56]
    knives = tl.intervals("Y_KNIVES")
    assert knives["duration_s"].tolist() == pytest.approx([3.7])


# ---------------------------------------------------------------------- plant I/O

def machine_for(program_text, consumers, inputs=(), scan_ms=10.0, tmp_path=None):
    program = parse_st(program_text, "gen.st")
    m = Machine("gen", Path("gen.toml"), Path("gen.st"), scan_ms=scan_ms)
    m.consumers = list(consumers)
    m.inputs = list(inputs)
    return program, m


def cylinder(name, valve, ret, ext, times=(0.1, 0.2), delay=0.02, kind="double_acting",
             initial="retracted"):
    switches = {}
    if ret:
        switches["retracted"] = ret
    if ext:
        switches["extended"] = ext
    return Consumer(name, kind, valve=list(valve), bore_mm=20, rod_mm=8, stroke_mm=50,
                    stroke_time_s=times, switch_delay_s=delay, switches=switches,
                    initial=initial)


PLANT_PROG = """PROGRAM P
VAR_INPUT go, r0, r1 : BOOL; END_VAR
VAR_OUTPUT y, yb_on, yb_off : BOOL; END_VAR
y := go;
yb_on := go AND r0;
yb_off := NOT go AND r1;
END_PROGRAM"""


def test_switches_follow_delay_and_separate_stroke_times():
    prog, m = machine_for(PLANT_PROG, [cylinder("c", ["y"], "r0", "r1", (0.1, 0.2), 0.02)],
                          [InputSchedule("go", pulses_s=[0.5], pulse_ms=1000)], scan_ms=1)
    tl = Sequencer(prog, m).run(parse_horizon("3s"))
    assert tl.edges("r0")["time_s"].tolist() == [0, 0.52, 1.72]
    assert tl.edges("r1")["time_s"].tolist() == [0, 0.62, 1.52]


def test_bistable_valve_keeps_its_state_and_initial_extended():
    prog, m = machine_for("""PROGRAM P VAR_INPUT go, back, r0, r1 : BOOL; END_VAR
VAR_OUTPUT ext, ret : BOOL; END_VAR
ext := go; ret := back;
END_PROGRAM""", [cylinder("c", ["ext", "ret"], "r0", "r1", (0.1, 0.1), 0.0,
                          initial="extended")],
                          [InputSchedule("go", pulses_s=[0.5, 1.5], pulse_ms=50),
                           InputSchedule("back", pulses_s=[1.0], pulse_ms=50)], scan_ms=1)
    tl = Sequencer(prog, m).run(parse_horizon("2s"))
    # starts extended; the first extend pulse changes nothing; the valve then keeps its
    # state after each pulse ends. With no switching delay the switch leaves at the scan
    # that commands the move and the PLC sees it at the next scan.
    assert tl.value_at("r1", 0) == 1
    assert tl.edges("r1")["time_s"].tolist() == [0, 1.001, 1.6]
    assert tl.edges("r0")["time_s"].tolist() == [0, 1.1, 1.501]


def test_single_acting_spring_return():
    prog, m = machine_for(PLANT_PROG, [cylinder("c", ["y"], None, "r1", (0.1, 0.3), 0.0,
                                                kind="single_acting")],
                          [InputSchedule("go", pulses_s=[0.2], pulse_ms=500)], scan_ms=1)
    tl = Sequencer(prog, m).run(parse_horizon("2s"))
    assert tl.edges("r1")["time_s"].tolist() == [0, 0.3, 0.701]   # leaves as the spring acts


def test_schedules_periodic_offset_and_seeded_jitter():
    prog, m = machine_for(PLANT_PROG, [],
                          [InputSchedule("go", period_s=1.0, offset_s=0.25, pulse_ms=100,
                                         jitter_s=0.05, seed=7)], scan_ms=1)
    a = Sequencer(prog, m).run(parse_horizon("10s"))
    b = Sequencer(prog, m).run(parse_horizon("10s"))
    assert a == b                                   # the seed makes it reproducible
    assert a.info["period_s"] is None               # random jitter disables tiling
    rises = a.intervals("go")["start_s"].to_numpy()
    assert len(rises) == 10
    assert np.all(np.abs(rises - (0.25 + np.arange(10))) <= 0.05 + 0.001)
    assert not np.allclose(rises, 0.25 + np.arange(10), atol=0.002)


def test_unscheduled_inputs_hold_their_declared_initial_value():
    prog = parse_st("PROGRAM P VAR_INPUT stop : BOOL := TRUE; END_VAR "
                    "VAR_OUTPUT run : BOOL; END_VAR run := stop; END_PROGRAM")
    tl = Sequencer(prog, None).run(parse_horizon("1s"))
    assert tl.value_at("stop", 0.5) == 1 and tl.value_at("run", 0.5) == 1


# ---------------------------------------------------------------------- generated programs

def _bool_expr(rng, names, depth=0):
    if depth > 1 or rng.random() < 0.35:
        n = rng.choice(names)
        return n if rng.random() < 0.7 else f"NOT {n}"
    op = rng.choice(["AND", "OR", "XOR"])
    return f"({_bool_expr(rng, names, depth + 1)} {op} {_bool_expr(rng, names, depth + 1)})"


def generated_program(seed):
    """A random station: scheduled inputs, two cylinders, timers of every kind, an edge
    detector, a counter, a CASE state machine, sometimes a read of a timer's ET."""
    rng = random.Random(seed)
    sigs = ["i0", "i1", "c0r", "c0e", "c1r", "c1e"]
    lines = []
    timers = []
    for k in range(4):
        kind = rng.choice(["TON", "TOF", "TP", "TONR"])
        timers.append((f"t{k}", kind))
    names = sigs + [f"t{k}.Q" for k in range(4)] + ["m0", "m1", "e.Q", "cnt.Q"]
    lines.append("e(CLK := " + _bool_expr(rng, sigs) + ");")
    lines.append(f"cnt(CU := e.Q, R := {_bool_expr(rng, sigs)}, PV := {rng.randint(2, 4)});")
    lines.append("CASE s OF")
    for st in range(3):
        lines.append(f"  {st}: IF {_bool_expr(rng, names)} THEN s := {(st + 1) % 3}; END_IF")
    lines.append("END_CASE;")
    for name, kind in timers:
        pt = rng.choice([30, 70, 150, 400, 1000])
        extra = f", RESET := {_bool_expr(rng, sigs)}" if kind == "TONR" else ""
        lines.append(f"{name}(IN := {_bool_expr(rng, names)}, PT := T#{pt}ms{extra});")
    lines.append(f"m0 := {_bool_expr(rng, names)};")
    lines.append(f"m1 := s = {rng.randint(0, 2)} OR {_bool_expr(rng, names)};")
    if rng.random() < 0.5:
        # ET against a constant (scheduled as an event) or in arithmetic (stepping)
        k, op = rng.randrange(4), rng.choice([">", ">=", "<", "<=", "=", "<>"])
        c = rng.choice([0, 20, 35, 100, 150, 500])
        lines.append(f"m1 := m1 {rng.choice(['AND', 'OR', 'XOR'])} (t{k}.ET {op} T#{c}ms);")
        if rng.random() < 0.3:
            lines.append(f"m0 := m0 AND t{k}.ET * 2 > T#{c}ms;")
    lines.append(f"y0 := {_bool_expr(rng, names)};")
    lines.append(f"y1 := s = {rng.randint(0, 2)} AND {_bool_expr(rng, names)};")
    decls = "\n".join(f"  {n} : {k};" for n, k in timers)
    text = f"""PROGRAM Gen
VAR_INPUT i0, i1, c0r, c0e, c1r, c1e : BOOL; END_VAR
VAR_OUTPUT y0, y1 : BOOL; END_VAR
VAR
{decls}
  e : R_TRIG; cnt : CTU; s : INT; m0, m1 : BOOL;
END_VAR
{chr(10).join(lines)}
END_PROGRAM
"""
    inputs = [InputSchedule(f"i{k}", period_s=rng.choice([0.7, 1.3, 2.9]),
                            offset_s=rng.choice([0.0, 0.123, 0.5]),
                            pulse_ms=rng.choice([5, 60, 300])) for k in range(2)]
    cyls = [cylinder(f"c{k}", [f"y{k}"], f"c{k}r", f"c{k}e",
                     (rng.choice([0.05, 0.2, 0.33]), rng.choice([0.07, 0.25])),
                     rng.choice([0.0, 0.013])) for k in range(2)]
    return text, inputs, cyls, rng.choice([1.0, 4.0, 10.0])


@pytest.mark.parametrize("seed", range(24))
def test_event_driven_equals_scan_stepping_on_generated_programs(seed):
    text, inputs, cyls, scan_ms = generated_program(seed)
    prog, m = machine_for(text, cyls, inputs, scan_ms=scan_ms)
    horizon = parse_horizon("12s")
    fast = Sequencer(prog, m).run(horizon, tiling=False)
    ref = Sequencer(prog, m).run(horizon, scan_stepping=True)
    assert fast == ref, text
    tiled = Sequencer(prog, m).run(parse_horizon("60s"))
    full = Sequencer(prog, m).run(parse_horizon("60s"), tiling=False)
    assert tiled == full, text


# ---------------------------------------------------------------------- files and CLI

def test_timeline_csv_contract(tmp_path):
    tl = unfold(SAMPLES / "prototype_rig" / "rig.toml", "20s")
    tl.to_csv(tmp_path / "timeline.csv")
    with open(tmp_path / "timeline.csv", newline="") as f:
        rows = list(csv.reader(f))
    assert rows[0] == ["time_s", "signal", "value"]
    body = rows[1:]
    times = [float(r[0]) for r in body]
    assert times == sorted(times)
    at_zero = {r[1] for r in body if float(r[0]) == 0}
    assert at_zero == set(tl.names)                      # every initial value at 0
    assert {r[2] for r in body} <= {"0", "1"}
    # one row per change: no signal repeats its previous value
    last = {}
    for t, s, v in body:
        assert last.get(s) != v
        last[s] = v


def test_cli_timeline_writes_the_file_and_reports(tmp_path):
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "plcpred.cli", "timeline",
                        str(SAMPLES / "sorter.toml"), "--horizon", "T#1m", "--out", str(out)],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "sorter" in r.stdout and (out / "timeline.csv").is_file()
    lines = (out / "timeline.csv").read_text().splitlines()
    assert float(lines[-1].split(",")[0]) <= 60


def test_cli_timeline_errors_are_clear(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('[machine]\nprogram = "nothere.st"\nsupply_bar_g = 5\n')
    r = subprocess.run([sys.executable, "-m", "plcpred.cli", "timeline", str(bad),
                        "--horizon", "10s", "--out", str(tmp_path / "o")],
                       capture_output=True, text=True)
    # a machine file's mistake is an input error (2), never a finding (1: "the gate failed")
    assert r.returncode == 2 and "nothere.st" in r.stderr and "Traceback" not in r.stderr
    assert not (tmp_path / "o" / "timeline.csv").exists()
    r = subprocess.run([sys.executable, "-m", "plcpred.cli", "timeline",
                        str(SAMPLES / "sorter.toml"), "--horizon", "soon", "--out",
                        str(tmp_path / "o")], capture_output=True, text=True)
    assert r.returncode == 2 and "horizon" in r.stderr


@pytest.mark.parametrize("text,ns", [("90s", 90 * 10**9), ("T#1m30s", 90 * 10**9),
                                     ("8h", 8 * 3600 * 10**9), ("1.5h", 5400 * 10**9),
                                     ("250ms", 250 * 10**6), ("2", 2 * 10**9),
                                     ("1m", 60 * 10**9)])
def test_parse_horizon(text, ns):
    assert parse_horizon(text) == ns


@pytest.mark.parametrize("text", ["", "0s", "-5s", "abc", "T#"])
def test_parse_horizon_rejects(text):
    with pytest.raises(ValueError):
        parse_horizon(text)


def test_signals_may_be_named_by_their_declared_address(tmp_path):
    rig = (SAMPLES / "prototype_rig" / "rig.toml").read_text()
    text = rig.replace('program = "rig.st"', f'program = "{SAMPLES / "prototype_rig" / "rig.st"}"')
    text = text.replace('valve = "Y_A"', 'valve = "%QX0.0"').replace(
        'retracted = "A_RET"', 'retracted = "%IX0.2"')
    (tmp_path / "m.toml").write_text(text)
    by_address = unfold(tmp_path / "m.toml", "20s")
    by_name = unfold(SAMPLES / "prototype_rig" / "rig.toml", "20s")
    assert np.array_equal(by_address.edge_times_ns("Y_A")[0], by_name.edge_times_ns("Y_A")[0])
    assert "Y_A" in by_address.names and "A_RET" in by_address.names


COUNTING = """PROGRAM P
VAR_INPUT go, r0, r1 : BOOL; END_VAR
VAR_OUTPUT y : BOOL; shown : INT; END_VAR
VAR parts : CTU; total : UDINT; edge : R_TRIG; END_VAR
y := go;
edge(CLK := r1);
parts(CU := edge.Q, PV := 1000);
total := total + 1;
{SHOW}
END_PROGRAM"""


@pytest.mark.parametrize("show,tiles", [("", True), ("shown := parts.CV;", False)])
def test_write_only_counters_do_not_stop_tiling(show, tiles):
    prog, m = machine_for(COUNTING.replace("{SHOW}", show),
                          [cylinder("c", ["y"], "r0", "r1", (0.1, 0.1), 0.01)],
                          [InputSchedule("go", period_s=1.0, offset_s=0.2, pulse_ms=400)])
    tl = Sequencer(prog, m).run(parse_horizon("30s"))
    assert (tl.info["period_s"] is not None) == tiles
    assert tl == Sequencer(prog, m).run(parse_horizon("30s"), tiling=False)


def test_a_timer_left_uncalled_does_not_force_scans():
    # t runs while step = 1 and is then no longer called with IN still TRUE
    prog = parse_st("""PROGRAM P
VAR_INPUT go : BOOL; END_VAR
VAR_OUTPUT y : BOOL; END_VAR
VAR t : TON; step : INT; END_VAR
IF step = 0 AND go THEN step := 1; END_IF
IF step = 1 THEN
    t(IN := TRUE, PT := T#200ms);
    IF t.Q THEN step := 2; END_IF
END_IF
y := step = 2 AND go;
END_PROGRAM""", "p.st")
    m = Machine("m", Path("m.toml"), Path("p.st"), scan_ms=10)
    m.inputs = [InputSchedule("go", period_s=5.0, offset_s=1.0, pulse_ms=1000)]
    fast = Sequencer(prog, m).run(parse_horizon("60s"), tiling=False)
    assert fast == Sequencer(prog, m).run(parse_horizon("60s"), scan_stepping=True)
    assert fast.info["scans"] < 200


@pytest.mark.parametrize("use,steps", [("hmi := TIME_TO_DINT(t.ET);", False),
                                       ("y := go AND t.ET < T#150ms;", False),
                                       ("y := go AND t.ET > T#155ms;", False),
                                       ("y := go AND t.ET * 2 < T#300ms;", True)])
def test_reading_et_steps_only_when_it_can_change_an_output(use, steps):
    # ET copied to a display variable changes nothing; compared with a constant it flips
    # at a time the sequencer can schedule; only other uses make it step scan by scan
    prog = parse_st(f"""PROGRAM P
VAR_INPUT go : BOOL; END_VAR
VAR_OUTPUT y : BOOL; END_VAR
VAR t : TON; hmi : DINT; END_VAR
t(IN := go, PT := T#2s);
y := go;
{use}
END_PROGRAM""", "p.st")
    m = Machine("m", Path("m.toml"), Path("p.st"), scan_ms=10)
    m.inputs = [InputSchedule("go", period_s=5.0, offset_s=1.0, pulse_ms=3000)]
    fast = Sequencer(prog, m).run(parse_horizon("20s"), tiling=False, replay=False)
    assert fast == Sequencer(prog, m).run(parse_horizon("20s"), scan_stepping=True)
    assert (fast.info["scans"] > 500) == steps


def test_direct_addresses_in_code(tmp_path):
    (tmp_path / "p.st").write_text("""PROGRAM Raw
VAR_OUTPUT y AT %QX0.1 : BOOL; END_VAR
VAR t : TON; END_VAR
t(IN := %IX0.0, PT := T#300ms);
%QX0.0 := t.Q;
%QX0.1 := NOT %IX0.2;
%QW2 := WORD#16#0008;
END_PROGRAM""")
    (tmp_path / "m.toml").write_text("""[machine]
program = "p.st"
supply_bar_g = 6
[[input]]
signal = "%IX0.0"
pulses_s = [1.0]
pulse_ms = 2000
[[consumer]]
name = "c"
kind = "double_acting"
bore_mm = 20
rod_mm = 8
stroke_mm = 50
valve = "%QX0.0"
stroke_time_s = [0.2, 0.2]
switches = { extended = "%IX0.2" }
""")
    m = load_machine(tmp_path / "m.toml")
    tl = unfold(m, "5s")
    assert not [w for w in m.warnings if "never read" in w]
    assert tl.edges("%QX0.0")["time_s"].tolist() == [0, 1.3, 3.0]
    assert tl.edges("%IX0.2")["time_s"].tolist() == [0, 1.5, 3.01]
    assert tl.edges("y")["time_s"].tolist() == [0, 1.5, 3.01]   # declared AT %QX0.1
    assert tl.value_at("%QW2", 1) == 8                          # a hidden WORD output


def test_programs_run_at_their_task_interval():
    prog = parse_st("""PROGRAM Fast
VAR_INPUT go : BOOL; END_VAR
VAR_OUTPUT fast : BOOL; END_VAR
fast := go;
END_PROGRAM
PROGRAM Slow
VAR_EXTERNAL g : BOOL; END_VAR
VAR_INPUT go2 : BOOL; END_VAR
VAR_OUTPUT slow : BOOL; END_VAR
slow := go2;
END_PROGRAM
CONFIGURATION C
  VAR_GLOBAL g : BOOL; END_VAR
  RESOURCE R ON PLC
    TASK T1(INTERVAL := T#10ms, PRIORITY := 1);
    TASK T2(INTERVAL := T#100ms, PRIORITY := 2);
    PROGRAM pf WITH T1 : Fast;
    PROGRAM ps WITH T2 : Slow;
  END_RESOURCE
END_CONFIGURATION""", "t.st")
    m = Machine("m", Path("m.toml"), Path("t.st"), scan_ms=10)
    m.inputs = [InputSchedule("pf.go", pulses_s=[0.23], pulse_ms=500),
                InputSchedule("ps.go2", pulses_s=[0.23], pulse_ms=500)]
    fast = Sequencer(prog, m).run(parse_horizon("3s"))
    assert fast == Sequencer(prog, m).run(parse_horizon("3s"), scan_stepping=True)
    assert fast.edges("pf.fast")["time_s"].tolist() == [0, 0.23, 0.73]
    assert fast.edges("ps.slow")["time_s"].tolist() == [0, 0.3, 0.8]     # every 100 ms


def _wave_line(stations: int, jitter_s: float = 0.0):
    """Stations of three cylinders, each started by the one before it finishing (a wave
    down the line), the middle cylinder on a bistable valve pulsed for one scan: most
    drives rest while a few move, the case the executor commands and reads lazily."""
    decl, body, consumers = [], [], []
    for s in range(stations):
        start = "part" if s == 0 else f"done{s - 1}"
        decl += [f"st{s} : INT; done{s} : BOOL; trig{s} : R_TRIG;",
                 *(f"a{s}_{c}, a{s}_{c}_off, o{s}_{c}, i{s}_{c} : BOOL;" for c in range(3))]
        body += [f"trig{s}(CLK := {start}); done{s} := FALSE;",
                 f"a{s}_1_off := FALSE;",
                 f"CASE st{s} OF",
                 f"0: IF trig{s}.Q THEN st{s} := 1; END_IF",
                 f"1: a{s}_0 := TRUE; IF o{s}_0 THEN st{s} := 2; END_IF",
                 f"2: a{s}_1 := NOT o{s}_1; IF o{s}_1 THEN st{s} := 3; END_IF",
                 f"3: a{s}_2 := TRUE; IF o{s}_2 THEN st{s} := 4; END_IF",
                 f"4: a{s}_2 := FALSE; a{s}_1_off := NOT i{s}_1; a{s}_0 := FALSE;",
                 f"   IF i{s}_0 AND i{s}_1 AND i{s}_2 THEN st{s} := 0; done{s} := TRUE; END_IF",
                 "END_CASE"]
        for c in range(3):
            valve = [f"a{s}_{c}", f"a{s}_{c}_off"] if c == 1 else [f"a{s}_{c}"]
            consumers.append(cylinder(f"S{s}C{c}", valve, f"i{s}_{c}", f"o{s}_{c}",
                                      (0.08 + 0.03 * c, 0.07 + 0.02 * c), 0.012))
    program = ("PROGRAM Line\nVAR_INPUT part : BOOL; END_VAR\nVAR\n" + "\n".join(decl)
               + "\nEND_VAR\n" + "\n".join(body) + "\nEND_PROGRAM\n")
    schedule = InputSchedule("part", period_s=0.5, offset_s=0.1, pulse_ms=60,
                             jitter_s=jitter_s, seed=3)
    return machine_for(program, consumers, [schedule], scan_ms=4)


@pytest.mark.parametrize("jitter_s", [0.0, 0.05])
def test_a_wave_down_a_wide_line_equals_scan_stepping(jitter_s):
    # parts every 0.5 s into six stations that each take longer than that: several
    # parts in flight, and each station waits for the one before it
    prog, m = _wave_line(6, jitter_s)
    fast = Sequencer(prog, m).run(parse_horizon("12s"), tiling=False)
    ref = Sequencer(prog, m).run(parse_horizon("12s"), scan_stepping=True)
    assert fast == ref
    assert fast.count_rising("o5_2") >= 5            # the wave reaches the last station
    assert fast.count_rising("i5_1") >= 5            # and its bistable valve returns
    if not jitter_s:
        assert Sequencer(prog, m).run(parse_horizon("12s")) == fast      # tiled


@pytest.mark.parametrize("write", ["go := FALSE;", "r := REF(go); r^ := FALSE;",
                                   "clear(x := go);"])
def test_inputs_are_written_every_scan_when_the_program_may_change_them(write):
    # a PLC writes its input image before every scan: a program that overwrites an
    # input (directly, through a reference, or through a VAR_IN_OUT) sees it again
    prog, m = machine_for(f"""FUNCTION_BLOCK FB_Clear
VAR_IN_OUT x : BOOL; END_VAR
x := FALSE;
END_FUNCTION_BLOCK
PROGRAM P
VAR_INPUT go : BOOL; END_VAR
VAR_OUTPUT seen : INT; END_VAR
VAR r : POINTER TO BOOL; clear : FB_Clear; END_VAR
IF go THEN seen := seen + 1; END_IF
{write}
END_PROGRAM""", [], [InputSchedule("go", pulses_s=[0.1], pulse_ms=50)], scan_ms=10)
    tl = Sequencer(prog, m).run(parse_horizon("0.3s"), scan_stepping=True)
    assert tl.value_at("seen", 0.3) == 5                # 50 ms of scans every 10 ms


def test_a_program_writing_a_located_input_sees_it_until_the_next_input_scan():
    # CODESYS, TwinCAT and Beremiz compile a write to an input; the next scan's input
    # image puts the signal's value back (so `seen` is TRUE every scan, and the input
    # follows its schedule)
    prog, m = machine_for("""PROGRAM P
VAR
    s AT %IX0.0 : BOOL;
    seen AT %QX0.0 : BOOL;
    copy AT %QX0.1 : BOOL;
END_VAR
copy := s;
s := TRUE;
seen := s;
END_PROGRAM""", [], [InputSchedule("s", pulses_s=[0.5], pulse_ms=200)], scan_ms=10)
    tl = Sequencer(prog, m).run(parse_horizon("1s"))
    assert tl == Sequencer(prog, m).run(parse_horizon("1s"), scan_stepping=True)
    assert tl.edges("copy")["time_s"].tolist() == pytest.approx([0.0, 0.5, 0.7])
    assert tl.value_at("seen", 0.3) and tl.value_at("seen", 0.9)
    assert not tl.value_at("copy", 0.3) and tl.value_at("copy", 0.6)


def test_timeline_to_frame_holds_each_signal_at_each_change():
    tl = unfold(SAMPLES / "prototype_rig" / "rig.toml", "30s")
    frame = tl.to_frame()
    assert frame.index.name == "time_s" and frame.columns.tolist() == tl.names
    assert frame.index.is_monotonic_increasing and frame.index[0] == 0
    assert len(frame) == len(np.unique(tl.time_ns))
    assert set(frame.dtypes.astype(str)) == {"bool"}
    # each column changes where that signal's edges are, and holds its value in between
    for sig in ("Y_A", "A_EXT", "Y_KNIVES"):
        edges = tl.edges(sig)
        changes = frame[sig][frame[sig] != frame[sig].shift()]
        assert changes.index.tolist() == pytest.approx(edges["time_s"].tolist())
        assert changes.tolist() == [bool(v) for v in edges["value"]]
    assert bool(frame["A_EXT"].loc[0.92]) and not bool(frame["A_EXT"].loc[:0.92 - 1e-9].iloc[-1])
    assert bool(frame.loc[2.0:, "Y_KNIVES"].iloc[0]) == (tl.value_at("Y_KNIVES", 2.0) != 0)


def test_timeline_to_frame_keeps_numbers_and_a_signal_set_twice_at_once():
    from plcpred.sequencer.timeline import NS, Signal, Timeline

    sigs = [Signal("x", "input", "bool"), Signal("n", "output", "int"),
            Signal("r", "output", "real")]
    tl = Timeline(sigs, [0, 0, 0, NS, NS, NS, 2 * NS], [0, 1, 2, 1, 1, 0, 2],
                  [0, 0, 0.5, 3, 4, 1, 2.25], 3 * NS)
    frame = tl.to_frame()
    assert frame.index.tolist() == [0.0, 1.0, 2.0]
    assert frame["x"].tolist() == [False, True, True]
    assert frame["n"].tolist() == [0, 4, 4] and str(frame["n"].dtype) == "int64"
    assert frame["r"].tolist() == [0.5, 0.5, 2.25]
