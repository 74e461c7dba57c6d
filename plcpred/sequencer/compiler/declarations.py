"""The project's declarations: constants, direct addresses, the program instances to
run, the memory the variables take, and each variable's initial value."""
from __future__ import annotations

import re

from ...parser import ir
from ...parser.names import ident
from .. import types as ty
from ..types import ArrayT, FbT, StdFbT, StructT
from .common import CompileError, constant_block, error_at, int_constants, stdfb_member
from .conversions import convert


class DeclarationsMixin:
    """Part of :class:`~.project.Compiler`: what the declarations of a project make."""

    def _collect_constants(self):
        """Integer constants usable in array bounds (``ARRAY[1..N]``), and TIME constants
        (timer thresholds)."""
        self.time_constants = {}
        for b in [g.block for g in self.program.globals] + [
                b for p in self.program.pous for b in p.var_blocks]:
            if constant_block(b):
                for d in b.decls:
                    if (isinstance(d.init, ir.Literal) and d.init.type_name in ("TIME", "LTIME")
                            and isinstance(d.type, ir.NamedType)
                            and ident(d.type.name) in ("TIME", "LTIME")):
                        self.time_constants[ident(d.name)] = int(d.init.value)
        blocks = [g.block for g in self.program.globals]
        blocks += [b for p in self.program.pous for b in p.var_blocks]
        for key, value in int_constants(blocks):
            self.types.constants[key] = value
        # a method's own constants (its array bounds may name them), never in place of a
        # POU's or a global one of the same name: the table is not scoped
        for key, value in int_constants(b for p in self.program.pous for m in p.methods
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

    def _direct(self, x: ir.DirectAddress, scope):
        """The variable a direct address stands for, as a Name to compile."""
        addr = x.address.upper()
        name = self.addr_names.get(addr)
        if name is not None and name.upper() in scope.names:
            return ir.Name(name, pos=x.pos)
        if addr in self.address_slots:
            return ir.Name(self.address_slots[addr], pos=x.pos)
        raise error_at(x, f"direct address {x.address} belongs to a variable of another "
                          "program; use that program's variable")

    def _program_instances(self):
        """(instance name, class name) of the programs to run, in scan order: those the
        configuration's tasks run, else the one PROGRAM."""
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
                        raise error_at(pi, f"PROGRAM instance {pi.name} names "
                                           f"'{pi.type_name}', which is not a PROGRAM")
                    out.append((pi.name, self.types.fbs[key].cls_name))
        if out:
            return out
        progs = [p for p in self.program.pous if p.kind == "PROGRAM"]
        if not progs:
            raise CompileError("no PROGRAM to run (the file has only functions, function "
                               "blocks or types)", self._file())
        if len(progs) > 1:
            raise error_at(progs[1], "several PROGRAMs and no CONFIGURATION saying which to "
                                     f"run ({', '.join(p.name for p in progs)})")
        return [(progs[0].name, self.types.fbs[ident(progs[0].name)].cls_name)]

    def _file(self) -> str:
        for p in self.program.pous:
            if p.pos is not None:
                return p.pos.file
        return "<program>"

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
            raise error_at(d, f"the program's variables hold {total:,} values (arrays and "
                              f"instances counted through), more than the executor's "
                              f"{ty.MAX_PROGRAM_CELLS:,}; {d.name} alone holds {n:,}")

    # ---------------------------------------------------------------- initial values
    def _init(self, t, init, scope, decl) -> str:
        """The code of a new value of type ``t``, initialised by ``init`` (or not)."""
        if isinstance(init, ir.ArrayInit):
            return self._array_init(t, init, scope, decl)
        if isinstance(init, ir.StructInit):
            return self._struct_init(t, init, scope, decl)
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
        return convert(code, vt, t, init)

    def _array_init(self, t, init: ir.ArrayInit, scope, decl) -> str:
        if not isinstance(t, ArrayT):
            raise error_at(init, "an array initialiser for a variable that is not an array")
        flat = []
        for count, item in init.items:
            if len(flat) + count > t.size:  # checked first: count may be huge
                raise error_at(init, f"{len(flat) + count:,} initial values for an array "
                                     f"of {t.size:,}")
            flat.extend([self._init(t.elem, item, scope, decl)] * count)
        flat += [self._init(t.elem, None, scope, decl)] * (t.size - len(flat))
        return f"_nest([{', '.join(flat)}], {[hi - lo + 1 for lo, hi in t.dims]!r})"

    def _struct_init(self, t, init: ir.StructInit, scope, decl) -> str:
        if t.cat not in ("struct", "fb", "stdfb"):
            raise error_at(init, "a structure initialiser for a variable that is neither a "
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
                raise error_at(init, f"'{fname}' is not a member of {t.name}")
            parts.append(f"{key}={self._init(mt, finit, scope, decl)}")
        base = self._init(t, None, scope, decl)
        return f"_setattrs({base}, {', '.join(parts)})"

    def _fb_member_type(self, t, key, node):
        if isinstance(t, StdFbT):
            return stdfb_member(t, key)[1]
        d = t.var(key)
        return None if d is None else self.types.resolve(d.type, d.pos)
