"""FBD and LD bodies of a PLCopen XML file (TC6 v2.01, as Beremiz, OpenPLC and CODESYS
export them) as IR statements, so that a graphical POU runs like its ST equivalent.

A graphical body is a graph: elements with a ``localId`` whose ``connectionPointIn``s name
the element (and, for a block, the output pin) they read. Its ST equivalent, as IEC
61131-3 (ed.3, 4.3 and 8.1.4) describes the evaluation of a network:

* *sinks* become statements: an ``outVariable`` or an ``inOutVariable`` with an input is
  an assignment, a coil assigns its power flow (``S``/``R`` storage sets or resets it, a
  negated coil assigns the complement), a function block instance is called once with
  its connected inputs, a ``jump`` or ``return`` fed by a condition is an ``IF``;
* *sources* become expressions: a variable, a block's output pin (``inst.Q``), a function
  or operator applied to its inputs, a contact (``power AND var``, the complement when
  negated), the left power rail (``TRUE``); several connections into one input are a
  wired OR (LD parallel branches);
* sinks run in the order the file gives (``executionOrderId``), else top to bottom and
  left to right as drawn; an element another sink reads (an instance's output, an
  ``inOutVariable``, a coil) runs first, so a network computes before it is used; a
  feedback loop reads the variable or instance output as the previous scan left it;
* an edge-detecting contact, coil or input pin gets its own ``R_TRIG``/``F_TRIG``
  instance, declared in the POU under a name no user name takes.

What cannot be converted (a jump into another network's middle is fine; an unknown
element, a dangling connection, a function's second output) raises :class:`GraphError`,
which the reader turns into an opaque body: the project loads, and only running that body
is an error that says why.
"""
from __future__ import annotations

from . import ir

# operators drawn as blocks: n-ary folds, binary ones, chained comparisons
_FOLD = {"ADD": "+", "MUL": "*", "AND": "AND", "OR": "OR", "XOR": "XOR"}
_BINARY = {"SUB": "-", "DIV": "/", "MOD": "MOD", "EXPT": "**"}
_COMPARE = {"GT": ">", "GE": ">=", "EQ": "=", "LE": "<=", "LT": "<", "NE": "<>"}
MAX_NETWORK_DEPTH = 150   # elements chained in one network (the expression limit is 100)
# wires followed in converting one body: a value read twice is written out twice, so a
# file of blocks each read by two others (a diamond lattice) would double per level
MAX_NETWORK_WORK = 200_000


class GraphError(Exception):
    """A graphical body that cannot be converted, and the element that stops it."""

    def __init__(self, el, message: str):
        super().__init__(message)
        self.el = el
        self.message = message


def _position(el) -> tuple[float, float]:
    p = el.find("position")
    if p is None:
        return 0.0, 0.0
    try:
        return float(p.attrib.get("y", 0)), float(p.attrib.get("x", 0))
    except ValueError:
        return 0.0, 0.0


def _order(el) -> int:
    try:
        return int(el.attrib.get("executionOrderId", 0))
    except ValueError:
        return 0


def _true(el, name: str) -> bool:
    return el.attrib.get(name, "false").lower() in ("true", "1")


