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
