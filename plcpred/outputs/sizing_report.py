"""The sizing report of ``plcpred size``: ``sizing.png`` (one cycle, the load-duration
curve, the air per cycle, the deficits), ``sizing.md``, ``sizing.html`` and ``sizing.json``."""
from __future__ import annotations

import base64
import datetime
import html
import math
import os
import re
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import __version__
from ..air.cycles import arrival_period_s
from ..air.sizing import receiver_deficit
from ..output import SHOWN_CONSUMERS, atomic_write_text, write_json
from .demand_plot import demand_layers, plot_demand
from .plotting import (
    Envelope,
    bin_width,
    bins,
    md_cell,
    plain,
    pyplot,
    save_fig,
    time_axis,
)


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


# windows worked out at once: ten years of a 4 s cycle are 79 million, of which the plot
# keeps a few thousand numbers. Arrays of half a MB the allocator keeps and reuses;
# chunks of a few MB it hands back and the system faults in again each time (at 500,000
# the system time was as long as the work)
WINDOW_CHUNK = 65_536
DEFICIT_BINS = 42


@dataclass
class SizingWindows:
    """The horizon cut into windows of one steady cycle (else of a minute, or a
    twentieth of a short horizon) from 0, reduced to what the sizing plot draws. A whole
    window's value is its air (NL; for windows that are not cycles its mean flow,
    NL/min); the last window may be cut by the horizon, and only whole windows have
    values. Worked out a chunk of windows at a time, so that the memory follows the
    plot, not the horizon."""
    what: str                       # "cycle", "minute" or "window"
    width_s: float
    n: int                          # windows, the cut one included
    n_whole: int
    k: int                          # whole windows per group
    groups_s: np.ndarray            # the groups' edges (s): every k-th whole window's start
    #                                 and the last whole one's end
    env: Envelope                   # per group: its first start, least, mean, greatest value
    least: float                    # over every whole window (nan if none)
    greatest: float
    mean: float
    total_nl: float                 # every window's air: the horizon's total
    deficit_max_nl: float           # the largest of the windows' largest deficits
    deficit_bins_nl: np.ndarray     # the histogram of each window's largest deficit over
    deficit_counts: np.ndarray      # the design flow: bin edges (NL) and windows per bin


def _window_width(profile, sizing) -> tuple[float, str]:
    horizon = profile.horizon_s
    if sizing.cycle_s and sizing.cycle_s < horizon:
        return float(sizing.cycle_s), "cycle"
    if horizon >= 600:
        return 60.0, "minute"
    return max(profile.dt_s, horizon / 20), "window"


