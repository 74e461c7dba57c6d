"""Measured data, I/O traces, horizons, identify data and plant parameters are untrusted
(CI runs plcpred on pull requests): every bad input ends in a PlcpredError naming the file
and line (or table and key) in bounded time and memory, never an internal error (exit 3)
or a run without end.

Each test failed before its fix (checked by hand against the earlier code): a csv field
over Python's limit and I/O trace times of 1e10 s were internal errors, traces had no row
limit and were read whole, a trace without one of the machine's valves was a KeyError, a
horizon of 301 years an OverflowError in the air model, ``identify flow`` printed C = inf
with exit 0, and a [[line]] with C = 1e-3 ran emulate without end. Limits are set small
with monkeypatch where a real-size file would be large.
"""
from pathlib import Path

import numpy as np
import pytest

import plcpred.datafile as datafile
import plcpred.diagnose.io as io
from plcpred.air.demand import (
    DemandError,
    consumer_models,
    demand_profile,
    passive_intervals,
    valve_transitions,
)
from plcpred.cli import main
from plcpred.diagnose import MeasuredDataError, read_io_timeline, read_measured
from plcpred.errors import PlcpredError
from plcpred.identify import IdentifyError, TankData, identify_tank, read_flow_data
from plcpred.machine import load_machine
from plcpred.sequencer import Timeline, parse_horizon, unfold
from plcpred.sequencer.timeline import MAX_HORIZON_NS, NS, HorizonError

ROOT = Path(__file__).resolve().parents[2]
PICK = ROOT / "samples" / "pick_place.toml"
LOG = "time_s,flow_l_min,supply_bar_g\n" + "".join(
    f"{0.1 * k:.1f},{3.5 + (k % 7)},6.0\n" for k in range(1, 60))
TRACE = ("time_s,signal,value\n0,qZ,0\n0,qX,0\n0,qGrip,0\n0,qVacuum,0\n"
         "1.0,qZ,1\n1.5,qGrip,1\n2.0,qZ,0\n2.5,qX,1\n3.5,qGrip,0\n4.0,qX,0\n")


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


# ---------------------------------------------------------------------- 1: csv field limit

def test_a_flow_log_cell_over_the_csv_field_limit_is_a_positioned_error(tmp_path):
    lines = LOG.splitlines()
    one_line = _write(tmp_path / "long.csv", "\n".join(
        lines[:5] + ["0.55," + "x" * 200_000 + ",6"] + lines[5:]) + "\n")
    with pytest.raises(MeasuredDataError, match=r"long\.csv: line 6: longer than 100,000"):
        read_measured(one_line)
    # a quote never closed: the field runs over many short lines
    quoted = _write(tmp_path / "quoted.csv", "\n".join(
        lines[:5] + ['0.55,"' + "\n".join(["y" * 50_000] * 4) + '",6'] + lines[5:]) + "\n")
    with pytest.raises(MeasuredDataError,
                       match=r"quoted\.csv: line \d+: a field longer than 131,072"):
        read_measured(quoted)


def test_an_io_trace_cell_over_the_csv_field_limit_is_exit_2(tmp_path, capsys):
    log = _write(tmp_path / "run.csv", LOG)
    trace = _write(tmp_path / "trace.csv", TRACE.replace(
        "1.0,qZ,1", '1.0,"' + "\n".join(["z" * 60_000] * 3) + '",1'))
    with pytest.raises(MeasuredDataError, match=r"trace\.csv: line \d+: a field longer"):
        read_io_timeline(trace, 10)
    code = main(["diagnose", str(PICK), "--measured", str(log), "--io", str(trace),
                 "--no-plant"])
    err = capsys.readouterr().err
    assert code == 2 and "trace.csv: line" in err and "internal error" not in err


def test_identify_data_with_a_huge_cell_is_exit_2(tmp_path, capsys):
    data = _write(tmp_path / "flow.csv", "p_up_bar_g,p_down_bar_g,flow_l_min\n6,0,100\n"
                  '5,0,"' + "\n".join(["9" * 60_000] * 3) + '"\n')
    assert main(["identify", "flow", str(data)]) == 2
    assert "flow.csv" in capsys.readouterr().err


