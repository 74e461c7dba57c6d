"""Reading what users bring to a diagnosis: flow-meter logs and recorded I/O traces.

A flow log is a CSV file with a header row: by default ``time_s,flow_l_min`` with an
optional ``supply_bar_g``, as ``plcpred emulate`` writes it, or any logger's columns chosen
with ``time_col``/``flow_col`` (a header name or a 1-based column number), below any lines
the logger writes before its header. Without them, a header with exactly one column named
as a time and one as a flow (``Timestamp``, ``Flow (m3/h)``, ``Zeit;Durchfluss [l/min]``)
is read so, in the unit the flow column's name gives unless one is given. Times are
seconds (milliseconds or minutes where the column's name says so: ``t_ms``, ``Zeit
[ms]``, ``time (min)``), ISO 8601 date-times, a logger's date-times (``24.11.2026 13:05:00,5``,
``2026/11/24 13:05:00``, ``11/24/2026 1:05:00 PM``) or times of day alone
(``13:05:00.5``, passing midnight); readings stamped to the whole second by a logger
that samples faster are spread evenly over their second. Flows are in ``l/min``,
``m3/h``, ``l/s`` or ``scfm`` at the meter's reference condition
(ISO 8778, DIN 1343 or ISO 2533), converted here to normal litres per minute at the
ISO 8778 reference every other part of plcpred uses (docs/reference/physics.md: reference
conditions: ``V_2 = V_1 * (P_1/P_2) * (T_2/T_1)``). Fields separated by ``,``, ``;`` or
tabs; with ``;`` a decimal comma is read too (European loggers).

Logs and traces are untrusted: they are read a block of lines at a time, keeping only
their numbers, and refused with an error naming the file and line beyond MAX_ROWS rows,
MAX_LINE_BYTES a line, a csv field over the csv module's limit (131,072 characters), a
flow over MAX_FLOW, or times spanning more than the ten years plcpred runs at most.
"""
from __future__ import annotations

import csv
import functools
import itertools
import math
import re
from array import array
from collections.abc import Iterator
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..datafile import (
    FLOW_UNIT_SPELLINGS,
    PRESSURE_UNIT_SPELLINGS,
    DataLines,
    known_units,
    unit_name,
)
from ..errors import PlcpredError
from ..physics import meter
from ..physics.units import BAR_PER_PSI, P_ATM_PA, PA_PER_BAR
from ..sequencer.timeline import (
    MAX_HORIZON_NS,
    MAX_HORIZON_TEXT,
    NS,
    Signal,
    Timeline,
    parse_horizon,
)

# volume units per minute -> litres per minute (the names FLOW_UNIT_SPELLINGS spells)
FLOW_UNITS = {"l/min": 1.0, "m3/h": 1000.0 / 60.0, "l/s": 60.0, "m3/min": 1000.0,
              "scfm": 28.316846592}
# pressure units -> (bar per unit, absolute): a supply column is read as bar(g), an
# absolute one less the standard atmosphere
PRESSURE_UNITS = {"bar": (1.0, False), "bara": (1.0, True),
                  "psi": (BAR_PER_PSI, False), "psia": (BAR_PER_PSI, True),
                  "kpa": (0.01, False), "kpaa": (0.01, True), "mpa": (10.0, False),
                  "mbar": (1e-3, False)}
# Limits of what a flow log or an I/O trace may hold. Both are read a line at a time and
# keep only their numbers (8 bytes a value: a flow log of MAX_ROWS rows holds at most about
# 500 MB, an I/O trace about 400 MB as the timeline it becomes), so memory stays bounded
# whatever the file's size; beyond a limit reading stops with an error naming the line.
MAX_ROWS = 20_000_000          # samples, and lines after the header's (blank too)
MAX_IO_SIGNALS = 100_000       # distinct signals of an I/O trace
MAX_FLOW = 1e9                 # a flow reading (in the log's unit): more is no meter's
MAX_SUPPLY_BAR = 1e3           # a supply reading beyond this is taken as not read


class MeasuredDataError(PlcpredError):
    """A flow log or I/O trace that cannot be read as one."""


# how much of the meter's response an instantaneous reading takes in (less than any
# prediction grid's cell: the response in the cell that holds the time stamp)
INSTANT_WINDOW_S = 1e-3


def reading_starts(sampling: str | None, interval_starts_s: np.ndarray,
                   times_s: np.ndarray) -> np.ndarray:
    """Start of what each reading averages of the meter's response: its interval
    (``mean``, or not said) or the moment it was read (``instant``)."""
    return times_s - INSTANT_WINDOW_S if sampling == "instant" else interval_starts_s


@dataclass
class MeasuredRun:
    """One flow log: sample times on the logger's clock (s) and flows in NL/min at the
    ISO 8778 reference. A sample at ``time_s[k]`` is the meter's reading then: with
    ``sampling`` "mean", the (lagged) flow averaged over the interval since the previous
    sample (a meter's own logger); with "instant", the lagged flow at that moment (a PLC
    polling the meter's analogue output); None: not said (``diagnose`` reads means and
    warns where instantaneous readings fit far better). Either way a reading stands for
    its whole interval in totals."""
    name: str
    time_s: np.ndarray
    flow_l_min: np.ndarray
    supply_bar_g: np.ndarray | None = None
    source: dict = field(default_factory=dict)   # unit, reference, columns, skipped rows
    sampling: str | None = None

    @property
    def span_s(self) -> float:
        return float(self.time_s[-1] - self.time_s[0])

    @functools.cached_property
    def interval_s(self) -> float:
        """The median sampling interval."""
        return float(np.median(np.diff(self.time_s)))

    def interval_starts_s(self) -> np.ndarray:
        """Start of each sample's averaging interval: the previous sample, except after a
        gap in the log (longer than 1.5 sampling intervals), where a reading still
        averages only one sampling interval (the first one as long as the median)."""
        return self._interval_starts_s.copy()

    def reading_starts_s(self) -> np.ndarray:
        """:func:`reading_starts` of this log's readings."""
        return reading_starts(self.sampling, self.interval_starts_s(), self.time_s)

    @functools.cached_property
    def unlogged_s(self) -> float:
        """Time the log has no reading for (its gaps beyond one sampling interval each):
        totals and errors cover only the intervals the log has."""
        t = self.time_s
        covered = np.sum(t - self._interval_starts_s)
        return max(0.0, float(t[-1] - t[0] + self.interval_s - covered))

    @functools.cached_property
    def _interval_starts_s(self) -> np.ndarray:
        t = self.time_s
        start = np.concatenate([[t[0] - self.interval_s], t[:-1]])
        gap = (t - start) > 1.5 * self.interval_s
        start[gap] = t[gap] - self.interval_s
        return start


