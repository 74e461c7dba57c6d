"""Tokenizer: literals, comments, pragmas, case-insensitive and context keywords."""
import pytest

from plcpred.parser import ProgramError
from plcpred.parser.lexer import Tokenizer


def types(text):
    return [(t.type, str(t)) for t in Tokenizer(text)]


def test_nested_comments_and_line_comments_are_skipped():
    toks = types("a (* outer (* inner *) still comment *) b // tail\n/* c */ d")
    assert [v for _, v in toks] == ["a", "b", "d"]


def test_positions_count_lines_inside_comments_and_strings():
    toks = list(Tokenizer("(* one\ntwo *)\n  x := 'a\nb';\ny"))
    by_value = {str(t): (t.line, t.column) for t in toks}
    assert by_value["x"] == (3, 3)
    assert by_value["y"] == (5, 1)


def test_keywords_are_case_insensitive():
    assert types("if If IF")[0][0] == types("IF")[0][0] == "IF"
    assert {t for t, _ in types("if If IF")} == {"IF"}


def test_step_is_an_identifier_unless_the_file_uses_sfc_steps():
    assert types("Step := 1;")[0][0] == "NAME"
    assert types("STEP s1: END_STEP")[0][0] == "STEP"


def test_typed_time_date_and_enum_literals_are_single_tokens():
    toks = types("T#1h2m3s4ms TIME#-250ms INT#-5 16#FF 2#1010_0101 TOD#12:30:00 "
                 "D#2024-01-15 DT#2024-01-15-08:00:00 E_Mode#Run %IX0.1 %Q* 1.5E-3")
    assert [t for t, _ in toks] == ["TIME_LIT", "TIME_LIT", "TYPED_LIT", "INTEGER", "INTEGER",
                                    "TOD_LIT", "DATE_LIT", "DT_LIT", "ENUM_LIT", "ADDRESS",
                                    "ADDRESS", "REAL"]


def test_range_dots_are_not_a_real_number():
    assert [t for t, _ in types("1..5")] == ["INTEGER", "_DOTDOT", "INTEGER"]


def test_pragmas_are_collected_with_position():
    tk = Tokenizer("{attribute 'qualified_only'}\nx")
    list(tk)
    assert tk.pragmas == [("{attribute 'qualified_only'}", 1, 1)]


@pytest.mark.parametrize("text, line, col, fragment", [
    ("x := 1;\n(* never closed", 2, 1, "never closed"),
    ("x := 'abc", 1, 6, "unexpected character \"'\""),
    ("x := 1 $ 2;", 1, 8, "unexpected character '$'"),
    ("a\n  \n  @", 3, 3, "unexpected character '@'"),
    ("x := T#5parsecs;", 1, 8, "malformed TIME"),
])
def test_lexical_errors_carry_line_and_column(text, line, col, fragment):
    with pytest.raises(ProgramError) as ei:
        list(Tokenizer(text, "f.st"))
    assert (ei.value.line, ei.value.col) == (line, col)
    assert fragment in ei.value.message
    assert str(ei.value).startswith(f"f.st:{line}:{col}: ")


def test_comments_nest_and_an_unbalanced_one_is_read_the_matiec_way():
    from plcpred.parser import parse_st
    nested = "PROGRAM P\nVAR x : INT; END_VAR\n(* a (* nested *) comment *)\nx := 1;\nEND_PROGRAM\n"
    assert len(parse_st(nested).pou("P").body) == 1
    # matiec does not nest: '(*' inside a comment opens nothing, the first '*)' closes it
    flat = "PROGRAM P\nVAR x : INT; END_VAR\n(* from (* OSCAT *)\nx := 1;\nEND_PROGRAM\n"
    assert len(parse_st(flat).pou("P").body) == 1
    with pytest.raises(Exception, match="never closed"):
        parse_st("PROGRAM P\n(* open\nEND_PROGRAM\n")
