"""The lark transformer that builds IR nodes as the LALR parser reduces (no parse tree is
ever materialised), and the glue that runs a grammar over a :class:`Tokenizer`."""
from __future__ import annotations

import contextvars
import gc
import threading
from functools import partial
from operator import itemgetter

from . import ir, tables
from .errors import ProgramError
from .lexer import Token
from .literals import parse_int, parse_real, parse_time_literal, parse_typed_literal, unquote_string

# IEC 61131-3 precedence, larger binds tighter (see grammar.py).
PRECEDENCE = {
    "OR": 1, "OR_ELSE": 1, "XOR": 2, "AND": 3, "AMP": 3, "AND_THEN": 3, "EQ": 4, "NE": 4,
    "LT": 5, "GT": 5, "LE": 5, "GE": 5, "PLUS": 6, "MINUS": 6, "STAR": 7, "SLASH": 7,
    "MOD": 7, "POW": 8,
}
OP_TEXT = {"AMP": "AND", "EQ": "=", "NE": "<>", "LT": "<", "GT": ">", "LE": "<=", "GE": ">=",
           "PLUS": "+", "MINUS": "-", "STAR": "*", "SLASH": "/", "POW": "**"}
ACCESS = {"PUBLIC", "PRIVATE", "PROTECTED", "INTERNAL"}
TIMED_QUALIFIERS = {"L", "D", "SD", "DS", "SL"}
_COMPOUND = (ir.If, ir.Case, ir.For, ir.While, ir.Repeat, ir.Try)
_STATEMENT_TYPES = tuple(ir.Stmt.__args__)


class _QualName(str):
    """A possibly dotted name (``Lib.FB_X``) that remembers where it was written."""

    def __new__(cls, text, pos):
        obj = super().__new__(cls, text)
        obj.pos = pos
        return obj


class _FbInit:
    """A type with FB_init arguments (``FB_T(5)``), until var_decl takes the arguments;
    ``per_element``: an array element type's arguments for each element in turn
    (``FB_T[(5), (6)]``)."""
    __slots__ = ("type", "args", "per_element")

    def __init__(self, type_, args, per_element=None):
        self.type = type_
        self.args = args
        self.per_element = per_element


class _Several(list):
    """Statements one construct stands for (``a := b := 0;``), spliced into the list."""


class _CaseHead:
    __slots__ = ("labels", "pos")

    def __init__(self, labels, pos):
        self.labels = labels
        self.pos = pos


def _spliced(items):
    for item in items:
        if isinstance(item, _Several):
            yield from item
        else:
            yield item


