"""TwinCAT 3 project files: object files, projects, errors at the XML line, tasks, GVLs."""
import shutil
from pathlib import Path

import pytest

from plcpred.cli import main
from plcpred.machine import load_machine
from plcpred.parser import ProgramError, ir, load_program
from plcpred.parser.check import check_program
from plcpred.parser.twincat import parse_twincat
from plcpred.sequencer import ExecutionError, unfold
from plcpred.sequencer.executor import ProgramInstance

SAMPLES = Path(__file__).resolve().parents[2] / "samples"
PROJECT = SAMPLES / "twincat_project" / "ClampStation"
HEAD = '<?xml version="1.0" encoding="utf-8"?>\n<TcPlcObject Version="1.1.0.1">\n'


def tcpou(name, decl, st, members="", lang="ST"):
    """A .TcPOU as TwinCAT writes it; ``members`` are Method/Property/Action elements."""
    return (HEAD + f'  <POU Name="{name}" Id="{{0}}" SpecialFunc="None">\n'
            f"    <Declaration><![CDATA[{decl}]]></Declaration>\n"
            f"    <Implementation>\n      <{lang}><![CDATA[{st}]]></{lang}>\n"
            f"    </Implementation>\n{members}  </POU>\n</TcPlcObject>\n")


def method(name, decl, st):
    return (f'    <Method Name="{name}" Id="{{1}}">\n'
            f"      <Declaration><![CDATA[{decl}]]></Declaration>\n"
            f"      <Implementation>\n        <ST><![CDATA[{st}]]></ST>\n"
            f"      </Implementation>\n    </Method>\n")


def test_the_sample_project_reads_as_folder_plcproj_and_parent_folder():
    by_proj = load_program(PROJECT / "ClampStation.plcproj")
    assert load_program(PROJECT) == by_proj
    assert load_program(PROJECT.parent) == by_proj
    assert {p.name for p in by_proj.pous} == {"FB_ActuatorBase", "FB_Clamp", "MAIN"}
    main_pou = by_proj.pou("MAIN")
    assert [a.name for a in main_pou.actions] == ["Sequence"]
    base = by_proj.pou("FB_ActuatorBase")
    assert [m.name for m in base.methods] == ["Move"]
    assert [(p.name, [a.kind for a in p.accessors]) for p in base.properties] == [
        ("Ready", ["GET"])]
    assert [i.name for i in by_proj.interfaces] == ["I_Actuator"]
    assert by_proj.globals[0].name == "GVL_IO"
    task = by_proj.configurations[0].resources[0]
    assert task.tasks[0].params["INTERVAL"] == ir.Literal(10_000_000, "TIME")
    assert [(p.name, p.task) for p in task.programs] == [("MAIN", "PlcTask")]
    errors, warnings = check_program(by_proj)
    assert errors == [] and warnings == []


def test_a_machine_predicts_from_the_project_as_from_its_st_twin():
    project = unfold(load_machine(SAMPLES / "twincat_station.toml"), "30s")
    st = unfold(load_machine(SAMPLES / "clamp_station.toml"), "30s")
    for signal in ("bClampValve", "bDrillValve", "bChipBlow"):
        assert project.count_rising(signal) == st.count_rising(signal) > 0
        for a, b in zip(project.edge_times_ns(signal), st.edge_times_ns(signal)):
            assert list(a) == list(b)


def test_errors_point_at_the_line_and_column_of_the_xml_file(tmp_path):
    text = tcpou("FB_A", "FUNCTION_BLOCK FB_A\nVAR\n    n : INT;\nEND_VAR", "n := n + 1;",
                 method("Bump", "METHOD Bump : BOOL;\nVAR_INPUT\n    k : INT;\nEND_VAR",
                        "n := n + k;\nn := * 2;"))
    line = next(i for i, t in enumerate(text.splitlines(), 1) if "n := * 2;" in t)
    with pytest.raises(ProgramError) as e:
        parse_twincat(text, "FB_A.TcPOU")
    assert (e.value.file, e.value.line, e.value.col) == ("FB_A.TcPOU", line, 6)
    # a semantic error too
    text = text.replace("n := * 2;", "nope := 2;")
    errors, _ = check_program(parse_twincat(text, "FB_A.TcPOU"))
    assert [(x.line, x.col) for x in errors] == [(line, 1)]


