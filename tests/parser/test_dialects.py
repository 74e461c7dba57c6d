"""Vendor dialects: constructs found in real CODESYS, TwinCAT, B&R and Beremiz code, each
read as its vendor reads it (one test per construct, not per file)."""
import re

import pytest

from plcpred.parser import ir, parse_st
from plcpred.parser.check import check_program
from plcpred.parser.printer import to_st
from plcpred.sequencer import CompileError, ExecutionError
from plcpred.sequencer.executor import ProgramInstance

MS = 1_000_000


def body(decls, code, name="P"):
    return f"PROGRAM {name}\nVAR\n{decls}\nEND_VAR\n{code}\nEND_PROGRAM\n"


def trace(src, outputs, inputs, scans=10, scan_ms=10):
    """Values of ``outputs`` after each scan, with ``inputs(k)`` set before scan k."""
    inst = ProgramInstance(parse_st(src, "t.st"))
    prog = inst.programs[0]
    got = []
    for k in range(scans):
        for name, value in inputs(k).items():
            setattr(prog, name, value)
        inst.guard(inst.scan, k * scan_ms * MS)
        got.append(tuple(getattr(prog, o) for o in outputs))
    return got


def problems(src):
    errors, _ = check_program(parse_st(src, "t.st"))
    return [str(e) for e in errors]


def checked_scan(src):
    """The PROGRAM of ``src`` after one scan, ``src`` having checked without errors."""
    assert problems(src) == []
    inst = ProgramInstance(parse_st(src, "t.st"))
    inst.guard(inst.scan, 0)
    return inst.programs[0]


# ---------------------------------------------------------------- standard FB pin names
PIN_DECLS = "c : CTU; d : CTD; ud : CTUD; s : SR; r : RS; x, y : BOOL; n, m, k : INT; qs, qr : BOOL;"
PIN_CODES = {
    "iec": "c(CU := x, R := y, PV := 3); d(CD := x, LD := y, PV := 2);"
           "ud(CU := x, CD := FALSE, R := y, LD := FALSE, PV := 2);"
           "s(S1 := x, R := y, Q1 => qs); r(S := x, R1 := y, Q1 => qr);"
           "n := c.CV; m := d.CV; k := ud.CV;",
    "codesys": "c(CU := x, RESET := y, PV := 3); d(CD := x, LOAD := y, PV := 2);"
               "ud(CU := x, CD := FALSE, RESET := y, LOAD := FALSE, PV := 2);"
               "s(SET1 := x, RESET := y, Q1 => qs); r(SET := x, RESET1 := y, Q1 => qr);"
               "n := c.CV; m := d.CV; k := ud.CV;",
}


def _pin_inputs(k):
    # x toggles every scan; y (reset / load) is high on scans 5 and 6
    return {"X": k % 2 == 0, "Y": k in (5, 6)}


def test_codesys_pin_names_of_standard_fbs_run_as_the_iec_pins():
    outs = ("N", "M", "K", "QS", "QR")
    iec = trace(body(PIN_DECLS, PIN_CODES["iec"]), outs, _pin_inputs)
    codesys = trace(body(PIN_DECLS, PIN_CODES["codesys"]), outs, _pin_inputs)
    assert codesys == iec
    # the reset really acted: the up counter counts x's rising edges until y clears it
    assert [row[0] for row in iec] == [1, 1, 2, 2, 3, 0, 0, 0, 1, 1]
    assert problems(body(PIN_DECLS, PIN_CODES["codesys"])) == []


def test_vendor_pin_names_as_members_and_in_initialisers():
    src = body("c : CTU; t : TON := (PT := T#20MS); q : BOOL; n : INT;",
               "c.RESET := TRUE; c(CU := TRUE, PV := 1); n := c.CV; t(IN := TRUE, Q => q);")
    got = trace(src, ("N", "Q"), lambda k: {})
    assert got[0] == (0, False) and got[2] == (0, True)   # held in reset; TON fires at 20 ms
    assert problems(src) == []


def test_a_pin_of_another_fb_is_still_rejected():
    src = body("t : TON; x : BOOL;", "t(IN := TRUE, RESET := FALSE); x := t.CV;")
    errors = problems(src)
    assert any("RESET" in e for e in errors) and any("CV" in e for e in errors)
    with pytest.raises(CompileError):
        ProgramInstance(parse_st(src, "t.st"))


# ---------------------------------------------------------------- opaque code
def test_beremiz_inline_c_is_kept_and_only_executing_it_is_an_error():
    from plcpred.sequencer import ExecutionError
    src = body("x : BOOL; n : INT;",
               "IF x THEN\n  {{ printf(\"hi\\n\");\n     fflush(stdout); }}\nEND_IF;\nn := n + 1;\nn := n +;")
    with pytest.raises(Exception) as e:   # the line count after the block is exact
        parse_st(src, "t.st")
    assert (e.value.line, e.value.col) == (10, 9)
    src = src.replace("n := n +;", "")
    errors, warnings = check_program(parse_st(src, "t.st"))
    assert errors == [] and [(w.line, w.col) for w in warnings] == [(6, 3)]
    assert trace(src, ("N",), lambda k: {}, scans=2) == [(1,), (2,)]   # never reached
    with pytest.raises(ExecutionError) as e:
        trace(src, ("N",), lambda k: {"X": k == 1}, scans=2)
    assert (e.value.line, "inline code" in str(e.value)) == (6, True)


# ---------------------------------------------------------------- expressions
def test_operators_called_as_functions():
    src = body("a, b, c, x, y, z : BOOL; n : INT := 17; m : INT;",
               "x := AND(a, b, c); y := OR(a, b); z := XOR(a, b); m := MOD(n, 5);")
    got = trace(src, ("X", "Y", "Z", "M"), lambda k: {"A": True, "B": k == 1, "C": True}, 2)
    assert got == [(False, True, True, 2), (True, True, False, 2)]
    assert problems(src) == []


