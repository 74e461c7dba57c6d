"""Compile a program's IR to Python source, one class per FUNCTION_BLOCK/PROGRAM and one
function per FUNCTION, so that a scan costs a few Python calls instead of a walk over the
syntax tree.

Mapping:

* variables are attributes of the instance (``self.X``, names upper-cased because IEC
  identifiers are case-insensitive and Python keywords never are all upper case); locals
  of FUNCTIONs, methods and property accessors are Python locals; globals live on ``_g``;
* integer assignments wrap to the declared width; ``/`` and ``MOD`` on integers truncate
  toward zero; TIME is integer nanoseconds;
* FB inputs keep their values between calls (they are attributes); standard FBs are the
  classes of :mod:`plcpred.sequencer.stdfb`, executed at the scan time ``_now``;
* VAR_IN_OUT of functions and methods receive a :class:`~.runtime.Ref` (copy in, copy out);
  VAR_IN_OUT of FBs are copied in before and out after the call;
* structs and arrays are copied on assignment; references and pointers to FBs are the
  instance itself, to elementary variables a :class:`~.runtime.Ref`;
* WHILE and REPEAT count iterations; a loop that runs away raises :class:`~.runtime.Watchdog`
  naming its line.

Direct addresses in code (``%QX0.0 := TRUE``) stand for the variable declared AT them, or
for a hidden global of the address's size. JMP works within one statement list.

Not supported (a positioned error at compile time): jumps into or out of blocks, pointer
arithmetic, variable-length arrays. ``__NEW`` of several elements (an array reached by
pointer arithmetic) compiles, and stops a run where it is executed. A UNION is treated as a
struct (its members do not overlap).
"""
from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass, field

from ..parser import ir
from ..parser.errors import ProgramError, at
from ..parser.generics import GENERIC_PRAGMA, readable, specialize
from ..parser.names import ident, validate_names
from ..parser.stdlib import STANDARD_FBS, WIDE_STRING_FUNCTIONS, is_standard_function, std_fb_pin
from . import types as ty
from .types import BOOL, STRING, TIME, ArrayT, Elem, EnumT, FbT, ItfT, PtrT, StdFbT, StructT

# loop iterations one scan may run, all loops together (nested loops, and loops in the
# FBs a loop calls, share it): a PLC's cycle watchdog, in work instead of time
WATCHDOG_ITERATIONS = 1_000_000
# an observed name followed by this: a bit of that variable is read (``wCount.2``), which
# a count's shift from one period to the next does not keep, so it is compared even then
BIT_READ = "."
# longest if/elif chain generated at once (Compiler._chain)
ELIF_CHAIN = 100

_STDFB_MEMBERS = {"IN": ty.BOOL, "PT": ty.TIME, "Q": ty.BOOL, "ET": ty.TIME, "CLK": ty.BOOL,
                  "S1": ty.BOOL, "R": ty.BOOL, "S": ty.BOOL, "R1": ty.BOOL, "Q1": ty.BOOL,
                  "CU": ty.BOOL, "CD": ty.BOOL, "LD": ty.BOOL, "PV": ty.DINT, "CV": ty.DINT,
                  "QU": ty.BOOL, "QD": ty.BOOL, "RESET": ty.BOOL}


def stdfb_member(t: StdFbT, key: str):
    """(IEC pin name, type) of member ``key`` of a standard FB (vendor pin names map to
    the IEC ones), or (None, None)."""
    pin = std_fb_pin(t.name, key)
    return (pin, _STDFB_MEMBERS[pin]) if pin else (None, None)


_CMP = {"=": "==", "<>": "!=", "<": "<", ">": ">", "<=": "<=", ">=": ">="}
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
_CONV = re.compile(r"^(?:([A-Z_]+?)_)?TO_([A-Z_]+)$")


class CompileError(ProgramError):
    pass


def _err(node, message: str) -> CompileError:
    e = at(getattr(node, "pos", None), message)
    return CompileError(e.message, e.file, e.line, e.col)


def _target_enum(compiler, target, scope):
    """The enumeration type of an assignment's target, if it has one (else None)."""
    try:
        t = compiler._expr(target, scope)[1]
    except CompileError:
        return None
    return t if isinstance(t, EnumT) else None


@dataclass
class Scope:
    """Names visible in one body: UPPER name -> (Python code, type)."""
    names: dict = field(default_factory=dict)
    fb: FbT | None = None          # the FB whose ``self`` is in scope
    pylocals: set = field(default_factory=set)
    ret: str = "return"            # what RETURN compiles to
    steps: dict = field(default_factory=dict)  # SFC step name -> index
    cls: str = ""                  # Python class of self
    pou: str = ""                  # the POU as __POUNAME() gives it (``FB.Method``)


class Source:
    """Generated lines with the program position each came from (for run-time errors)."""

    def __init__(self):
        self.lines: list[str] = []
        self.pos: list = []
        self.tmp = 0

    def emit(self, ind: int, text: str, pos=None):
        self.lines.append("    " * ind + text)
        self.pos.append(pos)

    def temp(self, stem="t") -> str:
        self.tmp += 1
        return f"_{stem}{self.tmp}"


@dataclass
class Compiled:
    """A compiled project: Python source plus what the executor needs to know."""
    source: str
    line_pos: list
    programs: list[tuple[str, str]]            # (instance name, class name) in scan order
    program_types: dict                        # instance name -> FbT
    globals_types: dict                        # UPPER -> (name, type, decl)
    reads_et: bool = False                     # the program reads a timer's ET
    reads_clock: bool = False                  # TIME()/NOW: step every scan
    types: object = None
    address_slots: dict = None                 # undeclared direct address -> global attr
    intervals: dict = None                     # program instance -> task INTERVAL (ns)
    et_thresholds: tuple = ()                  # constants ET is compared with (ns)
    written: frozenset | None = None           # names the program may write (None: any)
    # class name -> {attribute: (bits, signed) or None} of the variables left out of the
    # state the executor compares (Compiler._sinks): (bits, signed) for an integer that
    # only ever adds a step to itself (a count, which grows by the same amount each
    # period of a repeating machine), None for any other
    left_out: dict = None
    # names the machine file reads (Compiler's ``observed``): never left out, so that
    # everything they show is in the compared state
    observed: frozenset = frozenset()


