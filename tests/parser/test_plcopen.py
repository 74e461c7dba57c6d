"""PLCopen TC6 XML import."""
import pytest

from plcpred.parser import ProgramError, ir, load_program
from plcpred.parser.plcopen import parse_plcopen

HEAD = ('<?xml version="1.0" encoding="utf-8"?>\n'
        '<project xmlns="http://www.plcopen.org/xml/tc6_0201" '
        'xmlns:xhtml="http://www.w3.org/1999/xhtml">\n')


def project(pous="", types="", instances=""):
    return (HEAD + f"<types><dataTypes>{types}</dataTypes><pous>{pous}</pous></types>\n"
            + f"<instances><configurations>{instances}</configurations></instances>\n</project>\n")


def test_rig_xml_and_seq_give_the_same_chart(samples_dir):
    xml = load_program(samples_dir / "prototype_rig" / "rig.xml")
    seq = load_program(samples_dir / "prototype_rig" / "rig.seq")
    a, b = xml.pou("Rig").body, seq.pou("Rig").body
    assert a.steps == b.steps
    assert a.transitions == b.transitions
    assert a.actions == b.actions
    assert xml.types[0].type.values[1] == ("Auto", ir.Literal(1, "ANY_INT"))
    assert xml.globals[0].name == "GVL_Rig"
    res = xml.configurations[0].resources[0]
    assert res.tasks[0].params["INTERVAL"] == ir.Literal(10 * 10**6, "TIME")
    assert res.programs[0].type_name == "Rig" and res.programs[0].task == "Cyclic"


def test_st_pou_with_types_and_initial_values():
    prog = parse_plcopen(project(
        types='<dataType name="ST_P"><baseType><struct>'
              '<variable name="x"><type><REAL/></type></variable></struct></baseType></dataType>',
        pous='<pou name="F" pouType="function"><interface><returnType><INT/></returnType>'
             '<inputVars><variable name="a" address="%IW2"><type><INT/></type></variable></inputVars>'
             '<localVars constant="true"><variable name="arr"><type><array>'
             '<dimension lower="1" upper="3"/><baseType><INT/></baseType></array></type>'
             '<initialValue><arrayValue><value repetitionValue="3"><simpleValue value="7"/>'
             '</value></arrayValue></initialValue></variable>'
             '<variable name="s"><type><string length="10"/></type></variable>'
             '<variable name="p"><type><derived name="ST_P"/></type><initialValue><structValue>'
             '<value member="x"><simpleValue value="1.5"/></value></structValue></initialValue>'
             '</variable></localVars></interface>'
             '<body><ST><xhtml:p><![CDATA[F := a + arr[1];]]></xhtml:p></ST></body></pou>'), "f.xml")
    f = prog.pous[0]
    assert f.kind == "FUNCTION" and f.return_type == ir.NamedType("INT")
    d = {x.name: x for x in f.decls()}
    assert d["a"].address == "%IW2"
    assert d["arr"].init == ir.ArrayInit([(3, ir.Literal(7, "ANY_INT"))])
    assert d["s"].type == ir.StringType(False, ir.Literal(10, "ANY_INT"))
    assert d["p"].init == ir.StructInit([("x", ir.Literal(1.5, "ANY_REAL"))])
    assert f.var_blocks[1].qualifiers == ["CONSTANT"]
    assert isinstance(f.body[0], ir.Assign)


def sfc_pou(elements, transitions=""):
    return project(pous=f'<pou name="S" pouType="program"><interface><localVars>'
                        f'<variable name="go"><type><BOOL/></type></variable></localVars>'
                        f'</interface><body><SFC>{elements}</SFC></body>'
                        f'<transitions>{transitions}</transitions></pou>')


def cond(text):
    return f'<condition><inline name="c"><ST><xhtml:p>{text}</xhtml:p></ST></inline></condition>'


def conn(*ids):
    return ("<connectionPointIn>" + "".join(f'<connection refLocalId="{i}"/>' for i in ids)
            + "</connectionPointIn>")