# ---------------------------------------------------------------- statements
def test_an_array_element_or_member_as_for_variable():
    src = body("i : ARRAY[0..1] OF INT; n : INT; s : ARRAY[1..3] OF INT;",
               "n := 0;\nFOR i[1] := 1 TO 3 DO\n  s[i[1]] := i[1] * 10;\n  n := n + i[1];\nEND_FOR")
    inst = ProgramInstance(parse_st(src, "t.st"))
    inst.scan(0)
    p = inst.programs[0]
    assert (p.N, list(p.S), list(p.I)) == (6, [10, 20, 30], [0, 4])   # IEC: ends past END
    assert problems(src) == []
    from plcpred.parser.printer import to_st
    assert parse_st(to_st(parse_st(src, "t.st")), "t.st") == parse_st(src, "t.st")


# ---------------------------------------------------------------- declarations
def test_fb_init_arguments_in_declarations_parse_print_and_warn():
    src = ("FUNCTION_BLOCK FB_T\nVAR_INPUT\n  q : INT;\nEND_VAR\nEND_FUNCTION_BLOCK\n"
           + body("a : R_TRIG(); b : FB_T(5, x := 2) := (q := 1); r : INT(0..10);", "r := b.q;"))
    prog = parse_st(src, "t.st")
    decls = {d.name: d for d in prog.pou("P").decls()}
    assert decls["a"].init_args == [] and decls["r"].init_args is None
    assert [a.name for a in decls["b"].init_args] == [None, "x"]
    from plcpred.parser.printer import to_st
    assert parse_st(to_st(prog), "t.st") == prog
    errors, warnings = check_program(prog)
    assert errors == [] and [w.line for w in warnings if "FB_init" in w.message] == [8]
    assert trace(src, ("R",), lambda k: {}, scans=1) == [(1,)]
    with pytest.raises(Exception, match="FB_init arguments belong in a variable declaration"):
        parse_st("TYPE T : ARRAY[0..1] OF FB_T(1); END_TYPE", "t.st")


def test_semicolons_after_headers_and_access_specifiers():
    src = ("FUNCTION_BLOCK PUBLIC FB_A;\nVAR\n  n : INT;\nEND_VAR\n"
           "METHOD PUBLIC M : INT;\nM := n;\nEND_METHOD\n"
           "PROPERTY P : INT;\nPUBLIC GET\nP := n;\nEND_GET\nEND_PROPERTY\n"
           "END_FUNCTION_BLOCK\nINTERFACE PUBLIC I_X;\nEND_INTERFACE\n"
           "PROGRAM INTERNAL Main;\nVAR\n  fb : FB_A;\n  k : INT;\nEND_VAR\nk := fb.M() + fb.P + 1;\n"
           "END_PROGRAM\n")
    prog = parse_st(src, "t.st")
    assert prog.pou("Main").access == "INTERNAL" and prog.pou("FB_A").access == "PUBLIC"
    assert trace(src, ("K",), lambda k: {}, scans=1) == [(1,)]


def test_based_literals_in_base_10_and_the_unsigned_ltime_range():
    src = body("n : INT; t : LTIME;", "n := 10#12 + 2#1; t := LTIME#213503D23H34M33S709MS551US615NS;")
    assert trace(src, ("N", "T"), lambda k: {}, scans=1) == [(13, 2**64 - 1)]


# ---------------------------------------------------------------- calls
def test_implicit_en_eno_on_fb_and_function_calls():
    src = ("FUNCTION F_Twice : INT\nVAR_INPUT\n  a : INT;\nEND_VAR\nF_Twice := 2 * a;\n"
           "END_FUNCTION\n"
           + body("c : CTU; go, ok, ok2 : BOOL; n, m : INT;",
                  "c(EN := go, CU := NOT c.CU, PV := 100, ENO => ok);\nn := c.CV;\n"
                  "m := F_Twice(EN := go, a := n, ENO => ok2);"))
    got = trace(src, ("N", "M", "OK", "OK2"), lambda k: {"GO": k in (0, 1, 2, 5)}, scans=6)
    # the counter counts only on scans where EN is TRUE (its CU toggles only then, too)
    assert got == [(1, 2, True, True), (1, 2, True, True), (2, 4, True, True),
                   (2, 4, False, False), (2, 4, False, False), (2, 4, True, True)]
    assert problems(src) == []


def test_assigning_to_ones_own_input_runs_with_a_warning():
    src = ("FUNCTION_BLOCK FB_Clip\nVAR_INPUT\n  x : INT;\nEND_VAR\nVAR_OUTPUT\n  y : INT;\n"
           "END_VAR\nIF x > 10 THEN x := 10; END_IF\ny := x;\nEND_FUNCTION_BLOCK\n"
           + body("fb : FB_Clip; r : INT;", "fb(x := 25);\nr := fb.y;"))
    errors, warnings = check_program(parse_st(src, "t.st"))
    assert errors == [] and any("assignment to input 'x'" in w.message for w in warnings)
    assert trace(src, ("R",), lambda k: {}, scans=1) == [(10,)]


def test_a_method_called_by_its_bare_name_inside_its_fb_and_a_derived_one():
    src = ("FUNCTION_BLOCK FB_A\nVAR\n  n : INT;\nEND_VAR\nBump(2);\n"
           "METHOD Bump : INT\nVAR_INPUT\n  k : INT;\nEND_VAR\nn := n + k;\nBump := n;\nEND_METHOD\n"
           "END_FUNCTION_BLOCK\n"
           "FUNCTION_BLOCK FB_B EXTENDS FB_A\nVAR_OUTPUT\n  m : INT;\nEND_VAR\nm := Bump(10);\n"
           "END_FUNCTION_BLOCK\n"
           + body("a : FB_A; b : FB_B; r : INT;", "a(); b(); r := a.n * 100 + b.m;"))
    assert trace(src, ("R",), lambda k: {}, scans=2) == [(210,), (420,)]
    assert problems(src) == []


