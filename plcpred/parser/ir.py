"""The intermediate representation every front end produces and every later stage reads.

Structured Text, the ``.seq`` sequence-chart format and PLCopen XML all land here. Nodes are
plain dataclasses. Each carries a source position (``pos``) that is left out of equality, so
that a program printed back as ST and parsed again compares equal to the original.

Names keep the spelling of their declaration; IEC identifiers are case-insensitive, so
lookups use ``name.upper()``.
"""
from __future__ import annotations

import _thread
from collections import namedtuple
from dataclasses import MISSING, dataclass, field, fields
from operator import attrgetter

# (collections' named tuple rather than typing's, and ``|`` for the unions below: typing
# costs a syntax check about as much to import as parsing a small program takes)
Pos = namedtuple("Pos", ("file", "line", "col"))
Pos.__doc__ = """Where a node was written (1-based line and column). A tuple: one is built
for every name and literal, so it must be cheap."""


def _pos_text(self) -> str:
    return f"{self.file}:{self.line}:{self.col}"


Pos.__str__ = _pos_text


def _pos():
    return field(default=None, compare=False, repr=False, kw_only=True)


def node(cls):
    """``@dataclass(slots=True)``, with the methods dataclass would generate for each class
    made for all of them at once: ``__eq__`` and ``__repr__`` written once for every node
    (:func:`_node_eq`, :func:`_node_repr`), ``__init__`` compiled for every class in one
    go at the end of this module (:func:`_make_inits`). Generating them class by class
    took about 10 ms of a syntax check's start-up (this module's import, 18 ms, now 9). They behave as dataclass's: fields compared
    and shown in order (those with ``compare=False`` / ``repr=False`` left out), a node is
    not hashable, and ``__init__`` takes the fields in order, ``kw_only`` ones by name."""
    cls = dataclass(slots=True, init=False, eq=False, repr=False)(cls)
    compared = [f.name for f in fields(cls) if f.compare]
    _COMPARED[cls] = (attrgetter(*compared) if len(compared) > 1
                      else (lambda obj, get=attrgetter(*compared): (get(obj),)) if compared
                      else (lambda obj: ()))
    _SHOWN[cls] = tuple(f.name for f in fields(cls) if f.repr)
    cls.__eq__ = _node_eq
    cls.__repr__ = _node_repr
    cls.__hash__ = None   # compared by value and mutable, as a dataclass with eq=True is
    _WITHOUT_INIT.append(cls)
    return cls


# the node classes whose __init__ _make_inits has not made yet
_WITHOUT_INIT: list = []
class _Factory:
    """The default of a field with a default_factory, as dataclass marks it."""
    __slots__ = ()

    def __repr__(self) -> str:
        return "<factory>"


_FACTORY = _Factory()


def _make_inits() -> None:
    """The ``__init__`` dataclass would generate for each class of
    :data:`_WITHOUT_INIT`, compiled together: ``self.f = f`` for each field in order,
    defaults as given, a ``default_factory`` called where its field was not given."""
    namespace = {"__name__": __name__, "_FACTORY": _FACTORY}
    source = []
    for i, cls in enumerate(_WITHOUT_INIT):
        params, keywords, body = [], [], []
        for f in fields(cls):
            if f.default is not MISSING:
                namespace[f"_d{i}_{f.name}"] = f.default
                param = f"{f.name}=_d{i}_{f.name}"
            elif f.default_factory is not MISSING:
                namespace[f"_d{i}_{f.name}"] = f.default_factory
                param = f"{f.name}=_FACTORY"
            else:
                param = f.name
            (keywords if f.kw_only else params).append(param)
            body.append(f"self.{f.name} = _d{i}_{f.name}() if {f.name} is _FACTORY "
                        f"else {f.name}" if f.default_factory is not MISSING
                        else f"self.{f.name} = {f.name}")
        signature = ", ".join(["self", *params, *(["*", *keywords] if keywords else [])])
        source.append(f"def _init{i}({signature}):\n    " + "\n    ".join(body or ["pass"]))
    # the source is made of this module's field names and nothing else (no program text)
    exec("\n".join(source), namespace)  # noqa: S102
    for i, cls in enumerate(_WITHOUT_INIT):
        init = namespace[f"_init{i}"]
        init.__name__ = "__init__"
        init.__qualname__ = f"{cls.__qualname__}.__init__"
        init.__annotations__ = {**{f.name: f.type for f in fields(cls)}, "return": None}
        cls.__init__ = init
    _WITHOUT_INIT.clear()


# node class -> a function of a node giving the tuple of its compared fields' values
_COMPARED: dict = {}
# node class -> the names of the fields its repr shows
_SHOWN: dict = {}
# (id of a node, thread) whose repr is being made: a node inside itself shows as ...
_REPR_RUNNING: set = set()


