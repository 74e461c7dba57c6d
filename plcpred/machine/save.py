"""Writing machine files. A corrected machine file (``diagnose --write-machine``,
``identify flow --write-machine``) is the user's own file with only the values that
changed written anew: it is edited with a style-preserving TOML library (tomlkit), so
every table, comment, blank line and key order survives, and what is added carries a
comment saying what added it. The text is checked by reading it back (it must hold
exactly the new data) and loading it as a machine, then written atomically."""
from __future__ import annotations

import math
import os
import tomllib
from pathlib import Path

import tomlkit
from tomlkit.container import Container
from tomlkit.exceptions import TOMLKitError
from tomlkit.items import AoT, Comment, InlineTable, Table

from ..output import atomic_write_text
from ..parser import ProgramError
from ..parser.files import confined_to, read_bytes
from .load import MAX_MACHINE_BYTES, machine_from_data
from .model import Machine


def save_machine(data: dict, source: Machine, path, header: str = "",
                 by: str = "plcpred") -> None:
    """Write ``data`` (``source``'s machine-file data, changed) to ``path`` as ``source``'s
    file with the changes made: ``header`` comes first as comment lines, what ``data``
    adds is marked "added by ``by``". The program and library paths are written anew only
    where the new file's folder needs it (relative when near, else absolute). The text is
    loaded before it is written; a file that does not load is a bug."""
    path = Path(path)
    _program_paths_for(data, source, path)
    original = _original_text(source.path)
    text = machine_toml(data, original, header, by)
    # where the source's program may be read from, the written file's may too (a file
    # written outside the source's folder then needs --allow-root to be read again)
    machine_from_data(tomllib.loads(text), path, source.allowed_roots)
    atomic_write_text(path, text)


def _program_paths_for(data: dict, source: Machine, path: Path) -> None:
    """``program`` and ``libraries`` of ``data`` as the file at ``path`` must name them
    to reach ``source``'s (left as they are when they still do)."""
    folder = path.resolve().parent

    def near(target: Path) -> str:
        rel = Path(os.path.relpath(target, folder)).as_posix()
        return rel if rel.count("../") <= 2 else target.as_posix()

    def reaches(value, target: Path) -> bool:
        return isinstance(value, str) and (folder / value).resolve() == target.resolve()

    table = data["machine"]
    if not reaches(table.get("program"), source.program_path):
        table["program"] = near(source.program_path)
    libraries = table.get("libraries", [])
    if source.library_paths and not (
            len(libraries) == len(source.library_paths)
            and all(reaches(v, p) for v, p in zip(libraries, source.library_paths))):
        table["libraries"] = [near(p) for p in source.library_paths]


def _original_text(path) -> str | None:
    """The text of the machine file at ``path`` (None when it cannot be read)."""
    try:
        with confined_to(None):
            return read_bytes(Path(path), MAX_MACHINE_BYTES).decode("utf-8")
    except (ProgramError, OSError, UnicodeDecodeError):
        return None


def machine_toml(data: dict, original: str | None = None, header: str = "",
                 by: str = "plcpred") -> str:
    """``data`` as machine-file text: ``original`` (a machine file's text) with the values
    ``data`` changes written anew, the keys and tables it adds added (marked "added by
    ``by``") and those it drops removed; everything else of ``original`` byte for byte.
    Without ``original`` (or when it is not TOML) the whole of ``data``. Raises
    ValueError for what TOML cannot hold (NaN, infinity)."""
    _check_finite(data)
    doc, old, note = None, {}, f"added by {by}"
    if original is not None:
        try:
            doc = tomlkit.parse(original)
            old = tomllib.loads(original.replace("\r\n", "\n").replace("\r", "\n"))
        except (TOMLKitError, tomllib.TOMLDecodeError, RecursionError):
            doc = None
    if doc is None:
        doc, old, note = tomlkit.document(), {}, None
    try:
        _merge(doc, old, data, note)
        text = doc.as_string()
        kept = _same(tomllib.loads(text), data)
    except (TOMLKitError, tomllib.TOMLDecodeError, AttributeError, KeyError, TypeError):
        kept = False
    if not kept:
        # a layout the edit cannot extend in place: the data whole, in tomlkit's layout
        # (the user's comments lost), rather than a wrong file
        doc = tomlkit.document()
        _merge(doc, {}, data, None)
        text = doc.as_string()
    newline = "\r\n" if original is not None and "\r\n" in original else "\n"
    lines = [f"# {line}".rstrip() for line in header.splitlines()]
    return newline.join(lines + [""]) + newline + text if lines else text


