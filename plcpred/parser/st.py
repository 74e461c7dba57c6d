"""Structured Text front end: ``parse_st(text, filename)`` -> :class:`ir.Program`."""
from __future__ import annotations

from . import ir
from .build import DIALECT, GrammarRunner
from .errors import ProgramError
from .lexer import Tokenizer
from .names import validate_names

_RUNNER = GrammarRunner("st")


def parse_st(text: str, filename: str = "<input>", validate: bool = True,
             dialect: str = "iec", origin=None) -> ir.Program:
    """Parse IEC 61131-3 Structured Text (one or more POUs, TYPE blocks, interfaces,
    configurations, global variable lists). Raises :class:`ProgramError` with the file,
    line and column of the first problem. ``validate=False`` is for front ends that
    build on this one and validate their whole result themselves; ``dialect`` "bnr"
    reads B&R Automation Studio's forms where they differ (``Action;`` calls). A file
    whose one POU left open runs to its end (as CODESYS's editor shows a POU: no
    END_PROGRAM) is read to there, noted for :func:`unclosed_pous`. ``origin`` places a
    fragment of a larger file (:class:`~plcpred.parser.lexer.Tokenizer`)."""
    tokenizer = Tokenizer(text, filename, origin=origin)
    token = DIALECT.set(dialect)
    unclosed = None
    try:
        try:
            program = _RUNNER.parse(tokenizer, filename)
        except ProgramError as e:
            # a POU as CODESYS's editor shows it (and users copy it): header, declarations
            # and body, with no END_PROGRAM; read to the end of the file, with a warning
            unclosed = _unclosed_pou(text, filename) if "end of the file" in e.message \
                or e.message.startswith("unexpected end of file") else None
            if unclosed is None:
                raise
            tokenizer = Tokenizer(f"{text}\nEND_{unclosed[0]}\n", filename, origin=origin)
            try:
                program = _RUNNER.parse(tokenizer, filename)
            except ProgramError:
                raise e from None
    finally:
        DIALECT.reset(token)
    program.pragmas = [(p, ir.Pos(filename, *tokenizer.place(line, col)))
                       for p, line, col in tokenizer.pragmas]
    if unclosed is not None:
        program.pragmas.append((_UNCLOSED_NOTE + unclosed[0] + "}",
                                ir.Pos(filename, unclosed[1], 1)))
    program.source = filename
    return validate_names(program) if validate else program


_POU_OPENERS = ("PROGRAM", "FUNCTION_BLOCK", "FUNCTION")


def _unclosed_pou(text: str, filename: str) -> tuple[str, int] | None:
    """(kind, line) of the POU a file opens last and never closes, when it is the only
    one left open; None otherwise (or when the file does not even tokenize)."""
    try:
        tokens = list(Tokenizer(text, filename))
    except ProgramError:
        return None
    stack = []
    for t in tokens:
        if t.type in _POU_OPENERS:
            stack.append(t)
        elif t.type.startswith("_END_") and t.type[5:] in _POU_OPENERS:
            if not stack or stack[-1].type != t.type[5:]:
                return None
            stack.pop()
    if len(stack) != 1:
        return None
    return stack[0].type, stack[0].line


# the note a POU read to the end of its file leaves in the program's pragmas
_UNCLOSED_NOTE = "{unclosed-pou "


def unclosed_pous(program: ir.Program) -> list[tuple[str, ir.Pos]]:
    """(kind, header position) of each POU that :func:`parse_st` read to the end of its
    file for want of its END keyword."""
    return [(p[len(_UNCLOSED_NOTE):-1], pos) for p, pos in program.pragmas
            if p.startswith(_UNCLOSED_NOTE)]
