"""The one gate every program name passes before anything is generated from it.

Program files are untrusted: plcpred runs them in CI on pull requests anyone may write.
The compiler turns names into Python source, so a name must never be anything but an IEC
61131-3 identifier. :func:`validate_names` walks a whole :class:`~.ir.Program` (iteratively,
so deep nesting cannot exhaust the stack) and rejects, with the file, line and column, any
string in the IR that is not what its field allows:

* every name field (variables, types, POUs, members, steps, actions, labels, tasks, ...)
  must be an identifier as IEC 61131-3 (ed.3, 6.1.2) defines it, restricted to ASCII
  letters, digits and underscores and starting with a letter or an underscore; as CODESYS,
  TwinCAT and Beremiz accept, consecutive and trailing underscores are allowed (the vendor
  extension ``__NEW``-style names need), but a name must contain a letter or digit;
* operators, assignment kinds, block kinds and action qualifiers must be ones the IR
  defines; direct addresses must have the form ``%IX0.0`` / ``%Q*``;
* literal values must be plain numbers, booleans or strings (the compiler emits them
  through ``repr``).

Text that never reaches generated code (pragmas, file names, the source path) is listed
in :data:`_FREE_TEXT` and left alone. Any other string field added to the IR later is
checked as a name by default: a new field cannot open a hole by being forgotten here.

The compiler repeats the check on the names it emits (:func:`ident`), so a Program built
by hand through the library API cannot bypass it either.
"""
from __future__ import annotations

import dataclasses
import math
import re

from . import ir
from .errors import ProgramError, at

MAX_NAME_LENGTH = 255
# Nesting limits. Real PLC code stays far below them; they exist because every later stage
# (checks, the compiler, Python compiling the generated code: at most 100 indentation
# levels and 20 nested loops) has limits of its own, and a program file must meet a clear,
# positioned error here instead of a crash there.
MAX_EXPRESSION_DEPTH = 100   # operators, calls, indexing nested in one expression
MAX_STATEMENT_DEPTH = 40     # IF / CASE / loops nested in one body
MAX_LOOP_DEPTH = 12          # FOR / WHILE / REPEAT nested in one body
# ARRAY (each dimension), POINTER TO / REFERENCE TO and STRUCT nested in one declaration;
# through named types the nesting is bounded again, as a whole (see .typegraph)
MAX_TYPE_DEPTH = 32
MAX_INITIALIZER_DEPTH = 32   # [...] and (a := ...) initialisers nested in one another
_STATEMENTS = (ir.If, ir.Case, ir.For, ir.While, ir.Repeat, ir.Try)
_LOOPS = (ir.For, ir.While, ir.Repeat)
_EXPRESSIONS = (ir.Unary, ir.Binary, ir.Call, ir.Index, ir.Member, ir.BitAccess, ir.Deref,
                ir.Arg, ir.AssignExpr)
_TYPES = (ir.ArrayType, ir.PointerType, ir.StructType)
_INITIALIZERS = (ir.ArrayInit, ir.StructInit)
_NO_DEPTH = (0, 0, 0, 0, 0)

_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*", re.ASCII)
_HAS_ALNUM = re.compile(r"[A-Za-z0-9]", re.ASCII)
_ADDRESS = re.compile(r"%[IQM](?:\*|[XBWDL]?(?:\d{1,10}(?:\.\d{1,10}){0,7}|\*))", re.ASCII)

_UNARY_OPS = frozenset({"-", "+", "NOT"})
_BINARY_OPS = frozenset({"**", "*", "/", "MOD", "+", "-", "<", ">", "<=", ">=", "=", "<>",
                         "AND", "&", "AND_THEN", "XOR", "OR", "OR_ELSE"})
_ASSIGN_OPS = frozenset({":=", "REF=", "?=", "S=", "R="})
_POU_KINDS = frozenset({"PROGRAM", "FUNCTION_BLOCK", "FUNCTION"})

