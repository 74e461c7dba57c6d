"""Seeded random lines of stations, each station with its own jittered part sensor, for
the island tests (``test_islands.py``) and ``bench/sequencer_speed.py``.

A line is written in one of three ways engineers write them:

* ``fb_array``: an ``ARRAY OF FB_Station`` called in a FOR loop, each station holding an
  array of drive FBs (valve, done flag, watchdog TON latching a fault, a stroke count
  nothing reads), a CTU that blows the part off every K-th part, a TP, its I/O in a
  struct per station;
* ``flat``: one PROGRAM with a CASE step chain per station on global I/O, a MOD ring
  count, a TON, R_TRIG;
* ``sfc``: one SFC PROGRAM per station in a CONFIGURATION's task, on global I/O.

With ``coupled`` the stations share something: an interlock (a station starts only when
the one before is idle) or a count of every station's parts. Coupled stations are one
island; the others are islands of their own.
"""
from __future__ import annotations

import random
from dataclasses import dataclass

STYLES = ("fb_array", "flat", "sfc")
COUPLINGS = ("interlock", "count")
# (stroke extend s, retract s)
STROKES = [(0.15, 0.12), (0.2, 0.18), (0.25, 0.22), (0.3, 0.25)]


@dataclass
class Line:
    program: str
    machine: str
    stations: int
    style: str
    coupled: str | None


def line(seed, style: str | None = None, coupled: str | None | bool = False) -> Line:
    """A line of 2-4 stations of 1-3 drives. ``coupled``: False (independent), True (a
    random coupling), or a name of COUPLINGS."""
    rng = random.Random(seed)
    style = style or rng.choice(STYLES)
    if coupled is True:
        coupled = rng.choice(COUPLINGS)
    coupled = coupled or None
    n, d = rng.randint(2, 4), rng.randint(1, 3)
    k = rng.randint(2, 3)
    program = {"fb_array": _fb_array, "flat": _flat, "sfc": _sfc}[style](n, d, k, coupled)
    return Line(program, _machine(rng, n, d, style), n, style, coupled)


def _fb_array(n: int, d: int, k: int, coupled) -> str:
    couple = ""
    if coupled == "interlock":
        couple = (f"FOR s := 1 TO {n - 1} DO\n"
                  "    aStation[s].xFree := NOT aStation[s - 1].xBusy;\nEND_FOR\n")
    elif coupled == "count":
        couple = "nTotal := " + " + ".join(f"aStation[{s}].nParts" for s in range(n)) + ";\n"
    return f"""TYPE ST_Io :
STRUCT
    xPart, xBlow : BOOL;
    aExt, aRet, aValve : ARRAY[0..{d - 1}] OF BOOL;
END_STRUCT
END_TYPE

FUNCTION_BLOCK FB_Drive
VAR_INPUT
    xCmd, xExt, xRet : BOOL;
END_VAR
VAR_OUTPUT
    xValve, xDone, xFault : BOOL;
    nStrokes : UDINT;
END_VAR
VAR
    fbWatch : TON;
    fbEdge : R_TRIG;
END_VAR
fbEdge(CLK := xCmd);
IF fbEdge.Q THEN
    nStrokes := nStrokes + 1;
END_IF
xValve := xCmd AND NOT xFault;
xDone := (xCmd AND xExt) OR (NOT xCmd AND xRet);
fbWatch(IN := NOT xDone, PT := T#5S);
IF fbWatch.Q THEN
    xFault := TRUE;
END_IF
END_FUNCTION_BLOCK

FUNCTION_BLOCK FB_Station
VAR_IN_OUT
    io : ST_Io;
END_VAR
VAR_INPUT
    xFree : BOOL := TRUE;
END_VAR
VAR_OUTPUT
    nParts : UDINT;
    xBusy : BOOL;
END_VAR
VAR
    aDrive : ARRAY[0..{d - 1}] OF FB_Drive;
    nStep, i : INT;
    fbPart : R_TRIG;
    ctu : CTU;
    tpBlow : TP;
END_VAR
fbPart(CLK := io.xPart);
CASE nStep OF
    0:
        IF fbPart.Q AND xFree THEN
            nStep := 1;
        END_IF
    1..{d}:
        aDrive[nStep - 1].xCmd := TRUE;
        IF io.aExt[nStep - 1] THEN
            nStep := nStep + 1;
        END_IF
    {d + 1}:
        FOR i := 0 TO {d - 1} DO
            aDrive[i].xCmd := FALSE;
        END_FOR
        IF io.aRet[0] AND io.aRet[{d - 1}] THEN
            nParts := nParts + 1;
            nStep := 0;
        END_IF
END_CASE
ctu(CU := nStep = {d + 1}, RESET := ctu.Q, PV := {k});
tpBlow(IN := ctu.Q, PT := T#300MS);
io.xBlow := tpBlow.Q;
xBusy := nStep <> 0;
FOR i := 0 TO {d - 1} DO
    aDrive[i](xExt := io.aExt[i], xRet := io.aRet[i]);
    io.aValve[i] := aDrive[i].xValve;
END_FOR
END_FUNCTION_BLOCK

PROGRAM Line
VAR
    aIo : ARRAY[0..{n - 1}] OF ST_Io;
    aStation : ARRAY[0..{n - 1}] OF FB_Station;
    s : INT;
    nTotal : UDINT;
END_VAR
{couple}FOR s := 0 TO {n - 1} DO
    aStation[s](io := aIo[s]);
END_FOR
END_PROGRAM
"""


