"""``watch``: an OPC UA client subscribed to a machine's signals and flow meter, recording
what it sees (:mod:`.record`) and comparing it with the prediction cycle by cycle
(:mod:`.compare`).

Every value is taken at its source time stamp (the server's, not when it arrived).
Notifications of several nodes come grouped by node, so they are held for a few
publishing intervals and written in time order. A lost connection is tried again with
a growing pause, on a new session with a new subscription. Where the server keeps the
values' history (HistoryRead) back to the last value seen, the time it was away is read
from it and the segment goes on; otherwise the open segment ends where the last value
was seen, the next one starts with the values the server gives on reconnecting, and the
gap between them is an event. Nothing is invented for a gap, and a value is written once
however often it comes (a node's value at or before the last of its own written is
known).

The values a server gives on subscribing are not one snapshot: it reads each node's as
it creates that node's monitored item, and the machine runs on meanwhile (a restarted
server writes the values it owes in a burst), so a node whose item came early may change
before the last item is made. Its change then comes as a notification older than other
nodes' first values. A segment therefore starts once every node has given its first
value, at the newest of them, each signal at its newest value by then, first value or
change: a change older than the start goes into the start's values, not lost."""
from __future__ import annotations

import asyncio
import contextlib
import os
import time
from dataclasses import dataclass, field
from datetime import UTC, datetime, timedelta
from pathlib import Path

from asyncua import Client, ua

from ..diagnose.io import flow_unit_factor, reference_factor
from ..sequencer.timeline import NS
from .compare import LiveComparison
from .metrics import Metrics
from .periodic import PeriodicDiagnosis
from .plot import plot_comparison
from .record import EventLog, Recorder, iso_time
from .settings import LiveError, LiveSettings, machine_signals

QUEUE_SIZE = 10_000             # values a node may change between two publishes
FIRST_PAUSE_S, MAX_PAUSE_S = 0.5, 30.0
CHECK_EVERY_S = 1.0             # how often the connection is checked
HOLD_PUBLISHES = 3              # notifications held this many publishing intervals
DIAGNOSIS_END_WAIT_S = 120.0    # a diagnosis running at the watch's end given this long
FIRST_VALUES_WAIT_S = 10.0      # a node giving no first value this long is left unknown
_EPOCH = datetime(1970, 1, 1, tzinfo=UTC)
_METER, _PRESSURE = "\0meter", "\0pressure"


@dataclass
class WatchResult:
    cycles: int = 0
    alarms: list = field(default_factory=list)
    gaps: list = field(default_factory=list)
    files: list = field(default_factory=list)
    readings: int = 0
    changes: int = 0
    bad_readings: int = 0
    missing_nodes: list = field(default_factory=list)


def stamp_ns(dv) -> int | None:
    """A DataValue's source time stamp (else the server's) as ns since 1970, UTC."""
    ts = dv.SourceTimestamp or dv.ServerTimestamp
    if ts is None:
        return None
    if ts.tzinfo is None:
        ts = ts.replace(tzinfo=UTC)
    d = ts - _EPOCH
    pico = getattr(dv, "SourcePicoseconds", None) or 0 if dv.SourceTimestamp else 0
    return (d.days * 86_400 + d.seconds) * NS + d.microseconds * 1000 + pico // 100


class _Handler:
    """Collects notifications as (received, key, source ns, value, good, first)."""

    def __init__(self, keys: dict):
        self.keys, self.inbox, self.seen = keys, [], set()
        self.status: list = []

    def datachange_notification(self, node, val, data):
        key = self.keys.get(node.nodeid)
        if key is None:
            return
        dv = data.monitored_item.Value
        good = dv.StatusCode is None or dv.StatusCode.is_good()
        first = key not in self.seen
        self.seen.add(key)
        self.inbox.append((time.monotonic(), key, stamp_ns(dv), val, good, first))

    def status_change_notification(self, status):
        self.status.append(str(getattr(status, "Status", status)))

    def event_notification(self, event):
        pass


