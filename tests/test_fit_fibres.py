"""Fitting the fibre families (Kay-Kajiya layers, the microcylinder cloth model) to
anisotropic tables: back from tables made from them, geometry taken from the table."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from microsim.compare import bin_averages
from microsim.fit import family, fit_table
from microsim.recipe import resolve
from microsim.simulation import simulate
from microsim.surfaces import build_tile
from microsim.table_models import model_defaults


def template(surface: dict, materials: dict, phi: list) -> object:
    """A small simulated table of the surface (for its axes, bins and metadata)."""
    r = resolve({"surface": surface, "material": materials,
                 "simulation": {"theta_i": [20.0, 50.0], "phi_i": phi, "rays": 2000,
                                "bounces": 2},
                 "table": {"theta_bins": 4, "phi_bins": 8}})
    return simulate(build_tile(r.surface), r.material, r.simulation, r.table,
                    threads=1, recipe=r)


def made_from(table: object, spec: str, params: list) -> object:
    """The table with its bins replaced by the family's bin averages at ``params``,
    each with a 1% error: a noiseless anisotropic table of that model."""
    _, fam = family(spec, model_defaults(table.meta))
    avg = bin_averages(fam.build(np.asarray(params, float)), table.axes, 5)
    out = copy.copy(table)
    out.values = {c: avg for c in table.values}
    out.errors = {c: 0.01 * avg + 1e-12 for c in table.errors}
    return out


def test_microcylinder_fit_recovers_known_parameters_of_an_anisotropic_weave_table():
    """A twill table's bins replaced by the cloth model at known parameters (the weave's
    tangent curves from the table). Noiseless, the fit from the family's start
    reproduces the bins (median relative error below 1%) and recovers all 12 parameters
    to 1e-6 relative (the least-squares minimum is the truth; measured 1e-12), so a fit
    that lands on a different set of parameters reproducing the bins as well fails. With
    1% Gaussian noise on every bin (seeded), each parameter lies within 4 of its
    reported uncertainty of the truth (two-sided, 12 × 6e-5 ≈ 1e-3 by noise alone;
    measured |z| ≤ 1.8 over three seeds): the uncertainties are not too small."""
    table = template({"kind": "weave", "pattern": "twill", "segments": 4, "sides": 8},
                     {"kind": "lambertian", "albedo": 0.5}, [45.0])
    # gamma_s, gamma_v in degrees, as the model spec takes them
    truth = [0.7, 0.6, 1.6, math.degrees(0.12), math.degrees(0.3), 0.4, 0.2, 0.3, 0.8, 0.9,
             0.8, 0.7]
    clean = made_from(table, "microcylinder", truth)
    r = fit_table(clean, "microcylinder", "single")
    assert r.median_rel_error < 0.01
    assert list(r.params.values()) == pytest.approx(truth, rel=1e-6)
    rng = np.random.default_rng(0)
    noisy = copy.copy(clean)
    noisy.values = {c: v * (1 + 0.01 * rng.standard_normal(v.shape))
                    for c, v in clean.values.items()}
    r = fit_table(noisy, "microcylinder", "single", start=truth)  # convergence: above
    z = np.array([(r.params[k] - t) / r.uncertainty[k]
                  for k, t in zip(r.params, truth, strict=True)])
    assert np.all(np.abs(z) < 4), dict(zip(r.params, z, strict=True))


def test_kay_kajiya_fit_uses_the_cylinders_axis_and_coverage():
    """Kay-Kajiya on a cylinders table: the tangent (+y) and coverage (2r/s) come from
    the table, so a table made from kd = 0.02, ks = (0.3, 0.2, 0.1), n = 40 comes back
    within 2%."""
    table = template({"kind": "cylinders", "radius": 0.25, "spacing": 1.0},
                     {"kind": "lambertian", "albedo": 0.5}, [0.0, 60.0])
    assert model_defaults(table.meta)["coverage"] == pytest.approx(0.5)
    truth = [0.02, 0.02, 0.02, 0.3, 0.2, 0.1, 40.0]
    r = fit_table(made_from(table, "kay-kajiya", truth), "kay-kajiya", "single")
    for name, value in zip(r.params, truth, strict=True):
        assert r.params[name] == pytest.approx(value, rel=0.02)
