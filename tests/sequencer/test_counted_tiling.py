"""A machine that counts its parts to a threshold (a filter check after N parts) repeats
once the count is past it, as long as nothing reads the count itself: the counter is
compared with its count held at the threshold. Tiled must equal executed; a count that
something reads, or a threshold that may change, keeps the machine from tiling."""
import numpy as np
import pytest

from plcpred import unfold

PROGRAM = """
PROGRAM Station
VAR_INPUT
    bPart    AT %IX0.0 : BOOL;
    bService AT %IX0.1 : BOOL;
END_VAR
VAR_OUTPUT
    bBlow   AT %QX0.0 : BOOL;
    bFilter AT %QX0.1 : BOOL;
    nShown  : INT;
END_VAR
VAR
    fbBlow  : TP;
    fbParts : {counter};
    nLimit  : INT := 12;
    nSeen   : INT;
    pParts  : POINTER TO CTU;
    fbSvc   : R_TRIG;
END_VAR
VAR CONSTANT
    MAX_PARTS : INT := 12;
END_VAR
fbBlow(IN := bPart, PT := T#300ms);
bBlow := fbBlow.Q;
{count}
bFilter := fbParts.Q;
{extra}
END_PROGRAM
"""

MACHINE = """
[machine]
name = "counter"
program = "station.st"
scan_ms = 10
supply_bar_g = 6.0

[[input]]
signal = "bPart"
period_s = 1.0
offset_s = 0.2
pulse_ms = 100

[[consumer]]
name = "blow"
kind = "nozzle"
valve = "bBlow"
orifice_mm = 1.0
Cd = 0.7
"""

UP = "fbParts(CU := bPart, R := FALSE, PV := {pv});"
DOWN = "fbParts(CD := bPart, LD := FALSE, PV := {pv});"


SERVICE = """
[[input]]
signal = "bService"
period_s = 30.0
offset_s = 5.0
pulse_ms = 100
"""


def station(tmp_path, counter="CTU", count=UP, pv="MAX_PARTS", extra="", service=False):
    (tmp_path / "station.st").write_text(PROGRAM.format(
        counter=counter, count=count.format(pv=pv), extra=extra))
    (tmp_path / "m.toml").write_text(MACHINE + (SERVICE if service else ""))
    return tmp_path / "m.toml"


def assert_tiled_equals_executed(path, horizon):
    tiled = unfold(path, horizon)
    full = unfold(path, horizon, tiling=False)
    assert full.tiled is None
    for a, b in ((tiled.time_ns, full.time_ns), (tiled.signal_idx, full.signal_idx),
                 (tiled.values, full.values)):
        assert np.array_equal(a, b)
    return tiled


def test_a_parts_counter_past_its_threshold_lets_the_machine_repeat(tmp_path):
    tl = assert_tiled_equals_executed(station(tmp_path), "120s")
    assert tl.tiled is not None
    # the 12th part arrives at 11.2 s and sets the filter output; only then can it
    # repeat, with the parts' period
    t1, t2 = tl.tiled
    assert t1 >= 11.2e9 and t2 - t1 == 1_000_000_000
    filt = tl.edges("bFilter")
    assert list(filt["value"]) == [0, 1] and filt["time_s"].iloc[1] == pytest.approx(11.2)


def test_a_down_counter_repeats_once_it_reaches_zero(tmp_path):
    # CTD counts down from its initial CV; loaded once with LD it would start at PV
    path = station(tmp_path, "CTD", DOWN, pv="nLimit",
                   extra="IF fbParts.Q THEN nShown := 1; END_IF")
    text = (tmp_path / "station.st").read_text().replace(
        "fbParts : CTD;", "fbParts : CTD := (CV := 5);")
    (tmp_path / "station.st").write_text(text)
    tl = assert_tiled_equals_executed(path, "120s")
    assert tl.tiled is not None and tl.tiled[0] >= 4.2e9


@pytest.mark.parametrize("case", ["count read", "count bound", "instance handed on"])
def test_a_count_that_matters_keeps_the_machine_from_repeating(tmp_path, case):
    # each reaches a count of 100 (at 100.2 s) one way or another: held at 12, the
    # machine would repeat from 12 s on and blow for ever; tiled must equal executed
    stop = "IF {} > 100 THEN bBlow := FALSE; END_IF"
    kwargs = {
        "count read": {"extra": stop.format("fbParts.CV")},
        "count bound": {"count": UP.replace(");", ", CV => nSeen);"),
                        "extra": stop.format("nSeen")},
        "instance handed on": {"extra": "pParts := ADR(fbParts); "
                                        + stop.format("pParts^.CV")},
    }[case]
    tl = assert_tiled_equals_executed(station(tmp_path, **kwargs), "120s")
    assert tl.tiled is None
    assert tl.edges("bBlow")["time_s"].iloc[-1] < 101.0


def test_a_threshold_that_changes_keeps_the_count(tmp_path):
    # each service call switches the threshold between 12 and 100 (at 5, 35, 65, ...
    # s): at 65 s the count (65) is below 100, at 125 s it is past it. Held at 12, the
    # states at 35 s and 95 s would look alike and 125 s would copy 65 s
    toggle = ("fbSvc(CLK := bService); IF fbSvc.Q THEN "
              "IF nLimit = 12 THEN nLimit := 100; ELSE nLimit := 12; END_IF END_IF")
    tl = assert_tiled_equals_executed(
        station(tmp_path, pv="nLimit", extra=toggle, service=True), "200s")
    assert tl.tiled is None
    filt = tl.edges("bFilter")
    assert filt["value"].iloc[-1] == 1 and filt["time_s"].iloc[-1] < 100.0
