"""``plcpred check --syntax-only``, and what the full check (:mod:`.check`) shares with it:
reading the programs and reporting on them. A module of its own because a syntax check
needs neither the semantic checks, the library stubs nor the compiler, and so answers in
the time of a parse."""
from __future__ import annotations

import sys

from ..errors import EXIT_BAD_INPUT, EXIT_GATE_FAILED, EXIT_OK
from ..parser import ProgramError, ProgramFileError, ir, load_program


def summary(program) -> str:
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


class Reading:
    """The programs of a ``check`` as read: ``parsed`` (path -> program), and whether a
    file had syntax errors (``failed``) or could not be read as a program at all
    (``unreadable``), each already printed."""

    def __init__(self, args):
        self.parsed = {}
        self.failed = self.unreadable = False
        for path in args.programs:
            try:
                self.parsed[path] = load_program(path, libraries=False, dialect=args.dialect)
            except ProgramFileError as e:
                print(e, file=sys.stderr)
                self.unreadable = True
            except ProgramError as e:
                for err in [e, *getattr(e, "more", ())]:   # every syntax error, up to 20
                    print(err, file=sys.stderr)
                self.failed = True

    def report(self, results) -> int:
        """Print each program's warnings and errors (``results``: path -> (errors,
        warnings)) and its summary line. Exit 1 where a program has errors (what check
        looks for), 2 where a file cannot be read as a program at all (bad input)."""
        failed = self.failed
        for path, program in self.parsed.items():
            errors, warnings = results[path]
            for w in warnings:
                print(w, file=sys.stderr)
            for e in errors:
                print(e, file=sys.stderr)
            if errors:
                failed = True
                print(f"{path}: {len(errors)} error{'s' if len(errors) != 1 else ''}")
            else:
                note = (f" ({len(warnings)} warning{'s' if len(warnings) != 1 else ''})"
                        if warnings else "")
                print(f"{path}: ok{note}: {summary(program)}")
        if self.unreadable:
            return EXIT_BAD_INPUT
        return EXIT_GATE_FAILED if failed else EXIT_OK


def cmd_check_syntax(args) -> int:
    reading = Reading(args)
    return reading.report({path: ([], []) for path in reading.parsed})