def test_a_body_ending_in_a_line_comment_still_closes():
    text = tcpou("PRG", "PROGRAM PRG\nVAR\n    n : INT;\nEND_VAR", "n := n + 1; // count",
                 method("M", "METHOD M : INT", "M := n; // last line is a comment"))
    prog = parse_twincat(text, "PRG.TcPOU")
    assert [m.name for m in prog.pou("PRG").methods] == ["M"]


def test_gvl_name_qualifies_its_globals_in_check_and_run(tmp_path):
    (tmp_path / "GVL_IO.TcGVL").write_text(
        HEAD + '<GVL Name="GVL_IO"><Declaration><![CDATA[{attribute \'qualified_only\'}\n'
        "VAR_GLOBAL\n    bIn : BOOL;\n    nOut : INT;\nEND_VAR]]></Declaration></GVL>\n"
        "</TcPlcObject>")
    (tmp_path / "MAIN.TcPOU").write_text(tcpou(
        "MAIN", "PROGRAM MAIN\nVAR\nEND_VAR",
        "IF GVL_IO.bIn THEN GVL_IO.nOut := GVL_IO.nOut + 1; END_IF"))
    prog = load_program(tmp_path)
    assert check_program(prog) == ([], [])
    inst = ProgramInstance(prog)
    inst.ns["_g"].BIN = True
    for k in range(3):
        inst.scan(k * 10_000_000)
    assert inst.ns["_g"].NOUT == 3
    (tmp_path / "MAIN.TcPOU").write_text(tcpou("MAIN", "PROGRAM MAIN", "GVL_IO.nMissing := 1;"))
    errors, _ = check_program(load_program(tmp_path))
    assert len(errors) == 1 and "nMissing" in errors[0].message


def test_task_cycle_time_sets_how_often_the_program_runs(tmp_path):
    (tmp_path / "MAIN.TcPOU").write_text(tcpou(
        "MAIN", "PROGRAM MAIN\nVAR\n    n : INT;\nEND_VAR", "n := n + 1;"))
    (tmp_path / "Slow.TcTTO").write_text(
        HEAD + '<Task Name="Slow"><CycleTime>40000</CycleTime><PouCall><Name>MAIN</Name>'
        "</PouCall></Task></TcPlcObject>")
    inst = ProgramInstance(load_program(tmp_path))
    inst.set_scan(10_000_000)
    for k in range(8):                    # 80 ms of 10 ms scans: MAIN runs every 40 ms
        inst.scan(k * 10_000_000)
    assert inst.programs[0].N == 2


def test_graphical_bodies_load_with_a_warning_and_fail_only_when_run(tmp_path):
    (tmp_path / "FB_Fbd.TcPOU").write_text(tcpou(
        "FB_Fbd", "FUNCTION_BLOCK FB_Fbd\nVAR_INPUT\n    x : BOOL;\nEND_VAR", "",
        lang="FBD").replace("<FBD><![CDATA[]]></FBD>", "<FBD><network/></FBD>"))
    (tmp_path / "MAIN.TcPOU").write_text(tcpou(
        "MAIN", "PROGRAM MAIN\nVAR\n    fb : FB_Fbd;\n    go : BOOL;\n    n : INT;\nEND_VAR",
        "n := n + 1;\nIF go THEN fb(x := TRUE); END_IF"))
    prog = load_program(tmp_path)
    errors, warnings = check_program(prog)
    assert errors == [] and len(warnings) == 1
    assert "FBD body of function block FB_Fbd" in warnings[0].message
    fbd_line = (tmp_path / "FB_Fbd.TcPOU").read_text().splitlines().index("      <FBD><network/></FBD>") + 1
    assert warnings[0].file.endswith("FB_Fbd.TcPOU") and warnings[0].line == fbd_line
    inst = ProgramInstance(prog)
    inst.scan(0)
    assert inst.programs[0].N == 1        # runs while the FBD body is not called
    inst.programs[0].GO = True
    with pytest.raises(ExecutionError, match="FBD body of function block FB_Fbd"):
        inst.scan(10_000_000)


