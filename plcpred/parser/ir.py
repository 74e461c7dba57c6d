"""The intermediate representation every front end produces and every later stage reads.

Structured Text, the ``.seq`` sequence-chart format and PLCopen XML all land here. Nodes are
plain dataclasses. Each carries a source position (``pos``) that is left out of equality, so
that a program printed back as ST and parsed again compares equal to the original.

Names keep the spelling of their declaration; IEC identifiers are case-insensitive, so
lookups use ``name.upper()``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple, Union


class Pos(NamedTuple):
    """Where a node was written (1-based line and column). A tuple: one is built for
    every name and literal, so it must be cheap."""
    file: str
    line: int
    col: int

    def __str__(self) -> str:
        return f"{self.file}:{self.line}:{self.col}"


def _pos():
    return field(default=None, compare=False, repr=False, kw_only=True)


# --------------------------------------------------------------------------- expressions

@dataclass(slots=True)
class Literal:
    """A constant. ``type_name`` is the IEC type (``BOOL``, ``INT``, ``REAL``, ``TIME``,
    ``STRING``, ...) or ``ANY_INT``/``ANY_REAL`` for untyped numbers. TIME values are in
    seconds (float), TOD in seconds since midnight, DATE/DT in seconds since 1970-01-01."""
    value: object
    type_name: str
    pos: Pos | None = _pos()


@dataclass(slots=True)
class EnumLiteral:
    """``E_Mode#Run`` (an enumerated value qualified with ``#``)."""
    type_name: str
    value: str
    pos: Pos | None = _pos()


@dataclass(slots=True)
class Name:
    name: str
    pos: Pos | None = _pos()


@dataclass(slots=True)
class Member:
    """``base.member``: a struct field, FB output/input, method, or a qualified enum value."""
    base: "Expr"
    member: str
    pos: Pos | None = _pos()


@dataclass(slots=True)
class BitAccess:
    """``word.3``: a single bit of an integer variable."""
    base: "Expr"
    bit: int
    pos: Pos | None = _pos()


@dataclass(slots=True)
class Index:
    base: "Expr"
    indices: list["Expr"]
    pos: Pos | None = _pos()


@dataclass(slots=True)
class Deref:
    """``ptr^``."""
    base: "Expr"
    pos: Pos | None = _pos()


@dataclass(slots=True)
class DirectAddress:
    """A located variable used directly in code, e.g. ``%IX0.1``."""
    address: str
    pos: Pos | None = _pos()


@dataclass(slots=True)
class Unary:
    op: str  # "-", "+", "NOT"
    operand: "Expr"
    pos: Pos | None = _pos()


@dataclass(slots=True)
class Binary:
    op: str  # "**", "*", "/", "MOD", "+", "-", "<", ">", "<=", ">=", "=", "<>",
    #          "AND", "AND_THEN", "XOR", "OR", "OR_ELSE"
    left: "Expr"
    right: "Expr"
    pos: Pos | None = _pos()


@dataclass(slots=True)
class Arg:
    """A call argument: positional (``name`` is None), named input (``name := value``) or
    output binding (``name => target``, ``output`` True)."""
    name: str | None
    value: "Expr | None"
    output: bool = False
    negated: bool = False  # ``NOT Q => x`` output binding
    pos: Pos | None = _pos()


@dataclass(slots=True)
class Call:
    """A function, FB instance or method call. ``func`` is the callee expression."""
    func: "Expr"
    args: list[Arg]
    pos: Pos | None = _pos()


@dataclass(slots=True)
class ArrayInit:
    """``[1, 2, 3(0)]``: items are (repeat count, value); a value may be nested init."""
    items: list[tuple[int, "Initializer"]]
    pos: Pos | None = _pos()


@dataclass(slots=True)
class StructInit:
    """``(x := 1.0, y := 2.0)``: also used for FB instance initialisation."""
    fields: list[tuple[str, "Initializer"]]
    pos: Pos | None = _pos()


