"""``emulate.png``: min/max envelopes of flow, positions and pressures over the
horizon, one cycle at full resolution, the prediction overlaid."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..air.cycles import arrival_period_s, cycles_of
from .plotting import (
    MAX_POINTS,
    Envelope,
    bin_width,
    envelope,
    plain,
    pyplot,
    save_fig,
    time_axis,
    whole_periods,
)


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
    k = whole_periods(bin_width(len(rows)), period, float(rows[0, 0]), len(rows))
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
    scale, unit = time_axis(em.horizon_s)
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
    ax.set_title(plain(f"{em.machine.name}: emulated {em.horizon_s:g} s, "
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
    ax.set_title(plain(f"one cycle ({v.period_s:.3g} s, {v.period_source}), "
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
        draw(ax_pos, reduce(v.series(f"{name}_position_mm")), color, plain(name))
        # six chambers' bands would cover each other: their edges alone
        draw(ax_p, reduce(v.series(f"{name}_p_cap_bar_g")), color, plain(f"{name} cap"),
             fill=False)
        draw(ax_p, reduce(v.series(f"{name}_p_rod_bar_g")), color, plain(f"{name} rod"),
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