def reference_factor(reference: str) -> float:
    """:func:`plcpred.physics.meter.reference_factor`, an unknown name a MeasuredDataError."""
    try:
        return meter.reference_factor(reference)
    except ValueError as e:
        raise MeasuredDataError(str(e)) from None


def canonical_flow_unit(unit: str) -> str:
    """The FLOW_UNITS key ``unit`` spells (``Nm³/h``, ``m3h``, ``lpm``, ``NL/min``)."""
    name = unit_name(unit, FLOW_UNIT_SPELLINGS)
    if name is None:
        raise MeasuredDataError(f"unknown flow unit {unit!r} (known: "
                                f"{known_units(FLOW_UNIT_SPELLINGS)})")
    return name


def canonical_pressure_unit(unit: str) -> str:
    """The PRESSURE_UNITS key ``unit`` spells (``psig``, ``bar(g)``, ``kPa``)."""
    name = unit_name(unit, PRESSURE_UNIT_SPELLINGS)
    if name is None:
        raise MeasuredDataError(f"unknown pressure unit {unit!r} (known: "
                                f"{known_units(PRESSURE_UNIT_SPELLINGS)})")
    return name


def flow_unit_factor(unit: str) -> float:
    return FLOW_UNITS[canonical_flow_unit(unit)]


def _column_number(text) -> bool:
    """``--time-col 2``: a column by its number (ASCII digits: '²'.isdigit() is true too,
    and int() refuses it)."""
    return re.fullmatch(r"[0-9]{1,9}", str(text)) is not None


def _column(path: str, header: list[str], wanted, default: str | None, what: str,
            option: str, line: int) -> int | None:
    """The index of the column ``wanted`` names (a name or a 1-based number), or of
    ``default`` when nothing is wanted (None if the header has no such column)."""
    names = [h.strip() for h in header]
    if wanted is None:
        if default in names:
            return names.index(default)
        return None
    text = str(wanted).strip()
    if _column_number(text):
        k = int(text)
        if not 1 <= k <= len(names):
            raise MeasuredDataError(f"{path}: line {line}: {option} {k}: the header has "
                                    f"{len(names)} columns ({', '.join(names)})")
        return k - 1
    lower = [n.lower() for n in names]
    if text.lower() in lower:
        return lower.index(text.lower())
    raise MeasuredDataError(f"{path}: line {line}: no {what} column {text!r} (columns: "
                            f"{', '.join(names)}); name it with {option}")


# header words a logger's export names its columns with (English, German, French,
# Italian, Spanish), matched in a name without its unit: "Flow (m3/h)" is a flow
_TIME_WORDS = ("time", "timestamp", "zeit", "zeitstempel", "zeitpunkt", "uhrzeit",
               "datetime", "date time", "date/time", "date_time", "datum/zeit", "datum zeit",
               "datum/uhrzeit", "datum uhrzeit", "horodatage", "tempo", "tiempo", "heure",
               "hora", "ora", "t_s", "time_s", "t_ms")
# words of a column that holds the date alone, beside one with the time of day
_DATE_WORDS = ("date", "datum", "data", "fecha")
_TIME_OF_DAY_WORDS = ("time", "zeit", "uhrzeit", "heure", "hora", "ora", "tempo", "tiempo")
_FLOW_WORDS = ("flow", "durchfluss", "volumenstrom", "verbrauch", "luftverbrauch",
               "druckluftverbrauch", "luftmenge", "liefermenge", "fad", "free air delivery",
               "debit", "débit", "portata", "caudal", "consumption", "q")
_PRESSURE_WORDS = ("pressure", "supply", "supply pressure", "line pressure", "druck",
                   "netzdruck", "versorgungsdruck", "systemdruck", "leitungsdruck",
                   "pression", "pressione", "presión", "presion")

# a unit in brackets at the end of a name ("Druck [bar(g)]"), else anywhere ("Flow (m3/h)
# avg"), else after an underscore, "in" or a space ("flow_m3_min", "supply_bar_g")
_UNIT_AT_END = re.compile(r"[\(\[]\s*(.+?)\s*[\)\]]\s*$")
_UNIT_INSIDE = re.compile(r"[\(\[]\s*([^\)\]]+?)\s*[\)\]]")
_UNIT_AFTER = re.compile(r"(?:_|\s+in\s+|\s+)((?:n?m3|n?m³)_?/?(?:h|min)|n?l_?/?(?:min|s)|lpm"
                         r"|slpm|s?cfm|bar_?[ga]?|m?bar|psi[ga]?|k?pa_?[ga]?|mpa)$")


def _name_and_unit(name: str) -> tuple[str, str | None]:
    """(a header name in lower case without its unit, the unit's text if it names one):
    ``Flow (m3/h)`` -> (``flow``, ``m3/h``), ``supply_bar_g`` -> (``supply``, ``bar_g``)."""
    text = name.strip().lower()
    m = _UNIT_AT_END.search(text) or _UNIT_INSIDE.search(text) or _UNIT_AFTER.search(text)
    if m is None:
        return text.strip(" _-:"), None
    return (text[:m.start()] + text[m.end():]).strip(" _-:"), m.group(1)


