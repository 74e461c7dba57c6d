"""Resolved IEC types for the compiler: what a value is at run time and how it is
initialised, copied and compared."""
from __future__ import annotations

from dataclasses import dataclass, field

from ..parser import ir
from ..parser.errors import ProgramError, at
from ..parser.generics import readable
from ..parser.literals import INT_LITERAL_MAX, INT_TYPES
from ..parser.names import ident
from ..parser.stdlib import STANDARD_FBS
from ..parser.typegraph import MAX_INHERITANCE_DEPTH, check_type_graph

SIGNED = {"SINT", "INT", "DINT", "LINT"}
BIT_STRINGS = {"BYTE", "WORD", "DWORD", "LWORD"}
TIME_NAMES = {"TIME", "LTIME"}
DATE_NAMES = {"DATE", "LDATE", "TOD", "TIME_OF_DAY", "LTOD", "LTIME_OF_DAY", "DT",
              "DATE_AND_TIME", "LDT", "LDATE_AND_TIME"}


@dataclass(frozen=True)
class Elem:
    """An elementary type. ``cat``: bool, int, real, time, date, string."""
    name: str
    cat: str
    bits: int = 0      # integers: width (0 for an untyped literal)
    signed: bool = True

    def default(self):
        return {"bool": False, "real": 0.0, "string": ""}.get(self.cat, 0)


BOOL = Elem("BOOL", "bool")
ANY_INT = Elem("ANY_INT", "int")
ANY_REAL = Elem("ANY_REAL", "real")
REAL = Elem("LREAL", "real")
TIME = Elem("TIME", "time")
STRING = Elem("STRING", "string")
DINT = Elem("DINT", "int", 32, True)


def ns_per_count(name: str) -> int:
    """What one count of a time or date type is worth when converted to or from a number,
    as CODESYS and TwinCAT do it: DATE and DT count seconds since 1970, TIME and TOD
    milliseconds, the long types (LTIME, LDATE, LTOD, LDT) nanoseconds."""
    up = name.upper()
    if up in ("DATE", "DT", "DATE_AND_TIME"):
        return 1_000_000_000
    if up in ("LTIME", "LDATE", "LTOD", "LTIME_OF_DAY", "LDT", "LDATE_AND_TIME"):
        return 1
    return 1_000_000


def elementary(name: str) -> Elem | None:
    up = name.upper()
    if up in ("BOOL", "BIT"):
        return BOOL
    if up in INT_TYPES:
        return Elem(up, "int", INT_TYPES[up], up in SIGNED)
    if up in ("REAL", "LREAL"):
        return Elem(up, "real")
    if up in TIME_NAMES:
        return Elem(up, "time")
    if up in DATE_NAMES:
        return Elem(up, "date")
    if up in ("STRING", "WSTRING", "CHAR", "WCHAR"):
        return Elem(up, "string")
    if up in ("ANY_INT", "ANY_NUM", "ANY_BIT", "ANY", "ANY_ELEMENTARY"):
        return ANY_INT
    if up == "ANY_REAL":
        return ANY_REAL
    return None


@dataclass(eq=False)
class EnumT:
    name: str
    values: dict[str, int]
    cat = "int"
    bits = 0
    signed = True

    def default(self):
        return next(iter(self.values.values()), 0)


@dataclass(eq=False)
class StructT:
    name: str
    members: dict[str, "object"] = field(default_factory=dict)  # UPPER -> type
    decls: list = field(default_factory=list)
    union: bool = False
    cls_name: str = ""
    cat = "struct"


MAX_ARRAY_ELEMENTS = 1_000_000
MAX_PROGRAM_CELLS = 5_000_000  # variables (array elements counted) of a whole project


def cells(t, table: "TypeTable", _active=None) -> int:
    """How many values a variable of type ``t`` holds (arrays and FB instances counted
    through), the measure the executor's memory limit is stated in."""
    if isinstance(t, ArrayT):
        return t.size * cells(t.elem, table, _active)
    if isinstance(t, StructT):
        return max(1, sum(cells(m, table, _active) for m in t.members.values()))
    if isinstance(t, FbT):
        active = _active or set()
        if t.name.upper() in active:
            raise at(t.pou.pos, f"{t.name} contains an instance of itself")
        active = active | {t.name.upper()}
        total = 1
        for x in t.chain():
            for b in x.pou.var_blocks:
                if b.kind in ("VAR_EXTERNAL", "VAR_IN_OUT"):
                    continue
                for d in b.decls:
                    total += cells(table.resolve(d.type, d.pos), table, active)
                    if total > MAX_PROGRAM_CELLS:
                        return total
        return total
    return 1


