"""The files of a prediction (``timeline.csv``, ``demand.csv``, ``summary.json``,
``demand.png``) and of an emulation (``measured.csv``, ``timeline.csv``, ``plant.csv``,
``emulate.png``), each written through a temporary file."""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from ..air.cycles import arrival_period_s
from ..output import atomic_writer, csv_column_name
from .report import plot_demand, plot_emulation


def write_prediction(prediction, out_dir, plot: bool = True, timeline: bool = True
                     ) -> list[Path]:
    """``timeline.csv`` (unless ``timeline`` is false), ``demand.csv``, ``summary.json``
    and ``demand.png`` of a :class:`~plcpred.air.Prediction` in ``out_dir``; the time
    each took goes to its ``stage_s``."""
    p = prediction
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    files = []
    if timeline:
        p.timeline.to_csv(out / "timeline.csv")
        files.append(out / "timeline.csv")
    p.profile.to_csv(out / "demand.csv", shown=p.shown)
    p.profile.write_summary(out / "summary.json", {
        "machine": p.machine.name, "supply_bar_g": p.machine.supply_bar_g})
    p.stage_s["write_csv"] = time.perf_counter() - t0
    files += [out / "demand.csv", out / "summary.json"]
    if plot:
        t0 = time.perf_counter()
        plot_demand(p.profile, out / "demand.png",
                    title=f"{p.machine.name}: air demand over {_span(p.profile.horizon_s)}",
                    shown=p.shown, cycle_s=arrival_period_s(p.machine, p.timeline))
        p.stage_s["plot"] = time.perf_counter() - t0
        files.append(out / "demand.png")
    p.write_files = files
    return files


def _span(seconds: float) -> str:
    if seconds >= 7200:
        return f"{seconds / 3600:g} h"
    if seconds >= 120:
        return f"{seconds / 60:g} min"
    return f"{seconds:g} s"


def write_measured(emulation, path) -> None:
    """``measured.csv``: the emulated meter's log, as ``diagnose --measured`` reads it."""
    em = emulation
    with atomic_writer(path) as f:
        f.write("time_s,flow_l_min,supply_bar_g\n")
        np.savetxt(f, np.column_stack([em.measured_time_s, em.measured_flow_l_min,
                                       em.measured_supply_bar_g]),
                   fmt=["%.4f", "%.4f", "%.4f"], delimiter=",")


def write_plant(emulation, path, table=None) -> None:
    """``plant.csv``; ``table`` is the emulation's :meth:`plant_table` already made."""
    header, rows = table or emulation.plant_table()
    with atomic_writer(path) as f:
        f.write(",".join(csv_column_name(h) for h in header) + "\n")
        np.savetxt(f, rows, fmt="%.6g", delimiter=",")


def write_emulation(emulation, directory, plot: bool = True) -> list[Path]:
    """``measured.csv``, ``timeline.csv``, ``plant.csv`` and ``emulate.png`` of an
    :class:`~plcpred.plant.Emulation` in ``directory``."""
    directory = Path(directory)
    files = [directory / "measured.csv", directory / "timeline.csv",
             directory / "plant.csv"]
    write_measured(emulation, files[0])
    emulation.timeline.to_csv(files[1])
    table = emulation.plant_table()     # sampling the plant: once for the file and the plot
    write_plant(emulation, files[2], table)
    if plot:
        files.append(directory / "emulate.png")
        plot_emulation(emulation, files[-1], table)
    return files
