"""The ``.seq`` sequence-chart format: a plain-text SFC that is pleasant to write by hand.

It lands in the same SFC IR as IEC textual SFC and PLCopen SFC. Example::

    // Four-cylinder sequence
    sequence Station

    input  Start, A0, A1, B0, B1
    input  Stop := TRUE                 // normally-closed button: TRUE when not pressed
    output YA, YB, Knife
    var    cycles : INT := 0

    initial step Idle
        when Start AND A0 AND B0 -> ExtendA

    step ExtendA
        S YA                            // qualifier, then the variable or action it drives
        when A1 -> (ExtendB, Blow)      // simultaneous divergence

    step ExtendB
        N YB
        when B1 -> DoneB

    step Blow
        L 1500ms Knife                  // a time: T#1.5s, 1500ms or 1.5s
        after 2s -> DoneBlow            // timed wait: Blow.T >= T#2s

    step DoneB
    step DoneBlow

    join DoneB, DoneBlow -> Back        // simultaneous convergence
                                        // (optionally: join A, B when cond -> X)
    step Back
        R YA
        P CountCycle
        when A0 AND NOT Stop -> Idle    // transitions are tried in the order written
        when A0 -> Idle

    action CountCycle                   // an ST action body
        cycles := cycles + 1;
    end_action

Rules: undeclared names are errors (``plcpred check``); ``input``/``output`` declare BOOL
unless a type is given (``input Speed : INT``); conditions are ST boolean expressions over
signals and step flags (``Blow.X``) and times (``Blow.T >= T#1s``); keywords are
case-insensitive; comments are ``//``, ``(* *)`` and ``/* */``.
"""
from __future__ import annotations

from pathlib import Path

from . import ir
from .build import GrammarRunner, IRBuilder, make_action_assoc
from .errors import at
from .lexer import KEPT_KEYWORDS, KEYWORDS, Token, Tokenizer
from .literals import NS_PER_UNIT
from .names import MAX_NAME_LENGTH, is_identifier, validate_names

SEQ_KEYWORDS = KEYWORDS | {"SEQUENCE", "INPUT", "OUTPUT", "INITIAL", "STEP", "WHEN", "AFTER",
                           "GOTO", "JOIN", "ACTION"}
SEQ_KEPT = KEPT_KEYWORDS | {"SEQUENCE", "INPUT", "OUTPUT", "INITIAL", "WHEN", "AFTER", "JOIN"}

_UNITS = set(NS_PER_UNIT)


class _Decl:
    __slots__ = ("kind", "decls", "pos")

    def __init__(self, kind, decls, pos):
        self.kind, self.decls, self.pos = kind, decls, pos


class SeqBuilder(IRBuilder):
    def header(self, tok, name):
        return ("header", str(name))

    def seq_var(self, name, type_, init):
        return ir.VarDecl(str(name), type_ or ir.NamedType("BOOL"), init, pos=self._pos(name))

    def seq_decl(self, tok, *decls):
        kind = {"INPUT": "VAR_INPUT", "OUTPUT": "VAR_OUTPUT", "VAR": "VAR"}[tok.type]
        return _Decl(kind, list(decls), self._pos(tok))

    def seq_step(self, initial, tok, name, *items):
        step = ir.Step(str(name), initial is not None, pos=self._pos(tok))
        whens = []
        for item in items:
            if isinstance(item, ir.ActionAssoc):
                step.actions.append(item)
            else:
                whens.append(item)
        transitions = []
        for priority, (cond, targets, pos) in enumerate(whens):
            transitions.append(ir.Transition([step.name], targets, cond, priority, pos=pos))
        return (step, transitions)

    def seq_assoc(self, qualifier, time, target):
        pos = self._pos(qualifier)
        rest = [self.time_lit(time)] if time is not None else []
        return make_action_assoc(str(target), str(qualifier), rest, pos, self._err)

    def seq_when(self, tok, cond, targets):
        return (cond, targets, self._pos(tok))

    def seq_after(self, tok, time, _when, cond, targets):
        # the step's own name is not known here; the placeholder is filled in seq_step's
        # caller (start) once the step is built
        wait = ir.Binary(">=", ir.Member(ir.Name("<step>"), "T"), self.time_lit(time))
        full = wait if cond is None else ir.Binary("AND", wait, cond)
        return (full, targets, self._pos(tok))

    def seq_targets(self, *names):
        return [str(n) for n in names]

    def seq_join(self, tok, *rest):
        *sources, _when, cond, targets = rest
        return ir.Transition([str(s) for s in sources], targets,
                             cond if cond is not None else ir.Literal(True, "BOOL"),
                             pos=self._pos(tok))

    def seq_action(self, tok, name, body):
        return ir.SfcAction(str(name), body, pos=self._pos(tok))

    def start(self, header, *items):
        name = header[1] if header else None
        blocks: list[ir.VarBlock] = []
        steps, transitions, actions = [], [], []
        for item in items:
            if isinstance(item, _Decl):
                blocks.append(ir.VarBlock(item.kind, item.decls, pos=item.pos))
            elif isinstance(item, tuple):
                step, trs = item
                for t in trs:
                    _name_step_timer(t.condition, step.name)
                steps.append(step)
                transitions.extend(trs)
            elif isinstance(item, ir.Transition):
                transitions.append(item)
            else:
                actions.append(item)
        return name, blocks, steps, transitions, actions  # transitions in file order


