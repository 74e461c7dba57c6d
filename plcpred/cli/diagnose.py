"""``plcpred diagnose``: flow-meter logs against the prediction."""
from __future__ import annotations

import json
import sys

from ..diagnose import diagnose, read_io_timeline, read_measured
from ..diagnose.corrected import write_fixed_machine
from ..machine import load_machine
from ..output import (
    OutputError,
    atomic_write_text,
    check_out_dir,
    check_out_file,
    output_dir,
    write_json,
)
from ..outputs.diagnosis_report import diagnosis_html, plot_diagnosis
from ..progress import Progress
from .common import command_line, fail


def cmd_diagnose(args) -> int:
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
        return fail(str(e))
    machine = load_machine(args.machine)
    reference = args.reference or (machine.meter.reference if machine.meter else "iso8778")
    runs = [read_measured(p, time_col=args.time_col, flow_col=args.flow_col,
                          flow_unit=args.flow_unit, reference=reference,
                          supply_col=args.supply_col, supply_unit=args.supply_unit,
                          date_col=args.date_col)
            for p in args.measured]
    if args.sampling:
        for r in runs:
            r.sampling = args.sampling
    for r in runs:
        if "columns_guessed" in r.source:
            print(f"note: {r.name}: {r.source['columns_guessed']} (name them with "
                  "--time-col, --flow-col and --flow-unit if not)", file=sys.stderr)
        for w in r.source.get("warnings", ()):
            print(f"warning: {r.name}: {w}", file=sys.stderr)
    io = [read_io_timeline(p, horizon_s=r.span_s, machine=machine)
          for p, r in zip(args.io, runs)] if args.io else None
    with Progress.on_terminal(args.quiet) as progress:
        d = diagnose(machine, runs, io=io, offsets=args.offset, max_offset_s=args.max_offset,
                     effects=effects, program=args.program, dynamic=not args.no_plant,
                     progress=progress)
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

        with output_dir(out, command_line(args)) as staging:
            write_json(staging / "diagnose.json", summary)
            plot_diagnosis(d, staging / "diagnose.png")
            atomic_write_text(staging / "diagnose.html",
                              diagnosis_html(d, (staging / "diagnose.png").read_bytes()))
        print(f"wrote {out / 'diagnose.json'}, {out / 'diagnose.png'}, "
              f"{out / 'diagnose.html'}")
    if args.write_machine:
        print(f"wrote {args.write_machine}: {d.file_check.text()}")
        for left in d.file_check.left_out:
            print(f"  not written: {left}")
    return 0
