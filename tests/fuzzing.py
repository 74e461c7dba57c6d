"""Mutated inputs for every channel plcpred reads, and a harness that runs each one in a
forked child under a time and memory limit and sorts the outcome. Used by
``tests/safety/test_fuzz.py`` (a short deterministic run) and ``bench/fuzz.py`` (the long run).

Channels (``CHANNELS``): programs (ST, .seq, PLCopen; with type cycles, deep type
constructors and initialisers, long EXTENDS chains), machine files, command lines, truth
files (``emulate --truth``), measured flow logs and ``--io`` traces (``diagnose``), TwinCAT
project folders (``check``, ``init``, ``timeline``) and pre-existing ``--out`` folders
(planted manifests, symbolic links, the user's own files).

The mutators know nothing of plcpred's internals: they work on text (tokens, TOML values,
CSV cells, XML, argument strings) with values chosen to hit the classes of failure seen in
the wild (based and huge literals, deep nesting, Unicode, NaN, overflowing times, bad
paths, odd encodings, links out of a folder).

Outcomes (:class:`Outcome`): ``ok``; ``clean`` (exit 1, 2, or compare's 4/5, with a
message and no traceback); and the bad ones (``BAD``): ``traceback`` (exit 3, an
exception escaping ``main``, 'Traceback' in the output, a child killed by a signal other
than SIGKILL, an exit 1/2 that prints nothing), ``hang`` (over the time limit: the child's
stack is dumped, then it is killed), ``memory`` (peak RSS over the limit, a MemoryError,
plcpred's 'out of memory' error under the child's address-space limit, or a SIGKILL
nobody sent) and ``unsafe`` (a file outside ``--out``, or the user's own inside it, was
changed, removed or created).

``run_program`` and ``run_cli`` are the earlier in-process runners (SIGALRM for hangs,
no memory limit), kept for callers that use them.
"""
from __future__ import annotations

import contextlib
import dataclasses
import datetime
import faulthandler
import hashlib
import io
import json
import math
import os
import random
import re
import resource
import select
import shlex
import shutil
import signal
import sys
import tempfile
import time
import tomllib
import traceback
from pathlib import Path
from typing import Callable

ROOT = Path(__file__).resolve().parent.parent
SAMPLES = ROOT / "samples"
PROGRAM_FILES = sorted(p for p in SAMPLES.rglob("*") if p.suffix in (".st", ".seq", ".xml"))
MACHINE_FILES = sorted(SAMPLES.rglob("*.toml"))

# ------------------------------------------------------------------ programs

TRICKY_TOKENS = [
    "2#2", "8#9", "16#FFFFFFFFFFFFFFFFFFFFFFFF", "1" * 400, "1e999", "-1e-999", "16#",
    "TOD#25:99:99", "D#2026-02-30", "DT#2026-01-01-24:00:00", "INT#99999999999",
    "SINT#-129", "WORD#-1", "T#99999999999999999999d", "T#-1s", "LTIME#1ns", "w.2#1",
    ".99", "REAL#1e39", "'$'", "'$Q'", '"$"', "'" + "x" * 3000 + "'", "%IX99999999999.9",
    "%QX0.0", "%MW5", "ARRAY[0..2147483647] OF BOOL", "ARRAY[5..1] OF INT",
    "ARRAY[0..99999999] OF LREAL", "STRING(2147483647)", "(", ")", "[", "]", ":=", "=>",
    ";", ",", ".", "^", "#", "END_IF", "IF", "THEN", "ELSE", "FOR", "TO", "BY", "DO",
    "END_FOR", "WHILE", "END_WHILE", "REPEAT", "UNTIL", "CASE", "OF", "END_CASE", "EXIT",
    "RETURN", "JMP", "VAR", "END_VAR", "TON", "CTU", "SUPER^", "THIS^", "__NEW", "ADR",
    "REF=", "?=", "S=", "R=", "𝑒𝑥𝑒𝑐", "é", "\u200b", "\x00", "\t", "(*", "*)", "//",
    "{", "}", "1..2", "MOD 0", "/ 0", "** 99999", "SHL 99999", "-32768", "NOT",
    "x := x + 1;", "WHILE TRUE DO END_WHILE;", "FOR i := 0 TO 2000000000 DO END_FOR;",
    "REPEAT UNTIL FALSE END_REPEAT;", "__TRY", "__CATCH", "__CATCH(x)", "__FINALLY",
    "__ENDTRY", "XSIZEOF(POINTER TO INT)", "WString.",
]


def nested(rng) -> str:
    """A deeply nested construct (parentheses, NOT chains, IFs, loops, indices)."""
    n = rng.choice([50, 150, 400, 2000])
    kind = rng.randrange(6)
    if kind == 0:
        return "(" * n + "1" + ")" * n
    if kind == 1:
        return "NOT " * n + "TRUE"
    if kind == 2:
        return "IF TRUE THEN " * n + ";" + " END_IF;" * n
    if kind == 3:
        return "FOR i := 0 TO 1 DO " * (n // 10) + ";" + " END_FOR;" * (n // 10)
    if kind == 4:
        return " + ".join(["1"] * n)
    return "a[" * n + "0" + "]" * n


# type declarations that never end, nest without bound or chain far (the type graph's
# inputs): (declarations, the type of a variable using them, its initial value or None)
def _fb(name, extends="", body="", var="q : BOOL;"):
    ext = f" EXTENDS {extends}" if extends else ""
    return f"FUNCTION_BLOCK {name}{ext}\nVAR {var} END_VAR\n{body}\nEND_FUNCTION_BLOCK\n"


def type_trap(rng: random.Random) -> tuple[str, str, str | None]:
    n = rng.choice([2, 3, 8, 33, 63, 64, 65, 66, 129, 300, 1000, 3000])
    kind = rng.randrange(26)
    if kind == 0:
        return _fb("FzA", "FzA"), "FzA", None
    if kind == 1:
        return _fb("FzA", "FzB") + _fb("FzB", "FzC", var="r : BOOL;") + \
            _fb("FzC", "FzA", var="s : BOOL;"), "FzC", None
    if kind == 2:
        plus = rng.choice(["N", "(N + 1)", "(N * 2)", "(N - 1)"])
        return (f"FUNCTION_BLOCK FzG EXTENDS FzG<{plus}>\nVAR_GENERIC CONSTANT N : UDINT; "
                "END_VAR\nVAR q : BOOL; END_VAR\nEND_FUNCTION_BLOCK\n"), \
            f"FzG<{rng.choice([0, 1, 4, 4294967295])}>", None
    if kind == 3:
        return "TYPE FzS EXTENDS FzS : STRUCT a : INT; END_STRUCT; END_TYPE\n", "FzS", None
    if kind == 4:
        return ("TYPE FzS EXTENDS FzT : STRUCT a : INT; END_STRUCT; END_TYPE\n"
                "TYPE FzT EXTENDS FzS : STRUCT b : INT; END_STRUCT; END_TYPE\n"), "FzT", None
    if kind == 5:
        return ("INTERFACE FzI EXTENDS FzJ\nEND_INTERFACE\nINTERFACE FzJ EXTENDS FzI\n"
                "END_INTERFACE\n" + _fb("FzA", var="q : BOOL;") .replace(
                    "FUNCTION_BLOCK FzA", "FUNCTION_BLOCK FzA IMPLEMENTS FzI")), "FzA", None
    if kind == 6:
        return "TYPE FzA : FzA; END_TYPE\n", "FzA", None
    if kind == 7:
        return "TYPE FzA : FzB; END_TYPE\nTYPE FzB : FzA; END_TYPE\n", "FzA", None
    if kind == 8:
        return rng.choice(["TYPE FzP : POINTER TO FzP; END_TYPE\n",
                           "TYPE FzP : REFERENCE TO FzP; END_TYPE\n",
                           "TYPE FzP : POINTER TO FzQ; END_TYPE\nTYPE FzQ : ARRAY[0..1] OF FzP;"
                           " END_TYPE\n"]), "FzP", None
    if kind == 9:
        member = rng.choice(["s : FzS;", "s : ARRAY[0..1] OF FzS;", "p : POINTER TO FzS; s : FzS;",
                             "p : POINTER TO FzS;", "t : FzT;"])
        return (f"TYPE FzS : STRUCT a : INT; {member} END_STRUCT; END_TYPE\n"
                "TYPE FzT : STRUCT s : FzS; END_STRUCT; END_TYPE\n"), "FzS", None
    if kind == 10:
        return _fb("FzA", var="q : BOOL; a : FzA;"), "FzA", None
    if kind == 11:
        return _fb("FzA", "FzB") + _fb("FzB", var="a : ARRAY[1..2] OF FzA;"), "FzA", None
    if kind == 12:
        return ("TYPE FzS : STRUCT f : FzA; END_STRUCT; END_TYPE\n"
                + _fb("FzA", var="s : FzS;")), "FzA", None
    if kind in (13, 14):          # EXTENDS chains of FBs, structs, interfaces
        what = rng.choice(["FUNCTION_BLOCK", "STRUCT", "INTERFACE"])
        if what == "FUNCTION_BLOCK":
            text = _fb("Fz0", var="q : BOOL;", body="q := TRUE;") + "".join(
                _fb(f"Fz{i}", f"Fz{i - 1}", var=f"v{i} : INT;", body="SUPER^();")
                for i in range(1, n))
        elif what == "STRUCT":
            text = "TYPE Fz0 : STRUCT q : BOOL; END_STRUCT; END_TYPE\n" + "".join(
                f"TYPE Fz{i} EXTENDS Fz{i - 1} : STRUCT v{i} : INT; END_STRUCT; END_TYPE\n"
                for i in range(1, n))
        else:
            text = "INTERFACE Fz0\nEND_INTERFACE\n" + "".join(
                f"INTERFACE Fz{i} EXTENDS Fz{i - 1}\nEND_INTERFACE\n" for i in range(1, n))
            return text, "POINTER TO BOOL", None
        return text, f"Fz{n - 1}", None
    if kind == 15:                # named chains: aliases, structs holding the next, FBs
        what = rng.randrange(3)
        if what == 0:
            text = "".join(f"TYPE Fz{i} : Fz{i + 1}; END_TYPE\n" for i in range(n)) + \
                f"TYPE Fz{n} : INT; END_TYPE\n"
        elif what == 1:
            text = "".join(f"TYPE Fz{i} : STRUCT a : INT; s : Fz{i + 1}; END_STRUCT; END_TYPE\n"
                           for i in range(n)) + f"TYPE Fz{n} : STRUCT a : INT; END_STRUCT; END_TYPE\n"
        else:
            text = "".join(_fb(f"Fz{i}", var=f"q : BOOL; f : Fz{i + 1};", body="f(); q := f.q;")
                           for i in range(n)) + _fb(f"Fz{n}", body="q := TRUE;")
        return text, "Fz0", None
    if kind == 16:                # a ring of structs pointing at the next
        return "".join(f"TYPE Fz{i} : STRUCT a : INT; p : POINTER TO Fz{(i + 1) % n}; "
                       "END_STRUCT; END_TYPE\n" for i in range(n)), "Fz0", None
    if kind == 17:                # deep type constructors
        m = rng.choice([n, 5000])
        return "", rng.choice([
            "ARRAY[0..1] OF " * m + "INT", "ARRAY[0..0] OF " * m + "INT",
            "POINTER TO " * m + "INT", "REFERENCE TO " * m + "INT",
            "ARRAY[" + ", ".join(["0..0"] * m) + "] OF INT",
            "STRUCT a : " * min(m, 2000) + "INT;" + " END_STRUCT;" * min(m, 2000)]), None
    if kind == 18:                # deep initialisers
        m = rng.choice([n, 5000])
        return "", rng.choice(["ARRAY[0..1] OF INT", "ARRAY[0..0] OF " * 8 + "INT", "INT"]), \
            rng.choice(["[" * m + "1" + "]" * m, "(a := " * m + "1" + ")" * m,
                        "[" + ", ".join(["1"] * m) + "]", "(" * m + "1" + ")" * m])
    if kind == 19:                # structs nested by name with an initialiser as deep
        text = "".join(f"TYPE Fz{i} : STRUCT a : INT; s : Fz{i + 1}; END_STRUCT; END_TYPE\n"
                       for i in range(n)) + f"TYPE Fz{n} : STRUCT a : INT; END_STRUCT; END_TYPE\n"
        return text, "Fz0", "(s := " * n + "(a := 3)" + ")" * n
    if kind == 20:                # what is no struct, extended
        base = rng.choice(["TYPE FzB : INT; END_TYPE\n", "TYPE FzB : ARRAY[0..1] OF INT; END_TYPE\n",
                           _fb("FzB"), "TYPE FzB : (x, y); END_TYPE\n", ""])
        return base + "TYPE FzS EXTENDS FzB : STRUCT a : INT; END_STRUCT; END_TYPE\n", "FzS", None
    if kind == 21:                # huge arrays and strings, repetition counts
        return "", rng.choice(["ARRAY[0..2147483647] OF BOOL", "ARRAY[0..99999999] OF LREAL",
                               "ARRAY[-2147483648..2147483647] OF INT", "STRING(2147483647)",
                               "ARRAY[0..9999, 0..9999] OF INT", "WSTRING(99999999)",
                               "ARRAY[1..100000] OF STRING(255)"]), \
            rng.choice([None, "[2147483647(0)]", "[100000000(1)]", "'x'"])
    if kind == 22:                # enums and subranges
        return rng.choice([
            "TYPE FzE : (a := 1, a := 2); END_TYPE\n", "TYPE FzE : (a := 99999999999999999999); END_TYPE\n",
            "TYPE FzE : INT (a := 1, b := 70000); END_TYPE\n", "TYPE FzE : INT(5..1); END_TYPE\n",
            "TYPE FzE : INT(0..99999999999); END_TYPE\n", "TYPE FzE : (" + ", ".join(
                f"e{i}" for i in range(n)) + "); END_TYPE\n"]), "FzE", None
    if kind == 23:                # a type named like a builtin, or a member like its type
        return rng.choice(["TYPE INT : STRUCT a : INT; END_STRUCT; END_TYPE\n",
                           "TYPE TON : BOOL; END_TYPE\n", _fb("TON", var="Q : BOOL;"),
                           "TYPE FzS : STRUCT FzS : FzS; END_STRUCT; END_TYPE\n"]), \
            rng.choice(["INT", "TON", "FzS"]), None
    if kind == 24:                # methods and properties recursing into themselves
        return (_fb("FzA", body="q := M();").replace(
            "END_FUNCTION_BLOCK", "METHOD M : BOOL\nM := M();\nEND_METHOD\nEND_FUNCTION_BLOCK")
                ), "FzA", None
    return "", "FzNowhere", None


POU_START = re.compile(r"^[ \t]*(PROGRAM|FUNCTION_BLOCK|FUNCTION|TYPE|INTERFACE|CONFIGURATION)\b",
                       re.M)
VAR_BLOCK = re.compile(r"\bVAR\b[ \t]*\r?\n")


def insert_type_trap(text: str, rng: random.Random) -> str:
    """The declarations of a :func:`type_trap` before the first POU or type of an ST text,
    and a variable of its type in the first VAR block after them (and a call of it, which
    is only valid for an FB)."""
    decls, var_type, init = type_trap(rng)
    m = POU_START.search(text)
    if m is None:
        return text
    text = text[:m.start()] + decls + text[m.start():]
    v = VAR_BLOCK.search(text, m.start() + len(decls))
    if v is not None:
        decl = f"    xFz : {var_type}" + (f" := {init}" if init is not None else "") + ";\n"
        text = text[:v.end()] + decl + text[v.end():]
    return text


def mutate_program(text: str, rng: random.Random) -> str:
    """One to three edits: delete, duplicate, swap or replace a token, insert a tricky
    token or a nested construct, or cut the file short. An ST text (one with a POU or type
    at a line's start) gets a type trap (:func:`insert_type_trap`) one time in five, and
    then half of the time nothing else, so that the trap reaches the type checks."""
    if rng.random() < 0.2 and POU_START.search(text):
        text = insert_type_trap(text, rng)
        if rng.random() < 0.5:
            return text
    for _ in range(rng.randint(1, 3)):
        words = re.split(r"(\s+)", text)
        spots = [i for i, w in enumerate(words) if w and not w.isspace()]
        if not spots:
            return text
        i = rng.choice(spots)
        op = rng.randrange(7)
        if op == 0:
            words[i] = ""
        elif op == 1:
            words[i] = words[i] + " " + words[rng.choice(spots)]
        elif op == 2:
            j = rng.choice(spots)
            words[i], words[j] = words[j], words[i]
        elif op in (3, 4):
            words[i] = rng.choice(TRICKY_TOKENS)
        elif op == 5:
            words[i] = words[i] + " " + nested(rng)
        else:
            return "".join(words)[:rng.randrange(len(text) + 1)]
        text = "".join(words)
    return text


# ------------------------------------------------------------------ machine files

ODD_VALUES = [
    10**400, -10**400, 1e308, -1.0, 0, 0.0, 1e-300, 5e-324, math.nan, math.inf, -math.inf,
    "text", "", "$\\alpha$", "$x$ $y", "a\nb", "𝑒𝑥𝑒𝑐", "x" * 5000, True, [], [1, 2, 3],
    {"a": 1}, 2**63, -(2**63), 1e9, 1e12, 3650 * 86400.0, 1e-9, "auto", ["a", "b"], "%QX0.0",
]


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f'"{k}" = {_toml_value(x)}' for k, x in v.items()) + "}"
    raise TypeError(type(v))


