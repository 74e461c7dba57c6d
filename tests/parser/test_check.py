"""Semantic checks: errors a PLC compiler would stop on, and warnings."""
from plcpred.parser import parse_st
from plcpred.parser.check import check_program


def run(src, *context):
    prog = parse_st(src, "c.st")
    errors, warnings = check_program(prog, [parse_st(c, "ctx.st") for c in context])
    return [(e.line, e.message) for e in errors], [(w.line, w.message) for w in warnings]


def test_clean_program_has_no_findings():
    errors, warnings = run("""PROGRAM P
    VAR_INPUT start : BOOL; END_VAR
    VAR_OUTPUT valve : BOOL; END_VAR
    VAR t : TON; END_VAR
    t(IN := start, PT := T#1s);
    valve := t.Q;
    END_PROGRAM""")
    assert errors == [] and warnings == []


def test_undeclared_name_and_unknown_function():
    errors, _ = run("PROGRAM P\nVAR x : INT; END_VAR\nx := y + 1;\nx := Foo(2);\nEND_PROGRAM")
    assert errors == [(3, "undeclared name 'y'"),
                      (4, "unknown function or function block instance 'Foo'")]


def test_unknown_types_and_fb_types():
    errors, _ = run("PROGRAM P\nVAR t : TONN; s : ST_Missing; END_VAR\nEND_PROGRAM")
    assert [l for l, _ in errors] == [2, 2]
    assert "unknown type 'TONN'" in errors[0][1]


def test_unknown_fb_member_and_parameter():
    errors, _ = run("""PROGRAM P
    VAR t : TON; b : BOOL; END_VAR
    t(IN := b, PTT := T#1s);
    b := t.QQ;
    END_PROGRAM""")
    assert errors == [(3, "TON has no input 'PTT'"),
                      (4, "'t' (TON) has no input, output, method or property 'QQ'")]


def test_assignment_to_inputs_constants_and_fb_outputs():
    errors, warnings = run("""FUNCTION_BLOCK F
    VAR_INPUT i : INT; END_VAR
    VAR_OUTPUT o : INT; END_VAR
    VAR CONSTANT K : INT := 1; END_VAR
    VAR s AT %IX0.0 : BOOL; t : TON; END_VAR
    i := 2;
    K := 3;
    s := TRUE;
    t.Q := TRUE;
    %IX0.1 := FALSE;
    t.IN := TRUE;
    o := i + K;
    END_FUNCTION_BLOCK""")
    messages = [m for _, m in errors]
    # CODESYS and TwinCAT accept writing one's own input: a warning, not an error
    assert [m for _, m in warnings if "'i'" in m] == [
        "assignment to input 'i' (accepted as CODESYS and TwinCAT do; IEC 61131-3 forbids it)"]
    assert messages == ["cannot assign to constant 'K'",
                        "cannot assign to output 'Q' of TON instance 't'"]
    # a located input too (CODESYS, TwinCAT and Beremiz compile it; the next scan's
    # input image overwrites it)
    assert [m.split(" (")[0] for _, m in warnings if "located" in m or "%IX0.1" in m] == [
        "assignment to input 's' located at %IX0.0", "assignment to input %IX0.1"]


def test_duplicate_declarations():
    errors, _ = run("""PROGRAM P
    VAR a : INT; A : BOOL; END_VAR
    a := 1;
    END_PROGRAM
    PROGRAM P END_PROGRAM""")
    assert any("duplicate declaration of 'A'" in m for _, m in errors)
    assert any("duplicate declaration of 'P'" in m for _, m in errors)


def test_unused_variable_and_unwritten_output_warnings():
    _, warnings = run("""PROGRAM P
    VAR_OUTPUT done : BOOL; END_VAR
    VAR unused : INT; lamp AT %QX0.0 : BOOL; END_VAR
    END_PROGRAM""")
    assert warnings == [(2, "output 'done' is never written"),
                        (3, "variable 'unused' is declared but never used"),
                        (3, "output 'lamp' is never written")]


