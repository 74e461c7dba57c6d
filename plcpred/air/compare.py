"""Comparing the air use of two predictions: the CI gate behind ``plcpred compare``."""
from __future__ import annotations

import re
from dataclasses import dataclass


def parse_allowance(text: str) -> tuple[str, float]:
    """``"2%"`` -> ``("pct", 2.0)``; ``"0.5NL"`` (or ``"0.5L"``) -> ``("nl", 0.5)``."""
    t = text.strip().upper().replace(" ", "")
    m = re.fullmatch(r"([0-9.]+(?:E[+-]?\d+)?)(%|NL|L)", t)
    if not m:
        raise ValueError(f"an allowed increase is a percentage (2%) or normal litres "
                         f"(0.5NL), not {text!r}")
    value = float(m.group(1))
    return ("pct" if m.group(2) == "%" else "nl"), value


@dataclass
class Comparison:
    base: object            # Prediction
    new: object             # Prediction
    allowance: str
    allowed_increase_nl: float

    @property
    def delta_nl(self) -> float:
        return self.new.profile.total_nl - self.base.profile.total_nl

    @property
    def delta_pct(self) -> float:
        b = self.base.profile.total_nl
        return self.delta_nl / b * 100 if b else (0.0 if not self.delta_nl else float("inf"))

    @property
    def within_allowance(self) -> bool:
        return self.delta_nl <= self.allowed_increase_nl + 1e-9

    @property
    def new_moves(self) -> bool:
        """False when no valve of NEW ever leaves its rest over the horizon: a machine
        that never runs uses less air, and that must not pass the gate."""
        from ..sequencer import valves_moved

        return valves_moved(self.new.machine, self.new.timeline) is not False

    def stall_reason(self) -> str:
        """Why NEW does not move, from its warnings (an input nobody drives ...)."""
        why = [w.split(": ", 1)[-1] for w in self.new.machine.warnings
               if "nothing drives it" in w]
        return "; ".join(why) if why else "no valve output ever changes"

    @property
    def passes(self) -> bool:
        return self.within_allowance and self.new_moves

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
                "horizon_s": b.horizon_s, "delta_nl": self.delta_nl,
                "delta_pct": self.delta_pct, "max_increase": self.allowance,
                "allowed_increase_nl": self.allowed_increase_nl,
                "within_allowance": self.within_allowance, "new_moves": self.new_moves,
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
        lines.append(f"{'total':<{w}}  {b.total_nl:>10.2f}  {n.total_nl:>10.2f}  "
                     f"{self.delta_nl:>+10.2f}  {self.delta_pct:>+7.1f} %")
        if not self.new_moves:
            lines.append(f"FAIL: NEW never moves over {n.horizon_s:g} s ({self.stall_reason()})"
                         f"; its {self.delta_pct:+.1f} % says nothing about its air per part")
            return "\n".join(lines)
        verdict = "ok" if self.within_allowance else "FAIL"
        lines.append(f"{verdict}: new uses {self.delta_nl:+.2f} NL ({self.delta_pct:+.1f} %); "
                     f"allowed +{self.allowed_increase_nl:.2f} NL ({self.allowance})")
        return "\n".join(lines)


def compare(base, new=None, horizon="1h", max_increase: str = "0%", dt=None,
            program_base=None, program_new=None) -> Comparison:
    """Predict ``base`` and ``new`` (machine files or loaded machines; ``new`` defaults to
    ``base``, for comparing two programs) over the same horizon."""
    from .predict import predict

    kind, limit = parse_allowance(max_increase)
    if limit < 0:
        raise ValueError("the allowed increase must not be negative")
    b = predict(base, horizon, dt=dt, program=program_base)
    n = predict(new if new is not None else base, horizon, dt=dt, program=program_new)
    allowed = limit if kind == "nl" else b.profile.total_nl * limit / 100
    return Comparison(b, n, max_increase, allowed)