def _node_eq(self, other):
    if other.__class__ is self.__class__:
        values = _COMPARED[self.__class__]
        return values(self) == values(other)
    return NotImplemented


def _node_repr(self):
    key = id(self), _thread.get_ident()
    if key in _REPR_RUNNING:
        return "..."
    _REPR_RUNNING.add(key)
    try:
        return self.__class__.__qualname__ + "(" + ", ".join(
            f"{name}={getattr(self, name)!r}" for name in _SHOWN[self.__class__]) + ")"
    finally:
        _REPR_RUNNING.discard(key)


# --------------------------------------------------------------------------- expressions

@node
class Literal:
    """A constant. ``type_name`` is the IEC type (``BOOL``, ``INT``, ``REAL``, ``TIME``,
    ``STRING``, ...) or ``ANY_INT``/``ANY_REAL`` for untyped numbers. TIME values are in
    seconds (float), TOD in seconds since midnight, DATE/DT in seconds since 1970-01-01."""
    value: object
    type_name: str
    pos: Pos | None = _pos()


@node
class EnumLiteral:
    """``E_Mode#Run`` (an enumerated value qualified with ``#``)."""
    type_name: str
    value: str
    pos: Pos | None = _pos()


@node
class Name:
    """A variable, instance, constant or POU referenced by name."""
    name: str
    pos: Pos | None = _pos()


@node
class Member:
    """``base.member``: a struct field, FB output/input, method, or a qualified enum value."""
    base: "Expr"
    member: str
    pos: Pos | None = _pos()


@node
class BitAccess:
    """``word.3``: a single bit of an integer variable."""
    base: "Expr"
    bit: int
    pos: Pos | None = _pos()


@node
class Index:
    """``base[i, j]``: an array element."""
    base: "Expr"
    indices: list["Expr"]
    pos: Pos | None = _pos()


@node
class Deref:
    """``ptr^``."""
    base: "Expr"
    pos: Pos | None = _pos()


@node
class DirectAddress:
    """A located variable used directly in code, e.g. ``%IX0.1``."""
    address: str
    pos: Pos | None = _pos()


@node
class Unary:
    """``-x``, ``+x``, ``NOT x``."""
    op: str  # "-", "+", "NOT"
    operand: "Expr"
    pos: Pos | None = _pos()


@node
class Binary:
    """``left op right``; precedence is already applied (see grammar.py)."""
    op: str  # "**", "*", "/", "MOD", "+", "-", "<", ">", "<=", ">=", "=", "<>",
    #          "AND", "AND_THEN", "XOR", "OR", "OR_ELSE"
    left: "Expr"
    right: "Expr"
    pos: Pos | None = _pos()


@node
class Arg:
    """A call argument: positional (``name`` is None), named input (``name := value``) or
    output binding (``name => target``, ``output`` True)."""
    name: str | None
    value: "Expr | None"
    output: bool = False
    negated: bool = False  # ``NOT Q => x`` output binding
    pos: Pos | None = _pos()


@node
class Call:
    """A function, FB instance or method call. ``func`` is the callee expression."""
    func: "Expr"
    args: list[Arg]
    pos: Pos | None = _pos()


@node
class ArrayInit:
    """``[1, 2, 3(0)]``: items are (repeat count, value); a value may be nested init."""
    items: list[tuple[int, "Initializer"]]
    pos: Pos | None = _pos()


@node
class StructInit:
    """``(x := 1.0, y := 2.0)``: also used for FB instance initialisation."""
    fields: list[tuple[str, "Initializer"]]
    pos: Pos | None = _pos()


@node
class AssignExpr:
    """``(x := value)`` inside an expression (CODESYS, TwinCAT): stores ``value`` in
    ``target`` and is that value, as the target's type."""
    target: "Expr"
    value: "Expr"
    pos: Pos | None = _pos()


@node
class TypeExpr:
    """A type where a call takes one: ``__NEW(POINTER TO T, n)`` (CODESYS, TwinCAT)."""
    type: "TypeRef"
    pos: Pos | None = _pos()


Expr = (Literal | EnumLiteral | Name | Member | BitAccess | Index | Deref | DirectAddress
        | Unary | Binary | Call | AssignExpr | TypeExpr)
Initializer = Expr | ArrayInit | StructInit


# --------------------------------------------------------------------------- types

@node
class NamedType:
    """An elementary type (``INT``) or a user / FB type referenced by name.
    ``generic_args``: the values of a generic FB's VAR_GENERIC CONSTANTs (``FB_Buf<100>``),
    positional (``Arg.name`` None) or named."""
    name: str
    pos: Pos | None = _pos()
    generic_args: list["Arg"] | None = None


@node
class StringType:
    """``STRING`` / ``WSTRING`` (``wide``), with an optional maximum ``length``."""
    wide: bool = False
    length: "Expr | None" = None
    pos: Pos | None = _pos()