def column_unit(name: str, spellings: dict) -> str | None:
    """The unit of ``spellings`` (FLOW_UNIT_SPELLINGS, PRESSURE_UNIT_SPELLINGS) a
    column's header name gives (``Flow (m3/h)`` -> ``m3/h``), if it gives one."""
    unit = _name_and_unit(name)[1]
    return None if unit is None else unit_name(unit, spellings)


def _bare(name: str) -> tuple[str, str | None]:
    """(a header name without its unit, the flow unit it names, if one of FLOW_UNITS')."""
    text, unit = _name_and_unit(name)
    return text, None if unit is None else unit_name(unit, FLOW_UNIT_SPELLINGS)


def _pressure_unit_of(name: str) -> str | None:
    """The pressure unit a header name gives (``Druck [psi]`` -> ``psi``), if any."""
    unit = _name_and_unit(name)[1]
    return None if unit is None else unit_name(unit, PRESSURE_UNIT_SPELLINGS)


def _named_as(header: list[str], words, exclude=()) -> int | None:
    """The one column whose name (without its unit) is one of ``words`` or starts with
    one; None where no column or several are."""
    bare = [_name_and_unit(h)[0] for h in header]
    hits = [k for k, b in enumerate(bare) if k not in exclude and (
        b in words or any(b.startswith((w + " ", w + "_")) for w in words if len(w) > 2))]
    return hits[0] if len(hits) == 1 else None


def _time_named(header: list[str], exclude=()) -> int | None:
    """The column named as a time, else the one named as a date (a date-time in it)."""
    k = _named_as(header, _TIME_WORDS, exclude)
    return k if k is not None else _named_as(header, _DATE_WORDS, exclude)


TIME_UNITS_S = {"ms": 0.001, "s": 1.0, "sec": 1.0, "min": 60.0, "h": 3600.0}


def _time_unit_s(name: str) -> float:
    """Seconds per unit of a time column whose name gives its unit (``t_ms``,
    ``Zeit [ms]``, ``time (min)``); 1 where it gives none."""
    text = name.strip().lower()
    m = re.search(r"[\(\[]\s*(ms|s|sec|min|h)\s*[\)\]]", text) or re.search(
        r"[_\s](ms|s|sec|min|h)$", text)
    return TIME_UNITS_S[m.group(1)] if m else 1.0


MAX_PREAMBLE_LINES = 50


def _cells(line: str) -> list[str]:
    return next(csv.reader([line], delimiter=_delimiter(line)))


def _header_line(lines: list[str], time_col, flow_col) -> int:
    """Index of the header row: the first line, or the first of the first
    MAX_PREAMBLE_LINES lines that names the time and flow columns (a logger's export
    often starts with lines about the device); with columns given by number, the line
    before the first row whose time and flow read as numbers or date-times. Where none
    does, the line above the first row of data, whose columns the error then lists."""
    numbered = _column_number(time_col) and _column_number(flow_col)
    for k, line in enumerate(lines[:MAX_PREAMBLE_LINES]):
        if not line.strip():
            continue
        row = [c.strip() for c in _cells(line)]
        if numbered:
            ti, fi = int(time_col) - 1, int(flow_col) - 1
            if k and max(ti, fi) < len(row) and _reads_as_sample(row[ti], row[fi]):
                return max(j for j in range(k) if lines[j].strip())
        elif _names(row, time_col, "time_s", _time_named) and \
                _names(row, flow_col, "flow_l_min",
                       lambda h: _named_as(h, _FLOW_WORDS)):
            return k
    return _above_data(lines)


def _names(row: list[str], wanted, default: str, guess) -> bool:
    """Whether a header ``row`` holds the column ``wanted`` names (any row does for a
    number), or without one the default name or one ``guess`` finds."""
    if wanted is None:
        return default in row or guess(row) is not None
    text = str(wanted).strip()
    return _column_number(text) or text.lower() in [c.lower() for c in row]


def _above_data(lines: list[str]) -> int:
    """The last line with anything on it above the first row of data (every field a
    number, a date or a time, at least two of them), else the first such line: where the
    header most likely is, for an error that lists its columns."""
    filled = [k for k, line in enumerate(lines) if line.strip()]
    for before, k in itertools.pairwise(filled):
        # split as the header would be (1;1,5 holds a comma and a semicolon)
        delimiter = _delimiter(lines[before])
        if _data_row(lines[k], delimiter) and not _data_row(lines[before], delimiter):
            return before
    return filled[0]


_DATE_ONLY_FORMATS = ("%d.%m.%Y", "%d.%m.%y", "%Y-%m-%d", "%Y/%m/%d", "%m/%d/%Y",
                      "%d/%m/%Y")


def _data_row(line: str, delimiter: str) -> bool:
    """A row of data: at least two fields, every one a number, a date-time, a date or a
    time of day."""
    cells = [c.strip() for c in next(csv.reader([line], delimiter=delimiter)) if c.strip()]
    return len(cells) >= 2 and all(_data_cell(c) for c in cells)


def _data_cell(cell: str) -> bool:
    try:
        _number(cell, True)
        return True
    except ValueError:
        pass
    for fmt in _DATE_ONLY_FORMATS:
        try:
            datetime.strptime(cell, fmt)
            return True
        except ValueError:
            continue
    try:
        _timestamp(cell)
        return True
    except ValueError:
        return False


def _delimiter(line: str) -> str:
    """The field separator a CSV line uses the most of: ``,``, ``;`` or a tab."""
    return max((",", ";", "\t"), key=line.count)


def _reads_as_sample(time_cell: str, flow_cell: str) -> bool:
    try:
        _number(flow_cell, True)
    except ValueError:
        return False
    try:
        _number(time_cell, True)
        return True
    except ValueError:
        try:
            _timestamp(time_cell)
            return True
        except ValueError:
            return False


