"""Python compiles a module, or a function, at once, in memory many times its text: a
program body of 200,000 statements took 1.6 GB. The generated module is compiled in
pieces (its top-level classes and functions), and long statement lists and long IF/CASE
chains are functions of their own, so that what is compiled at once stays bounded.

The program is built as IR (the parser's own cost is not what is measured), run, and
checked against what it computes."""
import tracemalloc

import pytest

from plcpred.parser import ir
from plcpred.sequencer.compiler import compile_program
from plcpred.sequencer.compiler.common import PIECE_LINES
from plcpred.sequencer.compiler.statements import PART_ARMS, PART_NODES
from plcpred.sequencer.executor import ProgramInstance
from plcpred.sequencer.runtime import ExecutionError

STATEMENTS = 1_500          # x := x + k MOD 7 / d, in one body: 7,500 IR nodes
ARMS = 700                  # CASE s OF 0: y := 0; 1: y := 1; ...
DIVIDES = 1_234             # the statement that divides by d


def _at(line: int) -> ir.Pos:
    return ir.Pos("long.st", line, 3)


def _n(name: str, line: int | None = None) -> ir.Name:
    return ir.Name(name, pos=None if line is None else _at(line))


def _int(value: int) -> ir.Literal:
    return ir.Literal(value, "ANY_INT")


def _long_program() -> ir.Program:
    """PROGRAM Main: at lines 1..STATEMENTS ``x := x + k MOD 7`` (at DIVIDES, ``/ d``),
    then a CASE of ARMS arms on s (arm k sets y to k, ELSE y := -1), then s := s + 1."""
    def add(k: int):
        right = _int(k % 7)
        if k == DIVIDES:
            right = ir.Binary("/", right, _n("d", k), pos=_at(k))
        return ir.Assign(_n("x", k), ir.Binary("+", _n("x", k), right, pos=_at(k)), pos=_at(k))
    arms = [ir.CaseBranch([_int(k)], [ir.Assign(_n("y"), _int(k), pos=_at(9000 + k))])
            for k in range(ARMS)]
    body = [add(k) for k in range(1, STATEMENTS + 1)]
    body += [ir.Case(_n("s"), arms, [ir.Assign(_n("y"), _int(-1))], pos=_at(9000)),
             ir.Assign(_n("s"), ir.Binary("+", _n("s"), _int(1)))]
    decls = [ir.VarDecl(n, ir.NamedType("DINT")) for n in ("x", "y", "s")]
    decls.append(ir.VarDecl("d", ir.NamedType("DINT"), _int(1)))
    return ir.Program([ir.Pou("PROGRAM", "Main", [ir.VarBlock("VAR", decls)], body,
                              pos=_at(1))])


@pytest.fixture(scope="module")
def long_program():
    program = _long_program()
    return program, compile_program(program)


def _longest_def(lines: list[str]) -> int:
    """Lines of the longest top-level class or function of a generated module."""
    starts = [k for k, line in enumerate(lines) if line.startswith(("class ", "def "))]
    return max(b - a for a, b in zip(starts, starts[1:] + [len(lines)]))


def test_a_long_body_is_compiled_in_bounded_pieces(long_program):
    program, c = long_program
    assert STATEMENTS * 5 > PART_NODES and ARMS > 2 * PART_ARMS    # (it must split)
    lines = c.source.split("\n")
    assert _longest_def(lines) <= 1_000 + 10
    sizes = [b - a for a, b in zip(c.pieces, c.pieces[1:] + (len(lines),))]
    assert len(sizes) > 3 and max(sizes) <= PIECE_LINES + 1_000 + 10
    # what is compiled at once, not the module: well under the memory of compiling
    # the module whole
    tracemalloc.start()
    try:
        compile(c.source, "whole", "exec")
        whole = tracemalloc.get_traced_memory()[1]
        tracemalloc.reset_peak()
        instance = ProgramInstance(program, c)
        pieces = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert pieces < 0.6 * whole
    main = instance.programs[0]
    for k in range(3):
        instance.scan(k * 10_000_000)
    per_scan = sum(k % 7 for k in range(1, STATEMENTS + 1))
    assert (main.X, main.Y, main.S) == (3 * per_scan, 2, 3)
    main.S = ARMS - 1                      # the last arm, in the last part
    instance.scan(3 * 10_000_000)
    assert main.Y == ARMS - 1
    instance.scan(4 * 10_000_000)          # no arm: ELSE
    assert main.Y == -1


def test_a_run_time_error_in_a_piece_names_its_line(long_program):
    program, c = long_program
    instance = ProgramInstance(program, c)
    instance.programs[0].D = 0
    with pytest.raises(ExecutionError) as e:
        instance.guard(instance.scan, 0)
    assert (e.value.file, e.value.line) == ("long.st", DIVIDES)
