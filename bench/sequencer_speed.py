"""Sequencer speed on the sample machines.

For each sample machine prints:

* the real-time factor of a 24 h horizon, end to end (load, compile, run, timeline.csv
  written), and whether the cycle was tiled;
* for 1 h: the wall time of the event-driven run and of scan stepping (every scan
  executed), measured in the same process, and their ratio.

Then the target of issue 3: a 24 h horizon of the continuously cycling three-actuator
station (samples/pick_place.toml), timeline.csv written, in under 10 s. The same station
with jittered part arrivals (which rules out tiling) shows the cost without it.

    python bench/sequencer_speed.py [--stepping-horizon 1h] [--only NAME]
"""
from __future__ import annotations

import argparse
import copy
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


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--stepping-horizon", default="1h",
                    help="horizon of the event-driven vs scan-stepping comparison")
    ap.add_argument("--only", help="run only machines whose file name contains this")
    args = ap.parse_args(argv)
    day_s = parse_horizon(DAY) / 1e9
    step_h = args.stepping_horizon
    machines = [m for m in MACHINES if not args.only or args.only in m.name]
    print(f"{'machine':<16} {'24h wall s':>10} {'x real time':>12} {'tiled':>6} "
          f"{'changes':>9} | {step_h + ' event s':>10} {step_h + ' stepping s':>13} {'speed-up':>9}")
    with tempfile.TemporaryDirectory() as tmp:
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
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
