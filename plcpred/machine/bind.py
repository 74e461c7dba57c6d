"""The machine file against its program: every signal the file names must be a variable
of the program; what the program reads that nothing drives, and outputs that drive
nothing, are warnings."""
from __future__ import annotations

import difflib
import re
from pathlib import Path

from ..parser import ir
from ..parser.check import Checker
from .load import locate_error
from .model import Machine, MachineError


def program_addresses(program) -> dict[str, str]:
    """Hardware address -> name of the variable declared AT it (``"%QX0.0" -> "Y_A"``), so
    a machine file may name a signal by its address without a [signals] entry."""
    out = {}
    blocks = [g.block for g in program.globals]
    blocks += [b for c in program.configurations for b in c.var_blocks]
    blocks += [b for c in program.configurations for r in c.resources for b in r.var_blocks]
    blocks += [b for p in program.pous if p.kind == "PROGRAM" for b in p.var_blocks]
    for b in blocks:
        for d in b.decls:
            if d.address and "*" not in d.address:
                out.setdefault(d.address.upper(), d.name)
    return out


def _program_io(program):
    """(all variable names, output names, names read anywhere: upper case; inputs: upper
    case -> as declared; every name as declared) of a program."""

    names, outputs, inputs, spelled = set(), set(), {}, []
    blocks = [g.block for g in program.globals]
    blocks += [b for c in program.configurations for b in c.var_blocks]
    blocks += [b for c in program.configurations for r in c.resources for b in r.var_blocks]
    for pou in program.pous:
        if pou.kind == "PROGRAM":
            blocks += pou.var_blocks
    for b in blocks:
        for d in b.decls:
            key = d.name.upper()
            names.add(key)
            spelled.append(d.name)
            if b.kind == "VAR_OUTPUT" or (d.address or "").upper().startswith("%Q"):
                outputs.add(key)
            elif b.kind == "VAR_INPUT" or (d.address or "").upper().startswith("%I"):
                inputs[key] = d.name
    usage = Checker(program).run().program_usage
    return names, outputs, usage.read, inputs, spelled


class _Signals:
    """The program's variables as a machine file's signals name them (a name, an address
    through ``[signals]`` or an AT declaration, a bit of a word, a path into a variable):
    :meth:`require` finds one, or raises an error positioned in the machine file."""

    def __init__(self, machine: Machine, program):
        self.machine = machine
        self.names, self.outputs, read, self.inputs, self.spelled = _program_io(program)
        self.by_address = program_addresses(program)
        self.by_address.update({addr.upper(): name for addr, name in machine.signals.items()})
        # the program checked (a --program given instead of the file's is named as itself)
        self.program_file = next(
            (Path(p.pos.file).name for p in program.pous if p.pos is not None
             and p.pos.file and not p.pos.file.startswith("<")), machine.program_path.name)
        self.programs = {p.name.upper() for p in program.pous if p.kind == "PROGRAM"}
        self.programs |= {i.name.upper() for c in program.configurations
                          for r in c.resources for i in r.programs}
        self.used_addresses = {a.upper() for a in
                               ir.names_in(program, ir.DirectAddress, "address")}
        self.names |= self.used_addresses
        self.read = set(read) | self.used_addresses

    def require(self, where: str, key: str, signal: str) -> str:
        """The upper-case variable ``signal`` names (``key`` of ``where``)."""
        name = self.by_address.get(signal.upper(), signal)
        if name.upper() in self.used_addresses:
            return name.upper()  # an address the code uses directly
        base, dot, bit = name.rpartition(".")
        if dot and re.fullmatch(r"[0-9]+", bit) and base.upper() in self.names:
            name = base  # one bit of a WORD/BYTE variable
        if name.upper() in self.names:
            return name.upper()
        # a path into a variable (aValve[3], fbCyl[2].q, PRG.stCell.xOut): its variable is
        # checked here, the path itself when the program is compiled
        path = re.match(r"\s*([A-Za-z_][A-Za-z0-9_]*)\s*(?:\.\s*([A-Za-z_][A-Za-z0-9_]*))?"
                        r"\s*[.\[]", name + ".", re.ASCII)
        if path:
            first, second = path.group(1).upper(), (path.group(2) or "").upper()
            if first in self.names:
                return first
            if first in self.programs and second in self.names:
                return second
        near = difflib.get_close_matches(signal, sorted(set(self.spelled)), n=1, cutoff=0.6)
        hint = f"; did you mean '{near[0]}'?" if near else ""
        raise locate_error(MachineError(str(self.machine.path), where,
                                        f"{key} '{signal}' is not a variable of "
                                        f"{self.program_file}{hint}",
                                        key=key.partition(".")[0]),
                           self.machine.path, holding=signal)


def check_against_program(machine: Machine, program) -> list[str]:
    """Cross-check the machine's signals with the program's variables. Unknown signals are
    errors (raised); outputs that drive no consumer, switches the program never reads and
    inputs it reads that nothing drives are returned (and added to ``machine.warnings``)."""
    file = str(machine.path)
    sig = _Signals(machine, program)
    program_file, require = sig.program_file, sig.require
    driven = set()
    fed = set()     # inputs something drives: a schedule or a switch
    warnings = []
    for c in machine.consumers:
        where = f'consumer "{c.name}"'
        for v in c.valve:
            name = require(where, "valve", v)
            driven.add(name)
            if name in sig.inputs:
                warnings.append(f"{file}: {where}: valve '{v}' is an input of "
                                f"{program_file}, not an output: the program cannot drive it")
        for role, switch in c.switches.items():
            name = require(where, f"switches.{role}", switch)
            fed.add(name)
            if name not in sig.read:
                warnings.append(f"{file}: {where}: switch '{switch}' is never read by "
                                f"{program_file}")
    for s in machine.inputs:
        fed.add(require(f'input "{s.signal}"', "signal", s.signal))
    if machine.cycle_signal:
        # counted, not a consumer: an output that drives none is no surprise here
        driven.add(require("[machine]", "cycle_signal", machine.cycle_signal))
    for out in machine.no_air:      # said to switch no air: no surprise either
        driven.add(require("[machine]", "no_air", out))
    declared = {}               # upper case -> as the program spells it (the first)
    for name in sig.spelled:
        declared.setdefault(name.upper(), name)
    for out in sorted(sig.outputs - driven):
        warnings.append(f"{file}: output '{declared.get(out, out)}' of {program_file} drives "
                        "no consumer")
    for key in sorted((set(sig.inputs) & sig.read) - fed):
        warnings.append(f"{file}: input '{sig.inputs[key]}' is read by {program_file} but "
                        "nothing drives it (no [[input]] schedule, no switch): it keeps its "
                        "initial value")
    machine.warnings.extend(warnings)
    return warnings
