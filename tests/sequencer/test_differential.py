"""Differential test of the executor: the event-driven run (jumps over scans at fixed
points, tiles repeating periods, replays parts) must give exactly the timeline of running
every scan (``scan_stepping=True``, the reference), row for row.

* a few hundred generated programs with their machine files (``tests/progen.py``:
  counters, toggles, timers, edges, latches, step chains, SFC, drive FBs, arrays, bits
  of words, plain VARs the machine file names as valves, two tasks);
* every sample machine;
* minimal regressions of the bugs found so far.

The long run is ``python bench/fuzz.py --differential 2000``.
"""
from pathlib import Path

import pytest

import progen
from plcpred.machine import load_machine
from plcpred.sequencer import Signal, Timeline, unfold

SAMPLES = Path(__file__).resolve().parents[2] / "samples"
MACHINES = sorted(SAMPLES.glob("*.toml")) + sorted((SAMPLES / "prototype_rig").glob("*.toml"))

N_PROGRAMS = 300

def _both(machine_path, horizon):
    fast = unfold(load_machine(machine_path), horizon)
    ref = unfold(load_machine(machine_path), horizon, scan_stepping=True)
    return fast, ref


# ---------------------------------------------------------------------- generated programs

@pytest.fixture(scope="module")
def generated(tmp_path_factory):
    """seed -> (case, result) for every generated program, run once for all tests."""
    out = {}
    for seed in range(N_PROGRAMS):
        case = progen.generate(seed)
        d = tmp_path_factory.mktemp(f"gen{seed}")
        out[seed] = (case, progen.run_case(case, d, diagnose=False))
    return out


def _report(items) -> str:
    return "\n\n".join(f"seed {seed} ({', '.join(case.features)}), horizon {case.horizon}: "
                       f"{r.detail}\n{case.program}\n{case.machine}"
                       for seed, case, r in items[:3])


def test_generated_programs_parse_compile_and_run(generated):
    errors = [(s, c, r) for s, (c, r) in generated.items() if r.status == "error"]
    assert not errors, f"{len(errors)} generated programs fail to run:\n" + _report(errors)


def test_generated_programs_event_driven_equals_scan_stepping(generated):
    checked = [(s, c, r) for s, (c, r) in generated.items() if r.status != "error"]
    differ = [x for x in checked if x[2].status == "differ"]
    assert len(checked) > N_PROGRAMS // 2
    assert not differ, (f"{len(differ)} of {len(checked)} generated programs differ:\n"
                        + _report(differ))


def test_generated_programs_exercise_what_they_should(generated):
    """The generator keeps producing every construct, named plain VARs in the machine
    files, and runs in which the event-driven executor really skips scans."""
    features = {}
    for case, _ in generated.values():
        for f in case.features:
            features[f] = features.get(f, 0) + 1
    for f in ("toggle", "mod", "xor", "count", "CTU", "CTD", "TON", "TOF", "TP", "blink",
              "SR", "RS", "trig", "case-chain", "sfc-fb", "drive-fb", "fb-array",
              "array-shift", "array-onehot", "word-count", "shown-count", "cycle_signal",
              "two-tasks", "sfc-program"):
        assert features.get(f, 0) >= 3, (f, features)
    named = sum(bool(c.named) for c, _ in generated.values())
    assert named > N_PROGRAMS // 2, named
    # the event-driven runs skip scans: a third of them run under half the scans
    ran = [r for _, r in generated.values() if r.scans]
    assert sum(r.scans[0] < 0.5 * r.scans[1] for r in ran) > len(ran) // 3


def test_generation_is_deterministic():
    a, b = progen.generate(123), progen.generate(123)
    assert (a.program, a.machine, a.horizon) == (b.program, b.machine, b.horizon)
    assert progen.generate(124).program != a.program


def test_compare_names_the_first_difference():
    sig = [Signal("a", "input", "bool"), Signal("q", "output", "bool")]
    t = Timeline(sig, [0, 0, 10**8, 2 * 10**8], [0, 1, 1, 0], [0, 0, 1, 1], 10**9)
    same = Timeline(sig, [0, 0, 10**8, 2 * 10**8], [0, 1, 1, 0], [0, 0, 1, 1], 10**9)
    late = Timeline(sig, [0, 0, 10**8, 3 * 10**8], [0, 1, 1, 0], [0, 0, 1, 1], 10**9)
    assert progen.compare(t, same) is None
    msg = progen.compare(t, late)
    assert msg.startswith("a at 0.2 s: event-driven 1, scan-stepping 0"), msg
    other = Timeline([Signal("b", "input", "bool")], [0], [0], [0], 10**9)
    assert "signal lists differ" in progen.compare(t, other)


# ---------------------------------------------------------------------- samples

@pytest.mark.parametrize("path", MACHINES, ids=lambda p: f"{p.parent.name}/{p.stem}")
def test_every_sample_event_driven_equals_scan_stepping(path):
    # 10 s: every sample's parts repeat within it (pick_place's 4 s period tiles), and
    # each stepped run stays under a tenth of a second
    fast, ref = _both(path, "10s")
    diff = progen.compare(fast, ref)
    assert diff is None, diff
    assert fast.info["scans"] <= ref.info["scans"]


