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

STANDARD_FUNCTIONS = frozenset("""
ABS SQRT LN LOG EXP SIN COS TAN ASIN ACOS ATAN ATAN2 EXPT ADD SUB MUL DIV MOD MOVE
SHL SHR ROL ROR AND OR XOR NOT SEL MAX MIN LIMIT MUX GT GE EQ LE LT NE
LEN LEFT RIGHT MID CONCAT INSERT DELETE REPLACE FIND TRUNC ROUND
SIZEOF ADR BITADR REF INDEXOF LOWER_BOUND UPPER_BOUND __NEW __DELETE __ISVALIDREF
__QUERYINTERFACE __QUERYPOINTER TIME LTIME NOW
""".split())

# X_TO_Y, TO_Y, TRUNC_INT, ... conversion functions
_CONVERSION = re.compile(
    r"^(?:(?:[A-Z_]+)_TO_[A-Z_]+|TO_[A-Z_]+|TRUNC_[A-Z]+|[A-Z]+_TRUNC_[A-Z]+|"
    r"[A-Z]+_BCD_TO_[A-Z]+|[A-Z]+_TO_BCD_[A-Z]+)$")


def is_standard_function(name: str) -> bool:
    up = name.upper()
    return up in STANDARD_FUNCTIONS or bool(_CONVERSION.match(up))
