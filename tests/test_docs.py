"""The README and the pages under docs/ hold together: every relative link leads to a file
(and an anchor to a heading), the README stays short, and every `plcpred ...` command line
shown in the README and the guides is one the real command-line parser accepts."""
import contextlib
import io
import re
import shlex
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
README_MAX_LINES = 210

FENCE = re.compile(r"^ {0,3}(`{3,}|~{3,})\s*([\w+-]*)")
HEADING = re.compile(r"^ {0,3}(#{1,6})\s+(.*?)\s*#*\s*$")
INLINE_LINK = re.compile(r"!?\[(?:[^\[\]]|\[[^\]]*\])*\]\(\s*(<[^>]*>|[^\s)]+)(?:\s+\"[^\"]*\")?\s*\)")
REFERENCE_DEF = re.compile(r"^ {0,3}\[[^\]]+\]:\s*(\S+)")
CODE_SPAN = re.compile(r"(`+)(?:(?!\1).)+?\1")


def markdown_files():
    return [README] + sorted((ROOT / "docs").rglob("*.md"))


def split_blocks(text):
    """(prose lines, code blocks) of a markdown text: prose as (line number, line) outside
    fenced code, code blocks as (info string, [lines])."""
    prose, blocks = [], []
    fence, info, body = None, "", []
    for n, line in enumerate(text.splitlines(), 1):
        m = FENCE.match(line)
        if fence is None:
            if m:
                fence, info, body = m.group(1), m.group(2).lower(), []
            else:
                prose.append((n, line))
        elif line.strip().startswith(fence[0] * len(fence)) and not line.strip().strip(fence[0]):
            blocks.append((info, body))
            fence = None
        else:
            body.append(line)
    return prose, blocks


def github_slug(heading: str) -> str:
    """The anchor GitHub gives a heading: its text without markup, lower case, punctuation
    but '-' and '_' dropped, spaces as '-'."""
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", heading)   # links keep their text
    text = re.sub(r"<[^>]+>", "", text)                        # inline HTML
    text = text.replace("`", "").replace("*", "")
    text = text.strip().lower()
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def anchors(path: Path) -> set[str]:
    prose, _ = split_blocks(path.read_text(encoding="utf-8"))
    seen: dict[str, int] = {}
    out = set()
    for _, line in prose:
        m = HEADING.match(line)
        if not m:
            continue
        slug = github_slug(m.group(2))
        if slug in seen:
            seen[slug] += 1
            out.add(f"{slug}-{seen[slug]}")
        else:
            seen[slug] = 0
            out.add(slug)
    return out


def relative_links(path: Path):
    """(line number, target) of every link and image in the prose of a markdown file that
    is neither absolute (a scheme, //) nor an e-mail address."""
    prose, _ = split_blocks(path.read_text(encoding="utf-8"))
    for n, line in prose:
        bare = CODE_SPAN.sub("", line)
        targets = [m.group(1) for m in INLINE_LINK.finditer(bare)]
        m = REFERENCE_DEF.match(bare)
        if m:
            targets.append(m.group(1))
        for target in targets:
            target = target.strip("<>")
            if re.match(r"^[a-zA-Z][a-zA-Z0-9+.-]*:", target) or target.startswith("//"):
                continue
            yield n, target


def broken_links(path: Path) -> list[str]:
    problems = []
    for n, target in relative_links(path):
        file_part, _, anchor = target.partition("#")
        dest = (path.parent / file_part).resolve() if file_part else path
        where = f"{path.relative_to(ROOT)}:{n}: {target}"
        if not dest.exists():
            problems.append(f"{where}: no such file")
            continue
        if anchor and dest.suffix == ".md" and anchor not in anchors(dest):
            problems.append(f"{where}: no heading #{anchor} in {dest.relative_to(ROOT)}")
    return problems


@pytest.mark.parametrize("path", markdown_files(), ids=lambda p: str(p.relative_to(ROOT)))
def test_relative_links_resolve(path):
    problems = broken_links(path)
    assert not problems, "\n".join(problems)


def test_the_link_check_sees_broken_links(tmp_path):
    (tmp_path / "there.md").write_text("# A heading: `with code`\n\n## Twice\n\n## Twice\n")
    page = tmp_path / "page.md"
    page.write_text("[ok](there.md) [ok](there.md#a-heading-with-code) [ok](there.md#twice-1)\n"
                    "[ok](#local) [ok](https://example.com/x.md)\n\n## Local\n\n"
                    "```bash\n[not a link](missing.md)\n```\n"
                    "[gone](missing.md) ![gone](img/none.png) [bad](there.md#nowhere)\n")
    global ROOT
    saved, ROOT = ROOT, tmp_path
    try:
        problems = broken_links(page)
    finally:
        ROOT = saved
    assert [p.split(": ", 1)[1] for p in problems] == [
        "missing.md: no such file", "img/none.png: no such file",
        "there.md#nowhere: no heading #nowhere in there.md"]


