"""Plots and tables for people: the demand plot of ``plcpred predict`` and the printed
per-consumer table."""
from __future__ import annotations

import base64
import datetime
import html
import io
import os
import re
import tempfile
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import __version__
from ..air.cycles import arrival_period_s, cycles_of
from ..air.sizing import (
    DEFAULT_PRICE,
    production_hours,
    receiver_deficit,
    specific_energy_kwh_per_nm3,
)
from ..diagnose.io import TIME_OF_DAY_FORMATS
from ..machine import HOURS_PER_YEAR
from ..output import SHOWN_CONSUMERS, atomic_write_text, write_json

# a plotted point per pixel column of the 11-inch, 110 dpi figures (more are not seen,
# and drawing a stacked layer costs per point)
MAX_POINTS = 1200
MAX_CYCLES_DRAWN = 150    # more cycles than this on a time axis are drawn per bin


def _bin_width(n: int) -> int:
    """Cells per plotted point, so a plot has at most MAX_POINTS of them (a day at 10 ms
    would otherwise be 8.6 million points per layer)."""
    return max(1, int(np.ceil(n / MAX_POINTS)))


def _bins(values, k: int, reduce=np.mean):
    """``values`` reduced over groups of ``k`` cells along the last axis (the last group
    may be shorter)."""
    values = np.asarray(values)
    n = values.shape[-1]
    m = n // k * k
    if k == 1 or not m:
        return values
    head = reduce(values[..., :m].reshape(*values.shape[:-1], -1, k), axis=-1)
    if m == n:
        return head
    tail = reduce(values[..., m:], axis=-1)[..., None]
    return np.concatenate([head, tail], axis=-1)


def whole_periods(k: int, period_s: float | None, dt_s: float, n_cells: int) -> int:
    """Cells per plotted bin for a repeating machine: whole periods when the horizon
    holds too many cycles to draw one by one (bins that cut cycles in drifting places
    draw a moire of stripes; bins of whole cycles all average the same air), else ``k``."""
    if not period_s:
        return k
    per = max(1, round(period_s / dt_s))
    if n_cells / per <= MAX_CYCLES_DRAWN:
        return k
    return max(1, int(np.ceil(k / per))) * per


def _time_axis(horizon_s: float) -> tuple[float, str]:
    """(factor from seconds, unit) for a time axis over ``horizon_s``."""
    if horizon_s >= 7200:
        return 1 / 3600, "h"
    if horizon_s >= 600:
        return 1 / 60, "min"
    return 1.0, "s"


def _plain(text: str) -> str:
    """User text (machine and consumer names) for matplotlib, which would read ``$...$``
    as mathematics and fail on anything it cannot typeset."""
    return str(text).replace("\\", "\\\\").replace("$", r"\$")


def _cell(text: str) -> str:
    """User text for a Markdown table cell."""
    return str(text).replace("|", r"\|").replace("\n", " ")


def pyplot():
    """matplotlib's pyplot on the file-only Agg backend."""
    # matplotlib costs half a second to import: only a run that plots pays it
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def plot_demand(profile, path, title="Air demand", shown: int | None = SHOWN_CONSUMERS,
                cycle_s: float | None = None) -> None:
    """Stacked flow per consumer (the ``shown`` largest and "other" on a wide machine,
    see :meth:`DemandProfile.groups`) against time with the cumulative normal litres on
    a second axis; written through a temporary file. Over many cycles the bins are
    whole cycles: the run's period, or ``cycle_s`` for a run that does not repeat."""
    plt = pyplot()

    k = whole_periods(_bin_width(profile.n_cells),
                       getattr(profile, "period_s", None) or cycle_s,
                       profile.dt_s, profile.n_cells)
    bin_edges = profile.edges_s[::k]
    if bin_edges[-1] < profile.edges_s[-1]:
        bin_edges = np.append(bin_edges, profile.edges_s[-1])
    t = bin_edges[:-1]
    scale, unit = _time_axis(profile.horizon_s)
    fig, ax = plt.subplots(figsize=(11, 5.5), dpi=110)
    layers, flows = _layers(profile, shown, bin_edges)
    labels = [f"{_plain(label)} ({nl:.1f} NL)" for label, idx, nl in layers]
    if layers:
        cycle = [c["color"] for c in plt.rcParams["axes.prop_cycle"]]
        # the rest of a wide machine in grey, so it does not pass for one consumer
        colors = [("#a0a0a0" if len(idx) > 1 else cycle[n % len(cycle)])
                  for n, (_, idx, _) in enumerate(layers)]
        ax.stackplot(t * scale, flows, labels=labels, colors=colors, step="post", alpha=0.85)
    else:
        ax.text(0.5, 0.5, "the machine file has no consumers", transform=ax.transAxes,
                ha="center")
    ax.set_xlabel(f"time ({unit})")
    ax.set_ylabel("flow (NL/min)")
    ax.set_xlim(0, profile.horizon_s * scale)
    ax.set_ylim(bottom=0)
    ax.grid(True, alpha=0.3)
    avg = f", averaged over {profile.dt_s * k:g} s bins" if k > 1 else ""
    ax.set_title(f"{_plain(title)}\nmean {profile.mean_l_min:.1f} NL/min, peak "
                 f"{profile.peak_l_min():.1f} NL/min (instantaneous; grid "
                 f"{profile.dt_s:g} s{avg}), total {profile.total_nl:.1f} NL", fontsize=10)
    ax2 = ax.twinx()
    # the layers hold every consumer once: their bins add up to the cumulative (without
    # merging all the rectangles again, which a week that never repeats makes costly)
    cumulative_nl = np.concatenate([[0.0], np.cumsum(
        flows.sum(axis=0) * np.diff(bin_edges) / 60.0 if layers else np.zeros(len(t)))])
    ax2.plot(bin_edges * scale, cumulative_nl, color="black", lw=1.4,
             label="cumulative NL")
    ax2.set_ylabel("cumulative (NL)")
    ax2.set_ylim(bottom=0)
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = ax2.get_legend_handles_labels()
    ax.legend(h1[::-1] + h2, l1[::-1] + l2, loc="upper left", fontsize=8, framealpha=0.9)
    fig.tight_layout()
    save_fig(fig, path)


def _layers(profile, shown: int | None, edges_s):
    """The stacked layers of a demand plot on bins ``edges_s``: [(label, consumer
    indices, NL over the horizon)] (the ``shown`` largest and "other", leaks first, as
    the base layer they are, then the largest users) and their flows (NL/min), one row
    per layer, each layer's air integrated straight onto the bins (exact, as the grid
    is)."""
    groups = profile.groups(shown)
    nl = [float(profile.consumer_nl[idx].sum()) for _, idx in groups]
    order = sorted(range(len(groups)), key=lambda g: (
        not all(profile.roles[i] == "leak" for i in groups[g][1]), -nl[g]))
    layers = [(groups[g][0], groups[g][1], nl[g]) for g in order]
    widths = np.diff(edges_s)
    flows = np.array([profile.cells_nl(idx, edges_s) / widths * 60.0
                      for _, idx, _ in layers])
    return layers, flows


