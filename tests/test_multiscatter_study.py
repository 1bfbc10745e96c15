"""The per-order comparison of tables with Smith and Heitz et al. 2016's walk
(``microsim.comparison.orders``, run by scripts/multiscatter_study.py): it runs end to end,
says "no lobe" where a model has none, refuses a table without orders, and its
α-adjusted albedo residual errors are calibrated over independent ensembles."""

from __future__ import annotations

import importlib.util
import json
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from microsim.comparison.orders import compare_orders, lobe_errors
from microsim.measurement.simulation import simulate_recipe
from microsim.recipe import resolve
from microsim.tables.exr import write_table

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def study():
    spec = importlib.util.spec_from_file_location(
        "multiscatter_study", ROOT / "scripts" / "multiscatter_study.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def small_recipe(seed: int, realisations: int, theta: list[float], orders: int) -> dict:
    """A rough Gaussian surface (α = 0.6) of tiny tiles (32², 4 correlation lengths per
    side: their realised α spreads by ~10%)."""
    return resolve({"surface": {"kind": "gaussian", "alpha": 0.6, "resolution": 32,
                                "seed": 100 + seed},
                    "simulation": {"theta_i": theta, "rays": 4000, "seed": seed,
                                   "realisations": realisations},
                    "table": {"theta_bins": 4, "phi_bins": 8, "sh_order": 0,
                              "orders": orders}})


def test_study_runs_from_a_recipe_and_from_a_table(study, tmp_path, capsys) -> None:
    """One row per table, incidence and component, with albedo residuals against each
    reference and median lobe errors carrying error bars; Smith is compared with order 1
    and the total only; the walk's orders add up to its total, 1 for mirror facets; a
    recipe simulated here gets the α-adjusted errors, a table read from a file its own;
    the Markdown and figures are written."""
    recipe = tmp_path / "tiny.toml"
    recipe.write_text('[surface]\nkind = "gaussian"\nalpha = 0.8\nresolution = 32\n'
                      'seed = 3\n[simulation]\ntheta_i = [0, 50]\nrays = 4000\n'
                      'realisations = 3\n'
                      '[table]\ntheta_bins = 4\nphi_bins = 8\nsh_order = 0\norders = 3\n')
    table = tmp_path / "t.exr"
    write_table(simulate_recipe(small_recipe(0, 2, [0.0, 60.0], 3)), table)
    study.main([str(recipe), str(table), "--out", str(tmp_path / "out"), "--samples", "4",
                "--walks", "2000", "--replicates", "4"])
    rows = json.loads((tmp_path / "out" / "study.json").read_text())
    assert len(rows) == 2 * 2 * 4 and {r["table"] for r in rows} == {"tiny", "t"}
    for r in rows:
        assert ("residual_smith" in r) == (r["component"] in ("total", "order1"))
        assert ("residual_walk" in r) == (r["component"] != "order1")
        assert r["albedo_walk_err"] >= 0
        for ref in ("smith", "walk"):
            if f"residual_{ref}" not in r:
                continue
            assert r[f"residual_{ref}_err"] >= 0
            assert r[f"residual_{ref}_error_model"] == (
                "alpha-adjusted" if r["table"] == "tiny" else "table")
            if r[f"median_rel_{ref}"] is not None:
                assert r[f"median_rel_{ref}_err"] >= 0 and r[f"noise_floor_{ref}"] > 0
    for label in ("tiny", "t"):
        for theta in (0.0, 50.0, 60.0):
            mine = {r["component"]: r for r in rows
                    if r["table"] == label and r["theta_i"] == theta}
            if mine:
                parts = sum(mine[c]["albedo_walk"] for c in ("order1", "order2", "order3+"))
                assert parts == pytest.approx(mine["total"]["albedo_walk"], abs=1e-12)
                assert mine["total"]["albedo_walk"] == pytest.approx(1.0, abs=1e-12)
    for name in ("albedo.png", "lobe.png", "order2-tiny.png", "order2-t.png"):
        assert (tmp_path / "out" / name).stat().st_size > 0
    text = (tmp_path / "out" / "study.md").read_text()
    assert text.startswith("`python scripts/multiscatter_study.py ") and "order2 − walk" in text
    capsys.readouterr()


def test_a_model_without_lobe_bins_gives_no_lobe(study) -> None:
    """Where the model is zero everywhere (an order no walk reached), every statistic is
    NaN, quietly (no all-NaN warning), and the Markdown says "no lobe"."""
    table = simulate_recipe(small_recipe(1, 1, [0.0], 3))
    zero = np.zeros_like(table["order3+"].values)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        result = lobe_errors(table, "order3+", zero, zero, np.random.default_rng(0), 4)
    assert all(np.isnan(v).all() for v in result.values())
    row = {"median_rel_walk": None, "residual_walk": 0.001, "residual_walk_err": 0.0005}
    assert study._lobe(row, "walk") == "no lobe"
    assert study._lobe(row, "smith") == "—"


def test_a_table_without_orders_is_refused(study, tmp_path, capsys) -> None:
    """A table simulated without an order split: exit status 2, one ``error:`` line."""
    recipe = small_recipe(2, 1, [0.0], 3)
    recipe = replace(recipe, table=replace(recipe.table, orders=1))
    path = tmp_path / "one.exr"
    write_table(simulate_recipe(recipe), path)
    with pytest.raises(SystemExit) as exit_info:
        study.main([str(path), "--out", str(tmp_path / "out")])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("error: one: the table holds no order split")


def test_alpha_adjusted_albedo_errors_are_calibrated() -> None:
    """A reported standard error is a claim: over 48 independent ensembles (4 tiny tiles
    each, whose realised α spreads by ~10%), the empirical variance of the albedo residual
    (order 1 against Smith, orders 2+ against the walk, at θi = 0) over the mean reported
    variance lies within the two-sided χ²(47) band at significance 0.001 ([0.46, 1.82]; the
    reported variances, of 3 degrees of freedom each, average over 48 ensembles, which
    widens it by ~12%: inside the band). The table's own error, which counts the spread
    that the tiles' α explains, is far too large here (20–25 times the variance): it
    falls below the band, so the test tells the adjustment from its absence."""
    runs = 48
    residuals: dict[str, list[tuple[float, float, float]]] = {"order1": [], "order2+": []}
    for seed in range(runs):
        table = simulate_recipe(small_recipe(seed, 4, [0.0], 2))
        for row in compare_orders(table, "x", 2, 20_000, seed, 2)[0]:
            if row["component"] in residuals:
                ref = "smith" if row["component"] == "order1" else "walk"
                assert row[f"residual_{ref}_error_model"] == "alpha-adjusted"
                residuals[row["component"]].append((row[f"residual_{ref}"],
                                                    row[f"residual_{ref}_err"],
                                                    row["albedo_sim_err"]))
    low, high = stats.chi2.ppf([0.0005, 0.9995], runs - 1) / (runs - 1)
    for component, values in residuals.items():
        x = np.array(values)
        empirical = x[:, 0].var(ddof=1)
        ratio = empirical / np.mean(x[:, 1] ** 2)
        assert low < ratio < high, (component, ratio)
        assert empirical / np.mean(x[:, 2] ** 2) < low, component
