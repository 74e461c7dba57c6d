"""Golden files: every command's outputs on the bundled samples, byte for byte.

Each case runs ``plcpred`` in-process (``plcpred.cli.main``, from the repository root,
the samples named by their relative paths as a user types them) into a temporary
folder and compares what it wrote and printed with ``tests/data/golden/<command>/<case>/``:

- ``predict`` on every ``samples/**/*.toml`` (12 s, default grid, ``--no-plot``):
  timeline.csv, demand.csv, summary.json, manifest.json;
- ``size`` on every sample (30 s, so that the periodic machines show a steady cycle; size
  has no switch to leave its plots out): sizing.json, sizing.md, manifest.json;
- ``compare`` of press.toml against a copy whose press cylinder has a 100 mm bore
  (20 s): the table (exit 1, the gate fails) and ``--json --max-increase 40%`` (exit 0);
- ``sweep`` of the rig over 2 x 2 x 2 scenarios (10 s), once in-process (``--workers
  1``) and once in a process pool (``--workers 2``): sweep.csv, manifest.json;
- ``emulate --seed 1 --no-plot`` on the rig (6 s), the press and the sorter (5 s):
  measured.csv, timeline.csv, plant.csv, manifest.json;
- ``diagnose`` of the rig on a 25 s emulated log with a hidden leak (``emulate --truth``):
  the emulated measured.csv and timeline.csv and its manifest.json (which holds
  plant.csv's hash: the file itself, 2 MB, is not stored), then ``diagnose --json``.

Every case also stores ``console.txt``: the command line, the exit code, stdout and
stderr.

Normalisations (what is legitimately not the same from run to run; everything else is
compared as written):

- the case's temporary folder is written ``<TMP>`` and the repository root ``<REPO>``,
  wherever they appear (console output, manifest.json's ``command``);
- manifest.json: ``run_id`` (random) is ``<RUN_ID>`` and ``created`` (the time) is
  ``<CREATED>``; the size and SHA-256 of a file not compared (below) are ``<NOT
  COMPARED>``, and the SHA-256 of a file normalised here is ``<NORMALISED>`` (its size is
  kept). The other files' sizes and hashes stay, so the manifest still checks them;
- not compared at all: plots (``*.png``) and ``sizing.html`` (plots embedded): their
  bytes depend on matplotlib and its fonts; their names still appear in manifest.json;
- sizing.md: the date in its ``tool`` row is ``<DATE>``;
- emulate's stdout: the wall time of its ``plant:`` line and the speed against real
  time are ``<WALL>`` and ``<SPEED>``.

To accept new outputs (only when a change of behaviour is intended), rewrite the stored
files and look at ``git diff tests/data/golden``::

    PLCPRED_UPDATE_GOLDEN=1 python -m pytest tests/cli/test_golden.py -n0

(or ``'tests/cli/test_golden.py::test_golden[predict/press]'`` for one case; a mismatch
prints this command for its case). In that mode every case is rewritten and reported as
skipped, saying which files it wrote or removed, and stored cases that no longer exist
are removed. Some stored lines end in spaces (emulate's table pads its ``(hidden)`` row):
they are what plcpred prints, so leave them as they are.
"""
from __future__ import annotations

import difflib
import json
import os
import re
import shlex
import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import pytest

from plcpred.cli import main

ROOT = Path(__file__).resolve().parents[2]
GOLDEN = ROOT / "tests" / "data" / "golden"
UPDATE_ENV = "PLCPRED_UPDATE_GOLDEN"
UPDATE = os.environ.get(UPDATE_ENV, "") not in ("", "0")
REGENERATE = f"{UPDATE_ENV}=1 python -m pytest tests/cli/test_golden.py -n0"


def _regenerate(case: str) -> str:
    """The command that rewrites one case's stored files."""
    return f"{UPDATE_ENV}=1 python -m pytest 'tests/cli/test_golden.py::test_golden[{case}]' -n0"


# the samples, as paths relative to the repository root
MACHINES = sorted(p.relative_to(ROOT).as_posix() for p in (ROOT / "samples").rglob("*.toml"))

