"""Expressions: each compiles to (Python code, type)."""
from __future__ import annotations

import re

from ...parser import ir
from ...parser.errors import ProgramError
from ...parser.names import ident
from .. import types as ty
from ..types import BOOL, STRING, TIME, ArrayT, EnumT, FbT, ItfT, PtrT, StdFbT, StructT
from .common import COMPARISONS, Scope, error_at, stdfb_member
from .conversions import check_bit, deref_t, is_object_t, wider
from .flow import et_threshold

_LOGICAL = ("AND", "AND_THEN", "OR", "OR_ELSE", "XOR", "&")


class ExpressionsMixin:
    """Part of :class:`~.project.Compiler`: values read and computed."""

    def _expr(self, x, scope: Scope, expect=None, callee=False):
        """(Python code, type) of an expression."""
        if isinstance(x, ir.Literal):
            return self._literal(x, expect)
        if isinstance(x, ir.EnumLiteral):
            t = self.types.named(x.type_name, x.pos)
            if not isinstance(t, EnumT) or x.value.upper() not in t.values:
                raise error_at(x, f"'{x.value}' is not a value of {x.type_name}")
            return str(t.values[x.value.upper()]), t
        if isinstance(x, ir.Name):
            return self._name(x, scope, expect)
        if isinstance(x, ir.Member):
            return self._member(x, scope)
        if isinstance(x, ir.Index):
            bcode, bt = self._expr(x.base, scope)
            lst, idx, et = self._index(bcode, deref_t(bt), x, scope)
            return f"{lst}[{idx}]", et
        if isinstance(x, ir.BitAccess):
            code, t = self._expr(x.base, scope)
            check_bit(x, t)
            return f"_getbit({code}, {x.bit})", BOOL
        if isinstance(x, ir.AssignExpr):
            return self._assign_expr(x, scope)
        if isinstance(x, ir.Deref):
            return self._deref(x, scope)
        if isinstance(x, ir.Unary):
            return self._unary(x, scope, expect)
        if isinstance(x, ir.Binary):
            return self._binary(x, scope, expect)
        if isinstance(x, ir.Call):
            return self._call_expr(x, scope)
        if isinstance(x, ir.DirectAddress):
            return self._name(self._direct(x, scope), scope, expect)
        raise error_at(x, f"unsupported expression {type(x).__name__}")

    def _deref(self, x: ir.Deref, scope: Scope):
        if isinstance(x.base, ir.Name) and ident(x.base.name) == "THIS":
            if scope.fb is None:
                raise error_at(x, "THIS^ outside a function block")
            return "self", scope.fb
        code, t = self._expr(x.base, scope)
        if not isinstance(t, PtrT):
            raise error_at(x, "'^' applied to something that is not a pointer")
        if is_object_t(t.target):
            return code, t.target
        return f"{code}.get()", t.target

    def _unary(self, x: ir.Unary, scope: Scope, expect):
        code, t = self._expr(x.operand, scope, expect)
        if x.op == "-":
            return f"(-{code})", t
        if x.op == "+":
            return code, t
        if t.cat == "bool":
            return f"(not {code})", BOOL
        if t.cat == "int" and getattr(t, "bits", 0) and not t.signed:
            return f"({code} ^ {(1 << t.bits) - 1})", t
        return f"(~{code})", t

    def _literal(self, x: ir.Literal, expect):
        v, tn = x.value, ident(x.type_name)
        if tn == "BOOL":
            return ("True" if v else "False"), BOOL
        if tn == "ANY_INT":
            if expect is not None and expect.cat == "real":
                return repr(float(v)), ty.ANY_REAL
            return repr(int(v)), ty.ANY_INT
        if tn == "ANY_REAL":
            return repr(float(v)), ty.ANY_REAL
        if tn in ("STRING", "WSTRING", "CHAR", "WCHAR"):
            return repr(v), STRING
        t = ty.elementary(tn) or self.types.named(tn, x.pos)
        if isinstance(t, EnumT):
            return str(v), t
        if t.cat == "real":
            return repr(float(v)), t
        return repr(int(v) if not isinstance(v, bool) else bool(v)), t

    def _name(self, x: ir.Name, scope: Scope, expect=None):
        key = ident(x.name)
        if key in scope.names:
            code, t = scope.names[key]
            if isinstance(t, PtrT) and t.reference:
                return (code, t.target) if is_object_t(t.target) else (f"{code}.get()",
                                                                       t.target)
            return code, t
        if key in scope.steps:
            raise error_at(x, f"step {x.name} used as a value: use {x.name}.X or {x.name}.T")
        if isinstance(expect, EnumT) and key in expect.values:
            return str(expect.values[key]), expect
        cands = self.types.enum_candidates(key)
        if cands:
            t, v = cands[0]
            return str(v), t
        if key in ("TRUE", "FALSE"):
            return ("True" if key == "TRUE" else "False"), BOOL
        if key == "NULL":  # CODESYS/TwinCAT: the null pointer
            return "None", PtrT(ty.elementary("BYTE"))
        raise error_at(x, f"'{x.name}' is not declared here")

    # ---------------------------------------------------------------- members
    def _member(self, x: ir.Member, scope: Scope):
        key = ident(x.member)
        if isinstance(x.base, ir.Name):
            named = self._named_member(x, scope, key)
            if named is not None:
                return named
        bcode, bt = self._expr(x.base, scope)
        bt = deref_t(bt)
        if isinstance(bt, StdFbT):
            return self._stdfb_member(x, scope, bcode, bt, key)
        if isinstance(bt, StructT):
            if key not in bt.members:
                raise error_at(x, f"{bt.name} has no member '{x.member}'")
            return f"{bcode}.{key}", bt.members[key]
        if isinstance(bt, (FbT, ItfT)):
            if isinstance(bt, FbT):
                d = bt.var(key)
                if d is not None:
                    return f"{bcode}.{key}", self.types.resolve(d.type, d.pos)
            p = bt.prop(key)
            if p is not None:
                return f"{bcode}.p_get_{key}()", self.types.resolve(p[0].type, p[0].pos)
            raise error_at(x, f"{bt.name} has no variable or property '{x.member}'")
        if bt.cat == "int" and re.fullmatch(r"[0-9]{1,3}", x.member):
            why = ty.bit_access_error(bt, int(x.member))
            if why is not None:
                raise error_at(x, why)
            return f"_getbit({bcode}, {int(x.member)})", BOOL
        raise error_at(x, f"'.{x.member}' applied to a value of type "
                          f"{getattr(bt, 'name', bt)}")

    def _named_member(self, x: ir.Member, scope: Scope, key: str):
        """``name.member`` where the name is no variable: an SFC step's flag or time, a
        value of an enumeration type, a variable of a global variable list; else None."""
        base = x.base
        bkey = ident(base.name)
        if bkey in scope.steps and bkey not in scope.names:
            i = scope.steps[bkey]
            if key == "X":
                return f"self._sfc.x[{i}]", BOOL
            if key == "T":
                return f"self._sfc.t({i}, _now)", TIME
            raise error_at(x, f"a step has .X and .T, not .{x.member}")
        if bkey not in scope.names:
            try:
                t = self.types.named(base.name)
            except ProgramError:
                t = None
            if isinstance(t, EnumT):
                if key not in t.values:
                    raise error_at(x, f"'{x.member}' is not a value of {base.name}")
                return str(t.values[key]), t
            if bkey in self.gvl_names:
                return self._name(ir.Name(x.member, pos=x.pos), scope)
        return None

    def _stdfb_member(self, x: ir.Member, scope: Scope, bcode: str, bt: StdFbT, key: str):
        key, pt = stdfb_member(bt, key)
        if key is None:
            raise error_at(x, f"{bt.name} has no member '{x.member}'")
        if key == "ET" and not self._et_const:
            # inside an FB or PROGRAM the data flow decides whether it matters
            # (ComparedState.sinks); elsewhere assume it does
            if scope.fb is None:
                self.reads_et = True
            else:
                self._et_classes.add(scope.fb.name)
        return f"{bcode}.{key}", pt

    def _index(self, bcode, bt, node: ir.Index, scope):
        """(list code, index code, element type) of the last dimension."""
        if not isinstance(bt, ArrayT):
            raise error_at(node, "indexing something that is not an array")
        if len(node.indices) > len(bt.dims):
            raise error_at(node, f"{len(node.indices)} indices for an array of "
                                 f"{len(bt.dims)} dimensions")
        code = bcode
        idx_codes = []
        for (lo, hi), ie in zip(bt.dims, node.indices):
            ic, _ = self._expr(ie, scope)
            if isinstance(ie, ir.Literal) and isinstance(ie.value, int):
                if not lo <= ie.value <= hi:
                    raise error_at(ie, f"index {ie.value} outside [{lo}..{hi}]")
                idx_codes.append(str(ie.value - lo))
            else:
                ix = self.src.temp("ix")
                idx_codes.append(f"(({ix} - {lo}) if {lo} <= ({ix} := {ic}) <= {hi} else "
                                 f"_chkidx({ix}, {lo}, {hi}, {_describe(node.base)!r}))")
        for ic in idx_codes[:-1]:
            code = f"{code}[{ic}]"
        n = len(node.indices)
        et = bt.elem if n == len(bt.dims) else ArrayT(bt.dims[n:], bt.elem)
        return code, idx_codes[-1], et

    # ---------------------------------------------------------------- operators
    def _binary(self, x: ir.Binary, scope: Scope, expect):
        op = x.op
        threshold = et_threshold(x, self.time_constants)
        if threshold is not None:
            # the comparison can only flip when ET crosses the constant: an event
            self.et_thresholds.add(threshold)
            self._et_const = True
        try:
            lc, lt = self._expr(x.left, scope, expect if op not in COMPARISONS else None)
            rc, rt = self._expr(x.right, scope,
                                lt if isinstance(lt, EnumT) or lt.cat == "real"
                                else expect if op not in COMPARISONS else None)
        finally:
            self._et_const = False
        if lt.cat == "int" and rt.cat == "real" and isinstance(x.left, ir.Literal):
            lc = repr(float(lc))
        if (lt.cat == "string") != (rt.cat == "string") and "void" not in (lt.cat, rt.cat):
            raise error_at(x, f"'{op}' between {getattr(lt, 'name', lt.cat)} and "
                              f"{getattr(rt, 'name', rt.cat)}: convert one of them first")
        if op in ("=", "<>") and _is_null_test(lt, rt, x):
            # a pointer, reference or interface against 0: CODESYS' test for NULL
            side = lc if lt.cat in ("ptr", "itf") else rc
            return f"({side} {'is' if op == '=' else 'is not'} None)", BOOL
        if op in COMPARISONS:
            return f"({lc} {COMPARISONS[op]} {rc})", BOOL
        if op in _LOGICAL:
            return _logical(x, op, lc, lt, rc, rt)
        cats = {lt.cat, rt.cat}
        if cats & {"time", "date"}:
            return _time_arithmetic(x, op, lc, lt, rc, rt)
        if "string" in cats:
            if op == "+":
                return f"({lc} + {rc})", STRING
            raise error_at(x, f"'{op}' on strings")
        if op == "**":
            return f"_expt({lc}, {rc})", ty.REAL
        if "real" in cats:
            t = lt if lt.cat == "real" and lt is not ty.ANY_REAL else (
                rt if rt.cat == "real" else lt)
            if op == "/":
                return f"_fdiv({lc}, {rc})", t
            if op == "MOD":
                return f"_fmod({lc}, {rc})", t
            return f"({lc} {op} {rc})", t
        t = wider(lt, rt)
        if op == "/":
            return f"_idiv({lc}, {rc})", t
        if op == "MOD":
            return f"_imod({lc}, {rc})", t
        return f"({lc} {op} {rc})", t


