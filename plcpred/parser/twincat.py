"""TwinCAT 3 project files: ``.TcPOU``, ``.TcGVL``, ``.TcDUT``, ``.TcIO``, ``.TcTTO`` and
whole projects (a ``.plcproj`` or a folder).

A TwinCAT object file is XML whose CDATA sections hold plain ST: a POU's declaration and
implementation, each method's, each property accessor's, each action's. The importer
places every section at its own line and column of the XML file, fills the gaps with the
keywords the XML structure stands for (``END_METHOD``, ``GET`` ... ``END_GET``, ``ACTION
name:``, ``END_FUNCTION_BLOCK``) and parses the result as one ST text, so an error in any
section points at the line and column of the ``.TcPOU`` file, and every construct the ST
front end reads is read here too.

* Bodies in a graphical language (SFC, FBD, LD, CFC, IL networks) are kept as
  :class:`ir.Opaque` statements: the project loads and checks, with a warning, and only
  executing such a body is an error. Transitions belong to SFC bodies and are skipped.
* A GVL's name qualifies its globals (``GVL_IO.bStart``), as in TwinCAT.
* A task object (``.TcTTO``) becomes a configuration: its cycle time is the task
  INTERVAL and its POU calls are the programs that run, in order.
"""
from __future__ import annotations

import hashlib
import os
import re
from pathlib import Path

from . import ir
from .bnr import BNR_SUFFIXES
from .errors import ProgramError
from .files import current_roots, is_under, listing, outside_message, resolved
from .files import read_source as read_confined_source
from .names import is_identifier, validate_names
from .st import parse_st
from .xmltree import XmlElement, parse_xml

OBJECT_SUFFIXES = (".tcpou", ".tcgvl", ".tcdut", ".tcio", ".tctto", ".tctleo")
# files a project folder is read from, besides TwinCAT objects
_ST_SUFFIXES = (".st", ".iecst")
_POU_KIND = re.compile(r"\b(PROGRAM|FUNCTION_BLOCK|FUNCTION|INTERFACE)\b", re.I)
_COMMENTS = re.compile(r"\(\*[\s\S]*?\*\)|/\*[\s\S]*?\*/|//[^\n]*|\{[^}]*\}|'[^']*'|\"[^\"]*\"")


class _Stitch:
    """ST text assembled from pieces, each placed at its line and column in the XML file
    when the text written so far allows (pieces arrive in document order), and keywords
    placed in between."""

    def __init__(self):
        self.parts: list[str] = []
        self.line, self.col = 1, 1
        self.tail = ""  # the text on the current line

    def _advance(self, text: str) -> None:
        self.parts.append(text)
        nls = text.count("\n")
        if nls:
            self.line += nls
            self.col = len(text) - text.rfind("\n")
            self.tail = text[text.rfind("\n") + 1:]
        else:
            self.col += len(text)
            self.tail += text

    def place(self, text: str, line: int, col: int) -> None:
        if line > self.line:
            self._advance("\n" * (line - self.line))
        if line == self.line and col > self.col:
            self._advance(" " * (col - self.col))
        elif self.col > 1:
            self._advance(" ")
        self._advance(text)

    def keyword(self, text: str) -> None:
        # after a line comment, on a line of its own (it is then one line early, which
        # only shifts a later piece that shares the closing tag's line)
        self._advance(("\n" if "//" in self.tail else " ") + text + " ")

    def text(self) -> str:
        return "".join(self.parts)


