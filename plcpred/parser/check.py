"""Semantic checks on the IR: the errors a PLC compiler would stop on, and warnings for
code that is probably wrong.

Errors: undeclared names, unknown types and FB types, unknown FB members and call
parameters, assignments to inputs (a POU's own VAR_INPUT, ``%I`` located variables, an FB
instance's outputs) or constants, duplicate declarations.
Warnings: local variables never used, outputs never written.

``check_program(program, context=[...])`` resolves names against the program itself plus
any other programs given as context (a GVL file checked together with the POUs using it).
"""
from __future__ import annotations

from dataclasses import dataclass, field

from . import ir
from .build import anonymous_at_name
from .errors import ProgramError, ProgramWarning, at
from .generics import readable, specialize
from .libraries import referenced_names
from .literals import INT_TYPES
from .notes import missing_project_files, referenced_libraries, unread_library_files
from .shipped import BUILTIN_NAMESPACES, shipped_namespaces
from .st import unclosed_pous
from .stdlib import ELEMENTARY_TYPES, STANDARD_FBS, is_standard_function, std_fb_pins
from .typegraph import MAX_INHERITANCE_DEPTH, check_type_graph

_LOCAL_KINDS = ("VAR", "VAR_TEMP", "VAR_STAT", "VAR_INST")

# writing a located input: CODESYS, TwinCAT and Beremiz (matiec) compile it; the value
# holds until the next scan writes the input image again
_INPUT_WRITE = (" (accepted as CODESYS, TwinCAT and Beremiz do: the next scan's input "
                "image overwrites it; IEC 61131-3 forbids it)")


@dataclass
class _Var:
    decl: ir.VarDecl
    kind: str
    constant: bool
    owner: str  # POU name or "<global>"


@dataclass
class _Usage:
    read: set = field(default_factory=set)
    written: set = field(default_factory=set)


class _Globals:
    """Everything visible from every POU."""

    def __init__(self, programs: list[ir.Program]):
        self.programs = programs
        self.vars: dict[str, _Var] = {}
        self.pous: dict[str, ir.Pou] = {}
        self.types: dict[str, ir.TypeDecl] = {}
        self.interfaces: dict[str, ir.Interface] = {}
        self.enum_values: dict[str, str] = {}  # value -> enum type
        self.gvls: dict[str, set[str]] = {}  # GVL name -> its variables (for GVL.var)
        for prog in programs:
            for g in prog.globals:
                self._add_block(g.block)
                if g.name:
                    self.gvls.setdefault(g.name.upper(), set()).update(
                        d.name.upper() for d in g.block.decls)
            for c in prog.configurations:
                for b in c.var_blocks:
                    self._add_block(b)
                for r in c.resources:
                    for b in r.var_blocks:
                        self._add_block(b)
            for p in prog.pous:
                self.pous.setdefault(p.name.upper(), p)
                # an anonymous enumeration in a declaration (``s : (IDLE, RUN);``)
                for block in [*p.var_blocks, *(b for m in p.methods for b in m.var_blocks)]:
                    for d in block.decls:
                        if isinstance(d.type, ir.EnumType):
                            for value, _ in d.type.values:
                                self.enum_values.setdefault(value.upper(), d.name)
            for t in prog.types:
                self.types.setdefault(t.name.upper(), t)
                if isinstance(t.type, ir.EnumType):
                    for value, _ in t.type.values:
                        self.enum_values.setdefault(value.upper(), t.name)
            for itf in prog.interfaces:
                self.interfaces.setdefault(itf.name.upper(), itf)

    def _add_block(self, block: ir.VarBlock):
        for d in block.decls:
            self.vars.setdefault(d.name.upper(),
                                 _Var(d, block.kind, "CONSTANT" in block.qualifiers, "<global>"))

    def fb_members(self, type_name: str):
        """(inputs, outputs, others) of an FB type, or None if it is not an FB."""
        up = type_name.upper()
        if up in STANDARD_FBS:
            ins, outs = std_fb_pins(up)
            return ins, outs, set()
        pou = self.pous.get(up)
        if pou is None or pou.kind != "FUNCTION_BLOCK":
            return None
        ins, outs = set(), set()
        for p in self.fb_chain(pou):
            for b in p.var_blocks:
                names = {d.name.upper() for d in b.decls}
                if b.kind in ("VAR_INPUT", "VAR_IN_OUT"):
                    ins |= names
                elif b.kind == "VAR_OUTPUT":
                    outs |= names
        return ins, outs, self.callables(pou)

    def callables(self, pou: ir.Pou) -> set[str]:
        """Methods, properties and actions of a POU and those it inherits."""
        out = set()
        for p in self.fb_chain(pou):
            out |= {m.name.upper() for m in p.methods}
            out |= {pr.name.upper() for pr in p.properties}
            out |= {a.name.upper() for a in p.actions}
        return out

    def fb_internals(self, type_name: str) -> set[str]:
        """The VAR (and VAR_STAT, VAR_INST) variables of a user FB type and its bases."""
        pou = self.pous.get(type_name.upper())
        if pou is None or pou.kind != "FUNCTION_BLOCK":
            return set()
        return {d.name.upper() for p in self.fb_chain(pou) for b in p.var_blocks
                if b.kind in ("VAR", "VAR_STAT", "VAR_INST") for d in b.decls}

    def fb_chain(self, pou: ir.Pou) -> list[ir.Pou]:
        """The POU, its base, its base's base ... (stopping at an unknown base, a cycle or
        past MAX_INHERITANCE_DEPTH: the type graph reports those, and a chain of thousands
        followed for every POU would take minutes)."""
        chain, seen = [], set()
        while pou is not None and pou.name.upper() not in seen \
                and len(chain) <= MAX_INHERITANCE_DEPTH:
            seen.add(pou.name.upper())
            chain.append(pou)
            pou = self.pous.get(pou.extends.upper()) if pou.extends else None
        return chain

    def struct_members(self, type_name: str):
        t = self.types.get(type_name.upper())
        seen = set()
        members = set()
        while t is not None and isinstance(t.type, ir.StructType) \
                and t.name.upper() not in seen and len(seen) <= MAX_INHERITANCE_DEPTH:
            seen.add(t.name.upper())
            members |= {d.name.upper() for d in t.type.members}
            t = self.types.get(t.type.extends.upper()) if t.type.extends else None
        return members if seen else None