def _globals(n: int, d: int) -> list[str]:
    out = ["VAR_GLOBAL"]
    for s in range(n):
        out.append(f"    xPart_{s}, xBlow_{s} : BOOL;")
        for c in range(d):
            out.append(f"    q_{s}_{c}, xOut_{s}_{c}, xIn_{s}_{c} : BOOL;")
    return out + ["    nTotal : INT;", "END_VAR", ""]


def _flat(n: int, d: int, k: int, coupled) -> str:
    decl, body = ["PROGRAM Line", "VAR"], []
    for s in range(n):
        decl += [f"    nStep_{s}, nCount_{s} : INT;", f"    trig_{s} : R_TRIG;",
                 f"    tmr_{s} : TON;"]
        free = f" AND nStep_{s - 1} = 0" if coupled == "interlock" and s else ""
        count = " nTotal := nTotal + 1;" if coupled == "count" else ""
        body += [f"trig_{s}(CLK := xPart_{s});",
                 f"CASE nStep_{s} OF",
                 (f"    0: IF trig_{s}.Q{free} THEN nStep_{s} := 1; "
                  f"nCount_{s} := (nCount_{s} + 1) MOD {k};{count} END_IF")]
        for c in range(d):
            body.append(f"    {c + 1}: q_{s}_{c} := TRUE; "
                        f"IF xOut_{s}_{c} THEN nStep_{s} := {c + 2}; END_IF")
        for j, c in enumerate(reversed(range(d))):
            body.append(f"    {d + 1 + j}: q_{s}_{c} := FALSE; "
                        f"IF xIn_{s}_{c} THEN nStep_{s} := {d + 2 + j}; END_IF")
        body += [f"    {2 * d + 1}: nStep_{s} := 0;", "END_CASE",
                 f"tmr_{s}(IN := nStep_{s} = {d + 1}, PT := T#150MS);",
                 f"xBlow_{s} := tmr_{s}.Q OR nCount_{s} = 0 AND nStep_{s} = 1;"]
    decl.append("END_VAR")
    return "\n".join(_globals(n, d) + decl + body + ["END_PROGRAM", ""])