NOT_COMPARED = re.compile(r".*\.(png|html)$")      # plots, and the report embedding them
DIFF_LINES = 30                                    # diff lines shown for a mismatch
LINE_CHARS = 200                                   # longer diff lines are cut here


def _slug(machine: str) -> str:
    """prototype_rig/rig.toml -> prototype_rig.rig, press.toml -> press."""
    return machine.removeprefix("samples/").removesuffix(".toml").replace("/", ".")


# ------------------------------------------------------------------ normalisation

def _normalise_manifest(text: str, normalised: set[str]) -> str:
    text = re.sub(r'"run_id": "[^"]*"', '"run_id": "<RUN_ID>"', text)
    text = re.sub(r'"created": "[^"]*"', '"created": "<CREATED>"', text)
    for name in json.loads(text)["files"]:
        entry = ("(" + re.escape(json.dumps(name)) +
                 r': \{\s*"bytes": )(\d+)(,\s*"sha256": )"[^"]*"')
        if NOT_COMPARED.match(name):
            text, n = re.subn(entry, r'\1"<NOT COMPARED>"\3"<NOT COMPARED>"', text)
        elif name in normalised:
            text, n = re.subn(entry, r'\1\2\3"<NORMALISED>"', text)
        else:
            continue
        assert n == 1, f"manifest.json: cannot find the entry of {name!r} in:\n{text}"
    return text


# file name -> what to replace in it, for outputs that are not the same from run to run
FILE_RULES: dict[str, list[tuple[str, str]]] = {
    "sizing.md": [(r"(\| tool \| plcpred [^|,]*, )\d{4}-\d{2}-\d{2}", r"\1<DATE>")],
}
EMULATE_WALL = (r"(plant: \d+ pieces integrated, \d+ reused; )[0-9.]+ s \([0-9.]+x real time\)",
                r"\1<WALL> s (<SPEED>x real time)")


def _paths(text: str, tmp: Path) -> str:
    """The temporary folder as <TMP>, the repository as <REPO> (longest first, so either
    may hold the other)."""
    places = {str(tmp): "<TMP>", str(tmp.resolve()): "<TMP>",
              str(ROOT): "<REPO>", str(ROOT.resolve()): "<REPO>"}
    for path in sorted(places, key=len, reverse=True):
        text = text.replace(path, places[path])
    return text


# ------------------------------------------------------------------ running a command

@dataclass
class Run:
    """What one case produced: stored name -> normalised bytes."""
    tmp: Path
    outputs: dict[str, bytes] = field(default_factory=dict)

    def cli(self, capsys, args: list[str], prefix: str = "",
            rules: list[tuple[str, str]] = ()) -> int:
        """Run ``plcpred ARGS`` in-process and keep its console as PREFIX/console.txt."""
        capsys.readouterr()
        code = main(list(args))
        cap = capsys.readouterr()
        out, err = cap.out, cap.err
        for pattern, repl in rules:
            out = re.sub(pattern, repl, out)
            err = re.sub(pattern, repl, err)
        text = (f"$ plcpred {shlex.join(args)}\nexit {code}\n--- stdout\n{out}"
                f"--- stderr\n{err}")
        self.outputs[prefix + "console.txt"] = _paths(text, self.tmp).encode()
        return code

    def files(self, folder: Path, prefix: str = "", skip: tuple[str, ...] = ()) -> None:
        """Keep every file in FOLDER (normalised) as PREFIX/name, but plots and SKIP."""
        names = sorted(p.name for p in folder.iterdir())
        assert "manifest.json" in names, f"no manifest.json in {folder}: {names}"
        normalised = {n for n in names if n in FILE_RULES}
        for name in names:
            if NOT_COMPARED.match(name) or name in skip:
                continue
            data = (folder / name).read_bytes()
            text = data.decode("utf-8")
            for pattern, repl in FILE_RULES.get(name, []):
                text = re.sub(pattern, repl, text)
            if name == "manifest.json":
                text = _normalise_manifest(text, normalised)
            self.outputs[prefix + name] = _paths(text, self.tmp).encode()


def _out(run: Run, name: str = "out") -> Path:
    return run.tmp / name


# ------------------------------------------------------------------ the cases