@dataclass(slots=True)
class AssignExpr:
    """``(x := value)`` inside an expression (CODESYS, TwinCAT): stores ``value`` in
    ``target`` and is that value, as the target's type."""
    target: "Expr"
    value: "Expr"
    pos: Pos | None = _pos()


@dataclass(slots=True)
class TypeExpr:
    """A type where a call takes one: ``__NEW(POINTER TO T, n)`` (CODESYS, TwinCAT)."""
    type: "TypeRef"
    pos: Pos | None = _pos()


Expr = Union[Literal, EnumLiteral, Name, Member, BitAccess, Index, Deref, DirectAddress,
             Unary, Binary, Call, AssignExpr, TypeExpr]
Initializer = Union[Expr, ArrayInit, StructInit]


# --------------------------------------------------------------------------- types

@dataclass(slots=True)
class NamedType:
    """An elementary type (``INT``) or a user / FB type referenced by name.
    ``generic_args``: the values of a generic FB's VAR_GENERIC CONSTANTs (``FB_Buf<100>``),
    positional (``Arg.name`` None) or named."""
    name: str
    pos: Pos | None = _pos()
    generic_args: list["Arg"] | None = None


@dataclass(slots=True)
class StringType:
    wide: bool = False
    length: "Expr | None" = None
    pos: Pos | None = _pos()


@dataclass(slots=True)
class ArrayType:
    dims: list[tuple["Expr", "Expr"]]  # (low, high) inclusive; ``*`` dims use None
    element: "TypeRef"
    pos: Pos | None = _pos()


@dataclass(slots=True)
class PointerType:
    target: "TypeRef"
    reference: bool = False  # REFERENCE TO instead of POINTER TO
    pos: Pos | None = _pos()


@dataclass(slots=True)
class SubrangeType:
    base: str
    low: "Expr"
    high: "Expr"
    pos: Pos | None = _pos()


@dataclass(slots=True)
class EnumType:
    values: list[tuple[str, "Expr | None"]]
    base: str | None = None
    pos: Pos | None = _pos()


@dataclass(slots=True)
class StructType:
    members: list["VarDecl"]
    extends: str | None = None
    union: bool = False
    pos: Pos | None = _pos()


TypeRef = Union[NamedType, StringType, ArrayType, PointerType, SubrangeType, EnumType,
                StructType]


@dataclass(slots=True)
class TypeDecl:
    name: str
    type: TypeRef
    init: "Initializer | None" = None
    pragmas: list[str] = field(default_factory=list)
    pos: Pos | None = _pos()


# --------------------------------------------------------------------------- declarations

@dataclass(slots=True)
class VarDecl:
    name: str
    type: TypeRef
    init: "Initializer | None" = None
    address: str | None = None  # "%IX0.0", "%Q*"
    pos: Pos | None = _pos()
    # CODESYS/TwinCAT FB_init arguments: ``fb : FB_T(5)``, ``fb : FB_T(a := 1)``
    init_args: list[Arg] | None = None
    # an array of FBs with each element's FB_init arguments (TwinCAT:
    # ``ARRAY[1..2] OF FB_T[(a := 1), (a := 2)]``), in the order of the elements
    element_init_args: list[list[Arg]] | None = None
    # an input's edge qualifier: "R_EDGE" or "F_EDGE" (``x : BOOL R_EDGE;``)
    edge: str | None = None


VAR_KINDS = ("VAR", "VAR_INPUT", "VAR_OUTPUT", "VAR_IN_OUT", "VAR_TEMP", "VAR_GLOBAL",
             "VAR_EXTERNAL", "VAR_STAT", "VAR_INST", "VAR_CONFIG", "VAR_ACCESS", "VAR_GENERIC")