def dump_toml(data: dict) -> str:
    """Enough TOML for machine files: tables, arrays of tables, inline values."""
    out = []
    for key, value in data.items():
        if isinstance(value, dict):
            out.append(f"[{key}]")
            out += [f'"{k}" = {_toml_value(v)}' for k, v in value.items()]
        elif isinstance(value, list) and all(isinstance(x, dict) for x in value):
            for item in value:
                out.append(f"[[{key}]]")
                out += [f'"{k}" = {_toml_value(v)}' for k, v in item.items()]
        else:
            out.append(f'"{key}" = {_toml_value(value)}')
        out.append("")
    return "\n".join(out)


def mutate_machine(path: Path, rng: random.Random) -> str | bytes:
    """A machine file with one to three values replaced, keys removed or renamed, tables
    duplicated, or (sometimes) bytes that are not UTF-8. The program path is made
    absolute so the file can be written anywhere."""
    data = tomllib.loads(path.read_text(encoding="utf-8"))
    data["machine"]["program"] = str((path.parent / data["machine"]["program"]).resolve())
    for _ in range(rng.choice([1, 1, 2, 3])):
        tables = [data["machine"]] + data.get("input", []) + data.get("consumer", [])
        table = rng.choice(tables)
        keys = [k for k in table if k != "program"] or ["name"]
        numeric = [k for k in keys if isinstance(table[k], (int, float))
                   and not isinstance(table[k], bool) and abs(table[k]) < 1e300]
        key = rng.choice(keys)
        op = rng.randrange(12)
        if op < 6 and numeric:
            # a number scaled into odd but often still valid territory: deeper runs
            key = rng.choice(numeric)
            table[key] = table[key] * rng.choice([0.0, 1e-6, 1e-3, 0.5, 0.9, 1.1, 2.0, 1e3,
                                                  1e6, -1.0])
        elif op < 8:
            table[key] = rng.choice(ODD_VALUES)
        elif op == 8:
            table.pop(key, None)
        elif op == 9:
            table[key + "_typo"] = table.pop(key, 1)
        elif op == 10 and data.get("consumer"):
            data["consumer"].append(dict(rng.choice(data["consumer"])))
        else:
            table[key] = rng.choice(ODD_VALUES)
    text = dump_toml(data)
    if rng.random() < 0.03:
        raw = bytearray(text.encode())
        raw.insert(rng.randrange(len(raw)), rng.choice([0xff, 0xc3, 0x80, 0xfe]))
        return bytes(raw)
    return text


# ------------------------------------------------------------------ command lines

HORIZONS = ["1s", "20s", "0s", "-5s", "abc", "1e400s", "T#1s", "3650d", "1ns", "", "1.5h",
            "99999999999999999999d", "nan", "inf", "10s"]
DTS = ["10ms", "0s", "1ns", "-1s", "x", "1s", "100s", "1e-9s", "nan"]
SETTINGS = ["supply_bar_g=4,5", "supply_bar_g=nan", "supply_bar_g=-5", "A.bore_mm=-5",
            "A.bore_mm=1e400", "A.stroke_time_s=0.2/0.3", "scan_ms=0", "nozzle.C=abc",
            "program.X=';import os'", "program.BLOW_TIME=T#2s", "nosuch=1", "=", "a.b.c.d=1",
            "input.PB1.period_s=-1", "A.stroke_time_s=1e-300", "air knives.pressure_bar_g=2,3"]


def random_argv(rng: random.Random, machine: str, out_dir: Path, afile: Path) -> list[str]:
    command = rng.choice(["timeline", "predict", "size", "compare", "sweep", "check"])
    if command == "check":
        return ["check", rng.choice([str(p) for p in PROGRAM_FILES] + [machine, str(afile),
                                                                        "/nonexistent"])]
    argv = [command, rng.choice([machine, machine, str(afile), "/nonexistent.toml"])]
    if command == "compare":
        argv.append(rng.choice([machine, "/nonexistent.toml"]))
        if rng.random() < 0.5:
            argv += ["--max-increase", rng.choice(["2%", "0.5NL", "abc", "-1%", "nan%"])]
    argv += ["--horizon", rng.choice(HORIZONS)]
    if rng.random() < 0.5:
        argv += ["--dt", rng.choice(DTS)]
    if command in ("timeline", "predict", "size"):
        argv += ["--out", rng.choice([str(out_dir), str(afile), str(afile / "sub")])]
    if command == "sweep":
        argv += ["--set", rng.choice(SETTINGS)]
        if rng.random() < 0.3:
            argv += ["--workers", rng.choice(["0", "-1", "1", "x"])]
    if command == "size" and rng.random() < 0.5:
        argv += [rng.choice(["--allowance", "--band", "--hours", "--sec", "--price"]),
                 rng.choice(["-1", "nan", "abc", "1e400", "10%"])]
    if command == "predict":
        argv.append("--no-plot")
    return argv


# ------------------------------------------------------------------ running

class Hang(BaseException):  # not an Exception: the CLI must not catch it
    pass


@contextlib.contextmanager
def time_limit(seconds: float):
    def handler(signum, frame):
        raise Hang()
    previous = signal.signal(signal.SIGALRM, handler)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def run_program(text: str, suffix: str, seconds: float = 10.0) -> tuple[str, str]:
    """Parse, check, compile and run a few scans: ('ok' | 'clean' | 'traceback' | 'hang',
    detail)."""
    from plcpred.errors import PlcpredError
    from plcpred.parser.check import check_program
    from plcpred.parser.plcopen import parse_plcopen
    from plcpred.parser.seq import parse_seq
    from plcpred.parser.st import parse_st
    from plcpred.sequencer.executor import ProgramInstance

    parse = {".st": parse_st, ".seq": parse_seq, ".xml": parse_plcopen}[suffix]
    try:
        with time_limit(seconds):
            program = parse(text, "fuzz" + suffix)
            errors, _ = check_program(program)
            if errors:
                return "clean", str(errors[0])
            inst = ProgramInstance(program)
            for k in range(3):
                inst.scan(k * 10_000_000)
        return "ok", ""
    except Hang:
        return "hang", ""
    except PlcpredError as e:
        return "clean", str(e)
    except Exception as e:  # noqa: BLE001 - what the fuzzer is looking for
        return "traceback", f"{type(e).__name__}: {e}"[:300]


def run_cli(argv: list[str], seconds: float = 10.0) -> tuple[str, str]:
    """Run the command in-process: ('ok' | 'clean' | 'traceback' | 'hang', detail). Exit
    code 3 (internal error) and any exception escaping main count as tracebacks."""
    from plcpred import cli

    err = io.StringIO()
    try:
        with time_limit(seconds), contextlib.redirect_stdout(io.StringIO()), \
                contextlib.redirect_stderr(err):
            code = cli.main(argv)
    except Hang:
        return "hang", " ".join(argv)
    except SystemExit as e:  # argparse usage errors
        return ("clean" if e.code == 2 else "traceback"), err.getvalue()[-300:]
    except Exception as e:  # noqa: BLE001
        return "traceback", f"{type(e).__name__}: {e} <- {' '.join(argv)}"[:400]
    if code == 3:
        return "traceback", err.getvalue().strip()[-300:] + " <- " + " ".join(argv)
    return ("ok" if code == 0 else "clean"), err.getvalue()[-200:]


# ================================================================== the isolating harness

BAD = ("traceback", "hang", "memory", "unsafe")
OUTCOMES = ("ok", "clean") + BAD
# the folders a machine file written to a temporary folder may name programs in
ALLOW_ROOTS = os.pathsep.join([str(SAMPLES), str(ROOT / "tests" / "data")])
TRACEBACK = "Traceback (most recent call last)"


@dataclasses.dataclass
class Limits:
    seconds: float = 10.0         # wall time of one run: more is a hang
    rss_mb: float = 1500.0        # peak resident memory of the child: more is "memory"
    as_mb: float = 4096.0         # the child's address-space limit (RLIMIT_AS): a runaway
                                  # fails with MemoryError instead of taking the machine


@dataclasses.dataclass
class Outcome:
    outcome: str                  # one of OUTCOMES
    detail: str = ""
    rss_mb: float = 0.0           # the child's peak RSS (ru_maxrss)
    wall_s: float = 0.0
    stderr: str = ""              # the tail of what the run printed on stderr
    warnings: list = dataclasses.field(default_factory=list)   # Python warnings printed

    def __iter__(self):           # unpacks as (outcome, detail), as run_cli's result does
        return iter((self.outcome, self.detail))

    @property
    def bad(self) -> bool:
        return self.outcome in BAD


def _frames(tb_or_lines, limit: int = 3) -> str:
    """The innermost plcpred frames of a traceback, 'file.py:123 in f < ...'."""
    if isinstance(tb_or_lines, list):
        found = tb_or_lines
    else:
        found = [(f.filename, f.lineno, f.name) for f in traceback.extract_tb(tb_or_lines)]
    mine = [(fn, ln, name) for fn, ln, name in found if "plcpred" in fn and
            "/tests/" not in fn] or found
    parts = []
    for fn, ln, name in reversed(mine[-limit:]):
        short = fn[fn.rindex("plcpred"):] if "plcpred" in fn else os.path.basename(fn)
        parts.append(f"{short}:{ln} in {name}")
    return " < ".join(parts)


def describe_exception(e: BaseException) -> str:
    message = str(e).splitlines()[0][:200] if str(e) else ""
    return f"{type(e).__name__}{': ' + message if message else ''} @ {_frames(e.__traceback__)}"


def _read_tail(f, limit: int = 1 << 20) -> str:
    size = os.fstat(f.fileno()).st_size
    start = max(0, size - limit)
    return os.pread(f.fileno(), size - start, start).decode("utf-8", "replace")


def _dumped_frames(text: str) -> str:
    """The innermost plcpred frames of a faulthandler dump (most recent call first)."""
    frames = re.findall(r'File "([^"]+)", line (\d+) in (\S+)', text)
    found = [(fn, int(ln), name) for fn, ln, name in reversed(frames)]
    return _frames(found, 4) if found else text.strip()[:300]


