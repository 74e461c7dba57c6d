"""Speed of ``plcpred emulate`` (the physics plant in closed loop).

Targets of issue 9 on a 2-core machine: 60 s of the prototype rig in under 10 s, 1 h of
the pick-and-place station in under 2 minutes. Prints, per case, the wall time, the
ratio to real time, the ratio to the activation model's ``predict`` of the same horizon
run in this process (the baseline), and how many integration pieces were reused.

    python bench/emulate_speed.py [--pick-horizon 1h] [--rig-horizon 60s]
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from plcpred import load_machine, predict
from plcpred.outputs.files import write_emulation
from plcpred.plant import emulate
from plcpred.sequencer import parse_horizon

ROOT = Path(__file__).resolve().parent.parent


def case(label, path, horizon, target_s):
    horizon_s = parse_horizon(horizon) / 1e9
    machine = load_machine(path)
    t0 = time.perf_counter()
    predict(machine, horizon)
    base_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    em = emulate(path, horizon)
    with tempfile.TemporaryDirectory() as d:
        write_emulation(em, Path(d), plot=False)
    wall_s = time.perf_counter() - t0
    info = em.info
    verdict = "ok" if wall_s < target_s else "SLOWER THAN TARGET"
    print(f"{label}: {horizon} in {wall_s:.2f} s ({horizon_s / wall_s:.0f}x real time, "
          f"{wall_s / base_s:.1f}x predict's {base_s:.2f} s); run {info['wall_run_s']:.2f} s, "
          f"pieces {info['integrated_pieces']} integrated / {info['reused_pieces']} reused; "
          f"target {target_s:g} s: {verdict}")
    return wall_s


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rig-horizon", default="60s")
    ap.add_argument("--pick-horizon", default="1h")
    args = ap.parse_args()
    case("rig (sequence 1)", ROOT / "samples" / "prototype_rig" / "rig.toml",
         args.rig_horizon, 10.0)
    case("pick_place", ROOT / "samples" / "pick_place.toml", args.pick_horizon, 120.0)


if __name__ == "__main__":
    main()
