"""The examples of the README and the guides print what the docs show.

Every ``console`` block of README.md and docs/guide/*.md is run: each ``$ plcpred ...``
line in-process (``plcpred.cli.main``, stdout and stderr in one stream, as a terminal
shows them), ``$ head -N FILE`` and ``$ cat FILE`` by reading the file, and what they
print is compared with the lines that follow it in the block. Every ``pycon`` block
(``>>>`` prompts) is run as a doctest. Both run in a fresh folder holding a link to
``samples/``, so paths print as the docs show them and ``--out`` folders land in the
test's temporary folder. The conventions (a copy is in docs/development.md):

- a line ``...`` (alone, any indent) stands for any number of lines, and ``...`` inside a
  line for any text (doctest's ELLIPSIS): for what varies from run to run (timings,
  dates, random ids) and for long output cut short;
- runs of spaces compare as one, trailing spaces and blank lines at the end are ignored;
- a number may differ from the shown one by one unit in its last printed digit (it is
  compared within the precision printed), nothing else may differ;
- an HTML comment on the line(s) just above a block marks it (invisible on GitHub):
  ``<!-- example: skip REASON -->`` (not run: a server, a network), ``<!-- example:
  slow -->`` (run only with ``PLCPRED_SLOW_EXAMPLES=1``), ``<!-- example: exit N -->``
  (every command of the block exits N; default 0), ``<!-- example: file NAME -->``
  above any code block (its text is written to NAME in the folder, for the blocks
  after it on the page).

A failure prints the real output: paste it into the doc (with ``...`` where it varies).
"""
from __future__ import annotations

import contextlib
import doctest
import functools
import io
import os
import re
import shlex
from dataclasses import dataclass, field
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PAGES = [ROOT / "README.md"] + sorted((ROOT / "docs" / "guide").glob("*.md"))
SLOW = os.environ.get("PLCPRED_SLOW_EXAMPLES", "") not in ("", "0")

FENCE = re.compile(r"^ {0,3}(`{3,}|~{3,})\s*([\w+-]*)")
MARK = re.compile(r"^\s*<!--\s*example:\s*(\w+)\s*(.*?)\s*-->\s*$")
NUMBER = re.compile(r"([-+]?(?:\d+\.\d+|\d+)(?:[eE][-+]?\d+)?)")
RUN_INFOS = {"console", "pycon"}


@dataclass
class Block:
    path: Path
    line: int                   # the fence's line (1-based)
    info: str
    body: list[str]
    marks: dict = field(default_factory=dict)
    files: list = field(default_factory=list)   # (name, text) written before it runs

    @property
    def id(self) -> str:
        return f"{self.path.relative_to(ROOT)}:{self.line}"


def blocks_of(path: Path, text: str | None = None) -> list[Block]:
    """The code blocks of a markdown page with their marks; each runnable block carries
    the files the page's ``file`` marks above it define."""
    lines = (path.read_text(encoding="utf-8") if text is None else text).splitlines()
    out, files, marks = [], [], {}
    i = 0
    while i < len(lines):
        m = MARK.match(lines[i])
        if m:
            marks[m.group(1)] = m.group(2)
            i += 1
            continue
        f = FENCE.match(lines[i])
        if not f:
            if lines[i].strip():
                marks = {}          # a mark belongs to the block right below it
            i += 1
            continue
        fence, start, body = f.group(1), i + 1, []
        i += 1
        while i < len(lines) and not (lines[i].strip().startswith(fence)
                                      and not lines[i].strip().strip(fence[0])):
            body.append(lines[i])
            i += 1
        i += 1
        block = Block(path, start, f.group(2).lower(), body, marks, list(files))
        if "file" in marks:
            files.append((marks["file"], "\n".join(body) + "\n"))
        out.append(block)
        marks = {}
    return out


def runnable_blocks() -> list[Block]:
    return [b for p in PAGES for b in blocks_of(p) if b.info in RUN_INFOS]


