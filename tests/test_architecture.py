"""The layers of docs/architecture.md, as import-linter checks them, and the rule that the
compiled-code cache covers every file holding compiled code."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

from microsim.jit import PACKAGE, compiled_sources

ROOT = Path(__file__).resolve().parent.parent


def lint_imports(*args: str, cwd: Path = ROOT) -> subprocess.CompletedProcess:
    """``lint-imports`` of the venv this test runs in (its configuration: pyproject.toml)."""
    exe = shutil.which("lint-imports", path=str(Path(sys.executable).parent)) or "lint-imports"
    return subprocess.run([exe, "--no-cache", *args], cwd=cwd, capture_output=True,
                          text=True)


def test_the_import_contracts_hold() -> None:
    """Every module imports only from the layers below its own (pyproject.toml)."""
    result = lint_imports()
    assert result.returncode == 0, result.stdout + result.stderr
    assert "0 broken" in result.stdout


def test_a_wrong_arrow_breaks_a_contract(tmp_path: Path) -> None:
    """The contracts are not vacuous: the same configuration with one more contract that
    the code breaks (the kernel imports the material kinds) is reported broken."""
    config = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    config += ('\n[[tool.importlinter.contracts]]\nname = "A wrong arrow"\n'
               'type = "forbidden"\nsource_modules = ["microsim.kernel"]\n'
               'forbidden_modules = ["microsim.materials"]\n')
    (tmp_path / "pyproject.toml").write_text(config, encoding="utf-8")
    result = lint_imports("--config", str(tmp_path / "pyproject.toml"))
    assert result.returncode == 1
    assert "A wrong arrow BROKEN" in result.stdout
    assert "microsim.kernel.events -> microsim.materials" in result.stdout


def test_every_file_with_compiled_code_is_in_the_cache_digest() -> None:
    """numba's cache notices edits only in a compiled function's own file, so the cache
    folder's digest (``microsim.jit``) must cover every file that compiles code or holds
    kernel language: a file importing numba or marking functions with ``kernel``."""
    covered = set(compiled_sources())
    marks = re.compile(r"^\s*(from numba|import numba|@kernel\b)", re.M)
    holding = {path for path in PACKAGE.rglob("*.py")
               if marks.search(path.read_text(encoding="utf-8"))}
    assert holding, "found no compiled code at all"
    assert holding <= covered, sorted(str(p.relative_to(PACKAGE)) for p in holding - covered)