class IRBuilder:
    """Callbacks named after grammar rules and aliases, called with the rule's kept children
    as arguments. ``file`` is set before each parse."""

    def __init__(self):
        self.file = "<input>"

    # ------------------------------------------------------------------ helpers
    def _pos(self, tok: Token) -> ir.Pos:
        return ir.Pos(self.file, tok.line, tok.column)

    def _err(self, message: str, pos) -> ProgramError:
        if pos is None:
            return ProgramError(message, self.file, 0, 0)
        return ProgramError(message, pos.file, pos.line, pos.col)

    # ------------------------------------------------------------------ expressions
    def expr(self, *items):
        if len(items) == 1:
            return items[0]
        operands = [items[0]]
        ops: list[Token] = []

        def reduce():
            op = ops.pop()
            right = operands.pop()
            left = operands.pop()
            operands.append(ir.Binary(OP_TEXT.get(op.type, op.type), left, right, pos=left.pos))

        for i in range(1, len(items), 2):
            op = items[i]
            prec = PRECEDENCE[op.type]
            while ops and PRECEDENCE[ops[-1].type] >= prec:
                reduce()
            ops.append(op)
            operands.append(items[i + 1])
        while ops:
            reduce()
        return operands[0]

    def neg(self, tok, operand):
        return ir.Unary("-", operand, pos=self._pos(tok))

    def plus(self, tok, operand):
        return ir.Unary("+", operand, pos=self._pos(tok))

    def not_(self, tok, operand):
        return ir.Unary("NOT", operand, pos=self._pos(tok))

    def member(self, base, name):
        return ir.Member(base, str(name), pos=base.pos)

    def bit_access(self, base, bit):
        text = bit.value.replace("_", "")
        # the length first: int() of thousands of digits is an error of its own
        if not (text.isascii() and text.isdigit()) or len(text.lstrip("0")) > 2 \
                or int(text) > 63:
            shown = bit.value if len(bit.value) <= 20 else bit.value[:20] + "..."
            raise self._err(f"bit access .{shown}: a bit number 0..63 in decimal",
                            self._pos(bit))
        return ir.BitAccess(base, int(text), pos=base.pos)

    def index(self, base, *indices):
        return ir.Index(base, list(indices), pos=base.pos)

    def deref(self, base):
        return ir.Deref(base, pos=base.pos)

    def call(self, func, args):
        return ir.Call(func, args or [], pos=func.pos)

    def name(self, tok):
        return ir.Name(tok.value, pos=ir.Pos(self.file, tok.line, tok.column))

    def address(self, tok):
        return ir.DirectAddress(str(tok).upper(), pos=self._pos(tok))

    def int_lit(self, tok):
        text = tok.value
        try:
            value = int(text) if text.isdigit() and len(text) < 19 else parse_int(text)
        except ValueError as e:
            raise self._err(str(e), self._pos(tok)) from None
        return ir.Literal(value, "ANY_INT", pos=ir.Pos(self.file, tok.line, tok.column))

    def real_lit(self, tok):
        try:
            value = parse_real(tok.value)
        except ValueError as e:
            raise self._err(str(e), self._pos(tok)) from None
        return ir.Literal(value, "ANY_REAL", pos=self._pos(tok))

    def typed_lit(self, tok):
        try:
            value, type_name = parse_typed_literal(str(tok))
        except ValueError as e:
            raise self._err(str(e), self._pos(tok)) from None
        return ir.Literal(value, type_name, pos=self._pos(tok))

    def time_lit(self, tok):
        try:
            value, type_name = parse_time_literal(str(tok))
        except ValueError as e:
            shown = str(tok) if len(str(tok)) <= 40 else str(tok)[:40] + "..."
            raise self._err(f"bad time literal {shown}: {e}", self._pos(tok)) from None
        return ir.Literal(value, type_name, pos=self._pos(tok))

    def string_lit(self, tok):
        try:
            value = unquote_string(str(tok))
        except ValueError as e:
            raise self._err(str(e), self._pos(tok)) from None
        return ir.Literal(value, "WSTRING" if tok.type == "WSTRING_LIT" else "STRING",
                          pos=self._pos(tok))

    def bool_lit(self, tok):
        return ir.Literal(tok.type == "TRUE", "BOOL", pos=self._pos(tok))

    def enum_lit(self, tok):
        type_name, value = str(tok).split("#", 1)
        return ir.EnumLiteral(type_name, value, pos=self._pos(tok))

    def fn_operator(self, tok):
        return tok

    def new_string(self, func, tok, length, count):
        """``__NEW(STRING(80))``, ``SIZEOF(WSTRING(10))``: a string type where a call
        takes a type."""
        return self._type_call(func, tok, self.string_type(tok, length), count)

    def string_kw(self, tok):
        return tok

    def new_pointers(self, func, tok, target, count):
        """``__NEW(POINTER TO T, n)`` and ``SIZEOF(POINTER TO T)`` (TwinCAT's XSIZEOF
        too): the calls that take a pointer type."""
        pos = self._pos(tok)
        return self._type_call(func, tok, ir.PointerType(self._plain(target), pos=pos),
                               count)

    def _type_call(self, func, tok, type_, count):
        name = func.name.upper() if isinstance(func, ir.Name) else ""
        if name not in ("__NEW", "SIZEOF", "XSIZEOF") or (name != "__NEW"
                                                           and count is not None):
            raise self._err("only __NEW and SIZEOF take a type: __NEW(POINTER TO T, n), "
                            "SIZEOF(POINTER TO T)", self._pos(tok))
        pos = self._pos(tok)
        args = [ir.Arg(None, ir.TypeExpr(type_, pos=pos), pos=pos)]
        if count is not None:
            args.append(ir.Arg(None, count, pos=count.pos))
        return ir.Call(func, args, pos=func.pos)

    def assign_expr(self, target, value):
        return ir.AssignExpr(target, value, pos=target.pos)

    def operator_call(self, op, args):
        return ir.Call(ir.Name(str(op).upper(), pos=self._pos(op)), args, pos=self._pos(op))

    def args(self, *args):
        # an input bound to nothing (``x := ,``, as TwinCAT accepts) is left open
        return [a for a in args if a is not None]

    def pos_arg(self, value):
        return ir.Arg(None, value, pos=value.pos)

    def named_arg(self, name, value):
        if value is None:
            return None
        return ir.Arg(str(name), value, pos=self._pos(name))

    def out_arg(self, name, target):
        return ir.Arg(str(name), target, output=True, pos=self._pos(name))

    def neg_out_arg(self, _not, name, target):
        return ir.Arg(str(name), target, output=True, negated=True, pos=self._pos(name))

    # ------------------------------------------------------------------ statements
    def stmt_list(self, *stmts):
        out = []
        prev = None
        for s in _spliced(stmts):
            # ``END_IF;``: the semicolon vendors accept after a compound statement is not an
            # empty statement of its own.
            if type(s) is ir.Empty and isinstance(prev, _COMPOUND):
                prev = s
                continue
            out.append(s)
            prev = s
        return out

    def assign(self, target, value):
        return ir.Assign(target, value, pos=target.pos)

    def chained_assign(self, first, second, value):
        """``a := b := v;`` (CODESYS, TwinCAT): b := v, then a := b."""
        return _Several([ir.Assign(second, value, pos=second.pos),
                         ir.Assign(first, second, pos=first.pos)])

    def ref_assign(self, target, value):
        return ir.Assign(target, value, "REF=", pos=target.pos)

    def set_assign(self, target, value):
        return ir.Assign(target, value, "S=", pos=target.pos)

    def reset_assign(self, target, value):
        return ir.Assign(target, value, "R=", pos=target.pos)

    def attempt_assign(self, target, value):
        return ir.Assign(target, value, "?=", pos=target.pos)

    def call_stmt(self, expr):
        if isinstance(expr, (ir.Name, ir.Member)) and DIALECT.get() == "bnr":
            # B&R calls an action (or an FB instance) by its name alone: ``Blow;``
            return ir.CallStmt(ir.Call(expr, [], pos=expr.pos), pos=expr.pos)
        if not isinstance(expr, ir.Call):
            hint = (" (B&R calls an action by its name alone: read the file with "
                    "--dialect bnr)" if isinstance(expr, ir.Name) else "")
            raise self._err("expected ':=' (assignment) or '(' (call) after this "
                            f"expression{hint}", expr.pos)
        return ir.CallStmt(expr, pos=expr.pos)

    def if_stmt(self, tok, cond, body, *rest):
        else_body = rest[-1]
        branches = [(cond, body)] + list(rest[:-1])
        return ir.If(branches, else_body, pos=self._pos(tok))

    def elsif(self, cond, body):
        return (cond, body)

    def case_stmt(self, tok, selector, *rest):
        else_body = rest[-1]
        branches: list[ir.CaseBranch] = []
        prev = None
        for part in _spliced(rest[:-1]):
            if isinstance(part, _CaseHead):
                branches.append(ir.CaseBranch(part.labels, [], pos=part.pos))
            elif not branches:
                if type(part) is ir.Empty:
                    continue
                raise self._err("expected a CASE label such as '1:' before this statement",
                                getattr(part, "pos", None) or self._pos(tok))
            elif type(part) is ir.Empty and isinstance(prev, _COMPOUND):
                pass
            else:
                branches[-1].body.append(part)
            prev = part
        return ir.Case(selector, branches, else_body, pos=self._pos(tok))

    def case_head(self, *labels):
        return _CaseHead(list(labels), labels[0].pos)

    def case_range(self, low, high):
        return ir.CaseRange(low, high, pos=low.pos)

    def for_stmt(self, tok, var, start, end, step, body):
        if type(var) is ir.Name:
            return ir.For(var.name, start, end, step, body, pos=self._pos(tok))
        base = var
        while isinstance(base, (ir.Index, ir.Member)):
            base = base.base
        if type(base) is not ir.Name:
            raise self._err("the FOR control variable must be a variable, an array element "
                            "or a member", self._pos(tok))
        return ir.For(base.name, start, end, step, body, pos=self._pos(tok), target=var)

    def while_stmt(self, tok, cond, body):
        return ir.While(cond, body, pos=self._pos(tok))

    def repeat_stmt(self, tok, body, cond):
        return ir.Repeat(body, cond, pos=self._pos(tok))

    def try_stmt(self, tok, body, catch, finally_body):
        var, catch_body = catch if catch is not None else (None, None)
        return ir.Try(body, catch_body, finally_body, var, pos=self._pos(tok))

    def catch_plain(self, body):
        return (None, body)

    def catch_var(self, tok, body):
        return (ir.Name(str(tok), pos=self._pos(tok)), body)

    def exit_stmt(self, tok):
        return ir.Exit(pos=self._pos(tok))

    def continue_stmt(self, tok):
        return ir.Continue(pos=self._pos(tok))

    def return_stmt(self, tok):
        return ir.Return(pos=self._pos(tok))

    def conditional_return(self, tok, cond):
        """TwinCAT's ``RETURN(cond);``: return when ``cond`` is TRUE."""
        return ir.If([(cond, [ir.Return(pos=self._pos(tok))])], pos=self._pos(tok))

    def conditional_return_assign(self, tok, target, value):
        """``RETURN(x := cond);``: x := cond, then return when x is TRUE."""
        return _Several([ir.Assign(target, value, pos=target.pos),
                         self.conditional_return(tok, target)])

    def empty_stmt(self):
        return ir.Empty()

    def jmp_stmt(self, tok, label):
        return ir.Jmp(str(label), pos=self._pos(tok))

    def label_stmt(self, name):
        return ir.Label(str(name), pos=self._pos(name))

    def inline_stmt(self, tok):
        return ir.Opaque("inline code block {{ }}", str(tok)[2:-2], pos=self._pos(tok))

    # ------------------------------------------------------------------ types
    def qual_name(self, *names):
        return _QualName(".".join(str(n) for n in names), self._pos(names[0]))

    def name_list(self, *names):
        return list(names)

    def qual_list(self, *names):
        return list(names)

    def named_type(self, name):
        return ir.NamedType(str(name), pos=name.pos)

    def string_type(self, tok, length):
        return ir.StringType(tok.type == "WSTRING", length, pos=self._pos(tok))

    def array_type(self, *parts):
        element = parts[-1]
        if isinstance(element, _FbInit):
            # ``ARRAY[1..3] OF FB_T(5)``: every element gets the FB_init arguments
            # (``OF FB_T[(5), (6), (7)]``: each element its own)
            return _FbInit(ir.ArrayType(list(parts[:-1]), element.type), element.args,
                           element.per_element)
        return ir.ArrayType(list(parts[:-1]), element)

    def array_dim(self, low, high):
        return (low, high)

    def star_dim(self, _star):
        return (None, None)

    def pointer_type(self, tok, target):
        target = self._plain(target)
        return ir.PointerType(target, tok.type == "REFERENCE", pos=self._pos(tok))

    def generic_type(self, name, _lt, *rest):
        args = [a if isinstance(a, ir.Arg) else ir.Arg(None, a, pos=a.pos)
                for a in rest[:-1]]
        return ir.NamedType(str(name), pos=name.pos, generic_args=args)

    def generic_int(self, tok):
        return self.int_lit(tok)

    def generic_name(self, qn):
        return ir.Name(str(qn), pos=qn.pos)

    def named_generic_arg(self, name, value):
        return ir.Arg(str(name), value, pos=self._pos(name))

    def generic_fb_init_type(self, name, _lt, *rest):
        *generic, _gt, args = rest
        return _FbInit(self.generic_type(name, _lt, *generic, _gt), args or [])

    def fb_init_type(self, name, args):
        return _FbInit(ir.NamedType(str(name), pos=name.pos), args or [])

    def fb_init_args(self, args):
        return list(args or [])

    def fb_init_list_type(self, name, *lists):
        return _FbInit(ir.NamedType(str(name), pos=name.pos), None, list(lists))

    def _plain(self, t):
        """A type where FB_init arguments cannot stand."""
        if isinstance(t, _FbInit):
            raise self._err("FB_init arguments belong in a variable declaration",
                            t.type.pos)
        return t

    def subrange_type(self, base, low, high):
        return ir.SubrangeType(str(base), low, high, pos=base.pos)

    def enum_type(self, *parts):
        base = parts[-1]
        return ir.EnumType(list(parts[:-1]), str(base) if base is not None else None)

    def enum_value(self, name, value):
        return (str(name), value)

    def struct_type(self, tok, *decl_lists):
        members = [d for decls in decl_lists for d in decls]
        return ir.StructType(members, None, tok.type == "UNION", pos=self._pos(tok))

    def array_init(self, *items):
        return ir.ArrayInit(list(items))

    def single_item(self, value):
        return (1, value)

    def repeated_item(self, count, value):
        try:
            n = parse_int(count.value)
        except ValueError as e:
            raise self._err(str(e), self._pos(count)) from None
        return (n, value)

    def struct_init(self, *fields):
        return ir.StructInit(list(fields))

    def field_init(self, name, value):
        return (str(name), value)

    # ------------------------------------------------------------------ declarations
    def var_blocks(self, *blocks):
        return list(blocks)

    def var_kind(self, tok):
        return tok

    def var_qualifier(self, tok):
        return str(tok).upper()

    def var_block(self, kind, *rest):
        qualifiers = [r for r in rest if isinstance(r, str)]
        decls = [d for r in rest if isinstance(r, list) for d in r]
        return ir.VarBlock(kind.type, decls, qualifiers, pos=self._pos(kind))

    def var_decl(self, names, address, type_, edge, init):
        if edge is not None and str(edge).upper() not in ("R_EDGE", "F_EDGE"):
            raise self._err(f"expected R_EDGE, F_EDGE, ':=' or ';' after the type, found "
                            f"'{edge}'", self._pos(edge))
        args = per_element = None
        if isinstance(type_, _FbInit):
            if type_.per_element is not None and not isinstance(type_.type, ir.ArrayType):
                raise self._err("FB_init arguments in [...] are for the elements of an "
                                "ARRAY of function blocks", type_.type.pos)
            type_, args, per_element = type_.type, type_.args, type_.per_element
        addr = str(address).upper() if address is not None else None
        if addr is not None and len(names) > 1:
            raise self._err("an AT address can be given to one variable only",
                            self._pos(names[1]))
        edge = str(edge).upper() if edge is not None else None
        return [ir.VarDecl(str(n), type_, init, addr, pos=self._pos(n), init_args=args,
                           edge=edge, element_init_args=per_element) for n in names]

    def anonymous_at_decl(self, address, type_, init):
        """``AT %IX1.1 : BOOL;``: a located variable without a name (IEC 61131-3 allows
        it; code reads it by its address). It is declared under a name made from the
        address (``_AT_IX1_1``), which no IEC identifier the user writes can clash with
        by accident and which names the address in messages."""
        addr = address.value.upper()
        return [ir.VarDecl(anonymous_at_name(addr), self._plain(type_), init, addr,
                           pos=self._pos(address))]

    def access_decl(self, names, path, type_, mode):
        """A VAR_ACCESS entry: ``name : Resource.Instance.var : INT READ_WRITE;``. The
        access name is read as a variable of its own (the path is for a client, OPC or
        HMI, that reaches the program through it; plcpred does not follow it)."""
        if len(names) != 1:
            raise self._err("a VAR_ACCESS entry names one access path", self._pos(names[1]))
        if mode is not None and str(mode).upper() not in ("READ_WRITE", "READ_ONLY"):
            raise self._err(f"expected READ_WRITE or READ_ONLY, found '{mode}'",
                            self._pos(mode))
        return [ir.VarDecl(str(names[0]), self._plain(type_), pos=self._pos(names[0]))]

    def config_path(self, *names):
        return _QualName(".".join(n.value for n in names), self._pos(names[0]))

    def config_decl(self, path, address, type_, init):
        """A VAR_CONFIG entry: ``Resource.Instance.Variable AT %QX1.0 : BOOL``."""
        return [ir.VarDecl(str(path), self._plain(type_), init, address.value.upper(),
                           pos=path.pos)]

    # ------------------------------------------------------------------ POUs
    def modifiers(self, *mods):
        return list(mods)

    def modifier(self, tok):
        return str(tok).upper()

    def _split_modifiers(self, mods):
        access = next((m for m in mods if m in ACCESS), None)
        return access, [m for m in mods if m not in ACCESS]

    def body_items(self, *items):
        return self.stmt_list(*items)

    def _pou(self, kind, tok, name, var_blocks, items, **extra):
        stmts, steps, transitions, actions, methods, props = [], [], [], [], [], []
        for item in items:
            t = type(item)
            if t is ir.Step:
                steps.append(item)
            elif t is ir.Transition:
                transitions.append(item)
            elif t is ir.SfcAction:
                actions.append(item)
            elif t is ir.Method:
                methods.append(item)
            elif t is ir.Property:
                props.append(item)
            else:
                stmts.append(item)
        pou = ir.Pou(kind, str(name), var_blocks, stmts, methods=methods, properties=props,
                     pos=self._pos(tok), **extra)
        if steps or transitions:
            real = [s for s in stmts if type(s) is not ir.Empty]
            if real:
                raise self._err("statements cannot be mixed with SFC steps in one body",
                                real[0].pos)
            initial = [s for s in steps if s.initial]
            if len(initial) != 1:
                raise self._err(f"an SFC body needs exactly one INITIAL_STEP, found "
                                f"{len(initial)}", pou.pos)
            pou.body = ir.Sfc(steps, transitions, actions, pos=pou.pos)
        else:
            pou.actions = actions
        return pou

    def program_pou(self, tok, mods, name, var_blocks, items):
        access, modifiers = self._split_modifiers(mods)
        return self._pou("PROGRAM", tok, name, var_blocks, items, access=access,
                         modifiers=modifiers)

    def fb_pou(self, tok, mods, name, extends, implements, var_blocks, items):
        access, modifiers = self._split_modifiers(mods)
        base, base_args = extends if isinstance(extends, tuple) else (extends, [])
        return self._pou("FUNCTION_BLOCK", tok, name, var_blocks, items,
                         extends=str(base) if base else None, extends_args=base_args,
                         implements=[str(i) for i in implements or []], access=access,
                         modifiers=modifiers)

    def fb_pou_generic_head(self, tok, mods, name, head, extends, implements, var_blocks,
                            items):
        return self.fb_pou(tok, mods, name, extends, implements, [head] + var_blocks, items)

    def fb_pou_generic_head_impl(self, tok, mods, name, head, implements, var_blocks, items):
        return self.fb_pou(tok, mods, name, None, implements, [head] + var_blocks, items)

    def generic_head(self, block):
        if block.kind != "VAR_GENERIC":
            raise self._err(f"only VAR_GENERIC CONSTANT may stand before EXTENDS or "
                            f"IMPLEMENTS, not {block.kind}", block.pos)
        return block

    def extends_ref(self, name):
        return (str(name), [])

    def generic_extends(self, name, _lt, *rest):
        return (str(name), self.generic_type(name, _lt, *rest).generic_args)

    def class_pou(self, tok, mods, name, extends, implements, var_blocks, items):
        """A CLASS is read as the FUNCTION_BLOCK it is equivalent to (no body of its own:
        statements outside its methods are an error)."""
        if any(isinstance(i, _STATEMENT_TYPES) and type(i) is not ir.Empty for i in items):
            raise self._err(f"CLASS {name}: statements belong in its methods",
                            self._pos(tok))
        return self.fb_pou(tok, mods, name, extends, implements, var_blocks, items)

    def function_pou(self, tok, mods, name, ret, var_blocks, items):
        ret = self._plain(ret)
        access, modifiers = self._split_modifiers(mods)
        return self._pou("FUNCTION", tok, name, var_blocks, items, return_type=ret,
                         access=access, modifiers=modifiers)

    def method(self, tok, mods, name, ret, var_blocks, body):
        ret = self._plain(ret)
        access, modifiers = self._split_modifiers(mods)
        return ir.Method(str(name), ret, var_blocks, body, access, modifiers,
                         pos=self._pos(tok))

    def property(self, tok, mods, name, type_, *accessors):
        access, modifiers = self._split_modifiers(mods)
        return ir.Property(str(name), type_, list(accessors), access, modifiers,
                           pos=self._pos(tok))

    def accessor(self, mods, name, mods_after, var_blocks, body, end):
        kind = str(name).upper()
        if kind not in ("GET", "SET"):
            raise self._err(f"expected GET or SET in a PROPERTY, found '{name}'",
                            self._pos(name))
        if end != "END_" + kind:
            raise self._err(f"{kind} is closed by END_{kind}, not {end}", self._pos(name))
        return ir.PropertyAccessor(kind, var_blocks, body, pos=self._pos(name))

    def accessor_end(self, tok):
        return str(tok).upper()

    def action(self, tok, name, body):
        return ir.SfcAction(str(name), body, pos=self._pos(tok))

    def interface(self, tok, mods, name, extends, *items):
        return ir.Interface(str(name), [str(e) for e in extends or []],
                            [i for i in items if isinstance(i, ir.Method)],
                            [i for i in items if isinstance(i, ir.Property)],
                            pos=self._pos(tok))

    def type_block(self, tok, *decls):
        return list(decls)

    def type_decl(self, name, extends, type_, init):
        type_ = self._plain(type_)
        if extends is not None:
            if not isinstance(type_, ir.StructType):
                raise self._err("only a STRUCT type can EXTEND another", self._pos(name))
            type_.extends = str(extends)
        return ir.TypeDecl(str(name), type_, init, pos=self._pos(name))

    def global_block(self, block):
        return ir.GlobalVars(None, block, pos=block.pos)

    # ------------------------------------------------------------------ SFC
    def step(self, tok, name, *assocs):
        return ir.Step(str(name), tok.type == "INITIAL_STEP", list(assocs), pos=self._pos(tok))

    def action_assoc(self, name, args):
        qualifier, rest = ("N", []) if args is None else args
        pos = self._pos(name)
        return make_action_assoc(str(name), qualifier, rest, pos, self._err)

    def action_args(self, qualifier, *rest):
        return (str(qualifier), list(rest))

    def transition(self, tok, name, priority, sources, targets, cond):
        return ir.Transition(sources, targets, cond, priority or 0,
                             str(name) if name is not None else None, pos=self._pos(tok))

    def transition_priority(self, key, value):
        if str(key).upper() != "PRIORITY":
            raise self._err(f"expected PRIORITY := n, found '{key}'", self._pos(key))
        try:
            return parse_int(value.value)
        except ValueError as e:
            raise self._err(str(e), self._pos(value)) from None

    def step_set(self, *names):
        return [str(n) for n in names]

    # ------------------------------------------------------------------ configurations
    def configuration(self, tok, name, var_blocks, *items):
        resources = [i for i in items if isinstance(i, ir.Resource)]
        loose = [i for i in items if not isinstance(i, ir.Resource)]
        if loose:
            resources.insert(0, ir.Resource("", None,
                                            tasks=[i for i in loose if isinstance(i, ir.Task)],
                                            programs=[i for i in loose
                                                      if isinstance(i, ir.ProgramInstance)],
                                            pos=self._pos(tok)))
        return ir.Configuration(str(name), var_blocks, resources, pos=self._pos(tok))

    def resource(self, tok, name, on_kw, on, var_blocks, *items):
        if str(on_kw).upper() != "ON":
            raise self._err(f"expected ON after the resource name, found '{on_kw}'",
                            self._pos(on_kw))
        return ir.Resource(str(name), str(on), var_blocks,
                           [i for i in items if isinstance(i, ir.Task)],
                           [i for i in items if isinstance(i, ir.ProgramInstance)],
                           pos=self._pos(tok))

    def task(self, tok, name, params):
        return ir.Task(str(name), params or {}, pos=self._pos(tok))

    def task_params(self, *params):
        return dict(params)

    def task_param(self, key, value):
        return (str(key).upper(), value)

    def program_config(self, tok, retain, name, with_kw, task, type_name, args):
        if with_kw is not None and str(with_kw).upper() != "WITH":
            raise self._err(f"expected WITH, found '{with_kw}'", self._pos(with_kw))
        return ir.ProgramInstance(str(name), str(type_name), str(task) if task else None,
                                  args or [], retain, pos=self._pos(tok))

    def program_retain(self, tok):
        return str(tok).upper()

    # ------------------------------------------------------------------ root
    def start(self, *items):
        prog = ir.Program()
        last_pou = None
        for item in items:
            if isinstance(item, list):  # TYPE block
                prog.types.extend(item)
            elif prog.add(item):
                if isinstance(item, ir.Pou):
                    last_pou = item
            else:  # a METHOD, PROPERTY or ACTION written after its POU (TwinCAT/CODESYS export)
                if last_pou is None:
                    raise self._err(f"{type(item).__name__.upper()} '{item.name}' stands before "
                                    "any POU it could belong to", item.pos)
                if isinstance(item, ir.Method):
                    last_pou.methods.append(item)
                elif isinstance(item, ir.Property):
                    last_pou.properties.append(item)
                elif last_pou.is_sfc:
                    last_pou.body.actions.append(item)
                else:
                    last_pou.actions.append(item)
        return prog