def test_set_and_reset_assignments_and_a_variable_named_s():
    src = body("q, r, s, go, eq : BOOL; arr : ARRAY[0..1] OF BOOL := [FALSE, TRUE];",
               "q S= go;\narr[1] R= go;\nr R= s;\ns := go;\neq := s = TRUE;")
    got = trace(src, ("Q", "EQ"), lambda k: {"GO": k == 1}, scans=3)
    assert got == [(False, False), (True, True), (True, False)]   # S= holds, = compares
    prog = parse_st(src, "t.st")
    assert [s.op for s in prog.pou("P").body] == ["S=", "R=", "R=", ":=", ":="]


def test_twincat_conditional_return_and_trailing_commas():
    src = ("INTERFACE I_A\nEND_INTERFACE\nINTERFACE I_B\nEND_INTERFACE\n"
           "FUNCTION_BLOCK FB_A IMPLEMENTS I_A, I_B,\nVAR_INPUT\n  go : BOOL;\nEND_VAR\n"
           "VAR_OUTPUT\n  n : INT;\nEND_VAR\nRETURN(NOT go);\nn := n + 1;\nEND_FUNCTION_BLOCK\n"
           + body("fb : FB_A; x : BOOL; m : INT;", "fb(go := x,\n);\nm := fb.n;"))
    assert trace(src, ("M",), lambda k: {"X": k != 1}, scans=4) == [(1,), (1,), (2,), (3,)]
    assert problems(src) == []


def test_fb_init_arguments_on_a_namespaced_type():
    src = ("FUNCTION_BLOCK FB_Rng\nVAR_INPUT\n  seed : INT;\nEND_VAR\nEND_FUNCTION_BLOCK\n"
           + body("r : Lib.FB_Rng(0); s : Lib.FB_Rng; sub : INT(0..9);", ""))
    decl = next(parse_st(src, "t.st").pou("P").decls())
    assert (decl.type.name, len(decl.init_args)) == ("Lib.FB_Rng", 1)


def test_chained_assignment_and_return_with_an_assignment():
    src = ("FUNCTION_BLOCK FB_A\nVAR_INPUT\n  t : REAL;\nEND_VAR\nVAR_OUTPUT\n  bInit : BOOL;\n"
           "  n : INT;\nEND_VAR\nRETURN(bInit := t <= 0);\nn := n + 1;\nEND_FUNCTION_BLOCK\n"
           + body("fb : FB_A; a, b : INT; m : INT; k : REAL;",
                  "a := b := 7;\nCASE a OF 7: a := b := 8; END_CASE\nfb(t := k);\nm := fb.n;"))
    got = trace(src, ("A", "B", "M"), lambda k: {"K": float(k % 2)}, scans=3)
    assert got == [(8, 8, 0), (8, 8, 1), (8, 8, 1)]
    assert problems(src) == []


def test_empty_output_bindings_and_empty_declarations():
    src = ("FUNCTION_BLOCK FB_A\nVAR_OUTPUT\n  q : BOOL := TRUE;\n  n : INT := 3;\nEND_VAR\n"
           "END_FUNCTION_BLOCK\n"
           + body("fb : FB_A;; t : TON;; m : INT;",
                  "fb(q =>, n => m);\nt(IN := TRUE, PT := T#0MS, Q => , ET =>\n);"))
    assert trace(src, ("M",), lambda k: {}, scans=1) == [(3,)]
    assert problems(src) == []
    from plcpred.parser.printer import to_st
    assert parse_st(to_st(parse_st(src, "t.st")), "t.st") == parse_st(src, "t.st")


def test_empty_input_bindings_leave_the_input_as_it_was():
    # TwinCAT accepts ``i := ,``: the input is not assigned by this call
    src = ("FUNCTION_BLOCK FB_A\nVAR_INPUT\n  a : INT := 5;\n  b : INT;\nEND_VAR\n"
           "VAR_OUTPUT\n  s : INT;\nEND_VAR\ns := a + b;\nEND_FUNCTION_BLOCK\n"
           + body("fb : FB_A; m, k : INT;",
                  "fb(a := , b := k);\nm := fb.s;\nfb(a := 1, b :=);\nfb(a :=, b :=\n);"
                  "\nk := fb.s;"))
    # scan 2: a keeps the 1 of the call before (not its initial 5), b takes k = 1
    assert trace(src, ("M", "K"), lambda k: {}, scans=2) == [(5, 1), (2, 2)]
    assert problems(src) == []


def test_null_ref_to_bit_literals_partial_access_and_empty_initialisers():
    src = ("TYPE ST_X : STRUCT a : INT := 4; END_STRUCT END_TYPE\n"
           + body("p : POINTER TO INT; r : REF_TO INT; b : BOOL; s : ST_X := (); "
                  "w : WORD := 16#0005; q0, q1, q2 : BOOL; n : INT := 7; m, k : INT; wasnull : BOOL;",
                  "wasnull := p = NULL;\nIF p = NULL THEN p := ADR(n); END_IF\nm := p^;\n"
                  "r := REF(n);\nk := r^ + s.a;\nb := BIT#1;\n"
                  "q0 := w.%X0; q1 := w.%X1; q2 := w.%X2;"))
    got = trace(src, ("WASNULL", "M", "K", "B", "Q0", "Q1", "Q2"), lambda k: {}, scans=2)
    assert got == [(True, 7, 11, True, True, False, True), (False, 7, 11, True, True, False, True)]
    assert problems(src) == []


def test_keywords_as_names_where_the_vendors_allow_them():
    src = ("TYPE ST_Cfg : STRUCT\n  Program : INT;\n  Internal : BOOL;\n  Reference : REAL;\n"
           "END_STRUCT END_TYPE\n"
           "PROGRAM INTERNAL P\nVAR\n  Configuration : ST_Cfg;\n  Internal : BOOL;\n"
           "  p : REFERENCE TO INT;\n  n : INT;\nEND_VAR\n"
           "Configuration.Program := Configuration.Program + 1;\nInternal := NOT Internal;\n"
           "Configuration.Internal := Internal AND TRUE;\nn := Configuration.Program * 2;\n"
           "END_PROGRAM\n")
    assert trace(src, ("N", "INTERNAL"), lambda k: {}, scans=2) == [(2, True), (4, False)]
    assert problems(src) == []
    assert parse_st(src, "t.st").pou("P").access == "INTERNAL"


