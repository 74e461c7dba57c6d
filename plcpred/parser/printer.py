"""Print IR back as IEC 61131-3 Structured Text.

The output parses to an IR equal to the input (positions aside): the round-trip tests rely
on it, and it is how a ``.seq`` chart or a PLCopen import can be shown as ST.
"""
from __future__ import annotations

from . import ir
from .literals import format_time_literal, quote_string

_PREC = {"OR": 1, "OR_ELSE": 1, "XOR": 2, "AND": 3, "AND_THEN": 3, "=": 4, "<>": 4, "<": 5,
         ">": 5, "<=": 5, ">=": 5, "+": 6, "-": 6, "*": 7, "/": 7, "MOD": 7, "**": 8}
_UNARY_PREC = 9
_TIME_TYPES = {"TIME", "LTIME", "TOD", "LTOD", "DATE", "LDATE", "DT", "LDT"}


def format_literal(lit: ir.Literal) -> str:
    v, t = lit.value, lit.type_name
    if t == "BOOL":
        return "TRUE" if v else "FALSE"
    if t in _TIME_TYPES:
        return format_time_literal(v, t)
    if t in ("STRING", "WSTRING"):
        return quote_string(v, t == "WSTRING")
    if t in ("CHAR", "WCHAR"):
        return f"{t}#{quote_string(v, t == 'WCHAR')}"
    if t == "ANY_INT":
        return str(v)
    if t == "ANY_REAL":
        return repr(float(v))
    if t in ("REAL", "LREAL"):
        return f"{t}#{float(v)!r}"
    return f"{t}#{v}"


def expr(e, parent_prec: int = 0) -> str:
    t = type(e)
    if t is ir.Name:
        return e.name
    if t is ir.Literal:
        return format_literal(e)
    if t is ir.TypeExpr:
        return type_ref(e.type)
    if t is ir.AssignExpr:
        return f"({expr(e.target)} := {expr(e.value)})"
    if t is ir.Binary:
        p = _PREC[e.op]
        # left-associative: a right operand of equal precedence needs parentheses
        text = f"{expr(e.left, p)} {e.op} {expr(e.right, p + 1)}"
        return f"({text})" if p < parent_prec else text
    if t is ir.Unary:
        inner = expr(e.operand, _UNARY_PREC)
        text = f"NOT {inner}" if e.op == "NOT" else f"{e.op}{inner}"
        return f"({text})" if _UNARY_PREC < parent_prec else text
    if t is ir.Member:
        return f"{postfix_base(e.base)}.{e.member}"
    if t is ir.BitAccess:
        return f"{postfix_base(e.base)}.{e.bit}"
    if t is ir.Index:
        return f"{postfix_base(e.base)}[{', '.join(expr(i) for i in e.indices)}]"
    if t is ir.Deref:
        return f"{postfix_base(e.base)}^"
    if t is ir.Call:
        return f"{postfix_base(e.func)}({', '.join(arg(a) for a in e.args)})"
    if t is ir.EnumLiteral:
        return f"{e.type_name}#{e.value}"
    if t is ir.DirectAddress:
        return e.address
    raise TypeError(f"cannot print expression {e!r}")


def postfix_base(e) -> str:
    if type(e) in (ir.Name, ir.Member, ir.BitAccess, ir.Index, ir.Deref, ir.Call,
                   ir.DirectAddress):
        return expr(e)
    return f"({expr(e)})"


def arg(a: ir.Arg) -> str:
    if a.name is None:
        return expr(a.value)
    if a.output:
        target = "" if a.value is None else " " + expr(a.value)
        return f"{'NOT ' if a.negated else ''}{a.name} =>{target}"
    return f"{a.name} := {expr(a.value)}"


