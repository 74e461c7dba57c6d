"""The IEC 61131-3 standard function blocks (ed.3, 2013, tables 43-46), executed with
integer-nanosecond time.

An instance keeps its inputs between calls (IEC FB input retention): a call sets the
inputs it names and then runs :meth:`execute` with the current time. Timers also say when
their output will change next without any input changing (:meth:`next_event_ns`), which
is what lets the sequencer jump straight there instead of running every scan.

F_TRIG follows ed.3 (``Q := NOT CLK AND M; M := CLK``, M initially FALSE): unlike the
ed.2 body it does not report a falling edge on its first call with CLK FALSE.
"""
from __future__ import annotations

from operator import attrgetter


class StandardFB:
    INPUTS: tuple[str, ...] = ()
    OUTPUTS: tuple[str, ...] = ()
    __slots__ = ()

    def execute(self, now_ns: int) -> None:  # pragma: no cover - interface
        raise NotImplementedError

    def next_event_ns(self) -> int | None:
        """Absolute time at which an output changes on its own, or None."""
        return None

    def __init_subclass__(cls, **kw):
        super().__init_subclass__(**kw)
        if cls.__slots__:
            getter = attrgetter(*cls.__slots__)
            cls._state = getter if len(cls.__slots__) > 1 else (lambda self: (getter(self),))

    def state(self) -> tuple:
        """Everything that determines future behaviour (for detecting a repeating state)."""
        return self._state(self)

    def et_origin(self) -> int | None:
        """While ET grows with time: the instant it was 0 (so ET = now - origin), else
        None. Lets the sequencer schedule the moment ET crosses a constant."""
        return None

    def key(self, rel: int | None) -> tuple:
        """The state in a form that compares equal when the future behaves alike.

        ``rel=None``: absolute, for asking "did this scan change anything?" between two
        scans; the elapsed time of a running timer is left out because it follows from the
        start time. ``rel=now``: absolute times become ages, for noticing that the whole
        machine is back in an earlier state (tiling)."""
        return self.state()


# ---------------------------------------------------------------------- timers (table 46)

class TON(StandardFB):
    """On-delay: Q rises PT after IN rises and falls with IN; ET counts up to PT."""
    INPUTS, OUTPUTS = ("IN", "PT"), ("Q", "ET")
    __slots__ = ("IN", "PT", "Q", "ET", "_start")

    def __init__(self):
        self.IN, self.PT, self.Q, self.ET, self._start = False, 0, False, 0, None

    def execute(self, now_ns: int) -> None:
        if self.IN:
            if self._start is None:
                self._start = now_ns
            pt = max(self.PT, 0)
            elapsed = now_ns - self._start
            self.Q = elapsed >= pt
            self.ET = min(elapsed, pt)
        else:
            self._start, self.Q, self.ET = None, False, 0

    def next_event_ns(self):
        if self.IN and not self.Q and self._start is not None:
            return self._start + max(self.PT, 0)
        return None

    def et_origin(self):
        return self._start if self.IN and not self.Q else None

    def key(self, rel):
        start = self._start
        if start is None:
            return (self.IN, self.PT, self.Q, self.ET)
        return (self.IN, self.PT, self.Q, start if rel is None else rel - start, None)


class TOF(StandardFB):
    """Off-delay: Q follows IN up at once and falls PT after IN falls."""
    INPUTS, OUTPUTS = ("IN", "PT"), ("Q", "ET")
    __slots__ = ("IN", "PT", "Q", "ET", "_start")

    def __init__(self):
        self.IN, self.PT, self.Q, self.ET, self._start = False, 0, False, 0, None

    def execute(self, now_ns: int) -> None:
        if self.IN:
            self.Q, self.ET, self._start = True, 0, None
        elif self.Q:
            if self._start is None:
                self._start = now_ns
            pt = max(self.PT, 0)
            elapsed = now_ns - self._start
            if elapsed >= pt:
                self.Q, self.ET, self._start = False, pt, None
            else:
                self.ET = elapsed

    def next_event_ns(self):
        if not self.IN and self.Q and self._start is not None:
            return self._start + max(self.PT, 0)
        return None

    def et_origin(self):
        return self._start if not self.IN and self.Q else None

    def key(self, rel):
        start = self._start
        if start is None:
            return (self.IN, self.PT, self.Q, self.ET)
        return (self.IN, self.PT, self.Q, start if rel is None else rel - start, None)


