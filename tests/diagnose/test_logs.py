"""The logs engineers really have (issue 39): a logger's units in its header, m3/min and
psi, separate date and time columns, a preamble, a workbook instead of a CSV, the Windows
code page, and identify reading a test bench's own columns. The files are in
tests/data/logs and tests/data/identify."""
import json
from pathlib import Path

import numpy as np
import pytest

from plcpred.cli import build_parser, main
from plcpred.datafile import FLOW_UNIT_SPELLINGS, PRESSURE_UNIT_SPELLINGS
from plcpred.diagnose import MeasuredDataError, read_measured
from plcpred.diagnose.io import FLOW_UNITS, PRESSURE_UNITS
from plcpred.identify import DataColumns, IdentifyError, identify_steady, read_flow_data

DATA = Path(__file__).resolve().parents[1] / "data"
LOGS = DATA / "logs"
M3H = 1000.0 / 60.0             # l/min per m3/h
PSI_BAR = 0.0689476


@pytest.mark.parametrize("flow_col", ["3", "Volumenstrom [m3/h]"])
def test_a_named_flow_column_keeps_its_headers_unit(flow_col):
    """--flow-col 3 on 'Volumenstrom [m3/h]' read m3/h as l/min while the time column
    was found by its name: 16.7 times too low."""
    run = read_measured(LOGS / "volumenstrom_m3h.csv", flow_col=flow_col)
    assert run.flow_l_min.tolist() == pytest.approx([1.5 * M3H, 2.5 * M3H, 3.5 * M3H,
                                                     1.5 * M3H])
    assert run.source["flow_unit"] == "m3/h"
    assert "flow from 'Volumenstrom [m3/h]' in m3/h" in run.source["columns_guessed"]
    assert "warnings" not in run.source


def test_flow_unit_overrides_the_header_with_a_warning():
    run = read_measured(LOGS / "volumenstrom_m3h.csv", flow_col="3", flow_unit="l/min")
    assert run.flow_l_min[:3].tolist() == pytest.approx([1.5, 2.5, 3.5])
    assert run.source["warnings"] == [("column 'Volumenstrom [m3/h]' says m3/h, read as "
                                      "l/min as --flow-unit says")]
    # the same unit spelled otherwise is no disagreement
    agreed = read_measured(LOGS / "volumenstrom_m3h.csv", flow_col="3", flow_unit="Nm³/h")
    assert "warnings" not in agreed.source
    assert agreed.flow_l_min.tolist() == pytest.approx((run.flow_l_min * M3H).tolist())


def test_a_compressors_m3_per_min_and_a_supply_in_psi():
    run = read_measured(LOGS / "fad_m3min_psi.csv")
    assert run.flow_l_min.tolist() == pytest.approx([500.0, 750.0, 1000.0, 500.0])
    assert run.supply_bar_g.tolist() == pytest.approx(
        [87.0 * PSI_BAR, 85.5 * PSI_BAR, 88.5 * PSI_BAR, 87.0 * PSI_BAR])
    assert run.source["supply_unit"] == "psi"
    assert run.source["columns_guessed"] == (
        "time from column 'Time', flow from 'FAD [m3/min]' in m3/min, supply from "
        "'Pressure [psi]' in psi(g)")
    # a unit given for the supply wins, with a warning
    as_bar = read_measured(LOGS / "fad_m3min_psi.csv", supply_unit="bar")
    assert as_bar.supply_bar_g[0] == pytest.approx(87.0)
    assert as_bar.source["warnings"] == [("column 'Pressure [psi]' says psi, read as bar as "
                                         "--supply-unit says")]


def test_an_absolute_supply_is_read_as_gauge():
    run = read_measured(LOGS / "absolute_bara.csv")
    assert run.supply_bar_g.tolist() == pytest.approx([6.0, 6.0, 6.0])


def test_separate_date_and_time_columns_pass_midnight():
    run = read_measured(LOGS / "datum_uhrzeit.csv")
    assert np.diff(run.time_s).tolist() == [1.0, 1.0, 1.0]
    assert run.source["date_column"] == "Datum" and run.source["time_column"] == "Uhrzeit"
    assert run.source["time_format"] == "%d.%m.%Y %H:%M:%S"
    assert run.source["columns_guessed"].startswith("time from columns 'Datum' and 'Uhrzeit'")
    # named by the caller, the same
    named = read_measured(LOGS / "datum_uhrzeit.csv", time_col="Uhrzeit", date_col="1",
                          flow_col="3")
    assert named.time_s.tolist() == run.time_s.tolist()


def test_uhrzeit_alone_is_a_time_column():
    run = read_measured(LOGS / "uhrzeit.csv")
    assert run.time_s.tolist() == [47100.0, 47101.0, 47102.0]     # 13:05:00 on
    assert run.flow_l_min.tolist() == [10.0, 11.0, 12.0]


def test_a_preamble_error_points_at_the_header_line():
    with pytest.raises(MeasuredDataError, match=r"preamble\.csv: line 5: no time and flow "
                                                r"columns .*this file has Stamp, Value"):
        read_measured(LOGS / "preamble.csv")
    with pytest.raises(MeasuredDataError, match=r"preamble\.csv: line 5: no time column "
                                                r"'Zeit' \(columns: Stamp, Value \[m3/h\]\)"):
        read_measured(LOGS / "preamble.csv", time_col="Zeit", flow_col="2")
    run = read_measured(LOGS / "preamble.csv", time_col="Stamp", flow_col="2")
    assert run.flow_l_min.tolist() == pytest.approx([1.5 * M3H, 2.5 * M3H, 3.5 * M3H])


