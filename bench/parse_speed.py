"""Parser throughput on a generated 20,000-line Structured Text program.

Prints lines per second for tokenizing alone, parsing (tokenize + LALR + IR build) and the
semantic check, and the ratio of full parsing to tokenizing measured in the same process.
Target: at least 20,000 lines/s for parsing.

With ``--blark N`` (blark installed: ``pip install blark``) it also parses the first N lines'
worth of the program with blark, a lark-based IEC 61131-3 parser, and with plcpred, in the
same process, and prints the ratio of their times (target: plcpred at least 100x faster).
The program written for this comparison says ``EXPT(x, 2)`` where the main one says
``x ** 2``, which blark does not read.

    python bench/parse_speed.py [--lines N] [--repeat R] [--blark N]
"""
from __future__ import annotations

import argparse
import time

from plcpred.parser import parse_st
from plcpred.parser.check import check_program
from plcpred.parser.lexer import Tokenizer

FB = """FUNCTION_BLOCK FB_Station{n}
VAR_INPUT
    bStart : BOOL;
    bHome, bWork : BOOL;
    tDwell : TIME := T#1s500ms;
END_VAR
VAR_OUTPUT
    bValve : BOOL;
    nCount : DINT;
END_VAR
VAR
    nStep : INT;
    fbT : TON;
    fbEdge : R_TRIG;
    aBuf : ARRAY[0..9] OF REAL := [10(0.0)];
    i : INT;
END_VAR
(* state machine of station {n} *)
fbEdge(CLK := bStart);
CASE nStep OF
    0:
        IF fbEdge.Q AND bHome THEN
            nStep := 10;
        END_IF
    10:
        bValve := TRUE;
        IF bWork THEN
            nStep := 20;
        END_IF
    20:
        fbT(IN := TRUE, PT := tDwell);
        IF fbT.Q THEN
            fbT(IN := FALSE);
            nStep := 30;
        END_IF
    30:
        bValve := FALSE;
        IF bHome THEN
            nCount := nCount + 1;
            nStep := 0;
        END_IF
ELSE
    nStep := 0;
END_CASE
FOR i := 0 TO 8 DO
    aBuf[i] := aBuf[i + 1] * 0.5 + INT_TO_REAL(nStep) / 2.0; // smoothing
END_FOR
aBuf[9] := DINT_TO_REAL(nCount) ** 2 - (aBuf[0] + 16#10) * -1.0E-3;
END_FUNCTION_BLOCK

"""


def generate(lines: int) -> str:
    chunks = []
    total = 0
    n = 0
    while total < lines:
        text = FB.replace("{n}", str(n))
        chunks.append(text)
        total += text.count("\n")
        n += 1
    return "".join(chunks)


def best_of(fn, repeat):
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lines", type=int, default=20_000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--blark", type=int, default=0, metavar="N",
                    help="also compare with blark on an N-line program (blark takes about "
                         "15 s per 1,000 lines)")
    args = ap.parse_args(argv)
    src = generate(args.lines)
    n_lines = src.count("\n")
    parse_st("PROGRAM Warm END_PROGRAM")  # build the LALR tables outside the timing

    t_lex = best_of(lambda: sum(1 for _ in Tokenizer(src)), args.repeat)
    holder = {}
    t_parse = best_of(lambda: holder.__setitem__("p", parse_st(src, "bench.st")), args.repeat)
    t_check = best_of(lambda: check_program(holder["p"]), args.repeat)

    print(f"program: {n_lines} lines, {len(holder['p'].pous)} POUs")
    print(f"tokenize only : {n_lines / t_lex:10,.0f} lines/s  ({t_lex * 1e3:7.1f} ms)")
    print(f"parse (to IR) : {n_lines / t_parse:10,.0f} lines/s  ({t_parse * 1e3:7.1f} ms)")
    print(f"semantic check: {n_lines / t_check:10,.0f} lines/s  ({t_check * 1e3:7.1f} ms)")
    print(f"parse / tokenize time ratio: {t_parse / t_lex:.2f}")
    print(f"target 20,000 lines/s: {'met' if n_lines / t_parse >= 20_000 else 'NOT met'} "
          f"({n_lines / t_parse / 20_000:.2f}x)")
    if args.blark:
        compare_with_blark(args.blark)


def compare_with_blark(lines: int) -> None:
    try:
        from blark.parse import get_parser, parse_source_code
    except ImportError:
        print("blark is not installed (pip install blark): no comparison")
        return
    src = generate(lines).replace("DINT_TO_REAL(nCount) ** 2", "EXPT(DINT_TO_REAL(nCount), 2)")
    n_lines = src.count("\n")
    get_parser()                      # blark's grammar, built outside the timing
    t0 = time.perf_counter()
    result = parse_source_code(src)
    t_blark = time.perf_counter() - t0
    if result.exception is not None:
        print(f"blark did not read the program: {result.exception}")
        return
    t_ours = best_of(lambda: parse_st(src, "bench.st"), 3)
    print(f"blark         : {n_lines / t_blark:10,.0f} lines/s  ({t_blark * 1e3:7.1f} ms, "
          f"{n_lines} lines)")
    print(f"plcpred       : {n_lines / t_ours:10,.0f} lines/s  ({t_ours * 1e3:7.1f} ms)")
    ratio = t_blark / t_ours
    print(f"plcpred / blark speed: {ratio:.0f}x (target >= 100x: "
          f"{'met' if ratio >= 100 else 'NOT met'})")


if __name__ == "__main__":
    main()
