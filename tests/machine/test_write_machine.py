"""Machine files plcpred writes (``diagnose --write-machine``, ``identify flow
--write-machine``) are the user's file with only the changed values written anew: every
table the docs describe, every comment, blank line and key order survive byte for byte."""
import copy
import re
import shutil
import tomllib

import pytest
from conftest import ROOT, SAMPLES

from plcpred.cli import main
from plcpred.machine import dump_machine_toml, load_machine, read_machine_data, save_machine, schema
from plcpred.machine.save import machine_toml

# every table of docs/reference/machine-file.md, with comments of every kind
ALL_TABLES = '''# The press with every table a machine file has.
# Comments above, beside and between keys and tables must all survive.

[machine]
name = "press"            # shown in reports
program = "sfc_press.st"
scan_ms = 10
supply_bar_g = 6.0        # regulated at the drop
atmosphere_kpa = 101.325
ambient_c = 20
cycle_signal = "PressValve"

# names for the addresses the program uses
[signals]
"%IX2.0" = "TwoHandOK"

[[input]]
signal = "%IX2.0"         # the operator's two-hand start
period_s = 6.0
offset_s = 1.0
pulse_ms = 300

[[consumer]]
name = "clamp"
kind = "double_acting"
bore_mm = 32
rod_mm = 12
stroke_mm = 25
tube_id_mm = 4
tube_length_m = [1.0, 1.0]   # valve to cap end, to rod end
valve = "ClampValve"
stroke_time_s = [0.15, 0.15]
switch_delay_s = 0.015
switches = { retracted = "ClampOpen", extended = "ClampClosed" }
line = "press line"

[[consumer]]
name = "die blow"         # the nozzle identify fits
kind = "nozzle"
valve = "DieBlow"
orifice_mm = 1.5
Cd = 0.8

# the leak at the drop, measured at standstill
[[consumer]]
name = "drop leak"
kind = "leak"
C = 3.4e-10
b = 0.12
m = 0.9

[[line]]
name = "press line"       # after its own regulator
volume_l = 2.0
droop_bar = 0.3

[meter]
tau_s = 0.4               # a thermal meter
rate_hz = 2

[calendar]
shifts_per_day = 2        # two shifts
hours_per_shift = 8
days_per_week = 5
'''


def _doc_block(table: str) -> str | None:
    """The docs' example of ``[table]`` (a ```toml block that starts with it)."""
    doc = (ROOT / "docs" / "reference" / "machine-file.md").read_text()
    for block in re.findall(r"```toml\n(.*?)```", doc, re.DOTALL):
        if block.startswith(f"[{table}]"):
            return block
    return None


def _all_tables_text() -> str:
    """ALL_TABLES, and the docs' example of any table added to the schema since."""
    text = ALL_TABLES
    have = set(tomllib.loads(text))
    for table in schema.TABLES:
        if table not in have:
            block = _doc_block(table)
            assert block, f"no example of [{table}] in the docs to build the test file from"
            text += "\n" + block
    return text


@pytest.fixture
def press(tmp_path):
    shutil.copy(SAMPLES / "sfc_press.st", tmp_path / "sfc_press.st")
    path = tmp_path / "press.toml"
    path.write_text(_all_tables_text())
    return path


def test_the_test_file_has_every_documented_table_and_loads(press):
    data = tomllib.loads(press.read_text())
    assert set(schema.TABLES) | {"signals"} <= set(data)
    kinds = {c["kind"] for c in data["consumer"]}
    assert {"double_acting", "nozzle", "leak"} <= kinds
    assert load_machine(press).calendar is not None


def _header_and_body(text: str) -> tuple[list[str], str]:
    lines = text.split("\n")
    n = lines.index("")          # the header ends at the first blank line
    return lines[:n], "\n".join(lines[n + 1:])


