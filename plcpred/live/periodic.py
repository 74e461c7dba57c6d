"""``watch --diagnose-every``: the diagnosis (:func:`plcpred.diagnose.diagnose`) of the
last window of what was recorded, in a worker process, its verdict an event.

The diagnosis takes seconds to minutes of CPU; in a process of its own it holds neither
the event loop nor the interpreter's lock, so recording goes on at full pace while it
runs. It reads the open segment's files as far as they were written when it was asked
(hard links to them, so the segment may end and be renamed meanwhile) and, where the
window reaches back past the segment's start (a rotation, a gap), the ends of the
segments before, each a run of its own (one diagnosis run has one clock). At most one diagnosis runs; a
window falling due meanwhile waits and is the latest when the running one ends."""
from __future__ import annotations

import contextlib
import multiprocessing
import os
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from ..diagnose import diagnose, read_io_timeline, read_measured
from ..errors import PlcpredError
from ..machine import load_machine
from ..sequencer.timeline import NS
from .record import iso_time

MIN_WINDOW_S = 10.0          # a shorter stretch gives no diagnosis worth reporting
MAX_RUN_S = 900.0            # a worker running longer (wall clock) is stuck: ended
TOP_EFFECTS = 3


@dataclass
class Part:
    """A stretch of one segment: the first bytes of its two files, from ``from_s`` to
    ``to_s`` (seconds on the segment's clock, which began at ``origin_ns``).
    ``continues``: the segment before ended by rotation, so the two are one clock."""
    timeline: str
    timeline_bytes: int
    measured: str
    measured_bytes: int
    from_s: float
    to_s: float
    origin_ns: int
    continues: bool = False

    @property
    def start_ns(self) -> int:
        return self.origin_ns + round(self.from_s * NS)


@dataclass
class Window:
    """What one diagnosis reads: the last stretch of the open segment and, where the
    window reaches back past its start, the ends of the segments before (the last
    KEPT_SEGMENTS). Parts that continue one another (rotated files) are one run; after
    a gap or a clock jump a run of its own begins (a run has one clock)."""
    machine_path: str
    parts: list

    def runs(self) -> list[list[Part]]:
        out: list[list[Part]] = []
        for part in self.parts:
            if part.continues and out:
                out[-1].append(part)
            else:
                out.append([part])
        return out


def _prefix(path: str, nbytes: int) -> list[str]:
    with open(path, "rb") as f:
        text = f.read(nbytes).decode("utf-8")
    return text.splitlines()[1:]          # the header off


def cropped(run: list[Part]) -> tuple[str, str]:
    """(timeline CSV, measured CSV) of one run, times from its start: every signal's
    value at the start, then the changes; the readings within it."""
    first = run[0]
    states, changes, measured = {}, [], ["time_s,flow_l_min,supply_bar_g"]
    for k, part in enumerate(run):
        shift = (part.origin_ns - first.origin_ns) / NS - first.from_s
        for line in _prefix(part.timeline, part.timeline_bytes):
            t, signal, value = line.split(",")
            if k == 0 and float(t) <= part.from_s:
                states[signal] = value
            elif part.from_s < float(t) <= part.to_s:
                changes.append(f"{float(t) + shift:.9f},{signal},{value}")
        for line in _prefix(part.measured, part.measured_bytes):
            t, rest = line.split(",", 1)
            if part.from_s < float(t) <= part.to_s:
                measured.append(f"{float(t) + shift:.9f},{rest}")
    timeline = ["time_s,signal,value"] + [f"0,{s},{v}" for s, v in states.items()] + changes
    return "\n".join(timeline) + "\n", "\n".join(measured) + "\n"


