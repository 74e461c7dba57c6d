"""The globals a Beremiz project declares outside its ``plc.xml``.

A Beremiz project is a folder: ``beremiz.xml``, the PLCopen ``plc.xml``, and one folder
per extension ("confnode", ``NAME@KIND``) with a ``baseconfnode.xml`` (its name and IEC
channel). Extensions add PLC globals that ``plc.xml`` reaches as VAR_EXTERNAL:

* ``@py_ext`` (``pyfile.xml``) and ``@c_ext`` (``cfile.xml``): ``<variables>`` with a name,
  a type and an initial value;
* ``@svghmi``: ``CURRENT_PAGE_<channel>`` (an HMI_STRING; Beremiz's svghmi.py
  ``CTNGlobalInstances``).

Anything else an extension generates (C code, Python) does not run in plcpred.
"""
from __future__ import annotations

import os
import re
from pathlib import Path

from . import files, ir
from .errors import ProgramError
from .files import read_source
from .plcopen import PlcopenImporter
from .xmltree import XmlElement, parse_xml

_VARIABLE_FILES = {"py_ext": ("pyfile.xml", "PyFile"), "c_ext": ("cfile.xml", "CFile")}


def is_beremiz_project(folder: Path) -> bool:
    return (folder / "beremiz.xml").is_file()


def confnode_globals(folder: Path) -> list[ir.GlobalVars]:
    """The globals the extensions of the Beremiz project in ``folder`` declare (one
    block per extension, in the folder's order)."""
    blocks = []
    for node in _extensions(folder):
        kind = node.name.rsplit("@", 1)[1]
        decls: list[ir.VarDecl] = []
        if kind in _VARIABLE_FILES:
            name, root = _VARIABLE_FILES[kind]
            f = node / name
            if f.is_file():
                decls = _variables(f, root)
        elif kind == "svghmi":
            channel = _channel(node)
            if channel is not None:
                pos = ir.Pos(str(node / "baseconfnode.xml"), 1, 1)
                decls = [ir.VarDecl(f"CURRENT_PAGE_{channel}",
                                    ir.NamedType("HMI_STRING", pos=pos), pos=pos)]
        if decls:
            blocks.append(ir.GlobalVars(None, ir.VarBlock("VAR_GLOBAL", decls),
                                        pos=decls[0].pos))
    return blocks


def _extensions(folder: Path) -> list[Path]:
    """The extension folders (``NAME@KIND``) of the project in ``folder``, in name order
    (at most :data:`.files.MAX_FOLDER_ENTRIES` entries looked at)."""
    out = []
    try:
        with os.scandir(folder) as entries:
            for n, e in enumerate(entries):
                if n >= files.MAX_FOLDER_ENTRIES:
                    raise ProgramError(f"the folder holds more than {files.MAX_FOLDER_ENTRIES} "
                                       "files and folders, more than plcpred looks through",
                                       str(folder), 0, 0)
                if "@" in e.name and e.is_dir(follow_symlinks=False):
                    out.append(Path(e.path))
    except OSError as e:
        raise ProgramError(f"cannot read folder: {e.strerror}", str(folder), 0, 0) from None
    return sorted(out)


def _read(path: Path, root: str) -> tuple[XmlElement, PlcopenImporter]:
    text = read_source(path)    # a regular file, bounded, under the load's folders
    return parse_xml(text, str(path), root, f"a Beremiz {root} file"), PlcopenImporter(str(path))


def _variables(path: Path, root: str) -> list[ir.VarDecl]:
    el, imp = _read(path, root)
    holder = el.find("variables")
    out = []
    for v in holder.findall("variable") if holder is not None else []:
        type_name = imp.req(v, "type")
        pos = ir.Pos(str(path), v.line, v.col)
        t = ir.StringType(type_name.upper() == "WSTRING") \
            if type_name.upper() in ("STRING", "WSTRING") else ir.NamedType(type_name, pos=pos)
        initial = v.attrib.get("initial")
        init = imp.simple_value(v, initial, t) if initial else None
        out.append(ir.VarDecl(imp.req(v, "name"), t, init, pos=pos))
    return out


def _channel(node: Path) -> str | None:
    f = node / "baseconfnode.xml"
    if not f.is_file():
        return None
    try:
        el, _ = _read(f, "BaseParams")
    except ProgramError:
        return None
    channel = el.attrib.get("IEC_Channel", "")
    # ASCII digits only: '²'.isdigit() is true, and the name must be an identifier
    return channel if re.fullmatch(r"[0-9]{1,9}", channel) else None
