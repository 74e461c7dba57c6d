"""``serve``: the emulated machine as an OPC UA server (a digital twin).

Every signal of the machine file is a Boolean node ``ns=2;s={signal}``, the flow meter
``ns=2;s=flow_l_min`` (its reading, at the meter's reference) and the supply pressure
``ns=2;s=supply_bar_g`` (bar gauge). Each value is written when the served clock reaches
it, with that time as its source time stamp. The served clock runs ``speed`` times as
fast as the wall clock from ``epoch`` (the machine's start), so a server restarted with
the same epoch goes on where the machine would be, as a PLC runs on while its OPC UA
server restarts. With ``history``, the server keeps each node's last values for
HistoryRead (a client that lost its connection reads what it missed).

The values are worked out by the twin in a process of its own (:meth:`Twin.process`,
kept for a server restarted on the same twin), a stretch ahead of the one being
written: however long a closed-loop run takes, the event loop only writes."""
from __future__ import annotations

import asyncio
import threading
import time
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta

import numpy as np
from asyncua import Server, ua

from ..sequencer.timeline import NS
from .settings import LiveError, check_endpoint
from .twin import Twin

NAMESPACE_URI = "urn:plcpred:twin"
MAX_SPEED = 1000.0
WALL_CHUNK_S = 0.5        # values are worked out this far ahead (wall time)
MIN_CHUNK_S = 5.0         # ... and at least this much machine time
_EPOCH = datetime(1970, 1, 1, tzinfo=UTC)


@dataclass
class ServeResult:
    endpoint: str
    served_s: float
    values_written: int
    epoch: datetime