def test_identify_write_machine_changes_only_the_nozzles_values(press, tmp_path, capsys):
    fixed = tmp_path / "fixed.toml"
    data = SAMPLES / "prototype_rig" / "knives_flow.csv"
    code = main(["identify", "flow", str(data), "--machine", str(press), "--consumer",
                 "die blow", "--write-machine", str(fixed)])
    out = capsys.readouterr()
    assert code == 0, out.err
    # the fit is printed before the file is written
    assert out.out.index("parameter") < out.out.index(f"wrote {fixed}")
    header, body = _header_and_body(fixed.read_text())
    assert header == [("# press: die blow identified by plcpred identify flow from "
                      "knives_flow.csv")]
    nozzle = next(c for c in tomllib.loads(body)["consumer"] if c["name"] == "die blow")
    added = "".join(f"{k} = {nozzle[k]!r}  # added by plcpred identify flow\n"
                    for k in ("C", "b", "m"))
    expected = press.read_text().replace('valve = "DieBlow"\norifice_mm = 1.5\nCd = 0.8\n',
                                         'valve = "DieBlow"\n' + added)
    assert body == expected
    assert abs(nozzle["C"] - 6.56e-9) < 0.1e-9 and "a" not in nozzle
    assert load_machine(fixed).consumer("die blow").C == nozzle["C"]


def _diagnosed(data: dict) -> dict:
    """The kinds of change a diagnosis makes: values changed, keys and a consumer and a
    table added."""
    new = copy.deepcopy(data)
    new["machine"]["supply_bar_g"] = 5.6
    clamp = new["consumer"][0]
    clamp["tube_length_m"] = [2.5, 2.5]
    clamp["exhaust_tau_s"] = 0.05
    new["meter"]["tau_s"] = 0.8
    new["consumer"].append({"name": "leak (diagnosed)", "kind": "leak", "C": 1.2e-9,
                            "b": 0.2})
    return new


def test_a_diagnosis_written_keeps_every_table_and_comment(press, tmp_path):
    machine = load_machine(press)
    new = _diagnosed(read_machine_data(press))
    fixed = tmp_path / "fixed.toml"
    save_machine(copy.deepcopy(new), machine, fixed, "press, corrected\nverdict: leak",
                 by="plcpred diagnose")
    header, body = _header_and_body(fixed.read_text())
    assert header == ["# press, corrected", "# verdict: leak"]
    text = press.read_text()
    note = "  # added by plcpred diagnose"
    expected = (text
                .replace("supply_bar_g = 6.0        #", "supply_bar_g = 5.6        #")
                .replace("tube_length_m = [1.0, 1.0]   #", "tube_length_m = [2.5, 2.5]   #")
                .replace('line = "press line"\n',
                         f'line = "press line"\nexhaust_tau_s = 0.05{note}\n')
                .replace("tau_s = 0.4 ", "tau_s = 0.8 ")
                .replace("m = 0.9\n", f'm = 0.9\n\n[[consumer]]{note}\nname = "leak '
                                      '(diagnosed)"\nkind = "leak"\nC = 1.2e-09\nb = 0.2\n'))
    assert body == expected
    assert tomllib.loads(body) == new
    assert load_machine(fixed).consumer("leak (diagnosed)").C == 1.2e-9


def test_a_table_the_file_did_not_have_is_added_at_its_end(press, tmp_path):
    text = press.read_text().replace("[meter]\ntau_s = 0.4               # a thermal meter\n"
                                     "rate_hz = 2\n\n", "")
    press.write_text(text)
    new = read_machine_data(press)
    new["meter"] = {"tau_s": 0.6}
    out = machine_toml(new, text, "", "plcpred diagnose")
    assert out == text + "\n[meter]  # added by plcpred diagnose\ntau_s = 0.6\n"


def test_written_elsewhere_only_the_program_path_changes(press, tmp_path):
    machine = load_machine(press)
    other = tmp_path / "fixes" / "fixed.toml"
    save_machine(read_machine_data(press), machine, other)
    text = other.read_text()
    assert text == press.read_text().replace('program = "sfc_press.st"',
                                             'program = "../sfc_press.st"')
    assert load_machine(other, [tmp_path]).program_path == machine.program_path


def test_windows_newlines_survive(press, tmp_path):
    press.write_bytes(press.read_text().replace("\n", "\r\n").encode())
    machine = load_machine(press)
    new = read_machine_data(press)
    new["machine"]["supply_bar_g"] = 5.5
    fixed = tmp_path / "fixed.toml"
    save_machine(new, machine, fixed, "fixed")
    raw = fixed.read_bytes()
    assert raw.startswith(b"# fixed\r\n\r\n")
    assert raw[len(b"# fixed\r\n\r\n"):] == press.read_bytes().replace(
        b"supply_bar_g = 6.0 ", b"supply_bar_g = 5.5 ")


