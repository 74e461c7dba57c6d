"""The .seq sequence-chart format."""
import pytest

from plcpred.parser import ProgramError, ir, parse_st
from plcpred.parser.check import check_program
from plcpred.parser.printer import to_st
from plcpred.parser.seq import __doc__ as SEQ_DOC
from plcpred.parser.seq import parse_seq


def documented_example():
    block = SEQ_DOC.split("Example::")[1].split("Rules:")[0]
    return "\n".join(line[4:] for line in block.splitlines())


def test_documented_example_parses_checks_and_round_trips():
    prog = parse_seq(documented_example(), "doc.seq")
    errors, warnings = check_program(prog)
    assert errors == [] and warnings == []
    assert parse_st(to_st(prog)) == prog


def test_structure_of_documented_example():
    pou = parse_seq(documented_example(), "doc.seq").pous[0]
    assert pou.name == "Station"
    sfc = pou.body
    assert sfc.initial_step.name == "Idle"
    kinds = {d.name: b.kind for b in pou.var_blocks for d in b.decls}
    assert kinds["Start"] == "VAR_INPUT" and kinds["YA"] == "VAR_OUTPUT"
    assert kinds["cycles"] == "VAR"
    stop = next(d for d in pou.decls() if d.name == "Stop")
    assert stop.init == ir.Literal(True, "BOOL") and stop.type == ir.NamedType("BOOL")
    by_source = {}
    for t in sfc.transitions:
        by_source.setdefault(tuple(t.sources), []).append(t)
    assert by_source[("ExtendA",)][0].targets == ["ExtendB", "Blow"]
    assert by_source[("DoneB", "DoneBlow")][0].targets == ["Back"]
    # timed wait names the step's own timer
    assert by_source[("Blow",)][0].condition == ir.Binary(
        ">=", ir.Member(ir.Name("Blow"), "T"), ir.Literal(2 * 10**9, "TIME"))
    # order of 'when' lines is priority
    assert [t.priority for t in by_source[("Back",)]] == [0, 1]
    blow = next(s for s in sfc.steps if s.name == "Blow")
    assert blow.actions == [ir.ActionAssoc("Knife", "L", ir.Literal(1_500_000_000, "TIME"))]
    assert sfc.actions[0].name == "CountCycle"


@pytest.mark.parametrize("text, ns", [("2s", 2 * 10**9), ("1500ms", 1_500_000_000),
                                      ("1.5s", 1_500_000_000), ("T#1m", 60 * 10**9)])
def test_bare_and_iec_durations(text, ns):
    prog = parse_seq(f"output Y\ninitial step A\n D {text} Y\n after {text} -> A")
    step = prog.pous[0].body.steps[0]
    assert step.actions[0].time == ir.Literal(ns, "TIME")


def test_after_with_condition_and_name_from_file():
    prog = parse_seq("input go\ninitial step A\n after 1s when go goto B\nstep B", "my-chart.seq")
    assert prog.pous[0].name == "my_chart"
    cond = prog.pous[0].body.transitions[0].condition
    assert cond.op == "AND" and cond.right == ir.Name("go")


def test_keywords_case_insensitive():
    prog = parse_seq("INPUT go\nInitial Step A\n WHEN go -> B\nSTEP B\n")
    assert len(prog.pous[0].body.steps) == 2


@pytest.mark.parametrize("src, line, col, fragment", [
    ("input go\nstep A\n when go -> A\n", 2, 1, "exactly one 'initial step'"),
    ("input go\ninitial step A\n when go B\n", 3, 10, "expected"),
    ("initial step A\n X Y\n", 2, 2, "unknown action qualifier 'X'"),
    ("output Y\ninitial step A\n L Y\n", 3, 2, "needs a time"),
])
def test_errors_have_positions(src, line, col, fragment):
    with pytest.raises(ProgramError) as ei:
        parse_seq(src, "bad.seq")
    assert (ei.value.line, ei.value.col) == (line, col), str(ei.value)
    assert fragment in ei.value.message


def test_undeclared_signal_is_a_check_error():
    prog = parse_seq("initial step A\n when missing -> A\n", "u.seq")
    errors, _ = check_program(prog)
    assert [e.message for e in errors] == ["undeclared name 'missing'"]
