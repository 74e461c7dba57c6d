"""plcpred.live's twin over long horizons (issue 41): a machine that settles into its
cycle is served hours in from its last repeating period, at the values a direct
closed-loop run gives, from runs a few periods long; the server asks a process of its
own for them. Real runs, a real server and a real client over TCP; nothing is patched."""
import asyncio
import socket
import time
from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np
import pytest
from asyncua import Client

from plcpred.live import Twin, serve
from plcpred.plant import emulate
from plcpred.sequencer.timeline import NS

PICK = Path(__file__).resolve().parents[2] / "samples" / "pick_place.toml"
HOUR = 3600.0


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def split(twin, events):
    """(signal edges as (time ns, node, value), meter readings as (time ns, l/min), the
    supply's) of ``Twin.events``."""
    t, i, v = events
    signal = i < twin.meter_index
    meter = i == twin.meter_index
    return (t[signal], i[signal], v[signal]), (t[meter], v[meter]), v[i == twin.pressure_index]


def emulated_edges(twin, em, t0_s, t1_s):
    """The edges of an emulation in [t0, t1) as ``Twin.events`` gives them."""
    parts = []
    for k, name in enumerate(twin.signals):
        t, v = em.timeline.edge_times_ns(em.timeline.info["machine_signals"].get(name, name))
        m = (t >= round(t0_s * NS)) & (t < round(t1_s * NS))
        parts.append((t[m], np.full(m.sum(), k), v[m]))
    t, i, v = (np.concatenate(x) for x in zip(*parts))
    order = np.lexsort((i, t))
    return t[order], i[order], v[order]


def test_hours_in_the_values_are_the_last_period_tiled_and_a_direct_run_s():
    twin = Twin(PICK, 24 * HOUR, seed=3)
    t0 = time.perf_counter()
    late = twin.events(7 * HOUR, 7 * HOUR + 40.0)
    values = twin.values_at(7 * HOUR + 1.3)
    took = time.perf_counter() - t0
    # one closed-loop run of five periods, then the period repeated: no run of hours
    assert twin.status()["runs"] == [("nominal", 20.0)]
    assert twin.periods_s() == {"nominal": 4.0}
    assert took < 8.0
    t0 = time.perf_counter()
    later = twin.events(23 * HOUR, 23 * HOUR + 40.0)
    assert time.perf_counter() - t0 < 1.0       # what the first stretch cost, no more
    # a direct closed-loop run to 400 s (emulate: the meter on the same 1 ms grid)
    em = emulate(PICK, 400.0, seed=3)
    direct = twin.events(300.0, 340.0)
    (t, i, v), (mt, flow), supply = split(twin, direct)
    et, ei, ev = emulated_edges(twin, em, 300.0, 340.0)
    assert len(t) > 100
    assert np.array_equal(t, et) and np.array_equal(i, ei) and np.array_equal(v, ev)
    k = np.searchsorted(em.measured_time_s, mt / NS - 1e-6)
    assert np.allclose(em.measured_time_s[k], mt / NS, atol=1e-6) and len(mt) == 400
    assert np.allclose(flow, em.measured_flow_l_min[k], rtol=1e-4, atol=1e-3)
    assert np.allclose(supply, 6.0)
    # hours in: the same, a whole number of periods on (edges to the nanosecond)
    for far, shift_s in ((late, 7 * HOUR - 300.0), (later, 23 * HOUR - 300.0)):
        (ft, fi, fv), (fmt, fflow), _ = split(twin, far)
        assert np.array_equal(ft - round(shift_s * NS), t) and np.array_equal(fi, i)
        assert np.array_equal(fv, v) and np.array_equal(fmt - round(shift_s * NS), mt)
        # (the meter's cells are differences of a day's litres: 1e-8 of a reading)
        assert np.allclose(fflow, flow, rtol=1e-7, atol=1e-6)
    # a value hours in is the one a whole number of periods earlier
    early = twin.values_at(301.3)
    assert values[:twin.meter_index] == early[:twin.meter_index]
    # (a reading's fine grid is the span from its lead-in's start cut in whole cells,
    # which the rounding of times hours in may make one more: 1e-6 of a reading)
    assert values[twin.meter_index:] == pytest.approx(early[twin.meter_index:], rel=1e-6)