class Network:
    """One FBD or LD body (or the graphical part of an SFC) converted to statements.

    ``expr(node)`` parses the ST expression an element's ``<expression>`` or
    ``<variable>`` child holds (a variable name, a literal) at its position in the file;
    ``pos(el)`` gives an element's position;
    ``hidden(type_name)`` declares an edge-detecting instance in the owning POU and
    returns its name."""

    def __init__(self, elements, expr, pos, hidden):
        self.nodes = {}
        for el in elements:
            lid = el.attrib.get("localId")
            if lid is not None:
                self.nodes[lid] = el
        self._expr, self._pos, self._hidden = expr, pos, hidden
        self.connectors = {el.attrib.get("name"): el for el in elements
                           if el.tag == "connector"}
        self.stmts: list = []
        self._done: set[str] = set()       # sinks emitted
        self._running: set[str] = set()    # sinks being emitted (feedback stops here)
        self._trigs: dict[tuple[str, str], str] = {}
        self._depth = 0
        self._work = 0

    # ---------------------------------------------------------------- statements
    def statements(self) -> list:
        sinks = [el for el in self.nodes.values() if self._is_sink(el)]
        labels = [el for el in self.nodes.values() if el.tag == "label"]
        ordered = sorted(sinks + labels, key=lambda el: (
            (0, _order(el)) if _order(el) > 0 else (1, 0), *_position(el)))
        for el in ordered:
            if el.tag == "label":
                self.stmts.append(ir.Label(self._name_attr(el, "label"), pos=self._pos(el)))
            else:
                self._emit(el)
        return self.stmts

    def _is_sink(self, el) -> bool:
        if el.tag in ("outVariable", "coil", "jump", "return"):
            return True
        if el.tag == "inOutVariable":
            return self._connections(el, required=False) != []
        if el.tag == "block":
            return bool(el.attrib.get("instanceName"))
        return False

    def _emit(self, el) -> None:
        lid = el.attrib.get("localId")
        if lid in self._done or lid in self._running:
            return
        self._running.add(lid)
        pos = self._pos(el)
        if el.tag in ("outVariable", "inOutVariable"):
            value = self.value_into(el)
            if _true(el, "negated") or _true(el, "negatedIn"):
                value = ir.Unary("NOT", value, pos=pos)
            self.stmts.append(ir.Assign(self._variable(el, "expression"), value, pos=pos))
        elif el.tag == "coil":
            self._coil(el, pos)
        elif el.tag == "block":
            name = self._name_attr(el, "instanceName")
            args = self._block_args(el)
            self.stmts.append(ir.CallStmt(ir.Call(ir.Name(name, pos=pos), args, pos=pos),
                                          pos=pos))
        elif el.tag == "jump":
            jump = ir.Jmp(self._name_attr(el, "label"), pos=pos)
            self.stmts.append(self._when(el, [jump], pos))
        elif el.tag == "return":
            self.stmts.append(self._when(el, [ir.Return(pos=pos)], pos))
        self._running.discard(lid)
        self._done.add(lid)

    def _when(self, el, body, pos):
        if not self._connections(el, required=False):
            return body[0]
        return ir.If([(self.value_into(el), body)], pos=pos)

    def _coil(self, el, pos) -> None:
        power = self.value_into(el)
        target = self._variable(el, "variable")
        edge = el.attrib.get("edge", "none")
        if edge in ("rising", "falling"):
            power = self._trig(el, edge, power, pos)
        storage = el.attrib.get("storage", "none")
        if storage in ("set", "reset"):
            value = ir.Literal(storage == "set", "BOOL", pos=pos)
            self.stmts.append(ir.If([(power, [ir.Assign(target, value, pos=pos)])], pos=pos))
        else:
            if _true(el, "negated"):
                power = ir.Unary("NOT", power, pos=pos)
            self.stmts.append(ir.Assign(target, power, pos=pos))

    def _trig(self, el, edge: str, signal, pos):
        """``signal`` through an R_TRIG (rising) or F_TRIG (falling) instance of its own,
        called where the network computes it; its ``Q`` is the edge."""
        key = (el.attrib.get("localId", ""), edge)
        name = self._trigs.get(key)
        if name is None:
            name = self._hidden("R_TRIG" if edge == "rising" else "F_TRIG")
            self._trigs[key] = name
            call = ir.Call(ir.Name(name, pos=pos), [ir.Arg("CLK", signal, pos=pos)], pos=pos)
            self.stmts.append(ir.CallStmt(call, pos=pos))
        return ir.Member(ir.Name(name, pos=pos), "Q", pos=pos)

    # ---------------------------------------------------------------- expressions
    def _connections(self, el, required=True) -> list:
        cpi = el.find("connectionPointIn")
        conns = cpi.findall("connection") if cpi is not None else []
        if not conns and required:
            raise GraphError(el, f"{el.tag} is not connected")
        return conns

    def value_into(self, el):
        """The value flowing into ``el`` (any element with a ``connectionPointIn``, a
        transition's ``<condition>`` drawn in a chart too): its connections, ORed (a
        wired OR). What it needs to run first (an instance, an edge) is added to
        :attr:`stmts`."""
        value = None
        for conn in self._connections(el):
            v = self._source(conn)
            value = v if value is None else ir.Binary("OR", value, v, pos=self._pos(el))
        return value

    def _source(self, conn):
        ref = conn.attrib.get("refLocalId")
        el = self.nodes.get(ref)
        if el is None:
            raise GraphError(conn, f"connection to unknown localId {ref!r}")
        self._depth += 1
        self._work += 1
        if self._depth > MAX_NETWORK_DEPTH:
            raise GraphError(el, f"network deeper than {MAX_NETWORK_DEPTH} elements")
        if self._work > MAX_NETWORK_WORK:
            raise GraphError(el, f"network too large to convert (more than "
                                 f"{MAX_NETWORK_WORK:,} wires followed)")
        try:
            return self._value(el, conn.attrib.get("formalParameter") or None)
        finally:
            self._depth -= 1

    def _value(self, el, pin: str | None):
        pos = self._pos(el)
        tag = el.tag
        if tag == "inVariable":
            v = self._variable(el, "expression")
            return ir.Unary("NOT", v, pos=pos) if _true(el, "negated") else v
        if tag == "inOutVariable":
            if self._connections(el, required=False):
                self._emit(el)       # written before it is read (unless in a loop)
            v = self._variable(el, "expression")
            return ir.Unary("NOT", v, pos=pos) if _true(el, "negatedOut") else v
        if tag == "leftPowerRail":
            return ir.Literal(True, "BOOL", pos=pos)
        if tag == "contact":
            var = self._variable(el, "variable")
            edge = el.attrib.get("edge", "none")
            if edge in ("rising", "falling"):
                var = self._trig(el, edge, var, pos)
            elif _true(el, "negated"):
                var = ir.Unary("NOT", var, pos=pos)
            return ir.Binary("AND", self.value_into(el), var, pos=pos)
        if tag == "coil":
            self._emit(el)
            return self.value_into(el)   # power flows on through a coil
        if tag == "continuation":
            connector = self.connectors.get(el.attrib.get("name"))
            if connector is None:
                raise GraphError(el, f"continuation {el.attrib.get('name')!r} has no "
                                     "connector of that name")
            return self.value_into(connector)
        if tag == "block":
            return self._block_value(el, pin, pos)
        raise GraphError(el, f"a {tag} element does not give a value")

    def _block_value(self, el, pin, pos):
        if pin is not None and pin.upper() == "ENO":
            # ENO is TRUE when the block ran (EN TRUE or open): plcpred's blocks do not
            # fail, so it is the block's EN
            if el.attrib.get("instanceName"):
                self._emit(el)
            en = next((v for v in self._pins(el, "inputVariables")
                       if v.attrib.get("formalParameter", "").upper() == "EN"
                       and self._connections(v, required=False)), None)
            return self.value_into(en) if en is not None else ir.Literal(True, "BOOL", pos=pos)
        outputs = self._pins(el, "outputVariables")
        if not outputs:
            raise GraphError(el, f"block {el.attrib.get('typeName')!r} has no output")
        names = [o.attrib.get("formalParameter", "") for o in outputs]
        chosen = outputs[0] if pin is None else next(
            (o for o, n in zip(outputs, names) if n.upper() == pin.upper()), None)
        if chosen is None:
            raise GraphError(el, f"block {el.attrib.get('typeName')!r} has no output "
                                 f"{pin!r}")
        negate = _true(chosen, "negated")
        instance = el.attrib.get("instanceName")
        if instance:
            self._emit(el)
            v = ir.Member(ir.Name(self._name_attr(el, "instanceName"), pos=pos),
                          chosen.attrib.get("formalParameter", ""), pos=pos)
        else:
            if chosen is not outputs[0] and names[0].upper() not in ("ENO",):
                raise GraphError(el, f"output {pin!r} of function "
                                     f"{el.attrib.get('typeName')!r}: only a function's "
                                     "result can be read")
            v = self._function(el, pos)
        return ir.Unary("NOT", v, pos=pos) if negate else v

    def _function(self, el, pos):
        type_name = el.attrib.get("typeName", "")
        args = self._block_args(el)
        if any(a.output for a in args):
            raise GraphError(el, f"function {type_name!r} with bound outputs")
        op = type_name.upper()
        plain = [a.value for a in args if (a.name or "").upper() != "EN"]
        has_en = len(plain) != len(args)
        if not has_en and plain:
            if op in _FOLD and len(plain) >= 2:
                v = plain[0]
                for x in plain[1:]:
                    v = ir.Binary(_FOLD[op], v, x, pos=pos)
                return v
            if op in _BINARY and len(plain) == 2:
                return ir.Binary(_BINARY[op], plain[0], plain[1], pos=pos)
            if op in _COMPARE and len(plain) >= 2 and (op != "NE" or len(plain) == 2):
                v = None
                for a, b in zip(plain, plain[1:]):
                    c = ir.Binary(_COMPARE[op], a, b, pos=pos)
                    v = c if v is None else ir.Binary("AND", v, c, pos=pos)
                return v
            if op == "NOT" and len(plain) == 1:
                return ir.Unary("NOT", plain[0], pos=pos)
            if op == "MOVE" and len(plain) == 1:
                return plain[0]
        return ir.Call(ir.Name(self._name_attr(el, "typeName"), pos=pos), args, pos=pos)

    def _pins(self, el, group: str) -> list:
        g = el.find(group)
        return g.findall("variable") if g is not None else []

    def _block_args(self, el) -> list:
        args = []
        for var in self._pins(el, "inputVariables") + self._pins(el, "inOutVariables"):
            if not self._connections(var, required=False):
                continue           # left open: the pin keeps its default
            formal = var.attrib.get("formalParameter", "")
            pos = self._pos(var)
            value = self.value_into(var)
            edge = var.attrib.get("edge", "none")
            if edge in ("rising", "falling"):
                value = self._trig(var, edge, value, pos)
            elif _true(var, "negated"):
                value = ir.Unary("NOT", value, pos=pos)
            args.append(ir.Arg(formal, value, pos=pos))
        return args

    # ---------------------------------------------------------------- names
    def _variable(self, el, child: str):
        node = el.find(child)
        if node is None:
            raise GraphError(el, f"{el.tag} without <{child}>")
        text = node.all_text()[0].strip()
        if not text:
            raise GraphError(node, f"{el.tag} with an empty <{child}>")
        return self._expr(node)

    def _name_attr(self, el, attr: str) -> str:
        value = (el.attrib.get(attr) or "").strip()
        if not value:
            raise GraphError(el, f"{el.tag} without {attr}")
        return value      # checked as an identifier with the rest of the program
