"""End-to-end speed of ``plcpred predict`` on a continuously cycling sample.

A 24 h horizon of the pick-and-place station (samples/pick_place.toml) at ``--dt 1s``:
load and run the program, build the demand profile, write timeline.csv, demand.csv,
summary.json and demand.png. Prints the time per stage and the total against the
target of issue 4 (under 30 s), then the same with jittered part arrivals (no tiling),
and the air-model stage alone against a 10 ms grid (8.6 million cells).

    python bench/predict_speed.py [--horizon 24h] [--dt 1s]
"""
from __future__ import annotations

import argparse
import copy
import tempfile
import time
from pathlib import Path

from plcpred import load_machine
from plcpred.air import consumer_models, demand_profile, predict
from plcpred.outputs.files import write_prediction

ROOT = Path(__file__).resolve().parent.parent
TARGET_S = 30.0


def run(machine, horizon, dt, out):
    t0 = time.perf_counter()
    result = predict(machine, horizon, dt=dt)
    write_prediction(result, out)
    total = time.perf_counter() - t0
    return total, result


def show(label, total, result):
    st = result.stage_s
    stages = ", ".join(f"{k} {v:.2f} s" for k, v in st.items())
    print(f"{label}: {total:.2f} s ({stages}); {len(result.timeline.time_ns)} changes, "
          f"{result.profile.n_cells} grid cells, total {result.profile.total_nl:.0f} NL")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--horizon", default="24h")
    ap.add_argument("--dt", default="1s")
    args = ap.parse_args(argv)
    station = load_machine(ROOT / "samples" / "pick_place.toml")
    with tempfile.TemporaryDirectory() as tmp:
        total, result = run(station, args.horizon, args.dt, tmp)
        show(f"pick_place {args.horizon} at dt {args.dt}", total, result)
        verdict = "meets" if total < TARGET_S else "MISSES"
        print(f"  -> {verdict} the {TARGET_S:.0f} s target")
        jittered = copy.deepcopy(station)
        for s in jittered.inputs:
            s.jitter_s, s.seed = 0.2, 1
        total_j, result_j = run(jittered, args.horizon, args.dt, tmp)
        show("  same, jittered arrivals (no tiling)", total_j, result_j)
        models = consumer_models(station)

        def air(dt):
            """The profile with what the summary and the plot ask of it (the profile
            itself is read onto the grid only where asked)."""
            t0 = time.perf_counter()
            prof = demand_profile(result.timeline, models, dt)
            prof.summary()
            prof.total_cell_nl
            return time.perf_counter() - t0, prof
        t_fine, fine = air(0.01)
        t_coarse, _ = air(1.0)
        print(f"air model alone (profile, summary, total on the grid): {t_fine:.2f} s at "
              f"10 ms ({fine.n_cells} cells) vs {t_coarse:.3f} s at 1 s: "
              f"{t_fine / t_coarse:.0f}x for 100x the cells")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