def test_dropped_keys_and_consumers_go_and_inline_tables_change_in_place():
    text = ('consumer = [{ name = "a", kind = "leak", C = 1e-9, b = 0.2 },\n'
            '            { name = "b", kind = "leak", C = 2e-9, b = 0.2 }]\n\n'
            '[machine]\nprogram = "p.st"  # the program\nsupply_bar_g = 6\nscan_ms = 5\n')
    new = tomllib.loads(text)
    new["consumer"][0]["C"] = 3e-9
    del new["consumer"][1]
    del new["machine"]["scan_ms"]
    out = machine_toml(new, text)
    assert tomllib.loads(out) == new
    assert out == ('consumer = [{ name = "a", kind = "leak", C = 3e-09, b = 0.2 }]\n\n'
                   '[machine]\nprogram = "p.st"  # the program\nsupply_bar_g = 6\n')


def test_a_fresh_file_holds_every_table():
    """Without the user's file (data only), every table is written, [calendar] too."""
    data = tomllib.loads(_all_tables_text())
    text = dump_machine_toml(data, "made")
    assert text.startswith("# made\n\n")
    assert tomllib.loads(text) == data


def test_what_toml_cannot_hold_is_refused():
    data = tomllib.loads(ALL_TABLES)
    data["machine"]["supply_bar_g"] = float("nan")
    with pytest.raises(ValueError, match="nan"):
        machine_toml(data, ALL_TABLES)


def test_unchanged_data_is_written_back_byte_for_byte(press, tmp_path):
    """Also when the data says 10.0 where the file says 10 (a diagnosis computes floats):
    the same number, the user's text."""
    fixed = tmp_path / "same.toml"
    data = read_machine_data(press)
    data["machine"]["scan_ms"] = 10.0
    data["consumer"][0]["bore_mm"] = 32.0
    save_machine(data, load_machine(press), fixed)
    assert fixed.read_bytes() == press.read_bytes()


def test_diagnose_prints_its_report_before_a_file_fails_to_be_written(
        press, tmp_path, capsys, monkeypatch):
    """A file that cannot be written (the disk full at the end of a long diagnosis) does
    not lose the report: it is printed first."""
    import plcpred.cli.diagnose as cli_diagnose
    from plcpred.output import OutputError

    class Done:
        warnings = ()
        fixed_machine = None

        def report(self):
            return "THE REPORT"

        def summary(self):
            return {}

    def cannot_write(d, path):
        raise OutputError(f"{path}: disk full")

    monkeypatch.setattr(cli_diagnose, "diagnose", lambda *a, **k: Done())
    monkeypatch.setattr(cli_diagnose, "write_fixed_machine", cannot_write)
    log = tmp_path / "run.csv"
    log.write_text("time_s,flow_l_min\n0,1\n1,2\n2,3\n")
    code = main(["diagnose", str(press), "--measured", str(log), "--write-machine",
                 str(tmp_path / "fixed.toml")])
    out = capsys.readouterr()
    assert code == 2 and "THE REPORT" in out.out and "disk full" in out.err


@pytest.mark.parametrize("text", [
    'machine.name = "x"  # dotted keys\nmachine.supply_bar_g = 6\n',
    '[machine]\nsupply_bar_g = 6  # split\n[meter]\ntau_s = 1\n[machine.x]\ny = 1\n',
    'machine = { supply_bar_g = 6, name = "x" }  # inline\n',
    ('[machine]\nsupply_bar_g = 6  # sub-table\n[[consumer]]\nname = "a"\n'
    '[consumer.switches]\nretracted = "r"\n'),
])
def test_unusual_layouts_are_edited_in_place(text):
    new = tomllib.loads(text)
    new["machine"]["supply_bar_g"] = 5
    new["machine"]["ambient_c"] = 21
    new.setdefault("meter", {})["rate_hz"] = 2
    out = machine_toml(new, text, "", "t")
    assert tomllib.loads(out) == new
    assert re.search(r"#[^\n]*", text).group(0) in out       # the edit kept the comment


def test_a_change_the_edit_cannot_make_writes_the_data_whole(monkeypatch):
    """The text is read back: an edit that went wrong is never written; the data is,
    whole (without the user's comments)."""
    from plcpred.machine import save
    monkeypatch.setattr(save, "_merge_list", lambda *a: None)
    new = tomllib.loads(ALL_TABLES)
    new["consumer"].append({"name": "x", "kind": "leak", "C": 1e-9, "b": 0.2})
    out = machine_toml(new, ALL_TABLES)
    assert tomllib.loads(out) == new and "#" not in out
