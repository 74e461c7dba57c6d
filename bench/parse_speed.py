"""Parser throughput on realistic programs, and against blark in the same run.

The programs are lines as engineers write them (:func:`line_program`): one function block
per pneumatic drive (a valve, two reed switches, a watchdog timer, a stroke counter),
stations as CASE step chains over arrays of those blocks (dwell timers, a CTU parts
counter, start edges), stations in IEC textual SFC, and a main program mapping located
I/O to the stations; no two stations alike (a seeded random sequence of drives, dwells
and times).

In process, it prints lines per second for tokenizing alone, parsing (tokenize + LALR +
IR build + name validation) and the semantic check of a ``--lines`` program.

With blark (a lark-based IEC 61131-3 parser; ``pip install blark==0.8.3`` into a separate
venv and give its interpreter as ``--blark-python``, or install it here) it then parses
programs of each ``--sizes`` with both, whole-process (``plcpred check --syntax-only
FILE`` against a Python process that imports blark and parses the file) and in process
(the parse alone, blark's grammar built outside the timing), and prints the ratios of
blark's time to plcpred's: CPU time of the child processes (user + system), so that other
load on the machine does not flatter either. blark reads no SFC, so the programs compared
write their SFC stations as CASE chains. Goal: plcpred at least 300x faster whole-process
from 1,000 lines. blark takes about 15 s of CPU per 1,000 lines.

Children see compiled bytecode, as installed packages have it (see bench/startup.py).

    python bench/parse_speed.py [--lines N] [--repeat R] [--sizes 100,1000,2000]
        [--blark-python PATH] [--no-blark]
"""
from __future__ import annotations

import argparse
import random
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from startup import bytecode_env, run_once

from plcpred.parser import parse_st
from plcpred.parser.check import check_program
from plcpred.parser.lexer import Tokenizer

GOAL = 300

CYLINDER = """(* one pneumatic drive: a monostable valve, two reed switches, a watchdog *)
FUNCTION_BLOCK FB_Cylinder
VAR_INPUT
    bExtend : BOOL;
    bRetracted : BOOL;
    bExtended : BOOL;
    tWatchdog : TIME := T#2s;
END_VAR
VAR_OUTPUT
    bValve : BOOL;
    bFault : BOOL;
    nStrokes : UDINT;
END_VAR
VAR
    fbWatch : TON;
    fbStroke : R_TRIG;
END_VAR
bValve := bExtend AND NOT bFault;
// the watchdog runs while the valve and the switch disagree
fbWatch(IN := bValve <> bExtended, PT := tWatchdog);
IF fbWatch.Q THEN
    bFault := TRUE;
ELSIF bRetracted AND NOT bExtend THEN
    bFault := FALSE;
END_IF;
fbStroke(CLK := bExtended);
IF fbStroke.Q THEN
    nStrokes := nStrokes + 1;
END_IF;
END_FUNCTION_BLOCK

"""


def _station_head(n: int, drives: int) -> list[str]:
    return [f"(* station {n}: {drives} drives in a step chain, parts counted *)",
            f"FUNCTION_BLOCK FB_Station{n}",
            "VAR_INPUT",
            "    bStart : BOOL;",
            "    bStop : BOOL;  (* normally closed *)",
            f"    abRet : ARRAY[1..{drives}] OF BOOL;",
            f"    abExt : ARRAY[1..{drives}] OF BOOL;",
            "END_VAR",
            "VAR_OUTPUT",
            f"    abValve : ARRAY[1..{drives}] OF BOOL;",
            "    nParts : INT;",
            "    bBusy : BOOL;",
            "    rCycle : REAL;",
            "END_VAR",
            "VAR",
            "    nStep : INT := 0;",
            f"    afbDrive : ARRAY[1..{drives}] OF FB_Cylinder;",
            "    fbDwell : TON;",
            "    fbCycle : TON;",
            "    fbParts : CTU;",
            "    fbStartEdge : R_TRIG;",
            "    i : INT;",
            "END_VAR",
            "fbStartEdge(CLK := bStart);",
            "IF NOT bStop THEN",
            "    nStep := 0;",
            "END_IF;",
            "fbCycle(IN := nStep <> 0, PT := T#1h);",
            "CASE nStep OF",
            "    0: (* rest: all drives home *)",
            "        IF fbStartEdge.Q AND " + " AND ".join(
                f"abRet[{d}]" for d in range(1, drives + 1)) + " THEN",
            "            nStep := 10;",
            "        END_IF;"]


