"""Reading program files that come from untrusted places (a machine file or a project in a
pull request): where they may be, how large they may be, and how their bytes become text.

* **Where.** While a program is loaded with a set of allowed folders (``roots``: a machine
  file's folder, plus any the user allows), every file it reads - the program, a
  project's ``<Compile Include>``, a library, a Beremiz extension's file - must resolve
  (symbolic links followed, ``..`` applied) to a path under one of them. Outside, the
  file is not opened, and the error names the path only.
* **What.** Only regular files are read (not ``/dev/zero``, a FIFO or ``/dev/stdin``), each
  at most :data:`MAX_FILE_BYTES`; a folder is walked to at most
  :data:`MAX_FOLDER_ENTRIES` entries and :data:`MAX_FOLDER_DEPTH` levels, without
  entering linked folders.
* **Text.** A byte order mark decides (UTF-8, UTF-16, UTF-32); else an XML declaration's
  ``encoding``; else UTF-8, and Latin-1 where that fails (as older tools write).

The user widens the allowed folders with the ``PLCPRED_ALLOW_ROOTS`` environment variable
(folders separated by ``os.pathsep``), which :func:`extra_roots` sets for a command line
option, so that processes a sweep starts see them too.
"""
from __future__ import annotations

import codecs
import contextlib
import contextvars
import os
import re
import stat
from pathlib import Path

from .errors import ProgramError, ProgramFileError

MAX_FILE_BYTES = 64_000_000        # a program, library or project file (64 MB)
MAX_FOLDER_ENTRIES = 20_000         # files and folders a folder walk looks at
MAX_FOLDER_DEPTH = 32               # folders within folders a walk enters
ENV_ALLOW_ROOTS = "PLCPRED_ALLOW_ROOTS"

# the folders the load under way may read from (None: any)
_ROOTS: contextvars.ContextVar = contextvars.ContextVar("plcpred_roots", default=None)


# --------------------------------------------------------------------------- where

def env_roots() -> tuple[Path, ...]:
    """The folders the user allows besides a machine file's own (``PLCPRED_ALLOW_ROOTS``)."""
    text = os.environ.get(ENV_ALLOW_ROOTS, "")
    return tuple(resolved(Path(p)) for p in text.split(os.pathsep) if p.strip())


@contextlib.contextmanager
def extra_roots(paths):
    """Allow the folders ``paths`` (a command line's ``--allow-root``) for what runs
    inside, in this process and the ones it starts."""
    paths = [str(resolved(Path(p))) for p in paths or ()]
    old = os.environ.get(ENV_ALLOW_ROOTS)
    if paths:
        os.environ[ENV_ALLOW_ROOTS] = os.pathsep.join(paths + ([old] if old else []))
    try:
        yield
    finally:
        if paths:
            if old is None:
                os.environ.pop(ENV_ALLOW_ROOTS, None)
            else:
                os.environ[ENV_ALLOW_ROOTS] = old


def resolved(path: Path) -> Path:
    """``path`` made absolute with its links followed and ``..`` applied (what it really
    is); a path that cannot be resolved (a loop of links, a NUL) as it is written,
    made absolute and normalised (it then fails to be found)."""
    try:
        return Path(path).resolve()
    except (OSError, RuntimeError, ValueError):
        return Path(os.path.normpath(os.path.abspath(path)))


def is_under(path: Path, roots) -> bool:
    """Whether ``path`` (resolved) is one of ``roots`` or under one (resolved)."""
    real = resolved(path)
    return any(real == r or r in real.parents for r in roots)


def current_roots() -> tuple[Path, ...] | None:
    """The folders the load under way may read from, or None when any."""
    return _ROOTS.get()


@contextlib.contextmanager
def confined_to(roots):
    """Within, files are read only from under ``roots`` (None: anywhere)."""
    token = _ROOTS.set(None if roots is None else tuple(resolved(Path(r)) for r in roots))
    try:
        yield
    finally:
        _ROOTS.reset(token)


