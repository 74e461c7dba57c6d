"""The discrete-event executor: PLC scans (read inputs, run the programs, write outputs)
at multiples of the scan time, jumping over scans in which nothing can change.

Why jumping is exact: a scan is a deterministic function of the program state, the
inputs and the time. When a scan leaves the state exactly as the previous scan did (a
fixed point), every later scan does the same until something time-driven happens: an
input edge (schedule or plant switch), a timer reaching PT (``next_event_ns`` of the
standard FBs and of SFC action timers), or a step's elapsed time crossing a constant it
is compared with. The executor jumps to the first scan at or after the earliest of those.
Values that grow with time between scans (a running timer's ET, ``step.T`` read other
than against a constant, TIME()) make it step every scan while they change.
``scan_stepping=True`` runs every scan, as the reference the tests compare against.

Long horizons: at each fixed point the whole state (variables, FB instances, timers,
steps, cylinder motions, schedule phase) is recorded with times made relative; when a
state comes back, the edges since its first occurrence repeat, so they are tiled up to
the horizon. Random jitter in a schedule, pulses still to come and free-running counters
that never repeat simply keep the executor running scan by scan to the horizon.
"""
from __future__ import annotations

import builtins
import copy
import dataclasses
import hashlib
import math
import pickle
import re
import tempfile
import time as _time
from array import array
from dataclasses import dataclass, field
from heapq import heappop, heappush

import numpy as np

from ..errors import PlcpredError
from ..machine import MachineError, program_addresses
from ..parser import ir
from ..parser.names import ident
from . import runtime as rtm
from . import types
from .compiler import (
    BIT_READ,
    WATCHDOG_ITERATIONS,
    Compiled,
    CompileError,
    compile_program,
    stdfb_member,
)
from .islands import SlotCells, find_islands, island_snap, island_timers, slot_cell
from .plant import CylinderPlant, valve_command
from .sfc import ActionSpec, SfcRuntime, SfcSpec
from .stdfb import TOF, TON, TONR, TP, make_standard_fb
from .timeline import DEFAULT_MAX_CHANGES, NS, Signal, SpilledColumn, Timeline, wrap_array

_TIMERS = (TON, TOF, TP, TONR)
NEVER = 1 << 62      # "no event" in integer nanoseconds
MAX_KEYS = 20_000   # fixed points remembered when looking for a repeating state
MAX_PART_VARIANTS = 256     # recorded responses kept per rest state (part replay)
# ... of which those past the first FEW_PART_VARIANTS only while the state's responses
# hold fewer than MAX_PART_CHANGES changes in all
FEW_PART_VARIANTS = 16
MAX_PART_CHANGES = 200_000  # a response longer than this is not recorded
MAX_OPEN_PARTS = 8          # parts recorded at once (from different rest states)
MAX_PART_REPLAYS = 2_000    # a part holding more replays of others is not recorded
EAGER_MERGE = 2_000_000     # islands' edges merged into arrays at once up to this many
SPILL_REPLAYS = 1 << 20     # replays held in memory before most go to a file
KEEP_REPLAYS = 4 * MAX_PART_REPLAYS     # the last ones, which a part may still hold
_REPLAY = np.dtype([("at", np.int32), ("start", np.int64), ("pid", np.int32)])


class SequencerError(PlcpredError):
    """A problem running a machine (not a program syntax error)."""


def _naming_table(machine, signal: str) -> str:
    """Where the machine file names ``signal``: ``[[consumer]] "1A1" valve``, ``[[input]]
    signal`` and so on (empty where no table does, e.g. a [signals] alias)."""
    for c in machine.consumers:
        valves = c.valve if isinstance(c.valve, (list, tuple)) else [c.valve]
        if signal in valves:
            return f'[[consumer]] "{c.name}" valve'
        for role, name in (c.switches or {}).items():
            if name == signal:
                return f'[[consumer]] "{c.name}" switches.{role}'
    for k, i in enumerate(machine.inputs):
        if i.signal == signal:
            return f"[[input]] #{k + 1} signal"
    return ""


# ---------------------------------------------------------------------- namespace

class FbBase:
    __slots__ = ()


class _LeftOut:
    """The recorded signals that the compared state leaves out (``Compiled.left_out``: a
    parts count nothing reads, shown because the machine file names it): what a repeated
    period or a replayed part must do so that they show what execution would. A count
    that only adds a step to itself shows the first period's values plus the step per
    period; any other such signal must not have changed, or nothing is repeated."""

    def __init__(self, slots, left_out: dict | None):
        self.counts: dict = {}       # signal index -> (obj, attr, bits, signed)
        self.others: list = []       # signal indices
        for i, slot in enumerate(slots):
            if slot is None or not left_out:
                continue
            obj, attr = slot
            if isinstance(obj, (BitView, ItemView)):   # a bit or an element: no count
                if _left_out_kind(*_root_slot(obj, attr), left_out) is not _KEPT:
                    self.others.append(i)
                continue
            kind = _left_out_kind(obj, attr, left_out)
            if kind is None:
                self.others.append(i)
            elif kind is not _KEPT:
                self.counts[i] = (obj, attr) + tuple(kind)
        self.order = self.others + sorted(self.counts)
        left = set(self.order)
        self._kept = [i for i in range(len(slots)) if i not in left]

    def __bool__(self) -> bool:
        return bool(self.order)

    def values(self, values) -> tuple:
        return tuple(values[i] for i in self.order)

    def kept(self, values) -> tuple:
        """The values of the other signals."""
        return tuple([values[i] for i in self._kept])

    def period_drift(self, values, t1: int, tt, ss, vv) -> dict | None:
        """{signal: (step, bits, signed)} of the counts from ``t1`` to now; None when
        another left-out signal differs (the period cannot be repeated)."""
        if not self:
            return {}
        t = np.frombuffer(tt, dtype=np.int64)
        n = int(np.searchsorted(t, t1, side="right"))
        s = np.frombuffer(ss, dtype=np.int32)[:n]
        v = np.frombuffer(vv, dtype=np.float64)[:n]
        drift = {}
        for i in self.order:
            before = v[np.flatnonzero(s == i)[-1]]   # the first scan recorded every signal
            step = float(values[i]) - float(before)
            if step == 0:
                continue
            if i not in self.counts:
                return None
            drift[i] = (int(step), self.counts[i][2], self.counts[i][3])
        return drift

    def replayed(self, now, start, end, cs: bytes, cv: bytes):
        """A part recorded with these signals at ``start`` and ``end``, copied when they
        are at ``now``: its values (``cv`` with each count shifted by how far it has
        grown since), or None when another left-out signal is not where it was or
        changed in the part."""
        shifted = None
        for i, a, b, c in zip(self.order, now, start, end):
            if i not in self.counts:
                if a != b or b != c:
                    return None
                continue
            if a == b:
                continue
            if shifted is None:
                sig = np.frombuffer(cs, dtype=np.int32)
                shifted = np.frombuffer(cv, dtype=np.float64).copy()
            _, _, bits, signed = self.counts[i]
            mine = sig == i
            shifted[mine] = wrap_array(shifted[mine].astype(np.int64) + (int(a) - int(b)),
                                     bits, signed)
        return cv if shifted is None else shifted.tobytes()

    def advance(self, now, start, end) -> None:
        """After a copied part: each count grown by what it grew in the recorded part
        (the program did not run it)."""
        for i, a, b, c in zip(self.order, now, start, end):
            if i in self.counts and b != c:
                obj, attr, bits, signed = self.counts[i]
                setattr(obj, attr, rtm.wrap(int(a) + int(c) - int(b), bits, signed))


_KEPT = object()


def _root_slot(obj, attr):
    """The (object, attribute) of the variable a slot is part of (a bit's word, an
    element's array, the slot itself otherwise)."""
    if isinstance(obj, BitView):
        return _root_slot(obj.obj, obj.attr)
    if isinstance(obj, ItemView):
        return obj.root
    return obj, attr


def _left_out_kind(obj, attr: str, left_out: dict):
    """``Compiled.left_out``'s entry for ``obj.attr`` (its class or a base's), or _KEPT
    when the compared state holds it."""
    for cls in type(obj).__mro__:
        kinds = left_out.get(cls.__name__)
        if kinds and attr in kinds:
            return kinds[attr]
    return _KEPT


class ItemView:
    """One element of an array as a signal (``aValves[3]``, ``fbCyl[2].q`` in a machine
    file): ``root`` is the (object, attribute) of the variable the path starts from."""
    __slots__ = ("items", "k", "root")

    def __init__(self, items, k, root):
        self.items, self.k, self.root = items, k, root

    @property
    def V(self):
        return self.items[self.k]

    @V.setter
    def V(self, value) -> None:
        self.items[self.k] = value


class BitView:
    """One bit of an integer variable as a BOOL signal (``wValves.3`` in a machine file)."""
    __slots__ = ("obj", "attr", "mask")

    def __init__(self, obj, attr, bit):
        self.obj, self.attr, self.mask = obj, attr, 1 << bit

    @property
    def V(self) -> bool:
        return bool(getattr(self.obj, self.attr) & self.mask)

    @V.setter
    def V(self, on) -> None:
        x = getattr(self.obj, self.attr)
        setattr(self.obj, self.attr, x | self.mask if on else x & ~self.mask)


_SCALARS = (bool, int, float, str)


def _copy(v):
    """Value semantics for arrays, structs and FB instances on assignment."""
    if isinstance(v, list):
        if not v or isinstance(v[0], _SCALARS):
            return v[:]
        return [_copy(x) for x in v]
    return copy.deepcopy(v)


def _setattrs(obj, **kw):
    for k, v in kw.items():
        setattr(obj, k, v)
    return obj


def _nest(flat, sizes):
    if len(sizes) == 1:
        return list(flat)
    step = len(flat) // sizes[0]
    return [_nest(flat[i * step:(i + 1) * step], sizes[1:]) for i in range(sizes[0])]


def _snap_any(v, rel):
    if isinstance(v, list):
        return tuple(_snap_any(x, rel) for x in v)
    if hasattr(v, "_snap"):
        return v._snap(rel)
    if hasattr(v, "key"):
        return v.key(rel)
    return v


def _refkey(v):
    if v is None:
        return None
    if isinstance(v, rtm.Ref):
        return (id(v.obj), v.attr)
    return id(v)


def _for_range(start, end, step):
    if step == 0:
        raise ValueError("FOR with BY 0 never ends")
    return range(start, end + (1 if step > 0 else -1), step)


