"""Writing results: never a half-written file, never a directory that mixes two runs, and
never a file removed that plcpred cannot prove it wrote.

* :func:`atomic_write_text` / :func:`write_json` write one file through a temporary file
  beside it and rename it into place (POSIX ``rename`` is atomic within a directory).
* :func:`check_out_dir` says before any computation whether ``--out`` can be written, so a
  bad path fails in a second, not after an hour of simulation.
* :func:`output_dir` stages a whole run in a fresh hidden directory beside ``--out`` and
  moves it into place when the run succeeds:

  - when ``--out`` does not exist, or holds only files an earlier plcpred run provably
    wrote there, the staging directory replaces it as a whole (two renames): a reader
    sees the old run or the new one, never a mix;
  - otherwise (``--out .``, or a folder with the user's own files) those are left alone:
    the old ``manifest.json`` is removed first, each new file is renamed in, the old
    run's files that this run does not write are removed, and the new manifest is
    written last, so a manifest present always describes a complete run.

  ``manifest.json`` names the run (``run_id``), the command, the time and every file with
  its size and SHA-256. On an error, SIGINT or SIGTERM the staging directory is removed
  and ``--out`` is left as it was.

The rules that keep a folder someone else prepared (a pull request's checkout) safe:

* **Removal needs proof.** A file is removed only when the old manifest lists it under a
  plain base name (no folder, no ``..``), it is a regular file (a symbolic link is never
  followed or removed) and its size and SHA-256 match the manifest. A manifest is read
  only if it is a small regular file. Anything else it lists is left alone, with a
  warning naming it.
* **A symbolic link as --out is refused**: plcpred neither replaces the link nor writes
  through it; name the folder it points to.
* **``..`` follows only an existing folder**: ``--out missing/../o`` is an error, as in the
  shell, instead of creating ``missing/``.
* **Staging folders of killed runs are cleaned.** Each run holds an exclusive lock on
  ``.plcpred-staging-*.lock`` beside its staging folder; a later run into the same parent
  removes staging folders whose lock no process holds (and, for folders left by versions
  without locks, those untouched for an hour).
"""
from __future__ import annotations

import hashlib
import json
import math
import os
import shutil
import stat
import sys
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path

from .errors import PlcpredError


