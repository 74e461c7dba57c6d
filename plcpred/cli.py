"""The ``plcpred`` command line. Each subcommand is a thin layer over a library call."""
from __future__ import annotations

import argparse
import csv
import io
import json
import os
import re
import signal
import sys
from functools import reduce
from pathlib import Path

from . import __version__
from .errors import PlcpredError


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
    from .parser.check import ExternalWarning, check_program
    from .parser.libraries import library_program

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

    from .parser import ProgramError
    from .sequencer.compiler import compile_program

    if not any(p.kind == "PROGRAM" for prog in programs for p in prog.pous):
        return None
    try:
        compile_program(reduce(lambda a, b: a.merge(b), programs))
    except ProgramError as e:
        return e
    return None


def _durations(args) -> tuple[float, float | None]:
    """(horizon in s, grid step in s or None) from --horizon and --dt."""
    from .sequencer import parse_horizon

    horizon_s = parse_horizon(args.horizon) / 1e9
    dt = getattr(args, "dt", None)
    if not dt:
        return horizon_s, None
    try:
        return horizon_s, parse_horizon(dt) / 1e9
    except ValueError:
        raise ValueError(f"--dt: cannot read {dt!r}: write e.g. 10ms, 0.5s or 1s") from None


class UsageError(PlcpredError):
    """A bad option value: ``main`` prints it as ``plcpred: error: ...`` and exits 2."""


def _horizon_and_out(args):
    """(horizon in s, grid step in s or None, the checked output directory) of a command
    that runs a machine into DIR; bad values raise (exit 2 through ``main``)."""
    from .output import check_out_dir

    try:
        horizon_s, dt_s = _durations(args)
    except ValueError as e:
        raise UsageError(str(e)) from None
    return horizon_s, dt_s, check_out_dir(args.out)


def _shown_consumers(text: str) -> int | None:
    """``--consumers``: a number of consumers, or ``all``."""
    if text.strip().lower() == "all":
        return None
    try:
        n = int(text)
    except ValueError:
        n = 0
    if n < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1 or 'all', not {text!r}")
    return n


def _consumers_arg(p) -> None:
    from .output import SHOWN_CONSUMERS

    p.add_argument("--consumers", type=_shown_consumers, default=SHOWN_CONSUMERS,
                   metavar="N|all",
                   help="consumers shown one by one in demand.csv and demand.png: the N "
                        "largest users and 'other' for the rest when the machine has more "
                        f"than N+1 (default {SHOWN_CONSUMERS}); 'all' for every one (the "
                        "default grid then coarsens to keep demand.csv to a few million "
                        "values)")


def _command_line(args) -> str:
    """What the manifest records as the command that wrote a directory."""
    return " ".join(["plcpred"] + [str(a) for a in getattr(args, "argv", [])])


def _exit_code(e: PlcpredError) -> int:
    """2 for an error in what the user gave (a machine file, a path, a horizon), 1 for a
    finding about the program (it is invalid, or it cannot run): CI reads 1 as "the gate
    failed", and a typo in a machine file must never look like that."""
    from .machine import MachineError
    from .output import OutputError
    return 2 if isinstance(e, (MachineError, OutputError, UsageError, ValueError)) else 1


def _fail(message: str) -> int:
    print(f"plcpred: error: {message}", file=sys.stderr)
    return 2


def cmd_timeline(args) -> int:
    from .machine import load_machine
    from .output import output_dir
    from .sequencer import unfold

    horizon_s, _, out = _horizon_and_out(args)
    try:
        machine = load_machine(args.machine)
        tl = unfold(machine, horizon_s, scan_stepping=args.scan_stepping,
                    replay=not args.no_replay,
                    program=args.program, max_events=args.max_events)
    except PlcpredError as e:
        print(e, file=sys.stderr)
        return _exit_code(e)
    for w in machine.warnings:
        print(f"warning: {w}", file=sys.stderr)
    if tl.n_changes > args.max_rows:
        return _fail(_too_many_rows(tl.n_changes, args.max_rows) + "; shorten --horizon "
                     "or raise --max-rows")
    with output_dir(out, _command_line(args)) as staging:
        tl.to_csv(staging / "timeline.csv")
    info = tl.info
    mode = info["mode"]
    if info.get("period_s"):
        mode += (f", repeats every {info['period_s']:g} s from {info['tiled_from_s']:g} s "
                 "(tiled)")
    print(f"{machine.name}: {len(tl.signals)} signals, {tl.n_changes} changes over "
          f"{tl.horizon_s:g} s; {info['scans']} scans executed of "
          f"{int(tl.horizon_ns // (info['scan_ms'] * 1e6)) + 1} ({mode}); "
          f"{info['wall_s']:.2f} s")
    print(f"wrote {out / 'timeline.csv'}")
    return 0


def _too_many_rows(rows: int, limit: int) -> str:
    size_mb = rows * 30 / 1e6          # about 30 bytes a row
    size = f"{size_mb / 1e3:.1f} GB" if size_mb >= 1e3 else f"{size_mb:.0f} MB"
    return f"timeline.csv would hold {rows:,} rows (about {size}), more than --max-rows {limit:,}"


def _cut_stroke_warnings(machine, profile) -> list[str]:
    """Drives whose valve reverses before they arrive, booked in full by D1."""
    out = []
    for name, n in profile.cut_strokes.items():
        if n and not machine.consumer(name).partial_strokes:
            total = sum(profile.strokes.get(name, (0, 0)))
            out.append(f'consumer "{name}": {n} of its {total} strokes are cut short by the '
                       "next edge (the valve reverses before the drive arrives, as a short "
                       "pulse or a chattering valve does); D1 books each in full. "
                       "partial_strokes = true (with exhaust_tau_s) counts the share the "
                       "piston covers (docs/reference/physics.md)")
    return out


