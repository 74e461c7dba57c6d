"""Speed of ``plcpred emulate`` (the physics plant in closed loop), whole process.

Issue 40's target: ``plcpred emulate`` of the prototype rig, 60 s, at least 100x real time
as a whole process (start-up, imports, the plant, the meter, the files). Each case runs
``python -m plcpred emulate`` in a child process (``--no-plot`` unless ``--plot``) and
reads its wall time and CPU (``resource.getrusage(RUSAGE_CHILDREN)``), paired in the same
run with

- ``python -c pass`` (the interpreter's own start),
- the in-process ``predict`` of the same machine and horizon (the activation model),
- with ``--lsoda``: the same command on scipy's LSODA, the integrator the plant used
  before (``plcpred.physics.group.METHOD = "lsoda"``), for the ratio new/old;
- with ``--baseline-tree DIR``: the same command run from another copy of the package
  (``DIR/plcpred``, e.g. ``git archive HEAD plcpred | tar -x -C DIR``), for the ratio
  against an earlier version.

Byte-code is cached in a temporary ``PYTHONPYCACHEPREFIX`` (warmed by one run first), as
an installed package has it. Each figure is the median of ``--repeat`` runs.

    python bench/emulate_speed.py [--rig-horizon 60s] [--pick-horizon 1h] [--repeat 3]
                                  [--lsoda] [--baseline-tree DIR] [--plot]
"""
from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from plcpred import load_machine, predict
from plcpred.sequencer import parse_horizon

ROOT = Path(__file__).resolve().parent.parent
TARGET_X = 100.0
LSODA_SHIM = ("import sys, runpy; import plcpred.physics.group as g; g.METHOD = 'lsoda'; "
              "sys.argv = ['plcpred'] + sys.argv[1:]; runpy.run_module('plcpred', "
              "run_name='__main__')")


def child(argv, env, cwd=ROOT) -> tuple[float, float]:
    """(wall s, CPU s) of one child process (``python -m`` finds the package in ``cwd``
    first)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run(argv, env=env, cwd=cwd, check=True, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def median_run(argv, env, repeat, cwd=ROOT) -> tuple[float, float]:
    runs = [child(argv, env, cwd) for _ in range(repeat)]
    return statistics.median(r[0] for r in runs), statistics.median(r[1] for r in runs)


def case(label, path, horizon, args, env, out):
    horizon_s = parse_horizon(horizon) / 1e9
    cmd = ["emulate", str(path), "--horizon", horizon, "--out", str(out), "--quiet",
           "--seed", "1"] + ([] if args.plot else ["--no-plot"])
    new_argv = [sys.executable, "-m", "plcpred"] + cmd
    child(new_argv, env)                         # warms the byte-code cache
    base = median_run([sys.executable, "-c", "pass"], env, args.repeat)
    machine = load_machine(path)
    c0, t0 = time.process_time(), time.perf_counter()
    predict(machine, horizon)
    pred = (time.perf_counter() - t0, time.process_time() - c0)
    wall, cpu = median_run(new_argv, env, args.repeat)
    speed = horizon_s / wall
    verdict = "met" if speed >= TARGET_X else "NOT MET"
    print(f"{label}, {horizon}: whole process {wall:.2f} s wall, {cpu:.2f} s CPU "
          f"({speed:.0f}x real time by wall, {horizon_s / cpu:.0f}x by CPU; target "
          f"{TARGET_X:g}x: {verdict})")
    print(f"  python -c pass {base[0]:.3f} s wall / {base[1]:.3f} s CPU; emulate is "
          f"{cpu / max(base[1], 1e-9):.0f}x its CPU; in-process predict {pred[0]:.2f} s "
          f"wall / {pred[1]:.2f} s CPU (emulate {cpu / max(pred[1], 1e-9):.1f}x its CPU)")
    if args.lsoda:
        old = median_run([sys.executable, "-c", LSODA_SHIM] + cmd, env, args.repeat)
        print(f"  LSODA (before): {old[0]:.2f} s wall / {old[1]:.2f} s CPU; new/old "
              f"{wall / old[0]:.2f} by wall, {cpu / old[1]:.2f} by CPU")
    if args.baseline_tree:
        tree = Path(args.baseline_tree).resolve()
        base_env = dict(env, PYTHONPATH=str(tree))
        child(new_argv, base_env, tree)          # its byte-code too
        old = median_run(new_argv, base_env, args.repeat, tree)
        print(f"  {args.baseline_tree}: {old[0]:.2f} s wall / {old[1]:.2f} s CPU "
              f"({horizon_s / old[0]:.0f}x real time); new/old {wall / old[0]:.2f} by "
              f"wall, {cpu / old[1]:.2f} by CPU")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rig-horizon", default="60s")
    ap.add_argument("--pick-horizon", default="1h")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--lsoda", action="store_true", help="pair against scipy's LSODA")
    ap.add_argument("--baseline-tree", metavar="DIR",
                    help="also run the package found in DIR (an earlier version)")
    ap.add_argument("--plot", action="store_true", help="draw emulate.png as well")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        env = dict(os.environ, PYTHONPYCACHEPREFIX=str(Path(tmp) / "pycache"))
        env.pop("PYTHONDONTWRITEBYTECODE", None)
        case("rig (sequence 1)", ROOT / "samples" / "prototype_rig" / "rig.toml",
             args.rig_horizon, args, env, Path(tmp) / "rig")
        case("pick_place", ROOT / "samples" / "pick_place.toml", args.pick_horizon, args,
             env, Path(tmp) / "pick")


if __name__ == "__main__":
    main()
