"""Shared test helpers."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from microsim.cli import main


@pytest.fixture
def cli(capsys: pytest.CaptureFixture[str]) -> Callable[..., tuple[int, str, str]]:
    """Run ``microsim ARGS...`` in-process; return (exit status, stdout, stderr)."""

    def run(*argv: str) -> tuple[int, str, str]:
        code = main(list(argv))
        out, err = capsys.readouterr()
        return code, out, err

    return run


@pytest.fixture(scope="module")
def small_table(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small simulated table with spherical harmonics (two-part EXR: a 32² tile, θi 0
    and 60°, 8 × 16 bins, harmonics to order 4; ``test_robustness.SMALL``), made once per
    test module that asks for it."""
    from test_robustness import GAUSSIAN, SMALL

    path = tmp_path_factory.mktemp("table") / "small.exr"
    assert main(["simulate", GAUSSIAN, *SMALL, "--rays", "3000", "-o", str(path),
                 "--json"]) == 0
    return path
