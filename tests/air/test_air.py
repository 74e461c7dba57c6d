"""The air model against docs/reference/physics.md's equations and published figures, and hand
calculations."""
import csv
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from plcpred.air import activation_matrix, consumer_models, default_dt, demand_profile
from plcpred.air.demand import (
    ConsumerModel,
    cut_stroke_volumes_nl,
    residual_fill_nl,
    stroke_cuts,
    stroke_rectangles,
    valve_transitions,
)
from plcpred.machine import Consumer, load_machine
from plcpred.physics.flow import flow_nl_min, orifice_conductance, phi
from plcpred.physics.units import P0_PA, P_ATM_PA
from plcpred.physics.volumes import consumer_stroke_volumes_nl
from plcpred.sequencer.timeline import Signal, Timeline

SAMPLES = Path(__file__).resolve().parents[2] / "samples"
RIG = SAMPLES / "prototype_rig" / "rig.toml"
S = 10**9


# ---------------------------------------------------------------------- passive (D2, D3)

def passive_total(pressure_bar_abs, model):
    m = load_machine(RIG)
    knives, leak = m.consumer("air knives"), m.consumer("pilot leak")
    return sum(flow_nl_min(c.C, c.b, c.m, c.a, pressure_bar_abs * 1e5, P_ATM_PA,
                           flow_model=model) for c in (knives, leak))


@pytest.mark.parametrize("bar_abs,published", [(2.5, 104), (3.5, 145), (5.0, 207)])
def test_passive_linear_row_of_the_published_table(bar_abs, published):
    # the knives' C (docs/reference/physics.md table) plus the rig's leak, always choked
    assert passive_total(bar_abs, "choked") == pytest.approx(published, rel=0.01)


def test_full_model_lowers_the_flow_more_as_pressure_falls():
    corr = {p: passive_total(p, "iso6358") / passive_total(p, "choked") - 1
            for p in (2.5, 3.5, 5.0)}
    assert corr[2.5] < corr[3.5] < corr[5.0] <= 0
    # size: about 3.5 % at 2.5 bar (r = 0.405 against b = 0.22 for the knives), under 1 %
    # from 3.5 bar; the measured 91 NL/min at 2.5 bar is nearer the full model
    assert -0.06 < corr[2.5] < -0.02 and corr[3.5] > -0.01
    assert abs(passive_total(2.5, "iso6358") - 91) < abs(passive_total(2.5, "choked") - 91)


def test_phi_branches():
    assert phi(0.2, b=0.3) == 1.0
    assert phi(1.0, b=0.3) == 0.0
    r, b, m = 0.65, 0.3, 0.5
    assert phi(r, b, m) == pytest.approx(math.sqrt(1 - ((r - b) / (1 - b)) ** 2))
    assert phi(0.9, b=0.3, m=0.5, a=0.85) == 0.0           # cracking ratio closes it


def test_orifice_conductance_by_hand():
    # C = Cd * A * sqrt(gamma/R * (2/(gamma+1))^((gamma+1)/(gamma-1))) / (rho0 sqrt(T0))
    k = math.sqrt(1.4 / 287.05 * (2 / 2.4) ** 6)
    area = math.pi * 0.001 ** 2 / 4
    assert orifice_conductance(1.0, 0.8) == pytest.approx(0.8 * area * k / (1.185 * math.sqrt(293.15)))
    # a 1 mm nozzle at 6 bar(g): about 53 NL/min, the catalogue order of magnitude
    q = flow_nl_min(orifice_conductance(1.0, 0.8), 0.528, 0.5, 1.0, 7.01325e5, P_ATM_PA)
    assert 45 < q < 60


# ---------------------------------------------------------------------- active (D1)

def cyl(kind, bore=32.0, rod=12.0, stroke=100.0, tube=(2.0, 1.0), tube_id=4.0):
    return Consumer("c", kind, valve=["y"], bore_mm=bore, rod_mm=rod, stroke_mm=stroke,
                    tube_id_mm=tube_id, tube_length_m=tube)


P_S = 7.0e5            # 7 bar absolute
RATIO = P_S / P0_PA    # at the reference temperature


