"""Part replay: a run that cannot tile (jittered part arrivals) copies a recorded
response when the machine is at rest in a state it rested in before and the scheduled
edges ahead fall on the same scans; the result must equal executing every scan."""
import re
from pathlib import Path

import pytest

from plcpred.machine import load_machine
from plcpred.sequencer import parse_horizon
from plcpred.sequencer.executor import Sequencer

SAMPLES = Path(__file__).resolve().parents[2] / "samples"


def jittered(tmp_path, name, fraction=0.05, **replace):
    """A sample with every periodic input jittered by ``fraction`` of its period."""
    path = SAMPLES / f"{name}.toml"
    text = path.read_text()
    prog = re.search(r'^program\s*=\s*"([^"]+)"', text, re.M).group(1)
    text = text.replace(f'"{prog}"', f'"{(path.parent / prog).resolve().as_posix()}"', 1)
    for old, new in replace.items():
        text = re.sub(rf"^{old}\s*=.*$", f"{old} = {new}", text, flags=re.M)
    out, n = [], 0
    for line in text.splitlines():
        out.append(line)
        m = re.match(r"\s*period_s\s*=\s*([0-9.]+)", line)
        if m:
            out += [f"jitter_s = {float(m.group(1)) * fraction:.3f}", f"seed = {11 + n}"]
            n += 1
    p = tmp_path / f"{name}.toml"
    p.write_text("\n".join(out) + "\n")
    return load_machine(p)


@pytest.mark.parametrize("name,fraction,replace", [
    ("pick_place", 0.05, {}),
    ("clamp_station", 0.05, {}),
    # parts that may arrive while the last one is still handled: responses differ
    ("pick_place", 0.45, {"pulse_ms": "300"}),
    ("sorter", 0.05, {}),
    ("cleaning", 0.05, {}),
])
def test_replayed_parts_equal_every_scan_executed(tmp_path, name, fraction, replace):
    m = jittered(tmp_path, name, fraction, **replace)
    prog = m.read_program()
    horizon = parse_horizon("3min")
    replayed = Sequencer(prog, m).run(horizon)
    executed = Sequencer(prog, m).run(horizon, replay=False)
    assert replayed.tiled is None and executed.tiled is None
    assert replayed == executed
    stepped = Sequencer(prog, m).run(parse_horizon("40s"), scan_stepping=True)
    assert Sequencer(prog, m).run(parse_horizon("40s")) == stepped


def test_replay_executes_a_part_once_per_distinct_response(tmp_path):
    m = jittered(tmp_path, "pick_place")
    prog = m.read_program()
    horizon = parse_horizon("30min")
    replayed = Sequencer(prog, m).run(horizon)
    executed = Sequencer(prog, m).run(horizon, replay=False)
    assert replayed == executed
    # 450 parts: executed, each costs about 50 scans; replayed, about one
    assert executed.info["scans"] > 10 * replayed.info["scans"]


def test_timeline_rows_are_exact_for_every_kind_of_value():
    from plcpred.sequencer.timeline import Signal, Timeline, format_seconds
    tl = Timeline([Signal("a", "output", "real"), Signal("b", "output", "int"),
                   Signal("c", "input", "bool")],
                  [0, 0, 5, 10**9 + 1, 2 * 10**9, 2 * 10**9 + 250_000_000],
                  [0, 2, 1, 0, 1, 2], [0.1, 1.0, -3, float("nan"), 7, 0.0], 3 * 10**9)
    expected = "".join(
        f"{format_seconds(t)},{tl.names[s]},{v!r}\n" if s == 0 else
        f"{format_seconds(t)},{tl.names[s]},{int(v)}\n"
        for t, s, v in zip(tl.time_ns.tolist(), tl.signal_idx.tolist(), tl.values.tolist()))
    assert tl._rows(tl.time_ns, tl.signal_idx, tl.values) == expected
    assert expected.splitlines()[2] == "0.000000005,b,-3"


def test_timeline_no_replay_writes_the_same_file_executing_every_part(tmp_path):
    import subprocess
    import sys
    m = jittered(tmp_path, "pick_place")
    runs = {}
    for flag in ([], ["--no-replay"]):
        out = tmp_path / ("b" if flag else "a")
        r = subprocess.run([sys.executable, "-m", "plcpred", "timeline", str(m.path),
                            "--horizon", "10min", "--out", str(out)] + flag,
                           capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
        scans = int(re.search(r"(\d+) scans executed", r.stdout).group(1))
        runs[bool(flag)] = ((out / "timeline.csv").read_bytes(), scans)
    assert runs[False][0] == runs[True][0]
    assert runs[True][1] > 5 * runs[False][1]
