"""Signs of life for jobs that take more than a second: the stage a job is in with the
time it has taken so far, and bars over counted work, drawn by tqdm on stderr while
stderr is a terminal. In CI, in a pipe or a file, and with ``--quiet`` every call does
nothing, so a job makes its calls whether anyone watches or not.

A job takes a :class:`Progress` (``None`` stands for :data:`OFF`) and calls

* ``progress.stage("running the program")`` as it enters each part of its work;
* ``with progress.bar(total, "scenarios") as bar:`` around counted work, then
  ``bar.update()`` per item done, or ``bar.update_to(x)`` for work measured in something
  else (simulated seconds).

One line at a time: a stage or a bar replaces the line before it, and the line is
cleared when the job closes its Progress, so what the command prints stays as it was.
"""
from __future__ import annotations

import os
import sys
import threading
from contextlib import contextmanager
from typing import Self

from tqdm import tqdm

# how often the line is redrawn while nothing counts (a stage's clock keeps moving)
TICK_S = 0.5
REDRAW_S = 0.2          # a bar counting fast is redrawn at most this often
STAGE_FORMAT = "{desc} ... {elapsed}"


DEFAULT_WIDTH, DEFAULT_ROWS = 80, 24


def _width(stream) -> int:
    """The terminal's width in columns; 0 where it does not say."""
    try:
        return os.get_terminal_size(stream.fileno()).columns
    except (AttributeError, ValueError, OSError):
        return 0


def is_terminal(stream) -> bool:
    """True when ``stream`` is a terminal someone may be watching (not a pipe, a file or
    CI's log)."""
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):        # no isatty, or closed
        return False


class _Bar:
    """The handle ``Progress.bar`` yields: counts the work done."""

    def __init__(self, line=None):
        self._line = line

    def update(self, n: float = 1) -> None:
        if self._line is not None:
            self._line.update(n)

    def update_to(self, done: float) -> None:
        """Set the work done so far (it may only grow)."""
        if self._line is not None and done > self._line.n:
            self._line.update(min(done, self._line.total or done) - self._line.n)


class Progress:
    """Stages and bars on ``stream`` when ``enabled`` (module docstring); a no-op
    otherwise. Close it (or use it as a context manager) to clear its line."""

    def __init__(self, enabled: bool = False, stream=None, redraw_s: float = REDRAW_S):
        self.enabled = enabled
        self.stream = sys.stderr if stream is None else stream
        self.redraw_s = redraw_s
        self._line = None
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._ticker: threading.Thread | None = None

    @classmethod
    def on_terminal(cls, quiet: bool = False, stream=None) -> Progress:
        """Shown when ``stream`` (default stderr) is a terminal and not ``quiet``."""
        stream = sys.stderr if stream is None else stream
        return cls(not quiet and is_terminal(stream), stream)

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def stage(self, text: str) -> None:
        """The job enters a part of its work called ``text``."""
        if self.enabled:
            self._show(lambda: self._tqdm(desc=text, total=None, bar_format=STAGE_FORMAT))

    @contextmanager
    def bar(self, total: float, unit: str = "it", desc: str = ""):
        """A bar over ``total`` units of work, replacing the line before it."""
        if not self.enabled:
            yield _Bar()
            return
        line = self._show(lambda: self._tqdm(desc=desc or None, total=total, unit=unit))
        try:
            yield _Bar(line)
        finally:
            self._show(None)

    def close(self) -> None:
        """Clear the line and stop redrawing it."""
        if not self.enabled:
            return
        self._show(None)
        self._stop.set()
        if self._ticker is not None and self._ticker is not threading.current_thread():
            self._ticker.join()
            self._ticker = None

    def _tqdm(self, **kw):
        # a terminal that reports no width (a serial console, a bare pseudo-terminal)
        # gets a fixed one: tqdm would draw its lines zero characters wide
        width = {} if _width(self.stream) else {"ncols": DEFAULT_WIDTH, "nrows": DEFAULT_ROWS}
        return tqdm(file=self.stream, leave=False, dynamic_ncols=not width,
                    mininterval=self.redraw_s, **width, **kw)

    def _show(self, make):
        """Replace the line by ``make()`` (None: by none); the old one is cleared first,
        so the new one takes its place on the terminal."""
        with self._lock:
            if self._line is not None:
                self._line.close()
            self._line = line = make() if make is not None else None
        if line is not None and self._ticker is None:
            self._stop.clear()
            self._ticker = threading.Thread(target=self._tick, name="plcpred-progress",
                                            daemon=True)
            self._ticker.start()
        return line

    def _tick(self) -> None:
        while not self._stop.wait(TICK_S):
            with self._lock:
                if self._line is not None:
                    self._line.refresh()


OFF = Progress(enabled=False)


def progress_or_off(progress: Progress | bool | None) -> Progress:
    """``progress`` as a job's argument means it: a :class:`Progress`, True (shown on
    stderr), or None and False (:data:`OFF`, as for a job called from Python)."""
    if isinstance(progress, Progress):
        return progress
    return Progress(enabled=True) if progress else OFF
