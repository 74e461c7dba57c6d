"""Statements: assignments, IF and CASE chains, loops counted against the watchdog,
TRY, and JMP within one statement list."""
from __future__ import annotations

import dataclasses

from ...parser import ir
from ...parser.names import ident
from .. import types as ty
from ..types import BOOL, EnumT
from .common import ELIF_CHAIN, WATCHDOG_ITERATIONS, CompileError, Scope, error_at, pos_args
from .conversions import convert

# a statement list of more IR nodes than this (statements, expressions, names) is
# compiled as functions of about PART_LINES generated lines each, called in turn, and IF
# and CASE arms beyond PART_ARMS as functions of that many arms: Python compiles a
# function at once, in memory many times its text (one body of 200,000 statements took
# 1.6 GB)
PART_NODES = 5_000
PART_LINES = 1_000
PART_ARMS = 300


class StatementsMixin:
    """Part of :class:`~.project.Compiler`: statement lists into Python statements."""

    def _stmts(self, stmts, scope: Scope, ind: int, loop: bool = False):
        if any(isinstance(s, ir.Label) for s in stmts):
            self._jump_blocks(stmts, scope, ind, loop)
            return
        if len(stmts) > 1 and not loop and _larger_than(stmts, PART_NODES) \
                and self._can_part(scope):
            self._parts(stmts, scope, ind)
            return
        for s in stmts:
            self._stmt(s, scope, ind, loop)

    def _stmt(self, s, scope: Scope, ind: int, loop: bool):
        """One statement at indentation ``ind`` (``loop``: inside a loop's body)."""
        e = self.src.emit
        pos = s.pos
        if isinstance(s, (ir.CallStmt, ir.Assign)):
            desugared = self._en_eno(s, scope)
            if desugared is not None:
                return self._stmt(desugared, scope, ind, loop)
        if isinstance(s, ir.Assign):
            self._assign(s, scope, ind)
        elif isinstance(s, ir.CallStmt):
            self._call_stmt(s.call, scope, ind)
        elif isinstance(s, ir.If):
            def test(cond):
                code, t = self._expr(cond, scope)
                return convert(code, t, BOOL, cond)
            self._chain([(lambda c=cond: test(c), body, getattr(cond, "pos", None) or pos)
                         for cond, body in s.branches], s.else_body, scope, ind, pos, loop)
        elif isinstance(s, ir.Try):
            self._try(s, scope, ind, loop)
        elif isinstance(s, ir.Case):
            self._case(s, scope, ind, loop)
        elif isinstance(s, ir.For):
            self._for(s, scope, ind)
        elif isinstance(s, (ir.While, ir.Repeat)):
            self._while(s, scope, ind)
        elif isinstance(s, ir.Exit):
            if not loop:
                raise error_at(s, "EXIT outside a loop")
            e(ind, "break", pos)
        elif isinstance(s, ir.Continue):
            if not loop:
                raise error_at(s, "CONTINUE outside a loop")
            e(ind, "continue", pos)
        elif isinstance(s, ir.Return):
            e(ind, scope.ret, pos)
        elif isinstance(s, ir.Empty):
            pass
        elif isinstance(s, ir.Opaque):
            e(ind, f"_opaque({s.what!r}, {pos_args(pos)})", pos)
        elif isinstance(s, ir.Jmp):
            self._jmp(s, ind)
        else:  # pragma: no cover - the parser produces no other statements
            raise error_at(s, f"unsupported statement {type(s).__name__}")

    def _assign(self, s: ir.Assign, scope: Scope, ind: int) -> None:
        """``:=``, ``S=`` and ``R=`` (set and reset when the value is TRUE), ``REF=``."""
        e = self.src.emit
        pos = s.pos
        if s.op == "REF=":
            code, t = self._ref_of(s.value, scope)
            self._store(s.target, code, None, scope, ind, pos, raw=True, rebind=True)
        elif s.op in (":=", "S=", "R="):
            expect = None
            if isinstance(s.value, ir.Name) and s.op == ":=":
                # an enumeration value named by several enumerations is the target's
                expect = self._target_enum(s.target, scope)
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
            raise error_at(s, f"assignment '{s.op}' is not supported by the executor")

    def _target_enum(self, target, scope: Scope):
        """The enumeration type of an assignment's target, if it has one (else None)."""
        try:
            t = self._expr(target, scope)[1]
        except CompileError:
            return None
        return t if isinstance(t, EnumT) else None

    def _try(self, s: ir.Try, scope: Scope, ind: int, loop: bool) -> None:
        e = self.src.emit
        pos = s.pos
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

    def _case(self, s: ir.Case, scope: Scope, ind: int, loop: bool) -> None:
        pos = s.pos
        sel, st = self._expr(s.selector, scope)
        tmp = self.src.temp("sel")
        self.src.emit(ind, f"{tmp} = {sel}", pos)

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
                     for br in s.branches], s.else_body, scope, ind, pos, loop, (tmp,))

    def _chain(self, arms, else_body, scope: Scope, ind: int, pos, loop: bool,
               carry: tuple = (), hit: str | None = None) -> None:
        """``if``/``elif``/``else`` over ``arms`` [(a function giving the test's code, the
        body, its position)]. Python's compiler recurses once per ``elif``, so a chain
        longer than ELIF_CHAIN (a CASE of 20,000 labels ran it out of memory) is cut into
        chains that each run only when none before matched; more than PART_ARMS arms are
        functions of their own (:meth:`_arm_parts`; ``carry``: the Python locals their
        tests read). ``hit``: a variable set to whether an arm ran."""
        if len(arms) > PART_ARMS and not loop and self._can_part(scope):
            self._arm_parts(arms, else_body, scope, ind, pos, carry)
            return
        e = self.src.emit
        hit = hit or (self.src.temp("hit") if len(arms) > ELIF_CHAIN else None)
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

    # ---------------------------------------------------------------- parts
    def _can_part(self, scope: Scope) -> bool:
        """May statements of ``scope`` move into a module-level function: not inside a
        JMP dispatch (its ``continue``), nor of a class when the program declares a name
        ``__X`` (Python mangles those inside a class only)."""
        if self._jump is not None:
            return False
        if scope.fb is None:
            return True
        if self._declares_mangled is None:
            self._declares_mangled = _declares_mangled(self.program)
        return not self._declares_mangled

    def _part_call(self, scope: Scope, extra: tuple = ()):
        """(the parameters of a part of ``scope``'s code, the Python locals it hands
        back): ``self``, the carried ``extra``, then the locals, which it returns after
        a status (0: went on to its end)."""
        keep = tuple(sorted(scope.pylocals))
        params = ("self",) if scope.fb is not None else ()
        return ", ".join(params + extra + keep), keep

    def _part_def(self, name: str, params: str, keep: tuple, scope: Scope, status: int,
                  pos) -> Scope:
        """Emit (aside) the header of a part; the scope its statements compile in, where
        RETURN hands back ``status``."""
        self.src.emit(0, f"def {name}({params}):", pos)
        return dataclasses.replace(scope, ret=f"return {_status(status, keep)}")

    def _parts(self, stmts, scope: Scope, ind: int) -> None:
        """A long statement list as functions of about PART_LINES generated lines each,
        called in turn; RETURN in one ends the caller too."""
        e = self.src.emit
        params, keep = self._part_call(scope)
        k = 0
        while k < len(stmts):
            name, pos = self.src.temp("part"), stmts[k].pos
            with self.src.aside():
                inner = self._part_def(name, params, keep, scope, 1, pos)
                while k < len(stmts) and len(self.src.lines) < PART_LINES:
                    self._stmt(stmts[k], inner, 1, False)
                    k += 1
                e(1, f"return {_status(0, keep)}")
            if keep:
                st = self.src.temp("st")
                e(ind, f"{st}, {', '.join(keep)}, = {name}({params})", pos)
                e(ind, f"if {st}: {scope.ret}", pos)
            else:
                e(ind, f"if {name}({params}): {scope.ret}", pos)

    def _arm_parts(self, arms, else_body, scope: Scope, ind: int, pos, carry: tuple) -> None:
        """IF/CASE arms as functions of PART_ARMS arms each, tried in turn until one
        matches (status 1; 2: RETURN), then ELSE when none did."""
        e = self.src.emit
        params, keep = self._part_call(scope, carry)
        hit = self.src.temp("hit")
        for k in range(0, len(arms), PART_ARMS):
            name = self.src.temp("part")
            with self.src.aside():
                inner = self._part_def(name, params, keep, scope, 2, pos)
                found = self.src.temp("hit")
                self._chain(arms[k:k + PART_ARMS], None, inner, 1, pos, False, hit=found)
                e(1, f"return {_status(f'1 if {found} else 0', keep)}")
            at = ind
            if k:
                e(ind, f"if not {hit}:", pos)
                at = ind + 1
            e(at, f"{hit}{''.join(', ' + x for x in keep)}, = {name}({params})"
                  if keep else f"{hit} = {name}({params})", pos)
            e(at, f"if {hit} == 2: {scope.ret}", pos)
        if else_body is not None:
            e(ind, f"if not {hit}:", pos)
            self._stmts(else_body, scope, ind + 1)
            e(ind + 1, "pass")

    # ---------------------------------------------------------------- loops
    def _count_iteration(self, kind: str, ind: int, pos, n: int = 1) -> None:
        """Count ``n`` loop passes against the scan's budget (``_work``, reset by the
        executor each scan): a loop that runs away, or loops nested so that together
        they do, stop at the watchdog naming this loop."""
        self.src.emit(ind, f"_work[0] += {n}", pos)
        self.src.emit(ind, f"if _work[0] > {WATCHDOG_ITERATIONS}: _watchdog({kind!r}, "
                           f"{pos_args(pos)})", pos)

    def _for(self, s: ir.For, scope: Scope, ind: int) -> None:
        e = self.src.emit
        pos = s.pos
        var = s.target or ir.Name(s.var, pos=pos)
        self._expr(var, scope)          # the loop variable must be one
        start, _ = self._expr(s.start, scope)
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
        self._loop_body(s.body, scope, ind + 1)
        e(ind, "else:", pos)
        self._store(var, f"({r}[-1] + {r}.step if {r} else {start})", ty.ANY_INT, scope,
                    ind + 1, pos)

    def _while(self, s, scope: Scope, ind: int) -> None:
        """WHILE, and REPEAT, which tests its condition after the body: the first pass
        always runs, and CONTINUE still reaches the test."""
        e = self.src.emit
        pos = s.pos
        n = self.src.temp("n")
        code, t = self._expr(s.cond, scope)
        cond = convert(code, t, BOOL, s.cond)
        kind = "WHILE" if isinstance(s, ir.While) else "REPEAT"
        if kind == "WHILE":
            e(ind, f"while {cond}:", pos)
        else:
            e(ind, f"{n} = True", pos)
            e(ind, f"while {n} or not {cond}:", pos)
            e(ind + 1, f"{n} = False", pos)
        self._count_iteration(kind, ind + 1, pos)
        self._loop_body(s.body, scope, ind + 1)

    def _loop_body(self, body, scope: Scope, ind: int) -> None:
        self._loop_depth += 1
        self._stmts(body, scope, ind, True)
        self._loop_depth -= 1
        self.src.emit(ind, "pass")

    # ---------------------------------------------------------------- jumps
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

    def _jmp(self, s: ir.Jmp, ind: int) -> None:
        labels, jl, depth = self._jump or ({}, None, 0)
        if ident(s.label) not in labels:
            raise error_at(s, f"JMP {s.label}: no label {s.label} in the same statement list "
                              "(jumps into or out of IF, CASE and loops are not supported)")
        if depth != self._loop_depth:
            raise error_at(s, "JMP out of a FOR, WHILE or REPEAT loop is not supported")
        self.src.emit(ind, f"{jl} = {labels[ident(s.label)]}", s.pos)
        self.src.emit(ind, "continue", s.pos)


