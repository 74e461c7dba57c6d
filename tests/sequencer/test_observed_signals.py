"""Every signal the machine file names is observed, whatever the program does with it:
a plain VAR that drives a valve but reaches nothing else in the program was left out of
the state the executor compares, so the event-driven run jumped to the horizon and a
pull request could hide a valve's air from the gate."""
from __future__ import annotations

from pathlib import Path

import pytest

from plcpred.machine import load_machine
from plcpred.parser import parse_st
from plcpred.sequencer import Sequencer, compile_program, observed_names, unfold

NOZZLE = """[machine]
name = "hidden"
program = "p.st"
scan_ms = 10
supply_bar_g = 6.0

[[consumer]]
name = "purge"
kind = "nozzle"
valve = "{valve}"
orifice_mm = 1.0
Cd = 0.8
"""

HIDDEN = {
    "toggle": ("q", "PROGRAM Main VAR q : BOOL; END_VAR q := NOT q; END_PROGRAM"),
    "mod3": ("q", "PROGRAM Main VAR q : BOOL; n : INT; END_VAR\n"
                  "n := (n + 1) MOD 3; q := n = 0; END_PROGRAM"),
    "xor chain": ("q", "PROGRAM Main VAR q, a, b : BOOL; END_VAR\n"
                       "a := NOT a; b := b XOR a; q := b AND a; END_PROGRAM"),
    "array element": ("aV[2]", "PROGRAM Main VAR aV : ARRAY[1..3] OF BOOL; i : INT; END_VAR\n"
                               "i := (i MOD 3) + 1; aV[i] := NOT aV[i]; END_PROGRAM"),
    "fb internal": ("fb.x", "FUNCTION_BLOCK FB_T VAR x : BOOL; k : INT; END_VAR\n"
                            "k := (k + 1) MOD 4; x := k < 2; END_FUNCTION_BLOCK\n"
                            "PROGRAM Main VAR fb : FB_T; END_VAR fb(); END_PROGRAM"),
}


def _machine(tmp_path: Path, valve: str, src: str):
    (tmp_path / "p.st").write_text(src)
    (tmp_path / "m.toml").write_text(NOZZLE.format(valve=valve))
    return load_machine(tmp_path / "m.toml")


@pytest.mark.parametrize("case", sorted(HIDDEN))
def test_a_named_plain_var_is_run_as_every_scan_runs_it(tmp_path, case):
    valve, src = HIDDEN[case]
    machine = _machine(tmp_path, valve, src)
    fast = unfold(machine, "1s")
    ref = unfold(machine, "1s", scan_stepping=True)
    assert fast == ref, case
    # the valve really moves: the bug left two changes (its initial value and one edge)
    name = next(iter(fast.info["machine_signals"].values()))
    assert (fast.df["signal"] == name).sum() > 20


def test_the_compiled_program_of_another_machine_is_not_trusted(tmp_path):
    """A caller that compiled the program without the machine (diagnose's timing
    variants, a library user) still gets the full timeline: the Sequencer compiles again
    when the names its machine reads are not all observed."""
    valve, src = HIDDEN["mod3"]
    machine = _machine(tmp_path, valve, src)
    program = parse_st(src, str(tmp_path / "p.st"))
    bare = compile_program(program)
    assert "Q" not in bare.observed
    seq = Sequencer(program, machine, compiled=bare)
    assert "Q" in seq.compiled.observed
    tl = seq.run(1_000_000_000)
    assert tl == unfold(machine, "1s", scan_stepping=True)


def test_observed_names_reach_through_paths_and_addresses(tmp_path):
    (tmp_path / "p.st").write_text(
        "PROGRAM Main VAR fbCyl : ARRAY[1..2] OF BOOL; lamp AT %QX0.3 : BOOL; END_VAR\n"
        "END_PROGRAM")
    (tmp_path / "m.toml").write_text(NOZZLE.format(valve="%QX0.3").replace(
        "[[consumer]]", '[signals]\n"%IX0.1" = "sensor"\n\n[[consumer]]'))
    machine = load_machine(tmp_path / "m.toml")
    names = observed_names(machine, parse_st((tmp_path / "p.st").read_text(), "p.st"))
    assert {"LAMP", "SENSOR"} <= names
