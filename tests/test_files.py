"""Whole-or-nothing files and the marked sections benchmark scripts rewrite."""

from __future__ import annotations

from pathlib import Path

import pytest

from microsim.files import atomic_path, replace_marked

BEGIN, END = "<!-- x -->", "<!-- /x -->"


def test_a_failed_write_leaves_the_old_file_and_no_temporary(tmp_path: Path) -> None:
    target = tmp_path / "t.txt"
    target.write_text("old")
    with pytest.raises(RuntimeError), atomic_path(target) as tmp:
        tmp.write_text("half")
        raise RuntimeError("crash")
    assert target.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == ["t.txt"]


def test_replace_marked_keeps_the_rest_of_the_page(tmp_path: Path) -> None:
    page = tmp_path / "p.md"
    page.write_text(f"# Title\n\nbefore\n{BEGIN}\nold figures\n{END}\nafter\n")
    replace_marked(page, f"{BEGIN}\nnew figures\n{END}", BEGIN, END)
    assert page.read_text() == f"# Title\n\nbefore\n{BEGIN}\nnew figures\n{END}\nafter\n"


def test_replace_marked_appends_under_a_heading_once(tmp_path: Path) -> None:
    page = tmp_path / "p.md"
    page.write_text("# Title\n\ntext\n")
    for figures in ("first", "second"):
        replace_marked(page, f"{BEGIN}\n{figures}\n{END}", BEGIN, END, heading="## Bench")
    assert page.read_text() == f"# Title\n\ntext\n\n## Bench\n\n{BEGIN}\nsecond\n{END}\n"