def initializer(i) -> str:
    if isinstance(i, ir.ArrayInit):
        items = []
        for count, value in i.items:
            if count == 1 and value is not None:
                items.append(initializer(value))
            else:
                items.append(f"{count}({initializer(value) if value is not None else ''})")
        return f"[{', '.join(items)}]"
    if isinstance(i, ir.StructInit):
        return "(" + ", ".join(f"{n} := {initializer(v)}" for n, v in i.fields) + ")"
    return expr(i)


def type_ref(t, indent: str = "") -> str:
    if isinstance(t, ir.NamedType):
        if t.generic_args:
            return t.name + "<" + ", ".join(
                expr(a.value) if a.name is None and isinstance(a.value, ir.Literal)
                else f"({arg(a)})" for a in t.generic_args) + ">"
        return t.name
    if isinstance(t, ir.StringType):
        kw = "WSTRING" if t.wide else "STRING"
        return f"{kw}({expr(t.length)})" if t.length is not None else kw
    if isinstance(t, ir.ArrayType):
        dims = ", ".join("*" if lo is None else f"{expr(lo)}..{expr(hi)}" for lo, hi in t.dims)
        return f"ARRAY[{dims}] OF {type_ref(t.element, indent)}"
    if isinstance(t, ir.PointerType):
        return f"{'REFERENCE' if t.reference else 'POINTER'} TO {type_ref(t.target, indent)}"
    if isinstance(t, ir.SubrangeType):
        return f"{t.base}({expr(t.low)}..{expr(t.high)})"
    if isinstance(t, ir.EnumType):
        vals = ", ".join(n if v is None else f"{n} := {expr(v)}" for n, v in t.values)
        return f"({vals})" + (f" {t.base}" if t.base else "")
    if isinstance(t, ir.StructType):
        kw = "UNION" if t.union else "STRUCT"
        lines = [kw]
        lines += [indent + "    " + var_decl(d) for d in t.members]
        lines.append(indent + "END_" + kw)
        return "\n".join(lines)
    raise TypeError(f"cannot print type {t!r}")


def var_decl(d: ir.VarDecl, indent: str = "") -> str:
    text = d.name
    if d.address:
        text += f" AT {d.address}"
    if d.element_init_args is not None and isinstance(d.type, ir.ArrayType):
        # ARRAY[...] OF FB_T[(...), (...)]: each element's FB_init arguments
        per = ", ".join(f"({', '.join(arg(a) for a in args)})"
                        for args in d.element_init_args)
        text += f" : {type_ref(d.type, indent)}[{per}]"
    else:
        text += f" : {type_ref(d.type, indent)}"
    if d.init_args is not None:
        text += f"({', '.join(arg(a) for a in d.init_args)})"
    if d.edge:
        text += f" {d.edge}"
    if d.init is not None:
        text += f" := {initializer(d.init)}"
    return text + ";"


def var_block(b: ir.VarBlock, indent: str = "") -> list[str]:
    head = " ".join([b.kind] + b.qualifiers)
    return ([indent + head] + [indent + "    " + var_decl(d, indent + "    ") for d in b.decls]
            + [indent + "END_VAR"])


def statements(stmts, indent: str) -> list[str]:
    out = []
    for s in stmts:
        out.extend(statement(s, indent))
    return out