def test_sfc_simultaneous_and_selection_divergence_and_jump():
    xml = sfc_pou(
        '<step localId="1" name="Init" initialStep="true"/>'
        f'<transition localId="2">{conn(1)}{cond("go")}</transition>'
        f'<simultaneousDivergence localId="3">{conn(2)}</simultaneousDivergence>'
        f'<step localId="4" name="A">{conn(3)}</step>'
        f'<step localId="5" name="B">{conn(3)}</step>'
        f'<simultaneousConvergence localId="6">{conn(4, 5)}</simultaneousConvergence>'
        f'<transition localId="7">{conn(6)}{cond("A.T &gt;= T#1s")}</transition>'
        f'<step localId="8" name="C">{conn(7)}</step>'
        f'<selectionDivergence localId="9">{conn(8)}</selectionDivergence>'
        f'<transition localId="10">{conn(9)}{cond("go")}</transition>'
        f'<transition localId="11">{conn(9)}<condition><reference name="Back"/></condition></transition>'
        f'<jumpStep localId="12" targetName="Init">{conn(10)}</jumpStep>'
        f'<jumpStep localId="13" targetName="A">{conn(11)}</jumpStep>'
        f'<actionBlock localId="14">{conn(8)}<action localId="0" qualifier="L" duration="T#2s">'
        '<reference name="go"/></action><action localId="0" qualifier="P"><inline><ST>'
        '<xhtml:p>go := FALSE;</xhtml:p></ST></inline></action></actionBlock>',
        '<transition name="Back"><body><ST><xhtml:p>Back := NOT go;</xhtml:p></ST></body></transition>')
    sfc = parse_plcopen(xml, "s.xml").pous[0].body
    t = [(tr.sources, tr.targets, tr.priority) for tr in sfc.transitions]
    assert t == [(["Init"], ["A", "B"], 0), (["A", "B"], ["C"], 0), (["C"], ["Init"], 0),
                 (["C"], ["A"], 1)]
    assert sfc.transitions[3].condition == ir.Unary("NOT", ir.Name("go"))
    c = next(s for s in sfc.steps if s.name == "C")
    assert c.actions[0] == ir.ActionAssoc("go", "L", ir.Literal(2 * 10**9, "TIME"))
    assert c.actions[1].action == "C_action1" and sfc.actions[0].name == "C_action1"


def test_st_error_position_is_the_position_in_the_xml_file():
    xml = project(pous='<pou name="P" pouType="program"><body><ST><xhtml:p><![CDATA[\n'
                       'x := 1;\n'
                       'y := ;\n'
                       ']]></xhtml:p></ST></body></pou>')
    with pytest.raises(ProgramError) as ei:
        parse_plcopen(xml, "p.xml")
    lines = xml.splitlines()
    line = next(i for i, l in enumerate(lines, 1) if l.startswith("y := ;"))
    assert (ei.value.file, ei.value.line, ei.value.col) == ("p.xml", line, 6)


@pytest.mark.parametrize("xml, fragment", [
    (HEAD + "<types>", "not well-formed XML"),
    ('<?xml version="1.0"?><other/>', "not a PLCopen XML file"),
    (sfc_pou('<step localId="1" name="A"/>'), "exactly one initial step"),
    (sfc_pou('<step localId="1" name="A" initialStep="true"/>'
             f'<transition localId="2">{conn(1)}{cond("go")}</transition>'
             f'<jumpStep localId="3" targetName="Nowhere">{conn(2)}</jumpStep>'),
     "jump to unknown step 'Nowhere'"),
])
def test_unconvertible_input_is_named(xml, fragment):
    with pytest.raises(ProgramError) as ei:
        parse_plcopen(xml, "bad.xml")
    assert fragment in ei.value.message
    assert ei.value.line > 0


def test_graphical_pous_load_with_a_warning_and_only_running_one_is_an_error():
    from plcpred.parser.check import check_program
    from plcpred.sequencer import ExecutionError
    from plcpred.sequencer.executor import ProgramInstance
    xml = project(
        pous='<pou name="Lad" pouType="functionBlock"><interface><inputVars><variable name="a">'
             '<type><BOOL/></type></variable></inputVars></interface><body><IL/></body></pou>'
             '<pou name="P" pouType="program"><interface><localVars>'
             '<variable name="l"><type><derived name="Lad"/></type></variable>'
             '<variable name="go"><type><BOOL/></type></variable>'
             '<variable name="n"><type><INT/></type></variable></localVars></interface>'
             '<body><ST><xhtml:p><![CDATA[n := n + 1; IF go THEN l(a := TRUE); END_IF]]>'
             '</xhtml:p></ST></body></pou>')
    prog = parse_plcopen(xml, "g.xml")
    errors, warnings = check_program(prog)
    assert errors == [] and ["IL body of POU 'Lad'" in w.message for w in warnings] == [True]
    inst = ProgramInstance(prog)
    inst.scan(0)
    assert inst.programs[0].N == 1
    inst.programs[0].GO = True
    with pytest.raises(ExecutionError, match="IL body of POU 'Lad'"):
        inst.scan(10_000_000)