class Checker:
    def __init__(self, program: ir.Program, context: list[ir.Program] = (),
                 allow_external: bool = False):
        self.program = program
        self.allow_external = allow_external
        self._missing_libs = None  # see _libraries_not_at_hand
        self.g = _Globals([program, *[c for c in context if c is not program]])
        self.errors: list[ProgramError] = []
        self.warnings: list[ProgramWarning] = []
        self.program_usage = _Usage()  # reads and writes over all POUs of the program

    # ------------------------------------------------------------------ reporting
    def error(self, pos, message):
        self.errors.append(at(pos, message))

    def warn(self, pos, message):
        self.warnings.append(at(pos, message, ProgramWarning))

    def missing(self, pos, message):
        """A name nothing at hand declares: an error, or with ``allow_external`` a warning
        (it may come from a library the check was not given)."""
        if self.allow_external:
            self.warnings.append(at(pos, f"{message}: taken as external (declared in a "
                                         "library not at hand)", ExternalWarning))
            return
        missing = self._libraries_not_at_hand()
        if missing:
            message += (f" (the project uses libraries plcpred does not have: "
                        f"{', '.join(missing)}; give their declarations with --lib, or check "
                        "with --allow-external)")
        absent = [f"{p.file}:{p.line}:{p.col}: {include}"
                  for include, p in missing_project_files(self.g.programs)]
        for found, why in ((absent, "the .plcproj lists a file that is not there, which "
                                    "may declare it"),
                           (unread_library_files(self.g.programs),
                            "a library file plcpred could not read may declare it")):
            if found:
                more = f" and {len(found) - 1} more" if len(found) > 1 else ""
                message += f" ({why}: {found[0]}{more})"
        self.error(pos, message)

    def _libraries_not_at_hand(self) -> list[str]:
        """Libraries the project's .plcproj references that are neither shipped as stubs
        nor given (their namespaces)."""
        if self._missing_libs is None:
            known = BUILTIN_NAMESPACES | {ns.upper() for ns in shipped_namespaces()}
            self._missing_libs = sorted({r for r in referenced_libraries(self.g.programs)
                                         if r.upper() not in known})
        return self._missing_libs

    # ------------------------------------------------------------------ entry
    def run(self):
        for include, pos in missing_project_files([self.program]):
            self.warn(pos, f"the .plcproj lists {include}, which is not there: the project "
                           "is read without it")
        for kind, pos in unclosed_pous(self.program):
            self.warn(pos, f"the {kind} has no END_{kind}: read to the end of the file "
                           "(as CODESYS's editor shows a POU)")
        self._check_duplicates()
        for t in self.program.types:
            self._check_type(t.type, {})
        for g in self.program.globals:
            for d in g.block.decls:
                self._check_type(d.type, {})
        for p in self.program.pous:
            self._check_pou(p)
        for c in self.program.configurations:
            for r in c.resources:
                for pi in r.programs:
                    pou = self.g.pous.get(pi.type_name.upper())
                    if pou is None or pou.kind != "PROGRAM":
                        self.error(pi.pos, f"unknown PROGRAM type '{pi.type_name}'")
                    task_names = {t.name.upper() for t in r.tasks}
                    if pi.task and pi.task.upper() not in task_names:
                        self.error(pi.pos, f"unknown task '{pi.task}'")
        self._check_global_outputs()
        return self

    # ------------------------------------------------------------------ duplicates
    def _dups(self, items, what):
        seen = {}
        for name, pos in items:
            key = name.upper()
            if key in seen:
                first = seen[key]
                where = f" (first declared at line {first.line})" if first is not None else ""
                self.error(pos, f"duplicate {what} '{name}'{where}")
            else:
                seen[key] = pos

    def _check_duplicates(self):
        p = self.program
        self._dups([(x.name, x.pos) for x in p.pous] + [(t.name, t.pos) for t in p.types]
                   + [(i.name, i.pos) for i in p.interfaces], "declaration of")
        self._dups([(d.name, d.pos) for g in p.globals for d in g.block.decls],
                   "global variable")
        for t in p.types:
            if isinstance(t.type, ir.EnumType):
                self._dups([(n, t.pos) for n, _ in t.type.values], f"value in enum {t.name}:")
            if isinstance(t.type, ir.StructType):
                self._dups([(d.name, d.pos) for d in t.type.members], "struct member")

    # ------------------------------------------------------------------ types
    def _check_type(self, t, scope):
        if isinstance(t, ir.NamedType):
            up = t.name.upper()
            if not (up in ELEMENTARY_TYPES or up in self.g.types or up in STANDARD_FBS
                    or up in self.g.interfaces
                    or (up in self.g.pous and self.g.pous[up].kind == "FUNCTION_BLOCK")):
                self.missing(t.pos, f"unknown type '{t.name}' (not an elementary type, a TYPE, "
                                  "or a function block)")
        elif isinstance(t, ir.ArrayType):
            for lo, hi in t.dims:
                if lo is not None:
                    self._expr(lo, scope, None)
                    self._expr(hi, scope, None)
            self._check_type(t.element, scope)
        elif isinstance(t, ir.PointerType):
            self._check_type(t.target, scope)
        elif isinstance(t, ir.StructType):
            for d in t.members:
                self._check_type(d.type, scope)
        elif isinstance(t, ir.StringType) and t.length is not None:
            self._expr(t.length, scope, None)

    # ------------------------------------------------------------------ POUs
    def _pou_vars(self, pou: ir.Pou) -> dict[str, _Var]:
        scope: dict[str, _Var] = {}
        for p in reversed(self.g.fb_chain(pou)):
            for b in p.var_blocks:
                for d in b.decls:
                    scope[d.name.upper()] = _Var(d, b.kind, "CONSTANT" in b.qualifiers, p.name)
        return scope

    def _check_pou(self, pou: ir.Pou):
        self._dups([(d.name, d.pos) for d in pou.decls()], "declaration of")
        if pou.extends and pou.extends.upper() not in self.g.pous:
            self.missing(pou.pos, f"unknown FB type '{pou.extends}' in EXTENDS")
        for name in pou.implements:
            if name.upper() not in self.g.interfaces:
                self.missing(pou.pos, f"unknown interface '{name}' in IMPLEMENTS")
        scope = self._pou_vars(pou)
        for d in pou.decls():
            self._check_type(d.type, scope)
            if d.init is not None:
                self._init(d.init, scope)
            given = list(d.init_args or []) + [a for args in d.element_init_args or []
                                               for a in args]
            if given:
                for a in given:
                    self._expr(a.value, scope, None)
                if not self._has_fb_init(d.type):
                    self.warn(d.pos, f"FB_init arguments of '{d.name}' are not applied: "
                                     "its type has no FB_init method")
        extra = self.g.callables(pou)   # by bare name, inherited ones too
        if pou.kind == "FUNCTION":
            extra.add(pou.name.upper())
        if pou.kind == "FUNCTION_BLOCK":
            extra |= {"THIS", "SUPER"}
        usage = _Usage()
        ctx = _Ctx(pou, scope, extra, usage)
        if isinstance(pou.body, ir.Sfc):
            self._check_sfc(pou.body, ctx)
        else:
            self._stmts(pou.body, ctx)
            self._check_labels(pou.body)
        for a in pou.actions:
            self._stmts(a.body, ctx)
        for m in pou.methods:
            self._check_method(m, pou, scope, extra, usage)
        for prop in pou.properties:
            for acc in prop.accessors:
                self._check_method(ir.Method(prop.name, prop.type, acc.var_blocks, acc.body),
                                   pou, scope, extra, usage, own_name=prop.name)
        # warnings
        own = {d.name.upper(): (d, b.kind) for b in pou.var_blocks for d in b.decls}
        # a constant read in a declaration (an array bound, a string length, an
        # initial value) is used
        usage.read |= {n for kind, n in referenced_names(
            [(d.type, d.init) for d, _ in own.values()]) if kind == "V"}
        # a function block or function with no code at all is a declaration (a B&R .fun,
        # a library's interface): what it leaves unwritten is not a finding
        declaration_only = pou.kind != "PROGRAM" and not pou.body and not pou.methods \
            and not pou.actions and not pou.properties
        for key, (d, kind) in own.items():
            if declaration_only:
                break
            if d.address and key == anonymous_at_name(d.address):
                continue        # ``AT %IX1.1 : BOOL;`` types an address code reads as such
            is_output = kind == "VAR_OUTPUT" or (d.address or "").startswith("%Q")
            if is_output and key not in usage.written:
                self.warn(d.pos, f"output '{d.name}' is never written")
            elif kind in _LOCAL_KINDS and key not in usage.read and key not in usage.written:
                self.warn(d.pos, f"variable '{d.name}' is declared but never used")
        self.program_usage.read |= usage.read
        self.program_usage.written |= usage.written

    def _check_method(self, m: ir.Method, pou, fb_scope, fb_extra, usage, own_name=None):
        self._dups([(d.name, d.pos) for b in m.var_blocks for d in b.decls], "declaration of")
        scope = dict(fb_scope)
        for b in m.var_blocks:
            for d in b.decls:
                scope[d.name.upper()] = _Var(d, b.kind, "CONSTANT" in b.qualifiers, m.name)
        # a bound may name a constant of a later block (TwinCAT and CODESYS accept it)
        for d in (d for b in m.var_blocks for d in b.decls):
            self._check_type(d.type, scope)
        if m.return_type is not None:
            self._check_type(m.return_type, scope)
        extra = set(fb_extra) | {(own_name or m.name).upper()}
        local_usage = _Usage()
        self._stmts(m.body, _Ctx(pou, scope, extra, local_usage, method=m))
        usage.read |= local_usage.read
        usage.written |= local_usage.written

    def _check_global_outputs(self):
        """A located %Q global is an output of the whole program: warn if no POU here writes
        it (a GVL checked on its own has no POUs and gets no such warnings)."""
        if not self.program.pous:
            return
        written = self.program_usage.written
        for g in self.program.globals:
            for d in g.block.decls:
                if (d.address or "").startswith("%Q") and d.name.upper() not in written:
                    self.warn(d.pos, f"output '{d.name}' is never written")

    def _check_sfc(self, sfc: ir.Sfc, ctx: "_Ctx"):
        self._dups([(s.name, s.pos) for s in sfc.steps], "step")
        self._dups([(a.name, a.pos) for a in sfc.actions], "action")
        steps = {s.name.upper() for s in sfc.steps}
        actions = {a.name.upper() for a in sfc.actions}
        ctx.extra |= steps | actions
        for s in sfc.steps:
            for a in s.actions:
                key = a.action.upper()
                if key in actions:
                    continue
                var = ctx.scope.get(key) or self.g.vars.get(key)
                if var is None:
                    self.error(a.pos, f"step {s.name}: unknown action or variable '{a.action}'")
                else:
                    self._write_target(ir.Name(a.action, pos=a.pos), ctx)
                if a.time is not None:
                    self._expr(a.time, ctx.scope, ctx)
        for t in sfc.transitions:
            for n in t.sources + t.targets:
                if n.upper() not in steps:
                    self.error(t.pos, f"transition refers to unknown step '{n}'")
            self._expr(t.condition, ctx.scope, ctx)
        for a in sfc.actions:
            self._stmts(a.body, ctx)

    def _check_labels(self, stmts):
        labels = set()
        jumps = []

        def walk(body):
            for s in body:
                if isinstance(s, ir.Label):
                    labels.add(s.name.upper())
                elif isinstance(s, ir.Jmp):
                    jumps.append(s)
                for sub in _sub_bodies(s):
                    walk(sub)

        walk(stmts)
        for j in jumps:
            if j.label.upper() not in labels:
                self.error(j.pos, f"JMP to undefined label '{j.label}'")

    # ------------------------------------------------------------------ statements
    def _stmts(self, stmts, ctx):
        for s in stmts:
            t = type(s)
            if t is ir.Assign:
                self._expr(s.value, ctx.scope, ctx)
                self._write_target(s.target, ctx)
            elif t is ir.CallStmt:
                self._expr(s.call, ctx.scope, ctx)
            elif t is ir.If:
                for cond, body in s.branches:
                    self._expr(cond, ctx.scope, ctx)
                    self._stmts(body, ctx)
                if s.else_body:
                    self._stmts(s.else_body, ctx)
            elif t is ir.Case:
                self._expr(s.selector, ctx.scope, ctx)
                for br in s.branches:
                    for lab in br.labels:
                        if isinstance(lab, ir.CaseRange):
                            self._expr(lab.low, ctx.scope, ctx)
                            self._expr(lab.high, ctx.scope, ctx)
                        else:
                            self._expr(lab, ctx.scope, ctx)
                    self._stmts(br.body, ctx)
                if s.else_body:
                    self._stmts(s.else_body, ctx)
            elif t is ir.For:
                self._write_target(s.target or ir.Name(s.var, pos=s.pos), ctx)
                for e in (s.start, s.end, s.step):
                    if e is not None:
                        self._expr(e, ctx.scope, ctx)
                self._stmts(s.body, ctx)
            elif t is ir.While:
                self._expr(s.cond, ctx.scope, ctx)
                self._stmts(s.body, ctx)
            elif t is ir.Repeat:
                self._stmts(s.body, ctx)
                self._expr(s.cond, ctx.scope, ctx)
            elif t is ir.Try:
                self._stmts(s.body, ctx)
                if s.catch_var is not None:
                    self._write_target(s.catch_var, ctx)
                for body in (s.catch_body, s.finally_body):
                    if body:
                        self._stmts(body, ctx)
            elif t is ir.Opaque:
                self.warn(s.pos, f"{s.what} is not read: the program checks, but running "
                                 "it stops with an error")

    def _write_target(self, target, ctx):
        """Check an assignment target and record the write."""
        self._expr(target, ctx.scope, ctx, writing=True)
        target = self._gvl_qualified(target, ctx.scope) or target
        base = target
        while isinstance(base, (ir.Member, ir.Index, ir.BitAccess, ir.Deref)):
            base = self._gvl_qualified(base.base, ctx.scope) or base.base
        if isinstance(base, ir.DirectAddress):
            if base.address.startswith("%I"):
                self.warn(base.pos, f"assignment to input {base.address}{_INPUT_WRITE}")
            return
        if not isinstance(base, ir.Name):
            return
        key = base.name.upper()
        ctx.usage.written.add(key)
        var = ctx.scope.get(key) or self.g.vars.get(key)
        if var is None:
            return
        if target is base:
            if var.constant:
                self.error(target.pos, f"cannot assign to constant '{base.name}'")
            elif var.kind == "VAR_INPUT" and (ctx.method is None
                                              or var.owner == ctx.method.name):
                # IEC forbids it; CODESYS, TwinCAT and Beremiz accept it, and real code does it
                self.warn(target.pos, f"assignment to input '{base.name}' (accepted as "
                                      "CODESYS and TwinCAT do; IEC 61131-3 forbids it)")
            elif (var.decl.address or "").startswith("%I"):
                self.warn(target.pos, f"assignment to input '{base.name}' located at "
                                      f"{var.decl.address}{_INPUT_WRITE}")
        elif isinstance(target, ir.Member) and target.base is base:
            type_name = _type_name(var.decl.type)
            members = self.g.fb_members(type_name) if type_name else None
            if members and target.member.upper() in members[1]:
                self.error(target.pos, f"cannot assign to output '{target.member}' of "
                                       f"{type_name} instance '{base.name}'")

    # ------------------------------------------------------------------ expressions
    def _init(self, init, scope):
        if isinstance(init, ir.ArrayInit):
            for _, v in init.items:
                if v is not None:
                    self._init(v, scope)
        elif isinstance(init, ir.StructInit):
            for _, v in init.fields:
                self._init(v, scope)
        else:
            self._expr(init, scope, None)

    def _resolve(self, name: str, scope, ctx) -> bool:
        key = name.upper()
        if key in scope or key in self.g.vars or key in self.g.pous or key in self.g.types:
            return True
        if ctx is not None and key in ctx.extra:
            return True
        if key in self.g.enum_values or key in self.g.interfaces or key in self.g.gvls:
            return True
        if key in STANDARD_FBS or key in ELEMENTARY_TYPES or is_standard_function(key):
            return True
        if key == "NULL":  # CODESYS/TwinCAT: the null pointer
            return True
        return False

    def _expr(self, e, scope, ctx, writing=False):
        t = type(e)
        if t is ir.Name:
            if not self._resolve(e.name, scope, ctx):
                self.error(e.pos, f"undeclared name '{e.name}'")
            elif ctx is not None and not writing:
                ctx.usage.read.add(e.name.upper())
        elif t is ir.Member:
            if self.allow_external and type(e.base) is ir.Name \
                    and not self._resolve(e.base.name, scope, ctx):
                # Lib.X or GVL.X of a library not at hand
                self.missing(e.base.pos, f"undeclared name '{e.base.name}'")
                return
            self._expr(e.base, scope, ctx, writing)
            self._check_member(e, scope, ctx)
            if ctx is not None and not writing and self._gvl_qualified(e, scope):
                ctx.usage.read.add(e.member.upper())
        elif t is ir.BitAccess:
            self._expr(e.base, scope, ctx, writing)
            self._check_bit(e, scope)
        elif t is ir.Deref:
            self._expr(e.base, scope, ctx, writing)
        elif t is ir.Index:
            self._expr(e.base, scope, ctx, writing)
            for i in e.indices:
                self._expr(i, scope, ctx)
        elif t is ir.Unary:
            self._expr(e.operand, scope, ctx)
        elif t is ir.Binary:
            self._expr(e.left, scope, ctx)
            self._expr(e.right, scope, ctx)
        elif t is ir.Call:
            self._check_call(e, scope, ctx)
        elif t is ir.TypeExpr:
            self._check_type(e.type, scope)
        elif t is ir.AssignExpr:
            self._expr(e.value, scope, ctx)
            if ctx is not None:
                self._write_target(e.target, ctx)
            else:
                self._expr(e.target, scope, ctx, writing=True)
        elif t is ir.EnumLiteral:
            td = self.g.types.get(e.type_name.upper())
            if td is None or not isinstance(td.type, ir.EnumType):
                self.error(e.pos, f"unknown enumeration type '{e.type_name}'")
            elif e.value.upper() not in {v.upper() for v, _ in td.type.values}:
                self.error(e.pos, f"enumeration {e.type_name} has no value '{e.value}'")

    def _check_bit(self, e: ir.BitAccess, scope):
        """``v.n`` of a variable declared BOOL or an integer: n within its width (the
        compiler checks every other base, whose type takes resolving)."""
        if type(e.base) is not ir.Name:
            return
        var = scope.get(e.base.name.upper()) or self.g.vars.get(e.base.name.upper())
        if var is None or not isinstance(var.decl.type, ir.NamedType):
            return
        name = var.decl.type.name.upper()
        if name in ("BOOL", "BIT"):
            self.error(e.pos, f"bit access .{e.bit} on a BOOL, which has no bits to take")
        elif name in INT_TYPES and e.bit >= INT_TYPES[name]:
            self.error(e.pos, f"bit {e.bit} of a {name}: a {name} has bits "
                              f"0..{INT_TYPES[name] - 1}")
        elif name in _BITLESS:
            self.error(e.pos, f"bit access .{e.bit} on a value of type {name}: only "
                              "integers and bit strings (BYTE, WORD, DWORD, LWORD) have bits")

    def _gvl_qualified(self, e, scope):
        """``GVL.var`` as the Name ``var`` it stands for, else None."""
        if (isinstance(e, ir.Member) and isinstance(e.base, ir.Name)
                and e.base.name.upper() in self.g.gvls and e.base.name.upper() not in scope
                and e.member.upper() in self.g.gvls[e.base.name.upper()]):
            return ir.Name(e.member, pos=e.pos)
        return None

    def _check_member(self, e: ir.Member, scope, ctx):
        if not isinstance(e.base, ir.Name):
            return
        key = e.base.name.upper()
        var = scope.get(key) or self.g.vars.get(key)
        if var is None and key in self.g.gvls:
            if e.member.upper() not in self.g.gvls[key]:
                self.error(e.pos, f"global variable list {e.base.name} has no '{e.member}'")
            return
        if var is None:
            td = self.g.types.get(key)
            if td is not None and isinstance(td.type, ir.EnumType):
                if e.member.upper() not in {v.upper() for v, _ in td.type.values}:
                    self.error(e.pos, f"enumeration {td.name} has no value '{e.member}'")
            return
        type_name = _type_name(var.decl.type)
        if type_name is None:
            return
        members = self.g.fb_members(type_name)
        if members is not None:
            if e.member.upper() in self.g.fb_internals(type_name):
                self.warn(e.pos, f"'{e.base.name}.{e.member}' uses an internal variable of "
                                 f"{type_name} (CODESYS and TwinCAT allow it; IEC does not)")
            elif e.member.upper() not in set().union(*members):
                self.error(e.pos, f"'{e.base.name}' ({type_name}) has no input, output, method "
                                  f"or property '{e.member}'")
            return
        fields = self.g.struct_members(type_name)
        if fields is not None and e.member.upper() not in fields:
            self.error(e.pos, f"'{e.base.name}' ({type_name}) has no member '{e.member}'")

    def _is_known_non_fb(self, t) -> bool:
        """True when a call on a variable of type ``t`` is certainly wrong (an unknown type
        is reported once where it is declared, not again at every call)."""
        if isinstance(t, ir.NamedType):
            up = t.name.upper()
            return up in ELEMENTARY_TYPES or up in self.g.types
        return not isinstance(t, ir.PointerType)

    def _has_fb_init(self, t) -> bool:
        """Does type ``t`` (an FB, or an array of them) have an FB_init method, its own or
        a base's?"""
        while isinstance(t, ir.ArrayType):
            t = t.element
        pou = self.g.pous.get(t.name.upper()) if isinstance(t, ir.NamedType) else None
        return pou is not None and any(m.name.upper() == "FB_INIT"
                                       for p in self.g.fb_chain(pou) for m in p.methods)

    def _check_call(self, call: ir.Call, scope, ctx):
        func = call.func
        params = None
        first = call.args[0].value if call.args else None
        if isinstance(func, ir.Name) and func.name.upper() == "__NEW" and len(call.args) > 1:
            self.warn(call.pos, "__NEW with a count (an array reached through pointer "
                                "arithmetic) is not run by plcpred: the program checks, but "
                                "running it stops with an error")
        if isinstance(func, ir.Name) and func.name.upper() == "__NEW" \
                and isinstance(first, ir.Call) and isinstance(first.func, ir.Name):
            # __NEW(FB_T(a := 1)): a type with its FB_init arguments, not a call
            if first.func.name.upper() not in self.g.pous:
                self.missing(first.pos, f"unknown type '{first.func.name}'")
            for a in first.args + call.args[1:]:
                if a.value is not None:
                    self._expr(a.value, scope, ctx)
            return
        if isinstance(func, ir.Name):
            key = func.name.upper()
            var = scope.get(key) or self.g.vars.get(key)
            if var is not None:
                type_name = _type_name(var.decl.type)
                members = self.g.fb_members(type_name) if type_name else None
                if members is None and self._is_known_non_fb(var.decl.type):
                    self.error(func.pos, f"'{func.name}' is not a function block instance and "
                                         "cannot be called")
                elif members is not None:
                    params = (members[0], members[1], type_name)
                if ctx is not None:
                    ctx.usage.read.add(key)
            elif key in self.g.pous:
                pou = self.g.pous[key]
                # a PROGRAM is its one instance: other POUs call it by name (CODESYS,
                # TwinCAT: MAIN calls its sub-programs)
                if pou.kind not in ("FUNCTION", "PROGRAM"):
                    self.error(func.pos, f"'{func.name}' is a {pou.kind.replace('_', ' ')}: call "
                                         "an instance of it, not the type")
                ins = {d.name.upper() for d in pou.decls("VAR_INPUT", "VAR_IN_OUT")}
                outs = {d.name.upper() for d in pou.decls("VAR_OUTPUT")}
                params = (ins, outs, pou.name)
            elif not (is_standard_function(key) or (ctx is not None and key in ctx.extra)):
                self.missing(func.pos, f"unknown function or function block instance "
                                     f"'{func.name}'")
        else:
            self._expr(func, scope, ctx)
        for a in call.args:
            if params is not None and a.name is not None:
                ins, outs, type_name = params
                wanted = outs if a.output else ins
                implicit = "ENO" if a.output else "EN"  # IEC: every call has EN and ENO
                if a.name.upper() not in wanted and a.name.upper() != implicit:
                    kind = "output" if a.output else "input"
                    self.error(a.pos, f"{type_name} has no {kind} '{a.name}'")
            if a.output:
                if ctx is not None:
                    if a.value is not None:   # an empty binding, Q => ,
                        self._write_target(a.value, ctx)
                continue
            self._expr(a.value, scope, ctx)
            # a variable handed to a user POU may be written through VAR_IN_OUT
            if ctx is not None and isinstance(a.value, ir.Name) and not (
                    isinstance(func, ir.Name) and is_standard_function(func.name)):
                ctx.usage.written.add(a.value.name.upper())


