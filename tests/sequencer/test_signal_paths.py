"""Signals named as paths into a program's variables: large machines keep their valves
and switches in arrays and their drives in arrays of function blocks, so a machine file
names ``aValve[3]``, ``fbCyl[2].q``, ``stCell.xOut``, ``PRG.aIn[1]`` or a bit of an
element (``aWord[2].3``). Each step is looked up in the declared types; a wrong path is
an error naming the signal."""

import pytest

from plcpred.errors import PlcpredError
from plcpred.machine import load_machine
from plcpred.sequencer import parse_horizon
from plcpred.sequencer.executor import Sequencer

N = 4
PROGRAM = f"""
FUNCTION_BLOCK FB_Cyl
VAR_INPUT xStart : BOOL; xOut : BOOL; xIn : BOOL; END_VAR
VAR_OUTPUT q : BOOL; xDone : BOOL; END_VAR
VAR nStep : INT; trig : R_TRIG; tmr : TON; END_VAR
trig(CLK := xStart);
xDone := FALSE;
CASE nStep OF
  0: IF trig.Q THEN nStep := 1; END_IF
  1: q := TRUE; IF xOut THEN nStep := 2; END_IF
  2: tmr(IN := TRUE, PT := T#300MS); IF tmr.Q THEN tmr(IN := FALSE); nStep := 3; END_IF
  3: q := FALSE; IF xIn THEN nStep := 0; xDone := TRUE; END_IF
END_CASE
END_FUNCTION_BLOCK

TYPE ST_Cell : STRUCT xOut : BOOL; xIn : BOOL; END_STRUCT END_TYPE

VAR_GLOBAL
  xPart : BOOL;
  aValve : ARRAY[1..{N}] OF BOOL;
  aSw : ARRAY[0..1, 1..{N}] OF BOOL;     (* [0, i]: retracted, [1, i]: extended *)
  wBlow : ARRAY[1..2] OF WORD;
  stCell : ST_Cell;
END_VAR

PROGRAM Line
VAR
  fbCyl : ARRAY[1..{N}] OF FB_Cyl;
  fbLast : FB_Cyl;
  i : INT;
END_VAR
FOR i := 1 TO {N} DO
  fbCyl[i](xStart := xPart, xOut := aSw[1, i], xIn := aSw[0, i], q => aValve[i]);
END_FOR
fbLast(xStart := fbCyl[{N}].xDone, xOut := stCell.xOut, xIn := stCell.xIn);
wBlow[2].3 := fbLast.q;
END_PROGRAM
"""


def machine_text(extra_cylinder=True, last_valve="Line.fbLast.q", **swap):
    out = ["[machine]", 'name = "paths"', 'program = "line.st"', "scan_ms = 5",
           "supply_bar_g = 6.0", "", "[[input]]", 'signal = "xPart"', "period_s = 4.0",
           "offset_s = 0.5", "pulse_ms = 300"]
    for i in range(1, N + 1):
        out += ["", "[[consumer]]", f'name = "C{i}"', 'kind = "double_acting"',
                "bore_mm = 20", "rod_mm = 8", "stroke_mm = 40",
                f'valve = "{swap.get("valve", "aValve[{i}]").format(i=i)}"',
                "stroke_time_s = [0.2, 0.2]", "switch_delay_s = 0.01",
                f'switches = {{ retracted = "aSw[0, {i}]", extended = "aSw[1,{i}]" }}']
    if extra_cylinder:
        out += ["", "[[consumer]]", 'name = "last"', 'kind = "double_acting"',
                "bore_mm = 20", "rod_mm = 8", "stroke_mm = 40", f'valve = "{last_valve}"',
                "stroke_time_s = [0.2, 0.2]", "switch_delay_s = 0.01",
                'switches = { retracted = "stCell.xIn", extended = "stCell.xOut" }']
    out += ["", "[[consumer]]", 'name = "blow"', 'kind = "nozzle"', 'valve = "wBlow[2].3"',
            "orifice_mm = 1.0", "Cd = 0.8"]
    return "\n".join(out) + "\n"


def load(tmp_path, text=None, program=PROGRAM):
    (tmp_path / "line.st").write_text(program)
    (tmp_path / "m.toml").write_text(text or machine_text())
    return load_machine(tmp_path / "m.toml")


def run(m, horizon="30s", **kw):
    return Sequencer(m.read_program(), m).run(parse_horizon(horizon), **kw)


def test_array_elements_members_and_bits_drive_and_are_driven(tmp_path):
    m = load(tmp_path)
    tl = run(m)
    # a part every 4 s: each cylinder in the array and the one after them strokes
    # once per part, and the blow-off bit follows the last one's valve
    for i in range(1, N + 1):
        assert tl.count_rising(f"aValve[{i}]") == 8
    assert tl.count_rising("Line.fbLast.q") == 8
    t_last, v_last = tl.edge_times_ns("Line.fbLast.q")
    t_blow, v_blow = tl.edge_times_ns("wBlow[2].3")
    assert list(v_blow) == list(v_last) and list(t_blow) == list(t_last)
    # the switches were driven: each valve drops after its extended switch
    # (stroke 0.2 s after a 10 ms delay) and the 300 ms hold
    t, v = tl.edge_times_ns("aValve[1]")
    on, off = t[v == 1][0], t[(v == 0) & (t > t[v == 1][0])][0]
    assert (off - on) / 1e9 == pytest.approx(0.21 + 0.3, abs=0.011)