def statement(s, indent: str) -> list[str]:
    t = type(s)
    i2 = indent + "    "
    if t is ir.Assign:
        op = {"REF=": " REF= ", "?=": " ?= "}.get(s.op, " := ")
        return [f"{indent}{expr(s.target)}{op}{expr(s.value)};"]
    if t is ir.CallStmt:
        return [f"{indent}{expr(s.call)};"]
    if t is ir.If:
        out = []
        for n, (cond, body) in enumerate(s.branches):
            out.append(f"{indent}{'IF' if n == 0 else 'ELSIF'} {expr(cond)} THEN")
            out += statements(body, i2)
        if s.else_body is not None:
            out.append(f"{indent}ELSE")
            out += statements(s.else_body, i2)
        out.append(f"{indent}END_IF;")
        return out
    if t is ir.Case:
        out = [f"{indent}CASE {expr(s.selector)} OF"]
        for br in s.branches:
            labels = ", ".join(f"{expr(l.low)}..{expr(l.high)}" if isinstance(l, ir.CaseRange)
                               else expr(l) for l in br.labels)
            out.append(f"{i2}{labels}:")
            out += statements(br.body, i2 + "    ")
        if s.else_body is not None:
            out.append(f"{indent}ELSE")
            out += statements(s.else_body, i2)
        out.append(f"{indent}END_CASE;")
        return out
    if t is ir.For:
        by = f" BY {expr(s.step)}" if s.step is not None else ""
        var = s.var if s.target is None else expr(s.target)
        return ([f"{indent}FOR {var} := {expr(s.start)} TO {expr(s.end)}{by} DO"]
                + statements(s.body, i2) + [f"{indent}END_FOR;"])
    if t is ir.While:
        return ([f"{indent}WHILE {expr(s.cond)} DO"] + statements(s.body, i2)
                + [f"{indent}END_WHILE;"])
    if t is ir.Repeat:
        return ([f"{indent}REPEAT"] + statements(s.body, i2)
                + [f"{indent}UNTIL {expr(s.cond)}", f"{indent}END_REPEAT;"])
    if t is ir.Try:
        out = [f"{indent}__TRY"] + statements(s.body, i2)
        if s.catch_body is not None:
            out.append(f"{indent}__CATCH" + (f"({expr(s.catch_var)})" if s.catch_var else ""))
            out += statements(s.catch_body, i2)
        if s.finally_body is not None:
            out += [f"{indent}__FINALLY"] + statements(s.finally_body, i2)
        return out + [f"{indent}__ENDTRY"]
    if t is ir.Exit:
        return [f"{indent}EXIT;"]
    if t is ir.Continue:
        return [f"{indent}CONTINUE;"]
    if t is ir.Return:
        return [f"{indent}RETURN;"]
    if t is ir.Empty:
        return [f"{indent};"]
    if t is ir.Label:
        return [f"{indent}{s.name}:"]
    if t is ir.Jmp:
        return [f"{indent}JMP {s.label};"]
    if t is ir.Opaque:
        return [f"{indent}{{{{{s.text}}}}}"]
    raise TypeError(f"cannot print statement {s!r}")


def _head(kw: str, access, modifiers, name: str) -> str:
    return " ".join([kw] + ([access] if access else []) + list(modifiers) + [name])


def method(m: ir.Method, indent: str = "") -> list[str]:
    head = _head("METHOD", m.access, m.modifiers, m.name)
    if m.return_type is not None:
        head += f" : {type_ref(m.return_type)}"
    out = [indent + head]
    for b in m.var_blocks:
        out += var_block(b, indent)
    out += statements(m.body, indent + "    ")
    out.append(indent + "END_METHOD")
    return out


def prop(p: ir.Property, indent: str = "") -> list[str]:
    out = [indent + _head("PROPERTY", p.access, p.modifiers, p.name) + f" : {type_ref(p.type)}"]
    for a in p.accessors:
        out.append(indent + a.kind)
        for b in a.var_blocks:
            out += var_block(b, indent + "    ")
        out += statements(a.body, indent + "    ")
        out.append(indent + "END_" + a.kind)
    out.append(indent + "END_PROPERTY")
    return out


def action(a: ir.SfcAction, indent: str = "") -> list[str]:
    return [f"{indent}ACTION {a.name}:"] + statements(a.body, indent + "    ") + [
        f"{indent}END_ACTION"]


