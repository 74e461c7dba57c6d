"""The sequencer's result: the edges of every input, output and SFC step flag over a
horizon, with helpers to ask for a signal's intervals. Contract for ``timeline.csv``:
``shared/design.md`` ("Files"): ``time_s,signal,value``, one row per change, every signal's
initial value at time 0, sorted by time and stable within a scan (inputs as the scan read
them, then step flags, then outputs). BOOL values are written 1/0.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..output import atomic_write_text

if TYPE_CHECKING:  # pandas is imported where a DataFrame is built
    import pandas as pd

from ..parser.literals import parse_duration_ns

NS = 1_000_000_000


@dataclass(frozen=True)
class Signal:
    name: str
    kind: str    # "input" | "output" | "step"
    dtype: str   # "bool" | "int" | "real" | "time" | ...


class Timeline:
    """Edges as parallel arrays (``time_ns``, signal index, value), sorted by time."""

    def __init__(self, signals: list[Signal], time_ns, signal_idx, values, horizon_ns: int,
                 info: dict | None = None):
        self.signals = list(signals)
        self.time_ns = np.asarray(time_ns, dtype=np.int64)
        self.signal_idx = np.asarray(signal_idx, dtype=np.int32)
        self.values = np.asarray(values, dtype=np.float64)
        self.horizon_ns = int(horizon_ns)
        self.info = dict(info or {})
        self._index = {s.name.upper(): i for i, s in enumerate(self.signals)}

    # ------------------------------------------------------------------ access
    @property
    def horizon_s(self) -> float:
        return self.horizon_ns / NS

    @property
    def names(self) -> list[str]:
        return [s.name for s in self.signals]

    def signal(self, name: str) -> Signal:
        return self.signals[self._idx(name)]

    def _idx(self, name: str) -> int:
        try:
            return self._index[name.upper()]
        except KeyError:
            raise KeyError(f"no signal '{name}' in the timeline (signals: "
                           f"{', '.join(self.names)})") from None

    @property
    def df(self) -> "pd.DataFrame":
        """``time_s, signal, value`` as a DataFrame (one row per change)."""
        import pandas as pd  # only here: importing pandas costs half a second

        names = np.array(self.names, dtype=object)
        return pd.DataFrame({"time_s": self.time_ns / NS,
                             "signal": names[self.signal_idx] if len(names) else [],
                             "value": self.values})

    def edges(self, name: str) -> "pd.DataFrame":
        """The changes of one signal: ``time_s, value`` (the first row is its initial
        value at 0)."""
        import pandas as pd

        m = self.signal_idx == self._idx(name)
        return pd.DataFrame({"time_s": self.time_ns[m] / NS, "value": self.values[m]})

    def edge_times_ns(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        m = self.signal_idx == self._idx(name)
        return self.time_ns[m], self.values[m]

    def intervals(self, name: str) -> "pd.DataFrame":
        """Periods in which the signal is non-zero (TRUE): ``start_s, end_s, duration_s``;
        a period still open at the horizon ends there."""
        import pandas as pd

        t, v = self.edge_times_ns(name)
        on = v != 0
        starts, ends = [], []
        start = None
        for ti, oi in zip(t.tolist(), on.tolist()):
            if oi and start is None:
                start = ti
            elif not oi and start is not None:
                starts.append(start)
                ends.append(ti)
                start = None
        if start is not None:
            starts.append(start)
            ends.append(self.horizon_ns)
        s = np.asarray(starts, dtype=np.int64) / NS
        e = np.asarray(ends, dtype=np.int64) / NS
        return pd.DataFrame({"start_s": s, "end_s": e, "duration_s": e - s})

    def value_at(self, name: str, time_s: float):
        t, v = self.edge_times_ns(name)
        k = np.searchsorted(t, round(time_s * NS), side="right") - 1
        return v[max(k, 0)]

    def on_time_s(self, name: str) -> float:
        return float(self.intervals(name)["duration_s"].sum())

    def count_rising(self, name: str) -> int:
        _, v = self.edge_times_ns(name)
        on = v != 0
        return int(np.count_nonzero(on[1:] & ~on[:-1]))

    def __eq__(self, other) -> bool:
        return (isinstance(other, Timeline) and self.names == other.names
                and self.horizon_ns == other.horizon_ns
                and np.array_equal(self.time_ns, other.time_ns)
                and np.array_equal(self.signal_idx, other.signal_idx)
                and np.array_equal(self.values, other.values))

    def __repr__(self) -> str:
        return (f"Timeline({len(self.signals)} signals, {len(self.time_ns)} edges, "
                f"horizon {self.horizon_s:g} s)")

    # ------------------------------------------------------------------ files
    def to_csv(self, path) -> None:
        """Write ``timeline.csv`` (through a temporary file, so a failed run never leaves
        a half-written one)."""
        path = Path(path)
        names = self.names
        real = [s.dtype == "real" for s in self.signals]
        times = {}
        lines = ["time_s,signal,value\n"]
        append = lines.append
        for t, i, v in zip(self.time_ns.tolist(), self.signal_idx.tolist(),
                           self.values.tolist()):
            ts = times.get(t)
            if ts is None:
                ts = times[t] = format_seconds(t)
            append(f"{ts},{names[i]},{v!r}\n" if real[i] else f"{ts},{names[i]},{int(v)}\n")
        atomic_write_text(path, "".join(lines))


def format_seconds(t_ns: int) -> str:
    """Exact decimal seconds from integer nanoseconds (``12.3``, ``0``)."""
    sign = "-" if t_ns < 0 else ""
    t_ns = abs(t_ns)
    whole, frac = divmod(t_ns, NS)
    if not frac:
        return f"{sign}{whole}"
    return f"{sign}{whole}.{frac:09d}".rstrip("0")


_PLAIN = re.compile(r"^\s*(\d+(?:\.\d*)?|\.\d+)\s*(d|h|min|m|s|ms|us|ns)?\s*$", re.I)


def parse_horizon(text) -> int:
    """A horizon in nanoseconds from ``T#1m30s``, ``TIME#8h``, ``90s``, ``1.5h``, ``8h``,
    ``500ms`` or a plain number of seconds. ``m`` is minutes, as in IEC literals."""
    if isinstance(text, (int, float)):
        ns = round(float(text) * NS)
    else:
        s = str(text).strip()
        up = s.upper()
        try:
            if up.startswith(("T#", "TIME#", "LT#", "LTIME#")):
                ns = parse_duration_ns(s.split("#", 1)[1])
            else:
                m = _PLAIN.match(s)
                if m:
                    unit = (m.group(2) or "s").lower()
                    unit = "m" if unit == "min" else unit
                    ns = parse_duration_ns(m.group(1) + unit)
                else:
                    ns = parse_duration_ns(s.replace(" ", ""))
        except ValueError:
            raise ValueError(f"cannot read the horizon {text!r}: write e.g. 60s, 1m30s, 8h "
                             "or T#1m30s") from None
    if ns <= 0:
        raise ValueError(f"the horizon must be positive, not {text!r}")
    return ns