def test_paths_give_what_event_jumps_tiling_and_stepping_agree_on(tmp_path):
    m = load(tmp_path)
    tiled = run(m, "60s")
    assert tiled.tiled is not None
    assert tiled == run(m, "60s", tiling=False)
    assert run(m, "20s", tiling=False) == run(m, "20s", scan_stepping=True)


@pytest.mark.parametrize("valve, message", [
    ("aValve[{i}7]", r"index 17 outside \[1..4\]"),
    ("aValve[1, {i}]", "2 indices for an array of 1 dimensions"),
    ("fbCyl[{i}].nothing", "no member 'NOTHING'"),
    ("fbCyl[{i}]", "is a fb, not a BOOL"),
    ("xPart[{i}]", "not an array"),
    ("aValve[{i}]]", "cannot read ']'"),
])
def test_a_wrong_path_names_the_signal(tmp_path, valve, message):
    from plcpred.machine import MachineError
    m = load(tmp_path, machine_text(valve=valve))
    with pytest.raises(PlcpredError, match=message) as e:
        run(m)
    assert "signal '" in str(e.value) and "m.toml" in str(e.value)
    # the machine file's mistake: exit 2 like every other, naming the table that gives it
    assert isinstance(e.value, MachineError) and "[[consumer]]" in str(e.value)
    assert "valve" in str(e.value)


def test_a_path_whose_variable_does_not_exist_fails_before_the_run(tmp_path):
    from plcpred import unfold
    m = load(tmp_path, machine_text(valve="aValves[{i}]"))
    with pytest.raises(PlcpredError, match="valve 'aValves\\[1\\]' is not a variable of "
                                           "line.st"):
        unfold(m, "10s")


def test_an_element_named_twice_is_one_signal(tmp_path):
    # the last cylinder's valve also drives a nozzle, spelt another way
    text = machine_text().replace('valve = "wBlow[2].3"', 'valve = "Line.fbLast . q"')
    m = load(tmp_path, text.replace('extended = "aSw[1,2]"', 'extended = "aSw[ 1 , 2 ]"'))
    tl = run(m)
    names = [s.name for s in tl.signals]
    assert len(names) == len(set(names))
    assert sum("aSw" in n and "2" in n.split(",")[1] for n in names) == 2   # [0, 2], [1,2]


def test_a_count_inside_an_element_counts_on_when_the_run_repeats(tmp_path):
    program = PROGRAM.replace("VAR nStep : INT;", "VAR nParts : UINT; nStep : INT;").replace(
        "nStep := 0; xDone := TRUE;", "nStep := 0; xDone := TRUE; nParts := nParts + 1;")
    text = machine_text().replace("scan_ms = 5", 'scan_ms = 5\ncycle_signal = "fbCyl[2].nParts"')
    m = load(tmp_path, text, program)
    tiled = run(m, "2min")
    assert tiled.tiled is not None
    assert tiled == run(m, "2min", tiling=False)
    assert list(tiled.edge_times_ns("fbCyl[2].nParts")[1]) == list(range(31))


def test_a_two_dimensional_element_survives_timeline_csv(tmp_path):
    from plcpred.diagnose import read_io_timeline
    tl = run(load(tmp_path), "10s")
    assert "aSw[1,2]" in tl.names             # spelt without spaces, whatever the file says
    tl.to_csv(tmp_path / "timeline.csv")
    assert '"aSw[1,2]"' in (tmp_path / "timeline.csv").read_text()
    back = read_io_timeline(tmp_path / "timeline.csv", horizon_s=10)
    for name in ("aSw[1,2]", "aValve[3]", "wBlow[2].3"):
        t, v = tl.edge_times_ns(name)
        t2, v2 = back.edge_times_ns(name)
        assert list(t) == list(t2) and list(v) == list(v2)



def test_a_signal_missing_from_a_program_given_instead_names_that_program(tmp_path, capsys):
    from plcpred.cli import main
    m = tmp_path / "m.toml"
    (tmp_path / "p.st").write_text("PROGRAM Main VAR q : BOOL; END_VAR q := NOT q; END_PROGRAM\n")
    (tmp_path / "other.st").write_text("PROGRAM Main VAR r : BOOL; END_VAR r := NOT r; "
                                       "END_PROGRAM\n")
    m.write_text('[machine]\nname = "m"\nprogram = "p.st"\nscan_ms = 10\nsupply_bar_g = 6\n'
                 '[[consumer]]\nname = "n"\nkind = "nozzle"\nvalve = "q"\norifice_mm = 1\nCd = 0.8\n')
    rc = main(["predict", str(m), "--program", str(tmp_path / "other.st"), "--horizon", "1s",
               "--out", str(tmp_path / "o"), "--no-plot"])
    err = capsys.readouterr().err
    assert rc == 2 and "valve 'q' is not a variable of other.st" in err, err