def test_an_empty_type_block_as_b_and_r_writes_it():
    prog = parse_st("TYPE\nEND_TYPE\nTYPE\n  E : (A, B);\nEND_TYPE\n" + body("e : E;", "e := B;"),
                    "t.typ")
    assert [t.name for t in prog.types] == ["E"]


def test_r_edge_and_f_edge_inputs_see_the_edge_of_the_value_passed():
    src = ("FUNCTION_BLOCK FB_Count\nVAR_INPUT\n  up : BOOL R_EDGE;\n  down : BOOL F_EDGE;\n"
           "END_VAR\nVAR_OUTPUT\n  n, m : INT;\nEND_VAR\nIF up THEN n := n + 1; END_IF\n"
           "IF down THEN m := m + 1; END_IF\nEND_FUNCTION_BLOCK\n"
           + body("fb : FB_Count; x : BOOL; n, m : INT;", "fb(up := x, down := x);\nn := fb.n; m := fb.m;"))
    # x: F T T F T F: rises at scans 1 and 4, falls at 3 and 5
    xs = [False, True, True, False, True, False]
    got = trace(src, ("N", "M"), lambda k: {"X": xs[k]}, scans=6)
    assert got == [(0, 0), (1, 0), (1, 0), (1, 1), (2, 1), (2, 2)]
    assert problems(src) == []
    from plcpred.parser.printer import to_st
    assert parse_st(to_st(parse_st(src, "t.st")), "t.st") == parse_st(src, "t.st")
    with pytest.raises(Exception, match="expected R_EDGE, F_EDGE"):
        parse_st(body("x : BOOL EDGY;", ""), "t.st")


def test_an_iec_class_is_a_function_block_of_methods():
    src = ("CLASS C_Counter\nVAR\n  x : INT;\nEND_VAR\nMETHOD PUBLIC Bump : INT\nx := x + 1;\n"
           "Bump := x;\nEND_METHOD\nEND_CLASS\n"
           "CLASS C_Twice EXTENDS C_Counter\nMETHOD PUBLIC Bump : INT\nBump := SUPER^.Bump() * 2;\n"
           "END_METHOD\nEND_CLASS\n"
           + body("c : C_Twice; n : INT; Class : INT;", "n := c.Bump(); Class := 1;"))
    assert trace(src, ("N",), lambda k: {}, scans=3) == [(2,), (4,), (6,)]
    assert problems(src) == []
    assert parse_st(src, "t.st").pou("C_Twice").kind == "FUNCTION_BLOCK"
    with pytest.raises(Exception, match="statements belong in its methods"):
        parse_st("CLASS C\nVAR x : INT; END_VAR\nx := 1;\nEND_CLASS\n", "t.st")


def test_anonymous_enumerations_in_declarations_and_values_shared_by_two_enumerations():
    # IEC allows an enumeration written in the declaration; TwinCAT code uses it for
    # state machines. Two enumerations may both have a value of one name: an assignment
    # and a comparison take the one of the other side's type.
    src = ("TYPE E_A : (WAITING, RUN); END_TYPE\nTYPE E_B : (IDLE, BUSY, WAITING); END_TYPE\n"
           + body("eState : (WAITING, TRIGGER_WRITE, CONFIRM_WRITE);\n"
                  "eMode : (Idle := 0, Busy := 5) := Busy;\na : E_A; b : E_B; n, m : INT;",
                  "CASE eState OF\n  WAITING: eState := TRIGGER_WRITE; n := n + 1;\n"
                  "  TRIGGER_WRITE: eState := CONFIRM_WRITE;\n"
                  "  CONFIRM_WRITE: eState := WAITING;\nEND_CASE\n"
                  "IF eMode = Busy THEN n := n + 10; END_IF\n"
                  "b := WAITING; a := WAITING;\nIF b = WAITING THEN m := m + 1; END_IF"))
    assert problems(src) == []
    got = trace(src, ("ESTATE", "EMODE", "N", "A", "B", "M"), lambda k: {}, scans=4)
    assert got == [(1, 5, 11, 0, 2, 1), (2, 5, 21, 0, 2, 2), (0, 5, 31, 0, 2, 3),
                   (1, 5, 42, 0, 2, 4)]


def test_fb_init_arguments_on_an_array_of_function_blocks():
    src = ("FUNCTION_BLOCK FB_V\nVAR_OUTPUT q : INT; END_VAR\nq := q + 1;\n"
           "END_FUNCTION_BLOCK\n"
           + body("v : ARRAY[1..3] OF FB_V(SIZEOF(INT), 0); n : INT;", "v[2](); n := v[2].q;"))
    decl = next(d for d in parse_st(src, "t.st").pou("P").decls() if d.name == "v")
    assert isinstance(decl.type, ir.ArrayType) and len(decl.init_args) == 2
    assert problems(src) == []
    assert trace(src, ("N",), lambda k: {}, scans=2) == [(1,), (2,)]
    from plcpred.parser.printer import to_st
    assert parse_st(to_st(parse_st(src, "t.st")), "t.st") == parse_st(src, "t.st")


def test_anonymous_located_declarations_type_an_address():
    # IEC 61131-3: ``AT %IX1.1 : BOOL;`` declares the address without a name; code reads
    # it by its address
    src = body("AT %IX1.1 : BOOL;\nAT %QW2 : WORD;\nx AT %QX0.0 : BOOL;",
               "x := %IX1.1;\n%QW2 := 16#00FF;")
    prog = parse_st(src, "t.st")
    decls = {d.address: d for d in prog.pou("P").decls()}
    assert decls["%IX1.1"].type == ir.NamedType("BOOL")
    assert decls["%QW2"].type == ir.NamedType("WORD")
    errors, warnings = check_program(prog)
    assert errors == [] and warnings == []
    assert trace(src, ("X",), lambda k: {decls["%IX1.1"].name.upper(): k == 1},
                 scans=3) == [(False,), (True,), (False,)]