@node
class ArrayType:
    """``ARRAY[low..high, ...] OF element``."""
    dims: list[tuple["Expr", "Expr"]]  # (low, high) inclusive; ``*`` dims use None
    element: "TypeRef"
    pos: Pos | None = _pos()


@node
class PointerType:
    """``POINTER TO target``, ``REFERENCE TO target`` or ``REF_TO target``."""
    target: "TypeRef"
    reference: bool = False  # REFERENCE TO instead of POINTER TO
    pos: Pos | None = _pos()


@node
class SubrangeType:
    """``base(low..high)``: an integer type restricted to a range."""
    base: str
    low: "Expr"
    high: "Expr"
    pos: Pos | None = _pos()


@node
class EnumType:
    """``(Idle, Run := 5)``: the values with their optional numbers, and the base
    type written after the list (``(A, B) INT``)."""
    values: list[tuple[str, "Expr | None"]]
    base: str | None = None
    pos: Pos | None = _pos()


@node
class StructType:
    """``STRUCT ... END_STRUCT`` (``union``: ``UNION ... END_UNION``), with the
    struct it ``extends``."""
    members: list["VarDecl"]
    extends: str | None = None
    union: bool = False
    pos: Pos | None = _pos()


TypeRef = (NamedType | StringType | ArrayType | PointerType | SubrangeType | EnumType
           | StructType)


@node
class TypeDecl:
    """A ``TYPE`` declaration: ``name : type := init;``."""
    name: str
    type: TypeRef
    init: "Initializer | None" = None
    pragmas: list[str] = field(default_factory=list)
    pos: Pos | None = _pos()


# --------------------------------------------------------------------------- declarations

@node
class VarDecl:
    """One declared variable: its name, type, initial value and ``AT`` address."""
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


@node
class VarBlock:
    """``VAR_INPUT ... END_VAR`` and the like: ``kind``, the declarations, and
    qualifiers such as CONSTANT or RETAIN."""
    kind: str  # one of VAR_KINDS
    decls: list[VarDecl]
    qualifiers: list[str] = field(default_factory=list)  # CONSTANT, RETAIN, PERSISTENT, ...
    pos: Pos | None = _pos()


# --------------------------------------------------------------------------- statements

@node
class Assign:
    """``target := value;`` (or ``REF=``, ``?=``, ``S=``, ``R=`` by ``op``)."""
    target: Expr
    value: Expr
    op: str = ":="  # ":=", "REF=", "?=", "S=", "R="
    pos: Pos | None = _pos()


@node
class CallStmt:
    """A call standing as a statement: ``fb(IN := x);``."""
    call: Call
    pos: Pos | None = _pos()


@node
class If:
    """``IF ... ELSIF ... ELSE ... END_IF``."""
    branches: list[tuple[Expr, list["Stmt"]]]  # IF and ELSIF arms in order
    else_body: list["Stmt"] | None = None
    pos: Pos | None = _pos()


@node
class CaseRange:
    """A ``low..high`` label of a CASE branch."""
    low: Expr
    high: Expr
    pos: Pos | None = _pos()


@node
class CaseBranch:
    """One arm of a CASE: its labels and statements."""
    labels: list["Expr | CaseRange"]
    body: list["Stmt"]
    pos: Pos | None = _pos()


@node
class Case:
    """``CASE selector OF ... ELSE ... END_CASE``."""
    selector: Expr
    branches: list[CaseBranch]
    else_body: list["Stmt"] | None = None
    pos: Pos | None = _pos()


@node
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


@node
class While:
    """``WHILE cond DO ... END_WHILE``."""
    cond: Expr
    body: list["Stmt"]
    pos: Pos | None = _pos()


@node
class Repeat:
    """``REPEAT ... UNTIL cond END_REPEAT``."""
    body: list["Stmt"]
    cond: Expr
    pos: Pos | None = _pos()


@node
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


@node
class Exit:
    """``EXIT;``: leave the innermost loop."""
    pos: Pos | None = _pos()


@node
class Continue:
    """``CONTINUE;``: the innermost loop's next iteration."""
    pos: Pos | None = _pos()


@node
class Return:
    """``RETURN;``: leave the POU, method or action."""
    pos: Pos | None = _pos()


@node
class Empty:
    """``;`` on its own."""
    pos: Pos | None = _pos()


@node
class Label:
    """A jump target ``name:`` standing before the next statement."""
    name: str
    pos: Pos | None = _pos()


@node
class Jmp:
    """``JMP label;``."""
    label: str
    pos: Pos | None = _pos()


@node
class Opaque:
    """Code kept but not read: a graphical (FBD, LD, CFC, IL) body or a Beremiz ``{{ }}``
    inline C block. The project still loads and checks; executing it is an error naming
    ``what``. ``text`` is the block's source where it has one (printed back as ``{{ }}``)."""
    what: str
    text: str = ""
    pos: Pos | None = _pos()


