"""IR printed back as ST parses to an equal IR, for every sample program."""
import pytest

from plcpred.parser import load_program, parse_st
from plcpred.parser.printer import to_st
from conftest import SAMPLES

PROGRAMS = sorted(p for p in SAMPLES.rglob("*") if p.suffix in (".st", ".seq", ".xml"))


def test_there_are_samples_in_every_format():
    assert {p.suffix for p in PROGRAMS} >= {".st"}
    assert len([p for p in PROGRAMS if p.suffix == ".st"]) >= 6


@pytest.mark.parametrize("path", PROGRAMS, ids=lambda p: p.name)
def test_round_trip(path):
    program = load_program(path)
    text = to_st(program)
    again = parse_st(text, "printed.st")
    assert again == program
    # printing is a fixed point
    assert to_st(again) == text


def test_round_trip_keeps_semantics_of_tricky_expressions():
    src = """PROGRAM P
    VAR a, b, c : INT; x : BOOL; END_VAR
    a := (a - (b - c)) * -(b + c) ** 2 MOD 3;
    x := NOT (x AND (a < b)) OR (a = b) = x;
    a := T#1d2h3m4s5ms6us7ns / T#1ms + TOD#23:59:59.25 - D#2000-02-29 + DT#1999-12-31-23:59:59;
    END_PROGRAM"""
    p = parse_st(src)
    assert parse_st(to_st(p)) == p


@pytest.mark.parametrize("path", PROGRAMS, ids=lambda p: p.name)
def test_ir_pickles(path):
    """Sweeps send the IR to worker processes, so it must survive pickling."""
    import pickle
    program = load_program(path)
    assert pickle.loads(pickle.dumps(program)) == program
