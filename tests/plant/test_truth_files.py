"""Truth files (``emulate --truth``): a mistyped consumer names the one meant, and an
error points at the line of the file the wrong key came from."""
import shutil

import pytest
from conftest import SAMPLES

from plcpred.machine import MachineError
from plcpred.plant import load_real_machine


@pytest.fixture
def press(tmp_path):
    for f in ("press.toml", "sfc_press.st"):
        shutil.copy(SAMPLES / f, tmp_path / f)
    return tmp_path / "press.toml"


def _error(press, truth_text: str) -> str:
    truth = press.parent / "t.toml"
    truth.write_text(truth_text)
    with pytest.raises(MachineError) as ei:
        load_real_machine(press, truth)
    return str(ei.value).replace(str(press.parent) + "/", "")


def test_a_mistyped_consumer_names_the_one_meant_at_its_line(press):
    assert _error(press, '[meter]\ntau_s = 0.5\n\n[[consumer]]\nname = "pres"\nbore_mm = 70\n') \
        == ("t.toml:5: [[consumer]] #1: no consumer 'pres' in the machine file; did you mean "
            "'press'? (a consumer to add needs its kind)")
    assert "(its consumers: clamp, die blow, ejector, press)" in _error(
        press, '[[consumer]]\nname = "robot"\nbore_mm = 70\n')


def test_a_bad_value_from_the_truth_file_is_at_its_line_there(press):
    assert _error(press, '[[consumer]]\nname = "press"\nbore_mm = -70\n') == \
        't.toml:3: consumer "press": bore_mm must be > 0'
    assert _error(press, '[[consumer]]\nname = "leak"\nkind = "leak"\nC = 1e-9\n') == \
        ("t.toml:1: consumer \"leak\": missing required key 'b' (critical pressure ratio) "
         "with C")
    assert _error(press, '[machine]\n\nscan_ms = "fast"\n') == \
        "t.toml:3: [machine]: scan_ms must be a number, not 'fast'"


def test_an_error_the_truth_file_causes_in_a_nominal_key_is_at_the_nominal_line(press):
    """The truth file's bore makes the nominal rod too thick: the rod's line is named."""
    line = press.read_text().split("\n").index("rod_mm = 25") + 1
    assert _error(press, '[[consumer]]\nname = "press"\nbore_mm = 20\n') == (
        f'press.toml:{line}: consumer "press": rod_mm (25) must be smaller than bore_mm (20) '
        "(with the deviations of t.toml)")


def test_an_unknown_table_in_a_truth_file_names_the_one_meant(press):
    assert _error(press, "[meters]\ntau_s = 1\n").startswith(
        "t.toml:1: unknown table 'meters'; did you mean 'meter'?")