def test_var_access_paths_are_read():
    src = ("CONFIGURATION C\nVAR_ACCESS\n  speed : R.Main.nSpeed : INT READ_ONLY;\n"
           "  lamp : %QX0.1 : BOOL;\nEND_VAR\nRESOURCE R ON PLC\n TASK t(INTERVAL := T#10ms);\n"
           " PROGRAM Main WITH t : P;\nEND_RESOURCE\nEND_CONFIGURATION\n"
           + body("nSpeed : INT;", "nSpeed := nSpeed + 1;"))
    prog = parse_st(src, "t.st")
    (block,) = prog.configurations[0].var_blocks
    assert block.kind == "VAR_ACCESS"
    assert [(d.name, d.type) for d in block.decls] == [("speed", ir.NamedType("INT")),
                                                         ("lamp", ir.NamedType("BOOL"))]
    assert problems(src) == []
    with pytest.raises(Exception, match="READ_WRITE or READ_ONLY"):
        parse_st(src.replace("READ_ONLY", "READ_SOMETIMES"), "t.st")


def test_new_gives_a_pointer_to_a_fresh_value_and_delete_clears_it():
    # CODESYS/TwinCAT dynamic memory: __NEW(T) once, used through the pointer, then
    # __DELETE; the null test is the vendors' comparison with 0
    src = """TYPE ST_Data : STRUCT a : INT := 7; END_STRUCT END_TYPE
PROGRAM P
VAR p : POINTER TO INT; s : POINTER TO ST_Data; n : INT; END_VAR
VAR_OUTPUT v : INT; fresh, gone : BOOL; END_VAR
fresh := p = 0;
IF p = 0 THEN p := __NEW(INT); s := __NEW(ST_Data); END_IF
p^ := p^ + 1;
IF s <> 0 THEN v := s^.a + p^; END_IF
n := n + 1;
IF n = 3 THEN __DELETE(s); END_IF
gone := s = 0;
END_PROGRAM
"""
    assert problems(src) == []
    got = trace(src, ["V", "FRESH", "GONE"], lambda k: {}, scans=4)
    assert got == [(8, True, False), (9, False, False), (10, False, True), (10, False, True)]


def test_new_of_pointers_with_fb_init_arguments_and_of_several_elements():
    # TwinCAT Dynamic Collections: __NEW(POINTER TO T, n) for bucket arrays and
    # __NEW(FB_Array_List(Initial_Capacity := 0)) with the FB's FB_init arguments
    src = """TYPE ST_Node : STRUCT v : INT; next : POINTER TO ST_Node; END_STRUCT END_TYPE
FUNCTION_BLOCK FB_List
VAR_OUTPUT cap : INT; END_VAR
METHOD FB_init : BOOL
VAR_INPUT bInitRetains : BOOL; bInCopyCode : BOOL; Initial_Capacity : INT; END_VAR
cap := Initial_Capacity + 1;
END_METHOD
END_FUNCTION_BLOCK
PROGRAM P
VAR
    buckets : POINTER TO POINTER TO ST_Node;
    lst : POINTER TO FB_List;
    one : POINTER TO POINTER TO ST_Node;
    n : UDINT := 4;
    many : BOOL;
END_VAR
VAR_OUTPUT c : INT; nothing : BOOL; END_VAR
IF lst = 0 THEN lst := __NEW(FB_List(Initial_Capacity := 5)); END_IF
IF one = 0 THEN one := __NEW(POINTER TO ST_Node); END_IF
c := lst^.cap;
nothing := one^ = 0;
IF many THEN buckets := __NEW(POINTER TO ST_Node, n); END_IF
END_PROGRAM
"""
    program = parse_st(src, "t.st")
    assert parse_st(to_st(program), "printed.st") == program
    errors, warnings = check_program(program)
    assert errors == []
    assert [w.line for w in warnings if "__NEW with a count" in w.message] == [22]
    assert trace(src, ["C", "NOTHING"], lambda k: {}, scans=1) == [(6, True)]
    # only running the count is an error, at its place
    with pytest.raises(ExecutionError, match=r"t.st:22:\d+: cannot execute __NEW with a "
                                             r"count.*no pointer arithmetic"):
        trace(src, ["C"], lambda k: {"MANY": True}, scans=1)


GENERIC_FB = """FUNCTION_BLOCK FB_Buf
VAR_GENERIC CONSTANT
    maxlen : UDINT := 10;
END_VAR
VAR_INPUT x : INT; END_VAR
VAR_OUTPUT full : BOOL; size : UDINT; END_VAR
VAR buf : ARRAY[0..maxlen - 1] OF INT; n : UDINT; END_VAR
IF n < maxlen THEN buf[n] := x; n := n + 1; END_IF
full := n = maxlen;
size := maxlen;
END_FUNCTION_BLOCK
"""


def test_generic_function_blocks_take_their_constants_per_instance():
    # CODESYS / TwinCAT 3.1.4026: each instance's values in angle brackets size its array
    src = GENERIC_FB + """PROGRAM P
VAR b : FB_Buf<3>; c : FB_Buf<(2 + 3)>; d : ARRAY[1..2] OF FB_Buf<(maxlen := 4)>;
    e : FB_Buf; END_VAR
VAR_OUTPUT fb, fc, fd, fe : BOOL; sizes : UDINT; END_VAR
b(x := 1); c(x := 2); d[1](x := 3); e(x := 4);
fb := b.full; fc := c.full; fd := d[1].full; fe := e.full;
sizes := b.size * 1000 + c.size * 100 + d[2].size * 10 + e.size;
END_PROGRAM
"""
    assert problems(src) == []
    got = trace(src, ["FB", "FC", "FD", "FE"], lambda k: {}, scans=10)
    fills = [next(k for k, row in enumerate(got) if row[i]) + 1 for i in range(4)]
    assert fills == [3, 5, 4, 10]          # each instance's own buffer length
    # printed back as written, and read again to the same program
    program = parse_st(src, "t.st")
    text = to_st(program)
    assert "FB_Buf<3>" in text and "FB_Buf<(2 + 3)>" in text and "(maxlen := 4)" in text
    assert parse_st(text, "printed.st") == program


