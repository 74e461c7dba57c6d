"""What every plot of plcpred shares: matplotlib on the file-only Agg backend, figures
written atomically, long series in bins, time axes in a readable unit, user text made
safe for plots and Markdown."""
from __future__ import annotations

import io
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

# a plotted point per pixel column of the 11-inch, 110 dpi figures (more are not seen,
# and drawing a stacked layer costs per point)
MAX_POINTS = 1200
MAX_CYCLES_DRAWN = 150    # more cycles than this on a time axis are drawn per bin


def bin_width(n: int) -> int:
    """Cells per plotted point, so a plot has at most MAX_POINTS of them (a day at 10 ms
    would otherwise be 8.6 million points per layer)."""
    return max(1, int(np.ceil(n / MAX_POINTS)))


def bins(values, k: int, reduce=np.mean):
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


def time_axis(horizon_s: float) -> tuple[float, str]:
    """(factor from seconds, unit) for a time axis over ``horizon_s``."""
    if horizon_s >= 7200:
        return 1 / 3600, "h"
    if horizon_s >= 600:
        return 1 / 60, "min"
    return 1.0, "s"


def plain(text: str) -> str:
    """User text (machine and consumer names) for matplotlib, which would read ``$...$``
    as mathematics and fail on anything it cannot typeset."""
    return str(text).replace("\\", "\\\\").replace("$", r"\$")


def md_cell(text: str) -> str:
    """User text for a Markdown table cell."""
    return str(text).replace("|", r"\|").replace("\n", " ")


def pyplot():
    """matplotlib's pyplot on the file-only Agg backend."""
    # matplotlib costs half a second to import: only a run that plots pays it
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


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


def png_bytes(fig) -> bytes:
    plt = pyplot()
    buf = io.BytesIO()
    try:
        fig.savefig(buf, format="png", dpi=90)
    finally:
        plt.close(fig)
    return buf.getvalue()


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
    return Envelope(bins(np.asarray(t_s, dtype=float), k, np.min), bins(values, k, np.min),
                    bins(values, k), bins(values, k, np.max), k)
