"""Vendor libraries: the declarations (and, where it matters to timing, the behaviour) of
what real programs use from libraries that are not in their source.

plcpred ships ST stubs of the common ones under ``plcpred/libraries/`` (Beckhoff
Tc2_System, Tc2_Utilities, Tc2_EtherCAT and Tc2_Math basics, Tc3_JsonXml's writer,
Tc3_EventLogger's severities, CODESYS Util and SysFile, OSCAT BASIC's MULTIME, PLCopen
motion as Tc2_MC2 and SM3_Basic name it); the IEC
standard blocks (Tc2_Standard, CODESYS Standard) are built in. A user adds their own
library declarations as ST, TwinCAT or PLCopen files or folders (``plcpred check --lib
DIR``, ``libraries = [...]`` in the machine file).

* Only what a program refers to is taken from a library (and what that needs in turn),
  so a library's other POUs cost nothing and cannot clash with the program's own names.
  A name the program defines itself always wins.
* A library's namespace qualifies its names in TwinCAT and CODESYS (``Tc2_System.MEMCPY``,
  ``TcUnit.FB_TestSuite``): the qualifier is dropped where it names a known library.
"""
from __future__ import annotations

import dataclasses
import functools
import json
import sys
from pathlib import Path

from . import ir
from .errors import ProgramError
from .files import confined_to, env_roots, listing, resolved
from .notes import unread_pragma
from .read import read_file, read_program
from .shipped import BUILTIN_NAMESPACES, INDEX_FILE, SHIPPED_DIR, shipped_index, shipped_namespaces
from .twincat import project_files


@dataclasses.dataclass
class Library:
    """Everything one library declares, by upper-case name."""
    namespace: str
    pous: dict[str, ir.Pou]
    types: dict[str, ir.TypeDecl]
    interfaces: dict[str, ir.Interface]
    globals: list[ir.GlobalVars]
    unread: list[str] = dataclasses.field(default_factory=list)  # files left out, why
    # upper-case enumeration value -> its TYPE (built on first use)
    enum_values: dict | None = None


def _library(program: ir.Program, namespace: str) -> Library:
    return Library(namespace,
                   {p.name.upper(): p for p in program.pous},
                   {t.name.upper(): t for t in program.types},
                   {i.name.upper(): i for i in program.interfaces},
                   list(program.globals))


def _shipped_files() -> list[Path]:
    return sorted([*SHIPPED_DIR.glob("*.st"), *SHIPPED_DIR.glob("*.TcGVL")])


@functools.lru_cache(maxsize=None)
def _shipped_file(name: str) -> tuple[Library, ...]:
    """The libraries one stub file declares (one per namespace its pragma gives)."""
    f = SHIPPED_DIR / name
    prog = read_program(f)
    namespaces = [p[0] for p in prog.pragmas if p[0].lower().startswith("{library ")]
    return tuple(_library(prog, ns) for pragma in namespaces or ["{library " + f.stem + "}"]
                 for ns in pragma[len("{library "):-1].replace(",", " ").split())


@functools.lru_cache(maxsize=None)
def shipped() -> tuple[Library, ...]:
    """The stubs plcpred ships, all of them (parsed once per process, 0.2 s; a program's
    libraries are read through :func:`shipped_declaring`, which parses only the files
    that declare a name it uses)."""
    return tuple(lib for f in _shipped_files() for lib in _shipped_file(f.name))


def build_index() -> dict:
    """{stub file: {"namespaces": [...], "names": [...]}}: every upper-case name a stub
    file's libraries declare (POUs, types, interfaces, GVLs and their variables,
    enumeration values), as :data:`INDEX_FILE` keeps it."""
    out = {}
    for f in _shipped_files():
        libs = _shipped_file(f.name)
        names = set()
        for lib in libs:
            names |= set(lib.pous) | set(lib.types) | set(lib.interfaces)
            for g in lib.globals:
                names |= {d.name.upper() for d in g.block.decls}
                if g.name:
                    names.add(g.name.upper())
            names |= set(_enum_values(lib))
        strings = {name: "W" if t.type.wide else "S" for lib in libs
                   for name, t in lib.types.items() if isinstance(t.type, ir.StringType)}
        out[f.name] = {"namespaces": [lib.namespace for lib in libs], "names": sorted(names),
                       "strings": dict(sorted(strings.items()))}
    return out


def shipped_declaring(name: str):
    """The libraries of the stub files that declare ``name`` (upper case), in file
    order; a file is parsed when it first declares a name asked for."""
    for file, _, names in shipped_index():
        if name in names:
            yield from _shipped_file(file)