def run_window(window: Window) -> dict:
    """The diagnosis of ``window`` as the verdict event's fields (in the worker)."""
    try:
        machine = load_machine(window.machine_path)
        runs, io = [], []
        with tempfile.TemporaryDirectory() as tmp:
            for k, run in enumerate(window.runs()):
                timeline, measured = cropped(run)
                io_path, m_path = Path(tmp) / f"timeline-{k}.csv", Path(tmp) / f"run-{k}.csv"
                io_path.write_text(timeline, encoding="utf-8")
                m_path.write_text(measured, encoding="utf-8")
                runs.append(read_measured(m_path, reference="iso8778"))
                io.append(read_io_timeline(io_path, horizon_s=runs[-1].span_s,
                                           machine=machine))
            d = diagnose(machine, runs, io=io, offsets=[0.0] * len(runs))
        s = d.summary()
    except (PlcpredError, ValueError, OSError) as e:
        return {"error": str(e).splitlines()[0][:300] if str(e) else type(e).__name__}
    effects = sorted(s["effects"], key=lambda e: e.get("bic") or 0.0)[:TOP_EFFECTS]
    return {"verdict": s["verdict"], "alternatives": s["alternatives"],
            "error_pct_before": s["baseline"]["error_pct"],
            "combination": s["combination"],
            "effects": [{"name": e["name"], "parameters": e["parameters"],
                         "heldout_error_pct_after": e["heldout_error_pct_after"]}
                        for e in effects]}


def _worker(conn, window: Window) -> None:
    try:
        conn.send(run_window(window))
    except Exception as e:  # noqa: BLE001 - the worker reports, it never raises
        conn.send({"error": f"{type(e).__name__}: {e}"[:300]})
    finally:
        conn.close()