# ---------------------------------------------------------------- comparing

def _numbers_match(shown: str, printed: str) -> bool:
    """Whether ``printed`` is ``shown`` within the precision ``shown`` is printed to: one
    unit in its last digit."""
    if shown == printed:
        return True
    mant, _, exp = shown.lower().partition("e")
    pmant, _, pexp = printed.lower().partition("e")
    if ("." in mant) != ("." in pmant) or bool(exp) != bool(pexp):
        return False
    decimals = len(mant.partition(".")[2])
    if decimals != len(pmant.partition(".")[2]):
        return False
    unit = 10.0 ** (int(exp or 0) - decimals)
    return abs(float(shown) - float(printed)) <= unit * 1.000001


def line_matches(shown: str, printed: str) -> bool:
    shown, printed = " ".join(shown.split()), " ".join(printed.split())
    if "..." in shown:
        pattern = ".*".join(re.escape(part) for part in shown.split("..."))
        return re.fullmatch(pattern, printed) is not None
    a, b = NUMBER.split(shown), NUMBER.split(printed)
    if len(a) != len(b):
        return False
    # odd positions are numbers, even ones the text between them
    return all(x == y if k % 2 == 0 else _numbers_match(x, y)
               for k, (x, y) in enumerate(zip(a, b)))


def output_matches(shown: list[str], printed: list[str]) -> bool:
    """Whether ``printed`` is ``shown``, a line ``...`` standing for any lines."""
    shown, printed = _trimmed(shown), _trimmed(printed)

    @functools.cache
    def match(i: int, j: int) -> bool:
        if i == len(shown):
            return j == len(printed)
        if shown[i].strip() == "...":
            return match(i + 1, j) or (j < len(printed) and match(i, j + 1))
        return j < len(printed) and line_matches(shown[i], printed[j]) and match(i + 1, j + 1)

    return match(0, 0)


def _trimmed(lines: list[str]) -> list[str]:
    lines = [line.rstrip() for line in lines]
    while lines and not lines[-1]:
        lines.pop()
    return lines


# ---------------------------------------------------------------- running

def commands(block: Block) -> list[tuple[str, list[str]]]:
    """(command line, the output shown under it) of a console block."""
    out = []
    for line in block.body:
        if line.startswith("$ "):
            out.append((line[2:], []))
        elif out:
            out[-1][1].append(line)
    return out


def run_command(line: str, folder: Path) -> tuple[int, str]:
    """(exit code, stdout and stderr together) of one shown command, run in ``folder``."""
    words = shlex.split(line)
    words = words[:next((i for i, w in enumerate(words) if w.startswith("#")), len(words))]
    if words[0] == "plcpred":
        from plcpred.cli import main

        buf = io.StringIO()
        with contextlib.redirect_stdout(buf), contextlib.redirect_stderr(buf):
            try:
                code = main(words[1:])
            except SystemExit as e:             # argparse's own errors
                code = e.code if isinstance(e.code, int) else 2
        text = buf.getvalue()
        for prefix in (str(folder) + os.sep, str(ROOT) + os.sep):
            text = text.replace(prefix, "")
        return code, text
    if words[0] in ("head", "cat"):
        n, names = None, words[1:]
        if words[0] == "head":
            n = 10
            if names and re.fullmatch(r"-\d+", names[0]):
                n, names = int(names[0][1:]), names[1:]
            elif names[:1] == ["-n"]:
                n, names = int(names[1]), names[2:]
        text = "".join((folder / name).read_text(encoding="utf-8") for name in names)
        lines = text.splitlines(keepends=True)
        return 0, "".join(lines if n is None else lines[:n])
    raise AssertionError(f"can't run `{line}`: only plcpred, head and cat; mark the block "
                         "<!-- example: skip REASON -->")