# the dialect of the file being read where vendors disagree ("iec", or "bnr": B&R
# Automation Studio, whose files call an action by its name alone)
DIALECT: contextvars.ContextVar[str] = contextvars.ContextVar("dialect", default="iec")


def anonymous_at_name(address: str) -> str:
    """The name a located variable declared without one is kept under: ``%IX1.1`` ->
    ``_AT_IX1_1`` (upper case, as names are compared)."""
    return "_AT_" + "".join(ch if ch.isalnum() else "_" for ch in address.upper()[1:])


def make_action_assoc(name, qualifier, rest, pos, err):
    q = qualifier.upper()
    if q not in ir.ACTION_QUALIFIERS:
        raise err(f"unknown action qualifier '{qualifier}' (expected one of "
                  f"{', '.join(ir.ACTION_QUALIFIERS)})", pos)
    time = None
    if q in TIMED_QUALIFIERS:
        if not rest:
            raise err(f"qualifier {q} needs a time, e.g. {name}({q}, T#2s)", pos)
        time, rest = rest[0], rest[1:]
    indicator = None
    if rest:
        if len(rest) > 1 or not isinstance(rest[0], ir.Name):
            raise err("expected an indicator variable name after the qualifier", pos)
        indicator = rest[0].name
    return ir.ActionAssoc(name, q, time, indicator, pos=pos)


