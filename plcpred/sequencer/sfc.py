"""Sequential function chart evolution (IEC 61131-3 ed.3, 6.7.4-6.7.5).

Each scan of an SFC body:

1. **Transition clearing.** A transition is enabled when all its preceding steps are
   active. Enabled transitions whose condition is TRUE clear simultaneously: their
   preceding steps are deactivated and their following steps activated (a step both
   left and entered restarts). Among transitions leaving the same step (selection
   divergence) the one with the lowest ``priority`` (then the first declared) wins, and
   a step left by one transition cannot feed another in the same scan. A newly activated
   step's own transitions are first evaluated in the next scan (one layer per scan).
2. **Action control.** Every action named in an association has an action control block
   built from the standard FBs exactly as ed.2 figure 14 draws it:
   ``Q := NOT R AND (N OR (L AND NOT L_TMR.Q) OR D_TMR.Q OR P OR S_FF.Q1 OR SD_TMR.Q OR
   DS_FF.Q1 OR (SL_FF.Q1 AND NOT SL_TMR.Q) OR P1 OR P0)``; each qualifier input is the OR
   of the ``.X`` flags of the active steps that use it.
3. **Actions.** A Boolean action (a variable named in an association) is assigned ``Q``
   every scan. An action body runs while ``Q`` is TRUE and once more on the scan ``Q``
   falls (the final scan of 6.7.4.3), except when its only qualifiers are pulses
   (P, P1, P0), which run exactly once.

``step.T`` is the time since the step was activated while it is active and keeps its last
value after it is left; ``step.X`` is the activity flag.
"""
from __future__ import annotations

from .stdfb import R_TRIG, RS, TON

PULSES = {"P", "P1", "P0"}
TIMED = {"L", "D", "SD", "DS", "SL"}


class ActionSpec:
    """One action of a chart: a body (a method of the owning POU) or a Boolean variable
    (a setter), with the qualifiers that refer to it."""

    def __init__(self, name: str, body=None, setter=None):
        self.name, self.body, self.setter = name, body, setter
        self.assocs: list[tuple[int, str, object]] = []  # (step index, qualifier, time fn)

    @property
    def pulse_only(self) -> bool:
        return all(q in PULSES for _, q, _ in self.assocs)


class SfcSpec:
    def __init__(self, steps: list[str], initial: int, transitions, actions,
                 thresholds: dict[int, list[int]], t_read: set[int]):
        self.steps = steps
        self.initial = initial
        # (sources, targets, condition method, priority) in evaluation order
        self.transitions = transitions
        self.actions: list[ActionSpec] = actions
        self.thresholds = thresholds  # step -> constant step.T thresholds (ns) read
        self.t_read = t_read          # steps whose .T is read other than against a constant


class ActionControl:
    __slots__ = ("s_ff", "l_tmr", "d_tmr", "p_trig", "sd_ff", "sd_tmr", "ds_tmr", "ds_ff",
                 "sl_ff", "sl_tmr", "q")

    def __init__(self):
        self.s_ff, self.sd_ff, self.ds_ff, self.sl_ff = RS(), RS(), RS(), RS()
        self.l_tmr, self.d_tmr, self.sd_tmr, self.ds_tmr, self.sl_tmr = (
            TON(), TON(), TON(), TON(), TON())
        self.p_trig = R_TRIG()
        self.q = False

    def timers(self):
        return (self.l_tmr, self.d_tmr, self.sd_tmr, self.ds_tmr, self.sl_tmr)

    def update(self, now, inp: dict, times: dict) -> bool:
        r = inp.get("R", False)
        self.s_ff.S, self.s_ff.R1 = inp.get("S", False), r
        self.s_ff.execute(now)
        self.l_tmr.IN, self.l_tmr.PT = inp.get("L", False), times.get("L", 0)
        self.l_tmr.execute(now)
        self.d_tmr.IN, self.d_tmr.PT = inp.get("D", False), times.get("D", 0)
        self.d_tmr.execute(now)
        self.p_trig.CLK = inp.get("P", False)
        self.p_trig.execute(now)
        self.sd_ff.S, self.sd_ff.R1 = inp.get("SD", False), r
        self.sd_ff.execute(now)
        self.sd_tmr.IN, self.sd_tmr.PT = self.sd_ff.Q1, times.get("SD", 0)
        self.sd_tmr.execute(now)
        self.ds_tmr.IN, self.ds_tmr.PT = inp.get("DS", False), times.get("DS", 0)
        self.ds_tmr.execute(now)
        self.ds_ff.S, self.ds_ff.R1 = self.ds_tmr.Q, r
        self.ds_ff.execute(now)
        self.sl_ff.S, self.sl_ff.R1 = inp.get("SL", False), r
        self.sl_ff.execute(now)
        self.sl_tmr.IN, self.sl_tmr.PT = self.sl_ff.Q1, times.get("SL", 0)
        self.sl_tmr.execute(now)
        self.q = not r and (
            inp.get("N", False) or (inp.get("L", False) and not self.l_tmr.Q)
            or self.d_tmr.Q or self.p_trig.Q or self.s_ff.Q1 or self.sd_tmr.Q
            or self.ds_ff.Q1 or (self.sl_ff.Q1 and not self.sl_tmr.Q)
            or inp.get("P1", False) or inp.get("P0", False))
        return self.q

    def key(self, rel):
        return (self.q, self.p_trig.key(rel)) + tuple(
            f.Q1 for f in (self.s_ff, self.sd_ff, self.ds_ff, self.sl_ff)) + tuple(
            t.key(rel) for t in self.timers())


