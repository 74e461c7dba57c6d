"""A short, deterministic fuzz run of every input channel (the long one is
``bench/fuzz.py``): mutated programs, machine files, command lines, truth files, flow
logs, --io traces, TwinCAT folders and prepared --out folders each end in a result or a
clean error, never a traceback, a hang, a memory blow-up or harm outside --out. Each run
is a forked child under a time and memory limit (tests/fuzzing.py: Child); the harness
itself is tested first, so that a limit that stopped working would be noticed."""
import os
import random
import time

import pytest

import fuzzing as F

# cases per channel: each channel must produce both results and clean errors (the
# mutators keep some inputs valid and break others), and nothing bad
RUNS = {"programs": 80, "machines": 30, "commands": 40, "truths": 30, "flow logs": 15,
        "io traces": 15, "twincat": 30, "outs": 30}


@pytest.fixture(scope="module")
def fuzzer(tmp_path_factory):
    return F.Fuzzer(tmp_path_factory.mktemp("fuzz"), F.Limits(seconds=20.0))


def _report(tally) -> str:
    lines = [tally.line()]
    for outcome, found in tally.examples.items():
        for _, case, o in found[:5]:
            lines.append(f"{outcome}: {o.detail[:300]}\n    {case.describe()[:300]}\n"
                         f"    {case.work}\n{o.stderr[-1500:]}")
    return "\n".join(lines)


@pytest.mark.parametrize("channel", F.CHANNELS)
def test_channel(fuzzer, channel):
    tally = fuzzer.run(channel, RUNS[channel], seed="test")
    assert tally.bad == 0, _report(tally)
    assert tally.counts["ok"] >= 1 and tally.counts["clean"] >= 1, tally.line()
    assert tally.n == RUNS[channel]


def test_the_same_seed_makes_the_same_inputs(tmp_path):
    fz = F.Fuzzer(tmp_path, keep=True)
    for channel in ("truths", "twincat", "outs", "flow logs"):
        texts = []
        for seed in ("a", "a"):
            rng = random.Random(seed)
            case = fz.make(channel, rng, 0)
            texts.append((case.describe(), sorted(
                (str(p.relative_to(case.work)), p.read_bytes() if p.is_file() and
                 not p.is_symlink() and not p.is_fifo() else b"")
                for p in case.work.rglob("*") if p.name != "sentinel.txt")))
        assert texts[0] == texts[1], channel


def test_type_traps_reach_the_type_checks():
    """The program mutator's type traps are inserted where they parse: most of them alone
    give an error naming the type problem, not a syntax error."""
    from plcpred.errors import PlcpredError
    from plcpred.parser.check import check_program
    from plcpred.parser.st import parse_st
    text = (F.SAMPLES / "codesys_pick_place.st").read_text()
    rng = random.Random("traps")
    syntax = 0
    for _ in range(60):
        try:
            errors, _ = check_program(parse_st(F.insert_type_trap(text, rng), "t.st"))
        except PlcpredError as e:
            syntax += "unexpected" in str(e)
    assert syntax < 15, syntax


# ------------------------------------------------------------------ the harness itself

def _sleep():
    time.sleep(60)


def _hog():
    blocks = []
    while True:
        blocks.append(bytearray(50 * 2**20))


def test_a_hang_is_stopped_and_placed():
    o = F.Child(_sleep, F.Limits(seconds=0.5)).wait()
    # where it hung is best effort (the child's stack dump may come too late under load)
    assert o.outcome == "hang" and o.detail.startswith("over 0.5 s") and o.wall_s < 5, o


def test_memory_beyond_the_rss_limit_is_stopped():
    o = F.Child(_hog, F.Limits(rss_mb=400)).wait()
    assert o.outcome == "memory" and o.detail.startswith("RSS over 400 MB"), o


def test_memory_beyond_the_address_space_limit_is_a_memory_error():
    o = F.Child(_hog, F.Limits(rss_mb=100_000, as_mb=1200)).wait()
    assert o.outcome == "memory" and "MemoryError" in o.detail, o


def test_a_crash_is_a_traceback():
    o = F.Child(lambda: os.kill(os.getpid(), 11), F.Limits()).wait()
    assert o.outcome == "traceback" and "SIGSEGV" in o.detail, o


