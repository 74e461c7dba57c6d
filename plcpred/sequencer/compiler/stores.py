"""Writes: assignment targets, stores (as statements and inside expressions), and
references to variables (ADR, REF=, VAR_IN_OUT and the outputs of calls)."""
from __future__ import annotations

from ...parser import ir
from ...parser.names import ident
from ..types import FbT, ItfT, PtrT, StdFbT, StructT
from .common import Scope, error_at, stdfb_member
from .conversions import check_bit, convert, deref_t, is_object_t
from .flow import target_names


class StoresMixin:
    """Part of :class:`~.project.Compiler`: where values are written."""

    def _store(self, target, code: str, vt, scope: Scope, ind: int, pos, raw=False,
               rebind=False):
        """Emit ``target := code`` (converted from ``vt`` unless ``raw``); ``rebind``
        (REF=): a reference target is set to refer elsewhere, not written through."""
        e = self.src.emit
        if isinstance(target, ir.BitAccess):
            bcode, bt = self._expr(target.base, scope)
            check_bit(target, bt)
            self._store(target.base, f"_setbit({bcode}, {target.bit}, {code})", bt, scope,
                        ind, pos, raw=True)
            return
        kind, a, b, tt = self._lvalue(target, scope)
        value = code if raw else convert(code, vt, tt, target, copy=True)
        if kind == "name":
            e(ind, f"{a} = {value}", pos)
        elif kind == "attr":
            e(ind, f"{a}.{b} = {value}", pos)
        elif kind == "item":
            e(ind, f"{a}[{b}] = {value}", pos)
        elif kind == "prop":
            e(ind, f"{a}.p_set_{b}({value})", pos)
        elif kind == "deref" and rebind:
            e(ind, f"{a} = {value}", pos)
        elif kind == "deref":
            e(ind, f"{a}.set({value})", pos)

    def _assign_expr(self, x: ir.AssignExpr, scope: Scope):
        """``(target := value)``: the store as an expression that gives the stored value."""
        if isinstance(x.target, ir.BitAccess):
            raise error_at(x, "an assignment to a bit inside an expression is not supported")
        tt = self._lvalue(x.target, scope)[3]
        code, vt = self._expr(x.value, scope, tt)
        return self._store_expr(x.target, convert(code, vt, tt, x.target, copy=True),
                                scope), tt

    def _store_expr(self, target, value: str, scope: Scope) -> str:
        """An expression that stores ``value`` (code of the target's type) in ``target``
        and gives it (an assignment inside an expression; __DELETE clearing a pointer)."""
        kind, a, b, _ = self._lvalue(target, scope)
        if kind == "name":
            return f"({a} := {value})"
        if kind == "attr":
            return f"_Ref({a}, {b!r}).assign({value})"
        if kind == "item":
            return f"_ItemRef({a}, {b}).assign({value})"
        if kind == "deref":
            return f"{a}.assign({value})"
        raise error_at(target, "this cannot be assigned to inside an expression")

    def _lvalue(self, target, scope: Scope):
        """('name', code) | ('attr', obj, ATTR) | ('item', list, index) | ('prop', obj, NAME)
        | ('deref', ref), with the target's type."""
        if isinstance(target, ir.DirectAddress):
            target = self._direct(target, scope)
        if isinstance(target, ir.Name):
            key = ident(target.name)
            if key not in scope.names:
                raise error_at(target, f"'{target.name}' is not a variable here")
            code, t = scope.names[key]
            if isinstance(t, PtrT) and t.reference and not is_object_t(t.target):
                return "deref", code, None, t.target
            if "." in code:
                obj, attr = code.rsplit(".", 1)
                return "attr", obj, attr, t
            return "name", code, None, t
        if isinstance(target, ir.Member):
            return self._member_lvalue(target, scope)
        if isinstance(target, ir.Index):
            bcode, bt = self._expr(target.base, scope)
            bt = deref_t(bt)
            lst, idx, et = self._index(bcode, bt, target, scope)
            return "item", lst, idx, et
        if isinstance(target, ir.Deref):
            code, t = self._expr(target.base, scope)
            if isinstance(t, PtrT) and not is_object_t(t.target):
                return "deref", code, None, t.target
            raise error_at(target, "assignment through a pointer to a structure or function "
                                   "block is not supported")
        raise error_at(target, "this cannot be assigned to")

    def _member_lvalue(self, target: ir.Member, scope: Scope):
        if isinstance(target.base, ir.Name) and ident(target.base.name) in self.gvl_names:
            return self._lvalue(ir.Name(target.member, pos=target.pos), scope)
        bcode, bt = self._expr(target.base, scope)
        bt = deref_t(bt)
        key = ident(target.member)
        if isinstance(bt, (FbT, ItfT)):
            if isinstance(bt, FbT) and bt.var(key) is not None:
                d = bt.var(key)
                return "attr", bcode, key, self.types.resolve(d.type, d.pos)
            p = bt.prop(key)
            if p is not None:
                return "prop", bcode, key, self.types.resolve(p[0].type, p[0].pos)
        elif isinstance(bt, StdFbT):
            pin, pt = stdfb_member(bt, key)
            if pin:
                return "attr", bcode, pin, pt
        elif isinstance(bt, StructT) and key in bt.members:
            return "attr", bcode, key, bt.members[key]
        raise error_at(target, f"'{target.member}' is not a member that can be assigned")

    # ---------------------------------------------------------------- references
    def _ref_of(self, x, scope: Scope, for_call=False):
        """Code for a reference to ``x`` (ADR, REF=, VAR_IN_OUT and outputs of calls)."""
        self._referenced(x)
        if isinstance(x, ir.Name) and ident(x.name) in scope.names:
            code, t = scope.names[ident(x.name)]
            if isinstance(t, PtrT) and t.reference:
                # a reference variable refers on to what it refers to (r2 REF= r1)
                return code, t
        if isinstance(x, ir.Name) and ident(x.name) in scope.pylocals:
            return self._local_ref(x, scope, for_call)
        code, t = self._expr(x, scope)
        if is_object_t(t):
            return code, PtrT(t)
        if isinstance(x, ir.Index):
            bcode, bt = self._expr(x.base, scope)
            lst, idx, et = self._index(bcode, deref_t(bt), x, scope)
            return f"_ItemRef({lst}, {idx})", PtrT(et)
        if isinstance(x, (ir.Name, ir.Member)) and "." in code and code.rsplit(".", 1)[
                1].isidentifier() and not code.endswith(")"):
            obj, attr = code.rsplit(".", 1)
            return f"_Ref({obj}, {attr!r})", PtrT(t)
        raise error_at(x, "a reference needs a variable here")

    def _local_ref(self, x: ir.Name, scope: Scope, for_call: bool):
        """A reference to a Python local: an object is itself; an elementary value is
        boxed around the call it is an argument of (:meth:`_boxed`)."""
        key = ident(x.name)
        t = scope.names[key][1]
        if is_object_t(t):
            return key, PtrT(t)
        if not for_call:
            raise error_at(x, f"a reference to the local variable {x.name} of a function "
                              "or method is not supported")
        if self._boxes is None:
            raise error_at(x, "a reference to a local variable is only possible as a call "
                              "argument")
        box = self.src.temp("box")
        self._boxes.append((box, key))
        return box, PtrT(t)

    def _referenced(self, x) -> None:
        """Record that ``x`` may be written through a reference to it."""
        if self.referenced is not None and not target_names(x, self.referenced):
            self.referenced = None