def _number(cell: str, decimal_comma: bool) -> float:
    s = cell.strip()
    if decimal_comma:
        s = s.replace(",", ".")
    return float(s)


# date-times loggers write besides ISO 8601, tried in this order on a log's first time
# (a log keeps the one that read it): European day.month.year, year/month/day, US
# month/day/year (12- or 24-hour), then day/month/year; a time of day alone
_DATE_FORMATS = ("%d.%m.%Y %H:%M:%S.%f", "%d.%m.%Y %H:%M:%S", "%d.%m.%Y %H:%M",
                 "%d.%m.%y %H:%M:%S.%f", "%d.%m.%y %H:%M:%S", "%d.%m.%y %H:%M",
                 "%Y/%m/%d %H:%M:%S.%f", "%Y/%m/%d %H:%M:%S", "%Y/%m/%d %H:%M",
                 "%m/%d/%Y %I:%M:%S.%f %p", "%m/%d/%Y %I:%M:%S %p",
                 "%m/%d/%Y %H:%M:%S.%f", "%m/%d/%Y %H:%M:%S", "%m/%d/%Y %H:%M",
                 "%d/%m/%Y %H:%M:%S.%f", "%d/%m/%Y %H:%M:%S", "%d/%m/%Y %H:%M")
TIME_OF_DAY_FORMATS = ("%H:%M:%S.%f", "%H:%M:%S", "%H:%M")
_EPOCH = datetime(1970, 1, 1)
_FRACTION_COMMA = re.compile(r"(\d{1,2}:\d{2}:\d{2}),(\d+)")


def _timestamp(cell: str, fmt: str | None = None) -> tuple[float, str]:
    """(seconds, the format that read it) of a date-time cell: ISO 8601 (``Z`` or an
    offset taken into account), a logger's date format (:data:`_DATE_FORMATS`, a decimal
    comma in the seconds read too) or a time of day alone (seconds since midnight).
    ``fmt``: the format an earlier row of the log was read with."""
    s = _FRACTION_COMMA.sub(r"\1.\2", " ".join(cell.split()))
    if fmt in (None, "iso"):
        try:
            dt = datetime.fromisoformat(s[:-1] + "+00:00" if s.endswith("Z") else s)
        except ValueError:
            if fmt == "iso":
                raise
        else:
            seconds = dt.timestamp() if dt.tzinfo else (dt - _EPOCH).total_seconds()
            return seconds, "iso"
    for f in (fmt,) if fmt is not None else _DATE_FORMATS + TIME_OF_DAY_FORMATS:
        try:
            dt = datetime.strptime(s, f)
        except ValueError:
            if fmt is not None:
                raise
            continue
        if f in TIME_OF_DAY_FORMATS:
            return dt.hour * 3600.0 + dt.minute * 60.0 + dt.second + dt.microsecond / 1e6, f
        return (dt - _EPOCH).total_seconds(), f
    raise ValueError(cell)


def _csv_rows(reader, file: str, offset: int) -> Iterator[tuple[int, list[str]]]:
    """(line number, row) of a csv reader over lines from ``offset + 1`` on; a row the
    csv module cannot read (a quoted field that never ends) is a MeasuredDataError."""
    while True:
        try:
            row = next(reader)
        except StopIteration:
            return
        except csv.Error as e:
            raise MeasuredDataError(f"{file}: line {offset + reader.line_num}: "
                                    f"{_csv_problem(e)}") from None
        yield offset + reader.line_num, row


def _csv_problem(e: csv.Error) -> str:
    text = str(e)
    if "field larger than field limit" in text:
        return (f"a field longer than {csv.field_size_limit():,} characters (a quote "
                "that is never closed?)")
    return f"not CSV: {text}"


class _LogRequest(NamedTuple):
    """How the caller says to read a flow log (None: as its header says)."""
    time_col: object
    flow_col: object
    supply_col: object
    flow_unit: str | None           # a FLOW_UNITS key
    reference: str
    supply_unit: str | None = None  # a PRESSURE_UNITS key
    date_col: object = None


def read_measured(path, time_col=None, flow_col=None, flow_unit: str | None = None,
                  reference: str = "iso8778", supply_col=None,
                  supply_unit: str | None = None, date_col=None) -> MeasuredRun:
    """Read a flow log (see the module docstring). Rows whose flow is empty or not a
    number are skipped and counted in ``source["skipped_rows"]``; times must increase.
    Columns not named (a header name or a 1-based number) are found by their default
    names, else where exactly one column is named as a time (or a date beside a time of
    day: ``Datum``, ``Uhrzeit``), a flow or a pressure; ``source["columns_guessed"]``
    says what was taken. The flow is in the unit its column's name gives (``Flow
    (m3/h)``, ``Volumenstrom [m3/min]``) unless ``flow_unit`` is given (a warning in
    ``source["warnings"]`` where the two differ), else l/min; the supply likewise
    (``Druck [psi]``, ``supply_unit``), else bar(g).
    Raises :class:`MeasuredDataError` naming the file, the line and the column."""
    path = Path(path)
    flow_unit = None if flow_unit is None else canonical_flow_unit(flow_unit)
    supply_unit = None if supply_unit is None else canonical_pressure_unit(supply_unit)
    ref_k = reference_factor(reference)
    request = _LogRequest(time_col, flow_col, supply_col, flow_unit, reference, supply_unit,
                          date_col)
    with DataLines(path, MeasuredDataError, MAX_ROWS, extra=MAX_PREAMBLE_LINES + 1) as lines:
        return _read_measured(path, lines, request, ref_k)


