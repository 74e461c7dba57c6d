"""Decoding IEC 61131-3 literal text into values (and back, for the ST printer).

TIME, LTIME, TOD, DATE and DT values are integer nanoseconds (durations; since midnight for
TOD; since 1970-01-01 UTC for DATE and DT), so that time arithmetic in the sequencer is
exact.
"""
from __future__ import annotations

import re

NS_PER_UNIT = {"d": 86_400 * 10**9, "h": 3_600 * 10**9, "m": 60 * 10**9, "s": 10**9,
               "ms": 10**6, "us": 10**3, "ns": 1}
_TIME_PART = re.compile(r"(\d[\d_]*(?:\.\d+)?)(d|h|ms|m|s|us|ns)_?", re.I)

INT_TYPES = {"SINT": 8, "INT": 16, "DINT": 32, "LINT": 64, "USINT": 8, "UINT": 16,
             "UDINT": 32, "ULINT": 64, "BYTE": 8, "WORD": 16, "DWORD": 32, "LWORD": 64}
REAL_TYPES = {"REAL", "LREAL"}
SIGNED_INT_TYPES = {"SINT", "INT", "DINT", "LINT"}
REAL_MAX = {"REAL": 3.4028234663852886e38, "LREAL": 1.7976931348623157e308}
# the widest integer any IEC type holds (ULINT, LINT): larger literals are errors, which
# also keeps Python from converting thousands of digits
INT_LITERAL_MAX = (1 << 64) - 1
# durations are held as integer nanoseconds; LTIME's 64-bit range bounds them
DURATION_MAX_NS = (1 << 64) - 1  # TwinCAT's LTIME is unsigned: LTIME#213503d23h34m33s709ms551us615ns
_DIGITS = {2: "01", 8: "01234567", 10: "0123456789", 16: "0123456789abcdefABCDEF"}


def int_range(type_name: str) -> tuple[int, int]:
    """(lowest, highest) value of an IEC integer type."""
    bits = INT_TYPES[type_name]
    if type_name in SIGNED_INT_TYPES:
        return -(1 << (bits - 1)), (1 << (bits - 1)) - 1
    return 0, (1 << bits) - 1


def parse_int(text: str) -> int:
    """``1_000``, ``16#FF``, ``2#1010_0101``, ``8#17``, with an optional sign. Bases are
    2, 8 and 16 (IEC 61131-3 6.3.2) and the 10 CODESYS accepts; the digits must belong to the base, and the value
    must fit the widest integer type (64 bits)."""
    raw = text
    text = text.replace("_", "")
    sign = 1
    if text and text[0] in "+-":
        sign = -1 if text[0] == "-" else 1
        text = text[1:]
    base, digits = 10, text
    if "#" in text:
        base_text, digits = text.split("#", 1)
        # IEC bases are 2, 8 and 16; CODESYS and TwinCAT also accept 10#
        if base_text not in ("2", "8", "10", "16"):
            raise ValueError(f"integer literal {raw!r}: base {base_text} (the bases are 2, "
                             "8, 10 and 16)")
        base = int(base_text)
    if not digits or any(c not in _DIGITS[base] for c in digits):
        raise ValueError(f"integer literal {raw!r}: {digits!r} are not base-{base} digits")
    if len(digits) > 70:
        raise ValueError(f"integer literal {raw[:30]!r}...: larger than any integer type")
    value = sign * int(digits, base)
    if abs(value) > INT_LITERAL_MAX:
        raise ValueError(f"integer literal {raw!r} is larger than any integer type (64 bits)")
    return value


def parse_real(text: str, type_name: str = "LREAL") -> float:
    """``1.5``, ``1.5e3``, ``1_000.0``; an error if it overflows the type."""
    value = float(text.replace("_", ""))
    if not abs(value) <= REAL_MAX[type_name]:
        raise ValueError(f"real literal {text!r} is out of the range of {type_name}")
    return value


