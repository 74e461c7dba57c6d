"""ST execution semantics: the compiled program against hand-worked IEC results."""
import pytest

from plcpred.parser import parse_st
from plcpred.sequencer import CompileError, ExecutionError, Watchdog
from plcpred.sequencer.executor import ProgramInstance

MS = 1_000_000


def run(src, scans=1, scan_ms=10, setup=None):
    inst = ProgramInstance(parse_st(src, "t.st"))
    prog = inst.programs[0]
    for k in range(scans):
        if setup:
            setup(prog, k)
        inst.guard(inst.scan, k * scan_ms * MS)
    return prog


def body(decls, code):
    return f"PROGRAM P\nVAR\n{decls}\nEND_VAR\n{code}\nEND_PROGRAM\n"


def test_integer_types_wrap_at_assignment():
    p = run(body("a : INT := 32767; b : USINT := 250; c : SINT := -128; d : UDINT;",
                 "a := a + 1; b := b + 10; c := c - 1; d := d - 1;"))
    assert (p.A, p.B, p.C, p.D) == (-32768, 4, 127, 2**32 - 1)


def test_integer_division_and_mod_truncate_toward_zero():
    p = run(body("a, b, c, d : DINT; r : REAL;",
                 "a := -7 / 2; b := -7 MOD 2; c := 7 MOD -2; d := 7 / 2; r := 7.0 / 2;"))
    assert (p.A, p.B, p.C, p.D, p.R) == (-3, -1, 1, 3, 3.5)


def test_division_by_zero_names_the_line():
    with pytest.raises(ExecutionError) as e:
        run(body("a, z : INT;", "a := 1;\na := a / z;"))
    assert e.value.line == 6 and "division by zero" in str(e.value)


def test_time_arithmetic_and_conversions():
    p = run(body("t : TIME := T#1s; u : TIME; n : DINT; r : REAL; k : INT;",
                 "u := t * 3 + T#250ms; n := TIME_TO_DINT(u); r := DINT_TO_REAL(n) / 1000.0;"
                 "k := REAL_TO_INT(2.5); u := u / 2;"))
    assert p.U == 1_625 * MS and p.N == 3250 and p.R == 3.25 and p.K == 3


def test_dates_count_seconds_and_long_times_nanoseconds_when_converted():
    # CODESYS/TwinCAT: DT_TO_UDINT is seconds since 1970, TIME milliseconds, LTIME ns
    p = run(body("d : DT := DT#2024-01-01-00:30:00; e : DT; day : DATE := D#1970-01-02;"
                 "lt : LTIME := LTIME#1ms; s, n, k : ULINT; r : LREAL; tod : TOD;",
                 "s := DT_TO_ULINT(d); e := ULINT_TO_DT(s + 60); n := DATE_TO_ULINT(day);"
                 "k := LTIME_TO_ULINT(lt); r := DT_TO_LREAL(d); tod := UDINT_TO_TOD(1500);"))
    assert (p.S, p.N, p.K) == (1_704_069_000, 86_400, 1_000_000)
    assert p.E == (1_704_069_000 + 60) * 10 ** 9 and p.R == 1_704_069_000.0
    assert p.TOD == 1500 * MS


def test_standard_functions():
    p = run(body("a, b, c : INT; w : WORD; m : REAL; s : STRING;",
                 "a := MAX(3, 9, 4); b := LIMIT(0, 12, 10); c := SEL(TRUE, 1, 2) + MUX(2, 5, 6, 7);"
                 "w := ROL(WORD#16#8001, 1) OR SHL(WORD#1, 4); m := ABS(-2.0) + SQRT(16.0);"
                 "s := CONCAT('ab', LEFT('xyz', 2));"))
    assert (p.A, p.B, p.C) == (9, 10, 9)
    assert p.W == 0x0003 | 0x10
    assert p.M == 6.0 and p.S == "abxy"


def test_case_with_ranges_lists_and_else():
    src = body("i, r : INT;", "CASE i OF 0: r := 10; 1, 2: r := 20; 3..5: r := 30; "
                              "ELSE r := 99; END_CASE; i := i + 1;")
    seen = []
    inst = ProgramInstance(parse_st(src))
    for k in range(7):
        inst.scan(k)
        seen.append(inst.programs[0].R)
    assert seen == [10, 20, 20, 30, 30, 30, 99]