def consumer_table(profile, shown: int | None = SHOWN_CONSUMERS) -> str:
    """The per-consumer table ``plcpred predict`` prints (on a wide machine the ``shown``
    largest users and a row for the rest, :meth:`DemandProfile.groups`)."""
    rows = [("consumer", "kind", "strokes", "active NL", "passive NL", "total NL", "share")]
    total = profile.total_nl or 1.0
    active, passive = profile.active_nl, profile.passive_nl
    for label, idx in profile.groups(shown):
        i = idx[0]
        st = profile.strokes.get(label) if len(idx) == 1 else None
        part = float(profile.consumer_nl[idx].sum())
        rows.append((label, profile.roles[i] if len(idx) == 1 else "",
                     f"{st[0]}+{st[1]}" if st else "", f"{active[idx].sum():.2f}",
                     f"{passive[idx].sum():.2f}", f"{part:.2f}", f"{100 * part / total:.1f} %"))
    split = profile.by_role_nl()
    rows.append(("total", "", "", f"{split['active']:.2f}",
                 f"{split['passive'] + split['leak']:.2f}", f"{profile.total_nl:.2f}",
                 "100.0 %"))
    widths = [max(len(r[c]) for r in rows) for c in range(len(rows[0]))]
    lines = []
    for k, r in enumerate(rows):
        cells = [r[0].ljust(widths[0]), r[1].ljust(widths[1])] + [
            r[c].rjust(widths[c]) for c in range(2, len(r))]
        lines.append("  ".join(cells).rstrip())
        if k == 0 or k == len(rows) - 2:
            lines.append("  ".join("-" * w for w in widths))
    return "\n".join(lines)


# ---------------------------------------------------------------------- sizing report

def save_fig(fig, path) -> None:
    plt = pyplot()

    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".png")
    os.close(fd)
    try:
        fig.savefig(tmp, format="png")
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    finally:
        plt.close(fig)
        if os.path.exists(tmp):
            os.unlink(tmp)