# ---------------------------------------------------------------------- running a grammar

_END = Token("$END", "", 0, 0)  # end of input, fed through the same loop


class _Recording:
    """The last two tokens read, for error messages."""
    __slots__ = ("prev", "last")

    def __init__(self):
        self.prev = None
        self.last = None


TOKEN_NAMES = {
    "NAME": "an identifier", "INTEGER": "an integer", "REAL": "a number",
    "STRING_LIT": "a string", "WSTRING_LIT": "a string", "ADDRESS": "an address",
    "TYPED_LIT": "a literal", "TIME_LIT": "a time literal", "ENUM_LIT": "an enumerated value",
    "_ASSIGN": "':='", "_OUTASSIGN": "'=>'", "_DOTDOT": "'..'", "_LPAR": "'('",
    "_RPAR": "')'", "_LSQB": "'['", "_RSQB": "']'", "_COMMA": "','", "_SEMI": "';'",
    "_COLON": "':'", "_DOT": "'.'", "_CARET": "'^'", "_ARROW": "'->'",
    "_ATTEMPT": "'?='", "_REFASSIGN": "'REF='", "_SETASSIGN": "'S='", "_RESETASSIGN": "'R='",
    "INLINE_CODE": "an inline code block", "DT_LIT": "a literal", "TOD_LIT": "a literal",
    "DATE_LIT": "a literal", "$END": "end of file",
}
# statements that stay open until their END_ keyword, and what ends them
_OPENERS = {"IF": "_END_IF", "CASE": "_END_CASE", "FOR": "_END_FOR", "WHILE": "_END_WHILE",
            "REPEAT": "_END_REPEAT"}