def test_a_tcpou_saved_as_st_is_read_as_twincat_and_a_machine_file_is_named(tmp_path, capsys):
    f = tmp_path / "main.st"
    f.write_text("\ufeff" + tcpou("MAIN", "PROGRAM MAIN\nVAR\n    n : INT;\nEND_VAR",
                                  "n := n + 1;"), encoding="utf-8")
    assert [p.name for p in load_program(f).pous] == ["MAIN"]
    assert main(["check", str(SAMPLES / "clamp_station.toml")]) == 2
    err = capsys.readouterr().err
    assert "machine file" in err and "predict" in err


def test_names_in_attributes_are_identifiers_or_a_positioned_error(tmp_path):
    text = tcpou("MAIN", "PROGRAM MAIN", "",
                 '    <Action Name="A: x := 1; END_ACTION ACTION B" Id="{2}">\n'
                 "      <Implementation>\n        <ST><![CDATA[;]]></ST>\n"
                 "      </Implementation>\n    </Action>\n")
    with pytest.raises(ProgramError) as e:
        parse_twincat(text, "MAIN.TcPOU")
    action_line = next(i for i, t in enumerate(text.splitlines(), 1) if "<Action" in t)
    assert "not an IEC identifier" in e.value.message and e.value.line == action_line


def test_a_plcproj_naming_a_missing_file_and_a_folder_of_two_projects(tmp_path):
    shutil.copytree(PROJECT, tmp_path / "A")
    for f in (tmp_path / "A").rglob("*.Tc*"):
        f.unlink()
    with pytest.raises(ProgramError, match="none of the files the project lists"):
        load_program(tmp_path / "A")
    shutil.copytree(PROJECT, tmp_path / "B")
    with pytest.raises(ProgramError, match="2 PLC projects"):
        load_program(tmp_path)


@pytest.mark.parametrize("program", ["sfc_press.st", "twincat_project",
                                     "twincat_project/ClampStation/POUs/MAIN.TcPOU"])
def test_a_program_given_where_a_machine_file_is_wanted_is_named(program, capsys):
    assert main(["predict", str(SAMPLES / program), "--horizon", "1s", "--out", "/nonexistent"]) != 0
    err = capsys.readouterr().err
    assert "PLC program, not a machine file" in err and "Traceback" not in err


def test_a_missing_name_names_the_libraries_the_project_references_and_plcpred_lacks(
        tmp_path, capsys):
    shutil.copytree(PROJECT, tmp_path / "P")
    proj = tmp_path / "P" / "ClampStation.plcproj"
    proj.write_text(proj.read_text().replace(
        "  <ItemGroup>\n    <PlaceholderReference",
        '  <ItemGroup>\n    <PlaceholderReference Include="Vendor Lib">\n'
        "      <Namespace>Vendor_Lib</Namespace>\n    </PlaceholderReference>\n"
        '    <PlaceholderReference Include="Tc2_System">\n'
        "      <Namespace>Tc2_System</Namespace>\n    </PlaceholderReference>\n"
        "    <PlaceholderReference", 1))
    main_pou = tmp_path / "P" / "POUs" / "MAIN.TcPOU"
    main_pou.write_text(main_pou.read_text().replace("nParts    : UDINT;",
                                                     "nParts    : UDINT;\n    fbX : Vendor_Lib.FB_X;"))
    assert main(["check", str(tmp_path / "P")]) == 1
    err = capsys.readouterr().err
    assert "unknown type 'Vendor_Lib.FB_X'" in err
    assert "libraries plcpred does not have: Vendor_Lib;" in err      # Tc2_* are known


