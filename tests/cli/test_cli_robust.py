"""The command line never traces back, checks --out before working, and never leaves a
half-written or mixed output directory."""
import json
import os
import subprocess
import sys

import pytest

from plcpred import cli
from plcpred.cli import check as cli_check
from plcpred.output import MANIFEST, OutputError, check_out_dir, dumps_json, output_dir
from conftest import SAMPLES

RIG = SAMPLES / "prototype_rig" / "rig.toml"


def _leftovers(parent):
    return [p.name for p in parent.iterdir() if p.name.startswith(".plcpred-")]


def test_bad_out_fails_before_any_work(tmp_path, capsys):
    afile = tmp_path / "afile"
    afile.write_text("x")
    missing_machine = str(tmp_path / "nope.toml")
    for out in (afile, afile / "sub"):
        # the machine file does not exist either: --out is what is reported, so it was
        # checked first
        code = cli.main(["predict", missing_machine, "--horizon", "1s", "--out", str(out)])
        err = capsys.readouterr().err
        assert code == 2
        assert "--out" in err and "nope.toml" not in err, err
    assert afile.read_text() == "x"


@pytest.mark.parametrize("command", ["timeline", "predict", "size"])
def test_every_writing_command_checks_out(command, tmp_path, capsys):
    afile = tmp_path / "afile"
    afile.write_text("x")
    assert cli.main([command, str(RIG), "--horizon", "1s", "--out", str(afile)]) == 2
    assert "not a directory" in capsys.readouterr().err


def test_internal_error_is_one_line_with_exit_3_and_debug_shows_it(monkeypatch, capsys):
    def broken(args):
        raise RuntimeError("boom\nsecond line")
    monkeypatch.setattr(cli_check, "cmd_check", broken)
    assert cli.main(["check", "x.st"]) == 3
    err = capsys.readouterr().err
    assert err.strip() == ("plcpred: internal error: RuntimeError: boom (please report it; "
                           "run again with --debug for the traceback)")
    with pytest.raises(RuntimeError):
        cli.main(["--debug", "check", "x.st"])


def test_user_errors_not_caught_by_a_command_exit_2(monkeypatch, capsys):
    def failing(args):
        raise OutputError("--out x: disk full")
    monkeypatch.setattr(cli_check, "cmd_check", failing)
    assert cli.main(["check", "x.st"]) == 2
    assert capsys.readouterr().err.strip() == "plcpred: error: --out x: disk full"


def test_broken_pipe_ends_quietly(tmp_path):
    r = subprocess.run(f"{sys.executable} -m plcpred predict {RIG} --horizon 20s --no-plot "
                       f"--out {tmp_path / 'o'} | head -c 10", shell=True,
                       capture_output=True, text=True, timeout=120)
    assert "Traceback" not in r.stderr and "BrokenPipe" not in r.stderr, r.stderr


def test_sigterm_during_a_run_leaves_nothing(tmp_path):
    out = tmp_path / "o"
    p = subprocess.Popen([sys.executable, "-m", "plcpred", "predict",
                          str(SAMPLES / "cleaning.toml"), "--horizon", "24h", "--out",
                          str(out)], stderr=subprocess.PIPE, text=True)
    import time
    time.sleep(3)
    p.terminate()
    err = p.communicate(timeout=60)[1]
    assert p.returncode == 143, err
    assert "terminated" in err and "Traceback" not in err
    assert not out.exists() and _leftovers(tmp_path) == []


def _run_into(out, files, command="test"):
    with output_dir(out, command) as staging:
        for name, text in files.items():
            (staging / name).write_text(text)


def test_output_dir_replaces_a_previous_run_whole(tmp_path):
    out = tmp_path / "o"
    _run_into(out, {"a.csv": "1", "b.png": "2"})
    first = json.loads((out / MANIFEST).read_text())
    assert set(first["files"]) == {"a.csv", "b.png"}
    _run_into(out, {"a.csv": "3"})
    assert sorted(p.name for p in out.iterdir()) == ["a.csv", MANIFEST]
    second = json.loads((out / MANIFEST).read_text())
    assert second["run_id"] != first["run_id"]
    assert _leftovers(tmp_path) == []


def test_output_dir_keeps_the_users_own_files(tmp_path):
    out = tmp_path / "o"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    _run_into(out, {"a.csv": "1", "b.png": "2"})
    _run_into(out, {"a.csv": "3"})
    assert (out / "notes.txt").read_text() == "mine"
    assert sorted(p.name for p in out.iterdir()) == ["a.csv", MANIFEST, "notes.txt"]
    assert (out / "a.csv").read_text() == "3"


@pytest.mark.parametrize("exc", [RuntimeError, KeyboardInterrupt])
def test_a_failed_run_leaves_the_previous_one_untouched(tmp_path, exc):
    out = tmp_path / "o"
    _run_into(out, {"a.csv": "1"})
    before = (out / MANIFEST).read_text()
    with pytest.raises(exc):
        with output_dir(out) as staging:
            (staging / "a.csv").write_text("half")
            raise exc()
    assert (out / "a.csv").read_text() == "1" and (out / MANIFEST).read_text() == before
    assert _leftovers(tmp_path) == []


def test_check_out_dir(tmp_path):
    assert check_out_dir(tmp_path / "new" / "deeper") == tmp_path / "new" / "deeper"
    (tmp_path / "f").write_text("")
    with pytest.raises(OutputError, match="not a directory"):
        check_out_dir(tmp_path / "f")
    with pytest.raises(OutputError, match="is a file"):
        check_out_dir(tmp_path / "f" / "x")


def test_json_never_holds_nan():
    text = dumps_json({"a": float("nan"), "b": [1.0, float("inf")], "c": {"d": 2.5}})
    assert json.loads(text) == {"a": None, "b": [1.0, None], "c": {"d": 2.5}}
    assert "NaN" not in text and "Infinity" not in text


def test_summary_files_are_strict_json(tmp_path):
    assert cli.main(["predict", str(RIG), "--horizon", "20s", "--no-plot", "--out",
                     str(tmp_path / "o")]) == 0
    for name in ("summary.json", MANIFEST):
        json.loads((tmp_path / "o" / name).read_text(),
                   parse_constant=lambda c: pytest.fail(f"{name} holds {c}"))
    assert os.stat(tmp_path / "o").st_mode & 0o777 != 0o700


def test_names_with_mathtext_and_pipes_still_plot_and_report(tmp_path):
    text = RIG.read_text().replace('name = "air knives"', 'name = "$\\\\alpha$ knives | 2"')
    text = text.replace('program = "rig.st"', f'program = "{(RIG.parent / "rig.st").as_posix()}"')
    machine = tmp_path / "m.toml"
    machine.write_text(text)
    assert "$\\alpha$ knives | 2" in machine.read_text().replace("\\\\", "\\")
    assert cli.main(["predict", str(machine), "--horizon", "20s", "--out",
                     str(tmp_path / "p")]) == 0
    assert (tmp_path / "p" / "demand.png").stat().st_size > 1000
    assert cli.main(["size", str(machine), "--horizon", "20s", "--out",
                     str(tmp_path / "s")]) == 0
    md = (tmp_path / "s" / "sizing.md").read_text()
    assert "| $\\alpha$ knives \\| 2 |" in md


def test_unreachable_dask_scheduler_is_a_clean_error(capsys):
    pytest.importorskip("dask.distributed")
    code = cli.main(["sweep", str(RIG), "--horizon", "1s", "--set", "supply_bar_g=4,5",
                     "--engine", "dask", "--scheduler", "nonsense://x"])
    assert code == 2
    assert "no Dask scheduler answered" in capsys.readouterr().err