class Compiler:
    def __init__(self, program: ir.Program, observed=frozenset()):
        # the gate to code generation: whatever built this IR (a front end or a library
        # caller), no name reaches the generated source unless it is an identifier
        program = self.program = validate_names(specialize(program))
        self.types = ty.TypeTable(program)
        self.src = Source()
        self.reads_et = False
        self.reads_clock = False
        self.globals: dict = {}
        self.functions = {ident(p.name): p for p in program.pous if p.kind == "FUNCTION"}
        self.gvl_names = {ident(g.name) for g in program.globals if g.name}
        self._jump = None
        self._loop_depth = 0
        self.left_out: dict[str, dict] = {}     # class -> its sinks (Compiled.left_out)
        self.address_slots: dict[str, str] = {}  # undeclared direct address -> global
        self.addr_names: dict[str, str] = {}
        self._et_classes: set = set()
        self._pending_sfc: list = []   # (line, pos) of SFC specs, emitted after the classes
        self.intervals: dict[str, int] = {}
        self.et_thresholds: set = set()  # constants timers' ET is compared with (ns)
        self._et_const = False
        self._member_names = ir.names_in(program)
        # FBs another extends (the base's name without a library prefix)
        self._extended = {p.extends.rsplit(".", 1)[-1].upper() for p in program.pous
                          if p.extends}
        self._global_constants = {
            d.name.upper() for b in [g.block for g in program.globals]
            + [b for c in program.configurations for b in c.var_blocks]
            if _constant_block(b) for d in b.decls}
        self.referenced: set | None = set()   # names handed out by reference (_ref_of)
        # names that something outside the program reads (a valve the machine file
        # names): a variable of such a name is no sink, whatever the program does with it
        self.observed = frozenset(n.upper() for n in observed)

    def _chain(self, arms, else_body, scope: Scope, ind: int, pos, loop: bool) -> None:
        """``if``/``elif``/``else`` over ``arms`` [(a function giving the test's code, the
        body, its position)]. Python's compiler recurses once per ``elif``, so a chain
        longer than ELIF_CHAIN (a CASE of 20,000 labels ran it out of memory) is cut into
        chains that each run only when none before matched."""
        e = self.src.emit
        hit = self.src.temp("hit") if len(arms) > ELIF_CHAIN else None
        for start in range(0, len(arms), ELIF_CHAIN):
            inner = ind
            if start:
                e(ind, f"if not {hit}:", pos)
                inner = ind + 1
            if hit:
                e(inner, f"{hit} = True", pos)
            for k, (test, body, at) in enumerate(arms[start:start + ELIF_CHAIN]):
                e(inner, f"{'if' if k == 0 else 'elif'} {test()}:", at)
                self._stmts(body, scope, inner + 1, loop)
                e(inner + 1, "pass")
            if hit:
                e(inner, "else:", pos)
                e(inner + 1, f"{hit} = False", pos)
        if else_body is not None:
            e(ind, f"if not {hit}:" if hit else "else:" if arms else "if True:", pos)
            self._stmts(else_body, scope, ind + 1, loop)
            e(ind + 1, "pass")

    def _count_iteration(self, kind: str, ind: int, pos, n: int = 1) -> None:
        """Count ``n`` loop passes against the scan's budget (``_work``, reset by the
        executor each scan): a loop that runs away, or loops nested so that together
        they do, stop at the watchdog naming this loop."""
        self.src.emit(ind, f"_work[0] += {n}", pos)
        self.src.emit(ind, f"if _work[0] > {WATCHDOG_ITERATIONS}: _watchdog({kind!r}, "
                           f"{_pos_args(pos)})", pos)

    # ================================================================== project
    def compile(self) -> Compiled:
        e = self.src.emit
        e(0, "# generated by plcpred.sequencer.compiler; do not edit")
        self._collect_constants()
        gblocks = [g.block for g in self.program.globals]
        for c in self.program.configurations:
            gblocks += c.var_blocks
            for r in c.resources:
                gblocks += r.var_blocks
        gdecls = [d for b in gblocks if b.kind == "VAR_GLOBAL" for d in b.decls]
        gdecls += self._address_slots(gblocks)
        # CODESYS/TwinCAT: a PROGRAM is one instance, which other POUs may call by its
        # name (MAIN calls its sub-programs) or read (Sub.nCount): a global of its own
        taken = {ident(d.name) for d in gdecls}
        called = ir.names_in(self.program, ir.Name, "name")
        singletons = [ir.VarDecl(p.name, ir.NamedType(p.name, pos=p.pos), pos=p.pos)
                      for p in self.program.pous if p.kind == "PROGRAM"
                      and p.name.upper() in called and ident(p.name) not in taken]
        self._singletons = {ident(d.name) for d in singletons}
        gdecls += singletons
        for d in gdecls:
            self.globals[ident(d.name)] = (d.name, self.types.resolve(d.type, d.pos), d)
        fbs = [self.types.fb(ident(p.name)) for p in self.program.pous
               if p.kind in ("FUNCTION_BLOCK", "PROGRAM")]
        # structs first (FB classes may instantiate them), then FBs base-first
        gscope = Scope(names={k: (f"_g.{k}", t) for k, (n, t, d) in self.globals.items()})
        self._globals_class(gdecls, gscope)
        done = set()
        for fb in sorted(fbs, key=lambda t: len(list(t.chain()))):
            self._fb_class(fb, done)
        for f in self.functions.values():
            self._function(f)
        # a struct is listed when a declaration first resolves it, a function's locals
        # and a struct's members included: its class may be emitted after every user
        # (all refer to it at run time only), and each class may list more
        emitted = 0
        while emitted < len(self.types.structs):
            self._struct_class(self.types.structs[emitted])
            emitted += 1
        # SFC specs name methods of the classes above, so they come after them
        for text, pos in self._pending_sfc:
            e(0, text, pos)
        programs = self._program_instances()
        prog_types = {name: next(f for f in fbs if f.cls_name == cls) for name, cls in programs}
        self._check_memory(gdecls, prog_types.values())
        e(0, "def _build():")
        e(1, "global _g")
        e(1, "_g = k_GLOBALS()")
        made = set()
        instances = []
        for _, cls in programs:     # a called program runs as the one instance called
            key = next((k for k in self._singletons
                        if self.types.fbs[k].cls_name == cls), None)
            instances.append(f"_g.{key}" if key is not None and key not in made
                             else f"{cls}()")
            made.add(key)
        e(1, "return [" + ", ".join(instances) + "]")
        return Compiled("\n".join(self.src.lines) + "\n", self.src.pos, programs, prog_types,
                        self.globals, self.reads_et, self.reads_clock, self.types,
                        dict(self.address_slots), dict(self.intervals),
                        tuple(sorted(self.et_thresholds)), self._written(),
                        dict(self.left_out), self.observed)

    def _written(self) -> frozenset | None:
        by_name = written_names(self.program)
        if by_name is None or self.referenced is None:
            return None
        return frozenset(by_name | self.referenced)

    def _check_memory(self, gdecls, program_types):
        """The whole project's variables within MAX_PROGRAM_CELLS, else an error at the
        declaration that holds the most."""
        sizes = [(ty.cells(self.globals[ident(d.name)][1], self.types), d) for d in gdecls]
        for fb in program_types:
            for b in fb.pou.var_blocks:
                for d in b.decls:
                    if b.kind not in ("VAR_EXTERNAL", "VAR_IN_OUT"):
                        sizes.append((ty.cells(self.types.resolve(d.type, d.pos),
                                               self.types), d))
        total = sum(n for n, _ in sizes)
        if total > ty.MAX_PROGRAM_CELLS:
            n, d = max(sizes, key=lambda x: x[0])
            raise _err(d, f"the program's variables hold {total:,} values (arrays and "
                          f"instances counted through), more than the executor's "
                          f"{ty.MAX_PROGRAM_CELLS:,}; {d.name} alone holds {n:,}")

    def _et_compare(self, x: ir.Binary):
        """The threshold (ns) of ``timer.ET <op> constant`` (either way round), or None."""
        if x.op not in _CMP:
            return None
        for a, b in ((x.left, x.right), (x.right, x.left)):
            if isinstance(a, ir.Member) and ident(a.member) == "ET":
                c = self._const_time(b)
                if c is None and isinstance(b, ir.Name):
                    c = self.time_constants.get(ident(b.name))
                return c
        return None

    def _collect_constants(self):
        """Integer constants usable in array bounds (``ARRAY[1..N]``), and TIME constants
        (timer thresholds)."""
        self.time_constants = {}
        for b in [g.block for g in self.program.globals] + [
                b for p in self.program.pous for b in p.var_blocks]:
            if _constant_block(b):
                for d in b.decls:
                    if (isinstance(d.init, ir.Literal) and d.init.type_name in ("TIME", "LTIME")
                            and isinstance(d.type, ir.NamedType)
                            and ident(d.type.name) in ("TIME", "LTIME")):
                        self.time_constants[ident(d.name)] = int(d.init.value)
        blocks = [g.block for g in self.program.globals]
        blocks += [b for p in self.program.pous for b in p.var_blocks]
        for key, value in _int_constants(blocks):
            self.types.constants[key] = value
        # a method's own constants (its array bounds may name them), never in place of a
        # POU's or a global one of the same name: the table is not scoped
        for key, value in _int_constants(b for p in self.program.pous for m in p.methods
                                         for b in m.var_blocks):
            self.types.constants.setdefault(key, value)

    def _address_slots(self, gblocks) -> list:
        """Direct addresses used in code (``%IX0.0 := ...``): those declared AT a variable
        alias it; the others become hidden globals named ``AT_IX0_0``."""
        declared = {}
        for b in gblocks + [b for p in self.program.pous if p.kind == "PROGRAM"
                            for b in p.var_blocks]:
            for d in b.decls:
                if d.address and "*" not in d.address:
                    declared.setdefault(d.address.upper(), d.name)
        self.addr_names = declared
        used = sorted(ir.names_in(self.program, ir.DirectAddress, "address") - set(declared))
        taken = ir.names_in([self.program.pous, self.program.configurations,
                          self.program.globals], ir.VarDecl, "name")
        decls = []
        for addr in used:
            attr = "AT_" + re.sub(r"[^A-Z0-9]", "_", addr[1:].upper())
            while attr in taken:  # a user variable already has the name
                attr = "X" + attr
            taken.add(attr)
            size = addr[2:3] if len(addr) > 2 and addr[2].isalpha() else "X"
            tname = {"X": "BOOL", "B": "BYTE", "W": "WORD", "D": "DWORD",
                     "L": "LWORD"}.get(size, "BOOL")
            decls.append(ir.VarDecl(attr, ir.NamedType(tname), None, addr))
            self.address_slots[addr] = attr
        return decls

    def _direct(self, x: ir.DirectAddress, scope: Scope):
        """The variable a direct address stands for, as a Name to compile."""
        addr = x.address.upper()
        name = self.addr_names.get(addr)
        if name is not None and name.upper() in scope.names:
            return ir.Name(name, pos=x.pos)
        if addr in self.address_slots:
            return ir.Name(self.address_slots[addr], pos=x.pos)
        raise _err(x, f"direct address {x.address} belongs to a variable of another "
                      "program; use that program's variable")

    def _program_instances(self):
        out = []
        self.intervals = {}
        for c in self.program.configurations:
            for r in c.resources:
                tasks = {ident(t.name): t for t in r.tasks}
                for pi in r.programs:
                    task = tasks.get((pi.task or "").upper())
                    if task is not None and task.interval_ns is not None:
                        self.intervals[pi.name] = task.interval_ns
                    key = ident(pi.type_name)
                    if key not in self.types.fbs or self.types.fbs[key].pou.kind != "PROGRAM":
                        raise _err(pi, f"PROGRAM instance {pi.name} names '{pi.type_name}', "
                                       "which is not a PROGRAM")
                    out.append((pi.name, self.types.fbs[key].cls_name))
        if out:
            return out
        progs = [p for p in self.program.pous if p.kind == "PROGRAM"]
        if not progs:
            raise CompileError("no PROGRAM to run (the file has only functions, function "
                               "blocks or types)", self._file())
        if len(progs) > 1:
            raise _err(progs[1], "several PROGRAMs and no CONFIGURATION saying which to run "
                                 f"({', '.join(p.name for p in progs)})")
        return [(progs[0].name, self.types.fbs[ident(progs[0].name)].cls_name)]

    def _file(self) -> str:
        for p in self.program.pous:
            if p.pos is not None:
                return p.pos.file
        return "<program>"

    # ================================================================== classes
    def _globals_class(self, decls, scope):
        e = self.src.emit
        e(0, "class k_GLOBALS:")
        e(1, "__slots__ = (" + "".join(f"'{ident(d.name)}', " for d in decls) + ")")
        e(1, "def __init__(self):")
        e(2, "global _g")
        e(2, "_g = self")
        for d in decls:
            t = self.globals[ident(d.name)][1]
            e(2, f"self.{ident(d.name)} = {self._init(t, d.init, scope, d)}", d.pos)
        for d in decls:
            self._fb_init_calls(f"self.{ident(d.name)}", self.globals[ident(d.name)][1], d,
                                scope, 2)
        e(1, "def _snap(self, rel):")
        e(2, "return (" + "".join(f"{self._snap_code('self.' + ident(d.name), self.globals[ident(d.name)][1])}, " for d in decls) + ")")

    def _struct_class(self, s: StructT):
        e = self.src.emit
        scope = Scope()
        e(0, f"class {s.cls_name}:")
        keys = list(s.members)
        e(1, "__slots__ = (" + "".join(f"'{k}', " for k in keys) + ")")
        e(1, "def __init__(self):")
        for d in s.decls:
            e(2, f"self.{ident(d.name)} = "
                 f"{self._init(s.members[ident(d.name)], d.init, scope, d)}", d.pos)
        if not s.decls:
            e(2, "pass")
        e(1, "def _snap(self, rel):")
        e(2, "return (" + "".join(f"{self._snap_code('self.' + k, s.members[k])}, "
                                  for k in keys) + ")")

    def _scope_for(self, fb: FbT) -> Scope:
        names = {k: (f"_g.{k}", t) for k, (n, t, d) in self.globals.items()}
        for t in reversed(list(fb.chain())):
            for b in t.pou.var_blocks:
                for d in b.decls:
                    key = ident(d.name)
                    if b.kind == "VAR_EXTERNAL":
                        if key not in self.globals:
                            raise _err(d, f"VAR_EXTERNAL {d.name} has no VAR_GLOBAL")
                        continue
                    names[key] = (f"self.{key}", self.types.resolve(d.type, d.pos))
        sc = Scope(names=names, fb=fb, cls=fb.cls_name, pou=_shown_name(fb.pou))
        if fb.pou.is_sfc:
            sc.steps = {ident(s.name): i for i, s in enumerate(fb.pou.body.steps)}
        return sc

    def _fb_class(self, fb: FbT, done: set):
        if fb.cls_name in done:
            return
        if fb.base is not None:
            self._fb_class(fb.base, done)
        done.add(fb.cls_name)
        e = self.src.emit
        pou = fb.pou
        scope = self._scope_for(fb)
        own = [d for b in pou.var_blocks if b.kind != "VAR_EXTERNAL" for d in b.decls]
        base = fb.base.cls_name if fb.base else "k_FbBase"
        e(0, f"class {fb.cls_name}({base}):", pou.pos)
        edges = [d for d in own if d.edge]
        # an edge input's previous value (generated names have a lower-case letter)
        slots = [ident(d.name) for d in own] + [f"_e_{ident(d.name)}" for d in edges] + (
            ["_sfc"] if pou.is_sfc else [])
        e(1, "__slots__ = (" + "".join(f"'{k}', " for k in slots) + ")")
        e(1, "def __init__(self):")
        if fb.base:
            e(2, f"{fb.base.cls_name}.__init__(self)")
        for d in own:
            t = scope.names[ident(d.name)][1]
            e(2, f"self.{ident(d.name)} = {self._init(t, d.init, scope, d)}", d.pos)
        for d in own:
            self._fb_init_calls(f"self.{ident(d.name)}", scope.names[ident(d.name)][1], d,
                                scope, 2)
        for d in edges:
            e(2, f"self._e_{ident(d.name)} = False", d.pos)
        if pou.is_sfc:
            e(2, f"self._sfc = _SfcRuntime({self._sfc_spec(fb, scope)}, self)")
            e(2, "_register(self._sfc)")
        e(2, "pass")
        # body
        e(1, "def _body(self):")
        temps = [d for b in pou.var_blocks if b.kind == "VAR_TEMP" for d in b.decls]
        for d in temps:
            t = scope.names[ident(d.name)][1]
            e(2, f"self.{ident(d.name)} = {self._init(t, d.init, scope, d)}", d.pos)
        if pou.is_sfc:
            e(2, "self._sfc.run(_now)")
        else:
            self._stmts(pou.body, scope, 2)
        e(2, "pass")
        for m in pou.methods:
            self._method(m, fb, scope)
        for p in pou.properties:
            self._property(p, fb, scope)
        for a in pou.actions:
            e(1, f"def a_{ident(a.name)}(self):", a.pos)
            self._stmts(a.body, scope, 2)
            e(2, "pass")
        if pou.is_sfc:
            for a in pou.body.actions:
                e(1, f"def a_{ident(a.name)}(self):", a.pos)
                self._stmts(a.body, scope, 2)
                e(2, "pass")
        e(1, "def _snap(self, rel):")
        sinks = self._sinks(fb, scope)
        counted = self._threshold_counters(fb, scope) - sinks
        parts = [f"self.{ident(d.name)}.key_counted(rel)" if ident(d.name) in counted else
                 self._snap_code(f"self.{ident(d.name)}", scope.names[ident(d.name)][1])
                 for d in own if d not in temps and ident(d.name) not in sinks]
        parts += [f"self._e_{ident(d.name)}" for d in edges]
        if pou.is_sfc:
            parts.append("self._sfc.key(rel)")
        if fb.base:
            parts.append(f"{fb.base.cls_name}._snap(self, rel)")
        e(2, "return (" + "".join(p + ", " for p in parts) + ")")

    def _fb_init_calls(self, code: str, t, d: ir.VarDecl, scope: Scope, ind: int) -> None:
        """CODESYS/TwinCAT FB_init: once every variable of the instance holding ``d`` has
        its initial value, each FB instance ``d`` declares (every element of an array of
        them) runs its FB_init (:meth:`_fb_init_code`)."""
        inner = t
        while isinstance(inner, ArrayT):
            inner = inner.elem
        if not isinstance(inner, FbT) or not _fb_inits(inner):
            return
        e = self.src.emit
        per = d.element_init_args
        if per is not None:
            # each element its own arguments, in element order (the last index fastest);
            # elements the list does not reach get none
            k = self.src.temp("fbk")
            e(ind, f"{k} = 0", d.pos)
        while isinstance(t, ArrayT):
            for _ in t.dims:
                var = self.src.temp("fbi")
                e(ind, f"for {var} in {code}:", d.pos)
                code, ind = var, ind + 1
            t = t.elem
        if per is None:
            for line in self._fb_init_code(code, inner, d, scope):
                e(ind, line, d.pos)
            return
        for n, args in enumerate(per + [[]]):
            e(ind, "else:" if n == len(per) else f"{'el' if n else ''}if {k} == {n}:", d.pos)
            one = dataclasses.replace(d, init_args=args, element_init_args=None)
            for line in self._fb_init_code(code, inner, one, scope):
                e(ind + 1, line, d.pos)
        e(ind, f"{k} += 1", d.pos)

    def _fb_init_code(self, code: str, t: FbT, d: ir.VarDecl, scope: Scope) -> list[str]:
        """The FB_init calls of instance ``code`` of ``t`` declared by ``d``: bInitRetains
        and bInCopyCode FALSE and the declaration's arguments (``fb : FB_T(5)``), a base
        FB's FB_init first, each with the arguments its own parameters take."""
        out = []
        for ft, m in _fb_inits(t):
            call = ir.Call(ir.Name("FB_init", pos=d.pos), _fb_init_args(m, d), pos=d.pos)
            out.append(f"{ft.cls_name}.m_FB_INIT({code}, "
                       f"{self._named_args(m.var_blocks, call, scope, ft.name + '.FB_init')})")
        return out

    def _sinks(self, fb: FbT, scope: Scope) -> set:
        """Local variables whose values never reach an output, a condition, a call or an
        index: counters and statistics such as ``nParts := nParts + 1``. They are left out
        of the state the executor compares, so a machine that counts its parts still
        reaches fixed points and repeats its cycle. Decided from the data flow of the
        FB's own code; anything named as ``x.member`` anywhere is never a sink."""
        pou = fb.pou
        cands = set()
        for b in pou.var_blocks:
            if b.kind not in ("VAR", "VAR_TEMP"):
                continue
            for d in b.decls:
                t = scope.names[ident(d.name)][1]
                while isinstance(t, ArrayT):
                    t = t.elem
                if not d.address and t.cat in ("bool", "int", "real", "time", "date",
                                               "string", "struct", "stdfb"):
                    cands.add(ident(d.name))
        # a standard FB only changes its own outputs: its inputs flow into it, and it is a
        # sink when nothing reads those outputs (a parts counter nobody looks at)
        std = {k for k in cands if _base_t(scope.names[k][1]).cat == "stdfb"}
        cands -= self._member_names - std
        if not cands and fb.name not in self._et_classes:
            return set()
        flow = _Flow({k for k, f in self.functions.items()
                      if any(b.kind == "VAR_EXTERNAL" for b in f.var_blocks)
                      or ir.names_in(f.body, ir.Name, "name") & set(self.globals)}, std,
                     self._et_compare)
        bodies = []
        if pou.is_sfc:
            for tr in pou.body.transitions:
                flow.use(tr.condition)
            for st in pou.body.steps:
                for a in st.actions:
                    flow.used.add(ident(a.action))
                    if a.time is not None:
                        flow.use(a.time)
            bodies += [a.body for a in pou.body.actions]
        else:
            bodies.append(pou.body)
        bodies += [a.body for a in pou.actions] + [m.body for m in pou.methods]
        bodies += [acc.body for p in pou.properties for acc in p.accessors]
        for body in bodies:
            flow.stmts(body)
        while True:
            sinks = _unread(cands, flow)
            # a sink the machine file reads is shown: it must be compared, and so must
            # what flows into it; a count of parts may stay out (the executor shifts a
            # repeated period's counts, _LeftOut)
            shown = {k for k in sinks & self.observed
                     if k + BIT_READ in self.observed
                     or self._count_width(k, flow, sinks, scope) is None}
            if not shown:
                break
            flow.used |= shown
        if any(t is None or t not in sinks for t in flow.et_targets):
            # a running timer's ET reaches something that matters: the executor must
            # step scan by scan while timers run
            self.reads_et = True
        self.left_out[fb.cls_name] = {k: self._count_width(k, flow, sinks, scope)
                                      for k in sinks}
        return sinks

    @staticmethod
    def _count_width(name: str, flow, sinks: set, scope: Scope):
        """(bits, signed) when sink ``name`` is an integer whose every write adds to it a
        step that reads no sink (``n := n + 1``, ``n := n - k``): over a period of a
        repeating machine it then grows by the same amount, and a repeated period's
        values are the first period's plus that amount per period (modulo its width).
        None for any other sink."""
        t = scope.names[name][1]
        n, reads = flow.steps.get(name, (0, set()))
        if not n or n != sum(1 for target, _ in flow.flows if target == name) \
                or reads & sinks or isinstance(t, ArrayT):
            return None
        t = _base_t(t)
        if t.cat != "int" or (t.bits or 32) > 52:
            return None                     # a float64 holds no wider count exactly
        return (t.bits or 32, bool(t.signed))

    def _threshold_counters(self, fb: FbT, scope: Scope) -> set:
        """Counters whose count nothing reads, only their Q, which stops changing once
        the count is past the threshold: a CTU whose PV is one constant (Q := CV >= PV)
        or a CTD (Q := CV <= 0). They are compared with the count held at the threshold
        (``key_counted``), so that a machine that counts its parts to request a filter
        check after 5000 of them repeats its cycle once it has. Decided from the FB's
        own code: the instance is only called (every input named, PV one constant, CV
        bound to nothing) and its Q read; an instance named as ``x.member`` anywhere,
        or one of an FB that another extends, is left alone."""
        pou = fb.pou
        if pou.name.upper() in self._extended:
            return set()
        kinds = {}
        for b in pou.var_blocks:
            for d in b.decls if b.kind == "VAR" else ():
                t = scope.names[ident(d.name)][1]
                kind = t.name.upper().partition("_")[0] if isinstance(t, StdFbT) else None
                if kind in ("CTU", "CTD") and not d.address \
                        and d.name.upper() not in self._member_names \
                        and d.name.upper() not in self.observed:
                    kinds[d.name.upper()] = kind
        if not kinds:
            return set()
        own_constants = {d.name.upper() for b in pou.var_blocks if _constant_block(b)
                         for d in b.decls}
        local = {d.name.upper() for b in pou.var_blocks for d in b.decls} | {
            d.name.upper() for m in pou.methods for b in m.var_blocks for d in b.decls}

        def constant(x):
            if isinstance(x, ir.Literal):
                return ("literal", x.type_name, x.value)
            if isinstance(x, ir.Name) and (x.name.upper() in own_constants or (
                    x.name.upper() in self._global_constants and x.name.upper() not in local)):
                return ("name", x.name.upper())
            return None

        ok = dict.fromkeys(kinds, True)
        pv: dict = {k: set() for k in kinds}
        for name, node, parent in _name_uses(pou, set(kinds)):
            if isinstance(parent, ir.Call) and parent.func is node:
                for a in parent.args:
                    if a.name is None or a.name.upper() == "CV":
                        ok[name] = False
                    elif a.name.upper() == "PV":
                        pv[name].add(constant(a.value))
            elif not (isinstance(parent, ir.Member) and parent.base is node
                      and parent.member.upper() == "Q"):
                ok[name] = False        # CV read or written, the instance handed on, ...
        return {ident(k) for k, kind in kinds.items() if ok[k] and (
            kind == "CTD" or (len(pv[k]) <= 1 and None not in pv[k]))}

    def _snap_code(self, code: str, t) -> str:
        if t.cat in ("fb", "struct"):
            return f"{code}._snap(rel)"
        if t.cat == "stdfb":
            return f"{code}.key(rel)"
        if t.cat == "array":
            if len(t.dims) == 1:
                if isinstance(t.elem, (Elem, EnumT)):
                    return f"tuple({code})"
                if t.elem.cat in ("fb", "struct"):
                    return f"tuple([x._snap(rel) for x in {code}])"
                if t.elem.cat == "stdfb":
                    return f"tuple([x.key(rel) for x in {code}])"
            return f"_snap_any({code}, rel)"
        if t.cat in ("ptr", "itf"):
            return f"_refkey({code})"
        return code

    # ---------------------------------------------------------------- SFC
    def _sfc_spec(self, fb: FbT, scope: Scope) -> str:
        """Emit the spec of an SFC body as a module-level object; return its name."""
        sfc: ir.Sfc = fb.pou.body
        name = f"_sfcspec_{fb.cls_name}"
        idx = scope.steps
        out = []  # lines emitted after the class (the spec refers to methods)
        trans = []
        thresholds: dict[int, list[int]] = {}
        t_read: set[int] = set()
        self._step_t_uses = (thresholds, t_read)
        for k, tr in enumerate(sorted(enumerate(sfc.transitions),
                                      key=lambda it: (it[1].priority, it[0]))):
            i, tr = tr
            for s in tr.sources + tr.targets:
                if s.upper() not in idx:
                    raise _err(tr, f"transition refers to unknown step '{s}'")
            self._collect_step_t(tr.condition, scope, thresholds, t_read)
            code, t = self._expr(tr.condition, scope)
            fn = f"_tc_{fb.cls_name}_{i}"
            out.append((f"def {fn}(self):", tr.pos))
            out.append((f"    return {self._to(code, t, BOOL, tr.condition)}", tr.pos))
            srcs = tuple(idx[s.upper()] for s in tr.sources)
            tgts = tuple(idx[s.upper()] for s in tr.targets)
            trans.append(f"({srcs!r}, {tgts!r}, {fn}, {tr.priority})")
        body_actions = {ident(a.name): a for a in sfc.actions}
        body_actions.update({ident(a.name): a for a in fb.pou.actions})
        actions: dict[str, str] = {}
        assocs: dict[str, list[str]] = {}
        for si, step in enumerate(sfc.steps):
            for assoc in step.actions:
                key = ident(assoc.action)
                if key not in actions:
                    if key in body_actions:
                        actions[key] = (f"_ActionSpec({assoc.action!r}, "
                                        f"body={fb.cls_name}.a_{key})")
                    elif key in scope.names and scope.names[key][1] == BOOL:
                        setter = f"_set_{fb.cls_name}_{key}"
                        code = scope.names[key][0].replace("self.", "o.", 1)
                        out.append((f"def {setter}(o, v):", assoc.pos))
                        out.append((f"    {code} = v", assoc.pos))
                        actions[key] = f"_ActionSpec({assoc.action!r}, setter={setter})"
                    else:
                        raise _err(assoc, f"step {step.name}: '{assoc.action}' is neither an "
                                          "action nor a BOOL variable")
                    assocs[key] = []
                q = assoc.qualifier.upper()
                if q in ("L", "D", "SD", "DS", "SL"):
                    if assoc.time is None:
                        raise _err(assoc, f"qualifier {q} needs a time")
                    code, t = self._expr(assoc.time, scope)
                    tfn = f"_at_{fb.cls_name}_{len(out)}"
                    out.append((f"def {tfn}(self):", assoc.pos))
                    out.append((f"    return {code}", assoc.pos))
                else:
                    tfn = "None"
                assocs[key].append(f"({si}, {q!r}, {tfn})")
        lines = [(l, p) for l, p in out]
        lines.append((f"{name} = _SfcSpec({[s.name for s in sfc.steps]!r}, "
                      f"{next(i for i, s in enumerate(sfc.steps) if s.initial)}, "
                      f"[{', '.join(trans)}], [], {thresholds!r}, {t_read!r})", None))
        for key, spec in actions.items():
            lines.append((f"_a = {spec}", None))
            lines.append((f"_a.assocs.extend([{', '.join(assocs[key])}])", None))
            lines.append((f"{name}.actions.append(_a)", None))
        self._pending_sfc.extend(lines)
        return name

    def _collect_step_t(self, e, scope, thresholds, t_read):
        """Constant ``step.T`` comparisons become scheduled events; anything else that
        reads ``step.T`` makes the executor step every scan while the step is active."""
        if isinstance(e, ir.Binary) and e.op in _CMP:
            for a, b in ((e.left, e.right), (e.right, e.left)):
                si = self._step_member(a, scope, "T")
                if si is not None:
                    try:
                        c = self._const_time(b)
                    except CompileError:
                        c = None
                    if c is None:
                        t_read.add(si)
                    else:
                        thresholds.setdefault(si, []).append(c)
                    self._collect_step_t(b, scope, thresholds, t_read)
                    return
        si = self._step_member(e, scope, "T")
        if si is not None:
            t_read.add(si)
            return
        for child in _children(e):
            self._collect_step_t(child, scope, thresholds, t_read)

    def _step_member(self, e, scope, member):
        if (isinstance(e, ir.Member) and ident(e.member) == member
                and isinstance(e.base, ir.Name) and ident(e.base.name) in scope.steps):
            return scope.steps[ident(e.base.name)]
        return None

    def _const_time(self, e):
        if isinstance(e, ir.Literal) and isinstance(e.value, int) and not isinstance(
                e.value, bool):
            return int(e.value) if e.type_name in ("TIME", "LTIME") else int(e.value) * 10**6
        return None

    # ---------------------------------------------------------------- methods & functions
    def _local_scope(self, outer: Scope, var_blocks, extra=()) -> tuple[Scope, list]:
        sc = Scope(names=dict(outer.names), fb=outer.fb, cls=outer.cls, steps=outer.steps,
                   pou=outer.pou)
        params = []
        for b in var_blocks:
            for d in b.decls:
                key = ident(d.name)
                t = self.types.resolve(d.type, d.pos)
                sc.names[key] = (key, t)
                sc.pylocals.add(key)
                params.append((b.kind, d, t))
        for key, t in extra:
            sc.names[key] = (key, t)
            sc.pylocals.add(key)
        return sc, params

    def _callable(self, header: str, scope: Scope, var_blocks, body, ret_name, ret_t, ind,
                  pos):
        """The shared shape of functions, methods and property accessors."""
        e = self.src.emit
        extra = [(ret_name, ret_t)] if ret_t is not None else []
        sc, params = self._local_scope(scope, var_blocks, extra)
        args = []
        for kind, d, t in params:
            key = ident(d.name)
            if kind == "VAR_INPUT":
                args.append(f"{key}=_dflt")
            elif kind in ("VAR_OUTPUT", "VAR_IN_OUT"):
                args.append(f"_r_{key}=None")
        e(ind, header.replace("ARGS", ", ".join(args)), pos)
        for kind, d, t in params:
            key = ident(d.name)
            init = self._init(t, d.init, sc, d)
            if _has_fb(t):
                # a call's own instances must not join the executor's list of live timers
                init = f"_unlisted(lambda: {init})"
            if kind == "VAR_INPUT":
                conv = f"_copy({key})" if t.cat in ("struct", "array") else key
                e(ind + 1, f"{key} = {init} if {key} is _dflt else {conv}", d.pos)
            elif kind == "VAR_IN_OUT":
                e(ind + 1, f"{key} = _r_{key}.get() if _r_{key} is not None else {init}",
                  d.pos)
            else:
                e(ind + 1, f"{key} = {init}", d.pos)
        if ret_t is not None:
            e(ind + 1, f"{ret_name} = {self._init(ret_t, None, sc, None)}")
        outs = [(ident(d.name)) for kind, d, t in params if kind in ("VAR_OUTPUT",
                                                                      "VAR_IN_OUT")]
        sc.ret = f"return {ret_name}" if ret_t is not None else "return"
        if outs:
            e(ind + 1, "try:")
            self._stmts(body, sc, ind + 2)
            e(ind + 2, "pass")
            e(ind + 1, "finally:")
            for key in outs:
                e(ind + 2, f"if _r_{key} is not None: _r_{key}.set({key})")
        else:
            self._stmts(body, sc, ind + 1)
        e(ind + 1, sc.ret)

    def _function(self, f: ir.Pou):
        ret_t = self.types.resolve(f.return_type, f.pos) if f.return_type else None
        scope = Scope(names={k: (f"_g.{k}", t) for k, (n, t, d) in self.globals.items()},
                      pou=f.name)
        blocks = [b for b in f.var_blocks if b.kind != "VAR_EXTERNAL"]
        self._callable(f"def _fn_{ident(f.name)}(ARGS):", scope, blocks, f.body,
                       ident(f.name), ret_t, 0, f.pos)

    def _method(self, m: ir.Method, fb: FbT, scope: Scope):
        ret_t = self.types.resolve(m.return_type, m.pos) if m.return_type else None
        scope = dataclasses.replace(scope, pou=f"{_shown_name(fb.pou)}.{m.name}")
        self._callable(f"def m_{ident(m.name)}(self, ARGS):", scope, m.var_blocks, m.body,
                       ident(m.name), ret_t, 1, m.pos)

    def _property(self, p: ir.Property, fb: FbT, scope: Scope):
        t = self.types.resolve(p.type, p.pos)
        for acc in p.accessors:
            if acc.kind == "GET":
                self._callable(f"def p_get_{ident(p.name)}(self, ARGS):", scope,
                               acc.var_blocks, acc.body, ident(p.name), t, 1, acc.pos)
            else:
                blocks = [ir.VarBlock("VAR_INPUT", [ir.VarDecl(p.name, p.type)])]
                blocks += acc.var_blocks
                self._callable(f"def p_set_{ident(p.name)}(self, ARGS):", scope, blocks,
                               acc.body, "p_ret", None, 1, acc.pos)

    # ================================================================== initial values
    def _init(self, t, init, scope, decl) -> str:
        if isinstance(init, ir.ArrayInit):
            if not isinstance(t, ArrayT):
                raise _err(init, "an array initialiser for a variable that is not an array")
            flat = []
            for count, item in init.items:
                if len(flat) + count > t.size:  # checked first: count may be huge
                    raise _err(init, f"{len(flat) + count:,} initial values for an array "
                                     f"of {t.size:,}")
                flat.extend([self._init(t.elem, item, scope, decl)] * count)
            flat += [self._init(t.elem, None, scope, decl)] * (t.size - len(flat))
            return f"_nest([{', '.join(flat)}], {[hi - lo + 1 for lo, hi in t.dims]!r})"
        if isinstance(init, ir.StructInit):
            if t.cat not in ("struct", "fb", "stdfb"):
                raise _err(init, "a structure initialiser for a variable that is neither a "
                                 "structure nor a function block")
            members = t.members if isinstance(t, StructT) else None
            parts = []
            for fname, finit in init.fields:
                key = ident(fname)
                if isinstance(t, StdFbT):
                    key = stdfb_member(t, key)[0] or key
                mt = members.get(key) if members is not None else self._fb_member_type(
                    t, key, init)
                if mt is None:
                    raise _err(init, f"'{fname}' is not a member of {t.name}")
                parts.append(f"{key}={self._init(mt, finit, scope, decl)}")
            base = self._init(t, None, scope, decl)
            return f"_setattrs({base}, {', '.join(parts)})"
        if isinstance(t, ArrayT):
            one = self._init(t.elem, None, scope, decl)
            code = one
            for lo, hi in reversed(t.dims):
                code = f"[{code} for _ in range({hi - lo + 1})]"
            return code
        if isinstance(t, StructT):
            return f"{t.cls_name}()"
        if isinstance(t, FbT):
            return f"{t.cls_name}()"
        if isinstance(t, StdFbT):
            return f"_stdfb({t.name!r})"
        if t.cat in ("ptr", "itf"):
            return "None"
        if init is None:
            return repr(t.default())
        code, vt = self._expr(init, scope)
        return self._to(code, vt, t, init)

    def _fb_member_type(self, t, key, node):
        if isinstance(t, StdFbT):
            return stdfb_member(t, key)[1]
        d = t.var(key)
        return None if d is None else self.types.resolve(d.type, d.pos)

    # ================================================================== statements
    def _stmts(self, stmts, scope: Scope, ind: int, loop: bool = False):
        if any(isinstance(s, ir.Label) for s in stmts):
            self._jump_blocks(stmts, scope, ind, loop)
            return
        for s in stmts:
            self._stmt(s, scope, ind, loop)

    def _jump_blocks(self, stmts, scope: Scope, ind: int, loop: bool):
        """Statements with labels: blocks between labels run in order inside a dispatch
        loop; ``JMP l`` sets the block to resume at and restarts the loop (so backward
        jumps are loops, and counted by the watchdog)."""
        e = self.src.emit
        blocks, labels = [[]], {}
        for s in stmts:
            if isinstance(s, ir.Label):
                labels[ident(s.name)] = len(blocks)
                blocks.append([])
            else:
                blocks[-1].append(s)
        jl = self.src.temp("jl")
        pos = stmts[0].pos
        e(ind, f"{jl} = 0", pos)
        e(ind, "while True:", pos)
        self._count_iteration("JMP", ind + 1, pos)
        saved = self._jump
        self._jump = (labels, jl, self._loop_depth)
        try:
            for k, body in enumerate(blocks):
                e(ind + 1, f"if {jl} <= {k}:", pos)
                self._stmts(body, scope, ind + 2, False)
                e(ind + 2, "pass")
        finally:
            self._jump = saved
        e(ind + 1, "break", pos)

    def _en_eno(self, s, scope: Scope):
        """The IEC EN/ENO of a call (``fb(EN := c, ENO => ok)``, ``x := F(EN := c, a)``) as
        the IF it stands for: run the call only when EN is TRUE, ENO := EN. None when the
        statement has no such call or the callee declares EN/ENO itself."""
        call = s.call if isinstance(s, ir.CallStmt) else \
            s.value if isinstance(s, ir.Assign) and s.op == ":=" else None
        if not isinstance(call, ir.Call):
            return None
        en = [a for a in call.args if (a.name or "").upper() == "EN" and not a.output]
        eno = [a for a in call.args if (a.name or "").upper() == "ENO" and a.output]
        if not (en or eno) or self._declares_en(call.func, scope):
            return None
        rest = ir.Call(call.func, [a for a in call.args if a not in en and a not in eno],
                       pos=call.pos)
        inner = ir.CallStmt(rest, pos=s.pos) if isinstance(s, ir.CallStmt) else \
            ir.Assign(s.target, rest, s.op, pos=s.pos)
        cond = en[0].value if en else ir.Literal(True, "BOOL", pos=s.pos)
        then = [inner] + [ir.Assign(a.value, ir.Literal(True, "BOOL"), ":=", pos=a.pos)
                          for a in eno if a.value is not None]
        other = [ir.Assign(a.value, ir.Literal(False, "BOOL"), ":=", pos=a.pos)
                 for a in eno if a.value is not None]
        return ir.If([(cond, then)], other or None, pos=s.pos)

    def _declares_en(self, func, scope: Scope) -> bool:
        if isinstance(func, ir.Name) and ident(func.name) in self.functions \
                and ident(func.name) not in scope.names:
            return any(ident(d.name) in ("EN", "ENO")
                       for d in self.functions[ident(func.name)].decls())
        try:
            target = self._fb_instance(func, scope)
        except CompileError:
            return False
        if target is None or not isinstance(target[1], FbT):
            return False
        return any(target[1].var(k) is not None for k in ("EN", "ENO"))

    def _stmt(self, s, scope: Scope, ind: int, loop: bool):
        e = self.src.emit
        pos = s.pos
        if isinstance(s, (ir.CallStmt, ir.Assign)):
            desugared = self._en_eno(s, scope)
            if desugared is not None:
                return self._stmt(desugared, scope, ind, loop)
        if isinstance(s, ir.Assign):
            if s.op == "REF=":
                code, t = self._ref_of(s.value, scope)
                self._store(s.target, code, None, scope, ind, pos, raw=True, rebind=True)
            elif s.op in (":=", "S=", "R="):
                expect = None
                if isinstance(s.value, ir.Name) and s.op == ":=":
                    # an enumeration value named by several enumerations is the target's
                    expect = _target_enum(self, s.target, scope)
                code, t = self._expr(s.value, scope, expect)
                if s.op == "S=":
                    e(ind, f"if {code}:", pos)
                    self._store(s.target, "True", BOOL, scope, ind + 1, pos)
                elif s.op == "R=":
                    e(ind, f"if {code}:", pos)
                    self._store(s.target, "False", BOOL, scope, ind + 1, pos)
                else:
                    self._store(s.target, code, t, scope, ind, pos)
            else:
                raise _err(s, f"assignment '{s.op}' is not supported by the executor")
        elif isinstance(s, ir.CallStmt):
            self._call_stmt(s.call, scope, ind)
        elif isinstance(s, ir.If):
            def test(cond):
                code, t = self._expr(cond, scope)
                return self._to(code, t, BOOL, cond)
            self._chain([(lambda c=cond: test(c), body, getattr(cond, "pos", None) or pos)
                         for cond, body in s.branches], s.else_body, scope, ind, pos, loop)
        elif isinstance(s, ir.Try):
            e(ind, "try:", pos)
            self._stmts(s.body, scope, ind + 1, loop)
            e(ind + 1, "pass")
            if s.catch_body is not None:
                x = self.src.temp("x")
                # only what the PLC would raise is caught (a watchdog, or a construct
                # plcpred cannot run, still stops the run)
                e(ind, f"except _plc_exceptions as {x}:", pos)
                e(ind + 1, f"if _exception_code({x}) is None: raise", pos)
                if s.catch_var is not None:
                    self._store(s.catch_var, f"_exception_code({x})", ty.DINT, scope,
                                ind + 1, pos)
                self._stmts(s.catch_body, scope, ind + 1, loop)
                e(ind + 1, "pass")
            if s.finally_body is not None or s.catch_body is None:
                e(ind, "finally:", pos)
                self._stmts(s.finally_body or [], scope, ind + 1, loop)
                e(ind + 1, "pass")
        elif isinstance(s, ir.Case):
            sel, st = self._expr(s.selector, scope)
            tmp = self.src.temp("sel")
            e(ind, f"{tmp} = {sel}", pos)

            def labels(br):
                tests = []
                for lab in br.labels:
                    if isinstance(lab, ir.CaseRange):
                        lo, _ = self._expr(lab.low, scope, expect=st)
                        hi, _ = self._expr(lab.high, scope, expect=st)
                        tests.append(f"{lo} <= {tmp} <= {hi}")
                    else:
                        v, _ = self._expr(lab, scope, expect=st)
                        tests.append(f"{tmp} == {v}")
                return " or ".join(tests)
            self._chain([(lambda b=br: labels(b), br.body, br.pos or pos)
                         for br in s.branches], s.else_body, scope, ind, pos, loop)
        elif isinstance(s, ir.For):
            var = s.target or ir.Name(s.var, pos=pos)
            vcode, vt = self._expr(var, scope)
            start, st0 = self._expr(s.start, scope)
            end, _ = self._expr(s.end, scope)
            step = self._expr(s.step, scope)[0] if s.step is not None else "1"
            r = self.src.temp("r")
            i = self.src.temp("i")
            e(ind, f"{r} = _for_range({start}, {end}, {step})", pos)
            short = _short_for(s)
            if short is not None:
                # literal bounds: the whole loop counted once, as it starts
                self._count_iteration("FOR", ind, pos, short)
            e(ind, f"for {i} in {r}:", pos)
            if short is None:
                # counted like WHILE (an EXIT inside may end it earlier, so the range
                # alone does not decide)
                self._count_iteration("FOR", ind + 1, pos)
            self._store(var, i, ty.ANY_INT, scope, ind + 1, pos, raw=True)
            self._loop_depth += 1
            self._stmts(s.body, scope, ind + 1, True)
            self._loop_depth -= 1
            e(ind + 1, "pass")
            e(ind, "else:", pos)
            self._store(var, f"({r}[-1] + {r}.step if {r} else {start})", ty.ANY_INT, scope,
                        ind + 1, pos)
        elif isinstance(s, (ir.While, ir.Repeat)):
            # REPEAT tests its condition after the body: the first pass always runs, and
            # CONTINUE still reaches the test
            n = self.src.temp("n")
            code, t = self._expr(s.cond, scope)
            cond = self._to(code, t, BOOL, s.cond)
            kind = "WHILE" if isinstance(s, ir.While) else "REPEAT"
            if kind == "WHILE":
                e(ind, f"while {cond}:", pos)
            else:
                e(ind, f"{n} = True", pos)
                e(ind, f"while {n} or not {cond}:", pos)
                e(ind + 1, f"{n} = False", pos)
            self._count_iteration(kind, ind + 1, pos)
            self._loop_depth += 1
            self._stmts(s.body, scope, ind + 1, True)
            self._loop_depth -= 1
            e(ind + 1, "pass")
        elif isinstance(s, ir.Exit):
            if not loop:
                raise _err(s, "EXIT outside a loop")
            e(ind, "break", pos)
        elif isinstance(s, ir.Continue):
            if not loop:
                raise _err(s, "CONTINUE outside a loop")
            e(ind, "continue", pos)
        elif isinstance(s, ir.Return):
            e(ind, scope.ret, pos)
        elif isinstance(s, ir.Empty):
            pass
        elif isinstance(s, ir.Opaque):
            e(ind, f"_opaque({s.what!r}, {_pos_args(pos)})", pos)
        elif isinstance(s, ir.Jmp):
            labels, jl, depth = self._jump or ({}, None, 0)
            if ident(s.label) not in labels:
                raise _err(s, f"JMP {s.label}: no label {s.label} in the same statement list "
                              "(jumps into or out of IF, CASE and loops are not supported)")
            if depth != self._loop_depth:
                raise _err(s, "JMP out of a FOR, WHILE or REPEAT loop is not supported")
            e(ind, f"{jl} = {labels[ident(s.label)]}", pos)
            e(ind, "continue", pos)
        else:  # pragma: no cover - the parser produces no other statements
            raise _err(s, f"unsupported statement {type(s).__name__}")

    # ---------------------------------------------------------------- stores
    def _store(self, target, code: str, vt, scope: Scope, ind: int, pos, raw=False,
               rebind=False):
        """Emit ``target := code`` (converted from ``vt`` unless ``raw``); ``rebind``
        (REF=): a reference target is set to refer elsewhere, not written through."""
        e = self.src.emit
        if isinstance(target, ir.BitAccess):
            bcode, bt = self._expr(target.base, scope)
            _check_bit(target, bt)
            self._store(target.base, f"_setbit({bcode}, {target.bit}, {code})", bt, scope,
                        ind, pos, raw=True)
            return
        kind, a, b, tt = self._lvalue(target, scope)
        value = code if raw else self._to(code, vt, tt, target, copy=True)
        if kind == "name":
            e(ind, f"{a} = {value}", pos)
        elif kind == "attr":
            e(ind, f"{a}.{b} = {value}", pos)
        elif kind == "item":
            e(ind, f"{a}[{b}] = {value}", pos)
        elif kind == "prop":
            e(ind, f"{a}.p_set_{b}({value})", pos)
        elif kind == "deref" and rebind:
            e(ind, f"{a} = {value}", pos)
        elif kind == "deref":
            e(ind, f"{a}.set({value})", pos)

    def _assign_expr(self, x: ir.AssignExpr, scope: Scope):
        """``(target := value)``: the store as an expression that gives the stored value."""
        if isinstance(x.target, ir.BitAccess):
            raise _err(x, "an assignment to a bit inside an expression is not supported")
        tt = self._lvalue(x.target, scope)[3]
        code, vt = self._expr(x.value, scope, tt)
        return self._store_expr(x.target, self._to(code, vt, tt, x.target, copy=True),
                                scope), tt

    def _store_expr(self, target, value: str, scope: Scope) -> str:
        """An expression that stores ``value`` (code of the target's type) in ``target``
        and gives it (an assignment inside an expression; __DELETE clearing a pointer)."""
        kind, a, b, _ = self._lvalue(target, scope)
        if kind == "name":
            return f"({a} := {value})"
        if kind == "attr":
            return f"_Ref({a}, {b!r}).assign({value})"
        if kind == "item":
            return f"_ItemRef({a}, {b}).assign({value})"
        if kind == "deref":
            return f"{a}.assign({value})"
        raise _err(target, "this cannot be assigned to inside an expression")

    def _lvalue(self, target, scope: Scope):
        """('name', code) | ('attr', obj, ATTR) | ('item', list, index) | ('prop', obj, NAME)
        | ('deref', ref), with the target's type."""
        if isinstance(target, ir.DirectAddress):
            target = self._direct(target, scope)
        if isinstance(target, ir.Name):
            key = ident(target.name)
            if key not in scope.names:
                raise _err(target, f"'{target.name}' is not a variable here")
            code, t = scope.names[key]
            if isinstance(t, PtrT) and t.reference and not _is_object_t(t.target):
                return "deref", code, None, t.target
            if "." in code:
                obj, attr = code.rsplit(".", 1)
                return "attr", obj, attr, t
            return "name", code, None, t
        if isinstance(target, ir.Member):
            if isinstance(target.base, ir.Name) and ident(target.base.name) in self.gvl_names:
                return self._lvalue(ir.Name(target.member, pos=target.pos), scope)
            bcode, bt = self._expr(target.base, scope)
            bt = _deref_t(bt)
            key = ident(target.member)
            if isinstance(bt, (FbT, ItfT)):
                if isinstance(bt, FbT) and bt.var(key) is not None:
                    d = bt.var(key)
                    return "attr", bcode, key, self.types.resolve(d.type, d.pos)
                p = bt.prop(key)
                if p is not None:
                    return "prop", bcode, key, self.types.resolve(p[0].type, p[0].pos)
            elif isinstance(bt, StdFbT):
                pin, pt = stdfb_member(bt, key)
                if pin:
                    return "attr", bcode, pin, pt
            elif isinstance(bt, StructT):
                if key in bt.members:
                    return "attr", bcode, key, bt.members[key]
            raise _err(target, f"'{target.member}' is not a member that can be assigned")
        if isinstance(target, ir.Index):
            bcode, bt = self._expr(target.base, scope)
            bt = _deref_t(bt)
            lst, idx, et = self._index(bcode, bt, target, scope)
            return "item", lst, idx, et
        if isinstance(target, ir.Deref):
            code, t = self._expr(target.base, scope)
            if isinstance(t, PtrT) and not _is_object_t(t.target):
                return "deref", code, None, t.target
            raise _err(target, "assignment through a pointer to a structure or function "
                               "block is not supported")
        raise _err(target, "this cannot be assigned to")

    def _index(self, bcode, bt, node: ir.Index, scope):
        """(list code, index code, element type) of the last dimension."""
        if not isinstance(bt, ArrayT):
            raise _err(node, "indexing something that is not an array")
        if len(node.indices) > len(bt.dims):
            raise _err(node, f"{len(node.indices)} indices for an array of {len(bt.dims)} "
                             "dimensions")
        code = bcode
        idx_codes = []
        for (lo, hi), ie in zip(bt.dims, node.indices):
            ic, it = self._expr(ie, scope)
            if isinstance(ie, ir.Literal) and isinstance(ie.value, int):
                if not lo <= ie.value <= hi:
                    raise _err(ie, f"index {ie.value} outside [{lo}..{hi}]")
                idx_codes.append(str(ie.value - lo))
            else:
                ix = self.src.temp("ix")
                idx_codes.append(f"(({ix} - {lo}) if {lo} <= ({ix} := {ic}) <= {hi} else "
                                 f"_chkidx({ix}, {lo}, {hi}, {_describe(node.base)!r}))")
        for ic in idx_codes[:-1]:
            code = f"{code}[{ic}]"
        n = len(node.indices)
        et = bt.elem if n == len(bt.dims) else ArrayT(bt.dims[n:], bt.elem)
        return code, idx_codes[-1], et

    # ---------------------------------------------------------------- calls (statements)
    def _call_stmt(self, call: ir.Call, scope: Scope, ind: int):
        e = self.src.emit
        f = call.func
        pos = call.pos
        if isinstance(f, ir.Deref) and isinstance(f.base, ir.Name) \
                and ident(f.base.name) == "SUPER":
            if scope.fb is None or scope.fb.base is None:
                raise _err(call, "SUPER^() outside a function block that EXTENDS another")
            e(ind, f"{scope.fb.base.cls_name}._body(self)", pos)
            return
        target = self._fb_instance(f, scope)
        if target is not None:
            code, t = target
            self._fb_call(code, t, call, scope, ind)
            return
        action = self._action_of(f, scope) if call.args else None
        if action is not None:
            # inst.Act(in := x, out => y): the instance's inputs and outputs, as in a
            # call of the instance, around the action instead of the body (CODESYS and
            # TwinCAT; Beckhoff's FB_MemRingBuffer is driven so)
            code, t, key = action
            self._fb_call(code, t, call, scope, ind, body=f"a_{key}()")
            return
        code, t = self._expr(call, scope)
        e(ind, code, pos)

    def _action_of(self, f, scope):
        """(instance code, FB type, action key) when ``f`` names an action of a function
        block instance (``inst.Act``, or ``Act`` inside the FB), else None."""
        if isinstance(f, ir.Name):
            key = ident(f.name)
            if scope.fb is not None and key not in scope.names \
                    and scope.fb.action(key) is not None:
                return "self", scope.fb, key
            return None
        if not isinstance(f, ir.Member):
            return None
        target = self._fb_instance(f.base, scope)
        if target is None or not isinstance(target[1], FbT):
            return None
        key = ident(f.member)
        if target[1].action(key) is None or target[1].method(key) is not None:
            return None
        return target[0], target[1], key

    def _fb_instance(self, f, scope):
        """(code, type) when ``f`` names a function block instance, else None."""
        if isinstance(f, ir.Name) and ident(f.name) not in scope.names:
            return None
        if isinstance(f, ir.Name) and ident(f.name) in scope.pylocals and \
                scope.names[ident(f.name)][1].cat not in ("fb", "stdfb", "ptr", "itf"):
            return None
        try:
            code, t = self._expr(f, scope, callee=True)
        except CompileError:
            return None
        t = _deref_t(t)
        if isinstance(t, (FbT, StdFbT)):
            return code, t
        return None

    def _fb_call(self, code: str, t, call: ir.Call, scope: Scope, ind: int,
                 body: str = "_body()"):
        e = self.src.emit
        pos = call.pos
        f = self.src.temp("f")
        e(ind, f"{f} = {code}", pos)
        if isinstance(t, StdFbT):
            ins, outs = STANDARD_FBS[t.name]
            inouts = ()
            mtype = lambda k: _STDFB_MEMBERS[k]  # noqa: E731
        else:
            ins = [ident(d.name) for x in reversed(list(t.chain()))
                   for d in x.pou.decls("VAR_INPUT")]
            inouts = [ident(d.name) for x in reversed(list(t.chain()))
                      for d in x.pou.decls("VAR_IN_OUT")]
            outs = [ident(d.name) for x in reversed(list(t.chain()))
                    for d in x.pou.decls("VAR_OUTPUT")]

            def mtype(k):
                d = t.var(k)
                return self.types.resolve(d.type, d.pos)
        post = []
        positional = list(ins) + list(inouts)
        for k, arg in enumerate(call.args):
            if arg.name is None:
                if arg.output or k >= len(positional):
                    raise _err(arg, "too many arguments")
                name = positional[k]
            elif isinstance(t, StdFbT):
                name = std_fb_pin(t.name, arg.name) or ident(arg.name)
            else:
                name = ident(arg.name)
            if arg.output:
                if name not in outs and name not in ins:
                    raise _err(arg, f"'{arg.name}' is not an output of {t.name}")
                value = f"(not {f}.{name})" if arg.negated else f"{f}.{name}"
                if arg.value is not None:
                    post.append((arg.value, value, BOOL if arg.negated else mtype(name)))
                continue
            if name in inouts:
                self._referenced(arg.value)         # copied back after the call
                vcode, vt = self._expr(arg.value, scope)
                e(ind, f"{f}.{name} = {vcode}", arg.pos or pos)
                if not _is_object_t(vt):
                    post.append((arg.value, f"{f}.{name}", mtype(name)))
                continue
            if name not in ins:
                raise _err(arg, f"'{arg.name}' is not an input of {t.name}")
            vcode, vt = self._expr(arg.value, scope)
            value = self._to(vcode, vt, mtype(name), arg.value, copy=True)
            edge = t.var(name).edge if isinstance(t, FbT) else None
            if edge:   # the input is TRUE in the call where the value rose (fell)
                v = self.src.temp("v")
                e(ind, f"{v} = {value}", arg.pos or pos)
                seen = f"{v} and not {f}._e_{name}" if edge == "R_EDGE" else \
                    f"not {v} and {f}._e_{name}"
                e(ind, f"{f}._e_{name}, {f}.{name} = {v}, ({seen})", arg.pos or pos)
            else:
                e(ind, f"{f}.{name} = {value}", arg.pos or pos)
        if isinstance(t, StdFbT):
            e(ind, f"{f}.execute(_now)", pos)
        else:
            e(ind, f"{f}.{body}", pos)
        for target, value, vt in post:
            self._store(target, value, vt, scope, ind, pos)

    # ================================================================== expressions
    def _expr(self, x, scope: Scope, expect=None, callee=False):
        """(Python code, type) of an expression."""
        if isinstance(x, ir.Literal):
            return self._literal(x, expect)
        if isinstance(x, ir.EnumLiteral):
            t = self.types.named(x.type_name, x.pos)
            if not isinstance(t, EnumT) or x.value.upper() not in t.values:
                raise _err(x, f"'{x.value}' is not a value of {x.type_name}")
            return str(t.values[x.value.upper()]), t
        if isinstance(x, ir.Name):
            return self._name(x, scope, expect)
        if isinstance(x, ir.Member):
            return self._member(x, scope)
        if isinstance(x, ir.Index):
            bcode, bt = self._expr(x.base, scope)
            lst, idx, et = self._index(bcode, _deref_t(bt), x, scope)
            return f"{lst}[{idx}]", et
        if isinstance(x, ir.BitAccess):
            code, t = self._expr(x.base, scope)
            _check_bit(x, t)
            return f"_getbit({code}, {x.bit})", BOOL
        if isinstance(x, ir.AssignExpr):
            return self._assign_expr(x, scope)
        if isinstance(x, ir.Deref):
            if isinstance(x.base, ir.Name) and ident(x.base.name) == "THIS":
                if scope.fb is None:
                    raise _err(x, "THIS^ outside a function block")
                return "self", scope.fb
            code, t = self._expr(x.base, scope)
            if not isinstance(t, PtrT):
                raise _err(x, "'^' applied to something that is not a pointer")
            if _is_object_t(t.target):
                return code, t.target
            return f"{code}.get()", t.target
        if isinstance(x, ir.Unary):
            code, t = self._expr(x.operand, scope, expect)
            if x.op == "-":
                return f"(-{code})", t
            if x.op == "+":
                return code, t
            if t.cat == "bool":
                return f"(not {code})", BOOL
            if t.cat == "int" and getattr(t, "bits", 0) and not t.signed:
                return f"({code} ^ {(1 << t.bits) - 1})", t
            return f"(~{code})", t
        if isinstance(x, ir.Binary):
            return self._binary(x, scope, expect)
        if isinstance(x, ir.Call):
            return self._call_expr(x, scope)
        if isinstance(x, ir.DirectAddress):
            return self._name(self._direct(x, scope), scope, expect)
        raise _err(x, f"unsupported expression {type(x).__name__}")

    def _literal(self, x: ir.Literal, expect):
        v, tn = x.value, ident(x.type_name)
        if tn == "BOOL":
            return ("True" if v else "False"), BOOL
        if tn == "ANY_INT":
            if expect is not None and expect.cat == "real":
                return repr(float(v)), ty.ANY_REAL
            return repr(int(v)), ty.ANY_INT
        if tn == "ANY_REAL":
            return repr(float(v)), ty.ANY_REAL
        if tn in ("STRING", "WSTRING", "CHAR", "WCHAR"):
            return repr(v), STRING
        t = ty.elementary(tn) or self.types.named(tn, x.pos)
        if isinstance(t, EnumT):
            return str(v), t
        if t.cat == "real":
            return repr(float(v)), t
        return repr(int(v) if not isinstance(v, bool) else bool(v)), t

    def _name(self, x: ir.Name, scope: Scope, expect=None):
        key = ident(x.name)
        if key in scope.names:
            code, t = scope.names[key]
            if isinstance(t, PtrT) and t.reference:
                return (code, t.target) if _is_object_t(t.target) else (f"{code}.get()",
                                                                        t.target)
            return code, t
        if key in scope.steps:
            raise _err(x, f"step {x.name} used as a value: use {x.name}.X or {x.name}.T")
        if isinstance(expect, EnumT) and key in expect.values:
            return str(expect.values[key]), expect
        cands = self.types.enum_candidates(key)
        if cands:
            t, v = cands[0]
            return str(v), t
        if key in ("TRUE", "FALSE"):
            return ("True" if key == "TRUE" else "False"), BOOL
        if key == "NULL":  # CODESYS/TwinCAT: the null pointer
            return "None", PtrT(ty.elementary("BYTE"))
        raise _err(x, f"'{x.name}' is not declared here")

    def _member(self, x: ir.Member, scope: Scope):
        key = ident(x.member)
        base = x.base
        if isinstance(base, ir.Name):
            bkey = ident(base.name)
            if bkey in scope.steps and bkey not in scope.names:
                i = scope.steps[bkey]
                if key == "X":
                    return f"self._sfc.x[{i}]", BOOL
                if key == "T":
                    return f"self._sfc.t({i}, _now)", TIME
                raise _err(x, f"a step has .X and .T, not .{x.member}")
            if bkey not in scope.names:
                try:
                    t = self.types.named(base.name)
                except ProgramError:
                    t = None
                if isinstance(t, EnumT):
                    if key not in t.values:
                        raise _err(x, f"'{x.member}' is not a value of {base.name}")
                    return str(t.values[key]), t
                if bkey in self.gvl_names:
                    return self._name(ir.Name(x.member, pos=x.pos), scope)
        bcode, bt = self._expr(base, scope)
        bt = _deref_t(bt)
        if isinstance(bt, StdFbT):
            key, pt = stdfb_member(bt, key)
            if key is None:
                raise _err(x, f"{bt.name} has no member '{x.member}'")
            if key == "ET" and not self._et_const:
                # inside an FB or PROGRAM the data flow decides whether it matters
                # (_sinks); elsewhere assume it does
                if scope.fb is None:
                    self.reads_et = True
                else:
                    self._et_classes.add(scope.fb.name)
            return f"{bcode}.{key}", pt
        if isinstance(bt, StructT):
            if key not in bt.members:
                raise _err(x, f"{bt.name} has no member '{x.member}'")
            return f"{bcode}.{key}", bt.members[key]
        if isinstance(bt, (FbT, ItfT)):
            if isinstance(bt, FbT):
                d = bt.var(key)
                if d is not None:
                    return f"{bcode}.{key}", self.types.resolve(d.type, d.pos)
            p = bt.prop(key)
            if p is not None:
                return f"{bcode}.p_get_{key}()", self.types.resolve(p[0].type, p[0].pos)
            raise _err(x, f"{bt.name} has no variable or property '{x.member}'")
        if bt.cat == "int" and re.fullmatch(r"[0-9]{1,3}", x.member):
            why = ty.bit_access_error(bt, int(x.member))
            if why is not None:
                raise _err(x, why)
            return f"_getbit({bcode}, {int(x.member)})", BOOL
        raise _err(x, f"'.{x.member}' applied to a value of type {getattr(bt, 'name', bt)}")

    def _binary(self, x: ir.Binary, scope: Scope, expect):
        op = x.op
        threshold = self._et_compare(x)
        if threshold is not None:
            # the comparison can only flip when ET crosses the constant: an event
            self.et_thresholds.add(threshold)
            self._et_const = True
        try:
            lc, lt = self._expr(x.left, scope, expect if op not in _CMP else None)
            rc, rt = self._expr(x.right, scope, lt if isinstance(lt, EnumT) or lt.cat == "real"
                                else expect if op not in _CMP else None)
        finally:
            self._et_const = False
        if lt.cat == "int" and rt.cat == "real" and isinstance(x.left, ir.Literal):
            lc = repr(float(lc))
        if (lt.cat == "string") != (rt.cat == "string") and "void" not in (lt.cat, rt.cat):
            raise _err(x, f"'{op}' between {getattr(lt, 'name', lt.cat)} and "
                          f"{getattr(rt, 'name', rt.cat)}: convert one of them first")
        if op in ("=", "<>") and _is_null_test(lt, rt, x):
            # a pointer, reference or interface against 0: CODESYS' test for NULL
            side = lc if lt.cat in ("ptr", "itf") else rc
            return f"({side} {'is' if op == '=' else 'is not'} None)", BOOL
        if op in _CMP:
            return f"({lc} {_CMP[op]} {rc})", BOOL
        if op in ("AND", "AND_THEN", "OR", "OR_ELSE", "XOR", "&"):
            if {lt.cat, rt.cat} - {"bool", "int"} or (lt.cat == "bool") != (rt.cat == "bool"):
                raise _err(x, f"{op} needs two BOOL or two bit-string/integer operands, not "
                              f"{getattr(lt, 'name', lt.cat)} and {getattr(rt, 'name', rt.cat)}")
            op = "AND" if op == "&" else op
            if lt.cat == "bool" and rt.cat == "bool":
                if op == "XOR":
                    return f"({lc} != {rc})", BOOL
                py = "and" if op.startswith("AND") else "or"
                return f"({lc} {py} {rc})", BOOL
            py = "&" if op.startswith("AND") else "|" if op.startswith("OR") else "^"
            return f"({lc} {py} {rc})", _wider(lt, rt)
        cats = {lt.cat, rt.cat}
        if cats & {"time", "date"}:
            if op in ("+", "-"):
                if lt.cat == "date" and rt.cat == "date":
                    return f"({lc} - {rc})", TIME
                return f"({lc} {op} {rc})", lt if lt.cat in ("time", "date") else rt
            if op == "*":
                if lt.cat == "time":
                    return f"_tmul({lc}, {rc})", lt
                return f"_tmul({rc}, {lc})", rt
            if op == "/":
                if rt.cat == "time":
                    return f"_idiv({lc}, {rc})", ty.DINT
                return f"_tdiv({lc}, {rc})", lt
            if op == "MOD":
                return f"_imod({lc}, {rc})", lt
            raise _err(x, f"'{op}' on TIME values")
        if "string" in cats:
            if op == "+":
                return f"({lc} + {rc})", STRING
            raise _err(x, f"'{op}' on strings")
        if op == "**":
            return f"_expt({lc}, {rc})", ty.REAL
        if "real" in cats:
            t = lt if lt.cat == "real" and lt is not ty.ANY_REAL else (
                rt if rt.cat == "real" else lt)
            if op == "/":
                return f"_fdiv({lc}, {rc})", t
            if op == "MOD":
                return f"_fmod({lc}, {rc})", t
            return f"({lc} {op} {rc})", t
        t = _wider(lt, rt)
        if op == "/":
            return f"_idiv({lc}, {rc})", t
        if op == "MOD":
            return f"_imod({lc}, {rc})", t
        return f"({lc} {op} {rc})", t

    # ---------------------------------------------------------------- calls (expressions)
    def _call_expr(self, call: ir.Call, scope: Scope):
        en = [a for a in call.args if (a.name or "").upper() == "EN" and not a.output]
        eno = [a for a in call.args if (a.name or "").upper() == "ENO" and a.output]
        if (en or eno) and not self._declares_en(call.func, scope):
            # the implicit EN of a call inside an expression (OSCAT: T_PLC_MS(en := TRUE))
            if eno:
                raise _err(eno[0], "ENO of a call inside an expression is not supported: "
                                   "call it as a statement, or assign its result")
            code, t = self._call_expr(ir.Call(call.func, [a for a in call.args
                                                          if a not in en], pos=call.pos),
                                      scope)
            cond = en[0].value
            if isinstance(cond, ir.Literal) and cond.value is True:
                return code, t
            if _is_object_t(t) or t.cat == "void":
                raise _err(en[0], "EN of this call inside an expression is not supported: "
                                  "call it as a statement")
            ccode, _ = self._expr(cond, scope)
            # not run: the value the result type starts with
            return f"({code} if {ccode} else {t.default()!r})", t
        f = call.func
        if isinstance(f, ir.Name):
            key = ident(f.name)
            if key in self.functions and key not in scope.names:
                return self._user_function(self.functions[key], call, scope)
            if scope.fb is not None and scope.fb.action(key) is not None \
                    and key not in scope.names:
                return "self.a_" + key + "()", ty.VOID
            if scope.fb is not None and scope.fb.method(key) is not None \
                    and key not in scope.names:
                # a method of the FB (or one it inherits) by bare name, as THIS^.name
                this = ir.Member(ir.Deref(ir.Name("THIS", pos=f.pos), pos=f.pos), f.name,
                                 pos=f.pos)
                return self._call_expr(ir.Call(this, call.args, pos=call.pos), scope)
            if is_standard_function(key) and key not in scope.names:
                return self._std_function(key, call, scope)
            if key in scope.names:
                raise _err(call, f"{f.name} is a function block instance: call it as a "
                                 "statement, then read its outputs")
            raise _err(call, f"unknown function '{f.name}'")
        if isinstance(f, ir.Member):
            key = ident(f.member)
            if isinstance(f.base, ir.Deref) and isinstance(f.base.base, ir.Name) and \
                    ident(f.base.base.name) == "SUPER":
                if scope.fb is None or scope.fb.base is None:
                    raise _err(call, "SUPER^ outside a function block that EXTENDS another")
                m = scope.fb.base.method(key)
                if m is None:
                    raise _err(call, f"{scope.fb.base.name} has no method {f.member}")
                return self._boxed(lambda: f"{scope.fb.base.cls_name}.m_{key}(self, "
                                   f"{self._named_args(m[0].var_blocks, call, scope, f.member)})"
                                   ), self._ret_t(m[0])
            bcode, bt = self._expr(f.base, scope)
            bt = _deref_t(bt)
            if isinstance(bt, (FbT, ItfT)):
                m = bt.method(key)
                if m is not None:
                    return self._boxed(lambda: f"{bcode}.m_{key}("
                                       f"{self._named_args(m[0].var_blocks, call, scope, f.member)})"
                                       ), self._ret_t(m[0])
                if isinstance(bt, FbT) and bt.action(key) is not None:
                    return f"{bcode}.a_{key}()", ty.VOID
            raise _err(call, f"'{f.member}' is not a method of {getattr(bt, 'name', '?')}")
        raise _err(call, "this cannot be called in an expression")

    def _ret_t(self, m):
        return self.types.resolve(m.return_type, m.pos) if m.return_type else ty.VOID

    def _named_args(self, var_blocks, call: ir.Call, scope: Scope, what: str) -> str:
        ins, ios = [], []
        for b in var_blocks:
            for d in b.decls:
                if b.kind == "VAR_INPUT":
                    ins.append(d)
                elif b.kind in ("VAR_IN_OUT", "VAR_OUTPUT"):
                    ios.append((b.kind, d))
        positional = ins + [d for k, d in ios if k == "VAR_IN_OUT"]
        by_name = {ident(d.name): d for d in ins}
        io_names = {ident(d.name): d for k, d in ios}
        parts = []
        for k, arg in enumerate(call.args):
            if arg.name is None:
                if k >= len(positional):
                    raise _err(arg, f"too many arguments for {what}")
                d = positional[k]
            else:
                d = by_name.get(ident(arg.name)) or io_names.get(ident(arg.name))
                if d is None:
                    raise _err(arg, f"{what} has no parameter '{arg.name}'")
            key = ident(d.name)
            if key in by_name and not arg.output:
                vcode, vt = self._expr(arg.value, scope)
                t = self.types.resolve(d.type, d.pos)
                parts.append(f"{key}={self._to(vcode, vt, t, arg.value)}")
            elif arg.value is not None:
                if arg.negated:
                    raise _err(arg, "a negated output binding of a function is not supported")
                rcode, _ = self._ref_of(arg.value, scope, for_call=True)
                parts.append(f"_r_{key}={rcode}")
        return ", ".join(parts)

    def _user_function(self, fn: ir.Pou, call: ir.Call, scope: Scope):
        rt = self.types.resolve(fn.return_type, fn.pos) if fn.return_type else ty.VOID
        code = self._boxed(lambda: f"_fn_{ident(fn.name)}("
                           f"{self._named_args(fn.var_blocks, call, scope, fn.name)})")
        return code, rt

    def _boxed(self, make) -> str:
        """A call whose by-reference arguments include Python locals: box them, call, and
        write them back (``make`` builds the call and may register boxes)."""
        saved, self._boxes = getattr(self, "_boxes", None), []
        try:
            code = make()
            boxes = self._boxes
        finally:
            self._boxes = saved
        if not boxes:
            return code
        res = self.src.temp("res")
        pre = ", ".join(f"({b} := _Box({n}))" for b, n in boxes)
        post = ", ".join(f"({n} := {b}.v)" for b, n in boxes)
        return f"({pre}, ({res} := {code}), {post}, {res})[-1]"

    def _ref_of(self, x, scope: Scope, for_call=False):
        """Code for a reference to ``x`` (ADR, REF=, VAR_IN_OUT and outputs of calls)."""
        self._referenced(x)
        if isinstance(x, ir.Name) and ident(x.name) in scope.names:
            code, t = scope.names[ident(x.name)]
            if isinstance(t, PtrT) and t.reference:
                # a reference variable refers on to what it refers to (r2 REF= r1)
                return code, t
        if isinstance(x, ir.Name) and ident(x.name) in scope.pylocals:
            key = ident(x.name)
            t = scope.names[key][1]
            if _is_object_t(t):
                return key, PtrT(t)
            if not for_call:
                raise _err(x, f"a reference to the local variable {x.name} of a function "
                              "or method is not supported")
            if getattr(self, "_boxes", None) is None:
                raise _err(x, "a reference to a local variable is only possible as a call "
                              "argument")
            box = self.src.temp("box")
            self._boxes.append((box, key))
            return box, PtrT(t)
        code, t = self._expr(x, scope)
        if _is_object_t(t):
            return code, PtrT(t)
        if isinstance(x, ir.Index):
            bcode, bt = self._expr(x.base, scope)
            lst, idx, et = self._index(bcode, _deref_t(bt), x, scope)
            return f"_ItemRef({lst}, {idx})", PtrT(et)
        if isinstance(x, (ir.Name, ir.Member)) and "." in code and code.rsplit(".", 1)[
                1].isidentifier() and not code.endswith(")"):
            obj, attr = code.rsplit(".", 1)
            return f"_Ref({obj}, {attr!r})", PtrT(t)
        raise _err(x, "a reference needs a variable here")

    def _referenced(self, x) -> None:
        """Record that ``x`` may be written through a reference to it."""
        if self.referenced is not None and not _target_names(x, self.referenced):
            self.referenced = None

    def _std_function(self, key: str, call: ir.Call, scope: Scope):
        key = WIDE_STRING_FUNCTIONS.get(key, key)     # WLEN is LEN on a WSTRING
        args = [a for a in call.args if not a.output]
        if key == "__NEW":
            return self._new(call, args, scope)
        if key == "XSIZEOF":            # TwinCAT: SIZEOF as a platform-wide integer
            key = "SIZEOF"
        if key == "SIZEOF" and len(args) == 1 and isinstance(args[0].value, ir.TypeExpr):
            spec = args[0].value.type
            if isinstance(spec, ir.StringType) and isinstance(spec.length, ir.Literal) \
                    and isinstance(spec.length.value, int):
                # SIZEOF(STRING(10)): the characters and the terminator
                return str((spec.length.value + 1) * (2 if spec.wide else 1)), ty.DINT
            size = ty.byte_size(self.types.resolve(spec, args[0].value.pos))
            if size is None:
                raise _err(call, "SIZEOF of this type is not known to the executor")
            return str(size), ty.DINT
        if key == "__ISVALIDREF":
            # a reference (or pointer, interface) that refers to something: not NULL
            if len(args) != 1:
                raise _err(call, "__ISVALIDREF needs one argument: a reference")
            x = args[0].value
            if isinstance(x, ir.Name) and ident(x.name) in scope.names:
                code, t = scope.names[ident(x.name)]
                if t.cat in ("ptr", "itf"):     # the reference itself, not what it refers to
                    return f"({code} is not None)", BOOL
            return self._expr(ir.Binary("<>", args[0].value,
                                        ir.Literal(0, "ANY_INT", pos=call.pos),
                                        pos=call.pos), scope)
        if key == "__DELETE":
            # the memory goes with the last pointer to it; the pointer itself reads 0
            if len(args) != 1:
                raise _err(call, "__DELETE needs one argument: the pointer __NEW gave")
            if isinstance(args[0].value, ir.Name) and ident(args[0].value.name) == "THIS" \
                    and scope.fb is not None:
                # an instance deleting itself: it goes with the last pointer to it
                return "None", ty.VOID
            code, t = self._expr(args[0].value, scope)
            if t.cat != "ptr":
                raise _err(call, "__DELETE needs a pointer (what __NEW gave)")
            self._referenced(args[0].value)
            return self._store_expr(args[0].value, "None", scope), ty.VOID
        vals = [self._expr(a.value, scope) for a in args]
        codes = [c for c, _ in vals]
        ts = [t for _, t in vals]
        first = next((t for t in ts if t not in (ty.ANY_INT, ty.ANY_REAL)),
                     ts[0] if ts else ty.ANY_INT)

        def need(n):
            if len(vals) < n:
                raise _err(call, f"{key} needs {n} argument{'s' if n > 1 else ''}")
        m = _CONV.match(key)
        if m or key.startswith("TRUNC") or "_TRUNC_" in key:
            need(1)
            if key == "TRUNC" or key.startswith("TRUNC_") or "_TRUNC_" in key:
                dst = key.split("_")[-1] if "_" in key else "DINT"
                t = ty.elementary(dst) or ty.DINT
                return f"_wrap(int({codes[0]}), {t.bits or 32}, {t.signed})", t
            dst = m.group(2)
            t = ty.elementary(dst)
            if t is None:
                raise _err(call, f"unknown conversion {key}")
            src = ts[0].cat if ts[0].cat in ("bool", "int", "real", "time", "string") else (
                "time" if ts[0].cat == "date" else "int")
            if getattr(ts[0], "name", "") in ("CHAR", "WCHAR") and t.cat == "int":
                src = "char"          # a character's code, not its text read as a number
            # DT_TO_UDINT counts seconds, TIME_TO_UDINT milliseconds, LTIME nanoseconds
            unit = ty.ns_per_count(ts[0].name) if ts[0].cat in ("time", "date") else (
                ty.ns_per_count(t.name))
            if t.cat == "int":
                return f"_to_int({codes[0]}, {t.bits}, {t.signed}, {src!r}, {unit})", t
            if t.cat == "real":
                return f"_to_real({codes[0]}, {src!r}, {unit})", t
            if t.cat in ("time", "date"):
                return f"_to_time({codes[0]}, {src!r}, {unit})", t
            if t.cat == "bool":
                return f"_to_bool({codes[0]}, {src!r})", BOOL
            if dst in ("CHAR", "WCHAR"):
                return f"_to_string({codes[0]}, {src!r}, True)", t
            return f"_to_string({codes[0]}, {src!r})", STRING
        if key in ("MIN", "MAX"):
            need(1)
            return f"{key.lower()}({', '.join(codes)})", first
        if key == "LIMIT":
            need(3)
            return f"_limit({', '.join(codes)})", first
        if key == "SEL":
            need(3)
            return f"_sel({', '.join(codes)})", _wider(ts[1], ts[2])
        if key == "MUX":
            need(2)
            return f"_mux({', '.join(codes)})", ts[1]
        if key == "MOVE":
            need(1)
            return codes[0], ts[0]
        if key in ("SHL", "SHR", "ROL", "ROR"):
            need(2)
            bits = getattr(ts[0], "bits", 0) or 32
            return f"_{key.lower()}({codes[0]}, {codes[1]}, {bits})", ts[0]
        if key == "ABS":
            need(1)
            return f"abs({codes[0]})", ts[0]
        if key in ("SQRT", "LN", "LOG", "EXP", "SIN", "COS", "TAN", "ASIN", "ACOS", "ATAN",
                   "ATAN2", "EXPT"):
            need(2 if key in ("ATAN2", "EXPT") else 1)
            return f"_math[{key!r}]({', '.join(codes)})", ty.REAL
        if key in ("ADD", "MUL", "AND", "OR", "XOR") and len(args) >= 2:
            op = {"ADD": "+", "MUL": "*"}.get(key, key)
            e = args[0].value
            for a in args[1:]:
                e = ir.Binary(op, e, a.value, pos=call.pos)
            return self._expr(e, scope)
        binops = {"SUB": "-", "DIV": "/", "MOD": "MOD", "GT": ">", "GE": ">=", "EQ": "=",
                  "LE": "<=", "LT": "<", "NE": "<>"}
        if key in binops:
            need(2)
            return self._expr(ir.Binary(binops[key], args[0].value, args[1].value,
                                        pos=call.pos), scope)
        if key == "NOT":
            need(1)
            return self._expr(ir.Unary("NOT", args[0].value, pos=call.pos), scope)
        if key == "LEN":
            need(1)
            return f"len({codes[0]})", ty.Elem("INT", "int", 16, True)
        if key in ("LEFT", "RIGHT", "MID", "INSERT", "DELETE", "REPLACE"):
            n = {"LEFT": 2, "RIGHT": 2, "MID": 3, "INSERT": 3, "DELETE": 3, "REPLACE": 4}[key]
            need(n)
            return f"_{key.lower()}({', '.join(codes)})", STRING
        if key == "FIND":
            need(2)
            return f"_find({codes[0]}, {codes[1]})", ty.Elem("INT", "int", 16, True)
        if key == "CONCAT":
            return "(" + " + ".join(codes or ["''"]) + ")", STRING
        if key in ("ADR", "REF"):
            need(1)
            return self._ref_of(args[0].value, scope)
        if key == "__POUNAME":
            return repr(scope.pou), STRING
        if key in ("TIME", "NOW") and not args:
            self.reads_clock = True
            return "_now", TIME
        if key == "SIZEOF":
            need(1)
            size = ty.byte_size(ts[0])
            if size is not None:
                return str(size), ty.DINT
            return f"_sizeof({codes[0]})", ty.DINT
        if key in ("MEMCPY", "MEMMOVE", "MEMSET", "MEMCMP"):
            need(3)
            where = _pos_args(call.pos)
            fn = "_memcpy" if key in ("MEMCPY", "MEMMOVE") else "_" + key.lower()
            return f"{fn}({', '.join(codes[:3])}, {where})", \
                ty.DINT if key == "MEMCMP" else ty.elementary("UDINT")
        raise _err(call, f"standard function {key} is not supported by the executor")

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
            raise _err(call, "__NEW needs a type: __NEW(INT), __NEW(ST_Data), "
                             "__NEW(FB_T(a := 1))")
        if len(args) > 1:
            # kept: only running it is an error, at its place (check warns)
            what = "__NEW with a count (an array reached through pointer arithmetic)"
            why = "plcpred has no pointer arithmetic"
            return f"_opaque({what!r}, {_pos_args(call.pos)}, {why!r})", PtrT(t)
        one = self._init(t, None, scope, None)
        if isinstance(t, FbT):
            if init_args and not _fb_inits(t):
                raise _err(first, f"{t.name} has no FB_init method for these arguments")
            if _fb_inits(t):
                tmp = self.src.temp("new")
                decl = ir.VarDecl("new", ir.NamedType(t.name), init_args=init_args,
                                  pos=call.pos)
                calls = self._fb_init_code(tmp, t, decl, scope)
                return f"({tmp} := {one}, {', '.join(calls)}, {tmp})[-1]", PtrT(t)
        if _is_object_t(t):
            return one, PtrT(t)
        return f"_Box({one})", PtrT(t)

    # ---------------------------------------------------------------- conversions
    def _to(self, code: str, vt, tt, node, copy=False) -> str:
        """``code`` of type ``vt`` converted for storing into type ``tt``."""
        if tt is None or vt is None or tt.cat in ("void",):
            return code
        if _is_object_t(tt):
            return f"_copy({code})" if copy and _is_object_t(vt) else code
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
                raise _err(node, f"cannot use a {name} value as BOOL")
            raise _err(node, f"cannot store a {name} value in {tt.name}")
        return template.format(code=code, bits=getattr(tt, "bits", 0),
                               signed=getattr(tt, "signed", True))


