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
    assert main(["check", str(tmp_path / "nope.st")]) == 2
    assert "cannot read file" in capsys.readouterr().err


def test_console_script_runs_as_module(samples_dir):
    r = subprocess.run(check=False, args=[sys.executable, "-m", "plcpred.cli", "check",
                        str(samples_dir / "codesys_pick_place.st")],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr


def test_every_command_and_option_is_in_docs_cli():
    """docs/reference/cli.md (made from the --help texts) names every command and option."""
    from pathlib import Path

    from plcpred.cli import build_parser
    doc = (Path(__file__).resolve().parents[2] / "docs" / "reference" / "cli.md").read_text()
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
    r = subprocess.run(check=False, args=[sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "HEAVY []" in r.stdout
    import plcpred
    assert plcpred.predict is plcpred.air.predict and "predict" in dir(plcpred)


def test_summary_json_holds_the_peaks_the_console_prints(tmp_path, capsys):
    import json
    import re
    from pathlib import Path
    pick = Path(__file__).resolve().parents[2] / "samples" / "pick_place.toml"
    assert main(["predict", str(pick), "--horizon", "2m", "--out", str(tmp_path / "o"),
                 "--no-plot"]) == 0
    printed = capsys.readouterr().out
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    peaks = re.search(r"peak ([\d.]+) NL/min \(instantaneous.*\), ([\d.]+) NL/min \(1 s\), "
                      r"([\d.]+) NL/min \(1 min\)", printed).groups()
    assert [f"{summary[k]:.1f}" for k in ("peak_l_min", "peak_1s_l_min", "peak_1min_l_min")] \
        == list(peaks)
    assert summary["peak_1s_l_min"] > summary["peak_1min_l_min"] > summary["mean_l_min"]


def test_no_timeline_leaves_out_timeline_csv_and_the_old_runs_one(tmp_path, capsys):
    """--no-timeline writes no timeline.csv; one an earlier run wrote there goes, as any
    file of the old run this one does not write (the manifest proves it was ours), and
    the new manifest does not list it. A file of the user's stays."""
    import json
    from pathlib import Path
    pick = str(Path(__file__).resolve().parents[2] / "samples" / "pick_place.toml")
    out = tmp_path / "o"
    assert main(["predict", pick, "--horizon", "20s", "--out", str(out), "--no-plot"]) == 0
    assert (out / "timeline.csv").exists()
    (out / "notes.txt").write_text("mine")
    assert main(["predict", pick, "--horizon", "20s", "--out", str(out), "--no-plot",
                 "--no-timeline"]) == 0
    assert "timeline.csv" not in capsys.readouterr().out.splitlines()[-1]
    assert sorted(p.name for p in out.iterdir()) == ["demand.csv", "manifest.json",
                                                      "notes.txt", "summary.json"]
    listed = json.loads((out / "manifest.json").read_text())["files"]
    assert sorted(listed) == ["demand.csv", "summary.json"]


def test_identify_json_dash_prints_the_json_alone(tmp_path, capsys):
    import json
    from pathlib import Path
    bench = Path(__file__).resolve().parents[1] / "data" / "identify" / "bench_plain.csv"
    assert main(["identify", "flow", str(bench), "--json", "-"]) == 0
    captured = capsys.readouterr()
    assert json.loads(captured.out)["n_points"] == 24
    assert "95 % interval" in captured.err
    assert main(["identify", "flow", str(bench), "--json", str(tmp_path / "f.json")]) == 0
    captured = capsys.readouterr()
    assert "95 % interval" in captured.out
    assert json.loads((tmp_path / "f.json").read_text())["n_points"] == 24


# ---------------------------------------------------------------- docs/reference/cli.md

CLI_MD = __import__("pathlib").Path(__file__).resolve().parents[2] / "docs" / "reference" \
    / "cli.md"
UPDATE_CLI_MD = "PLCPRED_UPDATE_CLI_MD"     # =1: rewrite cli.md's help blocks, then look


def _help_texts(monkeypatch) -> dict:
    """Each command's --help as printed on an 80-column terminal."""
    from plcpred.cli import build_parser
    monkeypatch.setenv("COLUMNS", "80")
    sub = next(a for a in build_parser()._actions if a.dest == "command")
    return {name: parser.format_help().rstrip("\n") for name, parser in sub.choices.items()}


def _help_blocks(doc: str) -> dict:
    """command -> (start, end) of the code block under its '## `plcpred NAME`' heading."""
    import re
    blocks = {}
    for m in re.finditer(r"^## `plcpred (\S+)`\n", doc, re.MULTILINE):
        start = doc.index("```\n", m.end()) + 4
        blocks[m.group(1)] = (start, doc.index("\n```", start))
    return blocks


def test_docs_cli_is_the_help_texts(monkeypatch):
    """Every command's section of docs/reference/cli.md holds its --help, word for word
    (PLCPRED_UPDATE_CLI_MD=1 python -m pytest tests/cli/test_cli.py -n0 -k docs_cli rewrites
    them; look at git diff docs/reference/cli.md)."""
    import os
    helps = _help_texts(monkeypatch)
    doc = CLI_MD.read_text(encoding="utf-8")
    blocks = _help_blocks(doc)
    if os.environ.get(UPDATE_CLI_MD, "") not in ("", "0"):
        for name, (start, end) in sorted(blocks.items(), key=lambda kv: -kv[1][0]):
            if name in helps:
                doc = doc[:start] + helps[name] + doc[end:]
        CLI_MD.write_text(doc, encoding="utf-8")
        blocks = _help_blocks(doc)
    assert set(blocks) == set(helps), "commands without a section in cli.md (or sections " \
        "of commands that are gone)"
    stale = [name for name, (start, end) in blocks.items() if doc[start:end] != helps[name]]
    assert not stale, (f"docs/reference/cli.md differs from --help for {', '.join(stale)}: "
                       f"{UPDATE_CLI_MD}=1 python -m pytest tests/cli/test_cli.py -n0 -k docs_cli")


def test_compare_prints_the_machine_files_warnings(tmp_path, samples_dir, capsys):
    # psi typed as bar in NEW: the gate still runs, and says what looks wrong
    text = (samples_dir / "press.toml").read_text()
    new = tmp_path / "press.toml"
    new.write_text(text.replace("supply_bar_g = 6", "supply_bar_g = 87", 1))
    for f in samples_dir.glob("*.st"):
        (tmp_path / f.name).write_text(f.read_text())
    main(["compare", str(samples_dir / "press.toml"), str(new), "--horizon", "10s"])
    err = capsys.readouterr().err
    assert "warning:" in err and "psi typed as bar" in err, err
