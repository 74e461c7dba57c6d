"""Writing results: never a half-written file, never a directory that mixes two runs.

* :func:`atomic_write_text` / :func:`write_json` write one file through a temporary file
  beside it and rename it into place (POSIX ``rename`` is atomic within a directory).
* :func:`check_out_dir` says before any computation whether ``--out`` can be written, so a
  bad path fails in a second, not after an hour of simulation.
* :func:`output_dir` stages a whole run in a fresh hidden directory beside ``--out`` and
  moves it into place when the run succeeds:

  - when ``--out`` does not exist, or holds only what an earlier plcpred run wrote there
    (the files its ``manifest.json`` lists), the staging directory replaces it as a whole
    (two renames): a reader sees the old run or the new one, never a mix;
  - when ``--out`` also holds files of the user's (``--out .``), those are left alone: the
    old ``manifest.json`` is removed first, each new file is renamed in, and the new
    manifest is written last, so a manifest present always describes a complete run.

  ``manifest.json`` names the run (``run_id``), the command, the time and every file with
  its size and SHA-256. On an error, SIGINT or SIGTERM the staging directory is removed
  and ``--out`` is left as it was.
"""
from __future__ import annotations

import hashlib
import json
import math
import os
import shutil
import tempfile
import time
import uuid
from contextlib import contextmanager
from pathlib import Path

from .errors import PlcpredError

MANIFEST = "manifest.json"
_STAGING_PREFIX = ".plcpred-staging-"
_TRASH_PREFIX = ".plcpred-old-"


class OutputError(PlcpredError):
    """An output path that cannot be written."""


# consumers that demand.csv, demand.png and the printed table show one by one before
# grouping the rest as "other" (a wide machine would otherwise give a column and a plot
# layer per drive)
SHOWN_CONSUMERS = 12


def _umask() -> int:
    """The process umask (reading it means setting it; it is put back at once)."""
    umask = os.umask(0)
    os.umask(umask)
    return umask


def atomic_write_text(path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file in the same directory."""
    with atomic_writer(path) as f:
        f.write(text)


@contextmanager
def atomic_writer(path):
    """A text file to write in pieces (for output too large to build in memory), renamed
    into place when the block ends without an exception."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="") as f:
            yield f
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def json_safe(data):
    """``data`` with every non-finite float (NaN, inf) replaced by None: JSON has no NaN,
    and a file other tools cannot parse is worse than a null they can."""
    if isinstance(data, float):
        return data if math.isfinite(data) else None
    if isinstance(data, dict):
        return {k: json_safe(v) for k, v in data.items()}
    if isinstance(data, (list, tuple)):
        return [json_safe(v) for v in data]
    return data


def dumps_json(data) -> str:
    """Strict JSON (no NaN) with two-space indentation and a final newline."""
    return json.dumps(json_safe(data), indent=2, allow_nan=False) + "\n"


def write_json(path, data) -> None:
    atomic_write_text(path, dumps_json(data))


def check_out_dir(path) -> Path:
    """``path`` as a Path if a run can write its files there, else :class:`OutputError`
    saying why (it is a file, lies under a file, or is not writable)."""
    out = Path(path)
    if str(path) == "":
        raise OutputError("--out: empty path")
    if out.exists() and not out.is_dir():
        raise OutputError(f"--out {path}: exists and is not a directory")
    probe = out
    while not probe.exists():
        parent = probe.parent
        if parent == probe:
            break
        probe = parent
    if not probe.is_dir():
        raise OutputError(f"--out {path}: {probe} is a file, so no directory can be made "
                          "under it")
    # the staging directory is made beside --out, so its parent must be writable too
    target = out.parent if out.exists() else probe
    if not os.access(target, os.W_OK | os.X_OK):
        raise OutputError(f"--out {path}: {target} is not writable")
    return out


@contextmanager
def output_dir(path, command: str = ""):
    """Stage a run's files (module docstring). Yields the staging directory; files
    written there are moved into ``path`` when the block ends without an exception."""
    out = check_out_dir(path).absolute()
    out.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f"{_STAGING_PREFIX}{out.name}-", dir=out.parent))
    os.chmod(staging, 0o777 & ~_umask())  # mkdtemp's 0700 would become --out's mode
    run_id = uuid.uuid4().hex
    try:
        yield staging
        _write_manifest(staging, run_id, command)
        _commit(staging, out)
    except OSError as e:
        raise OutputError(f"--out {path}: {e.strerror or e}") from None
    finally:
        shutil.rmtree(staging, ignore_errors=True)


def _write_manifest(staging: Path, run_id: str, command: str) -> None:
    files = {}
    for f in sorted(staging.iterdir()):
        if f.is_file():
            h = hashlib.sha256()
            with open(f, "rb") as fh:
                for block in iter(lambda: fh.read(1 << 20), b""):
                    h.update(block)
            digest = h.hexdigest()
            files[f.name] = {"bytes": f.stat().st_size, "sha256": digest}
    manifest = {"run_id": run_id, "command": command,
                "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "files": files}
    write_json(staging / MANIFEST, manifest)


def _ours(out: Path) -> bool:
    """True when everything in ``out`` was written by an earlier plcpred run."""
    entries = {p.name for p in out.iterdir()}
    if not entries:
        return True
    try:
        listed = set(json.loads((out / MANIFEST).read_text(encoding="utf-8"))["files"])
    except (OSError, ValueError, KeyError, TypeError):
        return False
    return entries <= listed | {MANIFEST}


def _commit(staging: Path, out: Path) -> None:
    for _ in range(5):  # another run may be committing into the same place
        if not out.exists():
            try:
                os.rename(staging, out)
                staging.mkdir()  # so the caller's cleanup has something to remove
                return
            except OSError:
                continue
        if _ours(out):
            trash = Path(tempfile.mkdtemp(prefix=f"{_TRASH_PREFIX}{out.name}-",
                                          dir=out.parent))
            try:
                os.rename(out, trash / out.name)
            except OSError:
                shutil.rmtree(trash, ignore_errors=True)
                continue
            try:
                os.rename(staging, out)
                staging.mkdir()
            except OSError:
                os.rename(trash / out.name, out)  # put the old run back
                shutil.rmtree(trash, ignore_errors=True)
                continue
            shutil.rmtree(trash, ignore_errors=True)
            return
        # a directory with the user's own files: replace ours file by file, and remove
        # what the previous run wrote and this one does not
        try:
            old = set(json.loads((out / MANIFEST).read_text(encoding="utf-8"))["files"])
        except (OSError, ValueError, KeyError, TypeError):
            old = set()
        try:
            (out / MANIFEST).unlink()
        except FileNotFoundError:
            pass
        new = {f.name for f in staging.iterdir()}
        for name in sorted(new - {MANIFEST}):
            os.replace(staging / name, out / name)
        for name in sorted(old - new):
            try:
                (out / name).unlink()
            except OSError:
                pass
        os.replace(staging / MANIFEST, out / MANIFEST)
        return
    raise OutputError(f"--out {out}: another run kept replacing it; try again")