class PlcopenImporter:
    def __init__(self, filename: str, text: str = ""):
        self.file = filename
        self.gvl_names: list[str] = []
        self.opaque: list[ir.Opaque] = []
        # the markers of graphical bodies carry a digest of the file, which its own text
        # cannot hold (a file's ``{{#0}}`` is its own inline code, not one of them)
        data = text if isinstance(text, bytes) else text.encode("utf-8", "surrogatepass")
        self.nonce = hashlib.sha256(data).hexdigest()[:24]

    def error(self, el: XmlElement, message: str) -> ProgramError:
        return ProgramError(message, self.file, el.line, el.col)

    def name_of(self, el: XmlElement) -> str:
        """The element's Name attribute, which becomes ST text: an identifier or nothing."""
        name = el.attrib.get("Name", "")
        if not is_identifier(name):
            raise self.error(el, f"<{el.tag}> Name={name[:60]!r} is not an IEC identifier")
        return name

    # ------------------------------------------------------------------ sections
    def section(self, out: _Stitch, el: XmlElement | None) -> str:
        """Place the ST text under ``el`` (a Declaration or an ST element); returns it."""
        if el is None:
            return ""
        text, line, col = el.all_text()
        if text.strip():
            out.place(text, line, col)
        return text

    def implementation(self, out: _Stitch, owner: XmlElement, what: str) -> None:
        impl = owner.find("Implementation")
        if impl is None:
            return
        for lang in impl.children:
            if lang.tag == "ST":
                self.section(out, lang)
                # a body that ends in a comment or a label still needs its statements closed
                out.keyword(";")
                return
            # any other language: a marker parsed as an inline-code statement, swapped
            # for the Opaque after
            marker = f"{{{{#{self.nonce}:{len(self.opaque)}}}}}"
            self.opaque.append(ir.Opaque(f"the {lang.tag} body of {what}",
                                         pos=ir.Pos(self.file, lang.line, lang.col)))
            out.place(marker, lang.line, lang.col)
            return

    # ------------------------------------------------------------------ objects
    def pou(self, out: _Stitch, el: XmlElement) -> None:
        name = self.name_of(el)
        decl = self.section(out, el.find("Declaration"))
        kind = _POU_KIND.search(_COMMENTS.sub(" ", decl))
        if kind is None:
            raise self.error(el, f"POU '{name}': its declaration does not say PROGRAM, "
                                 "FUNCTION_BLOCK or FUNCTION")
        kind = kind.group(1).upper()
        if kind == "INTERFACE":
            return self.interface(out, el, name)
        self.implementation(out, el, f"{kind.replace('_', ' ').lower()} {name}")
        for child in el.children:
            if child.tag == "Method":
                self.section(out, child.find("Declaration"))
                self.implementation(out, child, f"method {name}.{self.name_of(child)}")
                out.keyword("END_METHOD")
            elif child.tag == "Property":
                self.property(out, child, f"{name}.{self.name_of(child)}")
            elif child.tag == "Action":
                action = self.name_of(child)
                out.keyword(f"ACTION {action}:")
                self.implementation(out, child, f"action {name}.{action}")
                out.keyword("END_ACTION")
        out.keyword(f"END_{kind}")

    def property(self, out: _Stitch, el: XmlElement, what: str, bodies: bool = True) -> None:
        self.section(out, el.find("Declaration"))
        for acc in el.children:
            if acc.tag in ("Get", "Set"):
                out.keyword(acc.tag.upper())
                self.section(out, acc.find("Declaration"))
                if bodies:
                    self.implementation(out, acc, f"property {what} {acc.tag.upper()}")
                out.keyword(f"END_{acc.tag.upper()}")
        out.keyword("END_PROPERTY")

    def interface(self, out: _Stitch, el: XmlElement, name: str) -> None:
        for child in el.children:
            if child.tag == "Method":
                self.section(out, child.find("Declaration"))
                out.keyword("END_METHOD")
            elif child.tag == "Property":
                self.property(out, child, f"{name}.{self.name_of(child)}", bodies=False)
        out.keyword("END_INTERFACE")

    def task(self, el: XmlElement) -> ir.Configuration:
        """A .TcTTO task: CycleTime (microseconds) and the POUs it calls, in order."""
        name = self.name_of(el)
        pos = ir.Pos(self.file, el.line, el.col)
        params = {}
        cycle = el.find("CycleTime")
        if cycle is not None:
            text = cycle.all_text()[0].strip()
            if not re.fullmatch(r"[0-9]{1,10}", text) or not 0 < int(text) <= 3_600_000_000:
                raise self.error(cycle, f"<CycleTime> {text[:40]!r}: expected a whole number "
                                        "of microseconds, 1..3600000000")
            params["INTERVAL"] = ir.Literal(int(text) * 1000, "TIME", pos=pos)
        resource = ir.Resource("PlcTask", None, tasks=[ir.Task(name, params, pos=pos)], pos=pos)
        for call in el.findall("PouCall"):
            target = call.find("Name")
            if target is None:
                continue
            pou = target.all_text()[0].strip()
            if not is_identifier(pou):
                raise self.error(target, f"<PouCall> names {pou[:60]!r}, not an IEC identifier")
            resource.programs.append(ir.ProgramInstance(pou, pou, name, pos=ir.Pos(
                self.file, target.line, target.col)))
        return ir.Configuration(f"{name}_config", resources=[resource], pos=pos)

    def object_file(self, root: XmlElement) -> ir.Program:
        out = _Stitch()
        configurations = []
        for el in root.children:
            if el.tag == "POU":
                self.pou(out, el)
            elif el.tag == "Itf":
                self.name_of(el)
                self.section(out, el.find("Declaration"))
                self.interface(out, el, el.attrib["Name"])
            elif el.tag in ("DUT", "EnumerationTextList"):
                # an enumeration with a text list (.TcTLEO) declares its TYPE as a DUT
                self.name_of(el)
                self.section(out, el.find("Declaration"))
            elif el.tag == "GVL":
                self.gvl_names.append(self.name_of(el))
                self.section(out, el.find("Declaration"))
            elif el.tag == "Task":
                configurations.append(self.task(el))
            # other objects (visualisations, text lists, recipes, ...) hold no code
        prog = parse_st(out.text(), self.file, validate=False)
        prog.configurations.extend(configurations)
        if self.gvl_names:
            # one GVL object per file: all its VAR_GLOBAL blocks carry its name
            for g in prog.globals:
                g.name = self.gvl_names[0]
        if self.opaque:
            _replace_markers(prog, {f"#{self.nonce}:{k}": op
                                    for k, op in enumerate(self.opaque)})
        return prog