# ---------------------------------------------------------------------- helpers

def _name_uses(root, names: set) -> list:
    """(upper-case name, node, parent) of every ``ir.Name`` in ``root`` whose name is in
    ``names``."""
    return [(x.name.upper(), x, parent) for x, parent in ir.nodes(root)
            if isinstance(x, ir.Name) and x.name.upper() in names]


def _constant_block(b) -> bool:
    return "CONSTANT" in [q.upper() for q in b.qualifiers]


def _target_names(e, out: set) -> bool:
    """Add to ``out`` the names along write target ``e`` (``a.b[i].c``: A, B and C);
    False when the target is not reached by names (a pointer, an address: %IX0.0 may be
    an input)."""
    while isinstance(e, (ir.Member, ir.Index, ir.BitAccess)):
        if isinstance(e, ir.Member):
            out.add(e.member.upper())
        e = e.base
    if isinstance(e, ir.Name):
        out.add(e.name.upper())
        return True
    return False


def written_names(program: ir.Program) -> set | None:
    """Every name the program may write by name, upper case: the variables and members
    along each assignment target (``a.b[i].c := x`` writes A, B and C), output bindings,
    FOR variables. None when a write goes where names cannot tell (through a pointer, to
    an address). What a call writes through VAR_IN_OUT and what ADR/REF hand out the
    compiler adds as it compiles them (``Compiled.written``). Conservative: for deciding
    what the program can never change (the inputs the executor writes need not be
    written again each scan)."""
    out: set = set()

    def target(e) -> bool:
        return _target_names(e, out)

    stack = [program.pous, program.configurations, program.globals]
    while stack:
        x = stack.pop()
        if isinstance(x, (list, tuple)):
            stack.extend(x)
            continue
        if not hasattr(x, "__dataclass_fields__"):
            continue
        if isinstance(x, (ir.Assign, ir.AssignExpr)) and not target(x.target):
            return None
        if isinstance(x, ir.Assign) and x.op == "REF=" and not target(x.value):
            return None         # a reference to it: written through the reference
        if isinstance(x, ir.Try) and x.catch_var is not None and not target(x.catch_var):
            return None
        if isinstance(x, ir.For):
            out.add(x.var.upper())
            if x.target is not None and not target(x.target):
                return None
        if isinstance(x, ir.Call):
            for a in x.args:
                if a.output and a.value is not None and not target(a.value):
                    return None
        stack.extend(getattr(x, f) for f in x.__dataclass_fields__ if f != "pos")
    return out