def test_a_truth_switched_on_hours_in_takes_over_at_its_time_and_tiles_its_own_period(
        tmp_path):
    truth = tmp_path / "leak.toml"
    truth.write_text('[[consumer]]\nname = "hidden leak"\nkind = "leak"\norifice_mm = 0.8\n'
                     'Cd = 0.6\n')
    onset_s = 2 * HOUR + 1.0
    twin = Twin(PICK, 24 * HOUR, truth=truth, truth_at_s=onset_s, seed=1)
    before = split(twin, twin.events(onset_s - 20.0, onset_s))[1][1]
    after = split(twin, twin.events(onset_s + 20.0, onset_s + 40.0))
    status = twin.status()
    # a leak changes no edge: the real machine is served from the onset on
    assert status["splice_s"] == onset_s
    assert status["runs"] == [("nominal", 20.0), ("real", 20.0)]
    assert status["periods_s"] == {"nominal": 4.0, "real": 4.0}
    # the real machine's own run, direct, a whole number of periods earlier
    real = emulate(PICK, 120.0, truth=truth, seed=1)
    shift_s = 4.0 * 1786                            # from 77 s on: 1,786 periods
    (mt, flow) = after[1]
    k = np.searchsorted(real.measured_time_s, mt / NS - shift_s - 1e-6)
    assert np.allclose(real.measured_time_s[k] + shift_s, mt / NS, atol=1e-6)
    assert np.allclose(flow, real.measured_flow_l_min[k], rtol=1e-4, atol=1e-3)
    assert flow.mean() > before.mean() + 15.0


def test_a_server_started_hours_into_its_machine_serves_the_twins_values_from_its_process():
    twin = Twin(PICK, 24 * HOUR, seed=3)
    speed, hours_in = 100.0, 5 * HOUR
    url = f"opc.tcp://127.0.0.1:{free_port()}"
    epoch = datetime.now(UTC) - timedelta(seconds=hours_in / speed)

    async def run():
        up = asyncio.Event()
        server = asyncio.create_task(serve(
            twin, url, speed=speed, epoch=epoch,
            report=lambda line: up.set() if line.startswith("machine clock") else None))
        try:
            await asyncio.wait_for(up.wait(), 60)
            async with Client(url) as client:
                read = []
                for _ in range(3):
                    await asyncio.sleep(0.3)    # (the meter's first reading written)
                    read.append([await client.get_node(f"ns=2;s={name}").read_data_value()
                                 for name in twin.names])
            status = await asyncio.to_thread(twin.process().call, "status")
        finally:
            server.cancel()
            with pytest.raises(asyncio.CancelledError):
                await server
        return read, status

    read, status = asyncio.run(run())
    assert twin.process().pid is not None and twin.process().alive()
    # the twin's process made one short run however far in the machine was
    assert status["runs"] == [("nominal", 20.0)] and status["periods_s"] == {"nominal": 4.0}
    seen_s = []
    for values in read:
        for k, (name, dv) in enumerate(zip(twin.names, values)):
            stamp = dv.SourceTimestamp
            stamp = stamp if stamp.tzinfo is not None else stamp.replace(tzinfo=UTC)
            at_s = (stamp - epoch).total_seconds()
            seen_s.append(at_s)
            if k < twin.meter_index:        # a signal: its value since its last edge
                assert dv.Value.Value == twin.values_at(at_s)[k], (name, at_s)
            elif k == twin.meter_index:     # the reading stamped then
                _, (_, flow), _ = split(twin, twin.events(at_s - 1e-4, at_s + 1e-4))
                # (the server's stretch began its meter's lead-in elsewhere: 1e-4)
                assert len(flow) == 1
                assert dv.Value.Value == pytest.approx(flow[0], rel=1e-4, abs=1e-2)
    assert min(seen_s) > hours_in - 10.0
    worker = twin.process()
    worker.close()
    assert not worker.alive()
