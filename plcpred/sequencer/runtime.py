"""Run-time support for compiled programs: references, IEC integer arithmetic, the standard
functions and type conversions. Compiled code (:mod:`plcpred.sequencer.compiler`) calls
these by name; nothing here knows about the IR.

Values: BOOL is ``bool``, every integer and bit-string type ``int`` (wrapped to its width
at assignment), REAL/LREAL ``float``, TIME/LTIME/TOD/DATE/DT integer nanoseconds, STRING
``str``. Conversions from TIME to a number give milliseconds and back, as CODESYS,
TwinCAT and OpenPLC do.
"""
from __future__ import annotations

import math

from ..errors import PlcpredError
from ..parser.literals import format_duration


class ExecutionError(PlcpredError):
    """A run-time failure of the PLC program (division by zero, index out of range, a scan
    that does not finish), positioned at the source line when known."""

    def __init__(self, message: str, file: str = "", line: int = 0, col: int = 0):
        super().__init__(message)
        self.message, self.file, self.line, self.col = message, file, line, col

    def __str__(self) -> str:
        where = f"{self.file}:{self.line}:{self.col}: " if self.file else ""
        return f"{where}{self.message}"

    def __reduce__(self):  # survives the trip back from a sweep's worker process
        return (type(self), (self.message, self.file, self.line, self.col))


class Watchdog(ExecutionError):
    pass


class NullPointer(ExecutionError):
    """A pointer or reference dereferenced while it is not set (NULL)."""


def null_access(e: BaseException) -> bool:
    """Whether ``e`` is compiled code reaching through a pointer, reference or interface
    that is not set: Python's AttributeError on None, or a :class:`NullPointer`."""
    return isinstance(e, NullPointer) or (isinstance(e, AttributeError)
                                          and "NoneType" in str(e))


class Ref:
    """A reference to an attribute (a variable of an FB instance, a struct member, a global):
    what ``ADR``/``REF=`` give for elementary variables and what VAR_IN_OUT receives."""
    __slots__ = ("obj", "attr")

    def __init__(self, obj, attr):
        self.obj, self.attr = obj, attr

    def get(self):
        return getattr(self.obj, self.attr)

    def set(self, value):
        setattr(self.obj, self.attr, value)

    def assign(self, value):
        """Store ``value`` and give it back (an assignment inside an expression)."""
        self.set(value)
        return value


class ItemRef(Ref):
    """A reference to an array element."""
    __slots__ = ()

    def get(self):
        return self.obj[self.attr]

    def set(self, value):
        self.obj[self.attr] = value


class Box:
    """A one-value cell: lets a function's local variable be passed by reference."""
    __slots__ = ("v",)

    def __init__(self, v):
        self.v = v

    def get(self):
        return self.v

    def set(self, value):
        self.v = value

    assign = Ref.assign


# ---------------------------------------------------------------------- integer arithmetic

def wrap(value: int, bits: int, signed: bool) -> int:
    """IEC integer overflow: keep the low ``bits`` bits (two's complement when signed)."""
    mask = (1 << bits) - 1
    value = int(value) & mask
    if signed and value >> (bits - 1):
        value -= 1 << bits
    return value


def idiv(a: int, b: int) -> int:
    """Integer division truncating toward zero (IEC, C), not Python's floor division."""
    if b == 0:
        raise ZeroDivisionError("integer division by zero")
    q = abs(a) // abs(b)
    return q if (a >= 0) == (b >= 0) else -q


def imod(a: int, b: int) -> int:
    """MOD with the sign of the dividend; ``x MOD 0`` is 0 (IEC 61131-3 table 29)."""
    if b == 0:
        return 0
    return a - b * idiv(a, b)


def tmul(t_ns: int, factor) -> int:
    """TIME * number."""
    return int(round(t_ns * factor)) if isinstance(factor, float) else t_ns * factor


def tdiv(t_ns: int, divisor) -> int:
    """TIME / number, truncated to whole nanoseconds."""
    if isinstance(divisor, float):
        return int(t_ns / divisor)
    return idiv(t_ns, divisor)


def fdiv(a, b) -> float:
    if b == 0:
        raise ZeroDivisionError("division by zero")
    return a / b


def getbit(value: int, bit: int) -> bool:
    return bool((value >> bit) & 1)


def setbit(value: int, bit: int, on) -> int:
    return value | (1 << bit) if on else value & ~(1 << bit)


def check_index(i: int, low: int, high: int, where: str) -> int:
    """Array subscript ``i`` of ``ARRAY[low..high]`` as a Python list index."""
    if not low <= i <= high:
        raise IndexError(f"array index {i} outside {where}[{low}..{high}]")
    return i - low


def round_half_away(x: float) -> int:
    """REAL to integer conversion: to the nearest, halves away from zero (IEC, CODESYS)."""
    return int(math.floor(abs(x) + 0.5)) * (1 if x >= 0 else -1)


# ---------------------------------------------------------------------- standard functions

def shl(value, n, bits):
    return (value << n) & ((1 << bits) - 1)


def shr(value, n, bits):
    return (value & ((1 << bits) - 1)) >> n


def rol(value, n, bits):
    n %= bits
    value &= (1 << bits) - 1
    return ((value << n) | (value >> (bits - n))) & ((1 << bits) - 1)