@pytest.mark.parametrize("kind,ext_area,ret_area", [
    ("double_acting", math.pi * 32**2 / 4, math.pi * (32**2 - 12**2) / 4),
    ("single_acting", math.pi * 32**2 / 4, None),
    ("double_rod", math.pi * (32**2 - 12**2) / 4, math.pi * (32**2 - 12**2) / 4),
    ("rodless", math.pi * 32**2 / 4, math.pi * 32**2 / 4),
    ("semi_rotary", math.pi * 32**2 / 4, math.pi * 32**2 / 4),
    ("gripper", math.pi * 32**2 / 4, math.pi * 32**2 / 4),
])
def test_stroke_volumes_by_hand_for_every_kind(kind, ext_area, ret_area):
    c = cyl(kind, rod=12.0 if kind in ("double_acting", "single_acting", "double_rod") else 0)
    tube_cap = 2000 * math.pi * 4**2 / 4          # mm^3
    tube_rod = 1000 * math.pi * 4**2 / 4
    v_ext, v_ret = consumer_stroke_volumes_nl(c, P_S)
    assert v_ext == pytest.approx((ext_area * 100 + tube_cap) * 1e-6 * RATIO)
    if ret_area is None:
        assert v_ret == 0.0
    else:
        assert v_ret == pytest.approx((ret_area * 100 + tube_rod) * 1e-6 * RATIO)


def test_supply_temperature_scales_the_reference_volume():
    c = cyl("rodless", rod=0)
    warm = consumer_stroke_volumes_nl(c, P_S, 313.15)[0]
    assert warm == pytest.approx(consumer_stroke_volumes_nl(c, P_S)[0] * 293.15 / 313.15)


@pytest.mark.parametrize("name,extend,retract", [("A", 0.176, 0.185), ("B", 0.226, 0.218),
                                                 ("C", 0.128, 0.114)])
def test_rig_strokes_reproduce_the_published_table(name, extend, retract):
    # the thesis' litres are free air at P_atm: ours * P0/P_atm; tube lengths in rig.toml
    # give the dead volumes the table implies; rounding of the table is 0.0005 L
    m = load_machine(RIG)
    model = next(x for x in consumer_models(m) if x.name == name)
    assert model.extend_nl * P0_PA / P_ATM_PA == pytest.approx(extend, abs=0.002)
    assert model.retract_nl * P0_PA / P_ATM_PA == pytest.approx(retract, abs=0.002)


def test_air_factor_calibrates_each_fill_of_one_drive():
    from plcpred.machine import MachineError, machine_from_data, read_machine_data
    data = read_machine_data(RIG)
    nominal = {x.name: x for x in consumer_models(machine_from_data(data, RIG))}
    drive = next(c for c in data["consumer"] if c["name"] == "A")
    drive["air_factor"] = [0.9, 1.1]
    calibrated = {x.name: x for x in consumer_models(machine_from_data(data, RIG))}
    assert calibrated["A"].extend_nl == pytest.approx(0.9 * nominal["A"].extend_nl, rel=1e-12)
    assert calibrated["A"].retract_nl == pytest.approx(1.1 * nominal["A"].retract_nl,
                                                       rel=1e-12)
    assert calibrated["B"].extend_nl == nominal["B"].extend_nl
    drive["air_factor"] = -1.0
    with pytest.raises(MachineError, match="air_factor"):
        machine_from_data(data, RIG)


def rig_total_without_leak(machine_file, horizon, choked=True):
    from plcpred import predict
    m = load_machine(SAMPLES / "prototype_rig" / machine_file)
    m.consumers = [c for c in m.consumers if c.kind != "leak"]
    if choked:
        for c in m.consumers:
            c.flow_model = "choked"
    return predict(m, horizon).profile.total_nl


def test_rig_sequence_1_matches_the_published_simplified_total():
    # 13.13 L (docs/reference/physics.md: figures). The knives' blow time is not published; the sample
    # uses the 3.7 s that makes this hold, so this checks consistency of the cylinder
    # volumes and the knife flow rather than validating them independently.
    assert rig_total_without_leak("rig.toml", "20s") == pytest.approx(13.13, rel=0.02)