def test_methods_exported_as_vendor_data():
    xml = project(pous='<pou name="FB" pouType="functionBlock"><interface><outputVars>'
                       '<variable name="q"><type><BOOL/></type></variable></outputVars></interface>'
                       '<body><ST><xhtml:p>q := Check(1);</xhtml:p></ST></body>'
                       '<addData><data name="http://www.3s-software.com/plcopenxml/method" '
                       'handleUnknown="implementation"><Method name="Check">'
                       '<interface><returnType><BOOL/></returnType><inputVars><variable name="n">'
                       '<type><INT/></type></variable></inputVars></interface>'
                       '<body><ST><xhtml:p>Check := n &gt; 0;</xhtml:p></ST></body>'
                       '</Method></data></addData></pou>')
    fb = parse_plcopen(xml, "m.xml").pous[0]
    (m,) = fb.methods
    assert m.name == "Check" and m.return_type == ir.NamedType("BOOL")
    assert m.body == [ir.Assign(ir.Name("Check"),
                                ir.Binary(">", ir.Name("n"), ir.Literal(0, "ANY_INT")))]
    from plcpred.parser.check import check_program
    assert check_program(parse_plcopen(xml, "m.xml"))[0] == []


def test_missing_attribute_is_reported_at_its_element():
    xml = project(pous='<pou pouType="program"><body><ST><xhtml:p>;</xhtml:p></ST></body></pou>')
    with pytest.raises(ProgramError) as ei:
        parse_plcopen(xml, "a.xml")
    assert ei.value.message == "<pou> needs a 'name' attribute"
    assert ei.value.line == 3


def test_beremiz_style_export_with_layout_data_and_uppercase_string():
    from pathlib import Path
    prog = load_program(Path(__file__).resolve().parents[1] / "data" / "beremiz_sfc.xml")
    pou = prog.pous[0]
    sfc = pou.body
    assert [(t.sources, t.targets) for t in sfc.transitions] == [(["Init"], ["Work"]),
                                                                 (["Work"], ["Init"])]
    assert sfc.steps[1].actions == [ir.ActionAssoc("valve", "N")]
    label = next(d for d in pou.decls() if d.name == "label")
    assert label.type == ir.StringType(False, None)
    assert label.init == ir.Literal("hi", "STRING")
    from plcpred.parser.check import check_program
    assert check_program(prog)[0] == []


@pytest.mark.parametrize("interval, ns", [("PT0.05S", 50_000_000), ("00:00:00.1", 100_000_000),
                                          ("P0DT0H1M0S", 60_000_000_000), ("T#20ms", 20_000_000)])
def test_task_intervals_as_xsd_durations_and_clock_times(interval, ns):
    xml = project(
        pous='<pou name="P" pouType="program"><body><ST><xhtml:p>;</xhtml:p></ST></body></pou>',
        instances='<configuration name="C"><resource name="R">'
                  f'<task name="T" interval="{interval}" priority="1">'
                  '<pouInstance name="p" typeName="P"/></task></resource></configuration>')
    task = parse_plcopen(xml, "t.xml").configurations[0].resources[0].tasks[0]
    assert task.params["INTERVAL"].value == ns


def test_a_task_interval_that_is_no_duration_is_named():
    xml = project(instances='<configuration name="C"><resource name="R">'
                            '<task name="T" interval="PT" priority="1"/></resource></configuration>')
    with pytest.raises(ProgramError, match="task interval 'PT'"):
        parse_plcopen(xml, "t.xml")


def test_a_pou_instance_with_an_empty_type_name_runs_the_program_it_is_named_after():
    xml = project(
        pous='<pou name="PRG_A" pouType="program"><body><ST><xhtml:p>;</xhtml:p></ST></body></pou>',
        instances='<configuration name="C"><resource name="R"><task name="T" interval="PT0.2S" '
                  'priority="1"><pouInstance name="PRG_A" typeName=""/></task></resource>'
                  '</configuration>')
    pi = parse_plcopen(xml, "t.xml").configurations[0].resources[0].programs[0]
    assert (pi.name, pi.type_name, pi.task) == ("PRG_A", "PRG_A", "T")


def test_type_and_value_errors_point_at_their_elements():
    from plcpred.parser.check import check_program
    xml = project(pous='<pou name="P" pouType="program"><interface><localVars>'
                       '<variable name="a"><type><derived name="NoSuchType"/></type></variable>'
                       '<variable name="n"><type><INT/></type><initialValue>'
                       '<simpleValue value="missing_const + 1"/></initialValue></variable>'
                       '</localVars></interface><body><ST><xhtml:p>;</xhtml:p></ST></body></pou>')
    errors, _ = check_program(parse_plcopen(xml, "p.xml"))
    lines = xml.splitlines()
    assert [(e.file, e.line) for e in errors] == [("p.xml", len(lines) - 2)] * 2
    assert [e.col > 1 for e in errors] == [True, True]


