"""Unfolding a PLC program into timelines: a discrete-event executor with PLC scan
semantics and a plant I/O model.

* :func:`unfold` - run a machine's program over a horizon, giving a :class:`Timeline`
* :class:`Sequencer` - the executor (event-driven, or every scan as a reference)
* :mod:`~plcpred.sequencer.compiler` - IR to Python, one class per POU
* :mod:`~plcpred.sequencer.sfc` - SFC evolution and action control
* :mod:`~plcpred.sequencer.stdfb` - the IEC 61131-3 standard function blocks
* :mod:`~plcpred.sequencer.plant` - cylinder end switches following their valves
"""
from .compiler import CompileError, compile_program
from .executor import Sequencer, SequencerError
from .runtime import ExecutionError, Watchdog
from .timeline import DEFAULT_MAX_CHANGES, Signal, Timeline, TimelineTooLarge, parse_horizon

__all__ = ["CompileError", "ExecutionError", "Sequencer", "SequencerError", "Signal",
           "Timeline", "TimelineTooLarge", "Watchdog", "compile_program", "parse_horizon", "unfold"]


def unfold(machine, horizon="60s", scan_stepping: bool = False, tiling: bool = True,
           program=None, max_events: int = DEFAULT_MAX_CHANGES) -> Timeline:
    """Run ``machine``'s program (or ``program``, an IR or a path, instead) over
    ``horizon`` (``"90s"``, ``"T#1m30s"``, ``"8h"`` or seconds) and return its timeline.

    Raises :class:`~plcpred.parser.ProgramError` (program text), :class:`CompileError`
    (constructs the executor cannot run), :class:`ExecutionError` (run-time faults such as
    a watchdog) or :class:`~plcpred.machine.MachineError` (machine file)."""
    from ..machine import Machine, check_against_program, load_machine
    from ..parser import load_program

    if not isinstance(machine, Machine):
        machine = load_machine(machine)
    horizon_ns = parse_horizon(horizon)
    if program is None:
        program = load_program(machine.program_path)
    elif not hasattr(program, "pous"):
        program = load_program(program)
    check_against_program(machine, program)
    return Sequencer(program, machine).run(horizon_ns, scan_stepping=scan_stepping,
                                           tiling=tiling, max_events=max_events)
