"""Structured Text constructs parse into the expected IR."""
import pytest

from plcpred.parser import ir, parse_st


def body(src, decls="VAR x, y, z : INT; b : BOOL; END_VAR"):
    return parse_st(f"PROGRAM P\n{decls}\n{src}\nEND_PROGRAM").pous[0].body


def value(expr_text):
    return body(f"x := {expr_text};")[0].value


# ------------------------------------------------------------------ expressions

def test_precedence_follows_iec_levels():
    e = value("a OR b XOR c AND d = e < f + g * h ** i")
    assert e.op == "OR"
    assert e.right.op == "XOR"
    assert e.right.right.op == "AND"
    eq = e.right.right.right
    assert eq.op == "=" and eq.right.op == "<"
    add = eq.right.right
    assert add.op == "+" and add.right.op == "*" and add.right.right.op == "**"


def test_unary_minus_binds_tighter_than_power():
    e = value("-2 ** 2")
    assert e == ir.Binary("**", ir.Unary("-", ir.Literal(2, "ANY_INT")), ir.Literal(2, "ANY_INT"))


def test_operators_are_left_associative():
    e = value("a - b - c")
    assert e.op == "-" and e.left.op == "-" and e.right == ir.Name("c")
    e = value("2 ** 3 ** 2")
    assert e.left.op == "**"


def test_ampersand_is_and_and_shortcut_operators():
    assert value("a & b").op == "AND"
    e = value("a AND_THEN b OR_ELSE c")
    assert e.op == "OR_ELSE" and e.left.op == "AND_THEN"


def test_not_and_parentheses():
    e = value("NOT (a OR b) AND c")
    assert e.op == "AND" and e.left == ir.Unary("NOT", ir.Binary("OR", ir.Name("a"), ir.Name("b")))


@pytest.mark.parametrize("text, expected", [
    ("42", ir.Literal(42, "ANY_INT")),
    ("1_000", ir.Literal(1000, "ANY_INT")),
    ("16#FF", ir.Literal(255, "ANY_INT")),
    ("2#1010_0101", ir.Literal(0b10100101, "ANY_INT")),
    ("8#17", ir.Literal(15, "ANY_INT")),
    ("1.5E-3", ir.Literal(1.5e-3, "ANY_REAL")),
    ("INT#5", ir.Literal(5, "INT")),
    ("INT#-5", ir.Literal(-5, "INT")),
    ("WORD#16#F0", ir.Literal(0xF0, "WORD")),
    ("REAL#2.5", ir.Literal(2.5, "REAL")),
    ("BOOL#1", ir.Literal(True, "BOOL")),
    ("TRUE", ir.Literal(True, "BOOL")),
    ("T#1h2m3s4ms", ir.Literal(((3600 + 120 + 3) * 1000 + 4) * 10**6, "TIME")),
    ("TIME#250ms", ir.Literal(250 * 10**6, "TIME")),
    ("T#-1.5s", ir.Literal(-1_500_000_000, "TIME")),
    ("t#1d_2h", ir.Literal(26 * 3600 * 10**9, "TIME")),
    ("LTIME#5us", ir.Literal(5000, "LTIME")),
    ("TOD#12:30:15.5", ir.Literal((12 * 3600 + 30 * 60 + 15) * 10**9 + 5 * 10**8, "TOD")),
    ("DATE#1970-01-02", ir.Literal(86400 * 10**9, "DATE")),
    ("DT#1970-01-01-00:01:00", ir.Literal(60 * 10**9, "DT")),
    ("'it$'s $$5 $N'", ir.Literal("it's $5 \n", "STRING")),
    ("'don''t'", ir.Literal("don't", "STRING")),
    ("'$41$42'", ir.Literal("AB", "STRING")),
    ('"wide $0041"', ir.Literal("wide A", "WSTRING")),
    ("E_Mode#Run", ir.EnumLiteral("E_Mode", "Run")),
    ("%IX0.7", ir.DirectAddress("%IX0.7")),
])
def test_literals(text, expected):
    assert value(text) == expected


