"""Fitting models back from tables made from them, and from a simulation."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from tablefixtures import changed

from microsim.analytic.brdf import OrenNayar, TorranceSparrow
from microsim.analytic.fresnel import SchlickFresnel
from microsim.analytic.ndf import Beckmann
from microsim.comparison.fit import fit_table
from microsim.comparison.metrics import model_table
from microsim.tables.binning import HemisphereBins

THETA_I = np.radians([0.0, 30.0, 60.0])


def table_of(model, sigma_rel=0.0, seed=0):
    """Bins = the model's bin averages (8² midpoints per bin), optionally with Gaussian
    noise of known relative σ, reported as the error."""
    return model_table(model, THETA_I, HemisphereBins(16, 32), sigma_rel,
                       np.random.default_rng(seed))


def test_beckmann_without_noise_comes_back_within_one_percent():
    truth = TorranceSparrow(Beckmann(0.4), fresnel=SchlickFresnel(np.array([0.9, 0.6, 0.3])))
    r = fit_table(table_of(truth), "beckmann")
    assert r.params["alpha"] == pytest.approx(0.4, rel=0.01)
    for ch, f0 in zip("RGB", (0.9, 0.6, 0.3), strict=True):
        assert r.params[f"F0_{ch}"] == pytest.approx(f0, rel=0.01)


def test_noisy_fit_within_two_sigma():
    """5% relative noise per bin: the fitted α lies within 2 reported σ of the truth
    (a 95% interval; fixed seed)."""
    truth = TorranceSparrow(Beckmann(0.25), fresnel=SchlickFresnel(np.array([0.8, 0.8, 0.8])))
    r = fit_table(table_of(truth, 0.05, seed=5), "beckmann")
    a, s = r.params["alpha"], r.uncertainty["alpha"]
    assert 0 < s < 0.05 and abs(a - 0.25) < 2 * s
    assert 0.5 < r.chi2_dof < 2.0  # the errors describe the noise


def test_oren_nayar_without_noise():
    truth = OrenNayar(0.35, [0.7, 0.5, 0.3])
    r = fit_table(table_of(truth), "oren-nayar")
    assert r.params["sigma"] == pytest.approx(math.degrees(0.35), rel=0.01)  # degrees
    assert r.params["albedo_G"] == pytest.approx(0.5, rel=0.01)


@pytest.mark.parametrize(("spec", "truth"), [
    ("ggx", {"alpha": 0.3, "F0_R": 0.9, "F0_G": 0.6, "F0_B": 0.3}),
    ("phong", {"n": 40.0, "ks_R": 0.6, "ks_G": 0.5, "ks_B": 0.4}),
    ("lafortune:2", {"Cxy_1": -0.9, "Cz_1": 0.95, "n_1": 30.0,
                     "Cxy_2": -0.4, "Cz_2": 0.5, "n_2": 3.0}),
])
def test_other_families_recover_their_own_parameters(spec, truth):
    """A noiseless table made from the family's own model with known parameters (8²
    midpoints per bin) comes back within 1% per parameter: the fit's coarser bin averages
    (5² midpoints) are the only difference, and moved no parameter by more than 0.2% when
    this was written."""
    from microsim.comparison.fit import family

    _, fam = family(spec)
    model = fam.build(np.array([truth[name] for name in fam.names]))
    r = fit_table(table_of(model), spec)
    assert set(r.params) == set(truth) == set(r.uncertainty)
    assert r.model == spec
    for name, value in truth.items():
        assert r.params[name] == pytest.approx(value, rel=0.01), name
    assert r.median_rel_error < 0.01


def test_simulated_gaussian_fits_beckmann_at_its_realised_alpha(cli, tmp_path):
    """A simulated α = 0.3 mirror surface (8 realisations of 256² tiles, 32 correlation
    lengths): the fitted α of its single scattering lies within 1.5% of the realised α
    pooled over the tiles (measured 0.34%, with the pooled α's own error 0.9%). On one
    tile the bound was 5%: its finite slope sample moved the fit 1.6% from its realised
    α."""
    from pathlib import Path

    recipe = Path(__file__).resolve().parent.parent / "surfaces" / "gaussian-0.3.toml"
    exr = tmp_path / "g.exr"
    assert cli("simulate", str(recipe), "-o", str(exr), "--rays", "100000",
               "--realisations", "8", "--set", "table.sh_order=0", "--set",
               "simulation.theta_i=[0, 30, 60]", "--set", "table.theta_bins=16",
               "--set", "table.phi_bins=32")[0] == 0
    code, out, err = cli("fit", str(exr), "--model", "beckmann", "--component", "single",
                         "--json", "--plot", str(tmp_path / "fit.png"))
    assert code == 0, err
    r = json.loads(out)
    from microsim import read_table
    realised = read_table(exr).meta.surface.alpha_realised.alpha
    assert r["params"]["alpha"] == pytest.approx(realised, rel=0.015)
    assert (tmp_path / "fit.png").stat().st_size > 20_000


@pytest.mark.parametrize(("model", "needle"), [("beckman", "must be one of"),
                                                ("lafortune:9", "1 to 4 lobes")])
def test_bad_model_exits_2(cli, tmp_path, model, needle):
    code, _, err = cli("fit", str(tmp_path / "none.exr"), "--model", model)
    assert code == 2 and err.startswith("error: ") and needle in err


def test_a_table_with_nothing_to_fit_is_an_error_line():
    """No light in the component (a black surface): every error undefined, nothing to fit
    (it printed parameters ± nan with exit 0); a model that is not finite over the bins
    is an error too (scipy's 'residuals are not finite' was a traceback): one Lafortune
    lobe at its widest C and sharpest n overflows at its peak."""
    from microsim.errors import InputError

    table = table_of(OrenNayar(0.35, [0.7, 0.5, 0.3]))
    for c in table.components:
        table[c].values[:] = 0.0
        table[c].errors[:] = np.nan
    with pytest.raises(InputError, match="has 0 bins with light"):
        fit_table(table, "beckmann")
    table = table_of(OrenNayar(0.35, [0.7, 0.5, 0.3]))
    with pytest.raises(InputError, match=r"^fit lafortune: .*not finite.* \(the model's "
                       r"values over this table's bins are not finite at the start values "
                       r"or during the fit\)$"):
        with np.errstate(over="ignore", invalid="ignore"):  # 50^(10^4) = inf
            fit_table(table, "lafortune", start=[-50.0, 50.0, 1e4])


def test_the_text_report_prints_digits_that_mean_something(cli):
    """fit's text report of a simulated table (the shipped reference: 8 realisations):
    the realised α with its standard error over the tiles, as simulate prints it, and
    no number with more than 6 decimals (it printed the α as 0.2989056262731985); the
    albedo columns name the channels they average, R, G and B for an RGB table."""
    import re
    from pathlib import Path

    reference = (Path(__file__).resolve().parent.parent / "tables" / "reference"
                 / "gaussian-0.3-facets.exr")
    code, out, err = cli("fit", str(reference), "--model", "beckmann")
    assert code == 0, err
    assert not re.search(r"\d\.\d{7,}", out), out
    assert re.search(r"surface: alpha realised 0\.\d{4} ± [\d.]+ over 8 tiles", out), out
    assert "(albedos: means over R, G and B; --json gives each)" in out


def _chi2_dof(table, model, nparams, component="total"):
    """χ²/dof of ``model`` against a table's component, the module docstring's residuals
    written out: r = (ln(m + ε) − ln(s + ε)) / √((σ / (s + ε))² + ρ²) over the bins with a
    defined error, ε = 10⁻³ × the peak, ρ = 1%, m the model's bin averages over 5²
    midpoints (as the fit's), dof = bins − parameters (at least 1)."""
    from microsim.comparison.metrics import bin_averages, channels_of

    sim, err = table[component].values, table[component].errors
    eps = 1e-3 * np.nanmax(sim)
    keep = np.isfinite(err)
    m = channels_of(bin_averages(model, table.axes, 5), table.channels.count)[keep]
    s = sim[keep]
    r = (np.log(np.maximum(m, 0.0) + eps) - np.log(s + eps)) / np.sqrt(
        (err[keep] / (s + eps)) ** 2 + 0.01**2)
    return float(r @ r) / max(int(keep.sum()) - nparams, 1)


def _beckmann(alpha, f0):
    return TorranceSparrow(Beckmann(alpha), fresnel=SchlickFresnel(np.asarray(f0, float)),
                           shadowing="smith-correlated")


def test_fit_json_is_the_result_with_one_row_per_incidence():
    """``FitResult.to_json`` (what ``fit --json`` prints): exactly the documented keys
    with the result's values, through a JSON round trip; per incidence θi, φi in degrees
    and the albedos Σ f_r Ω_proj per channel, of the table (its own albedo) and of the
    fitted model (its 8² midpoint bin averages made into a table, to 1e-9 relative:
    the same sums in another order). The table's total is twice its single scattering
    and the fit is of ``single``: its median relative error is against that (below 1%:
    the fit reproduces it). ``fitted`` is the model at the parameters (to 1e-12 at random
    directions: the same arithmetic) and ``model_bins`` its 8² midpoint bin averages (to
    1e-9)."""
    truth = OrenNayar(0.35, [0.7, 0.5, 0.3])
    table = table_of(truth)
    table = table.with_estimate("total", values=2.0 * table["single"].values)
    r = fit_table(table, "oren-nayar", "single")
    assert r.median_rel_error < 0.01
    j = json.loads(json.dumps(r.to_json()))
    assert set(j) == {"model", "params", "uncertainty", "held", "held_sources",
                      "chi2_dof", "median_rel_error", "per_theta_i", "nfev"}
    assert j["model"] == "oren-nayar"
    assert j["params"] == r.params and list(j["params"]) == list(r.params)
    assert j["uncertainty"] == r.uncertainty and set(j["uncertainty"]) == set(r.params)
    assert j["held"] == {"model": "full"} and j["held_sources"] == {"model": "default"}
    assert j["chi2_dof"] == r.chi2_dof and j["median_rel_error"] == r.median_rel_error
    assert j["nfev"] == r.nfev >= 1
    fitted = OrenNayar(np.radians(r.params["sigma"]),
                       [r.params[f"albedo_{c}"] for c in "RGB"])
    wi, wo = _directions(100, 5), _directions(100, 6)
    np.testing.assert_allclose(r.fitted.eval(wi, wo), fitted.eval(wi, wo), rtol=1e-12)
    expected = model_table(fitted, THETA_I, HemisphereBins(16, 32))
    np.testing.assert_allclose(r.model_bins, expected["total"].values, rtol=1e-9, atol=0)
    expected = expected["total"].albedo
    assert len(j["per_theta_i"]) == 3
    for k, row in enumerate(j["per_theta_i"]):
        assert set(row) == {"theta_i", "phi_i", "albedo_fit", "albedo_table"}
        assert row["theta_i"] == pytest.approx(math.degrees(THETA_I[k]), abs=1e-12)
        assert row["phi_i"] == 0.0
        assert row["albedo_table"] == table["single"].albedo[k, 0].tolist()
        assert row["albedo_fit"] == pytest.approx(expected[k, 0].tolist(), rel=1e-9)
        assert row == r.per_theta_i[k].to_json()


@pytest.mark.parametrize(("spec", "held"), [
    ("beckmann", {"shadowing": "smith-correlated"}),
    ("ggx", {"shadowing": "smith-correlated"}),
    ("oren-nayar", {"model": "full"}),
    ("phong", {"normalized": True}),
])
def test_families_hold_their_fixed_parameters_by_default(spec, held):
    """The analytic families hold one fixed choice each, the one their models are built
    with (``test_families_build_the_models_they_name``), from the family's default."""
    from microsim.comparison.fit import family

    _, fam = family(spec)
    assert fam.held == held
    assert fam.held_sources == dict.fromkeys(held, "default")


def _directions(n, seed):
    """n random directions in the upper hemisphere (z ≥ 0.05)."""
    rng = np.random.default_rng(seed)
    z = rng.uniform(0.05, 1.0, n)
    phi = rng.uniform(0.0, 2 * np.pi, n)
    s = np.sqrt(1 - z**2)
    return np.stack([s * np.cos(phi), s * np.sin(phi), z], axis=-1)


def test_families_build_the_models_they_name():
    """Each family's model at a parameter vector, at random pairs of directions, is the
    model it names built directly from those parameters (in the order of the names):
    GGX or Beckmann Torrance-Sparrow with Schlick's F0 per channel and correlated Smith
    masking, Oren-Nayar's full model with σ in degrees, normalised Phong times ks per
    channel, Lafortune's isotropic lobes (Cxy, Cxy, Cz, n). To 1e-12 relative: the same
    arithmetic."""
    from microsim.analytic.brdf import Lafortune, Phong
    from microsim.analytic.ndf import GGX
    from microsim.comparison.fit import family

    wi, wo = _directions(200, 1), _directions(200, 2)
    f0 = np.array([0.9, 0.6, 0.3])
    cases = [
        ("beckmann", [0.3, *f0], _beckmann(0.3, f0).eval(wi, wo)),
        ("ggx", [0.3, *f0], TorranceSparrow(GGX(0.3), fresnel=SchlickFresnel(f0),
                                            shadowing="smith-correlated").eval(wi, wo)),
        ("oren-nayar", [20.0, 0.7, 0.5, 0.3],
         OrenNayar(np.radians(20.0), [0.7, 0.5, 0.3], "full").eval(wi, wo)),
        ("phong", [30.0, 0.6, 0.5, 0.4],
         Phong(30.0, normalized=True).eval(wi, wo)[..., None] * [0.6, 0.5, 0.4]),
        ("lafortune:2", [-0.9, 0.95, 30.0, -0.4, 0.5, 3.0],
         Lafortune([(-0.9, -0.9, 0.95, 30.0), (-0.4, -0.4, 0.5, 3.0)]).eval(wi, wo)),
    ]
    for spec, params, expected in cases:
        _, fam = family(spec)
        got = np.asarray(fam.build(np.array(params, float)).eval(wi, wo))
        assert got.shape == np.shape(expected), spec
        assert np.all(np.isfinite(expected)) and np.ptp(expected) > 0, spec
        np.testing.assert_allclose(got, expected, rtol=1e-12, atol=0, err_msg=spec)


@pytest.mark.parametrize("reported", [1.0, 0.5])
def test_chi2_and_uncertainties_are_the_documented_ones(reported):
    """With 5% noise (seeded), reported as it is or as half of it (then χ²/dof is about
    2.1 and scales the uncertainties): the reported χ²/dof is the module docstring's,
    written out at the fitted parameters (to 1e-9 relative); the uncertainties are
    √diag((JᵀJ)⁻¹) × √max(χ²/dof, 1) with J the residuals' Jacobian by central
    differences (step 1e-6 relative), to 1% (the difference quotient's error and the
    least-squares solver's own Jacobian, which is also a difference quotient)."""
    truth = _beckmann(0.25, [0.8, 0.6, 0.4])
    table = table_of(truth, 0.05, seed=3)
    table = changed(table, errors=lambda e: e.errors * reported)
    r = fit_table(table, "beckmann")
    p = np.array(list(r.params.values()))
    assert r.chi2_dof == pytest.approx(_chi2_dof(table, _beckmann(p[0], p[1:]), 4), rel=1e-9)
    assert r.chi2_dof > (0.5 if reported == 1.0 else 1.5)

    from microsim.comparison.metrics import bin_averages

    sim, err = table["total"].values, table["total"].errors
    eps = 1e-3 * sim.max()
    keep = np.isfinite(err)
    sigma = np.sqrt((err[keep] / (sim[keep] + eps)) ** 2 + 0.01**2)

    def res(q):
        m = bin_averages(_beckmann(q[0], q[1:]), table.axes, 5)[keep]
        return (np.log(np.maximum(m, 0) + eps) - np.log(sim[keep] + eps)) / sigma

    jac = np.empty((int(keep.sum()), 4))
    for i in range(4):
        h = 1e-6 * p[i]
        dp = np.zeros(4)
        dp[i] = h
        jac[:, i] = (res(p + dp) - res(p - dp)) / (2 * h)
    expected = np.sqrt(np.diag(np.linalg.inv(jac.T @ jac)) * max(r.chi2_dof, 1.0))
    assert list(r.uncertainty.values()) == pytest.approx(expected.tolist(), rel=0.01)


def _with_surface(table, surface):
    from dataclasses import replace

    return replace(table, meta=replace(table.meta, surface=surface))


def test_microfacet_fits_start_at_the_tables_realised_alpha():
    """The first evaluation (the progress callback's first χ²/dof) is at the start: for
    a microfacet family α is the table's isotropic realised α (0.35 here) with the
    family's F0s; an explicit start is taken as given, and another family (Phong), an
    anisotropic realised α or a table without surface facts start at the family's
    ``start``. Each compared with the docstring's χ²/dof of the model built directly at
    that start, to 1e-9 relative; evaluations count from 1."""
    from microsim.analytic.brdf import Phong
    from microsim.comparison.fit import family
    from microsim.surfaces.facts import Roughness, SurfaceFacts, TileFacts

    table = table_of(_beckmann(0.4, [0.9, 0.6, 0.3]))

    def first(t, spec, start=None):
        seen = []
        fit_table(t, spec, start=start, progress=seen.append)
        assert [s.evaluations for s in seen] == list(range(1, len(seen) + 1))
        assert seen[0].to_json() == {"evaluations": 1, "chi2_dof": seen[0].chi2_dof}
        return seen[0].chi2_dof

    def facts(alpha):
        return SurfaceFacts(TileFacts(kind="analytic", alpha_realised=alpha))

    alpha, *f0 = family("beckmann")[1].start
    n, *ks = family("phong")[1].start
    realised = _with_surface(table, facts(Roughness(0.35)))
    assert first(realised, "beckmann") == pytest.approx(
        _chi2_dof(table, _beckmann(0.35, f0), 4), rel=1e-9)
    assert first(realised, "beckmann", [0.5, 0.8, 0.7, 0.6]) == pytest.approx(
        _chi2_dof(table, _beckmann(0.5, [0.8, 0.7, 0.6]), 4), rel=1e-9)

    class Scaled:
        def eval(self, wi, wo):
            return Phong(n, normalized=True).eval(wi, wo)[..., None] * np.array(ks)

    assert first(realised, "phong") == pytest.approx(_chi2_dof(table, Scaled(), 4), rel=1e-9)
    own = _chi2_dof(table, _beckmann(alpha, f0), 4)
    assert alpha != 0.35
    assert first(_with_surface(table, facts(Roughness(0.2, 0.5))), "beckmann") \
        == pytest.approx(own, rel=1e-9)
    assert first(_with_surface(table, None), "beckmann") == pytest.approx(own, rel=1e-9)


def test_a_fit_needs_more_bins_with_light_than_parameters():
    """Exactly as many bins with a defined error (per channel) as parameters (4 for
    Beckmann with RGB F0) is refused, naming both numbers; one more is fitted, with one
    degree of freedom: its χ²/dof is the docstring's written out with dof = 1 (to 1e-9
    relative), and positive (the five bins' values scaled apart so four parameters cannot
    meet them all)."""
    from microsim.errors import InputError

    table = table_of(_beckmann(0.4, [0.9, 0.6, 0.3]))
    flat = table["total"].errors.reshape(-1)
    lit = np.flatnonzero(table["total"].values.reshape(-1) > 0.1)
    table = changed(table, errors=lambda e: np.full_like(e.errors, np.nan))
    for c in table.components:
        table[c].errors.reshape(-1)[lit[:4]] = flat[lit[:4]]
    with pytest.raises(InputError, match="has 4 bins with light .* not more than the 4 "
                       "parameters to fit: nothing escaped into it to fit a model to"):
        fit_table(table, "beckmann")
    table = changed(table, values=lambda e: e.values.copy())
    for c in table.components:
        table[c].errors.reshape(-1)[lit[4]] = flat[lit[4]]
        table[c].values.reshape(-1)[lit[:5]] *= [1.0, 1.5, 0.7, 1.2, 0.8]
    r = fit_table(table, "beckmann")
    p = list(r.params.values())
    assert r.chi2_dof > 1.0
    assert r.chi2_dof == pytest.approx(_chi2_dof(table, _beckmann(p[0], p[1:]), 4), rel=1e-9)


def test_a_fit_over_the_memory_budget_names_its_residuals(monkeypatch):
    """16 × 32 bins × 3 incidences × 3 channels = 4608 residuals at 800 B each need
    3.69 MB = 0.00343 GiB; under a 1 MiB budget the refusal says what needs it, how
    much, and how to need less."""
    from microsim.errors import InputError

    monkeypatch.setenv("MICROSIM_MEMORY_LIMIT", str(2**-10))
    with pytest.raises(InputError, match=r"^fit beckmann: 4,608 residuals \(bins with "
                       r"light, per channel\) needs about 0\.00343 GiB \(estimated\), over "
                       r"the 0\.000976562 GiB limit; fit a table of fewer bins or "
                       r"incidences, or raise the limit"):
        fit_table(table_of(_beckmann(0.4, [0.9, 0.6, 0.3])), "beckmann")


def test_a_spectral_table_fits_one_colour_parameter_per_wavelength():
    """A table of two wavelengths: Beckmann's F0 per channel, named by wavelength, back
    within 1% (noiseless)."""
    from microsim.spectra.channels import Channels

    channels = Channels((450.0, 650.0))
    table = model_table(_beckmann(0.3, [0.8, 0.4]), THETA_I, HemisphereBins(16, 32),
                        channels=channels)
    r = fit_table(table, "beckmann")
    assert list(r.params) == ["alpha", "F0_450nm", "F0_650nm"]
    assert list(r.params.values()) == pytest.approx([0.3, 0.8, 0.4], rel=0.01)


@pytest.mark.parametrize(("spec", "model", "expected"), [
    # brighter than F0 = 1 allows: F0 stays a reflectance
    ("beckmann", _beckmann(0.3, [1.0] * 3), {"F0_R": 1.0, "F0_G": 1.0, "F0_B": 1.0}),
    # Lambertian with albedo 1.5: the facet albedo stays at most 1, σ at least 0
    ("oren-nayar", OrenNayar(0.0, [1.5] * 3), {"albedo_G": 1.0, "sigma": 0.0}),
    # Lambertian: the flattest Phong lobe, n = 0 (never negative)
    ("phong", OrenNayar(0.0, [0.5] * 3), {"n": 0.0}),
])
def test_fitted_reflectances_stay_physical(spec, model, expected):
    """Where a table asks for more than the model allows (F0 or an albedo above 1, or a
    slope spread or exponent below 0), the fit ends on the bound: within 1e-3 absolute
    (the solver stops within its tolerance of the optimum on the bound; measured
    within 1e-9)."""
    scale = 1.5 if spec == "beckmann" else 1.0
    table = table_of(model)
    table = changed(table, values=lambda e: e.values * scale,
                    errors=lambda e: e.errors * scale)
    r = fit_table(table, spec)
    for name, value in expected.items():
        assert r.params[name] == pytest.approx(value, abs=1e-3), (name, r.params)


def test_a_broad_lafortune_lobe_keeps_its_exponent_below_one():
    """A noiseless table of one broad lobe (Cxy = −0.8, Cz = 0.9, n = 0.5): the fitted
    exponent is within 10% of 0.5, not held at 1 or more. The lobe's edge, where its base
    crosses 0 and xⁿ has an infinite slope, is where the table's 8² midpoints and the
    fit's 5² differ most (χ²/dof 6-8) and the minimum is rough: from six starts n came
    back between 0.499 and 0.527. The spec without lobes is one lobe."""
    from microsim.analytic.brdf import Lafortune

    r = fit_table(table_of(Lafortune([(-0.8, -0.8, 0.9, 0.5)])), "lafortune")
    assert r.model == "lafortune:1" and list(r.params) == ["Cxy_1", "Cz_1", "n_1"]
    assert r.params["n_1"] == pytest.approx(0.5, rel=0.1)


RANGES = {
    "beckmann": {"alpha": ("0.001", "5"), "F0": ("0", "1")},
    "ggx": {"alpha": ("0.001", "5"), "F0": ("0", "1")},
    "oren-nayar": {"sigma": ("0", "85.9437"), "albedo": ("0", "1")},
    "phong": {"n": ("0", "100000"), "ks": ("0", "5")},
    "lafortune:2": {"Cxy": ("-50", "50"), "Cz": ("-50", "50"), "n": ("0", "10000")},
    "kay-kajiya": {"kd": ("0", "10"), "ks": ("0", "1000"), "n": ("0", "10000")},
    "microcylinder": {"a": ("0", "1"), "eta": ("1.01", "3"), "gamma_s": ("0.286479", "57.2958"),
                      "gamma_v": ("0.286479", "85.9437"), "kd": ("0", "1"), "A": ("0", "5")},
}
"""The ranges each family's parameters are fitted within, as the refusal prints them (6
significant figures): reflectances, albedos and coverages in [0, 1]; the angles in degrees
(σ and γ_v up to 1.5 rad, γ_s from 0.005 to 1 rad, γ_v from 0.005 rad); the caps the fits
in docs/compare.md and docs/surfaces.md end on (Kay-Kajiya's n = 10⁴, the cloth's η = 3,
γ_v = 85.9°, k_d = 1, a = 1); the others' caps (α 5, Phong's n 10⁵ and ks 5, Lafortune's
C ±50 and n 10⁴, Kay-Kajiya's kd 10 and ks 10³, the cloth's volume scales 5)."""


def test_a_start_outside_a_parameters_range_is_refused_naming_the_range():
    """Every parameter of every family, started just outside its range (above and below,
    by 10⁻⁵ relative: beyond the printed range's rounding) with the others at the
    family's start, is refused before any evaluation, naming the parameter and its range
    (it was scipy's "outside of provided bounds" with a parenthesis blaming non-finite
    model values), and so is a NaN; a start of another length than the parameters is
    refused naming them."""
    import re

    from microsim.comparison.fit import family
    from microsim.errors import InputError

    table = model_table(OrenNayar(0.3, 0.5), np.radians([30.0]), HemisphereBins(4, 8))
    for spec, ranges in RANGES.items():
        _, fam = family(spec)
        for i, name in enumerate(fam.names):
            lo, hi = ranges[name if name in ranges else name.split("_")[0]]
            for value in (float(lo) - 1e-5 * max(1.0, abs(float(lo))),
                          float(hi) + 1e-5 * max(1.0, abs(float(hi)))):
                start = np.array(fam.start)
                start[i] = value
                with pytest.raises(InputError, match=rf"^fit {re.escape(spec.split(':')[0])}: "
                                   rf"start {name} = \S+ outside its range "
                                   rf"\[{re.escape(lo)}, {re.escape(hi)}\]$"):
                    fit_table(table, spec, start=start)
    with pytest.raises(InputError, match=r"^fit phong: start n = nan outside its range "
                       r"\[0, 100000\]$"):
        fit_table(table, "phong", start=[np.nan, 1.0, 1.0, 1.0])
    for start in ([0.3, 0.9, 0.9], [0.3, 0.9, 0.9, 0.9, 0.9]):
        with pytest.raises(InputError, match=rf"^fit beckmann: {len(start)} start values for "
                           r"the 4 parameters \(alpha, F0_R, F0_G, F0_B\)$"):
            fit_table(table, "beckmann", start=start)


@pytest.mark.parametrize("k", ["1", "4"])
def test_lafortune_takes_one_to_four_lobes(k):
    """``lafortune:1`` to ``lafortune:4`` are K lobes of three parameters each (1 and 4
    here, the ends); 0, 5, a sign or a word are refused with the range and an example."""
    from microsim.comparison.fit import family
    from microsim.errors import InputError

    name, fam = family(f"lafortune:{k}")
    assert name == "lafortune"
    assert fam.names == tuple(f"{p}_{i}" for i in range(1, int(k) + 1)
                              for p in ("Cxy", "Cz", "n"))
    bad = {"1": "0", "4": "5"}[k]
    for spec in (f"lafortune:{bad}", "lafortune:-1", "lafortune:two"):
        with pytest.raises(InputError) as exc:
            family(spec)
        assert str(exc.value) == f"--model {spec}: lafortune takes 1 to 4 lobes, e.g. lafortune:2"


def test_a_singular_fit_reports_nan_uncertainties():
    """A Lafortune lobe of exponent 0 (f_r = 1 wherever its base is positive: all of the
    hemisphere for Cxy = 0, Cz > 0) fitted from that lobe: the residuals do not depend on
    Cxy and Cz there (x⁰ = 1), so JᵀJ is singular and every uncertainty is a float NaN,
    not an error; the parameters stay at the start (it fits exactly: χ²/dof below 1e-12)."""
    from microsim.analytic.brdf import Lafortune

    r = fit_table(table_of(Lafortune([(0.0, 0.0, 1.0, 0.0)])), "lafortune",
                  start=[0.0, 1.0, 0.0])
    assert r.chi2_dof < 1e-12
    assert r.params == pytest.approx({"Cxy_1": 0.0, "Cz_1": 1.0, "n_1": 0.0}, abs=1e-9)
    assert all(isinstance(v, float) and math.isnan(v) for v in r.uncertainty.values())
