"""The IEC 61131-3 standard functions (and the CODESYS/TwinCAT ones plcpred runs): type
conversions, selection, arithmetic, strings, references, memory, and ``__NEW``."""
from __future__ import annotations

import re

from ...parser import ir
from ...parser.names import ident
from ...parser.stdlib import WIDE_STRING_FUNCTIONS
from .. import types as ty
from ..types import BOOL, STRING, TIME, FbT, PtrT
from .common import Scope, error_at, fb_inits, pos_args
from .conversions import is_object_t, wider

_CONV = re.compile(r"^(?:([A-Z_]+?)_)?TO_([A-Z_]+)$")
_MATH = ("SQRT", "LN", "LOG", "EXP", "SIN", "COS", "TAN", "ASIN", "ACOS", "ATAN", "ATAN2",
         "EXPT")
# standard functions that are an operator of two operands
_BINARY = {"SUB": "-", "DIV": "/", "MOD": "MOD", "GT": ">", "GE": ">=", "EQ": "=",
           "LE": "<=", "LT": "<", "NE": "<>"}
_STRING_ARGS = {"LEFT": 2, "RIGHT": 2, "MID": 3, "INSERT": 3, "DELETE": 3, "REPLACE": 4}
_INT = ty.Elem("INT", "int", 16, True)


def _need(key: str, call: ir.Call, vals: list, n: int) -> None:
    """An error unless the call has at least ``n`` arguments."""
    if len(vals) < n:
        raise error_at(call, f"{key} needs {n} argument{'s' if n > 1 else ''}")


