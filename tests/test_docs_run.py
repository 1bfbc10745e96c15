"""The documentation's commands run: every shell block of README.md and docs/*.md.

The rule (docs/architecture.md, "Docs that run"): a fenced block tagged ``sh`` is a shell
block, and every shell block is tagged ``sh``; an untagged block (or one tagged ``bash``,
``shell``, ``console``) whose first command line starts with a command (``microsim``,
``python``, ``pip``, ``pytest``, ``dask``, ``bash``) fails the test, so a command cannot
hide from the run (usage lines with placeholders are tagged ``text``). Each file's blocks run in document order, each in
``bash -euo pipefail``, in one temporary folder per file holding a copy of surfaces/,
scripts/ and tables/reference/ (so a block may use what an earlier block of its file
made), with ``MICROSIM_EFFORT`` set (microsim/effort.py): the blocks are what a reader
pastes, at a hundredth of the rays, realisations and samples per pixel. A block that
cannot run here is preceded by ``<!-- docs-run: skip: REASON -->``; the test counts the
blocks run and skipped per file, so a new block is either run or marked.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
COPIED = ("surfaces", "scripts", "tables/reference")
"""What the blocks may read, copied into each file's folder (it starts without tables/)."""
EFFORT = "0.01"
"""$MICROSIM_EFFORT of the runs: a hundredth of the work, at least 2 realisations."""
TIMEOUT_S = 300
"""A block that runs longer than this has hung (the slowest, render.md's first, takes
~15 s of CPU)."""

EXPECTED = {
    "README.md": (0, 2),
    "docs/batch.md": (1, 2),
    "docs/compare.md": (0, 1),
    "docs/goniometer.md": (1, 0),
    "docs/materials.md": (2, 0),
    "docs/render.md": (3, 2),
    "docs/spectral.md": (1, 0),
}
"""(blocks run, blocks skipped) of every file that has ``sh`` blocks: a new block, or a new
page with blocks, changes the counts here."""

FENCE = re.compile(r"^(\s*)```\s*(\S*)")
SKIP = re.compile(r"^<!--\s*docs-run:\s*skip:\s*(\S.*?)\s*-->$")
SHELL_TAGS = ("", "bash", "shell", "console", "zsh")
"""Tags (or none) under which a command block would hide from the run: it must be ``sh``.
A usage line with placeholders is tagged ``text``."""
COMMAND = re.compile(r"^\$?\s*(\w+=\S*\s+)*(microsim|python3?|pip|pytest|dask|bash)(\s|$)")


@dataclass(frozen=True)
class Block:
    """A fenced code block: where it starts, its tag, its text and its skip reason."""

    file: str
    line: int
    tag: str
    text: str
    skip: str | None

    def first_command(self) -> str:
        """The block's first line that is neither blank nor a comment."""
        return next((s.strip() for s in self.text.splitlines()
                     if s.strip() and not s.strip().startswith("#")), "")


def blocks(path: Path) -> list[Block]:
    """Every fenced code block of a Markdown file, in order."""
    lines = path.read_text(encoding="utf-8").splitlines()
    name = path.relative_to(ROOT).as_posix()
    found, i = [], 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if m is None:
            i += 1
            continue
        end = next(j for j in range(i + 1, len(lines)) if lines[j].strip() == "```")
        before = next((s.strip() for s in reversed(lines[:i]) if s.strip()), "")
        skip = SKIP.match(before)
        found.append(Block(name, i + 1, m.group(2), "\n".join(lines[i + 1:end]),
                           skip.group(1) if skip else None))
        i = end + 1
    return found


def shell_blocks(path: Path) -> list[Block]:
    """The ``sh`` blocks of a file."""
    return [b for b in blocks(path) if b.tag == "sh"]


def test_every_command_block_is_tagged_sh():
    """A block that starts with a command is a shell block, tagged ``sh`` (and so run)."""
    untagged = [f"{b.file}:{b.line} ({b.tag or 'no tag'}): {b.first_command()}"
                for path in DOCS for b in blocks(path)
                if b.tag in SHELL_TAGS and COMMAND.match(b.first_command())]
    assert not untagged, "command blocks not tagged sh:\n" + "\n".join(untagged)