def test_rig_sequence_2_is_near_the_published_simplified_total():
    # 41.98 L: A 30 cycles, B once, C 50 cycles, knives 10 s at 2 bar(g). Ours is 2-4 %
    # higher: our litres are at P0 = 100 kPa (the thesis' at P_atm, 1.3 %), B's retract at
    # the end of the run is counted, and the knives' actual pressure is not published.
    total = rig_total_without_leak("rig_seq2.toml", "62s")
    assert total == pytest.approx(41.98, rel=0.04)
    assert total > 41.98


# ---------------------------------------------------------------------- edge rules

def timeline(signals: dict, horizon_s=10.0):
    """Signals as {name: [(time_s, value), ...]} (the first entry at 0)."""
    names = list(signals)
    rows = sorted((round(t * S), k, v) for k, n in enumerate(names) for t, v in signals[n])
    return Timeline([Signal(n, "output", "bool") for n in names], [r[0] for r in rows],
                    [r[1] for r in rows], [r[2] for r in rows], round(horizon_s * S))


def model(valve, **kw):
    kw.setdefault("extend_nl", 1.0)
    kw.setdefault("retract_nl", 0.5)
    return ConsumerModel("c", kw.pop("kind", "double_acting"), valve, "active", **kw)


def test_monostable_rising_fills_cap_falling_fills_rod():
    tl = timeline({"y": [(0, 0), (1, 1), (2, 0), (3, 1), (4, 0)]})
    prof = demand_profile(tl, [model(["y"])], 0.01)
    assert prof.strokes["c"] == (2, 2)
    assert prof.total_nl == pytest.approx(2 * 1.0 + 2 * 0.5)


def test_single_acting_fills_on_rising_only():
    tl = timeline({"y": [(0, 0), (1, 1), (2, 0), (3, 1), (4, 0)]})
    m = model(["y"], kind="single_acting", retract_nl=0.0)
    assert demand_profile(tl, [m], 0.01).total_nl == pytest.approx(2 * 1.0)


def test_bistable_last_pulse_decides_and_repeats_cost_nothing():
    tl = timeline({"ext": [(0, 0), (1, 1), (1.1, 0), (2, 1), (2.1, 0), (5, 1), (5.1, 0)],
                   "ret": [(0, 0), (3, 1), (3.1, 0), (4, 1), (4.1, 0), (5, 1), (5.1, 0)]})
    t, ext = valve_transitions(tl, model(["ext", "ret"]), {})
    # extend at 1 (2 repeats it), retract at 3 (4 repeats it), both at 5: no change
    assert (t / S).tolist() == [1.0, 3.0] and ext.tolist() == [True, False]
    assert demand_profile(tl, [model(["ext", "ret"])], 0.01).total_nl == pytest.approx(1.5)


def test_initially_extended_cylinder_retracting_at_start_costs_a_retract():
    tl = timeline({"y": [(0, 0), (2, 1)]})
    t, ext = valve_transitions(tl, model(["y"], initial_extended=True), {})
    assert (t / S).tolist() == [0.0, 2.0] and ext.tolist() == [False, True]


def test_each_edge_total_is_exact_whatever_the_grid_and_flows_after_the_delay():
    tl = timeline({"y": [(0, 0), (1.003, 1), (2.5, 0)], "n": [(0, 0), (0.25, 1), (3.333, 0)]})
    ms = [model(["y"], delay_s=0.02, stroke_time_s=(0.3, 0.2)),
          ConsumerModel("n", "nozzle", ["n"], "passive", flow_l_min=60.0)]
    totals = [demand_profile(tl, ms, dt).consumer_nl for dt in (0.001, 0.01, 0.37, 1.0, 7.0)]
    for tot in totals:
        assert tot == pytest.approx([1.5, 3.083], rel=1e-9)
    prof = demand_profile(tl, ms, 0.001)
    flow = prof.flow_l_min[0]
    on = np.nonzero(flow > 1e-9)[0] * 0.001
    # extend: 1.0 NL over 0.3 s from 1.003 + 0.02 s; retract 0.5 NL over 0.2 s from 2.52 s
    assert on.min() == pytest.approx(1.023, abs=0.0011) and on.max() == pytest.approx(2.72, abs=0.0011)
    assert flow[1100] == pytest.approx(1.0 / 0.3 * 60)
    assert flow[1010:1022].max() == 0.0         # the valve has not opened yet