@pytest.fixture
def folder(tmp_path, monkeypatch):
    (tmp_path / "samples").symlink_to(ROOT / "samples", target_is_directory=True)
    monkeypatch.chdir(tmp_path)
    return tmp_path


def _report(block: Block, line: str, shown: list[str], printed: str, code, want) -> str:
    return (f"{block.id}: `{line}` (exit {code}, expected {want}) printed:\n"
            + printed + "\n--- the doc shows:\n" + "\n".join(shown))


@pytest.mark.parametrize("block", runnable_blocks(), ids=lambda b: b.id)
def test_example_prints_what_the_doc_shows(block, folder):
    if "skip" in block.marks:
        pytest.skip(block.marks["skip"] or "marked skip")
    if "slow" in block.marks and not SLOW:
        pytest.skip("slow example: PLCPRED_SLOW_EXAMPLES=1 runs it")
    for name, text in block.files:
        (folder / name).write_text(text, encoding="utf-8")
    if block.info == "pycon":
        test = doctest.DocTestParser().get_doctest("\n".join(block.body) + "\n", {}, block.id,
                                                   str(block.path), block.line)
        runner = doctest.DocTestRunner(
            optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
        report = io.StringIO()
        result = runner.run(test, out=report.write, clear_globs=True)
        if result.failed:
            pytest.fail(report.getvalue(), pytrace=False)
        return
    want = int(block.marks.get("exit") or 0)
    shown_commands = commands(block)
    assert shown_commands, f"{block.id}: a console block with no `$ ` command"
    for line, shown in shown_commands:
        code, printed = run_command(line, folder)
        if code != want or not output_matches(shown, printed.splitlines()):
            pytest.fail(_report(block, line, shown, printed, code, want), pytrace=False)


def test_the_readme_has_checked_examples():
    readme = [b for b in runnable_blocks() if b.path.name == "README.md"]
    assert {b.info for b in readme} == {"console", "pycon"}
    assert not [b.id for b in readme if "skip" in b.marks or "slow" in b.marks]


# ---------------------------------------------------------------- the checker itself

def test_lines_match_within_the_printed_precision():
    assert line_matches("mean 35.3 NL/min, peak 161.1", "mean  35.4 NL/min, peak 161.1")
    assert not line_matches("mean 35.3 NL/min", "mean 35.5 NL/min")
    assert not line_matches("mean 35.3 NL/min", "mean 35.30 NL/min")
    assert line_matches("85 samples", "86 samples") and not line_matches("85", "87")
    assert line_matches("C 6.56e-09", "C 6.57e-09") and not line_matches("6.56e-09", "6.56e-08")
    assert not line_matches("error -35.4 %", "error -35.4 % !")
    assert line_matches("plant: 1 reused; ... s (...x real time)",
                        "plant: 1 reused; 2.9 s (7.0x real time)")
    assert output_matches(["a", "...", "d"], ["a", "b", "c", "d"])
    assert output_matches(["a", "  ...", "b"], ["a", "b", ""])
    assert not output_matches(["a", "...", "d"], ["a", "b", "c"])
    assert not output_matches(["a"], ["a", "b"])


def test_marks_and_files_are_read(tmp_path):
    page = tmp_path / "page.md"
    text = ("<!-- example: file p.st -->\n```st\nPROGRAM P\n```\n\ntext\n\n"
            "<!-- example: exit 1 -->\n<!-- example: slow -->\n```console\n$ plcpred check p.st\n"
            "p.st: ...\n```\n<!-- example: skip a server -->\n\nprose\n```console\n$ x\n```\n")
    blocks = blocks_of(page, text)
    assert [b.info for b in blocks] == ["st", "console", "console"]
    assert blocks[1].marks == {"exit": "1", "slow": ""}
    assert blocks[1].files == [("p.st", "PROGRAM P\n")]
    assert blocks[2].marks == {}                  # prose between the mark and the block
    assert commands(blocks[1]) == [("plcpred check p.st", ["p.st: ..."])]