class Child:
    """``fn()`` run in a forked child: stdin from /dev/null, stdout and stderr to
    temporary files, its own process group, RLIMIT_AS set, ``cwd`` and ``env`` applied
    (a value None unsets the variable). ``fn`` returns a dict: ``{"outcome", "detail"}``,
    or ``{"codes": [...]}`` for command lines (sorted by :func:`classify_exit`).
    :meth:`poll` enforces the limits; :meth:`finish` reaps the child and sorts the
    outcome."""

    def __init__(self, fn: Callable[[], dict], limits: Limits, cwd=None, env=None):
        self.limits = limits
        self.out = tempfile.TemporaryFile()
        self.err = tempfile.TemporaryFile()
        self.dump = tempfile.TemporaryFile()
        self.buf = bytearray()
        self.stopped: str | None = None
        self.polled_rss = 0
        rfd, wfd = os.pipe()
        for stream in (sys.stdout, sys.stderr):
            with contextlib.suppress(Exception):
                stream.flush()
        self.t0 = time.monotonic()
        pid = os.fork()
        if pid == 0:                                  # the child: never returns
            code = 70
            try:
                os.close(rfd)
                self._enter(cwd, env)
                try:
                    result = fn()
                except MemoryError as e:
                    result = {"outcome": "memory", "detail": describe_exception(e)}
                except BaseException as e:  # noqa: BLE001 - what the fuzzer looks for
                    traceback.print_exc()
                    result = {"outcome": "traceback", "detail": describe_exception(e)}
                for stream in (sys.stdout, sys.stderr):
                    with contextlib.suppress(Exception):
                        stream.flush()
                if isinstance(result.get("detail"), str):
                    result["detail"] = result["detail"][:4000]
                data = json.dumps(result, default=str).encode()[:60_000]
                os.write(wfd, data)
                code = 0
            finally:
                os._exit(code)
        os.close(wfd)
        os.set_blocking(rfd, False)
        self.pid, self.rfd = pid, rfd
        self.page = os.sysconf("SC_PAGE_SIZE")

    def _enter(self, cwd, env):
        os.setpgid(0, 0)
        signal.setitimer(signal.ITIMER_REAL, 0)
        for s in (signal.SIGALRM, signal.SIGINT, signal.SIGTERM, signal.SIGPIPE):
            signal.signal(s, signal.SIG_DFL)
        limit = int(self.limits.as_mb * 2**20)
        soft, hard = resource.getrlimit(resource.RLIMIT_AS)
        if hard != resource.RLIM_INFINITY:
            limit = min(limit, hard)
        resource.setrlimit(resource.RLIMIT_AS, (limit, hard))
        null = os.open(os.devnull, os.O_RDONLY)
        os.dup2(null, 0)
        os.dup2(self.out.fileno(), 1)
        os.dup2(self.err.fileno(), 2)
        sys.stdin = io.TextIOWrapper(io.FileIO(0, "r", closefd=False))
        sys.stdout = io.TextIOWrapper(io.FileIO(1, "w", closefd=False), write_through=True)
        sys.stderr = io.TextIOWrapper(io.FileIO(2, "w", closefd=False), write_through=True)
        sys.__stdout__, sys.__stderr__ = sys.stdout, sys.stderr
        faulthandler.enable(file=self.err, all_threads=True)        # SIGSEGV, SIGABRT
        faulthandler.register(signal.SIGUSR1, file=self.dump, all_threads=True)
        if cwd is not None:
            os.chdir(cwd)
        for k, v in (env or {}).items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v

    def fileno(self) -> int:
        return self.rfd

    def _read(self) -> None:
        while True:
            try:
                chunk = os.read(self.rfd, 65536)
            except BlockingIOError:
                return
            if not chunk:
                return
            self.buf += chunk

    def _rss(self) -> int:
        try:
            with open(f"/proc/{self.pid}/statm", "rb") as f:
                return int(f.read().split()[1]) * self.page
        except (OSError, IndexError, ValueError):
            return 0

    def _stop(self, why: str) -> None:
        """Dump the child's stack (faulthandler on SIGUSR1), then kill its group."""
        self.stopped = why
        with contextlib.suppress(ProcessLookupError):
            os.kill(self.pid, signal.SIGUSR1)
            end = time.monotonic() + 1.0
            while time.monotonic() < end and os.fstat(self.dump.fileno()).st_size == 0:
                time.sleep(0.02)
            time.sleep(0.05)
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(self.pid, signal.SIGKILL)

    def poll(self) -> bool:
        """True once the child has ended or been stopped for a limit."""
        self._read()
        if os.waitid(os.P_PID, self.pid, os.WEXITED | os.WNOHANG | os.WNOWAIT) is not None:
            return True
        if time.monotonic() - self.t0 > self.limits.seconds:
            self._stop("hang")
            return True
        rss = self._rss()
        self.polled_rss = max(self.polled_rss, rss)
        if rss > self.limits.rss_mb * 2**20:
            self._stop("memory")
            return True
        return False

    def wait(self) -> Outcome:
        while not self.poll():
            select.select([self.rfd], [], [], 0.02)
        return self.finish()

    def finish(self) -> Outcome:
        # the child (a zombie now, or killed) still holds its pid: its group is ours
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(self.pid, signal.SIGKILL)
        _, status, usage = os.wait4(self.pid, 0)
        wall = time.monotonic() - self.t0
        self._read()
        os.close(self.rfd)
        rss_mb = max(usage.ru_maxrss / 1024, self.polled_rss / 2**20)
        out, err = _read_tail(self.out), _read_tail(self.err)
        dump = _read_tail(self.dump)
        for f in (self.out, self.err, self.dump):
            f.close()
        warnings = re.findall(r"^\S+:\d+: (\w*Warning: .*)$", err, re.M)
        result = Outcome("traceback", "", rss_mb, wall, err[-20_000:], warnings)
        if self.stopped == "hang":
            result.outcome = "hang"
            result.detail = f"over {self.limits.seconds:g} s in {_dumped_frames(dump)}"
        elif self.stopped == "memory":
            result.outcome = "memory"
            result.detail = (f"RSS over {self.limits.rss_mb:g} MB in {_dumped_frames(dump)}")
        elif os.WIFSIGNALED(status):
            sig = signal.Signals(os.WTERMSIG(status)).name
            if os.WTERMSIG(status) == signal.SIGKILL:
                result.outcome, result.detail = "memory", "killed by SIGKILL (out of memory?)"
            else:
                frames = _dumped_frames(err) if "File " in err else err.strip()[-300:]
                result.detail = f"crashed with {sig} in {frames}"
        elif not self.buf:
            result.detail = (f"the child exited {os.WEXITSTATUS(status)} without a result: "
                             f"{err.strip()[-300:]}")
        else:
            try:
                data = json.loads(self.buf.decode("utf-8", "replace"))
            except ValueError:
                data = {"outcome": "traceback", "detail": "unreadable result: "
                        + self.buf[:200].decode("utf-8", "replace")}
            if "codes" in data:
                result.outcome, result.detail = classify_exit(data["codes"], out, err)
            else:
                result.outcome, result.detail = data["outcome"], data.get("detail", "")
        if result.outcome not in ("hang", "memory") and rss_mb > self.limits.rss_mb:
            result.outcome = "memory"
            result.detail = f"peak RSS {rss_mb:.0f} MB (limit {self.limits.rss_mb:g}); " \
                            + result.detail
        return result


# The executor reports any exception from a run as "run-time error: <its message>" (exit
# 1), the PLC's faults (division by zero, an index out of range, NULL) and its own bugs
# alike. Python's wording of what no PLC program can cause marks the second kind.
PY_LEAK = re.compile(
    r"run-time error: (?:name '[^']*' is not defined|.*referenced before assignment|"
    r".*cannot access local variable|.*unsupported operand type|.*object is not callable|"
    r".*positional argument|.*keyword argument|.*object is not subscriptable|"
    r".*not supported between instances|.*object has no attribute|.*is not iterable|"
    r".*unhashable type|.*can only concatenate|.*can't multiply sequence|"
    r".*object does not support item assignment|'[^']*'\s*$|"
    r"(?!ZeroDivisionError|IndexError|ValueError|OverflowError|RecursionError)"
    r"[A-Z]\w*(?:Error|Exception)\s*$)", re.M)


# Python's (and numpy's) wording in an error line: a bug caught by a broad ``except
# ValueError`` around a computation and printed as if it were the input's fault. The
# plant's "cannot integrate ... (ZeroDivisionError: ...)" names such an error on purpose.
PY_WORDING = re.compile(
    r"math domain error|operands could not be broadcast|cannot convert float \w+ to integer|"
    r"could not convert string to float|invalid literal for int\(\)|values to unpack|"
    r"array must not contain infs or NaNs|zero-size array to reduction|"
    r"index \d+ is out of bounds|list index out of range|tuple index out of range|"
    r"unsupported operand type|object is not subscriptable|object has no attribute|"
    r"'NoneType' object|referenced before assignment|must be real number, not|"
    r"cannot be interpreted as an integer|maximum recursion depth|int too large to convert|"
    r"Python int too large|float division by zero|integer division or modulo by zero|"
    r"not supported between instances|object is not iterable|unhashable type")


def _wording_leak(err: str) -> str | None:
    for line in err.splitlines():
        if "error" in line and "the plant cannot integrate" not in line and \
                "run-time error:" not in line and PY_WORDING.search(line):
            return line.strip()[:300]
    return None


def classify_exit(codes: list, out: str, err: str) -> tuple[str, str]:
    """The outcome of command lines that returned ``codes`` (one per run) and printed
    ``out`` and ``err``."""
    last = err.strip().splitlines()[-1][:300] if err.strip() else ""
    leak = PY_LEAK.search(err)
    if leak is not None:
        line = err[err.rfind("\n", 0, leak.start()) + 1:].split("\n", 1)[0]
        return "traceback", f"an internal error shown as a PLC run-time error: {line[:300]}"
    wording = _wording_leak(err)
    if wording is not None and any(c != 0 for c in codes):
        return "traceback", f"Python's wording in an error message: {wording}"
    if TRACEBACK in err:
        i = err.rindex(TRACEBACK)
        frames = re.findall(r'File "([^"]+)", line (\d+), in (\S+)', err[i:])
        tail = err[i:].strip().splitlines()[-1][:200]
        return "traceback", f"{tail} @ {_frames([(f, int(n), m) for f, n, m in frames])}"
    if 3 in codes:
        return "traceback", f"exit 3: {last}"
    if "out of memory" in err and 2 in codes:
        return "memory", last
    if all(c == 0 for c in codes):
        return "ok", last
    odd = [c for c in codes if c not in (0, 1, 2, 4, 5)]
    if odd:
        return "traceback", f"exit {odd[0]}: {last}"
    if not (out.strip() or err.strip()):
        return "traceback", f"exit {max(codes)} without a message"
    return "clean", last


def _cli_child(argvs: list[list[str]]) -> Callable[[], dict]:
    """Run each command line in turn with ``--debug`` (an internal error then escapes main,
    with its frames); stop after one that fails with 3."""
    def run() -> dict:
        from plcpred import cli
        codes = []
        for argv in argvs:
            try:
                code = cli.main(list(argv) + ["--debug"])
            except SystemExit as e:       # argparse: 2 (usage), 0 (--help)
                code = e.code if isinstance(e.code, int) else (0 if e.code is None else 2)
            codes.append(code)
            if code == 3:
                break
        return {"codes": codes}
    return run


def _program_child(text: str, suffix: str) -> Callable[[], dict]:
    """Parse, check, compile and run a few scans (what :func:`run_program` does)."""
    def run() -> dict:
        from plcpred.errors import PlcpredError
        from plcpred.parser.check import check_program
        from plcpred.parser.plcopen import parse_plcopen
        from plcpred.parser.seq import parse_seq
        from plcpred.parser.st import parse_st
        from plcpred.sequencer.executor import ProgramInstance

        from plcpred.sequencer.runtime import PLC_EXCEPTIONS, null_access

        parse = {".st": parse_st, ".seq": parse_seq, ".xml": parse_plcopen}[suffix]
        try:
            program = parse(text, "fuzz" + suffix)
            errors, _ = check_program(program)
            if errors:
                return {"outcome": "clean", "detail": str(errors[0])[:300]}
            inst = ProgramInstance(program)
            for k in range(3):     # as the sequencer runs it: exceptions as run-time errors
                inst.guard(inst.scan, k * 10_000_000)
        except PlcpredError as e:
            cause = e.__context__  # what compiled code raised, if this is a run-time error
            if cause is not None and "run-time error" in str(e) and (
                    not isinstance(cause, PLC_EXCEPTIONS) or
                    (isinstance(cause, AttributeError) and not null_access(cause))):
                traceback.print_exception(cause)
                return {"outcome": "traceback", "detail": "an internal error shown as a PLC "
                        f"run-time error: {describe_exception(cause)}"}
            return {"outcome": "clean", "detail": str(e)[:300]}
        return {"outcome": "ok", "detail": ""}
    return run


def isolated_cli(argv: list[str], limits: Limits | None = None, cwd=None,
                 env=None) -> Outcome:
    """``plcpred ARGV`` in a forked child under ``limits``."""
    return Child(_cli_child([argv]), limits or Limits(), cwd, env).wait()


def isolated_program(text: str, suffix: str, limits: Limits | None = None) -> Outcome:
    """:func:`run_program` in a forked child under ``limits``."""
    return Child(_program_child(text, suffix), limits or Limits()).wait()


_WARM = False


def warm_up() -> None:
    """Import what the commands import and run each front end and the main commands once,
    in the parent, so that each forked child starts with it all loaded (the ST grammar
    alone takes 0.1 s to load: a fork is a few milliseconds)."""
    global _WARM
    if _WARM:
        return
    import importlib
    import pkgutil

    import plcpred
    os.environ.setdefault("MPLBACKEND", "Agg")
    for mod in pkgutil.walk_packages(plcpred.__path__, "plcpred."):
        if mod.name.endswith("__main__"):
            continue
        with contextlib.suppress(Exception):
            importlib.import_module(mod.name)
    with contextlib.suppress(Exception):
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot  # noqa: F401
    for path in PROGRAM_FILES:
        with contextlib.suppress(Exception):
            run_program(path.read_text(), path.suffix, 30.0)
    from plcpred import cli
    press = str(SAMPLES / "press.toml")
    with tempfile.TemporaryDirectory(prefix="plcpred-warm-") as tmp:
        for argv in (["check", str(SAMPLES / "twincat_project")],
                     ["timeline", str(SAMPLES / "twincat_station.toml"), "--horizon", "1s",
                      "--out", f"{tmp}/t"],
                     ["predict", press, "--horizon", "1s", "--out", f"{tmp}/p"],
                     ["emulate", press, "--horizon", "1s", "--out", f"{tmp}/e"],
                     ["diagnose", str(SAMPLES / "prototype_rig/rig.toml"), "--measured",
                      str(SAMPLES / "prototype_rig/seq1_measured.csv"), "--no-plant"]):
            with contextlib.suppress(BaseException), \
                    contextlib.redirect_stdout(io.StringIO()), \
                    contextlib.redirect_stderr(io.StringIO()):
                cli.main(argv)
    _WARM = True


# ================================================================== channels

