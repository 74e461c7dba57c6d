"""The base of every error plcpred reports to a user (as opposed to a bug), and the exit
codes of the command line.

Each package keeps its own class (a program's :class:`~plcpred.parser.ProgramError` with
file, line and column; a machine file's ``MachineError`` with table and key; ...); they all
derive from :class:`PlcpredError`, so a caller can catch "anything plcpred says is wrong
with the input" in one clause, and the command line can tell those from internal errors.
"""

# The exit codes, for every command. CI reads 1 as "the gate failed", so only a result
# that is a verdict on the machine or program gives it; anything wrong with what was
# given (a typo in a machine file, a missing file, an option) is 2 on every command.
EXIT_OK = 0
EXIT_GATE_FAILED = 1
EXIT_BAD_INPUT = 2
EXIT_INTERNAL = 3
EXIT_NEVER_MOVES = 4       # compare: NEW never moves (a deadlock passes no air gate)
EXIT_THROUGHPUT_DROP = 5   # compare: NEW completes fewer cycles per hour than allowed
EXIT_INTERRUPTED = 130     # SIGINT (Ctrl-C)
EXIT_TERMINATED = 143      # SIGTERM

# (code, when), as docs/reference/cli.md shows them (a test keeps the two equal)
EXIT_CODES = (
    (EXIT_OK, ("success; for `check`: every program is valid; for `compare`: NEW is "
               "within the allowance")),
    (EXIT_GATE_FAILED, ("a gate failed: `compare` found that NEW uses more air than "
                        "allowed, `check` found errors in a program. No other command "
                        "exits 1")),
    (EXIT_BAD_INPUT, ("bad input or usage, on every command: a typo or a missing key in a "
                      "machine or truth file, a file that is missing or unreadable, a "
                      "program that does not compile or cannot run, a bad option value, "
                      "an output path that cannot be written (checked before any work)")),
    (EXIT_INTERNAL, "an internal error (a bug): one line; `--debug` shows the traceback"),
    (EXIT_NEVER_MOVES, "`compare` only: NEW never moves (no valve output ever changes)"),
    (EXIT_THROUGHPUT_DROP, ("`compare` only: NEW's cycles per hour drop by more than "
                            "`--max-throughput-drop` (or it completes none)")),
    (EXIT_INTERRUPTED, "interrupted (Ctrl-C); nothing half-written is left"),
    (EXIT_TERMINATED, "terminated (SIGTERM); nothing half-written is left"),
)


class PlcpredError(Exception):
    """A problem with the user's input, files or settings, with a message that says so."""
