"""plcpred identify flow: ISO 6358 parameters from steady-flow points and tank curves.

Synthetic data are written from D2 by hand here; the thesis' knife circuit is recovered
from data the physics plant generates (its own flow code, with its laminar tail, and an
isothermal tank emptied through the circuit)."""
import json
from pathlib import Path

import numpy as np
import pytest

from plcpred.cli import main
from plcpred.identify import (
    FlowData,
    IdentifyError,
    TankData,
    identify_steady,
    identify_tank,
    read_flow_data,
)
from plcpred.machine import Consumer, load_machine
from plcpred.physics import chamber as physics
from plcpred.physics.drive import drive_params
from plcpred.physics.group import Group, Supply

ROOT = Path(__file__).resolve().parent.parent
RIG = ROOT / "samples" / "prototype_rig" / "rig.toml"
ATM = 101_325.0
KNIVES = (6.56e-9, 0.22, 0.55)      # docs/reference/physics.md: figures, two air knives on one valve


def hand_flow_l_min(C, b, m, p_up, p_down):
    r = p_down / p_up
    phi = np.where(r <= b, 1.0, (1.0 - ((r - b) / (1.0 - b)) ** 2) ** m)
    return C * p_up * phi * 60_000.0


def bench_points():
    """An ISO 6358-style bench: the upstream pressure ramped against atmosphere, then the
    downstream pressure ramped at 6 bar gauge upstream."""
    p_up = np.concatenate([np.linspace(1.3e5, 8e5, 40), np.full(60, 6e5 + ATM)])
    p_down = np.concatenate([np.full(40, ATM), np.linspace(ATM, 5.95e5, 60)])
    return p_up, p_down


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_improved_method_recovers_c_b_m_within_3_percent(seed):
    C, b, m = 1.2e-8, 0.3, 0.62
    p_up, p_down = bench_points()
    rng = np.random.default_rng(seed)
    q = hand_flow_l_min(C, b, m, p_up, p_down) * (1 + 0.003 * rng.standard_normal(100))
    fit = identify_steady(FlowData(p_up, p_down, q, np.full(100, 293.15)))
    assert fit.C == pytest.approx(C, rel=0.03)
    assert fit.b == pytest.approx(b, rel=0.03)
    assert fit.m == pytest.approx(m, rel=0.03)
    # the intervals are honest: the truth lies within about 3 half-widths
    for name, true in (("C", C), ("b", b), ("m", m)):
        assert abs(getattr(fit, name) - true) < 3 * fit.ci[name]


def test_iso6358_method_fixes_m_and_finds_b():
    C, b = 8e-9, 0.35
    p_up, p_down = bench_points()
    rng = np.random.default_rng(5)
    q = hand_flow_l_min(C, b, 0.5, p_up, p_down) * (1 + 0.003 * rng.standard_normal(100))
    fit = identify_steady(FlowData(p_up, p_down, q, np.full(100, 293.15)), "iso6358")
    assert fit.m == 0.5 and "m" not in fit.ci
    assert fit.C == pytest.approx(C, rel=0.03)
    assert fit.b == pytest.approx(b, rel=0.03)


def test_knife_circuit_from_plant_flows():
    p_up, p_down = bench_points()
    rng = np.random.default_rng(7)
    q = np.array([physics.signed_mass_flow_kg_s(*KNIVES, pu, 293.15, pd, 293.15)
                  for pu, pd in zip(p_up, p_down)]) / 1.185 * 60_000.0
    q *= 1 + 0.003 * rng.standard_normal(len(q))
    fit = identify_steady(FlowData(p_up, p_down, q, np.full(len(q), 293.15)))
    for got, true in zip((fit.C, fit.b, fit.m), KNIVES):
        assert got == pytest.approx(true, rel=0.03)


