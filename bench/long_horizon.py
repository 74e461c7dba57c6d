"""Peak memory and time of long horizons (issue: resources stay bounded).

Runs ``plcpred timeline`` (or ``--command predict``) on samples/pick_place.toml (a part every 4 s) over a horizon in
a child process and prints its wall time, the rows written and the child's peak resident
memory, against the target of 500 MB, after a 1 h baseline run in the same invocation
(the ratio of the two peaks shows whether memory grows with the horizon). ``--horizon 3650d`` writes about 1.4 billion rows (28 GB,
about 15 minutes here); the output is removed afterwards.

    python bench/long_horizon.py [--horizon 3650d] [--machine samples/pick_place.toml]

``--jitter 0.2`` jitters every periodic input of the machine (each with its own seed): the
machine no longer repeats as a whole, parts are replayed and kept by reference (issue 40:
a year of jittered pick_place, ``--jitter 0.2 --horizon 365d``).

    python bench/long_horizon.py --jitter 0.2 --horizon 365d
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


def run(machine: str, horizon: str, command: str = "timeline", extra=()
        ) -> tuple[float, float, str]:
    out = Path(tempfile.mkdtemp(prefix="plcpred-long-")) / "o"
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "plcpred", command, machine, "--horizon",
                        horizon, "--out", str(out), "--max-rows", str(10**12), *extra],
                       capture_output=True, text=True)
    wall = time.perf_counter() - t0
    peak_mb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    if peak_mb * 1024 <= before:
        peak_mb = float("nan")  # an earlier child was larger: not measurable here
    shutil.rmtree(out.parent, ignore_errors=True)
    if r.returncode != 0:
        raise SystemExit(f"plcpred {command} failed: {r.stderr.strip()}")
    return wall, peak_mb, r.stdout.splitlines()[-1 if command == "predict" else 0]


def jittered_copy(machine: str, jitter_s: float, directory: Path) -> str:
    """A copy of the machine file in ``directory`` (its program named by its absolute
    path) with every periodic input jittered by +-``jitter_s``, each with its own seed."""
    source = Path(machine).resolve()
    out, k = [], 0
    for line in source.read_text().splitlines():
        if line.strip().startswith("program") and "=" in line:
            name = line.split("=", 1)[1].split("#")[0].strip().strip('"')
            line = f'program = "{source.parent / name}"'
        out.append(line)
        if line.strip().startswith("period_s"):
            k += 1
            out += [f"jitter_s = {jitter_s}", f"seed = {k}"]
    path = directory / f"{source.stem}-jittered.toml"
    path.write_text("\n".join(out) + "\n")
    return str(path)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--horizon", default="3650d")
    ap.add_argument("--machine", default=str(ROOT / "samples" / "pick_place.toml"))
    ap.add_argument("--command", default="timeline", choices=("timeline", "predict"),
                    help="predict also writes demand.csv, summary.json and demand.png "
                         "(3650d: about 10 minutes here)")
    ap.add_argument("--jitter", type=float, default=0.0,
                    help="jitter every periodic input by +- this many seconds")
    args = ap.parse_args()
    if args.jitter:
        args.machine = jittered_copy(args.machine, args.jitter,
                                     Path(tempfile.mkdtemp(prefix="plcpred-jitter-")))
    # the jittered copy names its program where the samples are
    extra = ("--allow-root", str(ROOT / "samples")) if args.jitter else ()
    # the baseline first: RUSAGE_CHILDREN keeps the largest child's peak so far
    wall0, peak0, _ = run(args.machine, "1h", args.command, extra)
    print(f"{'1h':>8s}: {wall0:7.1f} s, peak {peak0:6.0f} MB (baseline)")
    wall, peak, line = run(args.machine, args.horizon, args.command, extra)
    if peak != peak:  # NaN: no larger than the baseline
        peak = peak0
    print(f"{args.horizon:>8s}: {wall:7.1f} s, peak {peak:6.0f} MB, {peak / peak0:.2f}x the "
          f"baseline (target < {TARGET_MB:.0f} MB: {'ok' if peak < TARGET_MB else 'MISSED'})")
    print(f"          {line}")
    if args.jitter:
        shutil.rmtree(Path(args.machine).parent, ignore_errors=True)
    return 0 if peak < TARGET_MB else 1


if __name__ == "__main__":
    sys.exit(main())
