"""Memory of ``plcpred watch`` and ``plcpred serve`` over a long served run.

Serves samples/pick_place.toml (a cycle every 4 s) with ``plcpred serve --speed N`` and
watches it with ``plcpred watch`` (learned reference, hourly files, a diagnosis every
--diagnose-every of machine time), each in a child process, and prints the resident
memory (VmRSS) of the watch, the server and the server's twin process (where its
closed-loop runs are made) every --every seconds of wall time, with the cycles compared
so far and the machine time they cover; at the end each process's RSS after the
warm-up, at the middle and at the end with its growth per machine hour, and the speed
the served machine held (machine seconds compared per wall second). A simulated 24 h at
--speed 100 takes at least 14.4 min of wall time (longer where the server falls behind
the clock); --minutes stops earlier (the figures are then for the stretch run). The
diagnoses run in processes of their own, not counted in the watch's RSS. Say how
loaded the machine was (``uptime``, printed at the start and the end) with the figures.

    python bench/live_memory.py [--speed 100] [--minutes 5] [--every 10]
"""
from __future__ import annotations

import argparse
import os
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
MACHINE = ROOT / "samples" / "pick_place.toml"
WARM_UP_S = 60.0        # wall seconds before the first figure compared


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def children(pid: int) -> list[int]:
    """The processes ``pid`` started (the server's twin process)."""
    out = []
    for task in Path(f"/proc/{pid}/task").glob("*"):
        try:
            out += [int(c) for c in (task / "children").read_text().split()]
        except OSError:
            pass
    return out


def load() -> str:
    try:
        return "load average " + " ".join(Path("/proc/loadavg").read_text().split()[:3]) \
            + f" on {os.cpu_count()} cores"
    except OSError:
        return "load unknown"


def rss_mb(pid: int) -> float | None:
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    except OSError:
        return None
    return None


class Lines:
    """Counts a child's stdout lines by their first word (a thread reads them)."""

    def __init__(self, stream):
        self.counts: dict[str, int] = {}
        self.compared_s = 0.0            # machine time of the cycles compared
        self.last = ""
        self.said: dict[str, str] = {}   # first word -> its last line
        threading.Thread(target=self._read, args=(stream,), daemon=True).start()

    def _read(self, stream):
        for line in stream:
            word = line.split(" ", 1)[0]
            self.counts[word] = self.counts.get(word, 0) + 1
            if word == "cycle":
                self.compared_s += float(line.split()[4])
            else:
                self.last = self.said[word.rstrip(":")] = line.strip()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--speed", type=float, default=100.0)
    ap.add_argument("--minutes", type=float, default=14.5, help="wall time to run")
    ap.add_argument("--every", type=float, default=10.0, help="seconds between figures")
    ap.add_argument("--diagnose-every", default="1h")
    ap.add_argument("--horizon", default="24h", help="the served machine's horizon")
    ap.add_argument("--history", type=int, default=5000,
                    help="values the server keeps per node: a connection lost while the "
                         "machine is busy is filled from them")
    args = ap.parse_args()
    url = f"opc.tcp://127.0.0.1:{free_port()}"
    out = Path(tempfile.mkdtemp(prefix="plcpred-live-memory-"))
    py = [sys.executable, "-m", "plcpred"]
    serve = subprocess.Popen(py + ["serve", str(MACHINE), "--endpoint", url, "--speed",
                                   str(args.speed), "--horizon", args.horizon, "--seed", "1",
                                   "--history", str(args.history)],
                             stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    served = Lines(serve.stdout)
    while "machine" not in served.counts and serve.poll() is None:
        time.sleep(0.1)
    t0 = time.monotonic()
    watch = subprocess.Popen(py + ["watch", str(MACHINE), "--endpoint", url, "--out",
                                   str(out / "w"), "--cycle-signal", "qX",
                                   "--diagnose-every", args.diagnose_every,
                                   "--duration", f"{args.minutes * 60:.0f}s"],
                             stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    watched = Lines(watch.stdout)
    print(f"start: {load()}", flush=True)
    print(f"{'wall s':>7} {'cycles':>7} {'machine h':>9} {'watch MB':>9} {'serve MB':>9} "
          f"{'twin MB':>8}", flush=True)
    rows = []   # (wall s, machine h, watch MB, serve MB, twin MB)
    try:
        while watch.poll() is None:
            time.sleep(args.every)
            wall = time.monotonic() - t0
            w, s = rss_mb(watch.pid), rss_mb(serve.pid)
            if w is None:
                break
            twin = sum(filter(None, (rss_mb(c) for c in children(serve.pid)))) or None
            hours = watched.compared_s / 3600.0
            rows.append((wall, hours, w, s, twin))
            print(f"{wall:7.0f} {watched.counts.get('cycle', 0):7d} {hours:9.2f} {w:9.1f} "
                  + (f"{s:9.1f}" if s is not None else "        -")
                  + (f" {twin:8.1f}" if twin is not None else "        -"), flush=True)
    finally:
        watch.wait(timeout=300)
        serve.terminate()
        serve.wait(timeout=30)
    print(f"end: {load()}", flush=True)
    # up to the last cycle compared (the watch then writes its last files)
    rows = rows[:next((i + 1 for i, r in enumerate(rows) if r[1] == rows[-1][1]), 0)]
    late = [r for r in rows if r[0] >= WARM_UP_S]
    if len(late) >= 2 and late[-1][1] > late[0][1]:
        hours = late[-1][1] - late[0][1]
        print(f"speed held after {WARM_UP_S:g} s: {hours * 3600 / (late[-1][0] - late[0][0]):.1f} "
              f"machine s per wall s ({late[-1][1]:.2f} h of machine time compared in "
              f"{late[-1][0]:.0f} s of wall time)")
        for k, name in ((2, "watch"), (3, "serve"), (4, "twin")):
            had = [r for r in late if r[k] is not None]     # (the server ends at its horizon)
            if len(had) < 2 or had[-1][1] <= had[0][1]:
                continue
            middle = had[len(had) // 2]
            print(f"{name} RSS after {had[0][0]:.0f} s ({had[0][1]:.2f} h): {had[0][k]:.1f} MB, "
                  f"at {middle[1]:.2f} h {middle[k]:.1f} MB, at {had[-1][1]:.2f} h "
                  f"{had[-1][k]:.1f} MB, highest {max(r[k] for r in had):.1f} MB; "
                  f"{(had[-1][k] - had[0][k]) / (had[-1][1] - had[0][1]):+.2f} MB per "
                  "machine hour")
    print(f"server: {served.said.get('repeating', '(no repeating period)')}; {served.last}")
    print(f"diagnoses: {watched.counts.get('diagnosis', 0)}, connections lost: "
          f"{watched.counts.get('connection', 0)}, filled from history: "
          f"{watched.counts.get('read', 0)}; watch's last word: "
          f"{watched.last}; files in {out}")
    return 0


if __name__ == "__main__":
    os.environ.setdefault("PYTHONUNBUFFERED", "1")
    sys.exit(main())
