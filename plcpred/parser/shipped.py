"""The index of the library stubs plcpred ships (``plcpred/libraries/index.json``): which
stub file declares which names, so that a program's libraries are read without parsing
the stubs it does not use. :func:`.libraries.build_index` writes it."""
from __future__ import annotations

import functools
import json
from pathlib import Path

SHIPPED_DIR = Path(__file__).resolve().parent.parent / "libraries"
INDEX_FILE = SHIPPED_DIR / "index.json"
# namespaces whose blocks plcpred knows without a file: the IEC standard library
BUILTIN_NAMESPACES = {"TC2_STANDARD", "STANDARD", "IEC_61131", "TC2_SYSTEM"}


@functools.lru_cache(maxsize=None)
def shipped_index() -> tuple[tuple[str, tuple[str, ...], frozenset], ...]:
    """(stub file, its namespaces, the names it declares) as :data:`INDEX_FILE` has them
    (the test suite checks the file against :func:`build_index`)."""
    index = json.loads(INDEX_FILE.read_text(encoding="utf-8"))
    return tuple((name, tuple(e["namespaces"]), frozenset(e["names"]))
                 for name, e in index.items())


def shipped_namespaces() -> set[str]:
    """The namespaces of the stubs plcpred ships (no stub is parsed)."""
    return {ns for _, namespaces, _ in shipped_index() for ns in namespaces}


@functools.lru_cache(maxsize=None)
def _string_kinds() -> dict[str, str]:
    index = json.loads(INDEX_FILE.read_text(encoding="utf-8"))
    out: dict[str, str] = {}
    for e in index.values():
        for name, kind in e["strings"].items():
            out.setdefault(name, kind)
    return out


def shipped_string_kind(name: str) -> str | None:
    """"S" or "W" when a shipped stub declares ``name`` (upper case) as a STRING or
    WSTRING type (Beremiz SVGHMI's HMI_STRING); else None (no stub is parsed)."""
    return _string_kinds().get(name)
