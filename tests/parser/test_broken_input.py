"""Broken programs give a positioned ProgramError, never another exception.

Mutations of every sample (a token deleted, duplicated or swapped, or the file cut short)
are parsed and checked; a fixed seed keeps the run repeatable.
"""
import random

import pytest

from plcpred.parser import ProgramError
from plcpred.parser.check import check_program
from plcpred.parser.plcopen import parse_plcopen
from plcpred.parser.seq import parse_seq
from plcpred.parser.st import parse_st
from conftest import SAMPLES

PARSERS = {".st": parse_st, ".seq": parse_seq, ".xml": parse_plcopen}
FILES = sorted(p for p in SAMPLES.rglob("*") if p.suffix in PARSERS)


def mutants(text, rng, count):
    for _ in range(count):
        words = text.split(" ")
        i = rng.randrange(len(words))
        op = rng.randrange(4)
        if op == 0:
            del words[i]
        elif op == 1:
            words.insert(i, rng.choice(words))
        elif op == 2:
            j = rng.randrange(len(words))
            words[i], words[j] = words[j], words[i]
        else:
            yield text[:rng.randrange(len(text))]
            continue
        yield " ".join(words)


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.name)
def test_mutated_programs_fail_cleanly(path):
    parse = PARSERS[path.suffix]
    rng = random.Random(path.name)
    text = path.read_text()
    failures = 0
    for src in mutants(text, rng, 60):
        try:
            check_program(parse(src, "mutant" + path.suffix))
        except ProgramError as e:
            failures += 1
            assert e.file == "mutant" + path.suffix
            assert e.line >= 1 or path.suffix == ".xml", str(e)
    assert failures > 0  # the mutations do break things
