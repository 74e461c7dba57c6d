"""SFC evolution by IEC 61131-3 rules: clearing, divergence/convergence, qualifiers."""
from plcpred.parser.seq import parse_seq
from plcpred.parser import parse_st
from plcpred.sequencer.executor import ProgramInstance

MS = 1_000_000


class Chart:
    """Run a chart scan by scan (10 ms) with inputs set by hand."""

    def __init__(self, text, st=False):
        self.inst = ProgramInstance(parse_st(text) if st else parse_seq(text, "t.seq"))
        self.p = self.inst.programs[0]
        self.t = 0

    def scan(self, n=1, **inputs):
        for k, v in inputs.items():
            setattr(self.p, k.upper(), v)
        for _ in range(n):
            self.inst.scan(self.t)
            self.t += 10 * MS
        return self

    def active(self):
        sfc = self.p._sfc
        return {s for s, x in zip(sfc.spec.steps, sfc.x) if x}

    def __getattr__(self, name):
        return getattr(self.p, name.upper())


SEQ = """sequence S
input go, a, b
output y, k, n, d, p1
var count : INT
initial step Idle
    when go -> Work
step Work
    S y
    N n
    D 50ms d
    L 30ms k
    P Count
    when a -> (Left, Right)
step Left
    when b -> L2
step Right
step L2
join L2, Right -> Done
step Done
    R y
    when NOT go -> Idle
action Count
    count := count + 1;
end_action
"""


def test_transition_clearing_takes_one_layer_per_scan():
    c = Chart(SEQ).scan()
    assert c.active() == {"Idle"}
    c.scan(go=True)
    assert c.active() == {"Work"}
    c.scan(a=True, b=True)        # Work -> (Left, Right) only; Left's own transition waits
    assert c.active() == {"Left", "Right"}
    c.scan()
    assert c.active() == {"L2", "Right"}
    c.scan()                      # simultaneous convergence needs both
    assert c.active() == {"Done"}


def test_convergence_waits_for_all_branches():
    c = Chart(SEQ).scan().scan(go=True).scan(a=True)
    c.scan(3)
    assert c.active() == {"Left", "Right"}


def test_qualifiers_s_r_n_l_d_p():
    c = Chart(SEQ).scan().scan(go=True)
    assert c.y and c.n and c.k and not c.d and c.count == 1
    c.scan(2)          # 20 ms in the step
    assert c.k and not c.d and c.count == 1          # P runs exactly once
    c.scan()           # 30 ms: L ends
    assert not c.k and not c.d
    c.scan(2)          # 50 ms: D starts
    assert c.d and c.n
    c.scan(a=True, b=True)
    assert c.y and not c.n and not c.d               # N and D follow the step; S holds
    c.scan(2)
    assert c.active() == {"Done"} and not c.y        # R resets the stored action


def test_step_time_and_flags_in_st_sfc():
    src = """PROGRAM P
VAR o : BOOL; t : TIME; END_VAR
INITIAL_STEP A: END_STEP
STEP B: o(N); END_STEP
TRANSITION FROM A TO B := A.T >= T#30ms; END_TRANSITION
TRANSITION FROM B TO A := B.T > T#20ms; END_TRANSITION
END_PROGRAM"""
    c = Chart(src, st=True)
    xs = []
    for _ in range(12):
        c.scan()
        xs.append("B" in c.active())
    # A active from 0: A.T reaches 30 ms at the scan at 30 ms; B then fires at 60 ms
    # (B.T = 30 ms > 20 ms), A again from 60 ms to 90 ms
    assert xs == [False, False, False, True, True, True, False, False, False, True, True, True]


def test_selection_divergence_priority_is_the_order_written():
    text = """sequence S
input a
output x, y
initial step I
    when a -> X
    when a -> Y
step X
    N x
step Y
    N y
"""
    c = Chart(text).scan().scan(a=True)
    assert c.active() == {"X"} and c.x and not c.y


def test_action_body_gets_a_final_scan_when_its_step_is_left():
    text = """sequence S
input a
var runs : INT
initial step I
    N Body
    when a -> J
step J
action Body
    runs := runs + 1;
end_action
"""
    c = Chart(text).scan(3)
    assert c.runs == 3
    c.scan(a=True)          # I left: Q falls, the body runs once more
    assert c.runs == 4
    c.scan(3)
    assert c.runs == 4
