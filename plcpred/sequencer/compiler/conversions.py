"""Types as the generated code treats them: which values are objects (shared, copied on
assignment), and how a value is converted for storing into a variable of another type
(integers wrap to the declared width)."""
from __future__ import annotations

import re

from .. import types as ty
from ..types import ArrayT, Elem, EnumT, PtrT, StructT
from .common import error_at

# (target category, value category) -> how to store the value (assignment conversions)
_CONVERSIONS = {
    ("bool", "bool"): "{code}", ("bool", "int"): "({code} != 0)",
    ("bool", "real"): "({code} != 0)",
    ("int", "bool"): "int({code})",
    ("int", "real"): "_to_int({code}, {bits}, {signed}, 'real')",
    ("int", "time"): "_to_int({code}, {bits}, {signed}, 'time')",
    ("int", "date"): "_to_int({code}, {bits}, {signed}, 'time')",
    ("real", "real"): "{code}", ("real", "int"): "float({code})",
    ("real", "bool"): "float({code})", ("real", "time"): "_to_real({code}, 'time')",
    ("time", "time"): "{code}", ("time", "date"): "{code}",
    ("date", "time"): "{code}", ("date", "date"): "{code}",
    ("time", "int"): "_to_time({code}, 'int')", ("date", "int"): "_to_time({code}, 'int')",
    ("time", "real"): "_to_time({code}, 'real')", ("date", "real"): "_to_time({code}, 'real')",
}
_PLAIN = re.compile(r"[A-Za-z_][\w.]*")  # a variable read: already in range, no wrap


def convert(code: str, vt, tt, node, copy=False) -> str:
    """``code`` of type ``vt`` converted for storing into type ``tt`` (``copy``: a
    structure or array is copied, as an assignment does)."""
    if tt is None or vt is None or tt.cat in ("void",):
        return code
    if is_object_t(tt):
        return f"_copy({code})" if copy and is_object_t(vt) else code
    if tt.cat == "ptr" or isinstance(tt, EnumT):
        return code
    vc = vt.cat
    if tt.cat == "int" and vc == "int":
        if (isinstance(vt, Elem) and vt.name == tt.name and _PLAIN.fullmatch(code)) \
                or _literal_fits(code, tt):
            return code
        return _wrap_code(code, tt)
    if tt.cat == "string":
        return code if vc == "string" else f"_to_string({code}, {vc!r})"
    if tt.cat not in ("bool", "int", "real", "time", "date"):
        return code
    template = _CONVERSIONS.get((tt.cat, vc))
    if template is None:
        name = getattr(vt, "name", vc)
        if tt.cat == "bool":
            raise error_at(node, f"cannot use a {name} value as BOOL")
        raise error_at(node, f"cannot store a {name} value in {tt.name}")
    return template.format(code=code, bits=getattr(tt, "bits", 0),
                           signed=getattr(tt, "signed", True))


def _wrap_code(code: str, t) -> str:
    bits = t.bits
    if not bits:
        return code
    mask = (1 << bits) - 1
    if t.signed:
        half = 1 << (bits - 1)
        return f"((({code}) + {half}) & {mask}) - {half}"
    return f"(({code}) & {mask})"


def _literal_fits(code: str, t) -> bool:
    try:
        v = int(code)
    except ValueError:
        return False
    if not t.bits:
        return True
    lo = -(1 << (t.bits - 1)) if t.signed else 0
    hi = (1 << (t.bits - 1)) - 1 if t.signed else (1 << t.bits) - 1
    return lo <= v <= hi


def is_object_t(t) -> bool:
    return t is not None and t.cat in ty.OBJECT_CATS


def deref_t(t):
    """References and pointers to function blocks and structs are the object itself."""
    while isinstance(t, PtrT) and is_object_t(t.target):
        t = t.target
    return t


def base_t(t):
    """The element type of an array (of arrays), or ``t`` itself."""
    while isinstance(t, ArrayT):
        t = t.elem
    return t


def has_fb(t) -> bool:
    """Does a value of type ``t`` hold an FB instance (in an array or a structure too)?"""
    t = base_t(t)
    if t.cat in ("fb", "stdfb"):
        return True
    return isinstance(t, StructT) and any(has_fb(m) for m in t.members.values())


def wider(a, b):
    """The type of an operation on ``a`` and ``b``: the one with more bits."""
    if isinstance(a, EnumT):
        return a
    ab, bb = getattr(a, "bits", 0), getattr(b, "bits", 0)
    if not ab:
        return b
    if not bb:
        return a
    return a if ab >= bb else b


def check_bit(x, t):
    """An error unless ``x.bit`` is a bit of a value of type ``t`` (0..15 of a WORD)."""
    why = ty.bit_access_error(t, x.bit)
    if why is not None:
        raise error_at(x, why)