# ---------------------------------------------------------------------- 2: times and sizes

@pytest.mark.parametrize("time", ["1e10", "1e300", "315576001"])
def test_io_trace_times_beyond_ten_years_name_the_line(tmp_path, time):
    trace = _write(tmp_path / "trace.csv", TRACE + f"{time},qZ,1\n")
    with pytest.raises(MeasuredDataError, match=rf"trace\.csv: line 12: time {time} s is "
                                                "beyond 10 years"):
        read_io_timeline(trace, 10)


def test_io_trace_rows_are_limited(tmp_path, monkeypatch):
    monkeypatch.setattr(io, "MAX_ROWS", 8)
    trace = _write(tmp_path / "trace.csv", TRACE)      # 10 rows after the header
    with pytest.raises(MeasuredDataError, match=r"trace\.csv: line 10: more than 8 rows"):
        read_io_timeline(trace, 10)
    monkeypatch.setattr(io, "MAX_IO_SIGNALS", 3)
    monkeypatch.setattr(io, "MAX_ROWS", 100)
    with pytest.raises(MeasuredDataError, match=r"line 5: more than 3 signals"):
        read_io_timeline(trace, 10)


def test_a_flow_log_is_streamed_and_stops_at_its_row_limit(tmp_path, monkeypatch):
    """Read a line at a time: past the limit reading stops, so what comes later in the
    file (here bytes that are no UTF-8, which a reader of the whole file fails on first)
    is never read."""
    monkeypatch.setattr(io, "MAX_ROWS", 20)
    monkeypatch.setattr(datafile, "CHUNK_BYTES", 64)       # read in blocks of 1 MB
    path = tmp_path / "big.csv"
    path.write_bytes(LOG.encode() + b"9.9,\xff\xfe,6\n")
    with pytest.raises(MeasuredDataError, match=r"big\.csv: .*more than 20 (rows|samples)"):
        read_measured(path)
    # the bytes themselves are named by line when reached
    monkeypatch.setattr(io, "MAX_ROWS", 1000)
    with pytest.raises(MeasuredDataError, match=r"big\.csv: line 61: not UTF-8 text"):
        read_measured(path)


def test_flow_logs_refuse_absurd_flows_and_spans(tmp_path):
    with pytest.raises(MeasuredDataError, match=r"line 4, column 2: flow 1e308 is beyond"):
        read_measured(_write(tmp_path / "q.csv", LOG.replace("0.3,6.5", "0.3,1e308")))
    with pytest.raises(MeasuredDataError, match=r"line 5, column 1: time 1e300 is more "
                                                r"than 10 years \(.*\) after the first"):
        read_measured(_write(tmp_path / "t.csv", "time_s,flow_l_min\n0,1\n1,2\n2,3\n"
                                                 "1e300,4\n"))


def test_lines_split_as_before_across_read_blocks(tmp_path, monkeypatch):
    """The block reader splits lines where str.splitlines does (CR LF, CR alone, a byte
    order mark dropped), also where a block ends inside a CR LF."""
    monkeypatch.setattr(datafile, "CHUNK_BYTES", 3)
    text = "\ufefftime_s,flow_l_min\r\n0,1\r\n1,2\r2,3\n\n3,4\r\n"
    path = tmp_path / "crlf.csv"
    path.write_bytes(text.encode())
    with datafile.DataLines(path, io.MeasuredDataError) as lines:
        assert list(lines) == text.lstrip("\ufeff").splitlines()
    run = read_measured(path)
    assert run.time_s.tolist() == [0, 1, 2, 3] and run.flow_l_min.tolist() == [1, 2, 3, 4]


# ---------------------------------------------------------------------- 3: valves not traced