def cmd_predict(args) -> int:
    from .air import predict
    from .machine import load_machine
    from .output import output_dir
    from .outputs.files import write_prediction
    from .outputs.report import consumer_table

    horizon_s, dt_s, out = _horizon_and_out(args)
    try:
        machine = load_machine(args.machine)
        result = predict(machine, horizon_s, dt=dt_s, program=args.program,
                         max_events=args.max_events, shown=args.consumers)
    except PlcpredError as e:
        print(e, file=sys.stderr)
        return _exit_code(e)
    skipped = []
    keep_timeline = not args.no_timeline
    if keep_timeline and result.timeline.n_changes > args.max_rows:
        keep_timeline = False
        skipped.append(_too_many_rows(result.timeline.n_changes, args.max_rows)
                       + ": not written (demand.csv and summary.json cover the whole "
                         "horizon; raise --max-rows to write it)")
    with output_dir(out, _command_line(args)) as staging:
        written = [out / f.name for f in write_prediction(
            result, staging, plot=not args.no_plot, timeline=keep_timeline)]
    for w in machine.warnings + _cut_stroke_warnings(machine, result.profile) + skipped:
        print(f"warning: {w}", file=sys.stderr)
    prof = result.profile
    split = prof.by_role_nl()
    total = prof.total_nl or 1.0
    print(f"{machine.name}: {prof.horizon_s:g} s at {machine.supply_bar_g:g} bar(g), "
          f"grid {prof.dt_s:g} s")
    print()
    print(consumer_table(prof, args.consumers))
    print()
    print(f"active {split['active']:.2f} NL ({100 * split['active'] / total:.1f} %), "
          f"passive {split['passive']:.2f} NL ({100 * split['passive'] / total:.1f} %), "
          f"leaks {split['leak']:.2f} NL ({100 * split['leak'] / total:.1f} %)")
    # a stroke with neither stroke_time_s nor switch_delay_s is a step: it has a volume
    # but no rate, so the instantaneous peak leaves it out (the windowed ones count it)
    steps = (", strokes without stroke_time_s left out"
             if prof.has_steps else "")
    print(f"mean {prof.mean_l_min:.1f} NL/min, peak {prof.peak_l_min():.1f} NL/min "
          f"(instantaneous{steps}), {prof.peak_l_min(1.0):.1f} NL/min (1 s), "
          f"{prof.peak_l_min(60.0):.1f} NL/min (1 min)")
    print(f"wrote {', '.join(str(p) for p in written)}")
    return 0


def _fraction(text: str, option: str = "--allowance") -> float:
    """``10%`` or ``0.1``."""
    t = text.strip()
    try:
        return float(t[:-1]) / 100 if t.endswith("%") else float(t)
    except ValueError:
        raise ValueError(f"{option}: cannot read {text!r}: write e.g. 10% or 0.1") from None


def _bar(text: str, option: str = "--band") -> float:
    t = text.strip().lower()
    try:
        if t.endswith("kpa"):
            return float(t[:-3]) / 100
        return float(t[:-3]) if t.endswith("bar") else float(t)
    except ValueError:
        raise ValueError(f"{option}: cannot read {text!r}: write e.g. 1bar, 0.5 or "
                         "50kPa") from None


def cmd_size(args) -> int:
    from .air import predict
    from .air.sizing import size_prediction
    from .output import OutputError, check_out_dir, output_dir
    from .outputs.report import write_sizing_report
    from .sequencer import parse_horizon

    try:
        horizon_s, dt_s = _durations(args)
        allowance, band = _fraction(args.allowance), _bar(args.band)
        idle_after = parse_horizon(args.idle_after) / 1e9 if args.idle_after else 0.0
        out = check_out_dir(args.out)
    except (ValueError, OutputError) as e:
        return _fail(f"{e}")
    try:
        result = predict(args.machine, horizon_s, dt=dt_s, program=args.program,
                         max_events=args.max_events, shown=args.consumers)
        s = size_prediction(result, args.hours, allowance=allowance, band_bar=band,
                            sec_kwh_per_nm3=args.sec, price_per_kwh=args.price,
                            idle_after_s=idle_after, compressor=_compressor(args))
    except PlcpredError as e:
        print(e, file=sys.stderr)
        return _exit_code(e)
    except ValueError as e:
        return _fail(str(e))
    s.currency = args.currency
    name = result.machine.name
    for w in result.machine.warnings + s.warnings:
        print(f"warning: {w}", file=sys.stderr)
    with output_dir(out, _command_line(args)) as staging:
        files = [out / f.name for f in write_sizing_report(result, s, staging)]
    print(f"{name}: mean {s.mean_l_min:.1f} NL/min, peak {s.peak_l_min:.1f} (instant) / "
          f"{s.peak_1s_l_min:.1f} (1 s) / {s.peak_1min_l_min:.1f} (1 min) NL/min")
    print(f"compressor design flow {s.design_flow_l_min:.1f} NL/min "
          f"(mean + {100 * s.allowance:g} %); receiver {s.receiver_l:.1f} L for a "
          f"{s.band_bar:g} bar band (deficit {s.deficit_nl:.2f} NL at {s.deficit_at_s:g} s)")
    money = f" {s.currency}" if s.currency else ""
    print(f"energy {s.energy_kwh_per_year:,.0f} kWh/year, cost {s.cost_per_year:,.0f}{money}"
          f"/year; idle air {100 * s.idle_share:.1f} %")
    if result.machine.calendar is not None:
        print(f"year ([calendar]): {s.air_nm3_per_year:,.0f} Nm3, {s.hours_per_year:,.0f} h "
              f"producing at {s.mean_l_min:.1f} NL/min and {s.idle_hours_per_year:,.0f} h "
              f"standing at {s.idle_flow_l_min:.1f} NL/min (leaks"
              f"{', blowers left on' if result.machine.calendar.idle_state == 'program' else ''}"
              ")")
    if s.cycle_s is not None:
        print(f"cycle {s.cycle_s:.3g} s ({s.cycles_per_hour:.4g} per hour, by "
              f"{s.cycle_source}): {s.nl_per_cycle:.3f} NL per cycle")
    else:
        print("no steady cycle (no [machine] cycle_signal, no repeating state): the figures "
              f"are over the {s.horizon_s:g} s horizon")
    print(f"wrote {', '.join(str(f) for f in files if f.suffix != '.png')}")
    return 0


