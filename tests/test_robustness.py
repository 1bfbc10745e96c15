"""Bad and extreme input as a new user gives it: one ``error:`` line and exit 2, never a
traceback, and no silently wrong output."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
SURFACES = ROOT / "surfaces"
GAUSSIAN = str(SURFACES / "gaussian-0.3.toml")
SMALL = ["--set", "surface.resolution=32", "--set", "simulation.theta_i=[0, 60]",
         "--set", "table.theta_bins=8", "--set", "table.phi_bins=16",
         "--set", "table.sh_order=4"]
"""A small table: 32² tile, 2 incidences, 8 × 16 bins, harmonics to order 4."""


def one_error_line(code: int, err: str, *needles: str) -> str:
    """Assert exit 2 with exactly one ``error:`` line on stderr holding every needle."""
    lines = [line for line in err.strip().splitlines() if not line.startswith("warning:")]
    assert code == 2, err
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    return lines[0]


@pytest.fixture(scope="module")
def small_table(tmp_path_factory) -> Path:
    """A small simulated table with spherical harmonics (two-part EXR)."""
    from microsim.cli import main

    path = tmp_path_factory.mktemp("table") / "small.exr"
    assert main(["simulate", GAUSSIAN, *SMALL, "--rays", "3000", "-o", str(path),
                 "--json"]) == 0
    return path


# --- recipes that are not recipes ---------------------------------------------------------
def test_binary_recipe_is_an_error_line(cli, tmp_path):
    path = tmp_path / "random.toml"
    path.write_bytes(np.random.default_rng(0).integers(0, 256, 300, np.uint8).tobytes())
    code, _, err = cli("check", str(path))
    one_error_line(code, err, str(path), "not UTF-8")


def test_oversized_recipe_is_refused_before_it_is_read_whole(cli, tmp_path):
    """An endless input (/dev/zero) or a huge file is refused after reading at most
    ``MAX_BYTES + 1`` bytes."""
    from microsim.recipe import MAX_BYTES

    path = tmp_path / "huge.toml"
    path.write_text("# comment\n" * (MAX_BYTES // 10 + 1), encoding="utf-8")
    code, _, err = cli("check", str(path))
    one_error_line(code, err, str(path), "larger than")
    if Path("/dev/zero").exists():
        code, _, err = cli("check", "/dev/zero")
        one_error_line(code, err, "/dev/zero", "larger than")


def test_folder_as_recipe_is_an_error_line(cli, tmp_path):
    code, _, err = cli("check", str(tmp_path))
    one_error_line(code, err, str(tmp_path), "cannot read")


# --- shipped recipes and what commands print about a tile -------------------------------
def test_mesh_recipe_simulates_and_reports_its_roughness_without_a_target(cli, tmp_path):
    """A mesh has a realised roughness but no target: the summary says so, and so does
    ``measure g1`` (no "target None")."""
    out_path = tmp_path / "mesh.exr"
    code, out, err = cli("simulate", str(SURFACES / "mesh-example.toml"), "--rays", "2000",
                         "--set", "table.sh_order=2", "-o", str(out_path))
    assert code == 0, err
    assert out_path.is_file()
    line = next(line for line in out.splitlines() if line.startswith("surface:"))
    assert "alpha realised" in line and "target" not in line
    code, out, err = cli("measure", "g1", str(SURFACES / "mesh-example.toml"), "--rays",
                         "2000", "--theta", "0,60")
    assert code == 0, err
    assert "None" not in out and "alpha realised" in out


def test_generate_prints_rounded_summaries_not_a_value_per_groove(cli, tmp_path):
    """A million grooves print one line of slope facts; numbers carry 4 significant
    figures in text (JSON keeps full precision)."""
    recipe = SURFACES / "vgroove-30.toml"
    code, out, err = cli("generate", str(recipe), "--set", "surface.grooves=1000000",
                         "-o", str(tmp_path / "v.ply"))
    assert code == 0, err
    assert len(out) < 2000, len(out)
    slopes = next(line for line in out.splitlines() if "slopes_deg" in line)
    assert "count 1000000" in slopes and "29.99999" not in slopes and "min 30," in slopes
    code, out, _ = cli("generate", GAUSSIAN, "-o", str(tmp_path / "g.ply"))
    realised = next(line for line in out.splitlines() if "alpha_realised" in line)
    assert len(realised.split(":")[1].strip()) <= 6, realised
    code, out, _ = cli("generate", GAUSSIAN, "-o", str(tmp_path / "g.ply"), "--json")
    assert len(str(json.loads(out)["alpha_realised"])) > 8  # full precision in JSON