def test_loops_exit_continue_and_for_variable():
    p = run(body("i, s, n, w : INT;",
                 "FOR i := 1 TO 10 BY 2 DO IF i = 5 THEN CONTINUE; END_IF; s := s + i; END_FOR;"
                 "WHILE TRUE DO n := n + 1; IF n >= 4 THEN EXIT; END_IF; END_WHILE;"
                 "REPEAT w := w + 3; UNTIL w > 7 END_REPEAT;"))
    assert p.S == 1 + 3 + 7 + 9 and p.N == 4 and p.W == 9 and p.I == 11


def test_jmp_forward_and_backward():
    p = run(body("n, k : INT;", "again: n := n + 1; IF n < 5 THEN JMP again; END_IF;"
                                "JMP skip; k := 99; skip: k := k + 1;"))
    assert p.N == 5 and p.K == 1


def test_endless_loop_stops_with_watchdog_naming_the_line():
    src = body("i : INT;", "i := 0;\nWHILE i >= 0 DO\n  i := 1;\nEND_WHILE;")
    with pytest.raises(Watchdog) as e:
        run(src)
    assert e.value.line == 6 and "WHILE" in str(e.value)


@pytest.mark.parametrize("decls,code,line", [
    # three FORs of 1,000 passes each: 10^9 passes in one scan, each loop under the limit
    ("i, j, k : DINT; s : LINT;",
     "FOR i := 0 TO 999 DO\nFOR j := 0 TO 999 DO\nFOR k := 0 TO 999 DO\ns := s + 1;\n"
     "END_FOR; END_FOR; END_FOR;", 7),
    # a WHILE inside a FOR, each far below the limit alone
    ("i, j : DINT;",
     "FOR i := 1 TO 5000 DO\nj := 0;\nWHILE j < 5000 DO\nj := j + 1;\nEND_WHILE;\n"
     "END_FOR;", 7),
])
def test_nested_loops_share_one_watchdog_per_scan(decls, code, line):
    import time
    t0 = time.perf_counter()
    with pytest.raises(Watchdog) as e:
        run(body(decls, code))
    assert e.value.line == line and "all loops together" in str(e.value)
    assert time.perf_counter() - t0 < 20      # 10^9 passes before: hours


def test_loops_in_called_fbs_count_against_the_callers_scan():
    src = ("FUNCTION_BLOCK FB_I VAR_INPUT n : DINT; END_VAR VAR k : DINT; END_VAR\n"
           "FOR k := 1 TO n DO\n;\nEND_FOR;\nEND_FUNCTION_BLOCK\n"
           + body("i : DINT; fb : FB_I;", "FOR i := 1 TO 900000 DO fb(n := 900000); END_FOR;"))
    with pytest.raises(Watchdog) as e:
        run(src)
    assert e.value.line == 2


def test_the_watchdog_budget_is_per_scan():
    """Each scan starts a new budget: 600,000 passes a scan for three scans run."""
    p = run(body("i : DINT; s : DINT;", "FOR i := 1 TO 600000 DO s := s + 1; END_FOR;"),
            scans=3)
    assert p.S == 1_800_000


def test_a_case_of_thousands_of_labels_compiles_and_picks_the_first_match():
    """Chains are cut in pieces (ELIF_CHAIN); before, 20,000 labels ran Python's own
    compiler out of memory, reported as 'nested too deeply'. The same label twice: the
    first branch wins, across a cut too."""
    arms = "\n".join(f"{k}: y := {k * 2};" for k in range(2500))
    src = body("x, y : DINT;", f"CASE x OF\n{arms}\n150: y := -1;\n3, 7..9: y := -2;\n"
                              "ELSE y := -3;\nEND_CASE;")
    for x, y in ((0, 0), (99, 198), (100, 200), (150, 300), (2499, 4998), (2500, -3),
                 (-5, -3)):
        p = run(src, setup=lambda prog, k, x=x: setattr(prog, "X", x))
        assert p.Y == y, (x, p.Y)


def test_an_if_with_hundreds_of_elsifs_keeps_its_order():
    arms = "".join(f"ELSIF x < {k} THEN y := {k};\n" for k in range(10, 3000, 10))
    src = body("x, y : DINT;", f"IF x < 0 THEN y := -1;\n{arms}ELSE y := -9;\nEND_IF;")
    for x, y in ((-1, -1), (0, 10), (995, 1000), (2985, 2990), (5000, -9)):
        p = run(src, setup=lambda prog, k, x=x: setattr(prog, "X", x))
        assert p.Y == y, (x, p.Y)


