"""Seeded random PLC programs with matching machine files, and a differential runner that
unfolds each one event-driven and scan by scan (the reference) and reports the first
difference. Used by ``tests/sequencer/test_differential.py`` (a few hundred programs) and
``bench/fuzz.py --differential N`` (the long run).

A generated program is what engineers write for small pneumatic stations: scheduled
inputs (part sensors with jitter, start pulses, an enable held high), cylinders with end
switches the program reads, nozzles, and a random mix of

* counters: CTU/CTD and plain ``n := n + 1`` (sometimes the machine's ``cycle_signal``),
  ``MOD`` ring counters, XOR accumulators, ``NOT`` toggles;
* timers (TON, TOF, TP, blinkers, ``ET`` compared with constants), R_TRIG/F_TRIG, SR/RS;
* a CASE step chain or an SFC function block driving the cylinders and a blow-off;
* one user FUNCTION_BLOCK per drive (valve output, watchdog timer, end-switch inputs),
  single instances or ``ARRAY[1..N] OF FB_Drive``;
* ``ARRAY[1..N] OF BOOL`` (shift registers, rotating one-hot), bits of a WORD;
* "named plain VARs": plain ``VAR`` variables (no VAR_OUTPUT, no %Q address) that the
  machine file names as a nozzle's valve (``q``, ``aBits[2]``, ``wOut.3``, ``wCnt.2``,
  ``fbA.xPulse``, ``seq.xBlink``, ``ctu.Q``), often reaching nothing else in the program;
* inputs wired into arrays and word bits (``aIn[2]``, ``wIn.3``), switches written
  straight into a drive FB's inputs (``fbC0.xHome``), counts shown on INT outputs;
* sometimes a second PROGRAM (ST or SFC, its step flags recorded) in a slower task of a
  CONFIGURATION, linked through VAR_GLOBALs, its signals named ``pAux.x``.

``Case.features`` names the constructs a program holds (``toggle``, ``word-count``,
``two-tasks``, ...), so that differences can be grouped by what the programs hold.

Every program parses, compiles and runs (``tests/sequencer/test_differential.py`` checks it).

    case = generate(17)               # Case(seed, program, machine, horizon, features)
    result = run_case(case, tmpdir)   # Result(status "same"|"differ"|"error", detail, ...)
"""
from __future__ import annotations

import math
import random
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path

PROGRAM_FILE = "prog.st"
MACHINE_FILE = "machine.toml"


# ---------------------------------------------------------------------- generation

@dataclass
class Case:
    seed: object
    program: str            # ST text
    machine: str            # TOML text naming PROGRAM_FILE
    horizon: str            # "3s"
    features: list = field(default_factory=list)
    named: list = field(default_factory=list)   # plain VARs the machine file names

    def write(self, directory) -> Path:
        """Write the program and the machine file into ``directory``; the machine's path."""
        d = Path(directory)
        d.mkdir(parents=True, exist_ok=True)
        (d / PROGRAM_FILE).write_text(self.program)
        (d / MACHINE_FILE).write_text(self.machine)
        return d / MACHINE_FILE


def _ms(ms: int) -> str:
    """A TIME literal: T#150ms, T#1s200ms."""
    if ms >= 1000 and ms % 1000:
        return f"T#{ms // 1000}s{ms % 1000}ms"
    if ms >= 1000:
        return f"T#{ms // 1000}s"
    return f"T#{ms}ms"


def _toml(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {_toml(x)}" for k, x in v.items()) + " }"
    raise TypeError(type(v))