class Watcher:
    """One watch: its files, its comparison and its connection."""

    def __init__(self, machine, out: Path, settings: LiveSettings, report=print):
        self.machine, self.out, self.settings, self.report = machine, out, settings, report
        self.signals = machine_signals(machine)
        self.metrics = Metrics(settings.prometheus, machine.name) if settings.prometheus \
            else None
        out.mkdir(parents=True, exist_ok=True)
        self.events = EventLog(out / "events.jsonl")
        self.recorder = Recorder(out, self.signals, settings.rotate_s, self.events)
        self.comparison = LiveComparison(machine, settings)
        self.flow_k = flow_unit_factor(settings.meter_unit) * \
            reference_factor(settings.meter_reference)
        self.result = WatchResult()
        self.pending: list = []          # (received, key, ns, value, good, first)
        # before a segment opens (this session's values): each node's newest value (ns,
        # value, good), the time stamp of each one's first (None: it had none), the
        # nodes whose first is awaited, since when (monotonic)
        self.known: dict = {}
        self.firsts: dict = {}
        self.awaited: set = set()
        self.awaited_since = 0.0
        self.last_ns: int | None = None  # the latest source time written
        self.bad_streak = False
        self.subscribed = False
        self.outage = False              # lost with the segment open, not yet resumed
        self.cutoff: dict = {}           # per node: the newest time read from history
        self.wanted: list = []           # (key, node id) subscribed to
        self.periodic = None if not settings.diagnose_every_s else PeriodicDiagnosis(
            machine.path, settings.diagnose_every_s, out, self.events, report,
            on_result=None if self.metrics is None else self.metrics.diagnosis)

    # ------------------------------------------------------------------ connection
    async def run(self, duration_s: float | None = None, stop: asyncio.Event | None = None
                  ) -> WatchResult:
        deadline = None if duration_s is None else time.monotonic() + duration_s
        stop = stop or asyncio.Event()
        pause = FIRST_PAUSE_S
        self.events.write("watch", machine=self.machine.name, settings=self.settings.shown(),
                          signals=self.signals)
        interrupted = False
        try:
            while not stop.is_set() and (deadline is None or time.monotonic() < deadline):
                self.subscribed = False
                try:
                    await self._session(deadline, stop)
                    pause = FIRST_PAUSE_S
                except (TimeoutError, OSError, ua.UaError, ConnectionError) as e:
                    if self.subscribed:     # it was up: try again soon
                        pause = FIRST_PAUSE_S
                    self._lost(f"{type(e).__name__}: {e}"[:300], pause)
                    left = None if deadline is None else deadline - time.monotonic()
                    await asyncio.sleep(pause if left is None else max(0.0, min(pause, left)))
                    pause = min(2 * pause, MAX_PAUSE_S)
        except asyncio.CancelledError:
            interrupted = True
            raise
        finally:
            self._drain(final=True)
            await self._end_diagnosis(interrupted)
            self.recorder.finish("watch ended")
            self.result.files = list(self.recorder.written)
            self.events.write("end", cycles=self.result.cycles, readings=self.result.readings,
                              changes=self.result.changes, gaps=len(self.result.gaps))
            self.events.close()
            if self.metrics is not None:
                self.metrics.close()
            if self.settings.plot:          # Ctrl-C too: the usual end of a watch
                self._plot()
        return self.result

    def _plot(self) -> None:
        """``comparison.png`` drawn from the events (``[live] plot``); a watch that
        compared no cycle has none."""
        try:
            path = plot_comparison(self.out)
        except (LiveError, OSError) as e:
            self.report(f"no comparison.png: {e}")
            return
        self.result.files.append(path)
        self.report(f"wrote {path}")

    async def _end_diagnosis(self, interrupted: bool) -> None:
        """The diagnosis still running given its time to finish (recording has ended),
        or ended at once when the watch was interrupted."""
        if self.periodic is None:
            return
        if interrupted or self.periodic.running is None:
            self.periodic.stop(0.0)
            return
        self.report(f"waiting for the diagnosis still running (at most "
                    f"{DIAGNOSIS_END_WAIT_S:g} s)")
        await asyncio.to_thread(self.periodic.stop, DIAGNOSIS_END_WAIT_S)

    def _client(self) -> Client:
        s = self.settings
        client = Client(s.endpoint, timeout=4)
        if s.user:
            client.set_user(s.user)
            client.set_password(os.environ.get(s.password_env, ""))
        return client

    async def _session(self, deadline, stop) -> None:
        s = self.settings
        client = self._client()
        if s.security_policy != "None":
            await client.set_security_string(
                f"{s.security_policy},{s.security_mode},{s.certificate},{s.private_key}")
        await client.connect()
        try:
            handler = await self._subscribe(client)
            self.subscribed = True
            self.events.write("connected", endpoint=s.endpoint)
            self.report(f"connected to {s.endpoint}")
            if self.metrics is not None:
                self.metrics.connected.set(1)
            if self.outage:
                await self._resume(client)
            next_check = time.monotonic() + CHECK_EVERY_S
            while not stop.is_set() and (deadline is None or time.monotonic() < deadline):
                await asyncio.sleep(s.publishing_ms / 1000.0)
                self._take(handler)
                if self.periodic is not None:
                    self.periodic.tick(self.last_ns, self.recorder)
                if handler.status:
                    self.events.write("server_status", status=handler.status[:])
                    handler.status.clear()
                if time.monotonic() >= next_check:
                    await asyncio.wait_for(client.nodes.server.read_browse_name(), 4.0)
                    next_check = time.monotonic() + CHECK_EVERY_S
            await asyncio.sleep(HOLD_PUBLISHES * s.publishing_ms / 1000.0)
            self._take(handler)
        finally:
            # a connection already gone has nothing left to close
            with contextlib.suppress(OSError, TimeoutError, ua.UaError, ConnectionError,
                                     RuntimeError):
                await asyncio.wait_for(client.disconnect(), 2.0)

    async def _subscribe(self, client) -> _Handler:
        s = self.settings
        wanted = [(sig, s.node_id(sig)) for sig in self.signals]
        wanted += [(_METER, s.meter_node_id()), (_PRESSURE, s.pressure_node_id())]
        self.wanted = wanted
        keys = {ua.NodeId.from_string(node): key for key, node in wanted}
        handler = _Handler(keys)
        params = ua.CreateSubscriptionParameters(
            RequestedPublishingInterval=s.publishing_ms, RequestedLifetimeCount=10_000,
            RequestedMaxKeepAliveCount=max(1, int(10_000 / s.publishing_ms)),
            MaxNotificationsPerPublish=0, PublishingEnabled=True, Priority=0)
        sub = await client.create_subscription(params, handler)
        requests = []
        for n, (key, node) in enumerate(wanted):
            trigger = ua.DataChangeTrigger.StatusValueTimestamp if key == _METER else \
                ua.DataChangeTrigger.StatusValue
            mp = ua.MonitoringParameters(ClientHandle=1000 + n, SamplingInterval=s.sampling_ms,
                                         Filter=ua.DataChangeFilter(Trigger=trigger),
                                         QueueSize=QUEUE_SIZE, DiscardOldest=True)
            requests.append(ua.MonitoredItemCreateRequest(
                ItemToMonitor=ua.ReadValueId(NodeId=ua.NodeId.from_string(node),
                                             AttributeId=ua.AttributeIds.Value),
                MonitoringMode=ua.MonitoringMode.Reporting, RequestedParameters=mp))
        self.known, self.firsts = {}, {}
        self.awaited_since = time.monotonic()
        results = await sub.create_monitored_items(requests)
        self.awaited = {key for (key, _), r in zip(wanted, results)
                        if not isinstance(r, ua.StatusCode)}
        for (key, node), r in zip(wanted, results):
            if isinstance(r, ua.StatusCode) and key == _METER:
                raise LiveError(f"{s.endpoint}: the flow meter's node {node} is not on the "
                                f"server ({r.name}); [live] meter_node names it")
            if isinstance(r, ua.StatusCode) and key != _PRESSURE:
                name = {_METER: "the flow meter"}.get(key, key)
                if key not in self.result.missing_nodes:
                    self.result.missing_nodes.append(key)
                    self.events.write("node_missing", signal=name, node=node,
                                      status=r.name if hasattr(r, "name") else str(r))
                    self.report(f"warning: {node} ({name}): not on the server ({r.name})")
        return handler

    def _lost(self, why: str, pause: float) -> None:
        """The connection failed: write what was held; the open segment waits for the
        reconnection (:meth:`_resume`)."""
        self._drain(final=True)
        if self.metrics is not None:
            self.metrics.connected.set(0)
        if self.recorder.open and not self.outage:
            self.outage = True
            self.events.write("disconnected", last=iso_time(self.last_ns) if self.last_ns
                              else None, last_ns=self.last_ns, why=why)
            self.report(f"connection lost ({why}); trying again")
        else:
            self.events.write("connect_failed", why=why, retry_in_s=pause)
        self.known, self.firsts, self.cutoff = {}, {}, {}

    async def _resume(self, client) -> None:
        """Connected again after a loss: the values the server's history holds since
        the last one seen, held and written like notifications; or, where it keeps none
        that reach back so far, the open segment ended at the last value seen (the next
        starts from the values the server gives now: a gap)."""
        self.outage = False
        wanted = [(k, n) for k, n in self.wanted if k not in self.result.missing_nodes]
        got = await read_history(client, wanted, self.last_ns,
                                 self.recorder.last_reading_ns,
                                 self.comparison.reading_period_ns)
        if isinstance(got, str):
            self.recorder.finish("connection lost")
            self.events.write("no_history", why=got)
            return
        now = time.monotonic()
        for key, t_ns, value, good in got:
            self.pending.append((now, key, t_ns, value, good, False))
            self.cutoff[key] = max(self.cutoff.get(key, t_ns), t_ns)
        newest = max(self.cutoff.values())
        self.events.write("backfilled", **{"from": iso_time(self.last_ns)}, to=iso_time(newest),
                          seconds=(newest - self.last_ns) / NS, values=len(got))
        self.report(f"read {len(got)} values of {(newest - self.last_ns) / NS:.1f} s from "
                    "the server's history: no gap")

    # ------------------------------------------------------------------ values
    def _take(self, handler: _Handler) -> None:
        if self.cutoff:       # what history gave already: each value once
            self.pending += [p for p in handler.inbox
                             if p[2] is None or p[2] > self.cutoff.get(p[1], -1)]
        else:
            self.pending += handler.inbox
        handler.inbox = []
        self._drain()
        if not self.recorder.open and time.monotonic() > \
                self.awaited_since + FIRST_VALUES_WAIT_S:
            self._stop_awaiting()

    def _stop_awaiting(self) -> None:
        """Nodes subscribed to that never gave a first value (a server should): the
        segment starts without them, their values unknown until they change."""
        silent = sorted(self.awaited - self.firsts.keys())
        self.awaited -= set(silent)
        for key in silent:
            name = {_METER: "the flow meter", _PRESSURE: "the supply pressure"}.get(key, key)
            self.events.write("no_first_value", signal=name,
                              waited_s=FIRST_VALUES_WAIT_S)
            self.report(f"warning: {name}: no value from the server in "
                        f"{FIRST_VALUES_WAIT_S:g} s of subscribing; unknown until it changes")

    def _drain(self, final: bool = False) -> None:
        """Write the held notifications that no later one can precede: those older than
        the oldest source time among the ones received in the last few publishes."""
        if not self.pending:
            return
        now = time.monotonic()
        hold = HOLD_PUBLISHES * self.settings.publishing_ms / 1000.0
        fresh = [p[2] for p in self.pending if p[0] > now - hold and p[2] is not None]
        cut = None if final or not fresh else min(fresh)
        ready = [p for p in self.pending if cut is None or p[2] is None or p[2] < cut]
        self.pending = [p for p in self.pending if not (cut is None or p[2] is None
                                                        or p[2] < cut)]
        ready.sort(key=lambda p: (p[2] or 0, p[1] in (_METER, _PRESSURE)))
        for _, key, t_ns, value, good, first in ready:
            if t_ns is not None:
                self._value(key, t_ns, value, good, first)
            elif first:                 # a first value without a time: no state known
                self.firsts.setdefault(key, None)

    def _value(self, key: str, t_ns: int, value, good: bool, first: bool) -> None:
        if not self.recorder.open and not self._opens(key, t_ns, value, good, first):
            return
        if key == _PRESSURE:
            if good and value is not None:
                self.recorder.supply = float(value)
            return
        if key == _METER and t_ns <= self.recorder.last_reading_ns:
            if first:
                return                  # the reading it had when subscribed: known
            self._clock_went_back(t_ns)
        if t_ns < self.recorder.origin_ns:
            return                      # before the segment's start: in its first rows
        if self.recorder.due(t_ns):
            self.recorder.rotate_to(t_ns)
        self.last_ns = max(self.last_ns or t_ns, t_ns)
        if key == _METER:
            self._reading(t_ns, value, good)
        elif good and value is not None:
            v = float(value)
            if self.recorder.states.get(key) != v:
                self.result.changes += 1
            self.recorder.edge(t_ns, key, v)
            self.comparison.edge(t_ns, key, v)

    def _opens(self, key: str, t_ns: int, value, good: bool, first: bool) -> bool:
        """Before a segment: each node's newest value kept, first value or change (taken
        in time order). True when this value is the first after the segment's start,
        which opens the segment before it is written."""
        if first:
            self.firsts[key] = t_ns
        origin = self._origin()
        if origin is not None and t_ns > origin:
            self._start_segment(origin)
            return True
        held = self.known.get(key)
        if held is None or t_ns >= held[0]:
            self.known[key] = (t_ns, value, good)
        return False

    def _origin(self) -> int | None:
        """Where the segment starts: the newest of the first values the server gave on
        subscribing (and of the changes taken with them), once every node has given its
        own and a reading is known (None: not yet)."""
        if _METER not in self.known or not self.awaited <= self.firsts.keys():
            return None
        return max([t for t, _, _ in self.known.values()]
                   + [t for t in self.firsts.values() if t is not None])

    def _start_segment(self, origin: int) -> None:
        """A segment from ``origin``, each signal at its newest value then."""
        states = {k: float(v) for k, (_, v, good) in self.known.items()
                  if k not in (_METER, _PRESSURE) and good and v is not None}
        why = "connected"
        if self.last_ns is not None:
            gap = {"from": iso_time(self.last_ns), "to": iso_time(origin),
                   "seconds": (origin - self.last_ns) / NS}
            self.result.gaps.append(gap)
            if self.metrics is not None:
                self.metrics.gaps.inc()
            self.events.write("gap", **gap)
            why = "after a gap"
        self.recorder.start(origin, states, why)
        self.comparison.reset(origin)
        self.comparison.snapshot(states)
        self.last_ns = origin
        self.recorder.last_reading_ns = self.known[_METER][0]
        supply = self.known.get(_PRESSURE)
        if supply is not None and supply[2] and supply[1] is not None:
            self.recorder.supply = float(supply[1])
        self.known = {}

    def _clock_went_back(self, t_ns: int) -> None:
        self.events.write("clock_jump", from_=iso_time(self.recorder.last_reading_ns),
                          to=iso_time(t_ns))
        states = dict(self.recorder.states)
        self.recorder.finish("clock went back")
        self.recorder.start(t_ns, states, "clock went back")
        self.comparison.reset(t_ns)
        self.comparison.snapshot(states)

    def _reading(self, t_ns: int, value, good: bool) -> None:
        if not good or value is None:
            self.result.bad_readings += 1
            if not self.bad_streak:
                self.events.write("bad_reading", at=iso_time(t_ns))
            self.bad_streak = True
            return
        self.bad_streak = False
        flow = float(value) * self.flow_k
        self.recorder.reading(t_ns, flow)
        self.result.readings += 1
        for r in self.comparison.reading(t_ns, flow):
            self._cycle(r)

    def _cycle(self, r) -> None:
        self.result.cycles += 1
        if self.metrics is not None:
            self.metrics.cycle(r)
        origin = self.recorder.origin_ns
        gap, ref_gap = r.gap, r.reference_gap
        self.events.write("cycle", number=r.number, start=iso_time(r.start_ns),
                          duration_s=r.duration_s, measured_nl=r.measured_nl,
                          reference=r.reference, reference_nl=r.reference_nl,
                          reference_gap_percent=None if ref_gap is None else 100 * ref_gap,
                          predicted_nl=r.predicted_nl,
                          gap_percent=None if gap is None else 100 * gap,
                          idle_l_min=r.idle_l_min, idle_predicted_l_min=r.idle_predicted_l_min,
                          rolling_gap_percent=None if r.rolling_gap is None
                          else 100 * r.rolling_gap)
        reference = "       -   " if r.reference_nl is None else f"{r.reference_nl:8.3f} NL"
        self.report(f"cycle {r.number:5d}  {(r.start_ns - origin) / NS:9.2f} s  "
                    f"{r.duration_s:6.2f} s  measured {r.measured_nl:8.3f} NL  reference "
                    f"{reference} {_pct(ref_gap)}  D1 {r.predicted_nl:8.3f} NL {_pct(gap)}  "
                    "idle " + (f"{r.idle_l_min:6.1f} NL/min" if r.idle_l_min is not None
                               else "     -") + f"  rolling {_pct(r.rolling_gap)}"
                    f"  ({r.reference})")
        if r.learned_now:
            learned = self.comparison.reference.summary()
            self.events.write("reference_learned", **learned)
            self.report(f"reference {learned['reference']}: measured/D1 "
                        f"{learned['ratio']:.4f}, fit within {learned['fit_rms_percent']:.2f}% rms")
        for alarm in self.comparison.alarms(r):
            at = alarm.get("began_ns", alarm.get("at_ns"))
            alarm = {k: v for k, v in alarm.items() if not k.endswith("_ns")}
            self.events.write("alarm", **alarm, began=iso_time(at))
            self.result.alarms.append(alarm)
            if self.metrics is not None:
                self.metrics.alarm_state(alarm["alarm"], alarm["state"] == "raised")
            self.report(f"ALARM {alarm['alarm']} {alarm['state']} (began {iso_time(at)}, "
                        f"against {alarm.get('reference', 'the idle limit')})")