def source_time(epoch: datetime, t_ns: int) -> datetime:
    """The source time stamp of machine time ``t_ns`` (to the microsecond, as asyncua
    carries time stamps)."""
    return epoch + timedelta(microseconds=t_ns // 1000)


def _variant(value, boolean: bool):
    return ua.Variant(bool(value), ua.VariantType.Boolean) if boolean else \
        ua.Variant(float(value), ua.VariantType.Double)


async def serve(twin: Twin, endpoint: str, speed: float = 1.0, epoch: datetime | None = None,
                report=print, started=None, hold: asyncio.Event | None = None,
                history: int = 0) -> ServeResult:
    """Serve ``twin`` at ``endpoint`` until its horizon (machine time) is served.
    ``started(epoch)`` is called once the machine clock runs, with its start. With
    ``hold``, the server comes up with the machine at rest at its start and its clock
    starts when ``hold`` is set (a client connected first sees every edge). ``history``:
    the values kept per node for HistoryRead (0: none)."""
    if not 0 < speed <= MAX_SPEED:
        raise LiveError(f"--speed must be more than 0 and at most {MAX_SPEED:g}")
    check_endpoint(endpoint)
    start_s = 0.0
    if epoch is not None:     # a machine started before: on where it is now
        epoch = epoch.astimezone(UTC)
        start_s = max(0.0, (datetime.now(UTC) - epoch).total_seconds() * speed)
    if start_s >= twin.horizon_s:
        raise LiveError(f"--epoch {epoch.isoformat()}: at --speed {speed:g} the machine "
                        f"would be {start_s:g} s in, past the horizon of {twin.horizon_s:g} s")
    worker = twin.process()
    values = await _in_thread(worker.call, "values_at", start_s)
    # a restarted machine's values carry its clock from the first moment a client may
    # connect: a stamp of the wall clock would misplace the new segment's start
    first_stamp = None if epoch is None else source_time(epoch, round(start_s * NS))
    server, nodes, boolean = await _server(twin, endpoint, values, first_stamp, history)
    try:
        report(f"serving {twin.nominal.name} at {endpoint}: {len(twin.signals)} signals, "
               "meter and supply" + ("; holding at the start" if hold is not None else ""))
        if hold is not None and epoch is None:
            await hold.wait()
        if epoch is None:         # the machine starts now, on the millisecond
            now = datetime.now(UTC)
            epoch = now.replace(microsecond=now.microsecond // 1000 * 1000)
        stamp = source_time(epoch, round(start_s * NS))
        for node in nodes[:twin.meter_index] + nodes[twin.pressure_index:]:
            # every value as of the machine clock's start (the meter's first reading is
            # one period on)
            value = await node.read_data_value()
            await _put(server, node.nodeid, ua.DataValue(
                Value=value.Value, SourceTimestamp=stamp, ServerTimestamp=stamp), history)
        if started is not None:
            started(epoch)
        written = await _publish(server, twin, worker, nodes, boolean, speed, epoch,
                                 start_s, report, history)
    finally:
        await server.stop()
    return ServeResult(endpoint, twin.horizon_s - start_s, written, epoch)


async def _server(twin: Twin, endpoint: str, values: list, stamp: datetime | None,
                  history: int):
    """(the started server, its nodes, which of them are Boolean) with ``values``
    (stamped ``stamp`` where given), each keeping its last ``history`` values."""
    server = Server()
    await server.init()
    server.set_endpoint(endpoint)
    server.set_server_name(f"plcpred twin: {twin.nominal.name}")
    server.set_security_policy([ua.SecurityPolicyType.NoSecurity])
    idx = await server.register_namespace(NAMESPACE_URI)
    folder = await server.nodes.objects.add_object(ua.NodeId("machine", idx), twin.nominal.name)
    boolean = [i < len(twin.signals) for i in range(len(twin.names))]
    nodes = []
    for i, (name, value) in enumerate(zip(twin.names, values)):
        node = await folder.add_variable(ua.NodeId(name, idx), name,
                                         _variant(value, boolean[i]))
        nodes.append(node)
        if history:
            # kept by the writes themselves (_put): asyncua's own historizing samples
            # through a subscription and would drop values written in one burst
            await server.iserver.history_manager.storage.new_historized_node(
                node.nodeid, None, history)
            await node.write_attribute(ua.AttributeIds.Historizing, ua.DataValue(True))
            for attribute in (ua.AttributeIds.AccessLevel, ua.AttributeIds.UserAccessLevel):
                await node.set_attr_bit(attribute, ua.AccessLevel.HistoryRead)
        if stamp is not None:
            await _put(server, node.nodeid, ua.DataValue(
                Value=_variant(value, boolean[i]), SourceTimestamp=stamp,
                ServerTimestamp=stamp), history)
    try:
        await server.start()
    except OSError as e:
        raise LiveError(f"cannot serve at {endpoint}: {e.strerror or e}") from None
    return server, nodes, boolean


async def _put(server, nodeid, value: ua.DataValue, history: int) -> None:
    await server.write_attribute_value(nodeid, value)
    if history:
        await server.iserver.history_manager.storage.save_node_value(nodeid, value)


async def _publish(server, twin: Twin, worker, nodes, boolean, speed: float,
                   epoch: datetime, start_s: float, report, history: int = 0) -> int:
    """Write every value when the served clock reaches it, the twin's process working
    out the next stretch while this one is written."""
    wall0 = time.time() - (datetime.now(UTC) - epoch).total_seconds()
    report(f"machine clock from {epoch.isoformat()} at {speed:g}x"
           + (f", from {start_s:.3f} s" if start_s else ""))
    chunk_s = max(MIN_CHUNK_S, speed * WALL_CHUNK_S)
    done_s, written, tiled = start_s, 0, False
    ahead = _in_thread(worker.call, "events", done_s, min(done_s + chunk_s, twin.horizon_s))
    while done_s < twin.horizon_s:
        end_s = min(done_s + chunk_s, twin.horizon_s)
        t_ns, idx, values = await ahead
        if end_s < twin.horizon_s:
            ahead = _in_thread(worker.call, "events", end_s,
                               min(end_s + chunk_s, twin.horizon_s))
        written += await _write(server, nodes, boolean, t_ns, idx, values, wall0, speed, epoch,
                                history)
        done_s = end_s
        if not tiled and end_s < twin.horizon_s:
            tiled = await _report_tiling(worker, report)
    return written


async def _report_tiling(worker, report) -> bool:
    """Say once when the served values come from a repeating period (the closed loop
    runs no further); True once said, or once the runs have reached the horizon."""
    status = await _in_thread(worker.call, "status")
    periods, runs = status["periods_s"], status["runs"]
    if any(p is None for p in periods.values()):
        return bool(runs) and runs[-1][1] >= status["horizon_s"]
    report("repeating: " + ", ".join(f"{name} every {p:g} s" for name, p in periods.items())
           + f" (runs to {max(h for _, h in runs):g} s)")
    return True


def _in_thread(fn, *args) -> asyncio.Future:
    """``fn(*args)`` (a request to the twin's process) in a daemon thread: a server
    stopped (Ctrl-C, SIGTERM, its task cancelled) ends at once instead of waiting for an
    answer it no longer needs, as the event loop's own worker threads would make it."""
    loop = asyncio.get_running_loop()
    future = loop.create_future()

    def settle(result, error) -> None:
        if future.cancelled():
            return
        if error is not None:
            future.set_exception(error)
        else:
            future.set_result(result)

    def work() -> None:
        try:
            outcome = (fn(*args), None)
        except Exception as e:  # noqa: BLE001 - handed to the awaiting coroutine
            outcome = (None, e)
        try:
            loop.call_soon_threadsafe(settle, *outcome)
        except RuntimeError:
            pass                     # the loop is closed: no one waits for it any more

    threading.Thread(target=work, daemon=True, name="plcpred-twin").start()
    return future


async def _write(server, nodes, boolean, t_ns, idx, values, wall0: float, speed: float,
                 epoch: datetime, history: int) -> int:
    """Write the values at their wall times (a batch for all that are due at once)."""
    k, n = 0, len(t_ns)
    while k < n:
        due = wall0 + t_ns[k] / NS / speed
        wait = due - time.time()
        if wait > 0:
            await asyncio.sleep(wait)
        now_ns = round((time.time() - wall0) * speed * NS)
        end = max(k + 1, int(np.searchsorted(t_ns, now_ns, side="right")))
        for j in range(k, end):
            stamp = source_time(epoch, int(t_ns[j]))
            i = int(idx[j])
            await _put(server, nodes[i].nodeid,
                       ua.DataValue(Value=_variant(values[j], boolean[i]),
                                    SourceTimestamp=stamp, ServerTimestamp=stamp), history)
        k = end
    return n
