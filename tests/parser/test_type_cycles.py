"""Types that never end, nest without bound or name bits that are not there.

Program files are untrusted. Each case here made plcpred trace back (RecursionError), eat
gigabytes (``FUNCTION_BLOCK A EXTENDS A``: 1.7 GB in 12 s) or run for a minute before the
type graph was checked (:mod:`plcpred.parser.typegraph`) and type constructors and
initialisers were counted in the nesting limits (:mod:`plcpred.parser.names`). Now each is
an error naming file, line and column, from the checker and from the compiler alike, in
bounded time; and programs at the limits still compile and run.
"""
import resource
import subprocess
import sys
import time

import pytest

from plcpred.parser import ProgramError
from plcpred.parser.check import check_program
from plcpred.parser.names import MAX_INITIALIZER_DEPTH, MAX_TYPE_DEPTH
from plcpred.parser.st import parse_st
from plcpred.parser.typegraph import MAX_INHERITANCE_DEPTH, MAX_TYPE_NESTING
from plcpred.sequencer.compiler import compile_program
from plcpred.sequencer.executor import ProgramInstance

FILE = "t.st"


def _main(var_type="BOOL", body="o := NOT o;", init=None):
    decl = f"x : {var_type}" + (f" := {init}" if init is not None else "") + ";"
    return f"PROGRAM Main\nVAR\n  {decl}\n  o : BOOL;\nEND_VAR\n{body}\nEND_PROGRAM\n"


def _refused(src, match, line=None, seconds=8.0, checked=True) -> ProgramError:
    """The program is refused with a positioned ProgramError matching ``match`` by every
    stage it reaches (parser, checker unless not ``checked``, compiler), within
    ``seconds`` of CPU time in all (a guard against work without end, such as the 19 s
    of a 3,000-long EXTENDS chain before, not a benchmark: the suite shares its cores)."""
    start = time.process_time()
    try:
        program = parse_st(src, FILE)
    except ProgramError as e:
        found = [e]
    else:
        errors, _ = check_program(program, [program])
        assert errors or not checked, "the checker accepts it"
        with pytest.raises(ProgramError) as compiled:
            compile_program(program)
        found = errors[:1] + [compiled.value]
    assert time.process_time() - start < seconds
    for e in found:
        assert e.file == FILE and e.line >= 1 and e.col >= 1, str(e)
        assert line is None or e.line == line, str(e)
        assert match in e.message, str(e)
    return found[0]


def _runs(src, **values):
    """The program checks, compiles and runs; its variables end with ``values``."""
    program = parse_st(src, FILE)
    errors, _ = check_program(program, [program])
    assert not errors, errors
    inst = ProgramInstance(program)
    for k in range(3):
        inst.scan(k * 10_000_000)
    for name, want in values.items():
        obj, attr, _ = inst.locate(name)
        assert getattr(obj, attr) == want, name


# ------------------------------------------------------------------ inheritance

FB_A_EXTENDS_A = ("FUNCTION_BLOCK A EXTENDS A\nVAR q : BOOL; END_VAR\nq := NOT q;\n"
                  "END_FUNCTION_BLOCK\n")