class TP(StandardFB):
    """Pulse: a rising IN starts a pulse of length PT; edges during the pulse are ignored.
    After the pulse ET holds PT while IN stays TRUE and returns to 0 when IN falls."""
    INPUTS, OUTPUTS = ("IN", "PT"), ("Q", "ET")
    __slots__ = ("IN", "PT", "Q", "ET", "_start", "_prev_in")

    def __init__(self):
        self.IN, self.PT, self.Q, self.ET = False, 0, False, 0
        self._start, self._prev_in = None, False

    def execute(self, now_ns: int) -> None:
        if self._start is None and self.IN and not self._prev_in:
            self._start = now_ns
        if self._start is not None:
            pt = max(self.PT, 0)
            elapsed = now_ns - self._start
            if elapsed >= pt:
                self._start, self.Q, self.ET = None, False, pt
            else:
                self.Q, self.ET = True, elapsed
        if self._start is None:
            self.Q = False
            if not self.IN:
                self.ET = 0
        self._prev_in = self.IN

    def next_event_ns(self):
        if self._start is not None:
            return self._start + max(self.PT, 0)
        return None

    def et_origin(self):
        return self._start

    def key(self, rel):
        start = self._start
        if start is None:
            return (self.IN, self.PT, self.Q, self.ET, self._prev_in)
        return (self.IN, self.PT, self.Q, start if rel is None else rel - start, None,
                self._prev_in)


class TONR(StandardFB):
    """Retentive on-delay (CODESYS/TwinCAT): ET accumulates while IN, RESET clears it.
    The time between two calls counts when IN was TRUE and RESET FALSE during it (the
    values at the earlier call, which hold until the next), so event jumps and scan
    stepping agree."""
    INPUTS, OUTPUTS = ("IN", "PT", "RESET"), ("Q", "ET")
    __slots__ = ("IN", "PT", "RESET", "Q", "ET", "_last", "_was_in", "_last_pt")

    def __init__(self):
        self.IN, self.PT, self.RESET, self.Q, self.ET = False, 0, False, False, 0
        self._last, self._was_in, self._last_pt = None, False, 0

    def execute(self, now_ns: int) -> None:
        pt = max(self.PT, 0)
        if self.RESET:
            self.ET = 0
        elif self._was_in and self._last is not None:
            # the interval is capped by the PT in force during it
            self.ET = min(self.ET + now_ns - self._last, self._last_pt)
        self.ET = min(self.ET, pt)
        self._last, self._was_in, self._last_pt = now_ns, self.IN and not self.RESET, pt
        self.Q = not self.RESET and self.ET >= pt and (pt > 0 or self.IN)

    def next_event_ns(self):
        if self.IN and not self.RESET and not self.Q and self._last is not None:
            return self._last + max(self.PT, 0) - self.ET
        return None

    def et_origin(self):
        if self._was_in and not self.Q and self._last is not None:
            return self._last - self.ET
        return None

    def key(self, rel):
        head = (self.IN, self.PT, self.RESET, self.Q, self._was_in, self._last_pt)
        if not self._was_in or self._last is None or self.Q:
            return head + (self.ET, self._last is None)
        # while accumulating, ET grows with time: keep its virtual start instead
        start = self._last - self.ET
        return head + (start if rel is None else rel - start,)


# ---------------------------------------------------------------------- edges (table 44)

class R_TRIG(StandardFB):
    INPUTS, OUTPUTS = ("CLK",), ("Q",)
    __slots__ = ("CLK", "Q", "_m")

    def __init__(self):
        self.CLK, self.Q, self._m = False, False, False

    def key(self, rel):
        return (self.CLK, self.Q, self._m)

    def execute(self, now_ns: int) -> None:
        self.Q = self.CLK and not self._m
        self._m = self.CLK


class F_TRIG(StandardFB):
    INPUTS, OUTPUTS = ("CLK",), ("Q",)
    __slots__ = ("CLK", "Q", "_m")

    def __init__(self):
        self.CLK, self.Q, self._m = False, False, False

    def key(self, rel):
        return (self.CLK, self.Q, self._m)

    def execute(self, now_ns: int) -> None:
        self.Q = not self.CLK and self._m
        self._m = self.CLK


# ---------------------------------------------------------------------- bistables (table 43)

class SR(StandardFB):
    """Set-dominant: Q1 := S1 OR (NOT R AND Q1)."""
    INPUTS, OUTPUTS = ("S1", "R"), ("Q1",)
    __slots__ = ("S1", "R", "Q1")

    def __init__(self):
        self.S1, self.R, self.Q1 = False, False, False

    def execute(self, now_ns: int) -> None:
        self.Q1 = self.S1 or (not self.R and self.Q1)


class RS(StandardFB):
    """Reset-dominant: Q1 := NOT R1 AND (S OR Q1)."""
    INPUTS, OUTPUTS = ("S", "R1"), ("Q1",)
    __slots__ = ("S", "R1", "Q1")

    def __init__(self):
        self.S, self.R1, self.Q1 = False, False, False

    def execute(self, now_ns: int) -> None:
        self.Q1 = not self.R1 and (self.S or self.Q1)