def test_an_exception_escaping_is_a_traceback_with_its_place():
    def fail():
        return {}["x"]
    o = F.Child(fail, F.Limits()).wait()
    assert o.outcome == "traceback" and "KeyError" in o.detail and "fail" in o.detail, o


@pytest.mark.parametrize("codes, out, err, outcome", [
    ([0], "", "", "ok"), ([1], "", "t.st:1:1: bad", "clean"), ([2], "", "usage", "clean"),
    ([4], "table", "", "clean"), ([3], "", "plcpred: internal error: KeyError", "traceback"),
    ([2], "", "plcpred: error: out of memory (a shorter ...)", "memory"),
    ([1], "", "", "traceback"),                      # an error that says nothing
    ([0], "", "Traceback (most recent call last):\n  File \"x\", line 1, in f\nE: x",
     "traceback"), ([143], "", "terminated", "traceback"), ([0, 2], "", "x", "clean"),
    # the executor shows any exception of a run as a PLC run-time error: Python's wording
    # marks the ones that are bugs, not the program's faults
    ([1], "", "p.st:3:5: run-time error: name 'st_S' is not defined", "traceback"),
    ([1], "", "p.st:3:5: run-time error: 'k'", "traceback"),
    ([1], "", "p.st:3:5: run-time error: KeyError", "traceback"),
    ([1], "", "p.st:3:5: run-time error: integer division by zero", "clean"),
    ([1], "", "p.st:3:5: run-time error: array index 5 outside a[0..1]", "clean"),
    ([1], "", "run-time error: a pointer, reference or interface variable is not set (NULL)",
     "clean"),
    ([2], "", "plcpred: error: operands could not be broadcast together", "traceback"),
    ([1], "", "the plant cannot integrate drive(s) A from 0 s (ZeroDivisionError: float "
              "division by zero); check sizes", "clean")])
def test_exit_codes_are_sorted(codes, out, err, outcome):
    assert F.classify_exit(codes, out, err)[0] == outcome


def test_the_cli_runs_isolated(tmp_path):
    o = F.isolated_cli(["predict", str(F.SAMPLES / "press.toml"), "--horizon", "1s",
                        "--out", str(tmp_path / "o"), "--no-plot"])
    assert o.outcome == "ok" and 0 < o.rss_mb < 1500, o
    assert (tmp_path / "o" / "manifest.json").exists()
    assert F.isolated_cli(["check", "/nonexistent.st"]).outcome == "clean"
    assert F.isolated_cli(["bogus"]).outcome == "clean"


@pytest.mark.parametrize("harm", ["sentinel", "user file", "link", "outside folder"])
def test_the_out_check_notices_harm(tmp_path, harm):
    rng = random.Random("harm")
    case = F._out_case(rng, tmp_path)
    out = tmp_path / "out"
    if harm == "sentinel":
        (tmp_path / "sentinel.txt").unlink()
    elif harm == "user file":
        name = next(n for n in F.USER_FILES if (out / n).is_file())
        (out / name).write_text("overwritten")
    elif harm == "link":
        (out / "link.csv").unlink(missing_ok=True)
        (out / "link.csv").symlink_to(tmp_path / "elsewhere")
        if "link.csv" not in F._snapshot(out):
            pytest.skip("this seed plants no link")
    else:
        (tmp_path / "sentinel_dir" / "a.txt").write_text("changed")
    assert case.judge(F.Outcome("ok")).outcome == "unsafe"


# ------------------------------------------------------------------ machine values

@pytest.mark.parametrize("value", [10**400, float("nan"), float("inf"), 1e-300, -1.0,
                                   "$\\alpha$", "x" * 5000, [], {"a": 1}])
def test_each_odd_value_in_each_consumer_key(tmp_path, value):
    """Every key of every consumer of one machine, set to one odd value."""
    import tomllib
    base = tomllib.loads((F.SAMPLES / "pick_place.toml").read_text())
    base["machine"]["program"] = str(F.SAMPLES / base["machine"]["program"])
    for ci, consumer in enumerate(base["consumer"]):
        for key in consumer:
            data = tomllib.loads(F.dump_toml(base))
            data["consumer"][ci][key] = value
            path = tmp_path / "m.toml"
            path.write_text(F.dump_toml(data))
            r, detail = F.run_cli(["predict", str(path), "--horizon", "1s", "--no-plot",
                                   "--out", str(tmp_path / "o")])
            assert r in ("ok", "clean"), (key, value, detail)
