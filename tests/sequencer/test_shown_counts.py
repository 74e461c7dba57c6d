"""A count that nothing in the program reads is left out of the state the sequencer
compares, so a machine that counts its parts still repeats. When the machine file names
that count (``cycle_signal``), timeline.csv shows it: a repeated period, or a replayed
part of a jittered run, must then show the count as execution would (1, 2, 3, ... and
not the first period's values again), wrapping at its type's width as the PLC does. A
signal left out that does not just add a step to itself keeps the run from repeating."""
import re
from pathlib import Path

import numpy as np
import pytest

from plcpred.machine import load_machine
from plcpred.sequencer import parse_horizon
from plcpred.sequencer.executor import Sequencer

SAMPLES = Path(__file__).resolve().parents[2] / "samples"

COUNTS = {
    "step": ("nShown : UDINT;", "nShown := nShown + 1;"),
    "wraps": ("nShown : SINT;", "nShown := nShown + 50;"),          # -128..127
    "down": ("nShown : DINT := 7;", "nShown := 2 - 5 + nShown;"),
    "by_state": ("nShown : INT;", "nShown := nShown + SEL(xXCmd, 1, 2);"),
    # not a step (a DINT reaches -1 and stays there only after 32 parts)
    "doubles": ("nShown : DINT;", "nShown := nShown * 2 + 1;"),
    "real": ("nShown : REAL;", "nShown := nShown + 0.1;"),            # no exact sum
    "squares": ("nShown : DINT; nStep : DINT;",                       # a step that grows
                "nStep := nStep + 1; nShown := nShown + nStep;"),
}


def machine_with_count(tmp_path, kind, jitter=False):
    """pick_place with a count added where a part is released, named as cycle_signal."""
    decl, stmt = COUNTS[kind]
    st = (SAMPLES / "codesys_pick_place.st").read_text()
    st = st.replace("    xZCmd, xXCmd, xGripCmd : BOOL;\nEND_VAR",
                    f"    xZCmd, xXCmd, xGripCmd : BOOL;\n    {decl}\nEND_VAR")
    st = st.replace("            stCount.nParts := stCount.nParts + 1;\n",
                    f"            stCount.nParts := stCount.nParts + 1;\n            {stmt}\n")
    assert stmt in st
    (tmp_path / "p.st").write_text(st)
    text = (SAMPLES / "pick_place.toml").read_text()
    text = text.replace('program = "codesys_pick_place.st"', 'program = "p.st"')
    text = text.replace("scan_ms = 4\n", 'scan_ms = 4\ncycle_signal = "nShown"\n')
    if jitter:
        text = re.sub(r"^period_s = 4.0$", "period_s = 4.0\njitter_s = 0.2\nseed = 3", text,
                      flags=re.M)
    (tmp_path / "m.toml").write_text(text)
    return load_machine(tmp_path / "m.toml")


def shown(tl):
    return tl.edge_times_ns("nShown")[1]


@pytest.mark.parametrize("kind,tiles", [("step", True), ("wraps", True), ("down", True),
                                        ("by_state", True), ("doubles", False),
                                        ("real", False), ("squares", False)])
def test_a_shown_count_repeats_as_execution_shows_it(tmp_path, kind, tiles):
    m = machine_with_count(tmp_path, kind)
    prog = m.read_program()
    horizon = parse_horizon("2min")
    tiled = Sequencer(prog, m).run(horizon)
    full = Sequencer(prog, m).run(horizon, tiling=False)
    assert (tiled.tiled is not None) == tiles
    assert tiled == full
    # the files too: a repeated period's rows are not copied text
    tiled.to_csv(tmp_path / "tiled.csv")
    full.to_csv(tmp_path / "full.csv")
    assert (tmp_path / "tiled.csv").read_text() == (tmp_path / "full.csv").read_text()


def test_the_count_goes_on_counting_and_wraps_at_its_width(tmp_path):
    tl = Sequencer(*reversed((m := machine_with_count(tmp_path, "step"),
                              m.read_program()))).run(parse_horizon("10min"))
    assert tl.tiled is not None
    assert list(shown(tl)) == list(range(151))           # a part every 4 s: 150 parts
    tl = Sequencer(*reversed((m := machine_with_count(tmp_path, "wraps"),
                              m.read_program()))).run(parse_horizon("1min"))
    # SINT: 0, 50, 100, 150 - 256 = -106, -56, ...
    expected = [((50 * k + 128) % 256) - 128 for k in range(16)]
    assert list(shown(tl)) == expected


def test_replayed_parts_of_a_jittered_run_count_on(tmp_path):
    m = machine_with_count(tmp_path, "step", jitter=True)
    prog = m.read_program()
    horizon = parse_horizon("5min")
    replayed = Sequencer(prog, m).run(horizon)
    executed = Sequencer(prog, m).run(horizon, replay=False)
    assert replayed.tiled is None
    assert replayed == executed
    assert executed.info["scans"] > 5 * replayed.info["scans"]      # parts were copied
    values = shown(replayed)
    assert np.array_equal(values, np.arange(len(values)))


@pytest.mark.parametrize("kind", ["doubles", "squares"])
def test_replay_executes_parts_whose_left_out_signal_is_no_count(tmp_path, kind):
    m = machine_with_count(tmp_path, kind, jitter=True)
    prog = m.read_program()
    horizon = parse_horizon("2min")
    assert Sequencer(prog, m).run(horizon) == Sequencer(prog, m).run(horizon, replay=False)
