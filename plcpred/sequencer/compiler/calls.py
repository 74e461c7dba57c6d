"""Calls: of FB instances and their actions (statements), of functions and methods
(expressions), with their arguments, and the IEC EN/ENO around them."""
from __future__ import annotations

from ...parser import ir
from ...parser.names import ident
from ...parser.stdlib import STANDARD_FBS, is_standard_function, std_fb_pin
from .. import types as ty
from ..types import BOOL, FbT, ItfT, StdFbT
from .common import STDFB_MEMBERS, CompileError, Scope, error_at
from .conversions import convert, deref_t, is_object_t


def _en_eno_args(call: ir.Call) -> tuple[list, list]:
    """The EN input and ENO output arguments of a call."""
    en = [a for a in call.args if (a.name or "").upper() == "EN" and not a.output]
    eno = [a for a in call.args if (a.name or "").upper() == "ENO" and a.output]
    return en, eno


class CallsMixin:
    """Part of :class:`~.project.Compiler`: calls and their arguments."""

    # ---------------------------------------------------------------- EN / ENO
    def _en_eno(self, s, scope: Scope):
        """The IEC EN/ENO of a call (``fb(EN := c, ENO => ok)``, ``x := F(EN := c, a)``) as
        the IF it stands for: run the call only when EN is TRUE, ENO := EN. None when the
        statement has no such call or the callee declares EN/ENO itself."""
        call = s.call if isinstance(s, ir.CallStmt) else \
            s.value if isinstance(s, ir.Assign) and s.op == ":=" else None
        if not isinstance(call, ir.Call):
            return None
        en, eno = _en_eno_args(call)
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

    # ---------------------------------------------------------------- statements
    def _call_stmt(self, call: ir.Call, scope: Scope, ind: int):
        e = self.src.emit
        f = call.func
        pos = call.pos
        if isinstance(f, ir.Deref) and isinstance(f.base, ir.Name) \
                and ident(f.base.name) == "SUPER":
            if scope.fb is None or scope.fb.base is None:
                raise error_at(call, "SUPER^() outside a function block that EXTENDS another")
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
        t = deref_t(t)
        if isinstance(t, (FbT, StdFbT)):
            return code, t
        return None

    def _fb_call(self, code: str, t, call: ir.Call, scope: Scope, ind: int,
                 body: str = "_body()"):
        """A call of FB instance ``code``: its inputs set, its body (or ``body``) run,
        its outputs stored where the call binds them."""
        e = self.src.emit
        pos = call.pos
        f = self.src.temp("f")
        e(ind, f"{f} = {code}", pos)
        ins, inouts, outs, mtype = self._fb_pins(t)
        post = []
        positional = list(ins) + list(inouts)
        for k, arg in enumerate(call.args):
            if arg.name is None:
                if arg.output or k >= len(positional):
                    raise error_at(arg, "too many arguments")
                name = positional[k]
            elif isinstance(t, StdFbT):
                name = std_fb_pin(t.name, arg.name) or ident(arg.name)
            else:
                name = ident(arg.name)
            if arg.output:
                if name not in outs and name not in ins:
                    raise error_at(arg, f"'{arg.name}' is not an output of {t.name}")
                value = f"(not {f}.{name})" if arg.negated else f"{f}.{name}"
                if arg.value is not None:
                    post.append((arg.value, value, BOOL if arg.negated else mtype(name)))
                continue
            if name in inouts:
                self._referenced(arg.value)         # copied back after the call
                vcode, vt = self._expr(arg.value, scope)
                e(ind, f"{f}.{name} = {vcode}", arg.pos or pos)
                if not is_object_t(vt):
                    post.append((arg.value, f"{f}.{name}", mtype(name)))
                continue
            if name not in ins:
                raise error_at(arg, f"'{arg.name}' is not an input of {t.name}")
            self._fb_input(f, t, name, arg, mtype, scope, ind, pos)
        if isinstance(t, StdFbT):
            e(ind, f"{f}.execute(_now)", pos)
        else:
            e(ind, f"{f}.{body}", pos)
        for target, value, vt in post:
            self._store(target, value, vt, scope, ind, pos)

    def _fb_pins(self, t):
        """(inputs, in-outs, outputs, type of a pin by name) of an FB type."""
        if isinstance(t, StdFbT):
            ins, outs = STANDARD_FBS[t.name]
            return ins, (), outs, STDFB_MEMBERS.__getitem__
        chain = list(reversed(list(t.chain())))
        ins = [ident(d.name) for x in chain for d in x.pou.decls("VAR_INPUT")]
        inouts = [ident(d.name) for x in chain for d in x.pou.decls("VAR_IN_OUT")]
        outs = [ident(d.name) for x in chain for d in x.pou.decls("VAR_OUTPUT")]

        def mtype(k):
            d = t.var(k)
            return self.types.resolve(d.type, d.pos)
        return ins, inouts, outs, mtype

    def _fb_input(self, f: str, t, name: str, arg: ir.Arg, mtype, scope: Scope, ind: int,
                  pos) -> None:
        """Set input ``name`` of instance ``f``; an R_EDGE (F_EDGE) input is TRUE in the
        call where the value rose (fell)."""
        e = self.src.emit
        vcode, vt = self._expr(arg.value, scope)
        value = convert(vcode, vt, mtype(name), arg.value, copy=True)
        edge = t.var(name).edge if isinstance(t, FbT) else None
        if edge:
            v = self.src.temp("v")
            e(ind, f"{v} = {value}", arg.pos or pos)
            seen = f"{v} and not {f}._e_{name}" if edge == "R_EDGE" else \
                f"not {v} and {f}._e_{name}"
            e(ind, f"{f}._e_{name}, {f}.{name} = {v}, ({seen})", arg.pos or pos)
        else:
            e(ind, f"{f}.{name} = {value}", arg.pos or pos)

    # ---------------------------------------------------------------- expressions
    def _call_expr(self, call: ir.Call, scope: Scope):
        en, eno = _en_eno_args(call)
        if (en or eno) and not self._declares_en(call.func, scope):
            return self._call_with_en(call, scope, en, eno)
        f = call.func
        if isinstance(f, ir.Name):
            return self._call_by_name(call, f, scope)
        if isinstance(f, ir.Member):
            return self._method_call(call, f, scope)
        raise error_at(call, "this cannot be called in an expression")

    def _call_with_en(self, call: ir.Call, scope: Scope, en: list, eno: list):
        """The implicit EN of a call inside an expression (OSCAT: T_PLC_MS(en := TRUE))."""
        if eno:
            raise error_at(eno[0], "ENO of a call inside an expression is not supported: "
                                   "call it as a statement, or assign its result")
        code, t = self._call_expr(ir.Call(call.func, [a for a in call.args if a not in en],
                                          pos=call.pos), scope)
        cond = en[0].value
        if isinstance(cond, ir.Literal) and cond.value is True:
            return code, t
        if is_object_t(t) or t.cat == "void":
            raise error_at(en[0], "EN of this call inside an expression is not supported: "
                                  "call it as a statement")
        ccode, _ = self._expr(cond, scope)
        # not run: the value the result type starts with
        return f"({code} if {ccode} else {t.default()!r})", t

    def _call_by_name(self, call: ir.Call, f: ir.Name, scope: Scope):
        """A user function, an action or method of this FB, or a standard function."""
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
            raise error_at(call, f"{f.name} is a function block instance: call it as a "
                                 "statement, then read its outputs")
        raise error_at(call, f"unknown function '{f.name}'")

    def _method_call(self, call: ir.Call, f: ir.Member, scope: Scope):
        """``x.Method(...)``, ``SUPER^.Method(...)`` or ``x.Action()``."""
        key = ident(f.member)
        if isinstance(f.base, ir.Deref) and isinstance(f.base.base, ir.Name) and \
                ident(f.base.base.name) == "SUPER":
            if scope.fb is None or scope.fb.base is None:
                raise error_at(call, "SUPER^ outside a function block that EXTENDS another")
            m = scope.fb.base.method(key)
            if m is None:
                raise error_at(call, f"{scope.fb.base.name} has no method {f.member}")
            return self._boxed(lambda: f"{scope.fb.base.cls_name}.m_{key}(self, "
                               f"{self._named_args(m[0].var_blocks, call, scope, f.member)})"
                               ), self._ret_t(m[0])
        bcode, bt = self._expr(f.base, scope)
        bt = deref_t(bt)
        if isinstance(bt, (FbT, ItfT)):
            m = bt.method(key)
            if m is not None:
                return self._boxed(lambda: f"{bcode}.m_{key}("
                                   f"{self._named_args(m[0].var_blocks, call, scope, f.member)})"
                                   ), self._ret_t(m[0])
            if isinstance(bt, FbT) and bt.action(key) is not None:
                return f"{bcode}.a_{key}()", ty.VOID
        raise error_at(call, f"'{f.member}' is not a method of {getattr(bt, 'name', '?')}")

    def _ret_t(self, m):
        return self.types.resolve(m.return_type, m.pos) if m.return_type else ty.VOID

    def _named_args(self, var_blocks, call: ir.Call, scope: Scope, what: str) -> str:
        """The keyword arguments of a call of a function or method declaring
        ``var_blocks``: inputs by value, in-outs and outputs as references."""
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
                    raise error_at(arg, f"too many arguments for {what}")
                d = positional[k]
            else:
                d = by_name.get(ident(arg.name)) or io_names.get(ident(arg.name))
                if d is None:
                    raise error_at(arg, f"{what} has no parameter '{arg.name}'")
            key = ident(d.name)
            if key in by_name and not arg.output:
                vcode, vt = self._expr(arg.value, scope)
                t = self.types.resolve(d.type, d.pos)
                parts.append(f"{key}={convert(vcode, vt, t, arg.value)}")
            elif arg.value is not None:
                if arg.negated:
                    raise error_at(arg, "a negated output binding of a function is not "
                                        "supported")
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
        saved, self._boxes = self._boxes, []
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