def _replace_markers(prog: ir.Program, opaque: dict[str, ir.Opaque]) -> None:
    """Swap the parsed ``{{#nonce:k}}`` marker statements for the Opaque nodes they stand
    for (``opaque``: by the marker's text). Inline code the file holds itself, whatever
    it says, stays what it is."""
    def fix(body):
        if not isinstance(body, list):
            return
        for i, s in enumerate(body):
            if isinstance(s, ir.Opaque) and s.text in opaque:
                body[i] = opaque[s.text]

    for pou in prog.pous:
        fix(pou.body)
        for m in pou.methods:
            fix(m.body)
        for a in pou.actions:
            fix(a.body)
        for p in pou.properties:
            for acc in p.accessors:
                fix(acc.body)


def parse_twincat(text: str, filename: str = "<input>") -> ir.Program:
    """Import one TwinCAT 3 object file (``.TcPOU``, ``.TcGVL``, ``.TcDUT``, ``.TcIO``,
    ``.TcTTO``) into the IR."""
    root = parse_xml(text, filename, "TcPlcObject", "a TwinCAT 3 object file")
    return validate_names(PlcopenImporter(filename, text).object_file(root))


# --------------------------------------------------------------------------- projects

def project_files(path: Path, missing: list | None = None) -> list[Path]:
    """The program files of a TwinCAT project: those a ``.plcproj`` compiles (in its
    order), or for a folder, those of the one ``.plcproj`` under it, else every TwinCAT
    object and ST file under it (sorted). A file the ``.plcproj`` lists that is not there
    (left out of source control) is left out and added to ``missing`` as (file, where the
    .plcproj lists it): the project still loads, and a name it would have declared is
    then reported with it.

    A folder is walked as :func:`.files.listing` bounds it. A listed file must be under
    the folders the load may read (:func:`.files.confined_to`; when none are set, the
    .plcproj's own folder), reached without leaving them through ``..`` or a link."""
    if path.is_dir():
        found = listing(path)
        projects = [p for p in found if p.suffix.lower() == ".plcproj"]
        if len(projects) > 1:
            listed = ", ".join(str(p.relative_to(path)) for p in projects[:5])
            raise ProgramError(f"the folder holds {len(projects)} PLC projects ({listed}"
                               f"{', ...' if len(projects) > 5 else ''}): name one .plcproj "
                               "or its folder", str(path), 0, 0)
        if projects:
            return project_files(projects[0], missing)
        files = [p for p in found
                 if p.suffix.lower() in OBJECT_SUFFIXES + _ST_SUFFIXES + BNR_SUFFIXES]
        if not files:
            raise ProgramError("the folder holds no program files (.TcPOU, .TcGVL, .TcDUT, "
                               ".TcIO, .TcTTO, .st; B&R .var, .typ, .fun)", str(path), 0, 0)
        return files
    root = parse_xml(read_source(path), str(path), "Project", "a TwinCAT .plcproj file")
    roots = current_roots() or (resolved(path).parent,)
    files = []
    for group in root.findall("ItemGroup"):
        for item in group.findall("Compile"):
            include = item.attrib.get("Include", "").replace("\\", "/")
            if Path(include).suffix.lower() not in OBJECT_SUFFIXES + _ST_SUFFIXES:
                continue
            if "\0" in include or os.path.isabs(include) or re.match(r"[A-Za-z]:", include):
                raise ProgramError(f"<Compile Include={include[:200]!r}>: a project's files "
                                   "are named relative to its .plcproj, not by an absolute "
                                   "path", str(path), item.line, item.col)
            target = Path(os.path.normpath(path.parent / include))
            if not is_under(target, roots):
                raise ProgramError(f"<Compile Include={include[:200]!r}>: "
                                   + outside_message(None, roots), str(path),
                                   item.line, item.col)
            if not target.is_file():
                if missing is None:
                    raise ProgramError(f"<Compile Include={include[:200]!r}>: file not found",
                                       str(path), item.line, item.col)
                missing.append((include, ir.Pos(str(path), item.line, item.col)))
                continue
            files.append(target)
    return files