# (class, field) -> the set of values allowed
_ENUM_FIELDS = {
    (ir.Unary, "op"): _UNARY_OPS,
    (ir.Binary, "op"): _BINARY_OPS,
    (ir.Assign, "op"): _ASSIGN_OPS,
    (ir.VarBlock, "kind"): frozenset(ir.VAR_KINDS),
    (ir.ActionAssoc, "qualifier"): frozenset(ir.ACTION_QUALIFIERS),
    (ir.PropertyAccessor, "kind"): frozenset({"GET", "SET"}),
    (ir.Pou, "kind"): _POU_KINDS,
    (ir.VarDecl, "edge"): frozenset({"R_EDGE", "F_EDGE"}),
}
# type and interface references may be qualified with a library namespace (``Lib.T``);
# VAR_CONFIG / VAR_ACCESS declarations name instance paths (``Res.Inst.var``)
_PATH = ("path",)
_QUALIFIED = {(ir.NamedType, "name"), (ir.Pou, "extends"), (ir.Pou, "implements"),
              (ir.Interface, "extends"), (ir.StructType, "extends"),
              (ir.ProgramInstance, "type_name"), (ir.EnumLiteral, "type_name"), _PATH}
_ADDRESS_FIELDS = {(ir.DirectAddress, "address"), (ir.VarDecl, "address")}
# fields whose text never reaches generated code
_FREE_TEXT = {
    (ir.Pou, "pragmas"), (ir.Method, "pragmas"), (ir.TypeDecl, "pragmas"),
    (ir.Program, "pragmas"), (ir.Program, "source"),
    # emitted only through repr() (in the error raised when it is executed) or not at all
    (ir.Opaque, "what"), (ir.Opaque, "text"),
}


def is_identifier(name) -> bool:
    """True for an IEC identifier as plcpred accepts it (see the module docstring)."""
    return (isinstance(name, str) and len(name) <= MAX_NAME_LENGTH
            and _IDENT.fullmatch(name) is not None and _HAS_ALNUM.search(name) is not None)


def _bad_name(name, pos, what: str) -> ProgramError:
    shown = repr(name) if isinstance(name, str) else type(name).__name__
    if isinstance(name, str) and len(name) > 60:
        shown = repr(name[:60]) + "..."
    if isinstance(name, str) and len(name) > MAX_NAME_LENGTH and _IDENT.fullmatch(name):
        return at(pos, f"{what} is {len(name)} characters long; names are limited to "
                       f"{MAX_NAME_LENGTH}")
    return at(pos, f"{what} {shown} is not an IEC 61131-3 identifier (ASCII letters, digits "
                   "and '_', not starting with a digit)")


def _literal_ok(value) -> bool:
    if isinstance(value, float):
        return math.isfinite(value)
    return isinstance(value, (bool, int, str))


def is_qualified_name(name) -> bool:
    """``Namespace.Type`` (a library-qualified type or interface reference)."""
    return isinstance(name, str) and len(name) <= MAX_NAME_LENGTH and all(
        is_identifier(part) for part in name.split("."))


def _name_ok(name, ctx) -> bool:
    return is_qualified_name(name) if ctx in _QUALIFIED else is_identifier(name)