def _root(e):
    while isinstance(e, (ir.Member, ir.Index, ir.BitAccess)):
        e = e.base
    return ident(e.name) if isinstance(e, ir.Name) else None


def _unread(cands: set, flow) -> set:
    """The candidates whose values reach nothing that ``flow`` uses, directly or through
    other variables."""
    sinks = cands - flow.used
    changed = True
    while changed:
        changed = False
        for target, reads in flow.flows:
            if target is None or target not in sinks:
                if reads & sinks:
                    sinks -= reads
                    changed = True
    return sinks


class _Flow:
    """Where each variable's value goes: ``flows`` (assignment target, names read) and
    ``used`` (names read by conditions, calls, indices and anything else that can steer
    the program)."""

    def __init__(self, impure=frozenset(), std_fbs=frozenset(), et_compare=lambda x: None):
        self.flows: list[tuple[str | None, set]] = []
        self.used: set = set()
        self.impure = impure  # user functions that reach globals (VAR_EXTERNAL)
        self.std_fbs = std_fbs  # standard FB instances (pure: they only set their outputs)
        self.et_compare = et_compare
        self.et_targets: set = set()  # where timers' ET values go (None: steers the program)
        self._et = False
        # writes of the form x := x + e / x := e + x / x := x - e: x -> (how many, the
        # names the e read); a target of as many flows is written in no other way
        self.steps: dict[str, tuple[int, set]] = {}

    def reads(self, e) -> set:
        out = set()

        def walk(x):
            if isinstance(x, ir.Binary) and self.et_compare(x) is not None:
                for side in (x.left, x.right):   # an event, not a value that drifts
                    walk(side.base if isinstance(side, ir.Member) else side)
                return
            if isinstance(x, ir.Member) and ident(x.member) == "ET":
                self._et = True
            if isinstance(x, ir.Name):
                out.add(ident(x.name))
            elif isinstance(x, ir.AssignExpr):
                self.use(x.target)          # written here: never left out of a state
                walk(x.value)
            elif isinstance(x, ir.Index):
                walk(x.base)
                for i in x.indices:
                    self.use(i)
            elif isinstance(x, ir.Deref):
                self.use(x.base)
            elif isinstance(x, ir.Call):
                if isinstance(x.func, ir.Member) or (
                        isinstance(x.func, ir.Name) and ident(x.func.name) in self.impure):
                    # methods change their instance; some functions write globals
                    for a in x.args:
                        if a.value is not None:
                            self.use(a.value)
                elif isinstance(x.func, ir.Name) and ident(x.func.name) in ("ADR", "REF"):
                    for a in x.args:
                        if a.value is not None:
                            self.use(a.value)
                walk(x.func)
                for a in x.args:
                    if a.value is not None:
                        walk(a.value)
            else:
                for c in _children(x):
                    walk(c)
        walk(e)
        return out

    def use(self, e):
        self._et = False
        self.used |= self.reads(e)
        if self._et:
            self.et_targets.add(None)

    def stmts(self, body):
        for s in body:
            self.stmt(s)

    def stmt(self, s):
        if isinstance(s, ir.Assign):
            target = _root(s.target)
            self._et = False
            reads = self.reads(s.value)
            if self._et:
                self.et_targets.add(target)
            if isinstance(s.target, (ir.Index, ir.Member, ir.BitAccess)):
                reads |= self.reads(s.target) - {target}
            if s.op != ":=" or isinstance(s.target, ir.Deref) or target is None:
                self.used |= reads
                if target is not None:
                    self.used.add(target)
            self.flows.append((target, reads))
            step = _added_step(s) if s.op == ":=" else None
            if step is not None:
                n, names = self.steps.get(target, (0, set()))
                self.steps[target] = (n + 1, names | ir.names_in(step, ir.Name, "name"))
        elif isinstance(s, ir.CallStmt):
            callee = _root(s.call.func)
            if callee in self.std_fbs and isinstance(s.call.func, (ir.Name, ir.Index)):
                self._et = False
                self.flows.append((callee, set().union(*(
                    self.reads(a.value) for a in s.call.args
                    if a.value is not None and not a.output))))
                if self._et:
                    self.et_targets.add(callee)
                for a in s.call.args:
                    if a.output and a.value is not None:
                        self.flows.append((_root(a.value), {callee}))
                        if (a.name or "").upper() == "ET":
                            self.et_targets.add(_root(a.value))
                if isinstance(s.call.func, ir.Index):
                    for i in s.call.func.indices:
                        self.use(i)
                return
            self.use(s.call.func)
            for a in s.call.args:
                if a.value is None:
                    continue
                if a.output:
                    self.flows.append((_root(a.value), {_root(s.call.func) or ""}))
                    if (a.name or "").upper() == "ET":
                        self.et_targets.add(None)
                else:
                    self.use(a.value)
        elif isinstance(s, ir.If):
            for cond, body in s.branches:
                self.use(cond)
                self.stmts(body)
            self.stmts(s.else_body or [])
        elif isinstance(s, ir.Case):
            self.use(s.selector)
            for br in s.branches:
                self.stmts(br.body)
            self.stmts(s.else_body or [])
        elif isinstance(s, ir.For):
            self.used.add(ident(s.var))
            if s.target is not None:
                self.use(s.target)
            for e in (s.start, s.end, s.step):
                if e is not None:
                    self.use(e)
            self.stmts(s.body)
        elif isinstance(s, (ir.While, ir.Repeat)):
            self.use(s.cond)
            self.stmts(s.body)
        elif isinstance(s, ir.Try):
            self.stmts(s.body)
            if s.catch_var is not None:
                self.flows.append((_root(s.catch_var), set()))
            self.stmts(s.catch_body or [])
            self.stmts(s.finally_body or [])


