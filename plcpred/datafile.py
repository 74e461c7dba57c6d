"""Reading a data file a user brings (a flow log, an I/O trace, a test record) a block
at a time, so that memory stays bounded whatever the file's size and a bad line is an
error naming the file and line."""
from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

from .errors import PlcpredError

MAX_ROWS = 20_000_000          # lines of one file, unless the reader says fewer
MAX_LINE_BYTES = 100_000       # one line (a logger writes well under 1,000)
CHUNK_BYTES = 1 << 20          # read a megabyte at a time

# How a file that is no text starts: a zip archive (Excel .xlsx, LibreOffice .ods) or an
# OLE2 compound file (Excel 97-2003 .xls), which a user may give for the CSV they meant
_WORKBOOK_MAGIC = (b"PK\x03\x04", b"\xd0\xcf\x11\xe0\xa1\xb1\x1a\xe1")
_UTF16_BOMS = (b"\xff\xfe", b"\xfe\xff")

# The units a logged column may be in, as the readers know them: each name (what
# --flow-unit and --supply-unit take) with the spellings loggers write in headers (matched
# in lower case, without spaces, with 3 for ³). Flows are volumes of free air at the
# meter's reference condition; pressures are gauge unless the name ends in "a" (absolute).
FLOW_UNIT_SPELLINGS = {
    "l/min": ("l/min", "nl/min", "lpm", "slpm", "sl/min", "l_min", "nl_min", "lmin",
              "nlmin", "ln/min"),
    "l/s": ("l/s", "nl/s", "l_s", "nl_s", "ln/s"),
    "m3/h": ("m3/h", "nm3/h", "m3_h", "nm3_h", "m3h", "nm3h", "m3n/h"),
    "m3/min": ("m3/min", "nm3/min", "m3_min", "nm3_min", "m3min", "m3n/min"),
    "scfm": ("scfm", "cfm"),
}
PRESSURE_UNIT_SPELLINGS = {
    "bar": ("bar", "barg", "bar(g)", "bar_g", "bar(ü)", "barü"),
    "bara": ("bara", "bar(a)", "bar_a", "barabs", "bar(abs)", "bar_abs"),
    "psi": ("psi", "psig", "psi(g)", "psi_g"),
    "psia": ("psia", "psi(a)", "psi_a", "psiabs"),
    "kpa": ("kpa", "kpag", "kpa(g)", "kpa_g"),
    "kpaa": ("kpaa", "kpa(a)", "kpa_a", "kpaabs"),
    "mpa": ("mpa", "mpag", "mpa(g)", "mpa_g"),
    "mbar": ("mbar", "mbarg", "mbar(g)", "mbar_g"),
}


def unit_name(text: str, spellings: dict) -> str | None:
    """The name in ``spellings`` (FLOW_UNIT_SPELLINGS, PRESSURE_UNIT_SPELLINGS) that
    ``text`` spells (``Nm³/h`` -> ``m3/h``, ``psig`` -> ``psi``), or None."""
    key = text.strip().lower().replace(" ", "").replace("³", "3")
    return next((name for name, known in spellings.items() if key in known), None)


def known_units(spellings: dict) -> str:
    """The names and spellings of ``spellings`` as a help text lists them."""
    return ", ".join(f"{name} ({', '.join(s for s in known[1:] if '_' not in s)})"
                     if len(known) > 1 else name for name, known in spellings.items())


# what a file that is not UTF-8 is read as when its first block reads so: the code page
# Windows programs write CSV in (Western European; ³, °, ä as single bytes)
LEGACY_ENCODING = "cp1252"
_UTF8_SEQUENCE = re.compile(rb"[\xc2-\xf4][\x80-\xbf]")


def _legacy_text(data: bytes) -> list[str] | None:
    """``data``'s lines in LEGACY_ENCODING, or None where it is not such text either, or
    holds what UTF-8 writes for a character beyond ASCII (a UTF-8 file with a damaged
    byte, whose m³/h must not be read as mÂ³/h)."""
    if _UTF8_SEQUENCE.search(data):
        return None
    try:
        return data.decode(LEGACY_ENCODING).splitlines()
    except UnicodeDecodeError:
        return None


