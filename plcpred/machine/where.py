"""Where a table or a key stands in a machine file's text: the line an error or a warning
points at. TOML readers (tomllib, tomlkit) keep no positions, so the text is looked
through line by line, as TOML reads it: table headers, ``key =`` at the start of a line,
values that run over several lines (arrays, inline tables, multi-line strings) skipped.
"""
from __future__ import annotations

import re
import tomllib

_BARE = r"[A-Za-z0-9_-]+"
_QUOTED = r'"(?:[^"\\]|\\.)*"|\'[^\']*\''
_PART = rf"(?:{_BARE}|{_QUOTED})"
_DOTTED = rf"{_PART}(?:\s*\.\s*{_PART})*"
_HEADER = re.compile(rf"\s*(\[\[?)\s*({_DOTTED})\s*\]\]?")
_ASSIGN = re.compile(rf"\s*({_DOTTED})\s*=")

# (table, index of an array of tables or None, key or None) -> line (1-based); a key None
# is the table's header; the table "" is the top level
Place = tuple[str, "int | None", "str | None"]


def _parts(dotted: str) -> list[str]:
    """The names of a dotted key, unquoted (``a."b.c"`` -> ``["a", "b.c"]``)."""
    out = []
    for part in re.findall(_PART, dotted):
        if part.startswith('"'):
            try:
                part = tomllib.loads(f"k = {part}")["k"]
            except tomllib.TOMLDecodeError:
                part = part[1:-1]
        elif part.startswith("'"):
            part = part[1:-1]
        out.append(part)
    return out


class _Value:
    """How far a value that started on an earlier line is open: a multi-line string
    (its quotes) and the depth of brackets and braces."""

    def __init__(self):
        self.string = ""
        self.depth = 0

    @property
    def open(self) -> bool:
        return bool(self.string) or self.depth > 0

    def read(self, text: str) -> None:
        """Follow ``text`` (the rest of one line)."""
        i, n = 0, len(text)
        while i < n:
            if self.string:
                if self.string[0] == '"' and text[i] == "\\":
                    i += 2
                    continue
                if text.startswith(self.string, i):
                    i += len(self.string)
                    self.string = ""
                    continue
                i += 1
                continue
            ch = text[i]
            if ch == "#":
                break
            if text.startswith('"""', i) or text.startswith("'''", i):
                self.string = text[i:i + 3]
                i += 3
            elif ch in "\"'":
                self.string = ch
                i += 1
            elif ch in "[{":
                self.depth += 1
                i += 1
            elif ch in "]}":
                self.depth = max(0, self.depth - 1)
                i += 1
            else:
                i += 1
        if self.string in ('"', "'"):       # a one-line string ends with its line
            self.string = ""


def places(text: str) -> dict[Place, int]:
    """Every table header and key of a machine file's ``text``, with its line: the first
    place each stands. A sub-table of an array of tables (``[consumer.switches]`` after a
    ``[[consumer]]``) counts as that consumer's key ``switches``; a dotted key as its first
    name."""
    out: dict[Place, int] = {}
    counts: dict[str, int] = {}
    table, index, prefix = "", None, []
    value = _Value()
    for number, line in enumerate(text.replace("\r\n", "\n").replace("\r", "\n")
                                  .split("\n"), 1):
        if value.open:
            value.read(line)
            continue
        header = _HEADER.match(line)
        if header:
            names = _parts(header.group(2))
            if header.group(1) == "[[" and len(names) == 1:
                table, prefix = names[0], []
                index = counts[table] = counts.get(table, -1) + 1
            elif names[0] in counts and len(names) > 1:
                table, index, prefix = names[0], counts[names[0]], names[1:]
            else:
                table, index, prefix = names[0], None, names[1:]
            out.setdefault((table, index, prefix[0] if prefix else None), number)
            continue
        assign = _ASSIGN.match(line)
        if assign:
            names = prefix + _parts(assign.group(1))
            if table == "" and len(names) > 1:       # machine.name = "..." at the top
                out.setdefault((names[0], None, None), number)
                out.setdefault((names[0], None, names[1]), number)
            else:
                out.setdefault((table, index, names[0]), number)
                if table == "":
                    out.setdefault((names[0], None, None), number)
            value.read(line[assign.end():])
    return out


def line_of(text: str, table: str | None, index: int | None = None,
            key: str | None = None) -> int | None:
    """The line of ``key`` in ``table`` (the ``index``-th of an array of tables), else of
    the table's header; None when the text does not hold it (a table written inline)."""
    if table is None:
        return None
    found = places(text)
    for i in (index, 0) if index is None else (index,):     # [[input]] where [input] was meant
        if key is not None and (table, i, key) in found:
            return found[(table, i, key)]
        if (table, i, None) in found:
            return found[(table, i, None)]
    return None