def _added_step(s: ir.Assign):
    """``e`` of ``x := x + e``, ``x := e + x`` or ``x := x - e`` (x a plain name), else
    None."""
    v = s.value
    if not isinstance(s.target, ir.Name) or not isinstance(v, ir.Binary):
        return None
    x = ident(s.target.name)

    def is_x(e):
        return isinstance(e, ir.Name) and ident(e.name) == x
    if v.op in ("+", "-") and is_x(v.left):
        return v.right
    if v.op == "+" and is_x(v.right):
        return v.left
    return None


def _children(e):
    if isinstance(e, ir.Binary):
        return (e.left, e.right)
    if isinstance(e, ir.Unary):
        return (e.operand,)
    if isinstance(e, (ir.Member, ir.BitAccess, ir.Deref)):
        return (e.base,)
    if isinstance(e, ir.Index):
        return (e.base, *e.indices)
    if isinstance(e, ir.Call):
        return tuple(a.value for a in e.args if a.value is not None)
    if isinstance(e, ir.AssignExpr):
        return (e.target, e.value)
    return ()


def _short_for(s: ir.For) -> int | None:
    """How often a FOR with literal bounds runs, when that is within the watchdog (it
    is then counted once as it starts, not at each pass); None for any other FOR."""
    vals = [x.value if isinstance(x, ir.Literal) and isinstance(x.value, int) else None
            for x in (s.start, s.end, s.step or ir.Literal(1, "ANY_INT"))]
    if None in vals or vals[2] == 0:
        return None
    n = len(range(vals[0], vals[1] + (1 if vals[2] > 0 else -1), vals[2]))
    return n if n <= WATCHDOG_ITERATIONS else None


