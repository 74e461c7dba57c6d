"""What named types make of each other: no type holds itself, inheritance ends, and
nesting stays within limits.

Resolving types, sizing variables, generating their initial values, copying and comparing
them at run time all follow a type into the types it names, recursively. Program files are
untrusted, so the type graph they declare is checked first, iteratively, and every problem
is an error at the declaration that causes it:

* a FUNCTION_BLOCK, STRUCT or INTERFACE that EXTENDS itself, directly or through others;
* an EXTENDS chain deeper than :data:`MAX_INHERITANCE_DEPTH`;
* a type that holds a value of itself: an alias (``TYPE A : B; TYPE B : A;``), a STRUCT
  member, an array element, an FB instance or a base, directly or through other types.
  A POINTER TO or REFERENCE TO it (a linked list) is fine, and so are VAR_IN_OUT and
  VAR_EXTERNAL, which refer to a value held elsewhere;
* a variable or type whose value nests more than :data:`MAX_TYPE_NESTING` levels deep,
  counting each named type, array dimension and STRUCT it holds inside another (a pointer
  ends the count: what it points to is held elsewhere).

Within one declaration, :mod:`.names` bounds the nesting as written
(``ARRAY[0..1] OF ARRAY...``, initial values) before anything reaches this module.
"""
from __future__ import annotations

from . import ir
from .errors import ProgramError, at

# Real programs stay far below these: inheritance is a handful of levels, and values nest
# a few structures deep. The limits keep every recursive stage (and the generated Python,
# where nested arrays are nested list expressions) far from Python's own limits.
MAX_INHERITANCE_DEPTH = 64
MAX_TYPE_NESTING = 64

_OPEN, _DONE = 1, 2
_REFERENCE_BLOCKS = ("VAR_EXTERNAL", "VAR_IN_OUT")


def check_type_graph(programs, builtin, own: ir.Program | None = None) -> None:
    """Raise a :class:`ProgramError` for the first problem (see the module docstring) in
    the types ``programs`` declare together. ``builtin(NAME)`` tells the names the caller
    resolves before any declaration (elementary types, standard FBs); of names declared
    twice, the last declaration counts, as the compiler's type table takes them. With
    ``own``, only problems at a declaration of ``own`` are reported (each file of a project
    reports its own)."""
    _Graph(programs, builtin, own).check()


