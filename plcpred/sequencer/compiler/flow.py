"""Where values go in a program's code: the data flow the compared state is decided from
(:mod:`.compared_state`), the names a program may write, and the timer thresholds that
make a comparison an event."""
from __future__ import annotations

from ...parser import ir
from ...parser.names import ident
from .common import COMPARISONS


def const_time(e):
    """The nanoseconds of a TIME literal (a plain integer literal counts milliseconds),
    or None."""
    if isinstance(e, ir.Literal) and isinstance(e.value, int) and not isinstance(
            e.value, bool):
        return int(e.value) if e.type_name in ("TIME", "LTIME") else int(e.value) * 10**6
    return None


def et_threshold(x: ir.Binary, time_constants: dict):
    """The threshold (ns) of ``timer.ET <op> constant`` (either way round), or None."""
    if x.op not in COMPARISONS:
        return None
    for a, b in ((x.left, x.right), (x.right, x.left)):
        if isinstance(a, ir.Member) and ident(a.member) == "ET":
            c = const_time(b)
            if c is None and isinstance(b, ir.Name):
                c = time_constants.get(ident(b.name))
            return c
    return None


def children(e):
    """The expressions directly inside expression ``e``."""
    if isinstance(e, ir.Binary):
        return (e.left, e.right)
    if isinstance(e, ir.Unary):
        return (e.operand,)
    if isinstance(e, (ir.Member, ir.BitAccess, ir.Deref)):
        return (e.base,)
    if isinstance(e, ir.Index):
        return (e.base, *e.indices)
    if isinstance(e, ir.Call):
        return tuple(a.value for a in e.args if a.value is not None)
    if isinstance(e, ir.AssignExpr):
        return (e.target, e.value)
    return ()


def name_uses(root, names: set) -> list:
    """(upper-case name, node, parent) of every ``ir.Name`` in ``root`` whose name is in
    ``names``."""
    return [(x.name.upper(), x, parent) for x, parent in ir.nodes(root)
            if isinstance(x, ir.Name) and x.name.upper() in names]


def target_names(e, out: set) -> bool:
    """Add to ``out`` the names along write target ``e`` (``a.b[i].c``: A, B and C);
    False when the target is not reached by names (a pointer, an address: %IX0.0 may be
    an input)."""
    while isinstance(e, (ir.Member, ir.Index, ir.BitAccess)):
        if isinstance(e, ir.Member):
            out.add(e.member.upper())
        e = e.base
    if isinstance(e, ir.Name):
        out.add(e.name.upper())
        return True
    return False


def written_names(program: ir.Program) -> set | None:
    """Every name the program may write by name, upper case: the variables and members
    along each assignment target (``a.b[i].c := x`` writes A, B and C), output bindings,
    FOR variables. None when a write goes where names cannot tell (through a pointer, to
    an address). What a call writes through VAR_IN_OUT and what ADR/REF hand out the
    compiler adds as it compiles them (``Compiled.written``). Conservative: for deciding
    what the program can never change (the inputs the executor writes need not be
    written again each scan)."""
    out: set = set()

    def target(e) -> bool:
        return target_names(e, out)

    stack = [program.pous, program.configurations, program.globals]
    while stack:
        x = stack.pop()
        if isinstance(x, (list, tuple)):
            stack.extend(x)
            continue
        if not hasattr(x, "__dataclass_fields__"):
            continue
        if isinstance(x, (ir.Assign, ir.AssignExpr)) and not target(x.target):
            return None
        if isinstance(x, ir.Assign) and x.op == "REF=" and not target(x.value):
            return None         # a reference to it: written through the reference
        if isinstance(x, ir.Try) and x.catch_var is not None and not target(x.catch_var):
            return None
        if isinstance(x, ir.For):
            out.add(x.var.upper())
            if x.target is not None and not target(x.target):
                return None
        if isinstance(x, ir.Call):
            for a in x.args:
                if a.output and a.value is not None and not target(a.value):
                    return None
        stack.extend(getattr(x, f) for f in x.__dataclass_fields__ if f != "pos")
    return out


def root_name(e):
    """The variable a target is part of (``a`` of ``a.b[i]``), or None."""
    while isinstance(e, (ir.Member, ir.Index, ir.BitAccess)):
        e = e.base
    return ident(e.name) if isinstance(e, ir.Name) else None


def unread(cands: set, flow) -> set:
    """The candidates whose values reach nothing that ``flow`` uses, directly or through
    other variables."""
    sinks = cands - flow.used
    changed = True
    while changed:
        changed = False
        for target, reads in flow.flows:
            if (target is None or target not in sinks) and reads & sinks:
                sinks -= reads
                changed = True
    return sinks


def _added_step(s: ir.Assign):
    """``e`` of ``x := x + e``, ``x := e + x`` or ``x := x - e`` (x a plain name), else
    None."""
    v = s.value
    if not isinstance(s.target, ir.Name) or not isinstance(v, ir.Binary):
        return None
    x = ident(s.target.name)

    def is_x(e):
        return isinstance(e, ir.Name) and ident(e.name) == x
    if v.op in ("+", "-") and is_x(v.left):
        return v.right
    if v.op == "+" and is_x(v.right):
        return v.left
    return None