def test_valves_absent_from_a_trace_are_held_at_their_initial_value(tmp_path):
    m = load_machine(PICK)
    m.consumer("Z lift").initial = "extended"
    trace = _write(tmp_path / "trace.csv", "\n".join(
        line for line in TRACE.splitlines() if ",qX," not in line and ",qZ," not in line))
    tl = read_io_timeline(trace, 10, machine=m)
    for valve, held in (("qX", 0.0), ("qZ", 1.0)):    # Z starts extended: stays so
        t, v = tl.edge_times_ns(valve)
        assert t.tolist() == [0] and v.tolist() == [held]
    assert len(tl.info["warnings"]) == 1 and tl.info["warnings"] == m.warnings[-1:]
    assert "qX (X slide)" in m.warnings[-1] and "qZ (Z lift)" in m.warnings[-1]
    models = {c.name: c for c in consumer_models(m)}
    assert len(valve_transitions(tl, models["X slide"])[0]) == 0
    assert len(valve_transitions(tl, models["Z lift"])[0]) == 0
    assert len(valve_transitions(tl, models["gripper"])[0]) == 2
    # without the machine the air model says which valve is missing, not a KeyError
    bare = read_io_timeline(trace, 10)
    with pytest.raises(DemandError, match=r"trace\.csv: no rows for the valve 'qX'"):
        valve_transitions(bare, models["X slide"])
    # a trace with none of the machine's valves is the wrong file
    inputs_only = _write(tmp_path / "inputs.csv", "time_s,signal,value\n0,xZUp,1\n")
    with pytest.raises(MeasuredDataError, match=r"inputs\.csv: records none of the valves"):
        read_io_timeline(inputs_only, 10, machine=load_machine(PICK))


def test_the_diagnose_command_reads_a_partial_trace_with_the_machine(tmp_path, monkeypatch,
                                                                     capsys):
    import plcpred.cli.diagnose as diagnose_command
    from plcpred.diagnose import DiagnosisError

    seen = {}

    def fake_diagnose(machine, runs, io=None, **kw):
        seen["io"], seen["warnings"] = io, list(machine.warnings)
        raise DiagnosisError("stopped here")

    monkeypatch.setattr(diagnose_command, "diagnose", fake_diagnose)
    log = _write(tmp_path / "run.csv", LOG)
    trace = _write(tmp_path / "trace.csv", "\n".join(
        line for line in TRACE.splitlines() if ",qX," not in line))
    assert main(["diagnose", str(PICK), "--measured", str(log), "--io", str(trace),
                 "--no-plant"]) == 2
    assert "stopped here" in capsys.readouterr().err
    assert seen["io"][0].edge_times_ns("qX")[1].tolist() == [0.0]
    assert any("no rows for the valve(s) qX (X slide)" in w for w in seen["warnings"])


# ---------------------------------------------------------------------- 4: horizons

@pytest.mark.parametrize("horizon", ["110000d", "87661h", "T#106751d", "T#213503d", 1e300,
                                     float("inf"), float("nan"), 10 ** 40])
def test_horizons_beyond_ten_years_are_refused(horizon):
    with pytest.raises(HorizonError, match="longer than 10 years|finite number"):
        parse_horizon(horizon)
    assert issubclass(HorizonError, PlcpredError) and issubclass(HorizonError, ValueError)


