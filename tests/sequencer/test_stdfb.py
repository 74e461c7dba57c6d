"""Standard function blocks against the IEC 61131-3 timing diagrams (times in ms here)."""
import pytest

from plcpred.sequencer.stdfb import (CTD, CTU, CTUD, F_TRIG, R_TRIG, RS, SR, TOF, TON, TONR,
                                     TP, make_standard_fb)

MS = 10**6


def run(fb, steps, outputs=("Q", "ET")):
    """steps: (t_ms, {input: value}); returns the outputs after each call, ET in ms."""
    out = []
    for t, inputs in steps:
        for k, v in inputs.items():
            setattr(fb, k, v * MS if k == "PT" else v)
        fb.execute(t * MS)
        out.append(tuple(getattr(fb, o) / MS if o == "ET" else getattr(fb, o) for o in outputs))
    return out


def test_ton_delays_rising_edge_and_resets_with_in():
    fb = TON()
    got = run(fb, [(0, {"IN": True, "PT": 100}), (50, {}), (99, {}), (100, {}), (180, {}),
                   (200, {"IN": False}), (300, {"IN": True}), (350, {"IN": False}), (460, {})])
    assert got == [(False, 0), (False, 50), (False, 99), (True, 100), (True, 100),
                   (False, 0), (False, 0), (False, 0), (False, 0)]


def test_ton_next_event_and_pt_change_while_running():
    fb = TON()
    run(fb, [(10, {"IN": True, "PT": 100})])
    assert fb.next_event_ns() == 110 * MS
    assert run(fb, [(40, {"PT": 20})]) == [(True, 20)]  # the new PT is already passed
    assert fb.next_event_ns() is None


def test_ton_inputs_are_retained_between_calls():
    fb = TON()
    run(fb, [(0, {"IN": True, "PT": 50})])
    assert run(fb, [(60, {})]) == [(True, 50)]  # IN and PT still set from the first call


def test_tof_holds_q_after_falling_edge_and_retriggers():
    fb = TOF()
    got = run(fb, [(0, {"IN": False, "PT": 100}), (10, {"IN": True}), (100, {"IN": False}),
                   (150, {}), (160, {"IN": True}), (200, {"IN": False}), (299, {}), (300, {}),
                   (400, {})])
    assert got == [(False, 0), (True, 0), (True, 0), (True, 50), (True, 0), (True, 0),
                   (True, 99), (False, 100), (False, 100)]
    assert fb.next_event_ns() is None


def test_tof_next_event():
    fb = TOF()
    run(fb, [(0, {"IN": True, "PT": 30}), (5, {"IN": False})])
    assert fb.next_event_ns() == 35 * MS


def test_tp_pulse_ignores_retrigger_and_in_falling():
    fb = TP()
    got = run(fb, [(0, {"IN": True, "PT": 100}), (30, {"IN": False}), (40, {"IN": True}),
                   (99, {}), (100, {}), (120, {}), (130, {"IN": False}), (150, {"IN": True}),
                   (200, {})])
    assert got == [(True, 0), (True, 30), (True, 40), (True, 99), (False, 100), (False, 100),
                   (False, 0), (True, 0), (True, 50)]
    assert fb.next_event_ns() == 250 * MS


def test_tp_needs_a_new_rising_edge_after_the_pulse():
    fb = TP()
    got = run(fb, [(0, {"IN": True, "PT": 10}), (10, {}), (30, {}), (40, {"IN": False}),
                   (50, {"IN": True})])
    assert [q for q, _ in got] == [True, False, False, False, True]


def test_tonr_accumulates_and_resets():
    fb = TONR()
    got = run(fb, [(0, {"IN": True, "PT": 100}), (60, {"IN": False}), (200, {"IN": True}),
                   (240, {}), (250, {"RESET": True}), (260, {"RESET": False})])
    assert got == [(False, 0), (False, 60), (False, 60), (True, 100), (False, 0), (False, 0)]


def test_r_trig_and_f_trig():
    r, f = R_TRIG(), F_TRIG()
    clk = [False, True, True, False, False, True, False]
    assert [run(r, [(0, {"CLK": c})], ("Q",))[0][0] for c in clk] == [
        False, True, False, False, False, True, False]
    # ed.3: no falling edge reported on the first call with CLK FALSE
    assert [run(f, [(0, {"CLK": c})], ("Q",))[0][0] for c in clk] == [
        False, False, False, True, False, False, True]


def test_r_trig_fires_on_first_call_with_clk_true():
    assert run(R_TRIG(), [(0, {"CLK": True})], ("Q",)) == [(True,)]