def bit_access_error(t, bit: int) -> str | None:
    """Why ``value.bit`` cannot name a bit of a value of type ``t`` (None: it can). An
    integer or bit string has as many bits as its width (a WORD 0..15); an untyped number
    or an enumeration is taken as the widest (0..63)."""
    if isinstance(t, PtrT) and t.reference:
        t = t.target
    name = getattr(t, "name", None) or t.cat
    if t.cat == "int":
        width = getattr(t, "bits", 0) or 64
        if 0 <= bit < width:
            return None
        return f"bit {bit} of a {name}: a {name} has bits 0..{width - 1}"
    if t.cat == "bool":
        return f"bit access .{bit} on a BOOL, which has no bits to take"
    return (f"bit access .{bit} on a value of type {name}: only integers and bit strings "
            "(BYTE, WORD, DWORD, LWORD) have bits")


# bytes of the elementary types whose size their name does not give (TwinCAT's, 64-bit)
_ELEM_BYTES = {"BOOL": 1, "BIT": 1, "REAL": 4, "LREAL": 8, "TIME": 4, "LTIME": 8,
               "DATE": 4, "TOD": 4, "TIME_OF_DAY": 4, "DT": 4, "DATE_AND_TIME": 4,
               "LDATE": 8, "LTOD": 8, "LDT": 8, "CHAR": 1, "WCHAR": 2,
               "STRING": 81, "WSTRING": 162}
POINTER_BYTES = 8


def byte_size(t) -> int | None:
    """SIZEOF of a value of type ``t`` in bytes, as TwinCAT counts it for elementary
    types, arrays and pointers; a STRING of the default length (80 characters and the
    terminator: the executor does not keep a declared length); structures summed without
    alignment padding. None where the executor cannot tell (a function block)."""
    if isinstance(t, Elem):
        if t.cat == "int" and t.bits:
            return t.bits // 8
        return _ELEM_BYTES.get(t.name.upper())
    if isinstance(t, EnumT):
        return 2                           # an enumeration's default base type is INT
    if isinstance(t, PtrT):
        return POINTER_BYTES
    if isinstance(t, ArrayT):
        n = byte_size(t.elem)
        return None if n is None else n * t.size
    if isinstance(t, StructT):
        sizes = [byte_size(m) for m in t.members.values()]
        if any(n is None for n in sizes):
            return None
        return max(sizes, default=0) if t.union else sum(sizes)
    return None


@dataclass(eq=False)
class ArrayT:
    dims: list[tuple[int, int]]
    elem: object
    cat = "array"

    @property
    def size(self) -> int:
        n = 1
        for lo, hi in self.dims:
            n *= hi - lo + 1
        return n


@dataclass(eq=False)
class FbT:
    """A user FUNCTION_BLOCK (or PROGRAM) type."""
    name: str
    pou: ir.Pou
    base: "FbT | None" = None
    cls_name: str = ""
    cat = "fb"

    def chain(self):
        """This FB, its base, its base's base ... (the type graph is checked: the chain
        ends, within MAX_INHERITANCE_DEPTH; a hand-made cycle is an error, not a hang)."""
        t, n = self, 0
        while t is not None:
            yield t
            t = t.base
            n += 1
            if t is not None and n > MAX_INHERITANCE_DEPTH:
                raise at(self.pou.pos, f"{self.name} EXTENDS a chain of more than "
                                       f"{MAX_INHERITANCE_DEPTH} types, or itself")

    def var(self, key: str):
        """The declaration of variable ``key`` (upper case), its own or inherited."""
        for t in self.chain():
            table = t.__dict__.get("_vars")
            if table is None:      # made on first use: a wide program has thousands
                table = {}
                for d in t.pou.decls():
                    table.setdefault(ident(d.name), d)
                t._vars = table
            if key in table:
                return table[key]
        return None

    def method(self, key: str):
        for t in self.chain():
            for m in t.pou.methods:
                if ident(m.name) == key:
                    return m, t
        return None

    def prop(self, key: str):
        for t in self.chain():
            for p in t.pou.properties:
                if ident(p.name) == key:
                    return p, t
        return None

    def action(self, key: str):
        for t in self.chain():
            for a in t.pou.actions:
                if ident(a.name) == key:
                    return a, t
        return None


@dataclass(eq=False)
class StdFbT:
    name: str
    cat = "stdfb"

    @property
    def inputs(self):
        return STANDARD_FBS[self.name][0]

    @property
    def outputs(self):
        return STANDARD_FBS[self.name][1]


