"""Which variables the state the executor compares may leave out, so that a machine that
counts its parts still reaches fixed points and repeats its cycle: sinks (values that
reach nothing that matters), globals nothing reads, and counters compared only up to
their threshold."""
from __future__ import annotations

import functools

from ...parser import ir
from ...parser.names import ident
from ..types import ArrayT, StdFbT
from .common import BIT_READ, GLOBALS_CLASS, constant_block
from .conversions import base_t
from .flow import Flow, et_threshold, name_uses, unread


class ComparedState:
    """Decides, FB by FB, what the compared state leaves out; ``left_out`` collects it
    per class (``Compiled.left_out``)."""

    def __init__(self, program: ir.Program, functions: dict, globals_types: dict, observed):
        self.program = program
        self.functions = functions
        self.globals_types = globals_types      # UPPER -> (name, type, declaration)
        self.global_names = set(globals_types)
        self.observed = observed
        self.member_names = ir.names_in(program)
        # names bound in calls (``fb(x := a, q => b)``): an FB output bound anywhere is read
        self.bound_names = {a.name.upper() for a, _ in ir.nodes(program)
                            if isinstance(a, ir.Arg) and a.name}
        # FBs another extends (the base's name without a library prefix)
        self.extended = {p.extends.rsplit(".", 1)[-1].upper() for p in program.pous
                         if p.extends}
        self.global_constants = {
            d.name.upper() for b in [g.block for g in program.globals]
            + [b for c in program.configurations for b in c.var_blocks]
            if constant_block(b) for d in b.decls}
        self.left_out: dict[str, dict] = {}

    @functools.cached_property
    def impure(self) -> set:
        """User functions that reach globals (VAR_EXTERNAL, or a global's name)."""
        return {k for k, f in self.functions.items()
                if any(b.kind == "VAR_EXTERNAL" for b in f.var_blocks)
                or ir.names_in(f.body, ir.Name, "name") & self.global_names}

    @functools.cached_property
    def write_only_globals(self) -> set:
        """Globals whose value nothing can ever see: every use of the name anywhere (any
        POU, configuration or declaration, whoever's name it is) is the whole target of a
        plain ``:=`` or an output binding; no ``x.name`` names it; the machine file
        names none; none is located in the process image (%I the executor writes, %Q
        the timeline records) or at an address code names; each holds an elementary
        value (a struct's or an array's parts are written through a member or an
        index, which this does not follow). A word a program copies a count to for an
        HMI that the machine file does not name is one. Left out of the compared state
        (``left_out[GLOBALS_CLASS]``), and a sink for what flows into it."""
        roots = [self.program.pous, self.program.configurations, self.program.globals]
        addressed = ir.names_in(roots, ir.DirectAddress, "address")
        read = set()
        for x, parent in ir.nodes(roots):
            if not isinstance(x, ir.Name):
                continue
            written = (isinstance(parent, ir.Assign) and parent.op == ":="
                       and parent.target is x) or (
                isinstance(parent, ir.Arg) and parent.output and parent.value is x)
            if not written:
                read.add(x.name.upper())
        out = set()
        for k, (name, t, d) in self.globals_types.items():
            address = (d.address or "").upper()
            if name.upper() in read or k in read or name.upper() in self.member_names \
                    or name.upper() in self.observed or k in self.observed \
                    or address.startswith(("%I", "%Q")) or address in addressed \
                    or "*" in address:
                continue
            if base_t(t).cat in ("bool", "int", "real", "time", "date", "string"):
                out.add(k)
        if out:
            self.left_out[GLOBALS_CLASS] = dict.fromkeys(out)
        return out

    def sinks(self, fb, scope, time_constants: dict, reads_et: bool) -> tuple[set, bool]:
        """(local variables whose values never reach an output, a condition, a call or an
        index, whether a running timer's ET reaches something that matters). Sinks are
        counters and statistics such as ``nParts := nParts + 1``. Decided from the data
        flow of the FB's own code (``reads_et``: that code reads an ET); anything named
        as ``x.member`` anywhere is never a sink."""
        cands = self._declared(fb, scope, ("VAR", "VAR_TEMP")) | self._unread_outputs(fb, scope)
        # a standard FB only changes its own outputs: its inputs flow into it, and it is a
        # sink when nothing reads those outputs (a parts counter nobody looks at)
        std = {k for k in cands if base_t(scope.names[k][1]).cat == "stdfb"}
        cands -= self.member_names - std
        # what flows only into globals nothing reads is lost as surely as in a local sink
        # (a name the FB declares itself hides the global)
        lost = {k for k in self.write_only_globals
                if scope.names.get(k, ("",))[0] == f"_g.{k}"}
        cands |= lost
        if not cands and not reads_et:
            return set(), False
        flow = Flow(self.impure, std, functools.partial(et_threshold,
                                                        time_constants=time_constants))
        for body in self._bodies(fb.pou, flow):
            flow.stmts(body)
        while True:
            sinks = unread(cands, flow)
            # a sink the machine file reads is shown: it must be compared, and so must
            # what flows into it; a count of parts may stay out (the executor shifts a
            # repeated period's counts, _LeftOut)
            shown = {k for k in sinks & self.observed
                     if k + BIT_READ in self.observed
                     or count_width(k, flow, sinks, scope) is None}
            if not shown:
                break
            flow.used |= shown
        # a running timer's ET reaching something that matters: the executor must step
        # scan by scan while timers run
        et_matters = any(t is None or t not in sinks for t in flow.et_targets)
        self.left_out[fb.cls_name] = {k: count_width(k, flow, sinks, scope)
                                      for k in sinks - lost}
        return sinks - lost, et_matters

    def _unread_outputs(self, fb, scope) -> set:
        """A function block's outputs that nothing outside it can read: no ``x.name`` and
        no ``name => ...`` binding anywhere in the program, no FB extending it (whose code
        would read them by name), none the machine file names. An FB per drive that
        counts its strokes in an output nobody looks at is then as repeatable as one
        counting in a local variable. A PROGRAM's outputs are left alone (a
        configuration may connect them)."""
        pou = fb.pou
        if pou.kind != "FUNCTION_BLOCK" or pou.name.upper() in self.extended:
            return set()
        outside = self.member_names | self.bound_names | self.observed
        return {k for k in self._declared(fb, scope, ("VAR_OUTPUT",))
                if k.upper() not in outside}

    @staticmethod
    def _declared(fb, scope, kinds) -> set:
        """The plain variables of the given block kinds a candidate may be: no address,
        a value type (a standard FB counts: it only changes its own outputs)."""
        cands = set()
        for b in fb.pou.var_blocks:
            if b.kind not in kinds:
                continue
            for d in b.decls:
                t = base_t(scope.names[ident(d.name)][1])
                if not d.address and t.cat in ("bool", "int", "real", "time", "date",
                                               "string", "struct", "stdfb"):
                    cands.add(ident(d.name))
        return cands

    @staticmethod
    def _bodies(pou: ir.Pou, flow: Flow) -> list:
        """The statement lists of a POU's code; what an SFC's steps and transitions read
        is marked used in ``flow``."""
        bodies = []
        if pou.is_sfc:
            for tr in pou.body.transitions:
                flow.use(tr.condition)
            for st in pou.body.steps:
                for a in st.actions:
                    flow.used.add(ident(a.action))
                    if a.time is not None:
                        flow.use(a.time)
            bodies += [a.body for a in pou.body.actions]
        else:
            bodies.append(pou.body)
        bodies += [a.body for a in pou.actions] + [m.body for m in pou.methods]
        bodies += [acc.body for p in pou.properties for acc in p.accessors]
        return bodies

    def threshold_counters(self, fb, scope) -> set:
        """Counters whose count nothing reads, only their Q, which stops changing once
        the count is past the threshold: a CTU whose PV is one constant (Q := CV >= PV)
        or a CTD (Q := CV <= 0). They are compared with the count held at the threshold
        (``key_counted``), so that a machine that counts its parts to request a filter
        check after 5000 of them repeats its cycle once it has. Decided from the FB's
        own code: the instance is only called (every input named, PV one constant, CV
        bound to nothing) and its Q read; an instance named as ``x.member`` anywhere,
        or one of an FB that another extends, is left alone."""
        pou = fb.pou
        if pou.name.upper() in self.extended:
            return set()
        kinds = self._counters(pou, scope)
        if not kinds:
            return set()
        constant = self._constant_of(pou)
        ok = dict.fromkeys(kinds, True)
        pv: dict = {k: set() for k in kinds}
        for name, node, parent in name_uses(pou, set(kinds)):
            if isinstance(parent, ir.Call) and parent.func is node:
                for a in parent.args:
                    if a.name is None or a.name.upper() == "CV":
                        ok[name] = False
                    elif a.name.upper() == "PV":
                        pv[name].add(constant(a.value))
            elif not (isinstance(parent, ir.Member) and parent.base is node
                      and parent.member.upper() == "Q"):
                ok[name] = False        # CV read or written, the instance handed on, ...
        return {ident(k) for k, kind in kinds.items() if ok[k] and (
            kind == "CTD" or (len(pv[k]) <= 1 and None not in pv[k]))}

    def _counters(self, pou: ir.Pou, scope) -> dict:
        """UPPER name -> "CTU" or "CTD" of the counter instances a POU declares that
        nothing outside it names."""
        kinds = {}
        for b in pou.var_blocks:
            for d in b.decls if b.kind == "VAR" else ():
                t = scope.names[ident(d.name)][1]
                kind = t.name.upper().partition("_")[0] if isinstance(t, StdFbT) else None
                if kind in ("CTU", "CTD") and not d.address \
                        and d.name.upper() not in self.member_names \
                        and d.name.upper() not in self.observed:
                    kinds[d.name.upper()] = kind
        return kinds

    def _constant_of(self, pou: ir.Pou):
        """A function giving what a PV argument is when it is one constant (a literal, a
        constant of the POU, or a global one no local hides), else None."""
        own_constants = {d.name.upper() for b in pou.var_blocks if constant_block(b)
                         for d in b.decls}
        local = {d.name.upper() for b in pou.var_blocks for d in b.decls} | {
            d.name.upper() for m in pou.methods for b in m.var_blocks for d in b.decls}

        def constant(x):
            if isinstance(x, ir.Literal):
                return ("literal", x.type_name, x.value)
            if isinstance(x, ir.Name) and (x.name.upper() in own_constants or (
                    x.name.upper() in self.global_constants and x.name.upper() not in local)):
                return ("name", x.name.upper())
            return None
        return constant


def count_width(name: str, flow, sinks: set, scope):
    """(bits, signed) when sink ``name`` is an integer whose every write adds to it a
    step that reads no sink (``n := n + 1``, ``n := n - k``): over a period of a
    repeating machine it then grows by the same amount, and a repeated period's
    values are the first period's plus that amount per period (modulo its width).
    None for any other sink."""
    t = scope.names[name][1]
    n, reads = flow.steps.get(name, (0, set()))
    if not n or n != sum(1 for target, _ in flow.flows if target == name) \
            or reads & sinks or isinstance(t, ArrayT):
        return None
    t = base_t(t)
    if t.cat != "int" or (t.bits or 32) > 52:
        return None                     # a float64 holds no wider count exactly
    return (t.bits or 32, bool(t.signed))