@dataclass(slots=True)
class VarBlock:
    kind: str  # one of VAR_KINDS
    decls: list[VarDecl]
    qualifiers: list[str] = field(default_factory=list)  # CONSTANT, RETAIN, PERSISTENT, ...
    pos: Pos | None = _pos()


# --------------------------------------------------------------------------- statements

@dataclass(slots=True)
class Assign:
    target: Expr
    value: Expr
    op: str = ":="  # ":=", "REF=", "?=", "S=", "R="
    pos: Pos | None = _pos()


@dataclass(slots=True)
class CallStmt:
    call: Call
    pos: Pos | None = _pos()


@dataclass(slots=True)
class If:
    branches: list[tuple[Expr, list["Stmt"]]]  # IF and ELSIF arms in order
    else_body: list["Stmt"] | None = None
    pos: Pos | None = _pos()


@dataclass(slots=True)
class CaseRange:
    low: Expr
    high: Expr
    pos: Pos | None = _pos()


@dataclass(slots=True)
class CaseBranch:
    labels: list["Expr | CaseRange"]
    body: list["Stmt"]
    pos: Pos | None = _pos()


@dataclass(slots=True)
class Case:
    selector: Expr
    branches: list[CaseBranch]
    else_body: list["Stmt"] | None = None
    pos: Pos | None = _pos()


@dataclass(slots=True)
class For:
    """``var`` is the loop variable, or the variable whose element or member is the
    control variable, ``target`` (``FOR a[1] := ...``, as CODESYS and TwinCAT allow)."""
    var: str
    start: Expr
    end: Expr
    step: Expr | None
    body: list["Stmt"]
    pos: Pos | None = _pos()
    target: Expr | None = None


@dataclass(slots=True)
class While:
    cond: Expr
    body: list["Stmt"]
    pos: Pos | None = _pos()


@dataclass(slots=True)
class Repeat:
    body: list["Stmt"]
    cond: Expr
    pos: Pos | None = _pos()


@dataclass(slots=True)
class Try:
    """CODESYS/TwinCAT ``__TRY body __CATCH(var) catch_body __FINALLY finally_body
    __ENDTRY``: a run-time exception (division by zero, an index out of bounds, a null
    pointer) in ``body`` runs ``catch_body`` with its code in ``catch_var`` (a
    ``__SYSTEM.ExceptionCode``); ``finally_body`` runs in any case. ``catch_body`` None:
    there is no __CATCH and the exception goes on after __FINALLY."""
    body: list["Stmt"]
    catch_body: list["Stmt"] | None
    finally_body: list["Stmt"] | None
    catch_var: "Name | None" = None
    pos: Pos | None = _pos()


@dataclass(slots=True)
class Exit:
    pos: Pos | None = _pos()


@dataclass(slots=True)
class Continue:
    pos: Pos | None = _pos()


@dataclass(slots=True)
class Return:
    pos: Pos | None = _pos()


@dataclass(slots=True)
class Empty:
    pos: Pos | None = _pos()


@dataclass(slots=True)
class Label:
    """A jump target ``name:`` standing before the next statement."""
    name: str
    pos: Pos | None = _pos()


@dataclass(slots=True)
class Jmp:
    label: str
    pos: Pos | None = _pos()


@dataclass(slots=True)
class Opaque:
    """Code kept but not read: a graphical (FBD, LD, CFC, IL) body or a Beremiz ``{{ }}``
    inline C block. The project still loads and checks; executing it is an error naming
    ``what``. ``text`` is the block's source where it has one (printed back as ``{{ }}``)."""
    what: str
    text: str = ""
    pos: Pos | None = _pos()


Stmt = Union[Assign, CallStmt, If, Case, For, While, Repeat, Try, Exit, Continue, Return, Empty,
             Label, Jmp, Opaque]


# --------------------------------------------------------------------------- SFC

ACTION_QUALIFIERS = ("N", "R", "S", "L", "D", "P", "P0", "P1", "SD", "DS", "SL")