def cmd_compare(args) -> int:

    from .air.compare import compare, parse_allowance
    from .output import OutputError, check_out_file, write_json
    try:
        horizon_s, dt_s = _durations(args)
        parse_allowance(args.max_increase)
        drop_pct = _percentage(args.max_throughput_drop, "--max-throughput-drop")
        check_out_file(args.json, "--json")
    except (ValueError, OutputError) as e:
        print(f"plcpred: error: {e}", file=sys.stderr)
        return 2
    try:
        result = compare(args.base, args.new, horizon_s, args.max_increase, dt=dt_s,
                         program_base=args.program_base, program_new=args.program_new,
                         max_throughput_drop_pct=drop_pct)
    except PlcpredError as e:
        print(e, file=sys.stderr)
        return 2
    except (ValueError, OSError) as e:
        print(f"plcpred: error: {e}", file=sys.stderr)
        return 2
    if args.json == "-":
        print(json.dumps(result.to_dict(), indent=2))
    else:
        print(result.table())
        if args.json:
            write_json(args.json, result.to_dict())
    if not result.new_moves:
        return EXIT_NEVER_MOVES
    if not result.throughput_ok:
        return EXIT_THROUGHPUT_DROP
    return 0 if result.within_allowance else 1


def _currency(text: str) -> str:
    """A currency as reports show it: short printable text (EUR, USD, CHF, ...)."""
    t = text.strip()
    if t and (len(t) > 8 or not t.replace(" ", "").isalnum()):
        raise argparse.ArgumentTypeError(f"a currency is a short code such as EUR, not "
                                         f"{text!r}")
    return t


def _percentage(text: str, option: str) -> float:
    """``"5%"`` or ``"5"`` -> 5.0, from 0 to 100."""
    try:
        value = float(text.strip().rstrip("%"))
    except ValueError:
        raise ValueError(f"{option} takes a percentage such as 5%, not {text!r}") from None
    if not 0.0 <= value <= 100.0:
        raise ValueError(f"{option} takes a percentage from 0 to 100, not {text!r}")
    return value


def cmd_sweep(args) -> int:

    from .output import OutputError, atomic_write_text, check_out_dir, output_dir
    from .sweep import SweepError, measure_setting, parse_setting, sweep

    try:
        horizon_s, dt_s = _durations(args)
        out = check_out_dir(args.out) if args.out else None
        settings = [parse_setting(t) for t in args.set]
        settings += [measure_setting(t) for t in args.measure]
        if not settings:
            raise SweepError("give at least one --set or --measure")
        notes = []
        rows = sweep(args.machine, settings, horizon_s, dt_s, engine=args.engine,
                     scheduler=args.scheduler, workers=args.workers, program=args.program,
                     hours=args.hours, sec=args.sec, price=args.price,
                     compressor=_compressor(args), max_scenarios=args.max_scenarios,
                     notes=notes)
    except (SweepError, OutputError) as e:
        return _fail(str(e))
    except PlcpredError as e:
        print(e, file=sys.stderr)
        return _exit_code(e)
    except ValueError as e:
        return _fail(str(e))
    for note in notes:
        print(f"note: {note}", file=sys.stderr)
    keys = [st.key for st in settings]
    shown = keys + ["total_nl", "mean_l_min", "peak_l_min", "energy_kwh_per_year",
                    "cost_per_year"]
    heads = [f"cost_per_year_{args.currency}" if k == "cost_per_year" and args.currency
             else k for k in shown]
    table = [heads] + [[str(r[k]) if k in keys else f"{r[k]:.2f}" for k in shown]
                       for r in rows]
    widths = [max(len(row[c]) for row in table) for c in range(len(shown))]
    for k, row in enumerate(table):
        print("  ".join(cell.rjust(w) if k and c >= len(keys) else cell.ljust(w)
                        for c, (cell, w) in enumerate(zip(row, widths))).rstrip())
        if k == 0:
            print("  ".join("-" * w for w in widths))
    if out is not None:
        buf = io.StringIO()
        fields = list(dict.fromkeys(k for r in rows for k in r))
        w = csv.DictWriter(buf, fieldnames=fields, lineterminator="\n")
        w.writeheader()
        w.writerows(rows)
        with output_dir(out, _command_line(args)) as staging:
            atomic_write_text(staging / "sweep.csv", buf.getvalue())
        print(f"wrote {out / 'sweep.csv'}")
    return 0


HORIZON_HELP = "how long to run: 60s, 1m30s, 8h, T#1m30s (m = minutes)"
DT_HELP = ("grid step of the demand (default 10ms, coarser for long horizons so files stay "
           "under a few tens of MB)")


def _max_rows_arg(p, beyond: str) -> None:
    p.add_argument("--max-rows", type=_positive_int, default=DEFAULT_MAX_ROWS, metavar="N",
                   help=f"most rows of timeline.csv (default {DEFAULT_MAX_ROWS:,}, about "
                        f"{DEFAULT_MAX_ROWS * 30 / 1e9:.1f} GB); {beyond}")


def _machine_args(p, out: str | None = "output directory", dt: bool = True) -> None:
    """The arguments every machine-running command shares."""
    p.add_argument("machine", metavar="MACHINE", help="machine file (.toml)")
    p.add_argument("--horizon", required=True, help=HORIZON_HELP)
    if out:
        p.add_argument("--out", required=True, metavar="DIR", help=out)
    if dt:
        p.add_argument("--dt", help=DT_HELP)
    p.add_argument("--program", metavar="PROGRAM",
                   help="run this program instead of the one the machine file names")
    if out:
        p.add_argument("--max-events", type=_positive_int, default=DEFAULT_MAX_CHANGES,
                       metavar="N", help="most signal changes held in memory (default "
                       f"{DEFAULT_MAX_CHANGES:,}); a program that changes a signal every "
                       "scan over a long horizon stops with an error naming it")


DEFAULT_MAX_CHANGES = 20_000_000  # the sequencer's default (not imported: --help stays fast)
# timeline.csv rows written at most unless --max-rows says otherwise (about 30 bytes a
# row: 1.5 GB); a tiled year of a fast machine would otherwise fill the disk
DEFAULT_MAX_ROWS = 50_000_000
EXIT_NEVER_MOVES = 4   # compare: NEW never moves (a deadlock passes no air gate)
EXIT_THROUGHPUT_DROP = 5   # compare: NEW completes fewer cycles per hour than allowed


def _whole_number(text: str, least: int) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, not {text!r}") from None
    if n < least:
        raise argparse.ArgumentTypeError(f"must be at least {least}" if least else
                                         "must be 0 or more")
    return n


def _seed(text: str) -> int:
    return _whole_number(text, 0)


def _positive_int(text: str) -> int:
    return _whole_number(text, 1)