@dataclass(eq=False)
class ItfT:
    name: str
    itf: ir.Interface
    cat = "itf"
    bases: list = field(default_factory=list)   # the interfaces it EXTENDS (known ones)

    def _chain(self):
        """This interface, then those it extends, nearest first (each once)."""
        seen, stack = set(), [self]
        while stack:
            t = stack.pop(0)
            if id(t.itf) in seen:
                continue
            seen.add(id(t.itf))
            yield t
            stack.extend(t.bases)

    def method(self, key):
        for t in self._chain():
            for m in t.itf.methods:
                if ident(m.name) == key:
                    return m, None
        return None

    def prop(self, key):
        for t in self._chain():
            for p in t.itf.properties:
                if ident(p.name) == key:
                    return p, None
        return None


@dataclass(eq=False)
class PtrT:
    target: object
    reference: bool = False
    cat = "ptr"


VOID = Elem("VOID", "void")

OBJECT_CATS = ("struct", "array", "fb", "stdfb", "itf")


def is_object(t) -> bool:
    """Values held by reference in Python (copied explicitly on assignment)."""
    return t.cat in OBJECT_CATS


# resolve() calls nested in one another (three Python frames each at most). The type
# graph bounds what values hold (MAX_TYPE_NESTING, one call a level); pointers may chain
# types further, which only this stops before Python's recursion limit does
MAX_RESOLVE_DEPTH = 200


def _builtin(up: str) -> bool:
    """Names TypeTable.named resolves before any declaration."""
    return elementary(up) is not None or up in STANDARD_FBS