def _random_hex(digits: int) -> str:
    """A random name part (the uuid module would cost every command 10 ms to import)."""
    return os.urandom((digits + 1) // 2).hex()[:digits]


try:
    import fcntl
except ImportError:        # Windows: no advisory locks; stale folders are cleaned by age
    fcntl = None

MANIFEST = "manifest.json"
_STAGING_PREFIX = ".plcpred-staging-"
_TRASH_PREFIX = ".plcpred-old-"
_LOCK_SUFFIX = ".lock"
# a manifest larger than this was not written by plcpred (a run lists a handful of files)
MAX_MANIFEST_BYTES = 1 << 20
# a staging folder without a lock (left by a version before locks) is abandoned when
# nothing in it changed for this long: no run of that version is still writing it
STALE_UNLOCKED_S = 3600.0
# names whose warnings are printed one by one before the rest are counted
_SHOWN_WARNINGS = 10


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
    saying why (a symbolic link, ``..`` after a missing folder, a file, under a file, or
    not writable)."""
    if str(path) == "":
        raise OutputError("--out: empty path")
    out = Path(path)
    if out.is_symlink():
        raise OutputError(f"--out {path}: is a symbolic link; plcpred neither writes "
                          "through links nor replaces them (give the folder it points "
                          "to instead)")
    for i, part in enumerate(out.parts):
        if part == ".." and i > 0 and not Path(*out.parts[:i]).is_dir():
            raise OutputError(f"--out {path}: {Path(*out.parts[:i])} is not an existing "
                              "folder, so the '..' after it names nothing")
    if out.exists() and not out.is_dir():
        raise OutputError(f"--out {path}: exists and is not a directory")
    probe = _nearest_existing(out)
    if not probe.is_dir():
        raise OutputError(f"--out {path}: {probe} is a file, so no directory can be made "
                          "under it")
    # the staging directory is made beside --out, so its parent must be writable too
    target = out.parent if out.exists() else probe
    if not os.access(target, os.W_OK | os.X_OK):
        raise OutputError(f"--out {path}: {target} is not writable")
    return out


def _nearest_existing(path: Path) -> Path:
    """``path`` or the nearest of its parents that exists (where folders would be made)."""
    while not path.exists() and path.parent != path:
        path = path.parent
    return path


def check_out_file(path, option: str) -> None:
    """Raise :class:`OutputError` before any work when ``path`` (a ``--json`` or
    ``--write-machine`` file; ``-`` is stdout) cannot be written: a folder, a path under a
    file, or an unwritable folder."""
    if path is None or str(path) == "-":
        return
    if str(path) == "":
        raise OutputError(f"{option}: empty path")
    target = Path(path)
    if target.is_dir():
        raise OutputError(f"{option} {path}: is a folder; give a file name")
    probe = _nearest_existing(target.parent)
    if not probe.is_dir():
        raise OutputError(f"{option} {path}: {probe} is a file, so no folder can be made "
                          "under it")
    if not os.access(probe, os.W_OK | os.X_OK):
        raise OutputError(f"{option} {path}: {probe} is not writable")


def _real_out(out: Path) -> Path:
    """``out`` absolute, its parent's links resolved (the staging folder must sit on the
    same file system as the folder it is renamed to); the last name itself is kept."""
    out = out.absolute()
    if out.name in ("", ".", ".."):
        return out.resolve()
    return out.parent.resolve() / out.name


def _print_warning(message: str) -> None:
    print(f"warning: {message}", file=sys.stderr)


@contextmanager
def output_dir(path, command: str = "", warn=None):
    """Stage a run's files (module docstring). Yields the staging directory; files
    written there are moved into ``path`` when the block ends without an exception.
    ``warn(message)`` hears of files left alone (default: printed to stderr)."""
    warn = warn or _print_warning
    out = _real_out(check_out_dir(path))
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        clean_abandoned(out.parent)
        lock_fd, staging = _new_staging(out)
    except OSError as e:
        raise OutputError(f"--out {path}: {e.strerror or e}") from None
    run_id = _random_hex(32)
    try:
        yield staging
        _write_manifest(staging, run_id, command)
        for message in _commit(staging, out):
            warn(message)
    except OSError as e:
        # name the file in --out that stood in the way (a folder of the user's called
        # timeline.csv), not the staging folder's
        where = next((Path(f).name for f in (e.filename2, e.filename)
                      if f and Path(f).parent == out), None)
        raise OutputError(f"--out {path}: {e.strerror or e}"
                          + (f": {where}" if where else "")) from None
    finally:
        shutil.rmtree(staging, ignore_errors=True)
        os.close(lock_fd)
        _unlink_quietly(_lock_of(staging))


# ------------------------------------------------------------------ staging and its lock

def _lock_of(staging: Path) -> Path:
    return staging.with_name(staging.name + _LOCK_SUFFIX)


def _new_staging(out: Path) -> tuple[int, Path]:
    """(the held lock's descriptor, a new empty staging folder beside ``out``). The lock
    is taken under a temporary name and renamed, so no cleaner ever sees it unlocked."""
    fd, tmp = tempfile.mkstemp(prefix=".plcpred-new-", dir=out.parent)
    try:
        if fcntl is not None:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        staging = out.parent / f"{_STAGING_PREFIX}{out.name}-{_random_hex(12)}"
        os.rename(tmp, _lock_of(staging))
        staging.mkdir(mode=0o777)          # the umask applies, as it will to --out
    except BaseException:
        os.close(fd)
        _unlink_quietly(tmp)
        raise
    return fd, staging


def _unlink_quietly(path) -> None:
    try:
        os.unlink(path)
    except OSError:
        pass


def _abandoned(lock: Path) -> bool:
    """True when no running plcpred holds ``lock`` (its run was killed)."""
    try:
        fd = os.open(lock, os.O_RDWR | getattr(os, "O_NOFOLLOW", 0))
    except OSError:
        return False
    try:
        if fcntl is None:
            return time.time() - os.fstat(fd).st_mtime > STALE_UNLOCKED_S
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            return False                    # held: that run is still going
        return True
    finally:
        os.close(fd)


def _remove_folder(path: Path) -> None:
    """Remove a staging or trash folder of ours; a link of that name is only unlinked."""
    try:
        st = os.lstat(path)
    except OSError:
        return
    if stat.S_ISDIR(st.st_mode):
        shutil.rmtree(path, ignore_errors=True)   # never follows links inside
    else:
        _unlink_quietly(path)


def clean_abandoned(parent) -> list[str]:
    """Remove the staging folders (and half-replaced old runs) that killed plcpred runs
    left in ``parent``: those whose lock no process holds, and lockless ones of older
    versions untouched for :data:`STALE_UNLOCKED_S`. Returns the names removed."""
    parent = Path(parent)
    removed = []
    try:
        entries = list(os.scandir(parent))
    except OSError:
        return removed
    names = {e.name for e in entries}
    now = time.time()
    for entry in entries:
        name = entry.name
        if name.startswith(_STAGING_PREFIX) and name.endswith(_LOCK_SUFFIX):
            if not entry.is_file(follow_symlinks=False) or not _abandoned(Path(entry.path)):
                continue
            token = name[len(_STAGING_PREFIX):-len(_LOCK_SUFFIX)]
            for folder in (_STAGING_PREFIX + token, _TRASH_PREFIX + token):
                if folder in names:
                    _remove_folder(parent / folder)
                    removed.append(folder)
            _unlink_quietly(entry.path)
            removed.append(name)
            continue
        prefix = next((p for p in (_STAGING_PREFIX, _TRASH_PREFIX, ".plcpred-new-")
                       if name.startswith(p)), None)
        if prefix is None or name.endswith(_LOCK_SUFFIX):
            continue
        if prefix != ".plcpred-new-" and \
                f"{_STAGING_PREFIX}{name[len(prefix):]}{_LOCK_SUFFIX}" in names:
            continue                        # its lock decides (above)
        try:
            age_s = now - entry.stat(follow_symlinks=False).st_mtime
        except OSError:
            continue
        if age_s > STALE_UNLOCKED_S:
            _remove_folder(Path(entry.path))
            removed.append(name)
    return removed


# ------------------------------------------------------------------ the manifest

def _sha256(fd: int) -> str:
    h = hashlib.sha256()
    for block in iter(lambda: os.read(fd, 1 << 20), b""):
        h.update(block)
    return h.hexdigest()


def _write_manifest(staging: Path, run_id: str, command: str) -> None:
    files = {}
    for f in sorted(staging.iterdir()):
        if f.is_file():
            fd = os.open(f, os.O_RDONLY)
            try:
                digest = _sha256(fd)
            finally:
                os.close(fd)
            files[f.name] = {"bytes": f.stat().st_size, "sha256": digest}
    manifest = {"run_id": run_id, "command": command,
                "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "files": files}
    write_json(staging / MANIFEST, manifest)


def _listed(out: Path) -> dict:
    """The files an existing ``out/manifest.json`` lists, as written ({} when there is
    none, or it is a link, not a file, too large or not a manifest)."""
    path = out / MANIFEST
    try:
        st = os.lstat(path)
        if not stat.S_ISREG(st.st_mode) or st.st_size > MAX_MANIFEST_BYTES:
            return {}
        data = json.loads(path.read_bytes())
    except (OSError, ValueError, RecursionError):
        return {}
    files = data.get("files") if isinstance(data, dict) else None
    return files if isinstance(files, dict) else {}


def _plain_name(name) -> bool:
    return (isinstance(name, str) and name not in ("", ".", "..", MANIFEST)
            and "\0" not in name and "/" not in name
            and not (os.altsep and os.altsep in name) and os.sep not in name)


def _why_not_ours(out: Path, name, entry) -> str | None:
    """None when ``out/name`` is a file plcpred wrote as the manifest says; "" when there
    is nothing by that name; else why it is left alone."""
    if not _plain_name(name):
        return "it is not a plain file name inside the folder"
    path = out / name
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return ""
    except OSError as e:
        return f"it cannot be read ({e.strerror or e})"
    if stat.S_ISLNK(st.st_mode):
        return "it is a symbolic link"
    if not stat.S_ISREG(st.st_mode):
        return "it is not a regular file"
    size, digest = (entry.get("bytes"), entry.get("sha256")) if isinstance(entry, dict) \
        else (None, None)
    if not isinstance(size, int) or not isinstance(digest, str):
        return "the manifest gives no size and hash for it"
    if st.st_size != size:
        return "its size is not the one plcpred wrote (changed since, or not plcpred's)"
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
    except OSError as e:
        return f"it cannot be read ({e.strerror or e})"
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            return "it is not a regular file"
        if _sha256(fd) != digest.lower():
            return "its content is not what plcpred wrote (changed since, or not plcpred's)"
    finally:
        os.close(fd)
    return None


def proven_files(out) -> tuple[set, list[str]]:
    """(the names in ``out`` that an earlier run provably wrote, a warning for each other
    name its manifest lists that exists or escapes the folder)."""
    out = Path(out)
    proven, warnings = set(), []
    for name, entry in _listed(out).items():
        if name == MANIFEST:
            continue                        # replaced by every run in any case
        why = _why_not_ours(out, name, entry)
        if why is None:
            proven.add(name)
        elif why:
            warnings.append(f"--out {out}: left {name!r} alone although its manifest.json "
                            f"lists it: {why}")
    if len(warnings) > _SHOWN_WARNINGS:
        more = len(warnings) - _SHOWN_WARNINGS
        warnings = warnings[:_SHOWN_WARNINGS] + [f"--out {out}: {more} more names in its "
                                                 "manifest.json left alone likewise"]
    return proven, warnings


def _only_ours(out: Path, proven: set) -> bool:
    """True when everything in ``out`` is a file an earlier run provably wrote (or its
    manifest, a regular file)."""
    for entry in os.scandir(out):
        if entry.name == MANIFEST and entry.is_file(follow_symlinks=False):
            continue
        if entry.name not in proven:
            return False
    return True


def _commit(staging: Path, out: Path) -> list[str]:
    """Move the staged run into ``out``; the warnings about files left alone."""
    for _ in range(5):  # another run may be committing into the same place
        if not os.path.lexists(out):
            try:
                os.rename(staging, out)
                staging.mkdir()  # so the caller's cleanup has something to remove
                return []
            except OSError:
                continue
        if os.path.islink(out):
            raise OutputError(f"--out {out}: became a symbolic link during the run; "
                              "nothing written")
        proven, warnings = proven_files(out)
        if _only_ours(out, proven):
            trash = staging.with_name(_TRASH_PREFIX + staging.name[len(_STAGING_PREFIX):])
            try:
                trash.mkdir()
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
            return warnings
        # a directory with other files: replace ours file by file, and remove what the
        # previous run provably wrote and this one does not
        _unlink_quietly(out / MANIFEST)
        new = {f.name for f in staging.iterdir()}
        for name in sorted(new - {MANIFEST}):
            os.replace(staging / name, out / name)
        for name in sorted(proven - new):
            _unlink_quietly(out / name)
        os.replace(staging / MANIFEST, out / MANIFEST)
        return warnings
    raise OutputError(f"--out {out}: another run kept replacing it; try again")


def csv_column_name(name: str) -> str:
    """``name`` as a CSV column header: letters, digits and ``_-.``, anything else ``_``
    (a consumer's name may hold commas or quotes)."""
    return "".join(ch if ch.isalnum() or ch in "_-." else "_" for ch in name)
