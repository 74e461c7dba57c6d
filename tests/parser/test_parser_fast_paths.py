"""The parser's fast paths behave as the general code they stand for: literals decoded in
integer arithmetic as Fraction, datetime and calendar decode them, IR node methods made
at once as dataclass makes them one class at a time, a lexer that reads the text whole
but reports an error where a token-by-token reading would, and the parser's shortcuts
(runs of pass-through reductions) giving the same trees."""
import calendar
import dataclasses
import datetime
import inspect
import random
from fractions import Fraction

import pytest
from conftest import SAMPLES

from plcpred.parser import ProgramError, ir, literals, parse_st
from plcpred.parser.lexer import Tokenizer
from plcpred.parser.names import validate_names

# ----------------------------------------------------------------------- literals


def _reference_duration(text):
    sign = -1 if text[:1] == "-" else 1
    text = text.lstrip("+-")
    total = Fraction(0)
    for m in literals._TIME_PART.finditer(text):
        total += Fraction(m.group(1).replace("_", "")) * literals.NS_PER_UNIT[
            m.group(2).lower()]
    return sign * round(total)


def test_durations_are_exact_and_round_half_to_even_as_fractions_do():
    rnd = random.Random(3)
    for _ in range(20_000):
        parts = []
        for _ in range(rnd.randint(1, 4)):
            number = str(rnd.randint(0, 10 ** rnd.randint(0, 9)))
            if rnd.random() < 0.5:
                number += "." + "".join(rnd.choice("0123456789")
                                        for _ in range(rnd.randint(1, 12)))
            parts.append(number + rnd.choice(["d", "h", "m", "s", "ms", "us", "ns", "MS"]))
        text = rnd.choice(["", "-", "+"]) + "".join(parts)
        expected = _reference_duration(text)
        if abs(expected) > literals.DURATION_MAX_NS:
            with pytest.raises(ValueError, match="longer than LTIME holds"):
                literals.parse_duration_ns(text)
        else:
            assert literals.parse_duration_ns(text) == expected, text
    assert literals.parse_duration_ns("2.5ns") == 2 and literals.parse_duration_ns("3.5ns") == 4
    assert literals.parse_duration_ns("-0.5ns") == 0


def test_times_of_day_dates_and_their_errors_are_those_of_the_standard_library():
    rnd = random.Random(4)
    for _ in range(5_000):
        h, m, s = rnd.randint(0, 23), rnd.randint(0, 59), rnd.randint(0, 59)
        frac = "".join(rnd.choice("0123456789") for _ in range(rnd.randint(0, 9)))
        text = f"{h}:{m}:{s}" + (f".{frac}" if frac else "")
        expected = round(((h * 60 + m) * 60 + Fraction(f"{s}.{frac or 0}")) * 10 ** 9)
        assert literals.parse_tod_ns(text) == expected
    for _ in range(20_000):
        y, mo, d = rnd.choice([rnd.randint(0, 9999), 1900, 2000, 2100]), rnd.randint(0, 13), \
            rnd.randint(0, 32)
        text = f"{y:04d}-{mo}-{d}"
        try:
            datetime.date(y, mo, d)
        except ValueError as e:
            with pytest.raises(ValueError) as ours:
                literals.parse_date_ns(text)
            assert str(ours.value) == f"date {text!r} does not exist ({e})"
        else:
            assert literals.parse_date_ns(text) == calendar.timegm((y, mo, d, 0, 0, 0)) * 10**9


def test_dates_print_back_as_the_standard_library_counts_days():
    rnd = random.Random(5)
    first, last = datetime.date(1, 1, 1), datetime.date(9999, 12, 31)
    epoch = datetime.date(1970, 1, 1)
    for days in [(first - epoch).days, (last - epoch).days, 0, -1, 59, 60] + [
            rnd.randint((first - epoch).days, (last - epoch).days) for _ in range(20_000)]:
        d = epoch + datetime.timedelta(days=days)
        assert literals._civil_from_days(days) == (d.year, d.month, d.day)
    for days in [(first - epoch).days - 1, (last - epoch).days + 1]:
        with pytest.raises(OverflowError):
            literals._civil_from_days(days)


# ----------------------------------------------------------------------- IR nodes

def _reference(cls):
    """The dataclass that ``@dataclass(slots=True)`` makes of ``cls``'s fields."""
    specs = []
    for f in dataclasses.fields(cls):
        kw = {"compare": f.compare, "repr": f.repr, "kw_only": f.kw_only}
        if f.default is not dataclasses.MISSING:
            kw["default"] = f.default
        if f.default_factory is not dataclasses.MISSING:
            kw["default_factory"] = f.default_factory
        specs.append((f.name, f.type, dataclasses.field(**kw)))
    return dataclasses.make_dataclass(cls.__name__, specs, slots=True)


NODE_CLASSES = [c for c in vars(ir).values()
                if isinstance(c, type) and dataclasses.is_dataclass(c)]