def _logical(x: ir.Binary, op: str, lc: str, lt, rc: str, rt):
    """AND, OR, XOR of two BOOLs (Python's logic) or two bit strings (bitwise)."""
    if {lt.cat, rt.cat} - {"bool", "int"} or (lt.cat == "bool") != (rt.cat == "bool"):
        raise error_at(x, f"{op} needs two BOOL or two bit-string/integer operands, not "
                          f"{getattr(lt, 'name', lt.cat)} and {getattr(rt, 'name', rt.cat)}")
    op = "AND" if op == "&" else op
    if lt.cat == "bool" and rt.cat == "bool":
        if op == "XOR":
            return f"({lc} != {rc})", BOOL
        py = "and" if op.startswith("AND") else "or"
        return f"({lc} {py} {rc})", BOOL
    py = "&" if op.startswith("AND") else "|" if op.startswith("OR") else "^"
    return f"({lc} {py} {rc})", wider(lt, rt)


def _time_arithmetic(x: ir.Binary, op: str, lc: str, lt, rc: str, rt):
    """Arithmetic with a TIME, DATE or DT operand (integer nanoseconds)."""
    if op in ("+", "-"):
        if lt.cat == "date" and rt.cat == "date":
            return f"({lc} - {rc})", TIME
        return f"({lc} {op} {rc})", lt if lt.cat in ("time", "date") else rt
    if op == "*":
        if lt.cat == "time":
            return f"_tmul({lc}, {rc})", lt
        return f"_tmul({rc}, {lc})", rt
    if op == "/":
        if rt.cat == "time":
            return f"_idiv({lc}, {rc})", ty.DINT
        return f"_tdiv({lc}, {rc})", lt
    if op == "MOD":
        return f"_imod({lc}, {rc})", lt
    raise error_at(x, f"'{op}' on TIME values")


def _is_null_test(lt, rt, x: ir.Binary) -> bool:
    """Is ``x`` a pointer/reference/interface compared with the literal 0?"""
    def zero(e):
        return isinstance(e, ir.Literal) and e.value == 0 and not isinstance(e.value, bool)
    return (lt.cat in ("ptr", "itf") and zero(x.right)) or (
        rt.cat in ("ptr", "itf") and zero(x.left))


def _describe(e) -> str:
    if isinstance(e, ir.Name):
        return e.name
    if isinstance(e, ir.Member):
        return f"{_describe(e.base)}.{e.member}"
    return "array"