# tokens that end a statement list: a closer, or what starts the next POU or member
_LIST_ENDERS = {"PROGRAM", "FUNCTION_BLOCK", "FUNCTION", "METHOD", "PROPERTY", "ACTION", "TYPE",
                "INTERFACE", "END_GET", "END_SET", "CONFIGURATION"}
_NOT_ST = {"ELSEIF": "ELSIF", "ELSE_IF": "ELSIF", "ELIF": "ELSIF", "ENDIF": "END_IF",
           "ENDCASE": "END_CASE", "ENDFOR": "END_FOR", "ENDWHILE": "END_WHILE"}
_OPERATOR_TOKENS = {"PLUS", "MINUS", "STAR", "SLASH", "POW", "MOD", "LT", "GT", "LE", "GE",
                    "EQ", "NE", "AND", "AMP", "AND_THEN", "XOR", "OR", "OR_ELSE"}
_LITERAL_TOKENS = {"TYPED_LIT", "TIME_LIT", "DT_LIT", "TOD_LIT", "DATE_LIT", "ENUM_LIT",
                   "REAL", "WSTRING_LIT", "TRUE", "FALSE", "ADDRESS"}


def describe_token(tok) -> str:
    if tok is None:
        return "end of file"
    if tok.type in ("NAME",):
        return f"identifier '{tok}'"
    if tok.type.lstrip("_") == str(tok).upper():
        return f"keyword {str(tok).upper()}"
    return f"'{tok}'"