def station_fb(n: int, rnd: random.Random) -> str:
    """A station as a CASE step chain: its drives extend one after the other (in a random
    order, some with a dwell), then all retract and the part is counted."""
    drives = rnd.randint(2, 6)
    order = rnd.sample(range(1, drives + 1), drives)
    lines = _station_head(n, drives)
    step = 10
    for d in order:
        lines += [f"    {step}: (* drive {d} extends *)",
                  f"        afbDrive[{d}].bExtend := TRUE;",
                  f"        IF abExt[{d}] THEN",
                  f"            nStep := {step + 10};",
                  "        END_IF;"]
        step += 10
        if rnd.random() < 0.5:
            lines += [f"    {step}: (* dwell *)",
                      f"        fbDwell(IN := TRUE, PT := T#{rnd.randint(1, 40) * 50}ms);",
                      "        IF fbDwell.Q THEN",
                      "            fbDwell(IN := FALSE);",
                      f"            nStep := {step + 10};",
                      "        END_IF;"]
            step += 10
    lines += [f"    {step}: (* everything back, the part done *)"]
    lines += [f"        afbDrive[{d}].bExtend := FALSE;" for d in order]
    lines += ["        IF " + " AND ".join(f"abRet[{d}]" for d in order) + " THEN",
              "            fbParts(CU := TRUE, PV := 1000);",
              "            fbParts(CU := FALSE, PV := 1000);",
              "            rCycle := TIME_TO_REAL(fbCycle.ET) / 1000.0;",
              "            nStep := 0;",
              "        END_IF;",
              "ELSE",
              "    nStep := 0;",
              "END_CASE;",
              f"FOR i := 1 TO {drives} DO",
              "    afbDrive[i](bRetracted := abRet[i], bExtended := abExt[i]);",
              "    abValve[i] := afbDrive[i].bValve;",
              "END_FOR;",
              "bBusy := nStep <> 0;",
              "nParts := fbParts.CV;",
              "END_FUNCTION_BLOCK",
              "", ""]
    return "\n".join(lines)


def sfc_station(n: int, rnd: random.Random, first_byte: int) -> str:
    """A station in IEC textual SFC: a clamp and a press in turn, a timed blow, back to
    the start; its I/O located from byte ``first_byte`` on."""
    i, q = first_byte, first_byte
    dwell = rnd.randint(2, 30) * 100
    return f"""(* station {n} in SFC: clamp, press, blow, release *)
PROGRAM SfcStation{n}
VAR_INPUT
    bStart AT %IX{i}.0 : BOOL;
    bClampShut AT %IX{i}.1 : BOOL;
    bClampOpen AT %IX{i}.2 : BOOL;
    bPressDown AT %IX{i}.3 : BOOL;
    bPressUp AT %IX{i}.4 : BOOL;
END_VAR
VAR_OUTPUT
    yClamp AT %QX{q}.0 : BOOL;
    yPress AT %QX{q}.1 : BOOL;
    yBlow AT %QX{q}.2 : BOOL;
END_VAR
VAR
    nStrokes : UDINT;
END_VAR

INITIAL_STEP Ready:
END_STEP

STEP Clamp:
    yClamp(S);
END_STEP

STEP Press:
    yPress(N);
    CountStroke(P);
END_STEP

STEP Blow:
    yBlow(L, T#{dwell}ms);
END_STEP

STEP Release:
    yClamp(R);
END_STEP

TRANSITION FROM Ready TO Clamp
    := bStart AND bClampOpen AND bPressUp;
END_TRANSITION

TRANSITION FROM Clamp TO Press
    := bClampShut;
END_TRANSITION

TRANSITION FROM Press TO Blow
    := bPressDown;
END_TRANSITION

TRANSITION FROM Blow TO Release
    := Blow.T >= T#{dwell}ms AND bPressUp;
END_TRANSITION

TRANSITION FROM Release TO Ready
    := bClampOpen;
END_TRANSITION

ACTION CountStroke:
    nStrokes := nStrokes + 1;
END_ACTION
END_PROGRAM

"""


