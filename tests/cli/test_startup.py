"""What the command line imports before it answers: a syntax check and --help wait for
neither numpy, matplotlib, lark nor the compiler (bench/startup.py measures the time)."""
import json
import subprocess
import sys

import pytest
from conftest import SAMPLES

from plcpred.cli import main

RIG = str(SAMPLES / "prototype_rig" / "rig.st")
# what a syntax check or --help must not import: each a package or its modules
HEAVY = ("numpy", "matplotlib", "scipy", "pandas", "lark", "plcpred.sequencer")


def imported_by(argv: list[str]) -> set[str]:
    """The modules a fresh interpreter has imported after ``plcpred ARGV``."""
    code = ("import json, sys\nfrom plcpred.cli import main\n"
            f"try:\n    main({argv!r})\nexcept SystemExit:\n    pass\n"
            "print('MODULES', json.dumps(sorted(sys.modules)))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       check=False)
    assert r.returncode == 0, r.stderr
    line = next(x for x in r.stdout.splitlines() if x.startswith("MODULES "))
    return set(json.loads(line[len("MODULES "):]))


def heavy(modules: set[str]) -> set[str]:
    return {h for h in HEAVY for m in modules if m == h or m.startswith(h + ".")}


@pytest.mark.parametrize("argv", [
    ["check", "--syntax-only", RIG],
    ["--help"],
    ["check", "--help"],
    ["timeline", "--help"],
    ["diagnose", "--help"],
    ["emulate", "--help"],
])
def test_a_syntax_check_and_help_import_nothing_heavy(argv):
    assert heavy(imported_by(argv)) == set()


def test_a_full_check_imports_the_compiler_and_nothing_heavy():
    """The compiler, but neither numpy nor the executor nor the machine file's reader:
    the sequencer's package names load on first use."""
    modules = imported_by(["check", RIG])
    assert "plcpred.sequencer.compiler" in modules
    assert heavy(modules) <= {"plcpred.sequencer"}
    assert "numpy" not in modules and "plcpred.sequencer.executor" not in modules


def test_the_syntax_check_reports_every_syntax_error_and_unreadable_files(tmp_path, capsys):
    bad = tmp_path / "bad.st"
    bad.write_text("PROGRAM P\nVAR x : INT; END_VAR\nx := ;\nx := 1 +;\nEND_PROGRAM\n")
    ok = tmp_path / "ok.st"
    ok.write_text("PROGRAM P\nVAR x : INT; END_VAR\nx := 1;\nEND_PROGRAM\n")
    assert main(["check", "--syntax-only", str(bad), str(ok)]) == 1
    out, err = capsys.readouterr()
    assert err.count("bad.st:") == 2 and f"{ok}: ok: 1 POU (P)" in out
    assert main(["check", "--syntax-only", str(ok), str(tmp_path / "missing.st")]) == 2
    assert "cannot read file" in capsys.readouterr().err