@pytest.mark.parametrize("types, var_type, line", [
    (FB_A_EXTENDS_A, "A", 1),
    ("FUNCTION_BLOCK A EXTENDS B\nVAR q : BOOL; END_VAR\nEND_FUNCTION_BLOCK\n"
     "FUNCTION_BLOCK B EXTENDS C\nVAR r : BOOL; END_VAR\nEND_FUNCTION_BLOCK\n"
     "FUNCTION_BLOCK C EXTENDS A\nVAR s : BOOL; END_VAR\nEND_FUNCTION_BLOCK\n", "C", 1),
    # a generic block extending its own copy: the copy extends itself
    ("FUNCTION_BLOCK FB_G EXTENDS FB_G<N>\nVAR_GENERIC CONSTANT N : UDINT; END_VAR\n"
     "VAR q : BOOL; END_VAR\nEND_FUNCTION_BLOCK\n", "FB_G<4>", 1),
    ("TYPE S EXTENDS S : STRUCT a : INT; END_STRUCT; END_TYPE\n", "S", 1),
    ("TYPE S EXTENDS T : STRUCT a : INT; END_STRUCT; END_TYPE\n"
     "TYPE T EXTENDS S : STRUCT b : INT; END_STRUCT; END_TYPE\n", "T", 1),
    ("INTERFACE I EXTENDS J\nEND_INTERFACE\nINTERFACE J EXTENDS I\nEND_INTERFACE\n", "I", 1),
])
def test_a_type_extending_itself_is_an_error(types, var_type, line):
    _refused(types + _main(var_type), "EXTENDS itself", line)


def test_a_generic_block_extending_new_copies_of_itself_stops():
    src = ("FUNCTION_BLOCK FB_G EXTENDS FB_G<(N + 1)>\nVAR_GENERIC CONSTANT N : UDINT; "
           "END_VAR\nVAR q : BOOL; END_VAR\nEND_FUNCTION_BLOCK\n" + _main("FB_G<4>"))
    _refused(src, f"more than {MAX_INHERITANCE_DEPTH} levels deep", 1)


def _extends_chain(kind, n):
    if kind == "FUNCTION_BLOCK":
        head = "FUNCTION_BLOCK F0\nVAR_OUTPUT q : BOOL; END_VAR\nq := TRUE;\nEND_FUNCTION_BLOCK\n"
        return head + "".join(f"FUNCTION_BLOCK F{i} EXTENDS F{i - 1}\nVAR v{i} : INT; "
                              "END_VAR\nSUPER^();\nEND_FUNCTION_BLOCK\n" for i in range(1, n))
    if kind == "STRUCT":
        return "TYPE F0 : STRUCT q : BOOL; END_STRUCT; END_TYPE\n" + "".join(
            f"TYPE F{i} EXTENDS F{i - 1} : STRUCT v{i} : INT; END_STRUCT; END_TYPE\n"
            for i in range(1, n))
    return "INTERFACE F0\nEND_INTERFACE\n" + "".join(
        f"INTERFACE F{i} EXTENDS F{i - 1}\nEND_INTERFACE\n" for i in range(1, n))


@pytest.mark.parametrize("kind", ["FUNCTION_BLOCK", "STRUCT", "INTERFACE"])
def test_inheritance_depth_is_bounded(kind):
    # 3,000 took 19 s and then a RecursionError (FUNCTION_BLOCK); the error now comes
    # from the type graph, in linear time
    e = _refused(_extends_chain(kind, 3000) + _main("F2999"),
                 f"at most {MAX_INHERITANCE_DEPTH} are supported")
    assert "levels of EXTENDS" in e.message


@pytest.mark.parametrize("base", ["TYPE B : INT; END_TYPE\n",
                                  "TYPE B : ARRAY[0..1] OF INT; END_TYPE\n",
                                  "FUNCTION_BLOCK B\nVAR q : BOOL; END_VAR\nEND_FUNCTION_BLOCK\n"])
def test_a_struct_extending_what_is_no_struct_is_an_error(base):
    # found with the type graph's fuzzing: an AttributeError ('Elem' has no 'members')
    _refused(base + "TYPE S EXTENDS B : STRUCT a : INT; END_STRUCT; END_TYPE\n" + _main("S"),
             "STRUCT S EXTENDS B, which is not a structure", checked=False)


def test_inheritance_at_the_limit_runs():
    n = MAX_INHERITANCE_DEPTH + 1            # F0 and 64 levels above it
    _runs(_extends_chain("FUNCTION_BLOCK", n)
          + _main(f"F{n - 1}", "x(); o := x.q;"), o=True)
    _refused(_extends_chain("FUNCTION_BLOCK", n + 1) + _main(f"F{n}", "x(); o := x.q;"),
             "at most 64 are supported")


