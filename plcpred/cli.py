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


def _fail(message: str) -> int:
    print(f"plcpred: error: {message}", file=sys.stderr)
    return 2


def cmd_timeline(args) -> int:
    from pathlib import Path

    from .machine import MachineError, load_machine
    from .parser import ProgramError
    from .sequencer import (CompileError, ExecutionError, SequencerError, parse_horizon,
                            unfold)

    try:
        horizon_ns = parse_horizon(args.horizon)
    except ValueError as e:
        return _fail(str(e))
    try:
        machine = load_machine(args.machine)
        tl = unfold(machine, horizon_ns / 1e9, scan_stepping=args.scan_stepping,
                    program=args.program)
    except (MachineError, SequencerError, ProgramError, CompileError, ExecutionError) as e:
        print(e, file=sys.stderr)
        return 1
    for w in machine.warnings:
        print(f"warning: {w}", file=sys.stderr)
    out = Path(args.out)
    tl.to_csv(out / "timeline.csv")
    info = tl.info
    mode = info["mode"]
    if info.get("period_s"):
        mode += (f", repeats every {info['period_s']:g} s from {info['tiled_from_s']:g} s "
                 "(tiled)")
    print(f"{machine.name}: {len(tl.signals)} signals, {len(tl.time_ns)} changes over "
          f"{tl.horizon_s:g} s; {info['scans']} scans executed of "
          f"{int(tl.horizon_ns // (info['scan_ms'] * 1e6)) + 1} ({mode}); "
          f"{info['wall_s']:.2f} s")
    print(f"wrote {out / 'timeline.csv'}")
    return 0


def cmd_predict(args) -> int:
    from .air import predict
    from .machine import MachineError, load_machine
    from .parser import ProgramError
    from .report import consumer_table
    from .sequencer import (CompileError, ExecutionError, SequencerError, parse_horizon)

    try:
        horizon_ns = parse_horizon(args.horizon)
        dt_s = parse_horizon(args.dt) / 1e9 if args.dt else None
    except ValueError as e:
        return _fail(str(e).replace("horizon", "duration") if args.dt else str(e))
    try:
        machine = load_machine(args.machine)
        result = predict(machine, horizon_ns / 1e9, dt=dt_s, program=args.program)
        result.write(args.out, plot=not args.no_plot)
    except (MachineError, SequencerError, ProgramError, CompileError, ExecutionError) as e:
        print(e, file=sys.stderr)
        return 1
    for w in machine.warnings:
        print(f"warning: {w}", file=sys.stderr)
    prof = result.profile
    split = prof.by_role_nl()
    total = prof.total_nl or 1.0
    print(f"{machine.name}: {prof.horizon_s:g} s at {machine.supply_bar_g:g} bar(g), "
          f"grid {prof.dt_s:g} s")
    print()
    print(consumer_table(prof))
    print()
    print(f"active {split['active']:.2f} NL ({100 * split['active'] / total:.1f} %), "
          f"passive {split['passive']:.2f} NL ({100 * split['passive'] / total:.1f} %), "
          f"leaks {split['leak']:.2f} NL ({100 * split['leak'] / total:.1f} %)")
    print(f"mean {prof.mean_l_min:.1f} NL/min, peak {prof.peak_l_min():.1f} NL/min "
          f"(grid), {prof.peak_l_min(1.0):.1f} NL/min (1 s), "
          f"{prof.peak_l_min(60.0):.1f} NL/min (1 min)")
    print(f"wrote {', '.join(str(p) for p in result.write_files)}")
    return 0


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

    p = sub.add_parser("timeline", help="run a machine's program into output-bit timelines",
                       description="Run the machine's PLC program against its plant I/O "
                                   "model (cylinder end switches, input schedules) over a "
                                   "horizon and write DIR/timeline.csv: time_s,signal,value, "
                                   "one row per change, initial values at 0.")
    p.add_argument("machine", metavar="MACHINE", help="machine file (.toml)")
    p.add_argument("--horizon", required=True,
                   help="how long to run: 60s, 1m30s, 8h, T#1m30s (m = minutes)")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    p.add_argument("--program", metavar="PROGRAM",
                   help="run this program instead of the one the machine file names")
    p.add_argument("--scan-stepping", action="store_true",
                   help="execute every scan instead of jumping between events (the slow "
                        "reference the event-driven mode must equal)")
    p.set_defaults(func=cmd_timeline)

    p = sub.add_parser("predict", help="forecast a machine's compressed-air demand",
                       description="Run the machine's program (as `timeline` does) and turn "
                                   "its timeline into air demand: D1 volumes per cylinder "
                                   "stroke, D2 flows of nozzles while on and of leaks always. "
                                   "Writes DIR/timeline.csv, demand.csv (NL/min per consumer "
                                   "on a time grid), summary.json and demand.png, and prints "
                                   "a table of per-consumer totals.")
    p.add_argument("machine", metavar="MACHINE", help="machine file (.toml)")
    p.add_argument("--horizon", required=True,
                   help="how long to run: 60s, 1m30s, 8h, T#1m30s (m = minutes)")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    p.add_argument("--dt", help="grid step of demand.csv (default 10ms, coarser for long "
                                "horizons so the file stays under a few tens of MB)")
    p.add_argument("--program", metavar="PROGRAM",
                   help="run this program instead of the one the machine file names")
    p.add_argument("--no-plot", action="store_true", help="skip demand.png")
    p.set_defaults(func=cmd_predict)
    return ap


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