def parse_duration_ns(text: str) -> int:
    """``1h2m3s4ms``, ``-1.5s``, ``250ms`` (the part after ``T#``) -> nanoseconds."""
    sign = 1
    if text and text[0] in "+-":
        sign = -1 if text[0] == "-" else 1
        text = text[1:]
    # the exact sum as numerator / denominator (a power of ten): integers, not Fraction,
    # whose import a syntax check would wait for
    num, den = 0, 1
    pos = 0
    for m in _TIME_PART.finditer(text):
        if m.start() != pos:
            raise ValueError(f"malformed duration {text[:40]!r}")
        number = m.group(1).replace("_", "")
        if len(number) > 40:   # longer than LTIME holds, or finer than a nanosecond
            raise ValueError(f"a number of {len(number)} digits in a duration")
        whole, _, fraction = number.partition(".")
        part_den = 10 ** len(fraction)
        if part_den > den:
            num *= part_den // den
            den = part_den
        num += int(whole + fraction) * NS_PER_UNIT[m.group(2).lower()] * (den // part_den)
        pos = m.end()
    if pos != len(text) or pos == 0:
        raise ValueError(f"malformed duration {text[:40]!r}")
    ns = sign * _round_half_even(num, den)
    if abs(ns) > DURATION_MAX_NS:
        raise ValueError(f"duration {text[:40]!r} is longer than LTIME holds (about 584 years)")
    return ns


def _round_half_even(num: int, den: int) -> int:
    """``round(num / den)`` exactly (halves to the even neighbour), ``num >= 0``."""
    q, r = divmod(num, den)
    if 2 * r > den or (2 * r == den and q % 2):
        q += 1
    return q


_TOD = re.compile(r"(\d{1,2}):(\d{1,2})(?::(\d{1,2}(?:\.\d{1,9})?))?")
_DATE = re.compile(r"(\d{4})-(\d{1,2})-(\d{1,2})")


def parse_tod_ns(text: str) -> int:
    """``12:30:15.25`` -> nanoseconds since midnight; hours 0..23, minutes and seconds
    0..59."""
    m = _TOD.fullmatch(text.replace("_", ""))
    if m is None:
        raise ValueError(f"time of day {text!r}: write hh:mm:ss")
    h, mi = int(m.group(1)), int(m.group(2))
    whole, _, fraction = (m.group(3) or "0").partition(".")
    s_num, s_den = int(whole + fraction), 10 ** len(fraction)   # the seconds, exactly
    if h > 23 or mi > 59 or s_num >= 60 * s_den:
        raise ValueError(f"time of day {text!r} does not exist (hours 0..23, minutes and "
                         "seconds 0..59)")
    return _round_half_even(((h * 60 + mi) * 60 * s_den + s_num) * 10**9, s_den)


def parse_date_ns(text: str) -> int:
    """``2024-01-02`` -> nanoseconds since 1970-01-01 (a date that exists)."""

    m = _DATE.fullmatch(text)
    if m is None:
        raise ValueError(f"date {text!r}: write yyyy-mm-dd")
    y, mo, d = (int(g) for g in m.groups())
    problem = _date_problem(y, mo, d)
    if problem:
        raise ValueError(f"date {text!r} does not exist ({problem})")
    return _days_from_civil(y, mo, d) * 86_400 * 10**9


# the proleptic Gregorian calendar's dates, years 1 to 9999 (Python's date), in integer
# arithmetic (H. Hinnant's days_from_civil and civil_from_days): the datetime and
# calendar modules cost a syntax check about 3 ms to import, as much as parsing a small
# program
_MONTH_DAYS = (31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31)


def _date_problem(y: int, mo: int, d: int) -> str:
    """Why ``y-mo-d`` is not a date, in the words of Python's date(); "" if it is one."""
    if not 1 <= y <= 9999:
        return f"year {y} is out of range"
    if not 1 <= mo <= 12:
        return "month must be in 1..12"
    leap = y % 4 == 0 and (y % 100 != 0 or y % 400 == 0)
    if not 1 <= d <= _MONTH_DAYS[mo - 1] + (mo == 2 and leap):
        return "day is out of range for month"
    return ""


def _days_from_civil(y: int, mo: int, d: int) -> int:
    """Days from 1970-01-01 to the date ``y-mo-d``."""
    y -= mo <= 2
    era = y // 400
    yoe = y - era * 400
    doy = (153 * (mo + (-3 if mo > 2 else 9)) + 2) // 5 + d - 1
    doe = yoe * 365 + yoe // 4 - yoe // 100 + doy
    return era * 146097 + doe - 719468


def parse_time_literal(text: str) -> tuple[int, str]:
    """``TIME#1s`` / ``TOD#12:00:00`` / ``DATE#2024-01-02`` / ``DT#2024-01-02-03:04:05``
    (prefix already normalised by the lexer) -> (nanoseconds, type name)."""
    kind, value = text.split("#", 1)
    if kind in ("TIME", "LTIME"):
        return parse_duration_ns(value), kind
    if kind in ("TOD", "LTOD"):
        return parse_tod_ns(value), kind
    if kind in ("DATE", "LDATE"):
        return parse_date_ns(value), kind
    if value.count("-") < 3:
        raise ValueError(f"date and time {value!r}: write yyyy-mm-dd-hh:mm:ss")
    date, tod = value.rsplit("-", 1)
    return parse_date_ns(date) + parse_tod_ns(tod), kind


_ESCAPES = {"$": "$", "'": "'", '"': '"', "L": "\n", "N": "\n", "P": "\f", "R": "\r",
            "T": "\t"}


def unquote_string(text: str) -> str:
    """Decode a quoted IEC string: ``$`` escapes, ``$hh`` (``$hhhh`` in WSTRING), and a
    doubled quote character standing for one."""
    quote = text[0]
    body = text[1:-1]
    hexlen = 2 if quote == "'" else 4
    out = []
    i = 0
    n = len(body)
    while i < n:
        c = body[i]
        if c == "$" and i + 1 < n:
            e = body[i + 1]
            if e.upper() in _ESCAPES:
                out.append(_ESCAPES[e.upper()])
                i += 2
                continue
            code = body[i + 1:i + 1 + hexlen]
            if len(code) == hexlen and all(ch in "0123456789abcdefABCDEF" for ch in code):
                out.append(chr(int(code, 16)))
                i += 1 + hexlen
                continue
            raise ValueError(f"unknown escape '${e}' in string")
        if c == quote and i + 1 < n and body[i + 1] == quote:
            out.append(quote)
            i += 2
            continue
        out.append(c)
        i += 1
    return "".join(out)


def quote_string(value: str, wide: bool = False) -> str:
    quote = '"' if wide else "'"
    out = []
    for c in value:
        if c == "$":
            out.append("$$")
        elif c == quote:
            out.append("$" + quote)
        elif c == "\n":
            out.append("$N")
        elif c == "\t":
            out.append("$T")
        elif c == "\r":
            out.append("$R")
        elif c == "\f":
            out.append("$P")
        elif ord(c) < 32 or (not wide and ord(c) > 255):
            out.append(f"${ord(c):0{4 if wide else 2}X}")
        else:
            out.append(c)
    return quote + "".join(out) + quote


def format_duration(ns: int) -> str:
    """Nanoseconds -> ``1h2m3s4ms`` (exact, largest units first)."""
    if ns == 0:
        return "0s"
    sign = "-" if ns < 0 else ""
    ns = abs(ns)
    parts = []
    for unit in ("d", "h", "m", "s", "ms", "us", "ns"):
        size = NS_PER_UNIT[unit]
        if ns >= size:
            q, ns = divmod(ns, size)
            parts.append(f"{q}{unit}")
    return sign + "".join(parts)


def format_time_literal(ns: int, kind: str) -> str:
    if kind in ("TIME", "LTIME"):
        return f"{'T' if kind == 'TIME' else 'LTIME'}#{format_duration(ns)}"
    if kind in ("TOD", "LTOD"):
        return f"{kind}#{_format_tod(ns)}"
    days, rest = divmod(ns, 86_400 * 10**9)
    y, mo, d = _civil_from_days(days)
    if kind in ("DATE", "LDATE"):
        return f"{'D' if kind == 'DATE' else 'LDATE'}#{y:04d}-{mo:02d}-{d:02d}"
    return f"{kind}#{y:04d}-{mo:02d}-{d:02d}-{_format_tod(rest)}"


def _format_tod(ns: int) -> str:
    s, frac = divmod(ns, 10**9)
    h, rem = divmod(s, 3600)
    m, s = divmod(rem, 60)
    text = f"{h:02d}:{m:02d}:{s:02d}"
    if frac:
        text += "." + f"{frac:09d}".rstrip("0")
    return text


def _civil_from_days(days: int) -> tuple[int, int, int]:
    """The date ``days`` after 1970-01-01 (OverflowError outside years 1 to 9999, as
    Python's date arithmetic)."""
    if abs(days) > 999_999_999:     # as timedelta(days=days) says
        raise OverflowError(f"days={days}; must have magnitude <= 999999999")
    z = days + 719468
    era = z // 146097
    doe = z - era * 146097
    yoe = (doe - doe // 1460 + doe // 36524 - doe // 146096) // 365
    doy = doe - (365 * yoe + yoe // 4 - yoe // 100)
    mp = (5 * doy + 2) // 153
    d = doy - (153 * mp + 2) // 5 + 1
    mo = mp + (3 if mp < 10 else -9)
    y = yoe + era * 400 + (mo <= 2)
    if not 1 <= y <= 9999:
        raise OverflowError("date value out of range")
    return y, mo, d


def parse_typed_literal(text: str):
    """``INT#-5``, ``REAL#1.5``, ``BOOL#TRUE``, ``WORD#16#FF``, ``STRING#'x'`` ->
    (value, type name)."""
    type_name, value = text.split("#", 1)
    if type_name == "BIT":  # CODESYS: a BOOL stored as one bit of a structure
        type_name = "BOOL"
    if type_name == "BOOL":
        v = value.upper()
        if v in ("TRUE", "1"):
            return True, type_name
        if v in ("FALSE", "0"):
            return False, type_name
        raise ValueError(f"{value!r} is not a BOOL")
    if type_name in INT_TYPES:
        v = parse_int(value)
        lo, hi = int_range(type_name)
        bits = INT_TYPES[type_name]
        if "#" in value and lo < 0 and hi < v < (1 << bits):
            v -= 1 << bits  # INT#16#FFFF: a bit pattern, read as two's complement
        if not lo <= v <= hi:
            raise ValueError(f"{text} is out of the range of {type_name} ({lo}..{hi})")
        return v, type_name
    if type_name in REAL_TYPES:
        if "#" in value:
            return float(parse_int(value)), type_name
        return parse_real(value, type_name), type_name
    if type_name in ("STRING", "WSTRING", "CHAR", "WCHAR"):
        if value[:1] not in ("'", '"'):
            raise ValueError(f"{type_name} literal needs a quoted string")
        return unquote_string(value), type_name
    raise ValueError(f"no typed literals of type {type_name}")