def _watchdog(kind, file, line, col):
    raise rtm.Watchdog(f"watchdog: this {kind} loop did not finish within one scan "
                       f"(more than {WATCHDOG_ITERATIONS:,} loop passes in the scan, all "
                       "loops together)", file, line, col)


def _opaque(what, file, line, col, why="plcpred reads only ST and SFC bodies"):
    raise rtm.ExecutionError(f"cannot execute {what}: {why}", file, line, col)


def _fields(obj) -> list[str]:
    names = [n for cls in type(obj).__mro__ for n in getattr(cls, "__slots__", ())]
    return names + list(getattr(obj, "__dict__", ()))


def _deref(p, what, where):
    if p is None:
        raise rtm.NullPointer(f"{what}: a null pointer", *where)
    return p.get() if isinstance(p, rtm.Ref) else p


def _replace(dest, value):
    """Store ``value`` where pointer ``dest`` points: a Ref, an array or an object."""
    if isinstance(dest, rtm.Ref):
        dest.set(value)
    elif isinstance(dest, list):
        dest[:] = value
    else:
        for k in _fields(dest):
            setattr(dest, k, getattr(value, k))


def _memcpy(dest, src, n, *where):
    """MEMCPY/MEMMOVE of whole values: the source's value becomes the destination's.
    Bytes are not modelled, so both must hold values of one type."""
    value, current = _deref(src, "MEMCPY source", where), _deref(dest, "MEMCPY", where)
    if type(value) is not type(current):
        raise rtm.ExecutionError(
            f"MEMCPY from a {type(value).__name__} to a {type(current).__name__}: plcpred "
            "copies whole values of one type, not bytes", *where)
    _replace(dest, _copy(value))
    return n


def _zero(v):
    if isinstance(v, bool):
        return False
    if isinstance(v, (int, float, str)):
        return type(v)()
    if isinstance(v, list):
        return [_zero(x) for x in v]
    if v is None or isinstance(v, rtm.Ref):
        return None
    out = _copy(v)
    for k in _fields(out):
        setattr(out, k, _zero(getattr(out, k)))
    return out


def _memset(dest, fill, n, *where):
    """MEMSET to zero: every element and member of the value becomes 0/FALSE/''."""
    if fill != 0:
        raise rtm.ExecutionError(f"MEMSET with the fill value {fill}: plcpred models only "
                                 "clearing to 0", *where)
    _replace(dest, _zero(_deref(dest, "MEMSET", where)))
    return n


def _memcmp(a, b, n, *where):
    """MEMCMP of whole values: 0 when equal, else 1."""
    va, vb = _deref(a, "MEMCMP", where), _deref(b, "MEMCMP", where)
    return 0 if _snap_any(va, {}) == _snap_any(vb, {}) else 1


def _sizeof(v):
    return 1 if isinstance(v, bool) else 8


# The only builtins generated code may use: what the compiler emits (conversions, MIN/MAX,
# ABS, LEN, array construction, snapshots) and what a class statement needs. No import,
# open, eval, getattr or exec: a name in a program file that somehow reached the source
# could not reach the host through them.
_BUILTINS = {name: getattr(builtins, name) for name in (
    "__build_class__", "abs", "float", "int", "len", "max", "min", "range", "set", "tuple")}


def program_namespace(timers: list, sfcs: list) -> dict:
    """The globals generated program code runs in: the restricted builtins and the
    runtime helpers the compiler emits calls to, nothing else. Standard timers the
    program creates are appended to ``timers`` (the executor schedules their expiries)
    and SFC runtimes to ``sfcs``."""
    listing = [True]

    def _stdfb(name):
        fb = make_standard_fb(name)
        if isinstance(fb, _TIMERS) and listing[0]:
            timers.append(fb)
        return fb

    def _unlisted(make):
        """Build a function's or method's local instances without listing their timers
        (they live for one call, so they can schedule nothing)."""
        listing[0] = False
        try:
            return make()
        finally:
            listing[0] = True

    return {
        "__builtins__": _BUILTINS, "__name__": "plcpred_program",
        "k_FbBase": FbBase, "_SfcRuntime": SfcRuntime, "_SfcSpec": SfcSpec,
        "_ActionSpec": ActionSpec, "_register": sfcs.append, "_stdfb": _stdfb,
        "_unlisted": _unlisted,
        "_setattrs": _setattrs, "_nest": _nest, "_copy": _copy, "_snap_any": _snap_any,
        "_refkey": _refkey, "_for_range": _for_range, "_watchdog": _watchdog,
        "_work": [0],
        "_plc_exceptions": rtm.PLC_EXCEPTIONS, "_exception_code": rtm.exception_code,
        "_opaque": _opaque, "_memcpy": _memcpy, "_memset": _memset, "_memcmp": _memcmp,
        "_chkidx": rtm.check_index, "_getbit": rtm.getbit, "_setbit": rtm.setbit,
        "_wrap": rtm.wrap, "_idiv": rtm.idiv, "_imod": rtm.imod, "_fdiv": rtm.fdiv,
        "_fmod": math.fmod, "_tmul": rtm.tmul, "_tdiv": rtm.tdiv,
        "_expt": rtm.expt, "_limit": rtm.limit, "_sel": rtm.sel, "_mux": rtm.mux,
        "_shl": rtm.shl, "_shr": rtm.shr, "_rol": rtm.rol, "_ror": rtm.ror,
        "_math": rtm.MATH, "_to_int": rtm.to_int, "_to_real": rtm.to_real,
        "_to_time": rtm.to_time, "_to_bool": rtm.to_bool, "_to_string": rtm.to_string,
        "_left": rtm.left, "_right": rtm.right, "_mid": rtm.mid, "_insert": rtm.insert,
        "_delete": rtm.delete, "_replace": rtm.replace, "_find": rtm.find,
        "_Ref": rtm.Ref, "_ItemRef": rtm.ItemRef, "_Box": rtm.Box, "_dflt": object(),
        "_sizeof": _sizeof, "_now": 0, "_g": None,
    }


def _numbered_from(code, first: int):
    """``code`` (and the functions and classes it defines) with its line numbers
    ``first`` further on: a code object's lines count from its own first line."""
    consts = tuple(_numbered_from(c, first) if isinstance(c, type(code)) else c
                   for c in code.co_consts)
    return code.replace(co_firstlineno=code.co_firstlineno + first, co_consts=consts)


class ProgramInstance:
    """A compiled project, instantiated: its PROGRAM instances, globals and timers."""

    def __init__(self, program: ir.Program, compiled: Compiled | None = None):
        self.compiled = compiled or compile_program(program)
        self.filename = f"<plcpred {self._file(program)}>"
        self.timers: list = []
        self.sfcs: list = []
        self.ns = program_namespace(self.timers, self.sfcs)
        lines = self.compiled.source.split("\n")
        starts = self.compiled.pieces
        for a, b in zip(starts, starts[1:] + (len(lines),)):
            # piece by piece: Python holds a whole compilation's syntax tree and code at
            # once, many times the text (one of 200,000 statements took 1.6 GB)
            exec(self._compiled_piece(lines, a, b, program), self.ns)
        self._work = self.ns["_work"]    # loop passes in this scan (the watchdog's count)
        self.programs = self.guard(self.ns["_build"])
        self.g = self.ns["_g"]
        self.names = [n for n, _ in self.compiled.programs]
        self._bodies = [p._body for p in self.programs]
        self.every = None

    def _compiled_piece(self, lines: list[str], a: int, b: int, program):
        """Lines ``a`` to ``b`` of the generated source compiled, numbered as in the whole
        source (run-time errors find their program position by it)."""
        try:
            return _numbered_from(compile("\n".join(lines[a:b]) + "\n", self.filename,
                                          "exec"), a)
        except (SyntaxError, RecursionError, MemoryError) as e:
            # Python's own limits (nested parentheses, indentation, nested blocks): the
            # name gate's nesting limits keep programs below them; this names the place
            # should one still be reached
            line = getattr(e, "lineno", None)
            line = line + a if line else a + 1
            pos = self.compiled.line_pos[line - 1] if 0 < line <= len(
                self.compiled.line_pos) else None
            where = (pos.file, pos.line, pos.col) if pos else (self._file(program), 0, 0)
            if isinstance(e, MemoryError):
                raise CompileError("this program is too large for the executor to compile "
                                   "(Python ran out of memory); split its longest bodies "
                                   "into functions or function blocks", *where) from None
            raise CompileError("this statement is nested too deeply for the executor "
                               f"({getattr(e, 'msg', None) or type(e).__name__}); split it "
                               "with intermediate variables", *where) from None

    @staticmethod
    def _file(program) -> str:
        for p in program.pous:
            if p.pos is not None:
                return p.pos.file
        return "program"

    def set_scan(self, scan_ns: int) -> None:
        """Run each PROGRAM every k-th scan, k = its task's INTERVAL / the scan time
        (rounded, at least 1); programs without an interval run every scan."""
        iv = self.compiled.intervals or {}
        self.every = [max(1, round(iv[n] / scan_ns)) if n in iv else 1 for n in self.names]
        self.scan_ns = scan_ns
        self.ran_at = [-1] * len(self.names)
        self.quiet_scans = 0
        self._k = -1
        if all(k == 1 for k in self.every):
            self.every = None

    def settle_over_all_phases(self) -> None:
        """A fixed point must hold through every combination of the tasks' phases: the
        program writes an input the input image writes again before every scan, and a
        scan in which its task does not run shows the image's value, not the program's
        (a state that holds at the task's scans may change at the others)."""
        if self.every is not None:
            self.quiet_scans = math.lcm(*self.every)

    def scan(self, now_ns: int) -> None:
        self.ns["_now"] = now_ns
        self._work[0] = 0
        if self.every is None:
            for body in self._bodies:
                body()
            return
        k = self._k = now_ns // self.scan_ns
        for i, body in enumerate(self._bodies):
            if k % self.every[i] == 0:
                body()
                self.ran_at[i] = k

    def all_ran_since(self, k_change: int) -> bool:
        """Every program has run after scan ``k_change`` (a state change), and where it
        must (:meth:`settle_over_all_phases`) every phase of the tasks has passed since:
        only then can an unchanged state be a fixed point."""
        return self.every is None or (all(r > k_change for r in self.ran_at)
                                      and self._k - k_change >= self.quiet_scans)

    def last_run_by_all_ns(self) -> int:
        """The last scan time by which every program has run (NEVER without tasks: all
        of them run at every scan, the last one included)."""
        if self.every is None:
            return NEVER
        return min(self.ran_at) * self.scan_ns

    def phase(self, now_ns: int):
        if self.every is None:
            return ()
        k = now_ns // self.scan_ns
        return tuple(k % e for e in self.every)

    def guard(self, fn, *args):
        """Run compiled code, turning Python exceptions into positioned errors."""
        try:
            return fn(*args)
        except rtm.ExecutionError:
            raise
        except Exception as e:
            raise self.positioned(e) from None

    def positioned(self, e: BaseException) -> rtm.ExecutionError:
        """A Python exception raised by compiled code, as an error at its source line."""
        pos = self._position(e.__traceback__)
        msg = str(e) or type(e).__name__
        if isinstance(e, AttributeError) and rtm.null_access(e):
            msg = "a pointer, reference or interface variable is not set (NULL)"
        if isinstance(e, RecursionError):
            msg = "recursion: a POU calls itself"
        return rtm.ExecutionError(f"run-time error: {msg}", *pos)

    def _position(self, tb):
        found = None
        while tb is not None:
            if tb.tb_frame.f_code.co_filename == self.filename:
                found = tb.tb_lineno
            tb = tb.tb_next
        if found is not None:
            p = self.compiled.line_pos[found - 1] if found - 1 < len(
                self.compiled.line_pos) else None
            if p is not None:
                return (p.file, p.line, p.col)
        return ("", 0, 0)

    def snap(self, rel=None) -> tuple:
        return (self.g._snap(rel),) + tuple(p._snap(rel) for p in self.programs)

    # ------------------------------------------------------------------ variables
    def locate(self, name: str):
        """(object, attribute, type) of a program-level or global variable."""
        key = name.upper()
        hits = []
        for inst, prog in zip(self.names, self.programs):
            fbt = self.compiled.program_types[inst]
            if "." in key and key.split(".", 1)[0] == inst.upper():
                sub = key.split(".", 1)[1]
                d = fbt.var(sub)
                if d is not None:
                    return prog, sub, self.compiled.types.resolve(d.type, d.pos)
            d = fbt.var(key)
            if d is not None and not any(b.kind == "VAR_EXTERNAL" and any(d is x for x in b.decls)
                                         for t in fbt.chain() for b in t.pou.var_blocks):
                hits.append((prog, key, self.compiled.types.resolve(d.type, d.pos)))
        if key in self.compiled.globals_types:
            hits.append((self.g, key, self.compiled.globals_types[key][1]))
        if not hits:
            return None
        return hits[0]