def test_two_columns_named_as_a_flow_are_named_in_the_error(tmp_path):
    path = tmp_path / "two.csv"
    path.write_text("Zeit;Durchfluss A;Durchfluss B\n0;1;2\n1;2;3\n2;3;4\n")
    with pytest.raises(MeasuredDataError, match="Durchfluss A, Durchfluss B are each named "
                                                "as a flow: name one with --flow-col"):
        read_measured(path)


def test_a_workbook_is_answered_with_export_as_csv():
    with pytest.raises(MeasuredDataError, match=r"flow_log\.xlsx: a spreadsheet workbook "
                                                r".*export the sheet as CSV"):
        read_measured(LOGS / "flow_log.xlsx")
    with pytest.raises(IdentifyError, match="export the sheet as CSV"):
        read_flow_data(LOGS / "flow_log.xlsx")


def test_a_windows_code_page_log_keeps_its_unit(tmp_path):
    run = read_measured(LOGS / "cp1252_m3h.csv")
    assert run.source["flow_unit"] == "m3/h"
    assert run.flow_l_min[0] == pytest.approx(1.5 * M3H)
    # UTF-8 with a damaged byte stays an error: m³/h must not turn into mÂ³/h
    damaged = tmp_path / "damaged.csv"
    damaged.write_bytes("Zeit;Volumenstrom [m³/h]\n0;1,5\n1;\xff2,5\n2;3,5\n".encode()
                        .replace(b"\xc3\xbf", b"\xff"))
    with pytest.raises(MeasuredDataError, match="line 3: not UTF-8 text"):
        read_measured(damaged)


def test_flow_unit_offers_every_unit_the_reader_knows(capsys):
    assert set(FLOW_UNIT_SPELLINGS) == set(FLOW_UNITS)
    assert set(PRESSURE_UNIT_SPELLINGS) == set(PRESSURE_UNITS)
    for command in ("diagnose", "identify"):
        sub = next(a for a in build_parser()._actions if a.dest == "command")
        help_text = " ".join(sub.choices[command].format_help().split())
        for unit in FLOW_UNITS:
            assert unit in help_text.split("--flow-unit UNIT")[-1], (command, unit)
    args = build_parser().parse_args(["diagnose", "m.toml", "--measured", "x.csv",
                                      "--flow-unit", "Nm³/h", "--supply-unit", "psig"])
    assert (args.flow_unit, args.supply_unit) == ("m3/h", "psi")
    with pytest.raises(SystemExit):
        build_parser().parse_args(["diagnose", "m.toml", "--measured", "x.csv",
                                   "--flow-unit", "gallons"])
    assert "unknown flow unit 'gallons' (known: l/min, l/s, m3/h, m3/min, scfm)" in \
        capsys.readouterr().err


def test_diagnose_prints_the_unit_warning_before_it_works(tmp_path, capsys):
    # a log too short for a diagnosis: the command stops, after saying how it read it
    assert main(["diagnose", str(DATA.parent.parent / "samples" / "pick_place.toml"),
                 "--measured", str(LOGS / "volumenstrom_m3h.csv"), "--flow-col", "3",
                 "--flow-unit", "l/min", "--no-plant"]) == 2
    err = capsys.readouterr().err
    assert "warning: volumenstrom_m3h.csv: column 'Volumenstrom [m3/h]' says m3/h, read " \
           "as l/min as --flow-unit says" in err


# ---------------------------------------------------------------------- identify

def test_identify_reads_a_benchs_own_columns_and_units():
    """psi gauge, m3/h and decimal commas under the bench's names give the points (and
    so the fit) the default names and units give."""
    plain = read_flow_data(DATA / "identify" / "bench_plain.csv")
    logger = read_flow_data(DATA / "identify" / "bench_logger.csv", columns=DataColumns(
        flow_col="Q [m3/h]", p_up_col="1", p_down_col="p2 [psi]"))
    assert logger.flow_l_min == pytest.approx(plain.flow_l_min, rel=1e-5)
    assert logger.p_up_pa == pytest.approx(plain.p_up_pa, rel=1e-5)
    assert logger.p_down_pa == pytest.approx(plain.p_down_pa, rel=1e-5)
    fit = identify_steady(logger)
    assert (fit.C, fit.b, fit.m) == pytest.approx((1.2e-8, 0.3, 0.62), rel=0.01)
    with pytest.raises(IdentifyError, match=r"bench_logger\.csv:2: no column 'Flow' for "
                                            r"flow_l_min \(columns: p1 \[psi\], p2"):
        read_flow_data(DATA / "identify" / "bench_logger.csv",
                       columns=DataColumns(flow_col="Flow", p_up_col="1"))


def test_identify_cli_takes_the_column_options(tmp_path, capsys):
    out = tmp_path / "fit.json"
    assert main(["identify", "flow", str(DATA / "identify" / "bench_logger.csv"),
                 "--flow-col", "3", "--flow-unit", "m3/h", "--p-up-col", "p1 [psi]",
                 "--p-down-col", "2", "--pressure-unit", "psi", "--json", str(out)]) == 0
    fit = json.loads(out.read_text())
    assert fit["C"] == pytest.approx(1.2e-8, rel=0.01) and fit["n_points"] == 24