def _cycle_window(profile, sizing) -> tuple[float, float, str]:
    """(start s, end s, label) of the stretch the sizing plot shows at full resolution:
    the last whole steady cycle where the machine has one (a steady cycle is like every
    other), or the first minute."""
    if sizing.cycle_s:
        c = float(sizing.cycle_s)
        n = int(profile.horizon_s // c)
        if n >= 1:
            start = min(max(0.0, (n - 1) * c), profile.horizon_s - c)
            return start, start + c, f"one steady cycle ({c:.3g} s, {sizing.cycle_source})"
    end = min(profile.horizon_s, 60.0)
    return 0.0, end, f"the first {end:g} s"


def plot_sizing(profile, sizing, path, title="Sizing") -> None:
    """Four views of the total demand against the mean and the design flow: one cycle at
    the grid's full resolution, stacked by consumer (leaks as the base layer); the
    load-duration curve (the flow exceeded for a share of the time); the air of each
    cycle (or minute) over the horizon, which shows a machine that changes; how the
    receiver's largest deficit per cycle is spread, the largest (which sizes it)
    marked."""
    plt = pyplot()
    total = profile.total_flow_l_min
    _, _, deficit = receiver_deficit(total, profile.dt_s, sizing.design_flow_l_min)
    w = sizing_windows(profile, sizing, deficit)
    fig, axes = plt.subplots(2, 2, figsize=(12, 8), dpi=100,
                             gridspec_kw={"width_ratios": [3, 2], "height_ratios": [1, 1]})
    (ax_cycle, ax_ldc), (ax_trend, ax_def) = axes
    _draw_cycle(ax_cycle, profile, sizing, title)
    _draw_load_duration(ax_ldc, total, sizing)
    _draw_air_per_window(ax_trend, profile, sizing, w)
    _draw_deficits(ax_def, sizing, w)
    fig.tight_layout()
    save_fig(fig, path)


@dataclass
class SizingWindows:
    """The horizon cut into windows of one steady cycle (else of a minute, or a
    twentieth of a short horizon) from 0: each one's start, air (NL, exact: they add
    up to the horizon's total), whether it is whole (the last may be cut by the
    horizon) and the receiver's largest deficit over the design flow in it (NL)."""
    what: str                       # "cycle", "minute" or "window"
    width_s: float
    start_s: np.ndarray
    nl: np.ndarray
    whole: np.ndarray
    deficit_nl: np.ndarray


def sizing_windows(profile, sizing, deficit) -> SizingWindows:
    """:class:`SizingWindows` of a profile, ``deficit`` the receiver's deficit at the
    end of each grid cell (:func:`~plcpred.air.sizing.receiver_deficit`)."""
    horizon = profile.horizon_s
    if sizing.cycle_s and sizing.cycle_s < horizon:
        width, what = float(sizing.cycle_s), "cycle"
    elif horizon >= 600:
        width, what = 60.0, "minute"
    else:
        width, what = max(profile.dt_s, horizon / 20), "window"
    edges = np.append(np.arange(0.0, horizon - 1e-9 * horizon, width), horizon)
    nl = np.diff(profile.cumulative_nl_at(edges))
    whole = np.diff(edges) >= width * (1 - 1e-6)
    # each window's cells: those whose end lies in it (the deficit is at cell ends)
    cell_end = profile.edges_s[1:]
    first = np.minimum(np.searchsorted(cell_end, edges[:-1], side="right"),
                       len(deficit) - 1)
    deficit_nl = np.maximum.reduceat(np.asarray(deficit, dtype=float), first)
    return SizingWindows(what, width, edges[:-1], nl, whole, deficit_nl)


def _noun(w: SizingWindows, plural: bool = False) -> str:
    """What a window is, for labels: "cycle", "minute", "window of 1 s"."""
    s = "s" if plural else ""
    return f"window{s} of {w.width_s:.3g} s" if w.what == "window" else w.what + s


def window_layers(profile, w: SizingWindows, k: int):
    """The whole windows in groups of ``k``: the groups' edges (s), the layers of
    :func:`_layers` and each layer's mean air per window in each group (NL; for windows
    that are not cycles its mean flow, NL/min), one row per layer."""
    n = int(w.whole.sum())
    edges = np.append(w.start_s[:n], w.start_s[n - 1] + w.width_s if n else 0.0)
    groups = edges[::k]
    if groups[-1] < edges[-1]:
        groups = np.append(groups, edges[-1])
    layers, flows = _layers(profile, SHOWN_CONSUMERS, groups)
    return groups, layers, (flows * w.width_s / 60.0 if w.what == "cycle" else flows)


def _draw_air_per_window(ax, profile, sizing, w: SizingWindows) -> None:
    """The air of each whole window over the horizon, stacked by consumer (in groups of
    windows, their mean, and the band of the windows' least and greatest total, where
    there are more windows than pixels)."""
    scale, unit = _time_axis(profile.horizon_s)
    per_cycle = w.what == "cycle"
    values = w.nl[w.whole] if per_cycle else w.nl[w.whole] / w.width_s * 60.0
    ax.set_xlim(0, profile.horizon_s * scale)
    ax.set_xlabel(f"time ({unit})")
    ax.set_ylabel("air per cycle (NL)" if per_cycle else "mean flow (NL/min)")
    ax.grid(True, alpha=0.3)
    if not len(values):
        return
    k = _bin_width(len(values))
    groups, layers, stacks = window_layers(profile, w, k)
    if layers:
        ax.stackplot(groups * scale, np.column_stack([stacks, stacks[:, -1:]]), step="post",
                     alpha=0.85, labels=[_plain(label) for label, _, _ in layers])
    if k > 1:
        env = envelope(w.start_s[w.whole], values, k)
        ax.fill_between(env.t_s * scale, env.lo, env.hi, step="post", color="black",
                        alpha=0.15, lw=0, label=f"least to greatest of {k} "
                        f"{_noun(w, plural=True)}")
    if per_cycle and sizing.nl_per_cycle:
        ax.axhline(sizing.nl_per_cycle, color="black", ls="--", lw=0.8,
                   label=f"steady {sizing.nl_per_cycle:.3f} NL per cycle")
    elif not per_cycle:
        ax.axhline(sizing.mean_l_min, color="black", ls="--", lw=1,
                   label=f"mean {sizing.mean_l_min:.1f} NL/min")
    spread = (values.max() - values.min()) / max(abs(values.mean()), 1e-12)
    ax.set_title(f"each {_noun(w)} over the horizon: {len(values)} whole, they differ by "
                 f"{100 * spread:.1f} % ({values.min():.3g} to {values.max():.3g})",
                 fontsize=10)
    ax.set_ylim(0, values.max() * 1.3 if values.max() > 0 else 1)
    h, lab = ax.get_legend_handles_labels()
    ax.legend(h[::-1], lab[::-1], loc="upper right", fontsize=7, framealpha=0.9,
              ncol=2)


def _draw_deficits(ax, sizing, w: SizingWindows) -> None:
    """How many windows reach each largest deficit, the horizon's largest marked."""
    d = w.deficit_nl
    top = max(float(d.max()) if len(d) else 0.0, sizing.deficit_nl, 1e-9)
    # from 0, so cycles that all reach the same deficit read as one bar at its size
    ax.hist(d, bins=np.linspace(0.0, top * 1.05, 43), color="#fdae6b", edgecolor="#e6550d",
            lw=0.5, label=f"{len(d)} {_noun(w, plural=True)}")
    ax.set_xlim(0, top * 1.1)
    ax.axvline(sizing.deficit_nl, color="#d62728", lw=1.3,
               label=f"largest {sizing.deficit_nl:.3g} NL at {sizing.deficit_at_s:g} s")
    ax.set_xlabel(f"largest deficit over the design flow in a {_noun(w)} (NL)")
    ax.set_ylabel(_noun(w, plural=True))
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper left", fontsize=8)
    ax.set_title(f"receiver {sizing.receiver_l:.1f} L for {sizing.band_bar:g} bar covers "
                 f"the largest", fontsize=10)


def _levels(ax, sizing) -> None:
    """The mean and the design flow as lines across a flow axis."""
    design = sizing.design_flow_l_min
    ax.axhline(sizing.mean_l_min, color="black", ls="--", lw=1,
               label=f"mean {sizing.mean_l_min:.1f} NL/min")
    ax.axhline(design, color="#d62728", lw=1.3, label=f"design flow {design:.1f} NL/min")
    ax.set_ylim(bottom=0)
    ax.grid(True, alpha=0.3)


def _draw_cycle(ax, profile, sizing, title) -> None:
    """One cycle at full resolution, by consumer."""
    a, b, what = _cycle_window(profile, sizing)
    edges = profile.edges_s[(profile.edges_s >= a - 1e-9) & (profile.edges_s <= b + 1e-9)]
    if len(edges) >= 2:
        layers, flows = _layers(profile, SHOWN_CONSUMERS, edges)
        if layers:
            ax.stackplot(edges[:-1] - a, flows, step="post", alpha=0.85,
                         labels=[_plain(label) for label, _, _ in layers])
    _levels(ax, sizing)
    ax.set_xlim(0, b - a)
    ax.set_xlabel(f"time in the window (s; it starts at {a:g} s)")
    ax.set_ylabel("flow (NL/min)")
    ax.set_title(f"{_plain(title)}\n{what}, grid {profile.dt_s:g} s", fontsize=10)
    h, lab = ax.get_legend_handles_labels()
    ax.legend(h[::-1], lab[::-1], loc="upper right", fontsize=7, framealpha=0.9)


def _draw_load_duration(ax, total, sizing) -> None:
    ordered = np.sort(total)[::-1]
    share = (np.arange(len(ordered)) + 0.5) / max(len(ordered), 1) * 100.0
    ax.step(share, ordered, where="mid", color="#3182bd", lw=1.2, label="demand")
    _levels(ax, sizing)
    ax.set_xlim(0, 100)
    ax.set_xlabel("share of the time the flow is at least this (%)")
    ax.set_ylabel("flow (NL/min)")
    ax.set_title("load-duration curve", fontsize=10)
    ax.legend(loc="upper right", fontsize=8)


def sizing_assumptions(machine, s, today=None) -> list[tuple[str, str]]:
    """What a sizing rests on, for the report's assumptions table: the files, pressures,
    reference condition, consumers, horizon, allowances, hours, energy and price, the
    tool's version and the date."""

    kinds = Counter(c.kind for c in machine.consumers)
    sec_how = s.sec_basis
    money = f" {s.currency}" if s.currency else ""
    def shown(path) -> str:
        try:
            return os.path.relpath(path)
        except ValueError:          # another drive (Windows)
            return str(path)

    return [
        ("machine file", shown(machine.path)),
        ("program", shown(machine.program_path)),
        ("supply pressure", (f"{machine.supply_bar_g:g} bar(g), atmosphere "
                            f"{machine.atmosphere_kpa:g} kPa")),
        ("reference condition", "ISO 8778 (100 kPa, 20 °C)"),
        ("consumers", ", ".join(f"{n} {k}" for k, n in sorted(kinds.items())) or "none"),
        ("horizon, grid", f"{s.horizon_s:g} s, {s.dt_s:g} s"),
        ("design flow allowance, receiver band",
         f"{100 * s.allowance:g} % over the mean, {s.band_bar:g} bar"),
        ("operating hours per year", f"{s.hours_per_year:g} h" + (
            f" (the [calendar]: {_calendar_text(machine.calendar)})"
            if machine.calendar is not None else "")),
        ("specific energy", f"{s.sec_kwh_per_nm3:.4g} kWh/Nm³, {sec_how}"),
        ("energy price", f"{s.price_per_kwh:g}{money} per kWh"),
        ("tool", f"plcpred {__version__}, {(today or datetime.date.today()).isoformat()}"),
    ]


def _calendar_text(c) -> str:
    idle = ("leaks and the blowers the program leaves on" if c.idle_state == "program"
            else "leaks only")
    return (f"{c.shifts_per_day:g} x {c.hours_per_shift:g} h shifts, {c.days_per_week:g} "
            f"days a week, {c.weeks_per_year:g} weeks, {100 * c.production_share:g} % "
            f"producing; standing: {idle}, supply on all year")


def sizing_markdown(machine_name: str, s, profile, plots=("sizing.png", "demand.png"),
                    assumptions=()) -> str:
    def pct(x):
        return f"{100 * x:.1f} %"
    total = s.total_nl or 1.0
    money = f" {_cell(s.currency)}" if s.currency else ""
    lines = [
        f"# Compressed-air sizing: {machine_name}",
        "",
        (f"Horizon {s.horizon_s:g} s, grid {s.dt_s:g} s. Flows in NL/min at the ISO 8778 "
        "reference condition (100 kPa, 20 °C)."),
        "",
        "| quantity | value |",
        "|---|---|",
        f"| mean demand | {s.mean_l_min:.1f} NL/min |",
        f"| peak (instantaneous) | {s.peak_l_min:.1f} NL/min |",
        f"| peak over 1 s | {s.peak_1s_l_min:.1f} NL/min |",
        f"| peak over 1 min | {s.peak_1min_l_min:.1f} NL/min |",
        f"| 95th percentile (grid) | {s.p95_l_min:.1f} NL/min |",
        (f"| **compressor design flow** (mean + {pct(s.allowance)}) | "
        f"**{s.design_flow_l_min:.1f} NL/min** ({s.design_flow_l_min * 0.06:.2f} Nm³/h) |"),
        (f"| largest deficit over the design flow | {s.deficit_nl:.2f} NL at "
        f"{s.deficit_at_s:g} s |"),
        f"| **receiver** for a {s.band_bar:g} bar band | **{s.receiver_l:.1f} L** |",
        (f"| energy per year ({s.hours_per_year:g} h, {s.sec_kwh_per_nm3:.3g} kWh/Nm³) | "
         f"{s.energy_kwh_per_year:,.0f} kWh |" if not s.idle_hours_per_year else
         f"| energy per year ({s.hours_per_year:,.0f} h producing, "
         f"{s.idle_hours_per_year:,.0f} h standing at {s.idle_flow_l_min:.1f} NL/min; "
         f"{s.air_nm3_per_year:,.0f} Nm³ at {s.sec_kwh_per_nm3:.3g} kWh/Nm³) | "
         f"{s.energy_kwh_per_year:,.0f} kWh |"),
        (f"| cost per year (at {s.price_per_kwh:g}{money} per kWh) | "
        f"{s.cost_per_year:,.0f}{money} |"),
        f"| steady cycle | {s.cycle_s:.3g} s ({s.cycles_per_hour:.4g} per hour, by "
        f"{_cell(s.cycle_source)}) |" if s.cycle_s is not None else
        "| steady cycle | none found (no cycle_signal, no repeating state) |",
        f"| air per cycle | {s.nl_per_cycle:.3f} NL |" if s.cycle_s is not None else
        f"| air over the horizon | {s.total_nl:.2f} NL |",
        "",
        *[f"**Warning**: {_cell(w)}\n" for w in s.warnings],
        "| air | NL | share |",
        "|---|---|---|",
        (f"| active (cylinders, drives, grippers) | {s.active_nl:.2f} | "
        f"{pct(s.active_nl / total)} |"),
        f"| passive (nozzles, air knives) | {s.passive_nl:.2f} | {pct(s.passive_nl / total)} |",
        f"| leaks | {s.leak_nl:.2f} | {pct(s.leak_nl / total)} |",
        (f"| **while idle** (waiting: no cylinder moving, outputs as it waits) | "
        f"{s.idle_nl:.2f} | **{pct(s.idle_share)}** |"),
        f"| of it leaks | {s.idle_leak_nl:.2f} | {pct(s.idle_leak_nl / total)} |",
        (f"| of it nozzles and blowers left on | {s.idle_blowers_nl:.2f} | "
        f"{pct(s.idle_blowers_nl / total)} |"),
        "",
        ("A published industrial case study (an automated assembly module, 20 h of flow "
        "logging) found about a third of machine air non-productive (leaks 21 %, uncontrolled blowers 13 %); best practice keeps "
        "leakage below 10 % of production."),
        "",
        "| consumer | role | total NL | share |",
        "|---|---|---|---|",
    ]
    for i, name in enumerate(profile.names):
        lines.append(f"| {_cell(name)} | {profile.roles[i]} | {profile.consumer_nl[i]:.2f} | "
                     f"{pct(profile.consumer_nl[i] / total)} |")
    lines.append("")
    if assumptions:
        lines += ["| assumption | value |", "|---|---|"]
        lines += [f"| {_cell(k)} | {_cell(v)} |" for k, v in assumptions]
        lines.append("")
    for p in plots:
        lines.append(f"![{p}]({p})")
    lines.append("")
    return "\n".join(lines)


def sizing_html(markdown_text: str, images: dict) -> str:
    """A self-contained HTML page from the report's Markdown (tables, headings, bold,
    images embedded as data URIs)."""

    def inline(text):
        text = html.escape(text)
        return re.sub(r"\*\*(.+?)\*\*", r"<strong>\1</strong>", text)

    out = ["<!DOCTYPE html><html><head><meta charset='utf-8'><title>Sizing</title>",
           ("<style>body{font-family:sans-serif;max-width:980px;margin:2em auto;color:#222}"
           "table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #ccc;"
           "padding:4px 10px;text-align:left}th{background:#f3f3f3}img{max-width:100%}"
           "</style></head><body>")]
    rows = []

    def flush():
        if rows:
            out.append("<table>")
            for k, r in enumerate(rows):
                tag = "th" if k == 0 else "td"
                out.append("<tr>" + "".join(f"<{tag}>{inline(c)}</{tag}>" for c in r) +
                           "</tr>")
            out.append("</table>")
            rows.clear()
    for line in markdown_text.splitlines():
        if line.startswith("|"):
            cells = [c.strip() for c in line.strip("|").split("|")]
            if not all(set(c) <= {"-", ":"} for c in cells):
                rows.append(cells)
            continue
        flush()
        m = re.match(r"!\[(.*?)\]\((.*?)\)", line)
        if m:
            data = images.get(m.group(2))
            if data is not None:
                b64 = base64.b64encode(data).decode()
                out.append(f"<p><img alt='{html.escape(m.group(1))}' "
                           f"src='data:image/png;base64,{b64}'></p>")
        elif line.startswith("# "):
            out.append(f"<h1>{inline(line[2:])}</h1>")
        elif line.strip():
            out.append(f"<p>{inline(line)}</p>")
    flush()
    out.append("</body></html>")
    return "\n".join(out)


def write_sizing_report(result, sizing, out_dir) -> list[Path]:
    """``sizing.json``, ``sizing.md``, ``sizing.html`` (plots embedded) and the two plots
    they show, for a :class:`~plcpred.air.Prediction` and its
    :class:`~plcpred.air.sizing.Sizing`."""

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    name = result.machine.name
    data = {"machine": name, **sizing.to_dict(),
            "consumers": result.profile.summary()["consumers"]}
    write_json(out / "sizing.json", data)
    plot_sizing(result.profile, sizing, out / "sizing.png",
                title=f"{name}: demand and compressor design flow")
    plot_demand(result.profile, out / "demand.png", title=f"{name}: air demand",
                shown=result.shown, cycle_s=arrival_period_s(result.machine, result.timeline))
    md = sizing_markdown(name, sizing, result.profile,
                         assumptions=sizing_assumptions(result.machine, sizing))
    atomic_write_text(out / "sizing.md", md)
    images = {p: (out / p).read_bytes() for p in ("sizing.png", "demand.png")}
    atomic_write_text(out / "sizing.html", sizing_html(md, images))
    return [out / "sizing.json", out / "sizing.md", out / "sizing.html", out / "sizing.png",
            out / "demand.png"]


# ---------------------------------------------------------------------- diagnosis report

SIGN_NOTE = ("gap and residual = measured - predicted: positive where the machine draws "
             "more air than its file predicts")


def logger_axis(rd) -> tuple[np.ndarray, float, str]:
    """(the run's reading ends on the logger's clock, the origin subtracted from the
    clock's readings, the axis label): seconds as the log's time column has them, or,
    for a log stamped with dates or times of day, seconds after its first reading (a
    clock of 1.7e9 s says nothing to a reader)."""
    t = np.asarray(rd.end_s, dtype=float) + rd.offset_s
    source = rd.run.source
    fmt = source.get("time_format", "seconds")
    col = source.get("time_column", "time")
    if fmt == "seconds" or not len(t):
        return t, 0.0, f"the logger's clock: its '{col}' column (s)"
    origin = float(np.floor(t[0] - rd.weight_s[0]))
    try:
        at = datetime.datetime(1970, 1, 1) + datetime.timedelta(seconds=origin)
        day = "" if fmt in TIME_OF_DAY_FORMATS else "%Y-%m-%d "
        text = at.strftime(day + "%H:%M:%S")
    except (OverflowError, ValueError):
        text = f"{origin:g} s"
    return t - origin, origin, f"the logger's clock: s after {text} (its '{col}' column)"


def _draw_readings(ax, d, rd, base, fixed, corrected_label) -> None:
    """A run's meter readings, measured, predicted and corrected, on the logger's clock,
    the located gap's windows shaded; each reading a step over its interval."""
    t, origin, label = logger_axis(rd)
    ax.step(t, rd.measured_l_min, where="pre", color="black", lw=1.0, label="measured")
    ax.step(t, rd.readings(base), where="pre", color="tab:blue", lw=1.0, label="predicted")
    if corrected_label:
        ax.step(t, rd.readings(fixed), where="pre", color="tab:red", lw=1.0, ls="--",
                label=_plain(corrected_label))
    named = {c.context for c in d.contexts if c.stands_out}
    shaded = False
    for loc in d.locations[:30]:
        if loc.get("run") == rd.run.name and loc["context"] in named:
            ax.axvspan(loc["start_s"] - origin, loc["end_s"] - origin, color="orange",
                       alpha=0.15, lw=0, label=None if shaded else "located gap")
            shaded = True
    ax.set_ylabel("flow (NL/min)")
    ax.set_xlabel(_plain(label))
    ax.set_ylim(bottom=0)
    ax.grid(True, alpha=0.3)
    ax.set_title(_plain(f"{rd.run.name}: meter readings"), fontsize=10)
    ax.legend(loc="upper right", fontsize=8)


def _draw_cumulative(ax, d, corrected_label) -> None:
    """Cumulative air of every run one after another: measured, predicted, corrected."""
    offset = 0.0
    for n, (rd, base, fixed) in enumerate(zip(d.runs, d.bases, d.best_params())):
        # from the first reading's start, at nothing drawn yet
        t = np.concatenate([[0.0], rd.end_s - rd.end_s[0] + rd.weight_s[0]]) + offset
        w = rd.weight_s / 60.0

        def cum(flow, w=w):
            return np.concatenate([[0.0], np.cumsum(flow * w)])
        first = n == 0
        ax.plot(t, cum(rd.measured_l_min), color="black", lw=1.0,
                label="measured" if first else None)
        ax.plot(t, cum(rd.readings(base)), color="tab:blue", lw=1.0,
                label="predicted" if first else None)
        if corrected_label:
            ax.plot(t, cum(rd.readings(fixed)), color="tab:red", lw=1.0, ls="--",
                    label=_plain(corrected_label) if first else None)
        offset = t[-1]
    ax.set_ylabel("cumulative air (NL)")
    ax.set_xlabel("logged time (s; runs one after another)")
    ax.grid(True, alpha=0.3)
    ax.set_title("cumulative air", fontsize=10)
    ax.legend(loc="upper left", fontsize=8)


def _draw_contexts(ax, d) -> None:
    """The residual per context (what the machine was doing), +/- 3 sigma of noise."""
    ctx = d.contexts[:12]
    ax.barh([_plain(c.context) for c in ctx][::-1], [c.residual_nl for c in ctx][::-1],
            xerr=[3 * c.uncertainty_nl for c in ctx][::-1],
            color=["tab:orange" if c.stands_out else "lightgray" for c in ctx][::-1])
    ax.axvline(0, color="black", lw=0.8)
    ax.grid(True, axis="x", alpha=0.3)
    ax.set_xlabel("residual (NL), measured - predicted; bars +/- 3 sigma of noise")
    ax.set_title("by what the machine was doing (orange: stands out of the noise)",
                 fontsize=10)


def _draw_attribution(ax, d) -> None:
    """The residual fitted to each consumer's own predicted air (and an always-on flow)."""
    rows = d.attribution[:8]
    if not rows:
        ax.text(0.5, 0.5, "no attribution by consumer", ha="center", transform=ax.transAxes)
        ax.set_axis_off()
        return
    ax.barh([_plain(a["consumer"]) for a in rows][::-1],
            [a["residual_nl"] for a in rows][::-1], color="tab:purple")
    ax.axvline(0, color="black", lw=0.8)
    ax.grid(True, axis="x", alpha=0.3)
    ax.set_xlabel("residual (NL), measured - predicted")
    ax.set_title("by consumer (fitted to each one's own predicted air)", fontsize=10)


def _corrected_label(d) -> str | None:
    return ("corrected (" + " + ".join(d.combination["effects"]) + ")"
            if d.combination else None)


def plot_diagnosis(d, path) -> None:
    """``diagnose.png``: per run, the measured, predicted and corrected meter readings
    on the logger's clock with the located windows shaded; the cumulative air; the
    residual (measured - predicted) per context and per consumer."""
    plt = pyplot()
    runs = d.runs
    fig = plt.figure(figsize=(11, 3.0 * (len(runs) + 2)), constrained_layout=True)
    grid = fig.add_gridspec(len(runs) + 2, 2)
    label = _corrected_label(d)
    for n, (rd, base, fixed) in enumerate(zip(runs, d.bases, d.best_params())):
        _draw_readings(fig.add_subplot(grid[n, :]), d, rd, base, fixed, label)
    _draw_cumulative(fig.add_subplot(grid[len(runs), :]), d, label)
    _draw_contexts(fig.add_subplot(grid[-1, 0]), d)
    _draw_attribution(fig.add_subplot(grid[-1, 1]), d)
    fig.suptitle(_plain(f"{d.machine.name}: verdict {d.verdict}; {SIGN_NOTE}"), fontsize=10)
    save_fig(fig, path)


def diagnosis_figures(d) -> dict[str, bytes]:
    """The report's pictures as PNG bytes: "where" (the residual by context and by
    consumer) and "readings" (each run on the logger's clock, the cumulative air)."""
    plt = pyplot()
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 0.45 * max(len(d.contexts[:12]),
                                                                len(d.attribution[:8]), 4)
                                                + 1.4), constrained_layout=True)
    _draw_contexts(a1, d)
    _draw_attribution(a2, d)
    out = {"where": _png_bytes(fig)}
    label = _corrected_label(d)
    fig, axes = plt.subplots(len(d.runs) + 1, 1, figsize=(11, 3.0 * (len(d.runs) + 1)),
                             constrained_layout=True, squeeze=False)
    for ax, rd, base, fixed in zip(axes[:, 0], d.runs, d.bases, d.best_params()):
        _draw_readings(ax, d, rd, base, fixed, label)
    _draw_cumulative(axes[-1, 0], d, label)
    out["readings"] = _png_bytes(fig)
    return out