@dataclass
class _Ctx:
    pou: ir.Pou
    scope: dict
    extra: set
    usage: _Usage
    method: ir.Method | None = None


def _type_name(t):
    return t.name if isinstance(t, ir.NamedType) else None


def _sub_bodies(s):
    if isinstance(s, ir.If):
        yield from (b for _, b in s.branches)
        if s.else_body:
            yield s.else_body
    elif isinstance(s, ir.Case):
        yield from (b.body for b in s.branches)
        if s.else_body:
            yield s.else_body
    elif isinstance(s, (ir.For, ir.While, ir.Repeat)):
        yield s.body
    elif isinstance(s, ir.Try):
        yield from (b for b in (s.body, s.catch_body, s.finally_body) if b)


# elementary types that are no integer: ``v.3`` takes no bit of them
_BITLESS = frozenset("""REAL LREAL TIME LTIME DATE LDATE TOD TIME_OF_DAY LTOD LTIME_OF_DAY
DT DATE_AND_TIME LDT LDATE_AND_TIME STRING WSTRING CHAR WCHAR""".split())


class ExternalWarning(ProgramWarning):
    """A name taken as declared by a library that is not at hand (``allow_external``)."""


def check_program(program: ir.Program, context: list[ir.Program] = (),
                  allow_external: bool = False):
    """Run the semantic checks. Returns (errors, warnings), each sorted by position. With
    ``allow_external``, names nothing at hand declares are warnings (ExternalWarning)."""
    try:
        program = specialize(program, context)
        # cycles and runaway nesting of types first: the checks below follow types
        check_type_graph([*context, program], _builtin_type, own=program)
    except ProgramError as e:
        return readable([e], program), []
    c = Checker(program, context, allow_external).run()
    key = lambda e: (e.file, e.line, e.col)  # noqa: E731
    return (sorted(readable(c.errors, program), key=key),
            sorted(readable(c.warnings, program), key=key))


def _builtin_type(up: str) -> bool:
    """A type name the checker takes as built in, whatever the program declares."""
    return up in ELEMENTARY_TYPES or up in STANDARD_FBS
