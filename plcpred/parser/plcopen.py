"""PLCopen XML (TC6, v2.01 and the v2.00 dialect CODESYS/TwinCAT/Beremiz export) import.

Converts data types, global variables, configurations with resources and tasks, and POUs
whose bodies are ST, FBD or LD (:mod:`.graphical`) or SFC (steps, transitions with inline
or referenced ST, FBD or LD conditions, action blocks, selection/simultaneous divergence
and convergence, jumps) into the IR. An IL body, or a graphical one that cannot be
converted, is kept opaque: the project loads, and running it is an error that says why.
ST text is parsed with its true position in the XML file, so errors point at the file's
line and column.
"""
from __future__ import annotations

import dataclasses
import re

from . import ir
from .build import make_action_assoc
from .errors import ProgramError, at
from .graphical import GraphError, Network
from .names import validate_names
from .shipped import shipped_string_kind
from .st import parse_st
from .xmltree import XmlElement, parse_xml

ELEMENTARY = {"BOOL", "BYTE", "WORD", "DWORD", "LWORD", "SINT", "INT", "DINT", "LINT",
              "USINT", "UINT", "UDINT", "ULINT", "REAL", "LREAL", "TIME", "LTIME", "DATE",
              "DT", "TOD", "LDATE", "LDT", "LTOD", "CHAR", "WCHAR"}
_VAR_KINDS = {"localVars": "VAR", "inputVars": "VAR_INPUT", "outputVars": "VAR_OUTPUT",
              "inOutVars": "VAR_IN_OUT", "externalVars": "VAR_EXTERNAL",
              "globalVars": "VAR_GLOBAL", "tempVars": "VAR_TEMP", "accessVars": "VAR_ACCESS"}
_POU_KINDS = {"program": "PROGRAM", "functionBlock": "FUNCTION_BLOCK", "function": "FUNCTION"}


_XSD_DURATION = re.compile(r"P(?:(?P<d>\d+(?:\.\d+)?)D)?T?(?:(?P<h>\d+(?:\.\d+)?)H)?"
                           r"(?:(?P<m>\d+(?:\.\d+)?)M)?(?:(?P<s>\d+(?:\.\d+)?)S)?")
_CLOCK = re.compile(r"(?P<d>)(?P<h>\d{1,2}):(?P<m>\d{1,2}):(?P<s>\d{1,2}(?:\.\d+)?)")
_WHOLE = re.compile(r"[+-]?[0-9]{1,12}")   # ASCII digits: int() refuses '²', isdigit() not
def _place(node, pos: ir.Pos) -> None:
    """Give every node of a parsed attribute value the position of its element."""
    stack = [node]
    while stack:
        n = stack.pop()
        if isinstance(n, list):
            stack.extend(n)
        elif dataclasses.is_dataclass(n):
            for f in dataclasses.fields(n):
                v = getattr(n, f.name)
                if f.name == "pos":
                    setattr(n, "pos", pos)
                elif isinstance(v, list) or dataclasses.is_dataclass(v):
                    stack.append(v)


_SFC_PASSTHROUGH = {"selectionDivergence", "selectionConvergence", "simultaneousDivergence",
                    "simultaneousConvergence"}


def _number_selection_priorities(transitions: list) -> None:
    """Selection divergence: a transition's order among those leaving the same steps,
    where the file gives none."""
    by_source: dict[tuple, list[ir.Transition]] = {}
    for t in transitions:
        by_source.setdefault(tuple(t.sources), []).append(t)
    for group in by_source.values():
        if all(t.priority == 0 for t in group):
            for i, t in enumerate(group):
                t.priority = i


