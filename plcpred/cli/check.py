"""``plcpred check`` (parse and validate programs) and ``plcpred init`` (a machine file to
start from)."""
from __future__ import annotations

import sys
from functools import reduce
from pathlib import Path

from ..output import OutputError, atomic_write_text
from ..parser import ProgramError, ir, load_program
from ..parser.check import ExternalWarning, check_program
from ..parser.libraries import library_program
from ..sequencer.compiler import compile_program
from ..skeleton import machine_skeleton


def _summary(program) -> str:

    pous = program.pous
    n_vars = sum(len(b.decls) for p in pous for b in p.var_blocks)
    n_vars += sum(len(g.block.decls) for g in program.globals)
    n_vars += sum(len(b.decls) for c in program.configurations for b in c.var_blocks)
    addresses = [d.address for p in pous for d in p.decls() if d.address]
    addresses += [d.address for g in program.globals for d in g.block.decls if d.address]
    addresses += [d.address for c in program.configurations for b in c.var_blocks
                  for d in b.decls if d.address]
    n_in = sum(a.startswith("%I") for a in addresses)
    n_out = sum(a.startswith("%Q") for a in addresses)
    parts = []
    if pous:
        names = ", ".join(f"{p.name}{' [SFC]' if isinstance(p.body, ir.Sfc) else ''}"
                          for p in pous[:6])
        if len(pous) > 6:
            names += ", ..."
        parts.append(f"{len(pous)} POU{'s' if len(pous) != 1 else ''} ({names})")
    if program.types:
        parts.append(f"{len(program.types)} type{'s' if len(program.types) != 1 else ''}")
    if program.configurations:
        parts.append(f"{len(program.configurations)} configuration"
                     f"{'s' if len(program.configurations) != 1 else ''}")
    parts.append(f"{n_vars} variable{'s' if n_vars != 1 else ''}")
    parts.append(f"{len(addresses)} I/O address{'es' if len(addresses) != 1 else ''} "
                 f"({n_in} in, {n_out} out)")
    return ", ".join(parts)


def cmd_check(args) -> int:

    parsed = {}
    failed = False
    for path in args.programs:
        try:
            parsed[path] = load_program(path, libraries=False, dialect=args.dialect)
        except ProgramError as e:
            for err in [e, *getattr(e, "more", ())]:   # every syntax error, up to 20
                print(err, file=sys.stderr)
            failed = True
    context = list(parsed.values())
    if not args.syntax_only:
        try:
            # what the files use from libraries: checked against, not reported on
            context.append(library_program(context, args.lib))
        except ProgramError as e:
            print(e, file=sys.stderr)
            return 1
    results = {path: ([], []) if args.syntax_only else
               check_program(program, context, args.allow_external)
               for path, program in parsed.items()}
    externals = any(isinstance(w, ExternalWarning) for _, ws in results.values() for w in ws)
    if not args.syntax_only and not externals and \
            not any(errors for errors, _ in results.values()):
        compile_error = _compile_check(context)
        if compile_error is not None:
            path = next((p for p in parsed if p == compile_error.file), next(iter(parsed)))
            results[path][0].append(compile_error)
    for path, program in parsed.items():
        errors, warnings = results[path]
        for w in warnings:
            print(w, file=sys.stderr)
        for e in errors:
            print(e, file=sys.stderr)
        if errors:
            failed = True
            print(f"{path}: {len(errors)} error{'s' if len(errors) != 1 else ''}")
        else:
            note = f" ({len(warnings)} warning{'s' if len(warnings) != 1 else ''})" if warnings else ""
            print(f"{path}: ok{note}: {_summary(program)}")
    return 1 if failed else 0


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
        for err in [e, *getattr(e, "more", ())]:
            print(err, file=sys.stderr)
        return 1
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
