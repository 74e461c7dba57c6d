"""Peak memory and time of long horizons (issue: resources stay bounded).

Runs ``plcpred timeline`` (or ``--command predict``) on samples/pick_place.toml (a part every 4 s) over a horizon in
a child process and prints its wall time, the rows written and the child's peak resident
memory, against the target of 500 MB, after a 1 h baseline run in the same invocation
(the ratio of the two peaks shows whether memory grows with the horizon). ``--horizon 3650d`` writes about 1.4 billion rows (28 GB,
about 15 minutes here); the output is removed afterwards.

    python bench/long_horizon.py [--horizon 3650d] [--machine samples/pick_place.toml]
"""
from __future__ import annotations

import argparse
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
TARGET_MB = 500.0


def run(machine: str, horizon: str, command: str = "timeline") -> tuple[float, float, str]:
    out = Path(tempfile.mkdtemp(prefix="plcpred-long-")) / "o"
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "plcpred", command, machine, "--horizon",
                        horizon, "--out", str(out), "--max-rows", str(10**12)],
                       capture_output=True, text=True)
    wall = time.perf_counter() - t0
    peak_mb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    if peak_mb * 1024 <= before:
        peak_mb = float("nan")  # an earlier child was larger: not measurable here
    shutil.rmtree(out.parent, ignore_errors=True)
    if r.returncode != 0:
        raise SystemExit(f"plcpred {command} failed: {r.stderr.strip()}")
    return wall, peak_mb, r.stdout.splitlines()[-1 if command == "predict" else 0]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--horizon", default="3650d")
    ap.add_argument("--machine", default=str(ROOT / "samples" / "pick_place.toml"))
    ap.add_argument("--command", default="timeline", choices=("timeline", "predict"),
                    help="predict also writes demand.csv, summary.json and demand.png "
                         "(3650d: about 10 minutes here)")
    args = ap.parse_args()
    # the baseline first: RUSAGE_CHILDREN keeps the largest child's peak so far
    wall0, peak0, _ = run(args.machine, "1h", args.command)
    print(f"{'1h':>8s}: {wall0:7.1f} s, peak {peak0:6.0f} MB (baseline)")
    wall, peak, line = run(args.machine, args.horizon, args.command)
    if peak != peak:  # NaN: no larger than the baseline
        peak = peak0
    print(f"{args.horizon:>8s}: {wall:7.1f} s, peak {peak:6.0f} MB, {peak / peak0:.2f}x the "
          f"baseline (target < {TARGET_MB:.0f} MB: {'ok' if peak < TARGET_MB else 'MISSED'})")
    print(f"          {line}")
    return 0 if peak < TARGET_MB else 1


if __name__ == "__main__":
    sys.exit(main())
