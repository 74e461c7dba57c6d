"""A sweep on the local process pool against the same sweep on a Dask LocalCluster with
the same cores, in one run: wall time of each, their ratio (target: Dask within 1.1x of
local) and whether the rows are identical.

The scenarios: ``supply_bar_g`` x ``scan_ms`` x a cylinder's bore on the pick-and-place
station (64 by default), each predicted over ``--horizon``.

    python bench/sweep_speed.py [--scenarios 64] [--horizon 2h] [--workers N] [--repeat 3]
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

from plcpred.sweep import parse_setting, sweep

ROOT = Path(__file__).resolve().parent.parent
TARGET = 1.1


def settings_for(n: int):
    """About ``n`` scenarios as the product of three settings (4 x 4 x n/16)."""
    third = max(1, n // 16)
    return [parse_setting("supply_bar_g=" + ",".join(str(5 + 0.5 * k) for k in range(4))),
            parse_setting("scan_ms=" + ",".join(str(2 + k) for k in range(4))),
            parse_setting("Z lift.bore_mm=" + ",".join(
                str(16 + 2 * k) for k in range(third)))]


def _import_plcpred() -> None:
    """A Dask worker in the state a local pool's worker starts in: forked from this
    process, which has imported plcpred (0.2 s a fresh process pays)."""
    import importlib
    importlib.import_module("plcpred.air.predict")
    importlib.import_module("plcpred.sweep")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenarios", type=int, default=64)
    ap.add_argument("--horizon", default="2h")
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--repeat", type=int, default=3, help="runs of each engine (median)")
    args = ap.parse_args(argv)
    from dask.distributed import Client, LocalCluster

    from plcpred.sequencer import parse_horizon

    machine = ROOT / "samples" / "pick_place.toml"
    horizon_s = parse_horizon(args.horizon) / 1e9
    settings = settings_for(args.scenarios)
    # each engine --repeat times from the same start (a fresh local pool, a fresh
    # cluster), the medians compared: one run of a few seconds varies by +-10 % here
    local_s, dask_s = [], []
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        local = sweep(machine, settings, horizon_s, workers=args.workers, progress=False)
        local_s.append(time.perf_counter() - t0)
    for _ in range(args.repeat):
        with LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True,
                          dashboard_address=None) as cluster, Client(cluster) as client:
            # workers up, with plcpred imported, before the clock starts: the local
            # pool's workers are forked from this process and start with its imports
            client.run(_import_plcpred)
            t0 = time.perf_counter()
            remote = sweep(machine, settings, horizon_s, engine="dask", scheduler=client,
                           progress=False)
            dask_s.append(time.perf_counter() - t0)
    same = local == remote
    t_local, t_dask = statistics.median(local_s), statistics.median(dask_s)
    ratio = t_dask / t_local
    print(f"{len(local)} scenarios of {args.horizon} on {args.workers} workers, median of "
          f"{args.repeat}: local {t_local:.2f} s, dask {t_dask:.2f} s, ratio {ratio:.2f}x "
          f"(target <= {TARGET}x: {'ok' if ratio <= TARGET else 'MISSED'}); "
          f"rows identical: {same}")
    print("  local " + " ".join(f"{x:.2f}" for x in local_s) + " s; dask "
          + " ".join(f"{x:.2f}" for x in dask_s) + " s")
    return 0 if same and ratio <= TARGET else 1


if __name__ == "__main__":
    sys.exit(main())
