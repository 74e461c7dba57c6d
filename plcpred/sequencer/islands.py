"""Independent parts of a program: islands of state that share no variable.

A line of stations written as ``FOR s := 0 TO 19 DO aStation[s](io := aIo[s]); END_FOR``
holds twenty machines in one program: station ``s`` reads and writes only
``aStation[s]`` and ``aIo[s]``. When each station's part sensor jitters on its own, the
line as a whole never rests in a state it rested in before, although every station
does. A scan is a function of the state, the inputs and the time; when the state splits
into parts that no statement connects, the scan is that function part by part, so each
part's signals depend only on its own state and its own inputs. The executor then runs
the program once per part with only that part's inputs scheduled (the other parts rest
and their signals are dropped), where each part repeats or replays on its own, and
merges the parts' edges by time (:meth:`Sequencer.run`).

The analysis is on the program text (the IR) and conservative: a cell is a variable of
a PROGRAM or a global, or one element of such an array where the first index is a
constant or the variable of a FOR loop with constant bounds (the loop is unrolled).
Statements at the top of a program body (and of an unrolled loop body) each connect the
cells they touch, a statement with its nested statements as one (a condition decides
what its branches write). A function block instance is one cell with all it holds; a
call connects it with its arguments and with every global any function block or
function reads or writes. A FOR variable written only by FOR loops with constant bounds
holds at any point of a scan a value fixed by that point, so it connects nothing.
Anything the analysis cannot follow (pointers, references, interfaces, direct
addresses in code, jumps, program parameters, programs called by name, tasks of
different intervals, VAR_STAT) gives a single island: the program runs whole.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field

from ..parser import ir
from ..parser.names import ident
from .compiler.common import int_constants
from .sfc import SfcRuntime


class _Bail(Exception):
    """The analysis cannot follow the program: one island."""


_KINDS = {"VAR", "VAR_INPUT", "VAR_OUTPUT", "VAR_IN_OUT", "VAR_TEMP", "VAR_EXTERNAL",
          "VAR_GLOBAL"}
# calls that hand out or write through addresses
_ADDRESS_CALLS = {"ADR", "ADRINST", "REF", "MEMCPY", "MEMMOVE", "MEMSET", "__NEW",
                  "__DELETE", "__QUERYINTERFACE", "__QUERYPOINTER"}
_SFC = "__SFC__"            # the attribute naming a program's SFC state as a cell


@dataclass
class Partition:
    """The islands of a program instance's state: ``cells`` maps each cell, ``(owner,
    attribute, element or None)`` with owner "G" (the globals) or a program instance's
    name, to its island number."""
    cells: dict = field(default_factory=dict)
    n: int = 0


class _Union:
    def __init__(self):
        self.parent: dict = {}

    def find(self, x):
        p = self.parent.setdefault(x, x)
        while p != x:
            self.parent[x] = self.parent.setdefault(p, p)
            x, p = p, self.parent[p]
        return p

    def join(self, items) -> None:
        items = iter(items)
        first = next(items, None)
        if first is None:
            return
        a = self.find(first)
        for b in items:
            b = self.find(b)
            if b != a:
                self.parent[b] = a


def find_islands(program: ir.Program, compiled, inst, constant=frozenset()
                 ) -> Partition | None:
    """The islands of ``inst`` (a :class:`ProgramInstance` of ``compiled``), or None when
    the program is one island or the analysis cannot follow it. ``constant``: cells that
    hold one value through the run (an input no schedule changes and the program never
    writes, such as a conveyor's run signal held high): reading one tells nothing, so
    it connects nothing."""
    try:
        return _Analysis(program, compiled, inst, constant).partition()
    except _Bail:
        return None


class _Analysis:
    def __init__(self, program, compiled, inst, constant=frozenset()):
        self.program, self.compiled, self.inst = program, compiled, inst
        self.constant = frozenset(constant)
        self.union = _Union()
        self.whole_touched: set = set()     # (owner, attr) accessed as a whole
        self.owners = {"G": inst.g}
        self.owners.update(zip(inst.names, inst.programs))
        self.globals = set(compiled.globals_types)
        self.constants = dict(int_constants(
            [g.block for g in program.globals]
            + [b for c in program.configurations for b in c.var_blocks]
            + [b for c in program.configurations for r in c.resources for b in r.var_blocks]))
        self.program_names = {p.name.upper() for p in program.pous if p.kind == "PROGRAM"}

    # ------------------------------------------------------------------ checks
    def _check_project(self) -> None:
        c = self.compiled
        if c.reads_clock or c.intervals and len(set(c.intervals.values())) > 1 \
                or self.program.interfaces:
            raise _Bail
        for conf in self.program.configurations:
            for r in conf.resources:
                if any(p.args for p in r.programs):
                    raise _Bail
        for x, _ in ir.nodes(self.program):
            if isinstance(x, (ir.Deref, ir.DirectAddress, ir.PointerType)):
                raise _Bail
            if isinstance(x, ir.VarBlock) and x.kind not in _KINDS:
                raise _Bail
            if isinstance(x, ir.Assign) and x.op == "REF=":
                raise _Bail
            if isinstance(x, ir.Call) and isinstance(x.func, ir.Name) \
                    and x.func.name.upper() in _ADDRESS_CALLS:
                raise _Bail
            if isinstance(x, ir.Name) and x.name.upper() in self.program_names:
                raise _Bail             # a program called or read by name
        for pou in self.program.pous:
            if pou.kind == "PROGRAM" and (pou.methods or pou.properties or pou.extends
                                          or pou.actions and not pou.is_sfc):
                raise _Bail
            if pou.kind == "PROGRAM" and any(isinstance(x, ir.Return)
                                             for x, _ in ir.nodes(pou.body)):
                raise _Bail             # the statements after it depend on its condition

    # ------------------------------------------------------------------ reach
    def _global_reach(self) -> set:
        """The global cells any function block or function (with its methods, properties
        and actions) reads or writes: a call of one may touch them."""
        out = set()
        for pou in self.program.pous:
            if pou.kind == "PROGRAM":
                continue
            local = {ident(d.name) for b in pou.var_blocks if b.kind != "VAR_EXTERNAL"
                     for d in b.decls}
            for m in pou.methods:
                local |= {ident(d.name) for b in m.var_blocks for d in b.decls}
            for p in pou.properties:
                for a in p.accessors:
                    local |= {ident(d.name) for b in a.var_blocks for d in b.decls}
            for x, _ in ir.nodes(pou):
                if isinstance(x, ir.Name):
                    k = x.name.upper()
                    if k in self.globals and k not in local:
                        out.add(("G", k, None))
        return out

    # ------------------------------------------------------------------ the analysis
    def partition(self) -> Partition | None:
        self._check_project()
        self.reach = self._global_reach()
        for name in self.inst.names:
            fbt = self.compiled.program_types[name]
            self._program(name, fbt)
        # a variable accessed as a whole joins its elements
        for owner, attr in self.whole_touched:
            value = getattr(self.owners[owner], attr)
            if isinstance(value, list):
                self.union.join([(owner, attr, None)]
                                + [(owner, attr, k) for k in range(len(value))])
        cells = self._all_cells()
        roots, out = {}, Partition()
        for c in cells:
            out.cells[c] = roots.setdefault(self.union.find(c), len(roots))
        out.n = len(roots)
        return out if out.n > 1 else None

    def _all_cells(self) -> list:
        cells = []
        for owner, obj in self.owners.items():
            for attr in _attributes(obj):
                value = getattr(obj, attr)
                cells.append((owner, attr, None))
                if isinstance(value, list):
                    cells += [(owner, attr, k) for k in range(len(value))]
            if getattr(obj, "_sfc", None) is not None:
                cells.append((owner, _SFC, None))
        return cells

    def _program(self, name: str, fbt) -> None:
        pou = fbt.pou
        scope = _Scope(name, fbt, self)
        if pou.is_sfc:
            group = {(name, _SFC, None)}
            self._touch_all([pou.body, pou.actions], scope, {}, group)
            self.union.join(group - self.constant or group)
            return
        for group in self._groups(pou.body, scope, {}):
            # a constant joins nothing (it stays a cell of its own unless touched alone)
            self.union.join(group - self.constant or group)

    def _groups(self, stmts, scope, env) -> list:
        out = []
        jumped = self._jumped(stmts)
        if jumped is not None:
            # the statements a forward JMP may skip depend on its condition: one group
            # from the jump to its label
            a, b = jumped
            group = set()
            self._touch_all(stmts[a:b + 1], scope, env, group)
            return self._groups(stmts[:a], scope, env) + [group] + \
                self._groups(stmts[b + 1:], scope, env)
        for st in stmts:
            if isinstance(st, ir.For) and self._unrollable(st, scope, env):
                lo, hi, step = (self._const(e, scope, env) for e in
                                (st.start, st.end, st.step or ir.Literal(1, "INT")))
                if step == 0 or len(range(lo, hi + (1 if step > 0 else -1), step)) > 10_000:
                    raise _Bail
                var = ident(st.var)
                for v in range(lo, hi + (1 if step > 0 else -1), step):
                    out += self._groups(st.body, scope, {**env, var: v})
                continue
            group = set()
            self._touch_all(st, scope, env, group)
            out.append(group)
        return out

    @staticmethod
    def _jumped(stmts):
        """(first, last) index of the statements from the first JMP in ``stmts`` that
        leaves its statement to the last label it reaches in ``stmts``, or None."""
        labels = {x.name.upper(): i for i, x in enumerate(stmts) if isinstance(x, ir.Label)}
        first = last = None
        for i, st in enumerate(stmts):
            inner = {x.name.upper() for x, _ in ir.nodes(st) if isinstance(x, ir.Label)}
            for x, _ in ir.nodes(st):
                if isinstance(x, ir.Jmp) and x.label.upper() not in inner:
                    j = labels.get(x.label.upper())
                    if j is None or j <= i:
                        raise _Bail         # backwards (a loop) or out of this list
                    first = i if first is None else first
                    last = j if last is None else max(last, j)
        if first is None:
            return None
        # a jump out of the range into a later label widens it
        while True:
            wider = _Analysis._jumped_from(stmts, first, last, labels)
            if wider == last:
                return first, last
            last = wider

    @staticmethod
    def _jumped_from(stmts, first, last, labels) -> int:
        for st in stmts[first:last + 1]:
            for x, _ in ir.nodes(st):
                if isinstance(x, ir.Jmp):
                    last = max(last, labels.get(x.label.upper(), last))
        return last

    def _unrollable(self, st: ir.For, scope, env) -> bool:
        if ident(st.var) not in scope.position_vars:
            return False
        if any(isinstance(x, (ir.Exit, ir.Return)) for x, _ in ir.nodes(st.body)):
            return False
        try:
            for e in (st.start, st.end, st.step or ir.Literal(1, "INT")):
                self._const(e, scope, env)
        except _NotConstant:
            return False
        return True

    def _const(self, e, scope, env) -> int:
        if isinstance(e, ir.Literal) and isinstance(e.value, int) \
                and not isinstance(e.value, bool):
            return int(e.value)
        if isinstance(e, ir.Name):
            k = ident(e.name)
            if k in env:
                return env[k]
            if k in scope.constants:
                return scope.constants[k]
            raise _NotConstant
        if isinstance(e, ir.Unary) and e.op == "-":
            return -self._const(e.operand, scope, env)
        if isinstance(e, ir.Binary) and e.op in ("+", "-", "*"):
            a, b = self._const(e.left, scope, env), self._const(e.right, scope, env)
            return a + b if e.op == "+" else a - b if e.op == "-" else a * b
        raise _NotConstant

    def _touch_all(self, node, scope, env, group: set) -> None:
        """Every cell ``node`` (a statement, an expression, an SFC) reads or writes."""
        stack = [node]
        while stack:
            x = stack.pop()
            if isinstance(x, (list, tuple)):
                stack.extend(x)
                continue
            if not hasattr(x, "__dataclass_fields__"):
                continue
            if isinstance(x, ir.Name):
                group |= scope.cells_of(x.name, env)
                continue
            if isinstance(x, ir.Index):
                cell = self._element(x, scope, env)
                if cell is not None:
                    group.add(cell)
                    stack.extend(x.indices)
                    continue
            if isinstance(x, ir.Call) and not isinstance(x.func, ir.Name) \
                    or isinstance(x, ir.Call) and ident(x.func.name) in scope.functions:
                group |= self.reach     # a method, an element's FB, a user function
            if isinstance(x, ir.For):
                group |= scope.cells_of(x.var, env)
            if isinstance(x, ir.ActionAssoc):
                group |= scope.cells_of(x.action, env)   # a variable as an SFC action
                if x.indicator:
                    group |= scope.cells_of(x.indicator, env)
            stack.extend(getattr(x, f) for f in x.__dataclass_fields__ if f != "pos")

    def _element(self, x: ir.Index, scope, env):
        """The cell of ``a[i, ...]`` for an array variable ``a`` and a constant ``i``."""
        if not isinstance(x.base, ir.Name):
            return None
        hit = scope.variable(x.base.name)
        if hit is None:
            return None
        owner, attr, t = hit
        if getattr(t, "cat", None) != "array":
            return None
        try:
            k = self._const(x.indices[0], scope, env) - t.dims[0][0]
        except _NotConstant:
            return None
        if not 0 <= k < len(getattr(self.owners[owner], attr)):
            return None         # out of range: a run-time error the whole run raises
        return (owner, attr, k)


class _NotConstant(Exception):
    pass


class _Scope:
    """The names one program instance's code sees."""

    def __init__(self, name, fbt, analysis: _Analysis):
        self.name, self.fbt, self.a = name, fbt, analysis
        pou = fbt.pou
        self.local = {}
        for b in pou.var_blocks:
            if b.kind == "VAR_EXTERNAL":
                continue
            for d in b.decls:
                self.local[ident(d.name)] = d
        self.constants = dict(analysis.constants)
        self.constants.update(int_constants(pou.var_blocks))
        types = analysis.compiled.types
        self.types = {k: types.resolve(d.type, d.pos) for k, d in self.local.items()}
        if any(getattr(t, "cat", None) in ("ptr", "itf") for t in self.types.values()):
            raise _Bail
        self.position_vars = self._position_vars(pou)
        self.functions = {ident(p.name) for p in analysis.program.pous
                          if p.kind == "FUNCTION"}

    def _position_vars(self, pou) -> set:
        """Local FOR variables written only by FOR loops with constant bounds, none inside
        another over the same variable, and read only inside those loops: at any place
        they are read their value is fixed by the place. (After a loop the variable holds
        its end, which a loop inside a condition would make depend on the state.)"""
        fors, written = {}, set()
        self._read_outside(pou.body, (), written)
        for x, _ in ir.nodes(pou.body):
            if isinstance(x, ir.For):
                ok = True
                for e in (x.start, x.end, x.step):
                    if e is not None:
                        try:
                            self.a._const(e, self, {})
                        except _NotConstant:
                            ok = False
                k = ident(x.var)
                fors[k] = fors.get(k, True) and ok and not any(
                    isinstance(y, (ir.Exit, ir.Return)) for y, _ in ir.nodes(x.body))
            elif isinstance(x, ir.Assign):
                _targets(x.target, written)
            elif isinstance(x, ir.Arg) and x.output and x.value is not None:
                _targets(x.value, written)
            elif isinstance(x, ir.AssignExpr):
                _targets(x.target, written)
            elif isinstance(x, ir.Arg) and isinstance(x.value, ir.Name):
                written.add(ident(x.value.name))    # perhaps a VAR_IN_OUT
        return {k for k, ok in fors.items() if ok and k not in written and k in self.local}

    @staticmethod
    def _read_outside(body, loops: tuple, out: set) -> None:
        """Add to ``out`` the FOR variables read outside a loop over them, or looped over
        inside one (both disqualify them as position variables)."""
        stack = [(body, loops)]
        while stack:
            x, inside = stack.pop()
            if isinstance(x, (list, tuple)):
                stack.extend((y, inside) for y in x)
                continue
            if not hasattr(x, "__dataclass_fields__"):
                continue
            if isinstance(x, ir.For):
                k = ident(x.var)
                if k in inside:
                    out.add(k)
                stack.extend((e, inside) for e in (x.start, x.end, x.step) if e is not None)
                stack.append((x.body, inside + (k,)))
                continue
            if isinstance(x, ir.Name) and ident(x.name) not in inside:
                out.add(ident(x.name))
            stack.extend((getattr(x, f), inside) for f in x.__dataclass_fields__
                         if f != "pos")

    def variable(self, name: str):
        """(owner, attribute, type) of a variable, or None (a constant, a type, a
        function, an enum value)."""
        k = ident(name)
        if k in self.constants:
            return None
        if k in self.local:
            return self.name, k, self.types[k]
        if k in self.a.globals:
            return "G", k, self.a.compiled.globals_types[k][1]
        return None

    def cells_of(self, name: str, env) -> set:
        k = ident(name)
        if k in env or k in self.position_vars:
            return set()
        hit = self.variable(name)
        if hit is None:
            return set()
        owner, attr, t = hit
        self.a.whole_touched.add((owner, attr))
        cells = {(owner, attr, None)}
        if _holds_fb(t):
            cells |= self.a.reach       # its code may touch globals
        return cells


def _holds_fb(t) -> bool:
    while getattr(t, "cat", None) == "array":
        t = t.elem
    return getattr(t, "cat", None) in ("fb", "struct")


def _targets(e, out: set) -> None:
    while isinstance(e, (ir.Member, ir.Index, ir.BitAccess)):
        e = e.base
    if isinstance(e, ir.Name):
        out.add(ident(e.name))


def _attributes(obj) -> list[str]:
    """The variables of a generated instance (its slots, without the executor's own)."""
    names = [n for cls in type(obj).__mro__ for n in getattr(cls, "__slots__", ())]
    names += list(getattr(obj, "__dict__", ()))
    # generated names (``_sfc``, ``_e_X``) hold a lower-case letter; variables never do
    return [n for n in dict.fromkeys(names) if n.isupper()]


# ---------------------------------------------------------------------- runtime slots

def objects_by_cell(inst, cells=None) -> dict:
    """id of every object (array, struct, FB instance, standard FB) under a cell of
    ``inst`` (of ``cells``, when given) -> that cell; an array variable itself -> its
    whole cell."""
    by_id = {}

    def register(x, cell) -> None:
        stack = [x]
        while stack:
            y = stack.pop()
            if isinstance(y, (bool, int, float, str)) or y is None or id(y) in by_id:
                continue
            by_id[id(y)] = cell
            if isinstance(y, list):
                stack.extend(y)
            else:
                stack.extend(getattr(y, n, None) for n in _attributes(y))

    owners = {"G": inst.g, **dict(zip(inst.names, inst.programs))}
    if cells is None:
        cells = [(owner, attr, None) for owner, obj in owners.items()
                 for attr in _attributes(obj)]
    for owner, attr, k in cells:
        if attr == _SFC:
            continue
        value = getattr(owners[owner], attr)
        if k is not None:
            register(value[k], (owner, attr, k))
        elif isinstance(value, list):
            by_id[id(value)] = (owner, attr, None)
            for k, x in enumerate(value):
                register(x, (owner, attr, k))
        else:
            register(value, (owner, attr, None))
    return by_id


def island_timers(inst, cells) -> list:
    """The standard timers of ``inst`` under ``cells`` (and any not found under a cell)."""
    everything = objects_by_cell(inst)
    mine = objects_by_cell(inst, cells)
    return [tm for tm in inst.timers if id(tm) in mine or id(tm) not in everything]


def slot_cell(inst, obj, attr, views, by_id=None):
    """The cell of a plain variable slot ``(obj, attr)`` of a program or the globals
    (not an element, a member or a bit: those are parts of a larger cell), or None."""
    if isinstance(obj, views):
        return None
    if obj is inst.g:
        return ("G", attr, None)
    for n, p in zip(inst.names, inst.programs):
        if p is obj:
            return (n, attr, None)
    return None


class SlotCells:
    """The cell a runtime slot of the executor (``(object, attribute)``: a variable, an
    array element through ``ItemView``, a bit through ``BitView``, a step flag of an SFC
    runtime) belongs to, found by the identity of the objects under each cell."""

    def __init__(self, inst, partition: Partition, views: tuple):
        self.p = partition
        self.item_view, self.bit_view = views
        self.by_id: dict = {}
        self.owner_of = {id(inst.g): "G"}
        self.owner_of.update({id(p): n for n, p in zip(inst.names, inst.programs)})
        self.sfc_owner = {id(getattr(p, "_sfc", None)): n
                          for n, p in zip(inst.names, inst.programs)}
        self.by_id = objects_by_cell(inst)

    def island(self, obj, attr) -> int | None:
        """The island of slot ``(obj, attr)``, or None when it cannot be told."""
        if isinstance(obj, self.bit_view):
            return self.island(obj.obj, obj.attr)
        if isinstance(obj, self.item_view):
            cell = self.by_id.get(id(obj.items))
            if cell is None:
                return None
            if cell[2] is None and (cell[0], cell[1], obj.k) in self.p.cells:
                cell = (cell[0], cell[1], obj.k)
            return self.p.cells.get(cell)
        if isinstance(obj, SfcRuntime):
            owner = self.sfc_owner.get(id(obj))
            return None if owner is None else self.p.cells.get((owner, _SFC, None))
        owner = self.owner_of.get(id(obj))
        if owner is not None:
            return self.p.cells.get((owner, attr, None))
        cell = self.by_id.get(id(obj))
        return None if cell is None else self.p.cells.get(cell)


def island_snap(inst, cells, left_out: dict):
    """The compared state of the ``cells`` of ``inst``: what its ``snap`` holds of them
    (without the sinks ``left_out`` names, with R_EDGE memories and SFC state), as a
    function of ``rel`` as ``snap`` is."""
    owners = {"G": inst.g, **dict(zip(inst.names, inst.programs))}
    whole = {(o, a) for o, a, k in cells if k is None}
    items = []
    for o, a, k in cells:
        obj = owners[o]
        if a == _SFC:
            items.append((obj._sfc, None, _SFC))
            continue
        if a in left_out.get(type(obj).__name__, ()):
            continue
        if k is None:
            items.append((obj, a, None))
            if hasattr(obj, "_e_" + a):
                items.append((obj, "_e_" + a, None))
        elif (o, a) not in whole:
            items.append((obj, a, k))

    # one generated expression per item, chosen by its value's kind (a variable keeps
    # its type): a snapshot taken every executed scan costs what the program's own does
    # (the code holds only attribute names of generated classes, checked, and indices)
    names, parts = {"__builtins__": {"tuple": tuple}, "_snap_value": _snap_value}, []
    for i, (obj, a, k) in enumerate(items):
        names[f"o{i}"] = obj
        if k is _SFC:
            parts.append(f"o{i}.key(rel)")
            continue
        if not _NAME.fullmatch(a):
            raise ValueError(f"internal: {a!r} is not a generated attribute name")
        code = f"o{i}.{a}" if k is None else f"o{i}.{a}[{int(k)}]"
        parts.append(_snap_code(code, getattr(obj, a) if k is None else getattr(obj, a)[k]))
    src = "def snap(rel=None):\n    return (" + "".join(p + ", " for p in parts) + ")\n"
    exec(src, names)
    return names["snap"]


_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*", re.ASCII)
_SCALARS = (bool, int, float, str)


def _snap_code(code: str, v) -> str:
    if isinstance(v, list):
        if v and all(isinstance(x, _SCALARS) for x in v):
            return f"tuple({code})"
        if v and all(hasattr(x, "_snap") for x in v):
            return f"tuple([x._snap(rel) for x in {code}])"
        if v and all(hasattr(x, "key") and not isinstance(x, list) for x in v):
            return f"tuple([x.key(rel) for x in {code}])"
        return f"_snap_value({code}, rel)"
    if isinstance(v, _SCALARS):
        return code
    if hasattr(v, "_snap"):
        return f"{code}._snap(rel)"
    if hasattr(v, "key"):
        return f"{code}.key(rel)"
    return f"_snap_value({code}, rel)"


def _snap_value(v, rel):
    if isinstance(v, list):
        return tuple([_snap_value(x, rel) for x in v])
    if hasattr(v, "_snap"):
        return v._snap(rel)
    if hasattr(v, "key"):
        return v.key(rel)
    return v