def _energy_args(p) -> None:
    """How a year's energy and cost are counted (size and sweep)."""
    p.add_argument("--hours", type=_nonneg_float, default=None,
                   help="production hours per year (default: the machine file's "
                        "[calendar], else 4000)")
    p.add_argument("--sec", type=_nonneg_float, default=None,
                   help="specific energy, kWh per normal m^3 (default: isothermal "
                        "compression to the supply pressure over 57.4 %% efficiency, "
                        "0.1 at 7 bar gauge)")
    p.add_argument("--compressor-power", type=_specific_power, default=None,
                   metavar="POWER",
                   help="the compressor's specific package input power at full load, from "
                        "its data sheet: 16.5kW/100cfm (CAGI) or 5.8kW/(m3/min) (ISO "
                        "1217); the specific energy then follows the supply pressure with "
                        "this compressor's efficiency (instead of 57.4 %%)")
    p.add_argument("--compressor-bar", type=_nonneg_float, default=7.0, metavar="BAR_G",
                   help="the full-load pressure the data sheet rates it at, bar gauge "
                        "(default 7; 100 psig is 6.9)")
    p.add_argument("--price", type=_nonneg_float, default=0.15,
                   help="energy price per kWh (default 0.15)")
    p.add_argument("--currency", default="", type=_currency,
                   help="what --price and the cost are in, shown with them (EUR, USD, ...)")


# a data sheet's units of specific power: per 100 cfm (CAGI) or per m^3/min (ISO 1217)
_POWER_UNITS = {"kw/100cfm": "100cfm", "kw/(m3/min)": "m3/min", "kw/m3/min": "m3/min",
                "kw/(m³/min)": "m3/min", "kw/m³/min": "m3/min"}


def _specific_power(text: str) -> float:
    """A data sheet's specific power as kW per m^3/min: '16.5kW/100cfm', '5.8kW/(m3/min)'."""
    from .air.sizing import CFM_M3_MIN

    m = re.fullmatch(r"\s*([0-9.]+(?:[eE][-+]?\d+)?)\s*(\S+)\s*", text)
    unit = _POWER_UNITS.get(m.group(2).lower()) if m else None
    if unit is None:
        raise argparse.ArgumentTypeError(
            f"expected a specific power such as 16.5kW/100cfm or 5.8kW/(m3/min), not {text!r}")
    value = float(m.group(1)) / (100.0 * CFM_M3_MIN if unit == "100cfm" else 1.0)
    if not 0 < value < float("inf"):
        raise argparse.ArgumentTypeError("a specific power must be > 0")
    return value


def _compressor(args):
    """The data sheet of --compressor-power/--compressor-bar (None without them)."""
    from .air.sizing import CompressorSheet

    if args.compressor_power is None:
        return None
    if args.sec is not None:
        raise ValueError("give --sec or --compressor-power, not both: --sec is the specific "
                         "energy itself")
    return CompressorSheet(args.compressor_power, args.compressor_bar)