# AND, OR, XOR and MOD also start an expression, called as functions: AND(a, b)
_EXPRESSION_START = {"NAME", "INTEGER", "_LPAR", "MINUS", "PLUS", "NOT", "STRING_LIT", "AND",
                     "OR", "XOR", "MOD"}
_OP_NAMES = {"PLUS": "'+'", "MINUS": "'-'", "STAR": "'*'", "SLASH": "'/'", "POW": "'**'",
             "LT": "'<'", "GT": "'>'", "LE": "'<='", "GE": "'>='", "EQ": "'='", "NE": "'<>'",
             "AMP": "'&'"}


def describe_expected(expected: set[str]) -> str:
    """A short human list of what the parser could have accepted."""
    expected = set(expected)
    names = []
    if {"NAME", "INTEGER", "_LPAR"} <= expected:
        expected -= _EXPRESSION_START | _LITERAL_TOKENS | {"REAL"}
        names.append("an expression")
    ops = expected & _OPERATOR_TOKENS
    if len(ops) > 2:
        expected -= ops
    for t in sorted(expected, key=lambda t: (t not in ("_SEMI", "_ASSIGN", "_RPAR"), t)):
        names.append(TOKEN_NAMES.get(t) or _OP_NAMES.get(t) or t.lstrip("_"))
    if len(ops) > 2:
        names.append("an operator")
    names = list(dict.fromkeys(names))
    if len(names) > 8:
        names = names[:8] + ["..."]
    return names[0] if len(names) == 1 else "one of " + ", ".join(names)


class GrammarRunner:
    """One LALR parser for a grammar, shared by all parses (its tables read once, when
    first used: :mod:`.tables`).

    lark analysed the grammar (:mod:`.tablegen`); the reduce callbacks
    (:func:`_compile_rule`, lark's tree-building semantics calling :class:`IRBuilder`
    methods directly) and the shift/reduce loop are our own. lark's general loop and
    callback wrappers serve interactive parsing and debugging too, and cost about twice
    as much per token. Unit reductions of ``?`` rules, which only pass their single child
    up, skip the callback altogether.
    """

    def __init__(self, grammar: str, builder_cls=IRBuilder):
        self._grammar = grammar      # its name in grammar.GRAMMARS
        self._builder_cls = builder_cls
        self._tables = None
        self._builder = None
        self._chains: dict = {}
        self._lock = threading.Lock()

    def _get(self):
        if self._tables is None:
            self._builder = self._builder_cls()
            found = tables.load(self._grammar)
            self._tables = (found.rows, _Reducers(found.rules, self._builder), found.start,
                            found.end)
        return self._tables

    def parse(self, tokenizer, filename: str):
        with self._lock:
            states, reducers, start_state, end_state = self._get()
            self._builder.file = filename
            # the cyclic garbage collector finds nothing to free here (tokens and nodes
            # make no cycles), and its passes over the growing tree took a fifth of a
            # large file's parse; it is turned back on as it was found
            collecting = gc.isenabled()
            gc.disable()
            try:
                return _drive(iter(tokenizer), states, reducers, self._chains, start_state,
                              end_state, filename)
            finally:
                if collecting:
                    gc.enable()


