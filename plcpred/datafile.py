"""Reading a data file a user brings (a flow log, an I/O trace, a test record) a block
at a time, so that memory stays bounded whatever the file's size and a bad line is an
error naming the file and line."""
from __future__ import annotations

from pathlib import Path
from typing import Iterator

from .errors import PlcpredError

MAX_ROWS = 20_000_000          # lines of one file, unless the reader says fewer
MAX_LINE_BYTES = 100_000       # one line (a logger writes well under 1,000)
CHUNK_BYTES = 1 << 20          # read a megabyte at a time


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
            self._f = open(path, "rb")
        except OSError as e:
            raise self._exc(f"{path}: cannot read file: {e.strerror}") from None
        self._it = self._read()

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
                # the lines before the one that holds the byte (its start is their last)
                lines = (data[:e.start].decode(encoding) + "x").splitlines()[:-1]
                problem = (number + len(lines) + 1, "not UTF-8 text")
            else:
                if long_tail:
                    problem = (number + len(lines) + 1, None)
            if data:
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
