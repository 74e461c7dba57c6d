"""A global that nothing reads (a memory word a program copies a parts count to for an HMI
the machine file does not name) is left out of the state the executor compares, and so
is what flows only into it: a sorter whose queue count drifts with independently
jittered inputs still finds its rest states again and replays their parts. Read
anywhere (by name, by its address, by another program, by the machine file), it is
compared. Every fast path must equal the run with every scan executed."""
from pathlib import Path

import pytest

from plcpred.machine import Consumer, InputSchedule, Machine
from plcpred.parser import parse_st
from plcpred.sequencer import Sequencer, compile_program, parse_horizon
from plcpred.sequencer.compiler import GLOBALS_CLASS

SORTER = """
PROGRAM Sorter
  VAR_EXTERNAL
    gate, metal, pusher_out, pusher_home, pusher_valve, blow_valve, lamp : BOOL;
    queue_word : DINT;
  END_VAR
  VAR
    edge : R_TRIG;
    push : TP;
    blow : TP;
    queue : CTUD;
  END_VAR
  edge(CLK := gate);
  push(IN := edge.Q AND metal AND pusher_home, PT := T#400ms);
  blow(IN := edge.Q AND NOT metal, PT := T#150ms);
  pusher_valve := push.Q AND NOT pusher_out;
  blow_valve := blow.Q;
  queue(CU := edge.Q, CD := pusher_out, R := FALSE, LD := FALSE, PV := 100);
  queue_word := queue.CV;
  {extra}
END_PROGRAM
{other}
CONFIGURATION Config0
  VAR_GLOBAL
    gate AT %IX0.0 : BOOL;
    metal AT %IX0.1 : BOOL;
    pusher_out AT %IX0.2 : BOOL;
    pusher_home AT %IX0.3 : BOOL;
    pusher_valve AT %QX0.0 : BOOL;
    blow_valve AT %QX0.1 : BOOL;
    lamp AT %QX0.2 : BOOL;
    queue_word AT %MD0 : DINT;
  END_VAR
  RESOURCE Res0 ON PLC
    TASK task0(INTERVAL := T#20ms, PRIORITY := 0);
    PROGRAM instance0 WITH task0 : Sorter;
    {other_instance}
  END_RESOURCE
END_CONFIGURATION
"""

# a program of its own that reads the word: the count lights a lamp
LAMP_PROGRAM = """
PROGRAM Lamp
  VAR_EXTERNAL
    lamp : BOOL;
    queue_word : DINT;
  END_VAR
  lamp := queue_word > 3;
END_PROGRAM
"""


def sorter(extra: str = "", other: str = "", signals: dict | None = None):
    """The sorter with a part sensor and a metal sensor jittered on their own, so that
    the queue count drifts and never repeats."""
    text = SORTER.format(extra=extra, other=other, other_instance=(
        "PROGRAM instance1 WITH task0 : Lamp;" if other else ""))
    m = Machine("sorter", Path("sorter.toml"), Path("sorter.st"), scan_ms=20)
    m.inputs = [InputSchedule("gate", period_s=1.2, offset_s=0.3, pulse_ms=250,
                              jitter_s=0.2, seed=1),
                InputSchedule("metal", period_s=3.6, offset_s=0.25, pulse_ms=400,
                              jitter_s=0.2, seed=2)]
    m.consumers = [
        Consumer("pusher", "double_acting", valve=["pusher_valve"], bore_mm=32, rod_mm=12,
                 stroke_mm=80, stroke_time_s=(0.25, 0.3), switch_delay_s=0.015,
                 switches={"retracted": "pusher_home", "extended": "pusher_out"}),
        Consumer("blow", "nozzle", valve=["blow_valve"], orifice_mm=2.0)]
    if signals:
        m.signals.update(signals)
    return parse_st(text, "sorter.st"), m


def runs(program, machine, horizon="10min"):
    """(the fast run, the same with every part executed, each island not on its own)."""
    h = parse_horizon(horizon)
    fast = Sequencer(program, machine).run(h)
    executed = Sequencer(program, machine).run(h, tiling=False, replay=False,
                                              islands=False)
    return fast, executed


def left_out_globals(program, machine=None) -> set:
    compiled = Sequencer(program, machine).compiled if machine else compile_program(program)
    return set((compiled.left_out or {}).get(GLOBALS_CLASS, ()))


def test_a_count_copied_to_a_word_nothing_reads_lets_parts_replay():
    program, machine = sorter()
    assert left_out_globals(program, machine) == {"QUEUE_WORD"}
    fast, executed = runs(program, machine)
    assert fast.tiled is None
    assert fast == executed
    # about 500 parts: with the count compared nearly every rest state is new and
    # nearly every scan runs
    assert executed.info["scans"] > 2 * fast.info["scans"]
    stepped = Sequencer(program, machine).run(parse_horizon("40s"), scan_stepping=True)
    assert Sequencer(program, machine).run(parse_horizon("40s")) == stepped


@pytest.mark.parametrize("extra,other", [
    ("lamp := queue_word > 3;", ""),
    ("lamp := %MD0 > 3;", ""),
    ("", LAMP_PROGRAM),
    ("IF queue_word > 3 THEN lamp := TRUE; END_IF", ""),
], ids=["by-name", "by-address", "another-program", "condition"])
def test_a_word_read_anywhere_is_compared(extra, other):
    # the lamp shows the count: a run that left the word out would replay the parts
    # of a lamp that is off with it on, or the other way round
    program, machine = sorter(extra, other)
    assert "QUEUE_WORD" not in left_out_globals(program, machine)
    fast, executed = runs(program, machine, "4min")
    assert fast == executed
    assert executed.count_rising("lamp") >= 1


def test_a_word_the_machine_file_names_is_compared():
    program, machine = sorter(signals={"%MD0": "queue_word"})
    assert "QUEUE_WORD" not in left_out_globals(program, machine)
    fast, executed = runs(program, machine, "2min")
    assert fast == executed


def test_only_unlocated_and_memory_words_nothing_reads_are_left_out():
    program, _ = sorter()
    # the process image (inputs the executor writes, outputs the timeline records) and
    # the globals the sorter reads are compared
    assert left_out_globals(program) == {"QUEUE_WORD"}