Stmt = (Assign | CallStmt | If | Case | For | While | Repeat | Try | Exit | Continue | Return
        | Empty | Label | Jmp | Opaque)


# --------------------------------------------------------------------------- SFC

ACTION_QUALIFIERS = ("N", "R", "S", "L", "D", "P", "P0", "P1", "SD", "DS", "SL")


@node
class ActionAssoc:
    """A step's use of an action: ``action(qualifier, time)``. ``action`` names an SFC action
    or a BOOL variable (which is then driven directly, as IEC allows)."""
    action: str
    qualifier: str = "N"
    time: Expr | None = None  # for L, D, SD, DS, SL
    indicator: str | None = None
    pos: Pos | None = _pos()


@node
class Step:
    """An SFC step with the actions it drives; ``initial`` for the initial step."""
    name: str
    initial: bool = False
    actions: list[ActionAssoc] = field(default_factory=list)
    pos: Pos | None = _pos()


@node
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


@node
class SfcAction:
    """A named SFC action (or a POU's ACTION) and its statements."""
    name: str
    body: list[Stmt]
    pos: Pos | None = _pos()


@node
class Sfc:
    """A POU body in SFC: steps, transitions and actions."""
    steps: list[Step]
    transitions: list[Transition]
    actions: list[SfcAction] = field(default_factory=list)
    pos: Pos | None = _pos()

    @property
    def initial_step(self) -> Step:
        return next(s for s in self.steps if s.initial)


# --------------------------------------------------------------------------- POUs

@node
class Method:
    """A METHOD of a function block, class or interface."""
    name: str
    return_type: TypeRef | None
    var_blocks: list[VarBlock]
    body: list[Stmt]
    access: str | None = None
    modifiers: list[str] = field(default_factory=list)  # ABSTRACT, FINAL
    pragmas: list[str] = field(default_factory=list)
    pos: Pos | None = _pos()


@node
class PropertyAccessor:
    """A property's GET or SET (``kind``) with its declarations and body."""
    kind: str  # "GET" | "SET"
    var_blocks: list[VarBlock]
    body: list[Stmt]
    pos: Pos | None = _pos()


@node
class Property:
    """A PROPERTY of a function block, class or interface, with its accessors."""
    name: str
    type: TypeRef
    accessors: list[PropertyAccessor] = field(default_factory=list)
    access: str | None = None
    modifiers: list[str] = field(default_factory=list)
    pos: Pos | None = _pos()


@node
class Pou:
    """A program organisation unit: PROGRAM, FUNCTION_BLOCK (classes too) or FUNCTION."""
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


@node
class Interface:
    """``INTERFACE ... END_INTERFACE``: methods and properties without bodies."""
    name: str
    extends: list[str] = field(default_factory=list)
    methods: list[Method] = field(default_factory=list)
    properties: list[Property] = field(default_factory=list)
    pos: Pos | None = _pos()


@node
class Task:
    """A TASK of a resource, with its parameters (INTERVAL, PRIORITY, SINGLE)."""
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


@node
class ProgramInstance:
    """``PROGRAM name WITH task : type_name (args);`` in a resource."""
    name: str
    type_name: str
    task: str | None = None
    args: list[Arg] = field(default_factory=list)
    retain: str | None = None
    pos: Pos | None = _pos()


@node
class Resource:
    """A RESOURCE of a configuration: its globals, tasks and program instances."""
    name: str
    on: str | None
    var_blocks: list[VarBlock] = field(default_factory=list)
    tasks: list[Task] = field(default_factory=list)
    programs: list[ProgramInstance] = field(default_factory=list)
    pos: Pos | None = _pos()


@node
class Configuration:
    """``CONFIGURATION ... END_CONFIGURATION``: globals and resources."""
    name: str
    var_blocks: list[VarBlock] = field(default_factory=list)
    resources: list[Resource] = field(default_factory=list)
    pos: Pos | None = _pos()


@node
class GlobalVars:
    """A VAR_GLOBAL block standing on its own (TwinCAT GVL, PLCopen globalVars). ``name``
    (the GVL's name, usable as ``GVL.var``) has no ST syntax, so it is left out of equality."""
    name: str | None = field(compare=False)
    block: VarBlock = None
    pos: Pos | None = _pos()


@node
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


def field_names(cls) -> tuple[str, ...]:
    """The names of a node class's fields in order (``dataclasses.fields``, worked out
    once per class: walks over a whole program ask for them at every node)."""
    names = _FIELD_NAMES.get(cls)
    if names is None:
        names = _FIELD_NAMES[cls] = tuple(f.name for f in fields(cls))
    return names


_FIELD_NAMES: dict = {}


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


_make_inits()
