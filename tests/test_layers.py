"""The package's shape: each layer imports only from the ones below it (pyproject.toml's
import-linter contracts), no module takes part in an import cycle, imports sit at the top
of their module, and no module reaches for another's private names."""
from __future__ import annotations

import ast
from pathlib import Path

import grimp
import pytest
from importlinter.cli import lint_imports

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "plcpred"
# third-party modules slow to import that only some runs need: imported where used
HEAVY = {"scipy", "matplotlib", "pandas", "dask",
         "prometheus_client"}      # (optional: plcpred watch --prometheus only)
# the command line imports each command's code when the command runs, so that `--help`
# and a syntax check do not wait for numpy, scipy and the compiler
LAZY_MODULES = {"plcpred/cli/main.py",
                # lark (.tablegen) only when the shipped parser tables do not match a grammar
                "plcpred/parser/tables.py"}


def _modules():
    for path in sorted(PACKAGE.rglob("*.py")):
        yield path.relative_to(ROOT).as_posix(), path, ast.parse(path.read_text())


def _nested_imports(tree):
    """Every import statement inside a function."""
    out = []

    def visit(node, depth):
        for child in ast.iter_child_nodes(node):
            inner = depth + isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef))
            if depth and isinstance(child, (ast.Import, ast.ImportFrom)):
                out.append(child)
            visit(child, inner)
    visit(tree, 0)
    return out


def test_the_layer_contracts_hold(capsys, monkeypatch):
    monkeypatch.chdir(ROOT)
    code = lint_imports(config_filename=str(ROOT / "pyproject.toml"), no_cache=True,
                        no_logo=True)
    assert code == 0, capsys.readouterr().out


def test_no_module_is_part_of_an_import_cycle():
    """Function-level imports count, and so do a package and its own modules."""
    graph = grimp.build_graph("plcpred", cache_dir=None)
    modules = sorted(graph.modules)
    cycles = []
    for m in modules:
        for imported in graph.find_modules_directly_imported_by(m):
            if graph.chain_exists(imported=m, importer=imported):
                cycles.append(f"{m} -> {imported}")
    assert not cycles, "import cycles:\n" + "\n".join(cycles)


def test_imports_sit_at_the_top_of_their_module():
    """Inside a function only a heavy third-party module (with a comment saying why just
    before), or in the command line, the command's own code."""
    found = []
    for name, path, tree in _modules():
        lines = path.read_text().splitlines()
        for node in _nested_imports(tree):
            top = (node.module if isinstance(node, ast.ImportFrom) else node.names[0].name)
            top = (top or "").split(".")[0]
            if name in LAZY_MODULES and (getattr(node, "level", 0) or top == "importlib"):
                continue
            said_why = any(line.strip().startswith("#")
                           for line in lines[max(0, node.lineno - 4):node.lineno - 1])
            if getattr(node, "level", 0) or top not in HEAVY or not said_why:
                found.append(f"{name}:{node.lineno}: {lines[node.lineno - 1].strip()}")
    assert not found, "imports inside functions:\n" + "\n".join(found)


def _test_modules():
    for path in sorted((ROOT / "tests").rglob("*.py")):
        yield path.relative_to(ROOT).as_posix(), path, ast.parse(path.read_text())


@pytest.mark.parametrize("modules", [_modules, _test_modules], ids=["package", "tests"])
def test_no_module_imports_another_modules_private_names(modules):
    """Neither the package's modules nor the tests: a test of a private name pins an
    implementation, and a helper worth testing on its own is public."""
    found = []
    for name, _, tree in modules():
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and (
                    node.level or (node.module or "").startswith("plcpred")):
                private = [a.name for a in node.names
                           if a.name.startswith("_") and not a.name.startswith("__")]
                if private:
                    found.append(f"{name}:{node.lineno}: {', '.join(private)}")
    assert not found, "\n".join(found)


@pytest.mark.parametrize("planted, where", [
    ("from plcpred.diagnose.core import Diagnosis\n", "plcpred/air/_planted.py"),
    ("def f():\n    from ..machine import load_machine\n", "plcpred/physics/_planted.py"),
])
def test_an_upward_import_breaks_the_contracts(planted, where, capsys, monkeypatch):
    """The checks above see imports of either kind (the contract is not vacuous)."""
    path = ROOT / where
    path.write_text(planted)
    try:
        monkeypatch.chdir(ROOT)
        code = lint_imports(config_filename=str(ROOT / "pyproject.toml"), no_cache=True,
                            no_logo=True)
    finally:
        path.unlink()
    assert code == 1
    assert where.replace("/", ".")[:-3] in capsys.readouterr().out