def _png_bytes(fig) -> bytes:
    plt = pyplot()
    buf = io.BytesIO()
    try:
        fig.savefig(buf, format="png", dpi=90)
    finally:
        plt.close(fig)
    return buf.getvalue()


@dataclass
class GapCost:
    """What an extra flow costs a year if it goes on: the flow (NL/min), the hours it
    runs, the air (Nm³), the energy (kWh) and the cost at ``price`` per kWh."""
    flow_l_min: float
    hours: float
    hours_basis: str
    nm3: float
    sec_kwh_per_nm3: float
    kwh: float
    price: float
    cost: float


def gap_cost(machine, flow_l_min: float, always_on: bool) -> GapCost:
    """:class:`GapCost` of ``flow_l_min`` at the machine's supply pressure (E1), the
    default price of ``plcpred size``, over its production hours, or (``always_on``: a
    leak, which flows whenever the line is under pressure) the hours its [calendar]
    keeps the supply on."""
    hours = production_hours(machine, None)
    basis = (f"{hours:,.0f} h of production a year"
             + ("" if machine.calendar else " (plcpred size's default)"))
    if always_on and machine.calendar is not None:
        hours, basis = HOURS_PER_YEAR, "8,760 h a year (the supply stays on)"
    sec = specific_energy_kwh_per_nm3(machine.supply_bar_g, machine.atmosphere_kpa)
    nm3 = flow_l_min * 60.0 * hours / 1000.0
    kwh = nm3 * sec
    return GapCost(flow_l_min, hours, basis, nm3, sec, kwh, DEFAULT_PRICE,
                   kwh * DEFAULT_PRICE)