def _nonneg_float(text: str) -> float:
    try:
        x = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, not {text!r}") from None
    if not x >= 0 or x == float("inf"):
        raise argparse.ArgumentTypeError("must be a finite number >= 0")
    return x


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="plcpred",
        description="Predict the compressed-air demand of a machine from its PLC program.")
    ap.add_argument("--version", action="version", version=f"plcpred {__version__}")
    ap.add_argument("--debug", action="store_true",
                    help="show the Python traceback of an internal error (any position)")
    ap.add_argument("--allow-root", action="append", default=[], metavar="DIR",
                    help="also read programs, libraries and project files from under DIR "
                         "(repeatable, any position). By default only files under the "
                         "machine file's folder (or the project's) are read")
    sub = ap.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    p = sub.add_parser("check", help="parse and validate PLC programs",
                       description="Parse and validate programs (.st, .seq, PLCopen .xml, "
                                   "TwinCAT .TcPOU/.TcGVL/.TcDUT/.TcIO/.TcTTO, or a whole "
                                   "TwinCAT project as a .plcproj or a folder). "
                                   "Files given together are checked as one project, so a "
                                   "global variable list can be checked with the POUs using "
                                   "it. Errors print as file:line:col: message; exit 1 if any.")
    p.add_argument("programs", nargs="+", metavar="PROGRAM")
    p.add_argument("--syntax-only", action="store_true",
                   help="skip semantic checks (for fragments using libraries not at hand)")
    p.add_argument("--allow-external", action="store_true",
                   help="names nothing at hand declares (types, FBs, functions, library "
                        "qualifiers) are warnings, not errors: for code that uses a library "
                        "you do not have. Such a project cannot run, so the compile check "
                        "is skipped")
    p.add_argument("--lib", action="append", default=[], metavar="PATH",
                   help="declarations of a library the programs use: an ST, TwinCAT or "
                        "PLCopen file, a .plcproj or a folder (repeatable; its name is "
                        "its namespace, as in Lib.FB_X). Stubs of common vendor libraries "
                        "are built in")
    p.add_argument("--dialect", choices=("auto", "iec", "bnr"), default="auto",
                   help="where vendors read ST differently: auto (default) tells a B&R "
                        "Automation Studio program by its files (.var/.typ/.fun, "
                        "PROGRAM _CYCLIC); bnr reads every file the B&R way (Act; calls an "
                        "action; a file of actions is read with its program folder); iec "
                        "never does")
    p.set_defaults(func=cmd_check)

    p = sub.add_parser("init", help="write a machine file to start from, from a program's I/O",
                       description="Write a commented machine file for a program: its "
                                   "name, program and task interval filled in, every input "
                                   "as an [[input]] and every BOOL output as a [[consumer]] "
                                   "to uncomment and complete. The file loads as it is "
                                   "(the program alone, nothing scheduled). Without --out "
                                   "it is printed.")
    p.add_argument("program", metavar="PROGRAM",
                   help="the program (.st, .seq, PLCopen .xml, TwinCAT file, .plcproj or "
                        "folder)")
    p.add_argument("--out", "-o", metavar="MACHINE.toml",
                   help="write the machine file here (the program is named relative to it)")
    p.add_argument("--force", action="store_true", help="overwrite --out if it exists")
    p.set_defaults(func=cmd_init)

    p = sub.add_parser("timeline", help="run a machine's program into output-bit timelines",
                       description="Run the machine's PLC program against its plant I/O "
                                   "model (cylinder end switches, input schedules) over a "
                                   "horizon and write DIR/timeline.csv: time_s,signal,value, "
                                   "one row per change, initial values at 0.")
    _machine_args(p, dt=False)
    p.add_argument("--scan-stepping", action="store_true",
                   help="execute every scan instead of jumping between events (the slow "
                        "reference the event-driven mode must equal)")
    p.add_argument("--no-replay", action="store_true",
                   help="execute every part of a run that cannot tile instead of copying "
                        "the recorded response of a part that starts from a state the "
                        "machine rested in before (the result is the same, only slower)")
    _max_rows_arg(p, "a longer timeline is an error, before anything is written")
    p.set_defaults(func=cmd_timeline)

    p = sub.add_parser("predict", help="forecast a machine's compressed-air demand",
                       description="Run the machine's program (as `timeline` does) and turn "
                                   "its timeline into air demand: D1 volumes per cylinder "
                                   "stroke, D2 flows of nozzles while on and of leaks always. "
                                   "Writes DIR/timeline.csv, demand.csv (NL/min per consumer "
                                   "on a time grid), summary.json and demand.png, and prints "
                                   "a table of per-consumer totals.")
    _machine_args(p)
    _consumers_arg(p)
    p.add_argument("--no-plot", action="store_true", help="skip demand.png")
    p.add_argument("--no-timeline", action="store_true",
                   help="skip timeline.csv (the demand is computed all the same)")
    _max_rows_arg(p, "a longer timeline is not written, with a warning")
    p.set_defaults(func=cmd_predict)

    p = sub.add_parser("size", help="size the compressor and receiver for a machine",
                       description="Predict the machine's demand over the horizon and size "
                                   "its supply: mean, peaks (instantaneous, 1 s, 1 min), 95th "
                                   "percentile, a compressor design flow (mean plus an "
                                   "allowance), the receiver that holds the pressure within a "
                                   "band, energy and cost per year, and the air used while "
                                   "idle. Writes DIR/sizing.json, sizing.md and sizing.html "
                                   "(self-contained, plots embedded).")
    _machine_args(p)
    _consumers_arg(p)
    p.add_argument("--allowance", default="10%",
                   help="design flow above the mean (default 10%%)")
    p.add_argument("--band", default="1bar",
                   help="pressure band the receiver must hold (default 1bar)")
    _energy_args(p)
    p.add_argument("--idle-after", metavar="DURATION",
                   help="count air as idle only once no cylinder has moved for this long "
                        "(default: whenever no cylinder moves)")
    p.set_defaults(func=cmd_size)

    p = sub.add_parser("compare", help="compare two machines or programs (CI gate)",
                       description="Predict BASE and NEW over the same horizon and print a "
                                   "per-consumer table of totals and deltas. Air is compared "
                                   "per cycle when both machines have one ([machine] "
                                   "cycle_signal, or a state that repeats), else over the "
                                   "horizon. Exit 0 when NEW "
                                   "is within the allowance, 1 when it uses more air, 2 on an "
                                   "error, 4 when NEW never moves (no valve output ever "
                                   "changes: a deadlock uses less air but passes no gate), 5 "
                                   "when NEW's cycles per hour drop by more than "
                                   "--max-throughput-drop (or it completes none). NEW "
                                   "defaults to BASE, for comparing two programs with "
                                   "--program-new.")
    p.add_argument("base", metavar="BASE", help="machine file (.toml)")
    p.add_argument("new", metavar="NEW", nargs="?", help="machine file (default: BASE)")
    p.add_argument("--horizon", required=True, help=HORIZON_HELP)
    p.add_argument("--max-increase", default="0%",
                   help="allowed increase: a percentage (2%%) or normal litres (0.5NL); "
                        "default 0%%; per cycle when the gate compares cycles")
    p.add_argument("--max-throughput-drop", default="5%", metavar="PCT",
                   help="allowed fall of NEW's cycles per hour against BASE's, a percentage; "
                        "default 5%%")
    p.add_argument("--program-base", metavar="PROGRAM", help="program to run on BASE")
    p.add_argument("--program-new", metavar="PROGRAM", help="program to run on NEW")
    p.add_argument("--dt", help=DT_HELP)
    p.add_argument("--json", metavar="OUT", nargs="?", const="-",
                   help="write the comparison as JSON to OUT (- or no value: to stdout, "
                        "instead of the table)")
    p.set_defaults(func=cmd_compare)

    p = sub.add_parser("sweep", help="what-if study over combinations of settings",
                       description="Predict the machine for every combination of the --set "
                                   "values and print totals, mean, peak and energy per "
                                   "scenario. KEY is a [machine] key (supply_bar_g, scan_ms, "
                                   "...), CONSUMER.FIELD (\"air knives.pressure_bar_g\", "
                                   "A.stroke_time_s with 0.2/0.3 for extend/retract), "
                                   "input.SIGNAL.FIELD, program.VAR for a variable's "
                                   "initial value as an ST literal (program.BLOW_TIME=T#2s), "
                                   "or measure.leaks / measure.pressure / measure.blowoff "
                                   "(saving measures, "
                                   "also as --measure). Energy and cost count a year as "
                                   "size does (--hours, the machine file's [calendar]). "
                                   "Scenarios run in parallel local processes, or on a Dask "
                                   "cluster with --engine dask --scheduler ADDRESS.")
    _machine_args(p, out=None)
    p.add_argument("--set", action="append", default=[], metavar="KEY=V1,V2,...",
                   help="values to sweep (repeat for a cartesian product)")
    p.add_argument("--measure", action="append", default=[], metavar="NAME=VALUE",
                   help="an energy-saving measure, swept as without and with it: "
                        "leaks=-30%% (repair that share of every leak), pressure=-0.5bar "
                        "(lower the supply), blowoff=cycle (nozzles blow only while a "
                        "cycle runs, not while the machine waits); the same as --set "
                        "measure.NAME=AS_IS,VALUE")
    p.add_argument("--engine", choices=("local", "dask"), default="local")
    p.add_argument("--scheduler", metavar="ADDRESS", help="Dask scheduler (tcp://host:8786)")
    p.add_argument("--workers", type=int, help="local processes (default: one per core)")
    p.add_argument("--max-scenarios", type=_positive_int, default=10_000, metavar="N",
                   help="most scenarios (the product of the --set value counts) a sweep "
                        "runs (default 10,000); more is an error before any work")
    p.add_argument("--out", metavar="DIR", help="also write DIR/sweep.csv")
    _energy_args(p)
    p.set_defaults(func=cmd_sweep)

    p = sub.add_parser("diagnose", help="diagnose the gap between prediction and a measured "
                                        "flow log",
                       description="Compare a machine's prediction with measured flow "
                                   "logs: baseline error, where in the cycle the gap lies "
                                   "(idle, a drive's strokes, a nozzle on, SFC steps), which "
                                   "unmodelled effect causes it (leak, passive_flow, "
                                   "supply_pressure, dead_volume, incomplete_exhaust, "
                                   "shared_supply, valve_delay, stroke_time, sensor_lag, "
                                   "meter_gain; none within the model's accuracy, or "
                                   "unexplained) and how far the gap shrinks with it on samples the "
                                   "fit never saw. Prints a report; exit 0 whatever the "
                                   "verdict, 2 on bad input.")
    p.add_argument("machine", metavar="MACHINE", help="machine file (.toml)")
    p.add_argument("--measured", action="append", required=True, metavar="RUN.csv",
                   help="a flow log: time_s,flow_l_min[,supply_bar_g] or any logger's CSV "
                        "(see --time-col/--flow-col); repeat for several runs")
    p.add_argument("--io", action="append", metavar="RUN.timeline.csv",
                   help="recorded I/O of each run (time_s,signal,value): valve edges from "
                        "the trace instead of the sequencer (one per --measured)")
    p.add_argument("--offset", action="append", type=_seconds, metavar="S",
                   help="the logger's clock reading at the machine's start, per run "
                        "(default: found by correlating the log with the prediction)")
    p.add_argument("--max-offset", type=_seconds, metavar="S",
                   help="search the clock offset within this many seconds of the log's "
                        "first sample (default: half the run, at most 120 s)")
    p.add_argument("--time-col", metavar="NAME|N", help="time column (default time_s, else "
                   "the one column named as a time: Time, Timestamp, Zeit, ...; a name "
                   "such as t_ms or 'Zeit [ms]' gives numbers in ms, '(min)' in minutes); "
                   "seconds, ISO 8601 date-times, a logger's date-times (24.11.2026 "
                   "13:05:00,5; 2026/11/24 13:05:00; 11/24/2026 1:05:00 PM) or times of "
                   "day (13:05:00.5). Lines above the header (device, serial) are "
                   "skipped")
    p.add_argument("--flow-col", metavar="NAME|N",
                   help="flow column (default flow_l_min, else the one column named as a "
                        "flow: Flow, Durchfluss, Volumenstrom, Debit, ...)")
    p.add_argument("--supply-col", metavar="NAME|N",
                   help="supply pressure column, bar(g) (default supply_bar_g when the log "
                        "has one): its mean is compared with the machine file's supply")
    p.add_argument("--flow-unit", choices=("l/min", "m3/h", "m3/min", "l/s", "scfm"),
                   help="unit of the flow column (default: the unit its header names, as "
                        "in 'Flow (m3/h)', else l/min)")
    p.add_argument("--reference", choices=("iso8778", "din1343", "iso2533"),
                   help="the meter's reference condition (default: the machine file's "
                        "[meter] reference, else iso8778)")
    p.add_argument("--sampling", choices=("mean", "instant"),
                   help="what a reading is: the mean flow over its logging interval (a "
                        "meter's own logger) or the flow at that moment (a PLC polling the "
                        "meter's analogue output). Default: the machine file's [meter] "
                        "sampling, else mean (a warning says when the logs fit "
                        "instantaneous readings far better)")
    p.add_argument("--effects", metavar="A,B",
                   help="try only these effects (default: all that apply)")
    p.add_argument("--json", metavar="OUT", help="write the diagnosis as JSON (- for stdout)")
    p.add_argument("--out", metavar="DIR",
                   help="write diagnose.json, diagnose.png and diagnose.html to DIR")
    p.add_argument("--write-machine", metavar="FIXED.toml",
                   help="write the machine file with the diagnosed effect(s) added")
    p.add_argument("--program", metavar="PROGRAM",
                   help="run this program instead of the one the machine file names")
    p.add_argument("--no-plant", action="store_true",
                   help="do not run the machine through the physics plant as a second "
                        "reference (faster; the effects are then fitted in D1's terms "
                        "only)")
    p.set_defaults(func=cmd_diagnose)

    p = sub.add_parser("emulate", help="run a machine in closed loop with the physics plant "
                                       "(a virtual flow meter log)",
                       description="Run the machine's program against the physics plant "
                                   "(chamber thermodynamics, ISO 6358 flows, valve delays, "
                                   "friction and load, supply lines, the flow meter) and "
                                   "write what a flow meter on it would log. --truth applies "
                                   "a partial machine file of the real machine's deviations "
                                   "(a hidden leak, a longer tube, a slow meter) that the "
                                   "prediction does not see. The physics plant integrates every "
                                   "stroke: horizons up to 24 h.")
    _machine_args(p, "output directory (measured.csv, timeline.csv, plant.csv, "
                     "emulate.png)", dt=False)
    p.add_argument("--truth", metavar="T.toml",
                   help="the real machine's deviations from MACHINE (a partial machine file)")
    p.add_argument("--seed", type=_seed, metavar="N", help="seed of the meter's noise (a "
                   "whole number >= 0)")
    p.add_argument("--no-plot", action="store_true", help="do not draw emulate.png")
    p.set_defaults(func=cmd_emulate)

    p = sub.add_parser("identify", help="ISO 6358 C, b, m (a) of a component from test data",
                       description="Identify the extended ISO 6358 parameters (C, b, m, a) "
                                   "of a valve, nozzle, circuit or leak from steady-flow "
                                   "points (p_up_bar_g, p_down_bar_g, flow_l_min) or a tank's "
                                   "pressure curve (time_s, p_bar_g with --volume-l). Prints "
                                   "them with 95 %% confidence intervals.")
    p.add_argument("what", choices=("flow",), help="what to identify (flow)")
    p.add_argument("data", metavar="DATA.csv", help="the test data (CSV)")
    p.add_argument("--method", choices=("improved", "iso6358"), default="improved",
                   help="steady flow: improved (C from choked points, b and m by least "
                        "squares; default) or iso6358 (ISO 6358:1989, m = 0.5)")
    p.add_argument("--fit-a", action="store_true",
                   help="also fit the cracking pressure ratio a (check valves)")
    p.add_argument("--volume-l", type=float, metavar="L",
                   help="tank data: the tank's volume in litres")
    p.add_argument("--mode", choices=("discharge", "charge"), default="discharge",
                   help="tank data: emptying to atmosphere (default) or filling")
    p.add_argument("--supply-bar-g", type=float, metavar="P",
                   help="tank charge: the supply pressure (gauge)")
    p.add_argument("--atmosphere-kpa", type=float, default=101.325)
    p.add_argument("--temperature-c", type=float, default=20.0,
                   help="air temperature when the data have no t_up_c column")
    p.add_argument("--plot", metavar="FIT.png", help="write the fit plot")
    p.add_argument("--json", metavar="OUT", help="write the result as JSON (- for stdout)")
    p.add_argument("--machine", metavar="MACHINE.toml",
                   help="with --write-machine: the machine file to put the result into")
    p.add_argument("--consumer", metavar="NAME",
                   help="with --write-machine: the nozzle or leak that gets C, b, m, a")
    p.add_argument("--write-machine", metavar="OUT.toml",
                   help="write MACHINE with the identified C, b, m, a in CONSUMER")
    p.set_defaults(func=cmd_identify)
    return ap