def _read_measured(path: Path, lines: DataLines, request: _LogRequest, ref_k: float
                   ) -> MeasuredRun:
    """The flow log ``lines`` of ``path``: its header found, its columns chosen, its rows
    read and checked one at a time, and the samples in NL/min at the ISO 8778 reference."""
    file = str(path)
    start, top = _header_lines(lines, file, request)
    delimiter = _delimiter(top[0])
    decimal_comma = delimiter != ","
    rows = _csv_rows(csv.reader(itertools.chain(top, lines), delimiter=delimiter), file,
                     start)
    _, header = next(rows)
    cols = _log_columns(file, header, start, request)
    # a numeric time column's name may give its unit (t_ms, Zeit [ms])
    clock = _LogClock(decimal_comma, _time_unit_s(header[cols.time]))
    samples = _read_samples(rows, file, header, cols, clock)
    return _measured_run(path, header, cols, samples, clock.fmt, request.reference, ref_k)


def _header_lines(lines: DataLines, file: str, request: _LogRequest
                  ) -> tuple[int, list[str]]:
    """(index of a flow log's header line, the lines read from it on). The header is
    among the first MAX_PREAMBLE_LINES lines (or, after blank ones only, the first line
    with anything on it); the rows after it are left to be read as they come."""
    head = list(itertools.islice(lines, MAX_PREAMBLE_LINES))
    if any(line.strip() for line in head):
        try:
            start = _header_line(head, request.time_col, request.flow_col)
        except csv.Error as e:
            raise MeasuredDataError(f"{file}: {_csv_problem(e)}") from None
        return start, head[start:]
    start = len(head)
    for first in lines:
        if first.strip():
            break
        start += 1
    else:
        raise MeasuredDataError(f"{file}: empty file (expected a header such as "
                                "time_s,flow_l_min and rows of samples)")
    return start, [first]


class _Columns(NamedTuple):
    """Where a flow log's values stand, and the units of its flows and pressures."""
    time: int
    flow: int
    supply: int | None
    flow_unit: str                  # the caller's, else the header's, else l/min
    unit_k: float                   # l/min per unit of the log's flows
    guessed: list                   # what was taken from the header's names, as said
    date: int | None = None         # a date beside a time of day
    supply_unit: str = "bar"        # the caller's, else the header's, else bar(g)
    warnings: tuple = ()


def _log_columns(file: str, header: list[str], start: int, request: _LogRequest
                 ) -> _Columns:
    """The columns of a flow log: as the caller names them, else by their default
    names, else as a logger's own names say; the units as the caller gives them, else
    as the columns' names give them."""
    line = start + 1
    names = [h.strip() for h in header]
    t_idx = _column(file, header, request.time_col, "time_s", "time", "--time-col", line)
    f_idx = _column(file, header, request.flow_col, "flow_l_min", "flow", "--flow-col", line)
    guessed = []
    if t_idx is None and request.time_col is None:
        t_idx = _time_named(header, exclude=(f_idx,))
        if t_idx is not None:
            guessed.append(f"time from column '{names[t_idx]}'")
    if f_idx is None and request.flow_col is None:
        f_idx = _named_as(header, _FLOW_WORDS, exclude=(t_idx,))
    if t_idx is None or f_idx is None:
        raise _no_columns(file, header, start, t_idx, f_idx)
    d_idx = _date_column(file, header, request, t_idx, f_idx, line)
    if d_idx is not None and request.date_col is None:
        guessed[:] = [f"time from columns '{names[d_idx]}' and '{names[t_idx]}'"]
    warnings = []
    flow_unit, unit_said = _unit(names[f_idx], request.flow_unit, "--flow-unit", "l/min",
                                 lambda n: _bare(n)[1], warnings)
    if guessed or (request.flow_col is None and names[f_idx] != "flow_l_min") or unit_said:
        guessed.append(f"flow from '{names[f_idx]}' in {flow_unit}")
    s_idx = _column(file, header, request.supply_col, "supply_bar_g", "supply",
                    "--supply-col", line)
    s_guessed = s_idx is None and request.supply_col is None
    if s_guessed:
        s_idx = _named_as(header, _PRESSURE_WORDS, exclude=(t_idx, f_idx, d_idx))
        if s_idx is not None and _name_and_unit(names[s_idx])[1] is not None and \
                _pressure_unit_of(names[s_idx]) is None:
            s_idx = None                # a unit that is no pressure's: not the supply
    supply_unit = "bar"
    if s_idx is not None:
        supply_unit, unit_said = _unit(names[s_idx], request.supply_unit, "--supply-unit",
                                       "bar", _pressure_unit_of, warnings)
        if s_guessed or unit_said:
            guessed.append(f"supply from '{names[s_idx]}' in {_pressure_text(supply_unit)}")
    return _Columns(t_idx, f_idx, s_idx, flow_unit, FLOW_UNITS[flow_unit], guessed, d_idx,
                    supply_unit, tuple(warnings))


def _pressure_text(unit: str) -> str:
    """How a report names a pressure unit: gauge bar(g), psi(g), ...; absolute bar(a)."""
    text = {"kpa": "kPa", "kpaa": "kPaa", "mpa": "MPa"}.get(unit, unit)
    return f"{text[:-1]}(a)" if PRESSURE_UNITS[unit][1] else f"{text}(g)"


def _unit(name: str, given: str | None, option: str, default: str, of_header,
          warnings: list) -> tuple[str, bool]:
    """(the unit a column is read in, whether its header gave it): ``given`` (the
    caller's, with a warning where the header names another), else the header's, else
    ``default``."""
    said = of_header(name)
    if given is None:
        return (said, said != default) if said is not None else (default, False)
    if said is not None and said != given:
        warnings.append(f"column '{name}' says {said}, read as {given} as {option} says")
    return given, False


def _date_column(file: str, header: list[str], request: _LogRequest, t_idx: int,
                 f_idx: int, line: int) -> int | None:
    """The column of a date beside a time column that holds the time of day: as the
    caller names it, else the one column named as a date (``Datum`` beside ``Uhrzeit``)."""
    if request.date_col is not None:
        return _column(file, header, request.date_col, None, "date", "--date-col", line)
    if _name_and_unit(header[t_idx])[0] not in _TIME_OF_DAY_WORDS:
        return None
    return _named_as(header, _DATE_WORDS, exclude=(t_idx, f_idx))


