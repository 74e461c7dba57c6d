"""The long fuzz run of hostile and broken input (issue: a program never runs host code,
nothing traces back, resources stay bounded).

Mutated programs (ST, .seq, PLCopen; token edits, tricky literals, deep nesting, Unicode),
mutated machine files (odd numbers, NaN, huge and tiny times, wrong types, non-UTF-8
bytes) and random command lines (horizons, grids, --out paths, sweep settings, sizing
options) each end as a result ("ok"), a clean error, a traceback or a hang (over 10 s).
Prints the counts per kind and the first examples of each traceback or hang; exits 1 if
there was any. The mutators are in tests/fuzzing.py; the seed makes a run repeatable.

    python bench/fuzz.py [--programs 10000] [--machines 5000] [--commands 1000] [--seed 1]
"""
from __future__ import annotations

import argparse
import collections
import random
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))
import fuzzing as F  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--programs", type=int, default=10_000)
    ap.add_argument("--machines", type=int, default=5_000)
    ap.add_argument("--commands", type=int, default=1_000)
    ap.add_argument("--seed", default="1")
    ap.add_argument("--hang-s", type=float, default=10.0)
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="plcpred-fuzz-"))
    afile = tmp / "afile"
    afile.write_text("x")
    bad = 0
    for kind, n in (("programs", args.programs), ("machine files", args.machines),
                    ("command lines", args.commands)):
        rng = random.Random(f"{args.seed}-{kind}")
        counts = collections.Counter()
        examples = collections.OrderedDict()
        t0 = time.perf_counter()
        for k in range(n):
            if kind == "programs":
                path = rng.choice(F.PROGRAM_FILES)
                result, detail = F.run_program(F.mutate_program(path.read_text(), rng),
                                               path.suffix, args.hang_s)
            elif kind == "machine files":
                m = F.mutate_machine(rng.choice(F.MACHINE_FILES), rng)
                path = tmp / "m.toml"
                (path.write_bytes if isinstance(m, bytes) else path.write_text)(m)
                argv = [rng.choice(["timeline", "predict"]), str(path), "--horizon", "2s",
                        "--out", str(tmp / "o")]
                if argv[0] == "predict" and k % 10:
                    argv.append("--no-plot")  # every tenth draws its plot
                result, detail = F.run_cli(argv, args.hang_s)
            else:
                argv = F.random_argv(rng, str(rng.choice(F.MACHINE_FILES)), tmp / "o", afile)
                result, detail = F.run_cli(argv, args.hang_s)
            counts[result] += 1
            if result in ("traceback", "hang"):
                examples.setdefault(detail.split(" <- ")[0][:160], detail)
        wall = time.perf_counter() - t0
        bad += counts["traceback"] + counts["hang"]
        print(f"{kind:14s} {n:6d} in {wall:6.1f} s: ok {counts['ok']:6d}, clean errors "
              f"{counts['clean']:6d}, tracebacks {counts['traceback']:3d}, hangs over "
              f"{args.hang_s:g} s {counts['hang']:3d}")
        for detail in list(examples.values())[:10]:
            print(f"    {detail[:300]}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
