"""Recording a watched machine in the files ``plcpred diagnose`` reads: per segment a
``timeline-NNNN.csv`` (``time_s,signal,value``, ``diagnose --io``) and a
``measured-NNNN.csv`` (``time_s,flow_l_min[,supply_bar_g]``, ``diagnose --measured``),
and the events as JSON lines.

A segment is a stretch of machine time with one clock: its times are seconds from its
start, where its timeline holds every signal's value, so each pair is a run of its own
for the diagnosis. A new segment starts every ``rotate_s`` of machine time, after a
connection was lost (the gap between two segments is the time nothing was seen) and after
the server's clock went back. Rows go to disk as they come (memory stays bounded however
long the watch); a segment's files are written under a temporary name and renamed into
place when it ends, so a file with the final name is always whole."""
from __future__ import annotations

import json
import math
import os
from collections import deque
from datetime import UTC, datetime, timedelta
from pathlib import Path

from ..output import json_safe
from ..sequencer.timeline import NS, format_seconds

KEPT_SEGMENTS = 8        # the segments written that a periodic diagnosis may reach back to


def iso_time(t_ns: int) -> str:
    """An absolute time (ns since 1970, UTC) as ISO 8601 with microseconds."""
    base = datetime(1970, 1, 1, tzinfo=UTC)
    return (base + timedelta(microseconds=t_ns // 1000)).isoformat().replace("+00:00", "Z")


class EventLog:
    """``events.jsonl``: one JSON object a line, each written whole and flushed."""

    def __init__(self, path: Path):
        self.path = path
        # open for the whole watch: a line is written at each event
        self._f = open(path, "a", encoding="utf-8")  # noqa: SIM115

    def write(self, kind: str, **data) -> dict:
        event = {"event": kind, **json_safe(data)}
        self._f.write(json.dumps(event, allow_nan=False) + "\n")
        self._f.flush()
        return event

    def close(self) -> None:
        self._f.close()


class _PartialFile:
    """A text file written under a temporary name beside its final one."""

    def __init__(self, path: Path, header: str):
        self.path = path
        self.tmp = path.with_name(f".{path.name}.partial")
        # open for the whole segment: rows go to disk as they come
        self._f = open(self.tmp, "w", encoding="utf-8", newline="")  # noqa: SIM115
        self._f.write(header)
        self.rows = 0

    def write(self, line: str) -> None:
        self._f.write(line)
        self.rows += 1

    def flush(self) -> int:
        """Everything written so far handed to the system; the bytes it holds."""
        self._f.flush()
        return self._f.tell()

    def finish(self) -> None:
        self._f.flush()
        os.fsync(self._f.fileno())
        self._f.close()
        os.replace(self.tmp, self.path)

    def discard(self) -> None:
        self._f.close()
        try:
            os.unlink(self.tmp)
        except OSError:
            pass


class Recorder:
    """The segments of one watch in ``out``."""

    def __init__(self, out: Path, signals: list[str], rotate_s: float, events: EventLog):
        self.out, self.signals, self.events = out, list(signals), events
        self.rotate_ns = round(rotate_s * NS)
        self.number = self._first_free_number()
        self.origin_ns: int | None = None
        self.end_ns: int | None = None
        self.last_reading_ns: int | None = None
        self.states: dict[str, float] = {}
        self.supply: float | None = None
        self._timeline = self._measured = None
        self.written: list[Path] = []
        # the last segments written: (timeline, measured, origin ns, last reading ns,
        # why they ended)
        self.finished: deque = deque(maxlen=KEPT_SEGMENTS)

    def _first_free_number(self) -> int:
        used = [int(p.stem.rpartition("-")[2]) for p in self.out.glob("timeline-*.csv")
                if p.stem.rpartition("-")[2].isdigit()]
        return max(used, default=0) + 1

    @property
    def open(self) -> bool:
        return self._timeline is not None

    @property
    def timeline_file(self) -> _PartialFile | None:
        return self._timeline

    @property
    def measured_file(self) -> _PartialFile | None:
        return self._measured

    def start(self, origin_ns: int, states: dict[str, float], why: str) -> None:
        """A new segment from ``origin_ns`` (absolute, ns since 1970), every signal at
        its value in ``states`` (signals not in it: unknown, left out)."""
        if self.open:
            self.finish("rotated")
        self.origin_ns, self.end_ns = origin_ns, origin_ns + self.rotate_ns
        self.states.update(states)
        name = f"{self.number:04d}"
        self._timeline = _PartialFile(self.out / f"timeline-{name}.csv", "time_s,signal,value\n")
        self._measured = _PartialFile(self.out / f"measured-{name}.csv",
                                      "time_s,flow_l_min,supply_bar_g\n")
        for s in self.signals:
            if s in self.states:
                self._timeline.write(f"0,{s},{_value(self.states[s])}\n")
        self.events.write("segment", number=self.number, why=why, start=iso_time(origin_ns),
                          start_ns=origin_ns, timeline=self._timeline.path.name,
                          measured=self._measured.path.name)

    def due(self, t_ns: int) -> bool:
        """Whether ``t_ns`` lies past the open segment's end (time to rotate)."""
        return self.open and t_ns >= self.end_ns

    def rotate_to(self, t_ns: int) -> None:
        """End the open segment and start the one that holds ``t_ns`` (a whole number of
        ``rotate_s`` after the last start: empty ones are skipped)."""
        steps = (t_ns - self.origin_ns) // self.rotate_ns
        self.start(self.origin_ns + steps * self.rotate_ns, {}, "rotated")

    def edge(self, t_ns: int, signal: str, value: float) -> None:
        if self.states.get(signal) == value:
            return                        # a value seen again (after a reconnect): no edge
        self.states[signal] = value
        self._timeline.write(f"{format_seconds(t_ns - self.origin_ns)},{signal},"
                             f"{_value(value)}\n")

    def reading(self, t_ns: int, flow_l_min: float) -> None:
        supply = "" if self.supply is None else repr(round(self.supply, 6))
        self._measured.write(f"{format_seconds(t_ns - self.origin_ns)},"
                             f"{flow_l_min!r},{supply}\n")
        self.last_reading_ns = t_ns

    def finish(self, why: str) -> None:
        """Close the open segment: its files renamed into place (a segment without a
        reading is dropped: no diagnosis can read it)."""
        if not self.open:
            return
        if self._measured.rows == 0:
            self._timeline.discard()
            self._measured.discard()
            self.events.write("segment_dropped", number=self.number, why=why)
        else:
            self._timeline.finish()
            self._measured.finish()
            self.written += [self._timeline.path, self._measured.path]
            self.finished.append((str(self._timeline.path), str(self._measured.path),
                                  self.origin_ns, self.last_reading_ns, why))
            self.events.write("segment_end", number=self.number, why=why,
                              readings=self._measured.rows,
                              changes=self._timeline.rows)
            self.number += 1
        self._timeline = self._measured = None


def _value(v: float) -> str:
    if isinstance(v, bool):
        return "1" if v else "0"
    f = float(v)
    return str(int(f)) if math.isfinite(f) and f == int(f) else repr(f)