class _Graph:
    def __init__(self, programs, builtin, own):
        self.builtin = builtin
        self.types: dict[str, ir.TypeDecl] = {}
        self.pous: dict[str, ir.Pou] = {}
        self.itfs: dict[str, ir.Interface] = {}
        for prog in programs:
            for t in prog.types:
                self.types[t.name.upper()] = t
            for p in prog.pous:
                self.pous[p.name.upper()] = p
            for i in prog.interfaces:
                self.itfs[i.name.upper()] = i
        self.own = None
        self.programs = list(programs)
        if own is not None:
            self.own = {id(x) for x in (*own.types, *own.pous, *own.interfaces)}
            self.programs = [own]
        self.nesting: dict[object, int] = {}
        self.via: dict[object, tuple | None] = {}

    # ------------------------------------------------------------------ nodes
    def node(self, name):
        """The declaration a type name stands for (None: built in, or not declared)."""
        if not isinstance(name, str):
            return None
        up = name.upper()
        if self.builtin(up):
            return None
        if up in self.types:
            return self.types[up]
        p = self.pous.get(up)
        if p is not None and p.kind in ("FUNCTION_BLOCK", "PROGRAM"):
            return p
        return self.itfs.get(up)

    def _mine(self, decl) -> bool:
        return self.own is None or id(decl) in self.own

    def _nodes(self):
        return [*self.types.values(), *self.itfs.values(),
                *(p for p in self.pous.values() if p.kind in ("FUNCTION_BLOCK", "PROGRAM"))]

    # ------------------------------------------------------------------ edges
    def bases(self, decl):
        """(base declaration, 0, position) for each type ``decl`` EXTENDS."""
        if isinstance(decl, ir.Pou):
            names = [decl.extends] if decl.extends else []
        elif isinstance(decl, ir.Interface):
            names = decl.extends
        elif isinstance(decl.type, ir.StructType) and decl.type.extends:
            names = [decl.type.extends]
        else:
            names = []
        out = []
        for n in names:
            b = self.node(n)
            if b is not None:
                out.append((b, 1, decl.pos))
        return out

    def held(self, decl):
        """(declaration, levels, position) for each named type a value of ``decl``
        holds, ``levels`` deeper (a base counts 0: its members are the value's own)."""
        if isinstance(decl, ir.Interface):
            return []
        out = [(b, 0, pos) for b, _, pos in self.bases(decl)]
        if isinstance(decl, ir.Pou):
            for block in decl.var_blocks:
                if block.kind not in _REFERENCE_BLOCKS:
                    for d in block.decls:
                        out += self._refs(d.type, 0, d.pos)[0]
            return out
        t = decl.type
        if isinstance(t, ir.StructType):       # the type itself, not a level inside it
            for d in t.members:
                out += self._refs(d.type, 0, d.pos)[0]
        else:
            out += self._refs(t, 0, decl.pos)[0]
        return out

    def named_by_alias(self, decl):
        """(alias, 1, position) for each type alias ``decl``'s type names, through
        pointers too: an alias is resolved by resolving those (a STRUCT, an enumeration or
        an FB is known by its name before its members are resolved)."""
        out, todo = [], [decl.type]
        while todo:
            t = todo.pop()
            if isinstance(t, ir.NamedType):
                target = self.node(t.name)
                if isinstance(target, ir.TypeDecl) and _is_alias(target):
                    out.append((target, 1, t.pos or decl.pos))
            elif isinstance(t, ir.ArrayType):
                todo.append(t.element)
            elif isinstance(t, ir.PointerType):
                todo.append(t.target)
            elif isinstance(t, ir.StructType):
                todo.extend(d.type for d in t.members)
        return out

    def _refs(self, tr, level: int, pos):
        """([(declaration, levels, position)] of the named types type expression ``tr``
        holds, the deepest level it reaches by itself)."""
        refs, deepest = [], level
        todo = [(tr, level)]
        while todo:
            t, lv = todo.pop()
            deepest = max(deepest, lv)
            if isinstance(t, ir.NamedType):
                decl = self.node(t.name)
                if decl is not None and not isinstance(decl, ir.Interface):
                    refs.append((decl, lv + 1, t.pos or pos))
            elif isinstance(t, ir.ArrayType):
                todo.append((t.element, lv + max(1, len(t.dims))))
            elif isinstance(t, ir.StructType):
                if t.extends:
                    b = self.node(t.extends)
                    if b is not None and not isinstance(b, ir.Interface):
                        refs.append((b, lv + 1, t.pos or pos))
                todo.extend((d.type, lv + 1) for d in t.members)
            # POINTER TO / REFERENCE TO: the value is held elsewhere
        return refs, deepest

    # ------------------------------------------------------------------ checks
    def check(self):
        nodes = self._nodes()
        self._longest(nodes, self.bases, MAX_INHERITANCE_DEPTH, self._extends_cycle,
                      self._too_long)
        self.nesting = self._longest(nodes, self.held, MAX_TYPE_NESTING, self._holds_itself,
                                     self._too_deep)
        self._check_variables()
        aliases = [t for t in self.types.values() if _is_alias(t)]
        self._longest(aliases, self.named_by_alias, MAX_TYPE_NESTING, self._holds_itself,
                      self._too_many_aliases)

    def _longest(self, roots, edges, limit, cycle, too_deep) -> dict:
        """The longest path (summing the edges' levels) from each of ``roots`` in the
        graph ``edges`` gives, walked depth first without recursion; ``cycle(edges)`` and
        ``too_deep(node, depth, via)`` make the errors."""
        state: dict[int, int] = {}
        depth: dict[int, int] = {}
        via: dict[int, tuple | None] = {}
        for root in roots:
            if id(root) in state:
                continue
            state[id(root)] = _OPEN
            # frames: [declaration, its edges left, deepest so far, through what, the
            # edge (levels, position) that led here]
            stack = [[root, iter(edges(root)), 0, None, None]]
            while stack:
                frame = stack[-1]
                for target, levels, pos in frame[1]:
                    s = state.get(id(target))
                    if s == _OPEN:
                        start = next(k for k, f in enumerate(stack) if f[0] is target)
                        ring = [(f[0], g[4][1]) for f, g in zip(stack[start:],
                                                                 stack[start + 1:])]
                        ring.append((frame[0], pos))
                        error = cycle(ring)
                        if error is not None:
                            raise error
                        continue                   # another file's: it reports it
                    if s is None:
                        state[id(target)] = _OPEN
                        stack.append([target, iter(edges(target)), 0, None, (levels, pos)])
                        break
                    if levels + depth[id(target)] >= frame[2]:
                        frame[2], frame[3] = levels + depth[id(target)], (target, pos)
                else:
                    stack.pop()
                    node = frame[0]
                    state[id(node)] = _DONE
                    depth[id(node)], via[id(node)] = frame[2], frame[3]
                    if frame[2] > limit and self._mine(node):
                        raise too_deep(node, frame[2], via)
                    if stack:
                        parent, (levels, _) = stack[-1], frame[4]
                        if levels + frame[2] >= parent[2]:
                            parent[2], parent[3] = levels + frame[2], (node, frame[4][1])
        self.via = via
        return depth

    def _path(self, node, via, first=None) -> str:
        names = [first] if first is not None else []
        seen = set()
        while node is not None and id(node) not in seen:
            seen.add(id(node))
            names.append(node.name)
            step = via.get(id(node))
            node = step[0] if step else None
        if len(names) > 8:
            names = names[:4] + ["..."] + names[-3:]
        return " > ".join(names)

    @staticmethod
    def _ring_text(ring, k) -> str:
        names = [d.name for d, _ in ring[k:] + ring[:k]] + [ring[k][0].name]
        if len(names) > 8:
            names = names[:4] + ["..."] + names[-3:]
        return " > ".join(names)

    def _pick(self, ring):
        """The edge of a cycle to report: the first one leaving a declaration of ours."""
        return next((k for k, (d, _) in enumerate(ring) if self._mine(d)), None)

    def _extends_cycle(self, ring):
        k = self._pick(ring)
        if k is None:
            return None
        decl, pos = ring[k]
        if len(ring) == 1:
            return at(pos, f"{decl.name} EXTENDS itself")
        return at(pos, f"{decl.name} EXTENDS itself, through others: "
                       f"{self._ring_text(ring, k)}")

    def _holds_itself(self, ring):
        k = self._pick(ring)
        if k is None:
            return None
        decl, pos = ring[k]
        through = self._ring_text(ring, k)
        if isinstance(decl, ir.Pou):
            return at(pos, f"{decl.name} holds an instance of itself ({through}), which "
                           "never ends; a POINTER TO or REFERENCE TO it would not")
        if isinstance(decl.type, ir.StructType):
            return at(pos, f"STRUCT {decl.name} holds a value of itself ({through}), which "
                           "never ends; a POINTER TO or REFERENCE TO it would not")
        return at(pos, f"type {decl.name} is defined in terms of itself ({through})")

    def _too_long(self, decl, depth, via) -> ProgramError:
        return at(decl.pos, f"{decl.name} inherits through {depth} levels of EXTENDS "
                            f"({self._path(decl, via)}); at most {MAX_INHERITANCE_DEPTH} "
                            "are supported")

    def _too_deep(self, decl, depth, via) -> ProgramError:
        return at(decl.pos, f"{decl.name} nests types {depth} levels deep "
                            f"({self._path(decl, via)}): more than {MAX_TYPE_NESTING} "
                            "(each named type, array dimension and STRUCT inside another "
                            "counts)")

    def _too_many_aliases(self, decl, depth, via) -> ProgramError:
        return at(decl.pos, f"type {decl.name} is defined through {depth} other types in a "
                            f"row ({self._path(decl, via)}): more than {MAX_TYPE_NESTING}")

    def _check_variables(self):
        """Each variable's own type expression with the nesting of what it names."""
        for decl, pos, name in self._variables():
            refs, deepest = self._refs(decl.type if isinstance(decl, ir.VarDecl) else decl,
                                       0, pos)
            total, through = deepest, None
            for target, levels, p in refs:
                if levels + self.nesting.get(id(target), 0) > total:
                    total, through = levels + self.nesting.get(id(target), 0), target
            if total > MAX_TYPE_NESTING:
                path = self._path(through, self.via, first=name) if through is not None \
                    else name
                raise at(pos, f"{name} nests types {total} levels deep ({path}): more "
                              f"than {MAX_TYPE_NESTING} (each named type, array dimension "
                              "and STRUCT inside another counts)")

    def _variables(self):
        """(declaration or type expression, position, name) of every variable, return
        type and property of the POUs, GVLs and configurations (ours, with ``own``)."""
        seen = set()
        for prog in self.programs:
            if id(prog) in seen:
                continue
            seen.add(id(prog))
            blocks = [g.block for g in prog.globals if g.block is not None]
            for c in prog.configurations:
                blocks += c.var_blocks
                for r in c.resources:
                    blocks += r.var_blocks
            for p in prog.pous:
                blocks += p.var_blocks
                if p.return_type is not None:
                    yield p.return_type, p.pos, p.name
                for m in p.methods:
                    blocks += m.var_blocks
                    if m.return_type is not None:
                        yield m.return_type, m.pos, m.name
                for prop in p.properties:
                    yield prop.type, prop.pos, prop.name
                    for acc in prop.accessors:
                        blocks += acc.var_blocks
            for b in blocks:
                for d in b.decls:
                    yield d, d.pos, d.name


def _is_alias(decl: ir.TypeDecl) -> bool:
    """A TYPE that stands for another type expression (not a STRUCT or enumeration of
    its own)."""
    return not isinstance(decl.type, (ir.StructType, ir.EnumType))
