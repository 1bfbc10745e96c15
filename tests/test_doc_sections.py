"""Every measured section of the docs names the script that writes it: a section between
``<!-- name: begin -->`` and ``<!-- name: end -->`` in docs/*.md holds the command that
wrote it, ``python scripts/NAME.py ... --write``, and that script exists and takes
``--write``. So no section loses its source without this failing (the other direction,
each name a script writes being marked in its page, is tests/test_docs_run.py's)."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PAGES = sorted((ROOT / "docs").glob("*.md"))
MARKER = re.compile(r"^<!-- ([\w-]+): (begin|end) -->$", re.M)
COMMAND = re.compile(r"`python\s+scripts/([\w-]+)\.py(\s[^`]*)?`")


def sections(page: Path) -> list[tuple[str, str]]:
    """``(name, body)`` of every marked section of a page, in order (markers on lines of
    their own, as ``write_section`` writes them; one quoted in the prose is no marker);
    each begin closed by its own end before the next section opens (asserted)."""
    text = page.read_text(encoding="utf-8")
    found, open_name, start = [], None, 0
    for m in MARKER.finditer(text):
        name, edge = m.groups()
        if edge == "begin":
            assert open_name is None, f"{page.name}: {name!r} opens inside {open_name!r}"
            open_name, start = name, m.end()
        else:
            assert open_name == name, f"{page.name}: {name!r} ends, {open_name!r} is open"
            found.append((name, text[start:m.start()]))
            open_name = None
    assert open_name is None, f"{page.name}: {open_name!r} never ends"
    return found


def takes_write(script: Path) -> bool:
    """The script's argument parser has a ``--write`` option (``add_argument("--write",
    ...)`` anywhere in its source)."""
    for node in ast.walk(ast.parse(script.read_text(encoding="utf-8"))):
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                and node.func.attr == "add_argument" and node.args
                and isinstance(node.args[0], ast.Constant) and node.args[0].value == "--write"):
            return True
    return False


SECTIONS = [(page, name, body) for page in PAGES for name, body in sections(page)]


@pytest.mark.parametrize(("page", "name", "body"), SECTIONS,
                         ids=[f"{p.stem}-{n}" for p, n, _ in SECTIONS])
def test_a_section_names_the_script_that_writes_it(page: Path, name: str, body: str) -> None:
    """The section's first ``python scripts/NAME.py ...`` command is its source: the
    script is in scripts/, takes ``--write``, and the command gives it."""
    command = COMMAND.search(body)
    assert command, f"{page.name}: section {name!r} names no `python scripts/X.py` command"
    script = ROOT / "scripts" / f"{command.group(1)}.py"
    assert script.is_file(), f"{page.name}: section {name!r}: {script.name} does not exist"
    assert takes_write(script), f"{page.name}: section {name!r}: {script.name} has no --write"
    assert "--write" in (command.group(2) or "").split(), (
        f"{page.name}: section {name!r}: `{command.group(0)}` is not the writing command")


def test_the_sections_are_found() -> None:
    """The pages hold the sections the scripts write (guards the marker pattern itself:
    a pattern that matched nothing would pass every section above)."""
    assert len(SECTIONS) >= 30 and len({n for _, n, _ in SECTIONS}) == len(SECTIONS)
