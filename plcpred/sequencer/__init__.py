"""Unfolding a PLC program into timelines: a discrete-event executor with PLC scan
semantics and a plant I/O model.

* :func:`unfold` - run a machine's program over a horizon, giving a :class:`Timeline`
* :class:`Sequencer` - the executor (event-driven, or every scan as a reference)
* :mod:`~plcpred.sequencer.compiler` - IR to Python, one class per POU
* :mod:`~plcpred.sequencer.sfc` - SFC evolution and action control
* :mod:`~plcpred.sequencer.stdfb` - the IEC 61131-3 standard function blocks
* :mod:`~plcpred.sequencer.plant` - cylinder end switches following their valves
"""
from ..lazy import lazy_attributes

# Each name is imported from its module on first use (PEP 562): the compiler's package
# is imported by `plcpred check`, which must not wait for numpy, the machine file's
# reader and the executor (the start-up benchmark, bench/startup.py).
_LAZY = {
    "CompileError": ".compiler", "compile_program": ".compiler",
    "Sequencer": ".executor", "SequencerError": ".executor", "observed_names": ".executor",
    "ExecutionError": ".runtime", "Watchdog": ".runtime",
    "DEFAULT_MAX_CHANGES": ".timeline", "Signal": ".timeline", "Timeline": ".timeline",
    "TimelineTooLarge": ".timeline", "parse_horizon": ".timeline",
    "lint_timeline": ".unfolding", "unfold": ".unfolding", "valves_moved": ".unfolding",
}

__all__ = ["CompileError", "ExecutionError", "Sequencer", "SequencerError", "Signal",
           "Timeline", "TimelineTooLarge", "Watchdog", "compile_program", "lint_timeline",
           "observed_names", "parse_horizon", "unfold", "valves_moved"]


__getattr__, __dir__ = lazy_attributes(__name__, _LAZY)