def _pct(x: float) -> str:
    """A share with its sign, never "-0.0"."""
    return f"{x + 0.0:+.1f}".replace("-0.0", "+0.0") + " %"


def _gap_share(score) -> float:
    """measured - predicted as a share of the measured air (the report's error_pct is
    predicted - measured)."""
    return -float(score.error_pct)


def _verdict_effect(d):
    return next((e for e in d.effects if e.name == d.verdict), None)


def _physical_text(physical, depth: int = 0) -> str:
    """Fitted physical values as "name=value" (per consumer where nested)."""
    if not isinstance(physical, dict):
        return f"{physical:.3g}" if isinstance(physical, (int, float, np.floating)) \
            else str(physical)
    parts = []
    for k, v in physical.items():
        if isinstance(v, dict) and depth == 0:
            parts.append(f"{k}: {_physical_text(v, 1)}")
        elif isinstance(v, (int, float, np.floating)):
            parts.append(f"{k}={float(v):.3g}")
        else:
            parts.append(f"{k}={v}")
    return ", ".join(parts)


def diagnosis_conclusion(d) -> tuple[str, GapCost | None]:
    """The report's first paragraph in plain words (plain text: the page escapes it),
    and what the extra air costs a year where the verdict is a fault."""
    b = d.baseline
    logged_s = float(sum(np.sum(rd.weight_s) for rd in d.runs)) or 1.0
    gap_nl = b.measured_nl - b.predicted_nl
    mean_gap = gap_nl / logged_s * 60.0
    more = "more" if gap_nl >= 0 else "less"
    text = (f"The meter reads {abs(gap_nl):.2f} NL {more} than the machine file predicts "
            f"({_pct(_gap_share(b))} of the measured {b.measured_nl:.2f} NL over "
            f"{logged_s:g} s logged, {mean_gap:+.1f} NL/min on average). ")
    e = _verdict_effect(d)
    cost = None
    if d.verdict == "none":
        return text + ("That is no fault: the gap lies within the meter's noise and the "
                       "model's own accuracy."), None
    if d.verdict == "unexplained" or e is None:
        where = ", ".join(c.context for c in d.contexts[:3] if c.stands_out) or "no one context"
        text += ("No effect the diagnosis knows explains it; it lies mostly in "
                 f"{where}. Look there on the machine.")
    elif e.name in ("leak", "leak_from"):
        flow = float(e.physical.get("flow_l_min", mean_gap))
        title = e.title.split(" (")[0]         # without "(beyond the plant)" and such
        text += f"The likely cause is {title} of about {flow:.1f} NL/min."
        cost = gap_cost(d.machine, flow, always_on=True)
    else:
        text += f"The likely cause is {e.title} ({_physical_text(e.physical)})."
        if mean_gap > 0:
            cost = gap_cost(d.machine, mean_gap, always_on=False)
    if cost is not None:
        text += (f" Left as it is, it costs about {cost.kwh:,.0f} kWh and {cost.cost:,.0f} "
                 f"a year at {cost.price:g} per kWh ({cost.nm3:,.0f} Nm³ of air).")
    return text, cost