def test_a_struct_declared_only_in_a_function_has_its_class():
    """Structs were emitted before functions, so one that only a FUNCTION's locals named
    had no class: NameError at the first call (found by the fuzzer)."""
    src = ("TYPE Pt : STRUCT a : INT; next : POINTER TO Pt; END_STRUCT; END_TYPE\n"
           "TYPE Inner : STRUCT b : INT := 4; END_STRUCT; END_TYPE\n"
           "TYPE Outer : STRUCT i : Inner; END_STRUCT; END_TYPE\n"
           "FUNCTION F : INT VAR p : Pt; o : Outer; END_VAR p.a := 3; F := p.a + o.i.b;\n"
           "END_FUNCTION\n" + body("x : INT;", "x := F();"))
    assert run(src).X == 7


def test_arrays_structs_and_copy_semantics():
    src = """
TYPE Pt : STRUCT x : INT; y : INT := 7; END_STRUCT END_TYPE
PROGRAM P
VAR a : ARRAY[1..3] OF INT := [1, 2(5)]; m : ARRAY[0..1, 0..2] OF INT;
    p, q : Pt; ps : ARRAY[1..2] OF Pt := [(x := 3)]; i : INT := 3; s : INT; END_VAR
q := p; q.x := 4; m[1, 2] := 8; s := a[i] + a[1] + ps[1].x + ps[2].y + m[1, 2];
END_PROGRAM
"""
    p = run(src)
    assert p.P.X == 0 and p.Q.X == 4 and p.S == 5 + 1 + 3 + 7 + 8


def test_array_index_out_of_range_is_an_error():
    with pytest.raises(ExecutionError) as e:
        run(body("a : ARRAY[1..3] OF INT; i : INT := 4; x : INT;", "x := a[i];"))
    assert "outside" in str(e.value) and e.value.line == 5


def test_enums_bare_and_qualified():
    src = """TYPE E : (Idle, Run := 5, Stop); END_TYPE
PROGRAM P VAR st : E; n : INT; END_VAR
IF st = E.Idle THEN st := Run; ELSIF st = Run THEN st := E#Stop; END_IF
n := n + 1;
END_PROGRAM"""
    inst = ProgramInstance(parse_st(src))
    vals = []
    for k in range(3):
        inst.scan(k)
        vals.append(inst.programs[0].ST)
    assert vals == [5, 6, 6]


def test_function_with_in_out_output_and_defaults():
    src = """FUNCTION F : INT
VAR_INPUT a : INT; b : INT := 10; END_VAR
VAR_IN_OUT acc : INT; END_VAR
VAR_OUTPUT twice : INT; END_VAR
acc := acc + a; twice := 2 * a; F := a + b;
END_FUNCTION
PROGRAM P VAR r, acc, tw : INT; END_VAR
r := F(a := 3, acc := acc, twice => tw);
r := r + F(1, 1, acc);
END_PROGRAM"""
    p = run(src)
    assert (p.R, p.ACC, p.TW) == (13 + 2, 4, 6)


def test_fb_inputs_are_retained_between_calls():
    src = """FUNCTION_BLOCK Acc VAR_INPUT inc : INT := 1; END_VAR VAR_OUTPUT total : INT; END_VAR
total := total + inc;
END_FUNCTION_BLOCK
PROGRAM P VAR f : Acc; out : INT; n : INT; END_VAR
IF n = 0 THEN f(inc := 5); ELSE f(total => out); END_IF
n := n + 1;
END_PROGRAM"""
    p = run(src, scans=3)
    assert p.F.TOTAL == 15 and p.OUT == 15