class _Gen:
    """One program under construction."""

    def __init__(self, seed):
        self.rng = random.Random(f"progen-{seed}")
        self.seed = seed
        self.names: set = set()
        self.ins: list = []          # VAR_INPUT declarations "name : TYPE"
        self.outs: list = []         # VAR_OUTPUT declarations
        self.vars: list = []         # VAR declarations (name, "TYPE := init")
        self.fbs: list = []          # user FUNCTION_BLOCK texts, before the PROGRAM
        self.body: list = []         # statements of the program, in order
        self.bools: list = []        # BOOL expressions the program may read
        self.inputs: list = []       # [[input]] tables
        self.nozzle_valves: list = []  # signals a nozzle may be driven by (named VARs, ...)
        self.cycle_signal = None
        self.features: list = []
        self.cyls: list = []         # per cylinder: dict(home, work, cmd, times, ...)
        self.plain: set = set()      # named plain VARs among nozzle_valves
        self.emitted_plain: list = []  # those the machine file names

    # -------------------------------------------------------------- helpers
    def name(self, stem: str) -> str:
        k = 0
        while f"{stem}{k}".upper() in self.names:
            k += 1
        n = f"{stem}{k}"
        self.names.add(n.upper())
        return n

    def var(self, stem: str, decl: str) -> str:
        n = self.name(stem)
        self.vars.append((n, decl))
        return n

    def pt(self) -> int:
        return self.rng.choice([0, 10, 20, 30, 35, 50, 70, 100, 150, 200, 250, 400, 600,
                                1000, 1500, 7, 33, 125])

    def atom(self) -> str:
        x = self.rng.choice(self.bools)
        return x if self.rng.random() < 0.75 else f"NOT {x}"

    def cond(self, depth: int = 0) -> str:
        if depth >= 2 or self.rng.random() < 0.45:
            return self.atom()
        op = self.rng.choice(["AND", "OR", "AND", "XOR"])
        return f"({self.cond(depth + 1)} {op} {self.cond(depth + 1)})"

    def edge(self) -> str:
        """A rising (or falling) edge of some condition, as a trigger's Q."""
        kind = "R_TRIG" if self.rng.random() < 0.7 else "F_TRIG"
        n = self.var("trg", kind)
        self.body.append(f"{n}(CLK := {self.cond()});")
        return f"{n}.Q"

    def gate(self) -> str | None:
        """When a statement runs: every scan (it changes something every scan, and the
        executor steps), on an edge (once per event: the executor can jump) or while a
        condition holds."""
        r = self.rng.random()
        if r < 0.15:
            return None
        if r < 0.8:
            return self.edge()
        return self.cond()

    def gated(self, stmts: list, gate: str | None) -> None:
        if gate is None:
            self.body += stmts
        else:
            self.body.append(f"IF {gate} THEN " + " ".join(stmts) + " END_IF")

    def readable(self, expr: str, p: float = 0.5) -> None:
        """Let later code read ``expr`` (then it reaches something) with probability p."""
        if self.rng.random() < p:
            self.bools.append(expr)

    def named(self, signal: str) -> None:
        """A plain VAR (or a path into one) the machine file may name as a valve."""
        self.nozzle_valves.append(signal)
        self.plain.add(signal)

    # -------------------------------------------------------------- inputs and plant
    def add_inputs(self) -> None:
        rng = self.rng
        signals = []
        for _ in range(rng.randint(1, 3)):
            r = rng.random()
            if r < 0.12:                # sensors wired into an array: aIn[2]
                n = self.name("aIn")
                m = rng.randint(2, 3)
                self.ins.append(f"{n} : ARRAY[1..{m}] OF BOOL;")
                signals += [f"{n}[{k}]" for k in rng.sample(range(1, m + 1), rng.randint(1, m))]
            elif r < 0.2:               # or into the bits of an input word: wIn.3
                n = self.name("wIn")
                self.ins.append(f"{n} : WORD;")
                signals += [f"{n}.{k}" for k in rng.sample(range(0, 8), rng.randint(1, 2))]
            else:
                n = self.name("i")
                self.ins.append(f"{n} : BOOL;")
                signals.append(n)
        for n in signals:
            self.bools.append(n)
            table = {"signal": n}
            kind = rng.random()
            if kind < 0.6:
                period = rng.choice([0.3, 0.5, 0.7, 1.0, 1.3, 2.0])
                pulse = rng.choice([10, 20, 50, 100, 150, int(period * 400)])
                table.update(period_s=period, offset_s=rng.choice([0.0, 0.05, 0.1, 0.123, 0.5]),
                             pulse_ms=pulse)
                room = period - pulse / 1000.0
                if rng.random() < 0.35 and room > 0.05:
                    table["jitter_s"] = round(min(room / 2 - 0.01, rng.choice([0.01, 0.02,
                                                                             0.05, 0.1])), 3)
                    table["seed"] = rng.randrange(100)
            elif kind < 0.85:
                pulses = sorted({round(rng.uniform(0.0, 3.5), 3) for _ in range(rng.randint(1, 4))})
                gaps = [b - a for a, b in zip(pulses, pulses[1:])]
                longest = int(min(gaps) * 1000 * 0.8) if gaps else 500
                table.update(pulses_s=pulses, pulse_ms=max(1, min(rng.choice([5, 30, 100, 400]),
                                                                  longest)))
            else:
                table["initial"] = True        # an enable or a normally closed stop
                if rng.random() < 0.3:
                    del table["initial"]       # an input nobody drives: stays FALSE
            self.inputs.append(table)

    def add_cylinders(self) -> None:
        rng = self.rng
        for _ in range(rng.choice([0, 1, 1, 2, 2, 3])):
            k = len(self.cyls)
            cyl = {"k": k, "home": None, "work": None, "cmd": None,
                   "times": [rng.choice([0.05, 0.1, 0.15, 0.2, 0.33, 0.5]),
                             rng.choice([0.04, 0.1, 0.12, 0.25, 0.4])],
                   "delay": rng.choice([0.0, 0.0, 0.01, 0.012, 0.015, 0.02, 0.007]),
                   "kind": rng.choice(["double_acting"] * 4 + ["single_acting", "rodless",
                                                               "gripper"]),
                   "initial": "extended" if rng.random() < 0.1 else "retracted"}
            sw = rng.random()
            into = rng.random() < 0.2
            if into:
                # the machine file writes the switches straight into the drive FB's
                # inputs (fbC0.xHome), which the program reads from there
                cyl["fb"] = self.name(f"fbC{k}_")
            for role, has in (("home", sw < 0.85), ("work", sw < 0.7 or 0.85 <= sw < 0.93)):
                if not has:
                    continue
                if into:
                    cyl[role] = f"{cyl['fb']}.x{role.capitalize()}"
                else:
                    cyl[role] = self.name(f"c{k}_{role}")
                    self.ins.append(f"{cyl[role]} : BOOL;")
                self.bools.append(cyl[role])
            self.cyls.append(cyl)

    # -------------------------------------------------------------- blocks
    def blk_toggle(self):
        v = self.var("q", "BOOL")
        self.gated([f"{v} := NOT {v};"], self.gate())
        self.named(v)
        self.readable(v, 0.3)
        self.features.append("toggle")

    def blk_mod(self):
        n = self.var("n", self.rng.choice(["INT", "UINT", "DINT"]))
        k = self.rng.randint(2, 5)
        self.gated([f"{n} := ({n} + 1) MOD {k};"], self.gate())
        f = self.var("m", "BOOL")
        self.body.append(f"{f} := {n} = {self.rng.randrange(k)};")
        self.named(f)
        self.readable(f, 0.3)
        self.features.append("mod")

    def blk_xor(self):
        v = self.var("x", "BOOL")
        src = self.edge() if self.rng.random() < 0.75 else self.cond()
        self.body.append(f"{v} := {v} XOR {src};")
        self.named(v)
        self.readable(v, 0.3)
        self.features.append("xor")

    def blk_count(self):
        n = self.var("nCount", self.rng.choice(["INT", "UDINT", "DINT", "UINT"]))
        self.gated([f"{n} := {n} + {self.rng.choice([1, 1, 1, 2])};"], self.gate() or self.edge())
        r = self.rng.random()
        if r < 0.4:
            f = self.var("b", "BOOL")
            self.body.append(f"{f} := {n} >= {self.rng.randint(1, 8)};")
            self.readable(f, 0.6)
            self.named(f)
        elif r < 0.6 and self.cycle_signal is None:
            self.cycle_signal = n       # the machine counts its cycles on it
            self.features.append("cycle_signal")
        self.features.append("count")

    def blk_ctu(self):
        c = self.var("ctu", "CTU")
        reset = self.cond() if self.rng.random() < 0.6 else "FALSE"
        self.body.append(f"{c}(CU := {self.cond()}, R := {reset}, PV := {self.rng.randint(1, 6)});")
        self.readable(f"{c}.Q", 0.8)
        r = self.rng.random()
        if r < 0.3:
            f = self.var("b", "BOOL")
            self.body.append(f"{f} := {c}.CV = {self.rng.randint(0, 4)};")
            self.named(f)
            self.readable(f, 0.4)
        elif r < 0.45:
            self.named(f"{c}.Q")              # the counter's own output drives a valve
        elif r < 0.55:
            self.named(f"{c}.CV.{self.rng.randint(0, 2)}")   # a bit of its count
        self.features.append("CTU")

    def blk_ctd(self):
        c = self.var("ctd", "CTD")
        self.body.append(f"{c}(CD := {self.cond()}, LD := {self.cond()}, "
                         f"PV := {self.rng.randint(1, 5)});")
        self.readable(f"{c}.Q", 0.8)
        if self.rng.random() < 0.3:
            f = self.var("b", "BOOL")
            self.body.append(f"{f} := {c}.CV > {self.rng.randint(0, 3)};")
            self.named(f)
        self.features.append("CTD")

    def blk_timer(self):
        kind = self.rng.choice(["TON", "TOF", "TP"])
        t = self.var("t", kind)
        self.body.append(f"{t}(IN := {self.cond()}, PT := {_ms(self.pt())});")
        self.readable(f"{t}.Q", 0.85)
        if self.rng.random() < 0.15:
            self.named(f"{t}.Q")              # the timer's own output drives a valve
        if self.rng.random() < 0.25:
            f = self.var("b", "BOOL")
            op = self.rng.choice([">=", ">", "<", "<="])
            self.body.append(f"{f} := {t}.ET {op} {_ms(self.rng.choice([0, 20, 35, 60, 100]))};")
            self.readable(f, 0.6)
            self.named(f)
        self.features.append(kind)

    def blk_blink(self):
        t = self.var("tBlink", "TON")
        self.body.append(f"{t}(IN := NOT {t}.Q, PT := {_ms(self.rng.choice([20, 50, 100, 250, 400]))});")
        v = self.var("q", "BOOL")
        self.gated([f"IF {t}.Q THEN {v} := NOT {v}; END_IF"], self.cond() if
                   self.rng.random() < 0.5 else None)
        self.named(v)
        self.readable(v, 0.4)
        self.features.append("blink")

    def blk_latch(self):
        kind = self.rng.choice(["SR", "RS"])
        f = self.var("ff", kind)
        if kind == "SR":
            self.body.append(f"{f}(S1 := {self.cond()}, R := {self.cond()});")
        else:
            self.body.append(f"{f}(S := {self.cond()}, R1 := {self.cond()});")
        self.readable(f"{f}.Q1", 0.8)
        if self.rng.random() < 0.3:
            v = self.var("q", "BOOL")
            self.body.append(f"{v} := {f}.Q1;")
            self.named(v)
        self.features.append(kind)

    def blk_trig(self):
        e = self.edge()
        self.readable(e, 0.9)
        if self.rng.random() < 0.3:
            v = self.var("q", "BOOL")
            self.body.append(f"IF {e} THEN {v} := NOT {v}; END_IF")
            self.named(v)
            self.readable(v, 0.3)
        self.features.append("trig")

    def blk_array(self):
        rng = self.rng
        n = rng.randint(2, 5)
        a = self.var("aBits", f"ARRAY[1..{n}] OF BOOL")
        i = self.var("i", "INT")
        kind = rng.choice(["shift", "onehot", "toggle", "copy"])
        if kind == "shift":
            self.body.append(f"FOR {i} := {n} TO 2 BY -1 DO {a}[{i}] := {a}[{i} - 1]; END_FOR")
            self.body.append(f"{a}[1] := {self.cond()};")
        elif kind == "onehot":
            c = self.var("nPos", "INT")
            self.gated([f"{c} := ({c} MOD {n}) + 1;"], self.gate())
            self.body.append(f"FOR {i} := 1 TO {n} DO {a}[{i}] := {c} = {i}; END_FOR")
        elif kind == "toggle":                      # a binary counter, ripple carry
            carry = self.var("xCarry", "BOOL")
            self.gated([f"{carry} := TRUE; FOR {i} := 1 TO {n} DO IF {carry} THEN "
                        f"{a}[{i}] := NOT {a}[{i}]; {carry} := NOT {a}[{i}]; END_IF END_FOR"],
                       self.gate())
        else:
            self.body.append(f"FOR {i} := 1 TO {n} DO {a}[{i}] := {self.cond()}; END_FOR")
        for k in rng.sample(range(1, n + 1), rng.randint(1, 2)):
            self.named(f"{a}[{k}]")
            self.readable(f"{a}[{k}]", 0.25)
        self.features.append(f"array-{kind}")

    def blk_word(self):
        r = self.rng.random()
        if r < 0.35:
            w = self.var("wOut", "WORD := 16#0001")
            self.gated([f"{w} := ROL({w}, 1);"], self.gate())
            kind = "rol"
        elif r < 0.65:
            w = self.var("wOut", "WORD")
            self.body.append(f"{w} := SHL({w}, 1) OR SEL({self.cond()}, WORD#0, WORD#1);")
            kind = "shl"
        else:
            # a counting word whose bits drive valves (a binary divider): the count is
            # a plain "n := n + 1", its bits are what the machine file names
            w = self.var("wCnt", self.rng.choice(["WORD", "UINT", "BYTE", "DINT"]))
            self.gated([f"{w} := {w} + 1;"], self.gate())
            kind = "count"
        for b in self.rng.sample(range(0, 6), self.rng.randint(1, 2)):
            self.named(f"{w}.{b}")
        self.features.append(f"word-{kind}")

    def blk_shown(self):
        """A count shown on an integer output (an HMI value): recorded in the timeline."""
        n = self.name("nShown")
        self.outs.append(f"{n} : {self.rng.choice(['INT', 'UDINT', 'DINT'])};")
        r = self.rng.random()
        if r < 0.5:
            c = self.var("ctu", "CTU")
            self.body.append(f"{c}(CU := {self.cond()}, R := {self.cond() if r < 0.25 else 'FALSE'}, "
                             f"PV := {self.rng.randint(2, 9)});")
            self.body.append(f"{n} := {c}.CV;")
            self.readable(f"{c}.Q", 0.5)
        else:
            self.gated([f"{n} := {n} + 1;"], self.gate() or self.edge())
        self.features.append("shown-count")

    def blk_write_input(self):
        """The program overwrites one of its inputs (a latch cleared in the image)."""
        scalars = [d.split(" ")[0] for d in self.ins if d.endswith(": BOOL;")]
        if not scalars:
            return
        i = self.rng.choice(scalars)
        self.body.append(f"IF {self.cond()} THEN {i} := {self.rng.choice(['FALSE', 'TRUE'])}; END_IF")
        self.features.append("write-input")

    # -------------------------------------------------------------- sequences
    def blk_chain(self):
        """A CASE step chain over the cylinders (and a blow-off), started by an edge."""
        rng = self.rng
        st = self.var("nStep", "INT")
        start = self.edge() if rng.random() < 0.7 else self.cond()
        steps = [f"0: IF {start} THEN {st} := 10; END_IF"]
        nr = 10
        resets = rng.random() < 0.8          # timers reset when their step is left

        def wait(sig):
            """Leave step ``nr`` when switch ``sig`` closes (or a step timer ends)."""
            if sig is not None and rng.random() < 0.9:
                return f"IF {sig} THEN {st} := {nr + 10}; END_IF"
            t = self.var("tStep", "TON")
            leave = f"{t}(IN := FALSE); " if resets else ""
            return (f"{t}(IN := TRUE, PT := {_ms(self.pt())}); IF {t}.Q THEN {leave}"
                    f"{st} := {nr + 10}; END_IF")

        mine = [c for c in self.cyls if c["cmd"] is None and rng.random() < 0.8]
        blow = None
        for c in mine:
            cmd = self.var(f"xCmd{c['k']}_", "BOOL")
            c["cmd"] = cmd
            steps.append(f"{nr}: {cmd} := TRUE; {wait(c['work'])}")
            nr += 10
            if rng.random() < 0.5:
                if blow is None and rng.random() < 0.6:
                    blow = self.var("xBlow", "BOOL")
                t = self.var("tDwell", rng.choice(["TON", "TON", "TP"]))
                on = f"{blow} := TRUE; " if blow else ""
                off = f"{blow} := FALSE; " if blow else ""
                leave = f"{t}(IN := FALSE); " if resets else ""
                steps.append(f"{nr}: {on}{t}(IN := TRUE, PT := {_ms(self.pt())}); "
                             f"IF {t}.Q THEN {off}{leave}{st} := {nr + 10}; END_IF")
                nr += 10
            steps.append(f"{nr}: {cmd} := FALSE; {wait(c['home'])}")
            nr += 10
        if not mine:
            t = self.var("tStep", "TON")
            steps.append(f"{nr}: {t}(IN := TRUE, PT := {_ms(self.pt())}); IF {t}.Q THEN "
                         f"{t}(IN := FALSE); {st} := {nr + 10}; END_IF")
            nr += 10
        tail = ""
        if rng.random() < 0.5:
            cnt = self.var("nCycles", "UDINT")
            tail = f"{cnt} := {cnt} + 1; "
            if self.cycle_signal is None and rng.random() < 0.5:
                self.cycle_signal = cnt
                self.features.append("cycle_signal")
        steps.append(f"{nr}: {tail}{st} := 0;")
        self.body.append(f"CASE {st} OF\n    " + "\n    ".join(steps) + "\nEND_CASE")
        if blow:
            self.named(blow)
        self.readable(f"{st} = 0", 0.4)
        self.features.append("case-chain")

    def sfc_chart(self, ins: list, outs: list) -> tuple[str, list, list]:
        """An SFC chain reading ``ins`` (BOOL expressions) and setting the BOOL variables
        ``outs`` through action qualifiers (N, S/R, L, D), maybe with a blink action and
        a pulse-counting one: (steps, transitions and actions as text, extra VAR
        declarations, plain VARs the machine file may name)."""
        rng = self.rng
        n_steps = rng.randint(2, 5)
        steps = [f"S{j}" for j in range(n_steps)]
        assocs = {s: [] for s in steps}
        actions, extra_vars, named = [], [], []
        set_by = {}
        for o in outs:
            s = rng.choice(steps[1:])
            q = rng.choice(["N", "N", "S", "L", "D"])
            if q in ("L", "D"):
                assocs[s].append(f"{o}({q}, {_ms(rng.choice([30, 50, 100, 200]))});")
            else:
                assocs[s].append(f"{o}({q});")
            if q == "S":
                set_by[o] = s
        for o, s in set_by.items():         # reset later in the chain (or never)
            later = steps[steps.index(s) + 1:] + [steps[0]]
            if rng.random() < 0.85:
                assocs[rng.choice(later)].append(f"{o}(R);")
        if rng.random() < 0.4:
            assocs[rng.choice(steps[1:])].append("Blink(N);")
            actions.append("ACTION Blink:\n    xBlink := NOT xBlink;\nEND_ACTION")
            extra_vars.append("xBlink : BOOL;")
            named.append("xBlink")
        if rng.random() < 0.5:
            assocs[rng.choice(steps[1:])].append("CountIt(P);")
            actions.append("ACTION CountIt:\n    nCount := nCount + 1;\nEND_ACTION")
            extra_vars.append("nCount : UDINT;")
        trans = []
        for j, s in enumerate(steps):
            nxt = steps[(j + 1) % n_steps]
            r = rng.random()
            if r < 0.45:
                c = rng.choice(ins)
                c = c if rng.random() < 0.7 else f"NOT {c}"
            elif r < 0.8:
                c = f"{s}.T >= {_ms(rng.choice([20, 50, 100, 250, 500]))}"
            else:
                c = f"{rng.choice(ins)} AND {s}.T > {_ms(rng.choice([10, 40, 120]))}"
            trans.append(f"TRANSITION FROM {s} TO {nxt} := {c}; END_TRANSITION")
        body = []
        for j, s in enumerate(steps):
            kw = "INITIAL_STEP" if j == 0 else "STEP"
            body.append(f"{kw} {s}:\n" + "".join(f"    {a}\n" for a in assocs[s]) + "END_STEP")
        text = "\n".join(body) + "\n" + "\n".join(trans) + "\n" + "".join(
            a + "\n" for a in actions)
        return text, extra_vars, named

    def blk_sfc(self):
        """A function block whose body is an SFC, called by the program."""
        rng = self.rng
        fbname = self.name("FB_Seq")
        inst = self.var("seq", fbname)
        ins = [f"xIn{j}" for j in range(rng.randint(1, 3))]
        outs = [f"xOut{j}" for j in range(rng.randint(1, 3))]
        chart, extra_vars, named = self.sfc_chart(ins, outs)
        for n in named:
            self.named(f"{inst}.{n}")
        text = (f"FUNCTION_BLOCK {fbname}\nVAR_INPUT {', '.join(ins)} : BOOL; END_VAR\n"
                f"VAR_OUTPUT {', '.join(outs)} : BOOL; END_VAR\n"
                + (f"VAR {' '.join(extra_vars)} END_VAR\n" if extra_vars else "")
                + chart + "END_FUNCTION_BLOCK\n")
        self.fbs.append(text)
        self.body.append(f"{inst}(" + ", ".join(f"{i} := {self.cond()}" for i in ins) + ");")
        free = [c for c in self.cyls if c["cmd"] is None]
        for o in outs:
            if free and rng.random() < 0.6:
                free.pop(0)["cmd"] = f"{inst}.{o}"
            elif rng.random() < 0.6:
                self.nozzle_valves.append(f"{inst}.{o}")
            self.readable(f"{inst}.{o}", 0.3)
        self.features.append("sfc-fb")

    def sfc_program(self) -> None:
        """Make this (second) program an SFC: its inputs and the link from the other
        program drive the transitions; its step flags are recorded."""
        rng = self.rng
        outs = [self.name("ySfc") for _ in range(rng.randint(1, 2))]
        self.outs += [f"{o} : BOOL;" for o in outs]
        chart, extra_vars, named = self.sfc_chart(list(self.bools), outs)
        self.vars += [tuple(v.rstrip(";").split(" : ")) for v in extra_vars]
        self.nozzle_valves += outs
        for n in named:
            self.named(n)
        self.sfc_text = chart
        self.features.append("sfc-program")

    # -------------------------------------------------------------- drives
    def drive_fb(self) -> str:
        """The program's drive FUNCTION_BLOCK (one variant per program)."""
        if getattr(self, "_drive", None):
            return self._drive
        rng = self.rng
        self._drive = name = self.name("FB_Drive")
        lines = ["xValve := xCmd AND NOT xError;",
                 "xDone := (xCmd AND xWork) OR (NOT xCmd AND xHome);",
                 "fbWatch(IN := NOT xDone, PT := tWatch);",
                 "IF fbWatch.Q THEN xError := TRUE; END_IF"]
        local = ["fbWatch : TON;"]
        ins = ["xCmd : BOOL;", "xHome : BOOL;", "xWork : BOOL;",
               f"tWatch : TIME := {_ms(rng.choice([100, 300, 800, 2000]))};"]
        self._drive_pulse = rng.random() < 0.35
        if rng.random() < 0.5:
            ins.append("xReset : BOOL;")
            lines.append("IF xReset THEN xError := FALSE; END_IF")
            self._drive_reset = True
        else:
            self._drive_reset = False
        if rng.random() < 0.6:
            local += ["rtCmd : R_TRIG;", "nStrokes : UDINT;"]
            lines += ["rtCmd(CLK := xCmd);", "IF rtCmd.Q THEN nStrokes := nStrokes + 1; END_IF"]
        if self._drive_pulse:
            # a blow pulse train while the drive is at work: a plain VAR of the FB the
            # machine file names as a nozzle's valve (fbA.xPulse)
            local.append("xPulse : BOOL;")
            lines.append("IF xCmd AND xWork THEN xPulse := NOT xPulse; ELSE xPulse := FALSE; END_IF")
        text = (f"FUNCTION_BLOCK {name}\nVAR_INPUT\n    " + "\n    ".join(ins) + "\nEND_VAR\n"
                "VAR_OUTPUT\n    xValve : BOOL;\n    xDone : BOOL;\n    xError : BOOL;\nEND_VAR\n"
                "VAR\n    " + "\n    ".join(local) + "\nEND_VAR\n" + "\n".join(lines)
                + "\nEND_FUNCTION_BLOCK\n")
        self.fbs.append(text)
        self.features.append("drive-fb")
        return name

    def wire_cylinders(self) -> None:
        """Each cylinder's command (from a chain, an SFC output or some condition) reaches
        its valve directly, through a drive FB instance, or through an array of them."""
        rng = self.rng
        for c in self.cyls:
            if c["cmd"] is None:
                c["cmd"] = self.cond()
        todo = list(self.cyls)
        for c in [c for c in todo if c.get("fb")]:
            self.vars.append((c["fb"], self.drive_fb()))
            self.call_drive(c["fb"], c)
            todo.remove(c)
        if len(todo) >= 2 and rng.random() < 0.35:
            fb = self.drive_fb()
            n = len(todo)
            arr = self.var("aDrv", f"ARRAY[1..{n}] OF {fb}")
            for j, c in enumerate(todo, 1):
                self.call_drive(f"{arr}[{j}]", c)
            todo = []
            self.features.append("fb-array")
        for c in todo:
            r = rng.random()
            if r < 0.45:
                fb = self.drive_fb()
                inst = self.var(f"fbC{c['k']}_", fb)
                self.call_drive(inst, c)
            else:
                y = self.name(f"y{c['k']}_")
                if rng.random() < 0.8:
                    self.outs.append(f"{y} : BOOL;")
                else:
                    self.vars.append((y, "BOOL"))   # a plain VAR driving a cylinder
                self.body.append(f"{y} := {c['cmd']};")
                c["valve"] = [y]
        for c in self.cyls:
            if len(c["valve"]) == 1 and rng.random() < 0.1 and c["kind"] != "single_acting":
                # a bistable valve: the program pulses the other solenoid
                off = self.name(f"y{c['k']}_off")
                self.outs.append(f"{off} : BOOL;")
                self.body.append(f"{off} := NOT ({c['cmd']});")
                c["valve"].append(off)

    def call_drive(self, inst: str, c: dict) -> None:
        rng = self.rng
        home = c["home"] or ("NOT " + c["work"] if c["work"] else "TRUE")
        work = c["work"] or ("NOT " + c["home"] if c["home"] else "TRUE")
        args = [f"xCmd := {c['cmd']}"]
        if not c.get("fb"):
            args += [f"xHome := {home}", f"xWork := {work}"]
        else:                     # the machine file drives the switch inputs it names
            args += [f"x{role.capitalize()} := {v}" for role, v in (("home", home),
                                                                    ("work", work))
                     if c[role] is None]
        if self._drive_reset:
            args.append(f"xReset := {self.cond()}")
        r = rng.random()
        if r < 0.4:
            y = self.name(f"y{c['k']}_")
            self.outs.append(f"{y} : BOOL;")
            self.body.append(f"{inst}({', '.join(args + [f'xValve => {y}'])});")
            c["valve"] = [y]
        elif r < 0.7:
            self.body.append(f"{inst}({', '.join(args)});")
            c["valve"] = [f"{inst}.xValve"]
        else:
            y = self.name(f"y{c['k']}_")
            self.outs.append(f"{y} : BOOL;")
            self.body.append(f"{inst}({', '.join(args)});")
            self.body.append(f"{y} := {inst}.xValve;")
            c["valve"] = [y]
        self.readable(f"{inst}.xDone", 0.3)
        if self._drive_pulse:
            self.named(f"{inst}.xPulse")

    # -------------------------------------------------------------- the whole
    def blocks(self) -> list:
        blocks = [self.blk_toggle, self.blk_mod, self.blk_xor, self.blk_count, self.blk_ctu,
                  self.blk_ctd, self.blk_timer, self.blk_timer, self.blk_blink, self.blk_latch,
                  self.blk_trig, self.blk_array, self.blk_word, self.blk_shown]
        if self.rng.random() < 0.05:
            blocks.append(self.blk_write_input)
        return blocks

    def build(self) -> Case:
        rng = self.rng
        scan_ms = rng.choice([10, 10, 10, 10, 5, 4, 20, 7, 2.5])
        multi = rng.random() < 0.15      # a second PROGRAM in a slower task
        self.externals = []
        if multi:
            self.externals = ["gLink", "gBack"]
            self.bools.append("gBack")
        self.add_inputs()
        self.add_cylinders()
        blocks = self.blocks()
        for blk in rng.sample(blocks, rng.randint(2, 6)):
            blk()
        r = rng.random()
        if r < 0.45:
            self.blk_chain()
        elif r < 0.75:
            self.blk_sfc()
        for blk in rng.sample(blocks, rng.randint(0, 2)):
            blk()
        self.wire_cylinders()
        # a couple of plain outputs nobody's consumer uses, and nozzles
        if rng.random() < 0.4:
            y = self.name("yAux")
            self.outs.append(f"{y} : BOOL;")
            self.body.append(f"{y} := {self.cond()};")
            if rng.random() < 0.5:
                self.nozzle_valves.append(y)
        horizon = rng.choice(["2s", "3s", "4s", "5s", "2.5s", "3.333s"])
        gens = [(self, "Main", "")]
        config = ""
        if multi:
            self.body.append(f"gLink := {self.cond()};")
            aux = _Gen(f"{self.seed}-aux")
            aux.externals = ["gLink", "gBack"]
            aux.bools.append("gLink")
            aux.add_inputs()
            if aux.rng.random() < 0.4:
                aux.sfc_program()        # gBack is left FALSE
            else:
                for blk in aux.rng.sample(aux.blocks(), aux.rng.randint(1, 4)):
                    blk()
                aux.body.append(f"gBack := {aux.cond()};")
            if rng.random() < 0.3:
                self.nozzle_valves.append("gLink")
            self.features += aux.features + ["two-tasks"]
            every = rng.choice([2, 3, 5])
            slow = scan_ms * every if rng.random() < 0.8 else scan_ms * every + 3
            gens = [(self, "Main", "pMain."), (aux, "Aux", "pAux.")]
            config = ("CONFIGURATION Cfg\n  VAR_GLOBAL\n    gLink : BOOL;\n    gBack : BOOL;\n"
                      "  END_VAR\n  RESOURCE Res ON PLC\n"
                      f"    TASK tFast(INTERVAL := {_ms_any(scan_ms)}, PRIORITY := 1);\n"
                      f"    TASK tSlow(INTERVAL := {_ms_any(slow)}, PRIORITY := 2);\n"
                      "    PROGRAM pMain WITH tFast : Main;\n    PROGRAM pAux WITH tSlow : Aux;\n"
                      "  END_RESOURCE\nEND_CONFIGURATION\n")
        elif rng.random() < 0.2:
            gens = [(self, "Main", "Main.")]   # signals named through the program
        program = "".join(g.program_text(pou) for g, pou, _ in gens) + config
        machine = self.machine_text(scan_ms, gens)
        return Case(self.seed, program, machine, horizon, sorted(set(self.features)),
                    list(self.emitted_plain))

    def program_text(self, pou: str = "Main") -> str:
        out = list(self.fbs)
        out.append(f"PROGRAM {pou}")
        if self.externals:
            out.append("VAR_EXTERNAL\n" + "".join(f"    {n} : BOOL;\n" for n in self.externals)
                       + "END_VAR")
        if self.ins:
            out.append("VAR_INPUT\n" + "".join(f"    {d}\n" for d in self.ins) + "END_VAR")
        if self.outs:
            out.append("VAR_OUTPUT\n" + "".join(f"    {d}\n" for d in self.outs) + "END_VAR")
        if self.vars:
            out.append("VAR\n" + "".join(f"    {n} : {d};\n" for n, d in self.vars) + "END_VAR")
        out += [getattr(self, "sfc_text", None)] if getattr(self, "sfc_text", None) else self.body
        out.append("END_PROGRAM")
        return "\n".join(out) + "\n"

    def machine_text(self, scan_ms, gens) -> str:
        rng = self.rng
        out = ["[machine]", f'name = "generated {self.seed}"', f'program = "{PROGRAM_FILE}"',
               f"scan_ms = {scan_ms}", "supply_bar_g = 6.0"]
        if self.cycle_signal:
            out.append(f'cycle_signal = "{gens[0][2]}{self.cycle_signal}"')
        out.append("")
        for g, _, pre in gens:
            for table in g.inputs:
                out.append("[[input]]")
                out += [f"{k} = {_toml(pre + v if k == 'signal' else v)}"
                        for k, v in table.items()]
                out.append("")
        for c in self.cyls:
            pre = gens[0][2]
            switches = {}
            if c["home"]:
                switches["retracted"] = pre + c["home"]
            if c["work"]:
                switches["extended"] = pre + c["work"]
            valve = [pre + v for v in c["valve"]]
            t = {"name": f"cyl{c['k']}", "kind": c["kind"], "bore_mm": 20,
                 "stroke_mm": 50, "tube_id_mm": 4, "tube_length_m": 1.0,
                 "valve": valve[0] if len(valve) == 1 else valve,
                 "stroke_time_s": c["times"], "switch_delay_s": c["delay"]}
            if c["kind"] == "double_acting":
                t["rod_mm"] = 8
            if switches:
                t["switches"] = switches
            if c["initial"] != "retracted":
                t["initial"] = c["initial"]
            out.append("[[consumer]]")
            out += [f"{k} = {_toml(v)}" for k, v in t.items()]
            out.append("")
        seen = set()
        for g, _, pre in gens:
            for v in g.nozzle_valves:
                # most named VARs drive a nozzle: the class of signal the compared state
                # must hold even though nothing in the program reads it
                v = v if v.startswith("g") and v in ("gLink", "gBack") else pre + v
                if v in seen or rng.random() < 0.15:
                    continue
                seen.add(v)
                if v.removeprefix(pre) in g.plain:
                    self.emitted_plain.append(v)
                out += ["[[consumer]]", f'name = "nozzle{len(seen)}"', 'kind = "nozzle"',
                        f"valve = {_toml(v)}", "orifice_mm = 1.0", "Cd = 0.8", ""]
        if rng.random() < 0.2:
            out += ["[[consumer]]", 'name = "leaks"', 'kind = "leak"', "orifice_mm = 0.3",
                    "Cd = 0.6", ""]
        return "\n".join(out)


