"""A function block's output that nothing outside it reads (a stroke counter in an FB
per drive) is left out of the state the executor compares, as a local counter is: the
line repeats and tiles. Read anywhere (a member access, an output binding, the machine
file, a derived FB's code), it is compared. Tiled and event-driven runs must equal the
run with every scan executed."""
from pathlib import Path

import pytest

from plcpred.machine import Consumer, InputSchedule, Machine
from plcpred.parser import parse_st
from plcpred.sequencer import Sequencer, parse_horizon

FB_DRIVE = (Path(__file__).resolve().parents[1] / "data" / "lines" / "fb_drive.st").read_text()


def station(drives: int, extra_decl: str = "", extra_code: str = "", fb: str = FB_DRIVE,
            drive_type: str = "FB_Drive", temp_decl: str = "b : BOOL;"):
    """One station: a part sensor starts a step chain that extends the drives one after
    another (each step waits for its end switch), then retracts them all."""
    steps = "\n".join(f"{d + 1}: aDrv[{d}].xCmd := TRUE; IF e{d} THEN nStep := {d + 2}; END_IF"
                      for d in range(drives))
    calls = "\n".join(f"aDrv[{d}](xExt := e{d}, xRet := r{d}, tWatch := T#5s); "
                      f"v{d} := aDrv[{d}].xValve;" for d in range(drives))
    switches = " ".join(f"v{d}, e{d}, r{d} : BOOL;" for d in range(drives))
    text = f"""{fb}
PROGRAM Station
VAR
    part : BOOL; nStep : INT; i : INT;
    aDrv : ARRAY[0..{drives - 1}] OF {drive_type};
    {switches}
    {extra_decl}
END_VAR
VAR_TEMP
    {temp_decl}
END_VAR
CASE nStep OF
0: IF part THEN nStep := 1; END_IF
{steps}
{drives + 1}: FOR i := 0 TO {drives - 1} DO aDrv[i].xCmd := FALSE; END_FOR
   IF r0 AND r{drives - 1} THEN nStep := 0; END_IF
END_CASE
{calls}
{extra_code}
END_PROGRAM
"""
    m = Machine("station", Path("station.toml"), Path("station.st"), scan_ms=10)
    m.consumers = [Consumer(f"D{d}", "double_acting", valve=[f"v{d}"], bore_mm=20, rod_mm=8,
                            stroke_mm=50, stroke_time_s=(0.1 + 0.02 * d, 0.08),
                            switch_delay_s=0.012,
                            switches={"retracted": f"r{d}", "extended": f"e{d}"})
                   for d in range(drives)]
    m.inputs = [InputSchedule("part", period_s=2.0, offset_s=0.1, pulse_ms=100)]
    return parse_st(text, "station.st"), m


def runs(program, machine, horizon="30s"):
    h = parse_horizon(horizon)
    tiled = Sequencer(program, machine).run(h)
    every_scan = Sequencer(program, machine).run(h, scan_stepping=True)
    return tiled, every_scan


def test_an_fb_output_nothing_reads_lets_the_line_tile():
    tiled, every_scan = runs(*station(3))
    assert tiled == every_scan
    assert tiled.info["period_s"] == pytest.approx(2.0)
    assert tiled.count_rising("e2") == 15             # every part moves every drive


@pytest.mark.parametrize("decl,temp,code", [
    ("", "b : BOOL;", "vBlow := aDrv[0].nStrokes = 5;"),
    ("fbExtra : FB_Drive;", "nBound : UDINT;",
     "fbExtra(xCmd := part, nStrokes => nBound); vBlow := nBound = 5;"),
], ids=["member", "binding"])
def test_an_fb_output_read_anywhere_is_compared(decl, temp, code):
    # the fifth part is blown off, counted only in the FB's output (a VAR_TEMP is not
    # state): a run that left the count out would repeat the first part for ever
    program, machine = station(3, "vBlow : BOOL; " + decl, code, temp_decl=temp)
    machine.consumers.append(Consumer("blow", "nozzle", valve=["vBlow"], orifice_mm=1.0))
    tiled, every_scan = runs(program, machine)
    assert tiled == every_scan
    assert tiled.count_rising("vBlow") == 1


def test_an_output_the_machine_file_names_is_compared():
    program, machine = station(2)
    machine.signals = {"strokes": "aDrv[0].nStrokes"}
    tiled, every_scan = runs(program, machine, "20s")
    assert tiled == every_scan


def test_an_output_a_derived_fb_reads_is_compared():
    worn = FB_DRIVE + """
FUNCTION_BLOCK FB_Worn EXTENDS FB_Drive
SUPER^();
IF nStrokes > 3 THEN
    xValve := FALSE;
END_IF
END_FUNCTION_BLOCK
"""
    tiled, every_scan = runs(*station(2, fb=worn, drive_type="FB_Worn"))
    assert tiled == every_scan
    assert tiled.count_rising("e0") == 3              # its valve stays shut from the 4th