# how a reduction makes its value (see _Reducers): the top value stays (a ``?rule`` with
# one child), ``func(*children)``, ``func(*pick(children))``, ``func(children[i])``, or
# ``func(children)`` (the general callback of _compile_rule)
PASS, STAR, PICK, ONE, CALL = range(5)


def _drive(tokens, states, reducers, chains, start_state, end_state, filename):
    """The shift/reduce loop over ``tokens``, then the end of the input. Written for
    speed: it runs for every token of every program read. ``chains``: the outcomes of
    runs of pass-through reductions (:func:`_pass_run`), kept between parses."""
    state_stack = [start_state]
    value_stack = []
    push_state = state_stack.append
    push_value = value_stack.append
    errors: list[ProgramError] = []
    prev = last = None      # the last two tokens read, for error messages
    row = states[start_state]
    try:
        for tok in tokens:
            prev, last = last, tok
            ttype = tok.type
            while True:
                act = row.get(ttype)
                if act is None:
                    tok = _recover(tok, row, prev, last, errors, tokens, states, state_stack,
                                   value_stack, filename)
                    ttype = tok.type
                    row = states[state_stack[-1]]
                    continue
                if act >= 0:
                    push_state(act)
                    push_value(tok)
                    row = states[act]
                    break
                size, origin, kind, func, arg = reducers[~act]
                if kind:
                    if size:
                        args = value_stack[-size:]
                        del state_stack[-size:]
                        del value_stack[-size:]
                    else:
                        args = []
                    try:
                        if kind == STAR:
                            push_value(func(*args))
                        elif kind == PICK:
                            push_value(func(*arg(args)))
                        elif kind == ONE:
                            push_value(func(args[arg]))
                        else:
                            push_value(func(args))
                    except Exception:
                        if errors:  # after recovery the values may not fit the rule
                            raise _with_more(errors) from None
                        raise
                else:
                    # pass-through reductions (a ``?rule`` of one child) replace the top
                    # state and keep the value; a run of them ends, for a given state
                    # below, top state and token, in one state, worked out once
                    key = (state_stack[-2], state_stack[-1], ttype)
                    act = chains.get(key)
                    if act is None:
                        act = chains[key] = _pass_run(key, states, reducers)
                    state_stack[-1] = act
                    row = states[act]
                    continue
                act = states[state_stack[-1]][origin]
                push_state(act)
                row = states[act]
        return _finish(row, prev, last, errors, tokens, states, reducers, state_stack,
                       value_stack, end_state, filename)
    except ProgramError as e:   # the tokenizer's, or a builder's, after earlier ones
        if not errors or e in errors:
            raise
        errors.append(e)
        raise _with_more(errors) from None


def _pass_run(key, states, reducers) -> int:
    """The top state after the pass-through reductions that follow one another from
    ``key`` = (state below, top state, token type): each replaces the top state by the
    goto of the state below (which stays), until the token meets another action."""
    below, top, ttype = key
    while True:
        act = states[top].get(ttype)
        if act is None or act >= 0 or reducers[~act][2] != PASS:
            return top
        top = states[below][reducers[~act][1]]


def _recover(tok, row, prev, last, errors, tokens, states, state_stack, value_stack,
             filename):
    """A syntax error at ``tok``: recorded, and the token to go on with (_resume)."""
    feed = _Recording()
    feed.prev, feed.last = prev, last
    errors.append(_syntax_error(None if tok is _END else tok, _expected(row), feed,
                                filename, value_stack))
    return _resume(tok, errors, tokens, states, state_stack, value_stack)


def _finish(row, prev, last, errors, tokens, states, reducers, state_stack, value_stack,
            end_state, filename):
    """The end of the input: reduce until the start rule is complete (the value of the
    whole input), or report what is missing."""
    push_state = state_stack.append
    push_value = value_stack.append
    while True:
        act = row.get("$END")
        if act is None:
            _recover(_END, row, prev, last, errors, tokens, states, state_stack,
                     value_stack, filename)   # raises: nothing follows the end
        if act >= 0:
            push_state(act)
            push_value(_END)
            return None
        size, origin, kind, func, arg = reducers[~act]
        if kind:
            if size:
                args = value_stack[-size:]
                del state_stack[-size:]
                del value_stack[-size:]
            else:
                args = []
            try:
                value = (func(*args) if kind == STAR else func(*arg(args)) if kind == PICK
                         else func(args[arg]) if kind == ONE else func(args))
            except Exception:
                if errors:
                    raise _with_more(errors) from None
                raise
            push_value(value)
        else:
            del state_stack[-1]
        act = states[state_stack[-1]][origin]
        push_state(act)
        row = states[act]
        if act == end_state:
            if errors:
                raise _with_more(errors)
            return value_stack[-1]


class _Reducers(dict):
    """Rule number -> (symbols popped, the rule's name for the goto, kind, function,
    argument): how :func:`_drive` reduces by the rule (:func:`_reduction`), worked out
    when the rule is first reduced."""

    def __init__(self, rules, builder):
        super().__init__()
        self._rules = rules
        self._builder = builder

    def __missing__(self, number):
        plan = self._rules[number]
        entry = (plan[2], plan[1], *_reduction(plan, self._builder))
        self[number] = entry
        return entry


MAX_SYNTAX_ERRORS = 20


def _with_more(errors: list[ProgramError]) -> ProgramError:
    """The first error, carrying the others (``.more``) for those who list them all."""
    first = errors[0]
    first.more = errors[1:MAX_SYNTAX_ERRORS]
    return first


def _resume(tok, errors, tokens, states, state_stack, value_stack):
    """Panic-mode recovery after a syntax error, so that one run reports the file's
    other errors too: skip to the next ';', unwind to the innermost statement list (the
    IF, CASE, loop or POU body the error is in) and resume there with the ';' as an empty
    statement. Raises the errors when there is no such place, at the end of the file, or
    after MAX_SYNTAX_ERRORS; later errors on the line of the previous one (knock-on
    effects of the first) are not reported."""
    if len(errors) >= MAX_SYNTAX_ERRORS or tok is _END:
        raise _with_more(errors)
    if len(errors) > 1 and errors[-1].line <= errors[-2].line:
        errors.pop()
    while tok.type != "_SEMI":
        try:
            tok = next(tokens, _END)
        except ProgramError as e:  # the tokenizer's: a bad character or literal
            errors.append(e)
            raise _with_more(errors) from None
        if tok is _END:
            raise _with_more(errors)
    def in_statement_list(state):   # where a statement may start, ';' among them
        row = states[state]
        return "_SEMI" in row and "IF" in row

    while len(state_stack) > 1 and not in_statement_list(state_stack[-1]):
        del state_stack[-1]
        del value_stack[-1]
    if not in_statement_list(state_stack[-1]):
        raise _with_more(errors)
    return tok