def _name_step_timer(cond, step_name: str):
    """Replace the ``<step>`` placeholder of ``after`` waits with the step's name."""
    if isinstance(cond, ir.Binary):
        if (cond.op == ">=" and isinstance(cond.left, ir.Member)
                and cond.left.base == ir.Name("<step>")):
            cond.left.base = ir.Name(step_name, pos=cond.left.base.pos)
        _name_step_timer(cond.left, step_name)
        _name_step_timer(cond.right, step_name)


def _with_bare_durations(tokens):
    """``2s``, ``1500ms``, ``1.5s`` (a number directly followed by a unit) become time
    literals, so that charts can be written without ``T#``."""
    pending = None
    for tok in tokens:
        if pending is not None:
            if (tok.type == "NAME" and tok.value.lower() in _UNITS and tok.line == pending.line
                    and tok.column == pending.column + len(pending.value)):
                yield Token("TIME_LIT", f"TIME#{pending.value}{tok.value}", pending.line,
                            pending.column)
                pending = None
                continue
            yield pending
            pending = None
        if tok.type in ("INTEGER", "REAL"):
            pending = tok
        else:
            yield tok
    if pending is not None:
        yield pending


_RUNNER = GrammarRunner("seq", SeqBuilder)


def parse_seq(text: str, filename: str = "<input>") -> ir.Program:
    """Parse a ``.seq`` sequence chart into a Program with one SFC PROGRAM POU."""
    tokenizer = Tokenizer(text, filename, keywords=SEQ_KEYWORDS, context_keywords={},
                          kept=SEQ_KEPT)
    name, blocks, steps, transitions, actions = _RUNNER.parse(
        _with_bare_durations(tokenizer), filename)
    initial = [s for s in steps if s.initial]
    if len(initial) != 1:
        pos = (initial[1].pos if len(initial) > 1
               else (steps[0].pos if steps else ir.Pos(filename, 1, 1)))
        raise at(pos, f"a sequence needs exactly one 'initial step', found {len(initial)}")
    pou_name = name or _identifier(Path(filename).stem)
    pou = ir.Pou("PROGRAM", pou_name, blocks, ir.Sfc(steps, transitions, actions,
                                                      pos=ir.Pos(filename, 1, 1)),
                 pos=ir.Pos(filename, 1, 1))
    program = ir.Program(pous=[pou])
    program.pragmas = []
    program.source = filename
    return validate_names(program)


def _identifier(stem: str) -> str:
    text = "".join(c if c.isascii() and (c.isalnum() or c == "_") else "_" for c in stem)
    text = text[:MAX_NAME_LENGTH - 4]
    if not is_identifier(text):
        text = "SEQ_" + text
    return text