def _has_fb(t) -> bool:
    t = _base_t(t)
    if t.cat in ("fb", "stdfb"):
        return True
    return isinstance(t, StructT) and any(_has_fb(m) for m in t.members.values())


def _base_t(t):
    while isinstance(t, ArrayT):
        t = t.elem
    return t


def _is_object_t(t) -> bool:
    return t is not None and t.cat in ty.OBJECT_CATS


_FB_INIT_FLAGS = ("BINITRETAINS", "BINCOPYCODE")


def _int_constants(blocks):
    """(name key, value) of each integer literal constant the CONSTANT ``blocks`` declare."""
    for b in blocks:
        if _constant_block(b):
            for d in b.decls:
                if isinstance(d.init, ir.Literal) and isinstance(d.init.value, int) \
                        and not isinstance(d.init.value, bool):
                    yield ident(d.name), int(d.init.value)


def _fb_inits(t: FbT) -> list:
    """(FB type, FB_init method) along ``t``'s chain, base first."""
    return [(ft, m) for ft in reversed(list(t.chain())) for m in ft.pou.methods
            if ident(m.name) == "FB_INIT"]


def _fb_init_args(m: ir.Method, d: ir.VarDecl) -> list[ir.Arg]:
    """The arguments of FB_init method ``m`` for declaration ``d``: its two flags FALSE
    (a first download: no retains kept, no online change) and the declaration's own, by
    name, positional ones in the order of the parameters after the flags; arguments
    ``m`` has no parameter for are left out (a base FB's FB_init with fewer)."""
    params = [x for b in m.var_blocks if b.kind in ("VAR_INPUT", "VAR_IN_OUT")
              for x in b.decls]
    names = {ident(x.name) for x in params}
    args = [ir.Arg(x.name, ir.Literal(False, "BOOL", pos=d.pos), pos=d.pos)
            for x in params if ident(x.name) in _FB_INIT_FLAGS]
    rest = [x for x in params if ident(x.name) not in _FB_INIT_FLAGS]
    for k, a in enumerate(d.init_args or []):
        name = a.name if a.name is not None else (rest[k].name if k < len(rest) else None)
        if name is not None and ident(name) in names:
            args.append(ir.Arg(name, a.value, pos=a.pos))
    return args