def test_matrix_form_equals_the_exact_profile_on_a_fine_grid():
    m = load_machine(RIG)
    from plcpred import unfold
    tl = unfold(m, "20s")
    models = consumer_models(m)
    dt = 0.01
    A, Zx, Zr = activation_matrix(tl, models, dt)
    q_ext = np.array([x.extend_nl for x in models])
    q_ret = np.array([x.retract_nl for x in models])
    qdot = np.array([x.flow_l_min / 60 for x in models])
    active = (Zx.T @ q_ext + Zr.T @ q_ret).sum()
    passive = (A.T @ qdot).sum() * dt
    prof = demand_profile(tl, models, dt)
    assert active == pytest.approx(prof.by_role_nl()["active"], rel=1e-9)
    assert passive == pytest.approx(prof.by_role_nl()["passive"] + prof.by_role_nl()["leak"],
                                    rel=1e-3)


def test_default_grid_coarsens_for_long_horizons():
    assert default_dt(60) == 0.01
    for h in (3600, 8 * 3600, 86400, 7 * 86400):
        dt = default_dt(h)
        assert h / dt <= 400_000 and dt >= 0.01
    assert default_dt(86400) == 0.5


# ---------------------------------------------------------------------- predict end to end

def test_predict_files_integrate_to_the_summary(tmp_path):
    out = tmp_path / "o"
    r = subprocess.run([sys.executable, "-m", "plcpred.cli", "predict", str(RIG),
                        "--horizon", "30s", "--out", str(out), "--dt", "50ms"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "air knives" in r.stdout and "mean" in r.stdout and "peak" in r.stdout
    summary = json.loads((out / "summary.json").read_text())
    with open(out / "demand.csv", newline="") as f:
        rows = list(csv.reader(f))
    header, body = rows[0], np.array(rows[1:], dtype=float)
    assert header[:2] == ["time_s", "total_l_min"] and header[2] == "A_l_min"
    dt = body[1, 0] - body[0, 0]
    assert dt == pytest.approx(0.05)
    assert (body[:, 1] * dt / 60).sum() == pytest.approx(summary["total_nl"], rel=1e-6)
    assert body[:, 2:].sum(axis=1) == pytest.approx(body[:, 1])
    for key in ("total_nl", "mean_l_min", "peak_l_min", "horizon_s"):
        assert key in summary
    parts = summary["consumers"]
    assert sum(c["total_nl"] for c in parts.values()) == pytest.approx(summary["total_nl"])
    assert parts["A"]["active_nl"] > 0 and parts["A"]["passive_nl"] == 0
    assert (out / "demand.png").stat().st_size > 10_000
    assert (out / "timeline.csv").is_file()


def test_predict_rejects_a_bad_dt(tmp_path):
    r = subprocess.run([sys.executable, "-m", "plcpred.cli", "predict", str(RIG),
                        "--horizon", "30s", "--out", str(tmp_path), "--dt", "fast"],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "Traceback" not in r.stderr


def test_predict_says_when_the_instantaneous_peak_leaves_steps_out(tmp_path, capsys):
    """A stroke with no stroke_time_s and no switching delay is a step (a volume with no
    rate): the instantaneous peak cannot count it, and the printout says so."""
    from plcpred.cli import main
    (tmp_path / "p.st").write_text("PROGRAM P\nVAR go AT %IX0.0 : BOOL; v AT %QX0.0 : BOOL;"
                                   " END_VAR\nv := go;\nEND_PROGRAM\n")
    machine = tmp_path / "m.toml"
    machine.write_text('[machine]\nname = "m"\nprogram = "p.st"\nscan_ms = 10\n'
                       'supply_bar_g = 6\n[[input]]\nsignal = "go"\nperiod_s = 2\n'
                       'pulse_ms = 500\n[[consumer]]\nname = "stamp"\n'
                       'kind = "single_acting"\nbore_mm = 32\nstroke_mm = 50\nvalve = "v"\n')
    assert main(["predict", str(machine), "--horizon", "10s", "--out", str(tmp_path / "o"),
                 "--no-plot"]) == 0
    assert "(instantaneous, strokes without stroke_time_s left out)" in capsys.readouterr().out
    assert main(["predict", str(RIG), "--horizon", "10s", "--out", str(tmp_path / "r"),
                 "--no-plot"]) == 0
    out = capsys.readouterr().out
    assert "(instantaneous)" in out and "left out" not in out


def test_cut_strokes_by_hand():
    # delay 0.01 s, strokes 0.2 / 0.3 s, tau 0.1 s; D1 5.0 / 4.0 NL of which the swept
    # volumes are 4.0 / 3.0 (holding 3.4 / 2.6 above atmosphere), dead volumes hold 2.0 / 3.0
    t = np.array([0.0, 0.3, 0.36, 1.0])
    ext = np.array([True, False, True, False])
    args = (t, ext, 5.0, 4.0, 0.01, (0.2, 0.3), 0.1, (2.0, 3.0), (4.0, 3.0), (3.4, 2.6),
            True)
    assert stroke_cuts(t, ext, 0.01, (0.2, 0.3)).tolist() == [False, True, False, False]
    start, dur, vol = stroke_rectangles(*args)
    # the retract at 0.3 moves from 0.31 until the extend's valve opens at 0.37: a fifth
    # of its stroke, into a rod chamber exhausting since 0.21
    retract = 4.0 - 3.0 * 0.8 - 3.0 * math.exp(-0.09 / 0.1)
    # the extend at 0.36 finds the cap chamber still full (its exhaust had not ended):
    # its dead volume and the 80 % of swept volume the piston left open
    extend = 5.0 - (2.0 + 3.4 * 0.8)
    assert vol.tolist() == pytest.approx([5.0, retract, extend,
                                          4.0 - 3.0 * math.exp(-0.59 / 0.1)])
    assert dur.tolist() == pytest.approx([0.2, 0.06, 0.04, 0.3])
    assert start.tolist() == pytest.approx((t + 0.01).tolist())
    # without the option the transition rule books full strokes (D1), less the exhaust's
    # residual when that option is on
    _, _, d1 = stroke_rectangles(t, ext, 5.0, 4.0, 0.01, (0.2, 0.3), None, (2.0, 3.0),
                                 (4.0, 3.0), (3.4, 2.6))
    assert d1.tolist() == [5.0, 4.0, 5.0, 4.0]
    _, _, residual = stroke_rectangles(*args[:-1])
    assert residual.tolist() == pytest.approx(
        (d1 - residual_fill_nl(t, ext, 0.01, (0.2, 0.3), 0.1, (2.0, 3.0))).tolist())
    # strokes cut short without an exhaust option: every exhaust complete at once, so
    # only the retract the extend cut short takes less
    _, _, cut = stroke_rectangles(t, ext, 5.0, 4.0, 0.01, (0.2, 0.3), None, (2.0, 3.0),
                                  (4.0, 3.0), (3.4, 2.6), True)
    assert cut.tolist() == pytest.approx([5.0, 4.0 - 3.0 * 0.8, 5.0, 4.0])


def test_cut_strokes_agree_with_residual_when_none_is_cut():
    t = np.array([0.0, 1.0, 1.5, 3.0])
    ext = np.array([True, False, True, False])
    vol, dur = cut_stroke_volumes_nl(t, ext, 5.0, 4.0, 0.01, (0.2, 0.3), 0.1, (2.0, 3.0),
                                     (4.0, 3.0), (3.4, 2.6))
    saved = residual_fill_nl(t, ext, 0.01, (0.2, 0.3), 0.1, (2.0, 3.0))
    assert vol.tolist() == pytest.approx((np.array([5.0, 4.0, 5.0, 4.0]) - saved).tolist())
    assert dur.tolist() == pytest.approx([0.2, 0.3, 0.2, 0.3])


def test_a_pulse_shorter_than_the_stroke_with_partial_strokes(tmp_path):
    """A 50 ms pulse on a 0.2 s stroke: with ``partial_strokes`` the extend opens a
    quarter of the cap chamber's swept volume (after the 10 ms switching delay until the
    retract's valve opens 50 ms later); every exhaust completes at once without
    ``exhaust_tau_s``, so the retract refills the rod chamber whole (D1b)."""
    from plcpred import predict
    (tmp_path / "p.st").write_text(
        "PROGRAM P\nVAR go AT %IX0.0 : BOOL; v AT %QX0.0 : BOOL; t : TP; END_VAR\n"
        "t(IN := go, PT := T#50ms);\nv := t.Q;\nEND_PROGRAM\n")
    text = ('[machine]\nname = "m"\nprogram = "p.st"\nscan_ms = 5\nsupply_bar_g = 6\n'
            '[[input]]\nsignal = "go"\nperiod_s = 1\npulse_ms = 200\n[[consumer]]\n'
            'name = "cyl"\nkind = "double_acting"\nbore_mm = 20\nrod_mm = 8\n'
            'stroke_mm = 50\ntube_id_mm = 4\ntube_length_m = 0.5\nvalve = "v"\n'
            'stroke_time_s = [0.2, 0.2]\nswitch_delay_s = 0.01\n')
    (tmp_path / "d1.toml").write_text(text)
    (tmp_path / "cut.toml").write_text(text + "partial_strokes = true\n")
    full = predict(tmp_path / "d1.toml", "10s", dt=0.01)
    cut = predict(tmp_path / "cut.toml", "10s", dt=0.01)
    model = cut.models[0]
    # D1 at ISO 8778 (100 kPa, 20 degC) with the supply at the 20 degC default: P_s/P0
    d1_per_litre = (6e5 + P_ATM_PA) / P0_PA
    swept_cap_nl = math.pi / 4 * 20 ** 2 * 50 * 1e-6 * d1_per_litre
    assert model.swept_nl[0] == pytest.approx(swept_cap_nl, rel=1e-9)
    assert model.swept_nl[1] == pytest.approx(swept_cap_nl * (1 - 8 ** 2 / 20 ** 2), rel=1e-9)
    n = full.timeline.count_rising("v")
    assert n == 10
    assert full.profile.consumer_nl[0] == pytest.approx(
        n * (model.extend_nl + model.retract_nl), rel=1e-9)
    assert cut.profile.consumer_nl[0] == pytest.approx(
        n * (model.extend_nl - 0.75 * swept_cap_nl + model.retract_nl), rel=1e-6)


def test_strokes_cut_short_are_counted_and_predict_warns(tmp_path, capsys):
    """The sorter's pusher chatters: counted over a tiled minute as over every edge, and
    ``predict`` says that D1 books them in full (not once the drive has the option)."""
    from plcpred import predict
    from plcpred.cli import main
    res = predict(SAMPLES / "sorter.toml", "60s", dt=0.01)
    model = res.models[res.profile.names.index("pusher")]
    t_ns, ext = valve_transitions(res.timeline, model)
    every = int(stroke_cuts(t_ns / 1e9, ext, model.delay_s, model.stroke_time_s).sum())
    assert res.timeline.tiled is not None and every > 20
    assert res.profile.cut_strokes["pusher"] == every
    assert main(["predict", str(SAMPLES / "sorter.toml"), "--horizon", "60s", "--out",
                 str(tmp_path / "o"), "--no-plot"]) == 0
    err = capsys.readouterr().err
    assert f'consumer "pusher": {every} of its' in err and "partial_strokes" in err
    text = (SAMPLES / "sorter.toml").read_text().replace(
        "switch_delay_s = 0.015\n", "switch_delay_s = 0.015\npartial_strokes = true\n", 1)
    (tmp_path / "sorter.toml").write_text(text.replace(
        'program = "openplc_sorter.st"', f'program = "{SAMPLES / "openplc_sorter.st"}"'))
    assert main(["predict", str(tmp_path / "sorter.toml"), "--horizon", "60s", "--out",
                 str(tmp_path / "p"), "--no-plot"]) == 0
    assert "cut short" not in capsys.readouterr().err


MACHINES = sorted(SAMPLES.glob("*.toml")) + sorted((SAMPLES / "prototype_rig").glob("*.toml"))


@pytest.mark.parametrize("path", MACHINES, ids=lambda p: p.stem)
def test_every_sample_predicts_hand_totals_from_its_strokes_and_on_times(path):
    from plcpred import predict
    res = predict(path, "2m", dt=0.05)
    prof, tl = res.profile, res.timeline
    names = tl.info["machine_signals"]
    expected = 0.0
    for m in res.models:
        if m.role == "leak":
            expected += m.flow_l_min * 120 / 60
        elif m.role == "passive":
            expected += m.flow_l_min / 60 * tl.on_time_s(names[m.valve[0]])
        elif len(m.valve) == 1:
            # monostable: one extend per rising edge, one retract per falling edge, less
            # any stroke still flowing at the horizon
            n_up = tl.count_rising(names[m.valve[0]])
            t, v = tl.edge_times_ns(names[m.valve[0]])
            n_down = int(np.count_nonzero((v[1:] == 0) & (v[:-1] != 0)))
            n_down += int(m.initial_extended and v[0] == 0)
            expected += n_up * m.extend_nl + n_down * m.retract_nl
    tail = 0.0
    for m in res.models:    # strokes cut off by the horizon
        if m.role == "active" and m.stroke_time_s:
            t, ext = valve_transitions(tl, m, names)
            dur = np.where(ext, m.stroke_time_s[0], m.stroke_time_s[1])
            start = t / S + m.delay_s
            vol = np.where(ext, m.extend_nl, m.retract_nl)
            late = (start + dur) > 120
            tail += float((vol[late] * np.clip((start[late] + dur[late] - 120) / dur[late], 0, 1)).sum())
    assert prof.total_nl == pytest.approx(expected - tail, rel=1e-9)
    assert prof.total_nl > 0


def test_cell_volumes_equal_the_differences_of_the_exact_cumulative():
    # the linear-time placement onto the grid against the exact cumulative volume, for
    # rectangles and steps anywhere: inside cells, on edges, past the horizon
    from plcpred.air.demand import rectangles_cell_nl, rectangles_cumulative_nl, grid_edges_s

    rng = np.random.default_rng(0)
    for _ in range(200):
        horizon = rng.uniform(1, 100)
        edges = grid_edges_s(horizon, rng.choice([0.001, 0.01, 0.37, 1.0, 7.0]))
        n = int(rng.integers(0, 60))
        start = rng.uniform(0, horizon * 1.1, n)
        start[: n // 3] = edges[rng.integers(0, len(edges), n // 3)]
        dur = np.where(rng.random(n) < 0.3, 0.0, rng.uniform(0, 5, n))
        amount = rng.uniform(0, 3, n)
        # (assert_allclose: pytest.approx compares element by element in Python)
        np.testing.assert_allclose(
            rectangles_cell_nl(edges, start, dur, amount),
            np.diff(rectangles_cumulative_nl(edges, start, dur, amount)), rtol=1e-9, atol=1e-9)


def test_demand_to_frame_has_the_grid_and_a_column_per_consumer():
    from plcpred import predict

    p = predict(SAMPLES / "pick_place.toml", "20s", dt=0.05)
    frame = p.profile.to_frame()
    assert frame.index.name == "time_s" and len(frame) == p.profile.n_cells == 400
    assert frame.index[1] == pytest.approx(0.05)
    assert frame.columns.tolist() == ["total_l_min", "Z_lift_l_min", "X_slide_l_min",
                                      "gripper_l_min", "vacuum_l_min", "fittings_leak_l_min"]
    # the columns are NL/min per cell: their mean over the horizon is the mean flow, the
    # consumers add up to the total, and a leak flows all the time
    assert frame["total_l_min"].mean() == pytest.approx(p.profile.mean_l_min, rel=1e-9)
    assert np.allclose(frame.iloc[:, 1:].sum(axis=1), frame["total_l_min"])
    assert (frame["X_slide_l_min"].mean() * 20 / 60) == pytest.approx(
        p.profile.consumer_nl[1], rel=1e-9)
    assert frame["fittings_leak_l_min"].min() > 0
    assert p.profile.to_frame(consumers=False).columns.tolist() == ["total_l_min"]


def test_demand_to_frame_names_columns_as_demand_csv_does(tmp_path):
    from plcpred import predict

    p = predict(SAMPLES / "pick_place.toml", "8s", dt=0.1)
    p.profile.names[:2] = ["a, b", "a; b"]          # the same once cleaned
    assert p.profile.to_frame().columns[1:3].tolist() == ["a__b_l_min", "a__b__l_min"]
