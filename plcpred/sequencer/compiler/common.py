"""What every part of the compiler shares: its limits, its error, the scope of one body,
the generated source and the compiled result."""
from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass, field

from ...parser import ir
from ...parser.errors import ProgramError, at
from ...parser.generics import GENERIC_PRAGMA
from ...parser.names import ident
from ...parser.stdlib import std_fb_pin
from .. import types as ty
from ..types import FbT, StdFbT

# loop iterations one scan may run, all loops together (nested loops, and loops in the
# FBs a loop calls, share it): a PLC's cycle watchdog, in work instead of time
WATCHDOG_ITERATIONS = 1_000_000
# an observed name followed by this: a bit of that variable is read (``wCount.2``), which
# a count's shift from one period to the next does not keep, so it is compared even then
BIT_READ = "."
# the generated class holding the globals (``_g``), as ``Compiled.left_out`` names it
GLOBALS_CLASS = "k_GLOBALS"
# longest if/elif chain generated at once (StatementsMixin._chain)
ELIF_CHAIN = 100
# generated lines compiled at once, at least (top-level classes and functions joined):
# Python compiles a module or function whole, in memory many times its text, so the
# executor compiles the module in pieces, and long statement lists are functions of
# their own (StatementsMixin: PART_NODES)
PIECE_LINES = 500

# IEC comparison operators and their Python spelling
COMPARISONS = {"=": "==", "<>": "!=", "<": "<", ">": ">", "<=": "<=", ">=": ">="}

STDFB_MEMBERS = {"IN": ty.BOOL, "PT": ty.TIME, "Q": ty.BOOL, "ET": ty.TIME, "CLK": ty.BOOL,
                 "S1": ty.BOOL, "R": ty.BOOL, "S": ty.BOOL, "R1": ty.BOOL, "Q1": ty.BOOL,
                 "CU": ty.BOOL, "CD": ty.BOOL, "LD": ty.BOOL, "PV": ty.DINT, "CV": ty.DINT,
                 "QU": ty.BOOL, "QD": ty.BOOL, "RESET": ty.BOOL}


def stdfb_member(t: StdFbT, key: str):
    """(IEC pin name, type) of member ``key`` of a standard FB (vendor pin names map to
    the IEC ones), or (None, None)."""
    pin = std_fb_pin(t.name, key)
    return (pin, STDFB_MEMBERS[pin]) if pin else (None, None)


class CompileError(ProgramError):
    """A construct the executor cannot run, positioned in the program."""


def error_at(node, message: str) -> CompileError:
    """A CompileError positioned at ``node`` (where it has a position)."""
    e = at(getattr(node, "pos", None), message)
    return CompileError(e.message, e.file, e.line, e.col)


@dataclass
class Scope:
    """Names visible in one body: UPPER name -> (Python code, type)."""
    names: dict = field(default_factory=dict)
    fb: FbT | None = None          # the FB whose ``self`` is in scope
    pylocals: set = field(default_factory=set)
    ret: str = "return"            # what RETURN compiles to
    steps: dict = field(default_factory=dict)  # SFC step name -> index
    cls: str = ""                  # Python class of self
    pou: str = ""                  # the POU as __POUNAME() gives it (``FB.Method``)


