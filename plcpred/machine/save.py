"""Writing machine files: TOML text from a machine file's data, checked by loading it
before it is written, atomically."""
from __future__ import annotations

import math
import os
import re
from pathlib import Path

from ..output import atomic_write_text
from .load import machine_from_data
from .model import Machine


def save_machine(data: dict, source: Machine, path, header: str = "") -> None:
    """Write machine-file data derived from ``source`` to ``path``: the program path made
    relative to the new file when it is near (else absolute), the data checked by
    loading it first (a file that does not load is a bug), written atomically."""
    path = Path(path)

    def near(target: Path) -> str:
        rel = Path(os.path.relpath(target, path.resolve().parent)).as_posix()
        return rel if rel.count("../") <= 2 else target.as_posix()

    data["machine"]["program"] = near(source.program_path)
    if source.library_paths:
        data["machine"]["libraries"] = [near(p) for p in source.library_paths]
    # where the source's program may be read from, the written file's may too (a file
    # written outside the source's folder then needs --allow-root to be read again)
    machine_from_data(data, path, source.allowed_roots)
    atomic_write_text(path, dump_machine_toml(data, header))


# ---------------------------------------------------------------------- machine files

def _toml_key(key: str) -> str:
    return key if re.fullmatch(r"[A-Za-z0-9_-]+", key) else _toml_value(key)


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if not math.isfinite(v):
            raise ValueError(f"cannot write {v!r} to a machine file")
        return repr(v)
    if isinstance(v, str):
        out = ['"']
        for ch in v:
            if ch in '"\\':
                out.append("\\" + ch)
            elif ord(ch) < 0x20 or ord(ch) == 0x7F:
                out.append(f"\\u{ord(ch):04x}")
            else:
                out.append(ch)
        out.append('"')
        return "".join(out)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{_toml_key(k)} = {_toml_value(x)}"
                                for k, x in v.items()) + " }"
    raise ValueError(f"cannot write a {type(v).__name__} to a machine file")


def dump_machine_toml(data: dict, header: str = "") -> str:
    """A machine file's TOML data as text (the tables plcpred knows, in their usual
    order; comments of the original are not kept, ``header`` is written first)."""
    lines = [f"# {line}" if line else "#" for line in header.splitlines()]
    if lines:
        lines.append("")
    for table in ("machine", "signals", "meter"):
        if table in data:
            lines.append(f"[{table}]")
            lines += [f"{_toml_key(k)} = {_toml_value(v)}" for k, v in data[table].items()]
            lines.append("")
    for array in ("input", "line", "consumer"):
        for t in data.get(array, []):
            lines.append(f"[[{array}]]")
            lines += [f"{_toml_key(k)} = {_toml_value(v)}" for k, v in t.items()]
            lines.append("")
    for table, v in data.items():
        if table not in ("machine", "signals", "meter", "input", "line", "consumer"):
            raise ValueError(f"cannot write the table [{table}]")
    return "\n".join(lines)
