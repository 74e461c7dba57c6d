"""Comparing the air use of two predictions: the CI gate behind ``plcpred compare``."""
from __future__ import annotations

import functools
import re
from dataclasses import dataclass

from ..sequencer import valves_moved
from .cycles import cycles_of
from .predict import predict


def parse_allowance(text: str) -> tuple[str, float]:
    """``"2%"`` -> ``("pct", 2.0)``; ``"0.5NL"`` (or ``"0.5L"``) -> ``("nl", 0.5)``."""
    t = text.strip().upper().replace(" ", "")
    m = re.fullmatch(r"([0-9.]+(?:E[+-]?\d+)?)(%|NL|L)", t)
    if not m:
        raise ValueError(f"an allowed increase is a percentage (2%) or normal litres "
                         f"(0.5NL), not {text!r}")
    value = float(m.group(1))
    return ("pct" if m.group(2) == "%" else "nl"), value


DEFAULT_MAX_THROUGHPUT_DROP_PCT = 5.0


@dataclass
class Comparison:
    """BASE against NEW. Air is compared per cycle when both machines have one (a
    ``cycle_signal`` or a repeating state, :mod:`~plcpred.air.cycles`), else over the
    horizon; NEW also fails when it never moves or its throughput drops by more than
    ``max_throughput_drop_pct``."""
    base: object            # Prediction
    new: object             # Prediction
    allowance: str
    max_throughput_drop_pct: float = DEFAULT_MAX_THROUGHPUT_DROP_PCT

    @functools.cached_property
    def cycles(self) -> tuple:
        """(base, new) :class:`~plcpred.air.cycles.Cycles` (or None)."""

        return tuple(cycles_of(p.machine, p.timeline, p.profile)
                     for p in (self.base, self.new))

    @property
    def per_cycle(self) -> bool:
        """Whether the gate compares air per cycle (both have a steady cycle)."""
        return all(c is not None and c.nl_per_cycle is not None for c in self.cycles)

    def _figures(self) -> tuple[float, float]:
        """(base, new) NL per cycle when compared per cycle, else over the horizon."""
        if self.per_cycle:
            return self.cycles[0].nl_per_cycle, self.cycles[1].nl_per_cycle
        return self.base.profile.total_nl, self.new.profile.total_nl

    @property
    def allowed_increase_nl(self) -> float:
        kind, limit = parse_allowance(self.allowance)
        return limit if kind == "nl" else self._figures()[0] * limit / 100

    @property
    def delta_nl(self) -> float:
        """NEW - BASE, NL per cycle when compared per cycle, else over the horizon."""
        b, n = self._figures()
        return n - b

    @property
    def delta_pct(self) -> float:
        b = self._figures()[0]
        return self.delta_nl / b * 100 if b else (0.0 if not self.delta_nl else float("inf"))

    @property
    def within_allowance(self) -> bool:
        return self.delta_nl <= self.allowed_increase_nl + 1e-9

    @property
    def throughput_drop_pct(self) -> float | None:
        """How much NEW's cycles per hour fall short of BASE's (100: NEW completes no
        cycle); None when BASE has no cycle to compare with."""
        b, n = self.cycles
        if b is None or b.per_hour is None:
            return None
        if n is None:
            return None if self.new.machine.cycle_signal is None else 100.0
        if n.per_hour is None:
            return 100.0
        return (1.0 - n.per_hour / b.per_hour) * 100.0

    @property
    def throughput_ok(self) -> bool:
        drop = self.throughput_drop_pct
        return drop is None or drop <= self.max_throughput_drop_pct + 1e-9

    @property
    def new_moves(self) -> bool:
        """False when no valve of NEW ever leaves its rest over the horizon: a machine
        that never runs uses less air, and that must not pass the gate."""

        return valves_moved(self.new.machine, self.new.timeline) is not False

    def stall_reason(self) -> str:
        """Why NEW does not move, from its warnings (an input nobody drives ...)."""
        why = [w.split(": ", 1)[-1] for w in self.new.machine.warnings
               if "nothing drives it" in w]
        return "; ".join(why) if why else "no valve output ever changes"

    @property
    def passes(self) -> bool:
        return self.within_allowance and self.new_moves and self.throughput_ok

    def rows(self) -> list[dict]:
        b, n = self.base.profile, self.new.profile
        bt, nt = dict(zip(b.names, b.consumer_nl)), dict(zip(n.names, n.consumer_nl))
        out = []
        for name in dict.fromkeys(b.names + n.names):
            x, y = float(bt.get(name, 0.0)), float(nt.get(name, 0.0))
            out.append({"consumer": name, "base_nl": x, "new_nl": y, "delta_nl": y - x,
                        "delta_pct": (y - x) / x * 100 if x else None,
                        "only_in": "base" if name not in nt else "new" if name not in bt
                        else None})
        return out

    def to_dict(self) -> dict:
        b, n = self.base.profile, self.new.profile
        return {"base": {"machine": self.base.machine.name, "total_nl": b.total_nl,
                         "mean_l_min": b.mean_l_min, "peak_l_min": b.peak_l_min()},
                "new": {"machine": self.new.machine.name, "total_nl": n.total_nl,
                        "mean_l_min": n.mean_l_min, "peak_l_min": n.peak_l_min()},
                "horizon_s": b.horizon_s, "per": "cycle" if self.per_cycle else "horizon",
                "delta_nl": self.delta_nl, "delta_pct": self.delta_pct,
                "max_increase": self.allowance,
                "allowed_increase_nl": self.allowed_increase_nl,
                "within_allowance": self.within_allowance,
                "cycles": {"base": None if self.cycles[0] is None else
                           self.cycles[0].to_dict(),
                           "new": None if self.cycles[1] is None else
                           self.cycles[1].to_dict()},
                "throughput_drop_pct": self.throughput_drop_pct,
                "max_throughput_drop_pct": self.max_throughput_drop_pct,
                "throughput_ok": self.throughput_ok, "new_moves": self.new_moves,
                "passes": self.passes, "consumers": self.rows()}

    def table(self) -> str:
        """The per-consumer table and verdict, readable in a CI log."""
        rows = self.rows()
        b, n = self.base.profile, self.new.profile
        w = max([8] + [len(r["consumer"]) for r in rows])
        lines = [f"air use over {b.horizon_s:g} s: base {self.base.machine.name}, "
                 f"new {self.new.machine.name}",
                 f"{'consumer':<{w}}  {'base NL':>10}  {'new NL':>10}  {'delta NL':>10}  "
                 f"{'delta':>8}", "-" * (w + 46)]
        for r in rows:
            pct = "" if r["delta_pct"] is None else f"{r['delta_pct']:+.1f} %"
            note = f"  (only in {r['only_in']})" if r["only_in"] else ""
            lines.append(f"{r['consumer']:<{w}}  {r['base_nl']:>10.2f}  {r['new_nl']:>10.2f}"
                         f"  {r['delta_nl']:>+10.2f}  {pct:>8}{note}")
        lines.append("-" * (w + 46))
        total = n.total_nl - b.total_nl
        lines.append(f"{'total':<{w}}  {b.total_nl:>10.2f}  {n.total_nl:>10.2f}  "
                     f"{total:>+10.2f}  "
                     f"{total / b.total_nl * 100 if b.total_nl else 0.0:>+7.1f} %")
        for label, c in zip(("base", "new"), self.cycles):
            lines.append(f"cycles of {label}: " + ("none found (no cycle_signal, no repeating "
                                                   "state)" if c is None else _cycle_text(c)))
        if not self.new_moves:
            lines.append(f"FAIL: NEW never moves over {n.horizon_s:g} s ({self.stall_reason()})"
                         f"; its {self.delta_pct:+.1f} % says nothing about its air per part")
            return "\n".join(lines)
        per = " per cycle" if self.per_cycle else f" over {n.horizon_s:g} s"
        verdict = "ok" if self.within_allowance else "FAIL"
        lines.append(f"{verdict}: new uses {self.delta_nl:+.2f} NL{per} ({self.delta_pct:+.1f} %)"
                     f"; allowed +{self.allowed_increase_nl:.2f} NL ({self.allowance})")
        drop = self.throughput_drop_pct
        if drop is not None:
            verdict = "ok" if self.throughput_ok else "FAIL"
            what = ("NEW never completes a cycle" if drop >= 100.0 else
                    f"throughput {0.0 - drop:+.1f} %")
            lines.append(f"{verdict}: {what}; allowed -{self.max_throughput_drop_pct:g} % "
                         "(--max-throughput-drop)")
        return "\n".join(lines)


def _cycle_text(c) -> str:
    if c.cycle_s is None:
        return f"{c.count} by {c.source}, too few for a steady cycle"
    return (f"{c.cycle_s:.3g} s ({c.per_hour:.4g} per hour), {c.nl_per_cycle:.3f} NL per "
            f"cycle, by {c.source}")


def compare(base, new=None, horizon="1h", max_increase: str = "0%", dt=None,
            program_base=None, program_new=None,
            max_throughput_drop_pct: float = DEFAULT_MAX_THROUGHPUT_DROP_PCT) -> Comparison:
    """Predict ``base`` and ``new`` (machine files or loaded machines; ``new`` defaults to
    ``base``, for comparing two programs) over the same horizon."""

    kind, limit = parse_allowance(max_increase)
    if limit < 0:
        raise ValueError("the allowed increase must not be negative")
    if not 0.0 <= max_throughput_drop_pct <= 100.0:
        raise ValueError("the allowed throughput drop is a percentage from 0 to 100")
    b = predict(base, horizon, dt=dt, program=program_base)
    n = predict(new if new is not None else base, horizon, dt=dt, program=program_new)
    return Comparison(b, n, max_increase, max_throughput_drop_pct)