def test_methods_properties_inheritance_super_and_pointers():
    src = """FUNCTION_BLOCK Base VAR_OUTPUT n : INT; END_VAR VAR k : INT := 1; END_VAR
n := n + k;
METHOD Bump : INT VAR_INPUT amount : INT; END_VAR k := k + amount; Bump := k; END_METHOD
PROPERTY Twice : INT
GET Twice := 2 * n; END_GET
SET k := Twice; END_SET
END_PROPERTY
END_FUNCTION_BLOCK
FUNCTION_BLOCK Child EXTENDS Base VAR_OUTPUT calls : INT; END_VAR
SUPER^(); calls := calls + 1;
END_FUNCTION_BLOCK
PROGRAM P VAR c : Child; r : REFERENCE TO Child; p : POINTER TO Child; v, t : INT;
  x : INT; px : POINTER TO INT; END_VAR
r REF= c; p := ADR(c);
c();
v := r.Bump(amount := 2);
p^();
t := c.Twice;
c.Twice := 100;
px := ADR(x); px^ := 42;
END_PROGRAM"""
    p = run(src)
    assert p.C.CALLS == 2 and p.C.N == 1 + 3 and p.V == 3 and p.T == 8
    assert p.C.K == 100 and p.X == 42


def test_bit_access_read_and_write():
    p = run(body("w : WORD := 16#0004; b : BOOL;", "b := w.2; w.0 := TRUE; w.2 := FALSE;"))
    assert p.B is True and p.W == 1


def test_unsupported_constructs_are_positioned_compile_errors():
    with pytest.raises(CompileError) as e:
        ProgramInstance(parse_st(body("x : INT; p : POINTER TO INT;",
                                      "x := 1;\nx := __NEW(INT);"), "u.st"))
    assert (e.value.file, e.value.line) == ("u.st", 6)


def test_standard_fbs_in_programs_use_scan_time():
    src = body("t : TON; p : TP; q1, q2 : BOOL; c : CTU;",
               "t(IN := TRUE, PT := T#35ms, Q => q1); p(IN := NOT t.Q, PT := T#20ms);"
               "q2 := p.Q; c(CU := p.Q, PV := 2);")
    inst = ProgramInstance(parse_st(src))
    q1 = []
    for k in range(6):
        inst.scan(k * 10 * MS)
        q1.append(inst.programs[0].Q1)
    assert q1 == [False, False, False, False, True, True]
    assert inst.programs[0].C.CV == 1


def test_instances_local_to_a_method_are_fresh_each_call_and_not_listed():
    src = """FUNCTION_BLOCK Fb
VAR_OUTPUT n : INT; END_VAR
METHOD Tick : BOOL
VAR t : TON; e : R_TRIG; END_VAR
e(CLK := TRUE);
t(IN := TRUE, PT := T#0s);
Tick := e.Q AND t.Q;
END_METHOD
END_FUNCTION_BLOCK
PROGRAM P VAR f : Fb; k : INT; END_VAR
IF f.Tick() THEN k := k + 1; END_IF
END_PROGRAM"""
    inst = ProgramInstance(parse_st(src))
    for i in range(5):
        inst.scan(i * 10 * MS)
    assert inst.programs[0].K == 5          # a fresh R_TRIG sees an edge every call
    assert inst.timers == []


def test_an_action_called_with_inputs_and_outputs_like_its_instance():
    # CODESYS and TwinCAT: inst.Act(in := x, out => y) sets the instance's inputs, runs
    # the action (not the body) and reads the outputs
    p = run("""FUNCTION_BLOCK FB_Acc
VAR_INPUT step : INT; END_VAR
VAR_OUTPUT total, bodies : INT; END_VAR
bodies := bodies + 1;
ACTION Add:
total := total + step;
END_ACTION
END_FUNCTION_BLOCK
PROGRAM P
VAR acc : FB_Acc; seen : INT; END_VAR
acc.Add(step := 5);
acc.Add(step := 2, total => seen);
END_PROGRAM
""")
    assert (p.ACC.TOTAL, p.SEEN, p.ACC.STEP, p.ACC.BODIES) == (7, 7, 2, 0)


def test_sizeof_counts_bytes_of_the_declared_type():
    p = run(body("a : ARRAY[0..9] OF INT; b : ARRAY[1..2, 1..3] OF LREAL; s : ST_Pair; "
                 "q : POINTER TO INT; x : BOOL; n : ARRAY[1..5] OF DINT;",
                 "n[1] := SIZEOF(a); n[2] := SIZEOF(b); n[3] := SIZEOF(s); n[4] := SIZEOF(q); "
                 "n[5] := SIZEOF(x);")
            .replace("PROGRAM P", "TYPE ST_Pair : STRUCT w : WORD; d : UDINT; END_STRUCT "
                                  "END_TYPE\nPROGRAM P"))
    assert list(p.N) == [20, 48, 6, 8, 1]