def _ms_any(ms) -> str:
    """A TIME literal for a whole or fractional number of milliseconds."""
    if ms == int(ms):
        return _ms(int(ms))
    return f"T#{int(ms * 1000)}us"


def generate(seed) -> Case:
    """The program and machine file of ``seed`` (any hashable; the same seed gives the
    same case)."""
    return _Gen(seed).build()


# ---------------------------------------------------------------------- regressions

NOZZLE = """[machine]
name = "{name}"
program = "{program}"
scan_ms = {scan_ms}
supply_bar_g = 6.0

[[consumer]]
name = "nozzle"
kind = "nozzle"
valve = "{valve}"
orifice_mm = 1.0
Cd = 0.8
"""


def nozzle_case(name: str, program: str, valve: str, horizon: str = "1s",
                scan_ms: int = 10) -> Case:
    """A program whose plain VAR ``valve`` drives a nozzle (the known class of bug)."""
    return Case(name, program, NOZZLE.format(name=name, program=PROGRAM_FILE, valve=valve,
                                             scan_ms=scan_ms), horizon, ["regression"])


# ---------------------------------------------------------------------- comparing

NS = 1_000_000_000


def _rows(tl):
    names = tl.names
    return list(zip(tl.time_ns.tolist(), [names[i] for i in tl.signal_idx.tolist()],
                    tl.values.tolist()))


