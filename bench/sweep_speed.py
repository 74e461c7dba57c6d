"""A sweep on the local process pool against the same sweep on a Dask LocalCluster with
the same cores, in one run: wall time of each, their ratio (target: Dask within 1.1x of
local) and whether the rows are identical. The runs go in pairs, one of each engine,
and the ratio is the median of the pairs' ratios.

The scenarios: ``supply_bar_g`` x ``scan_ms`` x a cylinder's bore on the pick-and-place
station (64 by default), each predicted over ``--horizon``.

    python bench/sweep_speed.py [--scenarios 64] [--horizon 2h] [--workers N] [--repeat 6] [--dask-defaults]
"""
from __future__ import annotations

import argparse
import logging
import os
import statistics
import sys
import time
from pathlib import Path

from plcpred.sweep import DASK_WORKER_CONFIG, parse_setting, sweep

ROOT = Path(__file__).resolve().parent.parent
TARGET = 1.1


def settings_for(n: int):
    """About ``n`` scenarios as the product of three settings (4 x 4 x n/16)."""
    third = max(1, n // 16)
    return [parse_setting("supply_bar_g=" + ",".join(str(5 + 0.5 * k) for k in range(4))),
            parse_setting("scan_ms=" + ",".join(str(2 + k) for k in range(4))),
            parse_setting("Z lift.bore_mm=" + ",".join(
                str(16 + 2 * k) for k in range(third)))]


def _warm_worker(machine: str) -> None:
    """A process with plcpred imported (0.2-0.5 s a fresh process pays) and the
    machine's program read (the parser's tables, 0.1 s). This process calls it before
    the runs, so the local pool's workers are forked in that state; each Dask worker
    calls it before the clock starts, so both engines start from the same state."""
    import importlib
    importlib.import_module("plcpred.air.predict")
    importlib.import_module("plcpred.sweep")
    from plcpred.machine import machine_from_data, read_machine_data
    machine_from_data(read_machine_data(machine), machine).read_program(None)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenarios", type=int, default=64)
    ap.add_argument("--horizon", default="2h")
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--repeat", type=int, default=6,
                    help="pairs of runs, one of each engine (median)")
    ap.add_argument("--dask-defaults", action="store_true",
                    help="Dask's default worker settings instead of DASK_WORKER_CONFIG")
    args = ap.parse_args(argv)
    import dask
    from dask.distributed import Client, LocalCluster

    from plcpred.sequencer import parse_horizon

    machine = ROOT / "samples" / "pick_place.toml"
    horizon_s = parse_horizon(args.horizon) / 1e9
    settings = settings_for(args.scenarios)
    # the engines in pairs, one after the other (their order alternating), each from the
    # same start (a fresh local pool, a fresh cluster): this machine's speed drifts by
    # +-10 % over a minute, and a pair's ratio sees both engines at the same speed
    local_s, dask_s = [], []
    _warm_worker(str(machine))

    def run_local():
        t0 = time.perf_counter()
        rows = sweep(machine, settings, horizon_s, workers=args.workers, progress=False)
        local_s.append(time.perf_counter() - t0)
        return rows

    def run_dask():
        # the workers as plcpred's docs start them (plcpred.sweep.DASK_WORKER_CONFIG:
        # no stack sampling, slower monitors); --dask-defaults leaves Dask's own
        with dask.config.set({} if args.dask_defaults else DASK_WORKER_CONFIG), \
                LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True,
                             dashboard_address=None, silence_logs=logging.CRITICAL) \
                as cluster, Client(cluster) as client:
            # workers up and warmed before the clock starts, as the local pool's are
            client.run(_warm_worker, str(machine))
            t0 = time.perf_counter()
            rows = sweep(machine, settings, horizon_s, engine="dask", scheduler=client,
                         progress=False)
            dask_s.append(time.perf_counter() - t0)
        return rows

    same = True
    for k in range(args.repeat):
        if k % 2:
            remote, local = run_dask(), run_local()
        else:
            local, remote = run_local(), run_dask()
        same = same and local == remote
    t_local, t_dask = statistics.median(local_s), statistics.median(dask_s)
    ratio = statistics.median(d / x for d, x in zip(dask_s, local_s))
    print(f"{len(local)} scenarios of {args.horizon} on {args.workers} workers, "
          f"{args.repeat} pairs: local {t_local:.2f} s, dask {t_dask:.2f} s (medians), "
          f"ratio {ratio:.2f}x (median of the pairs') (target <= {TARGET}x: {'ok' if ratio <= TARGET else 'MISSED'}); "
          f"rows identical: {same}")
    print("  local " + " ".join(f"{x:.2f}" for x in local_s) + " s; dask "
          + " ".join(f"{x:.2f}" for x in dask_s) + " s")
    return 0 if same and ratio <= TARGET else 1


if __name__ == "__main__":
    sys.exit(main())
