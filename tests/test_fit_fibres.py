"""Fitting the fibre families (Kay-Kajiya layers, the microcylinder cloth model) to
anisotropic tables: back from tables made from them, geometry taken from the table."""

from __future__ import annotations

import math

import numpy as np
import pytest
from tablefixtures import changed
from test_fit import _directions

from microsim.comparison.fit import family, fit_table
from microsim.comparison.metrics import bin_averages
from microsim.comparison.table_models import model_defaults
from microsim.measurement.simulation import simulate
from microsim.recipe import resolve
from microsim.surfaces import build_tile


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
    return changed(table, values=lambda e: avg, errors=lambda e: 0.01 * avg + 1e-12)


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
    noisy = changed(clean, values=lambda e: e.values * (
        1 + 0.01 * rng.standard_normal(e.values.shape)))
    r = fit_table(noisy, "microcylinder", "single", start=truth)  # convergence: above
    z = np.array([(r.params[k] - t) / r.uncertainty[k]
                  for k, t in zip(r.params, truth, strict=True)])
    assert np.all(np.abs(z) < 4), dict(zip(r.params, z, strict=True))


def test_kay_kajiya_fit_uses_the_cylinders_axis_and_coverage():
    """Kay-Kajiya on a cylinders table: the tangent (+y) and coverage (2r/s) come from
    the table, so a table made from kd = 0.02, ks = (0.3, 0.2, 0.1), n = 40 comes back
    within 2%; the fit holds them with the table's sources."""
    table = template({"kind": "cylinders", "radius": 0.25, "spacing": 1.0},
                     {"kind": "lambertian", "albedo": 0.5}, [0.0, 60.0])
    assert model_defaults(table.meta)["coverage"] == pytest.approx(0.5)
    truth = [0.02, 0.02, 0.02, 0.3, 0.2, 0.1, 40.0]
    r = fit_table(made_from(table, "kay-kajiya", truth), "kay-kajiya", "single")
    for name, value in zip(r.params, truth, strict=True):
        assert r.params[name] == pytest.approx(value, rel=0.02)
    assert r.held == {"tangent_theta": 90.0, "tangent_phi": 90.0, "coverage": 0.5}
    # one row per incidence, θi outer and φi inner, with the table's albedo
    np.testing.assert_allclose([(row.theta_i, row.phi_i) for row in r.per_theta_i],
                               [(20.0, 0.0), (20.0, 60.0), (50.0, 0.0), (50.0, 60.0)],
                               rtol=0, atol=1e-12)
    table = made_from(table, "kay-kajiya", truth)
    for row, (k, j) in zip(r.per_theta_i, np.ndindex(2, 2), strict=True):
        np.testing.assert_array_equal(row.albedo_table, table["single"].albedo[k, j])
    assert r.held_sources == {"tangent_theta": "the cylinders' axis",
                              "tangent_phi": "the cylinders' axis",
                              "coverage": "2 radius / spacing of the recipe's surface"}


def test_fibre_families_hold_the_tables_geometry_with_its_source():
    """The fibre families hold their geometry: a key the defaults give is held at that
    value with the defaults' source (``ModelDefaults.sources``), or "the table's" for a
    plain mapping without sources; a key they do not give is held at the family's own
    default, with source "default"."""
    from microsim.comparison.table_models import ModelDefaults

    given = ModelDefaults()
    given.put("coverage", 0.4, "2 radius / spacing of the cylinders")
    given.put("tangent_phi", 30.0, "the cylinders' axis")
    _, fam = family("kay-kajiya", given)
    assert fam.held == {"tangent_theta": 90.0, "tangent_phi": 30.0, "coverage": 0.4}
    assert fam.held_sources == {"tangent_theta": "default",
                                "tangent_phi": "the cylinders' axis",
                                "coverage": "2 radius / spacing of the cylinders"}
    _, fam = family("kay-kajiya", {"coverage": 0.4})
    assert fam.held == {"tangent_theta": 90.0, "tangent_phi": 90.0, "coverage": 0.4}
    assert fam.held_sources == {"tangent_theta": "default", "tangent_phi": "default",
                                "coverage": "the table's"}
    _, fam = family("microcylinder", {"slope": 0.3})
    assert fam.held == {"slope": 0.3, "flat": 0.0}
    assert fam.held_sources == {"slope": "the table's", "flat": "default"}
    # without defaults: a straight thread along +y, fully covering
    _, fam = family("kay-kajiya")
    assert fam.held == {"tangent_theta": 90.0, "tangent_phi": 90.0, "coverage": 1.0}
    _, fam = family("microcylinder")
    assert fam.held == {"slope": 0.0, "flat": 0.0}
    assert set(fam.held_sources.values()) == {"default"}