@dataclass(slots=True)
class ActionAssoc:
    """A step's use of an action: ``action(qualifier, time)``. ``action`` names an SFC action
    or a BOOL variable (which is then driven directly, as IEC allows)."""
    action: str
    qualifier: str = "N"
    time: Expr | None = None  # for L, D, SD, DS, SL
    indicator: str | None = None
    pos: Pos | None = _pos()


@dataclass(slots=True)
class Step:
    name: str
    initial: bool = False
    actions: list[ActionAssoc] = field(default_factory=list)
    pos: Pos | None = _pos()


@dataclass(slots=True)
class Transition:
    """From all ``sources`` (simultaneous convergence if several) to all ``targets``
    (simultaneous divergence if several). Lower ``priority`` wins among transitions leaving
    the same step (selection divergence)."""
    sources: list[str]
    targets: list[str]
    condition: Expr
    priority: int = 0
    name: str | None = None
    pos: Pos | None = _pos()


@dataclass(slots=True)
class SfcAction:
    name: str
    body: list[Stmt]
    pos: Pos | None = _pos()


@dataclass(slots=True)
class Sfc:
    steps: list[Step]
    transitions: list[Transition]
    actions: list[SfcAction] = field(default_factory=list)
    pos: Pos | None = _pos()

    @property
    def initial_step(self) -> Step:
        return next(s for s in self.steps if s.initial)


# --------------------------------------------------------------------------- POUs

@dataclass(slots=True)
class Method:
    name: str
    return_type: TypeRef | None
    var_blocks: list[VarBlock]
    body: list[Stmt]
    access: str | None = None
    modifiers: list[str] = field(default_factory=list)  # ABSTRACT, FINAL
    pragmas: list[str] = field(default_factory=list)
    pos: Pos | None = _pos()


@dataclass(slots=True)
class PropertyAccessor:
    kind: str  # "GET" | "SET"
    var_blocks: list[VarBlock]
    body: list[Stmt]
    pos: Pos | None = _pos()


@dataclass(slots=True)
class Property:
    name: str
    type: TypeRef
    accessors: list[PropertyAccessor] = field(default_factory=list)
    access: str | None = None
    modifiers: list[str] = field(default_factory=list)
    pos: Pos | None = _pos()


@dataclass(slots=True)
class Pou:
    kind: str  # "PROGRAM" | "FUNCTION_BLOCK" | "FUNCTION"
    name: str
    var_blocks: list[VarBlock]
    body: list[Stmt] | Sfc
    return_type: TypeRef | None = None
    extends: str | None = None
    implements: list[str] = field(default_factory=list)
    access: str | None = None
    modifiers: list[str] = field(default_factory=list)
    methods: list[Method] = field(default_factory=list)
    properties: list[Property] = field(default_factory=list)
    actions: list[SfcAction] = field(default_factory=list)
    pragmas: list[str] = field(default_factory=list)
    pos: Pos | None = _pos()
    # the generic constants of a generic base block: EXTENDS FB_Base<7>
    extends_args: list[Arg] = field(default_factory=list)

    @property
    def is_sfc(self) -> bool:
        return isinstance(self.body, Sfc)

    def decls(self, *kinds: str):
        """All declarations, optionally only those of the given block kinds."""
        for block in self.var_blocks:
            if not kinds or block.kind in kinds:
                yield from block.decls


@dataclass(slots=True)
class Interface:
    name: str
    extends: list[str] = field(default_factory=list)
    methods: list[Method] = field(default_factory=list)
    properties: list[Property] = field(default_factory=list)
    pos: Pos | None = _pos()


@dataclass(slots=True)
class Task:
    name: str
    params: dict[str, Expr] = field(default_factory=dict)  # INTERVAL, PRIORITY, SINGLE
    pos: Pos | None = _pos()

    @property
    def interval_ns(self) -> int | None:
        """The task's INTERVAL when it is a positive TIME literal (TIME is in ns)."""
        iv = self.params.get("INTERVAL")
        if isinstance(iv, Literal) and isinstance(iv.value, int) and iv.value > 0:
            return int(iv.value)
        return None


