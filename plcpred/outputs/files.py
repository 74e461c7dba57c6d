"""The files of a prediction (``timeline.csv``, ``demand.csv``, ``summary.json``,
``demand.png``) and of an emulation (``measured.csv``, ``timeline.csv``, ``plant.csv``,
``emulate.png``), each written through a temporary file."""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from ..air.cycles import arrival_period_s
from ..output import SHOWN_CONSUMERS, atomic_writer, csv_column_name, write_json
from ..progress import Progress, progress_or_off
from ..sequencer.timeline import NS, seconds_texts
from .demand_plot import plot_demand
from .emulation_plot import plot_emulation


def write_prediction(prediction, out_dir, plot: bool = True, timeline: bool = True,
                     progress: Progress | None = None) -> list[Path]:
    """``timeline.csv`` (unless ``timeline`` is false), ``demand.csv``, ``summary.json``
    and ``demand.png`` of a :class:`~plcpred.air.Prediction` in ``out_dir``; the time
    each took goes to its ``stage_s``; ``progress`` shows which is being written."""
    p = prediction
    progress = progress_or_off(progress)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    files = []
    if timeline:
        progress.stage(f"writing timeline.csv ({p.timeline.n_changes:,} rows)")
        p.timeline.to_csv(out / "timeline.csv")
        files.append(out / "timeline.csv")
    progress.stage(f"writing demand.csv ({p.profile.n_cells:,} rows)")
    write_demand_csv(p.profile, out / "demand.csv", shown=p.shown)
    write_summary(p.profile, out / "summary.json", {
        "machine": p.machine.name, "supply_bar_g": p.machine.supply_bar_g})
    p.stage_s["write_csv"] = time.perf_counter() - t0
    files += [out / "demand.csv", out / "summary.json"]
    if plot:
        progress.stage("drawing demand.png")
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


def write_demand_csv(profile, path, shown: int | None = SHOWN_CONSUMERS,
                 values_per_write: int = 1_000_000) -> None:
    """``demand.csv``: ``time_s,total_l_min,<consumer>_l_min...`` (with more than
    ``shown + 1`` consumers, the ``shown`` largest and ``other_l_min``); each row is
    the mean flow over the cell starting at ``time_s``. Written in stretches of the
    grid, so memory does not grow with the horizon."""
    groups = profile.groups(shown)
    cells_of = [profile.cells_of(idx) for _, idx in groups]   # every consumer is in one
    header = "time_s,total_l_min," + ",".join(
        ("other" if len(idx) > 1 else csv_column_name(label)) + "_l_min" for label, idx in groups)
    rows = max(1000, values_per_write // (len(groups) + 2))
    per_min = 60.0 / profile.dt_s
    dt_ns = round(profile.dt_s * NS)
    with atomic_writer(path) as f:
        f.write(header + "\n")
        for a in range(0, profile.n_cells, rows):
            e = profile.edges_s[a:min(profile.n_cells, a + rows) + 1]
            cols = [cells(e) * per_min for cells in cells_of]
            flows = np.column_stack([np.sum(cols, axis=0) if cols else
                                     np.zeros(len(e) - 1)] + cols)
            f.write(csv_rows(a, dt_ns, flows))


def write_summary(profile, path, extra: dict | None = None) -> None:
    """``summary.json``: the profile's summary with the 1-minute peak the console
    prints (what a compressor's control sees), and ``extra`` keys."""
    data = {}
    for key, value in profile.summary().items():
        data[key] = value
        if key == "peak_1s_l_min":
            data["peak_1min_l_min"] = profile.peak_l_min(60.0)
    if extra:
        data.update(extra)
    write_json(path, data)


def csv_rows(first_cell: int, dt_ns: int, flows: np.ndarray) -> str:
    """``time,flow,flow...`` lines of cells ``first_cell, first_cell + 1, ...`` of
    ``dt_ns``, flows to 6 decimals. A machine's demand takes few distinct rows (a cycle's
    worth, the idle row), so each distinct row is formatted once and the lines are put
    together from it and the time (exact decimal seconds, from integer nanoseconds)."""
    micro = np.rint(flows * 1e6).astype(np.int64)       # what %.6f prints, as integers
    # distinct rows through a hash of each row (checked: a collision falls back to sorting
    # the rows themselves)
    weights = np.random.default_rng(0).integers(1, 2**62, micro.shape[1]) | 1
    key = micro @ weights
    _, first, which = np.unique(key, return_index=True, return_inverse=True)
    distinct = micro[first]
    if not np.array_equal(distinct[which.ravel()], micro):
        distinct, which = np.unique(micro, axis=0, return_inverse=True)
    texts = [",".join([f"{x / 1e6:.6f}" for x in row]) for row in distinct.tolist()]
    whole, frac_k, frac_texts = seconds_texts(
        (first_cell + np.arange(len(micro), dtype=np.int64)) * dt_ns)
    return "".join([f"{w}{frac_texts[f]},{texts[k]}\n" for w, f, k in zip(
        whole, frac_k, which.ravel().tolist())])


def write_measured(emulation, path) -> None:
    """``measured.csv``: the emulated meter's log, as ``diagnose --measured`` reads it."""
    em = emulation
    with atomic_writer(path) as f:
        f.write("time_s,flow_l_min,supply_bar_g\n")
        write_rows(f, np.column_stack([em.measured_time_s, em.measured_flow_l_min,
                                       em.measured_supply_bar_g]), "%.4f")


ROWS_PER_WRITE = 4096


def write_rows(f, rows: np.ndarray, fmt: str) -> None:
    """``np.savetxt(f, rows, fmt=fmt, delimiter=",")``, the same bytes, a block of
    rows formatted at once rather than row by row (a third less time: an emulation's
    plant.csv is 60,000 rows of 17 numbers, a third of a short emulation's time)."""
    if rows.ndim != 2 or not rows.shape[1]:
        np.savetxt(f, rows, fmt=fmt, delimiter=",")
        return
    row = ",".join([fmt] * rows.shape[1]) + "\n"
    for k in range(0, len(rows), ROWS_PER_WRITE):
        block = rows[k:k + ROWS_PER_WRITE]
        f.write((row * len(block)) % tuple(block.ravel().tolist()))


def write_plant(emulation, path, table=None) -> None:
    """``plant.csv``; ``table`` is the emulation's :meth:`plant_table` already made."""
    header, rows = table or emulation.plant_table()
    with atomic_writer(path) as f:
        f.write(",".join(csv_column_name(h) for h in header) + "\n")
        write_rows(f, rows, "%.6g")


def write_emulation(emulation, directory, plot: bool = True,
                    progress: Progress | None = None, predicted=None) -> list[Path]:
    """``measured.csv``, ``timeline.csv``, ``plant.csv`` and ``emulate.png`` of an
    :class:`~plcpred.plant.Emulation` in ``directory``; ``progress`` shows which is
    being written; ``predicted`` (the prediction's DemandProfile of the same horizon)
    is drawn with it."""
    progress = progress_or_off(progress)
    directory = Path(directory)
    files = [directory / "measured.csv", directory / "timeline.csv",
             directory / "plant.csv"]
    progress.stage("writing measured.csv and timeline.csv")
    write_measured(emulation, files[0])
    emulation.timeline.to_csv(files[1])
    progress.stage("sampling the plant into plant.csv")
    table = emulation.plant_table()     # sampling the plant: once for the file and the plot
    write_plant(emulation, files[2], table)
    if plot:
        progress.stage("drawing emulate.png")
        files.append(directory / "emulate.png")
        plot_emulation(emulation, files[-1], table, predicted=predicted)
    return files
