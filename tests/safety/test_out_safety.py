"""--out in a folder someone else prepared (a pull request's checkout): plcpred removes
only files it can prove it wrote, never follows a name out of the folder, refuses a
symbolic link as --out, and cleans the staging folders of killed runs."""
from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from plcpred import output
from plcpred.output import (MANIFEST, OutputError, check_out_dir, clean_abandoned,
                            output_dir)

ROOT = Path(__file__).resolve().parents[2]
PRESS = ROOT / "samples" / "press.toml"


def _run_into(out, files, warnings=None):
    with output_dir(out, "test", warn=(warnings.append if warnings is not None else None)) \
            as staging:
        for name, text in files.items():
            (staging / name).write_text(text)


def _plant(out, listed: dict):
    out.mkdir(parents=True, exist_ok=True)
    (out / MANIFEST).write_text(json.dumps({"files": listed}))


def _entry(text: str) -> dict:
    data = text.encode()
    return {"bytes": len(data), "sha256": hashlib.sha256(data).hexdigest()}


def test_a_planted_manifest_cannot_delete_a_file_outside_out(tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    out = tmp_path / "out"
    _plant(out, {str(victim): _entry("precious"), "../victim.txt": _entry("precious")})
    (out / "README.md").write_text("mine")
    warnings = []
    _run_into(out, {"a.csv": "1"}, warnings)
    assert victim.read_text() == "precious"
    assert (out / "README.md").read_text() == "mine"
    assert (out / "a.csv").read_text() == "1"
    assert any("victim.txt" in w and "not a plain file name" in w for w in warnings)


def test_the_cli_keeps_the_victim_of_the_issue(tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    out = tmp_path / "out"
    _plant(out, {str(victim): {}})
    (out / "README.md").write_text("mine")
    r = subprocess.run([sys.executable, "-m", "plcpred", "predict", str(PRESS),
                        "--horizon", "5s", "--out", str(out), "--no-plot"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert victim.read_text() == "precious" and (out / "README.md").read_text() == "mine"
    assert "victim.txt" in r.stderr and "left" in r.stderr


def test_a_listed_user_file_with_another_hash_is_left_alone(tmp_path):
    """A manifest that names the user's README (with any size or hash) does not make it
    plcpred's: not removed, not replaced with the folder."""
    out = tmp_path / "out"
    _plant(out, {"README.md": _entry("what plcpred wrote"), "notes.txt": {}})
    (out / "README.md").write_text("the user's own")
    (out / "notes.txt").write_text("x")
    warnings = []
    _run_into(out, {"a.csv": "1"}, warnings)
    assert (out / "README.md").read_text() == "the user's own"
    assert (out / "notes.txt").read_text() == "x"
    assert any("README.md" in w and "size" in w for w in warnings)
    assert any("notes.txt" in w and "no size and hash" in w for w in warnings)


def test_a_listed_name_that_is_the_same_size_but_another_content_stays(tmp_path):
    out = tmp_path / "out"
    _plant(out, {"b.csv": _entry("AAAA")})
    (out / "b.csv").write_text("BBBB")
    _run_into(out, {"a.csv": "1"}, [])
    assert (out / "b.csv").read_text() == "BBBB"


def test_a_listed_symlink_is_neither_followed_nor_removed(tmp_path):
    target = tmp_path / "target.txt"
    target.write_text("precious")
    out = tmp_path / "out"
    _plant(out, {"link.csv": _entry("precious")})
    (out / "link.csv").symlink_to(target)
    warnings = []
    _run_into(out, {"a.csv": "1"}, warnings)
    assert (out / "link.csv").is_symlink() and target.read_text() == "precious"
    assert any("symbolic link" in w for w in warnings)


def test_what_an_earlier_run_wrote_is_still_replaced_and_removed(tmp_path):
    """The proof holds for plcpred's own files: a second run into a folder with the
    user's notes removes the first run's file it does not write again."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    _run_into(out, {"a.csv": "1", "b.png": "2"})
    warnings = []
    _run_into(out, {"a.csv": "3"}, warnings)
    assert sorted(p.name for p in out.iterdir()) == ["a.csv", MANIFEST, "notes.txt"]
    assert warnings == []


def test_an_earlier_runs_file_edited_by_the_user_is_kept(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    _run_into(out, {"a.csv": "1", "b.png": "2"})
    (out / "b.png").write_text("edited by hand")
    warnings = []
    _run_into(out, {"a.csv": "3"}, warnings)
    assert (out / "b.png").read_text() == "edited by hand"
    assert len(warnings) == 1 and "'b.png'" in warnings[0]


def test_a_folder_of_only_proven_files_is_replaced_whole(tmp_path):
    out = tmp_path / "out"
    _run_into(out, {"a.csv": "1", "b.png": "2"})
    inode = os.stat(out).st_ino
    _run_into(out, {"a.csv": "3"})
    assert sorted(p.name for p in out.iterdir()) == ["a.csv", MANIFEST]
    assert os.stat(out).st_ino != inode          # the new run's folder, renamed in


def test_a_planted_manifest_that_lists_everything_does_not_make_the_folder_ours(tmp_path):
    """Before: a manifest listing every name made the whole folder "ours", and it was
    renamed away and deleted with the user's files in it."""
    out = tmp_path / "out"
    _plant(out, {"README.md": {}, "src.st": {}})
    (out / "README.md").write_text("mine")
    (out / "src.st").write_text("PROGRAM p END_PROGRAM")
    _run_into(out, {"a.csv": "1"}, [])
    assert (out / "README.md").read_text() == "mine" and (out / "src.st").exists()


@pytest.mark.parametrize("content", ["[1, 2]", "{\"files\": [\"a\"]}", "not json",
                                     "{\"files\": {\"a\": 5}}", "[" * 100_000])
def test_a_malformed_manifest_is_ignored(tmp_path, content):
    out = tmp_path / "out"
    out.mkdir()
    (out / MANIFEST).write_text(content)
    (out / "a").write_text("x")
    _run_into(out, {"b.csv": "1"}, [])
    assert (out / "a").read_text() == "x" and (out / "b.csv").exists()
    assert json.loads((out / MANIFEST).read_text())["files"].keys() == {"b.csv"}


def test_a_huge_manifest_is_not_read(tmp_path, monkeypatch):
    monkeypatch.setattr(output, "MAX_MANIFEST_BYTES", 100)
    out = tmp_path / "out"
    _run_into(out, {"a.csv": "1"})
    (out / "user.txt").write_text("x")
    (out / MANIFEST).write_text(json.dumps({"files": {"a.csv": _entry("1")},
                                            "pad": "x" * 200}))
    _run_into(out, {"b.csv": "2"}, [])
    assert (out / "a.csv").exists()     # not proven: the manifest was too large to read


def test_a_symlinked_out_is_refused(tmp_path):
    real = tmp_path / "real"
    real.mkdir()
    (real / "keep.txt").write_text("x")
    link = tmp_path / "link"
    link.symlink_to(real)
    with pytest.raises(OutputError, match="symbolic link"):
        check_out_dir(link)
    with pytest.raises(OutputError, match="symbolic link"):
        _run_into(link, {"a.csv": "1"})
    assert link.is_symlink() and sorted(p.name for p in real.iterdir()) == ["keep.txt"]
    dangling = tmp_path / "dangling"
    dangling.symlink_to(tmp_path / "nowhere")
    with pytest.raises(OutputError, match="symbolic link"):
        check_out_dir(dangling)


def test_a_symlinked_parent_is_followed(tmp_path):
    """Only the last name must not be a link: a link higher up (a bigger disk mounted
    through a link, /tmp on some systems) is an ordinary path."""
    real = tmp_path / "real"
    real.mkdir()
    (tmp_path / "via").symlink_to(real)
    _run_into(tmp_path / "via" / "out", {"a.csv": "1"})
    assert (real / "out" / "a.csv").read_text() == "1"
    assert [p.name for p in real.iterdir()] == ["out"]      # no staging left beside it


def test_dotdot_after_a_missing_folder_is_an_error(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(OutputError, match="nonexist is not an existing folder"):
        check_out_dir("nonexist/../dd")
    assert not (tmp_path / "nonexist").exists()
    (tmp_path / "there").mkdir()
    _run_into("there/../dd", {"a.csv": "1"})
    assert (tmp_path / "dd" / "a.csv").exists()


def test_the_cli_refuses_a_symlinked_out_with_exit_2(tmp_path):
    (tmp_path / "real").mkdir()
    (tmp_path / "link").symlink_to(tmp_path / "real")
    r = subprocess.run([sys.executable, "-m", "plcpred", "predict", str(PRESS),
                        "--horizon", "1s", "--out", str(tmp_path / "link"), "--no-plot"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "symbolic link" in r.stderr, r.stderr


def test_a_killed_runs_staging_is_cleaned_by_the_next_run(tmp_path):
    """A run killed with SIGKILL leaves its staging folder and lock; the next run into
    the same parent removes both (the lock is free) and leaves a live run's alone."""
    out = tmp_path / "o"
    script = (f"import os, time\nfrom plcpred.output import output_dir\n"
              f"with output_dir({str(out)!r}) as s:\n"
              f"    (s / 'big.csv').write_bytes(b'x' * 100000)\n"
              f"    print('ready', flush=True)\n    time.sleep(60)\n")
    victim = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE,
                              text=True)
    live = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE,
                            text=True)
    try:
        assert victim.stdout.readline().strip() == "ready"
        assert live.stdout.readline().strip() == "ready"
        victim.kill()
        victim.wait(timeout=30)
        staged = sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".plcpred-"))
        assert len(staged) == 4                  # two folders, two locks
        _run_into(out, {"a.csv": "1"})
        left = sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".plcpred-"))
        assert len(left) == 2 and set(left) < set(staged)   # only the live run's
    finally:
        live.kill()
        live.wait(timeout=30)
    clean_abandoned(tmp_path)
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".plcpred-")]


