"""The ``plcpred`` command line. Each subcommand is a thin layer over a library call."""
from __future__ import annotations

import argparse
import sys

from . import __version__


def _summary(program) -> str:
    from .parser import ir

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
    from .parser import ProgramError, load_program
    from .parser.check import check_program

    parsed = {}
    failed = False
    for path in args.programs:
        try:
            parsed[path] = load_program(path)
        except ProgramError as e:
            print(e, file=sys.stderr)
            failed = True
    context = list(parsed.values())
    for path, program in parsed.items():
        errors, warnings = ([], []) if args.syntax_only else check_program(program, context)
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


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="plcpred",
        description="Predict the compressed-air demand of a machine from its PLC program.")
    ap.add_argument("--version", action="version", version=f"plcpred {__version__}")
    sub = ap.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    p = sub.add_parser("check", help="parse and validate PLC programs",
                       description="Parse and validate programs (.st, .seq, PLCopen .xml). "
                                   "Files given together are checked as one project, so a "
                                   "global variable list can be checked with the POUs using "
                                   "it. Errors print as file:line:col: message; exit 1 if any.")
    p.add_argument("programs", nargs="+", metavar="PROGRAM")
    p.add_argument("--syntax-only", action="store_true",
                   help="skip semantic checks (for fragments using libraries not at hand)")
    p.set_defaults(func=cmd_check)
    return ap


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