def sizing_windows(profile, sizing, deficit, k: int | None = None,
                   chunk: int | None = None) -> SizingWindows:
    """:class:`SizingWindows` of a profile, ``deficit`` the receiver's deficit at the
    end of each grid cell (:func:`~plcpred.air.sizing.receiver_deficit`), the whole
    windows in groups of ``k`` (default: one group per plotted point,
    :func:`~plcpred.outputs.plotting.bin_width`), about ``chunk`` windows at a time
    (default: :data:`WINDOW_CHUNK`, or as many as the profile has rectangles)."""
    horizon = profile.horizon_s
    width, what = _window_width(profile, sizing)
    # window j starts at j * width, as np.arange(0.0, stop, width) has them; the last
    # ends at the horizon, and only it can be cut (j * width is exact to far below a
    # millionth of a window)
    n = max(1, math.ceil((horizon - 1e-9 * horizon) / width))
    n_whole = n - int(horizon - (n - 1) * width < width * (1 - 1e-6))
    k = k or bin_width(n_whole)
    deficit = np.asarray(deficit, dtype=float)
    # every cell from the first on is some window's (windows tile the horizon): their
    # largest deficit is the grid's, and it sets the histogram's bins before the first chunk
    deficit_max = float(deficit.max())
    top = max(deficit_max, sizing.deficit_nl, 1e-9)
    # from 0, so cycles that all reach the same deficit read as one bar at its size
    deficit_bins = np.linspace(0.0, top * 1.05, DEFICIT_BINS + 1)
    counts = np.zeros(DEFICIT_BINS, dtype=np.int64)
    if chunk is None:
        # a repeating profile's cumulative costs one period whatever the chunk; one that
        # does not repeat merges all its rectangles at each call: chunks of at least as
        # many windows as it has rectangles hold no more than that merge does
        n_rects = sum(len(r[0]) for r in profile.rects) if profile.templates is None else 0
        chunk = max(WINDOW_CHUNK, n_rects)
    step = k * max(1, chunk // k)                       # whole groups: none is cut
    parts: list[tuple] = []
    total_nl, value_sum = 0.0, 0.0
    for a in range(0, n, step):
        b = min(n, a + step)
        j = np.arange(a, b + 1, dtype=float)
        edges = j * width
        if b == n:
            edges[-1] = horizon
        nl = np.diff(profile.cumulative_nl_at(edges))
        total_nl += float(nl.sum())
        d = _largest_deficits(profile, deficit, edges[:-1], None if b == n else edges[-1])
        counts += _histogram(d, deficit_bins)
        m = max(0, min(b, n_whole) - a)
        if m:
            values = nl[:m] if what == "cycle" else nl[:m] / width * 60.0
            value_sum += float(np.sum(values))
            parts.append((_per_group(edges[:m], k, np.min), _per_group(values, k, np.min),
                          _per_group(values, k, np.mean), _per_group(values, k, np.max)))
    env = Envelope(*(np.concatenate([p[i] for p in parts]) if parts else np.zeros(0)
                     for i in range(4)), k)
    return SizingWindows(
        what, width, n, n_whole, k, _group_edges(n_whole, width, k), env,
        float(env.lo.min()) if n_whole else math.nan,
        float(env.hi.max()) if n_whole else math.nan,
        value_sum / n_whole if n_whole else math.nan, total_nl, deficit_max,
        deficit_bins, counts)


def _per_group(values, k: int, reduce) -> np.ndarray:
    """``values`` reduced in groups of ``k`` as :func:`bins` does, a last chunk of
    fewer than ``k`` to one group too (``bins`` leaves a series shorter than a group as
    it is)."""
    return bins(values, k, reduce) if len(values) >= k else reduce(values)[None]


def _largest_deficits(profile, deficit, starts_s, next_start_s) -> np.ndarray:
    """The largest deficit in each window of a run of them (their starts, and the start
    of the window after the run, None at the horizon): over the cells whose end lies in
    it (the deficit is at cell ends), or the cell that holds a window shorter than a
    cell."""
    cell_end = profile.edges_s[1:]
    last = len(deficit) - 1
    first = np.minimum(_cells_ending_by(cell_end, starts_s), last)
    after = (last + 1 if next_start_s is None else
             min(int(np.searchsorted(cell_end, next_start_s, side="right")), last))
    # the run's cells up to the next window's first (at least one past the run's last
    # first cell): each window reduces to its own, as it would over the whole grid
    cells = deficit[first[0]:max(after, first[-1] + 1)]
    return np.maximum.reduceat(cells, first - first[0])


def _cells_ending_by(cell_end, starts_s) -> np.ndarray:
    """``np.searchsorted(cell_end, starts_s, side="right")`` (the cells that end by each
    start) for sorted starts, worked from the cells between the first and last start:
    ten years of 4 s windows on a 1000 s grid are 250 windows a cell, and looking each
    one up on the grid took as long as the rest of the plot."""
    lo, hi = np.searchsorted(cell_end, starts_s[[0, -1]], side="right")
    # the starts before each of those cells' ends: the windows whose first it is not yet
    before = np.searchsorted(starts_s, cell_end[lo:hi], side="left")
    per_cell = np.diff(before, prepend=0, append=len(starts_s))
    return np.repeat(np.arange(lo, hi + 1), per_cell)


def _histogram(values, edges) -> np.ndarray:
    """``np.histogram(values, edges)[0]`` (bins closed on the left, the last on both
    sides, values outside left out) without its sort of every value."""
    inside = values[(values >= edges[0]) & (values <= edges[-1])]
    at = np.minimum(np.searchsorted(edges, inside, side="right") - 1, len(edges) - 2)
    return np.bincount(at, minlength=len(edges) - 1)


def _group_edges(n_whole: int, width: float, k: int) -> np.ndarray:
    """The edges of the whole windows in groups of ``k`` (s): every k-th window's start
    and the last whole window's end (its start plus a width)."""
    if not n_whole:
        return np.zeros(1)
    end = (n_whole - 1) * width + width
    idx = np.arange(0, n_whole + 1, k)
    groups = np.where(idx < n_whole, idx * width, end)
    return groups if groups[-1] >= end else np.append(groups, end)


def _noun(w: SizingWindows, plural: bool = False) -> str:
    """What a window is, for labels: "cycle", "minute", "window of 1 s"."""
    s = "s" if plural else ""
    return f"window{s} of {w.width_s:.3g} s" if w.what == "window" else w.what + s


def window_layers(profile, w: SizingWindows):
    """The whole windows in their groups of ``w.k``: the groups' edges (s), the layers of
    :func:`demand_layers` and each layer's mean air per window in each group (NL; for windows
    that are not cycles its mean flow, NL/min), one row per layer."""
    groups = w.groups_s
    layers, flows = demand_layers(profile, SHOWN_CONSUMERS, groups)
    return groups, layers, (flows * w.width_s / 60.0 if w.what == "cycle" else flows)


def _draw_air_per_window(ax, profile, sizing, w: SizingWindows) -> None:
    """The air of each whole window over the horizon, stacked by consumer (in groups of
    windows, their mean, and the band of the windows' least and greatest total, where
    there are more windows than pixels)."""
    scale, unit = time_axis(profile.horizon_s)
    per_cycle = w.what == "cycle"
    ax.set_xlim(0, profile.horizon_s * scale)
    ax.set_xlabel(f"time ({unit})")
    ax.set_ylabel("air per cycle (NL)" if per_cycle else "mean flow (NL/min)")
    ax.grid(True, alpha=0.3)
    if not w.n_whole:
        return
    groups, layers, stacks = window_layers(profile, w)
    if layers:
        ax.stackplot(groups * scale, np.column_stack([stacks, stacks[:, -1:]]), step="post",
                     alpha=0.85, labels=[plain(label) for label, _, _ in layers])
    if w.k > 1:
        env = w.env
        ax.fill_between(env.t_s * scale, env.lo, env.hi, step="post", color="black",
                        alpha=0.15, lw=0, label=f"least to greatest of {w.k} "
                        f"{_noun(w, plural=True)}")
    if per_cycle and sizing.nl_per_cycle:
        ax.axhline(sizing.nl_per_cycle, color="black", ls="--", lw=0.8,
                   label=f"steady {sizing.nl_per_cycle:.3f} NL per cycle")
    elif not per_cycle:
        ax.axhline(sizing.mean_l_min, color="black", ls="--", lw=1,
                   label=f"mean {sizing.mean_l_min:.1f} NL/min")
    spread = (w.greatest - w.least) / max(abs(w.mean), 1e-12)
    ax.set_title(f"each {_noun(w)} over the horizon: {w.n_whole} whole, they differ by "
                 f"{100 * spread:.1f} % ({w.least:.3g} to {w.greatest:.3g})",
                 fontsize=10)
    ax.set_ylim(0, w.greatest * 1.3 if w.greatest > 0 else 1)
    h, lab = ax.get_legend_handles_labels()
    ax.legend(h[::-1], lab[::-1], loc="upper right", fontsize=7, framealpha=0.9,
              ncol=2)


def _draw_deficits(ax, sizing, w: SizingWindows) -> None:
    """How many windows reach each largest deficit, the horizon's largest marked."""
    edges = w.deficit_bins_nl
    # the counts drawn as the histogram of the windows would be: one weighted value a bin
    ax.hist(edges[:-1], bins=edges, weights=w.deficit_counts, color="#fdae6b",
            edgecolor="#e6550d", lw=0.5, label=f"{w.n} {_noun(w, plural=True)}")
    ax.set_xlim(0, max(w.deficit_max_nl, sizing.deficit_nl, 1e-9) * 1.1)
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
        layers, flows = demand_layers(profile, SHOWN_CONSUMERS, edges)
        if layers:
            ax.stackplot(edges[:-1] - a, flows, step="post", alpha=0.85,
                         labels=[plain(label) for label, _, _ in layers])
    _levels(ax, sizing)
    ax.set_xlim(0, b - a)
    ax.set_xlabel(f"time in the window (s; it starts at {a:g} s)")
    ax.set_ylabel("flow (NL/min)")
    ax.set_title(f"{plain(title)}\n{what}, grid {profile.dt_s:g} s", fontsize=10)
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
    money = f" {md_cell(s.currency)}" if s.currency else ""
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
        f"{md_cell(s.cycle_source)}) |" if s.cycle_s is not None else
        "| steady cycle | none found (no cycle_signal, no repeating state) |",
        f"| air per cycle | {s.nl_per_cycle:.3f} NL |" if s.cycle_s is not None else
        f"| air over the horizon | {s.total_nl:.2f} NL |",
        "",
        *[f"**Warning**: {md_cell(w)}\n" for w in s.warnings],
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
        lines.append(f"| {md_cell(name)} | {profile.roles[i]} | {profile.consumer_nl[i]:.2f} | "
                     f"{pct(profile.consumer_nl[i] / total)} |")
    lines.append("")
    if assumptions:
        lines += ["| assumption | value |", "|---|---|"]
        lines += [f"| {md_cell(k)} | {md_cell(v)} |" for k, v in assumptions]
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