def test_lockless_staging_of_older_versions_is_cleaned_only_when_stale(tmp_path):
    old = tmp_path / ".plcpred-staging-o-abc"
    old.mkdir()
    (old / "timeline.csv").write_text("x")
    fresh = tmp_path / ".plcpred-old-o-def"
    fresh.mkdir()
    past = time.time() - 2 * output.STALE_UNLOCKED_S
    os.utime(old, (past, past))
    assert clean_abandoned(tmp_path) == [old.name]
    assert not old.exists() and fresh.exists()


def test_a_planted_staging_link_is_unlinked_not_followed(tmp_path):
    target = tmp_path / "elsewhere"
    target.mkdir()
    (target / "precious").write_text("x")
    link = tmp_path / ".plcpred-staging-o-abc"
    link.symlink_to(target)
    past = time.time() - 2 * output.STALE_UNLOCKED_S
    os.utime(link, (past, past), follow_symlinks=False)
    clean_abandoned(tmp_path)
    assert (target / "precious").read_text() == "x"


def test_json_and_write_machine_paths_are_checked_before_any_work(tmp_path):
    """diagnose --json to a folder failed only after the diagnosis (and lost it)."""
    import time

    from plcpred.output import check_out_file
    rig = ROOT / "samples" / "prototype_rig"
    log = next(rig.glob("*measured*.csv"))
    (tmp_path / "adir").mkdir()
    (tmp_path / "afile").write_text("")
    for option, value in (("--json", tmp_path / "adir"),
                          ("--write-machine", tmp_path / "afile" / "fixed.toml")):
        t0 = time.perf_counter()
        r = subprocess.run([sys.executable, "-m", "plcpred", "diagnose", str(rig / "rig.toml"),
                            "--measured", str(log), option, str(value)],
                           capture_output=True, text=True, timeout=120)
        assert r.returncode == 2 and option in r.stderr, r.stderr
        assert time.perf_counter() - t0 < 20
    check_out_file("-", "--json")
    check_out_file(tmp_path / "new" / "deeper" / "x.json", "--json")
    with pytest.raises(OutputError, match="is a folder"):
        check_out_file(tmp_path, "--json")


