"""``main``: one command run with the exit codes CI relies on, interrupts and internal
errors turned into one line each."""
from __future__ import annotations

import importlib
import os
import signal
import sys

from ..errors import (
    EXIT_BAD_INPUT,
    EXIT_INTERNAL,
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_TERMINATED,
    PlcpredError,
)
from ..memory import use_large_malloc_thresholds
from .parser import build_parser


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised where the program is so that temporary files are cleaned up."""


def _on_sigterm(signum, frame):
    raise Terminated()


def _allowed_roots(argv: list[str]) -> tuple[list[str], list[str]]:
    """``--allow-root DIR`` (or ``=DIR``) taken out wherever it stands, as ``--debug`` is:
    it belongs to no one command. (argv without them, the folders)."""
    rest, roots = [], []
    it = iter(argv)
    for a in it:
        if a == "--":
            rest += [a, *it]
        elif a == "--allow-root":
            root = next(it, None)
            if root is None:
                rest.append(a)              # argparse says what is missing
            else:
                roots.append(root)
        elif a.startswith("--allow-root="):
            roots.append(a.partition("=")[2])
        else:
            rest.append(a)
    return rest, roots


def command_of(args) -> tuple[str, str]:
    """(module, function) of the command ``args`` names. ``check --syntax-only`` has a
    module of its own (:mod:`.syntax`): a syntax check needs neither the semantic checks
    nor the compiler, and its module imports neither."""
    if tuple(args.run) == ("check", "cmd_check") and getattr(args, "syntax_only", False):
        return "syntax", "cmd_check_syntax"
    return tuple(args.run)


def run_command(args) -> int:
    """The command ``args`` names, its module imported now: each command pays only for
    what it uses (a syntax check does not wait for numpy, scipy and the compiler)."""
    module, function = command_of(args)
    command = getattr(importlib.import_module(f".{module}", __package__), function)
    # the parser's package is imported with the command, not for --help
    from ..parser.files import extra_roots
    with extra_roots(args.allow_root):
        return command(args)


def main(argv=None) -> int:
    """Run one command. Exit codes (plcpred.errors.EXIT_CODES): 0 ok, 1 a gate failed
    (``compare``, ``check``), 2 bad input or usage on every command, 3 an internal error
    (a bug: one line; ``--debug`` shows the traceback), 4/5 ``compare``'s never-moves and
    throughput gates, 130/143 interrupted by SIGINT/SIGTERM."""

    argv = list(sys.argv[1:] if argv is None else argv)
    debug = "--debug" in argv
    argv = [a for a in argv if a != "--debug"]
    argv, roots = _allowed_roots(argv)
    args = build_parser().parse_args(argv)
    args.argv = argv
    args.allow_root = list(args.allow_root) + roots
    use_large_malloc_thresholds()      # a third of a prediction's time otherwise (memory.py)
    try:
        previous = signal.signal(signal.SIGTERM, _on_sigterm)
    except ValueError:  # not the main thread (a library caller): leave signals alone
        previous = None
    try:
        code = run_command(args)
        sys.stdout.flush()
        return code
    except BrokenPipeError:
        # the reader went away (plcpred ... | head): not an error of ours; stop quietly
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return EXIT_OK
    except Terminated:
        print("plcpred: terminated; temporary files removed, nothing half-written left",
              file=sys.stderr)
        return EXIT_TERMINATED
    except KeyboardInterrupt:
        print("plcpred: interrupted; temporary files removed, nothing half-written left",
              file=sys.stderr)
        return EXIT_INTERRUPTED
    except Exception as e:
        if isinstance(e, PlcpredError):
            print(f"plcpred: error: {e}", file=sys.stderr)
            return EXIT_BAD_INPUT
        if isinstance(e, MemoryError):
            print("plcpred: error: out of memory (a shorter --horizon or a coarser --dt "
                  "needs less)", file=sys.stderr)
            return EXIT_BAD_INPUT
        if debug:
            raise
        message = str(e).splitlines()[0][:300] if str(e) else ""
        print(f"plcpred: internal error: {type(e).__name__}"
              f"{': ' + message if message else ''} (please report it; run again with "
              "--debug for the traceback)", file=sys.stderr)
        return EXIT_INTERNAL
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
