"""The live comparison as a picture: what a watch wrote to ``events.jsonl``, drawn per
cycle. Above, each cycle's measured air against the learned reference and D1's
prediction; below, the gap to the reference per cycle and over the last ten cycles, the
alarm threshold, and where the gap alarm began. The stretches nothing was seen (gaps)
are shaded, the cycles the reference was learned from marked.

matplotlib is imported only when a picture is drawn (:func:`plot_comparison`): ``import
plcpred.live`` does not load it."""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path

from ..outputs.plotting import plain, pyplot, save_fig, time_axis
from .settings import LiveError

MAX_EVENT_LINE = 1_000_000     # a longer line is no event a watch wrote
MAX_LABELLED_ALARMS = 3        # alarms named on the picture (the others: their lines)


@dataclass
class _Watched:
    """What the picture needs of one watch's events, times in seconds from ``t0``: the
    start of its first segment unless given."""
    t0: datetime | None = None
    machine: str = ""
    limit_percent: float | None = None
    cycles: list = field(default_factory=list)      # (start s, end s, event)
    gaps: list = field(default_factory=list)        # (from s, to s)
    alarms: list = field(default_factory=list)      # (began s, event) of raised ones
    learned_to: int | None = None                   # the last learning cycle

    def seconds(self, text: str) -> float:
        return (_when(text) - self.t0).total_seconds()


def _when(text: str) -> datetime:
    return datetime.fromisoformat(str(text))


def read_events(path, since: datetime | None = None) -> _Watched:
    """The cycles, gaps, alarms and the learned reference of ``events.jsonl``, times
    from ``since`` (default: the first segment's start)."""
    w = _Watched(t0=since)
    seen = False
    try:
        f = open(path, encoding="utf-8")  # noqa: SIM115 - closed below, read line by line
    except OSError as e:
        raise LiveError(f"{path}: cannot read the watch's events: {e.strerror or e}") from None
    with f:
        for n, line in enumerate(f, 1):
            if len(line) > MAX_EVENT_LINE:
                raise LiveError(f"{path}:{n}: not a line a watch writes")
            try:
                e = json.loads(line)
            except ValueError:
                if line.strip():
                    raise LiveError(f"{path}:{n}: not a JSON line") from None
                continue
            seen = _take(w, e) or seen
    if not seen:
        raise LiveError(f"{path}: no segment recorded (no value seen): nothing to draw")
    return w


def _take(w: _Watched, e: dict) -> bool:
    """``e`` taken into ``w``; whether it is a segment's start."""
    kind = e.get("event") if isinstance(e, dict) else None
    if kind == "watch":
        w.machine = str(e.get("machine", ""))
        w.limit_percent = (e.get("settings") or {}).get("gap_alarm_percent")
    elif kind == "segment":
        if w.t0 is None:
            w.t0 = _when(e["start"])
        return True
    elif kind == "cycle" and w.t0 is not None:
        start = w.seconds(e["start"])
        w.cycles.append((start, start + float(e["duration_s"]), e))
    elif kind == "gap" and w.t0 is not None:
        w.gaps.append((w.seconds(e["from"]), w.seconds(e["to"])))
    elif kind == "alarm" and e.get("state") == "raised" and w.t0 is not None:
        w.alarms.append((w.seconds(e["began"]), e))
    elif kind == "reference_learned":
        w.learned_to = e.get("to_cycle")
    return False


def _mark_alarms_and_moments(w, top, low, scale: float, marks: dict | None) -> None:
    """Each alarm's onset (labelled up to MAX_LABELLED_ALARMS) and each of ``marks``
    as a vertical line on both axes."""
    box = {"facecolor": "white", "edgecolor": "none", "alpha": 0.8, "pad": 1}
    for k, (began, e) in enumerate(w.alarms):
        for ax in (top, low):
            ax.axvline(scale * began, color="tab:red", lw=1.2)
        if k >= MAX_LABELLED_ALARMS:
            continue                # more would hide one another: lines only
        low.text(scale * began, 0.45, f" {e.get('alarm', 'gap')} alarm raised at cycle "
                 f"{e.get('cycle', '?')}, onset here ", transform=low.get_xaxis_transform(),
                 color="tab:red", fontsize=8, ha="right", bbox=box)
    for label, at in (marks or {}).items():
        at_s = (at - w.t0).total_seconds() if isinstance(at, datetime) else float(at)
        for ax in (top, low):
            ax.axvline(scale * at_s, color="tab:orange", lw=1, ls="--")
        top.text(scale * at_s, 0.5, f" {plain(label)}", transform=top.get_xaxis_transform(),
                 color="tab:orange", fontsize=8, bbox=box)


