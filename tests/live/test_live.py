"""plcpred.live: serve (the emulated machine as an OPC UA server) and watch (an OPC UA
client recording it and comparing it with the prediction), a real asyncua server and a
real client talking over TCP on localhost; nothing is patched."""
import asyncio
import json
import os
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from plcpred.diagnose import read_io_timeline, read_measured
from plcpred.live import Twin, live_settings, serve, watch
from plcpred.machine import MachineError, load_machine
from plcpred.plant import emulate
from plcpred.sequencer.timeline import NS

SAMPLES = Path(__file__).resolve().parents[2] / "samples"
PICK = SAMPLES / "pick_place.toml"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def events(out: Path) -> list[dict]:
    return [json.loads(line) for line in (out / "events.jsonl").read_text().splitlines()]


async def served_and_watched(tmp_path, twin, speed, machine=PICK, **overrides):
    """Serve ``twin``, holding its machine at the start until the watch has connected,
    and watch it until the horizon is served; (serve result, watch result, the folder)."""
    url = f"opc.tcp://127.0.0.1:{free_port()}"
    up, go, stop = asyncio.Event(), asyncio.Event(), asyncio.Event()
    server = asyncio.create_task(serve(twin, url, speed=speed, hold=go,
                                       report=lambda line: up.set()))
    await asyncio.wait_for(up.wait(), 30)
    m = load_machine(machine)
    out = tmp_path / "watch"
    watcher = asyncio.create_task(watch(
        m, out, live_settings(m, endpoint=url, **overrides), duration_s=60, stop=stop,
        report=lambda line: go.set() if line.startswith("connected") else None))
    served = await server
    await asyncio.sleep(0.5)
    stop.set()
    return served, await watcher, out


def recorded_edges(out: Path, number: int, origin_s: float) -> dict:
    """Each signal's recorded changes (after the segment's first rows) on the machine
    clock, as diagnose --io reads them."""
    tl = read_io_timeline(out / f"timeline-{number:04d}.csv")
    edges = {}
    for sig in tl.signals:
        t, v = tl.edge_times_ns(sig.name)
        edges[sig.name] = (t[1:] / NS + origin_s, v[1:])
    return edges


def test_watch_records_the_served_machine_as_diagnose_reads_it(tmp_path):
    twin = Twin(PICK, 24.0, seed=3)
    served, result, out = asyncio.run(served_and_watched(
        tmp_path, twin, speed=30.0, cycle_signal="qX"))
    ev = events(out)
    segment = next(e for e in ev if e["event"] == "segment")
    origin_s = (segment["start_ns"] - _epoch_ns(served.epoch)) / NS
    # the same machine emulated: the edges the server published, to the microsecond
    em = emulate(PICK, 24.0, seed=3)
    recorded = recorded_edges(out, 1, origin_s)
    assert set(recorded) == set(twin.signals)
    compared = 0
    for name, (t, v) in recorded.items():
        et, ev_ = em.timeline.edge_times_ns(em.timeline.info["machine_signals"].get(name, name))
        et, ev_ = et[1:] / NS, ev_[1:]            # after the initial values
        span = (et > origin_s) & (et <= t[-1] + 1e-9) if len(t) else np.zeros(len(et), bool)
        assert len(t) == span.sum(), name
        assert np.allclose(t, et[span], atol=2e-6) and np.array_equal(v, ev_[span]), name
        compared += len(t)
    assert compared > 40
    # the readings: the emulated meter's, at their times
    run = read_measured(out / "measured-0001.csv")
    assert len(run.time_s) > 100
    k = np.searchsorted(em.measured_time_s, run.time_s + origin_s - 1e-6)
    assert np.allclose(em.measured_time_s[k], run.time_s + origin_s, atol=2e-6)
    assert np.allclose(em.measured_flow_l_min[k], run.flow_l_min, rtol=1e-4, atol=1e-3)
    assert np.allclose(run.supply_bar_g, 6.0)
    # per cycle: the meter's air is the plant's, the prediction the air model's (D1 books
    # 7 % more than this plant's drives take, as emulate shows)
    cycles = [e for e in ev if e["event"] == "cycle"]
    assert result.cycles == len(cycles) >= 3
    true = em.true_total_cum_nl()
    for c in cycles:
        a = (_iso_ns(c["start"]) - _epoch_ns(served.epoch)) / NS
        b = a + c["duration_s"]
        plant_nl = np.interp(b, em.edges_s, true) - np.interp(a, em.edges_s, true)
        assert c["measured_nl"] == pytest.approx(plant_nl, rel=0.01)
        assert c["duration_s"] == pytest.approx(4.0, abs=0.02)
        assert -9.0 < c["gap_percent"] < -5.0
        assert c["idle_l_min"] == pytest.approx(c["idle_predicted_l_min"], rel=0.05)
    assert not result.alarms and not result.gaps