class _Splice(list):
    """Children of an inlined ``_rule``, to be spliced into the parent's children."""
    __slots__ = ()


def _reduction(rule, builder) -> tuple:
    """(kind, function, argument) of a rule's reduction (see :data:`PASS` ...): the
    builder method called directly where the rule's children need no reshaping (most
    reductions), else the callback of :func:`_compile_rule`."""
    name, _, size, expand1, plan, trailing = rule
    callback = _compile_rule(rule, builder)
    if callback is None:
        return PASS, None, None
    func = getattr(builder, name, None)
    keep = [i for i, splice, n in plan if not splice and not n]
    if func is None and not expand1 and not trailing and size == 2 \
            and plan == [[0, True, 0], [1, False, 0]]:
        # a list growing by one (lark's ``__x_star: __x_star x``), the most frequent of
        # the rest
        return CALL, partial(_grown, callback), None
    if func is None or trailing or len(keep) != len(plan) or (expand1 and len(keep) == 1):
        return CALL, callback, None
    if keep == list(range(size)):
        return STAR, func, None
    if len(keep) == 1:
        return ONE, func, keep[0]
    if keep:
        return PICK, func, itemgetter(*keep)
    return CALL, callback, None


def _grown(callback, children):
    """``callback(children)`` of a list rule ``__x_star: __x_star x``, which appends to
    the list it has so far, as the callback would."""
    first = children[0]
    if first.__class__ is _Splice:
        first.append(children[1])
        return first
    return callback(children)


def _compile_rule(rule, builder):
    """The reduce callback for one grammar rule (its plan, :func:`.tablegen.rule_plan`),
    with lark's tree-building semantics: filtered tokens dropped (unless ``!rule``),
    ``_rule`` children spliced in, ``None`` for absent ``[optional]`` items, ``?rule``
    with one child passing it up, then the builder method named after the alias or rule
    called with the children as arguments. Returns None for a pure pass-through (the
    driver then skips the call)."""
    name, _, size, expand1, plan, trailing = rule
    plan = [tuple(p) for p in plan]  # (child index, splice?, Nones to insert before it)
    func = getattr(builder, name, None)
    if expand1 and len(plan) == 1 and not plan[0][1] and plan[0][2] == 0 and not trailing \
            and size == 1:
        return None
    simple = not trailing and all(not splice and not n for _, splice, n in plan)
    keep = [i for i, _, _ in plan]
    everything = keep == list(range(size))

    def callback(children):
        if simple:
            filtered = children if everything else [children[i] for i in keep]
        else:
            filtered = None
            for i, splice, n in plan:
                if filtered is None:
                    if splice and not n and isinstance(children[i], _Splice):
                        # a left-recursive list (``_stmts: _stmts stmt``) grows in place:
                        # copying it at every reduction made long lists quadratic
                        filtered = children[i]
                        continue
                    filtered = _Splice()
                if n:
                    filtered.extend([None] * n)
                if splice:
                    filtered.extend(children[i])
                else:
                    filtered.append(children[i])
            if filtered is None:
                filtered = _Splice()
            if trailing:
                filtered.extend([None] * trailing)
        if expand1 and len(filtered) == 1:
            return filtered[0]
        if func is None:
            return filtered if isinstance(filtered, _Splice) else _Splice(filtered)
        return func(*filtered)

    return callback


def _expected(row) -> set[str]:
    return {s for s in row if s.isupper()}


def _syntax_error(tok, expected, feed: _Recording, filename: str,
                  value_stack=()) -> ProgramError:
    expected = set(expected)
    for t in (tok, feed.prev):
        if t is not None and t.type == "NAME" and t.value.upper() in _NOT_ST:
            return ProgramError(f"{t.value.upper()} is not Structured Text: did you mean "
                                f"{_NOT_ST[t.value.upper()]}?", filename, t.line, t.column)
    # the innermost statement still open, when the token is one that would have closed it
    opened = next((v for v in reversed(value_stack) if isinstance(v, Token)
                   and v.type in _OPENERS), None)
    ender = tok is None or tok.type.startswith("_END_") or tok.type in _LIST_ENDERS
    if opened is not None and ender and _OPENERS[opened.type] in expected | {
            "_END_REPEAT" if "_UNTIL" in expected else ""}:
        closer = _OPENERS[opened.type].lstrip("_")
        if opened.type == "REPEAT" and "_UNTIL" in expected:
            closer = "UNTIL ... END_REPEAT"
        found = "the end of the file" if tok is None else \
            f"{describe_token(tok)} at line {tok.line}"
        return ProgramError(f"{opened.type} is not closed: expected {closer} before {found}",
                            filename, opened.line, opened.column)
    if tok is None:  # end of input
        prev = feed.last
        line = prev.line if prev is not None else 1
        col = (prev.column + len(prev)) if prev is not None else 1
        # at the end of the file the useful hint is the construct left open
        pou = next((v for v in reversed(value_stack) if isinstance(v, Token)
                    and "_END_" + v.type in expected), None)
        if pou is not None:
            return ProgramError(f"unexpected end of file; expected END_{pou.type} (the "
                                f"{pou.type} at line {pou.line} is not closed)", filename,
                                line, col)
        closers = {t for t in expected if t.startswith("_END_")}
        return ProgramError(f"unexpected end of file; expected "
                            f"{describe_expected(closers or expected)}", filename, line, col)
    prev = feed.prev
    # a missing ';' is best reported where it belongs, at the end of the previous line
    if "_SEMI" in expected and prev is not None and prev.line < tok.line:
        return ProgramError(f"expected ';' after '{prev}' (found {describe_token(tok)} on the "
                            f"next line)", filename, prev.line, prev.column + len(prev))
    return ProgramError(f"unexpected {describe_token(tok)}; expected "
                        f"{describe_expected(expected)}", filename, tok.line, tok.column)
