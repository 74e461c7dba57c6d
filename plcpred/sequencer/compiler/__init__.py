"""Compile a program's IR to Python source, one class per FUNCTION_BLOCK/PROGRAM and one
function per FUNCTION, so that a scan costs a few Python calls instead of a walk over the
syntax tree.

The parts, each a module of this package: :mod:`.project` (the :class:`Compiler`, and the
gate every name passes first), :mod:`.declarations` (constants, addresses, initial
values), :mod:`.expressions`, :mod:`.stores` (assignment targets and references),
:mod:`.calls`, :mod:`.stdfunctions`, :mod:`.statements`, :mod:`.sfc_spec`,
:mod:`.classes` and :mod:`.callables` (what the generated module holds),
:mod:`.conversions` (types and assignment conversions), and :mod:`.flow` with
:mod:`.compared_state` (what the state the executor compares may leave out).

Mapping:

* variables are attributes of the instance (``self.X``, names upper-cased because IEC
  identifiers are case-insensitive and Python keywords never are all upper case); locals
  of FUNCTIONs, methods and property accessors are Python locals; globals live on ``_g``;
* integer assignments wrap to the declared width; ``/`` and ``MOD`` on integers truncate
  toward zero; TIME is integer nanoseconds;
* FB inputs keep their values between calls (they are attributes); standard FBs are the
  classes of :mod:`plcpred.sequencer.stdfb`, executed at the scan time ``_now``;
* VAR_IN_OUT of functions and methods receive a
  :class:`~plcpred.sequencer.runtime.Ref` (copy in, copy out); VAR_IN_OUT of FBs are
  copied in before and out after the call;
* structs and arrays are copied on assignment; references and pointers to FBs are the
  instance itself, to elementary variables a :class:`~plcpred.sequencer.runtime.Ref`;
* WHILE and REPEAT count iterations; a loop that runs away raises
  :class:`~plcpred.sequencer.runtime.Watchdog` naming its line;
* a long statement list (outside loops and JMP blocks) is module-level functions
  ``_partN`` called in turn, and IF/CASE arms past a few hundred likewise, whose
  RETURN ends their caller too (a FUNCTION's locals go in and come back out); with
  :attr:`Compiled.pieces` the executor compiles the module class by class, so that
  what Python compiles at once stays bounded whatever the program's size.

Direct addresses in code (``%QX0.0 := TRUE``) stand for the variable declared AT them, or
for a hidden global of the address's size. JMP works within one statement list.

Not supported (a positioned error at compile time): jumps into or out of blocks, pointer
arithmetic, variable-length arrays. ``__NEW`` of several elements (an array reached by
pointer arithmetic) compiles, and stops a run where it is executed. A UNION is treated as a
struct (its members do not overlap).
"""
from __future__ import annotations

from ...parser import ir
from ...parser.errors import ProgramError
from ...parser.generics import readable
from .common import (
    BIT_READ,
    ELIF_CHAIN,
    GLOBALS_CLASS,
    WATCHDOG_ITERATIONS,
    Compiled,
    CompileError,
    Scope,
    Source,
    stdfb_member,
)
from .flow import written_names
from .project import Compiler

__all__ = ["BIT_READ", "ELIF_CHAIN", "GLOBALS_CLASS", "WATCHDOG_ITERATIONS", "CompileError",
           "Compiled", "Compiler", "Scope", "Source", "compile_program", "stdfb_member",
           "written_names"]


def compile_program(program: ir.Program, observed=frozenset()) -> Compiled:
    """Compile a parsed project. ``observed``: names read from outside the program (the
    machine file's signals, :func:`~plcpred.sequencer.executor.observed_names`), which are
    always part of the state the executor compares. Raises :class:`CompileError`
    (positioned) for constructs the executor cannot run."""
    compiler = Compiler(program, observed)
    try:
        return compiler.compile()
    except ProgramError as e:       # a generic FB's copy named as the program writes it
        raise readable([e], compiler.program)[0] from None
