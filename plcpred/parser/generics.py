"""Generic function blocks (CODESYS, TwinCAT 3.1.4026): ``VAR_GENERIC CONSTANT``.

A function block may declare constants whose values each instance gives in angle brackets
after the type: ``fbBuf : FB_Buf<100>;``, ``FB_Buf<(N * 2)>``, ``FB_Pou<100, 1000>`` (in
the order declared) or ``FB_Pou<(nMax := 12)>`` (by name), also as an array's element type.
They size arrays and strings, so every distinct set of values is its own type: this module
writes one copy of the block per set (its generic constants become ordinary constants with
those values) and points each instance at its copy, before the checker or the compiler sees
the program. The block as declared keeps its initial values, which the vendors use only to
check it; a block without them exists only through its copies.
"""
from __future__ import annotations

import copy
import re

from . import ir
from .errors import ProgramError
from .printer import expr as expr_text
from .typegraph import MAX_INHERITANCE_DEPTH


def _generic_block(pou: ir.Pou) -> list[ir.VarDecl]:
    return [d for b in pou.var_blocks if b.kind == "VAR_GENERIC" for d in b.decls]


def _type_refs(program: ir.Program):
    """Everything in ``program`` with a ``type``: declarations of variables (of POUs,
    methods, property accessors, GVLs, configurations) and TYPE declarations."""
    blocks = []
    for pou in program.pous:
        blocks += pou.var_blocks
        for m in pou.methods:
            blocks += m.var_blocks
        for prop in pou.properties:
            for acc in prop.accessors:
                blocks += acc.var_blocks
    blocks += [g.block for g in program.globals if g.block is not None]
    for c in program.configurations:
        blocks += c.var_blocks
        for r in c.resources:
            blocks += r.var_blocks
    for b in blocks:
        yield from b.decls
    yield from program.types


def _walk(t, visit=None, bound=None):
    """Type ``t`` with every NamedType inside it replaced by ``visit(it)`` and every array
    bound and string length by ``bound(expression)`` (each left as it is when None)."""
    if isinstance(t, ir.NamedType):
        return visit(t) if visit is not None else t
    if isinstance(t, ir.ArrayType):
        if bound is not None:
            t.dims = [(None, None) if lo is None else (bound(lo), bound(hi))
                      for lo, hi in t.dims]
        t.element = _walk(t.element, visit, bound)
    elif isinstance(t, ir.StringType):
        if bound is not None and t.length is not None:
            t.length = bound(t.length)
    elif isinstance(t, ir.PointerType):
        t.target = _walk(t.target, visit, bound)
    elif isinstance(t, ir.StructType):
        for d in t.members:
            d.type = _walk(d.type, visit, bound)
    return t


def specialize(program: ir.Program, context=()) -> ir.Program:
    """``program`` with every instance of a generic FB typed by a copy of the FB for its
    values (the FBs may be declared in ``context`` too, a library). ``program`` itself is
    not changed; it is returned as it is when nothing in it is generic."""
    if not any(_generic_block(p) or p.extends_args for p in program.pous) and not any(
            _has_generic_args(h.type) for h in _type_refs(program)):
        return program
    out = copy.deepcopy(program)
    generic = {}
    for pou in [p for prog in context for p in prog.pous] + out.pous:
        if pou.kind == "FUNCTION_BLOCK" and _generic_block(pou):
            generic[pou.name.upper()] = pou
    taken = {p.name.upper() for prog in (*context, out) for p in prog.pous}
    copies: dict[tuple, str] = {}
    added = []

    def visit(t: ir.NamedType):
        if not t.generic_args:
            return t
        # a library's block named with its namespace (TOF_Collections.List<8>)
        pou = generic.get(t.name.upper()) or generic.get(t.name.rsplit(".", 1)[-1].upper())
        if pou is None:
            raise ProgramError(f"'{t.name}' has no VAR_GENERIC CONSTANT for the values in "
                               "angle brackets", *_where(t))
        values = _bind(pou, t)
        key = (pou.name.upper(), tuple(expr_text(v) for v in values))
        name = copies.get(key)
        if name is None:
            name = _fresh(pou.name, taken)
            added.append(_copy_with(pou, name, values))
            added[-1].pragmas.append(GENERIC_PRAGMA + f"{pou.name}<{', '.join(key[1])}>")
            copies[key] = name
        return ir.NamedType(name, pos=t.pos)

    for holder in _type_refs(out):
        holder.type = _walk(holder.type, visit)
    # the block as declared: its generic constants are constants with their initial
    # values (what the vendors check it with), or it exists only through its copies
    kept = []
    for pou in out.pous:
        decls = _generic_block(pou)
        if not decls:
            kept.append(pou)
        elif all(d.init is not None for d in decls):
            kept.append(_copy_with(pou, pou.name, [d.init for d in decls]))
    out.pous = kept + added
    # a block extending a generic one (EXTENDS FB_Base<7>) extends the base's copy for
    # those values; a copy may extend another generic block in turn, but not without end
    # (FB_G EXTENDS FB_G<(N + 1)> would make copies forever)
    done, seen = 0, len(added)
    level: dict[int, int] = {}      # id of a copy made for an EXTENDS -> how many deep
    while done < len(out.pous):
        pou = out.pous[done]
        done += 1
        if pou.extends_args:
            pou.extends = visit(ir.NamedType(pou.extends, pos=pou.pos,
                                             generic_args=pou.extends_args)).name
            pou.extends_args = []
            deeper = level.get(id(pou), 0) + 1
            for new in added[seen:]:
                level[id(new)] = deeper
            if added[seen:] and deeper >= MAX_INHERITANCE_DEPTH:
                shown = next((p[len(GENERIC_PRAGMA):] for p in pou.pragmas
                              if p.startswith(GENERIC_PRAGMA)), pou.name)
                if len(shown) > 60:
                    shown = shown[:60] + "...>"
                raise ProgramError(f"{shown} EXTENDS copies of generic blocks more than "
                                   f"{MAX_INHERITANCE_DEPTH} levels deep (each EXTENDS "
                                   "with other values makes one more)", *_where(pou))
            out.pous += added[seen:]
            seen = len(added)
    return out