def main_program(stations: list[tuple[int, int]], first_byte: int) -> str:
    """The line's PROGRAM: each station's sensors and valves located, mapped element by
    element to its block (``stations``: (number, drives) of the CASE stations)."""
    decls, body = [], []
    byte = first_byte
    for n, drives in stations:
        decls.append(f"    fbStation{n} : FB_Station{n};")
        for d in range(1, drives + 1):
            decls += [f"    S{n}_D{d}_RET AT %IX{byte}.{2 * (d - 1) % 8} : BOOL;",
                      f"    S{n}_D{d}_EXT AT %IX{byte}.{(2 * d - 1) % 8} : BOOL;",
                      f"    S{n}_D{d}_Y AT %QX{byte}.{d - 1} : BOOL;"]
            body += [f"fbStation{n}.abRet[{d}] := S{n}_D{d}_RET;",
                     f"fbStation{n}.abExt[{d}] := S{n}_D{d}_EXT;"]
        body.append(f"fbStation{n}(bStart := bStart AND NOT bFault, bStop := bStop);")
        body += [f"S{n}_D{d}_Y := fbStation{n}.abValve[{d}];" for d in range(1, drives + 1)]
        body.append(f"nParts := nParts + fbStation{n}.nParts;")
        byte += 1
    return "\n".join([
        "(* the line: every station's I/O, the start and stop buttons, the parts made *)",
        "PROGRAM Line",
        "VAR",
        "    bStart AT %IX0.0 : BOOL;",
        "    bStop AT %IX0.1 : BOOL;",
        "    bFault : BOOL;",
        "    nParts : DINT;",
        *decls,
        "END_VAR",
        "nParts := 0;",
        *body,
        "END_PROGRAM", ""])


def line_program(lines: int, sfc: bool = True, seed: int = 1) -> str:
    """A line of at least ``lines`` lines: the drive block, stations (every fourth one in
    SFC when ``sfc``, else all as CASE chains), and the main program."""
    rnd = random.Random(seed)
    parts = [CYLINDER]
    stations: list[tuple[int, int]] = []
    total = CYLINDER.count("\n")
    n = 0
    sfc_byte = 200
    while total + 20 * n < lines:     # the main program adds about 20 lines a station
        if sfc and n % 4 == 3:
            text = sfc_station(n, rnd, sfc_byte)
            sfc_byte += 1
        else:
            text = station_fb(n, rnd)
            stations.append((n, _drives(text)))
        parts.append(text)
        total += text.count("\n")
        n += 1
    parts.append(main_program(stations, 1))
    return "".join(parts)


def _drives(station: str) -> int:
    return int(station.split("abRet : ARRAY[1..", 1)[1].split("]", 1)[0])


def best_of(fn, repeat):
    """The least CPU time of ``repeat`` calls."""
    best = float("inf")
    for _ in range(repeat):
        t0 = time.process_time()
        fn()
        best = min(best, time.process_time() - t0)
    return best


def in_process(args) -> None:
    src = line_program(args.lines)
    n_lines = src.count("\n")
    parse_st("PROGRAM Warm END_PROGRAM")  # the tables read outside the timing
    t_lex = best_of(lambda: sum(1 for _ in Tokenizer(src)), args.repeat)
    holder = {}
    t_parse = best_of(lambda: holder.__setitem__("p", parse_st(src, "bench.st")), args.repeat)
    t_check = best_of(lambda: check_program(holder["p"]), args.repeat)
    errors = check_program(holder["p"])[0]
    print(f"program: {n_lines} lines, {len(holder['p'].pous)} POUs"
          f"{'' if not errors else f', {len(errors)} check errors (a generator bug)'}")
    print(f"tokenize only : {n_lines / t_lex:10,.0f} lines/s  ({t_lex * 1e3:7.1f} ms CPU)")
    print(f"parse (to IR) : {n_lines / t_parse:10,.0f} lines/s  ({t_parse * 1e3:7.1f} ms CPU)")
    print(f"semantic check: {n_lines / t_check:10,.0f} lines/s  ({t_check * 1e3:7.1f} ms CPU)")
    print(f"parse / tokenize time ratio: {t_parse / t_lex:.2f}")