def test_postfix_chains_bit_access_index_member_deref_call():
    e = value("a.b[1, i + 1].c^.3")
    assert isinstance(e, ir.BitAccess) and e.bit == 3
    assert isinstance(e.base, ir.Deref)
    m = e.base.base
    assert isinstance(m, ir.Member) and m.member == "c"
    idx = m.base
    assert isinstance(idx, ir.Index) and len(idx.indices) == 2
    assert idx.base == ir.Member(ir.Name("a"), "b")


def test_call_arguments_positional_named_and_output():
    stmt = body("fb(x, IN := TRUE, PT := T#1s, Q => y, NOT ET => z);")[0]
    assert isinstance(stmt, ir.CallStmt)
    args = stmt.call.args
    assert args[0] == ir.Arg(None, ir.Name("x"))
    assert args[1] == ir.Arg("IN", ir.Literal(True, "BOOL"))
    assert args[3] == ir.Arg("Q", ir.Name("y"), output=True)
    assert args[4] == ir.Arg("ET", ir.Name("z"), output=True, negated=True)


def test_fb_output_access_and_method_call_in_expression():
    e = value("t1.Q AND fb.Check(1)")
    assert e.left == ir.Member(ir.Name("t1"), "Q")
    assert isinstance(e.right, ir.Call) and e.right.func == ir.Member(ir.Name("fb"), "Check")


# ------------------------------------------------------------------ statements

def test_if_elsif_else_and_optional_semicolon_after_end_if():
    stmts = body("IF a THEN x := 1; ELSIF b THEN x := 2; ELSIF c THEN ; ELSE x := 3; END_IF;\ny := 1;")
    assert len(stmts) == 2
    s = stmts[0]
    assert len(s.branches) == 3 and s.branches[2][1] == [ir.Empty()]
    assert s.else_body == [ir.Assign(ir.Name("x"), ir.Literal(3, "ANY_INT"))]
    assert body("IF a THEN x := 1; END_IF")[0].else_body is None


def test_case_with_lists_ranges_enums_and_else():
    s = body("""CASE x OF
      1, 2: y := 1;
      3..5: y := 2; z := 2;
      E.Idle: ;
      Run: y := 4;
      E#Stop, -1: y := 5;
    ELSE
      y := 0;
    END_CASE""")[0]
    labels = [b.labels for b in s.branches]
    assert labels[0] == [ir.Literal(1, "ANY_INT"), ir.Literal(2, "ANY_INT")]
    assert labels[1] == [ir.CaseRange(ir.Literal(3, "ANY_INT"), ir.Literal(5, "ANY_INT"))]
    assert labels[2] == [ir.Member(ir.Name("E"), "Idle")]
    assert labels[3] == [ir.Name("Run")]
    assert labels[4] == [ir.EnumLiteral("E", "Stop"), ir.Unary("-", ir.Literal(1, "ANY_INT"))]
    assert len(s.branches[1].body) == 2
    assert s.else_body == [ir.Assign(ir.Name("y"), ir.Literal(0, "ANY_INT"))]


def test_loops_exit_continue_return():
    stmts = body("""FOR x := 10 TO 0 BY -2 DO IF x = 4 THEN CONTINUE; END_IF; EXIT; END_FOR
    WHILE b DO b := FALSE; END_WHILE
    REPEAT x := x + 1; UNTIL x > 3 END_REPEAT;
    RETURN;""")
    f, w, r, ret = stmts
    assert f.var == "x" and f.step == ir.Unary("-", ir.Literal(2, "ANY_INT"))
    assert isinstance(f.body[0].branches[0][1][0], ir.Continue) and isinstance(f.body[1], ir.Exit)
    assert isinstance(w, ir.While) and isinstance(r, ir.Repeat) and isinstance(ret, ir.Return)
    assert body("FOR x := 1 TO 3 DO END_FOR")[0].step is None