# ------------------------------------------------------------------ types holding themselves

@pytest.mark.parametrize("types, var_type, match, line", [
    ("TYPE A : A; END_TYPE\n", "A", "type A is defined in terms of itself", 1),
    ("TYPE A : B; END_TYPE\nTYPE B : A; END_TYPE\n", "A", "defined in terms of itself", None),
    ("TYPE P : POINTER TO P; END_TYPE\n", "P", "type P is defined in terms of itself", 1),
    ("TYPE P : POINTER TO Q; END_TYPE\nTYPE Q : ARRAY[0..1] OF P; END_TYPE\n", "P",
     "defined in terms of itself", None),
    ("TYPE S : STRUCT a : INT; s : S; END_STRUCT; END_TYPE\n", "S",
     "STRUCT S holds a value of itself", 1),
    ("TYPE S : STRUCT a : INT; t : T; END_STRUCT; END_TYPE\n"
     "TYPE T : STRUCT s : S; END_STRUCT; END_TYPE\n", "S", "holds a value of itself", None),
    ("TYPE S : STRUCT a : INT; s : ARRAY[0..1] OF S; END_STRUCT; END_TYPE\n", "S",
     "STRUCT S holds a value of itself", 1),
    ("FUNCTION_BLOCK A\nVAR q : BOOL; a : A; END_VAR\nEND_FUNCTION_BLOCK\n", "A",
     "A holds an instance of itself", 2),
    ("FUNCTION_BLOCK A EXTENDS B\nVAR q : BOOL; END_VAR\nEND_FUNCTION_BLOCK\n"
     "FUNCTION_BLOCK B\nVAR a : ARRAY[1..2] OF A; END_VAR\nEND_FUNCTION_BLOCK\n", "A",
     "holds an instance of itself", None),
    ("TYPE S : STRUCT f : A; END_STRUCT; END_TYPE\nFUNCTION_BLOCK A\nVAR s : S; END_VAR\n"
     "END_FUNCTION_BLOCK\n", "A", "holds", None),
])
def test_a_type_holding_itself_is_an_error(types, var_type, match, line):
    _refused(types + _main(var_type), match, line)


def test_a_pointer_to_itself_is_a_linked_list_not_an_error():
    body = "x.p := ADR(x); x.a := 4; o := x.p^.a = 4;"
    _runs("TYPE S : STRUCT a : INT; p : POINTER TO S; END_STRUCT; END_TYPE\n"
          + _main("S", body), o=True)
    _refused("TYPE S : STRUCT a : INT; p : POINTER TO S; s : S; END_STRUCT; END_TYPE\n"
             + _main("S", body), "STRUCT S holds a value of itself", 1)


# ------------------------------------------------------------------ nesting

@pytest.mark.parametrize("var_type, init, match", [
    ("ARRAY[0..1] OF " * 5000 + "INT", None, "type nested more than"),
    ("POINTER TO " * 5000 + "INT", None, "type nested more than"),
    ("REFERENCE TO " * 5000 + "INT", None, "type nested more than"),
    ("ARRAY[" + ", ".join(["0..0"] * 5000) + "] OF INT", None, "type nested more than"),
    ("STRUCT a : " * 2000 + "INT;" + " END_STRUCT;" * 2000, None, "type nested more than"),
    ("ARRAY[0..1] OF INT", "[" * 5000 + "1" + "]" * 5000, "initial value nested more than"),
    ("ARRAY[0..1] OF INT", "(a := " * 5000 + "1" + ")" * 5000,
     "initial value nested more than"),
])
def test_deeply_nested_types_and_initial_values_are_errors(var_type, init, match):
    _refused(_main(var_type, init=init), match, 3)


