"""Plots and tables for people: the demand plot of ``plcpred predict`` and the printed
per-consumer table."""
from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np

MAX_POINTS = 3000


def _binned(profile, max_points=MAX_POINTS):
    """Per-consumer flows averaged into at most ``max_points`` bins (a day at 10 ms would
    otherwise be 8.6 million points per layer)."""
    flows = profile.flow_l_min
    n = flows.shape[1]
    k = max(1, int(np.ceil(n / max_points)))
    m = n // k * k
    if k > 1 and m:
        head = flows[:, :m].reshape(flows.shape[0], -1, k).mean(axis=2)
        tail = flows[:, m:].mean(axis=1, keepdims=True) if m < n else None
        flows = head if tail is None else np.concatenate([head, tail], axis=1)
    t = np.arange(flows.shape[1]) * profile.dt_s * k
    return t, flows, k


def plot_demand(profile, path, title="Air demand") -> None:
    """Stacked flow per consumer against time with the cumulative normal litres on a
    second axis; written through a temporary file."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t, flows, k = _binned(profile)
    scale, unit = (1 / 3600, "h") if profile.horizon_s >= 7200 else (
        (1 / 60, "min") if profile.horizon_s >= 600 else (1, "s"))
    fig, ax = plt.subplots(figsize=(11, 5.5), dpi=110)
    order = np.argsort([-v for v in profile.consumer_nl])
    labels = [f"{profile.names[i]} ({profile.consumer_nl[i]:.1f} NL)" for i in order]
    ax.stackplot(t * scale, flows[order], labels=labels, step="post", alpha=0.85)
    ax.set_xlabel(f"time ({unit})")
    ax.set_ylabel("flow (NL/min)")
    ax.set_xlim(0, profile.horizon_s * scale)
    ax.set_ylim(bottom=0)
    ax.grid(True, alpha=0.3)
    avg = f", averaged over {profile.dt_s * k:g} s bins" if k > 1 else ""
    ax.set_title(f"{title}\nmean {profile.mean_l_min:.1f} NL/min, peak "
                 f"{profile.peak_l_min():.1f} NL/min (grid {profile.dt_s:g} s{avg}), "
                 f"total {profile.total_nl:.1f} NL", fontsize=10)
    ax2 = ax.twinx()
    cum = np.concatenate([[0.0], profile.cumulative_nl()])
    tc = np.arange(len(cum)) * profile.dt_s
    step = max(1, len(cum) // MAX_POINTS)
    ax2.plot(tc[::step] * scale, cum[::step], color="black", lw=1.4, label="cumulative NL")
    ax2.set_ylabel("cumulative (NL)")
    ax2.set_ylim(bottom=0)
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = ax2.get_legend_handles_labels()
    ax.legend(h1[::-1] + h2, l1[::-1] + l2, loc="upper left", fontsize=8, framealpha=0.9)
    fig.tight_layout()
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


def consumer_table(profile) -> str:
    """The per-consumer table ``plcpred predict`` prints."""
    rows = [("consumer", "kind", "strokes", "active NL", "passive NL", "total NL", "share")]
    total = profile.total_nl or 1.0
    for i, name in enumerate(profile.names):
        st = profile.strokes.get(name)
        rows.append((name, profile.roles[i], f"{st[0]}+{st[1]}" if st else "",
                     f"{profile.active_nl[i]:.2f}", f"{profile.passive_nl[i]:.2f}",
                     f"{profile.consumer_nl[i]:.2f}",
                     f"{100 * profile.consumer_nl[i] / total:.1f} %"))
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
