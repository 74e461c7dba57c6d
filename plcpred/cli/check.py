"""``plcpred check`` (parse and validate programs) and ``plcpred init`` (a machine file to
start from). ``check --syntax-only`` runs from :mod:`.syntax`, without the compiler."""
from __future__ import annotations

import sys
from functools import reduce
from pathlib import Path

from ..errors import EXIT_BAD_INPUT, EXIT_GATE_FAILED
from ..output import OutputError, atomic_write_text
from ..parser import ProgramError, load_program
from ..parser.check import ExternalWarning, check_program
from ..parser.libraries import library_program
from ..sequencer.compiler import compile_program
from ..skeleton import machine_skeleton
from .syntax import Reading, cmd_check_syntax


def cmd_check(args) -> int:
    """Exit 1 where a program has errors (what check looks for), 2 where a file cannot
    be read as a program at all (bad input)."""
    if args.syntax_only:
        return cmd_check_syntax(args)
    reading = Reading(args)
    parsed = reading.parsed
    context = list(parsed.values())
    try:
        # what the files use from libraries: checked against, not reported on
        context.append(library_program(context, args.lib))
    except ProgramError as e:
        print(e, file=sys.stderr)
        return EXIT_GATE_FAILED
    results = {path: check_program(program, context, args.allow_external)
               for path, program in parsed.items()}
    externals = any(isinstance(w, ExternalWarning) for _, ws in results.values() for w in ws)
    if not externals and not any(errors for errors, _ in results.values()):
        compile_error = _compile_check(context)
        if compile_error is not None:
            path = next((p for p in parsed if p == compile_error.file), next(iter(parsed)))
            results[path][0].append(compile_error)
    return reading.report(results)


def _compile_check(programs):
    """Compile the project as ``timeline`` would, so that ``check`` reports first what
    running it would reject: the CompileError, or None (also for a library, where no
    PROGRAM runs)."""
    if not any(p.kind == "PROGRAM" for prog in programs for p in prog.pous):
        return None
    try:
        compile_program(reduce(lambda a, b: a.merge(b), programs))
    except ProgramError as e:
        return e
    return None


def cmd_init(args) -> int:
    out = Path(args.out) if args.out else None
    if out is not None and out.exists() and not args.force:
        print(f"plcpred init: {out} exists; give --force to overwrite it", file=sys.stderr)
        return 2
    if out is not None and out.suffix.lower() != ".toml":
        print(f"plcpred init: {out}: a machine file ends in .toml", file=sys.stderr)
        return 2
    try:
        program = load_program(args.program)
    except ProgramError as e:
        # a program init cannot read is bad input: init writes nothing from it
        for err in [e, *getattr(e, "more", ())]:
            print(err, file=sys.stderr)
        return EXIT_BAD_INPUT
    text = machine_skeleton(program, Path(args.program), out)
    if out is None:
        print(text, end="")
        return 0
    try:
        atomic_write_text(out, text)
    except (OSError, OutputError) as e:
        print(f"plcpred init: cannot write {out}: {e}", file=sys.stderr)
        return 2
    print(f"wrote {out}: fill in its inputs and consumers, then "
          f"plcpred predict {out} --horizon 60s --out out/")
    return 0