def _same_value(a, b) -> bool:
    return a == b or (isinstance(a, float) and isinstance(b, float)
                      and math.isnan(a) and math.isnan(b))


def compare(tl_a, tl_b, names=("event-driven", "scan-stepping")) -> str | None:
    """None when the two timelines hold exactly the same (time, signal, value) rows in the
    same order; else the first difference, readable: the signal, the time and each
    timeline's value there (or what differs: the signal lists, the horizon, the order
    of rows within a scan)."""
    a_name, b_name = names
    if tl_a.names != tl_b.names:
        return (f"signal lists differ: {a_name} has {tl_a.names}, {b_name} has "
                f"{tl_b.names}")
    if tl_a.horizon_ns != tl_b.horizon_ns:
        return f"horizons differ: {tl_a.horizon_s:g} s against {tl_b.horizon_s:g} s"
    ra, rb = _rows(tl_a), _rows(tl_b)
    if len(ra) == len(rb) and all(x[0] == y[0] and x[1] == y[1] and _same_value(x[2], y[2])
                                  for x, y in zip(ra, rb)):
        return None
    # the earliest time at which some signal's value differs
    first = None
    for name in tl_a.names:
        ta, va = tl_a.edge_times_ns(name)
        tb, vb = tl_b.edge_times_ns(name)
        ea, eb = list(zip(ta.tolist(), va.tolist())), list(zip(tb.tolist(), vb.tolist()))
        k = 0
        while k < min(len(ea), len(eb)) and ea[k][0] == eb[k][0] and _same_value(
                ea[k][1], eb[k][1]):
            k += 1
        if k == len(ea) == len(eb):
            continue
        t = min(x[k][0] for x in (ea, eb) if k < len(x))

        def at(edges, t):
            v = None
            for te, ve in edges:
                if te > t:
                    break
                v = ve
            return v

        if first is None or t < first[0]:
            n_a, n_b = len(ea), len(eb)
            first = (t, name, at(ea, t), at(eb, t), n_a, n_b)
    if first is None:
        k = next((k for k, (x, y) in enumerate(zip(ra, rb)) if x != y), min(len(ra), len(rb)))
        return (f"same values but rows in another order at row {k}: {a_name} "
                f"{ra[k] if k < len(ra) else None}, {b_name} {rb[k] if k < len(rb) else None}")
    t, name, va, vb, n_a, n_b = first
    return (f"{name} at {t / NS:g} s: {a_name} {_fmt(va)}, {b_name} {_fmt(vb)} "
            f"({n_a} against {n_b} changes of {name} over {tl_a.horizon_s:g} s)")


