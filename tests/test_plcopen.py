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
             '<type><BOOL/></type></variable></inputVars></interface><body><LD/></body></pou>'
             '<pou name="P" pouType="program"><interface><localVars>'
             '<variable name="l"><type><derived name="Lad"/></type></variable>'
             '<variable name="go"><type><BOOL/></type></variable>'
             '<variable name="n"><type><INT/></type></variable></localVars></interface>'
             '<body><ST><xhtml:p><![CDATA[n := n + 1; IF go THEN l(a := TRUE); END_IF]]>'
             '</xhtml:p></ST></body></pou>')
    prog = parse_plcopen(xml, "g.xml")
    errors, warnings = check_program(prog)
    assert errors == [] and ["LD body of POU 'Lad'" in w.message for w in warnings] == [True]
    inst = ProgramInstance(prog)
    inst.scan(0)
    assert inst.programs[0].N == 1
    inst.programs[0].GO = True
    with pytest.raises(ExecutionError, match="LD body of POU 'Lad'"):
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
    prog = load_program(Path(__file__).parent / "data" / "beremiz_sfc.xml")
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
