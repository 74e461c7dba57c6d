"""Independent parts (islands) of a program: each runs on its own and the edges merge to
the timeline of the whole machine with every scan executed (issue 40)."""
import copy
import sys
from pathlib import Path

import pytest

from plcpred import load_machine, unfold
from plcpred.parser import load_program as parse_file
from plcpred.sequencer.executor import ProgramInstance, Sequencer
from plcpred.sequencer.islands import find_islands

sys.path.insert(0, str(Path(__file__).parent))
sys.path.insert(0, str(Path(__file__).parents[1]))
import linegen
import progen

ROOT = Path(__file__).resolve().parents[2]
SAMPLES = sorted((ROOT / "samples").glob("*.toml")) + sorted(
    (ROOT / "samples").glob("*/*.toml"))


def _write(tmp_path, text, machine, name="line"):
    (tmp_path / f"{name}.st").write_text(text)
    (tmp_path / "machine.toml").write_text(machine.replace('"line.st"', f'"{name}.st"'))
    return load_machine(tmp_path / "machine.toml")


def _same(a, b):
    diff = progen.compare(a, b, ("islands", "scan-stepping"))
    assert diff is None, diff


@pytest.mark.parametrize("seed", range(12))
def test_generated_lines_of_independent_stations_equal_every_scan_executed(tmp_path, seed):
    line = linegen.line(seed)
    m = _write(tmp_path, line.program, line.machine)
    fast = unfold(m, "40s")
    assert fast.info.get("islands") == line.stations, line.style
    _same(fast, unfold(m, "40s", scan_stepping=True))


@pytest.mark.parametrize("seed", range(8))
def test_coupled_stations_are_one_island_and_still_exact(tmp_path, seed):
    line = linegen.line(100 + seed, coupled=True)
    m = _write(tmp_path, line.program, line.machine)
    fast = unfold(m, "30s")
    assert fast.info.get("islands") is None, (line.style, line.coupled)
    _same(fast, unfold(m, "30s", scan_stepping=True))


def test_the_fb_line_with_jittered_stations_runs_per_station(tmp_path):
    sys.path.insert(0, str(ROOT / "bench"))
    import scale
    m = _write(tmp_path, scale.line_program(30, "fb_jittered"),
               scale.line_machine(30, "fb_jittered", "line.st"))
    fast = unfold(m, "90s")
    whole = unfold(m, "90s", islands=False)
    assert fast.info["islands"] == 3
    assert fast == whole == unfold(m, "90s", scan_stepping=True)
    # each station replays its parts: far fewer scans than the line as a whole
    assert whole.info["scans"] > 5 * fast.info["scans"]


@pytest.mark.parametrize("path", SAMPLES, ids=lambda p: p.stem)
def test_every_sample_jittered_input_by_input_equals_every_scan_executed(path):
    m = load_machine(path)
    for k, s in enumerate(m.inputs):
        if s.period_s is not None:
            s.jitter_s, s.seed = 0.2, k + 1
    _same(unfold(m, "90s"), unfold(m, "90s", scan_stepping=True))


def test_generated_programs_that_split_equal_every_scan_executed(tmp_path):
    split = 0
    for k in range(60):
        case = progen.generate(f"islands-{k}")
        m = load_machine(case.write(tmp_path / str(k % 2)))
        fast = unfold(m, case.horizon)
        if fast.info.get("islands"):
            split += 1
            _same(fast, unfold(m, case.horizon, scan_stepping=True))
    assert split >= 2       # the generator makes some programs with independent parts


SHARED = """VAR_GLOBAL
    xA, xB, qA, qB : BOOL;
    xSpare : BOOL;      (* touched by nothing: an island of its own, so never just one *)
    {extra}
END_VAR
PROGRAM P
VAR
    i : INT;
    aCount : ARRAY[0..1] OF INT;
    {local}
END_VAR
{body}
END_PROGRAM
"""


