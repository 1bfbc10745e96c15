"""Model bin averages and comparison metrics, checked by independent quadrature."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy import integrate

from microsim.comparison.metrics import bin_average, metrics
from microsim.geometry import direction


class Lobe:
    """A smooth test lobe f = (1 + 3 x_o^2) z_o^2 exp(-2 (1 - wi.r)) — not a model of
    anything, just a function with structure in both θ and φ."""

    def eval(self, wi, wo):
        r = wo * np.array([-1.0, -1.0, 1.0])
        return (1 + 3 * wo[..., 0] ** 2) * wo[..., 2] ** 2 * np.exp(
            -2 * (1 - np.sum(wi * r, axis=-1)))


def edges(nt, nph):
    theta = np.arcsin(np.sqrt(np.linspace(0, 1, nt + 1)))
    return theta, np.linspace(0, 2 * np.pi, nph + 1)


def test_direction_is_unit_and_follows_the_frame():
    w = direction(np.array([0.0, np.pi / 2, np.pi / 2]), np.array([1.0, 0.0, np.pi / 2]))
    np.testing.assert_allclose(w, [[0, 0, 1], [1, 0, 0], [0, 1, 0]], atol=1e-15)


def test_constant_lobe_averages_to_itself():
    class Const:
        def eval(self, wi, wo):
            return np.full(wo.shape[:-1], 1 / np.pi)

    te, pe = edges(5, 7)
    avg = bin_average(Const(), direction(0.3, 0.0), te, pe)
    np.testing.assert_allclose(avg, 1 / np.pi, rtol=1e-14)


@pytest.mark.parametrize("bin_index", [(0, 0), (2, 3), (4, 6)])
def test_bin_average_equals_quadrature(bin_index):
    """Midpoint rule with n = 64 against scipy dblquad of f cos θ sin θ over the bin. In
    u = sin²θ the integrand is smooth except for a √u term at the pole, so the midpoint
    error falls as n^-1.5: 2.3e-4 relative at n = 24 in the pole bin, ~5e-5 at n = 64."""
    te, pe = edges(5, 7)
    wi = direction(0.5, 0.2)
    model = Lobe()
    avg = bin_average(model, wi, te, pe, phi_i=0.2, n=64)
    i, j = bin_index

    def integrand(theta, phi):
        wo = direction(theta, 0.2 + phi)
        return model.eval(wi, wo) * np.cos(theta) * np.sin(theta)

    val, _ = integrate.dblquad(integrand, pe[j], pe[j + 1], te[i], te[i + 1],
                               epsabs=1e-12, epsrel=1e-10)
    proj = 0.5 * (np.sin(te[i + 1]) ** 2 - np.sin(te[i]) ** 2) * (pe[j + 1] - pe[j])
    assert avg[i, j, 0] == pytest.approx(val / proj, rel=1e-4)


def test_metrics_of_a_perfect_match_and_of_a_known_bias():
    rng = np.random.default_rng(7)
    te, pe = edges(8, 16)
    proj = 0.5 * np.diff(np.sin(te) ** 2)[:, None] * np.diff(pe)[None, :]
    model = bin_average(Lobe(), direction(0.4, 0.0), te, pe)
    sigma = 0.01 * model + 1e-3
    sim = model + sigma * rng.standard_normal(model.shape)
    m = metrics(sim, sigma, model, proj)
    # z of pure Gaussian noise of known sigma: mean 0 ± 1/sqrt(N), std 1 ± 1/sqrt(2N);
    # 4-sigma bounds over N = 3 x lobe bins samples
    n = 3 * m.lobe_bins
    assert abs(m.z_mean) < 4 / np.sqrt(n)
    assert abs(m.z_std - 1) < 4 / np.sqrt(2 * n)
    biased = metrics(1.05 * model, sigma, model, proj)
    assert biased.median_rel_error == pytest.approx(0.05, rel=1e-12)
    np.testing.assert_allclose(biased.albedo_difference,
                               0.05 * np.array(biased.albedo_model), rtol=1e-12)


def test_metrics_skip_undefined_errors():
    te, pe = edges(4, 4)
    proj = 0.5 * np.diff(np.sin(te) ** 2)[:, None] * np.diff(pe)[None, :]
    model = np.ones((4, 4, 3))
    err = np.full_like(model, np.nan)
    m = metrics(model, err, model, proj)
    assert np.isnan(m.z_mean) and m.median_rel_error == 0.0


# --- exact checks of the plumbing: each against the documented formula written out ------
class Recorder:
    """A model whose regular part is ``Lobe``'s and whose singular part (a delta: what
    mirror cylinders have) returns a fixed (nt, np, 3) array, recording its arguments."""

    def __init__(self, nt: int, nph: int):
        self.calls = []
        self.part = np.arange(nt * nph * 3, dtype=float).reshape(nt, nph, 3) / 100

    def eval(self, wi, wo):
        return Lobe().eval(wi, wo)

    def singular(self, wi, theta_edges, phi_edges, phi_i=0.0):
        self.calls.append((np.array(wi), np.array(theta_edges), np.array(phi_edges), phi_i))
        return self.part[:len(theta_edges) - 1, :len(phi_edges) - 1]


def test_normal_z_is_the_normal_quantile_of_the_student_t_probability():
    """normal_z(t, ν) = Φ⁻¹(F_ν(t)) against mpmath (F_ν from the regularised incomplete
    beta function, Φ⁻¹ from erf⁻¹, at 30 digits) to 1e-9 relative; t itself where
    ν ≥ NORMAL_DOF (exactly, also at ν = NORMAL_DOF), where the tail underflows (t = 1e12
    at ν = 30: F's tail ~1e-340) and for an all-normal array (as floats)."""
    import mpmath as mp

    from microsim.comparison.metrics import NORMAL_DOF, normal_z

    mp.mp.dps = 30

    def reference(t: float, nu: float) -> float:
        x = mp.mpf(nu) / (nu + mp.mpf(t) ** 2)
        tail = mp.betainc(nu / 2, 0.5, 0, x, regularized=True) / 2     # P(T > |t|)
        return float(mp.sign(t) * mp.sqrt(2) * mp.erfinv(1 - 2 * tail))

    t = np.array([-6.0, -2.5, -0.3, 0.0, 0.7, 3.0, 9.0, 2.0, 1e12, 4.0])
    dof = np.array([4.0, 4.0, 2.0, 3.0, 12.0, 30.0, 5.0, NORMAL_DOF, 30.0, np.inf])
    z = normal_z(t, dof)
    for i in range(7):
        assert z[i] == pytest.approx(reference(t[i], dof[i]), rel=1e-9, abs=1e-15), i
    assert z[7] == 2.0 and z[8] == 1e12 and z[9] == 4.0
    np.testing.assert_allclose(normal_z(t[:7], 4.0), [reference(x, 4.0) for x in t[:7]],
                               rtol=1e-9, atol=1e-15)
    normal = normal_z(np.array([1, -2]), NORMAL_DOF)
    assert normal.dtype == float and np.array_equal(normal, [1.0, -2.0])


def test_channels_of_keeps_repeats_or_refuses():
    """channels_of: the table's count as it is; a grey model's (channels equal) repeated
    to the count; differing channels not the table's refused, naming both counts."""
    from microsim.comparison.metrics import channels_of
    from microsim.errors import InputError

    rgb = np.arange(4 * 5 * 3, dtype=float).reshape(4, 5, 3)
    assert channels_of(rgb, 3) is rgb
    grey = np.repeat(np.arange(20.0).reshape(4, 5, 1), 3, axis=-1)
    out = channels_of(grey, 6)
    assert out.shape == (4, 5, 6) and np.array_equal(out, np.repeat(grey[..., :1], 6, -1))
    with pytest.raises(InputError) as e:
        channels_of(rgb, 6)
    assert str(e.value) == ("the model has 3 colour channels, the table 6: give the model's "
                            "colour parameters (eta, k, albedo) as one number, or leave "
                            "them out to take the table's own per channel")


def test_check_model_channels_refuses_what_rgb_only_models_cannot_compute():
    """check_model_channels: an RGB-only model (cylinders) with four colour values and no
    table, or against an RGB table, is refused (one or three); against a spectral table,
    values differing between its wavelengths are refused, naming them (the spec's over
    the table's defaults, a model's own defaults over the shared ones); grey values, three
    values without a spectral table, values that are not numbers (the spec's parser says
    what is allowed), keys the model does not take and other models pass."""
    from microsim.comparison.metrics import check_model_channels
    from microsim.comparison.table_models import ModelDefaults
    from microsim.errors import InputError
    from microsim.spectra.channels import Channels

    spectral = Channels((400.0, 500.0, 600.0, 700.0))
    four = "cylinders:albedo=[0.1,0.2,0.3,0.4]"
    for channels in (None, Channels()):
        with pytest.raises(InputError) as e:
            check_model_channels(four, None, channels, "--reference")
        assert str(e.value) == (f"--reference {four}: the cylinders model computes R, G and "
                                "B only; albedo must be one number or three (R, G, B)")
    for fine in ("cylinders:albedo=[0.1,0.2,0.3]", "cylinders:albedo=0.5",
                 "cylinders:albedo=abc", 'cylinders:albedo=["a","b","c","d"]',
                 "lambertian:albedo=[0.1,0.2,0.3,0.4]"):
        assert check_model_channels(fine, None, None) is None
    with pytest.raises(InputError, match="^model cylinders: 'albedo' must be key=value$"):
        check_model_channels("cylinders:albedo", None, None)
    with pytest.raises(InputError, match=r"; albedo, base_albedo must be one number or three"):
        check_model_channels(four + ",base_albedo=[0,0]", None, None)
    defaults = ModelDefaults()
    defaults.put("albedo", [0.1, 0.2, 0.3, 0.4], "the table")
    defaults.put("base_albedo", [0.5] * 4, "the table")
    defaults.put("alpha", [0.1, 0.2, 0.3, 0.4], "the table")
    with pytest.raises(InputError) as e:
        check_model_channels("cylinders", defaults, spectral)
    assert str(e.value) == ("--model cylinders: the cylinders model computes R, G and B "
                            "only, and albedo differ between this table's 4 wavelengths; "
                            "give each one number (e.g. cylinders:albedo=0.5), the same in "
                            "every wavelength")
    assert check_model_channels("cylinders:albedo=0.3", defaults, spectral) is None
    assert check_model_channels("cylinders", {"albedo": 0.3}, spectral) is None
    defaults.for_model["cylinders"] = {"albedo": 0.3, "base_albedo": [0.0, 0.1, 0.0, 0.1]}
    defaults.for_model["velvet-sparse"] = {"base_albedo": 0.0}
    with pytest.raises(InputError, match=r"and base_albedo differ .* cylinders:base_albedo="):
        check_model_channels("cylinders", defaults, spectral)
    with pytest.raises(InputError, match=r"and albedo, base_albedo differ .* cylinders:albedo="):
        check_model_channels("cylinders:albedo=[0.1,0.2,0.3,0.2]", defaults, spectral)
    with pytest.raises(InputError, match="albedo must be one number or three"):
        check_model_channels("cylinders", defaults, Channels())


def test_singular_albedo_is_pi_times_the_hemisphere_average_of_the_singular_part():
    """singular_albedo: 0 without a singular part; π × the singular part's average over the
    hemisphere as one bin (θ edges 0, π/2; φ edges 0, 2π) otherwise."""
    from microsim.comparison.metrics import singular_albedo

    wi = direction(0.4, 0.3)
    assert singular_albedo(Lobe(), wi) == 0.0
    model = Recorder(1, 1)
    model.part = np.array([[[0.1, 0.2, 0.6]]])
    assert singular_albedo(model, wi) == pytest.approx(np.pi * 0.3, rel=1e-15)
    (w, te, pe, _), = model.calls
    assert np.array_equal(w, wi) and np.array_equal(te, [0.0, np.pi / 2])
    assert np.array_equal(pe, [0.0, 2 * np.pi])


def test_bin_average_adds_the_singular_part_and_its_defaults():
    """bin_average adds a singular part's bin averages (called with the same incidence,
    edges and φi) to the regular part's; its defaults are φi = 0 and 8 midpoints; split
    into rows of θ bins (a small CHUNK_POINTS) it gives the same numbers."""
    import microsim.comparison.metrics as compare

    te, pe = edges(4, 5)
    wi = direction(0.5, 0.2)
    model = Recorder(4, 5)
    regular = bin_average(Lobe(), wi, te, pe, 0.2)
    both = bin_average(model, wi, te, pe, 0.2)
    np.testing.assert_allclose(both, regular + model.part, rtol=1e-15)
    (w, t, p, phi), = model.calls
    assert np.array_equal(w, wi) and np.array_equal(t, te) and np.array_equal(p, pe)
    assert phi == 0.2
    assert np.array_equal(bin_average(Lobe(), wi, te, pe), bin_average(Lobe(), wi, te, pe,
                                                                       0.0, 8))
    chunked = compare.CHUNK_POINTS
    try:
        compare.CHUNK_POINTS = 5 * 8 * 8
        rows = bin_average(Lobe(), wi, te, pe, 0.2)
    finally:
        compare.CHUNK_POINTS = chunked
    np.testing.assert_allclose(rows, regular, rtol=1e-14)


def test_bin_average_at_the_horizon_is_exact_for_a_lobe_growing_as_one_over_cos():
    """f = 1/cos θo (fibre layers seen edge-on): its projected-solid-angle average over
    θo in [θ1, θ2] is ∫ s ds/s / ∫ s ds = 2/(cos θ1 + cos θ2). The bin at the horizon
    (Gauss-Legendre in cos θo) is exact to rounding, and one ending 1e-9 rad short of it
    counts as at the horizon (exact to 1e-8: 2/(cos θ1 + 1e-9)); a last bin ending at 80°
    is not at the horizon and takes midpoints in sin²θo, within 1% (measured 0.41%; the bins
    below, 0.07% and less, within 0.3%)."""

    class Edgewise:
        def eval(self, wi, wo):
            return 1.0 / wo[..., 2]

    wi, pe = direction(0.3, 0.0), np.linspace(0, 2 * np.pi, 4)
    for top in (90.0, 80.0, 90.0 - np.degrees(1e-9)):
        te = np.radians([0.0, 30.0, 60.0, top])
        if top > 89:
            te[-1] = np.pi / 2 if top == 90.0 else np.pi / 2 - 1e-9
        avg = bin_average(Edgewise(), wi, te, pe)
        exact = 2 / (np.cos(te[:-1]) + np.cos(te[1:]))
        np.testing.assert_allclose(avg[-1], exact[-1], rtol=1e-8 if top > 89 else 1e-2)
        np.testing.assert_allclose(avg[:-1], exact[:-1, None, None] + 0 * avg[:-1],
                                   rtol=3e-3)
        if top == 80.0:
            assert abs(avg[-1, 0, 0] / exact[-1] - 1) > 1e-6     # midpoints, not GL


def test_bin_averages_follow_the_axes():
    """bin_averages: bin_average at every (θi, φi) of the axes with their n, outgoing
    azimuths relative to φi when isotropic and absolute (φi = 0 added) otherwise."""
    from microsim.comparison.metrics import bin_averages
    from microsim.tables.binning import HemisphereBins
    from microsim.tables.evaluate import Axes

    bins = HemisphereBins(3, 4)
    theta, phi = np.array([0.2, 0.9]), np.array([0.0, 1.1, 2.5])
    for iso in (True, False):
        got = bin_averages(Lobe(), Axes(bins, theta, phi, iso), n=3)
        for a, t in enumerate(theta):
            for b, p in enumerate(phi):
                want = bin_average(Lobe(), direction(t, p), bins.theta_edges,
                                   bins.phi_edges, p if iso else 0.0, 3)
                np.testing.assert_array_equal(got[a, b], want)
    assert np.array_equal(bin_averages(Lobe(), Axes(bins, theta, phi, True)),
                          bin_averages(Lobe(), Axes(bins, theta, phi, True), 8))


class Walker:
    """A StochasticModel whose random part is fixed numbers that depend on its arguments,
    with the given exact part."""

    def __init__(self, exact, channels: int):
        self.exact, self.channels, self.calls = exact, channels, []

    def eval(self, wi, wo):
        raise AssertionError("bin_estimate must not evaluate a stochastic model")

    def random_bin_average(self, wi, theta_edges, phi_edges, phi_i=0.0):
        self.calls.append((np.array(wi), np.array(theta_edges), np.array(phi_edges), phi_i))
        nt, nph = len(theta_edges) - 1, len(phi_edges) - 1
        base = (np.arange(nt * nph * self.channels, dtype=float).reshape(nt, nph, -1)
                + 1) * (1 + phi_i + wi[0])
        return base, base / 10


def test_bin_estimate_adds_the_exact_part_and_carries_the_random_errors():
    """bin_estimate: an analytic model's bin_average with zero errors (its n passed); a
    stochastic one's random_bin_average (same incidence, edges, φi), a single channel
    repeated to three, plus the exact part's bin_average, with the random part's errors;
    defaults φi = 0, n = 8."""
    from microsim.comparison.metrics import bin_estimate

    te, pe = edges(3, 4)
    wi = direction(0.6, 0.4)
    mean, err = bin_estimate(Lobe(), wi, te, pe, 0.4, n=3)
    assert np.array_equal(mean, bin_average(Lobe(), wi, te, pe, 0.4, 3))
    assert err.shape == mean.shape and not err.any()
    for channels in (1, 3):
        for exact in (None, Lobe()):
            model = Walker(exact, channels)
            mean, err = bin_estimate(model, wi, te, pe, 0.4, n=3)
            rand, rand_err = Walker(None, channels).random_bin_average(wi, te, pe, 0.4)
            rand, rand_err = (np.broadcast_to(x, (3, 4, 3)) for x in (rand, rand_err))
            extra = 0 if exact is None else bin_average(exact, wi, te, pe, 0.4, 3)
            np.testing.assert_allclose(mean, rand + extra, rtol=1e-15)
            np.testing.assert_array_equal(err, rand_err)
            (w, t, p, phi), = model.calls
            assert np.array_equal(w, wi) and np.array_equal(t, te)
            assert np.array_equal(p, pe) and phi == 0.4
    defaults, explicit = (bin_estimate(Walker(Lobe(), 3), wi, te, pe, *args)
                          for args in ((), (0.0, 8)))
    assert np.array_equal(defaults[0], explicit[0])
    one = np.array([0.0, 2 * np.pi])                       # one φ bin: (nt, 1, C) parts
    for channels in (1, 3):
        mean, err = bin_estimate(Walker(None, channels), wi, te, one, 0.4)
        rand, rand_err = Walker(None, channels).random_bin_average(wi, te, one, 0.4)
        assert np.array_equal(mean, np.broadcast_to(rand, (3, 1, 3)))
        assert np.array_equal(err, np.broadcast_to(rand_err, (3, 1, 3)))


def test_lobe_residuals_welch_satterthwaite_and_the_bins_kept():
    """lobe_residuals: lobe bins per channel at ≥ 10% of that channel's peak over the
    bins (a channel 100 times brighter does not take the others' lobe); z over the lobe
    bins with a finite, non-zero error only; with a model error m besides the table's e
    (ν degrees of freedom), z = normal_z(d / √(e² + m²), ν (1 + m²/e²)²) — against scipy's
    Student-t and normal quantiles per bin; a NaN ν, or an infinite one (e = 0 < m), is taken as
    normal. A bin with e = m = 0 is left out without a warning (0/0), one with e = 0 < m
    kept."""
    from scipy import stats

    from microsim.comparison.metrics import lobe_residuals

    model = np.zeros((3, 4, 3))
    model[..., 0] = [[1.0, 0.5, 0.05, 0.2], [0.3, 0.01, 0.9, 0.15], [0.02, 0.4, 0.6, 0.08]]
    model[..., 1] = model[..., 0][::-1, ::-1]
    model[..., 2] = 100 * model[..., 0]
    lobe_want = model >= 0.1 * model.max(axis=(0, 1))
    sim = model * (1 + 0.1 * np.sin(np.arange(model.size)).reshape(model.shape))
    err = 0.02 * model
    err[0, 0, 0], err[2, 1, 1], err[1, 2, 2] = 0.0, np.nan, 0.0
    model_err = 0.01 * model * (1 + np.arange(model.size).reshape(model.shape) % 3)
    model_err[1, 2, 2] = 0.0
    dof = np.array([3.0, 7.0, np.nan])
    rel, z, lobe = lobe_residuals(sim, err, model, model_err, dof)
    assert np.array_equal(lobe, lobe_want)
    np.testing.assert_allclose(rel, (np.abs(sim - model) / model)[lobe_want], rtol=1e-15)
    both = np.hypot(err, model_err)
    ok = lobe_want & np.isfinite(both) & (both > 0)
    e = both[ok]
    t = (sim - model)[ok] / e
    with np.errstate(divide="ignore", invalid="ignore"):
        nu = (np.broadcast_to(dof, model.shape) * (1 + (model_err / err) ** 2) ** 2)[ok]
    want = np.where(np.isnan(nu), t, stats.norm.isf(stats.t.sf(t, np.nan_to_num(nu, nan=1))))
    assert z.shape == (ok.sum(),) and ok.sum() < lobe_want.sum()
    np.testing.assert_allclose(z, want, rtol=1e-9)
    _, z_exact, _ = lobe_residuals(sim, err, model, None, 3.0)
    ok = lobe_want & np.isfinite(err) & (err > 0)
    e = err[ok]
    np.testing.assert_allclose(z_exact, stats.norm.isf(stats.t.sf((sim - model)[ok] / e, 3.0)),
                               rtol=1e-9)
    # a channel whose errors have no degrees of freedom (an ensemble's undefined
    # jackknife) gives no z-scores, with or without a model error; its relative errors stay
    for m_err in (None, model_err):
        rel0, z0, _ = lobe_residuals(sim, err, model, m_err, np.array([3.0, 0.0, 7.0]))
        e0 = err if m_err is None else np.hypot(err, m_err)
        kept = lobe_want & np.isfinite(e0) & (e0 > 0)
        kept[..., 1] = False
        assert z0.shape == (kept.sum(),) and np.isfinite(z0).all()
        np.testing.assert_array_equal(rel0, rel)


def test_normal_z_of_no_degrees_of_freedom_is_undefined():
    """ν ≤ 0 (an error that says nothing of its spread) gives NaN, not t: the Student-t
    tail at ν = 0 is NaN, and the fallback for a non-finite z (an underflowing tail) would
    otherwise score the bin as if its error were exact."""
    from microsim.comparison.metrics import normal_z

    z = normal_z(np.array([2.0, -1.0, 2.0, 2.0]), np.array([0.0, -1.0, 4.0, np.inf]))
    assert np.isnan(z[:2]).all() and np.isfinite(z[2:]).all() and z[3] == 2.0


def test_metrics_are_their_documented_sums():
    """metrics: median and 90th percentile of the lobe's relative errors, RMS over every
    bin, albedos Σ f Ω_proj, their difference, the model's albedo error √Σ (σ Ω_proj)²
    (zeros without a model error, one per channel), lobe bins counted in channel 0, and
    the z-scores of lobe_residuals with the given model error and degrees of freedom."""
    from microsim.comparison.metrics import lobe_residuals, residual_statistics

    rng = np.random.default_rng(3)
    te, pe = edges(4, 5)
    proj = 0.5 * np.diff(np.sin(te) ** 2)[:, None] * np.diff(pe)[None, :]
    model = bin_average(Lobe(), direction(0.4, 0.0), te, pe)
    model[..., 1] = model[..., 1] ** 4                    # a narrower lobe in channel 1
    sim = model * (1 + 0.05 * rng.standard_normal(model.shape))
    err, model_err = 0.04 * model, 0.03 * model
    m = metrics(sim, err, model, proj, model_err, 4.0)
    rel, z, lobe = lobe_residuals(sim, err, model, model_err, 4.0)
    assert m.lobe_bins == lobe[..., 0].sum() != lobe[..., 1].sum()
    assert (m.median_rel_error, m.p90_rel_error, m.z_mean, m.z_std) == \
        residual_statistics(rel, z)
    assert m.p90_rel_error == pytest.approx(np.percentile(rel, 90), rel=1e-15)
    assert m.rms_error == pytest.approx(np.sqrt(np.mean((sim - model) ** 2)), rel=1e-15)
    a_sim = np.einsum("tpc,tp->c", sim, proj)
    a_model = np.einsum("tpc,tp->c", model, proj)
    np.testing.assert_allclose(m.albedo_sim, a_sim, rtol=1e-14)
    np.testing.assert_allclose(m.albedo_difference, a_sim - a_model, rtol=1e-12)
    np.testing.assert_allclose(m.albedo_model_err,
                               np.sqrt(np.einsum("tpc,tp->c", model_err ** 2, proj ** 2)),
                               rtol=1e-14)
    exact = metrics(sim, err, model, proj)
    assert np.array_equal(exact.albedo_model_err, np.zeros(3))
    assert exact.z_mean != m.z_mean


def test_residual_statistics_of_few_values():
    """residual_statistics: NaN for no relative error or z, and for the spread of one z;
    with two or more the sample standard deviation (ddof = 1) and the 90th percentile."""
    from microsim.comparison.metrics import residual_statistics

    empty = np.zeros(0)
    assert all(np.isnan(residual_statistics(empty, empty)))
    median, p90, z_mean, z_std = residual_statistics(np.array([0.1, 0.3, 0.2]),
                                                     np.array([1.0]))
    assert (median, z_mean) == (0.2, 1.0) and np.isnan(z_std)
    assert p90 == pytest.approx(0.28, rel=1e-14)
    assert residual_statistics(empty, np.array([1.0, 3.0]))[3] == pytest.approx(np.sqrt(2))


def test_model_table_holds_the_bin_averages_as_documented():
    """model_table: both components the model's bin_averages (isotropic at φi = 0, or at
    the given absolute azimuths), errors σ_rel × average + 1e-12 (1e-12 without noise),
    Gaussian noise clipped at 0 with σ_rel > 0, albedo Σ f Ω_proj of the values with zero
    error, no lost energy, degrees of freedom of normal z-scores (≥ NORMAL_DOF), a surface
    of kind "analytic" unless given, and the given channels, a grey model filling them."""
    from microsim.comparison.metrics import NORMAL_DOF, bin_averages, model_table
    from microsim.errors import InputError
    from microsim.spectra.channels import Channels
    from microsim.tables.binning import HemisphereBins
    from microsim.tables.evaluate import Axes
    from microsim.tables.meta import TableMeta

    bins, theta = HemisphereBins(3, 4), np.array([0.3, 1.0])
    proj = bins.projected_solid_angle
    table = model_table(Lobe(), theta, bins)
    avg = bin_averages(Lobe(), Axes(bins, theta, np.zeros(1), True))
    assert table.isotropic and np.array_equal(table.phi_i, [0.0])
    assert table.components == ("total", "order1")
    for c in table.components:
        assert np.array_equal(table[c].values, avg)
        assert np.array_equal(table[c].errors, np.full(avg.shape, 1e-12))
        np.testing.assert_allclose(table[c].albedo, np.einsum("abtpc,tp->abc", avg, proj),
                                   rtol=1e-14)
        assert np.array_equal(table[c].albedo_err, np.zeros((2, 1, 3)))
        assert np.all(table[c].dof >= NORMAL_DOF)
    assert np.array_equal(table.lost_energy, np.zeros((2, 1, 3)))
    assert table.meta.surface.tile.kind == "analytic"
    noisy = model_table(Lobe(), theta, bins, 0.05, np.random.default_rng(1))
    np.testing.assert_allclose(noisy["total"].errors, 0.05 * avg + 1e-12, rtol=1e-15)
    z = (noisy["total"].values - avg) / noisy["total"].errors
    assert np.all(noisy["total"].values >= 0) and abs(z.mean()) < 4 / np.sqrt(z.size)
    phi = np.array([0.0, 1.2])
    aniso = model_table(Lobe(), theta, bins, phi_i=phi, meta=TableMeta())
    assert not aniso.isotropic and np.array_equal(aniso.phi_i, phi)
    assert aniso.meta.surface is None
    assert np.array_equal(aniso["total"].values,
                          bin_averages(Lobe(), Axes(bins, theta, phi, False)))
    spectral = Channels((450.0, 550.0, 650.0, 750.0))
    four = model_table(Lobe(), theta, bins, channels=spectral)
    assert four.channels == spectral and four["total"].values.shape == (2, 1, 3, 4, 4)
    assert np.array_equal(four["total"].values, np.repeat(avg[..., :1], 4, axis=-1))
    with pytest.raises(InputError, match="the model has 3 colour channels, the table 4"):
        model_table(Recorder(3, 4), theta, bins, channels=spectral)  # Lobe's are grey


class Orders:
    """A model holding chosen scattering orders: ``with_orders`` records them."""

    def __init__(self):
        self.orders = []

    def eval(self, wi, wo):
        return Lobe().eval(wi, wo)

    def with_orders(self, lo, hi):
        self.orders.append((lo, hi))
        return self


def test_compare_table_pools_every_incidence_and_reports_the_table():
    """compare_table: per incidence, metrics of the component against bin_estimate's
    averages and errors with the table's degrees of freedom, θi and φi in degrees and
    the share (total − single)/total of the albedo (NaN where the total is 0); pooled, the
    statistics of every incidence's lobe residuals; the table's error model, most
    realisations and fewest degrees of freedom; the model's averages and errors; a model
    with chosen orders restricted to the component's; progress after every incidence."""
    from microsim.comparison.metrics import (
        bin_estimate,
        compare_table,
        lobe_residuals,
        model_table,
        residual_statistics,
    )
    from microsim.tables.binning import HemisphereBins

    bins, theta, phi = HemisphereBins(3, 4), np.array([0.3, 1.0]), np.array([0.0, 1.2, 2.0])
    table = model_table(Lobe(), theta, bins, 0.05, np.random.default_rng(2), phi_i=phi)
    dof = np.full((2, 3, 3), 4.0)
    dof[1, 2] = 6.0
    albedo = table["total"].albedo.copy()
    albedo[1, 1] = 0.0
    table = table.with_estimate("order1", dof=dof, albedo=0.25 * table["total"].albedo)
    table = replace(table.with_estimate("total", albedo=albedo), error_model="ensemble",
                    realisations=np.array([[3, 5, 4], [2, 2, 2]]))
    model, steps = Walker(Lobe(), 3), []
    result = compare_table(table, model, "single", lambda *a: steps.append(a))
    assert steps == [(k, 6) for k in range(1, 7)]
    rels, zs = [], []
    for k, row in enumerate(result.per_theta_i):
        a, b = divmod(k, 3)
        avg, err = bin_estimate(model, direction(theta[a], phi[b]), bins.theta_edges,
                                bins.phi_edges, 0.0)
        assert np.array_equal(result.model[a, b], avg)
        assert np.array_equal(result.model_err[a, b], err)
        args = (table["order1"].values[a, b], table["order1"].errors[a, b], avg,
                bins.projected_solid_angle, err, table["order1"].dof[a, b])
        assert row.z_mean == metrics(*args).z_mean and row.rms_error == metrics(*args).rms_error
        rel, z, _ = lobe_residuals(*args[:3], err, args[5])
        rels.append(rel)
        zs.append(z)
        assert row.theta_i == pytest.approx(np.degrees(theta[a]), rel=1e-15)
        assert row.phi_i == pytest.approx(np.degrees(phi[b]), rel=1e-15)
        if (a, b) == (1, 1):
            assert np.isnan(row.multiple_scattering_share)
        else:
            assert row.multiple_scattering_share == pytest.approx(0.75, rel=1e-14)
    assert (result.median_rel_error, result.p90_rel_error, result.z_mean, result.z_std) == \
        residual_statistics(np.concatenate(rels), np.concatenate(zs))
    assert result.error_model == "ensemble" and result.realisations == 5
    assert result.dof == 4.0
    orders = Orders()
    compare_table(table, orders, "single")
    compare_table(table, orders)
    assert orders.orders == [(1, 1), (1, None)]