def test_fibre_families_build_the_models_they_name():
    """Each fibre family's model at a parameter vector, at random pairs of directions, is
    the model it names built directly (to 1e-12 relative, the same arithmetic; the
    spectral cloth to 1e-9, an affine combination of three RGB evaluations): Kay-Kajiya
    per channel with kd, ks per channel and a shared n, about the held tangent (θ, φ in
    degrees) with the held coverage; the microcylinder cloth with γ_s, γ_v in degrees
    and the volume scales per family (warp, then weft) and channel, on the held weave's
    tangent curves — for RGB channels and, channel by channel, for three wavelengths."""
    from microsim.analytic.brdf import KayKajiya
    from microsim.analytic.cloth import MicrocylinderCloth

    wi, wo = _directions(100, 3), _directions(100, 4)
    geometry = {"tangent_theta": 70.0, "tangent_phi": 30.0, "coverage": 0.4}
    _, fam = family("kay-kajiya", geometry)
    kd, ks, n = [0.02, 0.03, 0.04], [0.3, 0.2, 0.1], 40.0
    got = fam.build(np.array([*kd, *ks, n])).eval(wi, wo)
    th, ph = np.radians(70.0), np.radians(30.0)
    t = [np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)]
    expected = np.stack([KayKajiya(t, kd[c], ks[c], n, 0.4).eval(wi, wo)
                         for c in range(3)], axis=-1)
    assert np.ptp(expected) > 0
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=0)

    weave = {"slope": 0.5, "flat": 1 / 3}
    params = [0.7, 0.6, 1.6, 7.0, 17.0, 0.4, 0.2, 0.3, 0.8, 0.9, 0.8, 0.7]
    albedo = np.array(params[6:]).reshape(2, 3)
    expected = MicrocylinderCloth([0.7, 0.6], 1.6, np.radians(7.0), np.radians(17.0), 0.4,
                                  albedo, 0.5, 1 / 3).eval(wi, wo)
    assert expected.shape == (100, 3) and np.ptp(expected) > 0
    _, fam = family("microcylinder", weave)
    np.testing.assert_allclose(fam.build(np.array(params)).eval(wi, wo), expected,
                               rtol=1e-12, atol=0)
    spectral = ("450nm", "550nm", "650nm")
    _, fam = family("microcylinder", weave, spectral)
    assert fam.names[6:] == tuple(f"A_{p}_{c}" for p in ("warp", "weft") for c in spectral)
    np.testing.assert_allclose(fam.build(np.array(params)).eval(wi, wo), expected,
                               rtol=1e-9, atol=1e-15)


def test_fibre_families_name_their_parameters_and_start_from_the_tables_geometry():
    """The fibre families' parameters by name, in the order their builders read them
    (docs/compare.md, docs/surfaces.md): Kay-Kajiya's kd and ks per channel, then n; the
    cloth's a_warp, a_weft, η, γ_s, γ_v, k_d, then A per yarn family and channel. The
    starts a table's defaults set: Kay-Kajiya's kd at the table's (its Lambertian fibres'
    albedo / π²), else a mid-grey fibre's 0.5 / π² (0.05, to 1e-3); the cloth's coverages
    at yarn width / spacing (the weave's defaults 0.8 and 1 when the table has none),
    below 0.95 (as a weave's yarns are: ``surfaces.rules``), and each family's volume
    scales at the mean albedo of its yarns (0.5 without). Every start is finite and
    within the family's range."""
    rgb = ("R", "G", "B")
    _, fam = family("kay-kajiya", {"kd": 0.02})
    assert fam.names == ("kd_R", "kd_G", "kd_B", "ks_R", "ks_G", "ks_B", "n")
    assert fam.start[:3] == (0.02, 0.02, 0.02)
    _, fam = family("kay-kajiya")
    assert fam.start[:3] == pytest.approx([0.5 / np.pi**2] * 3, abs=1e-3)
    starts = [fam]
    _, fam = family("microcylinder")
    assert fam.names == ("a_warp", "a_weft", "eta", "gamma_s", "gamma_v", "kd",
                         *(f"A_{p}_{c}" for p in ("warp", "weft") for c in rgb))
    assert fam.start[:2] == pytest.approx((0.8, 0.8), rel=1e-12)
    assert fam.start[6:] == pytest.approx([0.5] * 6, rel=1e-12)
    starts.append(fam)
    weave = {"yarn_width": 0.6, "spacing": 2.0, "albedo_warp": [0.2, 0.4, 0.6],
             "albedo_weft": [0.1, 0.2, 0.3]}
    _, fam = family("microcylinder", weave)
    assert fam.start[:2] == pytest.approx((0.3, 0.3), rel=1e-12)
    assert fam.start[6:] == pytest.approx([0.4] * 3 + [0.2] * 3, rel=1e-12)
    starts.append(fam)
    _, fam = family("microcylinder", {"yarn_width": 1.2, "spacing": 1.0})
    assert fam.start[:2] == (0.95, 0.95)
    for f in [*starts, fam]:
        start = np.array(f.start)
        assert np.all(np.isfinite(start))
        assert np.all(np.array(f.lower) <= start) and np.all(start <= np.array(f.upper))


def test_cloth_of_two_wavelengths_is_the_rgb_model_channel_by_channel():
    """The cloth family of a two-wavelength table (neither RGB nor three channels) at a
    parameter vector is, per channel, ``MicrocylinderCloth`` built with that channel's
    volume scales for all three of its channels (to 1e-9 relative, atol 1e-15: an affine
    combination of three evaluations)."""
    from microsim.analytic.cloth import MicrocylinderCloth

    wi, wo = _directions(100, 7), _directions(100, 8)
    weave = {"slope": 0.5, "flat": 1 / 3}
    _, fam = family("microcylinder", weave, ("450nm", "650nm"))
    params = [0.7, 0.6, 1.6, 7.0, 17.0, 0.4, 0.2, 0.8, 0.9, 0.3]
    got = fam.build(np.array(params)).eval(wi, wo)
    albedo = np.array(params[6:]).reshape(2, 2)
    expected = np.stack([MicrocylinderCloth([0.7, 0.6], 1.6, np.radians(7.0),
                                            np.radians(17.0), 0.4,
                                            np.repeat(albedo[:, c:c + 1], 3, axis=1),
                                            0.5, 1 / 3).eval(wi, wo)[..., 0]
                         for c in range(2)], axis=-1)
    assert got.shape == (100, 2) and np.ptp(expected) > 0
    np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-15)