# ---------------------------------------------------------------------- inputs

class Schedule:
    """The edges one scheduled input goes through, (time_ns, value) in time order,
    generated a block of pulses at a time: a short period over a long horizon costs
    memory for one block, not for every pulse. Jittered pulses draw from the seeded
    generator in the same order whatever the block size, so runs repeat exactly."""

    BLOCK = 4096

    def __init__(self, spec, horizon_ns: int):
        self.spec = spec
        base = bool(spec.initial)
        self.initial = base
        self.value = base
        self.random = spec.jitter_s > 0
        self._pulse_ns = round(spec.pulse_ms * 1e6)
        self._last_end = -1
        self._next = 0  # index of the next pulse to generate
        if spec.period_s is not None:
            self.period_ns = round(spec.period_s * NS)
            self._offset_ns = round(spec.offset_s * NS)
            span = horizon_ns - self._offset_ns
            self._count = max(0, span // self.period_ns + 2) if span >= 0 else 0
            # uniform in +-jitter_s; without a seed, seed 0, so runs repeat exactly
            self._rng = np.random.default_rng(spec.seed if spec.seed is not None else 0) \
                if self.random else None
            self._pulses = None
        else:
            self.period_ns = None
            self._pulses = np.array([round(p * NS) for p in spec.pulses_s], dtype=np.int64)
            self._count = len(self._pulses)
        self.times: list = []
        self.values: list = []
        self.log: list | None = None    # the edges consumed, while a part is recorded
        self.k = 0
        self.first_ns = None
        self._fill()
        if self.times:
            self.first_ns = self.times[0]
            if self.period_ns is not None and not self.random:
                self.first_ns = max(self._offset_ns, 0)

    def _fill(self) -> bool:
        """Generate the next block of pulses; False when there are no more."""
        if self._next >= self._count:
            return False
        n = min(self.BLOCK, self._count - self._next)
        if self._pulses is not None:
            starts = self._pulses[self._next:self._next + n]
        else:
            k = np.arange(self._next, self._next + n, dtype=np.int64)
            starts = self._offset_ns + k * self.period_ns
            if self._rng is not None:
                starts = starts + self._rng.uniform(-self.spec.jitter_s, self.spec.jitter_s,
                                                    n) * NS
            starts = np.maximum(np.round(starts), 0).astype(np.int64)
        self._next += n
        times, values = [], []
        base, pulse_ns, last_end = self.initial, self._pulse_ns, self._last_end
        for st in starts.tolist():
            st = max(st, last_end)
            times += [st, st + pulse_ns]
            values += [not base, base]
            last_end = st + pulse_ns
        self._last_end = last_end
        self.times, self.values, self.k = times, values, 0
        return True

    def advance(self, t_ns: int) -> bool:
        while True:
            times, k = self.times, self.k
            while k < len(times) and times[k] <= t_ns:
                self.value = self.values[k]
                if self.log is not None:
                    self.log.append((times[k], self.values[k]))
                k += 1
            self.k = k
            if k < len(times) or not self._fill():
                return self.value

    def next_ns(self):
        if self.k >= len(self.times) and not self._fill():
            return None
        return self.times[self.k]

    def upcoming(self, until_ns: int):
        """The edges not yet consumed up to ``until_ns`` as (time, value), or None when
        they run past the block generated so far (the caller then does not look ahead)."""
        times, k = self.times, self.k
        out = []
        while k < len(times) and times[k] <= until_ns:
            out.append((times[k], self.values[k]))
            k += 1
        if k >= len(times) and self._next < self._count:
            return None
        return out

    def key(self, t_ns: int):
        """Phase of a periodic schedule; None when the future is not periodic."""
        if self.random:
            return None
        done = self.k >= len(self.times) and self._next >= self._count
        if self.period_ns is None or self.first_ns is None:
            return ("done", self.value) if done else None
        if t_ns < self.first_ns:
            return ("before", self.first_ns - t_ns)
        return ("phase", (t_ns - self.first_ns) % self.period_ns, self.value)


class Cylinder:
    """A cylinder of the machine file driving its end switches."""

    def __init__(self, consumer, valve_slots, switch_slots, plant=None):
        self.name = consumer.name
        if plant is None:
            st = consumer.stroke_times()
            plant = CylinderPlant(round(st[0] * NS), round(st[1] * NS),
                                  round(consumer.switch_delay_s * NS),
                                  consumer.initial == "extended")
        self.plant = plant
        self.valves = valve_slots       # [(obj, attr)]
        self.switches = switch_slots    # {"retracted"|"extended": (obj, attr)}
        self.prev = [False] * len(valve_slots)
        self.bistable = len(valve_slots) == 2
        self._until = -1                # switch values below are valid before this time
        self._from = 0
        self._values = (True, False)
        self.driven = None              # the values last written to the program
        self._rest_key = None           # state_key while at rest, until the next command

    def state_key(self, t_ns: int) -> tuple:
        """The motion from ``t_ns`` on and the valve's last outputs (for tiling); a
        cylinder at rest keeps its key until it is commanded again."""
        if self._rest_key is not None:
            return self._rest_key
        motion = self.plant.key(t_ns)
        key = (motion, tuple(self.prev))
        if len(motion) == 3 and motion[2] == 0:   # at rest, nothing planned
            self._rest_key = key
        return key

    def command(self, t_ns: int) -> None:
        self._rest_key = None
        if not self.bistable:
            o, a = self.valves[0]
            ext = bool(getattr(o, a))
            self.prev[0] = ext
            if ext == self.plant.extend_cmd:
                return False
        else:
            sol = [bool(getattr(o, a)) for o, a in self.valves]
            rising = [x and not p for x, p in zip(sol, self.prev)]
            self.prev = sol
            ext = valve_command(sol, self.plant.extend_cmd, rising)
            if ext == self.plant.extend_cmd:
                return False
        self.plant.forget_before(t_ns)
        self.plant.command(t_ns, ext)
        self._until = -1
        return True

    def read(self, t_ns: int) -> tuple[bool, bool]:
        """(retracted, extended) switch values at ``t_ns`` (times only move forward)."""
        if self._from <= t_ns < self._until:
            return self._values
        plant = self.plant
        self._values = plant.switches(t_ns)
        self._from = t_ns
        nxt = plant.next_event_ns(t_ns)
        self._until = nxt if nxt is not None else NEVER
        return self._values

    def next_event_ns(self, t_ns: int):
        self.read(t_ns)
        return self._until if self._until < NEVER else None


# ---------------------------------------------------------------------- a run's state

class _InputImage:
    """The inputs a run drives, written at the start of every scan: each schedule's
    signal, then each cylinder's switches, at fixed places of one list that one
    generated setter writes; and the cylinders' valve outputs, which command them."""

    def __init__(self, schedules, cylinders, written):
        self.schedules = schedules
        self.cylinders = cylinders
        slots = [(obj, attr) for _, obj, attr in schedules]
        self.switch_at = []         # per cylinder: (retracted, extended) place or -1
        for cyl in cylinders:
            at = []
            for role in ("retracted", "extended"):
                at.append(len(slots) if role in cyl.switches else -1)
                if role in cyl.switches:
                    slots.append(cyl.switches[role])
            self.switch_at.append(tuple(at))
        self.drive = [False] * len(slots)
        self.live = list(range(len(schedules)))     # the schedules with edges to come
        self.write = _value_setter(slots)
        # inputs the program never writes keep what was written: the image is written
        # again only when it changed (else every scan, as a PLC does)
        self.rewrite = written is None or any(_root_slot(obj, attr)[1].upper() in written
                                              for obj, attr in slots)
        self.stale = True
        # when each cylinder's switches change next (a heap of (time, cylinder), stale
        # entries left in it until they surface: ``due`` holds the live time of each),
        # and the cylinders whose switches must be read again at the next input update
        self.switch_queue: list = []
        self.due = [NEVER] * len(cylinders)
        self.unread = set(range(len(cylinders)))
        # every cylinder's valve outputs read in one go after a scan: only cylinders
        # whose outputs changed are commanded (all of them after the first scan)
        valve_slots, self.valve_owner = [], []
        for k, cyl in enumerate(cylinders):
            valve_slots += cyl.valves
            self.valve_owner += [k] * len(cyl.valves)
        self.valves_now = _value_getter(valve_slots)

    def update(self, t) -> int:
        """Input values at ``t`` and the first time any of them can change: only the
        cylinders whose switches are due (or were commanded) are read again."""
        drive, switch_queue, due, unread = self.drive, self.switch_queue, self.due, self.unread
        nxt = NEVER
        self.stale = True
        ended = None
        schedules = self.schedules
        for j in self.live:
            sch = schedules[j][0]
            drive[j] = sch.advance(t)
            e = sch.next_ns()
            if e is None:
                ended = [j] if ended is None else ended + [j]
            elif e < nxt:
                nxt = e
        if ended:       # held, or past their last edge: their value stays what it is
            self.live = [j for j in self.live if j not in ended]
        while switch_queue and switch_queue[0][0] <= t:
            u, k = heappop(switch_queue)
            if u == due[k]:
                unread.add(k)
        for k in unread:
            cyl = self.cylinders[k]
            r, e = cyl.driven = cyl.read(t)
            i_r, i_e = self.switch_at[k]
            if i_r >= 0:
                drive[i_r] = r
            if i_e >= 0:
                drive[i_e] = e
            due[k] = cyl._until
            if cyl._until < NEVER:
                heappush(switch_queue, (cyl._until, k))
        unread.clear()
        while switch_queue and switch_queue[0][0] != due[switch_queue[0][1]]:
            heappop(switch_queue)
        if switch_queue and switch_queue[0][0] < nxt:
            nxt = switch_queue[0][0]
        return nxt

    def command(self, t, valves, before, next_input) -> int:
        """The cylinders whose valve outputs changed since ``before`` (all of them after
        the first scan) follow them; the time the inputs must be driven again."""
        if before is None:
            commanded = range(len(self.cylinders))
        else:
            commanded = sorted({self.valve_owner[i] for i in _changed(valves, before)})
        for k in commanded:
            cyl = self.cylinders[k]
            if cyl.command(t):
                # the switches change now (no switching delay) or at their next edge;
                # until then the inputs driven now stay valid
                self.unread.add(k)
                if cyl.read(t) != cyl.driven:
                    next_input = t
                elif cyl._until < next_input:
                    next_input = cyl._until
        return next_input


class _Recorder:
    """The changes of the recorded signals, in typed arrays (8 bytes a change instead of
    a Python object, up to ``max_events`` of them)."""

    def __init__(self, signals, max_events: int, scan: int):
        self.signals = signals
        self.max_events = max_events
        self.scan = scan
        self.tt, self.ss, self.vv = array("q"), array("i"), array("d")
        # replayed parts kept by reference: where each replay lies among the executed
        # changes, its start, which part (``parts``: times from the start, signals, values)
        self.at, self.start, self.pid = array("i"), array("q"), array("i")
        self.parts: list = []
        # the replays of a long run go to an unnamed temporary file a block at a time
        # (16 bytes each: a year of a part every 4 s would hold 126 MB), all but the
        # last few, which a part being recorded may still hold
        self.spill = None
        self.spilled = 0

    @property
    def n_replays(self) -> int:
        return self.spilled + len(self.at)

    def replayed(self, t_s: int, pid: int) -> None:
        self.at.append(len(self.tt))
        self.start.append(t_s)
        self.pid.append(pid)
        if len(self.at) >= SPILL_REPLAYS:
            self._spill(len(self.at) - KEEP_REPLAYS)

    def _spill(self, n: int) -> None:
        if self.spill is None:
            # lives as long as the timeline reading it (unnamed: gone with the process)
            self.spill = tempfile.TemporaryFile(prefix="plcpred-replays-")  # noqa: SIM115
        block = np.empty(n, dtype=_REPLAY)
        block["at"], block["start"], block["pid"] = (self.at[:n], self.start[:n],
                                                     self.pid[:n])
        self.spill.write(block.tobytes())
        del self.at[:n], self.start[:n], self.pid[:n]
        self.spilled += n

    def since(self, i0: int, a0: int):
        """(times, signals, values) of the changes from executed change ``i0`` and
        replay ``a0`` on, in time order (a part that held replays of others); None when
        those replays were spilled already (the part is too long to record)."""
        if a0 < self.spilled:
            return None
        a0 -= self.spilled
        t = np.frombuffer(self.tt, dtype=np.int64)[i0:]
        s = np.frombuffer(self.ss, dtype=np.int32)[i0:]
        v = np.frombuffer(self.vv, dtype=np.float64)[i0:]
        if len(self.at) == a0:
            return t.copy(), s.copy(), v.copy()
        out, done = [], 0
        for p, st, k in zip(self.at[a0:], self.start[a0:], self.pid[a0:]):
            p -= i0
            out.append((t[done:p], s[done:p], v[done:p]))
            done = p
            pt, ps, pv = self.parts[k]
            out.append((pt + st, ps, pv))
        out.append((t[done:], s[done:], v[done:]))
        return tuple(np.concatenate([o[j] for o in out]) for j in range(3))

    def replays(self):
        """The replays as :class:`Timeline` takes them (spilled ones mapped from their
        file, read as they are needed), or None."""
        if not self.n_replays:
            return None
        if self.spill is None:
            return (np.frombuffer(self.at, dtype=np.int32),
                    np.frombuffer(self.start, dtype=np.int64),
                    np.frombuffer(self.pid, dtype=np.int32), self.parts)
        self._spill(len(self.at))
        self.spill.flush()
        return tuple(SpilledColumn(self.spill, _REPLAY, name, self.spilled)
                     for name in ("at", "start", "pid")) + (self.parts,)

    def record(self, t, values, before):
        """The signals that changed since ``before`` (all of them at the first scan)."""
        if before is None:
            changed = range(len(values))
        else:
            changed = _changed(values, before)
        tt = self.tt
        tt.extend([t] * len(changed))
        self.ss.extend(changed)
        self.vv.extend([float(values[k]) for k in changed])
        if len(tt) > self.max_events:
            raise self.too_many(t)

    def too_many(self, t) -> SequencerError:
        """The error of a run that holds more than ``max_events`` changes at ``t``."""
        return SequencerError(_too_many_changes(self.signals, self.ss, t, self.scan,
                                                self.max_events))


class _Variants:
    """The parts recorded from one rest state, each (edges, duration, changes' times,
    signals and values, shown values at start and end, part id), found by the scheduled
    edges ahead: a part matches when its edges are those ahead up to its end, so the
    edges ahead up to the longest part, taken prefix by prefix in time order, name every
    part that can match. Independent inputs (a part sensor and a metal sensor jittered
    each on its own) give a rest state hundreds of responses; each costs a look-up per
    edge ahead, not a comparison per part."""
    __slots__ = ("by_edges", "changes", "items", "longest", "sizes")

    def __init__(self):
        self.items: list = []
        self.by_edges: dict = {}    # edges -> indices into items
        self.sizes: list = []       # how many edges the parts hold, ascending
        self.longest = 0
        self.changes = 0

    def __len__(self) -> int:
        return len(self.items)

    def has_room(self) -> bool:
        return len(self.items) < FEW_PART_VARIANTS or (
            len(self.items) < MAX_PART_VARIANTS and self.changes < MAX_PART_CHANGES)

    def add(self, part: tuple) -> None:
        self.by_edges.setdefault(part[0], []).append(len(self.items))
        if len(part[0]) not in self.sizes:
            self.sizes = sorted(self.sizes + [len(part[0])])
        self.items.append(part)
        self.longest = max(self.longest, part[1])
        self.changes += len(part[2])

    def matching(self, live_idx, live, t_s: int, scan: int, horizon_ns: int):
        """The indices, in the order recorded, of the parts ending by ``horizon_ns``
        whose edges (as :meth:`Sequencer._edges_seen` gives them) are the scheduled
        edges from scan ``t_s`` to their end; None when the schedules have not generated
        their edges that far (each part is then compared on its own)."""
        until = t_s + self.longest
        ahead = []
        for j, sch in zip(live_idx, live):
            edges = sch.upcoming(until)
            if edges is None:
                return None
            ahead += [(e, j, -(-e // scan) * scan - t_s, v) for e, v in edges]
        ahead.sort()
        # a part that rested long holds thousands of edges: only prefixes as long as a
        # recorded part's edges are looked up
        del ahead[self.sizes[-1] + 1:]
        hits = []
        n = len(ahead)
        for i in self.sizes:
            # edges at one instant are all before a part's end or none is
            if i > n or 0 < i < n and ahead[i][0] == ahead[i - 1][0]:
                continue
            found = self.by_edges.get(tuple(sorted(x[1:] for x in ahead[:i])))
            if not found:
                continue
            # the part ends at or after the last of these edges, before the next one
            lo = t_s if i == 0 else ahead[i - 1][0]
            hi = horizon_ns if i == n else min(horizon_ns, ahead[i][0] - 1)
            hits += [k for k in found if lo <= t_s + self.items[k][1] <= hi]
        hits.sort()
        return hits


@dataclass
class _Repeats:
    """What a run remembers at fixed points to find a repeating state (tiling) or a
    part it can replay."""
    seen: dict = field(default_factory=dict)        # state digest -> its time
    seen_values: set = field(default_factory=set)   # hashes of the recorded values
    parts: dict = field(default_factory=dict)  # rest key -> _Variants
    opened: dict = field(default_factory=dict)  # rest key -> (first scan, first change, ...)
    timeless: set = field(default_factory=set)  # rest keys that hold no time


@dataclass(eq=False, slots=True)
class _Run:
    """One run's state, handed from step to step of :meth:`Sequencer.run`."""
    inst: ProgramInstance
    horizon_ns: int
    scan: int
    image: _InputImage
    rec: _Recorder
    values_now: object          # gives the recorded signals' values, as one tuple
    left: _LeftOut
    always_step: bool           # every scan executed (scan stepping, or TIME() read)
    can_tile: bool
    can_replay: bool
    slots: list = field(default_factory=list)   # the recorded signals' (object, attribute)
    # the compared state and the cylinders in it: the whole machine's, or one island's
    # (a run of the islands' own, :meth:`Sequencer._run_islands`)
    snap: object = None
    own_cylinders: list | None = None
    own_timers: list | None = None
    scan_loop: tuple = field(init=False, default=())
    repeats: _Repeats = field(default_factory=_Repeats)
    t: int = 0
    scans: int = 0
    next_input: int = 0         # the first time a driven input can change
    k_change: int = 0           # the scan at which the state last changed
    prev_snap: tuple | None = None
    prev_values: tuple | None = None
    prev_valves: tuple | None = None
    values: tuple | None = None     # the recorded signals' values at the last scan
    tiled_from: tuple | None = None
    drift: dict | None = None
    # a scan that took an input change (a schedule's edge or an end switch) and is no
    # fixed point: a busy machine (stations whose cycles overlap never rest all at
    # once) is checked for a repeat there
    probe: bool = False

    def __post_init__(self):
        # what the per-scan loop (Sequencer._scan_to_rest) reads, bound once a run: the
        # loop starts again after every fixed point
        image, inst = self.image, self.inst
        if self.snap is None:
            self.snap = inst.snap
        if self.own_cylinders is None:
            self.own_cylinders = image.cylinders
        if self.own_timers is None:
            self.own_timers = inst.timers
        self.scan_loop = (image, self.scan, self.horizon_ns, self.always_step, image.update,
                          image.write, image.drive, image.rewrite, image.valves_now,
                          self.values_now, self.rec.record, inst.scan, self.snap,
                          inst.all_ran_since)


# ---------------------------------------------------------------------- the executor

class Sequencer:
    """Run a program against a machine's plant I/O model.

    ``machine`` may be None (a bare program: inputs hold their declared initial values).
    ``plant`` replaces the piecewise-linear cylinder model: an object whose
    ``adapter(consumer)`` gives, for every consumer with a valve, something with
    :class:`CylinderPlant`'s ``extend_cmd``, ``command``, ``switches``, ``next_event_ns``
    and ``forget_before`` (the physics plant of ``plcpred.plant``). Runs with it do not tile.
    """

    def __init__(self, program: ir.Program, machine=None, scan_ms: float | None = None,
                 compiled: Compiled | None = None, plant=None):
        self.program = program
        self.machine = machine
        self.plant_model = plant
        self.scan_ns = round((scan_ms if scan_ms is not None else
                              (machine.scan_ms if machine is not None else 10.0)) * 1e6)
        if self.scan_ns <= 0:
            raise SequencerError("the scan time must be positive")
        observed = observed_names(machine, program)
        if compiled is None or not observed <= compiled.observed:
            # a program compiled for another machine (or none) may have left out of its
            # compared state a variable this machine file reads
            compiled = compile_program(program, observed | (
                compiled.observed if compiled is not None else frozenset()))
        self.compiled = compiled
        self._found: dict = {}      # signal -> how _locate found it

    # ------------------------------------------------------------------ setup
    def _signals(self, inst: ProgramInstance):
        """(inputs, outputs) as lists of (name, obj, attr, type)."""
        c = self.compiled
        ins, outs, seen = [], [], set()
        self.signal_names = {}  # machine file signal -> timeline name

        def add(lst, name, hit):
            obj, attr, t = hit
            # one signal per variable, however often and however spelt it is named
            # (aSw[1,2] and aSw[1, 2] are one element)
            k = (id(obj.items), obj.k) if isinstance(obj, ItemView) else \
                (id(obj.obj), obj.attr, obj.mask) if isinstance(obj, BitView) else \
                (id(obj), attr)
            if k in seen:
                return
            seen.add(k)
            lst.append((name, obj, attr, t))

        multi = len(inst.programs) > 1
        hidden = {attr: addr for addr, attr in (c.address_slots or {}).items()}
        for gname, (n, t, d) in c.globals_types.items():
            n = hidden.get(gname, n)
            if d.address and d.address.upper().startswith("%I"):
                add(ins, n, (inst.g, gname, t))
            elif d.address and d.address.upper().startswith("%Q"):
                add(outs, n, (inst.g, gname, t))
        for name, prog in zip(inst.names, inst.programs):
            fbt = c.program_types[name]
            for b in fbt.pou.var_blocks:
                for d in b.decls:
                    if b.kind == "VAR_EXTERNAL":
                        continue
                    addr = (d.address or "").upper()
                    label = f"{name}.{d.name}" if multi else d.name
                    t = c.types.resolve(d.type, d.pos)
                    if t.cat not in ("bool", "int", "real", "time"):
                        continue
                    if b.kind == "VAR_INPUT" or addr.startswith("%I"):
                        add(ins, label, (prog, d.name.upper(), t))
                    elif b.kind == "VAR_OUTPUT" or addr.startswith("%Q"):
                        add(outs, label, (prog, d.name.upper(), t))
        if self.machine is not None:
            for s in self._machine_inputs():
                hit = self._locate(inst, s)
                self.signal_names[s] = self._display(inst, s, hit)
                add(ins, self.signal_names[s], hit)
            recorded = [v for cons in self.machine.consumers for v in cons.valve]
            if self.machine.cycle_signal:
                recorded.append(self.machine.cycle_signal)   # counted per cycle
            for v in recorded:
                hit = self._locate(inst, v)
                self.signal_names[v] = self._display(inst, v, hit)
                add(outs, self.signal_names[v], hit)
        return ins, outs

    def _display(self, inst, signal, hit):
        obj, attr, t = hit
        if obj is inst.g:
            for addr, slot in (inst.compiled.address_slots or {}).items():
                if slot == attr:
                    return addr
            return inst.compiled.globals_types[attr][0]
        return "".join(self._resolve(signal).split())    # aSw[1, 2] shown as aSw[1,2]

    def _machine_inputs(self):
        names = [s.signal for s in self.machine.inputs]
        for cons in self.machine.consumers:
            names += list(cons.switches.values())
        return names

    def _resolve(self, signal: str) -> str:
        return resolve_signal(self.machine, self.program, signal)

    def _locate(self, inst, signal):
        """(object, attribute, type) of a machine file's signal in instance ``inst``; how
        it was found is kept, so that the next instance (each island's run makes one)
        follows it without parsing and resolving the path again."""
        found = self._found.get(signal)
        if found is not None:
            return _follow(inst, *found)
        name = self._resolve(signal)
        hit = inst.locate(name)
        slot = (self.compiled.address_slots or {}).get(name.upper())
        if hit is None and slot is not None:
            hit = (inst.g, slot, self.compiled.globals_types[slot][1])
        steps = []
        try:
            if hit is None:
                hit = self._locate_path(inst, name, f"signal '{signal}'", steps)
            if hit is None:
                raise SequencerError(f"signal '{signal}' is not a variable of the program")
        except SequencerError as e:
            if self.machine is None:
                raise
            # a name in the machine file the program does not have: the file's mistake
            # (exit 2, as every machine-file error), named by the table that gives it
            raise MachineError(str(self.machine.path), _naming_table(self.machine, signal),
                               str(e)) from None
        root = steps[0] if steps else hit
        owner = -1 if root[0] is inst.g else next(
            (k for k, p in enumerate(inst.programs) if p is root[0]), None)
        if owner is not None:
            self._found[signal] = ((owner,) + tuple(root[1:3]), steps[1:])
        return hit

    def _locate_path(self, inst, name: str, what: str, steps: list | None = None):
        """A signal given as a path into a variable: members (``fbCyl.q``,
        ``PRG.stCell.xOut``), array elements (``aValve[3]``, ``fbCyl[2, 1].q``) and bits of
        an integer (``wValves.3``). Each step is looked up in the declared types (no name
        from the machine file reaches generated code but a declared one); None when the
        first name is no variable."""
        name = name.strip()
        m = _PATH_ROOT.match(name)
        if m is None:
            return None
        hit, at = inst.locate(m.group(0)), m.end()
        if hit is None and m.group(0).upper() in (n.upper() for n in inst.names):
            step = _PATH_STEP.match(name, at)      # PRG.var: the program's own variable
            if step is not None and step.group(1):
                hit = inst.locate(f"{m.group(0)}.{step.group(1)}")
                at = step.end()
        if hit is None:
            return None
        root = hit[:2]
        steps = [] if steps is None else steps
        steps.append(hit)
        while at < len(name):
            step = _PATH_STEP.match(name, at)
            if step is None:
                raise SequencerError(f"{what}: cannot read '{name[at:]}' (a path is "
                                     "name.member, name[index] or name.bit)")
            at = step.end()
            obj, attr, t = hit
            member, indices, bit = step.groups()
            if bit is not None:
                if t.cat != "int" or at != len(name):
                    raise SequencerError(f"{what}: bit {bit} of something that is not an "
                                         "integer, or not at the end")
                hit = (BitView(obj, attr, int(bit)), "V", types.BOOL)
                steps.append(("bit", int(bit)))
            elif member is not None:
                hit = (getattr(obj, attr),) + self._member(t, member.upper(), what)
                steps.append(("member",) + hit[1:])
            else:
                hit = self._element(getattr(obj, attr), t, indices, root, what)
                at_ = [int(x) - lo for x, (lo, _) in zip(indices.split(","), t.dims)]
                steps.append(("element", at_, hit[2]))
        if hit[2].cat not in ("bool", "int", "real", "time"):
            raise SequencerError(f"{what} is a {hit[2].cat}, not a BOOL, number or TIME")
        return hit

    def _member(self, t, key: str, what: str) -> tuple:
        """(attribute, type) of member ``key`` of a value of type ``t``."""
        if isinstance(t, types.FbT):
            d = t.var(key)
            if d is not None:
                return ident(d.name), self.compiled.types.resolve(d.type, d.pos)
        elif isinstance(t, types.StructT):
            if key in t.members:
                return key, t.members[key]
        elif isinstance(t, types.StdFbT):
            pin, pt = stdfb_member(t, key)
            if pin:
                return pin, pt
        raise SequencerError(f"{what}: no member '{key}' in {getattr(t, 'name', t.cat)}")

    @staticmethod
    def _element(items, t, indices: str, root, what: str) -> tuple:
        """(ItemView, "V", type) of element ``indices`` ("3" or "2, 1") of an array."""
        if not isinstance(t, types.ArrayT):
            raise SequencerError(f"{what}: [{indices}] of something that is not an array")
        ks = [int(x) for x in indices.split(",")]
        if len(ks) > len(t.dims):
            raise SequencerError(f"{what}: {len(ks)} indices for an array of "
                                 f"{len(t.dims)} dimensions")
        for n, ((lo, hi), k) in enumerate(zip(t.dims, ks)):
            if not lo <= k <= hi:
                raise SequencerError(f"{what}: index {k} outside [{lo}..{hi}]")
            if n < len(ks) - 1:
                items = items[k - lo]
        rest = t.dims[len(ks):]
        return (ItemView(items, ks[-1] - t.dims[len(ks) - 1][0], root), "V",
                types.ArrayT(rest, t.elem) if rest else t.elem)

    # ------------------------------------------------------------------ run
    def run(self, horizon_ns: int, scan_stepping: bool = False,
            tiling: bool = True, max_events: int = DEFAULT_MAX_CHANGES,
            replay: bool = True, on_time=None, islands: bool = True) -> Timeline:
        """Unfold the program over ``[0, horizon_ns]`` and return the timeline. A run
        whose program keeps changing signals (more than ``max_events`` changes held in
        memory) stops with an error naming the signal that changes most.

        A run that cannot tile (jittered inputs) replays parts: when the machine is at
        rest (nothing but a scheduled input can change anything) in a state it rested in
        before, and the scheduled edges ahead fall on the same scans relative to the
        first as they did then, the recorded response up to the return to that state is
        copied instead of executed (``replay=False``: always execute). ``on_time(t_ns)``,
        if given, hears of the time the run has reached at each rest (a progress bar).

        A machine that replays and whose program splits into independent parts (islands:
        the stations of a line, each with its own part sensor, :mod:`.islands`) runs
        once per island with only that island's inputs scheduled, each repeating or
        replaying on its own, and the islands' edges merged (``islands=False``: the
        machine as a whole)."""
        wall0 = _time.perf_counter()
        r = self._start(horizon_ns, scan_stepping, tiling, max_events, replay)
        plan = self._island_plan(r) if islands and r.can_replay else None
        if plan is not None:
            return self._run_islands(plan, horizon_ns, tiling, max_events, on_time, wall0)
        self._unfold(r, on_time)
        return self._timeline(r, wall0, scan_stepping)

    def _unfold(self, r: _Run, on_time=None) -> None:
        """Scan, rest, replay or tile ``r`` to its horizon."""
        scan_to_rest, after_rest = self._scan_to_rest, self._after_rest
        try:
            while scan_to_rest(r) and after_rest(r):
                if on_time is not None:
                    on_time(r.t)
        except PlcpredError:    # ours, with its own message (the plant's among them)
            raise
        except Exception as e:  # a fault inside the compiled program
            raise r.inst.positioned(e) from None

    # ------------------------------------------------------------------ islands
    def _island_plan(self, r: _Run):
        """The island runs of ``r``'s machine: [(the schedules it drives, its cells, its
        cylinders, its signals)], or None when the program is one island, or only one
        island has inputs (the whole machine runs then)."""
        # inputs that no schedule changes and the program never writes hold one value
        written = self.compiled.written
        constant = set()
        if written is not None:
            for sch, obj, attr in r.image.schedules:
                if sch.next_ns() is None and attr.upper() not in written:
                    cell = slot_cell(r.inst, obj, attr, (ItemView, BitView))
                    if cell is not None:
                        constant.add(cell)
        part = find_islands(self.program, self.compiled, r.inst, constant)
        if part is None:
            return None
        where = SlotCells(r.inst, part, (ItemView, BitView))
        join = {}

        def find(i):
            while join.get(i, i) != i:
                i = join[i]
            return i

        def island(obj, attr):
            i = where.island(obj, attr)
            if i is None:
                raise LookupError
            return find(i)

        try:
            for cyl in r.image.cylinders:    # the plant joins a valve and its switches
                ids = {island(o, a) for o, a in cyl.valves + list(cyl.switches.values())}
                low = min(ids)
                for i in ids:
                    if i != low:
                        join[i] = low
            sched = [island(obj, attr) for _, obj, attr in r.image.schedules]
            cyls = [island(*(cyl.valves + list(cyl.switches.values()))[0])
                    for cyl in r.image.cylinders]
            sigs = [island(o, a) for o, a in r.slots]
        except LookupError:
            return None
        cells = {}
        for cell, i in part.cells.items():
            cells.setdefault(find(i), []).append(cell)
        sched = [find(j) for j in sched]
        # an island whose inputs change runs on its own; the islands no schedule changes
        # (a free-running ioniser, what never moves) run together, and repeat
        changing = [j for j, (sch, _, _) in enumerate(r.image.schedules)
                    if sch.next_ns() is not None]
        groups = [{i} for i in sorted({sched[j] for j in changing})]
        rest = set(cells) - set().union(*groups)
        if rest & {find(k) for k in sigs}:       # (islands nothing shows do not matter)
            groups.append(rest)
        if len(groups) < 2:
            return None
        runs = []
        for mine in groups:
            runs.append(([j for j in changing if sched[j] in mine],
                         [c for k in mine for c in cells[k]],
                         [j for j, k in enumerate(cyls) if find(k) in mine],
                         np.array([find(k) in mine for k in sigs], dtype=bool)))
        return runs

    def _run_islands(self, plan, horizon_ns, tiling, max_events, on_time, wall0) -> Timeline:
        """Run each island of ``plan`` on its own and merge their edges by time: within a
        scan the executor records changes in signal order, so (time, signal) sorts them
        as one run would."""
        tt, ss, vv, scans, rec, sources = [], [], [], 0, None, []
        for n, (driven, cells, cyls, mine) in enumerate(plan):
            r = self._start(horizon_ns, False, tiling, max_events, True,
                            driven=set(driven), cells=cells, cylinders=cyls)
            progress = None if on_time is None else (
                lambda t, n=n: on_time((n * horizon_ns + t) // len(plan)))
            self._unfold(r, progress)
            sources.append((self._timeline(r, wall0, False), mine))
            scans += r.scans
            rec = r.rec
        info = {"scans": scans, "scan_ms": self.scan_ns / 1e6,
                "wall_s": _time.perf_counter() - wall0, "mode": "event-driven",
                "period_s": None, "tiled_from_s": None, "islands": len(plan),
                "machine_signals": dict(self.signal_names)}
        if sum(tl.n_changes for tl, _ in sources) > min(max_events, EAGER_MERGE):
            # a long horizon: the runs are kept and merged as they are read (a signal's
            # edges come from its island's run)
            return Timeline(rec.signals, [], [], [], horizon_ns, info,
                            max_changes=max_events, sources=sources)
        for tl, mine in sources:
            keep = mine[tl.signal_idx]
            tt.append(tl.time_ns[keep])
            ss.append(tl.signal_idx[keep])
            vv.append(tl.values[keep])
        t, s, v = np.concatenate(tt), np.concatenate(ss), np.concatenate(vv)
        order = np.lexsort((s, t))
        return Timeline(rec.signals, t[order], s[order], v[order], horizon_ns, info,
                        max_changes=max_events)

    def _start(self, horizon_ns, scan_stepping, tiling, max_events, replay,
               driven=None, cells=None, cylinders=None) -> _Run:
        """The program instantiated, the machine's inputs and cylinders wired to it, the
        recorded signals chosen, and what this run may skip (tiling, replay). An island's
        run: only the schedules ``driven`` change (the others hold their initial value),
        and the compared state is that of ``cells`` and ``cylinders`` (indices)."""
        inst = ProgramInstance(self.program, self.compiled)
        ins, outs = self._signals(inst)
        schedules, all_cylinders = self._machine_io(inst, horizon_ns, driven)
        steps = []
        multi = len(inst.programs) > 1
        for name, prog in zip(inst.names, inst.programs):
            sfc = getattr(prog, "_sfc", None)
            if sfc is not None:
                for i, sname in enumerate(sfc.spec.steps):
                    steps.append((f"{name}.{sname}.X" if multi else f"{sname}.X", sfc, i))
        # initial inputs: schedules and switches (others keep their declared values)
        for sch, obj, attr in schedules:
            setattr(obj, attr, sch.initial)
        image = _InputImage(schedules, all_cylinders, self.compiled.written)
        signals = ([Signal(n, "input", t.cat) for n, _, _, t in ins]
                   + [Signal(n, "step", "bool") for n, _, _ in steps]
                   + [Signal(n, "output", t.cat) for n, _, _, t in outs])
        values_now = _value_getter([(o, a) for _, o, a, _ in ins]
                                   + [(sfc, i) for _, sfc, i in steps]
                                   + [(o, a) for _, o, a, _ in outs])
        left = _LeftOut([(o, a) for _, o, a, _ in ins] + [None] * len(steps)
                        + [(o, a) for _, o, a, _ in outs], self.compiled.left_out)
        always_step = scan_stepping or self.compiled.reads_clock
        can_tile = tiling and not scan_stepping and not self.compiled.reads_clock \
            and self.plant_model is None \
            and not any(s.random for s, _, _ in schedules)
        inst.set_scan(self.scan_ns)
        if image.rewrite:
            inst.settle_over_all_phases()
        can_replay = replay and not can_tile and not always_step \
            and self.plant_model is None and inst.every is None and bool(schedules)
        if can_replay:
            for sch, _, _ in schedules:
                sch.log = []          # the edges consumed while a part is recorded
        slots = ([(o, a) for _, o, a, _ in ins] + [(sfc, i) for _, sfc, i in steps]
                 + [(o, a) for _, o, a, _ in outs])
        snap = own = timers = None
        if cells is not None:
            # an island's run: the other islands rest (their inputs held) and what they
            # show is dropped, so only this island's state, cylinders and timers decide
            # when it rests and what it replays
            snap = island_snap(inst, cells, self.compiled.left_out or {})
            own = [all_cylinders[k] for k in cylinders]
            timers = island_timers(inst, cells)
        return _Run(inst, horizon_ns, self.scan_ns, image,
                    _Recorder(signals, max_events, self.scan_ns), values_now, left,
                    always_step, can_tile, can_replay, slots, snap, own, timers)

    def _machine_io(self, inst, horizon_ns, driven=None) -> tuple[list, list]:
        """(the machine's input schedules as (schedule, obj, attr), its cylinders); with
        ``driven``, the schedules of other indices hold their initial value."""
        machine = self.machine
        schedules, cylinders = [], []
        if machine is None:
            return schedules, cylinders
        for j, spec in enumerate(machine.inputs):
            if driven is not None and j not in driven:
                spec = dataclasses.replace(spec, pulses_s=[], period_s=None, jitter_s=0.0)
            obj, attr, _ = self._locate(inst, spec.signal)
            sch = Schedule(spec, horizon_ns)
            schedules.append((sch, obj, attr))
        for cons in machine.consumers:
            if self.plant_model is not None:
                if cons.valve:
                    cylinders.append(Cylinder(
                        cons, [self._locate(inst, v)[:2] for v in cons.valve],
                        {role: self._locate(inst, s)[:2] for role, s in
                         cons.switches.items()}, self.plant_model.adapter(cons)))
                continue
            if not cons.is_cylinder or not cons.switches:
                continue
            if cons.stroke_times() is None:
                raise SequencerError(
                    f"{machine.path}: consumer \"{cons.name}\": its switches need "
                    "stroke_time_s = [extend, retract]")
            valves = [self._locate(inst, v)[:2] for v in cons.valve]
            sw = {role: self._locate(inst, s)[:2] for role, s in cons.switches.items()}
            cylinders.append(Cylinder(cons, valves, sw))
        return schedules, cylinders

    @staticmethod
    def _scan_to_rest(r: _Run) -> bool:
        """Execute scans from ``r.t`` on: each drives the inputs, runs the programs,
        commands the cylinders whose valves changed and records the signals that did.
        True at a fixed point (the state at ``r.t`` is the one before: nothing changes
        until something time-driven does), False past the horizon."""
        # this loop runs once a scan: all it touches is a local
        (image, scan, horizon_ns, always_step, update, write, drive, rewrite, valves_now,
         values_now, record, scan_fn, snap_fn, all_ran_since) = r.scan_loop
        t, next_input, k_change, scans = r.t, r.next_input, r.k_change, r.scans
        prev_snap, prev_values, prev_valves = r.prev_snap, r.prev_values, r.prev_valves
        values, rests, probing, took_input = r.values, False, r.can_tile, False
        while t <= horizon_ns:
            if t >= next_input:
                next_input = update(t)
                took_input = probing
            if rewrite or image.stale:
                write(drive)
                image.stale = False
            scan_fn(t)
            scans += 1
            valves = valves_now()
            if valves != prev_valves:
                next_input = image.command(t, valves, prev_valves, next_input)
                prev_valves = valves
            values = values_now()
            moved = values != prev_values
            if moved:
                record(t, values, prev_values)
                prev_values = values
            if always_step:
                t += scan
                continue
            snap = snap_fn()
            # a fixed point needs the recorded signals still too: a shown count the
            # compared state leaves out may move while everything else rests
            if moved or snap != prev_snap or not all_ran_since(k_change):
                if snap != prev_snap or moved:
                    k_change = t // scan
                prev_snap = snap
                if took_input:
                    r.probe, rests = True, True     # _after_rest goes on from t + scan
                    break
                t += scan
                continue
            rests = True
            break
        r.t, r.next_input, r.k_change, r.scans = t, next_input, k_change, scans
        r.prev_snap, r.prev_values, r.prev_valves = prev_snap, prev_values, prev_valves
        r.values = values
        return rests

    def _after_rest(self, r: _Run) -> bool:
        """At a fixed point: replay a recorded part, or tile a repetition, or jump to the
        first scan at which anything can change. At a probe (a scan that took an input
        change, not a fixed point): tile a repetition, or go on with the next scan.
        False when the run ends here."""
        t, scan = r.t, r.scan
        if r.probe:
            r.probe = False
            if self._repeated(r):
                return False
            r.t = t + scan
            return True
        key = None
        while True:
            if r.next_input <= t:
                r.next_input = r.image.update(t)
            nxt, running = self._next_event(r)
            if not (r.can_replay and nxt is not None and nxt == r.next_input and not running
                    and not any(c._until < NEVER for c in r.own_cylinders)
                    and not any(sfc.next_event_ns(t) is not None for sfc in r.inst.sfcs)):
                break
            # at rest: only a scheduled input can change anything
            done, key = self._replay_at_rest(r, max(t + scan, -(-nxt // scan) * scan), key)
            if done is None:
                break
            # back at rest in the same state, at the fixed point the recorded part ended
            # in: go on from here as from that one (no scan to confirm it)
            r.t = t = done
            r.next_input = 0
        if r.can_tile and self._repeated(r):
            return False
        if nxt is None:
            return False  # nothing will ever change again
        r.t = max(t + scan, -(-nxt // scan) * scan)
        if r.inst.every is not None:
            # a task that does not run at this scan sees the event (a timer's PT, a
            # step's time) only at its next run: no fixed point until every program has
            # run from here on
            r.k_change = r.t // scan - 1
        return True

    def _next_event(self, r: _Run) -> tuple[int | None, bool]:
        """(the next time anything can change: an input edge (schedules, switches), a
        timer, a step time threshold; None for never, whether a timer runs)."""
        t = r.t
        nxt = r.next_input if r.next_input < NEVER else None
        et_thresholds = self.compiled.et_thresholds or ()
        # a timer whose PT lies in the past was not called since: it cannot change
        # until some other event makes the program call it again. Unless a slower task
        # has not run since it expired: that task calls it at its next run
        running = False
        seen_by_all = r.inst.last_run_by_all_ns()
        for tm in r.own_timers:
            e = tm.next_event_ns()
            if e is not None and e > t:
                running = True
                if nxt is None or e < nxt:
                    nxt = e
            elif e is not None and e > seen_by_all:
                nxt = t + r.scan
            if et_thresholds:
                # ET compared with constants: the comparisons flip at (or just after,
                # for strict ones) origin + constant
                o = tm.et_origin()
                if o is not None:
                    for c in et_thresholds:
                        e = o + c if o + c > t else o + c + 1
                        if e > t and (nxt is None or e < nxt):
                            nxt = e
        for sfc in r.inst.sfcs:
            e = sfc.next_event_ns(t)
            if e is not None and (e > t or e == t and sfc.spec.t_read) and (
                    nxt is None or e < nxt):
                nxt = e
        if self.compiled.reads_et and running:
            nxt = t + r.scan
        return nxt, running

    # ------------------------------------------------------------------ replay, tiling
    def _replay_at_rest(self, r: _Run, t_next: int, key=None):
        """At rest at ``r.t`` (the next scan that can change anything: ``t_next``): close
        the part recorded since this state was last left, replay one that matches the
        edges ahead, else start recording one. (The time a replayed part ends, at rest
        in the same state, and that state's key), or (None, None) when nothing was
        replayed. ``key``: the state's key when known (a part was just replayed: the
        objects are as they were before it)."""
        t, rec, left, rep = r.t, r.rec, r.left, r.repeats
        schedules = r.image.schedules
        if key is None:
            key = self._rest_key(r.snap, t, r.own_cylinders, rep.timeless, r.inst.sfcs)
        if key is not None:
            start = rep.opened.pop(key, None)
            changes = None if start is None else rec.since(*start[1])
            if changes is not None:       # back in a state a part began in
                t_s, _, at, shown_at = start
                ct, cs, cv = changes
                ct = ct - t_s
                cs, cv = cs.tobytes(), cv.tobytes()
                rec.parts.append((ct, np.frombuffer(cs, dtype=np.int32),
                                  np.frombuffer(cv, dtype=np.float64)))
                rep.parts.setdefault(key, _Variants()).add((
                    self._edges_seen([(j, sch.log[k:]) for j, ((sch, _, _), k) in
                                      enumerate(zip(schedules, at))], t_s, r.scan),
                    t - t_s, ct, cs, cv, shown_at, left.values(r.values),
                    len(rec.parts) - 1))
            # a replayed part is kept as a reference (a long run holds each part once)
            variants = rep.parts.get(key)
            done = None if variants is None else self._replay(
                variants, r.image, t_next, r.scan, r.horizon_ns, rec, left, r.values)
            if done is not None:
                if left:
                    r.prev_values = r.values = r.values_now()   # counts the part advanced
                if len(rec.tt) > rec.max_events:
                    raise rec.too_many(done)
                return done, key
            if (variants is None or variants.has_room()) \
                    and len(rep.parts) < MAX_KEYS and len(rep.opened) < MAX_OPEN_PARTS:
                rep.opened[key] = (t_next, (len(rec.tt), rec.n_replays),
                                   [len(sch.log) for sch, _, _ in
                                                         schedules], left.values(r.values))
        for k in [k for k, v in rep.opened.items() if len(rec.tt) - v[1][0] > MAX_PART_CHANGES
                  or rec.n_replays - v[1][1] > MAX_PART_REPLAYS]:
            del rep.opened[k]         # not a part that ends: stop recording it
        if not rep.opened:
            for sch, _, _ in schedules:
                sch.log.clear()
        return None, None

    def _repeated(self, r: _Run) -> bool:
        """Is the whole state at this fixed point one an earlier fixed point had (the
        run then tiles from that one, ``r.tiled_from``)?"""
        t, left, rep, values = r.t, r.left, r.repeats, r.values
        # the whole state can only repeat where the recorded signals do: its key
        # (costly on a wide machine) is made only at fixed points whose signal values
        # an earlier one had (a count shown on an output then costs nothing; a
        # repeating machine is found a period later) (a count the compared state leaves
        # out changes from one cycle to the next: the values shown without it)
        shown = hash(values if not left else left.kept(values))
        key = None
        if shown in rep.seen_values:
            key = _digest(self._state_key(r.inst, r.snap, t, r.image.schedules,
                                          r.own_cylinders))
        elif len(rep.seen_values) < MAX_KEYS:
            rep.seen_values.add(shown)
        else:
            rep.seen_values.clear()
        if key is None:
            return False
        t1 = rep.seen.get(key)
        if t1 is not None:
            drift = left.period_drift(values, t1, r.rec.tt, r.rec.ss, r.rec.vv)
            if drift is not None:
                r.tiled_from, r.drift = (t1, t), drift
                return True
        if len(rep.seen) >= MAX_KEYS:
            # start over: a machine that repeats only later (a counter past its
            # threshold) is still found if its period holds fewer than MAX_KEYS fixed
            # points
            rep.seen.clear()
        rep.seen[key] = t
        return False

    def _timeline(self, r: _Run, wall0: float, scan_stepping: bool) -> Timeline:
        """The recorded changes as a timeline, with what the run did (``info``)."""
        rec, tiled_from, scan = r.rec, r.tiled_from, r.scan
        # views of the typed arrays, not copies: nothing is added to them any more, and a
        # copy would double the peak memory of a long untiled run at its very end
        time_ns = np.frombuffer(rec.tt, dtype=np.int64)
        sig = np.frombuffer(rec.ss, dtype=np.int32)
        val = np.frombuffer(rec.vv, dtype=np.float64)
        info = {"scans": r.scans, "scan_ms": scan / 1e6,
                "wall_s": _time.perf_counter() - wall0,
                "mode": "scan-stepping" if scan_stepping else "event-driven",
                "period_s": (tiled_from[1] - tiled_from[0]) / NS if tiled_from else None,
                "tiled_from_s": tiled_from[1] / NS if tiled_from else None,
                "machine_signals": dict(self.signal_names)}
        return Timeline(rec.signals, time_ns, sig, val, r.horizon_ns, info, tiled=tiled_from,
                        max_changes=rec.max_events, drift=r.drift, replays=rec.replays())

    @staticmethod
    def _rest_key(snap, t, cylinders, timeless: set, sfcs=()):
        """The state at rest, or None when it holds a time (a finished timer's age, an
        SFC step's): replaying a part would leave that time behind. ``timeless`` holds
        the keys already found free of times (a key with a time in it differs later)."""
        def at(x):
            return snap(x), tuple((cyl.plant.key(x), tuple(cyl.prev)) for cyl in cylinders)
        for sfc in sfcs:
            sfc.rest_key = True     # step times nothing reads left out
        try:
            key = at(t)
            if key in timeless:
                return key
            if key != at(t + 1_000_003):
                return None
        finally:
            for sfc in sfcs:
                sfc.rest_key = False
        if len(timeless) < MAX_KEYS:
            timeless.add(key)
        return key

    @staticmethod
    def _edges_seen(logs, t_s: int, scan: int) -> tuple:
        """Scheduled edges as (schedule, scan that sees it relative to ``t_s``, value),
        from (schedule index, edges) pairs."""
        return tuple(sorted((j, -(-e // scan) * scan - t_s, v)
                            for j, log in logs for e, v in log))

    def _replay(self, variants: _Variants, image, t_s: int, scan: int, horizon_ns: int,
                rec, left: _LeftOut, values):
        """Copy a recorded part starting at scan ``t_s`` if the scheduled edges ahead
        match one (and the shown signals the state leaves out allow it); the time it
        ends (at rest again), or None."""
        now = left.values(values)
        # schedules past their last edge (or held) have none ahead
        live = [image.schedules[j][0] for j in image.live]
        hits = variants.matching(image.live, live, t_s, scan, horizon_ns)
        for k in range(len(variants)) if hits is None else hits:
            edges, dur, ct, cs, cv, shown_start, shown_end, pid = variants.items[k]
            end = t_s + dur
            if hits is None:
                if end > horizon_ns:
                    continue
                ahead = [(j, sch.upcoming(end)) for j, sch in zip(image.live, live)]
                if any(a is None for _, a in ahead) \
                        or self._edges_seen(ahead, t_s, scan) != edges:
                    continue
            shifted = cv
            if left:
                shifted = left.replayed(now, shown_start, shown_end, cs, cv)
                if shifted is None:
                    continue
                left.advance(now, shown_start, shown_end)
            if shifted is cv:
                rec.replayed(t_s, pid)
            else:
                # the changes as raw bytes: the typed arrays take them without a loop
                rec.tt.frombytes((ct + t_s).astype(np.int64).tobytes())
                rec.ss.frombytes(cs)
                rec.vv.frombytes(shifted)
            for sch in live:
                sch.advance(end)
            return end
        return None

    @staticmethod
    def _state_key(inst, snap, t, schedules, cylinders):
        parts = []
        for sch, _, _ in schedules:
            k = sch.key(t)
            if k is None:
                return None
            parts.append(k)
        return (snap(t), tuple(parts), tuple([cyl.state_key(t) for cyl in cylinders]),
                inst.phase(t))


def _follow(inst, root, steps):
    """Where :meth:`Sequencer._locate` found a signal, in instance ``inst``: ``root`` is
    (program index or -1 for the globals, attribute, type), then each step of a path."""
    owner, attr, t = root
    obj = inst.g if owner < 0 else inst.programs[owner]
    hit, first = (obj, attr, t), (obj, attr)
    for step in steps:
        obj, attr, t = hit
        if step[0] == "bit":
            hit = (BitView(obj, attr, step[1]), "V", types.BOOL)
        elif step[0] == "member":
            hit = (getattr(obj, attr), step[1], step[2])
        else:
            items = getattr(obj, attr)
            for k in step[1][:-1]:
                items = items[k]
            hit = (ItemView(items, step[1][-1], first), "V", step[2])
    return hit


_BIT_AT_END = re.compile(r"\.\s*\d+\s*$")


def resolve_signal(machine, program, signal: str, addresses: dict | None = None) -> str:
    """A machine file's signal as the program names it: a variable name, or a hardware
    address named in [signals] or declared with AT in the program (``addresses``: the
    program's, when the caller has them already)."""
    if machine is not None:
        for addr, name in machine.signals.items():
            if addr.upper() == signal.upper():
                return name
    if signal.startswith("%") and program is not None and hasattr(program, "pous"):
        if addresses is None:
            addresses = program_addresses(program)
        return addresses.get(signal.upper(), signal)
    return signal


def observed_names(machine, program=None) -> frozenset:
    """Every identifier in the signals ``machine`` reads or drives (valves, switches,
    inputs, the cycle signal; addresses through ``[signals]`` and the program's AT
    declarations): :func:`compile_program` keeps variables of these names in the state
    the executor compares, whatever the program does with them. A superset (``fbCyl[2].q``
    gives FBCYL and Q) costs at most a repeat found later, never a wrong timeline. A
    variable read by its bits (``wCount.2``) is also named with BIT_READ after it."""
    if machine is None:
        return frozenset()
    signals = [s.signal for s in machine.inputs]
    for cons in machine.consumers:
        signals += list(cons.valve) + list(cons.switches.values())
    if machine.cycle_signal:
        signals.append(machine.cycle_signal)
    signals += list(machine.signals.values())
    addresses = None
    if program is not None and hasattr(program, "pous") and any(
            s.startswith("%") for s in signals):
        addresses = program_addresses(program)       # once, not once per signal
    names = set()
    for s in signals:
        s = resolve_signal(machine, program, s, addresses)
        words = [w.upper() for w in _PATH_ROOT.findall(s)]
        names.update(words)
        if words and _BIT_AT_END.search(s):
            names.add(words[-1] + BIT_READ)
    return frozenset(names)


def _digest(key):
    """A fixed point's state as a 128-bit digest of its pickled form, so that the
    MAX_KEYS states remembered while looking for a repetition take 16 bytes each
    instead of a whole machine's variables (a wide program's state is kilobytes: 40 MB
    over a run that never repeats). Two states that differ share a digest with
    probability 2**-128; a state pickle cannot write is kept as it is."""
    if key is None:
        return None
    try:
        return hashlib.blake2b(pickle.dumps(key, protocol=5), digest_size=16).digest()
    except Exception:  # noqa: BLE001  (a value of a class made for the program)
        return key


_ATTR = re.compile(r"[A-Za-z_][A-Za-z0-9_]*", re.ASCII)
_PATH_ROOT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*", re.ASCII)
# .member | [i] or [i, j] | .bit
_PATH_STEP = re.compile(r"\s*(?:\.\s*([A-Za-z_][A-Za-z0-9_]*)"
                        r"|\[\s*(-?\d+(?:\s*,\s*-?\d+)*)\s*\]|\.\s*(\d+))", re.ASCII)


def _too_many_changes(signals, sig_idx, t_ns, scan_ns, limit) -> str:
    idx = np.frombuffer(sig_idx, dtype=np.int32)  # no copy of up to --max-events ints
    counts = np.bincount(idx[-100_000:], minlength=len(signals))
    worst = int(counts.argmax())
    n = int(np.count_nonzero(idx == worst))
    scans = max(1, t_ns // scan_ns)
    if n >= 0.9 * scans:
        return (f"more than {limit:,} signal changes by {t_ns / NS:g} s (--max-events): "
                f"'{signals[worst].name}' changes {n:,} times (every scan); a program that "
                "toggles an output on every scan cannot be predicted over a long horizon")
    return (f"more than {limit:,} signal changes by {t_ns / NS:g} s (--max-events): the "
            f"machine does not repeat, so every change is held in memory (about 20 bytes "
            f"each; '{signals[worst].name}' changes {n / max(t_ns / NS, 1e-9):,.2g} times/s); "
            "shorten --horizon or raise --max-events")


def _changed(values: tuple, before: tuple, chunk: int = 32) -> list[int]:
    """Indices where two equally long tuples differ. A scan changes a few of a wide
    machine's signals: slices compared in C find the chunks that hold them."""
    out = []
    for a in range(0, len(values), chunk):
        if values[a:a + chunk] != before[a:a + chunk]:
            out += [k for k in range(a, min(a + chunk, len(values)))
                    if values[k] != before[k]]
    return out


def _slot_expressions(slots) -> tuple[dict, str, list[str]]:
    """The one way slots reach generated code: each ``(object, attribute)`` becomes
    ``a<k>.<attribute>`` (``a<k>.x[<index>]`` for an SFC runtime's step flag), the
    attribute checked to be a generated (mangled) name, the object passed by name
    (``o<k>``, one per distinct object, taken into the local ``a<k>`` by the returned
    prologue: most slots are the globals' or one program's)."""
    names, parts, index = {}, [], {}
    for obj, attr in slots:
        if isinstance(obj, ItemView):
            # the element read where it lies, not through the view's property (a wide
            # machine's signals are mostly elements: 600 property calls a scan)
            k = index.setdefault(id(obj.items), len(index))
            names[f"o{k}"] = obj.items
            parts.append(f"a{k}[{int(obj.k)}]")
            continue
        if not (isinstance(attr, int) or _ATTR.fullmatch(attr)):
            raise ValueError(f"internal: slot {attr!r} is not a generated attribute name")
        k = index.setdefault(id(obj), len(index))
        names[f"o{k}"] = obj
        parts.append(f"a{k}.x[{attr}]" if isinstance(obj, SfcRuntime) else f"a{k}.{attr}")
    prologue = "".join(f"    a{k} = o{k}\n" for k in range(len(index)))
    return names, prologue, parts


def _value_getter(slots):
    """A function returning the current values of ``(object, attribute)`` slots (an SFC
    runtime with a step index reads that step's flag) as one tuple, built in one go."""
    names, prologue, parts = _slot_expressions(slots)
    src = "def values():\n" + prologue + "    return (" + "".join(
        p + ", " for p in parts) + ")\n"
    exec(src, names)
    return names["values"]


def _value_setter(slots):
    """A function writing a sequence of values to ``(object, attribute)`` slots in one
    statement (the input image of a scan)."""
    names, prologue, parts = _slot_expressions(slots)
    if not parts:
        return lambda values: None
    src = "def write(v):\n" + prologue + "    " + "".join(p + ", " for p in parts) + "= v\n"
    exec(src, names)
    return names["write"]
