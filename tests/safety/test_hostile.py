"""Program files are untrusted: nothing in them may run host code or trace back.

Three layers are tested separately, so that each would be caught failing on its own:
the name gate of every front end (``parser.names.validate_names``), the compiler's one
emission path (``ident``, which also guards IR built by hand), and the generated code's
namespace (no builtins beyond what the compiler emits). The payload files in
``tests/data/hostile`` ran Python on the code before the gate existed (checked by hand
against the earlier commit: ``unicode_exec.xml`` wrote its marker file and exited 0).
"""
import builtins
import keyword
import os
import random
import subprocess
import sys
from xml.sax.saxutils import quoteattr

import pytest

from plcpred.parser import ProgramError, ir
from plcpred.parser.check import check_program
from plcpred.parser.names import is_identifier, validate_names
from plcpred.parser.plcopen import parse_plcopen
from plcpred.parser.seq import parse_seq
from plcpred.parser.st import parse_st
from plcpred.sequencer.compiler import compile_program
from plcpred.sequencer.executor import ProgramInstance, program_namespace
from conftest import ROOT

HOSTILE = ROOT / "tests" / "data" / "hostile"
PAYLOADS = sorted(HOSTILE.glob("*.xml"))

# names that are valid identifiers but spell what the generated code or Python uses
TRICKY_VALID = ["_dflt", "_D", "self", "exec", "eval", "import", "_now", "_g", "k_FbBase",
                "fb_MAIN", "st_T", "__import__", "AT_IX0_0", "GLOBALS", "_t1", "_R_X",
                "p_ret", "_build", "__builtins__", "None_", "print", "open", "a_", "m_X",
                "Ellipsis", "_snap", "_body", "__slots__", "x__", "range", "int"]
# names no front end may accept
INVALID = ["𝑒𝑥𝑒𝑐", "x y", "a;b", "a\nb", "ＡＢＣ", "éa", "a.b(", "1abc", "__", "_", "",
           "a'b", 'a"b', "a)", "ıa", "ſelf", "ꓐ", "a\u200bb", "x" * 300, "a-b", "$a$",
           "X = exec('1'); self.Y"]


def _random_names(rng, n):
    alphabet = ("abcXYZ_09 ;:'\"()[]{}.\n\t\\#$%&*+-/<=>?@^`|~"
                "𝑒𝑥𝑐ℎéßıſＡＢ\u200b\u0301ꓐ中")
    out = []
    for _ in range(n):
        k = rng.randrange(1, 12)
        out.append("".join(rng.choice(alphabet) for _ in range(k)))
    out += [w for w in keyword.kwlist] + [w.upper() for w in keyword.kwlist]
    return out


def test_identifier_rule():
    assert all(is_identifier(n) for n in TRICKY_VALID)
    assert not any(is_identifier(n) for n in INVALID)


# ------------------------------------------------------------------ constructs

ST_TEMPLATE = """
TYPE {T} : STRUCT {M} : INT; END_STRUCT END_TYPE
TYPE {E} : ({EV}, Other) END_TYPE
FUNCTION {F} : INT
VAR_INPUT {I} : INT; END_VAR
VAR {L} : INT; END_VAR
{L} := {I} + 1;
{F} := {L};
END_FUNCTION
FUNCTION_BLOCK {FB}
VAR_INPUT {I} : BOOL; END_VAR
VAR_OUTPUT {O} : BOOL; END_VAR
VAR {V} : {T}; END_VAR
METHOD {MTH} : BOOL
VAR_INPUT {I} : BOOL; END_VAR
{MTH} := NOT {I};
END_METHOD
{O} := {I};
{V}.{M} := {F}({I} := 41);
END_FUNCTION_BLOCK
PROGRAM Main
VAR {INST} : {FB}; q : BOOL; n : INT; e : {E} := {EV}; END_VAR
{INST}({I} := TRUE, {O} => q);
n := {INST}.{V}.{M};
JMP {LBL};
n := 0;
{LBL}: q := q AND {INST}.{MTH}({I} := FALSE);
END_PROGRAM
"""
ST_SLOTS = {"T": "TPart", "M": "count", "E": "EMode", "EV": "Run", "F": "Inc", "I": "inp",
            "L": "tmp", "FB": "FbStation", "O": "outp", "V": "part", "MTH": "Check",
            "INST": "station", "LBL": "done"}

