"""Errors that point at a place in a program file."""
from __future__ import annotations

from ..errors import PlcpredError


class ProgramError(PlcpredError):
    """A problem at ``file:line:col``. ``str()`` gives the one-line form the CLI prints.
    A syntax error carries the file's further syntax errors in ``more``."""
    more: tuple = ()

    def __init__(self, message: str, file: str = "<input>", line: int = 0, col: int = 0):
        super().__init__(message)
        self.message = message
        self.file = file
        self.line = line
        self.col = col

    def __str__(self) -> str:
        return f"{self.file}:{self.line}:{self.col}: {self.message}"

    def __reduce__(self):  # survives the trip back from a sweep's worker process
        return (type(self), (self.message, self.file, self.line, self.col))


class ProgramWarning(ProgramError):
    """Not fatal: reported with ``warning:`` in front of the message."""

    def __str__(self) -> str:
        return f"{self.file}:{self.line}:{self.col}: warning: {self.message}"


def at(pos, message: str, cls=ProgramError) -> ProgramError:
    """An error at an IR position (which may be None for synthesised nodes)."""
    if pos is None:
        return cls(message)
    return cls(message, pos.file, pos.line, pos.col)