def _fmt(v):
    if v is None:
        return "no value"
    return f"{v:g}" if isinstance(v, float) else repr(v)


# ---------------------------------------------------------------------- running

@dataclass
class Result:
    status: str                 # "same" | "differ" | "error"
    detail: str = ""            # the first difference, or the error
    mechanism: str = ""         # for a difference: which event-driven variants also differ
    seconds: float = 0.0
    scans: tuple = ()           # (event-driven, scan-stepping)


def run_case(case: Case, directory, diagnose: bool = True) -> Result:
    """Write ``case`` into ``directory`` and unfold it event-driven (tiling and replay on,
    as ``plcpred timeline`` runs it) and scan by scan; ``status`` "same" when the
    timelines are identical. ``diagnose``: on a difference, also run without tiling and
    without replay, and say which of them still differ (``mechanism``)."""
    from plcpred.machine import load_machine
    from plcpred.sequencer import unfold

    t0 = time.perf_counter()
    path = case.write(directory)
    try:
        fast = unfold(load_machine(path), case.horizon)
        ref = unfold(load_machine(path), case.horizon, scan_stepping=True)
    except Exception as e:  # noqa: BLE001 - a generator bug or an executor fault
        detail = f"{type(e).__name__}: {e}"
        if not hasattr(e, "file"):        # not a positioned PlcpredError: keep where
            detail += " | " + traceback.format_exc(limit=-2).replace("\n", " ")[-400:]
        return Result("error", detail[:800], seconds=time.perf_counter() - t0)
    diff = compare(fast, ref)
    scans = (fast.info.get("scans"), ref.info.get("scans"))
    if diff is None:
        return Result("same", seconds=time.perf_counter() - t0, scans=scans)
    mech = ""
    if diagnose:
        parts = []
        for label, kw in (("no tiling", {"tiling": False}), ("no replay", {"replay": False}),
                          ("neither", {"tiling": False, "replay": False})):
            try:
                other = unfold(load_machine(path), case.horizon, **kw)
                parts.append(f"{label}: {'differs' if compare(other, ref) else 'same'}")
            except Exception as e:  # noqa: BLE001
                parts.append(f"{label}: {type(e).__name__}")
        mech = ", ".join(parts)
    return Result("differ", diff, mech, time.perf_counter() - t0, scans)