def outside_message(path: Path | None, roots) -> str:
    """Why ``path`` (None: "the file") is not read. It names the path, not the file's
    content."""
    shown = ", ".join(str(r) for r in roots)
    subject = "the file" if path is None else _shown(path)
    return (f"{subject} is outside the folders plcpred may read here ({shown}): "
            "programs, libraries and the files a project lists must be under the machine "
            "file's folder (or the project's), reached without leaving it through '..' or "
            "a symbolic link; allow another folder with --allow-root (or the "
            f"{ENV_ALLOW_ROOTS} environment variable)")


def _shown(path) -> str:
    text = str(path)
    return repr(text if len(text) <= 200 else text[:200] + "...")


def check_place(path: Path) -> None:
    """Raise a ProgramError when the load under way may not read ``path``."""
    roots = current_roots()
    if roots is not None and not is_under(path, roots):
        raise ProgramError(outside_message(path, roots), str(path), 0, 0)


# --------------------------------------------------------------------------- what

def read_bytes(path: Path, limit: int | None = None) -> bytes:
    """A regular file's bytes, at most ``limit`` of them (None: :data:`MAX_FILE_BYTES`),
    from a place the load under way may read; else a ProgramError that names the file
    (never its content)."""
    path = Path(path)
    limit = MAX_FILE_BYTES if limit is None else limit
    check_place(path)
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0) \
        | getattr(os, "O_BINARY", 0)
    try:
        # the path as checked (links followed once), so that what is opened is what was
        # checked
        fd = os.open(resolved(path) if current_roots() is not None else path, flags)
    except (OSError, ValueError) as e:
        raise ProgramFileError(f"cannot read file: {getattr(e, 'strerror', None) or e}",
                               str(path), 0, 0) from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise ProgramError("not a regular file (a device, a pipe or a folder): "
                               "plcpred reads programs from files", str(path), 0, 0)
        if st.st_size > limit:
            raise ProgramError(f"the file is {size_text(st.st_size)}; plcpred reads files "
                               f"of at most {size_text(limit)}", str(path), 0, 0)
        parts, size = [], 0
        while size <= limit:
            try:
                chunk = os.read(fd, min(1 << 20, limit + 1 - size))
            except BlockingIOError:
                raise ProgramError("the file does not read like a file (it blocks)",
                                   str(path), 0, 0) from None
            if not chunk:
                break
            parts.append(chunk)
            size += len(chunk)
        if size > limit:
            raise ProgramError(f"the file is larger than {size_text(limit)}, the most "
                               "plcpred reads", str(path), 0, 0)
        return b"".join(parts)
    except OSError as e:
        raise ProgramFileError(f"cannot read file: {e.strerror}", str(path), 0, 0) from None
    finally:
        os.close(fd)


def size_text(n: int) -> str:
    return f"{n / 1e6:.0f} MB" if n >= 1_000_000 else f"{n} bytes"


def listing(folder: Path, depth: int | None = None) -> list[Path]:
    """The files under ``folder`` (links to files included, linked folders not entered),
    sorted; a ProgramError naming the folder when it holds more than
    :data:`MAX_FOLDER_ENTRIES` entries or nests deeper than ``depth`` levels (0: the
    folder's own files only, the folders in it left out)."""
    folder = Path(folder)
    check_place(folder)
    depth = MAX_FOLDER_DEPTH if depth is None else depth
    out: list[Path] = []
    seen, limit = 0, MAX_FOLDER_ENTRIES
    stack = [(folder, 0)]
    while stack:
        where, level = stack.pop()
        try:
            with os.scandir(where) as entries:
                for e in entries:
                    seen += 1
                    if seen > limit:
                        raise ProgramError(
                            f"the folder holds more than {limit} files and "
                            "folders, more than plcpred looks through: name the project "
                            "file (.plcproj) or a smaller folder", str(folder), 0, 0)
                    try:
                        if e.is_dir(follow_symlinks=False):
                            if level < depth:
                                stack.append((Path(e.path), level + 1))
                            elif depth >= MAX_FOLDER_DEPTH:
                                raise ProgramError(
                                    f"folders nested more than {depth} deep "
                                    f"(at {_shown(e.path)})", str(folder), 0, 0)
                        elif e.is_file():
                            out.append(Path(e.path))
                    except OSError:
                        continue    # vanished or unreadable: not a file of the project
        except OSError as e:
            raise ProgramFileError(f"cannot read folder: {e.strerror}", str(where), 0, 0) \
                from None
    return sorted(out)