def test_a_leak_switched_on_is_flagged_with_its_onset(tmp_path):
    truth = tmp_path / "leak.toml"
    truth.write_text('[[consumer]]\nname = "hidden leak"\nkind = "leak"\norifice_mm = 0.8\n'
                     'Cd = 0.6\n')
    twin = Twin(PICK, 44.0, truth=truth, truth_at_s=14.0, seed=1)
    served, _, out = asyncio.run(served_and_watched(
        tmp_path, twin, speed=40.0, cycle_signal="qX", gap_alarm_cycles=2))
    ev = events(out)
    cycles = [e for e in ev if e["event"] == "cycle"]
    epoch_ns = _epoch_ns(served.epoch)
    before = [c for c in cycles if (_iso_ns(c["start"]) - epoch_ns) / NS + 4.0 <= 14.0]
    after = [c for c in cycles if (_iso_ns(c["start"]) - epoch_ns) / NS >= 14.0]
    assert before and len(after) >= 3
    assert all(-9.0 < c["gap_percent"] < -5.0 for c in before)
    assert all(c["gap_percent"] > 50.0 for c in after)
    alarms = [e for e in ev if e["event"] == "alarm" and e["state"] == "raised"]
    assert [a["alarm"] for a in alarms] == ["gap"]
    onset_s = (_iso_ns(alarms[0]["began"]) - epoch_ns) / NS
    assert 14.0 - 4.0 <= onset_s <= 14.0 + 4.0   # the first cycle with the leak in it
    flagged = next(c for c in cycles if c["number"] == alarms[0]["cycle"])
    assert (_iso_ns(flagged["start"]) - epoch_ns) / NS <= onset_s + 5 * 4.0
    # the leak's flow shows while the machine rests
    assert after[-1]["idle_l_min"] > before[0]["idle_l_min"] + 15.0


def _epoch_ns(epoch) -> int:
    from datetime import UTC, datetime
    d = epoch - datetime(1970, 1, 1, tzinfo=UTC)
    return (d.days * 86_400 + d.seconds) * NS + d.microseconds * 1000


def _iso_ns(text: str) -> int:
    from datetime import datetime
    return _epoch_ns(datetime.fromisoformat(text))


def test_live_table_is_checked_and_gives_node_ids(tmp_path):
    def machine(live: str):
        f = tmp_path / "m.toml"
        f.write_text(PICK.read_text().replace('program = "codesys_pick_place.st"',
                                              f'program = "{SAMPLES / "codesys_pick_place.st"}"')
                     + "\n[live]\n" + live)
        return load_machine(f)

    m = machine('endpoint = "opc.tcp://plc:4840"\nnode_template = "ns=4;s=MAIN.{signal}"\n'
                'nodes = { qZ = "ns=4;s=GVL.qZ" }\nmeter_unit = "m3/h"\n')
    s = live_settings(m)
    assert s.node_id("qZ") == "ns=4;s=GVL.qZ" and s.node_id("qX") == "ns=4;s=MAIN.qX"
    assert s.meter_node_id() == "ns=4;s=MAIN.flow_l_min" and s.meter_unit == "m3/h"
    assert s.endpoint == "opc.tcp://plc:4840"
    for bad, says in (('endpont = "x"', "unknown key 'endpont'"),
                      ('meter_unit = "gpm"', "meter_unit must be one of"),
                      ('node_template = "ns=4;s=MAIN.x"', "node_template must hold {signal}"),
                      ('security_policy = "Basic256Sha256"', "needs certificate"),
                      ("publishing_ms = 1", "outside the physical range"),
                      ('nodes = { qZ = 3 }', "nodes must be a table")):
        with pytest.raises(MachineError) as e:
            machine(bad)
        assert "[live]" in str(e.value) and says in str(e.value), bad


def _cli(*args, timeout=60):
    return subprocess.run([sys.executable, "-m", "plcpred", *args], check=False,
                          capture_output=True, text=True, timeout=timeout, env={**os.environ, "COLUMNS": "80"})


def test_cli_bad_input_exits_2_with_one_line(tmp_path, capsys):
    from plcpred.cli import main
    for args, says in (
            (["watch", str(PICK), "--out", str(tmp_path / "o")], "no endpoint"),
            (["watch", str(PICK), "--out", str(tmp_path / "o"), "--endpoint", "http://x:1"],
             "opc.tcp://HOST:PORT"),
            (["watch", str(PICK), "--out", str(tmp_path / "o"), "--endpoint",
              "opc.tcp://127.0.0.1:1", "--cycle-signal", "nope"], "cycle signal 'nope'"),
            (["serve", str(PICK), "--endpoint", "opc.tcp://127.0.0.1:1", "--speed", "0"],
             "--speed"),
            (["serve", str(PICK), "--endpoint", "opc.tcp://127.0.0.1:1", "--horizon", "25h"],
             "--horizon")):
        assert main(args) == 2, args
        err = capsys.readouterr().err
        assert says in err and "Traceback" not in err and err.count("\n") == 1, (args, err)
