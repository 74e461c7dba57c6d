"""FUNCTIONs, methods and property accessors: Python functions whose variables are
Python locals, with VAR_IN_OUT and VAR_OUTPUT passed back through references."""
from __future__ import annotations

import dataclasses

from ...parser import ir
from ...parser.names import ident
from ..types import FbT
from .common import Scope, shown_name
from .conversions import has_fb


class CallablesMixin:
    """Part of :class:`~.project.Compiler`: the callables of the generated module."""

    def _local_scope(self, outer: Scope, var_blocks, extra=()) -> tuple[Scope, list]:
        """``outer`` with the variables of ``var_blocks`` (and ``extra`` (key, type)) as
        Python locals; also [(block kind, declaration, type)] of those variables."""
        sc = Scope(names=dict(outer.names), fb=outer.fb, cls=outer.cls, steps=outer.steps,
                   pou=outer.pou)
        params = []
        for b in var_blocks:
            for d in b.decls:
                key = ident(d.name)
                t = self.types.resolve(d.type, d.pos)
                sc.names[key] = (key, t)
                sc.pylocals.add(key)
                params.append((b.kind, d, t))
        for key, t in extra:
            sc.names[key] = (key, t)
            sc.pylocals.add(key)
        return sc, params

    def _callable(self, header: str, scope: Scope, var_blocks, body, ret_name, ret_t, ind,
                  pos):
        """The shared shape of functions, methods and property accessors."""
        e = self.src.emit
        extra = [(ret_name, ret_t)] if ret_t is not None else []
        sc, params = self._local_scope(scope, var_blocks, extra)
        args = []
        for kind, d, t in params:
            key = ident(d.name)
            if kind == "VAR_INPUT":
                args.append(f"{key}=_dflt")
            elif kind in ("VAR_OUTPUT", "VAR_IN_OUT"):
                args.append(f"_r_{key}=None")
        e(ind, header.replace("ARGS", ", ".join(args)), pos)
        self._parameters(params, sc, ind + 1)
        if ret_t is not None:
            e(ind + 1, f"{ret_name} = {self._init(ret_t, None, sc, None)}")
        outs = [(ident(d.name)) for kind, d, t in params if kind in ("VAR_OUTPUT",
                                                                      "VAR_IN_OUT")]
        sc.ret = f"return {ret_name}" if ret_t is not None else "return"
        if outs:
            e(ind + 1, "try:")
            self._stmts(body, sc, ind + 2)
            e(ind + 2, "pass")
            e(ind + 1, "finally:")
            for key in outs:
                e(ind + 2, f"if _r_{key} is not None: _r_{key}.set({key})")
        else:
            self._stmts(body, sc, ind + 1)
        e(ind + 1, sc.ret)

    def _parameters(self, params: list, sc: Scope, ind: int) -> None:
        """Each variable's value as the call begins: an input's argument (else its
        initial value), an in-out's referent, any other its initial value."""
        e = self.src.emit
        for kind, d, t in params:
            key = ident(d.name)
            init = self._init(t, d.init, sc, d)
            if has_fb(t):
                # a call's own instances must not join the executor's list of live timers
                init = f"_unlisted(lambda: {init})"
            if kind == "VAR_INPUT":
                conv = f"_copy({key})" if t.cat in ("struct", "array") else key
                e(ind, f"{key} = {init} if {key} is _dflt else {conv}", d.pos)
            elif kind == "VAR_IN_OUT":
                e(ind, f"{key} = _r_{key}.get() if _r_{key} is not None else {init}", d.pos)
            else:
                e(ind, f"{key} = {init}", d.pos)

    def _function(self, f: ir.Pou):
        ret_t = self.types.resolve(f.return_type, f.pos) if f.return_type else None
        scope = Scope(names={k: (f"_g.{k}", t) for k, (n, t, d) in self.globals.items()},
                      pou=f.name)
        blocks = [b for b in f.var_blocks if b.kind != "VAR_EXTERNAL"]
        self._callable(f"def _fn_{ident(f.name)}(ARGS):", scope, blocks, f.body,
                       ident(f.name), ret_t, 0, f.pos)

    def _method(self, m: ir.Method, fb: FbT, scope: Scope):
        ret_t = self.types.resolve(m.return_type, m.pos) if m.return_type else None
        scope = dataclasses.replace(scope, pou=f"{shown_name(fb.pou)}.{m.name}")
        self._callable(f"def m_{ident(m.name)}(self, ARGS):", scope, m.var_blocks, m.body,
                       ident(m.name), ret_t, 1, m.pos)

    def _property(self, p: ir.Property, fb: FbT, scope: Scope):
        t = self.types.resolve(p.type, p.pos)
        for acc in p.accessors:
            if acc.kind == "GET":
                self._callable(f"def p_get_{ident(p.name)}(self, ARGS):", scope,
                               acc.var_blocks, acc.body, ident(p.name), t, 1, acc.pos)
            else:
                blocks = [ir.VarBlock("VAR_INPUT", [ir.VarDecl(p.name, p.type)])]
                blocks += acc.var_blocks
                self._callable(f"def p_set_{ident(p.name)}(self, ARGS):", scope, blocks,
                               acc.body, "p_ret", None, 1, acc.pos)
