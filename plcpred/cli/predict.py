"""``plcpred timeline``, ``predict``, ``size``, ``compare`` and ``sweep``: the machine file's
program run into timelines and air demand."""
from __future__ import annotations

import csv
import io
import sys
import time

from ..air import predict
from ..air.compare import compare, parse_allowance
from ..air.sizing import size_prediction
from ..errors import EXIT_NEVER_MOVES, EXIT_THROUGHPUT_DROP, PlcpredError
from ..machine import load_machine
from ..output import (
    OutputError,
    atomic_write_text,
    check_out_dir,
    check_out_file,
    dumps_json,
    output_dir,
    write_json,
)
from ..outputs.demand_plot import consumer_table
from ..outputs.files import write_prediction
from ..outputs.sizing_report import write_sizing_report
from ..progress import Progress
from ..sequencer import parse_horizon, unfold
from ..sweep import SweepError, measure_setting, parse_setting, sweep
from .args import bar, fraction, percentage
from .common import (
    command_line,
    compressor,
    cut_stroke_warnings,
    durations,
    exit_code,
    fail,
    horizon_and_out,
    too_many_rows,
)


def cmd_timeline(args) -> int:
    horizon_s, _, out = horizon_and_out(args)
    with Progress.on_terminal(args.quiet) as progress:
        try:
            progress.stage(f"reading {args.machine}")
            machine = load_machine(args.machine)
            progress.stage(f"running the program over {args.horizon}")
            tl = unfold(machine, horizon_s, scan_stepping=args.scan_stepping,
                        replay=not args.no_replay,
                        program=args.program, max_events=args.max_events)
        except PlcpredError as e:
            progress.close()
            print(e, file=sys.stderr)
            return exit_code(e)
        if tl.n_changes <= args.max_rows:
            progress.stage(f"writing timeline.csv ({tl.n_changes:,} rows)")
            with output_dir(out, command_line(args)) as staging:
                tl.to_csv(staging / "timeline.csv")
    for w in machine.warnings:
        print(f"warning: {w}", file=sys.stderr)
    if tl.n_changes > args.max_rows:
        return fail(too_many_rows(tl.n_changes, args.max_rows) + "; shorten --horizon "
                     "or raise --max-rows")
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


def staged_prediction(args, horizon_s: float, dt_s, progress: Progress):
    """:func:`~plcpred.air.predict` of ``args.machine`` in the stages a terminal shows:
    the machine file read, its program run, the timeline turned into demand."""
    progress.stage(f"reading {args.machine}")
    machine = load_machine(args.machine)
    progress.stage(f"running the program over {args.horizon}")
    t0 = time.perf_counter()
    timeline = unfold(machine, horizon_s, program=args.program, max_events=args.max_events)
    sequence_s = time.perf_counter() - t0
    progress.stage("turning the timeline into air demand")
    result = predict(machine, horizon_s, dt=dt_s, timeline=timeline, shown=args.consumers)
    result.stage_s["sequence"] = sequence_s
    return result


def cmd_predict(args) -> int:
    horizon_s, dt_s, out = horizon_and_out(args)
    with Progress.on_terminal(args.quiet) as progress:
        try:
            result = staged_prediction(args, horizon_s, dt_s, progress)
        except PlcpredError as e:
            progress.close()
            print(e, file=sys.stderr)
            return exit_code(e)
        skipped = []
        keep_timeline = not args.no_timeline
        if keep_timeline and result.timeline.n_changes > args.max_rows:
            keep_timeline = False
            skipped.append(too_many_rows(result.timeline.n_changes, args.max_rows)
                           + ": not written (demand.csv and summary.json cover the whole "
                             "horizon; raise --max-rows to write it)")
        with output_dir(out, command_line(args)) as staging:
            written = [out / f.name for f in write_prediction(
                result, staging, plot=not args.no_plot, timeline=keep_timeline,
                progress=progress)]
    machine = result.machine
    for w in machine.warnings + cut_stroke_warnings(machine, result.profile) + skipped:
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