def cmd_init(args) -> int:

    from .init import machine_skeleton
    from .output import OutputError, atomic_write_text
    from .parser import ProgramError, load_program

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


def cmd_identify(args) -> int:

    from .identify import (
        FlowData,
        IdentifyError,
        identify_steady,
        identify_tank,
        plot_fit,
        read_flow_data,
    )
    from .machine import MachineError, load_machine, read_machine_data, save_machine
    from .output import atomic_write_text, dumps_json

    if args.write_machine and not (args.machine and args.consumer):
        return _fail("--write-machine needs --machine and --consumer")
    from .output import OutputError, check_out_file
    try:
        check_out_file(getattr(args, "json", None), "--json")
        check_out_file(args.write_machine, "--write-machine")
        check_out_file(args.plot, "--plot")
    except OutputError as e:
        return _fail(str(e))
    if not 50.0 <= args.atmosphere_kpa <= 120.0:
        return _fail("--atmosphere-kpa must lie between 50 and 120")
    atm = args.atmosphere_kpa * 1e3
    try:
        data = read_flow_data(args.data, args.atmosphere_kpa, args.temperature_c)
        if isinstance(data, FlowData):
            fit = identify_steady(data, args.method, args.fit_a)
        else:
            if not args.volume_l or args.volume_l <= 0:
                return _fail(f"{args.data}: tank data need --volume-l (the tank's volume)")
            supply = args.supply_bar_g * 1e5 + atm if args.supply_bar_g is not None else None
            fit = identify_tank(data, args.volume_l, args.mode, supply, atm,
                                args.temperature_c + 273.15)
        to_write = None
        if args.write_machine:
            nominal = load_machine(args.machine)
            target = next((c for c in nominal.consumers if c.name == args.consumer), None)
            if target is None or target.is_cylinder:
                return _fail(f"{args.machine}: no nozzle or leak named {args.consumer!r}")
            raw = read_machine_data(args.machine)
            for t in raw["consumer"]:
                if t.get("name") == args.consumer:
                    for k in ("orifice_mm", "Cd"):
                        t.pop(k, None)
                    t.update({"C": float(f"{fit.C:.4g}"), "b": round(fit.b, 4),
                              "m": round(fit.m, 4), "a": round(fit.a, 4)})
            to_write = (raw, nominal)
    except (IdentifyError, MachineError) as e:
        print(e, file=sys.stderr)
        return 2
    print(f"{args.data}: {fit.method}, {fit.n_points} points, residual RMS "
          f"{fit.rms:.3g} {fit.rms_unit}")
    print()
    print(f"{'parameter':<10} {'value':>12} {'95 % interval':>16}")
    for name, unit in (("C", "m^3/(s Pa)"), ("b", ""), ("m", ""), ("a", "")):
        value = getattr(fit, name)
        half = fit.ci.get(name)
        shown = f"{value:.4g}" if name == "C" else f"{value:.4f}"
        ci = (f"+/- {half:.2g}" if name == "C" else f"+/- {half:.4f}") if half is not None \
            else "(fixed)"
        print(f"{name:<10} {shown:>12} {ci:>16}  {unit}")
    if args.plot:
        plot_fit(data, fit, args.plot, args.volume_l, args.mode,
                 args.supply_bar_g * 1e5 + atm if args.supply_bar_g is not None else None,
                 atm, args.temperature_c + 273.15)
        print(f"wrote {args.plot}")
    if args.json:
        text = dumps_json(fit.as_dict())
        if args.json == "-":
            print(text)
        else:
            atomic_write_text(args.json, text + "\n")
    if to_write is not None:
        raw, nominal = to_write
        save_machine(raw, nominal, args.write_machine,
                     f"{nominal.name}: {args.consumer} identified by plcpred identify flow "
                     f"from {Path(args.data).name}")
        print(f"wrote {args.write_machine}")
    return 0


