"""B&R Automation Studio program folders (plcpred/parser/bnr.py)."""
from pathlib import Path

import pytest

from plcpred import unfold
from plcpred.machine import load_machine
from plcpred.parser import ProgramError, load_program, parse_st
from plcpred.parser.check import check_program
from plcpred.sequencer.executor import ProgramInstance

BNR = Path(__file__).resolve().parents[1] / "data" / "bnr"
MS = 1_000_000


def test_a_program_folder_is_one_program_with_its_actions_types_and_variables():
    prog = load_program(BNR / "Logical", libraries=False)
    (station,) = [p for p in prog.pous if p.kind == "PROGRAM"]
    assert station.name == "Station"
    assert [a.name for a in station.actions] == ["BlowAction"]       # from its own file
    assert {t.name for t in prog.types} == {"State_enum", "Cfg_typ"}  # .typ
    assert prog.pou("LowPass").kind == "FUNCTION_BLOCK"               # .fun declaration
    declared = {d.name for g in prog.globals for d in g.block.decls}
    assert {"State", "Cfg", "diPart", "doBlow"} <= declared          # .var files
    errors, warnings = check_program(load_program(BNR / "Logical"))
    assert errors == [] and warnings == []
    # a file of the program stands for its folder
    assert load_program(BNR / "Logical" / "Station" / "Main.st", libraries=False).pou(
        "Station").actions[0].name == "BlowAction"


def test_init_runs_once_then_cyclic_every_scan():
    inst = ProgramInstance(load_program(BNR / "Logical"))
    g = inst.g                                # the .var files' variables are global

    def set_(name, value):
        setattr(g, name, value)

    def get(name):
        return getattr(g, name)

    counts = []
    for k in range(40):
        set_("DIPART", k % 10 == 1)           # a part every 10 scans
        set_("DIPUSHOUT", k % 10 == 3)
        inst.scan(k * 10 * MS)
        counts.append(int(get("COUNT")))
    assert counts[-1] == 4                    # _INIT's Count := 0 did not run again
    assert get("CFG").BLOWTIME == 300 * MS


def test_the_station_runs_from_its_machine_file():
    timeline = unfold(load_machine(BNR / "station.toml"), "10s")
    push, blow = timeline.intervals("doPush"), timeline.intervals("doBlow")
    assert push.start_s.tolist() == pytest.approx([0.5, 3.5, 6.5, 9.5])
    # the _INIT preset: a 300 ms blow after each push, in the action called as `BlowAction;`
    assert blow.duration_s.tolist()[:3] == pytest.approx([0.3] * 3)
    assert (blow.start_s.to_numpy()[:3] == push.end_s.to_numpy()[:3]).all()


def test_calling_an_action_by_its_name_alone_is_b_and_r_only():
    src = "PROGRAM P\nVAR x : INT; END_VAR\nAct;\nACTION Act:\nx := 1;\nEND_ACTION\nEND_PROGRAM\n"
    with pytest.raises(ProgramError, match="expected ':='"):
        parse_st(src, "p.st")
    prog = parse_st(src, "p.st", dialect="bnr")
    assert prog.pous[0].body[0].call.func.name == "Act"


def test_a_hostile_folder_name_becomes_a_plain_identifier(tmp_path):
    import shutil
    folder = tmp_path / "x\"); __import__('os').system('echo pwned') #é"
    shutil.copytree(BNR / "Logical" / "Station", folder)
    shutil.copy(BNR / "Logical" / "Global.var", tmp_path)
    prog = load_program(tmp_path)
    (station,) = [p for p in prog.pous if p.kind == "PROGRAM"]
    assert station.name.isidentifier() and station.name.isascii()
    inst = ProgramInstance(prog)
    inst.scan(0)


def test_the_dialect_option(tmp_path, capsys):
    from plcpred.cli import main
    f = tmp_path / "act.st"
    f.write_text("PROGRAM P\nVAR x : INT; END_VAR\nAct;\nACTION Act:\nx := 1;\nEND_ACTION\n"
                 "END_PROGRAM\n")
    assert main(["check", str(f)]) == 1
    assert "read the file with --dialect bnr" in capsys.readouterr().err
    assert main(["check", "--dialect", "bnr", str(f)]) == 0
    # iec never reads a folder the B&R way
    assert main(["check", "--dialect", "iec", str(BNR / "Logical")]) == 1
    assert main(["check", str(BNR / "Logical")]) == 0
    with pytest.raises(ValueError, match="dialect must be one of"):
        load_program(f, dialect="codesys2")
