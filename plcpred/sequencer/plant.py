"""The plant I/O model: how a cylinder's end switches follow its valve.

A valve command takes effect after the switching delay; the piston then moves at a
constant speed (stroke / stroke time, separately for extend and retract) until it reaches
an end. The retracted switch is on while the piston is at 0, the extended switch while it
is at the full stroke. A command that reverses a moving piston turns it round where it is
once the valve has switched, so the return takes the matching share of the stroke time.

The trajectory is piecewise linear and known in advance, so the sequencer can ask when
the next switch edge happens (:meth:`CylinderPlant.next_event_ns`) and jump there.
Times are integer nanoseconds; positions are fractions of the stroke.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class _Segment:
    t_ns: int        # start of the segment
    x: float         # position at the start, 0 (retracted) .. 1 (extended)
    direction: int   # +1 extending, -1 retracting, 0 at rest


class CylinderPlant:
    """One cylinder's motion. ``command(t, extend)`` is called when the valve's effective
    command changes (see :func:`valve_command` for monostable, bistable and single-acting
    valves)."""

    def __init__(self, extend_ns: int, retract_ns: int, delay_ns: int = 0,
                 initial_extended: bool = False):
        if extend_ns <= 0 or retract_ns <= 0 or delay_ns < 0:
            raise ValueError("stroke times must be > 0 and the switching delay >= 0")
        self.extend_ns, self.retract_ns, self.delay_ns = extend_ns, retract_ns, delay_ns
        self.extend_cmd = initial_extended
        self._segments = [_Segment(0, 1.0 if initial_extended else 0.0, 0)]

    # ------------------------------------------------------------------ trajectory
    def _duration(self, direction: int) -> int:
        return self.extend_ns if direction > 0 else self.retract_ns

    def _segment_at(self, t_ns: int) -> _Segment:
        seg = self._segments[0]
        for s in self._segments:
            if s.t_ns <= t_ns:
                seg = s
            else:
                break
        return seg

    def _end_time(self, seg: _Segment) -> int | None:
        """When a moving segment reaches its end of stroke."""
        if seg.direction == 0:
            return None
        remaining = (1.0 - seg.x) if seg.direction > 0 else seg.x
        return seg.t_ns + round(remaining * self._duration(seg.direction))

    def position(self, t_ns: int) -> float:
        seg = self._segment_at(t_ns)
        if seg.direction == 0:
            return seg.x
        end = self._end_time(seg)
        if t_ns >= end:
            return 1.0 if seg.direction > 0 else 0.0
        travelled = (t_ns - seg.t_ns) / self._duration(seg.direction)
        return seg.x + seg.direction * travelled

    def command(self, t_ns: int, extend: bool) -> None:
        """The valve commands extend (True) or retract (False) from ``t_ns`` on."""
        if extend == self.extend_cmd:
            return
        self.extend_cmd = extend
        t_switch = t_ns + self.delay_ns
        # the valve switches at t_switch: forget whatever was planned from then on
        self._segments = [s for s in self._segments if s.t_ns < t_switch] or [self._segments[0]]
        x = self.position(t_switch)
        direction = 1 if extend else -1
        if (direction > 0 and x >= 1.0) or (direction < 0 and x <= 0.0):
            direction = 0
        self._segments.append(_Segment(t_switch, x, direction))

    def forget_before(self, t_ns: int) -> None:
        """Drop trajectory segments that ended before ``t_ns`` (the sequencer only moves
        forward, so a long run keeps a handful of segments instead of its whole history)."""
        keep = 0
        for i, s in enumerate(self._segments):
            if s.t_ns <= t_ns:
                keep = i
        if keep:
            del self._segments[:keep]

    def key(self, t_ns: int) -> tuple:
        """The motion from ``t_ns`` on, with times relative to it (for noticing that the
        machine is back in an earlier state)."""
        last = self._segments[-1]
        if last.t_ns <= t_ns:           # nothing planned after now
            if last.direction == 0:
                return (self.extend_cmd, last.x, 0)
            if t_ns >= self._end_time(last):
                # at the end of its last stroke: the same state as resting there
                return (self.extend_cmd, 1.0 if last.direction > 0 else 0.0, 0)
        seg = self._segment_at(t_ns)
        future = tuple((s.t_ns - t_ns, s.x, s.direction) for s in self._segments
                       if s.t_ns > t_ns)
        return (self.extend_cmd, self.position(t_ns), seg.direction) + future

    # ------------------------------------------------------------------ switches
    def switches(self, t_ns: int) -> tuple[bool, bool]:
        """(retracted switch, extended switch) at ``t_ns``."""
        seg = self._segment_at(t_ns)
        x = self.position(t_ns)
        # a switch drops the moment the piston starts to move away from it
        return x <= 0.0 and seg.direction <= 0, x >= 1.0 and seg.direction >= 0

    def next_event_ns(self, after_ns: int) -> int | None:
        """The first time > ``after_ns`` at which a switch changes, or None."""
        now = self.switches(after_ns)
        candidates = []
        for s in self._segments:
            if s.t_ns > after_ns:
                candidates.append(s.t_ns)
            end = self._end_time(s)
            if end is not None and end > after_ns:
                candidates.append(end)
        for t in sorted(set(candidates)):
            if self.switches(t) != now:
                return t
            now = self.switches(t)
        return None


def valve_command(solenoids: list[bool], previous: bool, rising: list[bool]) -> bool:
    """The effective extend command of a valve.

    Monostable (one solenoid, spring return) and single-acting: extend while the solenoid
    is on. Bistable (two solenoids, extend and retract): the last one pulsed decides; a pulse
    that does not change the state costs nothing; if both rise in the same scan the valve
    keeps its state."""
    if len(solenoids) == 1:
        return solenoids[0]
    up_extend, up_retract = rising
    if up_extend and not up_retract:
        return True
    if up_retract and not up_extend:
        return False
    return previous
