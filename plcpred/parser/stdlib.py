"""Names the IEC 61131-3 standard library provides: elementary types, standard function
blocks with their interfaces, and standard functions. The checker resolves against these;
the sequencer implements them."""
from __future__ import annotations

import re

ELEMENTARY_TYPES = frozenset("""
BOOL SINT INT DINT LINT USINT UINT UDINT ULINT BYTE WORD DWORD LWORD REAL LREAL
TIME LTIME DATE LDATE TIME_OF_DAY TOD LTIME_OF_DAY LTOD DATE_AND_TIME DT LDATE_AND_TIME LDT
STRING WSTRING CHAR WCHAR BIT XWORD UXINT XINT __XWORD __UXINT __XINT
ANY ANY_INT ANY_REAL ANY_NUM ANY_BIT ANY_DATE ANY_ELEMENTARY ANY_STRING
""".split())

# name -> (inputs, outputs), in IEC order (positional calls use it)
STANDARD_FBS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "TON": (("IN", "PT"), ("Q", "ET")),
    "TOF": (("IN", "PT"), ("Q", "ET")),
    "TP": (("IN", "PT"), ("Q", "ET")),
    "LTON": (("IN", "PT"), ("Q", "ET")),
    "LTOF": (("IN", "PT"), ("Q", "ET")),
    "LTP": (("IN", "PT"), ("Q", "ET")),
    "TONR": (("IN", "PT", "RESET"), ("Q", "ET")),
    "R_TRIG": (("CLK",), ("Q",)),
    "F_TRIG": (("CLK",), ("Q",)),
    "CTU": (("CU", "R", "PV"), ("Q", "CV")),
    "CTD": (("CD", "LD", "PV"), ("Q", "CV")),
    "CTUD": (("CU", "CD", "R", "LD", "PV"), ("QU", "QD", "CV")),
    "SR": (("S1", "R"), ("Q1",)),
    "RS": (("S", "R1"), ("Q1",)),
}
for _width in ("INT", "DINT", "LINT", "UDINT", "ULINT"):
    for _base in ("CTU", "CTD", "CTUD"):
        STANDARD_FBS[f"{_base}_{_width}"] = STANDARD_FBS[_base]

# CODESYS and TwinCAT (Standard, Tc2_Standard) name some IEC pins differently; both
# names are accepted everywhere and mean the IEC pin.
PIN_ALIASES: dict[str, dict[str, str]] = {
    "CTU": {"RESET": "R"},
    "CTD": {"LOAD": "LD"},
    "CTUD": {"RESET": "R", "LOAD": "LD"},
    "SR": {"SET1": "S1", "RESET": "R"},
    "RS": {"SET": "S", "RESET1": "R1"},
}


def _base_fb(name: str) -> str:
    """CTU_DINT -> CTU (the sized counters share their base's pins)."""
    base, _, width = name.partition("_")
    return base if width and base in ("CTU", "CTD", "CTUD") else name


def std_fb_pin(fb_name: str, pin: str) -> str | None:
    """The IEC name of pin ``pin`` (either spelling, any case) of standard FB ``fb_name``,
    or None when the FB has no such pin."""
    fb, key = fb_name.upper(), pin.upper()
    ins, outs = STANDARD_FBS[fb]
    if key in ins or key in outs:
        return key
    return PIN_ALIASES.get(_base_fb(fb), {}).get(key)


def std_fb_pins(fb_name: str) -> tuple[set[str], set[str]]:
    """(inputs, outputs) of a standard FB, each under both its IEC and vendor names."""
    fb = fb_name.upper()
    ins, outs = STANDARD_FBS[fb]
    aliases = PIN_ALIASES.get(_base_fb(fb), {})
    return set(ins) | {a for a, c in aliases.items() if c in ins}, set(outs)


STANDARD_FUNCTIONS = frozenset("""
ABS SQRT LN LOG EXP SIN COS TAN ASIN ACOS ATAN ATAN2 EXPT ADD SUB MUL DIV MOD MOVE
SHL SHR ROL ROR AND OR XOR NOT SEL MAX MIN LIMIT MUX GT GE EQ LE LT NE
LEN LEFT RIGHT MID CONCAT INSERT DELETE REPLACE FIND TRUNC ROUND
SIZEOF ADR BITADR REF INDEXOF LOWER_BOUND UPPER_BOUND __NEW __DELETE __ISVALIDREF
__QUERYINTERFACE __QUERYPOINTER __POUNAME TIME LTIME NOW XSIZEOF
""".split())

# TwinCAT's WSTRING functions (Tc2_Standard): the string functions under another name
WIDE_STRING_FUNCTIONS = {"W" + f: f for f in
                         "LEN LEFT RIGHT MID CONCAT INSERT DELETE REPLACE FIND".split()}

# vendor functions built in (Tc2_System and CODESYS SysMem): whole values, see the runtime
VENDOR_FUNCTIONS = frozenset("MEMCPY MEMMOVE MEMSET MEMCMP".split())

# X_TO_Y, TO_Y, TRUNC_INT, ... conversion functions
_CONVERSION = re.compile(
    r"^(?:(?:[A-Z_]+)_TO_[A-Z_]+|TO_[A-Z_]+|TRUNC_[A-Z]+|[A-Z]+_TRUNC_[A-Z]+|"
    r"[A-Z]+_BCD_TO_[A-Z]+|[A-Z]+_TO_BCD_[A-Z]+)$")


def is_standard_function(name: str) -> bool:
    up = name.upper()
    return up in STANDARD_FUNCTIONS or up in VENDOR_FUNCTIONS \
        or up in WIDE_STRING_FUNCTIONS or bool(_CONVERSION.match(up))
