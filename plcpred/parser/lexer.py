"""A hand-written tokenizer for IEC 61131-3 text, feeding lark's LALR parser.

Why not lark's own lexer: IEC comments ``(* ... *)`` nest, which no regular expression can
match, and a few words (STEP, TRANSITION, ACTION, FROM, TASK) are keywords only in files
that use the constructs they open, because engineers routinely name variables ``Step``.
Keywords are case-insensitive; a keyword token's type is its upper-case spelling.
"""
from __future__ import annotations

import itertools
import re

from .errors import ProgramError


class Token:
    """A token: ``type`` (grammar terminal), ``value`` (source text), 1-based position.
    Lighter than lark's Token, which costs more to build than everything else the
    tokenizer does."""
    __slots__ = ("type", "value", "line", "column")

    def __init__(self, type_: str, value: str, line: int, column: int):
        self.type = type_
        self.value = value
        self.line = line
        self.column = column

    def __str__(self) -> str:
        return self.value

    def __len__(self) -> int:
        return len(self.value)

    def __repr__(self) -> str:
        return f"Token({self.type!r}, {self.value!r}, {self.line}:{self.column})"

KEYWORDS = frozenset("""
PROGRAM END_PROGRAM FUNCTION END_FUNCTION FUNCTION_BLOCK END_FUNCTION_BLOCK METHOD END_METHOD
PROPERTY END_PROPERTY INTERFACE END_INTERFACE EXTENDS IMPLEMENTS END_GET END_SET
VAR VAR_INPUT VAR_OUTPUT VAR_IN_OUT VAR_TEMP VAR_GLOBAL VAR_EXTERNAL VAR_STAT VAR_INST
VAR_CONFIG VAR_ACCESS VAR_GENERIC END_VAR CONSTANT RETAIN NON_RETAIN PERSISTENT AT
TYPE END_TYPE STRUCT END_STRUCT UNION END_UNION ARRAY OF POINTER REFERENCE TO REF_TO STRING WSTRING
IF THEN ELSIF ELSE END_IF CASE END_CASE FOR BY DO END_FOR WHILE END_WHILE REPEAT UNTIL
END_REPEAT EXIT CONTINUE RETURN JMP
AND OR XOR NOT MOD AND_THEN OR_ELSE TRUE FALSE
CONFIGURATION END_CONFIGURATION RESOURCE END_RESOURCE
PUBLIC PRIVATE PROTECTED INTERNAL ABSTRACT FINAL
INITIAL_STEP END_STEP END_TRANSITION END_ACTION
""".split())

# Keyword tokens the grammar keeps (they open a construct and give the node its position, or
# they are operators and values); every other keyword reaches the parser as ``_KEYWORD`` and
# is filtered out of the parse tree.
KEPT_KEYWORDS = frozenset("""
PROGRAM FUNCTION FUNCTION_BLOCK METHOD PROPERTY INTERFACE TYPE CONFIGURATION RESOURCE TASK
VAR VAR_INPUT VAR_OUTPUT VAR_IN_OUT VAR_TEMP VAR_GLOBAL VAR_EXTERNAL VAR_STAT VAR_INST
VAR_CONFIG VAR_ACCESS VAR_GENERIC CONSTANT RETAIN NON_RETAIN PERSISTENT STRING WSTRING POINTER REFERENCE REF_TO
IF CASE FOR WHILE REPEAT EXIT CONTINUE RETURN JMP AND OR XOR NOT MOD AND_THEN OR_ELSE TRUE FALSE
PUBLIC PRIVATE PROTECTED INTERNAL ABSTRACT FINAL INITIAL_STEP STEP TRANSITION ACTION
END_GET END_SET STRUCT UNION CLASS
""".split())

# Keywords switched on only when the file contains the word that closes their construct.
CONTEXT_KEYWORDS = {
    "STEP": "END_STEP",
    "TRANSITION": "END_TRANSITION",
    "FROM": "END_TRANSITION",
    "ACTION": "END_ACTION",
    "TASK": "END_CONFIGURATION",
    "CLASS": "END_CLASS",
    "END_CLASS": "END_CLASS",
    # CODESYS/TwinCAT exception handling
    "__TRY": "__ENDTRY",
    "__CATCH": "__ENDTRY",
    "__FINALLY": "__ENDTRY",
    "__ENDTRY": "__ENDTRY",
}
# token types of keywords that are not named after themselves
_KEYWORD_TYPES = {"__TRY": "TRY", "__CATCH": "_CATCH", "__FINALLY": "_FINALLY",
                  "__ENDTRY": "_ENDTRY"}
