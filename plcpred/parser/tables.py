"""The LALR tables of plcpred's grammars, kept so that no run waits for lark to build them.

Building a grammar's tables with lark (:mod:`.tablegen`) takes about half a second, and
importing lark some 20 ms, which a syntax check should not wait for (lark's own cache
still imports lark, and is a pickle). So:

1. :mod:`.lalr_tables`, generated from the grammars (``python -m plcpred.parser.tables
   --write``; the test suite checks that it is current), ships them with the package;
2. where its grammar text differs from the one in use (a grammar edited in a development
   tree), the tables are built with lark and kept in the user's cache directory
   (``$XDG_CACHE_HOME/plcpred`` or ``~/.cache/plcpred``), and read from there next time.

Tables are data, never code: JSON text, so that whatever a cache file holds, reading it
cannot run anything. A file is used only when it is whole (its CRC-32 matches), is in
this format, and was built from exactly the grammar in use; anything else is rebuilt. The
cache directory is used only when it belongs to the user and no one else may write to it
(a table that no one else can plant: a wrong one could misread programs).

The text: a header line (JSON: format, grammar, CRC-32 of the rest, the numbers of
states and rules, start and end state), then one line per state, a JSON object of
terminal or rule name -> number (``n >= 0``: shift or go to state ``n``; ``n < 0``:
reduce by rule ``~n``), then one line per rule, its reduce plan
(:func:`.tablegen.rule_plan`). States and rules are decoded when a parse first needs
them: a small file's parse visits a fraction of them.
"""
from __future__ import annotations

import json
import os
import stat
import sys
import zlib

from . import lalr_tables
from .grammar import GRAMMARS

FORMAT = 1


class Tables:
    """One grammar's tables: ``rows`` (state -> row) and ``rules`` (rule number -> plan),
    each decoded when first used; ``start`` and ``end`` states."""
    __slots__ = ("end", "rows", "rules", "start")

    def __init__(self, rows, rules, start: int, end: int):
        self.rows = rows
        self.rules = rules
        self.start = start
        self.end = end


class Rows(dict):
    """State number -> row, each decoded from its JSON line when first asked for: a
    parse visits a fraction of the states, and decoding them all costs more than a small
    file's whole parse."""

    def __init__(self, lines: list[str], n_rules: int):
        super().__init__()
        self._lines = lines
        self._n_rules = n_rules

    def __missing__(self, state):
        row = _decoded(self._lines[state])
        n_states = len(self._lines)
        if not isinstance(row, dict) or not all(
                type(v) is int and -self._n_rules <= v < n_states for v in row.values()):
            raise ValueError(f"parser table row {state} is malformed")
        self[state] = row
        return row


class Rules(dict):
    """Rule number -> plan (:func:`.tablegen.rule_plan`), decoded when first asked for."""

    def __init__(self, lines: list[str]):
        super().__init__()
        self._lines = lines

    def __missing__(self, number):
        plan = _decoded(self._lines[number])
        if not _plan_ok(plan):
            raise ValueError(f"parser table rule {number} is malformed")
        self[number] = plan
        return plan

    def __len__(self):
        return len(self._lines)


_scan_json = json.JSONDecoder().scan_once


def _decoded(line: str):
    """The JSON value of one whole line (the decoder's scanner alone: a parse's first
    states are decoded on the way, and json.loads costs three times as much)."""
    try:
        value, end = _scan_json(line, 0)
    except StopIteration:
        end = -1
    if end != len(line):
        raise ValueError("parser table line is not JSON")
    return value


def encode(grammar: str, start: int, end: int, rules: list, rows: list[dict]) -> str:
    """The text of tables analysed by :func:`.tablegen.analyse`."""
    body = "\n".join([json.dumps(row, separators=(",", ":")) for row in rows]
                     + [json.dumps(rule, separators=(",", ":")) for rule in rules])
    header = {"format": FORMAT, "crc": zlib.crc32(body.encode()), "states": len(rows),
              "rules": len(rules), "start": start, "end": end, "grammar": grammar}
    return json.dumps(header, separators=(",", ":")) + "\n" + body


def decode(text: str, grammar: str) -> Tables | None:
    """The tables ``text`` holds when it is whole, in this format and built from exactly
    ``grammar``; None otherwise (to be rebuilt). Rows and rules are checked as they are
    decoded."""
    head, sep, body = text.partition("\n")
    try:
        header = json.loads(head)
    except ValueError:
        return None
    if not (sep and isinstance(header, dict) and header.get("format") == FORMAT
            and header.get("grammar") == grammar
            and header.get("crc") == zlib.crc32(body.encode())):
        return None
    lines = body.split("\n")
    n_states, n_rules = header.get("states"), header.get("rules")
    start, end = header.get("start"), header.get("end")
    if not (type(n_states) is int and type(n_rules) is int
            and 0 < n_states and 0 <= n_rules and n_states + n_rules == len(lines)
            and all(type(s) is int and 0 <= s < n_states for s in (start, end))):
        return None
    return Tables(Rows(lines[:n_states], n_rules), Rules(lines[n_states:]), start, end)


