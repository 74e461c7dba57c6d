"""The diagnosis report: ``diagnose.png`` and ``diagnose.html`` (the conclusion first,
where the gap lies, how sure, then the printed report)."""
from __future__ import annotations

import base64
import datetime
import html
from dataclasses import dataclass

import numpy as np

from ..air.sizing import DEFAULT_PRICE, production_hours, specific_energy_kwh_per_nm3
from ..diagnose.io import TIME_OF_DAY_FORMATS
from ..machine import HOURS_PER_YEAR
from .plotting import plain, png_bytes, pyplot, save_fig

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
                label=plain(corrected_label))
    named = {c.context for c in d.contexts if c.stands_out}
    shaded = False
    for loc in d.locations[:30]:
        if loc.get("run") == rd.run.name and loc["context"] in named:
            ax.axvspan(loc["start_s"] - origin, loc["end_s"] - origin, color="orange",
                       alpha=0.15, lw=0, label=None if shaded else "located gap")
            shaded = True
    ax.set_ylabel("flow (NL/min)")
    ax.set_xlabel(plain(label))
    ax.set_ylim(bottom=0)
    ax.grid(True, alpha=0.3)
    ax.set_title(plain(f"{rd.run.name}: meter readings"), fontsize=10)
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
                    label=plain(corrected_label) if first else None)
        offset = t[-1]
    ax.set_ylabel("cumulative air (NL)")
    ax.set_xlabel("logged time (s; runs one after another)")
    ax.grid(True, alpha=0.3)
    ax.set_title("cumulative air", fontsize=10)
    ax.legend(loc="upper left", fontsize=8)


def _draw_contexts(ax, d) -> None:
    """The residual per context (what the machine was doing), +/- 3 sigma of noise."""
    ctx = d.contexts[:12]
    ax.barh([plain(c.context) for c in ctx][::-1], [c.residual_nl for c in ctx][::-1],
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
    ax.barh([plain(a["consumer"]) for a in rows][::-1],
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
    fig.suptitle(plain(f"{d.machine.name}: verdict {d.verdict}; {SIGN_NOTE}"), fontsize=10)
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
    out = {"where": png_bytes(fig)}
    label = _corrected_label(d)
    fig, axes = plt.subplots(len(d.runs) + 1, 1, figsize=(11, 3.0 * (len(d.runs) + 1)),
                             constrained_layout=True, squeeze=False)
    for ax, rd, base, fixed in zip(axes[:, 0], d.runs, d.bases, d.best_params()):
        _draw_readings(ax, d, rd, base, fixed, label)
    _draw_cumulative(axes[-1, 0], d, label)
    out["readings"] = png_bytes(fig)
    return out


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
