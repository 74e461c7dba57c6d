"""The long fuzz run of hostile and broken input on every channel plcpred reads.

The issue: a program never runs host code, nothing traces back, resources stay bounded,
--out never harms what is not plcpred's.

Channels (the mutators are in tests/fuzzing.py; the seed makes a run repeatable):

    --programs N   mutated programs (ST, .seq, PLCopen; token edits, tricky literals, deep
                   nesting, Unicode, type cycles, deep type constructors and initialisers,
                   long EXTENDS chains): parse, check, compile, three scans
    --machines N   mutated machine files (odd numbers, NaN, huge and tiny times, wrong types,
                   non-UTF-8 bytes): timeline / predict --horizon 2s
    --commands N   random command lines (horizons, grids, --out paths, sweep settings, ...)
    --truths N     truth files (consumer overrides, hidden leaks, [[line]], [meter], ...):
                   emulate MACHINE --truth T --horizon 2s
    --flows N      N mutated flow logs and N mutated --io traces (headers, units, decimal
                   commas, NaN/inf/1e308, times out of order or far away, BOMs, junk):
                   diagnose MACHINE --measured M.csv [--io T.csv] --no-plant
    --io N         the --io traces alone, N of them (default: as many as --flows)
    --twincat N    mutated copies of samples/twincat_project (XML structure, ST in CDATA,
                   <Compile Include> out of the folder, links, FIFOs, encodings, {{#N}}
                   markers, the task object): check / init / timeline / predict
    --outs N       commands writing into a prepared --out (planted manifest.json, links out,
                   the user's files, --out a link or a file or through '..'); afterwards a
                   sentinel outside and the user's files inside must be untouched

Each case runs in a forked child (tests/fuzzing.py: Child) with a wall-time limit
(--hang-s), a peak-RSS limit (--rss-mb) and an address-space limit (--as-mb), and ends as
ok, clean (an error message, exit 1/2), traceback, hang, memory or unsafe. Prints per
channel the count, wall time (and per 1,000 cases), each outcome, the largest child RSS,
and the first examples of each bad outcome with the folder holding its input
(outcome.txt: the command, the outcome, stderr); exits 1 if there was any.

    python bench/fuzz.py [--programs 10000] [--machines 5000] [--commands 1000]
        [--truths 2000] [--flows 2000] [--twincat 1000] [--outs 1000] [--seed 1]
        [--hang-s 10] [--rss-mb 1500] [--jobs 1]
    python bench/fuzz.py --only truths,flows --truths 300 --flows 300

``--differential N`` instead unfolds N generated programs with their machine files
(tests/progen.py) event-driven and scan by scan, and counts identical timelines,
differing ones and errors (a generated program that does not run is a generator bug or
an executor fault). Each differing case is saved to a temporary folder (prog.st,
machine.toml, difference.txt); the first few are printed with their first difference,
which event-driven variants (no tiling, no replay) still differ, and (``--shrink K``, 3 by
default) a shrunk program and machine file that still differ. Exits 1 if any differ or
fail. With --differential the other kinds run only when their counts are given.

    python bench/fuzz.py --differential 2000 [--seed 1] [--shrink 3] [--show 5]
"""
from __future__ import annotations

import argparse
import collections
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))
import fuzzing as F  # noqa: E402

# option: (channels it runs, default count)
KINDS = {"programs": (["programs"], 10_000), "machines": (["machines"], 5_000),
         "commands": (["commands"], 1_000), "truths": (["truths"], 2_000),
         "flows": (["flow logs"], 2_000), "io": (["io traces"], 2_000),
         "twincat": (["twincat"], 1_000), "outs": (["outs"], 1_000)}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    for name, (channels, default) in KINDS.items():
        ap.add_argument(f"--{name}", type=int, default=None, metavar="N",
                        help="as many as --flows" if name == "io" else
                        f"{default} (0 with --differential or --only)")
    ap.add_argument("--only", default=None, metavar="KIND,KIND",
                    help=f"run only these ({', '.join(KINDS)}); the others are 0")
    ap.add_argument("--seed", default="1")
    ap.add_argument("--hang-s", type=float, default=10.0, help="wall-time limit of a run")
    ap.add_argument("--rss-mb", type=float, default=1500.0,
                    help="peak RSS of a run beyond which it counts as 'memory'")
    ap.add_argument("--as-mb", type=float, default=4096.0,
                    help="address-space limit (RLIMIT_AS) of each child")
    ap.add_argument("--jobs", type=int, default=1, help="runs at once (forked children)")
    ap.add_argument("--examples", type=int, default=10, metavar="K",
                    help="print the first K distinct examples of each bad outcome")
    ap.add_argument("--differential", type=int, default=0, metavar="N",
                    help="unfold N generated programs event-driven and scan by scan")
    ap.add_argument("--shrink", type=int, default=3, metavar="K",
                    help="shrink the first K differing cases (--differential)")
    ap.add_argument("--show", type=int, default=5, metavar="K",
                    help="print the first K differing cases (--differential)")
    args = ap.parse_args()
    only = None
    if args.only is not None:
        only = {k.strip() for k in args.only.split(",") if k.strip()}
        unknown = only - set(KINDS)
        if unknown:
            ap.error(f"--only: unknown {', '.join(sorted(unknown))} (known: {', '.join(KINDS)})")
    for name, (_, default) in KINDS.items():
        if name == "io" and args.io is None and (only is None or "io" not in only):
            args.io = args.flows        # (--flows runs the --io traces too)
        elif getattr(args, name) is None:
            off = args.differential or (only is not None and name not in only)
            setattr(args, name, 0 if off else default)
    tmp = Path(tempfile.mkdtemp(prefix="plcpred-fuzz-"))
    limits = F.Limits(seconds=args.hang_s, rss_mb=args.rss_mb, as_mb=args.as_mb)
    print(f"cases in {tmp}; limits: {args.hang_s:g} s, {args.rss_mb:g} MB RSS, "
          f"{args.as_mb:g} MB address space; {args.jobs} at once", flush=True)
    fuzzer = F.Fuzzer(tmp / "cases", limits)
    bad = 0
    for name, (channels, _) in KINDS.items():
        n = getattr(args, name)
        if not n:
            continue
        for channel in channels:
            tally = fuzzer.run(channel, n, args.seed, args.jobs, _progress(channel, n))
            bad += tally.bad
            print(("\r" if sys.stderr.isatty() else "") + tally.line(), flush=True)
            _examples(tally, args.examples)
    if args.differential:
        bad += differential(args, tmp)
    return 1 if bad else 0