# ---------------------------------------------------------------------- counters (table 45)

_INT_RANGE = {"INT": (-32768, 32767), "DINT": (-2**31, 2**31 - 1), "LINT": (-2**63, 2**63 - 1),
              "UDINT": (0, 2**32 - 1), "ULINT": (0, 2**64 - 1)}


class CTU(StandardFB):
    """Up-counter: CV counts rising edges of CU (R resets); Q := CV >= PV."""
    INPUTS, OUTPUTS = ("CU", "R", "PV"), ("Q", "CV")
    __slots__ = ("CU", "R", "PV", "Q", "CV", "_cu", "_max")

    def __init__(self, width: str = "INT"):
        self.CU, self.R, self.PV, self.Q, self.CV, self._cu = False, False, 0, False, 0, False
        self._max = _INT_RANGE[width][1]

    def execute(self, now_ns: int) -> None:
        edge = self.CU and not self._cu
        self._cu = self.CU
        if self.R:
            self.CV = 0
        elif edge and self.CV < self._max:
            self.CV += 1
        self.Q = self.CV >= self.PV


    def key_counted(self, rel) -> tuple:
        """:meth:`key` with the count held at PV: for a counter whose CV nothing reads
        and whose PV stays, counts at or past PV behave alike (Q stays TRUE until R)."""
        return (self.CU, self.R, self.PV, self.Q, min(self.CV, self.PV), self._cu, self._max)


class CTD(StandardFB):
    """Down-counter: LD loads PV, each rising edge of CD counts down; Q := CV <= 0."""
    INPUTS, OUTPUTS = ("CD", "LD", "PV"), ("Q", "CV")
    __slots__ = ("CD", "LD", "PV", "Q", "CV", "_cd", "_min")

    def __init__(self, width: str = "INT"):
        self.CD, self.LD, self.PV, self.Q, self.CV, self._cd = False, False, 0, False, 0, False
        self._min = _INT_RANGE[width][0]

    def execute(self, now_ns: int) -> None:
        edge = self.CD and not self._cd
        self._cd = self.CD
        if self.LD:
            self.CV = self.PV
        elif edge and self.CV > self._min:
            self.CV -= 1
        self.Q = self.CV <= 0

    def key_counted(self, rel) -> tuple:
        """:meth:`key` with the count held at 0: for a counter whose CV nothing reads,
        counts at or below 0 behave alike (Q stays TRUE until LD loads PV)."""
        return (self.CD, self.LD, self.PV, self.Q, max(self.CV, 0), self._cd, self._min)


class CTUD(StandardFB):
    """Up-down counter: R (priority) clears, LD loads PV, otherwise one rising edge of CU
    or CD counts (both at once cancel); QU := CV >= PV, QD := CV <= 0."""
    INPUTS, OUTPUTS = ("CU", "CD", "R", "LD", "PV"), ("QU", "QD", "CV")
    __slots__ = ("CU", "CD", "R", "LD", "PV", "QU", "QD", "CV", "_cu", "_cd", "_min", "_max")

    def __init__(self, width: str = "INT"):
        self.CU = self.CD = self.R = self.LD = False
        self.PV, self.QU, self.QD, self.CV = 0, False, False, 0
        self._cu = self._cd = False
        self._min, self._max = _INT_RANGE[width]

    def execute(self, now_ns: int) -> None:
        up = self.CU and not self._cu
        down = self.CD and not self._cd
        self._cu, self._cd = self.CU, self.CD
        if self.R:
            self.CV = 0
        elif self.LD:
            self.CV = self.PV
        elif not (up and down):
            if up and self.CV < self._max:
                self.CV += 1
            elif down and self.CV > self._min:
                self.CV -= 1
        self.QU = self.CV >= self.PV
        self.QD = self.CV <= 0


STANDARD_FB_CLASSES: dict[str, type] = {
    "TON": TON, "TOF": TOF, "TP": TP, "LTON": TON, "LTOF": TOF, "LTP": TP, "TONR": TONR,
    "R_TRIG": R_TRIG, "F_TRIG": F_TRIG, "SR": SR, "RS": RS, "CTU": CTU, "CTD": CTD,
    "CTUD": CTUD,
}


def make_standard_fb(type_name: str) -> StandardFB:
    """A fresh instance of a standard FB (``CTU_DINT`` gives a DINT-range CTU)."""
    up = type_name.upper()
    if up in STANDARD_FB_CLASSES:
        return STANDARD_FB_CLASSES[up]()
    base, _, width = up.partition("_")
    if base in ("CTU", "CTD", "CTUD") and width in _INT_RANGE:
        return STANDARD_FB_CLASSES[base](width)
    raise KeyError(type_name)
