"""Start-up of the command line against a bare interpreter, measured in the same run.

Each command runs ``--rounds`` times, interleaved with the others (one of each per round,
so that the machine's load falls on all of them alike); printed per command: the median
and best wall time and CPU time (user + system of the child alone), and the ratio of the
medians to ``python -c pass``'s. Goal: ``plcpred check rig.st`` at most 4x a bare
interpreter; ``--help`` and ``check --syntax-only`` import neither numpy, matplotlib nor
the compiler (``check`` may import the compiler, not numpy). The modules each command
imported (``-X importtime``) are listed against that.

The children see compiled bytecode, as an installed package has it (pip compiles it when
it installs): PYTHONDONTWRITEBYTECODE is lifted and PYTHONPYCACHEPREFIX points at a fresh
temporary folder, which a first, uncounted run of each command fills. ``--as-is`` leaves
the environment alone (with PYTHONDONTWRITEBYTECODE=1 every module is compiled again in
every run).

    python bench/startup.py [--rounds 20] [--as-is]
"""
from __future__ import annotations

import argparse
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RIG = ROOT / "samples" / "prototype_rig" / "rig.st"
# what a check must not wait for (the compiler only with --syntax-only and --help)
HEAVY = ("numpy", "matplotlib", "scipy", "pandas", "lark", "plcpred.sequencer")
GOAL = 4.0


def plcpred_command() -> list[str]:
    """The ``plcpred`` console script next to this interpreter, else ``python -m plcpred``."""
    script = Path(sys.executable).parent / "plcpred"
    return [str(script)] if script.exists() else [sys.executable, "-m", "plcpred"]


def bytecode_env(folder: str) -> dict:
    """The environment of a child that reads and writes bytecode under ``folder``."""
    env = dict(os.environ)
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    env["PYTHONPYCACHEPREFIX"] = folder
    return env


def run_once(cmd: list[str], env: dict | None, out=None) -> tuple[float, float, int]:
    """(wall s, CPU s of the child, exit code) of one run; its output goes to ``out`` (a
    file, both streams), or nowhere."""
    t0 = time.perf_counter()
    child = subprocess.Popen(cmd, stdout=out or subprocess.DEVNULL,
                             stderr=out or subprocess.DEVNULL, env=env)
    _, status, usage = os.wait4(child.pid, 0)
    wall = time.perf_counter() - t0
    child.returncode = os.waitstatus_to_exitcode(status)
    return wall, usage.ru_utime + usage.ru_stime, child.returncode


def measure(commands: dict[str, list[str]], rounds: int, env: dict | None) -> dict:
    """label -> {"wall": [...], "cpu": [...], "codes": {...}}, the commands interleaved;
    a first run of each is not counted (it fills the bytecode cache)."""
    out = {label: {"wall": [], "cpu": [], "codes": set()} for label in commands}
    for cmd in commands.values():
        run_once(cmd, env)
    for _ in range(rounds):
        for label, cmd in commands.items():
            wall, cpu, code = run_once(cmd, env)
            out[label]["wall"].append(wall)
            out[label]["cpu"].append(cpu)
            out[label]["codes"].add(code)
    return out


def imported(cmd: list[str], env: dict | None) -> set[str]:
    """The modules ``cmd`` imports (``python -X importtime``), for a plcpred command."""
    if cmd[0] != sys.executable:
        cmd = [sys.executable, "-m", "plcpred", *cmd[1:]]
    err = subprocess.run([sys.executable, "-X", "importtime", *cmd[1:]], env=env,
                         capture_output=True, text=True, check=False).stderr
    return set(re.findall(r"^import time:\s+\d+ \|\s+\d+ \| *(\S+)$", err, re.MULTILINE))


def heavy_imports(modules: set[str]) -> set[str]:
    """Which of :data:`HEAVY` are among ``modules`` (a package for any of its modules)."""
    return {h for h in HEAVY for m in modules if m == h or m.startswith(h + ".")}


def report(results: dict, baseline: str) -> None:
    base_wall = statistics.median(results[baseline]["wall"])
    base_cpu = statistics.median(results[baseline]["cpu"])
    print(f"{'command':<44} {'wall ms median/best':>20} {'CPU ms median/best':>19} "
          f"{'ratio wall':>10} {'ratio CPU':>9}")
    for label, r in results.items():
        wall, cpu = statistics.median(r["wall"]), statistics.median(r["cpu"])
        codes = "" if r["codes"] <= {0} else f"  exit {sorted(r['codes'])}"
        print(f"{label:<44} {wall * 1e3:9.1f} /{min(r['wall']) * 1e3:7.1f}  "
              f"{cpu * 1e3:9.1f} /{min(r['cpu']) * 1e3:7.1f}  {wall / base_wall:9.2f}x "
              f"{cpu / base_cpu:8.2f}x{codes}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=20)
    ap.add_argument("--as-is", action="store_true",
                    help="leave the environment's bytecode settings alone")
    args = ap.parse_args(argv)
    plcpred = plcpred_command()
    commands = {
        "python -c pass": [sys.executable, "-c", "pass"],
        "plcpred --help": [*plcpred, "--help"],
        "plcpred check --help": [*plcpred, "check", "--help"],
        "plcpred check --syntax-only rig.st": [*plcpred, "check", "--syntax-only", str(RIG)],
        "plcpred check rig.st": [*plcpred, "check", str(RIG)],
    }
    cache = tempfile.mkdtemp(prefix="plcpred-startup-")
    try:
        env = None if args.as_is else bytecode_env(cache)
        print(f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}; bytecode: "
              f"{'as the environment has it' if args.as_is else 'compiled once, reused'}; "
              f"{args.rounds} rounds")
        results = measure(commands, args.rounds, env)
        report(results, "python -c pass")
        ratio = (statistics.median(results["plcpred check rig.st"]["cpu"])
                 / statistics.median(results["python -c pass"]["cpu"]))
        print(f"goal: plcpred check rig.st at most {GOAL:g}x python -c pass (CPU): "
              f"{'met' if ratio <= GOAL else 'NOT met'} ({ratio:.2f}x)")
        for label, cmd in list(commands.items())[1:]:
            heavy = sorted(heavy_imports(imported(cmd, env)))
            print(f"  {label} imports: {', '.join(heavy) or 'none of ' + ', '.join(HEAVY)}")
    finally:
        shutil.rmtree(cache, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