def test_a_file_the_plcproj_lists_but_that_is_not_there(samples_dir, tmp_path, capsys):
    """Left out of source control: the project still loads, and a name that file would
    have declared is reported with it."""
    import shutil

    from plcpred.cli import main
    project = tmp_path / "ClampStation"
    shutil.copytree(samples_dir / "twincat_project" / "ClampStation", project)
    (project / "DUTs" / "E_Step.TcDUT").unlink()
    assert main(["check", str(project)]) == 1
    err = capsys.readouterr().err
    assert "E_Step" in err and "the .plcproj lists a file that is not there" in err
    assert "ClampStation.plcproj:11:" in err and "E_Step.TcDUT" in err
    assert "warning: the .plcproj lists DUTs/E_Step.TcDUT, which is not there" in err
    assert "Traceback" not in err


def test_an_enumeration_text_list_object_and_interface_members_through_extends(tmp_path):
    # .TcTLEO: an enumeration with a text list declares its TYPE as a DUT does;
    # a property of an interface is found through the interfaces it EXTENDS, even where
    # the chain ends in one plcpred does not know (__SYSTEM.IQueryInterface)
    (tmp_path / "E_Mode.TcTLEO").write_text(
        HEAD + '  <EnumerationTextList Name="E_Mode" Id="{2}">\n'
        "    <Declaration><![CDATA[{attribute 'qualified_only'}\nTYPE E_Mode :\n"
        "(\n    Idle := 0,\n    Run\n)BYTE;\nEND_TYPE\n]]></Declaration>\n"
        "    <XmlArchive><Data/></XmlArchive>\n  </EnumerationTextList>\n</TcPlcObject>\n")
    (tmp_path / "I_Base.TcIO").write_text(
        HEAD + '  <Itf Name="I_Base" Id="{3}">\n'
        "    <Declaration><![CDATA[INTERFACE I_Base EXTENDS __SYSTEM.IQueryInterface]]>"
        "</Declaration>\n"
        '    <Property Name="Count" Id="{4}">\n'
        "      <Declaration><![CDATA[PROPERTY Count : INT]]></Declaration>\n"
        '      <Get Name="Get" Id="{5}"><Declaration><![CDATA[]]></Declaration></Get>\n'
        "    </Property>\n  </Itf>\n</TcPlcObject>\n")
    (tmp_path / "I_Derived.TcIO").write_text(
        HEAD + '  <Itf Name="I_Derived" Id="{6}">\n'
        "    <Declaration><![CDATA[INTERFACE I_Derived EXTENDS I_Base]]></Declaration>\n"
        "  </Itf>\n</TcPlcObject>\n")
    (tmp_path / "FB_Bag.TcPOU").write_text(tcpou(
        "FB_Bag", "FUNCTION_BLOCK FB_Bag IMPLEMENTS I_Derived\nVAR n : INT := 3; END_VAR", "",
        members='    <Property Name="Count" Id="{7}">\n'
                "      <Declaration><![CDATA[PROPERTY Count : INT]]></Declaration>\n"
                '      <Get Name="Get" Id="{8}"><Declaration><![CDATA[VAR END_VAR]]>'
                "</Declaration>\n        <Implementation><ST><![CDATA[Count := n;]]></ST>"
                "</Implementation>\n      </Get>\n    </Property>\n"))
    (tmp_path / "MAIN.TcPOU").write_text(tcpou(
        "MAIN", "PROGRAM MAIN\nVAR bag : FB_Bag; it : I_Derived; c : INT; m : E_Mode; END_VAR",
        "it := bag;\nc := it.Count;\nm := E_Mode.Run;"))
    assert main(["check", str(tmp_path)]) == 0
    inst = ProgramInstance(load_program(tmp_path))
    inst.guard(inst.scan, 0)
    p = inst.programs[0]
    assert (p.C, int(p.M)) == (3, 1)