def _no_columns(file: str, header: list[str], start: int, t_idx: int | None,
                f_idx: int | None) -> MeasuredDataError:
    """The error for a flow log whose time or flow column (or both) is not found: which
    is missing, or which columns are named alike (two flows: name one)."""
    missing = "time and flow columns" if t_idx is None and f_idx is None else (
        "time column" if t_idx is None else "flow column")
    alike = []
    for idx, words, what, option in ((t_idx, _TIME_WORDS, "a time", "--time-col"),
                                     (f_idx, _FLOW_WORDS, "a flow", "--flow-col")):
        hits = [h.strip() for k, h in enumerate(header)
                if k not in (t_idx, f_idx) and _named_as([h], words) == 0]
        if idx is None and len(hits) > 1:
            alike.append(f"{', '.join(hits)} are each named as {what}: name one with "
                         f"{option}")
    return MeasuredDataError(
        f"{file}: line {start + 1}: no {missing} (expected the header "
        f"time_s,flow_l_min, or one column named as a time and one as a flow; this "
        f"file has {', '.join(h.strip() for h in header) or 'no columns'}); "
        + ("; ".join(alike) if alike else "name the columns with --time-col and --flow-col"))


@dataclass
class _LogClock:
    """Reads a flow log's time cells: numbers (seconds, or the column's unit) or
    date-times, each row in the way the first row was read."""
    decimal_comma: bool
    unit_s: float                   # seconds per unit of a numeric time
    fmt: str | bool | None = None   # False: seconds; else the date-time format of row one
    day_s: float = 0.0              # a time of day alone: the days passed midnight adds

    def read(self, cell: str, file: str, lineno: int, col: int, times: array) -> float:
        """The time of ``cell`` in seconds (``times``: the samples read before it)."""
        try:
            if self.fmt is None:
                try:
                    t = _number(cell, self.decimal_comma) * self.unit_s
                    self.fmt = False
                except ValueError:
                    t, self.fmt = _timestamp(cell)
            else:
                t = _timestamp(cell, self.fmt)[0] if self.fmt else \
                    _number(cell, self.decimal_comma) * self.unit_s
        except (ValueError, OverflowError):
            raise MeasuredDataError(
                f"{file}: line {lineno}, column {col + 1}: cannot read the time "
                f"{cell.strip()[:40]!r} (seconds, an ISO 8601 date-time or a logger's "
                "date-time such as 24.11.2026 13:05:00,5"
                + (f"; the rows before were read as {self.fmt}" if self.fmt else "")
                + ")") from None
        if self.fmt in TIME_OF_DAY_FORMATS:
            t += self.day_s
            if times and t < times[-1] - 43_200.0:      # past midnight
                self.day_s += 86_400.0
                t += 86_400.0
        return t


@dataclass
class _Samples:
    """A flow log's numbers as read, 8 bytes each (a list of floats takes four times
    that)."""
    times: array = field(default_factory=lambda: array("d"))
    flows: array = field(default_factory=lambda: array("d"))
    supplies: array = field(default_factory=lambda: array("d"))
    skipped: int = 0                # rows without a number in the flow column
    date_used: bool = False         # the times are a date column's and a time column's
    repeated: tuple | None = None   # (line, time) of the first time equal to the one before


def _read_samples(rows, file: str, header: list[str], cols: _Columns, clock: _LogClock
                  ) -> _Samples:
    """The samples of a flow log's rows after its header, each row checked as it
    comes; a row without a number in the flow column is counted and skipped."""
    samples = _Samples()
    date = cols.date
    bar_per_unit, absolute = PRESSURE_UNITS[cols.supply_unit]
    atmosphere_bar = P_ATM_PA / PA_PER_BAR if absolute else 0.0
    for lineno, row in rows:
        if not row or not "".join(row).strip():
            continue
        if len(samples.times) >= MAX_ROWS:
            raise MeasuredDataError(f"{file}: more than {MAX_ROWS:,} samples")
        if max(cols.time, cols.flow, -1 if date is None else date) >= len(row):
            raise MeasuredDataError(f"{file}: line {lineno}: {len(row)} fields, the "
                                    f"header has {len(header)}")
        if date is not None and not samples.times and not _dated(row[date], row[cols.time]):
            date = None                 # the time column holds whole date-times
        cell = row[cols.time] if date is None else \
            f"{row[date].strip()} {row[cols.time].strip()}"
        t = clock.read(cell, file, lineno, cols.time, samples.times)
        q = _reading(row[cols.flow], clock.decimal_comma)
        if not math.isfinite(q):
            samples.skipped += 1
            continue
        _check_sample(file, lineno, row, cols, t, q, samples)
        samples.times.append(t)
        samples.flows.append(q)
        if cols.supply is not None and cols.supply < len(row):
            p = _reading(row[cols.supply], clock.decimal_comma) * bar_per_unit - atmosphere_bar
            samples.supplies.append(p if abs(p) <= MAX_SUPPLY_BAR else math.nan)  # not read
    samples.date_used = date is not None
    return samples


def _dated(date_cell: str, time_cell: str) -> bool:
    """Whether a date and a time of day read as one date-time (else the time column
    holds the date too, or seconds)."""
    try:
        _timestamp(f"{date_cell.strip()} {time_cell.strip()}")
        return True
    except ValueError:
        return False


def _reading(cell: str, decimal_comma: bool) -> float:
    """A flow or pressure cell's number; NaN where it holds none (not read)."""
    try:
        return _number(cell, decimal_comma)
    except ValueError:
        return math.nan