def cost_basis(d, cost: GapCost) -> str:
    """What the yearly figures of the conclusion rest on."""
    return (f"The yearly figures: {cost.flow_l_min:.1f} NL/min over {cost.hours_basis}, "
            f"{cost.sec_kwh_per_nm3:.3g} kWh per Nm³ at {d.machine.supply_bar_g:g} bar(g) "
            f"(E1) and plcpred size's default price of {cost.price:g} per kWh (its --price "
            "and a [calendar] in the machine file set your own).")


def where_summary(d) -> str:
    """The "where" section's sentence: the contexts that stand out and the consumer the
    residual fits best."""
    total = d.baseline.measured_nl - d.baseline.predicted_nl
    out = [c for c in d.contexts if c.stands_out][:3]
    text = ("Most of the gap lies in " + ", ".join(
        f"{c.context} ({c.residual_nl:+.2f} NL, {100 * c.share:.0f} %)" for c in out) + "."
        if out else f"No context stands out of the noise (gap {total:+.2f} NL).")
    if d.attribution:
        a = d.attribution[0]
        how = (f"an always-on flow of {a['flow_l_min']:+.2f} NL/min"
               if a["consumer"] == "always on" else
               f"{a['consumer']} ({a['relative_pct']:+.0f} % of its predicted air)")
        text += f" By consumer, it fits best as {how}."
    return text


def how_sure_rows(d) -> list[tuple[str, str]]:
    """(what, value) rows of the report's "how sure" table, signs as measured -
    predicted."""
    bh = d.baseline_heldout
    rows = [("held-out samples", d.fold_kind),
            ("before: held-out gap, RMSE",
             f"{_pct(_gap_share(bh))} of the measured air, {bh.rmse_l_min:.2f} NL/min")]
    if d.combination:
        h = d.combination["heldout"]
        rows.append((f"after ({' + '.join(d.combination['effects'])}): held-out gap, RMSE",
                     f"{_pct(_gap_share(h))}, {h.rmse_l_min:.2f} NL/min"))
    rows.append(("meter noise; left beyond it after the fix",
                 f"{d.meter_noise_l_min:.2g} NL/min; {d.left_l_min:.2g} NL/min RMS"))
    if d.flexed is not None:
        lo, hi = d.band_pct
        # band_pct is predicted - measured, as the report's error: flipped and swapped
        rows.append(("a healthy machine's gap (the model's own accuracy)",
                     f"{_pct(-hi)} to {_pct(-lo)}"))
    if d.alternatives:
        rows.append(("as good on held-out samples (cannot be told apart)",
                     ", ".join(d.alternatives)))
    fit = d.combination["fit"] if d.combination else None
    if fit is not None:
        for name, value, se, unit in zip(fit.names, fit.theta, fit.stderr, fit.units):
            interval = (f" (95 %: {value - 1.96 * se:.3g} to {value + 1.96 * se:.3g})"
                        if se is not None and np.isfinite(se) else "")
            rows.append((f"fitted {name}", f"{value:.3g} {unit}{interval}".replace("  ", " ")))
    return rows


def diagnosis_html(d, png: bytes | None = None, figures: dict | None = None) -> str:
    """``diagnose.html``: a self-contained report, the conclusion first (what the gap is,
    its likely cause and what it costs), then where it lies, how sure the diagnosis is,
    and the printed report in full. ``png``: ``diagnose.png`` (every panel in one
    picture), offered at the end; ``figures``: :func:`diagnosis_figures` if made."""
    esc = html.escape
    figures = diagnosis_figures(d) if figures is None else figures
    conclusion, cost = diagnosis_conclusion(d)
    parts = [_DIAG_HEAD,
             f"<h1>{esc(d.machine.name)}: what the flow log says</h1>",
             f"<p class='conclusion'>{esc(conclusion)}</p>",
             ("<p>To carry it in predictions: <code>plcpred diagnose ... --write-machine "
              "FIXED.toml</code> writes the machine file with what was fitted.</p>"
              if d.combination else ""),
             f"<p class='note'>{esc(cost_basis(d, cost))}</p>" if cost else "",
             f"<p class='note'>On this page {esc(SIGN_NOTE)}.</p>",
             *[f"<p class='warn'>Warning: {esc(w)}</p>" for w in d.warnings],
             "<h2>Where the gap lies</h2>", f"<p>{esc(where_summary(d))}</p>",
             _img(figures.get("where"), "where the gap lies"),
             _img(figures.get("readings"), "meter readings on the logger's clock"),
             "<h2>How sure</h2>", "<table>",
             *[f"<tr><th>{esc(k)}</th><td>{esc(v)}</td></tr>" for k, v in how_sure_rows(d)],
             "</table>",
             "<h2>Details</h2>",
             ("<p class='note'>The report as <code>plcpred diagnose</code> prints it. Its "
              "<em>error</em> columns are predicted - measured (the opposite sign of the "
              "gap above); its residuals are measured - predicted.</p>"),
             (f"<details open><summary>full report</summary><pre>{esc(d.report())}</pre>"
              "</details>")]
    if png is not None:
        parts.append("<details><summary>every panel in one picture (diagnose.png)"
                     f"</summary>{_img(png, 'diagnose.png')}</details>")
    parts.append("</body></html>")
    return "\n".join(parts)


def _img(data: bytes | None, alt: str) -> str:
    if data is None:
        return ""
    return (f"<p><img alt='{html.escape(alt)}' src='data:image/png;base64,"
            f"{base64.b64encode(data).decode()}'></p>")