def cmd_emulate(args) -> int:
    from .air import predict
    from .machine import load_machine
    from .output import output_dir
    from .outputs.files import write_emulation
    from .plant import emulate

    horizon_s, _, out = _horizon_and_out(args)
    try:
        em = emulate(args.machine, horizon_s, truth=args.truth, seed=args.seed,
                     program=args.program)
        nominal = load_machine(args.machine)
        predicted = predict(nominal, horizon_s, program=args.program,
                            max_events=args.max_events).profile
    except PlcpredError as e:
        print(e, file=sys.stderr)
        return _exit_code(e)
    with output_dir(out, _command_line(args)) as staging:
        written = [out / f.name for f in write_emulation(em, staging, plot=not args.no_plot)]
    for w in em.machine.warnings:
        print(f"warning: {w}", file=sys.stderr)
    print(f"{em.machine.name}: emulated {horizon_s:g} s at {em.machine.supply_bar_g:g} bar(g)"
          + (f" with the deviations of {args.truth}" if args.truth else ""))
    print()
    pred = dict(zip(predicted.names, (float(v) for v in predicted.consumer_nl)))
    width = max([len("consumer")] + [len(c.name) for c in em.machine.consumers])
    print(f"{'consumer':<{width}}  {'emulated NL':>11}  {'predicted NL':>12}  {'diff':>7}")
    for name, nl in em.consumer_nl().items():
        p = pred.get(name)
        if p is None:
            print(f"{name:<{width}}  {nl:11.3f}  {'(hidden)':>12}  {'':>7}")
        else:
            diff = f"{100 * (nl - p) / p:+6.1f}%" if p > 0 else ""
            print(f"{name:<{width}}  {nl:11.3f}  {p:12.3f}  {diff:>7}")
    total_p = float(predicted.total_nl)
    print(f"{'total':<{width}}  {em.total_nl:11.3f}  {total_p:12.3f}  "
          f"{100 * (em.total_nl - total_p) / total_p if total_p else 0.0:+6.1f}%")
    print()
    m = em.meter
    print(f"meter: {m.reference}, tau {m.tau_s:g} s, {m.rate_hz:g} Hz: "
          f"{len(em.measured_time_s)} readings, {em.measured_nl():.3f} NL ({m.reference})")
    info = em.info
    print(f"plant: {info['integrated_pieces']} pieces integrated, {info['reused_pieces']} "
          f"reused; {info['wall_s']:.1f} s ({horizon_s / max(info['wall_s'], 1e-9):.1f}x "
          "real time)")
    print(f"wrote {', '.join(str(p) for p in written)}")
    return 0


