"""Outputs stay bounded: timeline.csv holds at most --max-rows rows (a tiled year of a
fast machine streamed 1.8 GB a minute before)."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PRESS = ROOT / "samples" / "press.toml"


def _plcpred(*argv):
    return subprocess.run([sys.executable, "-m", "plcpred", *map(str, argv)],
                          capture_output=True, text=True, timeout=300)


def test_timeline_over_max_rows_is_an_error_before_writing(tmp_path):
    r = _plcpred("timeline", PRESS, "--horizon", "1h", "--max-rows", "1000",
                 "--out", tmp_path / "o")
    assert r.returncode == 2, r.stderr
    assert "more than --max-rows 1,000" in r.stderr and "rows" in r.stderr
    assert not (tmp_path / "o").exists()


def test_predict_over_max_rows_skips_the_timeline_with_a_warning(tmp_path):
    out = tmp_path / "o"
    r = _plcpred("predict", PRESS, "--horizon", "1h", "--max-rows", "1000", "--no-plot",
                 "--out", out)
    assert r.returncode == 0, r.stderr
    assert "timeline.csv would hold" in r.stderr and "not written" in r.stderr
    assert sorted(p.name for p in out.iterdir()) == ["demand.csv", "manifest.json",
                                                     "summary.json"]
    full = _plcpred("predict", PRESS, "--horizon", "1h", "--no-plot", "--out",
                    tmp_path / "full")
    assert full.returncode == 0, full.stderr
    # the demand does not depend on whether the timeline was written
    assert json.loads((out / "summary.json").read_text())["total_nl"] == \
        json.loads((tmp_path / "full" / "summary.json").read_text())["total_nl"]
    assert (tmp_path / "full" / "timeline.csv").exists()


def test_no_timeline(tmp_path):
    r = _plcpred("predict", PRESS, "--horizon", "10s", "--no-plot", "--no-timeline",
                 "--out", tmp_path / "o")
    assert r.returncode == 0, r.stderr
    assert not (tmp_path / "o" / "timeline.csv").exists()
    assert "timeline.csv" not in r.stdout