def predict_case(machine: str) -> Callable:
    def case(run: Run, capsys) -> None:
        out = _out(run)
        code = run.cli(capsys, ["predict", machine, "--horizon", "12s", "--out", str(out),
                                "--no-plot"])
        assert code == 0
        run.files(out)
    return case


def size_case(machine: str) -> Callable:
    def case(run: Run, capsys) -> None:
        out = _out(run)
        code = run.cli(capsys, ["size", machine, "--horizon", "30s", "--out", str(out)])
        assert code == 0
        run.files(out)
    return case


def emulate_case(machine: str, horizon: str) -> Callable:
    def case(run: Run, capsys) -> None:
        out = _out(run)
        code = run.cli(capsys, ["emulate", machine, "--horizon", horizon, "--seed", "1",
                                "--out", str(out), "--no-plot"], rules=[EMULATE_WALL])
        assert code == 0
        run.files(out)
    return case


def _bigger_press(run: Run) -> Path:
    """press.toml with a 100 mm press cylinder (80 mm in the sample)."""
    text = (ROOT / "samples" / "press.toml").read_text()
    assert text.count("bore_mm = 80\n") == 1 and text.count('program = "sfc_press.st"') == 1
    text = text.replace("bore_mm = 80\n", "bore_mm = 100\n").replace(
        'program = "sfc_press.st"', f'program = "{ROOT / "samples" / "sfc_press.st"}"')
    new = run.tmp / "press_bigger.toml"
    new.write_text(text)
    return new


def compare_table_case(run: Run, capsys) -> None:
    new = _bigger_press(run)
    assert run.cli(capsys, ["compare", "samples/press.toml", str(new),
                            "--horizon", "20s"]) == 1


def compare_json_case(run: Run, capsys) -> None:
    new = _bigger_press(run)
    assert run.cli(capsys, ["compare", "samples/press.toml", str(new), "--horizon", "20s",
                            "--json", "-", "--max-increase", "40%"]) == 0


def sweep_case(workers: int) -> Callable:
    def case(run: Run, capsys) -> None:
        out = _out(run)
        code = run.cli(capsys, ["sweep", "samples/prototype_rig/rig.toml", "--horizon", "10s",
                                "--set", "supply_bar_g=3,3.987",
                                "--set", "air knives.pressure_bar_g=1.5,2",
                                "--measure", "leaks=-30%", "--workers", str(workers),
                                "--out", str(out)])
        assert code == 0
        run.files(out)
    return case


HIDDEN_LEAK = """\
# the real machine's deviation the prediction does not see
[[consumer]]
name = "hidden"
kind = "leak"
C = 8e-10
b = 0.15
m = 0.7
"""


def diagnose_case(run: Run, capsys) -> None:
    truth = run.tmp / "truth.toml"
    truth.write_text(HIDDEN_LEAK)
    logged = _out(run, "emulated")
    machine = "samples/prototype_rig/rig.toml"
    assert run.cli(capsys, ["emulate", machine, "--horizon", "25s", "--seed", "1",
                            "--truth", str(truth), "--out", str(logged), "--no-plot"],
                   prefix="emulate/", rules=[EMULATE_WALL]) == 0
    run.files(logged, prefix="emulate/", skip=("plant.csv",))   # its hash is in the manifest
    report = run.tmp / "diagnose.json"
    assert run.cli(capsys, ["diagnose", machine, "--measured", str(logged / "measured.csv"),
                            "--json", str(report)], prefix="diagnose/") == 0
    run.outputs["diagnose/diagnose.json"] = _paths(report.read_text(), run.tmp).encode()


CASES: dict[str, Callable] = {}
for _m in MACHINES:
    CASES[f"predict/{_slug(_m)}"] = predict_case(_m)
for _m in MACHINES:
    CASES[f"size/{_slug(_m)}"] = size_case(_m)
CASES["compare/press-bigger-bore"] = compare_table_case
CASES["compare/press-bigger-bore-json"] = compare_json_case
CASES["sweep/rig-serial"] = sweep_case(1)
CASES["sweep/rig-pool"] = sweep_case(2)
for _m, _h in [("samples/prototype_rig/rig.toml", "6s"), ("samples/press.toml", "5s"),
               ("samples/sorter.toml", "5s")]:
    CASES[f"emulate/{_slug(_m)}"] = emulate_case(_m, _h)