def user_libraries(paths, allowed_roots=None) -> list[Library]:
    """Libraries from files or folders the user names; the namespace is the file's or
    folder's name (a .plcproj's stem). Each is read once while its files stay as they
    are (a check of many files against one library project reads it once).

    Its files are read only from under ``allowed_roots`` (a machine file's folders), or
    with None (a library named on the command line), from under its own folder and those
    ``PLCPRED_ALLOW_ROOTS`` allows."""
    out = []
    for p in paths:
        path = resolved(Path(p))
        if allowed_roots is None:
            roots = (path if path.is_dir() else path.parent,) + env_roots()
        else:
            roots = tuple(resolved(Path(r)) for r in allowed_roots)
        out.append(_user_library(path, _stamp(path, roots), roots))
    return out


def _stamp(path: Path, roots) -> tuple:
    """What changes when a library's files change: their names, sizes and times (a
    folder walked as :func:`.files.listing` bounds it)."""
    folder = path.parent if path.suffix.lower() == ".plcproj" else path
    with confined_to(roots):
        files = [path] if folder.is_file() else listing(folder)
    try:
        return tuple((str(f), f.stat().st_size, f.stat().st_mtime_ns) for f in files)
    except OSError:
        return ()


@functools.lru_cache(maxsize=16)
def _user_library(path: Path, _stamp: tuple, roots: tuple = ()) -> Library:
    """One library the user names. A library project (a folder or .plcproj) is read
    file by file when one of its files cannot be read: the rest still declares what it
    declares, and the files left out are named where a name is missing
    (:func:`unread_library_files`)."""
    namespace = path.stem or path.name
    try:
        return _library(read_program(path, allowed_roots=roots), namespace)
    except ProgramError:
        if not (path.is_dir() or path.suffix.lower() == ".plcproj"):
            raise
    read, unread = [], []
    with confined_to(roots):
        for f in project_files(path):
            try:
                read.append(read_file(f))
            except ProgramError as e:
                unread.append(str(e))
    program = functools.reduce(ir.Program.merge, read) if read else ir.Program()
    lib = _library(program, namespace)
    lib.unread = unread
    return lib


def main(argv=None) -> int:
    """``python -m plcpred.parser.libraries --index``: write :data:`INDEX_FILE` again
    after a stub changed."""
    args = sys.argv[1:] if argv is None else argv
    if args != ["--index"]:
        print("usage: python -m plcpred.parser.libraries --index", file=sys.stderr)
        return 2
    INDEX_FILE.write_text(json.dumps(build_index(), indent=1, sort_keys=True) + "\n",
                          encoding="utf-8")
    print(f"wrote {INDEX_FILE}")
    return 0


# ------------------------------------------------------------------------- namespaces

def strip_namespaces(program: ir.Program, namespaces: set[str]) -> None:
    """Drop a library qualifier (``Tc2_System.MEMCPY`` -> ``MEMCPY``) wherever the program
    writes one: in type names, EXTENDS/IMPLEMENTS and expressions. A qualifier that is
    also one of the program's own variables or GVLs is left alone."""
    own = {g.name.upper() for g in program.globals if g.name}
    ns = {n.upper() for n in namespaces} - own

    def strip(name):
        # a namespace may sit inside another (SysFile.SysTypes.RTS_IEC_HANDLE)
        while isinstance(name, str) and "." in name:
            head, rest = name.split(".", 1)
            if head.upper() not in ns:
                break
            name = rest
        return name

    for pou in program.pous:
        pou.extends = strip(pou.extends)
        pou.implements = [strip(i) for i in pou.implements]
    for itf in program.interfaces:
        itf.extends = [strip(i) for i in itf.extends]
    stack = [program]
    while stack:
        node = stack.pop()
        for name in ir.field_names(type(node)):
            value = getattr(node, name)
            if isinstance(value, ir.NamedType):
                value.name = strip(value.name)
            new = _unqualified(value, ns)
            if new is not value:
                setattr(node, name, new)
                value = new
            _push(stack, value, ns)


def _unqualified(value, ns):
    """``NS.x`` (a Member of the Name of a namespace) as the Name ``x``, also where the
    namespace is itself qualified by one (``SysFile.SysTypes.x``)."""
    if not isinstance(value, ir.Member):
        return value
    base = _unqualified(value.base, ns)
    if isinstance(base, ir.Name) and base.name.upper() in ns:
        return ir.Name(value.member, pos=value.pos)
    if base is not value.base:
        value.base = base
    return value


def _push(stack, value, ns):
    if dataclasses.is_dataclass(value):
        stack.append(value)
    elif isinstance(value, (list, tuple)):
        for i, v in enumerate(value):
            if isinstance(value, list):
                new = _unqualified(v, ns)
                if new is not v:
                    value[i] = v = new
            _push(stack, v, ns)
    elif isinstance(value, dict):
        for v in value.values():
            _push(stack, v, ns)


# ------------------------------------------------------------------------- selection