def test_beremiz_logger_and_python_blocks_come_from_the_shipped_stub(tmp_path):
    from plcpred.parser import load_program
    from plcpred.parser.check import check_program
    f = tmp_path / "plc.xml"
    f.write_text(project(pous='<pou name="P" pouType="program"><interface><localVars>'
                              '<variable name="log"><type><derived name="LOGGER"/></type></variable>'
                              '<variable name="py"><type><derived name="python_eval"/></type></variable>'
                              '<variable name="v"><type><derived name="HMI_INT"/></type></variable>'
                              '</localVars></interface><body><ST><xhtml:p><![CDATA['
                              'log(TRIG := TRUE, MSG := \'x\', LEVEL := INFO); py(TRIG := TRUE, CODE := \'1\');'
                              ' v := v + 1;]]></xhtml:p></ST></body></pou>'))
    errors, _ = check_program(load_program(f))
    assert errors == []


# ---------------------------------------------------------------- FBD and LD networks
def _at(x, y):
    return f'<position x="{x}" y="{y}"/>'


def _in(ref, formal=None):
    fp = f' formalParameter="{formal}"' if formal else ""
    return f'<connection refLocalId="{ref}"{fp}/>'


def _cpi(*conns):
    return "<connectionPointIn>" + "".join(conns) + "</connectionPointIn>"


def in_var(lid, expr, y, negated=False):
    return (f'<inVariable localId="{lid}" negated="{str(negated).lower()}">{_at(10, y)}'
            f'<connectionPointOut/><expression>{expr}</expression></inVariable>')


def out_var(lid, expr, y, *conns):
    return (f'<outVariable localId="{lid}">{_at(400, y)}{_cpi(*conns)}'
            f'<expression>{expr}</expression></outVariable>')


def in_out_var(lid, expr, y, *conns):
    return (f'<inOutVariable localId="{lid}">{_at(300, y)}{_cpi(*conns)}<connectionPointOut/>'
            f'<expression>{expr}</expression></inOutVariable>')


def block(lid, type_name, y, inputs, outputs=("OUT",), instance=None):
    inst = f' instanceName="{instance}"' if instance else ""
    negated = ' negated="true"'
    ins = "".join(f'<variable formalParameter="{f}"{negated if neg else ""}>'
                  f'{_cpi(c)}</variable>' for f, c, neg in inputs)
    outs = "".join(f'<variable formalParameter="{o}"><connectionPointOut/></variable>'
                   for o in outputs)
    return (f'<block localId="{lid}" typeName="{type_name}"{inst}>{_at(150, y)}'
            f'<inputVariables>{ins}</inputVariables><inOutVariables/>'
            f'<outputVariables>{outs}</outputVariables></block>')


def contact(lid, var, y, *conns, negated=False, edge=None):
    e = f' edge="{edge}"' if edge else ""
    return (f'<contact localId="{lid}" negated="{str(negated).lower()}"{e}>{_at(100, y)}'
            f'{_cpi(*conns)}<connectionPointOut/><variable>{var}</variable></contact>')


def coil(lid, var, y, *conns, negated=False, storage=None):
    st = f' storage="{storage}"' if storage else ""
    return (f'<coil localId="{lid}" negated="{str(negated).lower()}"{st}>{_at(300, y)}'
            f'{_cpi(*conns)}<connectionPointOut/><variable>{var}</variable></coil>')


def rail(lid, y):
    return f'<leftPowerRail localId="{lid}">{_at(0, y)}<connectionPointOut/></leftPowerRail>'


def graphical_pou(lang, body, variables):
    decls = "".join(f'<variable name="{n}"><type>{t}</type></variable>' for n, t in variables)
    return project(pous=f'<pou name="G" pouType="program"><interface><localVars>{decls}'
                        f'</localVars></interface><body><{lang}>{body}</{lang}></body></pou>')