class PlcopenImporter:
    def __init__(self, filename: str):
        self.file = filename
        self._hidden: list[ir.VarDecl] = []   # edge instances the POU's networks need
        self._taken: set[str] = set()          # names declared in the POU being read
        self._chart_networks: dict[int, Network] = {}   # an SFC's drawn conditions
        # upper-case names of the project's derived types that are strings ("S": STRING,
        # "W": WSTRING), and of all the types it declares
        self._string_types: dict[str, str] = {}
        self._declared: set[str] = set()
        # Beremiz and OpenPLC write a string's initial value without quotes; CODESYS and
        # TwinCAT quote it, so a bare name there is a constant's
        self._bare_strings = True

    def error(self, el: XmlElement, message: str) -> ProgramError:
        return ProgramError(message, self.file, el.line, el.col)

    def req(self, el: XmlElement, name: str) -> str:
        """A required attribute, or an error at the element that lacks it."""
        try:
            return el.attrib[name]
        except KeyError:
            raise self.error(el, f"<{el.tag}> needs a '{name}' attribute") from None

    def type_name(self, pi: XmlElement) -> str:
        """A pouInstance's typeName; CODESYS leaves it empty when the instance is named
        after its PROGRAM."""
        return pi.attrib.get("typeName") or self.req(pi, "name")

    def int_attr(self, el: XmlElement, name: str, default: int, low: int = 0,
                 high: int = 1 << 31) -> int:
        """An optional whole-number attribute in [low, high], or an error naming it."""
        text = (el.attrib.get(name) or "").strip()
        if not text:
            return default
        if not _WHOLE.fullmatch(text) or not low <= int(text) <= high:
            raise self.error(el, f"<{el.tag}> attribute {name}={text[:40]!r}: expected a "
                                 f"whole number {low}..{high}")
        return int(text)

    # ------------------------------------------------------------------ ST fragments
    def _fragment(self, header: str, text: str, line: int, col: int, footer: str):
        """The program of ST text ``text`` that stands at ``line``:``col`` of the file,
        after a header of ours: positions as in the file, from the tokenizer's origin
        (padding it with as many lines and spaces would be quadratic in the file's
        size)."""
        if line < 1:
            return parse_st(f"{header} {text}{footer}", self.file)
        return parse_st(f"{header}\n{text}{footer}", self.file, origin=(2, line, col))

    def st_body(self, el: XmlElement) -> list:
        text, line, col = el.all_text()
        return self._fragment("PROGRAM __plcopen_body", text, line, col,
                              "\nEND_PROGRAM").pous[0].body

    def st_expr(self, el: XmlElement):
        text, line, col = el.all_text()
        return self.expr_text(text, line, col)

    def expr_text(self, text: str, line: int = 0, col: int = 1):
        return self._fragment("PROGRAM __plcopen_expr __x :=", text, line, col,
                              "\n;END_PROGRAM").pous[0].body[0].value

    def interval(self, el: XmlElement, value: str):
        """A task interval: an ST TIME literal (``T#50ms``) or, as the PLCopen schema types
        it, an xsd:duration (``PT0.05S``) or a clock time (``00:00:00.1``)."""
        text = value.strip()
        m = _XSD_DURATION.fullmatch(text) or _CLOCK.fullmatch(text)
        if m is None:
            return self.value_text(el, value)
        d, h, mi, s = (float(m.group(g) or 0) for g in ("d", "h", "m", "s"))
        ns = round((((d * 24 + h) * 60 + mi) * 60 + s) * 1e9)
        if not 0 < ns < 10**15:
            raise self.error(el, f"task interval {value[:40]!r} is not a positive duration "
                                 "below 11 days")
        return ir.Literal(ns, "TIME", pos=ir.Pos(self.file, el.line, el.col))

    def value_text(self, el: XmlElement, value: str):
        """An attribute's ST value; its nodes point at the element that holds it."""
        try:
            expr = self.expr_text(value, 0)
        except ProgramError as e:
            raise self.error(el, f"bad value {value!r}: {e.message}") from None
        _place(expr, ir.Pos(self.file, el.line, el.col))
        return expr

    # ------------------------------------------------------------------ types
    def type_of(self, el: XmlElement | None, where: XmlElement) -> ir.TypeRef:
        if el is None or not el.children:
            raise self.error(where, "missing <type>")
        t = el.children[0]
        tag = t.tag
        here = ir.Pos(self.file, t.line, t.col)
        if tag.upper() in ELEMENTARY:
            return ir.NamedType(tag.upper(), pos=here)
        if tag.lower() in ("string", "wstring"):  # TC6 writes them lower case; some tools don't
            # a number, or a constant's name (CODESYS writes STRING(MAX_LEN) so)
            length = (t.attrib.get("length") or "").strip()
            return ir.StringType(tag.lower() == "wstring",
                                 self.value_text(t, length) if length else None)
        if tag == "derived":
            return ir.NamedType(self.req(t, "name"), pos=here)
        if tag == "array":
            dims = []
            for d in t.findall("dimension"):
                dims.append((self.value_text(d, self.req(d, "lower")),
                             self.value_text(d, self.req(d, "upper"))))
            return ir.ArrayType(dims, self.type_of(t.find("baseType"), t))
        if tag == "pointer":
            return ir.PointerType(self.type_of(t.find("baseType"), t))
        if tag in ("subrangeSigned", "subrangeUnsigned"):
            rng = t.find("range")
            if rng is None:
                raise self.error(t, f"<{tag}> needs a <range lower=... upper=...> element")
            base = self.type_of(t.find("baseType"), t)
            return ir.SubrangeType(base.name, self.value_text(rng, self.req(rng, "lower")),
                                   self.value_text(rng, self.req(rng, "upper")))
        if tag == "enum":
            values = []
            for v in t.find("values").findall("value") if t.find("values") else []:
                val = v.attrib.get("value")
                values.append((self.req(v, "name"), self.value_text(v, val) if val else None))
            base = t.find("baseType")
            return ir.EnumType(values, self.type_of(base, t).name if base is not None else None)
        if tag == "struct":
            return ir.StructType(self.variables(t, None))
        raise self.error(t, f"cannot convert data type <{tag}>")

    def string_kind(self, t: ir.TypeRef) -> str | None:
        """"S" (STRING) or "W" (WSTRING) when ``t`` is a string type, directly or as a
        derived type the project or a shipped library declares so; else None."""
        if isinstance(t, ir.StringType):
            return "W" if t.wide else "S"
        if not isinstance(t, ir.NamedType):
            return None
        up = t.name.upper()
        if up in self._string_types or up in self._declared or up in ELEMENTARY:
            return self._string_types.get(up)
        # a stub's string alias (Beremiz SVGHMI's HMI_STRING), from the stubs' index
        return shipped_string_kind(up)

    def simple_value(self, el: XmlElement, text: str, t: ir.TypeRef | None):
        """An initial value written as text, for a variable of type ``t``."""
        quote = {"S": "'", "W": '"'}.get(self.string_kind(t)) \
            if self._bare_strings and t is not None else None
        if quote and not (text.startswith(quote) or text.endswith(quote)):
            # Beremiz writes a string's initial value bare (value="test") and quotes it
            # when it generates ST (PLCGenerator.ComputeValue): so do we
            text = quote + text.replace("$", "$$").replace(quote, "$" + quote) + quote
        return self.value_text(el, text)

    def init_of(self, el: XmlElement | None, t: ir.TypeRef | None = None):
        if el is None or not el.children:
            return None
        v = el.children[0]
        if v.tag == "simpleValue":
            return self.simple_value(v, v.attrib.get("value", ""), t)
        if v.tag == "arrayValue":
            items = []
            for item in v.findall("value"):
                count = self.int_attr(item, "repetitionValue", 1, 0, 1 << 24)
                items.append((count, self.init_of(item)))
            return ir.ArrayInit(items)
        if v.tag == "structValue":
            return ir.StructInit([(self.req(item, "member"), self.init_of(item))
                                  for item in v.findall("value")])
        raise self.error(v, f"cannot convert initial value <{v.tag}>")

    def variables(self, el: XmlElement, kind: str | None) -> list[ir.VarDecl]:
        out = []
        for v in el.findall("variable"):
            t = self.type_of(v.find("type"), v)
            out.append(ir.VarDecl(self.req(v, "name"), t,
                                  self.init_of(v.find("initialValue"), t),
                                  v.attrib.get("address"),
                                  pos=ir.Pos(self.file, v.line, v.col)))
        return out

    def var_blocks(self, iface: XmlElement | None) -> list[ir.VarBlock]:
        blocks = []
        if iface is None:
            return blocks
        for child in iface.children:
            kind = _VAR_KINDS.get(child.tag)
            if kind is None:
                continue
            qualifiers = [q.upper() for q in ("constant", "retain", "persistent")
                          if child.attrib.get(q) in ("true", "1")]
            if child.attrib.get("nonretain") in ("true", "1"):
                qualifiers.append("NON_RETAIN")
            blocks.append(ir.VarBlock(kind, self.variables(child, kind), qualifiers,
                                      pos=ir.Pos(self.file, child.line, child.col)))
        return blocks

    # ------------------------------------------------------------------ POUs
    def body_of(self, pou_el: XmlElement, body: XmlElement | None, pou_name: str):
        if body is None:
            return []
        for lang in body.children:
            if lang.tag == "ST":
                return self.st_body(lang)
            if lang.tag == "SFC":
                return self.sfc(lang, pou_el)
            if lang.tag in ("FBD", "LD"):
                try:
                    return self.network(lang.children).statements()
                except GraphError as e:
                    # kept, not run: the project loads; only running this body is an error
                    return [ir.Opaque(f"the {lang.tag} body of POU '{pou_name}' "
                                      f"({e.message}, line {e.el.line})",
                                      pos=ir.Pos(self.file, lang.line, lang.col))]
            if lang.tag == "IL":
                return [ir.Opaque(f"the IL body of POU '{pou_name}'",
                                  pos=ir.Pos(self.file, lang.line, lang.col))]
        return []

    def network(self, elements) -> Network:
        """A graphical network of the POU being read (:mod:`.graphical`)."""
        def expr(node):
            text, line, col = node.all_text()
            return self.expr_text(text.strip(), line, col)

        return Network(elements, expr, lambda el: ir.Pos(self.file, el.line, el.col),
                       self._hidden_instance)

    def chart_network(self, sfc_el: XmlElement) -> Network:
        """The graphical elements drawn in an SFC (one network for all its conditions,
        so that a block two conditions read runs once)."""
        net = self._chart_networks.get(id(sfc_el))
        if net is None:
            net = self._chart_networks[id(sfc_el)] = self.network(sfc_el.children)
        return net

    def _hidden_name(self, kind: str) -> str:
        """A name the POU being read does not use, for what a network needs."""
        n = 1
        while f"_NETWORK_{kind}_{n}" in self._taken:
            n += 1
        name = f"_NETWORK_{kind}_{n}"
        self._taken.add(name)
        return name

    def _hidden_instance(self, type_name: str) -> str:
        """Declare an edge-detecting instance a network needs."""
        name = self._hidden_name(type_name)
        self._hidden.append(ir.VarDecl(name, ir.NamedType(type_name)))
        return name

    def pou(self, el: XmlElement) -> ir.Pou:
        name = self.req(el, "name")
        kind = _POU_KINDS.get(el.attrib.get("pouType", ""))
        if kind is None:
            raise self.error(el, f"POU '{name}': unknown pouType "
                                 f"{el.attrib.get('pouType')!r}")
        iface = el.find("interface")
        ret = None
        if iface is not None and iface.find("returnType") is not None:
            ret = self.type_of(iface.find("returnType"), iface)
        self._hidden = []
        self._taken = {v.attrib.get("name", "").upper()
                       for tag in ("variable", "action", "transition") for v in el.iter(tag)}
        actions = []
        acts = el.find("actions")
        for a in acts.findall("action") if acts is not None else []:
            actions.append(ir.SfcAction(self.req(a, "name"),
                                        self.body_of(el, a.find("body"), name) or [],
                                        pos=ir.Pos(self.file, a.line, a.col)))
        body = self.body_of(el, el.find("body"), name)
        pou = ir.Pou(kind, name, self.var_blocks(iface), body, return_type=ret,
                     pos=ir.Pos(self.file, el.line, el.col))
        # CODESYS and TwinCAT export a function block's methods as vendor data
        for add in el.findall("addData"):
            for m in add.iter("Method"):
                m_iface = m.find("interface")
                m_ret = None
                if m_iface is not None and m_iface.find("returnType") is not None:
                    m_ret = self.type_of(m_iface.find("returnType"), m_iface)
                pou.methods.append(ir.Method(self.req(m, "name"), m_ret,
                                             self.var_blocks(m_iface),
                                             self.body_of(el, m.find("body"), name) or [],
                                             pos=ir.Pos(self.file, m.line, m.col)))
        if isinstance(body, ir.Sfc):
            body.actions.extend(actions)
        else:
            pou.actions = actions
        if self._hidden:
            pou.var_blocks.append(ir.VarBlock("VAR", self._hidden))
        return pou

    # ------------------------------------------------------------------ SFC
    def sfc(self, sfc_el: XmlElement, pou_el: XmlElement) -> ir.Sfc:
        nodes, preds, succs = self._sfc_graph(sfc_el)
        steps = self._sfc_steps(nodes, sfc_el, pou_el)
        step_names = {s.name for s in steps.values()}
        transitions_el = pou_el.find("transitions")
        named_conditions = {self.req(t, "name"): t for t in transitions_el.findall("transition")
                            } if transitions_el is not None else {}
        transitions = []
        extra_actions = []
        for lid, el in nodes.items():
            if el.tag == "transition":
                sources = self._sfc_reach(lid, preds, nodes, steps, step_names)
                targets = self._sfc_reach(lid, succs, nodes, steps, step_names)
                if not sources or not targets:
                    raise self.error(el, "transition is not connected to steps on both sides")
                cond = self.condition(el, named_conditions, sfc_el)
                prio = self.int_attr(el, "priority", 0, -(1 << 31))
                transitions.append(ir.Transition(sources, targets, cond, prio,
                                                 pos=ir.Pos(self.file, el.line, el.col)))
            elif el.tag == "actionBlock":
                owners = [p for p in preds[lid] if p in steps]
                if len(owners) != 1:
                    raise self.error(el, "action block must be connected to one step")
                step = steps[owners[0]]
                for n, a in enumerate(el.findall("action")):
                    step.actions.append(self.action_assoc(a, step, n, extra_actions))
        self._sfc_drawn_conditions(sfc_el, list(steps.values()), extra_actions)
        _number_selection_priorities(transitions)
        return ir.Sfc(list(steps.values()), transitions, extra_actions,
                      pos=ir.Pos(self.file, sfc_el.line, sfc_el.col))

    def _sfc_graph(self, sfc_el: XmlElement):
        """(localId -> element, localId -> the ids it is connected from, localId -> the
        ids connected from it) of a chart."""
        nodes: dict[str, XmlElement] = {}
        for child in sfc_el.children:
            if "localId" in child.attrib:
                nodes[self.req(child, "localId")] = child
        preds: dict[str, list[str]] = {k: [] for k in nodes}
        succs: dict[str, list[str]] = {k: [] for k in nodes}
        for lid, el in nodes.items():
            for cpi in el.findall("connectionPointIn"):
                for conn in cpi.findall("connection"):
                    ref = conn.attrib.get("refLocalId")
                    if ref not in nodes:
                        raise self.error(conn, f"connection to unknown localId {ref!r}")
                    preds[lid].append(ref)
                    succs[ref].append(lid)
        return nodes, preds, succs

    def _sfc_steps(self, nodes: dict, sfc_el: XmlElement, pou_el: XmlElement) -> dict:
        """localId -> step, in the file's order; exactly one of them initial."""
        steps = {}
        for lid, el in nodes.items():
            if el.tag == "step":
                steps[lid] = ir.Step(self.req(el, "name"), el.attrib.get("initialStep") == "true",
                                     pos=ir.Pos(self.file, el.line, el.col))
        if sum(s.initial for s in steps.values()) != 1:
            raise self.error(sfc_el, f"SFC of POU '{pou_el.attrib.get('name')}' needs exactly "
                                     "one initial step")
        return steps

    def _sfc_reach(self, start: str, edges: dict, nodes: dict, steps: dict,
                   step_names: set) -> list[str]:
        """The steps (and jump targets) reached from ``start`` along ``edges``, through
        divergence and convergence nodes: depth first, iteratively (a file may chain any
        number of them)."""
        found: list[str] = []
        seen: set = set()
        pending = [iter(edges[start])]
        while pending:
            nxt = next(pending[-1], None)
            if nxt is None:
                pending.pop()
                continue
            if nxt in seen:
                continue
            seen.add(nxt)
            el = nodes[nxt]
            if el.tag == "step":
                found.append(steps[nxt].name)
            elif el.tag == "jumpStep":
                target = el.attrib.get("targetName")
                if target not in step_names:
                    raise self.error(el, f"jump to unknown step {target!r}")
                found.append(target)
            elif el.tag in _SFC_PASSTHROUGH:
                pending.append(iter(edges[nxt]))
        return found

    def _sfc_drawn_conditions(self, sfc_el: XmlElement, steps: list, extra_actions: list):
        """The blocks the chart's drawn conditions use: an action every step runs (so
        once in every scan of the chart)."""
        net = self._chart_networks.pop(id(sfc_el), None)
        if net is not None and net.stmts:
            name = self._hidden_name("ACTION")
            pos = ir.Pos(self.file, sfc_el.line, sfc_el.col)
            extra_actions.append(ir.SfcAction(name, net.stmts, pos=pos))
            for step in steps:
                step.actions.insert(0, ir.ActionAssoc(name, "N", pos=pos))

    def condition(self, el: XmlElement, named: dict, sfc_el: XmlElement):
        cond = el.find("condition")
        if cond is None:
            raise self.error(el, "transition without a condition")
        for c in cond.children:
            if c.tag == "inline":
                st = c.find("ST")
                if st is not None:
                    return self.st_expr(st)
                return self.graph_condition(c, c.attrib.get("name", ""))
            if c.tag == "reference":
                name = self.req(c, "name")
                t = named.get(name)
                if t is None:
                    raise self.error(c, f"reference to unknown transition {name!r}")
                body = t.find("body")
                st = body.find("ST") if body is not None else None
                if st is None:
                    return self.graph_condition(body if body is not None else t, name)
                text, line, col = st.all_text()
                if ":=" in text:  # CODESYS style: 'Name := expression;'
                    stmts = self.st_body(st)
                    assigns = [s for s in stmts if isinstance(s, ir.Assign)]
                    if len(assigns) != 1:
                        raise self.error(st, f"transition {name!r}: expected one assignment")
                    return assigns[0].value
                return self.st_expr(st)
            if c.tag == "connectionPointIn":
                # Beremiz: the condition is drawn in the SFC itself (contacts, blocks);
                # what its blocks must run (timers, edges) runs in every scan of the
                # chart, before the condition is read (see sfc())
                net = self.chart_network(sfc_el)
                try:
                    return net.value_into(cond)
                except GraphError as e:
                    raise self.error(e.el, f"transition condition: {e.message}") from None
        raise self.error(cond, "transition condition in a form plcpred does not read "
                               "(expected inline, referenced or connected)")

    def graph_condition(self, holder: XmlElement, name: str):
        """The condition an FBD or LD transition body computes: the value it assigns to
        the transition's name (or its only assignment)."""
        lang = next((c for c in holder.children if c.tag in ("FBD", "LD")), None)
        if lang is None:
            raise self.error(holder, f"transition {name!r}: its condition must be ST, FBD "
                                     "or LD")
        try:
            stmts = self.network(lang.children).statements()
        except GraphError as e:
            raise self.error(e.el, f"transition {name!r}: {e.message}") from None
        assigns = [s for s in stmts if isinstance(s, ir.Assign)]
        mine = [s for s in assigns if isinstance(s.target, ir.Name)
                and s.target.name.upper() == name.upper()] or assigns
        if len(mine) != 1 or len(stmts) != 1:
            raise self.error(lang, f"transition {name!r}: expected a network that only "
                                   "computes the condition (one output)")
        return mine[0].value

    def action_assoc(self, a: XmlElement, step: ir.Step, n: int, extra: list) -> ir.ActionAssoc:
        qualifier = a.attrib.get("qualifier", "N")
        rest = []
        if a.attrib.get("duration"):
            rest.append(self.value_text(a, self.req(a, "duration")))
        if a.attrib.get("indicator"):
            rest.append(ir.Name(self.req(a, "indicator")))
        ref = a.find("reference")
        if ref is not None:
            name = self.req(ref, "name")
        else:
            inline = a.find("inline")
            st = inline.find("ST") if inline is not None else None
            if st is None:
                raise self.error(a, "only referenced or inline ST actions can be converted")
            name = f"{step.name}_action{n}"
            extra.append(ir.SfcAction(name, self.st_body(st), pos=ir.Pos(self.file, a.line, a.col)))

        return make_action_assoc(name, qualifier, rest, ir.Pos(self.file, a.line, a.col),
                                 lambda message, pos: at(pos, message))

    # ------------------------------------------------------------------ project
    def project(self, root: XmlElement) -> ir.Program:
        prog = ir.Program()
        header = root.find("fileHeader")
        product = (header.attrib.get("productName", "") if header is not None else "").lower()
        self._bare_strings = not any(v in product for v in ("codesys", "twincat"))
        types = root.find("types")
        if types is not None:
            dts = types.find("dataTypes")
            declared = [(self.req(dt, "name"), self.type_of(dt.find("baseType"), dt), dt)
                        for dt in (dts.findall("dataType") if dts is not None else [])]
            self._declared = {name.upper() for name, _, _ in declared}
            for _ in range(len(declared) if self._bare_strings else 0):   # aliases of aliases
                more = {name.upper(): self.string_kind(t) for name, t, _ in declared
                        if self.string_kind(t)}
                if more.keys() <= self._string_types.keys():
                    break
                self._string_types.update(more)
            for name, t, dt in declared:
                prog.types.append(ir.TypeDecl(name, t, self.init_of(dt.find("initialValue"), t),
                                              pos=ir.Pos(self.file, dt.line, dt.col)))
            pous = types.find("pous")
            for p in pous.findall("pou") if pous is not None else []:
                prog.pous.append(self.pou(p))
        config_globals = set()
        instances = root.find("instances")
        if instances is not None:
            cfgs = instances.find("configurations")
            for c in cfgs.findall("configuration") if cfgs is not None else []:
                prog.configurations.append(self.configuration(c))
                config_globals |= {id(g) for g in c.iter("globalVars")}
        # global variable lists kept elsewhere (CODESYS puts GVLs under addData)
        for g in root.iter("globalVars"):
            if id(g) in config_globals:
                continue
            block = ir.VarBlock("VAR_GLOBAL", self.variables(g, "VAR_GLOBAL"),
                                ["CONSTANT"] if g.attrib.get("constant") == "true" else [],
                                pos=ir.Pos(self.file, g.line, g.col))
            prog.globals.append(ir.GlobalVars(g.attrib.get("name"), block,
                                              pos=ir.Pos(self.file, g.line, g.col)))
        prog.source = self.file
        return prog

    def configuration(self, c: XmlElement) -> ir.Configuration:
        cfg = ir.Configuration(self.req(c, "name"), pos=ir.Pos(self.file, c.line, c.col))
        for g in c.findall("globalVars"):
            cfg.var_blocks.append(ir.VarBlock("VAR_GLOBAL", self.variables(g, "VAR_GLOBAL"),
                                              pos=ir.Pos(self.file, g.line, g.col)))
        for r in c.findall("resource"):
            res = ir.Resource(self.req(r, "name"), "PLC", pos=ir.Pos(self.file, r.line, r.col))
            for g in r.findall("globalVars"):
                res.var_blocks.append(ir.VarBlock("VAR_GLOBAL", self.variables(g, "VAR_GLOBAL"),
                                                  pos=ir.Pos(self.file, g.line, g.col)))
            for t in r.findall("task"):
                params = {}
                if t.attrib.get("interval"):
                    params["INTERVAL"] = self.interval(t, self.req(t, "interval"))
                if t.attrib.get("priority"):
                    params["PRIORITY"] = self.value_text(t, self.req(t, "priority"))
                if t.attrib.get("single"):
                    params["SINGLE"] = self.value_text(t, self.req(t, "single"))
                res.tasks.append(ir.Task(self.req(t, "name"), params,
                                         pos=ir.Pos(self.file, t.line, t.col)))
                for pi in t.findall("pouInstance"):
                    res.programs.append(ir.ProgramInstance(self.req(pi, "name"),
                                                           self.type_name(pi),
                                                           self.req(t, "name"),
                                                           pos=ir.Pos(self.file, pi.line, pi.col)))
            for pi in r.findall("pouInstance"):
                res.programs.append(ir.ProgramInstance(self.req(pi, "name"), self.type_name(pi),
                                                       pos=ir.Pos(self.file, pi.line, pi.col)))
            cfg.resources.append(res)
        return cfg


def parse_plcopen(text: str, filename: str = "<input>") -> ir.Program:
    """Import a PLCopen TC6 XML project into the IR."""
    return validate_names(PlcopenImporter(filename).project(parse_xml(text, filename)))
