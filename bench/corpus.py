"""How much real, public PLC code plcpred reads: syntax, file-by-file check and
project check pass rates, and tracebacks (which must be zero), per source project.

    python bench/corpus.py --fetch            # clone the projects below into the cache
    python bench/corpus.py                    # measure (the cache, or --root DIR)
    python bench/corpus.py --failures 3       # and show the first problems of each project

The projects are fetched, not kept in the repository: their licences differ (MIT, GPL,
none stated), so only their names, commits and licences are listed here. ``--root`` may
point at any folder of checked-out projects (one sub-folder per project) to measure
another corpus the same way.

What counts:
* a *program file* is ST (``.st``, ``.iecst``, ``.exp``-free), a TwinCAT object file or a
  PLCopen XML project; other XML (Beremiz project settings, build files) is not one;
* *syntax*: the file loads (``plcpred check --syntax-only``);
* *file check*: it loads and ``check`` finds no error with the file on its own;
* *project check*: no error when checked with the other files of its project (the files
  its ``.plcproj`` compiles, or else those of its folder) and the libraries it uses
  (the shipped stubs; TcUnit for the TcUnit examples, as ``--lib`` would give it);
* *+extern*: the project check with ``--allow-external`` (names of libraries that are
  not at hand are warnings);
* a *traceback* is any exception that is not plcpred's positioned error.
"""
from __future__ import annotations

import argparse
import subprocess
import sys
import traceback
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from plcpred.parser import ProgramError, load_program  # noqa: E402
from plcpred.parser import _sniff  # noqa: E402
from plcpred.parser.check import check_program  # noqa: E402
from plcpred.parser.libraries import library_program  # noqa: E402
from plcpred.parser.twincat import OBJECT_SUFFIXES, read_source  # noqa: E402

# (GitHub repository, commit, licence as the repository states it)
SOURCES = [
    ("tcunit/TcUnit", "d447f95dff584cd9ae856784b189315a05ff93f1", "MIT"),
    ("tcunit/ExampleProjects", "c2e644cd9db3757ec95f6725925d5c5bd354e586", "none stated"),
    ("klauer/blark", "1922eed94885f41fcc2974981e1041196f7f99f6", "GPL-2.0"),
    ("wonka929/OSCAT_OpenPLC", "7805d6df1fba4b0de666a1a720b51971c7af8afa", "none stated"),
    ("pcdshub/lcls-twincat-motion", "3cec6ffe2ceeb9a2852dab8a508c346c0da3addf",
     "SLAC (BSD-like)"),
    ("fisothemes/FisoThemes-Controller-Toolbox-Library-for-TwinCAT",
     "1ff02710f784887dcf1db1d203d9abb06030a05c", "MIT"),
    ("MichielVanwelsenaere/HomeAutomation.CoDeSys3", "298b7bfd73761792e480cad00f342dc38d54a763",
     "MIT"),
    ("beremiz/beremiz", "9eb53af357cda387989c086aee00a211ef95689a", "GPL-2.0"),
]
# libraries the projects above use, fetched beside them (under _libraries/) but not
# measured themselves: SLAC's own TwinCAT libraries that lcls-twincat-motion references
LIBRARY_SOURCES = [
    ("pcdshub/lcls-twincat-general", "02ece2d1975fcf851e0f23f7799177b402036367",
     "SLAC (BSD-like)"),
    ("pcdshub/lcls-twincat-pmps", "21b168f8755ecb727f90e15e727fae3fb41b5bde",
     "SLAC (BSD-like)"),
    ("pcdshub/lcls-twincat-math", "37e2d8951dc5bf856a655b201996f1ae0c5ea814",
     "SLAC (BSD-like)"),
]
LIBS = "_libraries"
# libraries a project uses that another fetched project provides (as --lib would give them)
TCUNIT = "tcunit+TcUnit/TcUnit/TcUnit/TcUnit.plcproj"
LIBRARIES = {
    "tcunit+ExampleProjects": [TCUNIT],
    "tcunit+TcUnit": [TCUNIT],   # for its verifier
    "pcdshub+lcls-twincat-motion": [
        TCUNIT,
        f"{LIBS}/pcdshub+lcls-twincat-general/LCLSGeneral/LCLSGeneral/LCLSGeneral.plcproj",
        f"{LIBS}/pcdshub+lcls-twincat-pmps/lcls-twincat-pmps/PMPS/PMPS.plcproj",
        f"{LIBS}/pcdshub+lcls-twincat-math/lcls-twincat-math/lcls_twincat_math/"
        "lcls_twincat_math.plcproj"],
}
CACHE = Path.home() / ".cache" / "plcpred-corpus"
ST_SUFFIXES = (".st", ".iecst")


