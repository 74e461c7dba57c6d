"""``plcpred emulate``: the machine in closed loop with the physics plant."""
from __future__ import annotations

import sys

from ..air import predict
from ..errors import PlcpredError
from ..machine import load_machine
from ..output import output_dir
from ..outputs.files import write_emulation
from ..plant import emulate
from ..progress import Progress
from .common import command_line, exit_code, horizon_and_out


def cmd_emulate(args) -> int:
    horizon_s, _, out = horizon_and_out(args)
    with Progress.on_terminal(args.quiet) as progress:
        try:
            with progress.bar(horizon_s, "s", "physics plant, simulated") as bar:
                em = emulate(args.machine, horizon_s, truth=args.truth, seed=args.seed,
                             program=args.program, on_time=lambda t_ns: bar.update_to(
                                 round(t_ns / 1e9, 1)))
            progress.stage("predicting the same run for comparison")
            nominal = load_machine(args.machine)
            predicted = predict(nominal, horizon_s, program=args.program,
                                max_events=args.max_events).profile
        except PlcpredError as e:
            progress.close()
            print(e, file=sys.stderr)
            return exit_code(e)
        with output_dir(out, command_line(args)) as staging:
            written = [out / f.name for f in write_emulation(em, staging,
                                                             plot=not args.no_plot,
                                                             progress=progress,
                                                             predicted=predicted)]
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