# ``__CATCH(exc)``: one token, so that a statement in parentheses may follow a bare __CATCH
_CATCH_VARIABLE = re.compile(r"[ \t]*\([ \t]*([A-Za-z_][A-Za-z0-9_]*)[ \t]*\)")

ELEMENTARY_TYPES = frozenset("""
BOOL SINT INT DINT LINT USINT UINT UDINT ULINT BYTE WORD DWORD LWORD REAL LREAL
TIME LTIME DATE LDATE TIME_OF_DAY TOD LTIME_OF_DAY LTOD DATE_AND_TIME DT LDATE_AND_TIME LDT
STRING WSTRING CHAR WCHAR BIT
""".split())

TIME_PREFIXES = {"T": "TIME", "TIME": "TIME", "LT": "LTIME", "LTIME": "LTIME"}
TOD_PREFIXES = {"TOD": "TOD", "TIME_OF_DAY": "TOD", "LTOD": "LTOD", "LTIME_OF_DAY": "LTOD"}
DATE_PREFIXES = {"D": "DATE", "DATE": "DATE", "LD": "LDATE", "LDATE": "LDATE"}
DT_PREFIXES = {"DT": "DT", "DATE_AND_TIME": "DT", "LDT": "LDT", "LDATE_AND_TIME": "LDT"}

# Operators keep their token (the expression builder needs them); punctuation is filtered.
OPERATORS = {
    ":=": "_ASSIGN", "=>": "_OUTASSIGN", "<=": "LE", ">=": "GE", "<>": "NE", "**": "POW",
    "..": "_DOTDOT", "?=": "_ATTEMPT", "+": "PLUS", "-": "MINUS", "*": "STAR", "/": "SLASH",
    "<": "LT", ">": "GT", "=": "EQ", "(": "_LPAR", ")": "_RPAR", "[": "_LSQB", "]": "_RSQB",
    ",": "_COMMA", ";": "_SEMI", ":": "_COLON", ".": "_DOT", "^": "_CARET", "&": "AMP",
    "->": "_ARROW",
}

_VARIABLE_END = {"NAME", "_RSQB", "_RPAR", "_CARET"}
# keywords that vendors let programs use as names, when the context says it is one
SOFT_KEYWORDS = frozenset({"INTERNAL", "REFERENCE", "CONFIGURATION", "RESOURCE", "PROGRAM",
                           "CLASS", "PUBLIC", "PRIVATE", "PROTECTED", "ABSTRACT", "FINAL"})
_AFTER_A_NAME = {"_COLON", "_ASSIGN", "_SEMI", "_COMMA", "_RPAR", "_DOT", "_LSQB", "_OUTASSIGN",
                 "_RSQB", "PLUS", "MINUS", "STAR", "SLASH", "EQ", "NE", "LT", "GT", "LE", "GE",
                 "_CARET", "_THEN", "_DO"}
_BEFORE_A_NAME = {"_ASSIGN", "_LPAR", "_COMMA", "PLUS", "MINUS", "STAR", "SLASH", "EQ", "NE",
                  "LT", "GT", "LE", "GE", "_LSQB", "_OUTASSIGN"}
_WORD = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
# words whose token Tokenizer._word works out (REF=, S= and R=, a CATCH variable) or that
# may be read as a name after all (Tokenizer._neighbours); other names and keywords are
# read on the spot
_READ_AGAIN = SOFT_KEYWORDS | {"REF", "S", "R", "STRING", "WSTRING", "__CATCH"}

# Leading white space is part of every match, which halves the number of matches. Digits
# are ASCII ([0-9], not \d): int() of a literal must mean what the PLC reads.
_MASTER = re.compile(r"""\s*(?:
 (?P<lc>//[^\n]*)
|(?P<bc>/\*)
|(?P<pc>\(\*)
|(?P<pragma>\{)
|(?P<ident>[A-Za-z_][A-Za-z0-9_]*)
|(?P<num>[0-9][0-9_]*(?:\#[0-9A-Fa-f_]+|(?P<frac>\.[0-9][0-9_]*)?(?P<exp>[eE][+-]?[0-9]+)?))
|(?P<addr>%[IQM](?:[XBWDL]?(?:[0-9]+(?:\.[0-9]+)*|\*)|\*))
|(?P<part>%[Xx][0-9]+)
|(?P<str>'(?:[^'$]|\$[\s\S]|'')*')
|(?P<wstr>"(?:[^"$]|\$[\s\S]|"")*")
|(?P<op>:=|=>|<=|>=|<>|\*\*|\.\.|\?=|->|[-+*/<>=()\[\],;:.^&])
)""", re.X)