def test_nesting_at_the_limits_runs():
    n = MAX_TYPE_DEPTH
    idx = "[0]" * n
    _runs(_main("ARRAY[0..0] OF " * n + "INT",
                f"IF x{idx} = 7 THEN o := TRUE; END_IF; x{idx} := 0;",
                init="[" * n + "7" + "]" * n), o=True)
    _refused(_main("ARRAY[0..0] OF " * (n + 1) + "INT"), f"more than {n} levels", 3)
    m = MAX_INITIALIZER_DEPTH
    structs = "".join(f"TYPE S{i} : STRUCT a : INT; s : S{i + 1}; END_STRUCT; END_TYPE\n"
                      for i in range(m)) + f"TYPE S{m} : STRUCT a : INT; END_STRUCT; END_TYPE\n"
    init = "(s := " * (m - 1) + "(a := 3)" + ")" * (m - 1)
    _runs(structs + _main("S0", "o := x" + ".s" * (m - 1) + ".a = 3;", init=init), o=True)
    deeper = "(s := " * m + "(a := 3)" + ")" * m
    _refused(structs + _main("S0", init=deeper), f"more than {m} levels", m + 4)


def _alias_chain(n):
    return ("".join(f"TYPE T{i} : T{i + 1}; END_TYPE\n" for i in range(n))
            + f"TYPE T{n} : INT; END_TYPE\n")


def _struct_chain(n):
    return ("".join(f"TYPE T{i} : STRUCT a : INT; s : T{i + 1}; END_STRUCT; END_TYPE\n"
                    for i in range(n)) + f"TYPE T{n} : STRUCT a : INT; END_STRUCT; END_TYPE\n")


def _fb_chain(n):
    return ("".join(f"FUNCTION_BLOCK T{i}\nVAR q : BOOL; f : T{i + 1}; END_VAR\nf(); q := f.q;"
                    "\nEND_FUNCTION_BLOCK\n" for i in range(n))
            + f"FUNCTION_BLOCK T{n}\nVAR q : BOOL; END_VAR\nq := TRUE;\nEND_FUNCTION_BLOCK\n")


@pytest.mark.parametrize("chain", [_alias_chain, _struct_chain, _fb_chain])
def test_long_chains_of_named_types_are_errors(chain):
    e = _refused(chain(3000) + _main("T0"), f"more than {MAX_TYPE_NESTING}")
    assert "nests types 65 levels deep" in e.message


def test_named_nesting_at_the_limit_runs():
    n = MAX_TYPE_NESTING - 1                  # Main holds T0, which holds T1 ... T63
    _runs(_fb_chain(n) + _main("T0", "x(); o := x.q;"), o=True)
    e = _refused(_fb_chain(n + 1) + _main("T0", "x(); o := x.q;"), "more than 64")
    assert e.message.startswith("Main nests types 65 levels deep (Main > T0 > T1")


def test_types_chained_through_pointers_stop_before_the_stack_does():
    n = 3000            # a ring of structs, each pointing at the next: no value holds
    types = "".join(f"TYPE S{i} : STRUCT a : INT; p : POINTER TO S{(i + 1) % n}; "
                    "END_STRUCT; END_TYPE\n" for i in range(n))
    program = parse_st(types + _main("S0"), FILE)
    assert not check_program(program)[0]
    with pytest.raises(ProgramError, match="types refer to each other more than") as e:
        compile_program(program)
    assert e.value.file == FILE and e.value.line >= 1


# ------------------------------------------------------------------ bits

@pytest.mark.parametrize("var_type, good, bad, match", [
    ("BYTE", 7, 8, "bit 8 of a BYTE: a BYTE has bits 0..7"),
    ("WORD", 15, 16, "bit 16 of a WORD: a WORD has bits 0..15"),
    ("INT", 15, 16, "bit 16 of a INT"),
    ("DWORD", 31, 32, "bit 32 of a DWORD: a DWORD has bits 0..31"),
    ("BOOL", None, 0, "on a BOOL, which has no bits"),
    ("REAL", None, 3, "only integers and bit strings"),
])
def test_a_bit_index_is_within_the_width_of_the_type(var_type, good, bad, match):
    if good is not None:
        _runs(_main(var_type, f"x.{good} := TRUE; o := x.{good};"), o=True)
    _refused(_main(var_type, f"o := x.{bad};"), match, 6)
    _refused(_main(var_type, f"x.{bad} := TRUE;"), match, 6)


