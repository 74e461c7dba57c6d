"""``plcpred identify flow``: ISO 6358 parameters of a component from test data."""
from __future__ import annotations

import difflib
import sys
from pathlib import Path

from ..errors import EXIT_BAD_INPUT
from ..identify import (
    DataColumns,
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
    try:
        # the machine file and its consumer checked before the fit, not after it
        target = _target(args) if args.write_machine else None
        data, fit = _fit(args)
    except (IdentifyError, MachineError) as e:
        print(e, file=sys.stderr)
        return EXIT_BAD_INPUT
    # --json -: stdout holds the JSON alone, the table goes to stderr
    text_out = sys.stderr if args.json == "-" else sys.stdout
    _print_fit(args, fit, text_out)
    atm = args.atmosphere_kpa * 1e3
    if args.plot:
        plot_fit(data, fit, args.plot, args.volume_l, args.mode,
                 args.supply_bar_g * PA_PER_BAR + atm if args.supply_bar_g is not None else None,
                 atm, args.temperature_c + ZERO_C_K)
        print(f"wrote {args.plot}", file=text_out)
    if args.json:
        text = dumps_json(fit.as_dict())
        if args.json == "-":
            print(text, end="")
        else:
            atomic_write_text(args.json, text)
    if target is not None:
        _write_machine(args, fit, *target)
    return 0


def _target(args):
    """(the machine file's data, the machine) for --write-machine, its --consumer checked
    to be a nozzle or leak of it."""
    nominal = load_machine(args.machine)
    consumer = next((c for c in nominal.consumers if c.name == args.consumer), None)
    if consumer is None or consumer.is_cylinder:
        passive = [c.name for c in nominal.consumers if not c.is_cylinder]
        near = difflib.get_close_matches(args.consumer, passive, n=1, cutoff=0.6)
        raise MachineError(args.machine, "", f"no nozzle or leak named {args.consumer!r}"
                           + (f"; did you mean {near[0]!r}?" if near else
                              f" (its nozzles and leaks: {', '.join(passive) or 'none'})"))
    return read_machine_data(args.machine), nominal


def _fit(args):
    """(the test data, the fit) of ``args.data``."""
    atm = args.atmosphere_kpa * 1e3
    columns = DataColumns(args.time_col, args.flow_col, args.flow_unit, args.p_up_col,
                          args.p_down_col, args.pressure_col, args.pressure_unit)
    data = read_flow_data(args.data, args.atmosphere_kpa, args.temperature_c, columns)
    if isinstance(data, FlowData):
        return data, identify_steady(data, args.method, args.fit_a)
    if not args.volume_l or args.volume_l <= 0:
        raise IdentifyError(f"{args.data}: tank data need --volume-l (the tank's volume)")
    supply = args.supply_bar_g * PA_PER_BAR + atm if args.supply_bar_g is not None else None
    return data, identify_tank(data, args.volume_l, args.mode, supply, atm,
                               args.temperature_c + ZERO_C_K)


def _print_fit(args, fit, out=None) -> None:
    out = out or sys.stdout
    print(f"{args.data}: {fit.method}, {fit.n_points} points, residual RMS "
          f"{fit.rms:.3g} {fit.rms_unit}", file=out)
    print(file=out)
    print(f"{'parameter':<10} {'value':>12} {'95 % interval':>16}", file=out)
    for name, unit in (("C", "m^3/(s Pa)"), ("b", ""), ("m", ""), ("a", "")):
        value = getattr(fit, name)
        half = fit.ci.get(name)
        shown = f"{value:.4g}" if name == "C" else f"{value:.4f}"
        ci = (f"+/- {half:.2g}" if name == "C" else f"+/- {half:.4f}") if half is not None \
            else "(fixed)"
        print(f"{name:<10} {shown:>12} {ci:>16}  {unit}", file=out)


def _write_machine(args, fit, raw: dict, nominal) -> None:
    """The machine file with the fit in --consumer: its restriction replaced by C, b, m
    (and a, when fitted or given before), every other line as it was."""
    for t in raw["consumer"]:
        if t.get("name") == args.consumer:
            for k in ("orifice_mm", "Cd"):
                t.pop(k, None)
            t.update({"C": float(f"{fit.C:.4g}"), "b": round(fit.b, 4),
                      "m": round(fit.m, 4)})
            if "a" in fit.ci or "a" in t:
                t["a"] = round(fit.a, 4)
    save_machine(raw, nominal, args.write_machine,
                 f"{nominal.name}: {args.consumer} identified by plcpred identify flow "
                 f"from {Path(args.data).name}", by="plcpred identify flow")
    print(f"wrote {args.write_machine}", file=sys.stderr if args.json == "-" else sys.stdout)