def test_knife_circuit_from_a_plant_tank_discharge():
    """A 2 L isothermal tank (copper wool: a very high wall heat transfer) charged to 6 bar
    gauge, then emptied through the knife circuit; the pressure curve alone gives C, b,
    m."""
    tank = Consumer("tank", "single_acting", valve=["y"], bore_mm=20, rod_mm=0,
                    stroke_mm=1, stroke_time_s=(1.0, 1.0),
                    plant={"dead_volume_cm3": (2000.0, 2000.0), "friction_static_n": 1e5,
                           "friction_coulomb_n": 1e5, "exhaust_C": (KNIVES[0],) * 2,
                           "exhaust_b": (KNIVES[1],) * 2, "exhaust_m": (KNIVES[2],) * 2,
                           "heat_transfer_w_m2k": 1e5})
    g = Group([drive_params(tank)], Supply(6e5 + ATM, 293.15), cache={})
    g.command_valve(0.0, 0, True)
    g.advance(30.0)
    g.command_valve(30.0, 0, False)
    g.advance(45.0)
    t = np.linspace(30.0, 42.0, 121)
    p = g.state_at(t)[:, 0]
    fit = identify_tank(TankData(t - 30.0, p), 2.0)
    for got, true in zip((fit.C, fit.b, fit.m), KNIVES):
        assert got == pytest.approx(true, rel=0.03)


def _write_bench_csv(path, gauge=True):
    p_up, p_down = bench_points()
    rng = np.random.default_rng(3)
    q = hand_flow_l_min(*KNIVES, p_up, p_down) * (1 + 0.003 * rng.standard_normal(100))
    with open(path, "w") as f:
        f.write("p_up_bar_g,p_down_bar_g,flow_l_min\n" if gauge else
                "p_up_bar,p_down_bar,flow_l_min\n")
        for pu, pd, qq in zip(p_up, p_down, q):
            off = ATM if gauge else 0.0
            f.write(f"{(pu - off) / 1e5:.5f},{(pd - off) / 1e5:.5f},{qq:.4f}\n")


def test_read_flow_data_units_and_errors(tmp_path):
    _write_bench_csv(tmp_path / "g.csv")
    _write_bench_csv(tmp_path / "a.csv", gauge=False)
    g, a = read_flow_data(tmp_path / "g.csv"), read_flow_data(tmp_path / "a.csv")
    assert np.allclose(g.p_up_pa, a.p_up_pa, rtol=1e-5)
    bad = tmp_path / "bad.csv"
    bad.write_text("p_up_bar_g,flow_l_min\n5,100\n5,x\n")
    with pytest.raises(IdentifyError, match=r"bad\.csv:3:2: flow_l_min: not a number"):
        read_flow_data(bad)
    bad.write_text("a,b\n1,2\n")
    with pytest.raises(IdentifyError, match="expected steady-flow data"):
        read_flow_data(bad)


def test_identify_command_prints_plots_and_writes_the_machine(tmp_path, capsys):
    data = tmp_path / "knives.csv"
    _write_bench_csv(data)
    out = tmp_path / "rig_fixed.toml"
    code = main(["identify", "flow", str(data), "--plot", str(tmp_path / "fit.png"),
                 "--json", str(tmp_path / "fit.json"), "--machine", str(RIG),
                 "--consumer", "air knives", "--write-machine", str(out)])
    assert code == 0
    text = capsys.readouterr().out
    assert "95 % interval" in text and "C " in text
    assert (tmp_path / "fit.png").stat().st_size > 1000
    fit = json.loads((tmp_path / "fit.json").read_text())
    assert fit["C"] == pytest.approx(KNIVES[0], rel=0.03)
    knives = load_machine(out).consumer("air knives")
    assert knives.C == pytest.approx(fit["C"], rel=1e-3)
    assert knives.b == pytest.approx(fit["b"], abs=1e-4)


def test_identify_command_errors(tmp_path, capsys):
    tank = tmp_path / "tank.csv"
    tank.write_text("time_s,p_bar_g\n" + "".join(f"{i},{6 - i * 0.5}\n" for i in range(8)))
    assert main(["identify", "flow", str(tank)]) == 2
    assert "--volume-l" in capsys.readouterr().err
    data = tmp_path / "k.csv"
    _write_bench_csv(data)
    assert main(["identify", "flow", str(data), "--machine", str(RIG), "--consumer", "A",
                 "--write-machine", str(tmp_path / "x.toml")]) == 2
    assert "no nozzle or leak named 'A'" in capsys.readouterr().err
    assert not (tmp_path / "x.toml").exists()