@dataclasses.dataclass
class Case:
    """One run: the inputs are written into ``work`` (the child's working folder)."""
    channel: str
    work: Path
    argvs: list = dataclasses.field(default_factory=list)   # command lines, run in turn
    program: tuple | None = None          # (text, suffix) for the programs channel
    env: dict = dataclasses.field(default_factory=dict)
    check: Callable[[], str | None] | None = None           # after the run: what is unsafe
    note: str = ""                        # what the mutator did (for the report)

    def describe(self) -> str:
        if self.program is not None:
            return f"program{self.program[1]} ({len(self.program[0])} chars) {self.note}"
        return " && ".join("plcpred " + shlex.join(a) for a in self.argvs) + \
            (f"   [{self.note}]" if self.note else "")

    def child(self, limits: Limits) -> Child:
        if self.program is not None:
            (self.work / ("program" + self.program[1])).write_text(self.program[0],
                                                                    errors="surrogatepass")
            return Child(_program_child(*self.program), limits, self.work, self.env)
        (self.work / "argv.txt").write_text(
            "\n".join(shlex.join(["plcpred", *a]) for a in self.argvs) + "\n")
        return Child(_cli_child(self.argvs), limits, self.work, self.env)

    def run(self, limits: Limits | None = None) -> Outcome:
        outcome = self.child(limits or Limits()).wait()
        return self.judge(outcome)

    def judge(self, outcome: Outcome) -> Outcome:
        if self.check is not None:
            harm = self.check()
            if harm:
                outcome.outcome, outcome.detail = "unsafe", harm + " | " + outcome.detail
        return outcome


def _write(path: Path, content) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content, encoding="utf-8", errors="surrogatepass")
    return path


def _machine_data(path: Path) -> dict:
    """A sample machine file with its program (and libraries) named by absolute paths, so
    that it can be written anywhere (ALLOW_ROOTS lets the samples be read)."""
    data = tomllib.loads(path.read_text(encoding="utf-8"))
    data["machine"]["program"] = str((path.parent / data["machine"]["program"]).resolve()) \
        + ("/" if data["machine"]["program"].endswith("/") else "")
    if "libraries" in data["machine"]:
        data["machine"]["libraries"] = [str((path.parent / p).resolve())
                                        for p in data["machine"]["libraries"]]
    return data