def cmd_size(args) -> int:
    try:
        horizon_s, dt_s = durations(args)
        allowance, band = fraction(args.allowance), bar(args.band)
        idle_after = parse_horizon(args.idle_after) / 1e9 if args.idle_after else 0.0
        out = check_out_dir(args.out)
    except (ValueError, OutputError) as e:
        return fail(f"{e}")
    with Progress.on_terminal(args.quiet) as progress:
        try:
            result = staged_prediction(args, horizon_s, dt_s, progress)
            progress.stage("sizing the supply")
            s = size_prediction(result, args.hours, allowance=allowance, band_bar=band,
                                sec_kwh_per_nm3=args.sec, price_per_kwh=args.price,
                                idle_after_s=idle_after, compressor=compressor(args))
        except PlcpredError as e:
            progress.close()
            print(e, file=sys.stderr)
            return exit_code(e)
        except ValueError as e:
            progress.close()
            return fail(str(e))
        s.currency = args.currency
        progress.stage("writing the report")
        with output_dir(out, command_line(args)) as staging:
            files = [out / f.name for f in write_sizing_report(result, s, staging)]
    name = result.machine.name
    for w in result.machine.warnings + s.warnings:
        print(f"warning: {w}", file=sys.stderr)
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
    try:
        horizon_s, dt_s = durations(args)
        parse_allowance(args.max_increase)
        drop_pct = percentage(args.max_throughput_drop, "--max-throughput-drop")
        check_out_file(args.json, "--json")
    except (ValueError, OutputError) as e:
        print(f"plcpred: error: {e}", file=sys.stderr)
        return 2
    with Progress.on_terminal(args.quiet) as progress:
        progress.stage(f"predicting BASE and NEW over {args.horizon}")
        try:
            result = compare(args.base, args.new, horizon_s, args.max_increase, dt=dt_s,
                             program_base=args.program_base, program_new=args.program_new,
                             max_throughput_drop_pct=drop_pct)
        except PlcpredError as e:
            progress.close()
            print(e, file=sys.stderr)
            return 2
        except (ValueError, OSError) as e:
            progress.close()
            print(f"plcpred: error: {e}", file=sys.stderr)
            return 2
    for w in dict.fromkeys(result.base.machine.warnings + result.new.machine.warnings):
        print(f"warning: {w}", file=sys.stderr)
    # --json -: stdout holds the JSON alone, the table goes to stderr
    print(result.table(), file=sys.stderr if args.json == "-" else sys.stdout)
    if args.json == "-":
        print(dumps_json(result.to_dict()), end="")
    elif args.json:
        write_json(args.json, result.to_dict())
    if not result.new_moves:
        return EXIT_NEVER_MOVES
    if not result.throughput_ok:
        return EXIT_THROUGHPUT_DROP
    return 0 if result.within_allowance else 1


def cmd_sweep(args) -> int:


    try:
        horizon_s, dt_s = durations(args)
        out = check_out_dir(args.out) if args.out else None
        settings = [parse_setting(t) for t in args.set]
        settings += [measure_setting(t) for t in args.measure]
        if not settings:
            raise SweepError("give at least one --set or --measure")
        notes = []
        with Progress.on_terminal(args.quiet) as progress:
            rows = sweep(args.machine, settings, horizon_s, dt_s, engine=args.engine,
                         scheduler=args.scheduler, workers=args.workers,
                         program=args.program, hours=args.hours, sec=args.sec,
                         price=args.price, compressor=compressor(args),
                         max_scenarios=args.max_scenarios, notes=notes, progress=progress)
    except (SweepError, OutputError) as e:
        return fail(str(e))
    except PlcpredError as e:
        print(e, file=sys.stderr)
        return exit_code(e)
    except ValueError as e:
        return fail(str(e))
    for note in notes:
        print(f"note: {note}", file=sys.stderr)
    keys = [st.key for st in settings]
    for w in scenario_warnings(rows, keys):
        print(f"warning: {w}", file=sys.stderr)
    print(sweep_table(rows, keys, args.currency))
    if out is not None:
        buf = io.StringIO()
        fields = list(dict.fromkeys(k for r in rows for k in r if k != "warnings"))
        w = csv.DictWriter(buf, fieldnames=fields, lineterminator="\n",
                           extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)
        with output_dir(out, command_line(args)) as staging:
            atomic_write_text(staging / "sweep.csv", buf.getvalue())
        print(f"wrote {out / 'sweep.csv'}")
    return 0


# the columns sweep prints after the swept keys: what each scenario costs in air, per
# hour and per cycle (a scenario that picks a part twice doubles its NL per cycle at the
# same cycles per hour), and per year
SWEEP_COLUMNS = ("total_nl", "mean_l_min", "peak_l_min", "cycles_per_hour", "nl_per_cycle",
                 "energy_kwh_per_year", "cost_per_year")


def sweep_table(rows: list[dict], keys: list[str], currency: str = "") -> str:
    """The printed table of a sweep: one line per scenario; '-' where a scenario has no
    steady cycle."""
    shown = list(keys) + list(SWEEP_COLUMNS)
    heads = [f"cost_per_year_{currency}" if k == "cost_per_year" and currency else k
             for k in shown]
    table = [heads] + [[str(r[k]) if k in keys else
                        "-" if r.get(k) is None else f"{r[k]:.2f}" for k in shown]
                       for r in rows]
    widths = [max(len(row[c]) for row in table) for c in range(len(shown))]
    lines = []
    for k, row in enumerate(table):
        lines.append("  ".join(cell.rjust(w) if k and c >= len(keys) else cell.ljust(w)
                               for c, (cell, w) in enumerate(zip(row, widths))).rstrip())
        if k == 0:
            lines.append("  ".join("-" * w for w in widths))
    return "\n".join(lines)


def scenario_warnings(rows: list[dict], keys: list[str]) -> list[str]:
    """What ``size`` would warn of, per scenario: once for every scenario that has it,
    naming them by their row in the table (or by their settings, when one has it)."""
    texts: dict[str, list[int]] = {}
    for k, r in enumerate(rows, 1):
        for w in r.get("warnings", ()):
            texts.setdefault(w, []).append(k)
    out = []
    for w, where in texts.items():
        if len(where) == len(rows) and len(rows) > 1:
            out.append(f"every scenario: {w}")
        elif len(where) == 1:
            shown = ", ".join(f"{key}={rows[where[0] - 1][key]}" for key in keys)
            out.append(f"scenario {where[0]} ({shown}): {w}")
        else:
            out.append(f"scenarios {', '.join(map(str, where))} (rows of the table): {w}")
    return out