def validate_names(program: ir.Program) -> ir.Program:
    """Check every string of ``program`` against what its field allows (module docstring).
    Returns the program; raises :class:`ProgramError` at the offending node's position (or
    the nearest enclosing node that has one)."""
    stack = [(program, None, None, _NO_DEPTH)]
    # names already checked (names repeat): as identifiers, and as qualified names
    good, good_qualified = set(), set()
    while stack:
        node, pos, ctx, depth = stack.pop()
        cls = node.__class__
        if cls is ir.Pos:
            continue
        if cls is list or cls is tuple or isinstance(node, (list, tuple)):
            if isinstance(node, ir.Pos):
                continue
            known = good_qualified if ctx in _QUALIFIED else good
            for item in node:
                if isinstance(item, str):
                    if item not in known:
                        if not _name_ok(item, ctx):
                            raise _bad_name(item, pos, _what(*ctx) if ctx else "name")
                        known.add(item)
                elif item is not None and not isinstance(item, (int, float)):
                    stack.append((item, pos, ctx, depth))
            continue
        if isinstance(node, dict):
            for k, v in node.items():
                if not is_identifier(k):
                    raise _bad_name(k, pos, "name")
                stack.append((v, pos, ctx, depth))
            continue
        plan = _PLANS.get(cls)
        if plan is None:
            if not dataclasses.is_dataclass(node):
                raise at(pos, f"unexpected {type(node).__name__} in the program structure")
            plan = _plan(node)
        pos = getattr(node, "pos", None) or pos
        if plan[0]:
            depth = _deeper(node, depth, pos)
        paths = cls is ir.VarBlock and node.kind in ("VAR_CONFIG", "VAR_ACCESS")
        for name, key, check, allowed in plan[1]:
            value = getattr(node, name)
            if value is None or value.__class__ is bool:
                continue
            if check is _GENERIC:
                if isinstance(value, str):
                    known = good_qualified if key in _QUALIFIED else good
                    if value not in known:
                        if not _name_ok(value, key):
                            raise _bad_name(value, pos, _what(cls, name))
                        known.add(value)
                elif not isinstance(value, (int, float)):
                    stack.append((value, pos, key, depth))
            elif check is _ENUM:
                if value not in allowed:
                    raise at(pos, f"invalid {name} {str(value)[:60]!r}")
            elif check is _LITERAL:
                if not _literal_ok(value):
                    raise at(pos, f"invalid literal value of type {type(value).__name__}")
            elif check is _ADDRESS_FIELD:
                if not (isinstance(value, str) and _ADDRESS.fullmatch(value)):
                    raise at(pos, f"invalid direct address {str(value)[:60]!r}")
            else:
                _check_special(node, name, key, check, value, pos, ctx, depth, paths, stack)
    return program


# how validate_names checks a field (see _plan)
_GENERIC, _ENUM, _LITERAL, _ADDRESS_FIELD, _DECL_NAME, _BIT, _DECLS = range(7)
_DEPTH_CLASSES = _TYPES + _INITIALIZERS + _EXPRESSIONS + _STATEMENTS + (
    ir.Pou, ir.Method, ir.PropertyAccessor, ir.SfcAction)
# dataclass -> (whether _deeper counts it, ((field, key, check, allowed values), ...))
_PLANS: dict[type, tuple] = {}


def _plan(node) -> tuple:
    """How :func:`validate_names` checks the fields of ``node``'s class, in field order:
    worked out once per class (``dataclasses.fields`` for every node cost more than
    the checks)."""
    cls = type(node)
    fields = []
    for f in dataclasses.fields(node):
        key = (cls, f.name)
        if f.name == "pos" or key in _FREE_TEXT:
            continue
        if key in _ENUM_FIELDS:
            check = _ENUM
        elif key == (ir.Literal, "value"):
            check = _LITERAL
        elif key in _ADDRESS_FIELDS:
            check = _ADDRESS_FIELD
        elif key == (ir.VarDecl, "name"):
            check = _DECL_NAME
        elif key == (ir.BitAccess, "bit"):
            check = _BIT
        elif cls is ir.VarBlock and f.name == "decls":
            check = _DECLS
        else:
            check = _GENERIC
        fields.append((f.name, key, check, _ENUM_FIELDS.get(key)))
    plan = (issubclass(cls, _DEPTH_CLASSES), tuple(fields))
    if not isinstance(node, type):
        _PLANS[cls] = plan
    return plan