def test_skip_marks_say_why_and_mark_sh_blocks():
    """Every ``docs-run: skip`` comment precedes an ``sh`` block and gives a reason."""
    for path in DOCS:
        text = path.read_text(encoding="utf-8").splitlines()
        marks = [n for n, s in enumerate(text, 1)
                 if s.strip().startswith("<!--") and "docs-run:" in s]
        marked = {b.line for b in shell_blocks(path) if b.skip is not None}
        for n in marks:
            assert SKIP.match(text[n - 1].strip()), f"{path.name}:{n}: malformed mark"
            assert any(n < line <= n + 2 for line in marked), (
                f"{path.name}:{n}: a docs-run mark not right before an sh block")


def test_the_count_of_blocks_is_known():
    """Every Markdown file with shell blocks is listed with its counts of blocks run and
    skipped."""
    counts = {}
    for path in DOCS:
        found = shell_blocks(path)
        skipped = sum(b.skip is not None for b in found)
        if found:
            counts[path.relative_to(ROOT).as_posix()] = (len(found) - skipped, skipped)
    assert counts == EXPECTED


def run_environment() -> dict[str, str]:
    """The blocks' environment: this Python's scripts first on PATH, a quick effort,
    plots without a display."""
    env = dict(os.environ)
    env["PATH"] = os.pathsep.join([str(Path(sys.executable).parent), env.get("PATH", "")])
    env["MICROSIM_EFFORT"] = EFFORT
    env["MPLBACKEND"] = "Agg"
    env.pop("DISPLAY", None)
    env.pop("WAYLAND_DISPLAY", None)
    return env


@pytest.mark.parametrize("path", [p for p in DOCS
                                  if any(b.skip is None for b in shell_blocks(p))],
                         ids=lambda p: p.name)
def test_shell_blocks_run(path, tmp_path):
    """Each unmarked ``sh`` block of the file exits 0, in document order, in a folder
    holding copies of what the blocks read."""
    for name in COPIED:
        shutil.copytree(ROOT / name, tmp_path / name)
    env = run_environment()
    for block in shell_blocks(path):
        if block.skip is not None:
            continue
        done = subprocess.run(["bash", "-euo", "pipefail", "-c", block.text], cwd=tmp_path,
                              env=env, capture_output=True, text=True, timeout=TIMEOUT_S)
        assert done.returncode == 0, (
            f"{block.file}:{block.line} exited {done.returncode}:\n{block.text}\n"
            f"--- stdout\n{done.stdout[-3000:]}\n--- stderr\n{done.stderr[-3000:]}")


def test_nothing_cites_notes_outside_the_repository():
    """Conventions and reference numbers live in docs/conventions.md, which the code, tests
    and docs cite; no file names the design notes the project started from."""
    sources = [p for folder in ("microsim", "tests", "scripts", "docs")
               for p in (ROOT / folder).rglob("*") if p.suffix in (".py", ".md")]
    citing = [p.relative_to(ROOT).as_posix() for p in [*sources, ROOT / "README.md"]
              if "DESIGN" + ".md" in p.read_text(encoding="utf-8")]
    assert not citing


WRITTEN = re.compile(r'write_section\(DOC, "([\w-]+)"')
DOC_OF = re.compile(r'^DOC = .*"docs" / "([\w-]+\.md)"', re.M)


def test_the_sections_scripts_write_are_in_their_pages():
    """Each section a script writes by a literal name (``write_section(DOC, "name", ...)``)
    is marked once, begin before end, in the page the script's ``DOC`` names, so the
    numbers there are the script's and re-running it replaces them."""
    checked = 0
    for script in sorted((ROOT / "scripts").glob("*.py")):
        text = script.read_text(encoding="utf-8")
        doc = DOC_OF.search(text)
        for name in WRITTEN.findall(text):
            assert doc, f"{script.name}: writes {name!r} but names no DOC"
            page = (ROOT / "docs" / doc.group(1)).read_text(encoding="utf-8")
            begin, end = f"<!-- {name}: begin -->", f"<!-- {name}: end -->"
            assert page.count(begin) == page.count(end) == 1, (script.name, name)
            assert page.index(begin) < page.index(end), (script.name, name)
            checked += 1
    assert checked >= 4  # demo_numbers (2), hierarchy_consistency, vgroove_oren_nayar