@dataclass(slots=True)
class ProgramInstance:
    name: str
    type_name: str
    task: str | None = None
    args: list[Arg] = field(default_factory=list)
    retain: str | None = None
    pos: Pos | None = _pos()


@dataclass(slots=True)
class Resource:
    name: str
    on: str | None
    var_blocks: list[VarBlock] = field(default_factory=list)
    tasks: list[Task] = field(default_factory=list)
    programs: list[ProgramInstance] = field(default_factory=list)
    pos: Pos | None = _pos()


@dataclass(slots=True)
class Configuration:
    name: str
    var_blocks: list[VarBlock] = field(default_factory=list)
    resources: list[Resource] = field(default_factory=list)
    pos: Pos | None = _pos()


@dataclass(slots=True)
class GlobalVars:
    """A VAR_GLOBAL block standing on its own (TwinCAT GVL, PLCopen globalVars). ``name``
    (the GVL's name, usable as ``GVL.var``) has no ST syntax, so it is left out of equality."""
    name: str | None = field(compare=False)
    block: VarBlock = None
    pos: Pos | None = _pos()


@dataclass(slots=True)
class Program:
    """A whole source file (or several merged): the IR's root."""
    pous: list[Pou] = field(default_factory=list)
    types: list[TypeDecl] = field(default_factory=list)
    interfaces: list[Interface] = field(default_factory=list)
    configurations: list[Configuration] = field(default_factory=list)
    globals: list[GlobalVars] = field(default_factory=list)
    pragmas: list[tuple[str, Pos]] = field(default_factory=list, compare=False)
    source: str | None = field(default=None, compare=False)

    def pou(self, name: str) -> Pou:
        key = name.upper()
        for p in self.pous:
            if p.name.upper() == key:
                return p
        raise KeyError(name)

    def type(self, name: str) -> TypeDecl:
        key = name.upper()
        for t in self.types:
            if t.name.upper() == key:
                return t
        raise KeyError(name)

    def add(self, item) -> bool:
        """File a top-level item (POU, TYPE declaration, interface, configuration, global
        variable list) in its list; False for anything else."""
        for cls, items in ((Pou, self.pous), (TypeDecl, self.types),
                           (Interface, self.interfaces), (Configuration, self.configurations),
                           (GlobalVars, self.globals)):
            if isinstance(item, cls):
                items.append(item)
                return True
        return False

    def merge(self, other: "Program") -> "Program":
        """Both programs' contents in one (positions keep naming their files); the
        source is this one's."""
        return Program(self.pous + other.pous, self.types + other.types,
                       self.interfaces + other.interfaces,
                       self.configurations + other.configurations,
                       self.globals + other.globals, self.pragmas + other.pragmas,
                       self.source)


def nodes(root):
    """Every IR node under ``root`` with its parent, the node whose field holds it (lists
    are passed through; a project: its POUs and configurations). Iterative: statement
    nesting in a program file is unbounded."""
    stack = [([root.pous, root.configurations], None)] if isinstance(root, Program) \
        else [(root, None)]
    while stack:
        x, parent = stack.pop()
        if isinstance(x, (list, tuple)):
            stack.extend((y, parent) for y in x)
        elif hasattr(x, "__dataclass_fields__"):
            yield x, parent
            stack.extend((getattr(x, f), x) for f in x.__dataclass_fields__ if f != "pos")


def names_in(program, cls=Member, attr="member") -> set:
    """Every ``x.member`` name used in a project or IR subtree, upper case (with ``cls``
    and ``attr``: every ``Name.name``, every ``DirectAddress.address``, ...)."""
    return {getattr(x, attr).upper() for x, _ in nodes(program) if isinstance(x, cls)}