def _same_run(xml, st_source, names, inputs, scans=60, period_ns=10_000_000, seed=3):
    """Scan the graphical program and its ST equivalent with the same random inputs and
    return the values of ``names`` after every scan, for both."""
    import random

    from plcpred.parser import parse_st
    from plcpred.sequencer.executor import ProgramInstance
    runs = []
    for prog in (parse_plcopen(xml, "g.xml"), parse_st(st_source, "g.st")):
        rng = random.Random(seed)
        inst = ProgramInstance(prog)
        trace = []
        state = dict.fromkeys(inputs, False)
        for k in range(scans):
            for name in inputs:       # each input flips now and then, and holds
                state[name] ^= rng.random() < 0.25
                setattr(inst.programs[0], name.upper(), state[name])
            inst.scan(k * period_ns)
            trace.append(tuple(getattr(inst.programs[0], n.upper()) for n in names))
        runs.append(trace)
    return runs


BOOLS = [(n, "<BOOL/>") for n in ("a", "b", "c", "q", "s", "nq")]


def test_ld_rungs_run_as_their_st_equivalent():
    # rung 1: a in series with (b parallel to NOT c) -> q; rung 2: rising a sets s;
    # rung 3: b resets s; rung 4: a -> negated coil nq
    body = (rail(1, 0)
            + contact(2, "a", 10, _in(1)) + contact(3, "b", 10, _in(2))
            + contact(4, "c", 30, _in(2), negated=True) + coil(5, "q", 10, _in(3), _in(4))
            + rail(6, 100) + contact(7, "a", 100, _in(6), edge="rising")
            + coil(8, "s", 100, _in(7), storage="set")
            + rail(9, 200) + contact(10, "b", 200, _in(9)) + coil(11, "s", 200, _in(10),
                                                                 storage="reset")
            + rail(12, 300) + contact(13, "a", 300, _in(12)) + coil(14, "nq", 300, _in(13),
                                                                   negated=True))
    xml = graphical_pou("LD", body, BOOLS)
    prog = parse_plcopen(xml, "g.xml")
    hidden = [d for d in prog.pous[0].decls() if d.type == ir.NamedType("R_TRIG")]
    assert len(hidden) == 1 and hidden[0].name not in {n for n, _ in BOOLS}
    st = """PROGRAM G VAR a, b, c, q, s, nq : BOOL; e : R_TRIG; END_VAR
    q := a AND (b OR NOT c);
    e(CLK := a); IF e.Q THEN s := TRUE; END_IF;
    IF b THEN s := FALSE; END_IF;
    nq := NOT a;
    END_PROGRAM"""
    graphical, text = _same_run(xml, st, ["q", "s", "nq"], ["a", "b", "c"])
    assert graphical == text
    assert {v for row in graphical for v in row} == {True, False}   # the run exercises both


def test_fbd_network_with_feedback_instances_and_operators_runs_as_its_st_equivalent():
    # cnt := SEL(G := reset, IN0 := cnt + 1, IN1 := 0) with the loop through an
    # inOutVariable; out := cnt read after it is written; a TON instance; GT(cnt, 3)
    body = (in_var(1, "reset", 0) + in_var(2, "1", 20) + in_var(3, "0", 40)
            + block(4, "ADD", 20, [("IN1", _in(5), False), ("IN2", _in(2), False)])
            + in_out_var(5, "cnt", 10, _in(6, "OUT"))
            + block(6, "SEL", 10, [("G", _in(1), False), ("IN0", _in(4, "OUT"), False),
                                   ("IN1", _in(3), False)])
            + out_var(7, "out", 5, _in(5))
            + in_var(8, "a", 100) + in_var(9, "T#30ms", 120)
            + block(10, "TON", 100, [("IN", _in(8), False), ("PT", _in(9), False)],
                    outputs=("Q", "ET"), instance="t1")
            + out_var(11, "late", 100, _in(10, "Q"))
            + in_var(12, "3", 160)
            + block(13, "GT", 150, [("IN1", _in(5), False), ("IN2", _in(12), False)])
            + out_var(14, "big", 150, _in(13, "OUT"))
            + block(15, "AND", 180, [("IN1", _in(8), False), ("IN2", _in(1), True)])
            + out_var(16, "both", 180, _in(15))
            # a block's ENO is its EN (plcpred's blocks do not fail)
            + block(17, "MOVE", 200, [("EN", _in(15), False), ("IN", _in(5), False)],
                    outputs=("ENO", "OUT"))
            + out_var(18, "ran", 200, _in(17, "ENO")))
    variables = [("reset", "<BOOL/>"), ("a", "<BOOL/>"), ("late", "<BOOL/>"),
                 ("big", "<BOOL/>"), ("both", "<BOOL/>"), ("ran", "<BOOL/>"), ("cnt", "<INT/>"),
                 ("out", "<INT/>"), ("t1", '<derived name="TON"/>')]
    xml = graphical_pou("FBD", body, variables)
    st = """PROGRAM G VAR reset, a, late, big, both, ran : BOOL; cnt, out : INT; t1 : TON; END_VAR
    cnt := SEL(G := reset, IN0 := cnt + 1, IN1 := 0);
    out := cnt;
    t1(IN := a, PT := T#30ms); late := t1.Q;
    big := cnt > 3;
    both := a AND NOT reset;
    ran := both;
    END_PROGRAM"""
    graphical, text = _same_run(xml, st, ["cnt", "out", "late", "big", "both", "ran"],
                                ["reset", "a"])
    assert graphical == text
    assert max(row[0] for row in graphical) > 3 and any(row[2] for row in graphical)