def cmd_diagnose(args) -> int:
    from .diagnose import diagnose, read_io_timeline, read_measured
    from .diagnose.core import write_fixed_machine
    from .machine import load_machine
    from .output import (
        OutputError,
        atomic_write_text,
        check_out_dir,
        check_out_file,
        output_dir,
        write_json,
    )

    try:
        out = check_out_dir(args.out) if args.out else None
        check_out_file(args.json, "--json")
        check_out_file(args.write_machine, "--write-machine")
        if args.io and len(args.io) != len(args.measured):
            raise ValueError(f"give one --io per --measured run ({len(args.measured)}), "
                             f"not {len(args.io)}")
        if args.offset and len(args.offset) != len(args.measured):
            raise ValueError(f"give one --offset per --measured run ({len(args.measured)}),"
                             f" not {len(args.offset)}")
        effects = [e.strip() for e in args.effects.split(",")] if args.effects else None
    except (ValueError, OutputError) as e:
        return _fail(str(e))
    machine = load_machine(args.machine)
    reference = args.reference or (machine.meter.reference if machine.meter else "iso8778")
    runs = [read_measured(p, time_col=args.time_col, flow_col=args.flow_col,
                          flow_unit=args.flow_unit, reference=reference,
                          supply_col=args.supply_col)
            for p in args.measured]
    if args.sampling:
        for r in runs:
            r.sampling = args.sampling
    for r in runs:
        if "columns_guessed" in r.source:
            print(f"note: {r.name}: {r.source['columns_guessed']} (name them with "
                  "--time-col, --flow-col and --flow-unit if not)", file=sys.stderr)
    io = [read_io_timeline(p, horizon_s=r.span_s, machine=machine)
          for p, r in zip(args.io, runs)] if args.io else None
    d = diagnose(machine, runs, io=io, offsets=args.offset, max_offset_s=args.max_offset,
                 effects=effects, program=args.program, dynamic=not args.no_plant)
    for w in d.warnings:
        print(f"warning: {w}", file=sys.stderr)
    # the report first: a file that cannot be written must not lose it
    print(d.report(), file=sys.stderr if args.json == "-" else sys.stdout)
    if args.write_machine:
        write_fixed_machine(d, args.write_machine)
    summary = d.summary()
    if args.json == "-":
        print(json.dumps(summary, indent=2, allow_nan=False))
    elif args.json:
        write_json(args.json, summary)
    if out is not None:
        from .outputs.report import diagnosis_html, plot_diagnosis

        with output_dir(out, _command_line(args)) as staging:
            write_json(staging / "diagnose.json", summary)
            plot_diagnosis(d, staging / "diagnose.png")
            atomic_write_text(staging / "diagnose.html",
                              diagnosis_html(d, (staging / "diagnose.png").read_bytes()))
        print(f"wrote {out / 'diagnose.json'}, {out / 'diagnose.png'}, "
              f"{out / 'diagnose.html'}")
    if args.write_machine:
        print(f"wrote {args.write_machine}")
    return 0


def _seconds(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected seconds, not {text!r}") from None
    if v != v or abs(v) > 1e12:
        raise argparse.ArgumentTypeError(f"expected a finite number of seconds, not {text!r}")
    return v


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


def main(argv=None) -> int:
    """Run one command. Exit codes: 0 ok, 1 a finding (invalid program, gate failed), 2 a
    usage or input error, 3 an internal error (a bug: one line; ``--debug`` shows the
    traceback), 130/143 interrupted by SIGINT/SIGTERM."""

    argv = list(sys.argv[1:] if argv is None else argv)
    debug = "--debug" in argv
    argv = [a for a in argv if a != "--debug"]
    argv, roots = _allowed_roots(argv)
    args = build_parser().parse_args(argv)
    args.argv = argv
    args.allow_root = list(args.allow_root) + roots
    from .memory import use_large_malloc_thresholds
    use_large_malloc_thresholds()      # a third of a prediction's time otherwise (memory.py)
    try:
        previous = signal.signal(signal.SIGTERM, _on_sigterm)
    except ValueError:  # not the main thread (a library caller): leave signals alone
        previous = None
    try:
        from .parser.files import extra_roots
        with extra_roots(args.allow_root):
            code = args.func(args)
        sys.stdout.flush()
        return code
    except BrokenPipeError:
        # the reader went away (plcpred ... | head): not an error of ours; stop quietly
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0
    except Terminated:
        print("plcpred: terminated; temporary files removed, nothing half-written left",
              file=sys.stderr)
        return 143
    except KeyboardInterrupt:
        print("plcpred: interrupted; temporary files removed, nothing half-written left",
              file=sys.stderr)
        return 130
    except Exception as e:
        if isinstance(e, PlcpredError):
            print(f"plcpred: error: {e}", file=sys.stderr)
            return 2
        if isinstance(e, MemoryError):
            print("plcpred: error: out of memory (a shorter --horizon or a coarser --dt "
                  "needs less)", file=sys.stderr)
            return 2
        if debug:
            raise
        message = str(e).splitlines()[0][:300] if str(e) else ""
        print(f"plcpred: internal error: {type(e).__name__}"
              f"{': ' + message if message else ''} (please report it; run again with "
              "--debug for the traceback)", file=sys.stderr)
        return 3
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":
    sys.exit(main())
