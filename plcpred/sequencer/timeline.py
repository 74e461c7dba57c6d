"""The sequencer's result: the edges of every input, output and SFC step flag over a
horizon, with helpers to ask for a signal's intervals. ``timeline.csv``
(docs/guide/predict.md, ``plcpred timeline``): ``time_s,signal,value``, one row per
change, every signal's initial value at time 0, sorted by time and stable within a scan
(inputs as the scan read them, then step flags, then outputs). BOOL values are written
1/0.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..errors import PlcpredError
from ..output import atomic_writer

if TYPE_CHECKING:  # pandas is imported where a DataFrame is built
    import pandas as pd

from ..parser.literals import parse_duration_ns

NS = 1_000_000_000


@dataclass(frozen=True)
class Signal:
    name: str
    kind: str    # "input" | "output" | "step"
    dtype: str   # "bool" | "int" | "real" | "time" | ...


class TimelineTooLarge(PlcpredError):
    """More changes than a run may hold in memory (``max_changes``)."""


DEFAULT_MAX_CHANGES = 20_000_000  # about 400 MB of edge arrays


class Timeline:
    """Edges as parallel arrays (``time_ns``, signal index, value), sorted by time.

    A machine that repeats its cycle is stored as the edges up to the end of the first
    repetition plus the period (``tiled``): ``to_csv`` and ``n_changes`` work from that in
    bounded memory however long the horizon, and the full arrays are built only when
    asked for, refused with :class:`TimelineTooLarge` beyond ``max_changes``.

    Likewise a run that replays recorded parts (``replays``: for each replay the number of
    executed edges before it, its start time and which part, and the parts' edges with
    times from their start) holds each part once and 20 bytes a replay, and one merged
    from several runs (``sources``: (timeline, which signals it gives) pairs, the
    islands of a program) holds the runs."""

    def __init__(self, signals: list[Signal], time_ns, signal_idx, values, horizon_ns: int,
                 info: dict | None = None, tiled: tuple[int, int] | None = None,
                 max_changes: int = DEFAULT_MAX_CHANGES, drift: dict | None = None,
                 replays: tuple | None = None, sources: list | None = None):
        self.signals = list(signals)
        self._base = (np.asarray(time_ns, dtype=np.int64),
                      np.asarray(signal_idx, dtype=np.int32),
                      np.asarray(values, dtype=np.float64))
        self.horizon_ns = int(horizon_ns)
        self.info = dict(info or {})
        self.tiled = tiled
        # signal index -> (step, bits, signed): a count that each repetition of the period
        # shows ``step`` higher than the one before, modulo its integer width
        self.drift = {int(k): v for k, v in (drift or {}).items() if v[0]}
        self.max_changes = int(max_changes)
        self._replays = replays if replays is not None and len(replays[0]) else None
        self._sources = sources or None
        self._count = None
        self._full = None if (tiled is not None or self._replays is not None
                              or self._sources is not None) else self._base
        self._period = None
        self._index = {s.name.upper(): i for i, s in enumerate(self.signals)}

    # ------------------------------------------------------------------ edges
    def _period_edges(self):
        """(edge times, signals, values) of one period (t1, t2], and the number of
        repetitions after t2 that start within the horizon."""
        if self._period is None:
            t1, t2 = self.tiled
            t, s, v = self._base
            m = (t > t1) & (t <= t2)
            reps = max(0, int((self.horizon_ns - t2) // (t2 - t1)) + 1) if m.any() else 0
            self._period = (t[m], s[m], v[m], reps)
        return self._period

    @property
    def n_changes(self) -> int:
        """How many rows ``timeline.csv`` has (without building the arrays)."""
        if self._full is not None:
            return len(self._full[0])
        if self._replays is not None:
            _, _, pid, parts = self._replays
            sizes = np.array([len(p[0]) for p in parts], dtype=np.int64)
            return len(self._base[0]) + int(_times_replayed(pid, len(parts)) @ sizes)
        if self._sources is not None:
            if self._count is None:
                self._count = sum(tl.count_of(mine) for tl, mine in self._sources)
            return self._count
        t1, t2 = self.tiled
        pt, _, _, reps = self._period_edges()
        if not reps:
            return len(self._base[0])
        p = t2 - t1
        last = self.horizon_ns - reps * p  # the last repetition keeps edges <= last
        return len(self._base[0]) + (reps - 1) * len(pt) + int(np.count_nonzero(pt <= last))

    def count_of(self, mine: np.ndarray) -> int:
        """How many changes the signals ``mine`` marks (booleans by signal index) have."""
        if self._full is not None:
            return int(np.count_nonzero(mine[self._full[1]]))
        if self._replays is not None:
            _, _, pid, parts = self._replays
            per_part = np.array([np.count_nonzero(mine[p[1]]) for p in parts], dtype=np.int64)
            return int(np.count_nonzero(mine[self._base[1]])) + int(
                _times_replayed(pid, len(parts)) @ per_part)
        return sum(int(np.count_nonzero(mine[c[1]])) for c in self.chunks())

    def _materialize(self):
        if self._full is None:
            n = self.n_changes
            if n > self.max_changes:
                raise TimelineTooLarge(
                    f"{n:,} signal changes over {self.horizon_s:g} s exceed the limit of "
                    f"{self.max_changes:,} held in memory (--max-events); timeline.csv "
                    "streams any length, the air model needs a shorter --horizon")
            if self._replays is not None or self._sources is not None:
                parts = list(self.chunks(max(n, 1)))
                self._full = tuple(np.concatenate([p[k] for p in parts]) for k in range(3))
                return self._full
            t, s, v = self._base
            reps = self._period_edges()[3]
            if reps:
                tt, ss, vv = self._repetitions(1, reps)
                t, s, v = np.concatenate([t, tt]), np.concatenate([s, ss]), \
                    np.concatenate([v, vv])
            self._full = (t, s, v)
        return self._full

    def _repetitions(self, first: int, last: int, only: int | None = None,
                     until_ns: int | None = None):
        """(times, signals, values) of repetitions ``first..last`` of the period (of
        signal ``only``), cut at the horizon (or ``until_ns``)."""
        pt, ps, pv, _ = self._period_edges()
        if only is not None:
            mine = ps == only
            pt, ps, pv = pt[mine], ps[mine], pv[mine]
        k = np.arange(first, last + 1, dtype=np.int64)
        tt = (pt[None, :] + k[:, None] * (self.tiled[1] - self.tiled[0])).ravel()
        keep = tt <= (self.horizon_ns if until_ns is None else until_ns)
        ss, vv = np.tile(ps, len(k)), np.tile(pv, len(k))
        if self.drift:
            kk = np.repeat(k, len(pt))
            for i, (step, bits, signed) in self.drift.items():
                mine = ss == i
                vv[mine] = wrap_array(vv[mine].astype(np.int64) + kk[mine] * int(step),
                                    bits, signed)
        return tt[keep], ss[keep], vv[keep]

    @property
    def time_ns(self) -> np.ndarray:
        return self._materialize()[0]

    @property
    def signal_idx(self) -> np.ndarray:
        return self._materialize()[1]

    @property
    def values(self) -> np.ndarray:
        return self._materialize()[2]

    def chunks(self, rows: int = 1_000_000):
        """The edges in time order as (times, signals, values) arrays of about ``rows``
        each, built one at a time (a tiled timeline repeats its period)."""
        if self._full is not None:
            t, s, v = self._full
            for a in range(0, max(len(t), 1), rows):
                yield t[a:a + rows], s[a:a + rows], v[a:a + rows]
            return
        if self._replays is not None:
            yield from self._replayed_chunks(rows)
            return
        if self._sources is not None:
            yield from self._merged_chunks(rows)
            return
        yield self._base
        pt, _, _, reps = self._period_edges()
        per_chunk = max(1, rows // max(len(pt), 1))
        for k0 in range(1, reps + 1, per_chunk):
            yield self._repetitions(k0, min(reps, k0 + per_chunk - 1))

    def _replayed_chunks(self, rows: int):
        """The executed edges with each replayed part's in between, in about ``rows``."""
        t, s, v = self._base
        parts = self._replays[3]
        out, n, done = [], 0, 0
        for p, st, k in _replays_in_blocks(self._replays):
            if p > done:
                out.append((t[done:p], s[done:p], v[done:p]))
                n += p - done
                done = p
            pt, ps, pv = parts[k]
            out.append((pt + st, ps, pv))
            n += len(pt)
            if n >= rows:
                yield tuple(np.concatenate([o[j] for o in out]) for j in range(3))
                out, n = [], 0
        out.append((t[done:], s[done:], v[done:]))
        yield tuple(np.concatenate([o[j] for o in out]) for j in range(3))

    def _merged_chunks(self, rows: int):
        """The sources' edges (each only its own signals) merged by time, and within a
        time by signal (the order one run records a scan's changes in)."""
        streams = [_own(tl, mine, rows) for tl, mine in self._sources]
        empty = (np.zeros(0, np.int64), np.zeros(0, np.int32), np.zeros(0, np.float64))
        held, ended = [empty] * len(streams), [False] * len(streams)

        def pull(k) -> None:
            nxt = next(streams[k], None)
            if nxt is None:
                ended[k] = True
            else:
                held[k] = tuple(np.concatenate([a, b]) for a, b in zip(held[k], nxt))

        while True:
            for k in range(len(streams)):
                while not ended[k] and not len(held[k][0]):
                    pull(k)
            if not any(len(h[0]) for h in held):
                return
            # everything up to the earliest last time among the sources still running
            # can go, once those ending at that time hold all of it (a time may span
            # two chunks)
            lasts = [h[0][-1] for h, e in zip(held, ended) if not e and len(h[0])]
            upto = min(lasts) if lasts else None
            if upto is not None:
                for k in range(len(streams)):
                    while not ended[k] and len(held[k][0]) and held[k][0][-1] == upto:
                        pull(k)
            take = []
            for k, h in enumerate(held):
                cut = len(h[0]) if upto is None else int(np.searchsorted(h[0], upto, "right"))
                take.append(tuple(x[:cut] for x in h))
                held[k] = tuple(x[cut:] for x in h)
            t, s, v = (np.concatenate([x[j] for x in take]) for j in range(3))
            order = np.lexsort((s, t))
            yield t[order], s[order], v[order]

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
        # pandas costs half a second to import: only its users pay it
        import pandas as pd

        names = np.array(self.names, dtype=object)
        return pd.DataFrame({"time_s": self.time_ns / NS,
                             "signal": names[self.signal_idx] if len(names) else [],
                             "value": self.values})

    def to_frame(self) -> pd.DataFrame:
        """The timeline in wide form as a pandas DataFrame: indexed by ``time_s``, one
        row per time at which some signal changes (the first at 0 holds every initial
        value), one column per signal (named as in the program, in the timeline's order)
        holding its value from that time on: ``bool`` for BOOL signals, numbers for the
        others. The long form, one row per change, is :attr:`df` (``timeline.csv``'s
        rows). A repeating machine's timeline is expanded over the whole horizon (times x
        signals values: refused with :class:`TimelineTooLarge` where the changes are)."""
        # pandas is imported here: it is heavy (half a second), and most runs never need it
        import pandas as pd

        t, s, v = self.time_ns, self.signal_idx, self.values
        times, row = np.unique(t, return_inverse=True)
        n = len(self.signals)
        grid = np.full((len(times), n), np.nan)
        if len(t):
            # a signal changed twice at one time keeps its last value (edges are in order)
            key = row.astype(np.int64) * n + s
            _, last_rev = np.unique(key[::-1], return_index=True)
            keep = len(key) - 1 - last_rev
            grid[row[keep], s[keep]] = v[keep]
        frame = pd.DataFrame(grid, columns=self.names,
                             index=pd.Index(times / NS, name="time_s")).ffill()
        for sig in self.signals:
            column = frame[sig.name]
            if sig.dtype == "bool":
                frame[sig.name] = column.fillna(0.0).astype(bool)
            elif sig.dtype not in ("real", "lreal") and not column.isna().any() \
                    and bool((column == column.round()).all()):
                frame[sig.name] = column.astype(np.int64)
        return frame

    def edges(self, name: str) -> "pd.DataFrame":
        """The changes of one signal: ``time_s, value`` (the first row is its initial
        value at 0)."""
        # pandas costs half a second to import: only its users pay it
        import pandas as pd

        t, v = self.edge_times_ns(name)
        return pd.DataFrame({"time_s": t / NS, "value": v})

    def executed_edge_times_ns(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """``edge_times_ns`` over the part the executor ran (for a tiled run: up to the
        end of the first period, which the rest repeats), without building the whole."""
        if self._sources is not None:
            return self._source(name).executed_edge_times_ns(name)
        t, s, v = self._base
        m = s == self._idx(name)
        return t[m], v[m]

    def _source(self, name: str):
        i = self._idx(name)
        return next(tl for tl, mine in self._sources if mine[i])

    def edge_times_ns(self, name: str, until_ns: int | None = None
                      ) -> tuple[np.ndarray, np.ndarray]:
        """(times, values) of one signal's changes, the first its initial value at 0
        (with ``until_ns``, only those up to then). A tiled timeline repeats just this
        signal's edges of the period (the whole timeline is not built)."""
        i = self._idx(name)
        end = self.horizon_ns if until_ns is None else min(int(until_ns), self.horizon_ns)
        if self._sources is not None:
            return self._source(name).edge_times_ns(name, until_ns)
        if self._full is None and self._replays is not None:
            return self._replayed_edges(i, end)
        if self._full is not None:
            t, s, v = self._full
            m = (s == i) & (t <= end)
            return t[m], v[m]
        t, s, v = self._base
        m = (s == i) & (t <= end)
        _, ps, _, reps = self._period_edges()
        per_period = int(np.count_nonzero(ps == i))
        if reps:
            t1, t2 = self.tiled
            reps = min(reps, max(0, int((end - t2) // (t2 - t1)) + 1))
        if not reps or not per_period:
            return t[m], v[m]
        if reps * per_period > self.max_changes:
            raise TimelineTooLarge(
                f"{reps * per_period:,} changes of {self.names[i]} over {self.horizon_s:g} s "
                f"exceed the limit of {self.max_changes:,} held in memory (--max-events); "
                "the air model needs a shorter --horizon")
        tt, _, vv = self._repetitions(1, reps, only=i, until_ns=end)
        return np.concatenate([t[m], tt]), np.concatenate([v[m], vv])

    def _replayed_edges(self, i: int, end: int) -> tuple[np.ndarray, np.ndarray]:
        """One signal's edges of a run that replayed parts, up to ``end``."""
        t, s, v = self._base
        _, _, pid, parts = self._replays
        mine = [(pt[ps == i], pv[ps == i]) for pt, ps, pv in parts]
        counts = np.array([len(m[0]) for m in mine], dtype=np.int64)
        total = int(_times_replayed(pid, len(parts)) @ counts)
        if total > self.max_changes:
            raise TimelineTooLarge(
                f"{total:,} changes of {self.names[i]} over "
                f"{self.horizon_s:g} s exceed the limit of {self.max_changes:,} held in "
                "memory (--max-events); the air model needs a shorter --horizon")
        base = s == i
        # the executed edges and the replays' in time order: a replay comes before the
        # executed edges from its position on
        tt, vv = [], []
        at = np.flatnonzero(base)
        done = 0
        for p, st, k in _replays_in_blocks(self._replays):
            j = int(np.searchsorted(at, p))
            if j > done:
                tt.append(t[at[done:j]])
                vv.append(v[at[done:j]])
                done = j
            if counts[k]:
                tt.append(mine[k][0] + st)
                vv.append(mine[k][1])
        tt.append(t[at[done:]])
        vv.append(v[at[done:]])
        t_all, v_all = np.concatenate(tt), np.concatenate(vv)
        keep = t_all <= end
        return t_all[keep], v_all[keep]

    def intervals(self, name: str) -> "pd.DataFrame":
        """Periods in which the signal is non-zero (TRUE): ``start_s, end_s, duration_s``;
        a period still open at the horizon ends there."""
        # pandas costs half a second to import: only its users pay it
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
    def to_csv(self, path, rows_per_write: int = 200_000) -> None:
        """Write ``timeline.csv`` in pieces (bounded memory at any horizon), through a
        temporary file, so a failed run never leaves a half-written one. A tiled
        timeline's repetitions are written from the period's rows formatted once (only
        the whole seconds change from one repetition to the next)."""
        with atomic_writer(path) as f:
            f.write("time_s,signal,value\n")
            if self._full is not None or self.tiled is None:
                for t, s, v in self.chunks(rows_per_write):
                    f.write(self._rows(t, s, v))
                return
            f.write(self._rows(*self._base))
            pt, ps, pv, reps = self._period_edges()
            if not reps:
                return
            if self.drift:          # counts change from one repetition to the next
                pieces = self.chunks(rows_per_write)
                next(pieces)        # the executed part, written above
                for t, s, v in pieces:
                    f.write(self._rows(t, s, v))
                return
            t1, t2 = self.tiled
            p = t2 - t1
            # full repetitions k = 1..reps-1 by the fast path; the last one may be cut
            # by the horizon and goes through the general one
            cycle = NS // math.gcd(p, NS)  # repetitions after which the fractions repeat
            per_write = max(1, rows_per_write // max(len(pt), 1))
            if cycle * len(pt) <= 200_000:
                # per residue of k modulo the cycle: each row's whole-second carry and
                # its text after the whole seconds (fraction, signal, value)
                tails = [r.split(",", 1)[1] for r in self._rows(pt, ps, pv).splitlines(True)]
                ks = np.arange(cycle, dtype=np.int64)
                starts = pt[None, :] + ks[:, None] * p
                carries = starts // NS - (ks * p // NS)[:, None]
                suffixes = [[_frac_text(x) + "," + tail for x, tail in zip(row, tails)]
                            for row in (starts % NS).tolist()]
            for k in range(1, reps, per_write):
                kk = np.arange(k, min(reps, k + per_write), dtype=np.int64)
                if cycle * len(pt) > 200_000:
                    f.write(self._rows(*self._repetitions(k, int(kk[-1]))))
                    continue
                res = kk % cycle
                wholes = (carries[res] + (kk * p // NS)[:, None]).ravel().tolist()
                suf = suffixes[0] * len(kk) if cycle == 1 else [
                    x for r in res.tolist() for x in suffixes[r]]
                f.write("".join(map(str.__add__, map(str, wholes), suf)))
            f.write(self._rows(*self._repetitions(reps, reps)))

    def _rows(self, t, sig, val) -> str:
        """CSV rows for edges (general path: any times). Each distinct fraction of a
        second and each distinct (signal, value) is formatted once: a run has few of
        either (times fall on scans, a BOOL has two values)."""
        t = np.asarray(t, dtype=np.int64)
        if not len(t):
            return ""
        names = [_csv_field(n) for n in self.names]
        real = [s.dtype == "real" for s in self.signals]
        # (signal, value) pairs as one integer code: sorting codes is fast, rows are not
        vals, val_k = np.unique(np.asarray(val, dtype=np.float64), return_inverse=True)
        codes, pair_k = np.unique(np.asarray(sig, dtype=np.int64) * len(vals) + val_k.ravel(),
                                  return_inverse=True)
        vals = vals.tolist()
        pair_text = [f"{names[i]},{vals[k]!r}" if real[i] else f"{names[i]},{int(vals[k])}"
                     for i, k in (divmod(c, len(vals)) for c in codes.tolist())]
        if (t < 0).any():                        # not from the sequencer; the slow way
            return "".join(f"{format_seconds(x)},{pair_text[p]}\n"
                           for x, p in zip(t.tolist(), pair_k.ravel().tolist()))
        whole, frac_k, frac_text = seconds_texts(t)
        return "".join([f"{w}{frac_text[f]},{pair_text[p]}\n" for w, f, p in zip(
            whole, frac_k, pair_k.ravel().tolist())])


class SpilledColumn:
    """One column of a table of records in a file (``dtype`` a structured type), read a
    slice at a time: a long run's replays stay on disk, not in memory (a mapped file's
    pages would count as the process's once read)."""

    def __init__(self, file, dtype: np.dtype, field: str, n: int):
        self.file, self.dtype, self.field, self.n = file, np.dtype(dtype), field, int(n)

    def __len__(self) -> int:
        return self.n

    def __getitem__(self, k):
        if not isinstance(k, slice) or k.step not in (None, 1):
            raise TypeError("a spilled column is read by plain slices")
        a, b, _ = k.indices(self.n)
        if b <= a:
            return np.zeros(0, dtype=self.dtype[self.field])
        self.file.seek(a * self.dtype.itemsize)
        rows = np.frombuffer(self.file.read((b - a) * self.dtype.itemsize), dtype=self.dtype)
        return np.ascontiguousarray(rows[self.field])


def _times_replayed(pid, n_parts: int) -> np.ndarray:
    """How often each part was replayed (read a block at a time: ``pid`` may be mapped
    from a file)."""
    out = np.zeros(n_parts, dtype=np.int64)
    for a in range(0, len(pid), 1 << 20):
        out += np.bincount(np.asarray(pid[a:a + (1 << 20)]), minlength=n_parts)
    return out


def _replays_in_blocks(replays, block: int = 65_536):
    """(position, start, part) of each replay, as Python ints a block at a time (a year
    of replays as Python lists would take gigabytes)."""
    pos, start, pid, _ = replays
    for a in range(0, len(pos), block):
        yield from zip(pos[a:a + block].tolist(), start[a:a + block].tolist(),
                       pid[a:a + block].tolist())


def _own(tl, mine, rows: int):
    """``tl``'s edges of the signals ``mine`` marks, chunk by chunk."""
    for t, s, v in tl.chunks(rows):
        keep = mine[s]
        yield t[keep], s[keep], v[keep]


def _csv_field(text: str) -> str:
    """A CSV field: quoted when it holds a comma or a quote (a signal aSw[1,2])."""
    if any(c in text for c in ',"\n\r'):
        return '"' + text.replace('"', '""') + '"'
    return text


def wrap_array(values, bits: int, signed: bool) -> np.ndarray:
    """IEC integer overflow of int64 ``values`` (``runtime.wrap``, vectorised): the low
    ``bits`` bits, two's complement when signed, as float64 (bits <= 52: exact)."""
    span = 1 << bits
    out = np.mod(values, span)
    if signed:
        out = np.where(out >= span >> 1, out - span, out)
    return out.astype(np.float64)


def seconds_texts(t_ns) -> tuple[list, list, list]:
    """Times (integer nanoseconds, not negative) for CSV rows: (whole seconds, index of
    each time's fraction, the fractions' texts such as "" and ".25"). Each distinct
    fraction is formatted once: a run's times fall on a few phases of the scan."""
    whole, frac = np.divmod(np.asarray(t_ns, dtype=np.int64), NS)
    fracs, which = np.unique(frac, return_inverse=True)
    return whole.tolist(), which.ravel().tolist(), [_frac_text(x) for x in fracs.tolist()]


def _frac_text(frac_ns: int) -> str:
    return f".{frac_ns:09d}".rstrip("0") if frac_ns else ""


def format_seconds(t_ns: int) -> str:
    """Exact decimal seconds from integer nanoseconds (``12.3``, ``0``)."""
    sign = "-" if t_ns < 0 else ""
    t_ns = abs(t_ns)
    whole, frac = divmod(t_ns, NS)
    if not frac:
        return f"{sign}{whole}"
    return f"{sign}{whole}.{frac:09d}".rstrip("0")


_PLAIN = re.compile(r"^\s*(\d+(?:\.\d*)?|\.\d+)\s*(d|h|min|m|s|ms|us|ns)?\s*$", re.I)

# the longest horizon any command runs: ten years of 365.25 days (3652.5 d, 87,660 h). A
# machine's air over longer is ten years' scaled; beyond 292 years nanoseconds no longer
# fit the int64 edge times at all
MAX_HORIZON_NS = 36_525 * 86_400 * NS // 10
MAX_HORIZON_TEXT = "10 years (3652.5 d, 87,660 h)"


class HorizonError(PlcpredError, ValueError):
    """A horizon (or grid step) that cannot be read or is out of range. A ValueError
    too, so callers that catch those for a bad option keep doing so."""


def parse_horizon(text) -> int:
    """A horizon in nanoseconds from ``T#1m30s``, ``TIME#8h``, ``90s``, ``1.5h``, ``8h``,
    ``500ms`` or a plain number of seconds. ``m`` is minutes, as in IEC literals. At most
    :data:`MAX_HORIZON_NS` (ten years); raises :class:`HorizonError` otherwise."""
    if isinstance(text, (int, float)):
        if isinstance(text, float) and not math.isfinite(text):
            raise HorizonError(f"the horizon must be a finite number of seconds, not {text!r}")
        # compared before rounding: 1e300 s is no integer number of ns to work with
        ns = round(text * NS) if abs(text) <= MAX_HORIZON_NS // NS else \
            (MAX_HORIZON_NS + 1 if text > 0 else -1)
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
            raise HorizonError(f"cannot read the horizon {text!r}: write e.g. 60s, 1m30s, 8h "
                               "or T#1m30s") from None
    if ns <= 0:
        raise HorizonError(f"the horizon must be positive, not {text!r}")
    if ns > MAX_HORIZON_NS:
        raise HorizonError(f"the horizon {text!r} is longer than {MAX_HORIZON_TEXT}, the "
                           "most plcpred runs (for a longer period, scale a shorter run's "
                           "air)")
    return ns