def test_labels_and_jmp():
    stmts = body("start: x := 1; JMP start;")
    assert stmts == [ir.Label("start"), ir.Assign(ir.Name("x"), ir.Literal(1, "ANY_INT")),
                     ir.Jmp("start")]


def test_ref_assign_and_assignment_attempt():
    stmts = body("r REF= x; p ?= q;")
    assert [s.op for s in stmts] == ["REF=", "?="]


def test_keywords_case_insensitive_in_code():
    stmts = body("if b then x := 1; end_if\nfor x := 1 to 2 do ; end_for")
    assert isinstance(stmts[0], ir.If) and isinstance(stmts[1], ir.For)


# ------------------------------------------------------------------ declarations and types

def decls_of(text):
    return parse_st(f"PROGRAM P\n{text}\nEND_PROGRAM").pous[0].var_blocks


def test_var_block_kinds_and_qualifiers():
    blocks = decls_of("""VAR_INPUT a : BOOL; END_VAR VAR_OUTPUT b : BOOL; END_VAR
    VAR_IN_OUT c : INT; END_VAR VAR_TEMP d : INT; END_VAR VAR_EXTERNAL e : INT; END_VAR
    VAR_STAT f : INT; END_VAR VAR_INST g : INT; END_VAR VAR CONSTANT h : INT := 1; END_VAR
    VAR RETAIN PERSISTENT i : INT; END_VAR VAR_GLOBAL j : INT; END_VAR""")
    assert [b.kind for b in blocks] == ["VAR_INPUT", "VAR_OUTPUT", "VAR_IN_OUT", "VAR_TEMP",
                                        "VAR_EXTERNAL", "VAR_STAT", "VAR_INST", "VAR", "VAR",
                                        "VAR_GLOBAL"]
    assert blocks[7].qualifiers == ["CONSTANT"]
    assert blocks[8].qualifiers == ["RETAIN", "PERSISTENT"]


def test_located_variables_arrays_strings_pointers_and_inits():
    (block,) = decls_of("""VAR
      in1 AT %IX0.0 : BOOL;
      w AT %MW4 : WORD;
      any AT %I* : BOOL;
      a, b : INT := 3;
      arr : ARRAY[1..3, 0..1] OF INT := [1, 2, 3(0)];
      s : STRING(20) := 'x';
      s2 : STRING[10];
      ws : WSTRING;
      p : POINTER TO INT;
      r : REFERENCE TO INT;
      pt : ST_Point := (x := 1.0, y := -2.0);
      t : TON := (PT := T#1s);
      pts : ARRAY[0..1] OF ST_Point := [(x := 1.0), (x := 2.0)];
      open : ARRAY[*] OF INT;
    END_VAR""")
    d = {x.name: x for x in block.decls}
    assert d["in1"].address == "%IX0.0" and d["w"].address == "%MW4" and d["any"].address == "%I*"
    assert d["a"].init == d["b"].init == ir.Literal(3, "ANY_INT")
    assert d["arr"].type.dims == [(ir.Literal(1, "ANY_INT"), ir.Literal(3, "ANY_INT")),
                                  (ir.Literal(0, "ANY_INT"), ir.Literal(1, "ANY_INT"))]
    assert d["arr"].init.items == [(1, ir.Literal(1, "ANY_INT")), (1, ir.Literal(2, "ANY_INT")),
                                   (3, ir.Literal(0, "ANY_INT"))]
    assert d["s"].type == ir.StringType(False, ir.Literal(20, "ANY_INT"))
    assert d["s2"].type.length == ir.Literal(10, "ANY_INT")
    assert d["ws"].type == ir.StringType(True, None)
    assert d["p"].type == ir.PointerType(ir.NamedType("INT"))
    assert d["r"].type == ir.PointerType(ir.NamedType("INT"), reference=True)
    assert d["pt"].init.fields[1] == ("y", ir.Unary("-", ir.Literal(2.0, "ANY_REAL")))
    assert d["t"].init == ir.StructInit([("PT", ir.Literal(10**9, "TIME"))])
    assert isinstance(d["pts"].init.items[0][1], ir.StructInit)
    assert d["open"].type.dims == [(None, None)]