@pytest.mark.parametrize("decl, message", [
    ("b : FB_Buf<(size := 3)>;", r"t.st:\d+:5: 'size' is no generic constant of FB_Buf"),
    ("b : FB_Buf<3, 4>;", r"FB_Buf has 1 generic constant, not 2"),
    ("b : TON<3>;", r"'TON' has no VAR_GENERIC CONSTANT"),
])
def test_generic_values_that_do_not_fit_are_errors_where_they_are_written(decl, message):
    src = GENERIC_FB + body(decl, "")
    assert any(re.search(message, p) for p in problems(src)), problems(src)


def test_a_generic_block_without_initial_values_exists_through_its_instances():
    src = GENERIC_FB.replace("maxlen : UDINT := 10;", "maxlen : UDINT;") + body(
        "b : FB_Buf<2>;", "b(x := 1);")
    assert problems(src) == []
    src_bad = src.replace("b(x := 1);", "b(x := 1); b.missing := 1;")
    assert any("FB_Buf<2>" in p for p in problems(src_bad)), problems(src_bad)


def test_an_assignment_inside_an_expression_stores_and_gives_the_value():
    # SLAC's LCLSGeneral logger: IF ((nEventIdx := (nEventIdx + 1)) = nMaxEvents) THEN
    src = """PROGRAM P
VAR idx : INT; arr : ARRAY[0..2] OF INT; k : INT; END_VAR
VAR_OUTPUT wraps, last, loops : INT; END_VAR
IF ((idx := (idx + 1)) = 3) THEN idx := 0; wraps := wraps + 1; END_IF
last := (arr[idx] := idx * 10) + 1;
k := 0;
WHILE (k := k + 1) < 4 DO loops := loops + 1; END_WHILE
END_PROGRAM
"""
    assert problems(src) == []
    got = trace(src, ["IDX", "WRAPS", "LAST", "LOOPS"], lambda k: {}, scans=4)
    assert got == [(1, 0, 11, 3), (2, 0, 21, 6), (0, 1, 1, 9), (1, 1, 11, 12)]
    program = parse_st(src, "t.st")
    assert parse_st(to_st(program), "printed.st") == program


def test_an_assignment_inside_an_expression_is_checked_as_a_write():
    src = """PROGRAM P
VAR CONSTANT limit : INT := 3; END_VAR
VAR n : INT; END_VAR
IF (limit := n) > 0 THEN n := 0; END_IF
END_PROGRAM
"""
    assert any("cannot assign to constant 'limit'" in p for p in problems(src))


def test_pouname_gives_the_pou_a_call_stands_in():
    # TcUnit tests name themselves: TEST(__POUNAME());
    src = """FUNCTION_BLOCK FB_Test
VAR_OUTPUT own, meth : STRING; END_VAR
own := __POUNAME();
meth := Name();
METHOD Name : STRING
Name := __POUNAME();
END_METHOD
END_FUNCTION_BLOCK
FUNCTION F_Name : STRING
F_Name := __POUNAME();
END_FUNCTION
PROGRAM P
VAR t : FB_Test; END_VAR
VAR_OUTPUT a, b, c, d : STRING; END_VAR
t(); a := t.own; b := t.meth; c := F_Name(); d := __POUNAME();
END_PROGRAM
"""
    assert problems(src) == []
    got = trace(src, ["A", "B", "C", "D"], lambda k: {}, scans=1)
    assert got == [("FB_Test", "FB_Test.Name", "F_Name", "P")]


def test_fb_init_runs_once_each_instance_is_initialised():
    # CODESYS/TwinCAT: FB_init(bInitRetains, bInCopyCode, ...) with the declaration's
    # arguments, positional after the two flags or by name; a base's FB_init first
    src = """FUNCTION_BLOCK FB_Base
VAR_OUTPUT trace : INT; END_VAR
METHOD FB_init : BOOL
VAR_INPUT bInitRetains : BOOL; bInCopyCode : BOOL; END_VAR
trace := trace * 10 + 1;
END_METHOD
END_FUNCTION_BLOCK
FUNCTION_BLOCK FB_Valve EXTENDS FB_Base
VAR_OUTPUT on_ms : INT; name : STRING; flags : BOOL := TRUE; END_VAR
VAR preset : INT := 7; END_VAR
METHOD FB_init : BOOL
VAR_INPUT bInitRetains : BOOL; bInCopyCode : BOOL; nMs : INT; sName : STRING; END_VAR
on_ms := nMs + preset;      (* the instance's own initial values are already there *)
name := sName;
trace := trace * 10 + 2;
flags := bInitRetains OR bInCopyCode;
END_METHOD
END_FUNCTION_BLOCK
PROGRAM P
VAR
    a : FB_Valve(250, 'A');
    b : FB_Valve(sName := 'B', nMs := 40);
    arr : ARRAY[1..2, 1..2] OF FB_Valve(5, 'X');
    c : FB_Valve;
END_VAR
VAR_OUTPUT ta, tb, tarr, tc, tr : INT; na, nb : STRING; fl : BOOL; END_VAR
ta := a.on_ms; tb := b.on_ms; tarr := arr[2, 1].on_ms; tc := c.on_ms; tr := a.trace;
na := a.name; nb := b.name; fl := a.flags;
END_PROGRAM
"""
    errors, warnings = check_program(parse_st(src, "t.st"))
    assert errors == [] and not [w for w in warnings if "FB_init" in w.message]
    got = trace(src, ["TA", "TB", "TARR", "TC", "TR", "NA", "NB", "FL"], lambda k: {},
                scans=1)
    assert got == [(257, 47, 12, 7, 12, "A", "B", False)]


def test_implicit_en_of_a_call_inside_an_expression():
    # OSCAT: tx := UDINT_TO_TIME(T_PLC_MS(en := TRUE));
    src = ("FUNCTION F_Twice : INT\nVAR_INPUT\n  a : INT;\nEND_VAR\nF_Twice := 2 * a;\n"
           "END_FUNCTION\n"
           + body("go : BOOL; n, m : INT;",
                  "n := 1 + F_Twice(en := TRUE, a := 3);\n"
                  "m := 1 + F_Twice(EN := go, a := 5);"))
    assert problems(src) == []
    got = trace(src, ("N", "M"), lambda k: {"GO": k == 1}, scans=2)
    assert got == [(7, 1), (7, 11)]        # not run: the result type's initial value, 0
    with pytest.raises(CompileError, match="ENO of a call inside an expression"):
        ProgramInstance(parse_st(src.replace("a := 5)", "a := 5, ENO => go)"), "t.st"))


