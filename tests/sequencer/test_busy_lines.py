"""A line whose stations' cycles overlap never rests all at once: some drive is always
moving. Its repeat is looked for where a scheduled input is taken, not only where the
whole machine rests; tiled from there, the run must equal the run with every scan
executed."""
from pathlib import Path

import pytest

from plcpred.machine import Consumer, InputSchedule, Machine
from plcpred.parser import parse_st
from plcpred.sequencer import Sequencer, parse_horizon

FB_DRIVE = (Path(__file__).resolve().parents[1] / "data" / "lines" / "fb_drive.st").read_text()


def busy_line(stations: int, drives: int, spacing_s: float, jitter_s: float = 0.0):
    """Stations of FB drives extended one after another on their own part sensor, the
    sensors ``spacing_s`` apart within a 2 s period: twenty stations of five drives
    0.1 s apart change something at nearly every scan (no fixed point to look for a
    repeat at)."""
    decl, body, consumers, inputs = [], [], [], []
    for s in range(stations):
        decl.append(f"aDrv{s} : ARRAY[0..{drives - 1}] OF FB_Drive; nStep{s} : INT; "
                    f"part{s} : BOOL;")
        decl += [f"v{s}_{d}, e{s}_{d}, r{s}_{d} : BOOL;" for d in range(drives)]
        body.append(f"CASE nStep{s} OF\n0: IF part{s} THEN nStep{s} := 1; END_IF")
        body += [f"{d + 1}: aDrv{s}[{d}].xCmd := TRUE; IF e{s}_{d} THEN nStep{s} := {d + 2};"
                 " END_IF" for d in range(drives)]
        body.append(f"{drives + 1}: FOR i := 0 TO {drives - 1} DO aDrv{s}[i].xCmd := FALSE;"
                    f" END_FOR\n IF r{s}_0 AND r{s}_{drives - 1} THEN nStep{s} := 0; END_IF\n"
                    "END_CASE")
        body += [f"aDrv{s}[{d}](xExt := e{s}_{d}, xRet := r{s}_{d}, tWatch := T#5s); "
                 f"v{s}_{d} := aDrv{s}[{d}].xValve;" for d in range(drives)]
        consumers += [Consumer(f"S{s}D{d}", "double_acting", valve=[f"v{s}_{d}"], bore_mm=20,
                               rod_mm=8, stroke_mm=50, stroke_time_s=(0.15, 0.1),
                               switch_delay_s=0.012,
                               switches={"retracted": f"r{s}_{d}", "extended": f"e{s}_{d}"})
                      for d in range(drives)]
        inputs.append(InputSchedule(f"part{s}", period_s=2.0, offset_s=0.1 + spacing_s * s,
                                    pulse_ms=100, jitter_s=jitter_s, seed=s + 1))
    text = (FB_DRIVE + "PROGRAM Line\nVAR i : INT;\n" + "\n".join(decl) + "\nEND_VAR\n"
            + "\n".join(body) + "\nEND_PROGRAM\n")
    m = Machine("line", Path("line.toml"), Path("line.st"), scan_ms=10)
    m.consumers, m.inputs = consumers, inputs
    return parse_st(text, "line.st"), m


@pytest.mark.parametrize("stations,drives,spacing_s", [(20, 5, 0.1), (10, 10, 0.2)])
def test_a_line_that_never_rests_tiles_and_equals_every_scan(stations, drives, spacing_s):
    program, machine = busy_line(stations, drives, spacing_s)
    h = parse_horizon("20s")
    tiled = Sequencer(program, machine).run(h)
    executed = Sequencer(program, machine).run(h, tiling=False, replay=False)
    assert executed.info["scans"] > 1900            # of 2000: busy at nearly every scan
    assert tiled == executed
    assert tiled.info["period_s"] == pytest.approx(2.0)
    assert tiled.info["scans"] < executed.info["scans"] / 3
    assert tiled.count_rising(f"e{stations - 1}_{drives - 1}") >= 9     # the last station too


def test_a_jittered_busy_line_is_executed_not_tiled():
    program, machine = busy_line(10, 5, 0.2, jitter_s=0.05)
    h = parse_horizon("12s")
    run = Sequencer(program, machine).run(h)
    assert run.info["period_s"] is None
    assert run == Sequencer(program, machine).run(h, scan_stepping=True)


def test_a_program_writing_its_input_in_a_slower_task_is_not_at_rest():
    # the input image writes the schedule's value before every scan and the slow task
    # writes TRUE over it at its own scans: a state that holds at the task's scans
    # changes at the others (found by bench/fuzz.py --differential, seed full-1128-1033)
    program = parse_st("""PROGRAM Aux
VAR_INPUT i0 : BOOL; END_VAR
VAR ctd0 : CTD; END_VAR
IF ((NOT ctd0.Q XOR i0) XOR ctd0.Q) THEN i0 := TRUE; END_IF
END_PROGRAM
CONFIGURATION Cfg
  RESOURCE Res ON PLC
    TASK tSlow(INTERVAL := T#10500us, PRIORITY := 2);
    PROGRAM pAux WITH tSlow : Aux;
  END_RESOURCE
END_CONFIGURATION""", "aux.st")
    machine = Machine("aux", Path("aux.toml"), Path("aux.st"), scan_ms=2.5)
    machine.inputs = [InputSchedule("pAux.i0", pulses_s=[0.829, 1.186, 2.001, 2.031],
                                    pulse_ms=200)]
    h = parse_horizon("3.333s")
    for kw in ({}, {"tiling": False, "replay": False}):
        assert Sequencer(program, machine).run(h, **kw) == Sequencer(program, machine).run(
            h, scan_stepping=True)


def test_a_timer_expiring_between_its_slow_tasks_runs_is_not_forgotten():
    # a fixed point found after a timer of the slow task expired, before that task ran
    # again: the task still sees the expiry at its next run (bench/fuzz.py
    # --differential, seed full-1128-898)
    program = parse_st("""PROGRAM Main
VAR_INPUT i2 : BOOL; END_VAR
VAR_OUTPUT y2_0 : BOOL; END_VAR
END_PROGRAM
PROGRAM Aux
VAR tBlink0 : TON; q0 : BOOL; aBits0 : ARRAY[1..3] OF BOOL; i2 : INT; END_VAR
tBlink0(IN := NOT tBlink0.Q, PT := T#250ms);
IF tBlink0.Q THEN q0 := NOT q0; END_IF
FOR i2 := 3 TO 2 BY -1 DO aBits0[i2] := aBits0[i2 - 1]; END_FOR
END_PROGRAM
CONFIGURATION Cfg
  RESOURCE Res ON PLC
    TASK tFast(INTERVAL := T#7ms, PRIORITY := 1);
    TASK tSlow(INTERVAL := T#35ms, PRIORITY := 2);
    PROGRAM pMain WITH tFast : Main;
    PROGRAM pAux WITH tSlow : Aux;
  END_RESOURCE
END_CONFIGURATION""", "blink.st")
    machine = Machine("blink", Path("blink.toml"), Path("blink.st"), scan_ms=7)
    machine.inputs = [InputSchedule("pMain.i2", pulses_s=[0.144, 1.784, 2.879], pulse_ms=200)]
    machine.consumers = [Consumer("nozzle", "nozzle", valve=["pAux.q0"], orifice_mm=1.0)]
    h = parse_horizon("3s")
    every_scan = Sequencer(program, machine).run(h, scan_stepping=True)
    assert every_scan.count_rising("pAux.q0") == 4
    for kw in ({}, {"tiling": False, "replay": False}):
        assert Sequencer(program, machine).run(h, **kw) == every_scan
