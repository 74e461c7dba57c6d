"""A machine's program run over a horizon (:func:`unfold`), and the warnings a run
gives about its machine (nothing moved, both solenoids of a bistable valve on)."""
import numpy as np

from ..machine import Machine, check_against_program, load_machine
from .executor import Sequencer
from .timeline import DEFAULT_MAX_CHANGES, Timeline, parse_horizon

__all__ = ["lint_timeline", "unfold", "valves_moved"]

def unfold(machine, horizon="60s", scan_stepping: bool = False, tiling: bool = True,
           program=None, max_events: int = DEFAULT_MAX_CHANGES,
           replay: bool = True, compiled=None, islands: bool = True) -> Timeline:
    """Run ``machine``'s program (or ``program``, an IR or a path, instead) over
    ``horizon`` (``"90s"``, ``"T#1m30s"``, ``"8h"`` or seconds) and return its timeline.
    ``tiling``, ``replay`` (repeating states and parts copied instead of executed) and
    ``islands`` (independent parts of the program run on their own, :meth:`Sequencer.run`)
    can be turned off to check them against full execution.
    ``compiled``: :func:`compile_program` of the IR ``program``, for callers that run
    one program many times (the diagnosis' timing variants).

    Raises :class:`~plcpred.parser.ProgramError` (program text), :class:`CompileError`
    (constructs the executor cannot run), :class:`ExecutionError` (run-time faults such as
    a watchdog) or :class:`~plcpred.machine.MachineError` (machine file)."""

    if not isinstance(machine, Machine):
        machine = load_machine(machine)
    horizon_ns = parse_horizon(horizon)
    if program is None or not hasattr(program, "pous"):
        program = machine.read_program(program)
    check_against_program(machine, program)
    timeline = Sequencer(program, machine, compiled=compiled).run(
        horizon_ns, scan_stepping=scan_stepping, tiling=tiling, max_events=max_events,
        replay=replay, islands=islands)
    machine.warnings.extend(lint_timeline(machine, timeline))
    return timeline


def valves_moved(machine, timeline) -> bool | None:
    """Whether any consumer's valve command ever left its rest in the run (None: the
    machine has no valves at all). Checked on the executed part of a tiled run."""
    return _valve_lint(machine, timeline)[0]


def lint_timeline(machine, timeline) -> list[str]:
    """Warnings a run gives about its machine: no valve output ever changed (nothing
    moved: an input nobody drives? a program waiting for something?), or both solenoids
    of a bistable valve on at once (the valve keeps its state; the wiring or the program
    is wrong). A tiled run is checked on the part executed, which the rest repeats."""
    moved, out = _valve_lint(machine, timeline)
    if moved is False:
        out.append(f"{machine.path}: no valve output changed over {timeline.horizon_s:g} s: "
                   "nothing moved (an input nobody drives? a program waiting for something?)")
    return out


def _valve_lint(machine, timeline) -> tuple[bool | None, list[str]]:
    file = str(machine.path)
    names = timeline.info.get("machine_signals", {})
    known = {sig.name for sig in timeline.signals}
    out, moved, any_valve = [], False, False
    for c in machine.consumers:
        series = []
        for v in c.valve:
            name = names.get(v, v)
            if name not in known:
                break
            series.append(timeline.executed_edge_times_ns(name))
        else:
            if not series:
                continue
            any_valve = True
            # a change after the first scan, or a first scan that already commands the
            # consumer away from its rest (a cylinder's initial position, a nozzle off)
            rest = c.initial == "extended" if c.is_cylinder else False
            first = [bool(v[0]) if len(v) else False for _, v in series]
            away = first[0] != rest if len(series) == 1 else (
                first[0] and not rest) or (first[1] and rest)
            moved = moved or away or any(np.any(t > 0) for t, _ in series)
            if len(series) == 2:
                times = np.union1d(series[0][0], series[1][0])
                on = [v[np.maximum(np.searchsorted(t, times, side="right") - 1, 0)] != 0
                      for t, v in series]
                both = times[on[0] & on[1]]
                if both.size:
                    out.append(f'{file}: consumer "{c.name}": both solenoids of its bistable '
                               f"valve ({c.valve[0]}, {c.valve[1]}) are on at "
                               f"{both[0] / 1e9:g} s; the valve keeps its state")
    return (moved if any_valve else None), out
