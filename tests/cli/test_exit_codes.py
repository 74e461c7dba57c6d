"""Exit codes CI can rely on (docs/reference/cli.md#exit-codes): 1 is "the gate failed"
and nothing else. A typo in a machine file, a missing or broken machine file and a program
that does not compile exit 2 on every command, never 1."""
import shutil
from pathlib import Path

import pytest
from conftest import ROOT, SAMPLES

from plcpred import errors
from plcpred.cli import build_parser, main

PRESS = SAMPLES / "press.toml"

# every command, with "{M}" where it takes the machine file (an output folder or file
# under "{D}"); a new command must be added here
COMMANDS = {
    "timeline": ["timeline", "{M}", "--horizon", "1s", "--out", "{D}"],
    "predict": ["predict", "{M}", "--horizon", "1s", "--out", "{D}"],
    "size": ["size", "{M}", "--horizon", "1s", "--out", "{D}"],
    "compare": ["compare", "{M}", "--horizon", "1s"],
    "sweep": ["sweep", "{M}", "--horizon", "1s", "--set", "supply_bar_g=5,6", "--workers",
              "1"],
    "diagnose": ["diagnose", "{M}", "--measured", "{D}/run.csv"],
    "emulate": ["emulate", "{M}", "--horizon", "1s", "--out", "{D}"],
    "identify": ["identify", "flow", "{D}/flow.csv", "--machine", "{M}", "--consumer",
                 "die blow", "--write-machine", "{D}/fixed.toml"],
    "serve": ["serve", "{M}", "--endpoint", "opc.tcp://127.0.0.1:1"],
    "watch": ["watch", "{M}", "--out", "{D}", "--endpoint", "opc.tcp://127.0.0.1:1"],
}
# the commands that read programs, not machine files
PROGRAM_COMMANDS = ("check", "init")
# the commands that compile the machine file's program
RUNNING = ("timeline", "predict", "size", "compare", "sweep", "diagnose", "emulate")


def _commands():
    sub = next(a for a in build_parser()._actions if a.__class__.__name__ ==
               "_SubParsersAction")
    return list(sub.choices)


def test_every_command_is_tested():
    assert sorted(_commands()) == sorted([*COMMANDS, *PROGRAM_COMMANDS]), \
        "a command without a line in COMMANDS: add it"


@pytest.fixture
def work(tmp_path):
    """A folder with the press (its program beside it), a flow log and test data."""
    for f in ("press.toml", "sfc_press.st"):
        shutil.copy(SAMPLES / f, tmp_path / f)
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "run.csv").write_text(
        "time_s,flow_l_min\n" + "".join(f"{t / 2},{10 + t % 7}\n" for t in range(40)))
    shutil.copy(SAMPLES / "prototype_rig" / "knives_flow.csv", tmp_path / "out" / "flow.csv")
    return tmp_path


def _run(command: str, machine: Path, work: Path, capsys) -> tuple[int, str]:
    argv = [a.replace("{M}", str(machine)).replace("{D}", str(work / "out"))
            for a in COMMANDS[command]]
    code = main(argv)
    return code, capsys.readouterr().err


@pytest.mark.parametrize("command", COMMANDS)
def test_a_typo_in_the_machine_file_exits_2_naming_its_line(command, work, capsys):
    machine = work / "press.toml"
    text = machine.read_text()
    machine.write_text(text.replace("bore_mm = 32", "bor_mm = 32"))
    line = text.split("\n").index("bore_mm = 32") + 1
    code, err = _run(command, machine, work, capsys)
    assert code == 2, err
    assert f"{machine}:{line}: " in err and "did you mean 'bore_mm'?" in err, err


@pytest.mark.parametrize("command", COMMANDS)
def test_a_missing_machine_file_exits_2(command, work, capsys):
    code, err = _run(command, work / "nope.toml", work, capsys)
    assert code == 2, err
    assert "nope.toml" in err and "Traceback" not in err


@pytest.mark.parametrize("command", COMMANDS)
def test_a_machine_file_that_is_not_toml_exits_2_at_line_and_column(command, work, capsys):
    machine = work / "press.toml"
    text = machine.read_text()
    machine.write_text(text.replace("scan_ms = 10", "scan_ms = = 10"))
    line = text.split("\n").index("scan_ms = 10") + 1
    code, err = _run(command, machine, work, capsys)
    assert code == 2, err
    assert f"{machine}:{line}:11: not valid TOML" in err, err


@pytest.mark.parametrize("command", RUNNING)
def test_a_program_that_does_not_compile_exits_2(command, work, capsys):
    (work / "sfc_press.st").write_text("PROGRAM P\nVAR x : BOOL; END_VAR\nx := ;\nEND_PROGRAM\n")
    code, err = _run(command, work / "press.toml", work, capsys)
    assert code == 2, err
    assert "sfc_press.st:3:6:" in err, err


@pytest.mark.parametrize("command", PROGRAM_COMMANDS)
def test_a_missing_program_exits_2(command, tmp_path, capsys):
    assert main([command, str(tmp_path / "nope.st")]) == 2


@pytest.mark.parametrize("command", PROGRAM_COMMANDS)
def test_a_machine_file_given_as_a_program_exits_2(command, capsys):
    assert main([command, str(PRESS)]) == 2


def test_check_exits_1_only_for_a_program_with_errors(tmp_path, capsys):
    bad = tmp_path / "bad.st"
    bad.write_text("PROGRAM P\nVAR x : BOOL; END_VAR\nx := ;\nEND_PROGRAM\n")
    assert main(["check", str(bad)]) == 1
    assert main(["check", str(SAMPLES / "sfc_press.st")]) == 0


@pytest.mark.parametrize("option", ["--json", "--write-machine"])
@pytest.mark.parametrize("command", ["diagnose", "identify"])
def test_an_output_path_that_cannot_be_written_exits_2_before_any_work(
        command, option, work, capsys, monkeypatch):
    """A folder given as a file: exit 2 at once (the machine file, which does not exist,
    is not even read)."""
    import plcpred.cli.diagnose as cli_diagnose
    import plcpred.cli.identify as cli_identify
    for module, name in ((cli_diagnose, "diagnose"), (cli_identify, "identify_steady")):
        monkeypatch.setattr(module, name, lambda *a, **k: pytest.fail("worked first"))
    argv = [a.replace("{M}", str(work / "nope.toml")).replace("{D}", str(work / "out"))
            for a in COMMANDS[command]]
    if option in argv:
        argv = argv[:argv.index(option)] + argv[argv.index(option) + 2:]
    code = main(argv + [option, str(work / "out")])
    err = capsys.readouterr().err
    assert code == 2 and f"{option} {work / 'out'}: is a folder" in err, err


def test_the_docs_exit_code_table_is_the_one_in_plcpred_errors():
    doc = (ROOT / "docs" / "reference" / "cli.md").read_text()
    section = doc.split("\n## Exit codes\n", 1)[1].split("\n## ", 1)[0]
    rows = [ln for ln in section.split("\n") if ln.startswith("| ") and
            ln[2].isdigit()]
    assert rows == [f"| {code} | {when} |" for code, when in errors.EXIT_CODES]


def test_the_compare_gates_have_their_own_codes():
    assert (errors.EXIT_NEVER_MOVES, errors.EXIT_THROUGHPUT_DROP) == (4, 5)
    assert len({code for code, _ in errors.EXIT_CODES}) == len(errors.EXIT_CODES)
