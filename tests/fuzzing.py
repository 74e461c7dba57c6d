"""Mutated programs, machine files and command lines, and a runner that sorts outcomes
into clean errors, successes, tracebacks and hangs. Used by ``tests/test_fuzz.py`` (a short
deterministic run) and ``bench/fuzz.py`` (the long run).

The mutators know nothing of plcpred's internals: they work on text (tokens, TOML values,
argument strings) with values chosen to hit the classes of failure seen in the wild
(based and huge literals, deep nesting, Unicode, NaN, overflowing times, bad paths).
"""
from __future__ import annotations

import contextlib
import io
import math
import random
import re
import signal
import tomllib
from pathlib import Path

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


def mutate_program(text: str, rng: random.Random) -> str:
    """One to three edits: delete, duplicate, swap or replace a token, insert a tricky
    token or a nested construct, or cut the file short."""
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
    for _ in range(rng.randint(1, 3)):
        tables = [data["machine"]] + data.get("input", []) + data.get("consumer", [])
        table = rng.choice(tables)
        keys = [k for k in table if k != "program"] or ["name"]
        numeric = [k for k in keys if isinstance(table[k], (int, float))
                   and not isinstance(table[k], bool) and abs(table[k]) < 1e300]
        key = rng.choice(keys)
        op = rng.randrange(10)
        if op < 4 and numeric:
            # a number scaled into odd but often still valid territory: deeper runs
            key = rng.choice(numeric)
            table[key] = table[key] * rng.choice([0.0, 1e-6, 1e-3, 0.5, 2.0, 1e3, 1e6, -1.0])
        elif op < 6:
            table[key] = rng.choice(ODD_VALUES)
        elif op == 6:
            table.pop(key, None)
        elif op == 7:
            table[key + "_typo"] = table.pop(key, 1)
        elif op == 8 and data.get("consumer"):
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