@pytest.mark.parametrize("cls, s, r, expected", [
    (SR, "S1", "R", [True, True, False, True]),   # set dominant: S1 and R together -> TRUE
    (RS, "S", "R1", [True, True, False, False]),  # reset dominant
])
def test_bistables(cls, s, r, expected):
    fb = cls()
    steps = [{s: True, r: False}, {s: False, r: False}, {s: False, r: True}, {s: True, r: True}]
    assert [run(fb, [(0, st)], ("Q1",))[0][0] for st in steps] == expected


def test_ctu_counts_rising_edges_resets_and_saturates():
    fb = CTU()
    steps = [{"CU": True, "PV": 2}, {"CU": True}, {"CU": False}, {"CU": True}, {"CU": False},
             {"CU": True}, {"R": True}, {"R": False, "CU": False}]
    assert run(fb, [(0, s) for s in steps], ("Q", "CV")) == [
        (False, 1), (False, 1), (False, 1), (True, 2), (True, 2), (True, 3), (False, 0),
        (False, 0)]
    fb.CV = 32767
    fb.R = False
    assert run(fb, [(0, {"CU": True})], ("CV",)) == [(32767,)]
    wide = make_standard_fb("CTU_DINT")
    wide.CV = 32767
    assert run(wide, [(0, {"CU": True})], ("CV",)) == [(32768,)]


def test_ctd_loads_and_counts_down():
    fb = CTD()
    steps = [{"LD": True, "PV": 2}, {"LD": False, "CD": True}, {"CD": False}, {"CD": True},
             {"CD": False}, {"CD": True}]
    assert run(fb, [(0, s) for s in steps], ("Q", "CV")) == [
        (False, 2), (False, 1), (False, 1), (True, 0), (True, 0), (True, -1)]


def test_ctud_both_edges_cancel_and_reset_wins_over_load():
    fb = CTUD()
    steps = [{"PV": 2, "CU": True}, {"CU": False}, {"CU": True, "CD": True},
             {"CU": False, "CD": False}, {"CU": True}, {"R": True, "LD": True},
             {"R": False, "LD": True}]
    assert run(fb, [(0, s) for s in steps], ("QU", "QD", "CV")) == [
        (False, False, 1), (False, False, 1), (False, False, 1), (False, False, 1),
        (True, False, 2), (False, True, 0), (True, False, 2)]


def test_state_captures_everything_that_matters():
    a, b = TON(), TON()
    run(a, [(0, {"IN": True, "PT": 100})])
    run(b, [(0, {"IN": True, "PT": 100})])
    assert a.state() == b.state()
    run(b, [(10, {})])
    assert a.state() != b.state()


@pytest.mark.parametrize("name", ["TON", "TOF", "TP", "TONR"])
@pytest.mark.parametrize("seed", range(8))
def test_event_jumps_give_the_same_edges_as_scan_stepping(name, seed):
    """Calling a timer only when an input changes or when it says an output will change
    (rounded up to the next scan) yields exactly the output edges of calling it every scan."""
    import random
    rng = random.Random(seed)
    scan = 10 * MS
    horizon = 3000 * MS
    changes = {}
    t = 0
    while t < horizon:
        t += rng.randrange(1, 40) * scan
        changes[t] = {"IN": rng.random() < 0.6}
        if name == "TONR" and rng.random() < 0.15:
            changes[t]["RESET"] = rng.random() < 0.5
        if rng.random() < 0.1:
            changes[t]["PT"] = rng.randrange(0, 30) * 7 * MS  # PT need not be a whole scan

    def edges(fb, times):
        out, last = [], None
        for t in times:
            for k, v in changes.get(t, {}).items():
                setattr(fb, k, v)
            fb.execute(t)
            q = fb.Q
            if q != last:
                out.append((t, q))
                last = q
        return out

    def pt_init(fb):
        fb.PT = 100 * MS
        return fb

    stepped = edges(pt_init(make_standard_fb(name)), range(0, horizon, scan))

    fb = pt_init(make_standard_fb(name))
    times, t = [], 0
    pending = sorted(changes)
    while t < horizon:
        times.append(t)
        for k, v in changes.get(t, {}).items():
            setattr(fb, k, v)
        fb.execute(t)
        nxt = [c for c in pending if c > t][:1]
        ev = fb.next_event_ns()
        if ev is not None:
            nxt.append(max(-(-ev // scan) * scan, t + scan))
        if not nxt:
            break
        t = min(nxt)
    jumped = edges(pt_init(make_standard_fb(name)), [x for x in times if x < horizon])
    assert jumped == stepped
    assert len(times) < horizon // scan  # and it really skipped scans