_DIAG_HEAD = (
    "<!DOCTYPE html><html><head><meta charset='utf-8'><title>Diagnosis</title><style>"
    "body{font-family:sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;"
    "color:#222;line-height:1.4}pre{background:#f6f6f6;padding:1em;overflow-x:auto;font-size:85%}"
    "img{max-width:100%}.conclusion{font-size:120%;background:#fff7e6;border-left:5px "
    "solid #f28e2b;padding:0.8em 1em}.note{color:#555;font-size:90%}.warn{color:#a33}"
    "table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:4px 10px;"
    "text-align:left;vertical-align:top}th{background:#f3f3f3;font-weight:normal}"
    "</style></head><body>")


# ---------------------------------------------------------------------- emulate

@dataclass
class Envelope:
    """A series reduced to bins of ``k`` samples: each bin's first time and the least,
    mean and greatest value in it (``k`` = 1: the series itself). Min and max keep what
    a mean hides: the full stroke of a drive that moves for a tenth of each bin."""
    t_s: np.ndarray
    lo: np.ndarray
    mean: np.ndarray
    hi: np.ndarray
    k: int


def envelope(t_s, values, k: int) -> Envelope:
    values = np.asarray(values, dtype=float)
    return Envelope(_bins(np.asarray(t_s, dtype=float), k, np.min), _bins(values, k, np.min),
                    _bins(values, k), _bins(values, k, np.max), k)


def emulation_period_s(em, predicted=None) -> tuple[float | None, str]:
    """(the emulated machine's cycle time, where it comes from): its ``cycle_signal``
    as the closed loop ran it, else its part arrivals' period, else the period the
    prediction repeats with; (None, "") for a machine that does not cycle."""
    m = em.machine
    if m.cycle_signal:
        cyc = cycles_of(m, em.timeline, _Cumulative(em.edges_s, em.true_total_cum_nl()))
        if cyc is not None and cyc.cycle_s:
            return float(cyc.cycle_s), cyc.source
    arrival = arrival_period_s(m, em.timeline)
    if arrival:
        return float(arrival), "the part arrivals' period"
    period = getattr(predicted, "period_s", None)
    if period:
        return float(period), "the period the prediction repeats with"
    return None, ""


class _Cumulative:
    """The emulation's true cumulative air as :func:`cycles_of` reads a profile."""

    def __init__(self, edges_s, cumulative_nl):
        self.edges_s, self.cumulative_nl = edges_s, cumulative_nl

    def cumulative_nl_at(self, at_s):
        return np.interp(at_s, self.edges_s, self.cumulative_nl)


def zoom_window(t_s, flow_l_min, horizon_s: float, period_s: float | None
                ) -> tuple[float, float] | None:
    """(start, end) s of the one cycle the emulation plot shows at full resolution: a
    whole period within the last two, started just before the flow rises out of its
    longest quiet spell (so the cycle reads from its first stroke, not from its
    middle). None when the horizon does not hold two periods (the whole run is then
    drawn at full resolution) or the machine does not cycle."""
    if not period_s or horizon_s < 2 * period_s:
        return None
    t = np.asarray(t_s, dtype=float)
    lo = horizon_s - 2 * period_s
    span = (t >= lo) & (t <= horizon_s)
    t, f = t[span], np.asarray(flow_l_min, dtype=float)[span]
    if len(f) < 3:
        return None
    # the quiet level against the strokes' flows (a valve's fill spike of a few ms
    # would otherwise set the scale)
    quiet = f <= f.min() + 0.05 * (np.percentile(f, 95) - f.min())
    a = horizon_s - period_s
    rises = np.flatnonzero(quiet[:-1] & ~quiet[1:]) + 1
    if len(rises):
        falls = np.flatnonzero(~quiet[:-1] & quiet[1:]) + 1
        # each rise's quiet spell began at the last fall before it (or the span's start)
        began = np.array([falls[falls < r][-1] if (falls < r).any() else 0 for r in rises])
        r = rises[np.argmax(t[rises] - t[began])]
        a = float(t[r]) - 0.05 * period_s
        a = a - period_s if a > horizon_s - period_s else a
        a = min(max(a, lo), horizon_s - period_s)
    return a, a + period_s


def predicted_flow_l_min(predicted, edges_s) -> np.ndarray:
    """The prediction's total flow (NL/min) on cells ``edges_s``: its exact air per cell
    over the cell's width."""
    edges_s = np.asarray(edges_s, dtype=float)
    return predicted.cells_nl(None, edges_s) / np.diff(edges_s) * 60.0


def _table_edges(t_end_s) -> np.ndarray:
    """The cell edges of plant.csv's rows (their times are the cells' ends)."""
    t_end_s = np.asarray(t_end_s, dtype=float)
    return np.concatenate([[0.0], t_end_s])


def _scaled(e: Envelope, scale: float) -> Envelope:
    """``e`` on a time axis in other units (minutes, hours)."""
    return Envelope(e.t_s * scale, e.lo, e.mean, e.hi, e.k)


def _draw_envelope(ax, env: Envelope, color, label: str, lw: float = 1.0, ls="-",
                   fill: bool = True, mean: bool = True, steps: bool = True) -> None:
    """The mean line, and where bins hold several samples the band from their least to
    their greatest value (step-wise: a bin's values hold over its width). Without
    ``mean`` a binned series is its band and the band's edges: the mean of a drive's
    position is a place it never stands. ``steps`` false: unbinned samples are states
    at instants (a position), joined by lines."""
    if env.k > 1 and fill:
        ax.fill_between(env.t_s, env.lo, env.hi, step="post", color=color, alpha=0.2,
                        lw=0)
    if env.k > 1 and not mean:
        ax.step(env.t_s, env.hi, where="post", color=color, lw=lw * 0.7, ls=ls, label=label)
        ax.step(env.t_s, env.lo, where="post", color=color, lw=lw * 0.7, ls=ls)
        return
    if env.k == 1 and not steps:
        ax.plot(env.t_s, env.mean, color=color, lw=lw, ls=ls, label=label)
        return
    ax.step(env.t_s, env.mean, where="post", color=color, lw=lw, ls=ls, label=label)