def test_a_program_called_by_its_name_is_its_one_instance():
    # TwinCAT/CODESYS: MAIN calls its sub-programs by name and reads their variables;
    # the task runs MAIN only
    src = """PROGRAM P_Sub
VAR_INPUT go : BOOL; END_VAR
VAR_OUTPUT count : INT; END_VAR
IF go THEN count := count + 1; END_IF
END_PROGRAM
PROGRAM MAIN
VAR_OUTPUT c, d : INT; END_VAR
P_Sub(go := TRUE);
P_Sub(go := TRUE, count => c);
d := P_Sub.count;
END_PROGRAM
CONFIGURATION Cfg
RESOURCE R ON PLC
TASK T(INTERVAL := T#10ms, PRIORITY := 1);
PROGRAM Main WITH T : MAIN;
END_RESOURCE
END_CONFIGURATION
"""
    assert problems(src) == []
    assert trace(src, ["C", "D"], lambda k: {}, scans=3) == [(2, 2), (4, 4), (6, 6)]
    # a program the task also runs is the same instance the others call
    both = src.replace("PROGRAM Main WITH T : MAIN;",
                       "PROGRAM Main WITH T : MAIN;\nPROGRAM Sub WITH T : P_Sub;")
    inst = ProgramInstance(parse_st(both, "t.st"))
    inst.guard(inst.scan, 0)
    main, sub = inst.programs
    # MAIN's two calls, then the task's own, with go still TRUE from MAIN (inputs keep
    # their value between calls): one instance counted three times
    assert (main.C, sub.COUNT) == (2, 3)


# ---------------------------------------------------------------- __TRY / __CATCH
def test_try_catch_finally_catches_what_the_plc_raises():
    # TwinCAT/CODESYS exception handling (trofimich/TwinCAT.OpenFramework writes it in
    # every Try* method): the body stops where it fails, the catch gets the RTSEXCPT code
    src = body("a, b, q, r : INT; arr : ARRAY[1..3] OF INT; i : INT := 5; exc, exc2 : DINT;"
               "caught, fin, fin2 : BOOL; p : POINTER TO INT;",
               "__TRY\n  q := 7;\n  r := a / b;\n  q := 99;\n__CATCH(exc)\n  caught := TRUE;\n"
               "__FINALLY\n  fin := TRUE;\n__ENDTRY\n"
               "__try arr[i] := 1; __catch (exc2) __endtry;\n"
               "__TRY r := p^; __CATCH r := -1; __ENDTRY\n"
               "__TRY q := q + 1; __FINALLY fin2 := TRUE; __ENDTRY")
    p = checked_scan(src)
    assert (p.Q, p.CAUGHT, p.FIN, p.FIN2) == (8, True, True, True)
    assert (p.EXC, p.EXC2, p.R) == (0x102, 0x101, -1)   # DIVIDEBYZERO, ARRAYBOUNDS
    # printed back as written, and read again the same
    again = to_st(parse_st(src, "t.st"))
    assert "__CATCH(exc)" in again and "__FINALLY" in again and "__ENDTRY" in again
    assert to_st(parse_st(again, "u.st")) == again


def test_try_without_catch_runs_finally_and_the_error_goes_on():
    src = body("a, b, r : INT; fin : BOOL;",
               "__TRY\n  r := a / b;\n__FINALLY\n  fin := TRUE;\n__ENDTRY")
    inst = ProgramInstance(parse_st(src, "t.st"))
    with pytest.raises(ExecutionError, match="t.st:6:"):
        inst.guard(inst.scan, 0)
    assert inst.programs[0].FIN
    # a watchdog is plcpred's, not the PLC's: a __CATCH does not swallow it
    loop = body("x : INT; e : DINT;", "__TRY WHILE TRUE DO x := x + 1; END_WHILE; "
                                     "__CATCH(e) x := -1; __ENDTRY")
    inst = ProgramInstance(parse_st(loop, "t.st"))
    with pytest.raises(ExecutionError, match="WHILE"):
        inst.guard(inst.scan, 0)
    # without __ENDTRY in the file the words are names, as before
    assert problems(body("__try : INT;", "__try := 1;")) == []


def test_exception_codes_by_name_from_the_system_library(tmp_path):
    from plcpred.parser import load_program
    f = tmp_path / "exc.st"
    f.write_text(body("a, b, r : INT; exc : __SYSTEM.ExceptionCode; zero : BOOL;",
                      "__TRY r := a / b; __CATCH(exc) "
                      "zero := exc = __SYSTEM.ExceptionCode.RTSEXCPT_DIVIDEBYZERO; __ENDTRY"))
    inst = ProgramInstance(load_program(f))
    inst.guard(inst.scan, 0)
    assert inst.programs[0].ZERO


def test_sizeof_of_a_pointer_type_and_xsizeof():
    # TwinCAT.OpenFramework: MEMCPY(dst, src, TO_UDINT(XSIZEOF(POINTER TO IException) * n))
    src = body("a, b, c : DINT; x : ARRAY[1..4] OF INT;",
               "a := SIZEOF(POINTER TO INT); b := TO_DINT(XSIZEOF(POINTER TO BOOL) * 3);"
               "c := XSIZEOF(x);")
    p = checked_scan(src)
    assert (p.A, p.B, p.C) == (8, 24, 8)          # TwinCAT x64: a pointer is 8 bytes
    with pytest.raises(Exception, match="only __NEW and SIZEOF take a type"):
        parse_st(body("a : DINT;", "a := LEN(POINTER TO INT);"), "t.st")


