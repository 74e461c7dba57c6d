"""Builds a grammar's LALR tables with lark, as plain data (:mod:`.tables` keeps them).

lark analyses the grammar; nothing of lark is kept: the tables become states of terminal
or rule name -> shift target or rule number, and each rule becomes the plan of its reduce
callback (:func:`rule_plan`). Only :mod:`.tables` calls this, and only when neither the
tables shipped in :mod:`.lalr_tables` nor the user's cache match the grammar (a grammar
edited in a development tree): analysing a grammar takes about half a second.
"""
from __future__ import annotations

from lark import Lark
from lark.lexer import Lexer


class _Feed(Lexer):
    """A do-nothing lexer, so that lark builds the LALR tables without compiling a lexer
    of its own: tokens come from :class:`~.lexer.Tokenizer`, and
    :meth:`~.build.GrammarRunner.parse` drives the tables itself."""
    __future_interface__ = 2

    def __init__(self, lexer_conf):
        pass

    def lex(self, lexer_state, parser_state):
        return lexer_state.text


def analyse(grammar: str) -> tuple[int, int, list, list[dict[str, int]]]:
    """(start state, end state, rules, rows) of ``grammar``'s LALR(1) tables. A row maps
    a terminal or rule name to a number: ``n >= 0`` shifts (or, after a reduction, goes)
    to state ``n``; ``n < 0`` reduces by rule ``~n``, whose :func:`rule_plan` is
    ``rules[~n]``. States are numbered as lark numbers them."""
    parser = Lark(grammar, parser="lalr", lexer=_Feed, maybe_placeholders=True)
    table = parser.parser.parser.parser.parse_table  # frontend -> LALR_Parser -> _Parser
    start = parser.options.start[0]
    # lark numbers states in an order that may change from run to run (it walks sets):
    # number them in the order a walk from the start state meets them, symbols sorted,
    # so that the same grammar always gives the same tables
    lark_rows = {state: sorted((str(sym), action.name == "Shift", arg)
                               for sym, (action, arg) in row.items())
                 for state, row in table.states.items()}
    order = [table.start_states[start]]
    number = {order[0]: 0}
    for state in order:
        for _, shift, arg in lark_rows[state]:
            if shift and arg not in number:
                number[arg] = len(order)
                order.append(arg)
    order += [state for state in sorted(lark_rows) if state not in number]
    number.update({state: i for i, state in enumerate(order)})
    rule_numbers: dict = {}
    rules: list = []
    rows: list[dict[str, int]] = []
    for state in order:
        out = {}
        for sym, shift, arg in lark_rows[state]:
            if shift:
                out[sym] = number[arg]
                continue
            if arg not in rule_numbers:
                rule_numbers[arg] = len(rules)
                rules.append(rule_plan(arg))
            out[sym] = ~rule_numbers[arg]
        rows.append(out)
    return 0, number[table.end_states[start]], rules, rows


def rule_plan(rule) -> list:
    """How lark's tree-building semantics treat a rule's children, as plain data:
    ``[name, origin, size, expand1, plan, trailing]``. ``name`` is the alias or the rule's
    name (the builder method called), ``origin`` the rule's name (the goto after the
    reduction), ``size`` the number of symbols popped, ``expand1`` a ``?rule`` without an
    alias (one child is passed up), ``plan`` the kept children as ``[index, splice,
    nones]`` (filtered tokens dropped unless ``!rule``, ``_rule`` children spliced in,
    ``nones`` Nones for absent ``[optional]`` items inserted before it), ``trailing`` the
    Nones after the last one."""
    expansion = rule.expansion
    opts = rule.options
    if opts.empty_indices:
        bits = "".join(str(int(b)) for b in opts.empty_indices)
        empty_counts = [len(run) for run in bits.split("0")]
    else:
        empty_counts = [0] * (len(expansion) + 1)
    plan = []
    nones = 0
    for i, sym in enumerate(expansion):
        nones += empty_counts[i]
        if opts.keep_all_tokens or not (sym.is_term and sym.filter_out):
            plan.append([i, (not sym.is_term) and sym.name.startswith("_"), nones])
            nones = 0
    trailing = nones + empty_counts[len(expansion)]
    expand1 = bool(opts.expand1) and not rule.alias  # an alias disables ? (as in lark)
    return [str(rule.alias or rule.origin.name), str(rule.origin.name), len(expansion),
            expand1, plan, trailing]