_TIME_VALUE = re.compile(
    r"[-+]?(?:[0-9][0-9_]*(?:\.[0-9]+)?(?:d|h|ms|m|s|us|ns)_?)+(?![A-Za-z0-9_])", re.I)
_TOD_VALUE = re.compile(r"[0-9]+:[0-9]+(?::[0-9]+(?:\.[0-9]+)?)?")
_DATE_VALUE = re.compile(r"[0-9]{4}-[0-9]{1,2}-[0-9]{1,2}")
_DT_VALUE = re.compile(r"[0-9]{4}-[0-9]{1,2}-[0-9]{1,2}-[0-9]+:[0-9]+(?::[0-9]+(?:\.[0-9]+)?)?")
_TYPED_VALUE = re.compile(
    r"[-+]?(?:[0-9][0-9_]*\#[0-9A-Fa-f_]+|[0-9][0-9_]*(?:\.[0-9][0-9_]*)?(?:[eE][+-]?[0-9]+)?)"
    r"|TRUE\b|FALSE\b|'(?:[^'$]|\$[\s\S]|'')*'|\"(?:[^\"$]|\$[\s\S]|\"\")*\"", re.I)
_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


class Tokenizer:
    """Turns source text into lark Tokens. ``pragmas`` collects ``{...}`` blocks with their
    positions. ``keywords`` is the reserved-word set (ST by default)."""

    def __init__(self, text: str, filename: str = "<input>", keywords=KEYWORDS,
                 context_keywords=CONTEXT_KEYWORDS, kept=KEPT_KEYWORDS, origin=None):
        self.text = text
        self.filename = filename
        # (line of the text, line in the file, its first column): a fragment of a larger
        # file (a PLCopen ST body) placed where it stands there, without padding it
        self.origin = origin
        upper = text.upper()
        enabled = {kw for kw, closer in context_keywords.items() if closer in upper}
        # keyword (upper case) -> token type
        self.keywords = {kw: _KEYWORD_TYPES.get(kw, kw if kw in kept else "_" + kw)
                         for kw in keywords | enabled}
        self.pragmas: list[tuple[str, int, int]] = []

    def error(self, message: str, line: int, col: int) -> ProgramError:
        return ProgramError(message, self.filename, *self.place(line, col))

    def place(self, line: int, col: int) -> tuple[int, int]:
        """Where a position of the text lies in its file (``origin``): lines before the
        origin's (a header of the front end's own) at the origin itself."""
        if self.origin is None:
            return line, col
        text_line, file_line, file_col = self.origin
        if line < text_line:
            return file_line, file_col
        if line == text_line:
            return file_line, col + file_col - 1
        return line - text_line + file_line, col

    def __iter__(self):
        """Tokens, with two readings that need a neighbour:

        * the CODESYS/TwinCAT set and reset assignments ``x S= c;`` and ``x R= c;`` are
          one token: an ``S`` or ``R`` right against ``=`` after the end of a variable (a
          name, ``]``, ``)`` or ``^``);
        * a keyword is a name where the vendors allow one: after ``.`` (``st.Program``),
          STRING and WSTRING before ``.`` or ``:`` (a GVL's ``WString : WideStrings;``
          and ``WString.Concat2(...)``), and, for the modifier-like keywords of
          :data:`SOFT_KEYWORDS`, where only a name can stand (``Internal : BOOL;``,
          ``x := Reference + 1;``).

        The text is read whole when iteration starts (one loop, no generator per token:
        the parser benchmark's largest share); an error in it is raised where a token by
        token reading would have raised it, after the tokens before it."""
        raw, marks, error = self._scan()
        tokens = self._neighbours(raw, marks, error)
        if self.origin is not None:
            tokens = [Token(t.type, t.value, *self.place(t.line, t.column)) for t in tokens]
        return iter(tokens) if error is None else itertools.chain(tokens, _raising(error))

    def _neighbours(self, raw: list, marks: list[int], error) -> list:
        """``raw`` with the readings of :meth:`__iter__` applied at the tokens ``marks``
        lists (the only ones they can change), in order, each seeing the tokens before it
        as read and the one after it as scanned. With an ``error``, the last token (and an
        ``S=`` it ends) is left out: reading it needed the token after it."""
        n = len(raw)
        for i in marks:
            tok = raw[i]
            prev = raw[i - 1] if i else None
            if prev is None and i > 1:      # the '=' of an S= before it
                prev = raw[i - 2]
            nxt = raw[i + 1] if i + 1 < n else None
            if tok.type == "NAME":
                if prev is not None and prev.type in _VARIABLE_END \
                        and tok.value.upper() in ("S", "R") and nxt is not None \
                        and nxt.type == "EQ" and nxt.line == tok.line \
                        and nxt.column == tok.column + 1:
                    raw[i] = Token("_SETASSIGN" if tok.value.upper() == "S" else
                                   "_RESETASSIGN", tok.value.upper() + "=", tok.line,
                                   tok.column)
                    raw[i + 1] = None
            elif _WORD.fullmatch(tok.value) and (
                    (prev is not None and prev.type == "_DOT")
                    # a namespace or block named like a type: String.Concat2(...)
                    or (tok.type in ("STRING", "WSTRING") and nxt is not None
                        and nxt.type in ("_DOT", "_COLON"))
                    or (tok.value.upper() in SOFT_KEYWORDS and (
                        nxt is None or nxt.type in _AFTER_A_NAME
                        or (prev is not None and prev.type in _BEFORE_A_NAME)))):
                raw[i] = Token("NAME", tok.value, tok.line, tok.column)
        if error is not None and n:
            del raw[n - 2 if raw[n - 1] is None else n - 1:]
        return [t for t in raw if t is not None] if len(marks) else raw

    def _scan(self) -> tuple[list, list[int], ProgramError | None]:
        """(every token of the text as scanned, the positions of those
        :meth:`_neighbours` may read otherwise, the error that stopped the scan or None).
        One loop on purpose: it runs once per token of every program read."""
        text = self.text
        n = len(text)
        pos = 0
        line = 1
        line_start = 0
        keywords = self.keywords
        match = _MASTER.match
        ops = OPERATORS
        tokens: list = []
        append = tokens.append
        marks: list[int] = []
        try:
            while pos < n:
                m = match(text, pos)
                if m is None:
                    self._no_token(pos, line, line_start)   # raises, or the text ends
                    break
                kind = m.lastgroup
                start = m.start(kind)
                if start != pos and text.find("\n", pos, start) >= 0:
                    line += text.count("\n", pos, start)
                    line_start = text.rindex("\n", pos, start) + 1
                pos = start
                end = m.end()
                if kind == "op":
                    value = text[pos:end]
                    append(Token(ops[value], value, line, pos - line_start + 1))
                elif kind == "ident":
                    word = text[pos:end]
                    upper = word.upper()
                    toktype = keywords.get(upper)
                    if (end < n and text[end] == "#") or upper in _READ_AGAIN or (
                            toktype is not None and tokens and tokens[-1].type == "_DOT"):
                        end = self._word(pos, end, line, pos - line_start + 1, tokens, marks)
                    else:
                        append(Token(toktype or "NAME", word, line, pos - line_start + 1))
                elif kind == "num":
                    value = text[pos:end]
                    append(Token("REAL" if "." in value or "#" not in value and (
                        "e" in value or "E" in value) else "INTEGER", value, line,
                        pos - line_start + 1))
                else:
                    end, line, line_start = self._other(kind, m, pos, line, line_start,
                                                        append)
                pos = end
        except ProgramError as e:
            return tokens, marks, e
        return tokens, marks, None

    def _no_token(self, pos: int, line: int, line_start: int) -> None:
        """Where nothing matches: white space to the end of the text, or a character no
        token starts with (an error)."""
        text = self.text
        n = len(text)
        stop = n - len(text[pos:].lstrip())  # first non-space character, or n
        nls = text.count("\n", pos, stop)
        if nls:
            line += nls
            line_start = text.rindex("\n", pos, stop) + 1
        if stop < n:
            raise self.error(f"unexpected character {text[stop]!r}", line,
                             stop - line_start + 1)

    def _word(self, pos: int, end: int, line: int, col: int, tokens: list,
              marks: list[int]) -> int:
        """The token of an identifier-like word at ``pos``: a typed, time or enumerated
        literal, a keyword, ``REF=``, a CATCH variable or a name; where it ends."""
        text = self.text
        word = text[pos:end]
        if end < len(text) and text[end] == "#":
            tok, end = self._hash_literal(word, end, line, col)
            tokens.append(tok)
            return end
        upper = word.upper()
        toktype = self.keywords.get(upper)
        if toktype is None:
            if upper == "REF" and text.startswith("=", end) and not text.startswith("=>", end):
                tokens.append(Token("_REFASSIGN", "REF=", line, col))
                return end + 1
            if upper == "S" or upper == "R":
                marks.append(len(tokens))
            tokens.append(Token("NAME", word, line, col))
            return end
        if toktype == "_CATCH" and (m2 := _CATCH_VARIABLE.match(text, end)):
            marks.append(len(tokens))
            tokens.append(Token("CATCH_VAR", m2.group(1), line, col))
            return m2.end()
        if (upper in SOFT_KEYWORDS or toktype == "STRING" or toktype == "WSTRING"
                or (tokens and tokens[-1].type == "_DOT")):
            marks.append(len(tokens))
        tokens.append(Token(toktype, word, line, col))
        return end

    def _other(self, kind: str, m, pos: int, line: int, line_start: int, append):
        """Strings, addresses, comments, pragmas and inline code at ``pos``: (where they
        end, the line and the line's start there)."""
        text = self.text
        col = pos - line_start + 1
        end = m.end()
        value = m.group(kind)
        if kind in ("str", "wstr"):
            append(Token("STRING_LIT" if kind == "str" else "WSTRING_LIT", value, line, col))
        elif kind == "addr":
            append(Token("ADDRESS", value, line, col))
            return end, line, line_start
        elif kind == "part":  # IEC partial access w.%X3: the bit access w.3
            append(Token("INTEGER", value[2:], line, col))
            return end, line, line_start
        elif kind == "lc":
            return end, line, line_start
        elif kind == "pc":
            end = self._nested_comment_end(pos, line, col)
        elif kind == "bc":
            end = text.find("*/", pos + 2)
            if end < 0:
                raise self.error("comment '/*' is never closed", line, col)
            end += 2
        elif text.startswith("{{", pos):  # Beremiz/matiec inline C: a statement
            end = text.find("}}", pos + 2)
            if end < 0:
                raise self.error("inline code '{{' is never closed", line, col)
            end += 2
            append(Token("INLINE_CODE", text[pos:end], line, col))
        else:  # pragma
            end = text.find("}", pos + 1)
            if end < 0:
                raise self.error("pragma '{' is never closed", line, col)
            end += 1
            self.pragmas.append((text[pos:end], line, col))
        chunk = text[pos:end]
        nls = chunk.count("\n")
        if nls:
            line += nls
            line_start = pos + chunk.rfind("\n") + 1
        return end, line, line_start

    def _nested_comment_end(self, pos: int, line: int, col: int) -> int:
        """Where a ``(*`` comment ends. CODESYS and TwinCAT nest comments; matiec (Beremiz,
        OpenPLC) does not, so a ``(*`` inside a comment opens nothing there. Nesting is
        read first; a comment that nesting leaves open to the end of the file but that a
        ``*)`` closes is read the non-nesting way."""
        text = self.text
        depth = 0
        i = pos
        while True:
            a = text.find("(*", i)
            b = text.find("*)", i)
            if b < 0:
                first = text.find("*)", pos + 2)
                if first >= 0:
                    return first + 2
                raise self.error("comment '(*' is never closed", line, col)
            if 0 <= a < b:
                depth += 1
                i = a + 2
            else:
                depth -= 1
                i = b + 2
                if depth == 0:
                    return i

    def _hash_literal(self, word: str, hash_pos: int, line: int, col: int):
        """``PREFIX#value``: a typed literal, a time/date literal, or ``Enum#Value``."""
        text = self.text
        upper = word.upper()
        vstart = hash_pos + 1
        for table, regex, tokname in ((TIME_PREFIXES, _TIME_VALUE, "TIME_LIT"),
                                      (DT_PREFIXES, _DT_VALUE, "DT_LIT"),
                                      (TOD_PREFIXES, _TOD_VALUE, "TOD_LIT"),
                                      (DATE_PREFIXES, _DATE_VALUE, "DATE_LIT")):
            if upper in table:
                m = regex.match(text, vstart)
                if m is None:
                    raise self.error(f"malformed {table[upper]} literal after '{word}#'",
                                     line, col + len(word) + 1)
                return Token(tokname, f"{table[upper]}#{m.group()}", line, col), m.end()
        if upper in ELEMENTARY_TYPES:
            m = _TYPED_VALUE.match(text, vstart)
            if m is None:
                raise self.error(f"malformed {upper} literal after '{word}#'",
                                 line, col + len(word) + 1)
            return Token("TYPED_LIT", f"{upper}#{m.group()}", line, col), m.end()
        m = _IDENT.match(text, vstart)
        if m is None:
            raise self.error(f"expected an enumeration value after '{word}#'",
                             line, col + len(word) + 1)
        return Token("ENUM_LIT", f"{word}#{m.group()}", line, col), m.end()


def _raising(error: ProgramError):
    """An iterator that raises ``error`` when asked for its first item."""
    raise error
    yield  # a generator: the error is raised when it is first advanced