def _plan_ok(rule) -> bool:
    """A rule plan as :func:`.tablegen.rule_plan` writes it."""
    if not (isinstance(rule, list) and len(rule) == 6):
        return False
    name, origin, size, expand1, plan, trailing = rule
    return (isinstance(name, str) and isinstance(origin, str) and type(size) is int
            and 0 <= size and type(expand1) is bool and type(trailing) is int
            and 0 <= trailing and isinstance(plan, list)
            and all(isinstance(p, list) and len(p) == 3 and type(p[0]) is int
                    and 0 <= p[0] < size and type(p[1]) is bool and type(p[2]) is int
                    and p[2] >= 0 for p in plan))


def load(name: str) -> Tables:
    """The tables of grammar ``name`` (:data:`.grammar.GRAMMARS`): the shipped ones, else
    the user's cached ones, else built now (and cached)."""
    grammar = GRAMMARS[name]
    shipped = lalr_tables.TABLES.get(name)
    tables = decode(shipped, grammar) if shipped is not None else None
    if tables is not None:
        return tables
    path = cache_file(name, grammar)
    text = _read_own(path) if path is not None else None
    tables = decode(text, grammar) if text is not None else None
    if tables is not None:
        return tables
    text = build(grammar)
    if path is not None:
        _write_own(path, text)
    return decode(text, grammar)


def build(grammar: str) -> str:
    """The tables of ``grammar``, analysed by lark now."""
    # lark is imported only here: when neither the shipped tables nor the user's cache
    # match the grammar (a development tree), not for a normal run
    from .tablegen import analyse
    return encode(grammar, *analyse(grammar))


def cache_dir() -> str | None:
    """The user's cache directory for plcpred, created (mode 0700) if need be; None when
    there is none that only the user can write to."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    path = os.path.join(base, "plcpred")
    try:
        os.makedirs(path, mode=0o700, exist_ok=True)
        st = os.stat(path, follow_symlinks=False)
    except (OSError, ValueError):
        return None
    return path if _only_mine(st) and stat.S_ISDIR(st.st_mode) else None


def _only_mine(st) -> bool:
    """Owned by this user, and no one else may write to it."""
    return st.st_uid == os.getuid() and not st.st_mode & (stat.S_IWGRP | stat.S_IWOTH)


def cache_file(name: str, grammar: str) -> str | None:
    folder = cache_dir()
    if folder is None:
        return None
    return os.path.join(folder, f"lalr-{name}-{zlib.crc32(grammar.encode()):08x}.json")


def _read_own(path: str) -> str | None:
    """The text of a cache file that is the user's own (a regular file, not a link); None
    when there is none, or it is not."""
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
    except OSError:
        return None
    try:
        st = os.fstat(fd)
        if not (stat.S_ISREG(st.st_mode) and _only_mine(st)):
            return None
        with os.fdopen(os.dup(fd), "rb") as f:
            return f.read().decode("utf-8", errors="replace")
    except OSError:
        return None
    finally:
        os.close(fd)


def _write_own(path: str, text: str) -> None:
    """Write a cache file whole or not at all (a new file renamed over the old one), mode
    0600; a cache that cannot be written is no error."""
    tmp = f"{path}.{os.getpid()}.tmp"
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL
                     | getattr(os, "O_NOFOLLOW", 0), 0o600)
        with os.fdopen(fd, "wb") as f:
            f.write(text.encode("utf-8"))
        os.replace(tmp, path)
    except OSError:
        try:
            os.unlink(tmp)
        except OSError:
            pass


def shipped_source() -> str:
    """The text of :mod:`.lalr_tables` for the grammars as they are now."""
    lines = ['"""The LALR tables of the grammars of :mod:`.grammar` (see :mod:`.tables`).',
             "",
             "Generated by ``python -m plcpred.parser.tables --write``: do not edit. The test",
             'suite checks that they are current."""',
             "TABLES = {"]
    for name, grammar in GRAMMARS.items():
        lines.append(f"    {name!r}: {build(grammar)!r},")
    lines.append("}")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    """``python -m plcpred.parser.tables --write``: write :mod:`.lalr_tables` again after
    a grammar changed."""
    args = sys.argv[1:] if argv is None else argv
    if args != ["--write"]:
        print("usage: python -m plcpred.parser.tables --write", file=sys.stderr)
        return 2
    with open(lalr_tables.__file__, "w", encoding="utf-8") as f:
        f.write(shipped_source())
    print(f"wrote {lalr_tables.__file__}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