def _damage_text(text: str, rng: random.Random) -> str | bytes:
    """Text-level damage to a TOML or CSV file: a byte that is not UTF-8, a cut, a line
    doubled, a NUL, a BOM in the middle."""
    op = rng.randrange(6)
    if op == 0:
        raw = bytearray(text.encode("utf-8", "surrogatepass"))
        raw.insert(rng.randrange(len(raw) + 1), rng.choice([0xff, 0xc3, 0x80, 0xfe, 0xed]))
        return bytes(raw)
    if op == 1:
        return text[:rng.randrange(len(text) + 1)]
    lines = text.splitlines(keepends=True) or [""]
    i = rng.randrange(len(lines))
    if op == 2:
        lines.insert(i, lines[i])
    elif op == 3:
        lines[i] = lines[i][:len(lines[i]) // 2] + "\x00" + lines[i][len(lines[i]) // 2:]
    elif op == 4:
        lines.insert(i, "\ufeff")
    else:
        lines[i] = lines[i].replace("=", "==", 1).replace(",", ",,", 1)
    return "".join(lines)


# ------------------------------------------------------------------ truth files

CONSUMER_KEYS = {   # key: (low, high) of a plausible value, or a list of choices
    "bore_mm": (8, 100), "rod_mm": (3, 40), "stroke_mm": (5, 500), "tube_id_mm": (2, 10),
    "tube_length_m": (0, 5), "stroke_time_s": (0.02, 2), "switch_delay_s": (0, 0.05),
    "payload_kg": (0, 50), "mount_angle_deg": (-90, 90), "moving_mass_kg": (0.01, 10),
    "supply_C": (1e-9, 1e-7), "supply_b": (0, 0.6), "supply_m": (0.3, 0.9),
    "exhaust_C": (1e-10, 1e-7), "exhaust_b": (0, 0.6), "exhaust_m": (0.3, 0.9),
    "check_valve": [True, False], "friction_coulomb_n": (0, 300),
    "friction_static_n": (0, 400), "friction_viscous_ns_m": (0, 500),
    "stribeck_velocity_m_s": (0.001, 0.1), "spring_n": (0, 200), "switch_ramp_s": (0, 0.05),
    "heat_transfer_w_m2k": (0, 200), "dead_volume_cm3": (0, 100), "exhaust_tau_s": (0, 2),
    "partial_strokes": [True, False], "C": (1e-11, 1e-7), "b": (0, 0.6), "m": (0.3, 1),
    "a": (0.6, 1), "orifice_mm": (0.05, 5), "Cd": (0.3, 1), "pressure_bar_g": (0.5, 8),
    "flow_model": ["iso6358", "choked", "bogus"], "initial": ["retracted", "extended", "x"],
    "kind": ["leak", "nozzle", "double_acting", "single_acting", "double_rod", "rodless",
             "semi_rotary", "gripper", "bogus"],
}
LINE_KEYS = {"volume_l": (0.01, 10), "pressure_bar_g": (1, 8), "network_bar_g": (2, 10),
             "C": (1e-9, 1e-6), "b": (0, 0.6), "m": (0.3, 1), "droop_bar": (0, 1),
             "check_valves": [True, False]}
METER_KEYS = {"tau_s": (0, 2), "rate_hz": (0.1, 100), "noise_l_min": (0, 10),
              "offset_l_min": (-5, 5), "full_scale_l_min": (1, 2000),
              "reference": ["iso8778", "din1343", "iso2533", "bogus", ""],
              "sampling": ["mean", "instant", "bogus"]}
MACHINE_KEYS = {"supply_bar_g": (0.5, 10), "scan_ms": (1, 100), "atmosphere_kpa": (60, 110),
                "ambient_c": (-40, 100)}
INPUT_KEYS = {"period_s": (0.1, 10), "offset_s": (0, 5), "pulse_ms": (1, 2000),
              "jitter_s": (0, 1), "seed": (0, 99), "initial": [True, False],
              "pulses_s": (0, 5)}
ODD_NUMBERS = [0, 0.0, -1.0, -0.0, math.nan, math.inf, -math.inf, 1e308, -1e308, 1e-300,
               5e-324, 1e9, 1e12, 10**400, -(10**400), 2**63, 1e-9]
NAMES = ["hidden leak", "A", "", " ", "x" * 300, "𝑒𝑥𝑒𝑐", "é", "a\nb", "leak", "other",
         "\x00", "$\\alpha$", "../etc", "L1", "Y_A"]


CYLINDER_KEYS = {"bore_mm", "rod_mm", "stroke_mm", "tube_id_mm", "tube_length_m",
                 "stroke_time_s", "switch_delay_s", "payload_kg", "mount_angle_deg",
                 "moving_mass_kg", "supply_C", "supply_b", "supply_m", "exhaust_C", "exhaust_b",
                 "exhaust_m", "check_valve", "friction_coulomb_n", "friction_static_n",
                 "friction_viscous_ns_m", "stribeck_velocity_m_s", "spring_n", "switch_ramp_s",
                 "heat_transfer_w_m2k", "dead_volume_cm3", "exhaust_tau_s", "partial_strokes",
                 "initial"}
FLOW_KEYS = {"C", "b", "m", "a", "orifice_mm", "Cd", "pressure_bar_g", "flow_model"}
# keys that take a number or [cap, rod] / [extend, retract]
LISTABLE = {"tube_length_m", "stroke_time_s", "supply_C", "supply_b", "supply_m", "exhaust_C",
            "exhaust_b", "exhaust_m", "friction_coulomb_n", "spring_n", "dead_volume_cm3"}


def _value(spec, rng: random.Random, current=None, listable: bool = False):
    """Mostly a plausible value (or the current one scaled), sometimes an odd number,
    rarely a value of the wrong type."""
    r = rng.random()
    if r < 0.05:
        return rng.choice(ODD_VALUES)
    if r < 0.15:
        return rng.choice(ODD_NUMBERS)
    if isinstance(spec, list):
        return rng.choice(spec)
    if isinstance(current, (int, float)) and not isinstance(current, bool) and \
            rng.random() < 0.4 and abs(current) < 1e300:
        return current * rng.choice([0.0, 0.1, 0.5, 0.9, 1.1, 2.0, 10.0])
    if isinstance(current, list) and current and rng.random() < 0.4:
        return [_value(spec, rng, x) for x in current]
    lo, hi = spec
    v = rng.uniform(lo, hi) if lo <= 0 or hi / lo < 1e3 else \
        math.exp(rng.uniform(math.log(lo), math.log(hi)))
    if listable and rng.random() < 0.3:
        return [v, _value(spec, rng)]
    return round(v, 4) if v > 1e-3 else v


def mutate_truth(machine: dict, rng: random.Random, base: dict | None = None) -> dict:
    """A truth file (a partial machine file) for ``machine``: overrides of its consumers'
    keys, new leaks and nozzles, ``[[line]]`` tables, ``[meter]``, ``[machine]`` and
    ``[[input]]`` overrides, odd names and tables; starting from ``base`` (another truth)
    when given."""
    truth = json.loads(json.dumps(base)) if base else {}
    consumers = machine.get("consumer", [])
    names = [c["name"] for c in consumers] or ["A"]
    valves = [c["valve"] for c in consumers if isinstance(c.get("valve"), str)] or ["qX"]
    lines = [l.get("name") for l in truth.get("line", [])]
    for _ in range(rng.choice([1, 1, 2, 3])):
        op = rng.choices(range(12), [30, 15, 8, 8, 8, 12, 4, 10, 1, 4, 1, 2])[0]
        if op <= 2:         # override a consumer's keys (mostly ones its kind takes)
            name = rng.choice(names)
            current = next((c for c in consumers if c["name"] == name), {})
            if rng.random() < 0.1:
                keys = sorted(CONSUMER_KEYS)
            elif current.get("kind") in ("nozzle", "leak"):   # the family it already has
                keys = ["pressure_bar_g", "flow_model", "a"] + (
                    ["C", "b", "m"] if "C" in current else ["orifice_mm", "Cd"])
            else:
                keys = sorted(CYLINDER_KEYS - ({"spring_n"} if current.get("kind") !=
                                               "single_acting" else set()))
            entry = {"name": name}
            for key in rng.sample(keys, rng.randint(1, 3)):
                entry[key] = _value(CONSUMER_KEYS[key], rng, current.get(key),
                                    key in LISTABLE)
            if rng.random() < 0.2:
                entry["line"] = rng.choice(lines + ["nosuch", ""] if lines else ["nosuch"])
            truth.setdefault("consumer", []).append(entry)
        elif op == 3:       # a hidden leak
            leak = {"name": rng.choice(NAMES) if rng.random() < 0.2 else
                    f"leak {rng.randrange(99)}",
                    "kind": rng.choice(["leak"] * 6 + ["nozzle", "bogus"])}
            if rng.random() < 0.6:
                leak["C"], leak["b"] = _value(CONSUMER_KEYS["C"], rng), _value((0, 0.6), rng)
            else:
                leak["orifice_mm"], leak["Cd"] = _value((0.05, 3), rng), _value((0.3, 1), rng)
            if rng.random() < 0.3:
                leak["pressure_bar_g"] = _value((0.5, 10), rng)
            if rng.random() < 0.2:
                leak["line"] = rng.choice(lines + ["nosuch"])
            if rng.random() < 0.1:
                leak["valve"] = rng.choice(valves)
            truth.setdefault("consumer", []).append(leak)
        elif op == 4:       # a new nozzle or drive on an existing or unknown valve
            kind = rng.choice(["nozzle", "double_acting", "single_acting", "gripper"])
            new = {"name": f"new {rng.randrange(99)}", "kind": kind,
                   "valve": rng.choice(valves + ["nosuch", "%QX0.0", ""])}
            if kind == "nozzle":
                new["orifice_mm"], new["Cd"] = _value((0.1, 3), rng), 0.7
            elif rng.random() < 0.3:
                new["switches"] = {"retracted": rng.choice(valves + ["nosuch"]),
                                   "extended": rng.choice(valves + ["nosuch"])}
            else:
                new.update(bore_mm=_value((8, 80), rng), rod_mm=_value((3, 20), rng),
                           stroke_mm=_value((5, 200), rng))
                if rng.random() < 0.5:
                    new["stroke_time_s"] = _value((0.05, 1), rng)
            truth.setdefault("consumer", []).append(new)
        elif op in (5, 6):  # a supply line
            name = rng.choice(["L1", "L2", f"L{rng.randrange(9)}"] * 4 + ["", "𝑒𝑥𝑒𝑐"])
            line = {"name": name}
            for key in rng.sample(sorted(LINE_KEYS), rng.randint(1, 4)):
                line[key] = _value(LINE_KEYS[key], rng)
            truth.setdefault("line", []).append(line)
            lines.append(name)
            for cname in rng.sample(names, rng.randint(0, len(names))):
                truth.setdefault("consumer", []).append({"name": cname, "line": name})
        elif op == 7:       # the meter
            meter = truth.setdefault("meter", {})
            for key in rng.sample(sorted(METER_KEYS), rng.randint(1, 3)):
                meter[key] = _value(METER_KEYS[key], rng)
            if rng.random() < 0.1:
                meter["line"] = rng.choice(lines + ["nosuch"])
        elif op == 8:       # the machine
            m = truth.setdefault("machine", {})
            key = rng.choice(sorted(MACHINE_KEYS) + ["program", "name", "cycle_signal",
                                                     "libraries", "bogus"])
            if key == "program":
                m[key] = rng.choice(["/etc/passwd", "../x.st", "/dev/zero", "",
                                     str(rng.choice(PROGRAM_FILES)), "nosuch.st"])
            elif key == "libraries":
                m[key] = rng.choice([["/"], [".."], ["/etc/hostname"], [], "x"])
            elif key in MACHINE_KEYS:
                m[key] = _value(MACHINE_KEYS[key], rng, machine["machine"].get(key))
            else:
                m[key] = rng.choice(ODD_VALUES + valves)
        elif op == 9:       # an input
            inputs = machine.get("input", [])
            signal_ = rng.choice([i["signal"] for i in inputs] + ["nosuch", "%IX0.0"]) \
                if inputs else "nosuch"
            entry = {"signal": signal_}
            for key in rng.sample(sorted(INPUT_KEYS), rng.randint(1, 2)):
                entry[key] = _value(INPUT_KEYS[key], rng)
            truth.setdefault("input", []).append(entry)
        elif op == 10:      # signals, calendar, unknown tables
            key = rng.choice(["signals", "calendar", "bogus", "plant"])
            truth[key] = {rng.choice(["%IX0.0", "x", "shifts_per_day", "idle_state"]):
                          rng.choice(ODD_VALUES + valves)}
        else:               # the same consumer twice, or a consumer without a name
            if truth.get("consumer"):
                c = dict(rng.choice(truth["consumer"]))
                if rng.random() < 0.5:
                    c.pop("name", None)
                truth["consumer"].append(c)
    return truth


def _truth_case(rng: random.Random, work: Path) -> Case:
    path = rng.choice(MACHINE_FILES)
    machine = _machine_data(path)
    base = None
    if path.name == "rig.toml" and rng.random() < 0.4:
        base = tomllib.loads((ROOT / "tests/data/plant/rig_two_lines.truth.toml").read_text())
    truth = mutate_truth(machine, rng, base)
    text = dump_toml(truth)
    if rng.random() < 0.05:
        text = _damage_text(text, rng)
    m = _write(work / "m.toml", dump_toml(machine))
    t = _write(work / "truth.toml", text)
    argv = ["emulate", str(m), "--truth", str(t), "--horizon", "2s", "--out", str(work / "o")]
    if rng.random() < 0.9:
        argv.append("--no-plot")
    if rng.random() < 0.1:
        argv += ["--seed", rng.choice(["0", "7", "-1", "99999999999999999999", "x"])]
    return Case("truths", work, [argv], env={"PLCPRED_ALLOW_ROOTS": ALLOW_ROOTS},
                note=path.name)


# ------------------------------------------------------------------ flow logs and --io traces

FLOW_BASE_MACHINES = ["prototype_rig/rig.toml", "pick_place.toml", "clamp_station.toml",
                      "twincat_station.toml"]
TIME_NAMES = ["time_s", "Time", "Timestamp", "Zeit", "t_ms", "Zeit [ms]", "time (min)",
              "Time [s]", "zeit", "TIME_S", "", "time_s ", "Datum/Zeit", "t", "time_s;flow"]
FLOW_NAMES = ["flow_l_min", "Flow", "Flow (m3/h)", "Durchfluss [l/min]", "Volumenstrom",
              "Debit", "flow [scfm]", "Flow (l/s)", "flow (NL/min)", "Flow (furlong/s)", "",
              "flow_l_min ", "Durchfluß [m³/h]", "Q", "flow_l_min,x"]
ODD_CELLS = ["NaN", "nan", "inf", "-inf", "Infinity", "1e308", "-1e308", "1e309", "1e-320",
             "", " ", "abc", "--1", "1.2.3", "0x1F", "١٢", "\u22125", "1_0", "1e", "e5", ".",
             "-", "+", '""', "'5'", "1" * 400, "9" * 5000, "TRUE", "null", "#N/A", "\x00",
             "5\x00", "1,5", "1.234,5", " 7 ", "+5", "2.5E+01", "１２", "½", "1e10", "-0"]
IO_SIGNALS = ["nosuch", "%QX9.9", "%IX0.0", "a[99]", "fb.q", "wOut.3", "𝑒𝑥𝑒𝑐", "x" * 300,
              "Line.fbCyl[3].q", "Y_A.0", "é", "a b", "%MW5"]
IO_TIMES = ["1e10", "1e300", "-1", "NaN", "inf", "-inf", "", "abc", "-0", "1e-300", "3e8",
            "315360001", "0x10", "1,5", "9" * 400]
IO_VALUES = ["2", "-1", "0.5", "TRUE", "true", "x", "", "1e308", "nan", "01", " 1", "inf",
             "255", "-32768", "1e-300", "1e309"]
BOMS = [b"\xef\xbb\xbf", b"\xff\xfe", b"\xfe\xff", b"\xff\xfe\x00\x00"]


@dataclasses.dataclass
class FlowBase:
    """A machine and what emulating it logged: a flow log and its I/O trace."""
    name: str
    machine: str            # the machine file's text (program by absolute path)
    measured: str           # measured.csv
    timeline: str           # timeline.csv
    valves: list


def make_flow_bases(folder: Path, limits: Limits | None = None) -> list[FlowBase]:
    """Emulate each of FLOW_BASE_MACHINES for a few seconds (in a child) for the base
    logs; plus the prototype rig's measured sequence 1 (no trace)."""
    bases = []
    for k, rel in enumerate(FLOW_BASE_MACHINES):
        data = _machine_data(SAMPLES / rel)
        d = folder / f"base{k}"
        m = _write(d / "m.toml", dump_toml(data))
        argv = ["emulate", str(m), "--horizon", "6s", "--out", str(d / "o"), "--no-plot",
                "--seed", str(k)]
        outcome = isolated_cli(argv, limits or Limits(seconds=60), d,
                               {"PLCPRED_ALLOW_ROOTS": ALLOW_ROOTS})
        if outcome.outcome != "ok":
            raise RuntimeError(f"cannot make the base flow log of {rel}: {outcome.detail}")
        valves = [c["valve"] for c in data.get("consumer", []) if isinstance(c.get("valve"), str)]
        bases.append(FlowBase(rel, m.read_text(), (d / "o/measured.csv").read_text(),
                              (d / "o/timeline.csv").read_text(), valves))
    rig = bases[0]
    bases.append(FlowBase("seq1_measured", rig.machine,
                          (SAMPLES / "prototype_rig/seq1_measured.csv").read_text(), "",
                          rig.valves))
    return bases


def _csv_rows_of(text: str) -> tuple[list[str], list[list[str]]]:
    lines = [l for l in text.splitlines() if l.strip()]
    return lines[0].split(","), [l.split(",") for l in lines[1:]]


def _to_bytes(text: str, rng: random.Random) -> bytes:
    """The file's text, encoded; sometimes with a BOM, as UTF-16/32, or with junk."""
    r = rng.random()
    if r < 0.04:
        return rng.choice(BOMS) + text.encode("utf-8", "surrogatepass")
    if r < 0.07:
        return text.encode(rng.choice(["utf-16", "utf-16-le", "utf-32", "utf-8-sig"]),
                           "surrogatepass")
    if r < 0.09:
        return text.encode("latin-1", "replace")
    data = text.encode("utf-8", "surrogatepass")
    if r < 0.13:
        junk = bytes(rng.randrange(256) for _ in range(rng.choice([1, 16, 300])))
        at = rng.choice([0, len(data), rng.randrange(len(data) + 1)])
        return data[:at] + junk + data[at:]
    if r < 0.15:
        return b""
    if r < 0.16:
        return rng.choice(BOMS)
    return data


def _time_text(t: float, style: str) -> str:
    start = datetime.datetime(2026, 11, 24, 13, 5, 0)
    at = start + datetime.timedelta(seconds=max(min(t, 1e9), -1e9))
    if style == "iso":
        return at.isoformat(timespec="milliseconds")
    if style == "iso_z":
        return at.isoformat(timespec="milliseconds") + rng_tz(t)
    if style == "german":
        return at.strftime("%d.%m.%Y %H:%M:%S") + f",{at.microsecond // 100000}"
    if style == "us":
        return at.strftime("%m/%d/%Y %I:%M:%S %p")
    if style == "tod":
        return at.strftime("%H:%M:%S") + f".{at.microsecond // 1000:03d}"
    if style == "ms":
        return f"{t * 1000:.0f}"
    if style == "min":
        return f"{t / 60:.6f}"
    return f"{t:.4f}"


def rng_tz(t: float) -> str:
    return ["Z", "+01:00", "-05:30", "+99:00"][int(abs(t) * 10) % 4]


def mutate_flow_log(text: str, rng: random.Random) -> tuple[str | bytes, list[str]]:
    """A measured flow log (CSV) with one to three edits: headers, time formats and units,
    decimal commas and separators, odd cells, times out of order or far away, rows
    removed, ragged or doubled, preambles; then sometimes a BOM, another encoding or
    junk bytes. Returns the file and the options (--time-col, --flow-unit, ...) that
    might go with it."""
    header, rows = _csv_rows_of(text)
    times = []
    for r in rows:
        try:
            times.append(float(r[0]))
        except (ValueError, IndexError):
            times.append(0.0)
    sep, eol, comma, preamble, options, headless = ",", "\n", False, [], [], False
    for _ in range(rng.choice([1, 1, 2, 3])):
        op = rng.randrange(14)
        if op == 0:
            header[0] = rng.choice(TIME_NAMES)
        elif op == 1 and len(header) > 1:
            header[1] = rng.choice(FLOW_NAMES)
        elif op == 2:      # another time format, its header to match
            style = rng.choice(["iso", "iso_z", "german", "us", "tod", "ms", "min"])
            header[0] = {"ms": rng.choice(["t_ms", "Zeit [ms]", "time_s"]),
                         "min": rng.choice(["time (min)", "Zeit (min)"])}.get(
                style, rng.choice(["Timestamp", "Zeit", "Time", "time_s"]))
            for r, t in zip(rows, times):
                if r:
                    r[0] = _time_text(t, style)
            if style == "german":
                sep = ";"
        elif op == 3:      # decimal commas with ; (or without)
            comma = True
            sep = rng.choice([";", ";", ",", "\t"])
        elif op == 4 and rows:
            r = rng.choice(rows)
            if r:
                r[rng.randrange(len(r))] = rng.choice(ODD_CELLS)
        elif op == 5 and rows:     # times: negative, out of order, far, repeated
            how = rng.randrange(8)
            if how == 0:
                for r in rows:
                    if r and not r[0].startswith("-"):
                        r[0] = "-" + r[0]
            elif how == 1:
                i, j = rng.randrange(len(rows)), rng.randrange(len(rows))
                rows[i], rows[j] = rows[j], rows[i]
            elif how == 2:
                rows.reverse()
            elif how == 3:
                r = rng.choice(rows)
                if r:
                    r[0] = rng.choice(["1e10", "1e300", "-1", "NaN", "1e308", "3.2e8", "inf"])
            elif how == 4:
                k = rng.randrange(len(rows))
                rows.insert(k, list(rows[k]))
            elif how == 5:
                scale = rng.choice([1e-9, 1e-6, 1e6, 1e9])
                for r, t in zip(rows, times):
                    if r:
                        r[0] = repr(t * scale)
            elif how == 6:         # a logger's clock: time of day, days in, an epoch
                shift = rng.choice([47_100.0, 1e5, 3e6, 1.7e9])
                for r, t in zip(rows, times):
                    if r:
                        r[0] = f"{t + shift:.3f}"
                options += ["--offset", rng.choice(["0", f"{shift - 2:.3f}", "5"])]
            else:
                first = next((r[0] for r in rows if r), "0")
                for r in rows:
                    if r:
                        r[0] = first
        elif op == 6:      # few rows
            rows = rows[:rng.choice([0, 1, 2, 3, 4])]
        elif op == 7 and rows:     # ragged rows, trailing separators, blank or comment lines
            k = rng.randrange(len(rows))
            rows[k] = rng.choice([rows[k][:1], rows[k] + ["x"], rows[k] + [""], [],
                                  ["# comment"], ['"' + "".join(rows[k][:1])]])
        elif op == 8:      # a preamble (a logger's device lines), sometimes long
            preamble = [rng.choice(["Device: FlowMeter 3000", "Serial;12345", "",
                                    "Exported 24.11.2026", "time_s,flow_l_min"])
                        for _ in range(rng.choice([1, 3, 49, 50, 51, 200]))]
        elif op == 9:      # the supply column: odd, missing, extra columns
            how = rng.randrange(3)
            if how == 0 and len(header) > 2:
                for r in rows:
                    if len(r) > 2:
                        r[2] = rng.choice(["nan", "1e9", "-1", "4,0", "", "6.0"])
            elif how == 1:
                header.append(rng.choice(["supply_bar_g", "comment", "flow_l_min", "time_s"]))
                for r in rows:
                    r.append(rng.choice(["1", "x", "", "5.5"]))
            else:
                header = header[:2]
                rows = [r[:2] for r in rows]
        elif op == 10:     # line endings
            eol = rng.choice(["\r\n", "\r", "\n\n", "\n\r\n"])
        elif op == 11 and rows:    # a huge cell, or a line past the line limit
            r = rng.choice(rows)
            if r:
                r[rng.randrange(len(r))] = rng.choice(["1" * 5000, "x" * 150_000,
                                                       "9" * 100_001])
        elif op == 12:     # no header, or the header twice
            if rng.random() < 0.5:
                headless = True
            else:
                rows.insert(rng.randrange(len(rows) + 1), list(header))
        else:              # options for the columns and units
            options += rng.choice([
                ["--time-col", rng.choice(["0", "1", "-1", "99", "nosuch", "", "time_s",
                                           "Zeit [ms]", "2"])],
                ["--flow-col", rng.choice(["0", "1", "2", "-1", "nosuch", "flow_l_min", ""])],
                ["--supply-col", rng.choice(["2", "supply_bar_g", "nosuch", "0"])],
                ["--flow-unit", rng.choice(["l/min", "m3/h", "l/s", "scfm"])]])
    body = ([] if headless else [header]) + rows
    if comma:
        body = [[c.replace(".", ",") for c in r] for r in body]
    text = eol.join(preamble + [sep.join(r) for r in body]) + (eol if rng.random() < 0.9 else "")
    return _to_bytes(text, rng), options


def mutate_io_trace(text: str, valves: list, rng: random.Random) -> str | bytes:
    """An I/O trace (time_s,signal,value) with one to three edits: unknown signals, a
    valve's rows removed, odd times and values, duplicate and unsorted rows, header
    variants, separators, many signals; then sometimes a BOM or junk."""
    lines = text.splitlines()
    header, rows = lines[0], [l.split(",") for l in lines[1:] if l]
    sep, eol = ",", "\n"
    for _ in range(rng.choice([1, 1, 2, 3])):
        op = rng.randrange(12)
        if op == 0:
            for _ in range(rng.randint(1, 5)):
                rows.insert(rng.randrange(len(rows) + 1),
                            [rng.choice(["0", "0.5", "1", "2.25"]), rng.choice(IO_SIGNALS),
                             rng.choice(["0", "1"])])
        elif op == 1:      # a valve (or all of them) never recorded
            gone = set(valves) if rng.random() < 0.3 else {rng.choice(valves or ["x"])}
            rows = [r for r in rows if len(r) < 2 or r[1] not in gone]
        elif op == 2 and rows:
            r = rng.choice(rows)
            if r:
                r[0] = rng.choice(IO_TIMES)
        elif op == 3 and rows:
            r = rng.choice(rows)
            if len(r) > 2:
                r[2] = rng.choice(IO_VALUES)
        elif op == 4 and rows:     # duplicates, conflicting values at one time
            k = rng.randrange(len(rows))
            dup = list(rows[k])
            if len(dup) > 2 and rng.random() < 0.5:
                dup[2] = "1" if dup[2] == "0" else "0"
            rows.insert(k, dup)
        elif op == 5:
            rng.shuffle(rows) if rng.random() < 0.5 else rows.reverse()
        elif op == 6:
            header = rng.choice(["time,signal,value", "signal,time_s,value",
                                 "time_s,signal,value,extra", "time_s,signal", "",
                                 "TIME_S , SIGNAL , VALUE", "time_s;signal;value",
                                 "\ufefftime_s,signal,value"])
        elif op == 7:
            sep = rng.choice([";", "\t", " , "])
        elif op == 8 and rows:     # ragged rows, a huge cell
            k = rng.randrange(len(rows))
            t = "".join(rows[k][:1])
            rows[k] = rng.choice([rows[k][:2], rows[k] + ["x"], [], ["x" * 150_000],
                                  [t, "", "1"], ['"' + t, "a", "1"]])
        elif op == 9:      # many distinct signals
            n = rng.choice([100, 5000])
            rows += [["1.0", f"sig{i}", "1"] for i in range(n)]
        elif op == 10:     # rows kept to a few, or none
            rows = rows[:rng.choice([0, 1, 2])]
        else:              # a signal's case changed (names are case-insensitive)
            for r in rows:
                if len(r) > 1 and rng.random() < 0.3:
                    r[1] = r[1].lower() if rng.random() < 0.5 else r[1].upper()
    text = eol.join([header] + [sep.join(r) for r in rows]) + eol
    return _to_bytes(text, rng)


def _diagnose_options(rng: random.Random, work: Path) -> list[str]:
    opts = []
    if rng.random() < 0.15:
        opts += ["--offset", rng.choice(["0", "5", "-5", "nan", "inf", "1e300", "-1e300",
                                         "abc", "1e-9", "1000"])]
    if rng.random() < 0.1:
        opts += ["--max-offset", rng.choice(["0", "1", "-1", "nan", "1e300", "x", "120"])]
    if rng.random() < 0.1:
        opts += ["--reference", rng.choice(["iso8778", "din1343", "iso2533"])]
    if rng.random() < 0.1:
        opts += ["--sampling", rng.choice(["mean", "instant"])]
    if rng.random() < 0.1:
        opts += ["--effects", rng.choice(["leak", "leak,bogus", "", ",", "leak,leak",
                                          "valve_delay,stroke_time", "sensor_lag"])]
    if rng.random() < 0.1:
        opts += ["--json", rng.choice(["-", str(work / "d.json")])]
    if rng.random() < 0.03:
        opts += ["--out", str(work / "o")]
    if rng.random() < 0.05:
        opts += ["--write-machine", str(work / "fixed.toml")]
    return opts


def _flow_case(rng: random.Random, work: Path, bases: list[FlowBase], trace: bool) -> Case:
    """A diagnose run: with ``trace``, the --io trace is mutated (and the log only lightly,
    one time in five); else the flow log is mutated (and a trace, unmutated, goes with it
    two times in five)."""
    base = rng.choice([b for b in bases if b.timeline] if trace else bases)
    m = _write(work / "m.toml", base.machine)
    if rng.random() < 0.1:        # the machine's meter too
        meter = {k: _value(v, rng) for k, v in rng.sample(sorted(METER_KEYS.items()), 2)}
        _write(m, base.machine + "\n" + dump_toml({"meter": meter}))
    options = []
    if trace and rng.random() >= 0.2:
        log = base.measured
    else:
        log, options = mutate_flow_log(base.measured, rng)
    measured = _write(work / "measured.csv", log)
    argv = ["diagnose", str(m), "--measured", str(measured)]
    if trace:
        io_text = mutate_io_trace(base.timeline, base.valves, rng)
        argv += ["--io", str(_write(work / "io.csv", io_text))]
    elif base.timeline and rng.random() < 0.4:
        argv += ["--io", str(_write(work / "io.csv", base.timeline))]
    if rng.random() < 0.04:       # two runs, with one trace or two
        argv += ["--measured", str(measured)]
        if "--io" in argv and rng.random() < 0.5:
            argv += ["--io", argv[argv.index("--io") + 1]]
    argv += options + _diagnose_options(rng, work) + ["--no-plant"]
    return Case("io traces" if trace else "flow logs", work, [argv],
                env={"PLCPRED_ALLOW_ROOTS": ALLOW_ROOTS}, note=base.name)


# ------------------------------------------------------------------ TwinCAT folders

TWINCAT = SAMPLES / "twincat_project"
TWINCAT_MACHINE = SAMPLES / "twincat_station.toml"
ENCODINGS = ["x-bogus", "utf-16", "UTF-16LE", "latin-1", "ISO-8859-1", "ascii", "utf-32",
             "cp1252", "rot13", "zlib", "base64", "punycode", "idna", "utf-7", "hex", "uu",
             "bz2", "", "utf-8-sig", "shift_jis", "utf_16_be", "mbcs", "utf8", "UTF-8 ",
             "cp037", "unicode_escape", "raw_unicode_escape", "\u00e9"]
MARKERS = ["{{#0}}", "{{#1}}", "{{#99}}", "{{#\u00b2}}", "{{#-1}}", "{{#0:0}}",
           "{{#deadbeef:0}}", "{{#}}", "{{", "}}", "{{#99999999999999999999}}", "{{#0}}{{#0}}",
           "{ {#0} }", "{{#1:0}}"]
INCLUDES = ["/etc/passwd", "C:\\Windows\\win.ini", "..\\..\\outside.TcPOU",
            "..\\outside.TcPOU", "POUs\\Missing.TcPOU", "POUs\\Link.TcPOU", "POUs\\Dev.TcPOU",
            "POUs\\Loop.TcPOU", "POUs\\DirLink.TcPOU", "POUs\\Fifo.TcPOU", "POUs", "",
            "POUs\\*.TcPOU", "%2e%2e\\outside.TcPOU", "POUs/MAIN.TcPOU", "POUs\\MAIN.TcPOU ",
            "POUs\\MAIN.TcPOU\\..\\MAIN.TcPOU", "\\\\server\\share\\x.TcPOU", "ABS",
            "POUs\\\u00e9.TcPOU", "POUs\\Sparse.TcPOU", ".", "POUs\\..\\..\\..\\etc\\passwd"]
BODY_LANGS = ["FBD", "LD", "CFC", "SFC", "IL", "ST", "XYZ"]
CDATA = re.compile(r"<!\[CDATA\[(.*?)\]\]>", re.S)
ELEMENT = re.compile(r"<(Declaration|Implementation|ST|Action|Method|Property|Get|Set|POU|"
                     r"DUT|GVL|Itf|Task|PouCall|Compile|ItemGroup|Folder|CycleTime|Name)\b"
                     r"[^>]*?(?:/>|>.*?</\1>)", re.S)


def _cdata_edit(text: str, rng: random.Random, how: str) -> str:
    sections = list(CDATA.finditer(text))
    if not sections:
        return text
    m = rng.choice(sections)
    body = m.group(1)
    if how == "st":
        body = mutate_program(body, rng)
    elif how == "marker":
        at = rng.choice([0, len(body), rng.randrange(len(body) + 1)] +
                        [i + 1 for i, c in enumerate(body) if c == ";"][:20])
        body = body[:at] + rng.choice(MARKERS) + body[at:]
    elif how == "escape":          # ']]>' inside, or the CDATA made plain escaped text
        return text[:m.start()] + rng.choice([
            "<![CDATA[" + body[:len(body) // 2] + "]]>" + body[len(body) // 2:] + "]]>",
            body.replace("&", "&amp;").replace("<", "&lt;"),
            "<![CDATA[" + body + "]]><![CDATA[" + body + "]]>", body]) + text[m.end():]
    return text[:m.start()] + "<![CDATA[" + body.replace("]]>", "]] >") + "]]>" + text[m.end():]


def _xml_edit(text: str, rng: random.Random) -> str:
    """Structure edits of a TwinCAT XML file, on its text."""
    elements = list(ELEMENT.finditer(text))
    op = rng.randrange(11)
    if op == 0 and elements:       # an element removed
        m = rng.choice(elements)
        return text[:m.start()] + text[m.end():]
    if op == 1 and elements:       # an element doubled
        m = rng.choice(elements)
        return text[:m.end()] + m.group(0) + text[m.end():]
    if op == 2:                    # a Name attribute changed
        names = list(re.finditer(r'Name="([^"]*)"', text))
        if names:
            m = rng.choice(names)
            new = rng.choice(["", "main", "𝑒𝑥𝑒𝑐", "A B", m.group(1) * 2, "FB_Clamp", "MAIN",
                              "x" * 300, "a&amp;b", "__import__", "E_Step"])
            return text[:m.start(1)] + new + text[m.end(1):]
    if op == 3:                    # a closing tag removed, or the file cut
        closes = list(re.finditer(r"</\w+>", text))
        if closes and rng.random() < 0.5:
            m = rng.choice(closes)
            return text[:m.start()] + text[m.end():]
        return text[:rng.randrange(len(text) + 1)]
    if op == 4:                    # unknown or deeply nested elements
        tags = [m.end() for m in re.finditer(r">", text)]
        at = rng.choice(tags) if tags else 0
        n = rng.choice([1, 100, 5000, 100_000])
        insert = rng.choice(["<Foo/>", "<Foo>x</Foo>", "<a>" * n + "</a>" * n,
                             "<?pi data?>", "<!-- ]]> -->", "<Implementation/>",
                             "<ST><![CDATA[x := 1;]]></ST>"])
        return text[:at] + insert + text[at:]
    if op == 5:                    # entities: amplification, external, undefined
        doctype = rng.choice([
            '<!DOCTYPE l [<!ENTITY a "aaaaaaaaaa">' + "".join(
                f'<!ENTITY {chr(98 + k)} "{("&" + chr(97 + k) + ";") * 10}">' for k in range(8))
            + "]>",
            '<!DOCTYPE p [<!ENTITY x SYSTEM "file:///etc/passwd">]>',
            '<!DOCTYPE p [<!ENTITY x SYSTEM "http://127.0.0.1:9/x">]>',
            '<!DOCTYPE p [<!ENTITY % x SYSTEM "file:///etc/passwd"> %x;]>', "<!DOCTYPE p>"])
        use = rng.choice(["&i;", "&x;", "&undefined;", "&#0;", "&#x110000;", "&amp;"])
        decl_end = text.find("?>") + 2 if text.lstrip("\ufeff").startswith("<?xml") else 0
        body = text[decl_end:]
        names = list(re.finditer(r'Name="([^"]*)"', body))
        if names:
            m = rng.choice(names)
            body = body[:m.start(1)] + use + body[m.end(1):]
        return text[:decl_end] + doctype + body
    if op == 6:                    # the ST body swapped for another language
        lang = rng.choice(BODY_LANGS)
        return re.sub(r"<ST>(.*?)</ST>", lambda m: f"<{lang}>{m.group(1)}</{lang}>"
                      if rng.random() < 0.5 else m.group(0), text, flags=re.S)
    if op == 7:                    # attributes of the root
        return re.sub(r'Version="[^"]*"', f'Version="{rng.choice(["", "99", "x", "1.1.0.1"])}"',
                      text, count=1)
    if op == 8:                    # a LineIds block, a huge attribute
        return text.replace("</TcPlcObject>", rng.choice([
            '<LineIds Name="MAIN"><LineId Id="1" Count="99999999999"/></LineIds></TcPlcObject>',
            f'<Foo a="{"x" * 200_000}"/></TcPlcObject>']))
    if op == 9:                    # the declaration and implementation of two POUs swapped
        decls = list(re.finditer(r"<Declaration>.*?</Declaration>", text, re.S))
        if len(decls) >= 2:
            a, b = rng.sample(decls, 2)
            a, b = sorted((a, b), key=lambda m: m.start())
            return text[:a.start()] + b.group(0) + text[a.end():b.start()] + a.group(0) + \
                text[b.end():]
    return _cdata_edit(text, rng, "escape")


def _encoding_edit(raw: bytes, rng: random.Random) -> bytes:
    text = raw.decode("utf-8-sig", "replace")
    op = rng.randrange(6)
    if op == 0:                    # another encoding declared
        return re.sub(r'encoding="[^"]*"', f'encoding="{rng.choice(ENCODINGS)}"', text,
                      count=1).encode("utf-8", "surrogatepass")
    if op == 1:                    # the file in UTF-16/32, declared or not
        enc = rng.choice(["utf-16", "utf-16-le", "utf-16-be", "utf-32", "cp1252", "latin-1"])
        if rng.random() < 0.5:
            text = re.sub(r'encoding="[^"]*"', f'encoding="{rng.choice(ENCODINGS[:9])}"', text,
                          count=1)
        return text.encode(enc, "replace")
    if op == 2:                    # BOMs: none, two, the wrong one
        body = text.encode()
        return rng.choice([body, BOMS[0] * 2 + body, BOMS[1] + body, BOMS[2] + body])
    if op == 3:                    # bytes that are no UTF-8 in a CDATA
        data = bytearray(raw)
        i = raw.find(b"CDATA[")
        at = i + 6 if i >= 0 and rng.random() < 0.7 else rng.randrange(len(data) + 1)
        data[at:at] = rng.choice([b"\xe9", b"\xff\xfe", b"\xc3", b"\xed\xa0\x80", b"\x00"])
        return bytes(data)
    if op == 4:                    # no XML declaration
        return re.sub(r"^\ufeff?<\?xml[^>]*\?>", "", text).encode()
    return ("\ufeff" + text.replace("\n", "\r\n")).encode()


def _project_files(proj: Path) -> list[Path]:
    return sorted(p for p in proj.rglob("*") if p.is_file() and not p.is_symlink())


def mutate_twincat(proj: Path, work: Path, rng: random.Random) -> list[str]:
    """Mutate the copy of a TwinCAT project at ``proj`` (its .plcproj folder) in place:
    XML structure, ST in the CDATA (type traps among the edits), ``<Compile Include>``
    paths (absolute, ``..``, missing, links out, devices, FIFOs), declared encodings,
    ``{{#N}}`` markers, the task object, files added and removed. Returns what was done."""
    done = []
    plcproj = next(proj.glob("*.plcproj"), None)
    for _ in range(rng.choice([1, 1, 2, 3])):
        files = _project_files(proj)
        if not files:
            break
        op = rng.choices(range(9), [14, 24, 14, 8, 6, 5, 5, 4, 4])[0]
        target = rng.choice(files)
        if op in (0, 1, 4, 5) and target.suffix in (".plcproj",) and rng.random() < 0.7:
            target = rng.choice([f for f in files if f.suffix != ".plcproj"] or files)
        raw = target.read_bytes()
        text = raw.decode("utf-8", "replace")
        if op == 0:
            target.write_text(_xml_edit(text, rng), errors="surrogatepass")
            done.append(f"xml {target.name}")
        elif op == 1:
            target.write_text(_cdata_edit(text, rng, "st"), errors="surrogatepass")
            done.append(f"st {target.name}")
        elif op == 2 and plcproj is not None and plcproj.exists():
            done.append("include " + _include_edit(plcproj, proj, work, rng))
        elif op == 3:
            target.write_bytes(_encoding_edit(raw, rng))
            done.append(f"encoding {target.name}")
        elif op == 4:
            target.write_text(_cdata_edit(text, rng, "marker"), errors="surrogatepass")
            done.append(f"marker {target.name}")
        elif op == 5:
            tto = next(proj.glob("*.TcTTO"), None)
            if tto is not None:
                t = tto.read_text(encoding="utf-8-sig", errors="replace")
                if rng.random() < 0.6:
                    t = re.sub(r"<CycleTime>[^<]*</CycleTime>", "<CycleTime>" + rng.choice(
                        ["0", "-1", "1e30", "\u00b2", "", "99999999999999999999", "10000.5",
                         "0x10", "\u0661\u0660\u0660\u0660\u0660", " 10000 ", "1"]) +
                        "</CycleTime>", t)
                else:
                    t = re.sub(r"<Name>MAIN</Name>", "<Name>" + rng.choice(
                        ["", "NOSUCH", "FB_Clamp", "MAIN.Sequence", "E_Step", "GVL_IO",
                         "MAIN</Name></PouCall><PouCall><Name>MAIN"]) + "</Name>", t)
                tto.write_text(t)
                done.append("task")
        elif op == 6:                  # a file removed, added or doubled
            how = rng.randrange(4)
            if how == 0:
                target.unlink()
                done.append(f"removed {target.name}")
            elif how == 1:
                extra = proj / rng.choice(["POUs", "DUTs", "."]) / rng.choice(
                    ["Extra.TcPOU", "MAIN2.TcPOU", "x.TcDUT", "y.TcGVL", "z.TcIO", "t.TcTTO"])
                text_main = (proj / "POUs/MAIN.TcPOU")
                src = text_main.read_text(errors="replace") if text_main.exists() else text
                extra.parent.mkdir(parents=True, exist_ok=True)
                extra.write_text(mutate_program(src, rng) if rng.random() < 0.5 else src)
                done.append(f"added {extra.relative_to(proj)}")
            elif how == 2:
                (proj / "Copy.plcproj").write_bytes(plcproj.read_bytes() if plcproj and
                                                    plcproj.exists() else raw)
                done.append("second plcproj")
            else:
                target.write_bytes(rng.choice([b"", bytes(rng.randrange(256)
                                                          for _ in range(500))]))
                done.append(f"emptied {target.name}")
        elif op == 7:                  # links, deep folders, many files inside the folder
            how = rng.randrange(4)
            # (an edit may be drawn twice for one folder: each tolerates its own traces)
            if how == 0:
                if not os.path.lexists(proj / "Loop"):
                    (proj / "Loop").symlink_to(".", target_is_directory=True)
                done.append("folder link to itself")
            elif how == 1:
                deep = proj.joinpath(*["d"] * rng.choice([10, 33, 40]))
                deep.mkdir(parents=True, exist_ok=True)
                shutil.copy(proj / "POUs/MAIN.TcPOU" if (proj / "POUs/MAIN.TcPOU").exists()
                            else target, deep / "Deep.TcPOU")
                done.append("deep folder")
            elif how == 2:
                many = proj / "Many"
                many.mkdir(exist_ok=True)
                for i in range(rng.choice([50, 500])):
                    (many / f"f{i}.TcDUT").write_text("")
                done.append("many files")
            else:
                if not os.path.lexists(proj / "Out"):
                    (proj / "Out").symlink_to(work, target_is_directory=True)
                done.append("folder link out")
        else:                          # the GVL or a DUT replaced by a type trap
            decls, var_type, init = type_trap(rng)
            dut = proj / "DUTs" / "E_Step.TcDUT"
            if dut.exists():
                t = dut.read_text(encoding="utf-8-sig", errors="replace")
                t = CDATA.sub(lambda m: "<![CDATA[" + (decls or "TYPE FzX : INT; END_TYPE\n")
                              .replace("]]>", "") + "]]>", t, count=1)
                dut.write_text(t)
                done.append("type trap in a DUT")
    return done


def _include_edit(plcproj: Path, proj: Path, work: Path, rng: random.Random) -> str:
    """One ``<Compile Include>`` of the .plcproj pointed somewhere odd (creating the link,
    device link, FIFO or outside file it names)."""
    text = plcproj.read_text(encoding="utf-8-sig", errors="replace")
    include = rng.choice(INCLUDES)
    outside = work / "outside.TcPOU"
    main = proj / "POUs" / "MAIN.TcPOU"
    if main.exists():
        outside.write_bytes(main.read_bytes())
    pous = proj / "POUs"
    pous.mkdir(exist_ok=True)
    with contextlib.suppress(OSError):
        if include == "ABS":
            include = str(main)
        elif include.endswith("Link.TcPOU") and not include.endswith("DirLink.TcPOU"):
            (pous / "Link.TcPOU").symlink_to(outside)
        elif include.endswith("Dev.TcPOU"):
            (pous / "Dev.TcPOU").symlink_to(rng.choice(["/dev/zero", "/dev/stdin",
                                                         "/proc/self/environ", "/dev/null"]))
        elif include.endswith("Loop.TcPOU"):
            (pous / "Loop.TcPOU").symlink_to("Loop2.TcPOU")
            (pous / "Loop2.TcPOU").symlink_to("Loop.TcPOU")
        elif include.endswith("DirLink.TcPOU"):
            (pous / "DirLink.TcPOU").symlink_to(work, target_is_directory=True)
        elif include.endswith("Fifo.TcPOU"):
            os.mkfifo(pous / "Fifo.TcPOU")
        elif include.endswith("Sparse.TcPOU"):
            with open(pous / "Sparse.TcPOU", "wb") as f:
                f.truncate(65 * 2**20)      # over the 64 MB a file may have, without the bytes
    includes = list(re.finditer(r'<Compile Include="([^"]*)"', text))
    escaped = include.replace("&", "&amp;").replace('"', "&quot;").replace("<", "&lt;")
    if includes and rng.random() < 0.6:
        m = rng.choice(includes)
        text = text[:m.start(1)] + escaped + text[m.end(1):]
    else:
        text = text.replace("<ItemGroup>", f'<ItemGroup>\n    <Compile Include="{escaped}" />', 1)
    plcproj.write_text(text)
    return include


def _twincat_case(rng: random.Random, work: Path) -> Case:
    root = work / "proj"
    shutil.copytree(TWINCAT, root, symlinks=True)
    proj = root / "ClampStation"
    done = mutate_twincat(proj, work, rng)
    machine = TWINCAT_MACHINE.read_text().replace('"twincat_project/ClampStation/"',
                                                   rng.choice(['"proj/ClampStation/"'] * 3 + [
                                                       '"proj/ClampStation/ClampStation.plcproj"',
                                                       '"proj"']))
    m = _write(work / "station.toml", machine)
    out = str(work / "o")
    r = rng.random()
    target = str(rng.choice([proj, proj, proj / "ClampStation.plcproj", root]))
    if r < 0.45:
        argvs = [["check", target] + rng.choice([[], [], ["--syntax-only"],
                                                 ["--allow-external"]])]
    elif r < 0.55:
        files = _project_files(proj) or [proj]
        argvs = [["check"] + [str(p) for p in rng.sample(files, min(len(files), 3))]]
    elif r < 0.7:
        argvs = [["init", target, "--out", str(work / "init.toml")],
                 ["timeline", str(work / "init.toml"), "--horizon", "2s", "--out", out]]
        if rng.random() < 0.3:
            argvs = [["init", target]]
    elif r < 0.9:
        argvs = [["timeline", str(m), "--horizon", "2s", "--out", out]]
    else:
        argvs = [["predict", str(m), "--horizon", "2s", "--out", out, "--no-plot"]]
    # the rules on where a project's files may be apply as to anyone's: no roots allowed
    return Case("twincat", work, argvs, env={"PLCPRED_ALLOW_ROOTS": None},
                note=", ".join(done))


# ------------------------------------------------------------------ pre-existing --out folders

# what the commands of this channel write into --out: a planted link or folder of one of
# these names stands where plcpred writes (its target must stay untouched, the name not)
OUTPUT_NAMES = ["timeline.csv", "demand.csv", "summary.json", "demand.png", "sizing.json",
                "sizing.md", "sizing.html", "measured.csv", "plant.csv", "emulate.png",
                "diagnose.json", "diagnose.html", "diagnose.png", "sweep.csv"]
USER_FILES = {"README.md": "the user's own", "notes.txt": "x", ".keep": "",
              "src.st": "PROGRAM p END_PROGRAM", "data.bin": "\x00\x01binary",
              "précis.txt": "é", "sub/keep.txt": "kept", "sub/deeper/a.csv": "1,2"}


def _sha(data: bytes) -> dict:
    return {"bytes": len(data), "sha256": hashlib.sha256(data).hexdigest()}


def _snapshot(path: Path) -> dict:
    """What a folder holds (names, link targets, file contents), without following links."""
    state = {}
    if not os.path.lexists(path):
        return state
    for dirpath, dirnames, filenames in os.walk(path):
        for name in dirnames + filenames:
            p = Path(dirpath) / name
            rel = str(p.relative_to(path))
            if p.is_symlink():
                state[rel] = ("link", os.readlink(p))
            elif p.is_file():
                state[rel] = ("file", hashlib.sha256(p.read_bytes()).hexdigest())
            elif p.is_dir():
                state[rel] = ("dir", "")
            else:
                state[rel] = ("other", "")
    return state


def _changes(before: dict, after: dict, may_create=()) -> str:
    """What differs between two snapshots, but for new files named in ``may_create``."""
    gone = [k for k in before if k not in after]
    altered = [k for k in before if k in after and after[k] != before[k]]
    new = [k for k in after if k not in before and Path(k).name not in may_create]
    return "; ".join(f"{what} {', '.join(names[:5])}" for what, names in
                     (("removed", gone), ("changed", altered), ("created", new)) if names)


def _planted_manifest(rng: random.Random, work: Path, sentinel: Path) -> str | bytes:
    """A manifest.json someone else put there: listing paths out of the folder, ``..``,
    links, folders, the user's files with wrong hashes, odd entries; or malformed."""
    sentinel_entry = _sha(sentinel.read_bytes())
    if rng.random() < 0.25:
        return rng.choice([
            "not json", "[1, 2]", '{"files": ["a", "b"]}', "[" * 100_000, "{" * 50_000,
            '{"files": {"README.md": 5}}', '{"files": null}', "", "\x00" * 10,
            '{"files": {"README.md": {"bytes": NaN, "sha256": null}}}',
            '{"files": {}, "files": {"README.md": {}}}', json.dumps({"pad": "x" * (2 << 20)}),
            "\ufeff" + json.dumps({"files": {"README.md": {}}}),
            json.dumps({"files": {"README.md": {}}}).encode("utf-16"),
            '{"files": ' + "[" * 5000 + "]" * 5000 + "}"])
    files = {}
    for _ in range(rng.randint(1, 8)):
        name = rng.choice([
            str(sentinel), "../sentinel.txt", "../../sentinel.txt", "..", ".", "", "/",
            "sub/keep.txt", "sub", "README.md", "notes.txt", "readme.md", "README.md/",
            "README.md ", "..\\sentinel.txt", "link.csv", "linkdir", "dangling.csv",
            "hard.csv", "manifest.json", "\x00", "a/../README.md", "x" * 5000, "précis.txt",
            "pre\u0301cis.txt", "timeline.csv", "~", "$HOME", "sub/../../sentinel.txt",
            str(work / "sentinel_dir" / "a.txt"), "*"])
        entry = rng.choice([
            sentinel_entry, {}, {"bytes": 3, "sha256": "0" * 64}, None, [], 5, "x",
            {"bytes": -1, "sha256": 5}, {"bytes": 1e308}, {"bytes": "12"},
            _sha(b"what plcpred wrote"), {"bytes": 2**70, "sha256": "g" * 64}])
        if name in ("hard.csv",):
            entry = sentinel_entry          # a hard link to the sentinel: proven, removable
        files[name] = entry
    data = {"files": files}
    if rng.random() < 0.3:
        data.update(run_id=rng.choice(["x", 5, None, "../.."]), command="predict")
    return json.dumps(data)


def _out_case(rng: random.Random, work: Path) -> Case:
    """A command writing into an --out folder someone else prepared: the user's files,
    a planted manifest, links out of it (some named as outputs, so that a write through
    them would land outside), staging folders of 'killed runs' that are links; or --out
    itself a link, a file, a path through ``..``, the case folder, ``.``. The check: the
    sentinel file and folder outside, the user's own files inside, and where links point
    stay as they were, and nothing is created where a link points out."""
    sentinel = _write(work / "sentinel.txt", f"precious {rng.random()}")
    sdir = work / "sentinel_dir"
    _write(sdir / "a.txt", "precious a")
    _write(sdir / "manifest.json", json.dumps({"files": {"README.md": _sha(
        USER_FILES["README.md"].encode())}}))
    out = work / "out"
    out.mkdir()
    user = {k: v for k, v in USER_FILES.items() if rng.random() < 0.7}
    for name, text in user.items():
        _write(out / name, text)
    notes = []
    if rng.random() < 0.8:
        m = _planted_manifest(rng, work, sentinel)
        _write(out / "manifest.json", m)
    elif rng.random() < 0.5:          # the manifest a link out, to a folder, or a FIFO
        how = rng.randrange(4)
        if how == 0:
            (out / "manifest.json").symlink_to(sdir / "manifest.json")
        elif how == 1:
            (out / "manifest.json").symlink_to(sentinel)
        elif how == 2:
            (out / "manifest.json").mkdir()
            _write(out / "manifest.json" / "inner.txt", "user")
        else:
            os.mkfifo(out / "manifest.json")
        notes.append(f"manifest {['link to a manifest outside', 'link to the sentinel', 'a folder', 'a FIFO'][how]}")
    # links: to the sentinel, its folder, nowhere; some named as outputs
    traps = rng.sample(OUTPUT_NAMES, rng.randint(0, 3))
    for name in traps:
        how = rng.randrange(4)
        if how == 0:
            (out / name).symlink_to(sentinel)
        elif how == 1:
            (out / name).symlink_to(sdir, target_is_directory=True)
        elif how == 2:
            (out / name).symlink_to(work / f"created_{name}")      # dangling: nothing may
        else:                                                     # be created there
            _write(out / name / "inner.txt", "user's folder named like an output")
    notes += [f"trap {n}" for n in traps]
    if rng.random() < 0.5:
        (out / "link.csv").symlink_to(sentinel)
        (out / "linkdir").symlink_to(sdir, target_is_directory=True)
        (out / "dangling.csv").symlink_to(work / "nowhere.csv")
    if rng.random() < 0.3:
        os.link(sentinel, out / "hard.csv")
    if rng.random() < 0.2:            # "killed runs": staging folders that are links
        for name in (".plcpred-staging-out-abc", ".plcpred-old-out-def",
                     ".plcpred-staging-out-ghi.lock"):
            (work / name).symlink_to(sdir, target_is_directory=True)
            past = time.time() - 7200
            os.utime(work / name, (past, past), follow_symlinks=False)
        notes.append("staging links")
    # where --out is
    where = rng.choices(["out", "link", "file", "dotdot", "missing-dotdot", "case", "dot",
                         "sub", "new"], [40, 8, 6, 8, 4, 8, 6, 8, 4])[0]
    real = work / "real"
    if where == "link":
        _write(real / "keep.txt", "user")
        target = work / "outlink"
        target.symlink_to(rng.choice([real, out, sdir]), target_is_directory=True)
    elif where == "file":
        target = sentinel if rng.random() < 0.5 else out / "README.md"
    elif where == "dotdot":
        target = Path(str(out / "sub") + "/../../out")
    elif where == "missing-dotdot":
        target = Path(str(work / "missing") + "/../out2")
    elif where == "case":
        target = work
    elif where == "dot":
        target = Path(".")
    elif where == "sub":
        target = out / "sub"
        (out / "sub").mkdir(exist_ok=True)
    elif where == "new":
        target = out / "new"
    else:
        target = out
    notes.insert(0, f"--out {where}")
    # the command (quick ones), sometimes twice into the same folder
    press = _write(work / "m.toml", dump_toml(_machine_data(SAMPLES / "press.toml")))

    def command() -> list[str]:
        t = str(target)
        return rng.choice([
            ["predict", str(press), "--horizon", "1s", "--out", t, "--no-plot"],
            ["predict", str(press), "--horizon", "1s", "--out", t],
            ["timeline", str(press), "--horizon", "1s", "--out", t],
            ["size", str(press), "--horizon", "2s", "--out", t],
            ["emulate", str(press), "--horizon", "1s", "--out", t, "--no-plot"],
            ["sweep", str(press), "--horizon", "1s", "--set", "supply_bar_g=4,5", "--workers",
             "1", "--out", t],
            ["init", str(SAMPLES / "press.st" if (SAMPLES / "press.st").exists() else
                         SAMPLES / "sfc_press.st"), "--out", str(Path(t) / rng.choice(
                             ["m.toml", "README.md", "link.csv", "dangling.csv"]))]])
    argvs = [command()]
    if rng.random() < 0.3:
        argvs.append(command())
    # init --out FILE writes FILE where its path leads, through a linked folder too (only
    # the last name must not be a link): that new file is no harm
    init_files = {Path(a[a.index("--out") + 1]).name for a in argvs if a[0] == "init"}
    # what must hold afterwards
    outside = {"sentinel": _snapshot(sentinel.parent / "sentinel.txt"),
               "sentinel_dir": _snapshot(sdir)}
    real_before = _snapshot(real)
    kept = {name: (out / name).read_bytes() for name in user}
    links = {p.name: os.readlink(p) for p in out.iterdir()
             if p.is_symlink() and p.name not in OUTPUT_NAMES and p.name != "manifest.json"}
    folders = {name: (out / name / "inner.txt").read_bytes() for name in traps
               if (out / name / "inner.txt").exists() and not (out / name).is_symlink()}
    sentinel_bytes = sentinel.read_bytes()

    def check() -> str | None:
        harm = []
        if not sentinel.is_file() or sentinel.is_symlink():
            harm.append("the sentinel file outside --out is gone")
        elif sentinel.read_bytes() != sentinel_bytes:
            harm.append("the sentinel file outside --out was overwritten")
        changed = _changes(outside["sentinel_dir"], _snapshot(sdir), init_files)
        if changed:
            harm.append(f"the folder outside --out changed ({changed})")
        changed = _changes(real_before, _snapshot(real), init_files)
        if real.exists() and changed:
            harm.append(f"the folder an --out link points to changed ({changed})")
        for name, data in kept.items():
            p = out / name
            if p.is_symlink() or not p.is_file():
                harm.append(f"the user's {name} is gone")
            elif p.read_bytes() != data:
                harm.append(f"the user's {name} was overwritten")
        for name, dest in links.items():
            p = out / name
            if not p.is_symlink() or os.readlink(p) != dest:
                harm.append(f"the user's link {name} was removed or changed")
        for name, data in folders.items():
            if not (out / name / "inner.txt").is_file() or \
                    (out / name / "inner.txt").read_bytes() != data:
                harm.append(f"the user's folder {name} lost its file")
        created = [p.name for p in work.glob("created_*")] + \
            (["nowhere.csv"] if (work / "nowhere.csv").exists() else [])
        if created:
            harm.append(f"written through a dangling link: {', '.join(created)}")
        return "; ".join(harm) or None

    return Case("outs", work, argvs, check=check, note=", ".join(notes),
                env={"PLCPRED_ALLOW_ROOTS": ALLOW_ROOTS})


# ------------------------------------------------------------------ the earlier channels

def _program_case(rng: random.Random, work: Path) -> Case:
    path = rng.choice(PROGRAM_FILES)
    text = mutate_program(path.read_text(), rng)
    return Case("programs", work, program=(text, path.suffix), note=path.name)


def _machine_case(rng: random.Random, work: Path, k: int) -> Case:
    m = mutate_machine(rng.choice(MACHINE_FILES), rng)
    path = _write(work / "m.toml", m)
    argv = [rng.choice(["timeline", "predict"]), str(path), "--horizon", "2s",
            "--out", str(work / "o")]
    if argv[0] == "predict" and k % 10:
        argv.append("--no-plot")          # every tenth draws its plot
    if argv[0] == "timeline" and rng.random() < 0.2:
        argv.append(rng.choice(["--scan-stepping", "--no-replay"]))
    return Case("machines", work, [argv], env={"PLCPRED_ALLOW_ROOTS": ALLOW_ROOTS})


def _command_case(rng: random.Random, work: Path, afile: Path) -> Case:
    argv = random_argv(rng, str(rng.choice(MACHINE_FILES)), work / "o", afile)
    return Case("commands", work, [argv])


# ------------------------------------------------------------------ running a channel

CHANNELS = ["programs", "machines", "commands", "truths", "flow logs", "io traces",
            "twincat", "outs"]


@dataclasses.dataclass
class Tally:
    channel: str
    counts: dict = dataclasses.field(default_factory=lambda: {o: 0 for o in OUTCOMES})
    examples: dict = dataclasses.field(default_factory=dict)   # outcome: [(key, case, o)]
    warnings: dict = dataclasses.field(default_factory=dict)   # a Python warning: count
    max_rss_mb: float = 0.0
    wall_s: float = 0.0
    n: int = 0
    largest: tuple | None = None      # (case, outcome) of the largest peak RSS
    slowest: tuple | None = None      # (case, outcome) of the longest run

    def add(self, case: Case, outcome: Outcome, keep: int = 10) -> None:
        self.n += 1
        self.counts[outcome.outcome] = self.counts.get(outcome.outcome, 0) + 1
        self.max_rss_mb = max(self.max_rss_mb, outcome.rss_mb)
        if self.largest is None or outcome.rss_mb > self.largest[1].rss_mb:
            self.largest = (case, outcome)
        if self.slowest is None or outcome.wall_s > self.slowest[1].wall_s:
            self.slowest = (case, outcome)
        for w in outcome.warnings:
            key = re.sub(r"\d+", "N", w)[:160]
            self.warnings[key] = self.warnings.get(key, 0) + 1
        if outcome.bad:
            found = self.examples.setdefault(outcome.outcome, [])
            key = re.sub(r"/tmp/\S+|\d+", "_", outcome.detail)[:120]
            if len(found) < keep and all(key != k for k, _, _ in found):
                found.append((key, case, outcome))

    @property
    def bad(self) -> int:
        return sum(self.counts.get(o, 0) for o in BAD)

    def line(self) -> str:
        c = self.counts
        per = 1000 * self.wall_s / self.n if self.n else 0.0
        return (f"{self.channel:10s} {self.n:6d} in {self.wall_s:7.1f} s ({per:6.0f} s/1000): "
                f"ok {c['ok']:5d}, clean {c['clean']:5d}, traceback {c['traceback']:3d}, "
                f"hang {c['hang']:3d}, memory {c['memory']:3d}, unsafe {c['unsafe']:3d}; "
                f"max RSS {self.max_rss_mb:5.0f} MB")


class Fuzzer:
    """Makes and runs the cases of each channel under ``limits``: each case's inputs in
    ``root/CHANNEL/K``, removed after a good outcome unless ``keep`` (a bad one keeps its
    folder, with outcome.txt: what ran, the outcome, stderr)."""

    def __init__(self, root: Path, limits: Limits | None = None, keep: bool = False):
        self.root = Path(root)
        self.root.mkdir(parents=True, exist_ok=True)
        self.limits = limits or Limits()
        self.keep = keep
        self._bases = None
        self.afile = _write(self.root / "afile", "x")
        warm_up()

    def bases(self) -> list[FlowBase]:
        if self._bases is None:
            self._bases = make_flow_bases(self.root / "bases")
        return self._bases

    def make(self, channel: str, rng: random.Random, k: int) -> Case:
        work = self.root / channel.replace(" ", "_") / f"{k:06d}"
        if work.exists():
            _rmtree(work)
        work.mkdir(parents=True)
        if channel == "programs":
            return _program_case(rng, work)
        if channel == "machines":
            return _machine_case(rng, work, k)
        if channel == "commands":
            return _command_case(rng, work, self.afile)
        if channel == "truths":
            return _truth_case(rng, work)
        if channel in ("flow logs", "io traces"):
            return _flow_case(rng, work, self.bases(), channel == "io traces")
        if channel == "twincat":
            return _twincat_case(rng, work)
        if channel == "outs":
            return _out_case(rng, work)
        raise ValueError(f"unknown channel {channel!r} (channels: {', '.join(CHANNELS)})")

    def run(self, channel: str, n: int, seed="1", jobs: int = 1,
            progress: Callable[[int], None] | None = None) -> Tally:
        """``n`` cases of ``channel`` (seeded: the same seed makes the same inputs), up to
        ``jobs`` at once."""
        if channel in ("flow logs", "io traces"):
            self.bases()
        rng = random.Random(f"{seed}-{channel}")
        tally = Tally(channel)
        running: list[tuple[Case, Child]] = []
        k = 0
        t0 = time.monotonic()
        while k < n or running:
            while k < n and len(running) < max(1, jobs):
                case = self.make(channel, rng, k)
                running.append((case, case.child(self.limits)))
                k += 1
            select.select([c for _, c in running], [], [], 0.02)
            for item in list(running):
                case, child = item
                if not child.poll():
                    continue
                running.remove(item)
                outcome = case.judge(child.finish())
                before = (tally.largest, tally.slowest)
                tally.add(case, outcome)
                self._settle(case, outcome, tally, before)
                if progress is not None:
                    progress(tally.n)
        tally.wall_s = time.monotonic() - t0
        return tally

    def _settle(self, case: Case, outcome: Outcome, tally: Tally | None = None,
                before: tuple = (None, None)) -> None:
        """Keep the folder of a bad case (with outcome.txt), and of the largest and the
        slowest case so far; remove the rest (unless ``keep``)."""
        held = [] if tally is None else [x[0] for x in (tally.largest, tally.slowest) if x]
        if outcome.bad or any(case is h for h in held):
            _write(case.work / "outcome.txt",
                   f"{outcome.outcome}: {outcome.detail}\n\n{case.describe()}\n\n"
                   f"peak RSS {outcome.rss_mb:.0f} MB, {outcome.wall_s:.2f} s\n\n"
                   f"stderr:\n{outcome.stderr}")
        elif not self.keep:
            _rmtree(case.work)
        for old in before:               # a case no longer the largest or slowest
            if old is not None and not any(old[0] is h for h in held) and \
                    not old[1].bad and not self.keep:
                _rmtree(old[0].work)


def _rmtree(path: Path) -> None:
    def unblock(func, p, exc):
        with contextlib.suppress(OSError):
            os.chmod(p, 0o700, follow_symlinks=False)
            func(p)
    shutil.rmtree(path, onerror=unblock)
