"""Plots and tables for people: the demand plot of ``plcpred predict`` and the printed
per-consumer table."""
from __future__ import annotations

import base64
import datetime
import html
import os
import re
import tempfile
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import __version__
from ..air.cycles import arrival_period_s
from ..air.sizing import receiver_deficit
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
    load-duration curve (the flow exceeded for a share of the time); the trend over the
    horizon as min, mean and max per bin (a long horizon is not drawn cell by cell); the
    receiver's deficit over the design flow."""
    plt = pyplot()
    total = profile.total_flow_l_min
    _, _, deficit = receiver_deficit(total, profile.dt_s, sizing.design_flow_l_min)
    # trend bins of whole cycles where there is one: a bin then never cuts a cycle in a
    # different place from its neighbour (the moire a long horizon otherwise shows)
    k = whole_periods(_bin_width(len(total)), sizing.cycle_s, profile.dt_s, len(total))
    mean_b = _bins(total, k)
    bins = _SizingBins(k, np.arange(len(mean_b)) * profile.dt_s * k,
                       _bins(total, k, np.min), mean_b, _bins(total, k, np.max),
                       _bins(deficit, k, np.max))
    fig, axes = plt.subplots(2, 2, figsize=(12, 8), dpi=100,
                             gridspec_kw={"width_ratios": [3, 2], "height_ratios": [1, 1]})
    (ax_cycle, ax_ldc), (ax_trend, ax_def) = axes
    _draw_cycle(ax_cycle, profile, sizing, title)
    _draw_load_duration(ax_ldc, total, sizing)
    scale, unit = _time_axis(profile.horizon_s)
    _draw_trend(ax_trend, profile, sizing, bins, scale, unit)
    _draw_deficit(ax_def, profile, sizing, bins, scale, unit)
    fig.tight_layout()
    save_fig(fig, path)


@dataclass
class _SizingBins:
    """The horizon in bins of ``k`` cells: their start times and the total flow's min,
    mean and max in each, and the receiver's largest deficit."""
    k: int
    start_s: np.ndarray
    min_l_min: np.ndarray
    mean_l_min: np.ndarray
    max_l_min: np.ndarray
    deficit_nl: np.ndarray


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


def _draw_trend(ax, profile, sizing, bins: _SizingBins, scale: float, unit: str) -> None:
    """Min, mean and max per bin over the horizon."""
    span = profile.dt_s * bins.k
    ax.fill_between(bins.start_s * scale, bins.min_l_min, bins.max_l_min, step="post",
                    color="#c6dbef", label=f"min to max per {span:g} s")
    ax.step(bins.start_s * scale, bins.mean_l_min, where="post", color="#3182bd", lw=1.0,
            label=f"mean per {span:g} s")
    _levels(ax, sizing)
    ax.set_xlim(0, profile.horizon_s * scale)
    ax.set_xlabel(f"time ({unit})")
    ax.set_ylabel("flow (NL/min)")
    ax.set_title("over the horizon", fontsize=10)
    ax.legend(loc="upper right", fontsize=8)


def _draw_deficit(ax, profile, sizing, bins: _SizingBins, scale: float, unit: str) -> None:
    """The receiver's deficit over the design flow, its largest marked."""
    ax.fill_between(bins.start_s * scale, 0, bins.deficit_nl, step="post", color="#fdae6b")
    ax.axvline(sizing.deficit_at_s * scale, color="#d62728", lw=1)
    ax.set_ylabel("deficit over design flow (NL)")
    ax.set_xlabel(f"time ({unit})")
    ax.set_xlim(0, profile.horizon_s * scale)
    ax.set_ylim(bottom=0)
    ax.grid(True, alpha=0.3)
    ax.set_title(f"largest {sizing.deficit_nl:.2f} NL -> receiver "
                 f"{sizing.receiver_l:.1f} L for {sizing.band_bar:g} bar", fontsize=10)


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