def referenced_names(node) -> set[tuple[str, str]]:
    """Every name (upper case) a piece of IR refers to, as ("T", name) where only a type
    (a POU, TYPE or interface) can answer it and ("V", name) where a variable can too."""
    names, stack = set(), [node]
    while stack:
        n = stack.pop()
        if isinstance(n, (list, tuple)):
            stack.extend(n)
            continue
        if isinstance(n, dict):
            stack.extend(n.values())
            continue
        if not dataclasses.is_dataclass(n):
            continue
        if isinstance(n, ir.NamedType):
            names.add(("T", n.name.upper()))
        elif isinstance(n, ir.Name):
            names.add(("V", n.name.upper()))
        elif isinstance(n, ir.Pou):
            names.update(("T", x.upper()) for x in [n.extends or ""] + n.implements if x)
        elif isinstance(n, ir.Interface):
            names.update(("T", x.upper()) for x in n.extends)
        stack.extend(getattr(n, name) for name in ir.field_names(type(n)))
    return names


def _defined(programs) -> set[tuple[str, str]]:
    """What ``programs`` declare, in the terms of :func:`referenced_names`: a variable named
    like a type (``GetCpuCounter : GETCPUCOUNTER``) does not declare the type."""
    out = set()
    for p in programs:
        for x in [*p.pous, *p.types, *p.interfaces]:
            out.update({("T", x.name.upper()), ("V", x.name.upper())})
        for g in p.globals:
            out.update(("V", d.name.upper()) for d in g.block.decls)
            if g.name:
                out.add(("V", g.name.upper()))
    return out


def library_program(programs: list[ir.Program], paths=(), allowed_roots=None
                    ) -> ir.Program:
    """What ``programs`` use from the libraries (user libraries first, then the shipped
    stubs), as one Program; library qualifiers in ``programs`` are dropped. The user's
    libraries are read from under ``allowed_roots`` (see :func:`user_libraries`)."""
    users = user_libraries(paths, allowed_roots)
    namespaces = {lib.namespace for lib in users} | BUILTIN_NAMESPACES | shipped_namespaces()
    for p in programs:
        strip_namespaces(p, namespaces)
    out = ir.Program(source="<libraries>")
    out.pragmas += [(unread_pragma(why), ir.Pos("<libraries>", 0, 0))
                    for lib in users for why in lib.unread]

    def libraries_for(name: str):
        """The libraries that may declare ``name``, in order: the user's, then the stub
        files that declare it (parsed on first need)."""
        yield from users
        yield from shipped_declaring(name)
    have = _defined(programs)
    wanted = set().union(*(referenced_names(p) for p in programs)) - have
    added: set[int] = set()
    own_values = {v.upper() for p in programs for t in p.types
                  if isinstance(t.type, ir.EnumType) for v, _ in t.type.values}
    while wanted:
        kind, name = wanted.pop()
        if (kind, name) in have:
            continue
        # a value named bare brings its enumeration, unless anything else has the name
        by_value = kind == "V" and name not in own_values and not any(
            name in lib.pous or name in lib.types or name in lib.interfaces
            for lib in libraries_for(name))
        for lib in libraries_for(name):
            found = lib.pous.get(name) or lib.types.get(name) or lib.interfaces.get(name) \
                or (by_value and _enum_of(lib, name)) or None
            gvl = None if found or kind == "T" else next(
                (g for g in lib.globals if name in {d.name.upper() for d in g.block.decls}
                 or (g.name or "").upper() == name), None)
            if found is None and gvl is None:
                continue
            # a named GVL comes whole (all its VAR_GLOBAL blocks: it is one object)
            items = [found] if found else [g for g in lib.globals if g is gvl or (
                gvl.name and (g.name or "").upper() == gvl.name.upper())]
            items = [i for i in items if id(i) not in added]
            for item in items:
                # an enumeration comes once, however many of its values are named bare
                added.add(id(item))
                out.add(item)
            new = _defined([out]) | have
            wanted |= referenced_names(items) - new
            have = new
            break
    return out


def _enum_values(lib: Library) -> dict:
    """Upper-case enumeration value -> the first of ``lib``'s TYPEs that has it."""
    if lib.enum_values is None:
        lib.enum_values = {}
        for t in lib.types.values():
            if isinstance(t.type, ir.EnumType):
                for v, _ in t.type.values:
                    lib.enum_values.setdefault(v.upper(), t)
    return lib.enum_values


def _enum_of(lib: Library, value: str) -> ir.TypeDecl | None:
    """The enumerated type of ``lib`` that has the value ``value`` (upper case), where a
    program names the value bare (``IBaseLibrary.TYPE_BIT``)."""
    return _enum_values(lib).get(value)


if __name__ == "__main__":
    raise SystemExit(main())
