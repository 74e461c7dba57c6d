"""``plcpred identify flow``: ISO 6358 parameters of a component from test data."""
from __future__ import annotations

import sys
from pathlib import Path

from ..identify import (
    FlowData,
    IdentifyError,
    identify_steady,
    identify_tank,
    plot_fit,
    read_flow_data,
)
from ..machine import MachineError, load_machine, read_machine_data, save_machine
from ..output import OutputError, atomic_write_text, check_out_file, dumps_json
from ..physics.units import PA_PER_BAR, ZERO_C_K
from .common import fail


def cmd_identify(args) -> int:


    if args.write_machine and not (args.machine and args.consumer):
        return fail("--write-machine needs --machine and --consumer")
    try:
        check_out_file(getattr(args, "json", None), "--json")
        check_out_file(args.write_machine, "--write-machine")
        check_out_file(args.plot, "--plot")
    except OutputError as e:
        return fail(str(e))
    if not 50.0 <= args.atmosphere_kpa <= 120.0:
        return fail("--atmosphere-kpa must lie between 50 and 120")
    atm = args.atmosphere_kpa * 1e3
    try:
        data = read_flow_data(args.data, args.atmosphere_kpa, args.temperature_c)
        if isinstance(data, FlowData):
            fit = identify_steady(data, args.method, args.fit_a)
        else:
            if not args.volume_l or args.volume_l <= 0:
                return fail(f"{args.data}: tank data need --volume-l (the tank's volume)")
            supply = args.supply_bar_g * PA_PER_BAR + atm if args.supply_bar_g is not None else None
            fit = identify_tank(data, args.volume_l, args.mode, supply, atm,
                                args.temperature_c + ZERO_C_K)
        to_write = None
        if args.write_machine:
            nominal = load_machine(args.machine)
            target = next((c for c in nominal.consumers if c.name == args.consumer), None)
            if target is None or target.is_cylinder:
                return fail(f"{args.machine}: no nozzle or leak named {args.consumer!r}")
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
                 args.supply_bar_g * PA_PER_BAR + atm if args.supply_bar_g is not None else None,
                 atm, args.temperature_c + ZERO_C_K)
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