def ror(value, n, bits):
    return rol(value, bits - (n % bits), bits)


def limit(mn, value, mx):
    return mn if value < mn else mx if value > mx else value


def mux(k, *values):
    if not 0 <= k < len(values):
        raise IndexError(f"MUX selector {k} outside 0..{len(values) - 1}")
    return values[k]


def sel(g, in0, in1):
    return in1 if g else in0


def expt(a, b):
    return float(a) ** b


def sqrt(x):
    if x < 0:
        raise ValueError(f"SQRT of a negative number ({x})")
    return math.sqrt(x)


def ln(x):
    if x <= 0:
        raise ValueError(f"LN of a number <= 0 ({x})")
    return math.log(x)


def log10(x):
    if x <= 0:
        raise ValueError(f"LOG of a number <= 0 ({x})")
    return math.log10(x)


def left(s, n):
    return s[:max(int(n), 0)]


def right(s, n):
    return s[len(s) - int(n):] if n > 0 else ""


def mid(s, n, p):
    return s[int(p) - 1:int(p) - 1 + int(n)]


def insert(s1, s2, p):
    return s1[:int(p)] + s2 + s1[int(p):]


def delete(s, n, p):
    return s[:int(p) - 1] + s[int(p) - 1 + int(n):]


def replace(s1, s2, n, p):
    return s1[:int(p) - 1] + s2 + s1[int(p) - 1 + int(n):]


def find(s1, s2):
    return s1.find(s2) + 1


MATH = {"ABS": abs, "SQRT": sqrt, "LN": ln, "LOG": log10, "EXP": math.exp, "SIN": math.sin,
        "COS": math.cos, "TAN": math.tan, "ASIN": math.asin, "ACOS": math.acos,
        "ATAN": math.atan, "ATAN2": math.atan2, "EXPT": expt}


# ------------------------------------------------------------ exceptions (__TRY)

# what compiled code raises where a PLC raises an exception, and its
# __SYSTEM.ExceptionCode (CODESYS/TwinCAT RTSEXCPT_* numbers)
PLC_EXCEPTIONS = (ZeroDivisionError, IndexError, AttributeError, ValueError, OverflowError,
                  RecursionError, NullPointer)
RTSEXCPT_ACCESS_VIOLATION = 0x51
RTSEXCPT_STACK_OVERFLOW = 0x54
RTSEXCPT_ARRAYBOUNDS = 0x101
RTSEXCPT_DIVIDEBYZERO = 0x102
RTSEXCPT_OVERFLOW = 0x103
RTSEXCPT_FPU_ERROR = 0x150


def exception_code(e: BaseException) -> int | None:
    """The PLC exception code of an error raised in compiled code, None for what is no
    PLC exception (a watchdog, a construct plcpred cannot execute, a bug)."""
    if isinstance(e, ZeroDivisionError):
        return RTSEXCPT_DIVIDEBYZERO
    if isinstance(e, IndexError):
        return RTSEXCPT_ARRAYBOUNDS
    if isinstance(e, RecursionError):
        return RTSEXCPT_STACK_OVERFLOW
    if isinstance(e, OverflowError):
        return RTSEXCPT_OVERFLOW
    if isinstance(e, ValueError):
        return RTSEXCPT_FPU_ERROR          # SQRT, LN, LOG of numbers out of their domain
    if null_access(e):
        return RTSEXCPT_ACCESS_VIOLATION
    return None


# ---------------------------------------------------------------------- conversions

def to_int(value, bits: int, signed: bool, source: str, ns_per_count: int = 1_000_000):
    """Any elementary value to an integer type of ``bits`` width. ``source`` is the
    category of the value: bool, int, real, time or string; a time or date (held in
    nanoseconds) counts in units of ``ns_per_count`` (types.ns_per_count)."""
    if source == "real":
        value = round_half_away(value)
    elif source == "time":
        value = int(value) // ns_per_count
    elif source == "string":
        value = int(str(value).strip() or 0)
    elif source == "char":        # CHAR_TO_BYTE: the character's code
        value = ord(value[0]) if value else 0
    return wrap(int(value), bits, signed)


def to_real(value, source: str, ns_per_count: int = 1_000_000) -> float:
    if source == "time":
        return value / ns_per_count
    if source == "string":
        return float(str(value).strip() or 0)
    return float(value)


def to_time(value, source: str, ns_per_count: int = 1_000_000) -> int:
    """A number as a time or date whose count is worth ``ns_per_count`` nanoseconds."""
    if source == "real":
        return round_half_away(value * ns_per_count)
    if source == "time":
        return int(value)
    return int(value) * ns_per_count


def to_bool(value, source: str) -> bool:
    if source == "string":
        return str(value).strip().upper() in ("TRUE", "1")
    return value != 0


def to_string(value, source: str, char: bool = False) -> str:
    """``value`` as text; with ``char``, an integer is a character code (BYTE_TO_CHAR)."""
    if char and source == "int":
        return chr(int(value) & 0xFFFF)
    if source == "bool":
        return "TRUE" if value else "FALSE"
    if source == "time":
        return "T#" + format_duration(value)
    if source == "real":
        return repr(float(value))
    return str(value)