def test_github_slugs():
    assert github_slug("`plcpred diagnose`: the gap between prediction and a flow meter") \
        == "plcpred-diagnose-the-gap-between-prediction-and-a-flow-meter"
    assert github_slug("`[[input]]`: inputs the world drives") == "input-inputs-the-world-drives"
    assert github_slug("B&R Automation Studio programs") == "br-automation-studio-programs"
    assert github_slug("The plant as the diagnosis' reference") \
        == "the-plant-as-the-diagnosis-reference"


def test_readme_is_short():
    n = len(README.read_text(encoding="utf-8").splitlines())
    assert n <= README_MAX_LINES, f"README.md has {n} lines, at most {README_MAX_LINES}"


# ---------------------------------------------------------------- command lines

SHELL_BLOCKS = {"bash", "sh", "console", "shell"}
PLACEHOLDERS = ("<", "...", "$")


def command_lines(text: str) -> list[list[str]]:
    """Every `plcpred ...` command shown in the bash, sh and console blocks of a markdown
    text: continuation lines joined, a console's prompt taken off (its other lines are
    output), the plcpred part of `&&`, `||`, `;` and `|` chains, comments dropped. Lines
    with placeholders (<FILE>, ..., $VAR) are left out."""
    _, blocks = split_blocks(text)
    found = []
    for info, body in blocks:
        if info not in SHELL_BLOCKS:
            continue
        logical, pending = [], ""
        for line in body:
            if info == "console" and not pending:
                if not line.startswith("$ "):
                    continue
                line = line[2:]
            if line.rstrip().endswith("\\"):
                pending += line.rstrip()[:-1] + " "
                continue
            logical.append(pending + line)
            pending = ""
        for line in logical:
            if any(p in line for p in PLACEHOLDERS):
                continue
            words = shlex.split(line)
            for i, w in enumerate(words):
                if w.startswith("#"):
                    words = words[:i]
                    break
            part: list[str] = []
            for w in words + ["&&"]:
                if w in ("&&", "||", ";", "|"):
                    if part and part[0] == "plcpred":
                        found.append(part)
                    part = []
                else:
                    part.append(w)
    return found


def parse_error(words: list[str]) -> str | None:
    """None when the real parser accepts the command line (its words, `plcpred` first),
    else what it printed."""
    from plcpred.cli import build_parser
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            build_parser().parse_args(words[1:])
    except SystemExit as e:
        return f"exit {e.code}: {err.getvalue().strip()}"
    return None


DOCS_WITH_COMMANDS = [README] + sorted((ROOT / "docs" / "guide").glob("*.md"))


@pytest.mark.parametrize("path", DOCS_WITH_COMMANDS, ids=lambda p: str(p.relative_to(ROOT)))
def test_command_lines_parse(path):
    commands = command_lines(path.read_text(encoding="utf-8"))
    assert commands, f"{path.relative_to(ROOT)} shows no plcpred command"
    bad = [f"{shlex.join(c)}\n    {e}" for c in commands if (e := parse_error(c))]
    assert not bad, "\n".join(bad)


def test_the_readme_walks_through_every_step():
    commands = [c[1] for c in command_lines(README.read_text(encoding="utf-8"))]
    for step in ("predict", "init", "check", "size", "compare", "emulate", "diagnose"):
        assert step in commands, step


def test_command_lines_are_found_and_wrong_ones_fail():
    text = ("```bash\npython3 -m venv .venv && . .venv/bin/activate && plcpred predict m.toml"
            " --horizon 20s --out out/rig\nplcpred compare a.toml --horizon 1h \\\n"
            "    --max-increase 2%   # a gate\nplcpred check <FILE>\n```\n"
            "```console\n$ plcpred sweep m.toml --set program.T=T#2s --set \"a b.C=1,2\" --horizon 20s\n"
            "plcpred output line, not a command\n$ plcpred predict m.toml --hroizon 1h --out o\n```\n"
            "```toml\nplcpred = 'not a command'\n```\n")
    commands = command_lines(text)
    assert [shlex.join(c) for c in commands] == [
        "plcpred predict m.toml --horizon 20s --out out/rig",
        "plcpred compare a.toml --horizon 1h --max-increase 2%",
        "plcpred sweep m.toml --set 'program.T=T#2s' --set 'a b.C=1,2' --horizon 20s",
        "plcpred predict m.toml --hroizon 1h --out o"]
    assert [parse_error(c) is None for c in commands] == [True, True, True, False]
