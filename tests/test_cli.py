"""The ``plcpred check`` command."""
import subprocess
import sys

from plcpred.cli import main


def test_check_ok_prints_one_summary_line_per_file(samples_dir, capsys):
    files = [str(samples_dir / "prototype_rig" / "rig.st"), str(samples_dir / "sfc_press.st")]
    assert main(["check", *files]) == 0
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 2
    assert out[0].startswith(files[0] + ": ok") and "12 I/O addresses (8 in, 4 out)" in out[0]
    assert "PressSFC [SFC]" in out[1]


def test_check_reports_errors_with_position_and_exit_1(tmp_path, capsys):
    bad = tmp_path / "bad.st"
    bad.write_text("PROGRAM P\nVAR x : INT; END_VAR\nx := 1\nx := 2;\nEND_PROGRAM\n")
    good = tmp_path / "good.st"
    good.write_text("PROGRAM Q\nVAR_OUTPUT y : INT; END_VAR\ny := 1;\nEND_PROGRAM\n")
    assert main(["check", str(bad), str(good)]) == 1
    captured = capsys.readouterr()
    assert f"{bad}:3:7: expected ';'" in captured.err
    assert "Traceback" not in captured.err
    assert f"{good}: ok" in captured.out


def test_semantic_errors_and_syntax_only(tmp_path, capsys):
    f = tmp_path / "frag.st"
    f.write_text("PROGRAM P\nVAR t : LibTimer; END_VAR\nt(IN := TRUE);\nEND_PROGRAM\n")
    assert main(["check", str(f)]) == 1
    assert f"{f}:2:9: unknown type 'LibTimer'" in capsys.readouterr().err
    assert main(["check", "--syntax-only", str(f)]) == 0


def test_missing_file_is_a_clear_error(tmp_path, capsys):
    assert main(["check", str(tmp_path / "nope.st")]) == 1
    assert "cannot read file" in capsys.readouterr().err


def test_console_script_runs_as_module(samples_dir):
    r = subprocess.run([sys.executable, "-m", "plcpred.cli", "check",
                        str(samples_dir / "codesys_pick_place.st")],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr


def test_every_command_and_option_is_in_docs_cli():
    """docs/reference/cli.md (made from the --help texts) names every command and option."""
    from pathlib import Path

    from plcpred.cli import build_parser
    doc = (Path(__file__).resolve().parent.parent / "docs" / "reference" / "cli.md").read_text()
    sub = [a for a in build_parser()._actions if a.__class__.__name__ == "_SubParsersAction"]
    for name, parser in sub[0].choices.items():
        assert f"## `plcpred {name}`" in doc, name
        for action in parser._actions:
            for opt in action.option_strings:
                assert opt in doc, f"plcpred {name} {opt}"


def test_help_imports_neither_numpy_nor_the_sequencer():
    # --help and argument errors answer at once: the package imports its parts lazily
    code = ("import sys\nfrom plcpred.cli import main\n"
            "try:\n    main(['--help'])\nexcept SystemExit:\n    pass\n"
            "heavy = [m for m in ('numpy', 'plcpred.sequencer', 'plcpred.parser', "
            "'plcpred.air') if m in sys.modules]\nprint('HEAVY', heavy)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "HEAVY []" in r.stdout
    import plcpred
    assert plcpred.predict is plcpred.air.predict and "predict" in dir(plcpred)