def test_a_folder_in_the_way_of_an_output_file_is_named(tmp_path):
    out = tmp_path / "out"
    (out / "a.csv").mkdir(parents=True)
    (out / "a.csv" / "mine.txt").write_text("x")
    with pytest.raises(OutputError, match=r"a\.csv"):
        _run_into(out, {"a.csv": "1"})
    assert (out / "a.csv" / "mine.txt").read_text() == "x"


def test_emulate_refuses_a_negative_seed_and_a_denormal_stroke(tmp_path):
    r = subprocess.run([sys.executable, "-m", "plcpred", "emulate", str(PRESS), "--horizon",
                        "1s", "--out", str(tmp_path / "o"), "--seed", "-1"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "--seed" in r.stderr, r.stderr
    text = PRESS.read_text()
    import re
    m = re.search(r"stroke_mm = [0-9.]+", text)
    assert m, "press.toml has a stroke"
    bad = tmp_path / "m.toml"
    bad.write_text(text.replace(m.group(0), "stroke_mm = 5e-324").replace(
        'program = "sfc_press.st"', f'program = "{PRESS.parent / "sfc_press.st"}"'))
    r = subprocess.run([sys.executable, "-m", "plcpred", "--allow-root", str(PRESS.parent),
                        "emulate", str(bad), "--horizon", "1s", "--out", str(tmp_path / "o")],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode in (1, 2) and "stroke_mm" in r.stderr and "internal" not in r.stderr, \
        r.stderr
