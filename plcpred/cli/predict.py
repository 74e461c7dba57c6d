"""``plcpred timeline``, ``predict``, ``size``, ``compare`` and ``sweep``: the machine file's
program run into timelines and air demand."""
from __future__ import annotations

import csv
import io
import json
import sys

from ..air import predict
from ..air.compare import compare, parse_allowance
from ..air.sizing import size_prediction
from ..errors import PlcpredError
from ..machine import load_machine
from ..output import (
    OutputError,
    atomic_write_text,
    check_out_dir,
    check_out_file,
    output_dir,
    write_json,
)
from ..outputs.files import write_prediction
from ..outputs.report import consumer_table, write_sizing_report
from ..sequencer import parse_horizon, unfold
from ..sweep import SweepError, measure_setting, parse_setting, sweep
from .args import EXIT_NEVER_MOVES, EXIT_THROUGHPUT_DROP, bar, fraction, percentage
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
    try:
        machine = load_machine(args.machine)
        tl = unfold(machine, horizon_s, scan_stepping=args.scan_stepping,
                    replay=not args.no_replay,
                    program=args.program, max_events=args.max_events)
    except PlcpredError as e:
        print(e, file=sys.stderr)
        return exit_code(e)
    for w in machine.warnings:
        print(f"warning: {w}", file=sys.stderr)
    if tl.n_changes > args.max_rows:
        return fail(too_many_rows(tl.n_changes, args.max_rows) + "; shorten --horizon "
                     "or raise --max-rows")
    with output_dir(out, command_line(args)) as staging:
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


def cmd_predict(args) -> int:

    horizon_s, dt_s, out = horizon_and_out(args)
    try:
        machine = load_machine(args.machine)
        result = predict(machine, horizon_s, dt=dt_s, program=args.program,
                         max_events=args.max_events, shown=args.consumers)
    except PlcpredError as e:
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
            result, staging, plot=not args.no_plot, timeline=keep_timeline)]
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
    try:
        result = predict(args.machine, horizon_s, dt=dt_s, program=args.program,
                         max_events=args.max_events, shown=args.consumers)
        s = size_prediction(result, args.hours, allowance=allowance, band_bar=band,
                            sec_kwh_per_nm3=args.sec, price_per_kwh=args.price,
                            idle_after_s=idle_after, compressor=compressor(args))
    except PlcpredError as e:
        print(e, file=sys.stderr)
        return exit_code(e)
    except ValueError as e:
        return fail(str(e))
    s.currency = args.currency
    name = result.machine.name
    for w in result.machine.warnings + s.warnings:
        print(f"warning: {w}", file=sys.stderr)
    with output_dir(out, command_line(args)) as staging:
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

    try:
        horizon_s, dt_s = durations(args)
        parse_allowance(args.max_increase)
        drop_pct = percentage(args.max_throughput_drop, "--max-throughput-drop")
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


def cmd_sweep(args) -> int:


    try:
        horizon_s, dt_s = durations(args)
        out = check_out_dir(args.out) if args.out else None
        settings = [parse_setting(t) for t in args.set]
        settings += [measure_setting(t) for t in args.measure]
        if not settings:
            raise SweepError("give at least one --set or --measure")
        notes = []
        rows = sweep(args.machine, settings, horizon_s, dt_s, engine=args.engine,
                     scheduler=args.scheduler, workers=args.workers, program=args.program,
                     hours=args.hours, sec=args.sec, price=args.price,
                     compressor=compressor(args), max_scenarios=args.max_scenarios,
                     notes=notes)
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
        with output_dir(out, command_line(args)) as staging:
            atomic_write_text(staging / "sweep.csv", buf.getvalue())
        print(f"wrote {out / 'sweep.csv'}")
    return 0