def test_fbd_transition_body_is_the_condition():
    # Beremiz draws a referenced transition as a network assigning the transition's name
    net = (in_var(1, "go", 0) + block(2, "NOT", 0, [("IN", _in(1), False)])
           + out_var(3, "STOP", 0, _in(2, "OUT")))
    xml = sfc_pou('<step localId="1" name="A" initialStep="true"/>'
                  f'<transition localId="2">{conn(1)}<condition><reference name="STOP"/>'
                  f'</condition></transition><step localId="3" name="B">{conn(2)}</step>',
                  transitions=f'<transition name="STOP"><body><FBD>{net}</FBD></body>'
                              '</transition>')
    t = parse_plcopen(xml, "t.xml").pous[0].body.transitions[0]
    assert t.condition == ir.Unary("NOT", ir.Name("go"))


def test_ld_condition_drawn_in_the_chart_is_the_condition():
    xml = sfc_pou('<step localId="1" name="A" initialStep="true"/>'
                  + rail(5, 0) + contact(6, "go", 0, _in(5), negated=True)
                  + f'<transition localId="2">{conn(1)}<condition>{_cpi(_in(6))}'
                    '</condition></transition>'
                  f'<step localId="3" name="B">{conn(2)}</step>')
    t = parse_plcopen(xml, "t.xml").pous[0].body.transitions[0]
    assert t.condition == ir.Binary("AND", ir.Literal(True, "BOOL"),
                                    ir.Unary("NOT", ir.Name("go")))


def _diamonds(levels):
    """Blocks each read twice by the next: written out as expressions they would double
    per level (2**levels reads), a hostile file's way to make the import run forever."""
    out = in_var(1, "a", 0)
    for k in range(levels):
        lid = 10 + k
        prev = 1 if k == 0 else lid - 1
        out += block(lid, "ADD", k, [("IN1", _in(prev), False), ("IN2", _in(prev), False)])
    return out + out_var(9, "q", 0, _in(10 + levels - 1))


@pytest.mark.parametrize("body, reason", [
    (out_var(1, "q", 0, _in(9)), "connection to unknown localId '9'"),
    (in_var(1, "a", 0) + block(2, "DIVMOD", 0, [("IN", _in(1), False)],
                               outputs=("Q", "R")) + out_var(3, "q", 0, _in(2, "R")),
     "only a function's result can be read"),
    (block(1, "ADD", 0, [("IN1", _in(2, "OUT"), False)])
     + block(2, "ADD", 0, [("IN1", _in(1, "OUT"), False)]) + out_var(3, "q", 0, _in(1)),
     "deeper than"),
    (_diamonds(40), "too large to convert"),
])
def test_a_network_that_cannot_be_converted_loads_and_says_why(body, reason):
    from plcpred.parser.check import check_program
    prog = parse_plcopen(graphical_pou("FBD", body, BOOLS), "g.xml")
    (opaque,) = prog.pous[0].body
    assert isinstance(opaque, ir.Opaque) and reason in opaque.what
    errors, warnings = check_program(prog)
    assert errors == [] and any(reason in w.message for w in warnings)


def test_a_machine_programmed_in_ladder_logic_predicts(samples_dir):
    """samples/ld_ejector.xml: a part every 4 s sets the ejector valve (rising-edge
    contact, S coil), the end switch resets it (R coil), a TP gives a 300 ms blast when the
    ejector is out. From the machine file alone: the valve is on from the part's edge until
    the scan after the end switch (switching delay 15 ms + extend 350 ms), 15 times in 60 s."""
    from plcpred import unfold
    from plcpred.machine import load_machine
    timeline = unfold(load_machine(samples_dir / "ld_ejector.toml"), "60s")
    eject = timeline.intervals("eject_valve")
    blast = timeline.intervals("blow_valve")
    assert len(eject) == len(blast) == 15
    assert eject.start_s.tolist() == pytest.approx([0.5 + 4 * k for k in range(15)])
    assert eject.duration_s.min() >= 0.365 and eject.duration_s.max() <= 0.365 + 0.0101
    assert blast.duration_s.tolist() == pytest.approx([0.3] * 15, abs=1e-9)
    assert (blast.start_s.to_numpy() == eject.end_s.to_numpy()).all()
    assert timeline.intervals("jammed").empty