def _islands(tmp_path, body, extra="", local=""):
    text = SHARED.format(body=body, extra=extra, local=local)
    (tmp_path / "p.st").write_text(text)
    prog = parse_file(tmp_path / "p.st")
    seq = Sequencer(prog, None)
    inst = ProgramInstance(prog, seq.compiled)
    part = find_islands(prog, seq.compiled, inst)
    if part is None:
        return None
    return part.cells[("G", "QA", None)] == part.cells[("G", "QB", None)]


def test_analysis_keeps_apart_only_what_shares_nothing(tmp_path):
    assert _islands(tmp_path, "qA := xA;\nqB := xB;") is False
    # a statement touching both, a condition, a variable both use
    assert _islands(tmp_path, "qA := xA AND xB;\nqB := xB;") is True
    assert _islands(tmp_path, "IF xA THEN qB := xB; END_IF\nqA := xA;") is True
    assert _islands(tmp_path, "n := n + 1;\nqA := xA AND n > 3;\nqB := xB AND n > 4;",
                    local="n : INT;") is True
    # elements of an array indexed by a constant or an unrolled loop are cells
    assert _islands(tmp_path, "FOR i := 0 TO 1 DO aCount[i] := aCount[i] + 1; END_FOR\n"
                    "qA := xA AND aCount[0] > 2;\nqB := xB AND aCount[1] > 2;") is False
    # ... but not when the loop variable is read after the loop (its end value depends
    # on nothing here, yet the rule is simple), or the loop may EXIT
    assert _islands(tmp_path, "FOR i := 0 TO 1 DO aCount[i] := aCount[i] + 1; END_FOR\n"
                    "qA := xA AND aCount[0] > i;\nqB := xB AND aCount[1] > 2;") is True
    assert _islands(tmp_path, "FOR i := 0 TO 1 DO aCount[i] := aCount[i] + 1; "
                    "IF xA THEN EXIT; END_IF END_FOR\n"
                    "qA := aCount[0] > 2;\nqB := xB AND aCount[1] > 2;") is True
    # an index the analysis cannot tell joins every element
    assert _islands(tmp_path, "aCount[n] := 1;\nqA := xA AND aCount[0] > 2;\n"
                    "qB := xB AND aCount[1] > 2;", local="n : INT;") is True
    # what it cannot follow at all: one island
    assert _islands(tmp_path, "qA := xA;\nIF xB THEN RETURN; END_IF\nqB := xB;") is None
    assert _islands(tmp_path, "qA := xA;\nqB := xB;\np := ADR(qA);",
                    local="p : POINTER TO BOOL;") is None


def test_function_blocks_that_touch_globals_join_every_caller(tmp_path):
    text = """VAR_GLOBAL
    xA, xB, qA, qB : BOOL;
    nShared : INT;
END_VAR
FUNCTION_BLOCK FB_Count
VAR_INPUT x : BOOL; END_VAR
VAR_OUTPUT q : BOOL; END_VAR
IF x THEN nShared := nShared + 1; END_IF
q := x AND nShared > 2;
END_FUNCTION_BLOCK
PROGRAM P
VAR
    fbA, fbB : FB_Count;
END_VAR
fbA(x := xA);
qA := fbA.q;
fbB(x := xB);
qB := fbB.q;
END_PROGRAM
"""
    (tmp_path / "p.st").write_text(text)
    prog = parse_file(tmp_path / "p.st")
    seq = Sequencer(prog, None)
    part = find_islands(prog, seq.compiled, ProgramInstance(prog, seq.compiled))
    assert part is None or part.cells[("G", "QA", None)] == part.cells[("G", "QB", None)]
    without = text.replace("nShared := nShared + 1", "q := TRUE").replace(
        "AND nShared > 2", "")
    (tmp_path / "p.st").write_text(without)
    prog = parse_file(tmp_path / "p.st")
    seq = Sequencer(prog, None)
    part = find_islands(prog, seq.compiled, ProgramInstance(prog, seq.compiled))
    assert part.cells[("G", "QA", None)] != part.cells[("G", "QB", None)]


def test_islands_equal_the_machine_run_as_a_whole_with_replay(tmp_path):
    # the merge by time keeps the order one run records within a scan (signal order)
    for style in linegen.STYLES:
        line = linegen.line(3, style=style)
        m = _write(tmp_path, line.program, line.machine)
        fast = unfold(m, "60s")
        assert fast.info["islands"] == line.stations
        assert fast == unfold(copy.deepcopy(m), "60s", islands=False)