def _check_sample(file: str, lineno: int, row: list[str], cols: _Columns, t: float,
                  q: float, samples: _Samples) -> None:
    """Refuse a sample at a time that is not finite, beyond the longest run plcpred
    models or before the sample's before it, or with a flow beyond any meter's; note the
    first time equal to the one before (a logger stamping to the whole second)."""
    times = samples.times
    cell = row[cols.time]
    if not math.isfinite(t):
        raise MeasuredDataError(f"{file}: line {lineno}, column {cols.time + 1}: the time "
                                "is not a finite number")
    if abs(q) > MAX_FLOW:
        raise MeasuredDataError(f"{file}: line {lineno}, column {cols.flow + 1}: flow "
                                f"{row[cols.flow].strip()[:40]} is beyond any meter's "
                                f"(at most {MAX_FLOW:g} in the log's unit)")
    if times and t - times[0] > MAX_HORIZON_NS / NS:
        raise MeasuredDataError(f"{file}: line {lineno}, column {cols.time + 1}: time "
                                f"{cell.strip()[:40]} is more than {MAX_HORIZON_TEXT} "
                                "after the first sample, longer than plcpred runs a "
                                "machine")
    if times and t <= times[-1]:
        if t < times[-1] or t != math.floor(t):
            raise _not_increasing(file, lineno, cols.time, cell.strip())
        samples.repeated = samples.repeated or (lineno, cell.strip())


def _measured_run(path: Path, header: list[str], cols: _Columns, samples: _Samples,
                  time_format, reference: str, ref_k: float) -> MeasuredRun:
    """The run of a flow log's samples: at least three, times increasing (whole seconds
    repeated only where every time is one, then spread over their second), flows in
    NL/min at the ISO 8778 reference."""
    file = str(path)
    if len(samples.times) < 3:
        raise MeasuredDataError(f"{file}: a flow log needs at least 3 samples with a "
                                f"flow, found {len(samples.times)}"
                                + (f" ({samples.skipped} rows without a number in the "
                                   "flow column)" if samples.skipped else ""))
    # the arrays' own memory, not a copy (writable: an array.array's buffer is)
    time_s = np.frombuffer(samples.times, dtype=float)
    if samples.repeated and np.any(time_s != np.floor(time_s)):
        raise _not_increasing(file, samples.repeated[0], cols.time, samples.repeated[1])
    time_s, spread = _spread_whole_seconds(time_s)
    flow = np.frombuffer(samples.flows, dtype=float)
    flow *= cols.unit_k * ref_k
    supply = np.frombuffer(samples.supplies, dtype=float) if cols.supply is not None and \
        len(samples.supplies) == len(samples.times) else None
    source = {}
    guessed = [g for g in cols.guessed
               if samples.date_used or not g.startswith("time from columns")]
    if cols.date is not None and not samples.date_used and cols.guessed and \
            cols.guessed[0].startswith("time from columns"):
        guessed.insert(0, f"time from column '{header[cols.time].strip()}'")
    if guessed:
        source["columns_guessed"] = ", ".join(guessed)
    if cols.warnings:
        source["warnings"] = list(cols.warnings)
    if supply is not None:
        source.update(supply_column=header[cols.supply].strip(),
                      supply_unit=cols.supply_unit)
    if samples.date_used:
        source["date_column"] = header[cols.date].strip()
    return MeasuredRun(path.name, time_s, flow, supply,
                       {**source, "path": file, "flow_unit": cols.flow_unit,
                        "reference": reference,
                        "time_format": ("iso8601" if time_format == "iso" else time_format)
                        if time_format else "seconds",
                        "time_column": header[cols.time].strip(),
                        "flow_column": header[cols.flow].strip(),
                        "skipped_rows": samples.skipped, "spread_rows": spread})


def _not_increasing(file: str, lineno: int, t_idx: int, text: str) -> MeasuredDataError:
    return MeasuredDataError(f"{file}: line {lineno}, column {t_idx + 1}: time {text} does "
                             "not increase (previous row is later or equal)")


def _spread_whole_seconds(t: np.ndarray) -> tuple[np.ndarray, int]:
    """Times stamped to the whole second by a logger that samples faster (12:00:01 twice
    at 2 Hz): the k readings of one second spread evenly over it (t, t + 1/k, ...), as
    a steady logger took them. (times, how many readings were moved)."""
    if len(t) < 2 or not np.any(t[1:] == t[:-1]):
        return t, 0
    start = np.concatenate([[True], t[1:] != t[:-1]])
    first = np.flatnonzero(start)
    counts = np.diff(np.append(first, len(t)))
    run = np.repeat(np.arange(len(first)), counts)
    j = np.arange(len(t)) - first[run]
    out = t + j / counts[run]
    return out, int(np.count_nonzero(j))


def read_io_timeline(path, horizon_s: float | None = None, machine=None):
    """A recorded I/O trace in ``timeline.csv`` form (``time_s,signal,value``, one row
    per change, as a PLC trace or an OPC logger records it) as a
    :class:`~plcpred.sequencer.Timeline`. Signals first seen after time 0 start at 0
    (FALSE). The horizon is the last change unless ``horizon_s`` is longer.

    With ``machine``, a valve of its consumers that the trace never records (traces often
    hold only some signals) is held at its initial value for the whole run: 0 (off), or
    1 for the single solenoid of a cylinder that starts extended, so that it neither
    moves nor blows; a warning naming them goes to ``machine.warnings`` (and the
    timeline's ``info["warnings"]``). A trace that records none of the machine's valves
    is an error (the wrong file, or other names). Times beyond ten years (the longest
    horizon plcpred runs), more than MAX_ROWS rows or MAX_IO_SIGNALS signals, and lines
    longer than MAX_LINE_BYTES are errors naming the line."""
    path = Path(path)
    file = str(path)
    trace = _read_io_trace(path, file)
    warnings = _hold_missing_valves(file, machine, trace) if machine is not None else []
    return _trace_timeline(trace, file, horizon_s, warnings)