class Source:
    """Generated lines with the program position each came from (for run-time errors),
    and where each top-level class or function starts: Python compiles a module whole,
    so the executor compiles these pieces one by one (:attr:`Compiled.pieces`).

    Lines emitted :meth:`aside` (a part of a long statement list, a function of its
    own) are held and placed at the top level before the next top-level line."""

    def __init__(self):
        self.lines: list[str] = []
        self.pos: list = []
        self.tmp = 0
        self.starts: list[int] = []     # lines where a top-level class or def starts
        self._held: list[tuple[list, list]] = []
        self._aside = 0

    def emit(self, ind: int, text: str, pos=None):
        if not ind and not self._aside:
            self.flush()
            if text.startswith(("class ", "def ")):
                self.starts.append(len(self.lines))
        self.lines.append("    " * ind + text)
        self.pos.append(pos)

    def temp(self, stem="t") -> str:
        self.tmp += 1
        return f"_{stem}{self.tmp}"

    @contextmanager
    def aside(self):
        """Emit a top-level function apart from the lines being emitted (which may be
        inside a class): it joins the module before the next top-level line."""
        lines, pos = self.lines, self.pos
        self.lines, self.pos = [], []
        self._aside += 1
        try:
            yield
        finally:
            self._aside -= 1
            self._held.append((self.lines, self.pos))
            self.lines, self.pos = lines, pos

    def flush(self) -> None:
        """Place the functions emitted aside (each a piece of its own)."""
        held, self._held = self._held, []
        for lines, pos in held:
            self.starts.append(len(self.lines))
            self.lines += lines
            self.pos += pos


@dataclass
class Compiled:
    """A compiled project: Python source plus what the executor needs to know."""
    source: str
    line_pos: list
    programs: list[tuple[str, str]]            # (instance name, class name) in scan order
    program_types: dict                        # instance name -> FbT
    globals_types: dict                        # UPPER -> (name, type, decl)
    reads_et: bool = False                     # the program reads a timer's ET
    reads_clock: bool = False                  # TIME()/NOW: step every scan
    types: object = None
    address_slots: dict = None                 # undeclared direct address -> global attr
    intervals: dict = None                     # program instance -> task INTERVAL (ns)
    et_thresholds: tuple = ()                  # constants ET is compared with (ns)
    written: frozenset | None = None           # names the program may write (None: any)
    # class name -> {attribute: (bits, signed) or None} of the variables left out of the
    # state the executor compares (ComparedState.sinks): (bits, signed) for an integer
    # that only ever adds a step to itself (a count, which grows by the same amount each
    # period of a repeating machine), None for any other
    left_out: dict = None
    # names the machine file reads (Compiler's ``observed``): never left out, so that
    # everything they show is in the compared state
    observed: frozenset = frozenset()
    # the lines where the pieces of the source start that are compiled one by one (Python
    # compiles a module or function at once, in memory many times its text)
    pieces: tuple = (0,)


def pieces(starts, n_lines: int) -> tuple:
    """The first lines of the pieces the executor compiles one by one: the top-level
    classes and functions starting at ``starts`` (ascending), consecutive ones joined
    until a piece holds PIECE_LINES lines (fewer, larger compilations)."""
    out = [0]
    for a in starts:
        if a - out[-1] >= PIECE_LINES and a < n_lines:
            out.append(a)
    return tuple(out)


def pos_args(pos) -> str:
    """A program position as the arguments of a run-time helper (file, line, column)."""
    if pos is None:
        return "'', 0, 0"
    return f"{pos.file!r}, {pos.line}, {pos.col}"


def shown_name(pou: ir.Pou) -> str:
    """A POU's name as the program wrote it (a generic FB's copy as ``FB_Buf<100>``)."""
    return next((p[len(GENERIC_PRAGMA):] for p in pou.pragmas
                 if p.startswith(GENERIC_PRAGMA)), pou.name)


def constant_block(b) -> bool:
    return "CONSTANT" in [q.upper() for q in b.qualifiers]


def int_constants(blocks):
    """(name key, value) of each integer literal constant the CONSTANT ``blocks`` declare."""
    for b in blocks:
        if constant_block(b):
            for d in b.decls:
                if isinstance(d.init, ir.Literal) and isinstance(d.init.value, int) \
                        and not isinstance(d.init.value, bool):
                    yield ident(d.name), int(d.init.value)


def fb_inits(t: FbT) -> list:
    """(FB type, FB_init method) along ``t``'s chain, base first."""
    return [(ft, m) for ft in reversed(list(t.chain())) for m in ft.pou.methods
            if ident(m.name) == "FB_INIT"]