def plot_diagnosis(d, path) -> None:
    """``diagnose.png``: per run, the measured, predicted and corrected meter readings
    against the logger's clock with the located windows shaded; the cumulative NL of
    all three; the residual per context."""
    plt = pyplot()

    runs = d.runs
    fig, axes = plt.subplots(len(runs) + 2, 1, figsize=(11, 3.0 * (len(runs) + 2)),
                             constrained_layout=True)
    best = d.best_params()
    named = {c.context for c in d.contexts if c.stands_out}
    corrected_label = ("corrected (" + " + ".join(d.combination["effects"]) + ")"
                       if d.combination else None)
    for ax, rd, base, fixed in zip(axes, runs, d.bases, best):
        t = rd.end_s + rd.offset_s
        ax.plot(t, rd.measured_l_min, color="black", lw=1.0, label="measured")
        ax.plot(t, rd.readings(base), color="tab:blue", lw=1.0, label="predicted")
        if corrected_label:
            ax.plot(t, rd.readings(fixed), color="tab:red", lw=1.0, ls="--",
                    label=_plain(corrected_label))
        for loc in d.locations[:30]:
            if loc.get("run") == rd.run.name and loc["context"] in named:
                ax.axvspan(loc["start_s"], loc["end_s"], color="orange", alpha=0.15, lw=0)
        ax.set_ylabel("NL/min")
        ax.set_title(_plain(f"{rd.run.name}: meter readings (shaded: located gap)"),
                     fontsize=10)
        ax.legend(loc="upper right", fontsize=8)
    ax = axes[-2]
    offset = 0.0
    for rd, base, fixed in zip(runs, d.bases, best):
        t = rd.end_s + offset
        w = rd.weight_s / 60.0
        ax.plot(t, np.cumsum(rd.measured_l_min * w), color="black", lw=1.0)
        ax.plot(t, np.cumsum(rd.readings(base) * w), color="tab:blue", lw=1.0)
        if corrected_label:
            ax.plot(t, np.cumsum(rd.readings(fixed) * w), color="tab:red", lw=1.0, ls="--")
        offset = t[-1]
    ax.set_ylabel("NL")
    ax.set_xlabel("time in the prediction, s (runs one after another)")
    ax.set_title("cumulative air: measured (black), predicted (blue), corrected (red)",
                 fontsize=10)
    ax = axes[-1]
    ctx = d.contexts[:12]
    ax.barh([_plain(c.context) for c in ctx][::-1], [c.residual_nl for c in ctx][::-1],
            xerr=[3 * c.uncertainty_nl for c in ctx][::-1],
            color=["tab:orange" if c.stands_out else "lightgray" for c in ctx][::-1])
    ax.axvline(0, color="black", lw=0.8)
    ax.set_xlabel("residual NL (measured - predicted); bars +/- 3 sigma of noise")
    ax.set_title(_plain(f"where the gap lies; verdict: {d.verdict}"), fontsize=10)
    save_fig(fig, path)


def diagnosis_html(d, png: bytes | None) -> str:
    """``diagnose.html``: the printed report and the plot in one self-contained page."""

    parts = ["<!DOCTYPE html><html><head><meta charset='utf-8'><title>Diagnosis</title>",
             ("<style>body{font-family:sans-serif;max-width:1100px;margin:2em auto;"
             "color:#222}pre{background:#f6f6f6;padding:1em;overflow-x:auto}"
             "img{max-width:100%}</style></head><body>"),
             f"<h1>{html.escape(d.machine.name)}: diagnosis of the sim-to-real gap</h1>",
             f"<pre>{html.escape(d.report())}</pre>"]
    if png is not None:
        parts.append(f"<p><img alt='diagnosis' src='data:image/png;base64,"
                     f"{base64.b64encode(png).decode()}'></p>")
    parts.append("</body></html>")
    return "\n".join(parts)


# ---------------------------------------------------------------------- emulate

def plot_emulation(em, path, table=None) -> None:
    """``emulate.png``: the meter's log against the plant's true total flow; each drive's
    position; each drive's chamber pressures. ``table``: ``em.plant_table()`` if made."""
    plt = pyplot()

    header, rows = table or em.plant_table()
    k = _bin_width(len(rows))
    t = _bins(rows[:, 0], k)
    col = {h: i for i, h in enumerate(header)}
    drives = [c.name for c in em.machine.consumers if c.is_cylinder]
    fig, axes = plt.subplots(3 if drives else 1, 1, figsize=(11, 8 if drives else 3.5),
                             sharex=True, constrained_layout=True, squeeze=False)
    axes = axes[:, 0]
    ax = axes[0]
    ax.plot(t, _bins(rows[:, col["total_l_min"]], k), color="tab:blue", lw=0.8,
            label="true total (ISO 8778)")
    ax.step(em.measured_time_s, em.measured_flow_l_min, where="pre", color="black", lw=1.0,
            label=f"meter ({em.meter.reference}, tau {em.meter.tau_s:g} s, "
                  f"{em.meter.rate_hz:g} Hz)")
    ax.set_ylabel("NL/min")
    ax.set_title(_plain(f"{em.machine.name}: emulated flow, {em.total_nl:.2f} NL true"),
                 fontsize=10)
    ax.legend(loc="upper right", fontsize=8)
    if drives:
        for name in drives:
            ax = axes[1]
            ax.plot(t, _bins(rows[:, col[f"{name}_position_mm"]], k), lw=0.9,
                    label=_plain(name))
            axes[2].plot(t, _bins(rows[:, col[f"{name}_p_cap_bar_g"]], k), lw=0.8,
                         label=_plain(f"{name} cap"))
            axes[2].plot(t, _bins(rows[:, col[f"{name}_p_rod_bar_g"]], k), lw=0.8, ls="--",
                         label=_plain(f"{name} rod"))
        axes[1].set_ylabel("position, mm")
        axes[1].legend(loc="upper right", fontsize=8, ncol=min(6, len(drives)))
        axes[2].set_ylabel("chamber, bar(g)")
        axes[2].legend(loc="upper right", fontsize=7, ncol=min(6, 2 * len(drives)))
    axes[-1].set_xlabel("time, s")
    save_fig(fig, path)