# --------------------------------------------------------------------------- text

_BOMS = ((codecs.BOM_UTF32_LE, "utf-32-le"), (codecs.BOM_UTF32_BE, "utf-32-be"),
         (codecs.BOM_UTF8, "utf-8"), (codecs.BOM_UTF16_LE, "utf-16-le"),
         (codecs.BOM_UTF16_BE, "utf-16-be"))
# '<?' in UTF-16 or UTF-32 without a byte order mark (XML 1.0, appendix F)
_XML_STARTS = ((b"<\0\0\0?\0\0\0", "utf-32-le"), (b"\0\0\0<\0\0\0?", "utf-32-be"),
               (b"<\0?\0", "utf-16-le"), (b"\0<\0?", "utf-16-be"))
_XML_DECLARATION = re.compile(
    rb"<\?xml\s[^>]{0,200}?\bencoding\s*=\s*([\"'])([^\"'>]{0,60})\1", re.ASCII)
# codecs Python has that are no character set a file is written in
_NOT_CHARSETS = {"punycode", "idna", "unicode-escape", "raw-unicode-escape", "undefined",
                 "utf-7", "mbcs", "oem"}


def _codec(name: str) -> str | None:
    """The codec of a declared encoding name, or None when it is none plcpred reads."""
    if not re.fullmatch(r"[A-Za-z][A-Za-z0-9._:-]*", name, re.ASCII):
        return None
    try:
        info = codecs.lookup(name)
    except LookupError:
        return None
    # a bytes-to-bytes or str-to-str codec (zlib, base64, rot13) is no character set
    if not getattr(info, "_is_text_encoding", True) or info.name in _NOT_CHARSETS:
        return None
    return info.name


def decode(data: bytes, filename: str = "<input>") -> str:
    """A file's text: by its byte order mark, else by its XML declaration's encoding,
    else UTF-8, and Latin-1 where that fails. The mark is dropped."""
    for bom, codec in _BOMS:
        if data.startswith(bom):
            return _strict(data[len(bom):], codec, filename)
    for start, codec in _XML_STARTS:
        if data.startswith(start):
            return _strict(data, codec, filename)
    m = _XML_DECLARATION.match(data, 0, 300)
    if m:
        name = m.group(2).decode("ascii", "replace").strip()
        codec = _codec(name)
        if codec is None:
            col = m.start(2) + 1
            raise ProgramError(f"the XML declaration names encoding {name[:60]!r}, which "
                               "plcpred does not know (UTF-8, UTF-16, ISO-8859-1, "
                               "Windows-1252 and the other character sets Python reads "
                               "are read)", filename, 1, col)
        # a file without a byte order mark declared as UTF-16 or -32 is really in an
        # 8-bit encoding (the declaration was read as ASCII): read it as undeclared
        if codec not in ("utf-8", "ascii") and not codec.startswith(("utf-16", "utf-32")):
            return _strict(data, codec, filename)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return data.decode("latin-1")


def _strict(data: bytes, codec: str, filename: str) -> str:
    try:
        return data.decode(codec)
    except UnicodeDecodeError as e:
        raise ProgramError(f"not valid {codec.upper()} text (at byte {e.start})",
                           filename, 0, 0) from None
    except (LookupError, ValueError) as e:   # a codec that reads no bytes after all
        raise ProgramError(f"cannot read the file as {codec.upper()}: {e}", filename, 0, 0) \
            from None


def read_source(path: Path) -> str:
    """A program file's text (see :func:`decode`), read as :func:`read_bytes` allows."""
    return decode(read_bytes(path), str(path))