def _sfc(n: int, d: int, k: int, coupled) -> str:
    out = _globals(n, d)
    for s in range(n):
        ext = [f"xPart_{s}", *(f"q_{s}_{c}" for c in range(d)),
               *(f"xOut_{s}_{c}" for c in range(d)), *(f"xIn_{s}_{c}" for c in range(d)),
               f"xBlow_{s}"]
        if coupled == "interlock" and s:
            ext.append(f"q_{s - 1}_0")
        out += [f"PROGRAM Station{s}", "VAR_EXTERNAL", f"    {', '.join(ext)} : BOOL;"]
        if coupled == "count":
            out.append("    nTotal : INT;")
        out += ["END_VAR", "", "INITIAL_STEP Idle:", "END_STEP", ""]
        for c in range(d):
            out += [f"STEP Ext{c}:", f"    q_{s}_{c}(S);", "END_STEP", ""]
        count = ["    Count(P);"] if coupled == "count" else []
        out += ["STEP Blow:", f"    xBlow_{s}(N);", *count, "END_STEP", "", "STEP Ret:"]
        out += [f"    q_{s}_{c}(R);" for c in range(d)] + ["END_STEP", ""]
        free = f" AND NOT q_{s - 1}_0" if coupled == "interlock" and s else ""
        out += ["TRANSITION FROM Idle TO Ext0", f"    := xPart_{s}{free};", "END_TRANSITION", ""]
        for c in range(1, d):
            out += [f"TRANSITION FROM Ext{c - 1} TO Ext{c}", f"    := xOut_{s}_{c - 1};",
                    "END_TRANSITION", ""]
        out += [f"TRANSITION FROM Ext{d - 1} TO Blow", f"    := xOut_{s}_{d - 1};",
                "END_TRANSITION", "", "TRANSITION FROM Blow TO Ret", "    := Blow.T >= T#200MS;",
                "END_TRANSITION", "", "TRANSITION FROM Ret TO Idle",
                "    := " + " AND ".join(f"xIn_{s}_{c}" for c in range(d))
                + f" AND NOT xPart_{s};", "END_TRANSITION", ""]
        if coupled == "count":
            out += ["ACTION Count:", "    nTotal := nTotal + 1;", "END_ACTION"]
        out += ["END_PROGRAM", ""]
    out += ["CONFIGURATION Cell", "  RESOURCE Cpu ON PLC",
            "    TASK Main(INTERVAL := T#10MS, PRIORITY := 1);"]
    out += [f"    PROGRAM St{s} WITH Main : Station{s};" for s in range(n)]
    out += ["  END_RESOURCE", "END_CONFIGURATION", ""]
    return "\n".join(out)


def _machine(rng: random.Random, n: int, d: int, style: str) -> str:
    out = ["[machine]", 'name = "line"', 'program = "line.st"', "scan_ms = 10",
           "supply_bar_g = 6.0"]
    for s in range(n):
        part = f"aIo[{s}].xPart" if style == "fb_array" else f"xPart_{s}"
        period = rng.choice([2.5, 3.0, 3.5, 4.0])
        out += ["", "[[input]]", f'signal = "{part}"', f"period_s = {period}",
                f"offset_s = {round(rng.uniform(0.1, 1.0), 2)}",
                f"pulse_ms = {rng.choice([200, 300, 400])}",
                f"jitter_s = {rng.choice([0.05, 0.1, 0.2])}", f"seed = {rng.randint(1, 99)}"]
        for c in range(d):
            te, tr = rng.choice(STROKES)
            if style == "fb_array":
                v, ret, ext = (f"aIo[{s}].aValve[{c}]", f"aIo[{s}].aRet[{c}]",
                               f"aIo[{s}].aExt[{c}]")
            else:
                v, ret, ext = f"q_{s}_{c}", f"xIn_{s}_{c}", f"xOut_{s}_{c}"
            out += ["", "[[consumer]]", f'name = "S{s}C{c}"', 'kind = "double_acting"',
                    "bore_mm = 20", "rod_mm = 8", "stroke_mm = 50", "tube_id_mm = 4",
                    "tube_length_m = [1.0, 1.0]", f'valve = "{v}"',
                    f"stroke_time_s = [{te}, {tr}]", "switch_delay_s = 0.012",
                    f'switches = {{ retracted = "{ret}", extended = "{ext}" }}']
        blow = f"aIo[{s}].xBlow" if style == "fb_array" else f"xBlow_{s}"
        out += ["", "[[consumer]]", f'name = "blow S{s}"', 'kind = "nozzle"',
                f'valve = "{blow}"', "orifice_mm = 1.0", "Cd = 0.8"]
    return "\n".join(out + [""])