async def read_history(client, wanted: list, from_ns: int, last_reading_ns: int | None,
                       period_ns: int | None) -> list | str:
    """Every node's values after ``from_ns`` from the server's history as (key, ns,
    value, good), or why there are none to trust: history must be kept for every node
    (the supply pressure's may be missing), and the meter's (it ticks, the witness) must
    begin within two reading periods of the last reading seen, else its oldest values
    are gone."""
    if from_ns is None or last_reading_ns is None or not period_ns:
        return "nothing seen before the loss to go on from"
    start = _EPOCH + timedelta(microseconds=from_ns // 1000)
    out = []
    for key, node in wanted:
        try:
            values = await client.get_node(node).read_raw_history(start, None)
        except (ua.UaError, TimeoutError) as e:
            if key == _PRESSURE:
                continue
            return f"{node}: no history ({type(e).__name__}: {e})"[:300]
        got = [(key, stamp_ns(dv), dv.Value.Value if dv.Value is not None else None,
                dv.StatusCode is None or dv.StatusCode.is_good()) for dv in values]
        got = [g for g in got if g[1] is not None and g[1] > from_ns]
        if key == _METER and (not got or min(g[1] for g in got)
                              > last_reading_ns + 2 * period_ns):
            return f"{node}: the history does not reach back to the last reading seen"
        out += got
    return out


def _pct(x) -> str:
    return "      -" if x is None else f"{100 * x:+6.1f}%"


async def watch(machine, out, settings: LiveSettings, duration_s: float | None = None,
                stop: asyncio.Event | None = None, report=print) -> WatchResult:
    """Watch ``machine`` (loaded) at ``settings.endpoint`` into folder ``out`` for
    ``duration_s`` (wall clock; None: until ``stop`` is set)."""
    return await Watcher(machine, Path(out), settings, report).run(duration_s, stop)