class DataLines:
    """A text file's lines without their line ends (split where ``str.splitlines``
    splits), read and decoded a block at a time: none longer than MAX_LINE_BYTES, at
    most ``max_rows`` + ``extra`` of them (``extra``: a header's). Errors are ``error``s
    naming the file and line. Iterate it once (in a ``with`` block)."""

    def __init__(self, path: Path, error: type[PlcpredError], max_rows: int = MAX_ROWS,
                 extra: int = 0):
        self.file = str(path)
        self.max_rows = max_rows
        self.limit = max_rows + extra
        self._exc = error
        try:
            # held open while the lines are iterated; closed by __exit__
            self._f = open(path, "rb")  # noqa: SIM115
        except OSError as e:
            raise self._exc(f"{path}: cannot read file: {e.strerror}") from None
        try:
            self._refuse_binary(self._f.read(8))
            self._f.seek(0)
        except BaseException:
            self._f.close()
            raise
        self._it = self._read()

    def _refuse_binary(self, start: bytes) -> None:
        """A spreadsheet or UTF-16 text, refused with what to do instead."""
        if start.startswith(_WORKBOOK_MAGIC):
            raise self._exc(f"{self.file}: a spreadsheet workbook (.xlsx, .xls or .ods), "
                            "not CSV text: export the sheet as CSV (in Excel: File > Save "
                            "As > CSV UTF-8 (comma delimited)) and give that file")
        if start.startswith(_UTF16_BOMS):
            raise self._exc(f"{self.file}: UTF-16 text (Excel's \"Unicode text\"): save "
                            "it as CSV UTF-8 (in Excel: File > Save As > CSV UTF-8 (comma "
                            "delimited)) and give that file")

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self._it.close()
        self._f.close()

    def __iter__(self):
        return self._it

    def _error(self, line: int, what: str) -> PlcpredError:
        return self._exc(f"{self.file}: line {line}: {what}")

    def _too_long(self, line: int) -> PlcpredError:
        return self._error(line, f"longer than {MAX_LINE_BYTES:,} bytes (a data file's "
                                 "lines are short: is this the right file?)")

    def _read(self) -> Iterator[str]:
        number = 0              # lines read before the block
        encoding = "utf-8-sig"  # a byte order mark at the start is no text
        tail = b""
        while True:
            try:
                block = self._f.read(CHUNK_BYTES)
            except OSError as e:
                raise self._exc(f"{self.file}: cannot read file: {e.strerror}") from None
            data = tail + block
            if not data:
                return
            problem = None      # (line, what): raised after the lines before it
            if block:
                # whole lines only: up to the last line end (a CR at the very end may be
                # the first half of a CR LF)
                cut = max(data.rfind(b"\n"), data.rfind(b"\r", 0, len(data) - 1)) + 1
                data, tail = data[:cut], data[cut:]
                long_tail = len(tail) > MAX_LINE_BYTES
            else:
                tail, long_tail = b"", False
            try:
                lines = data.decode(encoding).splitlines()
            except UnicodeDecodeError as e:
                legacy = _legacy_text(data) if number == 0 else None
                if legacy is not None:
                    # a logger's export in the Windows code page (Volumenstrom [m³/h])
                    encoding, lines = LEGACY_ENCODING, legacy
                else:
                    # the lines before the one that holds the byte (its start is their last)
                    lines = (data[:e.start].decode(encoding) + "x").splitlines()[:-1]
                    problem = (number + len(lines) + 1, "not UTF-8 text")
            if problem is None and long_tail:
                problem = (number + len(lines) + 1, None)
            if data and encoding == "utf-8-sig":
                encoding = "utf-8"
            if max(map(len, lines), default=0) > MAX_LINE_BYTES:
                k = next(k for k, line in enumerate(lines) if len(line) > MAX_LINE_BYTES)
                lines, problem = lines[:k], (number + k + 1, None)
            if number + len(lines) > self.limit:
                yield from lines[:self.limit - number]
                raise self._error(self.limit + 1, f"more than {self.max_rows:,} rows, the most "
                                  "plcpred reads from one file (split the log into runs)")
            number += len(lines)
            yield from lines
            if problem is not None:
                line, what = problem
                raise self._error(line, what) if what else self._too_long(line)