class SfcRuntime:
    """The state of one chart instance: step flags, activation times, action controls."""

    def __init__(self, spec: SfcSpec, owner):
        self.spec, self.owner = spec, owner
        n = len(spec.steps)
        self.x = [False] * n
        self.x[spec.initial] = True
        self.t0 = [0] * n       # activation time (ns) of active steps
        self.tlast = [0] * n    # step.T frozen when the step was left
        self.entered = [False] * n
        self.left = [False] * n
        self.ctl = [ActionControl() for _ in spec.actions]
        self.ran = [False] * len(spec.actions)
        self.started = False
        self.rest_key = False

    def t(self, i: int, now: int) -> int:
        return now - self.t0[i] if self.x[i] else self.tlast[i]

    def timers(self):
        for c in self.ctl:
            yield from c.timers()

    def run(self, now: int) -> None:
        spec, x, owner = self.spec, self.x, self.owner
        n = len(x)
        entered, left = [False] * n, [False] * n
        if not self.started:
            self.started = True
            self.t0[spec.initial] = now
            entered[spec.initial] = True
        else:
            taken = set()
            activate = []
            for sources, targets, cond, _prio in spec.transitions:
                if all(x[s] for s in sources) and not taken.intersection(sources):
                    if cond(owner):
                        taken.update(sources)
                        activate.extend(targets)
            for s in taken:
                x[s] = False
                left[s] = True
                self.tlast[s] = now - self.t0[s]
            for s in activate:
                x[s] = True
                entered[s] = True
                left[s] = False
                self.t0[s] = now
        self.entered, self.left = entered, left
        for k, act in enumerate(spec.actions):
            inp, times = {}, {}
            for s, q, tfn in act.assocs:
                if q == "P1":
                    on = entered[s]
                elif q == "P0":
                    on = left[s]
                else:
                    on = x[s]
                if on:
                    inp[q] = True
                    if q in TIMED and q not in times:
                        times[q] = tfn(owner)
            was = self.ctl[k].q
            q = self.ctl[k].update(now, inp, times)
            if act.setter is not None:
                act.setter(owner, q)
            elif q or (was and not act.pulse_only):
                act.body(owner)

    def next_event_ns(self, now: int):
        """The earliest time a constant ``step.T`` comparison or an action timer can change
        something without an input changing; ``now`` means "every scan" (a step whose
        elapsed time is read in a way that cannot be predicted is active)."""
        best = None
        for i, active in enumerate(self.x):
            if not active:
                continue
            if i in self.spec.t_read:
                return now
            for c in self.spec.thresholds.get(i, ()):
                for t in (self.t0[i] + c, self.t0[i] + c + 1):
                    if t > now and (best is None or t < best):
                        best = t
        for tmr in self.timers():
            t = tmr.next_event_ns()
            if t is not None and (best is None or t < best):
                best = t
        return best

    def key(self, rel):
        """The chart's state, its step times from ``rel``. With ``rest_key`` set (the
        executor's key of a state at rest, for part replay): step times only of steps
        whose time the program reads, and a time compared only with constants only up
        to the largest (past it every comparison stays as it is), so that a chart
        resting in a step nothing times holds no time and its parts replay."""
        if not self.rest_key:
            if rel is None:
                times = tuple(self.t0[i] if a else self.tlast[i]
                              for i, a in enumerate(self.x))
            else:
                times = tuple(rel - self.t0[i] if a else self.tlast[i]
                              for i, a in enumerate(self.x))
            return (tuple(self.x), times, self.started) + tuple(
                c.key(rel) for c in self.ctl)
        spec, times = self.spec, []
        for i, a in enumerate(self.x):
            limits = spec.thresholds.get(i)
            if i not in spec.t_read and not limits:
                times.append(None)
            elif rel is None:
                times.append(self.t0[i] if a else self.tlast[i])
            else:
                elapsed = rel - self.t0[i] if a else self.tlast[i]
                times.append(elapsed if i in spec.t_read else min(elapsed, max(limits) + 1))
        return (tuple(self.x), tuple(times), self.started) + tuple(
            c.key(rel) for c in self.ctl)