def shrink(case: Case, directory, still_fails=None) -> Case:
    """A smaller case that still differs: drops lines of the program (statements,
    declarations, whole blocks when their lines go one by one) and tables of the machine
    file one at a time while the run still gives a difference (``still_fails(result)``
    to keep something else). Slow (a run per try); for reports, not for tests."""
    def fails(c):
        if c is None:
            return False
        try:
            r = run_case(c, directory, diagnose=False)
        except Exception:  # noqa: BLE001
            return False
        return r.status == "differ" if still_fails is None else still_fails(r)

    if not fails(case):
        return case

    def cut(items, make, removable=lambda run: True):
        """Drop runs of 8, 4, 2 and 1 items from the end while the case still fails."""
        changed = True
        while changed:
            changed = False
            for size in (8, 4, 2, 1):
                k = len(items) - size
                while k >= 0:
                    trial = items[:k] + items[k + size:]
                    if removable(items[k:k + size]) and fails(make(trial)):
                        items = trial
                        changed = True
                    k -= 1
        return items

    checked = _well_formed(case.program.splitlines())
    while True:
        before = (case.program, case.machine)

        def with_program(lines):
            if checked and not _well_formed(lines):
                return None
            return Case(case.seed, "\n".join(lines) + "\n", case.machine, case.horizon,
                        case.features)

        case = with_program(cut(case.program.splitlines(), with_program, _whole_blocks))

        def with_machine(lines):
            return Case(case.seed, case.program, "\n".join(lines), case.horizon,
                        case.features)

        # the machine file's tables (and then its lines: keys with defaults)
        blocks = case.machine.split("\n\n")
        head, tables = blocks[:1], blocks[1:]
        tables = cut(tables, lambda t: with_machine(["\n\n".join(head + t)]))
        case = with_machine(["\n\n".join(head + tables)])
        case = with_machine(cut(case.machine.splitlines(), with_machine))
        if (case.program, case.machine) == before:
            return case


