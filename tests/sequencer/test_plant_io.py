"""The cylinder plant I/O model: end switches follow the valve."""
import pytest

from plcpred.sequencer.plant import CylinderPlant, valve_command

MS = 10**6


def edges(plant, until_ms):
    """All switch edges as (t_ms, retracted, extended), following next_event_ns."""
    out, t = [], 0
    while True:
        t = plant.next_event_ns(t)
        if t is None or t > until_ms * MS:
            return out
        out.append((t / MS, *plant.switches(t)))


def test_extend_then_retract_with_delay_and_separate_stroke_times():
    p = CylinderPlant(extend_ns=250 * MS, retract_ns=300 * MS, delay_ns=20 * MS)
    assert p.switches(0) == (True, False)
    p.command(100 * MS, True)
    p.command(1000 * MS, False)
    assert edges(p, 5000) == [(120, False, False), (370, False, True),
                              (1020, False, False), (1320, True, False)]


def test_reversal_mid_stroke_returns_over_the_travelled_share():
    p = CylinderPlant(extend_ns=200 * MS, retract_ns=400 * MS, delay_ns=10 * MS)
    p.command(0, True)            # moves from 10 ms
    p.command(90 * MS, False)     # valve switches at 100 ms: 45 % out
    assert p.position(100 * MS) == pytest.approx(0.45)
    # back over 45 % of the 400 ms retract time
    assert edges(p, 2000) == [(10, False, False), (280, True, False)]


def test_short_pulse_moves_the_piston_between_the_two_valve_switchings():
    p = CylinderPlant(extend_ns=100 * MS, retract_ns=100 * MS, delay_ns=30 * MS)
    p.command(0, True)            # valve switches at 30 ms
    p.command(10 * MS, False)     # and back at 40 ms: 10 % out, 10 ms back
    assert edges(p, 1000) == [(30, False, False), (50, True, False)]
    assert p.switches(500 * MS) == (True, False)


def test_initial_extended_and_repeated_commands_are_idempotent():
    p = CylinderPlant(extend_ns=100 * MS, retract_ns=100 * MS, initial_extended=True)
    assert p.switches(0) == (False, True)
    p.command(0, True)
    assert edges(p, 1000) == []
    p.command(50 * MS, False)
    p.command(60 * MS, False)
    assert edges(p, 1000) == [(50, False, False), (150, True, False)]


def test_zero_delay_edge_is_at_the_command_time():
    p = CylinderPlant(extend_ns=80 * MS, retract_ns=80 * MS)
    p.command(40 * MS, True)
    assert p.switches(40 * MS) == (False, False)
    assert p.switches(120 * MS) == (False, True)


@pytest.mark.parametrize("solenoids, rising, previous, expected", [
    ([True], [True], False, True),       # monostable / single-acting: follows the solenoid
    ([False], [False], True, False),
    ([True, False], [True, False], False, True),   # bistable: last pulsed wins
    ([False, True], [False, True], True, False),
    ([False, False], [False, False], True, True),  # both off: keeps its state
    ([True, False], [False, False], False, False), # held, no new pulse: no change
    ([True, True], [True, True], True, True),      # both pulsed together: keeps state
])
def test_valve_command(solenoids, rising, previous, expected):
    assert valve_command(solenoids, previous, rising) == expected


def test_bad_parameters():
    with pytest.raises(ValueError):
        CylinderPlant(extend_ns=0, retract_ns=100)


def test_state_key_of_a_finished_stroke_is_that_of_resting_at_its_end():
    moved = CylinderPlant(extend_ns=100 * MS, retract_ns=100 * MS, delay_ns=10 * MS)
    moved.command(0, True)
    resting = CylinderPlant(extend_ns=100 * MS, retract_ns=100 * MS, delay_ns=10 * MS,
                            initial_extended=True)
    # while it moves the key follows the position; once there it is the resting one
    keys = [moved.key(t * MS) for t in (5, 40, 80)]
    assert len(set(keys)) == 3
    assert moved.key(110 * MS) == resting.key(110 * MS) == (True, 1.0, 0)
    assert moved.key(500 * MS) == moved.key(110 * MS)
