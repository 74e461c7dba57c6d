"""Errors that point at a place in a program file."""
from __future__ import annotations

from ..errors import PlcpredError


class Positioned:
    """A message about ``file:line:col`` of a program; ``str()`` gives the one-line form
    the CLI prints."""
    prefix = ""

    def __init__(self, message: str, file: str = "<input>", line: int = 0, col: int = 0):
        if isinstance(self, BaseException):
            super().__init__(message)
        self.message = message
        self.file = file
        self.line = line
        self.col = col

    def __str__(self) -> str:
        return f"{self.file}:{self.line}:{self.col}: {self.prefix}{self.message}"

    def __reduce__(self):  # survives the trip back from a sweep's worker process
        return (type(self), (self.message, self.file, self.line, self.col))


class ProgramError(Positioned, PlcpredError):
    """A problem at ``file:line:col`` that stops the program from being read or run. A
    syntax error carries the file's further syntax errors in ``more``."""
    more: tuple = ()


class ProgramFileError(ProgramError):
    """A program file that cannot be read at all (missing, unreadable, a machine file
    given as a program): bad input (exit 2), not a finding in a program (exit 1)."""


class ProgramWarning(Positioned):
    """Not fatal: collected, never raised (so ``except ProgramError`` never takes one),
    and reported with ``warning:`` in front of the message."""
    prefix = "warning: "


def at(pos, message: str, cls=ProgramError) -> ProgramError:
    """An error at an IR position (which may be None for synthesised nodes)."""
    if pos is None:
        return cls(message)
    return cls(message, pos.file, pos.line, pos.col)
