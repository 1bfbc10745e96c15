"""$MICROSIM_EFFORT: a fraction of the rays, realisations and samples per pixel
(microsim/effort.py, docs/goniometer.md "A quick look")."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from microsim import recipe
from microsim.effort import EFFORT_ENV, scaled

SURFACES = Path(__file__).resolve().parent.parent / "surfaces"
GAUSSIAN = SURFACES / "gaussian-0.3.toml"   # 3 200 000 rays, the generator's 32 realisations
VGROOVE = str(SURFACES / "vgroove-30.toml")  # deterministic: one realisation


def test_unset_or_one_changes_nothing(monkeypatch):
    monkeypatch.delenv(EFFORT_ENV, raising=False)
    full = recipe.load(GAUSSIAN)
    assert (full.simulation.rays, full.simulation.realisations) == (3_200_000, 32)
    monkeypatch.setenv(EFFORT_ENV, "1")
    assert recipe.load(GAUSSIAN) == full


def test_a_hundredth_keeps_two_realisations_and_the_rest_of_the_recipe(monkeypatch):
    monkeypatch.delenv(EFFORT_ENV, raising=False)
    full = recipe.load(GAUSSIAN, ["simulation.max_rays=6400000",
                                  "simulation.max_realisations=256"])
    monkeypatch.setenv(EFFORT_ENV, "0.01")
    quick = recipe.load(GAUSSIAN, ["simulation.max_rays=6400000",
                                   "simulation.max_realisations=256"])
    s = quick.simulation
    assert (s.rays, s.realisations, s.max_rays, s.max_realisations) == (32_000, 2, 64_000, 3)
    assert s.theta_i == full.simulation.theta_i and s.seed == full.simulation.seed
    assert (quick.surface, quick.material, quick.table) == (full.surface, full.material,
                                                           full.table)


def test_the_rays_stay_enough_for_every_realisation(monkeypatch):
    """10 rays over 4 realisations at a hundredth: 1 ray would leave the ray variance
    undefined, so each realisation keeps 2."""
    monkeypatch.setenv(EFFORT_ENV, "0.01")
    s = recipe.load(GAUSSIAN, ["simulation.rays=400", "simulation.realisations=4"]).simulation
    assert (s.rays, s.realisations) == (4, 2)


def test_scaled_rounds_up_and_keeps_the_least(monkeypatch):
    monkeypatch.setenv(EFFORT_ENV, "0.25")
    assert [scaled(n) for n in (1, 3, 4, 5, 64)] == [1, 1, 1, 2, 16]
    assert [scaled(n, least=2) for n in (1, 2, 5, 64)] == [1, 2, 2, 16]


@pytest.mark.parametrize("value", ["0", "-0.5", "1.5", "nan", "inf", "lots"])
def test_bad_values_are_one_error_line(cli, monkeypatch, value):
    monkeypatch.setenv(EFFORT_ENV, value)
    code, out, err = cli("check", VGROOVE)
    assert code == 2 and out == ""
    assert err.startswith(f"error: ${EFFORT_ENV} = {value!r}: must be a number in (0, 1]")
    assert len(err.strip().splitlines()) == 1


def test_the_command_says_so_and_the_table_records_the_rays(cli, monkeypatch, tmp_path):
    """A simulation at a tenth traces a tenth of the rays (rounded up), which the table's
    metadata and the summary report, after one warning line."""
    monkeypatch.setenv(EFFORT_ENV, "0.1")
    code, out, err = cli("simulate", VGROOVE, "--rays", "2001", "--set",
                         "simulation.theta_i=[0, 40]", "--set", "table.sh_order=0",
                         "-o", str(tmp_path / "t.exr"), "--json")
    assert code == 0, err
    assert err.splitlines()[0] == (f"warning: ${EFFORT_ENV} = 0.1: 10% of the rays, "
                                   "realisations and samples per pixel asked for (a quick "
                                   "look; unset it for the real numbers)")
    summary = json.loads(out)
    assert set(summary["theta_i"]) == {0, 40} and set(summary["rays_per_direction"]) == {201}
    from microsim.tables.exr import read_table

    assert {d.rays for d in read_table(tmp_path / "t.exr").meta.directions} == {201}
