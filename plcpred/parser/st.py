"""Structured Text front end: ``parse_st(text, filename)`` -> :class:`ir.Program`."""
from __future__ import annotations

from . import ir
from .build import DIALECT, GrammarRunner
from .grammar import ST_GRAMMAR
from .lexer import Tokenizer
from .names import validate_names

_RUNNER = GrammarRunner(ST_GRAMMAR)


def parse_st(text: str, filename: str = "<input>", validate: bool = True,
             dialect: str = "iec") -> ir.Program:
    """Parse IEC 61131-3 Structured Text (one or more POUs, TYPE blocks, interfaces,
    configurations, global variable lists). Raises :class:`ProgramError` with the file,
    line and column of the first problem. ``validate=False`` is for front ends that
    build on this one and validate their whole result themselves; ``dialect`` "bnr"
    reads B&R Automation Studio's forms where they differ (``Action;`` calls)."""
    tokenizer = Tokenizer(text, filename)
    token = DIALECT.set(dialect)
    try:
        program = _RUNNER.parse(tokenizer, filename)
    finally:
        DIALECT.reset(token)
    program.pragmas = [(p, ir.Pos(filename, line, col)) for p, line, col in tokenizer.pragmas]
    program.source = filename
    return validate_names(program) if validate else program