class TypeTable:
    """Named types of a project, resolved lazily (types may refer to later ones)."""

    def __init__(self, program: ir.Program):
        # no type holds itself, inheritance ends, nesting is bounded: what the recursive
        # resolution below (and everything using its types) relies on
        try:
            check_type_graph([program], _builtin)
        except ProgramError as e:   # a generic FB's copy named as the program writes it
            raise readable([e], program)[0] from None
        self.program = program
        self.decls = {ident(t.name): t for t in program.types}
        self.pous = {ident(p.name): p for p in program.pous}
        self.interfaces = {ident(i.name): i for i in program.interfaces}
        self.resolved: dict[str, object] = {}
        self.structs: list[StructT] = []
        self.fbs: dict[str, FbT] = {}
        self.itfs: dict[str, ItfT] = {}
        self.enum_values: dict[str, list[tuple[EnumT, int]]] = {}
        self.constants: dict[str, int] = {}  # integer constants for array bounds
        self._every_enum = False
        self._depth = 0          # resolve() calls in progress
        self._aliases: list[str] = []  # the type aliases being resolved, outermost first

    def enum_candidates(self, key: str):
        """(type, number) of each enumeration with a value ``key``; enumerations no
        declaration has used yet are resolved the first time a value is not found (a
        library's LOGLEVEL is named by its values before anything declares one)."""
        if key not in self.enum_values and not self._every_enum:
            self._every_enum = True
            for up, decl in self.decls.items():
                if isinstance(decl.type, ir.EnumType) and up not in self.resolved:
                    self.named(decl.name, decl.pos)
        return self.enum_values.get(key)

    def named(self, name: str, pos=None):
        up = name.upper()
        if up in self.resolved:
            return self.resolved[up]
        e = elementary(up)
        if e is not None:
            return e
        if up in STANDARD_FBS:
            return StdFbT(up)
        if up in self.decls:
            decl = self.decls[up]
            if isinstance(decl.type, ir.StructType):
                t = StructT(decl.name, union=decl.type.union, cls_name=f"st_{ident(decl.name)}")
                self.resolved[up] = t
                self.structs.append(t)
                base = self.named(decl.type.extends, decl.pos) if decl.type.extends else None
                if base is not None and not isinstance(base, StructT):
                    raise at(decl.pos, f"STRUCT {decl.name} EXTENDS {decl.type.extends}, "
                                       "which is not a structure")
                if base is not None:
                    t.members.update(base.members)
                    t.decls.extend(base.decls)
                for d in decl.type.members:
                    t.members[ident(d.name)] = self.resolve(d.type)
                    t.decls.append(d)
                return t
            if isinstance(decl.type, ir.EnumType):
                t = self._enum(decl.name, decl.type)
                self.resolved[up] = t
                return t
            if up in self._aliases:
                ring = [self.decls[k].name for k in self._aliases[self._aliases.index(up):]]
                ring.append(decl.name)
                raise at(decl.pos, f"type {decl.name} is defined in terms of itself "
                                   f"({' > '.join(ring)})")
            self._aliases.append(up)
            try:
                t = self.resolve(decl.type)
            finally:
                self._aliases.pop()
            self.resolved[up] = t
            return t
        if up in self.pous and self.pous[up].kind in ("FUNCTION_BLOCK", "PROGRAM"):
            return self.fb(up)
        if up in self.interfaces:
            return self._interface(up)
        raise at(pos, f"unknown type '{name}'")

    def _interface(self, up: str) -> ItfT:
        t = self.itfs.get(up)
        if t is None:
            itf = self.interfaces[up]
            t = self.itfs[up] = ItfT(itf.name, itf)
            # a base plcpred does not know (__SYSTEM.IQueryInterface) adds nothing here
            t.bases = [self._interface(ident(b)) for b in itf.extends
                       if ident(b) in self.interfaces]
        return t

    def fb(self, up: str) -> FbT:
        if up not in self.fbs:
            pou = self.pous[up]
            t = FbT(pou.name, pou, cls_name=f"fb_{ident(pou.name)}")
            self.fbs[up] = t
            if pou.extends:
                base = self.named(pou.extends, pou.pos)
                if not isinstance(base, FbT):
                    raise at(pou.pos, f"{pou.name} EXTENDS {pou.extends}, which is not a "
                                      "function block")
                t.base = base
        return self.fbs[up]

    def _enum(self, name, et: ir.EnumType) -> EnumT:
        values, nxt = {}, 0
        for vname, vexpr in et.values:
            if vexpr is not None:
                nxt = self.const_int(vexpr)
            values[vname.upper()] = nxt
            nxt += 1
        t = EnumT(name, values)
        for k, v in values.items():
            self.enum_values.setdefault(k, []).append((t, v))
        return t

    def const_int(self, e) -> int:
        if isinstance(e, ir.Literal) and isinstance(e.value, int):
            return int(e.value)
        if isinstance(e, ir.Unary) and e.op == "-":
            return -self.const_int(e.operand)
        if isinstance(e, ir.Binary) and e.op in ("+", "-", "*"):
            a, b = self.const_int(e.left), self.const_int(e.right)
            v = a + b if e.op == "+" else a - b if e.op == "-" else a * b
            if abs(v) > INT_LITERAL_MAX:   # before products of products grow without end
                raise at(getattr(e, "pos", None), "constant expression out of range: "
                                                  "larger than any integer type (64 bits)")
            return v
        if isinstance(e, ir.Name):
            c = self.constants.get(ident(e.name))
            if c is not None:
                return c
        raise at(getattr(e, "pos", None), "expected a constant integer here")

    def resolve(self, tr, pos=None):
        # types refer to types through pointers, which the type graph allows without
        # bound: resolving them must stop before Python's recursion limit does
        self._depth += 1
        try:
            if self._depth > MAX_RESOLVE_DEPTH:
                raise at(getattr(tr, "pos", None) or pos,
                         f"types refer to each other more than {MAX_RESOLVE_DEPTH} levels "
                         "deep (through POINTER TO or REFERENCE TO): name fewer types in a "
                         "row")
            return self._resolve(tr, pos)
        finally:
            self._depth -= 1

    def _resolve(self, tr, pos):
        if isinstance(tr, ir.NamedType):
            return self.named(tr.name, tr.pos or pos)
        if isinstance(tr, ir.StringType):
            return STRING
        if isinstance(tr, ir.ArrayType):
            dims = []
            for lo, hi in tr.dims:
                if lo is None:
                    raise at(tr.pos, "ARRAY[*] (variable length) is not supported by the "
                                     "executor")
                low, high = self.const_int(lo), self.const_int(hi)
                if high < low:
                    raise at(tr.pos or pos, f"ARRAY[{low}..{high}]: the upper bound is below the "
                                     "lower one")
                dims.append((low, high))
            t = ArrayT(dims, self.resolve(tr.element, tr.pos))
            if t.size > MAX_ARRAY_ELEMENTS:
                raise at(tr.pos or pos, f"an array of {t.size:,} elements; the executor holds at "
                                 f"most {MAX_ARRAY_ELEMENTS:,} per array")
            return t
        if isinstance(tr, ir.PointerType):
            return PtrT(self.resolve(tr.target, tr.pos), tr.reference)
        if isinstance(tr, ir.SubrangeType):
            return self.named(tr.base, tr.pos)
        if isinstance(tr, ir.EnumType):
            return self._enum("<anonymous>", tr)
        if isinstance(tr, ir.StructType):
            t = StructT("<anonymous>", cls_name=f"st_anon{len(self.structs)}",
                        union=tr.union)
            for d in tr.members:
                t.members[ident(d.name)] = self.resolve(d.type)
                t.decls.append(d)
            self.structs.append(t)
            return t
        raise at(pos, f"unsupported type {type(tr).__name__}")