class PeriodicDiagnosis:
    """Starts a diagnosis every ``every_s`` of machine time and writes its verdict."""

    def __init__(self, machine_path, every_s: float, out: Path, events, report,
                 on_result=None):
        self.machine_path, self.every_ns = str(machine_path), round(every_s * NS)
        self.links = out / ".diagnosis"
        self.events, self.report, self.on_result = events, report, on_result
        self.next_ns: int | None = None
        self.waiting = False                 # a window fell due while one ran
        self.running = None                  # (process, connection, event fields)
        self.count = 0
        self._ctx = multiprocessing.get_context("spawn")

    def tick(self, now_ns: int | None, recorder) -> None:
        """Collect a finished diagnosis; start one when due (called as values come)."""
        self.poll(now_ns)
        if now_ns is None or not recorder.open:
            return
        if self.next_ns is None:
            self.next_ns = now_ns + self.every_ns
        if now_ns >= self.next_ns:
            self.next_ns += self.every_ns * max(1, (now_ns - self.next_ns) // self.every_ns + 1)
            self.waiting = True
        if self.waiting and self.running is None:
            self._start(now_ns, recorder)

    def _link(self, path, name: str) -> str:
        """A hard link to ``path``: the same file, whatever becomes of its name."""
        link = self.links / name
        if link.exists():
            link.unlink()
        os.link(path, link)
        return str(link)

    def _parts(self, now_ns: int, recorder) -> list[Part]:
        """The window's parts (see :class:`Window`), each of at least MIN_WINDOW_S."""
        from_ns = now_ns - self.every_ns
        self.links.mkdir(exist_ok=True)
        parts, rotated = [], False
        for k, (timeline, measured, origin_ns, end_ns, why) in enumerate(recorder.finished):
            a_s = max(0.0, (from_ns - origin_ns) / NS)
            if end_ns > from_ns and os.path.exists(timeline):
                parts.append(Part(self._link(timeline, f"timeline-{self.count}-{k}.csv"),
                                  os.path.getsize(timeline),
                                  self._link(measured, f"measured-{self.count}-{k}.csv"),
                                  os.path.getsize(measured), a_s,
                                  (end_ns - origin_ns) / NS, origin_ns, rotated))
            rotated = why == "rotated"
        to_s = (now_ns - recorder.origin_ns) / NS
        a_s = max(0.0, (from_ns - recorder.origin_ns) / NS)
        t, m = recorder.timeline_file, recorder.measured_file
        sizes = (t.flush(), m.flush())
        parts.append(Part(self._link(t.tmp, f"timeline-{self.count}-open.csv"), sizes[0],
                          self._link(m.tmp, f"measured-{self.count}-open.csv"), sizes[1],
                          a_s, to_s, recorder.origin_ns, rotated))
        window = Window(self.machine_path, parts)
        keep = [p for run in window.runs() for p in run
                if sum(q.to_s - q.from_s for q in run) >= MIN_WINDOW_S]
        for p in parts:
            if p not in keep:
                os.unlink(p.timeline)
                os.unlink(p.measured)
        return keep

    def _start(self, now_ns: int, recorder) -> None:
        self.waiting = False
        self.count += 1
        parts = self._parts(now_ns, recorder)
        if not parts:
            self.count -= 1
            self.events.write("diagnosis_skipped", at=iso_time(now_ns),
                              why=f"no stretch of at least {MIN_WINDOW_S:g} s recorded "
                                  "in the window")
            return
        runs = Window(self.machine_path, parts).runs()
        fields = {"number": self.count, "window_from": iso_time(parts[0].start_ns),
                  "window_to": iso_time(now_ns),
                  "window_s": sum(p.to_s - p.from_s for p in parts), "runs": len(runs),
                  "requested_at": iso_time(now_ns), "segment": recorder.number}
        self.events.write("diagnosis_started", **fields)
        fields["_starts_ns"] = [run[0].start_ns for run in runs]
        parent, child = self._ctx.Pipe(duplex=False)
        process = self._ctx.Process(target=_worker, args=(child, Window(self.machine_path,
                                                                        parts)),
                                    daemon=True, name=f"plcpred-diagnosis-{self.count}")
        process.start()
        child.close()
        links = [p.timeline for p in parts] + [p.measured for p in parts]
        self.running = (process, parent, fields, links, time.monotonic())

    def poll(self, finished_at_ns: int | None = None) -> bool:
        """Write the running diagnosis's verdict if it has finished; whether one runs."""
        if self.running is None:
            return False
        process, conn, fields, links, started = self.running
        if process.is_alive() and not conn.poll():
            if time.monotonic() - started < MAX_RUN_S:
                return True
            process.terminate()
            process.join(timeout=5)
            fields["error"] = f"ended after {MAX_RUN_S:g} s without a verdict"
        try:
            result = conn.recv() if conn.poll() else {"error": fields.pop(
                "error", f"the diagnosis worker ended (exit code {process.exitcode})")}
        except (EOFError, OSError):
            result = {"error": f"the diagnosis worker ended (exit code {process.exitcode})"}
        process.join(timeout=5)
        conn.close()
        for link in links:
            with contextlib.suppress(OSError):  # already gone
                os.unlink(link)
        self.running = None
        self._write(fields, result, finished_at_ns)
        return False

    def _write(self, fields: dict, result: dict, finished_at_ns) -> None:
        if finished_at_ns is not None:
            fields["finished_at"] = iso_time(finished_at_ns)
        starts = fields.pop("_starts_ns")
        found = (result.get("combination") or {}).get("parameters") or {}
        if isinstance(found.get("onset_s"), (int, float)):
            # the diagnosis's onset is on its run's clock (run-K.csv: the window's K-th)
            run = str(found.get("onset_run", "run-0.csv"))
            k = int(run[4:-4]) if run[4:-4].isdigit() else 0
            result["onset"] = iso_time(starts[min(k, len(starts) - 1)]
                                       + round(found["onset_s"] * NS))
        self.events.write("diagnosis", **fields, **result)
        if self.on_result is not None:
            self.on_result({**fields, **result})
        if "error" in result:
            self.report(f"diagnosis {fields['number']}: failed: {result['error']}")
        else:
            self.report(f"diagnosis {fields['number']} of {fields['window_from']} to "
                        f"{fields['window_to']}: verdict {result['verdict']}")

    def stop(self, wait_s: float) -> None:
        """At the watch's end: the running diagnosis given ``wait_s`` to finish, then
        ended (its verdict or why not is written either way)."""
        if self.running is None:
            return
        process = self.running[0]
        process.join(timeout=wait_s)
        if process.is_alive():
            process.terminate()
            process.join(timeout=5)
        self.poll()
        with contextlib.suppress(OSError):  # already gone
            self.links.rmdir()