SEQ_TEMPLATE = """
sequence {SEQ}
input  {IN}
output {OUT}
var    {VAR} : INT := 0
initial step {S1}
    when {IN} -> {S2}
step {S2}
    S {OUT}
    P {ACT}
    after 1s -> {S1}
action {ACT}
    {VAR} := {VAR} + 1;
end_action
"""
SEQ_SLOTS = {"SEQ": "Station", "IN": "start", "OUT": "valve", "VAR": "cycles", "S1": "Idle",
             "S2": "Work", "ACT": "Count"}

XML_TEMPLATE = """<?xml version="1.0" encoding="utf-8"?>
<project xmlns="http://www.plcopen.org/xml/tc6_0201">
  <fileHeader companyName="x" productName="x" productVersion="1" creationDateTime="2026-11-23T08:00:00"/>
  <contentHeader name="Fuzz"><coordinateInfo><fbd><scaling x="1" y="1"/></fbd><ld><scaling x="1" y="1"/></ld><sfc><scaling x="1" y="1"/></sfc></coordinateInfo></contentHeader>
  <types><dataTypes>
    <dataType name={T}><baseType><struct><variable name={M}><type><INT/></type></variable></struct></baseType></dataType>
  </dataTypes><pous>
    <pou name={FB} pouType="functionBlock">
      <interface>
        <inputVars><variable name={I}><type><BOOL/></type></variable></inputVars>
        <outputVars><variable name={O}><type><BOOL/></type></variable></outputVars>
        <localVars><variable name={V}><type><derived name={T}/></type></variable></localVars>
      </interface>
      <actions><action name={ACT}><body><ST><xhtml xmlns="http://www.w3.org/1999/xhtml">{O_} := NOT {I_};</xhtml></ST></body></action></actions>
      <body><ST><xhtml xmlns="http://www.w3.org/1999/xhtml">{O_} := {I_}; {ACT_}();</xhtml></ST></body>
    </pou>
    <pou name="Main" pouType="program">
      <interface><localVars>
        <variable name={INST}><type><derived name={FB}/></type></variable>
        <variable name="q"><type><BOOL/></type></variable>
      </localVars></interface>
      <body><ST><xhtml xmlns="http://www.w3.org/1999/xhtml">{INST_}({I_} := TRUE, {O_} =&gt; q);</xhtml></ST></body>
    </pou>
  </pous></types>
  <instances><configurations/></instances>
</project>
"""
XML_SLOTS = {"T": "TPart", "M": "count", "FB": "FbStation", "I": "inp", "O": "outp",
             "V": "part", "ACT": "Flip", "INST": "station"}


def _st(slot, name):
    return ST_TEMPLATE.format(**{**ST_SLOTS, slot: name})


def _seq(slot, name):
    return SEQ_TEMPLATE.format(**{**SEQ_SLOTS, slot: name})


def _xml(slot, name):
    names = {**XML_SLOTS, slot: name}
    # attributes carry any text (quoted); body text is ST, where the name is escaped too
    values = {k: quoteattr(v) for k, v in names.items()}
    values.update({k + "_": v.replace("&", "&amp;").replace("<", "&lt;")
                   for k, v in names.items()})
    return XML_TEMPLATE.format(**values)


FRONT_ENDS = {"st": (_st, parse_st, ST_SLOTS), "seq": (_seq, parse_seq, SEQ_SLOTS),
              "xml": (_xml, parse_plcopen, XML_SLOTS)}


def _run(program, scans=3):
    inst = ProgramInstance(program)
    for k in range(scans):
        inst.scan(k * 10_000_000)
    return inst


def _attempt(parse, text, filename):
    """Parse, check, compile and run: a ProgramError, or the running instance."""
    try:
        program = parse(text, filename)
        check_program(program)
        return _run(program)
    except ProgramError as e:
        assert e.file == filename, str(e)
        return e


@pytest.mark.parametrize("fe", sorted(FRONT_ENDS))
def test_templates_run_with_ordinary_names(fe):
    make, parse, slots = FRONT_ENDS[fe]
    result = _attempt(parse, make("T" if fe != "seq" else "SEQ", slots.get("T", "Station")),
                      "t." + fe)
    assert isinstance(result, ProgramInstance), str(result)


@pytest.mark.parametrize("fe", sorted(FRONT_ENDS))
def test_hostile_names_in_every_construct_never_execute_or_trace_back(fe, tmp_path,
                                                                       monkeypatch):
    marker = tmp_path / "pwned"
    monkeypatch.setenv("PLCPRED_PWNED", str(marker))
    make, parse, slots = FRONT_ENDS[fe]
    rng = random.Random(f"hostile-{fe}")
    names = INVALID + _random_names(rng, 40)
    for slot in slots:
        for name in names + [rng.choice(TRICKY_VALID) for _ in range(3)]:
            result = _attempt(parse, make(slot, name), "t." + fe)
            if not is_identifier(name):
                assert isinstance(result, ProgramError), (slot, name)
            assert not marker.exists()