def test_type_block_enum_struct_subrange_alias_union():
    prog = parse_st("""TYPE
      E_Mode : (Idle, Run := 5, Stop) := Idle;
      E_Typed : (A, B) DINT;
      ST_P : STRUCT x : REAL; y : REAL := 1.0; END_STRUCT;
      ST_Q EXTENDS ST_P : STRUCT z : REAL; END_STRUCT
      T_Pct : INT (0..100);
      T_Alias : LREAL;
      T_Arr : ARRAY[1..5] OF ST_P;
      U : UNION a : WORD; b : BYTE; END_UNION;
      T_Str : STRING(80);
    END_TYPE""")
    t = {x.name: x for x in prog.types}
    assert t["E_Mode"].type.values == [("Idle", None), ("Run", ir.Literal(5, "ANY_INT")),
                                       ("Stop", None)]
    assert t["E_Mode"].init == ir.Name("Idle")
    assert t["E_Typed"].type.base == "DINT"
    assert [m.name for m in t["ST_P"].type.members] == ["x", "y"]
    assert t["ST_Q"].type.extends == "ST_P"
    assert t["T_Pct"].type == ir.SubrangeType("INT", ir.Literal(0, "ANY_INT"),
                                              ir.Literal(100, "ANY_INT"))
    assert t["T_Alias"].type == ir.NamedType("LREAL")
    assert t["U"].type.union
    assert t["T_Str"].type.length == ir.Literal(80, "ANY_INT")


# ------------------------------------------------------------------ POUs

def test_several_pous_function_with_return_type_and_fb_members():
    prog = parse_st("""
    FUNCTION Add3 : INT
    VAR_INPUT a, b, c : INT; END_VAR
    Add3 := a + b + c;
    END_FUNCTION
    FUNCTION_BLOCK PUBLIC ABSTRACT FB_Base IMPLEMENTS I_A, Lib.I_B
    VAR_INPUT i : INT; END_VAR
    METHOD PROTECTED FINAL Run : BOOL
    VAR_INPUT n : INT; END_VAR
    Run := n > 0;
    END_METHOD
    PROPERTY PUBLIC Level : INT
    GET Level := i; END_GET
    SET VAR tmp : INT; END_VAR tmp := Level; END_SET
    END_PROPERTY
    END_FUNCTION_BLOCK
    FUNCTION_BLOCK FB_D EXTENDS FB_Base
    END_FUNCTION_BLOCK
    METHOD Later : INT
    Later := 1;
    END_METHOD
    ACTION Act:
    i := 0;
    END_ACTION
    PROGRAM Main
    END_PROGRAM
    """)
    add3, base, derived, main = prog.pous
    assert add3.kind == "FUNCTION" and add3.return_type == ir.NamedType("INT")
    assert base.access == "PUBLIC" and base.modifiers == ["ABSTRACT"]
    assert base.implements == ["I_A", "Lib.I_B"]
    assert base.methods[0].access == "PROTECTED" and base.methods[0].modifiers == ["FINAL"]
    assert [a.kind for a in base.properties[0].accessors] == ["GET", "SET"]
    assert derived.extends == "FB_Base"
    # methods and actions written after END_FUNCTION_BLOCK belong to that FB
    assert derived.methods[0].name == "Later" and derived.actions[0].name == "Act"
    assert main.kind == "PROGRAM" and main.body == []