def _jittered_sample(name, seed=3):
    m = load_machine(ROOT / "samples" / f"{name}.toml")
    for k, s in enumerate(m.inputs):
        if s.period_s is not None:
            s.jitter_s, s.seed = 0.2, seed + k
    return m


def _same_everywhere(a, b, tmp_path):
    """Two timelines alike in every way one is read: arrays, rows, each signal's edges."""
    assert a.n_changes == b.n_changes
    a.to_csv(tmp_path / "a.csv")
    b.to_csv(tmp_path / "b.csv")
    assert (tmp_path / "a.csv").read_bytes() == (tmp_path / "b.csv").read_bytes()
    for name in a.names:
        for until in (None, 777 * 10**9 + 5):
            (ta, va), (tb, vb) = a.edge_times_ns(name, until), b.edge_times_ns(name, until)
            assert ta.tolist() == tb.tolist() and va.tolist() == vb.tolist(), name
    assert a == b


def test_replayed_parts_kept_by_reference_read_as_every_part_executed(tmp_path):
    m = _jittered_sample("pick_place")
    prog = m.read_program()
    kept = Sequencer(prog, m).run(1800 * 10**9, islands=False)
    executed = Sequencer(prog, m).run(1800 * 10**9, islands=False, replay=False)
    # the parts are held once: a few executed changes and a reference per replay
    assert kept._replays is not None and len(kept._base[0]) < executed.n_changes / 10
    _same_everywhere(kept, executed, tmp_path)


def test_islands_of_a_long_run_merge_as_they_are_read(tmp_path):
    sys.path.insert(0, str(ROOT / "bench"))
    import scale
    m = _write(tmp_path, scale.line_program(30, "fb_jittered"),
               scale.line_machine(30, "fb_jittered", "line.st"))
    prog = m.read_program()
    lazy = Sequencer(prog, m).run(300 * 10**9, max_events=5_000)
    whole = Sequencer(prog, m).run(300 * 10**9, islands=False, replay=False)
    assert lazy._sources is not None and lazy.n_changes > 5_000
    from plcpred.sequencer.timeline import TimelineTooLarge
    with pytest.raises(TimelineTooLarge):
        _ = lazy.time_ns                # more than max_events are not held at once
    lazy.to_csv(tmp_path / "a.csv")
    whole.to_csv(tmp_path / "b.csv")
    assert (tmp_path / "a.csv").read_bytes() == (tmp_path / "b.csv").read_bytes()
    for name in ("aIo[1].aValve[3]", "aIo[2].xPart", "aIo[0].aRet[9]"):
        (ta, va), (tb, vb) = lazy.edge_times_ns(name), whole.edge_times_ns(name)
        assert ta.tolist() == tb.tolist() and va.tolist() == vb.tolist()


def test_a_chart_resting_in_a_step_nothing_times_replays_its_parts():
    # the press rests in its initial step, whose time nothing reads
    m = _jittered_sample("press")
    prog = m.read_program()
    fast = Sequencer(prog, m).run(600 * 10**9)
    executed = Sequencer(prog, m).run(600 * 10**9, replay=False)
    assert fast == executed == Sequencer(prog, m).run(600 * 10**9, scan_stepping=True)
    assert executed.info["scans"] > 5 * fast.info["scans"]


def test_replays_of_a_long_run_spilled_to_a_file_read_back_the_same(tmp_path, monkeypatch):
    from plcpred.sequencer import executor
    monkeypatch.setattr(executor, "SPILL_REPLAYS", 64)
    monkeypatch.setattr(executor, "KEEP_REPLAYS", 8)
    m = _jittered_sample("pick_place", seed=5)
    prog = m.read_program()
    spilled = Sequencer(prog, m).run(1800 * 10**9, islands=False)
    assert len(spilled._replays[0]) > 64
    executed = Sequencer(prog, m).run(1800 * 10**9, islands=False, replay=False)
    _same_everywhere(spilled, executed, tmp_path)