def _status(status, keep: tuple) -> str:
    """What a part returns: its status, and the locals it hands back."""
    return f"({status}, {', '.join(keep)},)" if keep else str(status)


def _larger_than(root, limit: int) -> bool:
    """Does ``root`` (IR, lists included) hold more than ``limit`` nodes?"""
    for n, _ in enumerate(ir.nodes(root)):
        if n >= limit:
            return True
    return False


def _declares_mangled(program: ir.Program) -> bool:
    """Does ``program`` declare a variable, member or parameter ``__X``? (Inside a
    class, Python mangles such a name; the generated code names nothing else a program
    names.)"""
    blocks = [p.var_blocks for p in program.pous]
    blocks += [m.var_blocks for p in program.pous for m in p.methods]
    blocks += [a.var_blocks for p in program.pous for pr in p.properties
               for a in pr.accessors]
    roots = [blocks, program.types, program.globals, program.configurations]
    return any(isinstance(node, ir.VarDecl) and node.name.startswith("__")
               for node, _ in ir.nodes(roots))


def _short_for(s: ir.For) -> int | None:
    """How often a FOR with literal bounds runs, when that is within the watchdog (it
    is then counted once as it starts, not at each pass); None for any other FOR."""
    vals = [x.value if isinstance(x, ir.Literal) and isinstance(x.value, int) else None
            for x in (s.start, s.end, s.step or ir.Literal(1, "ANY_INT"))]
    if None in vals or vals[2] == 0:
        return None
    n = len(range(vals[0], vals[1] + (1 if vals[2] > 0 else -1), vals[2]))
    return n if n <= WATCHDOG_ITERATIONS else None