@dataclass
class _IoTrace:
    """A recorded I/O trace's changes as read: the numbers only (8 + 4 + 8 bytes a row:
    lists of Python numbers take four times it), signals by their first spelling."""
    index: dict = field(default_factory=dict)        # NAME (upper case) -> signal index
    names: list = field(default_factory=list)
    t_ns: array = field(default_factory=lambda: array("q"))
    sig: array = field(default_factory=lambda: array("i"))
    val: array = field(default_factory=lambda: array("d"))

    def add(self, k: int, t_ns: int, value: float) -> None:
        """Signal ``k`` changes to ``value`` at ``t_ns``."""
        self.t_ns.append(t_ns)
        self.sig.append(k)
        self.val.append(value)

    def signal(self, name: str, file: str, lineno: int) -> int:
        """The index of signal ``name``, a new one where it is first seen."""
        key = name.upper()
        k = self.index.get(key)
        if k is None:
            if len(self.names) >= MAX_IO_SIGNALS:
                raise MeasuredDataError(f"{file}: line {lineno}: more than "
                                        f"{MAX_IO_SIGNALS:,} signals")
            k = self.index[key] = len(self.names)
            self.names.append(name)
        return k


def _read_io_trace(path: Path, file: str) -> _IoTrace:
    """The changes of a ``time_s,signal,value`` trace, each row checked as it comes; a
    signal first seen after time 0 is FALSE (0) from time 0 until then."""
    trace = _IoTrace()
    with DataLines(path, MeasuredDataError, MAX_ROWS, extra=1) as lines:
        rows = _csv_rows(csv.reader(lines), file, 0)
        header = [h.strip().lower() for h in next(rows, (0, []))[1]]
        if header[:3] != ["time_s", "signal", "value"]:
            raise MeasuredDataError(f"{file}: line 1: expected the header "
                                    "time_s,signal,value (the timeline.csv form)")
        for lineno, row in rows:
            if not row or not "".join(row).strip():
                continue
            t, name, v = _io_change(row, file, lineno)
            new = name.upper() not in trace.index
            k = trace.signal(name, file, lineno)
            if new and t > 0:
                trace.add(k, 0, 0.0)
            trace.add(k, round(t * NS), v)
    if not trace.names:
        raise MeasuredDataError(f"{file}: no rows")
    return trace


def _io_change(row: list[str], file: str, lineno: int) -> tuple[float, str, float]:
    """(time s, signal name, value) of a trace's row, refused where a field is missing
    or not a number, the time negative or beyond the longest run, or the name empty."""
    if len(row) < 3:
        raise MeasuredDataError(f"{file}: line {lineno}: expected time_s,signal,value")
    try:
        t = float(row[0])
        v = float(row[2])
    except ValueError:
        raise MeasuredDataError(f"{file}: line {lineno}: time and value must be "
                                "numbers") from None
    if not (math.isfinite(t) and math.isfinite(v)) or t < 0:
        raise MeasuredDataError(f"{file}: line {lineno}: time must be >= 0 and "
                                "values finite")
    if t > MAX_HORIZON_NS / NS:
        raise MeasuredDataError(
            f"{file}: line {lineno}: time {row[0].strip()[:40]} s is beyond "
            f"{MAX_HORIZON_TEXT}, the longest run plcpred models (times are "
            "seconds from the run's start)")
    name = row[1].strip()
    if not name:
        raise MeasuredDataError(f"{file}: line {lineno}: empty signal name")
    return t, name, v


def _trace_timeline(trace: _IoTrace, file: str, horizon_s: float | None,
                    warnings: list[str]) -> Timeline:
    """The trace's changes sorted by time as a recorded Timeline, its horizon the last
    change or ``horizon_s`` where that is longer."""
    t_arr = np.frombuffer(trace.t_ns, dtype=np.int64)
    s_arr = np.frombuffer(trace.sig, dtype=np.int32)
    v_arr = np.frombuffer(trace.val, dtype=float)
    if np.any(t_arr[1:] < t_arr[:-1]):
        order = np.argsort(t_arr, kind="stable")
        t_arr, s_arr, v_arr = t_arr[order], s_arr[order], v_arr[order]
    horizon_ns = int(t_arr[-1])
    if horizon_s is not None and horizon_s > 0:
        horizon_ns = max(horizon_ns, parse_horizon(float(horizon_s)))
    signals = [Signal(n, "output", "bool") for n in trace.names]
    return Timeline(signals, t_arr, s_arr, v_arr, max(horizon_ns, 1),
                    info={"mode": "recorded", "source": file, "warnings": warnings})


def _hold_missing_valves(file: str, machine, trace: _IoTrace) -> list[str]:
    """Add the machine's valves a trace lacks, each held at its initial value from time
    0 (see :func:`read_io_timeline`); the warning that says so, if any."""
    held: dict[str, tuple[str, float, list[str]]] = {}   # KEY -> (name, value, consumers)
    for c in machine.consumers:
        for v in c.valve:
            if v.upper() in trace.index:
                continue
            value = 1.0 if (c.is_cylinder and len(c.valve) == 1
                            and c.initial == "extended") else 0.0
            held.setdefault(v.upper(), (v, value, []))[2].append(c.name)
    if not held:
        return []
    names = trace.names
    if len(held) == len({v.upper() for c in machine.consumers for v in c.valve}):
        raise MeasuredDataError(
            f"{file}: records none of the valves of {machine.name} "
            f"({', '.join(v for v, _, _ in held.values())}); its signals are "
            f"{', '.join(names[:12])}" + (" ..." if len(names) > 12 else "")
            + " (the wrong trace, or the valves under other names?)")
    for key, (v, value, _) in held.items():
        trace.index[key] = len(names)
        names.append(v)
        trace.add(trace.index[key], 0, value)
    listed = "; ".join(f"{v} ({', '.join(who)})" for v, _, who in held.values())
    warning = (f"{file}: no rows for the valve(s) {listed}: held at their initial value "
               "(off, or on for a cylinder that starts extended) for the whole run; record "
               "them for a diagnosis of those consumers")
    machine.warnings.append(warning)
    return [warning]
