"""A short, deterministic fuzz run (the long one is ``bench/fuzz.py``): mutated programs,
machine files and command lines end in a result or a clean error, never a traceback or a
hang."""
import random

import pytest

import fuzzing as F


def _tally(results):
    bad = [d for r, d in results if r in ("traceback", "hang")]
    assert not bad, bad[:5]
    return {r: sum(1 for x, _ in results if x == r) for r in ("ok", "clean")}


def test_mutated_programs():
    rng = random.Random("fuzz-programs")
    results = []
    for _ in range(1200):
        path = rng.choice(F.PROGRAM_FILES)
        results.append(F.run_program(F.mutate_program(path.read_text(), rng), path.suffix))
    counts = _tally(results)
    # the mutations both break programs and leave some running: the run explores both
    assert counts["clean"] > 100 and counts["ok"] > 20, counts


def test_mutated_machine_files(tmp_path):
    rng = random.Random("fuzz-machines")
    results = []
    for k in range(150):
        m = F.mutate_machine(rng.choice(F.MACHINE_FILES), rng)
        path = tmp_path / "m.toml"
        (path.write_bytes if isinstance(m, bytes) else path.write_text)(m)
        argv = ["predict", str(path), "--horizon", "2s", "--out", str(tmp_path / "o")]
        results.append(F.run_cli(argv + (["--no-plot"] if k % 5 else [])))
    counts = _tally(results)
    assert counts["clean"] > 50 and counts["ok"] > 5, counts


def test_command_lines(tmp_path):
    rng = random.Random("fuzz-cli")
    afile = tmp_path / "afile"
    afile.write_text("x")
    results = [F.run_cli(F.random_argv(rng, str(rng.choice(F.MACHINE_FILES)),
                                       tmp_path / "o", afile)) for _ in range(60)]
    counts = _tally(results)
    assert counts["clean"] > 10 and counts["ok"] > 3, counts


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