def test_context_program_provides_globals():
    src = "PROGRAM P\nVAR_EXTERNAL g : BOOL; END_VAR\ng := NOT gIn;\nEND_PROGRAM"
    errors, _ = run(src)
    assert errors == [(3, "undeclared name 'gIn'")]
    errors, _ = run(src, "VAR_GLOBAL gIn AT %IX0.0 : BOOL; END_VAR")
    assert errors == []


def test_enum_values_qualified_and_hash_form():
    errors, _ = run("""TYPE E : (A, B); END_TYPE
    PROGRAM P
    VAR m : E; END_VAR
    m := E.A; m := E#B; m := E.C; m := E#D; m := F#A;
    END_PROGRAM""")
    assert [m for _, m in errors] == ["enumeration E has no value 'C'",
                                      "enumeration E has no value 'D'",
                                      "unknown enumeration type 'F'"]


def test_inherited_members_methods_and_jump_labels():
    errors, _ = run("""FUNCTION_BLOCK Base
    VAR_OUTPUT q : BOOL; END_VAR
    q := TRUE;
    END_FUNCTION_BLOCK
    FUNCTION_BLOCK D EXTENDS Base
    VAR_INPUT i : BOOL; END_VAR
    q := i;
    Helper();
    JMP nowhere;
    METHOD Helper
    q := FALSE;
    END_METHOD
    END_FUNCTION_BLOCK""")
    assert [m for _, m in errors] == ["JMP to undefined label 'nowhere'"]


def test_sfc_unknown_step_and_action():
    errors, _ = run("""PROGRAM S
    VAR go : BOOL; END_VAR
    INITIAL_STEP A: Missing(N); END_STEP
    TRANSITION FROM A TO B := go AND A.X; END_TRANSITION
    END_PROGRAM""")
    assert [m for _, m in errors] == ["step A: unknown action or variable 'Missing'",
                                      "transition refers to unknown step 'B'"]


def test_samples_check_clean(samples_dir):
    from plcpred.parser import load_program
    for path in sorted(samples_dir.rglob("*.st")):
        errors, _ = check_program(load_program(path))
        assert errors == [], (path, [str(e) for e in errors])


def test_a_constant_read_only_in_a_declaration_is_used():
    from plcpred.parser import parse_st
    from plcpred.parser.check import check_program
    prog = parse_st("PROGRAM P\nVAR\n  a : ARRAY[1..N] OF INT;\n  s : STRING(L);\nEND_VAR\n"
                    "VAR CONSTANT\n  N : INT := 3;\n  L : INT := 8;\n  unused : INT := 1;\n"
                    "END_VAR\na[3] := 5; s := 'x';\nEND_PROGRAM\n", "t.st")
    errors, warnings = check_program(prog)
    assert errors == []
    assert [w.message for w in warnings] == ["variable 'unused' is declared but never used"]


def test_a_method_bound_may_name_a_constant_of_a_later_block():
    errors, _ = run("""FUNCTION_BLOCK FB_Fwd
METHOD Fill : UINT
VAR
    a : ARRAY[1..LEN_A] OF UINT;
END_VAR
VAR CONSTANT
    LEN_A : UINT := 2;
END_VAR
Fill := a[1];
END_METHOD
END_FUNCTION_BLOCK""")
    assert errors == []
    errors, _ = run("""FUNCTION_BLOCK FB_Fwd
METHOD Fill : UINT
VAR
    a : ARRAY[1..LEN_B] OF UINT;
END_VAR
Fill := a[1];
END_METHOD
END_FUNCTION_BLOCK""")
    assert errors == [(4, "undeclared name 'LEN_B'")]


def test_a_warning_is_not_an_error():
    """``except ProgramError`` must not swallow a warning, and a warning prints as one."""
    from plcpred.parser.errors import ProgramError, ProgramWarning
    w = ProgramWarning("unused variable", "a.st", 3, 7)
    assert not isinstance(w, ProgramError) and not isinstance(w, BaseException)
    assert str(w) == "a.st:3:7: warning: unused variable"
    assert str(ProgramError("bad", "a.st", 1, 2)) == "a.st:1:2: bad"