CASES["diagnose/rig-hidden-leak"] = diagnose_case


# ------------------------------------------------------------------ comparing

def _diff(name: str, want: bytes, got: bytes) -> str:
    a = want.decode("utf-8", "replace").splitlines()
    b = got.decode("utf-8", "replace").splitlines()
    lines = list(difflib.unified_diff(a, b, f"stored/{name}", f"now/{name}", n=1,
                                      lineterm=""))
    if not lines:      # the same lines: the difference is in line endings or the last one
        return f"  (same lines, different bytes: {len(want)} stored, {len(got)} now)"
    shown = [ln if len(ln) <= LINE_CHARS else ln[:LINE_CHARS] + " [...]"
             for ln in lines[:DIFF_LINES]]
    if len(lines) > DIFF_LINES:
        shown.append(f"... ({len(lines) - DIFF_LINES} more diff lines)")
    return "\n".join(shown)


def _stored(folder: Path) -> dict[str, bytes]:
    if not folder.is_dir():
        return {}
    return {p.relative_to(folder).as_posix(): p.read_bytes()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def _update(folder: Path, outputs: dict[str, bytes]) -> list[str]:
    """Make FOLDER hold exactly OUTPUTS; what was done, file by file."""
    stored = _stored(folder)
    done = []
    for name in sorted(set(stored) | set(outputs)):
        path = folder / name
        if name not in outputs:
            path.unlink()
            done.append(f"removed {name}")
        elif stored.get(name) != outputs[name]:
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(outputs[name])
            done.append(f"{'rewrote' if name in stored else 'wrote'} {name}")
    for d in sorted((p for p in folder.rglob("*") if p.is_dir()), reverse=True):
        if not any(d.iterdir()):
            d.rmdir()
    return done


@pytest.mark.parametrize("case", list(CASES))
def test_golden(case, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(ROOT)            # samples are named relative to the repository
    run = Run(tmp_path)
    CASES[case](run, capsys)
    folder = GOLDEN / case
    if UPDATE:
        done = _update(folder, run.outputs)
        pytest.skip(f"{UPDATE_ENV}: {case}: {', '.join(done) if done else 'unchanged'}")
    stored = _stored(folder)
    rerun = _regenerate(case)
    if not stored:
        pytest.fail(f"no stored outputs for {case} in {folder.relative_to(ROOT)}; write "
                    f"them with:\n  {rerun}", pytrace=False)
    problems, diffs = [], []
    for name in sorted(set(stored) | set(run.outputs)):
        if name not in run.outputs:
            problems.append(f"{name}: stored but no longer written")
        elif name not in stored:
            problems.append(f"{name}: written now but not stored")
        elif stored[name] != run.outputs[name]:
            problems.append(f"{name}: differs")
            if not diffs:
                diffs.append(_diff(name, stored[name], run.outputs[name]))
    if problems:
        pytest.fail(f"{case}: the outputs differ from {folder.relative_to(ROOT)}/:\n  "
                    + "\n  ".join(problems) + "\n\n" + "\n".join(diffs)
                    + f"\n\nif the change is intended, rewrite the stored files with:\n  "
                    f"{rerun}\nand review git diff {folder.relative_to(ROOT)}",
                    pytrace=False)


def test_no_stored_case_without_a_test():
    """Every folder of stored outputs belongs to a case (a renamed or removed case leaves
    none behind); with the update switch, stale ones are removed."""
    stale = sorted(p.relative_to(GOLDEN).as_posix()
                   for p in GOLDEN.glob("*/*") if p.is_dir()
                   and p.relative_to(GOLDEN).as_posix() not in CASES)
    stale += sorted(p.relative_to(GOLDEN).as_posix() for p in GOLDEN.glob("*")
                    if p.is_dir() and not any(c.startswith(p.name + "/") for c in CASES))
    if UPDATE:
        for name in stale:
            shutil.rmtree(GOLDEN / name, ignore_errors=True)
        return
    if stale:
        pytest.fail(f"stored outputs of no case: {', '.join(stale)} (remove them, or run "
                    f"{REGENERATE})", pytrace=False)