def dump_machine_toml(data: dict, header: str = "") -> str:
    """A machine file's TOML data as text, ``header`` first as comment lines."""
    return machine_toml(data, None, header)


def _check_finite(value) -> None:
    if isinstance(value, float) and not math.isfinite(value):
        raise ValueError(f"cannot write {value!r} to a machine file")
    if isinstance(value, dict):
        for v in value.values():
            _check_finite(v)
    elif isinstance(value, (list, tuple)):
        for v in value:
            _check_finite(v)


def _same(a, b) -> bool:
    """Equal as a machine file means it: 6 and 6.0 alike, true and 1 not."""
    if isinstance(a, bool) or isinstance(b, bool):
        return type(a) is type(b) and a == b
    if isinstance(a, (int, float)) and isinstance(b, (int, float)):
        return a == b
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    return type(a) is type(b) and a == b


def _is_tables(value) -> bool:
    return isinstance(value, list) and bool(value) and all(isinstance(t, dict) for t in value)


def _merge(container, old: dict, new: dict, note: str | None) -> None:
    """Make the tomlkit ``container`` (holding ``old``) hold ``new``, touching only what
    differs."""
    for key in [k for k in old if k not in new]:
        del container[key]
    for key, value in new.items():
        if key not in old:
            _add(container, key, value, note)
        elif isinstance(value, dict) and isinstance(old[key], dict):
            _merge(container[key], old[key], value, note)
        elif _is_tables(value) and _is_tables(old[key]):
            _merge_list(container[key], old[key], value, note)
        elif not _same(old[key], value):
            container[key] = _plain(value)      # keeps the line's comment


def _merge_list(tables, old: list, new: list, note: str | None) -> None:
    """An array of tables (or of inline tables) changed entry by entry, new ones added at
    its end, dropped ones removed from its end."""
    for i in range(min(len(old), len(new))):
        _merge(tables[i], old[i], new[i], note)
    for i in range(len(old) - 1, len(new) - 1, -1):
        del tables[i]
    for value in new[len(old):]:
        if isinstance(tables, AoT):
            table = _table(value, note, ends_file=False)
            if tables.body and not tables.body[-1].as_string().endswith("\n\n"):
                table.trivia.indent = "\n"         # a blank line before it, as before tables
            tables.append(table)
        else:
            tables.append(_plain(value))


def _plain(value):
    """A value as tomlkit writes it, tuples as arrays."""
    if isinstance(value, tuple):
        value = list(value)
    if isinstance(value, list):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    return value


def _table(value: dict, note: str | None, ends_file: bool = True) -> Table:
    """A new table of ``value``, its header commented with ``note``, a blank line after
    it (unless it ends the file)."""
    table = tomlkit.table()
    for k, v in value.items():
        if isinstance(v, dict):
            table.add(k, tomlkit.inline_table())
            table[k].update(_plain(v))
        else:
            table.add(k, _plain(v))
    if note:
        table.comment(note)
        table.trivia.comment_ws = "  "
    if not ends_file:
        table.add(tomlkit.nl())
    return table


def _add(container, key: str, value, note: str | None) -> None:
    """``key = value`` added to ``container``: a table or an array of tables at the end of
    the file, a value after its table's last value (ahead of the comments that introduce
    what follows), a key of an inline table inside it."""
    if isinstance(container, InlineTable):
        container[key] = _plain(value)
    elif isinstance(container, Table) or not (isinstance(value, dict) or _is_tables(value)):
        _add_value(container, key, tomlkit.item(_plain(value)), note)
    elif isinstance(value, dict):
        container.add(key, _table(value, note))
    else:
        aot = tomlkit.aot()
        for t in value:
            aot.append(_table(t, note))
        container.add(key, aot)


def _add_value(container, key: str, item, note: str | None) -> None:
    """``item`` after the last value of ``container`` (a table, or the top of the file),
    ahead of the comments and blank lines that close it."""
    if note:
        item.comment(note)
        item.trivia.comment_ws = "  "
    body = container.value if isinstance(container, Table) else container
    if not isinstance(body, Container):       # a table split over the file, dotted keys
        container[key] = item
        return
    last = max((i for i, (k, v) in enumerate(body.body)
                if k is not None and not isinstance(v, (Table, AoT))), default=-1)
    insert_at = getattr(body, "_insert_at", None)
    if last >= 0 and insert_at is not None and any(
            isinstance(v, Comment) for _, v in body.body[last + 1:]):
        # tomlkit appends after a table's closing comments, which belong to what follows;
        # its insertion at a position is the one way to go before them
        insert_at(last + 1, key, item)
    else:
        container.add(key, item)
