"""The classes of the generated module: the globals, one per structure and one per
FUNCTION_BLOCK/PROGRAM (its variables, FB_init calls, body, methods, actions), each with
the snapshot (``_snap``) the executor compares."""
from __future__ import annotations

import dataclasses

from ...parser import ir
from ...parser.names import ident
from ..types import ArrayT, Elem, EnumT, FbT, StructT
from .common import GLOBALS_CLASS, Scope, error_at, fb_inits, shown_name

# the two flags every CODESYS/TwinCAT FB_init takes before its own parameters
_FB_INIT_FLAGS = ("BINITRETAINS", "BINCOPYCODE")


class ClassesMixin:
    """Part of :class:`~.project.Compiler`: the classes of the generated module."""

    def _globals_class(self, decls, scope):
        e = self.src.emit
        e(0, f"class {GLOBALS_CLASS}:")
        e(1, "__slots__ = (" + "".join(f"'{ident(d.name)}', " for d in decls) + ")")
        e(1, "def __init__(self):")
        e(2, "global _g")
        e(2, "_g = self")
        self._variables_init(decls, lambda d: self.globals[ident(d.name)][1], scope)
        lost = self.compared.write_only_globals
        e(1, "def _snap(self, rel):")
        e(2, "return (" + "".join(
            f"{self._snap_code('self.' + ident(d.name), self.globals[ident(d.name)][1])}, "
            for d in decls if ident(d.name) not in lost) + ")")

    def _struct_class(self, s: StructT):
        e = self.src.emit
        scope = Scope()
        e(0, f"class {s.cls_name}:")
        keys = list(s.members)
        e(1, "__slots__ = (" + "".join(f"'{k}', " for k in keys) + ")")
        e(1, "def __init__(self):")
        for d in s.decls:
            e(2, f"self.{ident(d.name)} = "
                 f"{self._init(s.members[ident(d.name)], d.init, scope, d)}", d.pos)
        if not s.decls:
            e(2, "pass")
        e(1, "def _snap(self, rel):")
        e(2, "return (" + "".join(f"{self._snap_code('self.' + k, s.members[k])}, "
                                  for k in keys) + ")")

    def _scope_for(self, fb: FbT) -> Scope:
        """The names an FB's own code sees: the globals, then its own and its bases'
        variables (``self.X``)."""
        names = {k: (f"_g.{k}", t) for k, (n, t, d) in self.globals.items()}
        for t in reversed(list(fb.chain())):
            for b in t.pou.var_blocks:
                for d in b.decls:
                    key = ident(d.name)
                    if b.kind == "VAR_EXTERNAL":
                        if key not in self.globals:
                            raise error_at(d, f"VAR_EXTERNAL {d.name} has no VAR_GLOBAL")
                        continue
                    names[key] = (f"self.{key}", self.types.resolve(d.type, d.pos))
        sc = Scope(names=names, fb=fb, cls=fb.cls_name, pou=shown_name(fb.pou))
        if fb.pou.is_sfc:
            sc.steps = {ident(s.name): i for i, s in enumerate(fb.pou.body.steps)}
        return sc

    # ---------------------------------------------------------------- FBs and programs
    def _fb_class(self, fb: FbT, done: set):
        """The class of an FB or PROGRAM (its base's first; ``done``: those emitted)."""
        if fb.cls_name in done:
            return
        if fb.base is not None:
            self._fb_class(fb.base, done)
        done.add(fb.cls_name)
        e = self.src.emit
        pou = fb.pou
        scope = self._scope_for(fb)
        own = [d for b in pou.var_blocks if b.kind != "VAR_EXTERNAL" for d in b.decls]
        base = fb.base.cls_name if fb.base else "k_FbBase"
        e(0, f"class {fb.cls_name}({base}):", pou.pos)
        edges = [d for d in own if d.edge]
        # an edge input's previous value (generated names have a lower-case letter)
        slots = [ident(d.name) for d in own] + [f"_e_{ident(d.name)}" for d in edges] + (
            ["_sfc"] if pou.is_sfc else [])
        e(1, "__slots__ = (" + "".join(f"'{k}', " for k in slots) + ")")
        self._fb_constructor(fb, scope, own, edges)
        temps = self._fb_body(fb, scope)
        for m in pou.methods:
            self._method(m, fb, scope)
        for p in pou.properties:
            self._property(p, fb, scope)
        for a in list(pou.actions) + (list(pou.body.actions) if pou.is_sfc else []):
            e(1, f"def a_{ident(a.name)}(self):", a.pos)
            self._stmts(a.body, scope, 2)
            e(2, "pass")
        self._fb_snap(fb, scope, [d for d in own if d not in temps], edges)

    def _fb_constructor(self, fb: FbT, scope: Scope, own: list, edges: list) -> None:
        """``__init__``: the base's, each variable's initial value, then the FB_init
        calls of the instances it holds, the edge inputs' memories, the SFC runtime."""
        e = self.src.emit
        e(1, "def __init__(self):")
        if fb.base:
            e(2, f"{fb.base.cls_name}.__init__(self)")
        self._variables_init(own, lambda d: scope.names[ident(d.name)][1], scope)
        for d in edges:
            e(2, f"self._e_{ident(d.name)} = False", d.pos)
        if fb.pou.is_sfc:
            e(2, f"self._sfc = _SfcRuntime({self._sfc_spec(fb, scope)}, self)")
            e(2, "_register(self._sfc)")
        e(2, "pass")

    def _variables_init(self, decls, type_of, scope: Scope) -> None:
        """In ``__init__``: each variable's initial value, then, once all have theirs, the
        FB_init calls of the FB instances among them."""
        for d in decls:
            self.src.emit(2, f"self.{ident(d.name)} = "
                             f"{self._init(type_of(d), d.init, scope, d)}", d.pos)
        for d in decls:
            self._fb_init_calls(f"self.{ident(d.name)}", type_of(d), d, scope, 2)

    def _fb_body(self, fb: FbT, scope: Scope) -> list:
        """``_body``: the VAR_TEMP reset, then the code (an SFC's runtime). Returns the
        VAR_TEMP declarations."""
        e = self.src.emit
        pou = fb.pou
        e(1, "def _body(self):")
        temps = [d for b in pou.var_blocks if b.kind == "VAR_TEMP" for d in b.decls]
        for d in temps:
            t = scope.names[ident(d.name)][1]
            e(2, f"self.{ident(d.name)} = {self._init(t, d.init, scope, d)}", d.pos)
        if pou.is_sfc:
            e(2, "self._sfc.run(_now)")
        else:
            self._stmts(pou.body, scope, 2)
        e(2, "pass")
        return temps

    def _fb_snap(self, fb: FbT, scope: Scope, kept: list, edges: list) -> None:
        """``_snap``: the instance's compared state (its variables but VAR_TEMP and the
        sinks, counters held at their threshold, edge memories, SFC state, the base's)."""
        sinks, et_matters = self.compared.sinks(fb, scope, self.time_constants,
                                                fb.name in self._et_classes)
        if et_matters:
            self.reads_et = True
        counted = self.compared.threshold_counters(fb, scope) - sinks
        parts = [f"self.{ident(d.name)}.key_counted(rel)" if ident(d.name) in counted else
                 self._snap_code(f"self.{ident(d.name)}", scope.names[ident(d.name)][1])
                 for d in kept if ident(d.name) not in sinks]
        parts += [f"self._e_{ident(d.name)}" for d in edges]
        if fb.pou.is_sfc:
            parts.append("self._sfc.key(rel)")
        if fb.base:
            parts.append(f"{fb.base.cls_name}._snap(self, rel)")
        self.src.emit(1, "def _snap(self, rel):")
        self.src.emit(2, "return (" + "".join(p + ", " for p in parts) + ")")

    @staticmethod
    def _snap_code(code: str, t) -> str:
        """The code of a hashable snapshot of value ``code`` of type ``t``."""
        if t.cat in ("fb", "struct"):
            return f"{code}._snap(rel)"
        if t.cat == "stdfb":
            return f"{code}.key(rel)"
        if t.cat == "array":
            if len(t.dims) == 1:
                if isinstance(t.elem, (Elem, EnumT)):
                    return f"tuple({code})"
                if t.elem.cat in ("fb", "struct"):
                    return f"tuple([x._snap(rel) for x in {code}])"
                if t.elem.cat == "stdfb":
                    return f"tuple([x.key(rel) for x in {code}])"
            return f"_snap_any({code}, rel)"
        if t.cat in ("ptr", "itf"):
            return f"_refkey({code})"
        return code

    # ---------------------------------------------------------------- FB_init
    def _fb_init_calls(self, code: str, t, d: ir.VarDecl, scope: Scope, ind: int) -> None:
        """CODESYS/TwinCAT FB_init: once every variable of the instance holding ``d`` has
        its initial value, each FB instance ``d`` declares (every element of an array of
        them) runs its FB_init (:meth:`_fb_init_code`)."""
        inner = t
        while isinstance(inner, ArrayT):
            inner = inner.elem
        if not isinstance(inner, FbT) or not fb_inits(inner):
            return
        e = self.src.emit
        per = d.element_init_args
        if per is not None:
            # each element its own arguments, in element order (the last index fastest);
            # elements the list does not reach get none
            k = self.src.temp("fbk")
            e(ind, f"{k} = 0", d.pos)
        while isinstance(t, ArrayT):
            for _ in t.dims:
                var = self.src.temp("fbi")
                e(ind, f"for {var} in {code}:", d.pos)
                code, ind = var, ind + 1
            t = t.elem
        if per is None:
            for line in self._fb_init_code(code, inner, d, scope):
                e(ind, line, d.pos)
            return
        for n, args in enumerate(per + [[]]):
            e(ind, "else:" if n == len(per) else f"{'el' if n else ''}if {k} == {n}:", d.pos)
            one = dataclasses.replace(d, init_args=args, element_init_args=None)
            for line in self._fb_init_code(code, inner, one, scope):
                e(ind + 1, line, d.pos)
        e(ind, f"{k} += 1", d.pos)

    def _fb_init_code(self, code: str, t: FbT, d: ir.VarDecl, scope: Scope) -> list[str]:
        """The FB_init calls of instance ``code`` of ``t`` declared by ``d``: bInitRetains
        and bInCopyCode FALSE and the declaration's arguments (``fb : FB_T(5)``), a base
        FB's FB_init first, each with the arguments its own parameters take."""
        out = []
        for ft, m in fb_inits(t):
            call = ir.Call(ir.Name("FB_init", pos=d.pos), _fb_init_args(m, d), pos=d.pos)
            out.append(f"{ft.cls_name}.m_FB_INIT({code}, "
                       f"{self._named_args(m.var_blocks, call, scope, ft.name + '.FB_init')})")
        return out


def _fb_init_args(m: ir.Method, d: ir.VarDecl) -> list[ir.Arg]:
    """The arguments of FB_init method ``m`` for declaration ``d``: its two flags FALSE
    (a first download: no retains kept, no online change) and the declaration's own, by
    name, positional ones in the order of the parameters after the flags; arguments
    ``m`` has no parameter for are left out (a base FB's FB_init with fewer)."""
    params = [x for b in m.var_blocks if b.kind in ("VAR_INPUT", "VAR_IN_OUT")
              for x in b.decls]
    names = {ident(x.name) for x in params}
    args = [ir.Arg(x.name, ir.Literal(False, "BOOL", pos=d.pos), pos=d.pos)
            for x in params if ident(x.name) in _FB_INIT_FLAGS]
    rest = [x for x in params if ident(x.name) not in _FB_INIT_FLAGS]
    for k, a in enumerate(d.init_args or []):
        name = a.name if a.name is not None else (rest[k].name if k < len(rest) else None)
        if name is not None and ident(name) in names:
            args.append(ir.Arg(name, a.value, pos=a.pos))
    return args