def _progress(channel: str, n: int):
    if not sys.stderr.isatty():
        return None
    step = max(1, n // 100)

    def show(k: int) -> None:
        if k % step == 0 or k == n:
            print(f"\r{channel} {k}/{n}", end="", file=sys.stderr, flush=True)
    return show


def _examples(tally, k: int) -> None:
    for outcome in F.BAD:
        for _, case, o in tally.examples.get(outcome, [])[:k]:
            print(f"    {outcome}: {o.detail[:400]}")
            print(f"        {case.describe()[:400]}")
            print(f"        input: {case.work} (outcome.txt); {o.wall_s:.1f} s, "
                  f"{o.rss_mb:.0f} MB")
    for what, item in (("largest", tally.largest), ("slowest", tally.slowest)):
        if item is not None:
            case, o = item
            print(f"    {what}: {o.rss_mb:.0f} MB, {o.wall_s:.1f} s, {o.outcome}: "
                  f"{case.describe()[:300]}  ({case.work})")
    if tally.warnings:
        top = sorted(tally.warnings.items(), key=lambda kv: -kv[1])[:5]
        print("    Python warnings (not failures): " + "; ".join(f"{c}x {w}" for w, c in top))


def differential(args, tmp: Path) -> int:
    """Generated programs event-driven against scan-stepping: prints the counts and the
    first differing cases; returns how many differed or failed."""
    import progen

    counts = collections.Counter()
    differing, errors = [], collections.OrderedDict()
    by_feature = collections.Counter()
    t0 = time.perf_counter()
    work = tmp / "run"
    for k in range(args.differential):
        seed = f"{args.seed}-{k}"
        case = progen.generate(seed)
        try:
            with F.time_limit(args.hang_s):
                result = progen.run_case(case, work, diagnose=len(differing) < args.show)
        except F.Hang:
            result = progen.Result("error", f"hang over {args.hang_s:g} s")
        counts[result.status] += 1
        if result.status == "same":
            continue
        where = tmp / f"{result.status}-{seed}"
        case.write(where)
        (where / "difference.txt").write_text(
            f"seed {seed}, horizon {case.horizon}, features {', '.join(case.features)}\n"
            f"{result.detail}\n{result.mechanism}\n")
        if result.status == "error":
            errors.setdefault(result.detail.split(" | ")[0][:160], (seed, where, result))
        else:
            differing.append((seed, where, case, result))
            by_feature.update(case.features)
    wall = time.perf_counter() - t0
    n = args.differential
    print(f"differential   {n:6d} in {wall:6.1f} s: identical {counts['same']:6d}, differing "
          f"{counts['differ']:5d}, errors {counts['error']:4d}   (cases in {tmp})")
    if differing:
        common = ", ".join(f"{f} {c}" for f, c in by_feature.most_common(8))
        print(f"    features of the differing cases (how many hold each): {common}")
    for j, (seed, where, case, result) in enumerate(differing[:args.show]):
        print(f"  seed {seed} ({', '.join(case.features)}), horizon {case.horizon}: "
              f"{result.detail}")
        if result.mechanism:
            print(f"      {result.mechanism}")
        print(f"      {where / progen.PROGRAM_FILE}")
        if j < args.shrink:
            small = progen.shrink(case, tmp / f"shrink-{seed}")
            out = small.write(tmp / f"shrunk-{seed}")
            r = progen.run_case(small, tmp / f"shrink-{seed}", diagnose=False)
            print(f"      shrunk ({out.parent}): {r.detail}")
            for line in (small.program.rstrip() + "\n---\n" + small.machine.rstrip()).splitlines():
                print(f"        {line}")
    for seed, where, result in list(errors.values())[:args.show]:
        print(f"  error, seed {seed}: {result.detail[:300]}")
        print(f"      {where / progen.PROGRAM_FILE}")
    return counts["differ"] + counts["error"]


if __name__ == "__main__":
    sys.exit(main())