def project_references(path: Path) -> list[str]:
    """The namespaces of the libraries a project references (its .plcproj's
    PlaceholderReference and LibraryReference items), for naming the ones not at hand."""
    if path.is_dir():
        projects = [p for p in listing(path) if p.suffix.lower() == ".plcproj"]
        if len(projects) != 1:
            return []
        path = projects[0]
    if path.suffix.lower() != ".plcproj":
        return []
    root = parse_xml(read_source(path), str(path), "Project", "a TwinCAT .plcproj file")
    out = []
    for group in root.findall("ItemGroup"):
        for item in group.children:
            if item.tag in ("PlaceholderReference", "LibraryReference"):
                ns = item.find("Namespace")
                name = (ns.all_text()[0] if ns is not None else "").strip() or \
                    item.attrib.get("Include", "").split(",")[0].strip()
                if name:
                    out.append(name)
    return out


def read_source(path: Path) -> str:
    """A program file's text: by its byte order mark (UTF-8, UTF-16, UTF-32), else its XML
    declaration's encoding, else UTF-8, and Latin-1 where that fails, as older tools
    write. Only a regular file of at most :data:`.files.MAX_FILE_BYTES` is read, and
    while a load is confined (:func:`.files.confined_to`), only one under its folders."""
    return read_confined_source(path)