# ---------------------------------------------------------------------- regressions

def _case(tmp_path, name, program, valve, horizon="1s", scan_ms=10):
    case = progen.nozzle_case(name, program, valve, horizon, scan_ms)
    return case.write(tmp_path / name)


@pytest.mark.parametrize("name,program,valve", [pytest.param(*p, id=p[0]) for p in [
    # a plain VAR named as a nozzle's valve that reaches nothing in the program: left
    # out of the compared state, the first scan looked like a fixed point (2 changes
    # event-driven in 1 s against 101)
    ("not_toggle", "PROGRAM Main VAR q : BOOL; END_VAR q := NOT q; END_PROGRAM", "q"),
    ("mod3", "PROGRAM Main VAR n : INT; q : BOOL; END_VAR n := (n + 1) MOD 3; q := n = 0; "
             "END_PROGRAM", "q"),
    ("purge", "PROGRAM Main VAR k : INT; purge : BOOL; END_VAR k := (k + 1) MOD 2; "
              "purge := k = 0; END_PROGRAM", "purge"),
    # the same through a path: an array element, a member of an FB instance
    ("array_shift", "PROGRAM Main VAR a : ARRAY[1..3] OF BOOL; i : INT; END_VAR "
                    "FOR i := 3 TO 2 BY -1 DO a[i] := a[i - 1]; END_FOR a[1] := NOT a[1]; "
                    "END_PROGRAM", "a[3]"),
    ("fb_member", "FUNCTION_BLOCK FB_B VAR_OUTPUT y : BOOL; END_VAR VAR p : BOOL; END_VAR "
                  "p := NOT p; y := TRUE; END_FUNCTION_BLOCK "
                  "PROGRAM Main VAR b : FB_B; END_VAR b(); END_PROGRAM", "b.p"),
]])
def test_named_plain_var_reaching_nothing(tmp_path, name, program, valve):
    fast, ref = _both(_case(tmp_path, name, program, valve), "1s")
    diff = progen.compare(fast, ref)
    assert diff is None, diff
    assert len(ref.time_ns) > 30


def test_bit_of_a_counting_word_named_as_a_valve(tmp_path):
    """A count may stay out of the compared state (its periods are shifted), but not when
    a bit of it is read: before, 1 change against 26."""
    path = _case(tmp_path, "word_bit", "PROGRAM Main VAR wCnt : WORD; END_VAR "
                 "wCnt := wCnt + 1; END_PROGRAM", "wCnt.2")
    fast, ref = _both(path, "1s")
    assert progen.compare(fast, ref) is None, progen.compare(fast, ref)


SLOW_TIMER = """PROGRAM Main
VAR_OUTPUT y : BOOL; END_VAR
y := FALSE;
END_PROGRAM
PROGRAM Aux
VAR_OUTPUT blink : BOOL; END_VAR
VAR t : TON; END_VAR
t(IN := NOT t.Q, PT := T#30ms);
blink := t.Q;
END_PROGRAM
CONFIGURATION Cfg
  RESOURCE Res ON PLC
    TASK tFast(INTERVAL := T#10ms, PRIORITY := 1);
    TASK tSlow(INTERVAL := T#20ms, PRIORITY := 2);
    PROGRAM pMain WITH tFast : Main;
    PROGRAM pAux WITH tSlow : Aux;
  END_RESOURCE
END_CONFIGURATION
"""

SLOW_CHART = """PROGRAM Aux
VAR_OUTPUT y : BOOL; END_VAR
INITIAL_STEP S0:
END_STEP
STEP S1:
    {action}
END_STEP
TRANSITION FROM S0 TO S1 := S0.T {condition}; END_TRANSITION
TRANSITION FROM S1 TO S0 := S1.T >= T#200ms; END_TRANSITION
END_PROGRAM
CONFIGURATION Cfg
  RESOURCE Res ON PLC
    TASK tSlow(INTERVAL := T#20ms, PRIORITY := 1);
    PROGRAM pAux WITH tSlow : Aux;
  END_RESOURCE
END_CONFIGURATION
"""


@pytest.mark.parametrize("program,valve", [
    (SLOW_TIMER, "pAux.blink"),                                    # 1 change against 31
    (SLOW_CHART.format(action="y(N);", condition="> T#120ms"), "y"),  # S0.X: 1 against 6
    (SLOW_CHART.format(action="y(L, T#30ms);", condition=">= T#50ms"), "y"),  # 2 against 9
], ids=["timer", "sfc_step_time", "sfc_timed_action"])
def test_event_in_a_slower_task(tmp_path, program, valve):
    """An event jump to a timer's PT (a step time's threshold, a timed action's end) may
    land on a scan where the program's slower task does not run; before, it was then
    taken as past and never revisited."""
    # 10 ms scans, the program in a 20 ms task: the timer's 30 ms (the step's 120 ms + 1
    # ns, the L action's 30 ms) fall between two of its runs
    path = _case(tmp_path, "slow_task", program, valve)
    fast, ref = _both(path, "1s")
    assert progen.compare(fast, ref) is None, progen.compare(fast, ref)