def test_interface_and_configuration():
    prog = parse_st("""
    INTERFACE I_Move EXTENDS I_Base
    METHOD Go : BOOL
    VAR_INPUT target : REAL; END_VAR
    END_METHOD
    PROPERTY Pos : REAL
    END_PROPERTY
    END_INTERFACE
    PROGRAM Main END_PROGRAM
    CONFIGURATION Cell
      VAR_GLOBAL g AT %QX0.0 : BOOL; END_VAR
      RESOURCE CPU ON PLC
        TASK Fast(INTERVAL := T#5ms, PRIORITY := 1);
        TASK Slow(SINGLE := trig, PRIORITY := 5);
        PROGRAM RETAIN m1 WITH Fast : Main(x := g, y => g);
        PROGRAM m2 : Main;
      END_RESOURCE
    END_CONFIGURATION""")
    itf = prog.interfaces[0]
    assert itf.extends == ["I_Base"] and itf.methods[0].name == "Go"
    assert itf.properties[0].name == "Pos"
    cfg = prog.configurations[0]
    assert cfg.var_blocks[0].decls[0].address == "%QX0.0"
    res = cfg.resources[0]
    assert (res.name, res.on) == ("CPU", "PLC")
    assert res.tasks[0].params["INTERVAL"] == ir.Literal(5 * 10**6, "TIME")
    m1, m2 = res.programs
    assert (m1.name, m1.task, m1.type_name, m1.retain) == ("m1", "Fast", "Main", "RETAIN")
    assert m1.args[1].output and m2.task is None


def test_global_variable_list_and_pragmas_kept():
    prog = parse_st("{attribute 'qualified_only'}\nVAR_GLOBAL CONSTANT N : INT := 4; END_VAR")
    assert prog.globals[0].block.qualifiers == ["CONSTANT"]
    assert prog.pragmas[0][0] == "{attribute 'qualified_only'}"


def test_sfc_textual_form():
    prog = parse_st("""PROGRAM S
    VAR a, b, go : BOOL; END_VAR
    INITIAL_STEP Init: END_STEP
    STEP S1: a(N); Count(P); b(L, T#2s); END_STEP
    STEP S2: END_STEP
    STEP S3: END_STEP
    TRANSITION FROM Init TO (S1, S2) := go; END_TRANSITION
    TRANSITION T2 (PRIORITY := 2) FROM (S1, S2) TO S3 := S1.T >= T#1s AND S2.X; END_TRANSITION
    TRANSITION FROM S3 TO Init := TRUE; END_TRANSITION
    ACTION Count: a := NOT a; END_ACTION
    END_PROGRAM""")
    sfc = prog.pous[0].body
    assert isinstance(sfc, ir.Sfc)
    assert sfc.initial_step.name == "Init"
    s1 = sfc.steps[1]
    assert [(a.action, a.qualifier) for a in s1.actions] == [("a", "N"), ("Count", "P"), ("b", "L")]
    assert s1.actions[2].time == ir.Literal(2 * 10**9, "TIME")
    t1, t2, _ = sfc.transitions
    assert t1.targets == ["S1", "S2"] and t2.sources == ["S1", "S2"]
    assert t2.priority == 2 and t2.name == "T2"
    assert sfc.actions[0].name == "Count"


def test_var_config_with_instance_paths():
    prog = parse_st("""PROGRAM Main VAR_OUTPUT lamp : BOOL; END_VAR END_PROGRAM
    CONFIGURATION C
      VAR_CONFIG
        Res.Inst.lamp AT %QX1.0 : BOOL := TRUE;
      END_VAR
      RESOURCE Res ON PLC
        PROGRAM Inst : Main;
      END_RESOURCE
    END_CONFIGURATION""")
    block = prog.configurations[0].var_blocks[0]
    assert block.kind == "VAR_CONFIG"
    assert block.decls == [ir.VarDecl("Res.Inst.lamp", ir.NamedType("BOOL"),
                                      ir.Literal(True, "BOOL"), "%QX1.0")]
    from plcpred.parser.printer import to_st
    assert parse_st(to_st(prog)) == prog