def _shown_name(pou: ir.Pou) -> str:
    """A POU's name as the program wrote it (a generic FB's copy as ``FB_Buf<100>``)."""
    return next((p[len(GENERIC_PRAGMA):] for p in pou.pragmas
                 if p.startswith(GENERIC_PRAGMA)), pou.name)


def _is_null_test(lt, rt, x: ir.Binary) -> bool:
    """Is ``x`` a pointer/reference/interface compared with the literal 0?"""
    def zero(e):
        return isinstance(e, ir.Literal) and e.value == 0 and not isinstance(e.value, bool)
    return (lt.cat in ("ptr", "itf") and zero(x.right)) or (
        rt.cat in ("ptr", "itf") and zero(x.left))


def _check_bit(x: ir.BitAccess, t):
    """An error unless ``x.bit`` is a bit of a value of type ``t`` (0..15 of a WORD)."""
    why = ty.bit_access_error(t, x.bit)
    if why is not None:
        raise _err(x, why)


def _deref_t(t):
    """References and pointers to function blocks and structs are the object itself."""
    while isinstance(t, PtrT) and _is_object_t(t.target):
        t = t.target
    return t


def _wider(a, b):
    if isinstance(a, EnumT):
        return a
    ab, bb = getattr(a, "bits", 0), getattr(b, "bits", 0)
    if not ab:
        return b
    if not bb:
        return a
    return a if ab >= bb else b


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


def _pos_args(pos) -> str:
    if pos is None:
        return "'', 0, 0"
    return f"{pos.file!r}, {pos.line}, {pos.col}"


def _describe(e) -> str:
    if isinstance(e, ir.Name):
        return e.name
    if isinstance(e, ir.Member):
        return f"{_describe(e.base)}.{e.member}"
    return "array"


def compile_program(program: ir.Program, observed=frozenset()) -> Compiled:
    """Compile a parsed project. ``observed``: names read from outside the program (the
    machine file's signals, :func:`~plcpred.sequencer.executor.observed_names`), which are
    always part of the state the executor compares. Raises :class:`CompileError`
    (positioned) for constructs the executor cannot run."""
    compiler = Compiler(program, observed)
    try:
        return compiler.compile()
    except ProgramError as e:       # a generic FB's copy named as the program writes it
        raise readable([e], compiler.program)[0] from None