class StdFunctionsMixin:
    """Part of :class:`~.project.Compiler`: calls of standard functions."""

    def _std_function(self, key: str, call: ir.Call, scope: Scope):
        key = WIDE_STRING_FUNCTIONS.get(key, key)     # WLEN is LEN on a WSTRING
        args = [a for a in call.args if not a.output]
        if key == "__NEW":
            return self._new(call, args, scope)
        if key == "XSIZEOF":            # TwinCAT: SIZEOF as a platform-wide integer
            key = "SIZEOF"
        on_form = self._std_on_argument_form(key, call, args, scope)
        if on_form is not None:
            return on_form
        vals = [self._expr(a.value, scope) for a in args]
        if _CONV.match(key) or key.startswith("TRUNC") or "_TRUNC_" in key:
            _need(key, call, vals, 1)
            return _conversion(key, call, *vals[0])
        for group in (self._std_numeric, self._std_strings, self._std_references):
            out = group(key, call, args, vals, scope)
            if out is not None:
                return out
        raise error_at(call, f"standard function {key} is not supported by the executor")

    def _std_on_argument_form(self, key: str, call: ir.Call, args: list, scope: Scope):
        """The functions that look at what their argument is rather than its value:
        ``SIZEOF(type)``, ``__ISVALIDREF(ref)``, ``__DELETE(ptr)``; None for others."""
        if key == "SIZEOF" and len(args) == 1 and isinstance(args[0].value, ir.TypeExpr):
            spec = args[0].value.type
            if isinstance(spec, ir.StringType) and isinstance(spec.length, ir.Literal) \
                    and isinstance(spec.length.value, int):
                # SIZEOF(STRING(10)): the characters and the terminator
                return str((spec.length.value + 1) * (2 if spec.wide else 1)), ty.DINT
            size = ty.byte_size(self.types.resolve(spec, args[0].value.pos))
            if size is None:
                raise error_at(call, "SIZEOF of this type is not known to the executor")
            return str(size), ty.DINT
        if key == "__ISVALIDREF":
            # a reference (or pointer, interface) that refers to something: not NULL
            if len(args) != 1:
                raise error_at(call, "__ISVALIDREF needs one argument: a reference")
            x = args[0].value
            if isinstance(x, ir.Name) and ident(x.name) in scope.names:
                code, t = scope.names[ident(x.name)]
                if t.cat in ("ptr", "itf"):     # the reference itself, not what it refers to
                    return f"({code} is not None)", BOOL
            return self._expr(ir.Binary("<>", args[0].value,
                                        ir.Literal(0, "ANY_INT", pos=call.pos),
                                        pos=call.pos), scope)
        if key == "__DELETE":
            return self._delete(call, args, scope)
        return None

    def _delete(self, call: ir.Call, args: list, scope: Scope):
        """The memory goes with the last pointer to it; the pointer itself reads 0."""
        if len(args) != 1:
            raise error_at(call, "__DELETE needs one argument: the pointer __NEW gave")
        if isinstance(args[0].value, ir.Name) and ident(args[0].value.name) == "THIS" \
                and scope.fb is not None:
            # an instance deleting itself: it goes with the last pointer to it
            return "None", ty.VOID
        _, t = self._expr(args[0].value, scope)
        if t.cat != "ptr":
            raise error_at(call, "__DELETE needs a pointer (what __NEW gave)")
        self._referenced(args[0].value)
        return self._store_expr(args[0].value, "None", scope), ty.VOID

    def _std_numeric(self, key: str, call: ir.Call, args: list, vals: list, scope: Scope):
        """Selection, bit shifts, arithmetic and comparisons; None for other functions."""
        codes = [c for c, _ in vals]
        ts = [t for _, t in vals]
        first = next((t for t in ts if t not in (ty.ANY_INT, ty.ANY_REAL)),
                     ts[0] if ts else ty.ANY_INT)
        if key in ("MIN", "MAX"):
            _need(key, call, vals, 1)
            return f"{key.lower()}({', '.join(codes)})", first
        if key == "LIMIT":
            _need(key, call, vals, 3)
            return f"_limit({', '.join(codes)})", first
        if key == "SEL":
            _need(key, call, vals, 3)
            return f"_sel({', '.join(codes)})", wider(ts[1], ts[2])
        if key == "MUX":
            _need(key, call, vals, 2)
            return f"_mux({', '.join(codes)})", ts[1]
        if key == "MOVE":
            _need(key, call, vals, 1)
            return codes[0], ts[0]
        if key in ("SHL", "SHR", "ROL", "ROR"):
            _need(key, call, vals, 2)
            bits = getattr(ts[0], "bits", 0) or 32
            return f"_{key.lower()}({codes[0]}, {codes[1]}, {bits})", ts[0]
        if key == "ABS":
            _need(key, call, vals, 1)
            return f"abs({codes[0]})", ts[0]
        if key in _MATH:
            _need(key, call, vals, 2 if key in ("ATAN2", "EXPT") else 1)
            return f"_math[{key!r}]({', '.join(codes)})", ty.REAL
        if key in ("ADD", "MUL", "AND", "OR", "XOR") and len(args) >= 2:
            op = {"ADD": "+", "MUL": "*"}.get(key, key)
            e = args[0].value
            for a in args[1:]:
                e = ir.Binary(op, e, a.value, pos=call.pos)
            return self._expr(e, scope)
        if key in _BINARY:
            _need(key, call, vals, 2)
            return self._expr(ir.Binary(_BINARY[key], args[0].value, args[1].value,
                                        pos=call.pos), scope)
        if key == "NOT":
            _need(key, call, vals, 1)
            return self._expr(ir.Unary("NOT", args[0].value, pos=call.pos), scope)
        return None

    def _std_strings(self, key: str, call: ir.Call, args: list, vals: list, scope: Scope):
        """String functions; None for other functions."""
        codes = [c for c, _ in vals]
        if key == "LEN":
            _need(key, call, vals, 1)
            return f"len({codes[0]})", _INT
        if key in _STRING_ARGS:
            _need(key, call, vals, _STRING_ARGS[key])
            return f"_{key.lower()}({', '.join(codes)})", STRING
        if key == "FIND":
            _need(key, call, vals, 2)
            return f"_find({codes[0]}, {codes[1]})", _INT
        if key == "CONCAT":
            return "(" + " + ".join(codes or ["''"]) + ")", STRING
        return None

    def _std_references(self, key: str, call: ir.Call, args: list, vals: list,
                        scope: Scope):
        """References, the POU's name, the clock, sizes and memory; None for other
        functions."""
        codes = [c for c, _ in vals]
        if key in ("ADR", "REF"):
            _need(key, call, vals, 1)
            return self._ref_of(args[0].value, scope)
        if key == "__POUNAME":
            return repr(scope.pou), STRING
        if key in ("TIME", "NOW") and not args:
            self.reads_clock = True
            return "_now", TIME
        if key == "SIZEOF":
            _need(key, call, vals, 1)
            size = ty.byte_size(vals[0][1])
            if size is not None:
                return str(size), ty.DINT
            return f"_sizeof({codes[0]})", ty.DINT
        if key in ("MEMCPY", "MEMMOVE", "MEMSET", "MEMCMP"):
            _need(key, call, vals, 3)
            where = pos_args(call.pos)
            fn = "_memcpy" if key in ("MEMCPY", "MEMMOVE") else "_" + key.lower()
            return f"{fn}({', '.join(codes[:3])}, {where})", \
                ty.DINT if key == "MEMCMP" else ty.elementary("UDINT")
        return None

    def _new(self, call: ir.Call, args, scope: Scope):
        """CODESYS/TwinCAT ``__NEW(T)``: a pointer to a new, initialised T (a structure
        or FB instance itself, an elementary value in a cell of its own); an FB runs its
        FB_init, with the arguments of ``__NEW(FB_T(a := 1))``. ``__NEW(T, n)`` (n of
        them, reached by pointer arithmetic) is not supported."""
        first = args[0].value if args and args[0].name is None else None
        init_args = []
        if isinstance(first, ir.Name):
            t = self.types.resolve(ir.NamedType(first.name, pos=first.pos), first.pos)
        elif isinstance(first, ir.Call) and isinstance(first.func, ir.Name):
            t = self.types.resolve(ir.NamedType(first.func.name, pos=first.pos), first.pos)
            init_args = first.args
        elif isinstance(first, ir.TypeExpr):
            t = self.types.resolve(first.type, first.pos)
        else:
            raise error_at(call, "__NEW needs a type: __NEW(INT), __NEW(ST_Data), "
                                 "__NEW(FB_T(a := 1))")
        if len(args) > 1:
            # kept: only running it is an error, at its place (check warns)
            what = "__NEW with a count (an array reached through pointer arithmetic)"
            why = "plcpred has no pointer arithmetic"
            return f"_opaque({what!r}, {pos_args(call.pos)}, {why!r})", PtrT(t)
        one = self._init(t, None, scope, None)
        if isinstance(t, FbT):
            if init_args and not fb_inits(t):
                raise error_at(first, f"{t.name} has no FB_init method for these arguments")
            if fb_inits(t):
                tmp = self.src.temp("new")
                decl = ir.VarDecl("new", ir.NamedType(t.name), init_args=init_args,
                                  pos=call.pos)
                calls = self._fb_init_code(tmp, t, decl, scope)
                return f"({tmp} := {one}, {', '.join(calls)}, {tmp})[-1]", PtrT(t)
        if is_object_t(t):
            return one, PtrT(t)
        return f"_Box({one})", PtrT(t)


