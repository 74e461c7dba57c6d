"""The base of every error plcpred reports to a user (as opposed to a bug).

Each package keeps its own class (a program's :class:`~plcpred.parser.ProgramError` with
file, line and column; a machine file's ``MachineError`` with table and key; ...); they all
derive from :class:`PlcpredError`, so a caller can catch "anything plcpred says is wrong
with the input" in one clause, and the command line can tell those from internal errors.
"""


class PlcpredError(Exception):
    """A problem with the user's input, files or settings, with a message that says so."""