def test_a_block_or_global_named_string_or_wstring():
    # a library's string helpers reached as String.Concat2(...) and WString.Concat2(...)
    src = ("FUNCTION_BLOCK WideStrings\nMETHOD Concat2 : WSTRING\n"
           "VAR_INPUT a, b : WSTRING; END_VAR\nConcat2 := WCONCAT(a, b);\nEND_METHOD\n"
           "END_FUNCTION_BLOCK\nVAR_GLOBAL\n  WString : WideStrings;\nEND_VAR\n"
           + body("s : WSTRING; t : STRING;", 's := WString.Concat2("ab", "cd"); t := \'x\';'))
    assert checked_scan(src).S == "abcd"


def test_generic_blocks_as_twincat_writes_them_in_a_library():
    # TwinCAT.OpenFramework: VAR_GENERIC CONSTANT before EXTENDS/IMPLEMENTS, a generic
    # base (EXTENDS Lib.AutomationController<7>) and a generic instance with its FB_init
    # arguments (Collections.List<0>(0))
    src = """FUNCTION_BLOCK ABSTRACT Base
VAR_GENERIC CONSTANT
    N : INT := 0;
END_VAR
EXTENDS Root IMPLEMENTS I_Thing
VAR
    items : ARRAY[0..N] OF INT;
END_VAR
METHOD Count : INT
Count := N; items[N] := 1;
END_METHOD
END_FUNCTION_BLOCK
FUNCTION_BLOCK Root
VAR_OUTPUT root : BOOL := TRUE; END_VAR
END_FUNCTION_BLOCK
INTERFACE I_Thing
END_INTERFACE
FUNCTION_BLOCK OnlyGeneric
VAR_GENERIC CONSTANT
    K : INT := 2;
END_VAR
IMPLEMENTS I_Thing
VAR_OUTPUT k2 : INT; END_VAR
k2 := K * 2;
END_FUNCTION_BLOCK
FUNCTION_BLOCK List
VAR_GENERIC CONSTANT
    CAP : INT := 0;
END_VAR
VAR
    cap0 : INT;
END_VAR
METHOD FB_init : BOOL
VAR_INPUT
    bInitRetains : BOOL;
    bInCopyCode : BOOL;
    initial : INT;
END_VAR
cap0 := initial + CAP;
END_METHOD
END_FUNCTION_BLOCK
FUNCTION_BLOCK Seven EXTENDS Lib.Base<7>
END_FUNCTION_BLOCK
FUNCTION_BLOCK Twice
VAR_GENERIC CONSTANT
    M : INT := 1;
END_VAR
EXTENDS Base<(M * 2)>
END_FUNCTION_BLOCK
""" + body("s : Seven; t : Twice<5>; l : List<3>(40); o : OnlyGeneric<4>; n, m, c, k : INT;"
           "r : BOOL;",
           "n := s.Count(); m := t.Count(); c := l.cap0; r := s.root; o(); k := o.k2;")
    p = checked_scan(src)
    assert (p.N, p.M, p.C, p.R, p.K) == (7, 10, 43, True, 8)
    program = parse_st(src, "t.st")
    printed = to_st(program)
    assert "EXTENDS Lib.Base<7>" in printed and "EXTENDS Base<(M * 2)>" in printed
    assert to_st(parse_st(printed, "u.st")) == printed
    with pytest.raises(Exception, match="only VAR_GENERIC CONSTANT may stand before"):
        parse_st("FUNCTION_BLOCK B\nVAR x : INT; END_VAR\nEXTENDS Root\nEND_FUNCTION_BLOCK\n",
                 "t.st")


def test_new_and_sizeof_of_a_string_type():
    # TwinCAT.OpenFramework: namespaceUriPointer := __NEW(STRING(MAX_STRING_LENGTH));
    src = body("p : POINTER TO STRING(40); w : POINTER TO WSTRING; n, m : DINT; s : STRING;",
               "IF p = 0 THEN p := __NEW(STRING(40)); w := __NEW(WSTRING); END_IF\n"
               "p^ := 'hello'; s := p^; n := SIZEOF(STRING(10)); m := SIZEOF(WSTRING(10));")
    p = checked_scan(src)
    assert (p.S, p.N, p.M) == ("hello", 11, 22)
    assert "__NEW(STRING(40))" in to_st(parse_st(src, "t.st"))


def test_an_assignment_as_the_condition_of_if():
    # TwinCAT.OpenFramework's Timer: IF Restart := Start() THEN
    src = ("FUNCTION Start : BOOL\nStart := TRUE;\nEND_FUNCTION\n"
           + body("r, q : BOOL; n : INT;",
                  "IF r := Start() THEN n := 1; ELSIF q := NOT r THEN n := 2; END_IF"))
    p = checked_scan(src)
    assert (p.R, p.N) == (True, 1)
    assert "IF (r := Start()) THEN" in to_st(parse_st(src, "t.st"))


def test_a_pou_as_the_codesys_editor_shows_it_without_its_end_keyword(tmp_path):
    # CODESYS tutorials and copied code: declarations and body of one POU, no END_PROGRAM
    f = tmp_path / "PLC_PRG.st"
    f.write_text("PROGRAM PLC_PRG\nVAR\n    n : INT;\nEND_VAR\nCASE n OF\n0: n := 1;\n"
                 "END_CASE")
    from plcpred.parser import load_program
    program = load_program(f)
    errors, warnings = check_program(program)
    assert errors == []
    assert [(w.line, w.message) for w in warnings] == [
        (1, "the PROGRAM has no END_PROGRAM: read to the end of the file (as CODESYS's "
            "editor shows a POU)")]
    inst = ProgramInstance(program)
    inst.guard(inst.scan, 0)
    assert inst.programs[0].N == 1
    # a statement left open is still the error it was
    with pytest.raises(Exception, match="CASE is not closed"):
        parse_st("PROGRAM P\nVAR n : INT; END_VAR\nCASE n OF\n0: n := 1;\n", "t.st")
    with pytest.raises(Exception, match=r"t.st:3:1: IF is not closed"):
        parse_st("PROGRAM P\nVAR n : INT; END_VAR\nIF n > 0 THEN n := 1;", "t.st")