def test_a_timer_drawn_in_the_chart_times_its_transition():
    # Beremiz's traffic light: a TON drawn in the SFC, fed by a step flag, is the
    # condition of the transition out of that step; it runs every scan of the chart
    xml = project(pous=(
        '<pou name="S" pouType="program"><interface><localVars>'
        '<variable name="t"><type><derived name="TON"/></type></variable>'
        '<variable name="inB"><type><BOOL/></type></variable></localVars></interface>'
        '<body><SFC><step localId="1" name="A" initialStep="true"/>'
        + in_var(10, "A.X", 0) + in_var(11, "T#50ms", 20)
        + block(12, "TON", 0, [("IN", _in(10), False), ("PT", _in(11), False)],
                outputs=("Q", "ET"), instance="t")
        + f'<transition localId="2">{conn(1)}<condition>{_cpi(_in(12, "Q"))}</condition>'
          '</transition>'
        f'<step localId="3" name="B">{conn(2)}</step>'
        f'<actionBlock localId="4">{conn(3)}<action localId="0" qualifier="N">'
        '<reference name="inB"/></action></actionBlock>'
        '</SFC></body></pou>'))
    from plcpred.sequencer.executor import ProgramInstance
    inst = ProgramInstance(parse_plcopen(xml, "s.xml"))
    first_in_b = None
    for k in range(12):
        inst.scan(k * 10_000_000)
        if inst.programs[0].INB and first_in_b is None:
            first_in_b = k
    # the timer runs from scan 0 (A active): Q at 50 ms, B active from the scan after
    assert first_in_b in (5, 6)


def test_beremiz_project_string_initials_and_extension_globals(tmp_path, capsys):
    """A Beremiz project folder: string initial values written bare (value="test", as
    Beremiz saves them), and globals its extensions declare (py_ext, c_ext variables and
    svghmi's CURRENT_PAGE_<channel>) reached through VAR_EXTERNAL."""
    from plcpred.cli import main
    from plcpred.sequencer.executor import ProgramInstance

    def var(name, type_xml, init=None):
        value = f'<initialValue><simpleValue value="{init}"/></initialValue>' if init else ""
        return f'<variable name="{name}"><type>{type_xml}</type>{value}</variable>'
    body = ("copy := Py_Count + C_In; page := CURRENT_PAGE_0; "
            "same := (s = 'te''st') AND (h = 'blup') AND (q = 'quoted');")
    (tmp_path / "plc.xml").write_text(project(
        types='<dataType name="MY_STR"><baseType><string/></baseType></dataType>',
        pous='<pou name="main" pouType="program"><interface><localVars>'
             + var("s", "<string/>", "te&apos;st") + var("h", '<derived name="MY_STR"/>', "blup")
             + var("q", "<string/>", "&apos;quoted&apos;")
             + var("copy", "<DINT/>") + var("page", '<derived name="HMI_STRING"/>')
             + var("same", "<BOOL/>")
             + '</localVars><externalVars>' + var("Py_Count", "<DINT/>")
             + var("C_In", "<SINT/>") + var("CURRENT_PAGE_0", '<derived name="HMI_STRING"/>')
             + f'</externalVars></interface><body><ST><xhtml:p><![CDATA[{body}]]></xhtml:p>'
             '</ST></body></pou>',
        instances='<configuration name="c"><resource name="r"><task name="t" interval="T#10ms" '
                  'priority="0"><pouInstance name="i" typeName="main"/></task></resource>'
                  '</configuration>'))
    (tmp_path / "beremiz.xml").write_text('<?xml version="1.0"?><BeremizRoot/>')
    py = tmp_path / "py_ext_0@py_ext"
    py.mkdir()
    (py / "pyfile.xml").write_text(
        '<?xml version="1.0"?><PyFile><variables>'
        '<variable name="Py_Count" type="DINT" initial="40"/></variables></PyFile>')
    c = tmp_path / "c_code@c_ext"
    c.mkdir()
    (c / "cfile.xml").write_text(
        '<?xml version="1.0"?><CFile><variables>'
        '<variable name="C_In" type="SINT" initial="2"/></variables></CFile>')
    hmi = tmp_path / "svghmi_0@svghmi"
    hmi.mkdir()
    (hmi / "baseconfnode.xml").write_text(
        '<?xml version="1.0"?><BaseParams IEC_Channel="0" Name="svghmi_0"/>')
    assert main(["check", str(tmp_path / "plc.xml")]) == 0
    inst = ProgramInstance(load_program(tmp_path / "plc.xml"))
    inst.guard(inst.scan, 0)
    p = inst.programs[0]
    assert (p.COPY, p.PAGE, p.SAME) == (42, "", True)
    # without beremiz.xml the folder is not a Beremiz project: the globals are missing
    (tmp_path / "beremiz.xml").unlink()
    capsys.readouterr()
    assert main(["check", str(tmp_path / "plc.xml")]) == 1
    assert "VAR_EXTERNAL Py_Count has no VAR_GLOBAL" in capsys.readouterr().err