def test_a_method_array_bound_names_a_constant_declared_after_it():
    # TcUnit's verifier: VAR a : ARRAY[1..N] ... END_VAR VAR CONSTANT N : UINT := 2;
    p = run("""FUNCTION_BLOCK FB_Fwd
VAR_OUTPUT total : UINT; END_VAR
METHOD Fill : UINT
VAR
    a : ARRAY[1..LEN_A] OF UINT := [4, 5];
    i : UINT;
END_VAR
VAR CONSTANT
    LEN_A : UINT := 2;
END_VAR
FOR i := 1 TO LEN_A DO
    Fill := Fill + a[i];
END_FOR
END_METHOD
total := Fill();
END_FUNCTION_BLOCK
PROGRAM P
VAR fb : FB_Fwd; END_VAR
fb();
END_PROGRAM
""")
    assert p.FB.TOTAL == 9


def test_an_array_of_function_blocks_with_each_elements_fb_init_arguments():
    # TwinCAT: ARRAY[..] OF FB_T[(args of the first), (args of the second), ...]; an
    # element the list does not reach gets no arguments
    src = """FUNCTION_BLOCK FB_Runner
VAR_OUTPUT id : INT; label : STRING; END_VAR
METHOD FB_init : BOOL
VAR_INPUT
    bInitRetains : BOOL;
    bInCopyCode : BOOL;
    nId : INT;
    sName : STRING;
END_VAR
id := nId;
label := sName;
END_METHOD
END_FUNCTION_BLOCK
PROGRAM P
VAR
    runners : ARRAY[1..2, 0..1] OF FB_Runner[(nId := 1, sName := 'a'), (nId := 2), (3, 'c')];
    ids : ARRAY[1..4] OF INT;
    last : STRING;
END_VAR
ids[1] := runners[1, 0].id; ids[2] := runners[1, 1].id;
ids[3] := runners[2, 0].id; ids[4] := runners[2, 1].id;
last := runners[2, 0].label;
END_PROGRAM
"""
    p = run(src)
    assert list(p.IDS) == [1, 2, 3, 0] and p.LAST == "c" and p.RUNNERS[0][0].LABEL == "a"
    from plcpred.parser.check import check_program
    from plcpred.parser.printer import to_st
    prog = parse_st(src, "t.st")
    assert check_program(prog)[0] == []
    assert parse_st(to_st(prog), "t.st") == prog     # printed and read back


def test_ref_assign_rebinds_a_reference_to_an_elementary_value_and_isvalidref():
    # REF= sets what a REFERENCE TO INT refers to (it wrote through the unset reference
    # and stopped), and a reference given to REF= passes on what it refers to;
    # __ISVALIDREF tells a set reference from an unset one
    p = run("""FUNCTION_BLOCK FB_X
VAR_OUTPUT n : INT := 4; END_VAR
END_FUNCTION_BLOCK
PROGRAM P
VAR
    x : FB_X;
    i, j : INT := 7;
    rx : REFERENCE TO FB_X;
    ri, rj : REFERENCE TO INT;
    before, after : ARRAY[1..2] OF BOOL;
    v : INT;
END_VAR
before[1] := __ISVALIDREF(rx);
before[2] := __ISVALIDREF(ri);
rx REF= x;
ri REF= i;
after[1] := __ISVALIDREF(rx);
after[2] := __ISVALIDREF(ri);
ri := 10;
ri REF= j;
ri := ri + 1;
v := ri + rx.n;
rj REF= ri;         (* a reference refers on to what the other refers to *)
rj := rj + 100;
END_PROGRAM
""")
    assert list(p.BEFORE) == [False, False] and list(p.AFTER) == [True, True]
    assert (p.I, p.J, p.V) == (10, 108, 12)


def test_an_instance_deleting_itself_is_left_to_its_last_pointer():
    p = run("""FUNCTION_BLOCK FB_Node
VAR_OUTPUT alive : BOOL := TRUE; END_VAR
METHOD Dispose : BOOL
alive := FALSE;
__DELETE(THIS);
Dispose := TRUE;
END_METHOD
END_FUNCTION_BLOCK
PROGRAM P
VAR p : POINTER TO FB_Node; ok : BOOL; END_VAR
p := __NEW(FB_Node);
ok := p^.Dispose();
END_PROGRAM
""")
    assert p.OK and not p.P.ALIVE