def _has_generic_args(t) -> bool:
    found = []
    _walk(t, lambda n: (found.append(bool(n.generic_args)), n)[1])   # visits, changes nothing
    return any(found)


# the pragma a copy carries: the type as the program wrote it, for messages
GENERIC_PRAGMA = "plcpred generic copy of "


def shown_as(program: ir.Program) -> dict[str, str]:
    """Upper-case name of each generic copy -> the type as written (``FB_Buf<100>``)."""
    return {p.name.upper(): prag[len(GENERIC_PRAGMA):] for p in program.pous
            for prag in p.pragmas if prag.startswith(GENERIC_PRAGMA)}


def readable(problems, program: ir.Program):
    """``problems`` (errors or warnings) with generic copies named as the program
    writes them."""
    names = shown_as(program)
    if not names:
        return problems
    pattern = re.compile(r"\b(" + "|".join(re.escape(n) for n in names) + r")\b", re.I)
    for p in problems:
        p.message = pattern.sub(lambda m: names[m.group(1).upper()], p.message)
        p.args = (p.message,)
    return problems


def _where(t) -> tuple:
    pos = t.pos
    return (pos.file, pos.line, pos.col) if pos is not None else ("", 0, 0)


def _bind(pou: ir.Pou, t: ir.NamedType) -> list:
    """The values of ``pou``'s generic constants that ``t``'s angle brackets give."""
    decls = _generic_block(pou)
    values = [d.init for d in decls]
    given = [False] * len(decls)
    index = {d.name.upper(): i for i, d in enumerate(decls)}
    for k, a in enumerate(t.generic_args):
        if a.name is None:
            if k >= len(decls):
                raise ProgramError(f"{pou.name} has {len(decls)} generic constant"
                                   f"{'s' if len(decls) != 1 else ''}, not "
                                   f"{len(t.generic_args)}", *_where(t))
            i = k
        else:
            i = index.get(a.name.upper())
            if i is None:
                raise ProgramError(f"'{a.name}' is no generic constant of {pou.name}",
                                   *_where(t))
        values[i], given[i] = a.value, True
    for d, v in zip(decls, values):
        if v is None:
            raise ProgramError(f"{pou.name}<...> gives no value for its generic constant "
                               f"'{d.name}' (and it has no initial value)", *_where(t))
    return values


def _fresh(name: str, taken: set) -> str:
    k = 1
    while f"{name}__G{k}".upper() in taken:
        k += 1
    taken.add(f"{name}__G{k}".upper())
    return f"{name}__G{k}"


def _copy_with(pou: ir.Pou, name: str, values: list) -> ir.Pou:
    """A copy of generic ``pou`` named ``name`` whose generic constants are CONSTANTs
    with ``values``."""
    new = copy.deepcopy(pou)
    new.name = name
    blocks = []
    k = 0
    for b in new.var_blocks:
        if b.kind != "VAR_GENERIC":
            blocks.append(b)
            continue
        decls = []
        for d in b.decls:
            d.init = copy.deepcopy(values[k])
            k += 1
            decls.append(d)
        blocks.append(ir.VarBlock("VAR", decls, ["CONSTANT"], pos=b.pos))
    new.var_blocks = blocks
    # array bounds and string lengths are worked out before any instance exists: there
    # the constants stand for their values, written in
    by_name = {d.name.upper(): v for d, v in zip(_generic_block(pou), values)}
    for holder in _type_refs(ir.Program(pous=[new])):
        holder.type = _walk(holder.type, bound=lambda e: _substituted(e, by_name))
    for a in new.extends_args:          # EXTENDS FB_Base<N> with this block's own N
        a.value = _substituted(a.value, by_name)
    return new


def _substituted(e, by_name: dict):
    """Expression ``e`` with names in ``by_name`` replaced by (copies of) their values."""
    if isinstance(e, ir.Name) and e.name.upper() in by_name:
        return copy.deepcopy(by_name[e.name.upper()])
    if isinstance(e, ir.Binary):
        return ir.Binary(e.op, _substituted(e.left, by_name), _substituted(e.right, by_name),
                         pos=e.pos)
    if isinstance(e, ir.Unary):
        return ir.Unary(e.op, _substituted(e.operand, by_name), pos=e.pos)
    return e