def time_bins_mean(t_s, values, width_s: float, horizon_s: float
                   ) -> tuple[np.ndarray, np.ndarray]:
    """(bin starts, mean per bin) of samples at times ``t_s`` in bins of ``width_s``
    from 0 (the meter's readings on the plant table's bins; empty bins are NaN)."""
    n = max(1, int(np.ceil(horizon_s / width_s - 1e-9)))
    idx = np.clip((np.asarray(t_s, dtype=float) // width_s).astype(np.int64), 0, n - 1)
    count = np.bincount(idx, minlength=n)
    total = np.bincount(idx, weights=np.asarray(values, dtype=float), minlength=n)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.arange(n) * width_s, np.where(count > 0, total / np.maximum(count, 1),
                                                np.nan)


@dataclass
class _EmulationView:
    """What the emulation plot draws, from the plant table: the columns by name, the
    horizon's bin width, the zoomed cycle (None: none) and the prediction on the rows."""
    col: dict
    rows: np.ndarray
    k: int
    zoom: tuple[float, float] | None
    period_s: float | None
    period_source: str
    predicted_l_min: np.ndarray | None

    def series(self, name: str) -> np.ndarray:
        return self.rows[:, self.col[name]]

    def horizon(self, values) -> Envelope:
        return envelope(self.rows[:, 0] - self.dt_s, values, self.k)

    @property
    def dt_s(self) -> float:
        return float(self.rows[0, 0]) if len(self.rows) else 0.0

    def in_zoom(self) -> np.ndarray:
        a, b = self.zoom
        t = self.rows[:, 0]
        return (t > a) & (t <= b + 1e-9)


def emulation_view(em, table=None, predicted=None) -> _EmulationView:
    """The arrays the emulation plot draws (a pure function of the run, for the tests)."""
    header, rows = table or em.plant_table()
    col = {h: i for i, h in enumerate(header)}
    period, source = emulation_period_s(em, predicted)
    k = whole_periods(_bin_width(len(rows)), period, float(rows[0, 0]), len(rows))
    zoom = zoom_window(rows[:, 0], rows[:, col["total_l_min"]], em.horizon_s, period)
    pred = (predicted_flow_l_min(predicted, _table_edges(rows[:, 0]))
            if predicted is not None else None)
    return _EmulationView(col, rows, k, zoom, period, source, pred)


def plot_emulation(em, path, table=None, predicted=None) -> None:
    """``emulate.png``: the meter's log, the plant's true total flow and the prediction
    (``predicted``: the :class:`~plcpred.air.DemandProfile` of the same horizon); each
    drive's position; each drive's chamber pressures. Over a long horizon each bin shows
    its least and greatest value around its mean, and a second column shows one cycle
    at the plant table's full resolution. ``table``: ``em.plant_table()`` if made."""
    plt = pyplot()
    v = emulation_view(em, table, predicted)
    drives = [c.name for c in em.machine.consumers if c.is_cylinder]
    n_rows = 3 if drives else 1
    cols = 2 if v.zoom else 1
    fig, axes = plt.subplots(n_rows, cols, figsize=(14 if v.zoom else 11, 9 if drives else 4),
                             sharex="col", constrained_layout=True, squeeze=False,
                             gridspec_kw={"width_ratios": [3, 2] if v.zoom else [1]})
    scale, unit = _time_axis(em.horizon_s)
    _draw_emulated_flow(axes[0, 0], em, v, scale, predicted)
    if drives:
        _draw_drives(axes[1, 0], axes[2, 0], v, drives, v.horizon, scale)
    axes[-1, 0].set_xlabel(f"time ({unit})")
    axes[0, 0].set_xlim(0, em.horizon_s * scale)
    if v.zoom:
        a, b = v.zoom
        _draw_zoom_flow(axes[0, 1], em, v)
        if drives:
            sel = v.in_zoom()
            _draw_drives(axes[1, 1], axes[2, 1], v, drives,
                         # the states are sampled at the rows' mid-times
                         lambda x: envelope(v.rows[sel, 0] - v.dt_s / 2 - a, x[sel], 1), 1.0,
                         legend=False)
        axes[-1, 1].set_xlabel(f"time in the cycle (s; it starts at {a:.1f} s)")
        axes[0, 1].set_xlim(0, b - a)
    save_fig(fig, path)


def _draw_emulated_flow(ax, em, v: _EmulationView, scale: float, predicted) -> None:
    """The horizon's flow: the plant's true total (its band and mean per bin), the
    meter's log and the prediction (their means per bin; the prediction's greatest per
    bin where bins are long enough for the peaks to differ from the mean)."""
    true = v.horizon(v.series("total_l_min"))
    width = v.dt_s * v.k
    binned = f", band: min to max per {width:.3g} s" if v.k > 1 else ""
    _draw_envelope(ax, _scaled(true, scale), "tab:blue", f"true total (ISO 8778{binned})",
                   lw=0.9)
    if len(em.measured_time_s) <= MAX_POINTS:
        ax.step(em.measured_time_s * scale, em.measured_flow_l_min, where="pre",
                color="black", lw=1.0, label=_meter_label(em))
    else:
        t, mean = time_bins_mean(em.measured_time_s - 0.5 / em.meter.rate_hz,
                                 em.measured_flow_l_min, width, em.horizon_s)
        ax.step(t * scale, mean, where="post", color="black", lw=0.8,
                label=_meter_label(em) + ", mean per bin")
    if v.predicted_l_min is not None:
        pred = v.horizon(v.predicted_l_min)
        _draw_envelope(ax, _scaled(pred, scale), "tab:orange", "predicted (machine file)"
                       + (", mean per bin" if v.k > 1 else ""), lw=1.2, ls="--", fill=False)
        if width >= 0.5:
            ax.step(pred.t_s * scale, pred.hi, where="post", color="tab:orange", lw=0.8,
                    ls=":", label="predicted, max per bin")
    ax.set_ylabel("flow (NL/min)")
    ax.set_ylim(bottom=0)
    ax.grid(True, alpha=0.3)
    pred_text = ""
    if predicted is not None and predicted.total_nl > 0:
        p = float(predicted.total_nl)
        pred_text = (f", {p:.2f} NL predicted (true - predicted "
                     f"{100 * (em.total_nl - p) / p:+.1f} % of predicted)")
    ax.set_title(_plain(f"{em.machine.name}: emulated {em.horizon_s:g} s, "
                        f"{em.total_nl:.2f} NL true{pred_text}"), fontsize=10)
    ax.legend(loc="upper right", fontsize=7, framealpha=0.9)


def _meter_label(em) -> str:
    m = em.meter
    return f"meter ({m.reference}, tau {m.tau_s:g} s, {m.rate_hz:g} Hz)"


def _draw_zoom_flow(ax, em, v: _EmulationView) -> None:
    """One cycle's flow at the plant table's resolution: true, metered, predicted."""
    a, b = v.zoom
    sel = v.in_zoom()
    t = v.rows[sel, 0] - v.dt_s - a
    ax.step(t, v.series("total_l_min")[sel], where="post", color="tab:blue", lw=0.9,
            label="true total")
    m = (em.measured_time_s > a) & (em.measured_time_s <= b)
    ax.step(em.measured_time_s[m] - a, em.measured_flow_l_min[m], where="pre",
            color="black", lw=1.0, label="meter")
    if v.predicted_l_min is not None:
        ax.step(t, v.predicted_l_min[sel], where="post", color="tab:orange", lw=1.2,
                ls="--", label="predicted")
    ax.set_ylim(bottom=0)
    ax.grid(True, alpha=0.3)
    ax.set_title(_plain(f"one cycle ({v.period_s:.3g} s, {v.period_source}), "
                        f"rows every {v.dt_s:.3g} s"), fontsize=10)
    ax.legend(loc="upper right", fontsize=7, framealpha=0.9)


def _draw_drives(ax_pos, ax_p, v: _EmulationView, drives, reduce, scale: float = 1.0,
                 legend: bool = True) -> None:
    """Each drive's position and chamber pressures, reduced by ``reduce`` (an
    :class:`Envelope` of a column)."""
    colors = [c["color"] for c in pyplot().rcParams["axes.prop_cycle"]]

    def draw(ax, env, color, label, ls="-", fill=True):
        _draw_envelope(ax, _scaled(env, scale), color, label, lw=0.9, ls=ls, mean=False,
                       fill=fill, steps=False)
    for n, name in enumerate(drives):
        color = colors[n % len(colors)]
        draw(ax_pos, reduce(v.series(f"{name}_position_mm")), color, _plain(name))
        # six chambers' bands would cover each other: their edges alone
        draw(ax_p, reduce(v.series(f"{name}_p_cap_bar_g")), color, _plain(f"{name} cap"),
             fill=False)
        draw(ax_p, reduce(v.series(f"{name}_p_rod_bar_g")), color, _plain(f"{name} rod"),
             ls="--", fill=False)
    env = reduce(v.series(f"{drives[0]}_position_mm"))
    per = f",\nmin to max per {v.dt_s * env.k:.3g} s" if env.k > 1 else ""
    ax_pos.set_ylabel(f"position (mm){per}")
    ax_p.set_ylabel(f"chamber (bar(g)){per}")
    for ax in (ax_pos, ax_p):
        ax.grid(True, alpha=0.3)
    if legend:
        ax_pos.legend(loc="upper right", fontsize=8, ncol=min(6, len(drives)))
        ax_p.legend(loc="upper right", fontsize=7, ncol=min(6, 2 * len(drives)))
