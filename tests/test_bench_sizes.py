"""The blind benchmarks count a case only when its effect is visible in the log. The
diagnosis never knows the logger's clock, so the size of an effect is what is left after
the best clock shift (bench/gap_blind.py ``observable_size``)."""
import importlib.util
from pathlib import Path

import numpy as np
import pytest

BENCH = Path(__file__).resolve().parent.parent / "bench" / "gap_blind.py"


@pytest.fixture(scope="module")
def observable_size():
    spec = importlib.util.spec_from_file_location("gap_blind_for_test", BENCH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.observable_size


def _log(t, delay_s=0.0, scale=1.0):
    # strokes of 0.3 s every 2 s, 60 NL/min, through no meter
    return scale * 60.0 * (((t - delay_s) % 2.0) < 0.3)


def test_a_pure_delay_of_the_whole_machine_is_no_visible_effect(observable_size):
    t = np.arange(0.0, 40.0, 0.01)
    raw = np.sqrt(np.mean((_log(t, 0.25) - _log(t)) ** 2))
    assert raw > 20.0                                  # large sample by sample
    assert observable_size(t, _log(t, 0.25), _log(t)) < 0.5


def test_a_change_of_volume_keeps_its_full_size(observable_size):
    t = np.arange(0.0, 40.0, 0.01)
    q0, q1 = _log(t), _log(t, scale=1.3)
    expected = np.sqrt(np.mean((q1 - q0) ** 2))        # 0.3 x 60 NL/min on 15 % of samples
    assert observable_size(t, q1, q0) == pytest.approx(expected, rel=0.01)
    assert expected == pytest.approx(18.0 * np.sqrt(0.15), rel=0.01)


def test_a_delay_beyond_the_shifts_tried_stays_visible(observable_size):
    # half a period out of phase and no shift within 0.5 s to undo it
    t = np.arange(0.0, 40.0, 0.01)
    assert observable_size(t, _log(t, 1.0), _log(t), max_shift_s=0.5) > 20.0
