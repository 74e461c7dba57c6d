"""The parser's LALR tables: shipped current with the package, kept in the user's cache
only where the user alone can write, and rebuilt (never trusted) when stale or damaged."""
import json
import os
import stat
import zlib

import pytest
from conftest import SAMPLES

from plcpred.parser import lalr_tables, parse_st, tables
from plcpred.parser.build import GrammarRunner
from plcpred.parser.grammar import GRAMMARS, ST_GRAMMAR
from plcpred.parser.lexer import Tokenizer


@pytest.mark.parametrize("name", sorted(GRAMMARS))
def test_the_shipped_tables_are_those_of_the_grammar(name):
    # a grammar changed without `python -m plcpred.parser.tables --write` fails here
    assert lalr_tables.TABLES[name] == tables.build(GRAMMARS[name]), \
        "run: python -m plcpred.parser.tables --write"
    assert tables.decode(lalr_tables.TABLES[name], GRAMMARS[name]) is not None


def test_tables_are_built_the_same_every_time():
    # lark numbers states in an order that may change between runs; ours does not
    assert tables.build(ST_GRAMMAR) == tables.build(ST_GRAMMAR)


@pytest.fixture
def cache_home(tmp_path, monkeypatch):
    """A user cache directory of the test's own, and shipped tables that no longer match
    the grammar (as in a development tree where it was just edited)."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.setattr(lalr_tables, "TABLES", {})
    return tmp_path / "plcpred"


def _counting_builds(monkeypatch):
    built = []
    real = tables.build

    def build(grammar):
        built.append(grammar)
        return real(grammar)
    monkeypatch.setattr(tables, "build", build)
    return built


def test_stale_shipped_tables_are_built_once_then_read_from_the_users_cache(
        cache_home, monkeypatch):
    built = _counting_builds(monkeypatch)
    first = tables.load("st")
    assert len(built) == 1
    [cached] = list(cache_home.iterdir())
    assert stat.S_IMODE(cache_home.stat().st_mode) == 0o700
    assert stat.S_IMODE(cached.stat().st_mode) == 0o600
    second = tables.load("st")
    assert len(built) == 1                      # read from the cache, lark not asked
    assert (second.start, second.end) == (first.start, first.end)
    assert second.rows[first.start] == first.rows[first.start]


@pytest.mark.parametrize("damage", [
    lambda text: text[:len(text) // 2],                        # cut short
    lambda text: text.replace('":', '":9', 1),                 # a bit of the header
    lambda text: text[:-3] + "99}",                            # a bit of the body
    lambda text: "",
    lambda text: "\x00\xff not json",
    lambda text: text.replace('"format":1', '"format":0'),      # an older format
    lambda text: text.replace("IF", "FI", 1),                   # another grammar's
])
def test_a_damaged_or_foreign_cache_file_is_rebuilt_not_trusted(cache_home, monkeypatch,
                                                                 damage):
    tables.load("st")
    [cached] = list(cache_home.iterdir())
    good = cached.read_text()
    cached.write_text(damage(good))
    built = _counting_builds(monkeypatch)
    tables.load("st")
    assert len(built) == 1
    assert cached.read_text() == good           # written again, whole
    program = parse_st((SAMPLES / "prototype_rig" / "rig.st").read_text(), "rig.st")
    assert program.pous[0].name == "Rig"


def test_a_body_damaged_under_a_matching_crc_is_refused_when_read():
    # the CRC makes this all but impossible; the rows are still checked as they are read
    text = tables.build(ST_GRAMMAR)
    head, body = text.split("\n", 1)
    lines = body.split("\n")
    lines[0] = json.dumps({"NAME": 10 ** 9})
    header = json.loads(head)
    body = "\n".join(lines)
    header["crc"] = zlib.crc32(body.encode())
    found = tables.decode(json.dumps(header) + "\n" + body, ST_GRAMMAR)
    with pytest.raises(ValueError, match="malformed"):
        found.rows[0]


def test_a_cache_folder_others_may_write_to_is_neither_read_nor_written(cache_home,
                                                                        monkeypatch):
    tables.load("st")
    os.chmod(cache_home, 0o777)
    try:
        assert tables.cache_dir() is None
        built = _counting_builds(monkeypatch)
        tables.load("st")
        assert len(built) == 1                  # the file there was not read
    finally:
        os.chmod(cache_home, 0o700)


def test_a_cache_file_others_may_write_to_or_a_link_is_not_read(cache_home, monkeypatch,
                                                                tmp_path):
    tables.load("st")
    [cached] = list(cache_home.iterdir())
    os.chmod(cached, 0o666)
    built = _counting_builds(monkeypatch)
    tables.load("st")
    assert len(built) == 1
    elsewhere = tmp_path / "planted.json"
    elsewhere.write_text(cached.read_text())
    cached.unlink()
    cached.symlink_to(elsewhere)
    tables.load("st")
    assert len(built) == 2                      # the link was not followed
    assert elsewhere.read_text().startswith("{")


def test_without_a_cache_folder_the_tables_are_built_and_parsing_works(tmp_path,
                                                                      monkeypatch):
    not_a_folder = tmp_path / "file"
    not_a_folder.write_text("")
    monkeypatch.setenv("XDG_CACHE_HOME", str(not_a_folder))
    monkeypatch.setattr(lalr_tables, "TABLES", {})
    assert tables.cache_dir() is None
    text = (SAMPLES / "sfc_press.st").read_text()
    runner = GrammarRunner("st")
    assert runner.parse(Tokenizer(text), "p.st") == parse_st(text, validate=False)