@pytest.mark.parametrize("fe", sorted(FRONT_ENDS))
def test_names_that_spell_generated_or_python_names_run_correctly(fe):
    make, parse, slots = FRONT_ENDS[fe]
    for slot in slots:
        for name in TRICKY_VALID:
            if name.upper() in {v.upper() for k, v in slots.items() if k != slot}:
                continue  # would clash with another slot's default name
            result = _attempt(parse, make(slot, name), "t." + fe)
            if isinstance(result, ProgramError):
                # a name the language reserves is a clean error, never a crash
                assert "identifier" not in result.message, (slot, name, str(result))
                continue
            assert isinstance(result, ProgramInstance)


def test_function_input_named_like_a_generated_sentinel_is_passed():
    # an input named _D used to clash with the compiler's "no argument" sentinel and was
    # silently ignored
    src = """FUNCTION Inc : INT VAR_INPUT _D : INT; END_VAR Inc := _D + 1; END_FUNCTION
PROGRAM Main VAR n : INT; END_VAR n := Inc(_D := 41); END_PROGRAM"""
    inst = _run(parse_st(src, "t.st"), scans=1)
    assert inst.programs[0].N == 42


def test_struct_member_through_a_function_with_tricky_names_computes():
    inst = _run(parse_st(_st("L", "_dflt"), "t.st"))
    assert inst.programs[0].N == 42


# ------------------------------------------------------------------ defence in depth

def test_compiler_rejects_unvalidated_names_in_hand_built_ir():
    decl = ir.VarDecl("X = 1; import os", ir.NamedType("BOOL"))
    pou = ir.Pou("PROGRAM", "Main", [ir.VarBlock("VAR", [decl])], [])
    with pytest.raises(ProgramError, match="not an IEC 61131-3 identifier"):
        compile_program(ir.Program(pous=[pou]))
    with pytest.raises(ProgramError):
        validate_names(ir.Program(pous=[ir.Pou("PROGRAM", "𝑒𝑥𝑒𝑐", [], [])]))
    bad_op = ir.Program(pous=[ir.Pou("PROGRAM", "Main", [], [
        ir.Assign(ir.Name("x"), ir.Binary("+ __import__('os') +", ir.Literal(1, "INT"),
                                          ir.Literal(2, "INT")))])])
    with pytest.raises(ProgramError, match="invalid op"):
        compile_program(bad_op)


def test_generated_code_has_only_the_builtins_it_needs():
    ns = program_namespace([], [])
    allowed = set(ns["__builtins__"])
    for dangerous in ("exec", "eval", "compile", "open", "__import__", "getattr",
                      "setattr", "globals", "vars", "breakpoint", "input", "type", "object"):
        assert dangerous not in allowed
    assert allowed <= set(dir(builtins))
    with pytest.raises(NameError):
        exec("__import__('os')", ns)


@pytest.mark.parametrize("path", PAYLOADS, ids=lambda p: p.name)
def test_payload_files_are_refused_by_every_command(path, tmp_path):
    marker = tmp_path / "pwned"
    machine = tmp_path / "m.toml"
    machine.write_text(f'[machine]\nname = "m"\nprogram = {str(path)!r}\nscan_ms = 10\n'
                       "supply_bar_g = 5.0\n")
    env = dict(os.environ, PLCPRED_PWNED=str(marker))
    commands = [["check", str(path)],
                ["timeline", str(machine), "--horizon", "1s", "--out", str(tmp_path / "o")],
                ["predict", str(machine), "--horizon", "1s", "--out", str(tmp_path / "o")],
                ["size", str(machine), "--horizon", "1s", "--out", str(tmp_path / "o")],
                ["compare", str(machine), str(machine), "--horizon", "1s"],
                ["sweep", str(machine), "--horizon", "1s", "--set", "supply_bar_g=4,5",
                 "--out", str(tmp_path / "o")]]
    for cmd in commands:
        r = subprocess.run([sys.executable, "-m", "plcpred", *cmd], capture_output=True,
                           text=True, env=env, timeout=120)
        assert r.returncode in (1, 2), (cmd, r.returncode, r.stderr)
        assert "Traceback" not in r.stderr, (cmd, r.stderr)
        assert f"{path}:" in r.stderr and "identifier" in r.stderr, (cmd, r.stderr)
        assert not marker.exists(), cmd


