"""Signs of life (issue 39): every long job shows its stages or a bar on stderr while
stderr is a terminal (here a pseudo-terminal), and nothing when it is a pipe or a file
(CI) or with --quiet."""
import io
import os
import sys
import threading
from pathlib import Path

import pytest

from plcpred.cli import main
from plcpred.progress import OFF, Progress, is_terminal, progress_or_off

ROOT = Path(__file__).resolve().parents[2]
SAMPLES = ROOT / "samples"
PICK = SAMPLES / "pick_place.toml"
RIG = SAMPLES / "prototype_rig" / "rig.toml"
RIG_LOG = SAMPLES / "prototype_rig" / "seq1_measured.csv"


def test_stages_and_bars_are_drawn_and_cleared():
    stream = io.StringIO()
    with Progress(True, stream, redraw_s=0.0) as progress:
        progress.stage("running the program")
        with progress.bar(4, "scenarios") as bar:
            for _ in range(4):
                bar.update()
        with progress.bar(10.0, "s", "physics plant") as bar:
            bar.update_to(2.5)
            bar.update_to(1.0)          # never back
    text = stream.getvalue()
    assert "running the program ... 00:00" in text
    assert "4/4" in text and "scenarios" in text
    assert "physics plant:  25%" in text and "2.5/10.0" in text
    assert text.endswith("\r")           # the last line cleared: what follows starts clean
    assert "\n" not in text


def test_off_writes_nothing():
    stream = io.StringIO()
    for progress in (Progress(False, stream), OFF, progress_or_off(None),
                     progress_or_off(False), Progress.on_terminal(stream=stream),
                     Progress.on_terminal(quiet=True, stream=stream)):
        with progress:
            progress.stage("x")
            with progress.bar(3) as bar:
                bar.update()
                bar.update_to(3)
    assert stream.getvalue() == ""
    assert not is_terminal(stream) and not is_terminal(object())


# ---------------------------------------------------------------------- the commands

def _on_a_terminal(argv, monkeypatch) -> tuple[int, str]:
    """(exit code, what reached the terminal) of ``plcpred argv`` run in this process
    with stderr on a pseudo-terminal."""
    master, slave = os.openpty()
    tty = os.fdopen(slave, "w", encoding="utf-8", errors="replace")
    assert tty.isatty()
    chunks = []

    def drain():
        while True:
            try:
                data = os.read(master, 65536)
            except OSError:
                return
            if not data:
                return
            chunks.append(data)
    reader = threading.Thread(target=drain, daemon=True)
    reader.start()
    monkeypatch.setattr(sys, "stderr", tty)
    try:
        code = main(argv)
    finally:
        tty.flush()
        monkeypatch.setattr(sys, "stderr", sys.__stderr__)
        tty.close()
        reader.join(5)
        os.close(master)
    return code, b"".join(chunks).decode("utf-8", "replace")


def _commands(tmp: Path) -> dict:
    """Each long job, small, with what its progress says while it runs."""
    return {
        "predict": (["predict", str(PICK), "--horizon", "30s", "--out", str(tmp / "p"),
                     "--no-plot"], "running the program over 30s"),
        "timeline": (["timeline", str(PICK), "--horizon", "30s", "--out", str(tmp / "t")],
                     "running the program over 30s"),
        "size": (["size", str(PICK), "--horizon", "30s", "--out", str(tmp / "s")],
                 "sizing the supply"),
        "compare": (["compare", str(PICK), "--horizon", "30s"],
                    "predicting BASE and NEW over 30s"),
        "sweep": (["sweep", str(PICK), "--set", "supply_bar_g=5,6", "--horizon", "10s",
                   "--workers", "1"], "scenarios"),
        "emulate": (["emulate", str(PICK), "--horizon", "2s", "--out", str(tmp / "e"),
                     "--no-plot"], "physics plant"),
        "diagnose": (["diagnose", str(RIG), "--measured", str(RIG_LOG), "--no-plant",
                      "--effects", "leak"], "fitting 1 effects"),
    }


COMMANDS = ["predict", "timeline", "size", "compare", "sweep", "emulate", "diagnose"]


@pytest.mark.parametrize("command", COMMANDS)
def test_a_long_job_shows_its_progress_on_a_terminal(command, tmp_path, monkeypatch):
    argv, shown = _commands(tmp_path)[command]
    code, terminal = _on_a_terminal(argv, monkeypatch)
    assert code == 0, terminal
    assert shown in terminal
    assert "\r" in terminal


@pytest.mark.parametrize("command", COMMANDS)
def test_no_progress_in_a_pipe(command, tmp_path, capsys):
    argv, shown = _commands(tmp_path)[command]
    assert main(argv) == 0                  # stderr captured: not a terminal
    piped = capsys.readouterr().err
    assert shown not in piped and "\r" not in piped and " ... 00:0" not in piped


@pytest.mark.parametrize("command", COMMANDS)
def test_no_progress_with_quiet(command, tmp_path, monkeypatch):
    argv, shown = _commands(tmp_path)[command]
    code, terminal = _on_a_terminal(argv + ["--quiet"], monkeypatch)
    assert code == 0
    assert shown not in terminal and " ... 00:0" not in terminal and "%|" not in terminal