def test_a_codesys_export_keeps_a_bare_string_initial_value_as_a_constant_name():
    # CODESYS quotes string literals in its exports: value="C_NAME" names a constant
    text = project(
        pous='<pou name="P" pouType="program"><interface><localVars>'
             '<variable name="s"><type><string/></type><initialValue>'
             '<simpleValue value="C_NAME"/></initialValue></variable></localVars>'
             '</interface><body><ST><xhtml:p><![CDATA[s := s;]]></xhtml:p></ST></body></pou>')
    codesys = text.replace("<types>", '<fileHeader companyName="" productName="CODESYS" '
                                      'productVersion="3.5" creationDateTime="2026-01-01T00:00:00"/>'
                                      "<types>")
    init = parse_plcopen(codesys, "c.xml").pous[0].var_blocks[0].decls[0].init
    assert isinstance(init, ir.Name) and init.name == "C_NAME"
    # the same file as Beremiz writes it: the bare value is the string
    init = parse_plcopen(text, "b.xml").pous[0].var_blocks[0].decls[0].init
    assert init == ir.Literal("C_NAME", "STRING")


def test_st_bodies_on_one_long_line_parse_in_linear_time_at_their_columns():
    """Each ST fragment was padded to its line and column with newlines and spaces: a
    0.9 MB file on one line took 53 s. The tokenizer now starts at the fragment's place.
    An error in the last body still names its true column."""
    import time

    from plcpred.parser import ProgramError
    pou = ('<pou name="F{k}" pouType="function"><interface><returnType><BOOL/></returnType>'
           '</interface><body><ST><xhtml:p>F{k} := {value};</xhtml:p></ST></body></pou>')
    head = ('<?xml version="1.0" encoding="utf-8"?><project xmlns="http://www.plcopen.org/'
            'xml/tc6_0201" xmlns:xhtml="http://www.w3.org/1999/xhtml"><types><dataTypes/>'
            '<pous>')
    pous = "".join(pou.format(k=k, value="TRUE") for k in range(3000))
    bad = pou.format(k=3000, value="TRUE +")
    text = head + pous + bad + "</pous></types></project>"
    assert "\n" not in text and len(text) > 400_000
    t0 = time.perf_counter()
    program = parse_plcopen(text.replace(bad, ""), "one_line.xml")
    assert len(program.pous) == 3000
    with pytest.raises(ProgramError) as e:
        parse_plcopen(text, "one_line.xml")
    assert time.perf_counter() - t0 < 30          # minutes before
    assert e.value.line == 1
    # the ';' after the dangling '+', at its column of the file's one line
    assert text[e.value.col - 1:].startswith(";</xhtml:p>")
    assert e.value.col == text.index("F3000 := TRUE +;") + len("F3000 := TRUE +") + 1


def test_a_file_of_millions_of_elements_stops_at_the_element_limit(monkeypatch):
    """12 MB of empty elements took 1 GB; now at most MAX_XML_ELEMENTS are read (set
    small here), and elements without children, text or attributes share empty ones."""
    import plcpred.parser.xmltree as xmltree
    from plcpred.parser import ProgramError
    monkeypatch.setattr(xmltree, "MAX_XML_ELEMENTS", 1000)
    text = ('<?xml version="1.0"?><project xmlns="http://www.plcopen.org/xml/tc6_0201">'
            + "<a/>" * 1200 + "</project>")
    with pytest.raises(ProgramError, match="more than 1,000 XML elements") as e:
        parse_plcopen(text, "many.xml")
    assert e.value.line == 1 and e.value.col > 1000 * 4
    tree = xmltree.parse_xml(text.replace("<a/>" * 1200, "<a/>" * 900), "x.xml")
    assert len(tree.children) == 900 and tree.children[0].children is tree.children[1].children