# blark's side, run by its own interpreter: the grammar built (that is part of its whole
# process), then the parse timed alone; prints wall and CPU seconds of the parse
BLARK_PARSE = """
import sys, time
from blark.parse import get_parser, parse_source_code
get_parser()
text = open(sys.argv[1], encoding="utf-8").read()
t0, c0 = time.perf_counter(), time.process_time()
result = parse_source_code(text)
print(time.perf_counter() - t0, time.process_time() - c0)
if result.exception is not None:
    print(result.exception, file=sys.stderr)
    sys.exit(1)
"""


def find_blark(given: str | None) -> str | None:
    """An interpreter that imports blark: ``given``, or this one; None if neither."""
    for python in ([given] if given else [sys.executable]):
        try:
            ok = subprocess.run([python, "-c", "import blark"], capture_output=True,
                                check=False).returncode
        except OSError:     # no such interpreter
            continue
        if ok == 0:
            return python
    return None


def compare_with_blark(sizes: list[int], blark: str, repeat: int) -> None:
    version = subprocess.run([blark, "-c", "import blark; print(blark.__version__)"],
                             capture_output=True, text=True, check=False).stdout.strip()
    folder = tempfile.mkdtemp(prefix="plcpred-parse-")
    env = bytecode_env(str(Path(folder) / "pycache"))
    plcpred = [sys.executable, "-m", "plcpred", "check", "--syntax-only"]
    print(f"\nagainst blark {version} (CPU time of each process, plcpred the median of "
          f"{repeat}; SFC stations written as CASE chains, which blark reads)")
    print(f"{'lines':>6} {'blark process':>14} {'plcpred process':>16} {'ratio':>7} "
          f"{'blark parse':>12} {'plcpred parse':>14} {'ratio':>7}")
    try:
        for size in sizes:
            src = line_program(size, sfc=False)
            path = Path(folder) / f"line{size}.st"
            path.write_text(src, encoding="utf-8")
            run_once([*plcpred, str(path)], env)            # bytecode compiled, not counted
            ours = sorted(run_once([*plcpred, str(path)], env)[1] for _ in range(repeat))
            ours_cpu = ours[len(ours) // 2]
            log = Path(folder) / "blark.txt"
            with open(log, "w") as out:
                _, blark_cpu, code = run_once([blark, "-c", BLARK_PARSE, str(path)], env, out)
            said = log.read_text()
            if code != 0:
                print(f"{src.count(chr(10)):>6} blark did not read the program: "
                      f"{said.strip()[-300:]}")
                continue
            blark_parse = float(said.split()[1])
            ours_parse = best_of(lambda src=src, path=path: parse_st(src, str(path)), repeat)
            print(f"{src.count(chr(10)):>6} {blark_cpu:12.2f} s {ours_cpu * 1e3:13.1f} ms "
                  f"{blark_cpu / ours_cpu:6.0f}x {blark_parse:10.2f} s "
                  f"{ours_parse * 1e3:11.1f} ms {blark_parse / ours_parse:6.0f}x")
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    print(f"goal: whole-process at least {GOAL}x from 1,000 lines")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lines", type=int, default=20_000)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--sizes", default="100,1000,2000",
                    help="program sizes (lines) compared with blark (blark: about 15 s "
                         "of CPU per 1,000 lines)")
    ap.add_argument("--blark-python", metavar="PATH",
                    help="an interpreter with blark installed (default: this one)")
    ap.add_argument("--no-blark", action="store_true")
    args = ap.parse_args(argv)
    in_process(args)
    if args.no_blark:
        return
    blark = find_blark(args.blark_python)
    if blark is None:
        print("\nblark is not installed: no comparison (pip install blark==0.8.3 into a "
              "separate venv and give its python as --blark-python)")
        return
    compare_with_blark([int(s) for s in args.sizes.split(",")], blark, args.repeat)


if __name__ == "__main__":
    main()
