"""Sequencer speed on the sample machines.

For each sample machine prints:

* the real-time factor of a 24 h horizon, end to end (load, compile, run, timeline.csv
  written), and whether the cycle was tiled;
* for 1 h: the wall time of the event-driven run and of scan stepping (every scan
  executed), measured in the same process, and their ratio.

Then the target of issue 3: a 24 h horizon of the continuously cycling three-actuator
station (samples/pick_place.toml), timeline.csv written, in under 10 s. The same station
with jittered part arrivals (which rules out tiling) shows the cost without it.

Then every sample with each periodic input jittered on its own (+-0.2 s, its own seed;
issue 40): 24 h end to end against the tiled run measured just before it in the same
process (the paired ratio, wall and CPU), whether it split into islands, how many scans
it executed, and (``--check``) that its timeline over 10 min equals the run with every
scan executed.

    python bench/sequencer_speed.py [--stepping-horizon 1h] [--only NAME] [--check]
"""
from __future__ import annotations

import argparse
import copy
import resource
import tempfile
import time
from pathlib import Path

from plcpred import load_machine, unfold
from plcpred.sequencer import parse_horizon

ROOT = Path(__file__).resolve().parent.parent
MACHINES = sorted((ROOT / "samples").glob("*.toml")) + [
    ROOT / "samples" / "prototype_rig" / "rig.toml"]
DAY = "24h"
TARGET_S = 10.0


def end_to_end(machine, horizon, out_dir, **kw):
    t0 = time.perf_counter()
    tl = unfold(machine, horizon, **kw)
    tl.to_csv(Path(out_dir) / "timeline.csv")
    return time.perf_counter() - t0, tl


def cpu_s() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def jittered(machine, jitter_s: float = 0.2):
    """``machine`` with each periodic input jittered on its own (its own seed)."""
    out = copy.deepcopy(machine)
    for k, s in enumerate(out.inputs):
        if s.period_s is not None:
            s.jitter_s, s.seed = jitter_s, k + 1
    return out


def jittered_pairs(machines, tmp, check: bool) -> None:
    """Every sample tiled and independently jittered, 24 h each, paired."""
    print(f"\n{'jittered 24h':<16} {'tiled s':>8} {'cpu':>6} {'jittered s':>10} {'cpu':>6} "
          f"{'ratio':>6} {'cpu ratio':>9} {'islands':>7} {'scans':>9} {'changes':>9}"
          + ("  10 min = every scan" if check else ""))
    for path in machines:
        machine = load_machine(path)
        if not any(s.period_s is not None for s in machine.inputs):
            continue
        c0 = cpu_s()
        wall_t, _ = end_to_end(machine, DAY, tmp)
        cpu_t = cpu_s() - c0
        jit = jittered(machine)
        c0 = cpu_s()
        wall_j, tl = end_to_end(jit, DAY, tmp)
        cpu_j = cpu_s() - c0
        same = ""
        if check:
            same = "  " + ("yes" if unfold(jit, "10min") == unfold(
                jit, "10min", scan_stepping=True) else "MISMATCH")
        print(f"{path.stem:<16} {wall_t:>8.2f} {cpu_t:>6.2f} {wall_j:>10.2f} {cpu_j:>6.2f} "
              f"{wall_j / wall_t:>5.1f}x {cpu_j / max(cpu_t, 1e-9):>8.1f}x "
              f"{tl.info.get('islands') or 1:>7} {tl.info['scans']:>9} {tl.n_changes:>9}"
              + same, flush=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--stepping-horizon", default="1h",
                    help="horizon of the event-driven vs scan-stepping comparison")
    ap.add_argument("--only", help="run only machines whose file name contains this")
    ap.add_argument("--check", action="store_true",
                    help="check each jittered sample over 10 min against every scan executed")
    ap.add_argument("--jittered-only", action="store_true",
                    help="only the jittered samples against their tiled runs")
    args = ap.parse_args(argv)
    day_s = parse_horizon(DAY) / 1e9
    step_h = args.stepping_horizon
    machines = [m for m in MACHINES if not args.only or args.only in m.name]
    print(f"{'machine':<16} {'24h wall s':>10} {'x real time':>12} {'tiled':>6} "
          f"{'changes':>9} | {step_h + ' event s':>10} {step_h + ' stepping s':>13} {'speed-up':>9}")
    with tempfile.TemporaryDirectory() as tmp:
        if args.jittered_only:
            jittered_pairs(machines, tmp, args.check)
            return 0
        for path in machines:
            machine = load_machine(path)
            wall, tl = end_to_end(machine, DAY, tmp)
            tiled = "yes" if tl.info.get("period_s") else "no"
            t0 = time.perf_counter()
            fast = unfold(machine, step_h, tiling=False)
            t_fast = time.perf_counter() - t0
            t0 = time.perf_counter()
            ref = unfold(machine, step_h, scan_stepping=True)
            t_ref = time.perf_counter() - t0
            same = "" if fast == ref else "  MISMATCH"
            print(f"{path.stem:<16} {wall:>10.2f} {day_s / wall:>12.0f} {tiled:>6} "
                  f"{len(tl.time_ns):>9} | {t_fast:>10.2f} {t_ref:>13.2f} "
                  f"{t_ref / t_fast:>8.0f}x{same}")

        station = load_machine(ROOT / "samples" / "pick_place.toml")
        wall, tl = end_to_end(station, DAY, tmp)
        ok = "meets" if wall < TARGET_S else "MISSES"
        print(f"\ntarget: 24 h of the cycling three-actuator station (pick_place), "
              f"timeline.csv written: {wall:.2f} s ({ok} the {TARGET_S:.0f} s target; "
              f"{tl.info['scans']} scans executed, tiled every {tl.info['period_s']} s)")
        jittered = copy.deepcopy(station)
        for s in jittered.inputs:
            s.jitter_s, s.seed = 0.2, 1
        wall, tl = end_to_end(jittered, DAY, tmp)
        print(f"same station, part arrivals jittered +-0.2 s (no tiling possible): "
              f"{wall:.2f} s, {tl.info['scans']} scans executed of "
              f"{int(day_s * 1000 / station.scan_ms) + 1}")
        jittered_pairs(machines, tmp, args.check)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
