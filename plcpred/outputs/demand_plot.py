"""The demand plot of ``plcpred predict`` and the per-consumer table it prints."""
from __future__ import annotations

import numpy as np

from ..output import SHOWN_CONSUMERS
from .plotting import bin_width, plain, pyplot, save_fig, time_axis, whole_periods


def plot_demand(profile, path, title="Air demand", shown: int | None = SHOWN_CONSUMERS,
                cycle_s: float | None = None) -> None:
    """Stacked flow per consumer (the ``shown`` largest and "other" on a wide machine,
    see :meth:`DemandProfile.groups`) against time with the cumulative normal litres on
    a second axis; written through a temporary file. Over many cycles the bins are
    whole cycles: the run's period, or ``cycle_s`` for a run that does not repeat."""
    plt = pyplot()

    k = whole_periods(bin_width(profile.n_cells),
                       getattr(profile, "period_s", None) or cycle_s,
                       profile.dt_s, profile.n_cells)
    bin_edges = profile.edges_s[::k]
    if bin_edges[-1] < profile.edges_s[-1]:
        bin_edges = np.append(bin_edges, profile.edges_s[-1])
    t = bin_edges[:-1]
    scale, unit = time_axis(profile.horizon_s)
    fig, ax = plt.subplots(figsize=(11, 5.5), dpi=110)
    layers, flows = demand_layers(profile, shown, bin_edges)
    labels = [f"{plain(label)} ({nl:.1f} NL)" for label, idx, nl in layers]
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
    ax.set_title(f"{plain(title)}\nmean {profile.mean_l_min:.1f} NL/min, peak "
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


def demand_layers(profile, shown: int | None, edges_s):
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
