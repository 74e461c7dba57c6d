"""Syntax errors name file, line and column, and say what was found and expected."""
import pytest

from plcpred.parser import ProgramError, parse_st


@pytest.mark.parametrize("src, line, col, fragments", [
    # missing semicolon: reported at the end of the line that lacks it
    ("PROGRAM P\nVAR x : INT; END_VAR\nx := 1\nx := 2;\nEND_PROGRAM", 3, 7, ["expected ';'"]),
    ("PROGRAM P\nVAR x : INT; END_VAR\nIF x > THEN x := 1; END_IF\nEND_PROGRAM", 3, 8,
     ["keyword THEN", "expected an expression"]),
    ("PROGRAM P\nVAR x : INT; END_VAR\nx := (1 + 2;\nEND_PROGRAM", 3, 12, ["';'", "')'"]),
    ("PROGRAM P\nx := 1;\nEND_FUNCTION", 3, 1, ["END_FUNCTION", "END_PROGRAM"]),
    # (a POU left open at the end of its file is read to there, with a warning:
    # test_dialects, as CODESYS's editor shows a POU)
    ("PROGRAM P\nVAR x : INT;\n", 2, 13, ["end of file", "END_VAR"]),
    ("PROGRAM P\nVAR x INT; END_VAR\nEND_PROGRAM", 2, 7, ["identifier 'INT'", "':'"]),
    ("PROGRAM P\nCASE x OF\n  y := 1;\nEND_CASE\nEND_PROGRAM", 3, 3, ["CASE label"]),
    ("PROGRAM P\nx;\nEND_PROGRAM", 2, 1, ["':='"]),
    # a statement left open: at the statement, naming the token that ended it and its line
    ("PROGRAM P\nIF a THEN\n  x := 1;\nEND_WHILE\nEND_PROGRAM", 2, 1,
     ["IF is not closed", "END_IF", "END_WHILE at line 4"]),
    ("PROGRAM P\nVAR x : BOOL; END_VAR\nIF x THEN\n  x := 1;\nEND_PROGRAM", 3, 1,
     ["IF is not closed: expected END_IF before keyword END_PROGRAM at line 5"]),
    ("PROGRAM P\nWHILE a DO\n  FOR i := 1 TO 3 DO\n    x := 1;\nEND_WHILE\nEND_PROGRAM", 3, 3,
     ["FOR is not closed", "END_FOR", "END_WHILE at line 5"]),
    ("PROGRAM P\nCASE n OF\n1: x := 1;\nFUNCTION_BLOCK F\nEND_FUNCTION_BLOCK", 2, 1,
     ["CASE is not closed", "FUNCTION_BLOCK at line 4"]),
    ("PROGRAM P\nREPEAT\n  x := 1;\nEND_PROGRAM", 2, 1, ["UNTIL ... END_REPEAT"]),
    ("PROGRAM P\nIF a THEN\n  x := 1;\n", 2, 1, ["IF is not closed", "end of the file"]),
    ("PROGRAM P\nIF a THEN x := 1;\nELSEIF b THEN x := 2;\nEND_IF\nEND_PROGRAM", 3, 1,
     ["did you mean ELSIF"]),
    ("PROGRAM P\nx ?= 1 2;\nEND_PROGRAM", 2, 8, ["'2'"]),
    ("PROGRAM P\nINITIAL_STEP A: x(Q); END_STEP\nEND_PROGRAM", 2, 17, ["qualifier 'Q'"]),
    ("PROGRAM P\nSTEP A: END_STEP\nEND_PROGRAM", 1, 1, ["INITIAL_STEP"]),
    ("FUNCTION_BLOCK F\nPROPERTY P : INT\nFETCH P := 1; END_GET\nEND_PROPERTY\nEND_FUNCTION_BLOCK",
     3, 1, ["GET or SET"]),
])
def test_syntax_error_positions(src, line, col, fragments):
    with pytest.raises(ProgramError) as ei:
        parse_st(src, "prog.st")
    err = ei.value
    assert (err.file, err.line, err.col) == ("prog.st", line, col), str(err)
    for f in fragments:
        assert f in err.message, err.message


@pytest.mark.parametrize("src", [
    "PROGRAM P\nx ?= 1 2;\nEND_PROGRAM", "PROGRAM P\nx REF= ;\nEND_PROGRAM",
    "PROGRAM P\nVAR a : INT END_VAR\nEND_PROGRAM", "PROGRAM P\nx S= 1 2;\nEND_PROGRAM",
    "PROGRAM P\na := b c;\nEND_PROGRAM", "PROGRAM P\nfb(a := 1 b := 2);\nEND_PROGRAM",
])
def test_messages_use_no_internal_token_names(src):
    with pytest.raises(ProgramError) as ei:
        parse_st(src, "prog.st")
    for internal in ("ATTEMPT", "REFASSIGN", "SETASSIGN", "INLINE_CODE", "_SEMI", "NAME", "$END",
                     "_LIT"):
        assert internal not in ei.value.message


def test_all_syntax_errors_of_a_file_are_reported_up_to_20(tmp_path, capsys):
    from plcpred.cli import main
    src = ("PROGRAM P\nVAR x : INT; y : BOOL; END_VAR\nx := 1 2;\ny := TRUE;\nx := ;\n"
           "IF y THEN\n  x := 3 +;\nEND_IF\nx := x * ;\nEND_PROGRAM\n")
    with pytest.raises(ProgramError) as ei:
        parse_st(src, "e.st")
    found = [(e.line, e.col) for e in [ei.value, *ei.value.more]]
    assert found == [(3, 8), (5, 6), (7, 11), (9, 10)]
    f = tmp_path / "e.st"
    f.write_text(src)
    assert main(["check", str(f)]) == 1
    assert len(capsys.readouterr().err.strip().splitlines()) == 4
    # a correct file after recovery parses the same as ever; 30 errors stop at 20
    many = "PROGRAM P\nVAR x : INT; END_VAR\n" + "x := 1 2;\n" * 30 + "END_PROGRAM\n"
    with pytest.raises(ProgramError) as ei:
        parse_st(many, "m.st")
    assert 1 + len(ei.value.more) == 20


def test_recovery_reports_an_error_in_a_later_pou_and_stops_at_a_bad_character():
    src = ("FUNCTION_BLOCK A\nVAR x : INT; END_VAR\nx := ;\nEND_FUNCTION_BLOCK\n"
           "PROGRAM P\nVAR y : INT; END_VAR\ny := y + ;\ny := 1 # 2;\nEND_PROGRAM\n")
    with pytest.raises(ProgramError) as ei:
        parse_st(src, "e.st")
    found = [(e.line, e.message[:20]) for e in [ei.value, *ei.value.more]]
    assert [line for line, _ in found] == [3, 7, 8]