def test_predict_with_a_301_year_horizon_is_exit_2(tmp_path, capsys):
    assert parse_horizon("3650d") == 3650 * 86400 * NS      # ten years still run
    assert parse_horizon("87660h") == MAX_HORIZON_NS
    assert main(["predict", str(PICK), "--horizon", "110000d", "--out",
                 str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "longer than 10 years" in err and "internal error" not in err


def test_the_air_model_counts_horizons_beyond_int64_nanoseconds():
    """A timeline built by hand may hold any horizon: a repeating one is counted in exact
    integers (it overflowed int64 at 292 years), an output on at such a horizon ends
    there as a float."""
    m = load_machine(PICK)
    tl = unfold(m, "20s")
    assert tl.tiled is not None
    years = 300
    big = Timeline(tl.signals, *tl._base, years * 365 * 86400 * NS, info=tl.info,
                   tiled=tl.tiled)
    profile = demand_profile(big, consumer_models(m), 1e5)
    cycles = years * 365 * 86400 / 4.0            # a part every 4 s
    assert profile.strokes["Z lift"][0] == pytest.approx(cycles, rel=1e-6)
    vacuum = [c for c in consumer_models(m) if c.name == "vacuum"][0]
    t, s, v = tl._base
    v = np.where(s == tl.names.index("qVacuum"), 1.0, v)
    on = Timeline(tl.signals, t, s, v, big.horizon_ns, info=tl.info)
    starts, ends = passive_intervals(on, vacuum)
    assert ends[-1] == pytest.approx(big.horizon_ns)
    huge = Timeline(tl.signals, *tl._base, 10 ** 40, info=tl.info, tiled=tl.tiled)
    with pytest.raises(DemandError, match="more often than the air model counts"):
        demand_profile(huge, consumer_models(m), 1e30)


# ---------------------------------------------------------------------- 5: identify flow

def test_identify_flows_of_1e308_are_exit_2(tmp_path, capsys):
    data = _write(tmp_path / "flow.csv", "p_up_bar_g,p_down_bar_g,flow_l_min\n" + "".join(
        f"{pu},{pd},1e308\n" for pu, pd in ((6, 0), (5, 0), (4, 0), (6, 4), (6, 5), (6, 5.8))))
    assert main(["identify", "flow", str(data)]) == 2
    err = capsys.readouterr().err
    assert "flow.csv:2:3: flow_l_min: 1e308 is outside" in err


def test_identify_refuses_a_fit_no_component_has(tmp_path, capsys):
    """Flows in range but 1e6 times too large for the pressures: C = 0.0025 m^3/(s Pa),
    beyond what a machine file takes."""
    data = _write(tmp_path / "flow.csv", "p_up_bar_g,p_down_bar_g,flow_l_min\n" + "".join(
        f"{pu},{pd},{q}\n" for pu, pd, q in ((6, 0, 1e8), (5, 0, 9e7), (4, 0, 8e7),
                                             (6, 4, 7e7), (6, 5, 6e7), (6, 5.8, 2e7))))
    for method in ("improved", "iso6358"):
        assert main(["identify", "flow", str(data), "--method", method]) == 2
        err = capsys.readouterr().err
        assert "flow.csv: steady flow" in err and "is outside 1e-15 to 0.001" in err


def test_identify_tank_curves_out_of_range_are_errors(tmp_path, monkeypatch):
    t = np.linspace(0.0, 20.0, 41)
    p = 1e5 + 6e5 * np.exp(-t / 8.0)
    rows = "".join(f"{a:g},{b / 1e5:.5f}\n" for a, b in zip(t, p))
    span = _write(tmp_path / "span.csv", "time_s,p_bar\n" + "".join(
        f"{a * 1e298:g},{b / 1e5:.5f}\n" for a, b in zip(t, p)))
    with pytest.raises(IdentifyError, match=r"span\.csv:3:1: time_s: 5e\+297 is outside"):
        read_flow_data(span)
    with pytest.raises(IdentifyError, match="needs a C of .* outside"):
        identify_tank(TankData(t * 1e-300, p), 10.0)
    with pytest.raises(IdentifyError, match="volume nan l is outside"):
        identify_tank(TankData(t, p), float("nan"))
    # the tank model's steps are budgeted: an absurd curve stops with an error
    monkeypatch.setattr("plcpred.identify.MAX_TANK_EVALUATIONS", 20)
    with pytest.raises(IdentifyError, match="more than 20 steps"):
        identify_tank(read_flow_data(_write(tmp_path / "ok.csv", "time_s,p_bar\n" + rows)),
                      10.0)


# ---------------------------------------------------------------------- 6: plant budget

def test_a_stiff_line_stops_emulate_with_an_error_naming_it(tmp_path, capsys, monkeypatch):
    """A regulator of C = 1e-3 (allowed by validation) refills a 1 l line in 0.4 us: the
    solver crawled without end. A budget of evaluations per piece stops it, naming the
    line and the key to change."""
    import plcpred.physics.group as group

    monkeypatch.setattr(group, "MAX_PIECE_EVALUATIONS", 3000)
    truth = _write(tmp_path / "T.toml", '[[line]]\nname = "main"\nC = 1e-3\n\n'
                                        '[[consumer]]\nname = "Z lift"\nline = "main"\n')
    out = tmp_path / "o"
    assert main(["emulate", str(PICK), "--horizon", "1s", "--out", str(out),
                 "--truth", str(truth)]) == 2      # a truth file the plant cannot run
    err = capsys.readouterr().err
    assert 'the plant cannot integrate line "main" (drives "Z lift")' in err
    assert "more than 3,000 evaluations" in err
    assert '[[line]] "main": its regulator (C = 0.001' in err and "volume_l" in err
    assert "Traceback" not in err and not out.exists()


# ---------------------------------------------------------------------- digits and offsets

def test_a_superscript_column_number_is_a_clean_error(tmp_path, capsys):
    """'²'.isdigit() is true and int('²') fails: --time-col ² was an internal error."""
    log = _write(tmp_path / "run.csv", LOG)
    code = main(["diagnose", str(PICK), "--measured", str(log), "--time-col", "\u00b2",
                 "--no-plant"])
    err = capsys.readouterr().err
    assert code == 2 and "internal error" not in err and "\u00b2" in err, err


@pytest.mark.parametrize("digit", ["\u0663", "\u00b2", "\uff13"])
def test_non_ascii_digits_are_no_number_in_a_program(digit):
    """Arabic-Indic, superscript and full-width digits were read as numbers by the lexer
    (\\d): 'x := ٣' checked as 3."""
    from plcpred.parser import ProgramError, parse_st
    with pytest.raises(ProgramError) as e:
        parse_st(f"PROGRAM P VAR x : INT; END_VAR x := {digit}; END_PROGRAM", "p.st")
    assert e.value.line == 1


def test_a_bit_read_as_a_member_is_checked_against_its_type():
    from plcpred.parser import parse_st
    from plcpred.sequencer import CompileError, compile_program
    src = "PROGRAM P VAR b : BYTE; q : BOOL; END_VAR q := b.{bit}; END_PROGRAM"
    compile_program(parse_st(src.format(bit=7), "p.st"))
    with pytest.raises((CompileError, PlcpredError), match="bit"):
        compile_program(parse_st(src.format(bit=8), "p.st"))


def test_a_huge_max_offset_is_searched_within_the_log(tmp_path, capsys):
    """--max-offset 1e7 took 30 s and 8 GB: the search is held to the log's length."""
    import time
    log = _write(tmp_path / "run.csv", LOG)
    t0 = time.perf_counter()
    code = main(["diagnose", str(PICK), "--measured", str(log), "--max-offset", "1e7",
                 "--no-plant", "--effects", "leak"])
    err = capsys.readouterr().err
    assert code == 0, err
    assert "--max-offset 1e+07 s is longer than the log" in err
    assert time.perf_counter() - t0 < 60


def test_a_sparse_log_is_diagnosed_not_an_internal_error(tmp_path, capsys):
    """Six readings 1,000 s apart: the head of the log the timing effects align on held
    one reading, and its interval was NaN (ValueError in the alignment, exit 3)."""
    log = _write(tmp_path / "sparse.csv", "time_s,flow_l_min\n" + "".join(
        f"{t},{10 + k % 3}\n" for k, t in enumerate((53000, 54000, 55000, 57000, 58000,
                                                      59000))))
    code = main(["diagnose", str(ROOT / "samples" / "press.toml"), "--measured", str(log),
                 "--no-plant", "--effects", "valve_delay"])
    err = capsys.readouterr().err
    assert code in (0, 2) and "internal error" not in err, err
