"""``plcpred init``: a machine file to start from, written from a program's I/O."""
import re
from pathlib import Path

import pytest

from plcpred.cli import main
from plcpred.machine import load_machine


def test_init_writes_a_machine_file_that_loads_and_lists_the_io(samples_dir, tmp_path, capsys):
    out = tmp_path / "machines" / "rig.toml"
    out.parent.mkdir()
    program = samples_dir / "prototype_rig" / "rig.st"
    assert main(["init", str(program), "--out", str(out)]) == 0
    text = out.read_text()
    machine = load_machine(out)                      # loads as it is
    assert machine.program_path.resolve() == program.resolve()
    assert machine.scan_ms == 10 and machine.consumers == []
    # every located output is a consumer to fill in, every located input a schedule
    for name in re.findall(r"(\w+)\s+AT\s+%Q", program.read_text()):
        assert f'# valve = "{name}"' in text
    for name in re.findall(r"(\w+)\s+AT\s+%I", program.read_text()):
        assert f'# signal = "{name}"' in text or f"# {name} at %I" in text
    assert "# A_EXT at %IX0.3: the extended end switch of Y_A (in its `switches` below)" in text
    assert '# switches = { retracted = "A_RET", extended = "A_EXT" }' in text


def test_a_consumer_block_uncommented_is_a_valid_consumer(samples_dir, tmp_path, capsys):
    out = tmp_path / "rig.toml"
    assert main(["init", str(samples_dir / "prototype_rig" / "rig.st"), "-o", str(out)]) == 0
    text = out.read_text()
    start = text.index("# [[consumer]]")
    block = text[start:text.index("\n\n", start)].splitlines()
    uncommented = "\n".join(line[2:] for line in block if not line.startswith("#   ("))
    out.write_text(text + "\n" + uncommented.replace('"..."', '"A_RET"', 1)
                   .replace('"..."', '"A_EXT"', 1) + "\n")
    machine = load_machine(out)
    (c,) = machine.consumers
    assert (c.kind, c.bore_mm, c.stroke_mm) == ("double_acting", 32, 100)
    assert main(["predict", str(out), "--horizon", "5s", "--out", str(tmp_path / "p"),
                 "--no-plot"]) == 0


def test_init_prints_without_out_and_refuses_to_overwrite(samples_dir, tmp_path, capsys):
    program = samples_dir / "twincat_project"
    assert main(["init", str(program)]) == 0
    printed = capsys.readouterr().out
    assert 'name = "MAIN"' in printed and "twincat_project/" in printed
    out = tmp_path / "m.toml"
    out.write_text("keep me")
    assert main(["init", str(program), "-o", str(out)]) == 2
    assert "--force" in capsys.readouterr().err and out.read_text() == "keep me"
    assert main(["init", str(program), "-o", str(out), "--force"]) == 0
    assert main(["init", str(program), "-o", str(tmp_path / "m.txt")]) == 2
    bad = tmp_path / "bad.st"
    bad.write_text("PROGRAM P\nVAR x : INT; END_VAR\nx := ;\nEND_PROGRAM\n")
    assert main(["init", str(bad)]) == 2
    assert f"{bad}:3:6:" in capsys.readouterr().err


def test_a_file_name_cannot_write_toml_of_its_own(tmp_path, capsys):
    import tomllib
    folder = tmp_path / 'odd"\n[[consumer]]\nname = "x'
    folder.mkdir()
    (folder / "p.st").write_text("PROGRAM P\nVAR y AT %QX0.0 : BOOL; END_VAR\ny := TRUE;\n"
                                 "END_PROGRAM\n")
    out = tmp_path / "m.toml"
    assert main(["init", str(folder / "p.st"), "-o", str(out)]) == 0
    data = tomllib.loads(out.read_text())
    assert set(data) == {"machine"}                 # the name stayed inside its string
    assert data["machine"]["program"] == folder.name + "/p.st"
    from plcpred.machine import MachineError
    with pytest.raises(MachineError, match=r"\[machine\]: program must be printable"):
        load_machine(out)