@pytest.mark.parametrize("cls", NODE_CLASSES, ids=lambda c: c.__name__)
def test_a_node_is_made_compared_and_shown_as_a_dataclass(cls):
    ref = _reference(cls)
    mine, theirs = inspect.signature(cls), inspect.signature(ref)
    assert [(p.name, p.kind, repr(p.default), p.annotation)
            for p in mine.parameters.values()] == \
        [(p.name, p.kind, repr(p.default), p.annotation)
         for p in theirs.parameters.values()]
    assert cls.__hash__ is None and cls.__match_args__ == ref.__match_args__
    required = [p.name for p in mine.parameters.values()
                if p.default is inspect.Parameter.empty]
    rnd = random.Random(cls.__name__)
    for _ in range(20):
        values = {name: rnd.choice([1, "a", None, [1, 2], 2.5]) for name in required}
        other = {name: rnd.choice([1, "a", None, [1, 2], 2.5]) for name in required}
        where = {"pos": ir.Pos("f", 1, 1)} if "pos" in mine.parameters else {}
        a, b = cls(**values), cls(**other, **where)
        ra, rb = ref(**values), ref(**other, **where)
        assert repr(a) == repr(ra) and repr(b) == repr(rb)
        assert (a == b) == (ra == rb) and (a != b) == (ra != rb)
        assert a == cls(**values) and (a == 5) is False
        for f in dataclasses.fields(cls):
            assert getattr(a, f.name) == getattr(ra, f.name)
            if f.default_factory is not dataclasses.MISSING:
                assert getattr(a, f.name) is not getattr(cls(**values), f.name)


def test_a_node_inside_itself_shows_as_dots():
    block = ir.VarBlock("VAR", [])
    block.decls.append(block)
    assert repr(block) == "VarBlock(kind='VAR', decls=[...], qualifiers=[])"


# ----------------------------------------------------------------------- the lexer

def _read(text):
    out = []
    try:
        for t in Tokenizer(text):
            out.append((t.type, t.value, t.line, t.column))
    except ProgramError as e:
        out.append(str(e))
    return out


def test_a_syntax_error_before_a_lexical_one_is_reported_first():
    text = "PROGRAM P\nVAR x : INT; END_VAR\nx := ;\nx := 1 ? 2;\nEND_PROGRAM\n"
    with pytest.raises(ProgramError) as e:
        parse_st(text, "c.st")
    assert str(e.value) == "c.st:3:6: unexpected ';'; expected an expression"
    assert [str(m) for m in e.value.more] == ["c.st:4:8: unexpected character '?'"]
    # the token before the bad character is not read: telling it needed the next one
    assert _read(text)[-2:] == [("_ASSIGN", ":=", 4, 3),
                                "<input>:4:8: unexpected character '?'"]


def test_set_and_reset_assignments_and_names_that_are_keywords_elsewhere():
    assert _read("x S= TRUE; y R= z;")[:5] == [
        ("NAME", "x", 1, 1), ("_SETASSIGN", "S=", 1, 3), ("TRUE", "TRUE", 1, 6),
        ("_SEMI", ";", 1, 10), ("NAME", "y", 1, 12)]
    assert _read("x S= ?") == [("NAME", "x", 1, 1), "<input>:1:6: unexpected character '?'"]
    assert _read("a.Program := Internal; String.Concat2(x); WString : INT;") == [
        ("NAME", "a", 1, 1), ("_DOT", ".", 1, 2), ("NAME", "Program", 1, 3),
        ("_ASSIGN", ":=", 1, 11), ("NAME", "Internal", 1, 14), ("_SEMI", ";", 1, 22),
        ("NAME", "String", 1, 24), ("_DOT", ".", 1, 30), ("NAME", "Concat2", 1, 31),
        ("_LPAR", "(", 1, 38), ("NAME", "x", 1, 39), ("_RPAR", ")", 1, 40),
        ("_SEMI", ";", 1, 41), ("NAME", "WString", 1, 43), ("_COLON", ":", 1, 51),
        ("NAME", "INT", 1, 53), ("_SEMI", ";", 1, 56)]


def test_a_fragment_is_placed_where_it_stands_in_its_file():
    toks = list(Tokenizer("HEAD\nx S= 1;", "f.xml", origin=(2, 40, 7)))
    assert [(t.type, t.line, t.column) for t in toks] == [
        ("NAME", 40, 7), ("NAME", 40, 7), ("_SETASSIGN", 40, 9), ("INTEGER", 40, 12),
        ("_SEMI", 40, 13)]


# ----------------------------------------------------------------------- the parser

def test_trees_do_not_depend_on_what_was_parsed_before():
    # runs of pass-through reductions are remembered between parses: a tree is the same
    # whether a file is read first or after others
    text = (SAMPLES / "codesys_pick_place.st").read_text()
    first = parse_st(text, "a.st")
    for sample in sorted(SAMPLES.glob("*.st")):
        parse_st(sample.read_text(), sample.name)
    again = parse_st(text, "a.st")
    assert again == first and repr(again) == repr(first)
    assert validate_names(again) is again