class Flow:
    """Where each variable's value goes: ``flows`` (assignment target, names read) and
    ``used`` (names read by conditions, calls, indices and anything else that can steer
    the program)."""

    def __init__(self, impure=frozenset(), std_fbs=frozenset(), et_compare=lambda x: None):
        self.flows: list[tuple[str | None, set]] = []
        self.used: set = set()
        self.impure = impure  # user functions that reach globals (VAR_EXTERNAL)
        self.std_fbs = std_fbs  # standard FB instances (pure: they only set their outputs)
        self.et_compare = et_compare
        self.et_targets: set = set()  # where timers' ET values go (None: steers the program)
        self._et = False
        # writes of the form x := x + e / x := e + x / x := x - e: x -> (how many, the
        # names the e read); a target of as many flows is written in no other way
        self.steps: dict[str, tuple[int, set]] = {}

    def reads(self, e) -> set:
        """The names ``e`` reads (what it steers, such as an index, is marked used)."""
        out = set()

        def walk(x):
            if isinstance(x, ir.Binary) and self.et_compare(x) is not None:
                for side in (x.left, x.right):   # an event, not a value that drifts
                    walk(side.base if isinstance(side, ir.Member) else side)
                return
            if isinstance(x, ir.Member) and ident(x.member) == "ET":
                self._et = True
            if isinstance(x, ir.Name):
                out.add(ident(x.name))
            elif isinstance(x, ir.AssignExpr):
                self.use(x.target)          # written here: never left out of a state
                walk(x.value)
            elif isinstance(x, ir.Index):
                walk(x.base)
                for i in x.indices:
                    self.use(i)
            elif isinstance(x, ir.Deref):
                self.use(x.base)
            elif isinstance(x, ir.Call):
                self._call_reads(x)
                walk(x.func)
                for a in x.args:
                    if a.value is not None:
                        walk(a.value)
            else:
                for c in children(x):
                    walk(c)
        walk(e)
        return out

    def _call_reads(self, x: ir.Call) -> None:
        """Arguments of a call that may change something beyond its result are used."""
        if isinstance(x.func, ir.Member) or (
                isinstance(x.func, ir.Name) and ident(x.func.name) in self.impure):
            # methods change their instance; some functions write globals
            for a in x.args:
                if a.value is not None:
                    self.use(a.value)
        elif isinstance(x.func, ir.Name) and ident(x.func.name) in ("ADR", "REF"):
            for a in x.args:
                if a.value is not None:
                    self.use(a.value)

    def use(self, e):
        self._et = False
        self.used |= self.reads(e)
        if self._et:
            self.et_targets.add(None)

    def stmts(self, body):
        for s in body:
            self.stmt(s)

    def stmt(self, s):
        if isinstance(s, ir.Assign):
            self._assign(s)
        elif isinstance(s, ir.CallStmt):
            self._call_stmt(s)
        elif isinstance(s, ir.If):
            for cond, body in s.branches:
                self.use(cond)
                self.stmts(body)
            self.stmts(s.else_body or [])
        elif isinstance(s, ir.Case):
            self.use(s.selector)
            for br in s.branches:
                self.stmts(br.body)
            self.stmts(s.else_body or [])
        elif isinstance(s, ir.For):
            self.used.add(ident(s.var))
            if s.target is not None:
                self.use(s.target)
            for e in (s.start, s.end, s.step):
                if e is not None:
                    self.use(e)
            self.stmts(s.body)
        elif isinstance(s, (ir.While, ir.Repeat)):
            self.use(s.cond)
            self.stmts(s.body)
        elif isinstance(s, ir.Try):
            self.stmts(s.body)
            if s.catch_var is not None:
                self.flows.append((root_name(s.catch_var), set()))
            self.stmts(s.catch_body or [])
            self.stmts(s.finally_body or [])

    def _assign(self, s: ir.Assign) -> None:
        target = root_name(s.target)
        self._et = False
        reads = self.reads(s.value)
        if self._et:
            self.et_targets.add(target)
        if isinstance(s.target, (ir.Index, ir.Member, ir.BitAccess)):
            reads |= self.reads(s.target) - {target}
        if s.op != ":=" or isinstance(s.target, ir.Deref) or target is None:
            self.used |= reads
            if target is not None:
                self.used.add(target)
        self.flows.append((target, reads))
        step = _added_step(s) if s.op == ":=" else None
        if step is not None:
            n, names = self.steps.get(target, (0, set()))
            self.steps[target] = (n + 1, names | ir.names_in(step, ir.Name, "name"))

    def _call_stmt(self, s: ir.CallStmt) -> None:
        callee = root_name(s.call.func)
        if callee in self.std_fbs and isinstance(s.call.func, (ir.Name, ir.Index)):
            self._std_fb_call(s.call, callee)
            return
        self.use(s.call.func)
        for a in s.call.args:
            if a.value is None:
                continue
            if a.output:
                self.flows.append((root_name(a.value), {root_name(s.call.func) or ""}))
                if (a.name or "").upper() == "ET":
                    self.et_targets.add(None)
            else:
                self.use(a.value)

    def _std_fb_call(self, call: ir.Call, callee: str) -> None:
        """A standard FB's inputs flow into it, its outputs out of it."""
        self._et = False
        self.flows.append((callee, set().union(*(
            self.reads(a.value) for a in call.args
            if a.value is not None and not a.output))))
        if self._et:
            self.et_targets.add(callee)
        for a in call.args:
            if a.output and a.value is not None:
                self.flows.append((root_name(a.value), {callee}))
                if (a.name or "").upper() == "ET":
                    self.et_targets.add(root_name(a.value))
        if isinstance(call.func, ir.Index):
            for i in call.func.indices:
                self.use(i)
