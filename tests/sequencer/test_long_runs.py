"""Long horizons in bounded memory: tiled timelines are written from their period, a run
that changes signals too often stops with a clear error, and too fine a demand grid is
refused before it is allocated."""
import re

import numpy as np
import pytest
from conftest import SAMPLES

from plcpred import cli, predict, unfold
from plcpred.air.predict import GridError
from plcpred.cli import args as cli_args
from plcpred.sequencer import SequencerError, TimelineTooLarge
from plcpred.sequencer.timeline import DEFAULT_MAX_CHANGES, Timeline

PICK = SAMPLES / "pick_place.toml"


def _variant(tmp_path, period_s):
    text = PICK.read_text().replace("period_s = 4.0", f"period_s = {period_s}")
    text = text.replace('program = "codesys_pick_place.st"',
                        f'program = "{(SAMPLES / "codesys_pick_place.st").as_posix()}"')
    path = tmp_path / f"pp_{period_s}.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("period_s", [4.0, 2.5, 3.332, 4.004])
def test_tiled_csv_equals_the_csv_of_the_full_arrays(tmp_path, period_s):
    # whole-second periods repeat their fractions every repetition, the others after 2,
    # 250 or 250 repetitions: the writer's table of residues
    tl = unfold(_variant(tmp_path, period_s), "900s")
    assert tl.tiled is not None
    full = Timeline(tl.signals, tl.time_ns, tl.signal_idx, tl.values, tl.horizon_ns)
    tl.to_csv(tmp_path / "a.csv", rows_per_write=97)
    full.to_csv(tmp_path / "b.csv")
    a, b = (tmp_path / "a.csv").read_text(), (tmp_path / "b.csv").read_text()
    assert a == b
    assert len(a.splitlines()) == tl.n_changes + 1


@pytest.mark.parametrize("period_ns", [1_000_000_007, 3 * 10**9, 1_500_000_000])
def test_tiled_writer_on_handmade_periods(tmp_path, period_ns):
    # an odd-nanosecond period never repeats its fractions: the general path
    rng = np.random.default_rng(period_ns)
    n = 40
    t = np.sort(rng.integers(1, 3 * period_ns, n))
    t[0] = 0
    sig = rng.integers(0, 3, n).astype(np.int32)
    val = rng.integers(0, 2, n).astype(float)
    from plcpred.sequencer.timeline import Signal
    sigs = [Signal("a", "output", "bool"), Signal("b", "output", "bool"),
            Signal("r", "output", "real")]
    t1 = int(t[n // 4])
    keep = t <= t1 + period_ns  # the executor stops at the end of the first repetition
    tiled = Timeline(sigs, t[keep], sig[keep], val[keep], 200 * period_ns + 12345,
                     tiled=(t1, t1 + period_ns))
    tiled.to_csv(tmp_path / "a.csv", rows_per_write=13)
    Timeline(sigs, tiled.time_ns, tiled.signal_idx, tiled.values,
             tiled.horizon_ns).to_csv(tmp_path / "b.csv")
    assert (tmp_path / "a.csv").read_text() == (tmp_path / "b.csv").read_text()


def test_n_changes_does_not_build_the_arrays():
    tl = unfold(PICK, "3650d")
    assert tl._full is None
    per_day = unfold(PICK, "1d").n_changes
    assert tl.n_changes == pytest.approx(per_day * 3650, rel=1e-3)
    with pytest.raises(TimelineTooLarge, match="--max-events"):
        tl.time_ns


def test_chunks_cover_the_timeline_in_order():
    tl = unfold(PICK, "600s")
    t = np.concatenate([c[0] for c in tl.chunks(rows=50)])
    assert np.array_equal(t, tl.time_ns) and np.all(np.diff(t) >= 0)


def test_a_signal_changing_every_scan_stops_with_its_name(tmp_path):
    prog = tmp_path / "toggle.st"
    prog.write_text("PROGRAM Toggle\nVAR_OUTPUT q : BOOL; END_VAR\nq := NOT q;\n"
                    "END_PROGRAM\n")
    m = tmp_path / "m.toml"
    m.write_text('[machine]\nprogram = "toggle.st"\nscan_ms = 10\nsupply_bar_g = 5\n'
                 '[[consumer]]\nname = "knife"\nkind = "nozzle"\nvalve = "q"\nC = 1e-9\n'
                 "b = 0.3\n")
    with pytest.raises(SequencerError, match=r"'q' changes .* \(every scan\)"):
        unfold(m, "1h", max_events=10_000)
    assert cli.main(["timeline", str(m), "--horizon", "1h", "--max-events", "5000",
                     "--out", str(tmp_path / "o")]) == 2
    assert not (tmp_path / "o").exists()


def test_too_fine_a_grid_is_refused_before_it_is_built(tmp_path, capsys):
    with pytest.raises(GridError, match="coarser --dt"):
        predict(PICK, "1h", dt=1e-6)
    assert cli.main(["predict", str(PICK), "--horizon", "1s", "--dt", "1ns", "--out",
                     str(tmp_path / "o")]) == 2          # a usage error, not a finding
    assert "coarser --dt" in capsys.readouterr().err


def test_cli_default_matches_the_sequencer():
    assert cli_args.DEFAULT_MAX_CHANGES == DEFAULT_MAX_CHANGES
    assert re.search(r"--max-events N", cli.build_parser().format_help()) is None  # per command


def test_a_periodic_input_starting_after_the_horizon(tmp_path):
    text = PICK.read_text().replace("offset_s = 0.5", "offset_s = 5000")
    text = text.replace('program = "codesys_pick_place.st"',
                        f'program = "{(SAMPLES / "codesys_pick_place.st").as_posix()}"')
    m = tmp_path / "m.toml"
    m.write_text(text)
    tl = unfold(m, "60s")
    assert tl.count_rising("xPartPresent") == 0


def test_jittered_schedules_are_the_same_whatever_the_block_size(monkeypatch):
    from plcpred.machine import InputSchedule
    from plcpred.sequencer.executor import Schedule
    spec = InputSchedule("x", period_s=1.0, offset_s=0.3, pulse_ms=100, jitter_s=0.2, seed=7)

    def edges(block):
        monkeypatch.setattr(Schedule, "BLOCK", block)
        s = Schedule(spec, 3_000 * 10**9)
        out = []
        while (t := s.next_ns()) is not None:
            s.advance(t)
            out.append((t, s.value))
        return out
    a, b = edges(4096), edges(7)
    assert a == b and len(a) == 2 * 3001  # pulses up to one period past the horizon