# ------------------------------------------------------------------ literals and nesting

def _st_expr(expr, decl="w : WORD; x : LREAL; i : INT; b : BOOL; a : ARRAY[0..3] OF INT;"):
    return f"PROGRAM P\nVAR {decl} END_VAR\nx := {expr};\nEND_PROGRAM\n"


@pytest.mark.parametrize("literal, message", [
    ("2#2", "not base-2 digits"), ("8#9", "not base-8 digits"), ("3#12", "base 3"),
    ("16#FFFFFFFFFFFFFFFFFFFFFFFFFFFFFFFF", "larger than any integer"),
    ("1" * 5000, "larger than any integer"),
    ("TOD#25:99:99", "does not exist"), ("D#2026-02-30", "does not exist"),
    ("INT#99999999999", "out of the range of INT"), ("SINT#-129", "out of the range"),
    ("WORD#-1", "out of the range of WORD"), ("1e999", "out of the range of LREAL"),
    ("REAL#1e39", "out of the range of REAL"), ("T#99999999999999999999d", "longer than"),
    ("w.2#1", "bit number"), ("w.64", "bit number"),
])
def test_bad_literals_are_positioned_errors(literal, message):
    with pytest.raises(ProgramError, match=message) as e:
        parse_st(_st_expr(literal), "t.st")
    assert (e.value.line, e.value.col) >= (3, 1)


@pytest.mark.parametrize("literal, value", [
    ("INT#16#FFFF", -1), ("TOD#23:59:59.5", 86_399_500_000_000), ("16#FF", 255),
    ("LINT#-9223372036854775808", -(1 << 63)), ("ULINT#18446744073709551615", (1 << 64) - 1),
    ("T#1d2h", 26 * 3600 * 10**9)])
def test_edge_literals_are_read(literal, value):
    assert parse_st(_st_expr(literal), "t.st").pous[0].body[0].value.value == value


@pytest.mark.parametrize("body, message", [
    ("x := " + " + ".join(["i"] * 150) + ";", "expression nested more than"),
    ("b := " + "NOT " * 3000 + "b;", "expression nested more than"),
    ("i := " + "a[" * 40 + "0" + "]" * 40 + ";", "expression nested more than"),
    ("IF b THEN " * 60 + "i := 1;" + " END_IF;" * 60, "statements nested more than"),
    ("FOR i := 0 TO 1 DO " * 13 + "b := TRUE;" + " END_FOR;" * 13, "loops nested more"),
])
def test_nesting_beyond_the_limits_is_a_positioned_error(body, message):
    src = _st_expr("0").replace("x := 0;", body)
    with pytest.raises(ProgramError, match=message) as e:
        parse_st(src, "t.st")
    assert e.value.line == 3


@pytest.mark.parametrize("body", [
    "x := " + "(" * 5000 + "1" + ")" * 5000 + ";",  # parentheses leave no trace in the IR
    "i := " + " + ".join(["i"] * 99) + ";",
    "i := " + "a[" * 33 + "0" + "]" * 33 + ";",
    "IF b THEN " * 40 + "i := 1;" + " END_IF;" * 40,
    "FOR i := 0 TO 1 DO " * 12 + "b := TRUE;" + " END_FOR;" * 12,
])
def test_nesting_within_the_limits_compiles_and_runs(body):
    src = _st_expr("0").replace("x := 0;", body)
    _run(parse_st(src, "t.st"), scans=1)


_LAUGHS = ('<?xml version="1.0"?><!DOCTYPE l [<!ENTITY a "aaaaaaaaaa">'
           + "".join(f'<!ENTITY {chr(98 + k)} "{("&" + chr(97 + k) + ";") * 10}">'
                     for k in range(8))
           + ']><project>&i;</project>')


@pytest.mark.parametrize("xml, message", [
    (_LAUGHS, "amplification"),
    ('<?xml version="1.0"?><!DOCTYPE p [<!ENTITY x SYSTEM "file:///etc/passwd">]>'
     '<project><types><pous><pou name="&x;" pouType="program"/></pous></types></project>',
     "external entity"),
    ("<project>" + "<a>" * 100_000 + "</a>" * 100_000 + "</project>", "nested more than"),
])
def test_xml_attacks_are_refused(xml, message):
    with pytest.raises(ProgramError, match=message):
        parse_plcopen(xml, "t.xml")