_PAIRS = [(r"PROGRAM\s+\w+$", r"END_PROGRAM\b"), (r"FUNCTION_BLOCK\b", r"END_FUNCTION_BLOCK\b"),
          (r"(INITIAL_)?STEP\b", r"END_STEP\b"), (r"ACTION\b", r"END_ACTION\b"),
          (r"CONFIGURATION\b", r"END_CONFIGURATION\b"), (r"RESOURCE\b", r"END_RESOURCE\b"),
          (r"CASE\b", r"END_CASE\b")]


_HEADER = r"VAR(_INPUT|_OUTPUT|_EXTERNAL|_GLOBAL|_IN_OUT|_TEMP)?"


def _whole_blocks(run) -> bool:
    """Whether the shrinker may cut these lines: a declaration block's first or last
    line only with the whole block (no declaration moves into another block)."""
    import re
    depth = 0
    for t in (ln.strip() for ln in run):
        if re.fullmatch(_HEADER, t):
            depth += 1
        elif t == "END_VAR":
            depth -= 1
            if depth < 0:
                return False
    return depth == 0


def _well_formed(lines) -> bool:
    """What the shrinker keeps: every block closed where it was (plcpred reads some
    programs without their END_ lines or with declarations moved into another block;
    an engineer would not), every declaration block closed, every task a program
    names declared."""
    import re
    text = [ln.strip() for ln in lines]
    for a, b in _PAIRS:
        if sum(bool(re.match(a, t)) for t in text) != sum(bool(re.match(b, t)) for t in text):
            return False
    inside = False
    for t in text:
        if re.fullmatch(_HEADER, t):
            if inside:
                return False
            inside = True
        elif t == "END_VAR":
            if not inside:
                return False
            inside = False
    tasks = {m.group(1).upper() for t in text for m in [re.match(r"TASK\s+(\w+)", t)] if m}
    used = {m.group(1).upper() for t in text for m in [re.search(r"\bWITH\s+(\w+)", t)] if m}
    return not inside and used <= tasks