def plot_comparison(out, path=None, marks: dict | None = None, since=None,
                    dpi: int = 100) -> Path:
    """Draw the comparison of the watch that wrote folder ``out`` (its
    ``events.jsonl``) to ``path`` (default ``out/comparison.png``); the picture's path.
    ``since``: (an absolute datetime, what it is) the time axis counts from, as
    ``(epoch, "the machine's start")`` (default: the watch's first value).
    ``marks``: more moments to mark, {label: seconds on that axis or an absolute
    datetime} (a fault switched on, a repair)."""
    out = Path(out)
    since_at, since_label = since if since is not None else (None, "the watch's first value")
    w = read_events(out / "events.jsonl", since_at)
    if not w.cycles:
        raise LiveError(f"{out / 'events.jsonl'}: no cycle compared yet: nothing to draw")
    path = Path(path) if path is not None else out / "comparison.png"
    end_s = max(c[1] for c in w.cycles)
    scale, unit = time_axis(end_s)
    plt = pyplot()
    fig, (top, low) = plt.subplots(2, 1, figsize=(10, 6), dpi=dpi, sharex=True,
                                   gridspec_kw={"height_ratios": [3, 2]})
    mid = [scale * (a + b) / 2 for a, b, _ in w.cycles]
    events = [e for _, _, e in w.cycles]

    def series(key):
        return [e.get(key) if e.get(key) is not None else float("nan") for e in events]

    top.plot(mid, series("measured_nl"), "o-", color="tab:blue", ms=3, lw=1,
             label="measured")
    top.plot(mid, series("reference_nl"), "-", color="tab:green", lw=1.5,
             label="learned reference")
    top.plot(mid, series("predicted_nl"), "--", color="0.45", lw=1,
             label="D1 (activation model)")
    top.set_ylabel("air per cycle (NL)")
    low.plot(mid, series("reference_gap_percent"), "o", color="tab:blue", ms=3,
             label="gap to the reference, per cycle")
    low.plot(mid, series("rolling_gap_percent"), "-", color="tab:purple", lw=1.5,
             label="rolling gap (last 10 cycles)")
    if w.limit_percent is not None:
        limit = float(w.limit_percent)
        low.axhspan(-limit, limit, color="tab:green", alpha=0.08, lw=0)
        for y in (-limit, limit):
            low.axhline(y, color="tab:red", lw=0.8, ls=":")
        low.text(scale * end_s, limit, f" alarm at ±{limit:g} %", color="tab:red",
                 va="bottom", ha="right", fontsize=8)
    low.axhline(0.0, color="0.3", lw=0.6)
    low.set_ylabel("gap (%)")
    low.set_xlabel(f"machine time from {plain(since_label)} ({unit})")
    for ax in (top, low):
        for a, b in w.gaps:
            ax.axvspan(scale * a, scale * b, color="0.85", lw=0)
        if w.learned_to:
            learned = [c for c in w.cycles if c[2].get("number", 0) <= w.learned_to]
            if learned:
                ax.axvspan(scale * learned[0][0], scale * learned[-1][1], color="tab:green",
                           alpha=0.06, lw=0)
        ax.grid(True, alpha=0.3)
    if w.learned_to:
        top.text(scale * w.cycles[0][0], 1.0, f" learning (cycles 1-{w.learned_to})",
                 transform=top.get_xaxis_transform(), va="top", fontsize=8,
                 color="tab:green")
    _mark_alarms_and_moments(w, top, low, scale, marks)
    top.legend(loc="upper left", bbox_to_anchor=(0.0, 0.93), fontsize=8)
    low.legend(loc="upper left", fontsize=8)
    top.set_title(f"{plain(w.machine)}: measured air per cycle against the prediction"
                  + (f", {len(w.gaps)} gap{'s' * (len(w.gaps) != 1)}" if w.gaps else ""),
                  fontsize=10)
    fig.tight_layout()
    save_fig(fig, path)
    return path