def _check_special(node, name, key, check, value, pos, ctx, depth, paths, stack) -> None:
    """The checks of a VarDecl's name, a bit number and a VarBlock's declarations, as
    for any other field but for what sets them apart."""
    if isinstance(value, str):
        if check is _DECL_NAME and ctx == _PATH:
            key = _PATH  # VAR_CONFIG / VAR_ACCESS: an instance path, never emitted
        if not _name_ok(value, key):
            raise _bad_name(value, pos, _what(type(node), name))
    elif isinstance(value, (int, float)):
        if check is _BIT and not (isinstance(value, int) and 0 <= value < 64):
            raise at(pos, f"bit number {value} is outside 0..63")
    elif check is _DECLS and paths:
        stack.extend((d, pos, _PATH, depth) for d in value)
    else:
        stack.append((value, pos, key, depth))


def _deeper(node, depth, pos):
    """The (expression, statement, loop, type, initialiser) nesting inside ``node``; an
    error past a limit."""
    expr, stmt, loop, typ, init = depth
    if isinstance(node, _TYPES):
        typ += len(node.dims) if isinstance(node, ir.ArrayType) else 1
        if typ > MAX_TYPE_DEPTH:
            raise at(pos, f"type nested more than {MAX_TYPE_DEPTH} levels deep (ARRAY "
                          "dimensions, POINTER TO, REFERENCE TO and STRUCT inside each "
                          "other); name the inner types with TYPE declarations")
    elif isinstance(node, _INITIALIZERS):
        init += 1
        if init > MAX_INITIALIZER_DEPTH:
            raise at(pos, f"initial value nested more than {MAX_INITIALIZER_DEPTH} levels "
                          "deep ([...] and (name := ...) inside each other)")
    elif isinstance(node, _EXPRESSIONS):
        expr += 3 if isinstance(node, ir.Index) else 1  # a bounds check wraps each index
        if expr > MAX_EXPRESSION_DEPTH:
            raise at(pos, f"expression nested more than {MAX_EXPRESSION_DEPTH} levels deep; "
                          "split it with intermediate variables")
    elif isinstance(node, _STATEMENTS):
        expr, stmt = 0, stmt + 1
        if stmt > MAX_STATEMENT_DEPTH:
            raise at(pos, f"statements nested more than {MAX_STATEMENT_DEPTH} levels deep "
                          "(IF, CASE and loops inside each other)")
        if isinstance(node, _LOOPS):
            loop += 1
            if loop > MAX_LOOP_DEPTH:
                raise at(pos, f"loops nested more than {MAX_LOOP_DEPTH} levels deep")
    elif isinstance(node, (ir.Pou, ir.Method, ir.PropertyAccessor, ir.SfcAction)):
        return _NO_DEPTH
    return (expr, stmt, loop, typ, init)


def _what(cls, field_name: str) -> str:
    kind = cls.__name__
    label = {"Name": "name", "Member": "member name", "NamedType": "type name",
             "VarDecl": "variable name", "Pou": "POU name", "Method": "method name",
             "Property": "property name", "Step": "step name", "SfcAction": "action name",
             "ActionAssoc": "action name", "Label": "label", "Jmp": "label",
             "TypeDecl": "type name", "Task": "task name", "Arg": "parameter name"}
    return label.get(kind, f"{kind} {field_name}")


def ident(name: str) -> str:
    """The one way a program's name becomes a Python name in generated code.

    IEC identifiers are case-insensitive, so the compiler upper-cases them; every name
    the compiler itself generates contains a lower-case letter (``_now``, ``fb_MOTOR``,
    ``m_START``), and an upper-cased ASCII identifier is never a Python keyword or
    builtin, so the two namespaces cannot meet. A name that is not an identifier here is
    a bug in a front end (they all pass :func:`validate_names`), reported as such."""
    if not is_identifier(name):
        raise ProgramError(f"internal: name {str(name)[:60]!r} reached the compiler "
                           "unvalidated")
    return name.upper()