def sfc(body: ir.Sfc) -> list[str]:
    out = []
    for st in body.steps:
        out.append(f"{'INITIAL_STEP' if st.initial else 'STEP'} {st.name}:")
        for a in st.actions:
            args = [a.qualifier]
            if a.time is not None:
                args.append(expr(a.time))
            if a.indicator:
                args.append(a.indicator)
            out.append(f"    {a.action}({', '.join(args)});")
        out.append("END_STEP")
    for tr in body.transitions:
        head = "TRANSITION"
        if tr.name:
            head += f" {tr.name}"
        if tr.priority:
            head += f" (PRIORITY := {tr.priority})"

        def steps(names):
            return names[0] if len(names) == 1 else f"({', '.join(names)})"

        out.append(f"{head} FROM {steps(tr.sources)} TO {steps(tr.targets)}")
        out.append(f"    := {expr(tr.condition)};")
        out.append("END_TRANSITION")
    for a in body.actions:
        out += action(a)
    return out


def pou(p: ir.Pou) -> list[str]:
    head = p.kind if p.kind == "PROGRAM" else _head(p.kind, p.access, p.modifiers, "")[:-1]
    head = f"{head} {p.name}"
    if p.extends:
        head += f" EXTENDS {type_ref(ir.NamedType(p.extends, generic_args=p.extends_args))}"
    if p.implements:
        head += f" IMPLEMENTS {', '.join(p.implements)}"
    if p.return_type is not None:
        head += f" : {type_ref(p.return_type)}"
    out = [head]
    for b in p.var_blocks:
        out += var_block(b)
    if isinstance(p.body, ir.Sfc):
        out += sfc(p.body)
    else:
        out += statements(p.body, "    ")
    for a in p.actions:
        out += action(a)
    for m in p.methods:
        out += method(m)
    for pr in p.properties:
        out += prop(pr)
    out.append(f"END_{p.kind}")
    return out


def type_decl(t: ir.TypeDecl) -> str:
    ext = ""
    type_ = t.type
    if isinstance(type_, ir.StructType) and type_.extends:
        ext = f" EXTENDS {type_.extends}"
    text = f"    {t.name}{ext} : {type_ref(type_, '    ')}"
    if t.init is not None:
        text += f" := {initializer(t.init)}"
    return text + ";"


def configuration(c: ir.Configuration) -> list[str]:
    out = [f"CONFIGURATION {c.name}"]
    for b in c.var_blocks:
        out += var_block(b, "    ")

    def items(res: ir.Resource, indent: str):
        lines = []
        for tk in res.tasks:
            params = ", ".join(f"{k} := {expr(v)}" for k, v in tk.params.items())
            lines.append(f"{indent}TASK {tk.name}({params});")
        for pi in res.programs:
            text = f"{indent}PROGRAM {pi.retain + ' ' if pi.retain else ''}{pi.name}"
            if pi.task:
                text += f" WITH {pi.task}"
            text += f" : {pi.type_name}"
            if pi.args:
                text += f"({', '.join(arg(a) for a in pi.args)})"
            lines.append(text + ";")
        return lines

    for res in c.resources:
        if res.name == "" and res.on is None:
            out += items(res, "    ")
            continue
        out.append(f"    RESOURCE {res.name} ON {res.on}")
        for b in res.var_blocks:
            out += var_block(b, "        ")
        out += items(res, "        ")
        out.append("    END_RESOURCE")
    out.append("END_CONFIGURATION")
    return out


def to_st(program: ir.Program) -> str:
    """The whole program as Structured Text."""
    out: list[str] = []
    if program.types:
        out.append("TYPE")
        out += [type_decl(t) for t in program.types]
        out += ["END_TYPE", ""]
    for g in program.globals:
        out += var_block(g.block) + [""]
    for itf in program.interfaces:
        head = f"INTERFACE {itf.name}"
        if itf.extends:
            head += f" EXTENDS {', '.join(itf.extends)}"
        out.append(head)
        for m in itf.methods:
            out += method(m, "    ")
        for p in itf.properties:
            out += prop(p, "    ")
        out += ["END_INTERFACE", ""]
    for p in program.pous:
        out += pou(p) + [""]
    for c in program.configurations:
        out += configuration(c) + [""]
    return "\n".join(out)