def test_the_widest_types_keep_their_64_bits():
    _runs(_main("LWORD", "x.63 := TRUE; o := x.63 AND NOT x.62;"), o=True)
    _runs(_main("ULINT", "x.63 := TRUE; o := x = ULINT#16#8000000000000000;"), o=True)
    _refused(_main("LWORD", "o := x.64;"), "a bit number 0..63")
    _refused(_main("UDINT", "o := x.32;"), "bit 32 of a UDINT: a UDINT has bits 0..31", 6)


# ------------------------------------------------------------------ huge literals

@pytest.mark.parametrize("body, match", [
    ("o := x." + "9" * 5000 + ";", "a bit number 0..63"),
    ("o := x.%X" + "9" * 5000 + ";", "a bit number 0..63"),
    ("x := T#" + "9" * 5000 + "s;", "a number of 5000 digits"),
    ("x := T#1." + "9" * 5000 + "s;", "a number of 5002 digits"),
])
def test_literals_of_thousands_of_digits_are_errors(body, match):
    e = _refused(_main("WORD" if "x." in body else "TIME", body), match, 6)
    assert len(e.message) < 200


def _product(leaf, n):
    items = [leaf] * n
    while len(items) > 1:
        items = [f"({a} * {b})" for a, b in zip(items[::2], items[1::2])]
    return items[0]


@pytest.mark.parametrize("types, var_type", [
    ("", "ARRAY[0.." + _product("18446744073709551615", 2048) + "] OF INT"),
    ("TYPE E : (a := " + _product("18446744073709551615", 2048) + ", b); END_TYPE\n", "E"),
])
def test_constant_expressions_beyond_64_bits_are_errors(types, var_type):
    # each factor is a valid literal; their product had 40,000 digits (the checker does
    # not work out array bounds: the compiler, which `plcpred check` runs too, does)
    _refused(types + _main(var_type), "constant expression out of range", checked=False)


# ------------------------------------------------------------------ the command line

def _limit_memory():
    resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30))


@pytest.mark.parametrize("src", [
    FB_A_EXTENDS_A + _main("A"),
    "TYPE A : B; END_TYPE\nTYPE B : A; END_TYPE\n" + _main("A"),
    _main("ARRAY[0..1] OF " * 20_000 + "INT"),
    _main("WORD", "o := x.16;"),
    _extends_chain("FUNCTION_BLOCK", 3000) + _main("F2999"),
], ids=["extends-itself", "alias-cycle", "deep-array", "bit-16", "extends-chain"])
def test_the_command_line_names_the_place(src, tmp_path):
    program = tmp_path / "p.st"
    program.write_text(src)
    machine = tmp_path / "m.toml"
    machine.write_text('[machine]\nname = "m"\nprogram = "p.st"\nscan_ms = 10\n'
                       'supply_bar_g = 6.0\n')
    # (check's gate finds errors: 1; a program another command cannot run: bad input, 2)
    for cmd, code in ((["check", str(program)], 1),
                      (["timeline", str(machine), "--horizon", "1s", "--out",
                        str(tmp_path / "o")], 2)):
        r = subprocess.run([sys.executable, "-m", "plcpred", *cmd], capture_output=True,
                           text=True, timeout=60, preexec_fn=_limit_memory)
        assert r.returncode == code, (cmd, r.returncode, r.stderr)
        assert "Traceback" not in r.stderr and "internal error" not in r.stderr, r.stderr
        assert f"{program}:" in r.stderr, (cmd, r.stderr)