def test_init_names_the_elements_of_bool_arrays(tmp_path, capsys):
    program = tmp_path / "line.st"
    program.write_text("VAR_GLOBAL aValve : ARRAY[1..200] OF BOOL; aSw : ARRAY[0..1, 1..200] "
                       "OF BOOL; nCount : ARRAY[1..3] OF INT; END_VAR\n"
                       "PROGRAM Line VAR aLocal : ARRAY[5..6] OF BOOL; END_VAR\n"
                       "aValve[1] := aSw[1, 1]; aLocal[5] := TRUE; END_PROGRAM\n")
    out = tmp_path / "line.toml"
    assert main(["init", str(program), "--out", str(out)]) == 0
    text = out.read_text()
    assert "aValve: ARRAY[1..200] OF BOOL -> aValve[1]" in text
    assert "aSw: ARRAY[0..1, 1..200] OF BOOL -> aSw[0, 1]" in text
    assert "aLocal: ARRAY[5..6] OF BOOL -> aLocal[5]" in text
    assert "nCount" not in text                       # not BOOL
    load_machine(out)


# ---------------------------------------------------------------- end switches

SAMPLE_MACHINES = sorted((Path(__file__).resolve().parents[2] / "samples").rglob("*.toml"))


def proposed_switches(text: str) -> dict[str, dict[str, str]]:
    """valve -> switches of the commented consumer blocks ``init`` wrote (filled ones)."""
    import tomllib
    out = {}
    for block in text.split("\n\n"):
        valve = re.search(r'^# valve = "([^"]*)"', block, re.MULTILINE)
        switches = re.search(r"^# (switches = \{[^}]*\})", block, re.MULTILINE)
        if valve and switches and '"..."' not in switches.group(1):
            out[valve.group(1)] = tomllib.loads(switches.group(1))["switches"]
    return out


@pytest.mark.parametrize("path", SAMPLE_MACHINES, ids=lambda p: p.name)
def test_init_gives_the_samples_end_switches_to_their_cylinders(path, tmp_path, capsys):
    machine = load_machine(path)
    out = tmp_path / "m.toml"
    assert main(["init", str(machine.program_path), "-o", str(out)]) == 0
    text = out.read_text()
    found = proposed_switches(text)
    want = {c.valve[0]: c.switches for c in machine.consumers if c.valve}
    for valve, switches in want.items():
        assert found.get(valve, {}) == switches, valve
        for name in switches.values():          # a switch is no input to schedule
            assert f'# signal = "{name}"' not in text
    for s in machine.inputs:                    # what the world drives still is one
        if "." not in s.signal and not s.signal.startswith("%"):
            assert f'# signal = "{s.signal}"' in text
    load_machine(out)


def test_init_leaves_out_switches_the_program_never_reads(samples_dir, tmp_path, capsys):
    # sequence 2 of the rig runs on timers and reads only the retracted switches
    assert main(["init", str(samples_dir / "prototype_rig" / "rig_seq2.st")]) == 0
    text = capsys.readouterr().out
    assert proposed_switches(text)["Y_A"] == {"retracted": "A_RET"}
    assert "A_EXT at %IX0.3: the extended end switch of Y_A by its name, never read" in text
    assert '# signal = "A_EXT"' not in text


def test_end_switches_by_name():
    from plcpred.skeleton import Signal, end_switches

    def io(*names, kind="BOOL"):
        return [Signal(n, kind, "") for n in names]

    outs = io("qZylinder1", "Y_Gripper", "1Y1", "2Y1", "qLamp", "bClampValve", "qClamp")
    ins = io("xZylinder1Ausgefahren", "xZylinder1Eingefahren", "Gripper_closed",
             "Gripper_open", "1B1", "1B2", "2S2", "bClampHome", "xPartPresent", "bStart")
    assert end_switches(ins, outs) == {
        "qZylinder1": {"retracted": "xZylinder1Eingefahren", "extended": "xZylinder1Ausgefahren"},
        "Y_Gripper": {"retracted": "Gripper_open", "extended": "Gripper_closed"},
        "1Y1": {"retracted": "1B1", "extended": "1B2"},
        "2Y1": {"extended": "2S2"}}             # bClampHome fits two valves: left out
    # a bare end name belongs to the only output there is
    assert end_switches(io("xExtended", "bRetracted"), io("qCyl")) == {
        "qCyl": {"retracted": "bRetracted", "extended": "xExtended"}}
    assert end_switches(io("xExtended"), io("qA", "qB")) == {}
    # two switches for one end, or a WORD, are no guess
    assert end_switches(io("A_EXT", "A_OUT"), io("Y_A")) == {}
    assert end_switches(io("A_EXT", kind="WORD"), io("Y_A")) == {}


def test_init_lists_twincat_io_linked_in_the_io_tree(samples_dir, capsys):
    assert main(["init", str(samples_dir / "twincat_project")]) == 0
    text = capsys.readouterr().out
    assert "# bStart at %I*" in text and '# signal = "bStart"' in text
    assert "# bChipBlow at %Q*" in text and '# valve = "bChipBlow"' in text