def _conversion(key: str, call: ir.Call, code: str, vt):
    """``X_TO_Y``, ``TO_Y`` and ``TRUNC`` of ``code`` (of type ``vt``)."""
    if key == "TRUNC" or key.startswith("TRUNC_") or "_TRUNC_" in key:
        dst = key.split("_")[-1] if "_" in key else "DINT"
        t = ty.elementary(dst) or ty.DINT
        return f"_wrap(int({code}), {t.bits or 32}, {t.signed})", t
    dst = _CONV.match(key).group(2)
    t = ty.elementary(dst)
    if t is None:
        raise error_at(call, f"unknown conversion {key}")
    src = vt.cat if vt.cat in ("bool", "int", "real", "time", "string") else (
        "time" if vt.cat == "date" else "int")
    if getattr(vt, "name", "") in ("CHAR", "WCHAR") and t.cat == "int":
        src = "char"          # a character's code, not its text read as a number
    # DT_TO_UDINT counts seconds, TIME_TO_UDINT milliseconds, LTIME nanoseconds
    unit = ty.ns_per_count(vt.name) if vt.cat in ("time", "date") else (
        ty.ns_per_count(t.name))
    if t.cat == "int":
        return f"_to_int({code}, {t.bits}, {t.signed}, {src!r}, {unit})", t
    if t.cat == "real":
        return f"_to_real({code}, {src!r}, {unit})", t
    if t.cat in ("time", "date"):
        return f"_to_time({code}, {src!r}, {unit})", t
    if t.cat == "bool":
        return f"_to_bool({code}, {src!r})", BOOL
    if dst in ("CHAR", "WCHAR"):
        return f"_to_string({code}, {src!r}, True)", t
    return f"_to_string({code}, {src!r})", STRING