def fetch(root: Path) -> None:
    root.mkdir(parents=True, exist_ok=True)
    for repo, commit, _ in SOURCES + LIBRARY_SOURCES:
        dest = root / (LIBS if (repo, commit, _) in LIBRARY_SOURCES else "") / repo.replace(
            "/", "+")
        dest.parent.mkdir(parents=True, exist_ok=True)
        if not dest.exists():
            subprocess.run(["git", "clone", "--quiet", "--filter=blob:limit=5m",
                            f"https://github.com/{repo}.git", str(dest)], check=True)
        subprocess.run(["git", "-C", str(dest), "checkout", "--quiet", commit], check=True)


def program_files(project: Path) -> list[Path]:
    out = []
    for p in sorted(project.rglob("*")):
        if not p.is_file() or ".git" in p.parts:
            continue
        suffix = p.suffix.lower()
        if suffix in ST_SUFFIXES + OBJECT_SUFFIXES:
            out.append(p)
        elif suffix == ".xml" and _sniff(read_source(p)[:4096]) == ".xml":
            out.append(p)
    return out


def group_of(path: Path, project: Path) -> Path:
    """The files a file is checked with: its .plcproj's folder, else its own folder
    (a PLCopen file is a project on its own)."""
    if path.suffix.lower() == ".xml":
        return path
    for parent in path.parents:
        if parent == project.parent:
            break
        if any(c.suffix.lower() == ".plcproj" for c in parent.iterdir()):
            return parent
    return path.parent


class Tally:
    def __init__(self):
        self.files = self.syntax = self.file_ok = self.project_ok = self.tracebacks = 0
        self.external_ok = 0
        self.problems: list[str] = []


def _load(path: Path, tally: Tally):
    try:
        return load_program(path, libraries=False), None
    except ProgramError as e:
        return None, str(e)
    except Exception:  # noqa: BLE001 - counting them is the point
        tally.tracebacks += 1
        return None, f"{path}: TRACEBACK\n{traceback.format_exc(limit=3)}"


def _check(program, context, tally: Tally, libs=(), external=False):
    """Errors of ``program`` checked with ``context`` and what they use from libraries,
    as ``plcpred check`` does (``--allow-external`` with ``external``)."""
    try:
        context = list(context) + [library_program([program, *context], libs)]
        return [str(e) for e in check_program(program, context, external)[0]]
    except Exception:  # noqa: BLE001
        tally.tracebacks += 1
        return [f"{program.source}: TRACEBACK in check\n{traceback.format_exc(limit=3)}"]


def measure(project: Path, libs=()) -> Tally:
    t = Tally()
    loaded = {}
    for f in program_files(project):
        t.files += 1
        prog, problem = _load(f, t)
        if prog is None:
            t.problems.append(problem)
            continue
        t.syntax += 1
        loaded[f] = prog
        errors = _check(prog, [], t)
        t.file_ok += not errors
    groups = defaultdict(list)
    for f in loaded:
        groups[group_of(f, project)].append(f)
    for files in groups.values():
        context = [loaded[f] for f in files]
        for f in files:
            errors = _check(loaded[f], context, t, libs)
            if errors:
                t.problems.append(errors[0])
            else:
                t.project_ok += 1
            t.external_ok += not _check(loaded[f], context, t, libs, external=True)
    return t


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--root", type=Path, default=CACHE,
                    help=f"folder of checked-out projects (default {CACHE})")
    ap.add_argument("--fetch", action="store_true", help="clone the listed projects first")
    ap.add_argument("--failures", type=int, default=0, metavar="N",
                    help="print the first N problems of each project")
    args = ap.parse_args(argv)
    if args.fetch:
        fetch(args.root)
    projects = sorted(p for p in args.root.iterdir() if p.is_dir() and p.name != LIBS
                      ) if args.root.is_dir() else []
    if not projects:
        print(f"no projects under {args.root}: run with --fetch, or give --root")
        return 2
    pct = lambda a, b: f"{100 * a / b:5.1f} %" if b else "    -"  # noqa: E731
    print(f"{'project':38} {'files':>5} {'syntax':>8} {'file chk':>8} {'proj chk':>8} "
          f"{'+extern':>8} {'tracebk':>7}")
    total = Tally()
    for project in projects:
        t = measure(project, [args.root / p for p in LIBRARIES.get(project.name, [])])
        for k in ("files", "syntax", "file_ok", "project_ok", "external_ok", "tracebacks"):
            setattr(total, k, getattr(total, k) + getattr(t, k))
        print(f"{project.name[:38]:38} {t.files:5} {pct(t.syntax, t.files):>8} "
              f"{pct(t.file_ok, t.files):>8} {pct(t.project_ok, t.files):>8} "
              f"{pct(t.external_ok, t.files):>8} {t.tracebacks:7}")
        for problem in t.problems[:args.failures]:
            print("    " + problem.replace("\n", "\n    ")[:400])
    t = total
    print(f"{'all':38} {t.files:5} {pct(t.syntax, t.files):>8} {pct(t.file_ok, t.files):>8} "
          f"{pct(t.project_ok, t.files):>8} {pct(t.external_ok, t.files):>8} {t.tracebacks:7}")
    return 1 if total.tracebacks else 0


if __name__ == "__main__":
    sys.exit(main())
