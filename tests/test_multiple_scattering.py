"""Heitz et al. 2016's random walk, checked without the simulator: visible-normal sampling
against its density (mpmath and quadrature), order 1 against Torrance-Sparrow with
height-correlated Smith, the white furnace, reciprocity, the escape statistics against
the next-event estimates, and the single-scattering albedos in docs/conventions.md.

Thresholds: a z-score |z| < Z_MAX = 3.5 per check (a fixed seed; each check has a 1 in
2000 chance of failing under the null hypothesis, and there are fewer than 60 of them, so
the whole file has a few per cent), except the white furnace's ±3σ (its docstring says why).
"""

from __future__ import annotations

import math
import re

import mpmath as mp
import numpy as np
import pytest
from scipy import stats

from microsim.analytic.brdf import TorranceSparrow
from microsim.analytic.fresnel import ConductorFresnel, DielectricFresnel
from microsim.analytic.multiple_scattering import SmithMultipleScattering
from microsim.analytic.ndf import GGX, Beckmann
from microsim.analytic.visible_normals import (
    SLOPE_RANGE,
    projected_area,
    sample_visible,
    visible_pdf,
)
from microsim.geometry import direction

Z_MAX = 3.5
GOLD = ConductorFresnel(np.array([0.2, 0.92, 1.1]), np.array([3.9, 2.45, 2.14]))
GLASS = DielectricFresnel(1.5)
NDFS = [Beckmann(0.5), GGX(0.5), Beckmann(alpha_x=0.3, alpha_y=0.9),
        GGX(alpha_x=0.9, alpha_y=0.3)]


def cosine_directions(rng: np.random.Generator, n: int) -> np.ndarray:
    """Directions with density cos θ / π on the upper hemisphere."""
    u1, u2 = rng.random(n), rng.random(n)
    return direction(np.arcsin(np.sqrt(u1)), 2 * np.pi * u2)


# --- visible normals ----------------------------------------------------------------------
@pytest.mark.parametrize("theta", [0.3, 1.2, 2.0, 2.8])
def test_beckmann_visible_slope_follows_its_cdf(theta: float) -> None:
    """The slope x = −m_x/m_z along the view azimuth, for views above and below the
    horizon (2.8 rad: 160°, a ray travelling almost straight up, A(ω) ≈ 1e-17), has the
    CDF (cos θ erfc(−x/α)/2 + sin θ α e^{−x²/α²}/(2√π)) / A(ω) (closed form, mpmath at
    40 digits). Kolmogorov-Smirnov on 8 000 samples, p > 0.001."""
    mp.mp.dps = 40
    alpha, n = 0.5, 8_000
    rng = np.random.default_rng(7)
    w = np.repeat(direction(theta, 0.0)[None], n, axis=0)
    m = sample_visible(Beckmann(alpha), w, rng.random(n), rng.random(n))
    assert np.all(m[:, 2] >= 0) and np.all(np.sum(w * m, axis=1) >= -1e-12)
    c, s = mp.cos(theta), mp.sin(theta)

    def cdf(x: float) -> float:
        x = min(mp.mpf(x), c / s)
        return c * mp.erfc(-x / alpha) / 2 + s * alpha * mp.exp(-(x / alpha) ** 2) / (
            2 * mp.sqrt(mp.pi))

    area = cdf(float(c / s))
    assert float(area) == pytest.approx(float(projected_area(Beckmann(alpha), w[:1])[0]),
                                        rel=1e-9)
    x = np.sort(-m[:, 0] / m[:, 2])
    assert stats.kstest(x, lambda q: np.array([float(cdf(v) / area) for v in q])).pvalue > 1e-3


@pytest.mark.parametrize("ndf", NDFS, ids=["beckmann", "ggx", "beckmann-aniso", "ggx-aniso"])
@pytest.mark.parametrize("theta", [0.0, 1.2, 1.9])
def test_visible_normals_histogram_matches_the_density(ndf: object, theta: float) -> None:
    """Sampled normals binned in (cos θm, φm), 10 × 16 bins, against ∫_bin D_ω(m) dm by a
    24² midpoint rule of ``visible_pdf`` (whose sum over the hemisphere must be 1 within
    2e-3: that checks A(ω) = (1 + Λ) cos θ above and Λ |cos θ| below the horizon);
    Pearson χ² over bins expecting ≥ 5 samples, p > 0.001."""
    n, nt, nphi, g = 50_000, 10, 16, 24
    rng = np.random.default_rng(3)
    w = direction(theta, 0.4)[None]
    m = sample_visible(ndf, np.repeat(w, n, axis=0), rng.random(n), rng.random(n))
    cos_m, phi_m = m[:, 2], np.mod(np.arctan2(m[:, 1], m[:, 0]), 2 * np.pi)
    it = np.minimum(((1 - cos_m) * nt).astype(int), nt - 1)
    ip = np.minimum((phi_m / (2 * np.pi) * nphi).astype(int), nphi - 1)
    observed = np.bincount(it * nphi + ip, minlength=nt * nphi)
    t = (np.arange(g) + 0.5) / g
    c = 1 - (np.arange(nt)[:, None] + t) / nt                          # (nt, g)
    p = (np.arange(nphi)[:, None] + t) / nphi * 2 * np.pi              # (nphi, g)
    normals = direction(np.arccos(c)[:, None, :, None], p[None, :, None, :])
    density = visible_pdf(ndf, np.broadcast_to(w, normals.shape).reshape(-1, 3),
                          normals.reshape(-1, 3)).reshape(normals.shape[:-1])
    expected = density.mean(axis=(2, 3)).ravel() / nt * (2 * np.pi / nphi)
    assert expected.sum() == pytest.approx(1.0, abs=2e-3)
    keep = expected * n >= 5
    e = n * expected[keep] / expected[keep].sum()
    chi2 = ((observed[keep] - e) ** 2 / e).sum()
    assert stats.chi2.sf(chi2, keep.sum() - 1) > 1e-3
    assert observed[~keep].sum() < max(20, 4 * n * expected[~keep].sum())


def test_visible_pdf_is_zero_where_no_facet_is_seen() -> None:
    """A(ω) = 0 exactly at the horizon ((1 + Λ) · 0, Λ finite there) and straight down
    (Λ = 0): D_ω is exactly 0 there, a float array, without a division by zero (this
    suite makes RuntimeWarnings errors), also for a normal the horizon view sees
    (⟨ω, m⟩ = 0.6); above the horizon it is ⟨ω, m⟩ D(m) / ((1 + Λ(ω)) cos θ) to rounding."""
    w = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.6, 0.0, 0.8]])
    m = np.array([[0.6, 0.0, 0.8]] * 3)
    for ndf in (Beckmann(0.5), GGX(0.5)):
        pdf = visible_pdf(ndf, w, m)
        assert pdf.dtype == np.float64
        assert pdf[0] == 0.0 and pdf[1] == 0.0
        assert pdf[2] == pytest.approx(ndf.D(m[2]) / ((1 + ndf.Lambda(w[2])) * 0.8), rel=1e-12)


@pytest.mark.parametrize("theta", [0.3, 1.2, 2.0])
def test_visible_normals_at_the_ends_of_the_unit_interval(theta: float) -> None:
    """u1, u2 ∈ {0, ½, 1 − 2⁻⁵³} (a generator's [0, 1) includes 0): finite unit normals with
    m_z ≥ 0 facing ω, and no floating-point error raised (underflow aside). For Beckmann,
    u1 = 0 is the lower end of the inversion's bracket, the α = 1 slope
    min(cot θ′, 0) − SLOPE_RANGE (θ′ the view stretched to α = 1) to 1e-12, and u2 = ½ the
    perpendicular slope 0."""
    alpha, ends = 0.5, np.array([0.0, 0.5, 1.0 - 2.0**-53])
    u1, u2 = (g.ravel() for g in np.meshgrid(ends, ends))
    w = np.repeat(direction(theta, 0.0)[None], len(u1), axis=0)
    for ndf in (Beckmann(alpha), GGX(alpha)):
        with np.errstate(all="raise", under="ignore"):
            m = sample_visible(ndf, w, u1, u2)
        assert np.all(np.isfinite(m))
        assert np.allclose(np.linalg.norm(m, axis=1), 1.0, atol=1e-12)
        assert np.all(m[:, 2] >= 0) and np.all(np.sum(w * m, axis=1) >= -1e-12)
    lowest = min(math.cos(theta) / (alpha * math.sin(theta)), 0.0) - SLOPE_RANGE
    m = sample_visible(Beckmann(alpha), w[:1], np.zeros(1), np.full(1, 0.5))
    assert -m[0, 0] / (alpha * m[0, 2]) == pytest.approx(lowest, abs=1e-12)
    assert m[0, 1] == pytest.approx(0.0, abs=1e-15)


def test_visible_normals_of_a_view_almost_straight_down() -> None:
    """θ = 3.1 rad, 2.4° from straight down: the α = 1 Beckmann slope density has underflowed
    to 0 over the whole bracket (A(ω) is 0 in floats, and Newton's step is 0/0); the
    samplers still return finite unit normals with m_z ≥ 0 facing ω, without a floating-point
    warning (RuntimeWarnings are errors in this suite)."""
    rng = np.random.default_rng(2)
    w = np.repeat(direction(3.1, 0.7)[None], 200, axis=0)
    for ndf in (Beckmann(0.5), GGX(0.5)):
        m = sample_visible(ndf, w, rng.random(200), rng.random(200))
        assert np.all(np.isfinite(m))
        assert np.allclose(np.linalg.norm(m, axis=1), 1.0, atol=1e-12)
        assert np.all(m[:, 2] >= 0) and np.all(np.sum(w * m, axis=1) >= -1e-12)


@pytest.mark.parametrize("theta", [0.3, 1.2, 2.0])
def test_beckmann_visible_slope_inverts_its_cdf_to_rounding(theta: float) -> None:
    """The slope drawn for u1 is the root of CDF(x) = u1 A(ω) (the closed form above, mpmath
    at 40 digits), not only near it: |CDF(x)/A − u1| < 2e-14 for u1 = 0.02 … 0.98. Newton's
    error after its last step (< 1e-12 (1 + |x|)) is of the order of that step squared;
    what remains is the float evaluation of the CDF and the recovery of x from m, ≤ 2e-15
    measured here. An iteration that stops on bisection steps instead (a Newton step
    landing on the bracket's end refused) leaves residuals of 1e-13 to 1e-12."""
    mp.mp.dps = 40
    alpha = 0.5
    u1 = np.linspace(0.02, 0.98, 49)
    w = np.repeat(direction(theta, 0.0)[None], len(u1), axis=0)
    m = sample_visible(Beckmann(alpha), w, u1, np.full(len(u1), 0.5))
    x = -m[:, 0] / (alpha * m[:, 2])
    c, s = mp.cos(theta), alpha * mp.sin(theta)
    c, s = c / mp.hypot(c, s), s / mp.hypot(c, s)

    def cdf(v: float) -> mp.mpf:
        return c * mp.erfc(-v) / 2 + s * mp.exp(-v * v) / (2 * mp.sqrt(mp.pi))

    area = cdf(c / s)
    residual = [abs(float(cdf(mp.mpf(float(v))) / area) - q) for v, q in zip(x, u1, strict=True)]
    assert max(residual) < 2e-14


def test_ggx_visible_normals_are_heitz_2018_listing_1() -> None:
    """The GGX sampler maps (u1, u2) as Heitz 2018's listing 1 does, transcribed here per
    sample in plain floats (stretch, the basis T1 (or x̂ for a vertical view), T2 = V × T1,
    t2 ← (1 − s) √(1 − t1²) + s t2, lift, unstretch): to 1e-12 for views above and below
    the horizon and the pole, anisotropic."""
    def listing_1(ve: tuple, ax: float, ay: float, u1: float, u2: float) -> np.ndarray:
        vh = np.array([ax * ve[0], ay * ve[1], ve[2]])
        vh /= math.sqrt(vh @ vh)
        lensq = vh[0] ** 2 + vh[1] ** 2
        t1v = (np.array([-vh[1], vh[0], 0.0]) / math.sqrt(lensq) if lensq > 0
               else np.array([1.0, 0.0, 0.0]))
        t2v = np.cross(vh, t1v)
        r, phi = math.sqrt(u1), 2 * math.pi * u2
        t1, t2 = r * math.cos(phi), r * math.sin(phi)
        s = 0.5 * (1 + vh[2])
        t2 = (1 - s) * math.sqrt(1 - t1 * t1) + s * t2
        nh = t1 * t1v + t2 * t2v + math.sqrt(max(0.0, 1 - t1 * t1 - t2 * t2)) * vh
        ne = np.array([ax * nh[0], ay * nh[1], max(0.0, nh[2])])
        return ne / math.sqrt(ne @ ne)

    rng = np.random.default_rng(5)
    ax, ay = 0.9, 0.3
    views = [direction(t, p) for t, p in [(0.0, 0.0), (0.7, 0.4), (1.4, 2.5), (2.2, 4.0)]]
    for ve in views:
        u1, u2 = rng.random(20), rng.random(20)
        m = sample_visible(GGX(alpha_x=ax, alpha_y=ay), np.repeat(ve[None], 20, axis=0), u1,
                           u2)
        ref = np.array([listing_1(ve, ax, ay, a, b) for a, b in zip(u1, u2, strict=True)])
        assert np.allclose(m, ref, rtol=0, atol=1e-12)


# --- the walk -------------------------------------------------------------------------------
PAIRS = [((0.0, 0.0), (0.5, 2.0)), ((0.5, 0.0), (0.5, np.pi)), ((1.1, 0.3), (0.4, 2.5)),
         ((1.4, 1.0), (1.3, 4.0)), ((0.8, 2.0), (1.2, 0.1))]


@pytest.mark.parametrize("ndf, fresnel", [(n, GOLD) for n in NDFS]
                         + [(NDFS[0], GLASS), (NDFS[3], GLASS)],
                         ids=["beckmann", "ggx", "beckmann-aniso", "ggx-aniso",
                              "beckmann-glass", "ggx-aniso-glass"])
def test_first_order_of_the_walk_is_torrance_sparrow(ndf: object, fresnel: tuple) -> None:
    """The walk's own estimate of order 1 (no exact part) against Torrance-Sparrow with
    height-correlated Smith G2 = 1/(1 + Λi + Λo), with gold's Fresnel (RGB) or a
    dielectric's (reflection only), at 5 direction pairs: |z| < Z_MAX per pair and
    colour, with 20 000 walks each. Where Λ(ωo) ≈ 0 (a steep ωo on a smooth Beckmann
    surface) the masking is 1 at every height and the estimate has no variance: there the
    bound is round-off, 1e-12 relative."""
    model = SmithMultipleScattering(ndf, fresnel, max_order=1, samples=20_000, seed=1,
                                    analytic_single=False)
    ts = TorranceSparrow(ndf, fresnel=fresnel, shadowing="smith-correlated")
    for (ti, pi), (to, po) in PAIRS:
        wi, wo = direction(ti, pi), direction(to, po)
        f, err = model.estimate(wi, wo)
        exact = ts.eval(wi, wo)
        assert np.all(np.abs(f - exact) < Z_MAX * err + 1e-12 * exact), (ti, to, f, exact)


@pytest.mark.parametrize("ndf, analytic", [(Beckmann(0.5), True), (GGX(1.0), True),
                                           (Beckmann(alpha_x=0.4, alpha_y=1.2), False)],
                         ids=["beckmann", "ggx", "beckmann-aniso-walk-only"])
def test_white_furnace(ndf: object, analytic: bool) -> None:
    """F = 1: ∫ f_r cos θo dωo = 1 (a closed microsurface keeps all energy; Heitz et al.
    2016) within ±3σ at θi = 0, 45, 75 and 89° (grazing), by cosine-weighted ωo with
    2 walks each (40 000 directions: σ ≈ 0.003-0.01). The sum of next-event estimates
    over orders is what is integrated, so this checks the phase function's normalisation
    and the heights' masking together."""
    rng = np.random.default_rng(5)
    model = SmithMultipleScattering(ndf, samples=2, seed=2, analytic_single=analytic)
    for theta in (0.0, 45.0, 75.0, 89.0):
        wo = cosine_directions(rng, 40_000)
        x = np.pi * model.eval(direction(math.radians(theta), 0.7), wo)
        mean, err = x.mean(), x.std(ddof=1) / math.sqrt(len(x))
        assert abs(mean - 1.0) < 3 * err, (theta, mean, err)


@pytest.mark.parametrize("fresnel", [None, GOLD, GLASS], ids=["mirror", "gold", "glass"])
def test_reciprocity(fresnel: tuple | None) -> None:
    """f_r(ωi, ωo) = f_r(ωo, ωi) for all orders, the walk estimating every order (no
    exact part), for mirror, gold and reflecting glass facets, on an anisotropic GGX and a
    Beckmann surface: z of the difference of two
    independent estimates (20 000 walks each) within Z_MAX per pair and colour."""
    for ndf in (GGX(alpha_x=0.3, alpha_y=0.8), Beckmann(0.9)):
        model = SmithMultipleScattering(ndf, fresnel, samples=20_000, seed=3,
                                        analytic_single=False)
        for (ti, pi), (to, po) in PAIRS[1:]:
            a, b = direction(ti, pi), direction(to, po)
            f1, e1 = model.estimate(a, b)
            f2, e2 = model.estimate(b, a)
            assert np.all(np.abs(f1 - f2) < Z_MAX * np.hypot(e1, e2)), (ti, to, f1, f2)


def test_escapes_and_next_event_estimates_agree_per_order() -> None:
    """Two estimators of the albedo of each order: where the walks leave (``albedo``) and
    ∫ f_order cos θo dωo from next-event estimates (cosine-weighted ωo). Independent
    walks; their difference within Z_MAX for orders 1, 2 and 3+ on a rough gold surface
    (GGX α = 0.8, θi = 30°), and the escape statistics of F = 1 sum to 1 exactly."""
    rng = np.random.default_rng(9)
    ndf, wi = GGX(0.8), direction(math.radians(30.0), 0.0)
    model = SmithMultipleScattering(ndf, GOLD, samples=2, seed=4, analytic_single=False)
    ranges = [(1, 1), (2, 2), (3, None)]
    escape, escape_err = model.albedo(wi, 100_000, ranges)
    for row, (lo, hi) in enumerate(ranges):
        wo = cosine_directions(rng, 30_000)
        x = np.pi * model.with_orders(lo, hi).eval(wi, wo)
        mean, err = x.mean(axis=0), x.std(axis=0, ddof=1) / math.sqrt(len(x))
        z = (mean - escape[row]) / np.hypot(err, escape_err[row])
        assert np.all(np.abs(z) < Z_MAX), (lo, mean, escape[row])
    white, white_err = SmithMultipleScattering(ndf, seed=5).albedo(
        wi, 20_000, [(1, 1), (2, 3), (4, None), (1, None)])
    assert white[:3].sum() == pytest.approx(1.0, abs=1e-12)
    assert white[3, 0] == pytest.approx(1.0, abs=1e-12) and white_err[3, 0] < 1e-7


@pytest.mark.parametrize("ndf, reference", [(Beckmann(0.5), 0.893), (Beckmann(1.0), 0.664),
                                         (GGX(0.5), 0.700), (GGX(1.0), 0.409)],
                         ids=["beckmann-0.5", "beckmann-1", "ggx-0.5", "ggx-1"])
def test_single_scattering_albedo_of_the_reference_figures(ndf: object,
                                                           reference: float) -> None:
    """docs/conventions.md: single-scattering albedo with F = 1 and height-correlated G2,
    averaged over the hemisphere (cosine-weighted: 2 ∫ E(μ) μ dμ). The share of walks that leave
    after one event, from cosine-weighted ωi (60 000 walks: σ ≈ 0.002), within
    Z_MAX σ + 0.0005 (the figure's rounding); all orders together are 1 (no walk is cut)."""
    rng = np.random.default_rng(11)
    model = SmithMultipleScattering(ndf, seed=6)
    wi = cosine_directions(rng, 60_000)
    walks = model.walk(wi, None, rows=2)
    single = walks.escaped[:, 0, 0]
    mean, err = single.mean(), single.std(ddof=1) / math.sqrt(len(single))
    assert abs(mean - reference) < Z_MAX * err + 5e-4, (mean, err)
    assert walks.cut == 0 and walks.escaped.sum() == len(wi)


def test_estimates_are_reproducible_and_errors_calibrated() -> None:
    """The same seed gives the same numbers; the reported standard error of one estimate
    (200 walks) predicts the spread of 40 independent ones: their variance ratio lies
    within the 0.1% quantiles of χ²(39)/39, per colour."""
    wi, wo = direction(0.6, 0.0), direction(0.9, 2.8)
    a = SmithMultipleScattering(GGX(0.7), GOLD, samples=200, seed=8)
    b = SmithMultipleScattering(GGX(0.7), GOLD, samples=200, seed=8)
    assert np.array_equal(a.estimate(wi, wo)[0], b.estimate(wi, wo)[0])
    runs = np.array([a.estimate(wi, wo) for _ in range(40)])           # (40, 2, 3)
    ratio = runs[:, 0].var(axis=0, ddof=1) / np.mean(runs[:, 1] ** 2, axis=0)
    lo, hi = stats.chi2.ppf([1e-3, 1 - 1e-3], 39) / 39
    assert np.all((ratio > lo) & (ratio < hi)), ratio


def test_mean_error_is_the_sample_mean_and_its_standard_error() -> None:
    """``_mean_error`` along an axis: x = 1, 2, 3, 4 has mean 5/2, s² = 5/3 and standard
    error √(s²/4) = √(5/12); a second row 2x has twice both (exact to rounding)."""
    from microsim.analytic.multiple_scattering import _mean_error

    x = np.array([[1.0, 2.0, 3.0, 4.0], [2.0, 4.0, 6.0, 8.0]])
    mean, err = _mean_error(x.T, axis=0)
    assert mean == pytest.approx([2.5, 5.0], rel=1e-15)
    assert err == pytest.approx([math.sqrt(5 / 12), 2 * math.sqrt(5 / 12)], rel=1e-15)


def test_random_bin_average_is_the_bin_average_of_torrance_sparrow_at_order_one() -> None:
    """``random_bin_average`` of the walk's own order 1 (no exact part) on an anisotropic
    GGX surface with gold's Fresnel, lit from θi = 40°, φi = 0.7, over 4 × 6 bins
    (the last at the horizon) of azimuths relative to φi: against the bin averages of
    Torrance-Sparrow with height-correlated Smith (``compare.bin_average`` with 32 × 32
    midpoints: 8 × 8 differ from it by 0.5% at most, so its own error, of order 1/n², is
    near 3e-4, a tenth of the walks' 0.2-1.3%), each of the 24 bins' z per colour within
    Z_MAX, and Σ z² of the red channel within the 0.1% quantiles of
    χ²(24) (the errors are neither too small nor too large)."""
    from microsim.comparison.metrics import bin_average

    ndf, phi_i = GGX(alpha_x=0.3, alpha_y=0.6), 0.7
    wi = direction(math.radians(40.0), phi_i)
    theta_edges = np.radians([0.0, 25.0, 45.0, 65.0, 90.0])
    phi_edges = np.linspace(0.0, 2 * np.pi, 7)
    model = SmithMultipleScattering(ndf, GOLD, max_order=1, samples=4000, seed=12,
                                    analytic_single=False)
    assert model.exact is None
    mean, err = model.random_bin_average(wi, theta_edges, phi_edges, phi_i)
    reference = bin_average(model.single, wi, theta_edges, phi_edges, phi_i, n=32)
    assert mean.shape == err.shape == (4, 6, 3)
    z = (mean - reference) / err
    assert np.all(np.abs(z) < Z_MAX), z
    lo, hi = stats.chi2.ppf([1e-3, 1 - 1e-3], z[..., 0].size)
    assert lo < np.sum(z[..., 0] ** 2) < hi, np.sum(z[..., 0] ** 2)


def test_model_defaults_and_which_first_order_is_exact() -> None:
    """The documented defaults (256 walks, seed 0, all orders, order 1 exact) and when the
    first order is ``exact``: held (min_order 1) and ``analytic_single``; ``with_orders``
    keeps samples, seed and ``analytic_single`` and shares the generator. Exact checks."""
    model = SmithMultipleScattering(GGX(0.5))
    assert (model.samples, model.seed, model.min_order, model.max_order) == (256, 0, 1, None)
    assert model.analytic_single is True and model.exact is model.single
    assert SmithMultipleScattering(GGX(0.5), min_order=2).exact is None
    assert SmithMultipleScattering(GGX(0.5), analytic_single=False).exact is None
    base = SmithMultipleScattering(GGX(0.5), samples=7, seed=3, min_order=2)
    other = base.with_orders(1, 2)
    assert (other.samples, other.seed, other.min_order, other.max_order) == (7, 3, 1, 2)
    assert other.exact is other.single and other.rng is base.rng
    walk_only = SmithMultipleScattering(GGX(0.5), analytic_single=False).with_orders(1, 1)
    assert walk_only.analytic_single is False and walk_only.exact is None
    with pytest.raises(ValueError, match=r"^samples must be >= 2 \(the error is a sample "
                                         r"variance\)$"):
        SmithMultipleScattering(GGX(0.5), samples=1)


def test_estimate_is_the_mean_of_the_walks_next_event_estimates(monkeypatch) -> None:
    """``estimate`` written out: with ``CHUNK`` = 3 walks at a time (so the running merge
    of chunk means and squared deviations, and a pair with a single walk in a chunk, are
    exercised), the same seed's walks, ``samples`` = 5 per pair, pair after pair, give per
    pair the mean of the order estimates plus Torrance-Sparrow's f_r cos θo, over cos θo,
    and the standard error s/√5/cos θo with the two-pass sample variance, to 1e-12
    (rounding); the shape is the pairs' shape and a colour axis for RGB, none for F = 1."""
    import microsim.analytic.multiple_scattering as ms

    monkeypatch.setattr(ms, "CHUNK", 3)
    k = 5
    wi = np.array([direction(0.5, 0.3), direction(1.1, 2.0)])[:, None]      # (2, 1, 3)
    wo = np.array([direction(0.9, 2.8), direction(1.2, 5.0)])[:, None]
    model = SmithMultipleScattering(GGX(1.0), GOLD, samples=k, seed=8)
    f, err = model.estimate(wi, wo)
    assert f.shape == err.shape == (2, 1, 3)
    ref = SmithMultipleScattering(GGX(1.0), GOLD, samples=k, seed=8)
    wi_k, wo_k = np.repeat(wi[:, 0], k, axis=0), np.repeat(wo[:, 0], k, axis=0)
    x = np.concatenate([ref.walk(wi_k[s:s + 3], wo_k[s:s + 3]).nee[:, 0]
                        for s in range(0, 2 * k, 3)]).reshape(2, k, 3)
    cos_o = wo[:, 0, 2:3]
    exact = model.single.eval(wi[:, 0], wo[:, 0]).reshape(2, 3)
    assert np.all(x.std(axis=1) > 0)
    assert f[:, 0] == pytest.approx(x.mean(axis=1) / cos_o + exact, rel=1e-12)
    assert err[:, 0] == pytest.approx(x.std(axis=1, ddof=1) / math.sqrt(k) / cos_o,
                                      rel=1e-12)
    mirror, mirror_err = SmithMultipleScattering(GGX(1.0), samples=k).estimate(
        wi[:, 0], wo[:, 0])
    assert mirror.shape == mirror_err.shape == (2,)


def test_estimate_is_zero_for_directions_on_or_below_the_horizon() -> None:
    """f_r and its error are exactly 0 (not 0/0, not a walk from below) where ωi or ωo is
    on the horizon or below it, and no walk runs for them: the pair above gets the numbers
    the same seed gives it alone."""
    up, flat = direction(0.6, 0.2), np.array([0.6, 0.8, 0.0])
    wi = np.array([up, flat, direction(2.0, 0.0), up, up])
    wo = np.array([direction(1.0, 2.5), up, up, -flat, direction(2.5, 1.0)])
    for fresnel in (None, GOLD):
        model = SmithMultipleScattering(GGX(0.8), fresnel, samples=8, seed=2,
                                        analytic_single=False)
        f, err = model.estimate(wi, wo)
        assert np.all(f[1:] == 0.0) and np.all(err[1:] == 0.0), (f, err)
        assert np.all(f[0] > 0) and np.all(err[0] > 0)
        alone = SmithMultipleScattering(GGX(0.8), fresnel, samples=8, seed=2,
                                        analytic_single=False).estimate(wi[0], wo[0])
        assert np.array_equal(f[0], alone[0]) and np.array_equal(err[0], alone[1])


def test_walk_is_cut_after_max_order_events_and_keeps_order_rows(monkeypatch) -> None:
    """With ``MAX_ORDER`` = 2, walks still on the surface after 2 scattering events are
    cut: with F = 1 the escapes after one event and the cut walks add up to all of them,
    exactly, and no escape is recorded in the rows of orders 2 and 3+. The next-event
    estimates land in the row of their order: a model holding order 1 only fills row 0
    of 2 rows, one holding order 2 only row 1."""
    import microsim.analytic.multiple_scattering as ms

    n = 2000
    wi = np.repeat(direction(0.5, 0.0)[None], n, axis=0)
    wo = np.repeat(direction(1.0, 2.0)[None], n, axis=0)
    with monkeypatch.context() as m:
        m.setattr(ms, "MAX_ORDER", 2)
        walks = SmithMultipleScattering(GGX(1.0), seed=7).walk(wi, None, rows=3)
    assert 0 < walks.cut < n
    assert np.all(walks.escaped[:, 1:] == 0.0)
    assert walks.escaped[:, 0].sum() + walks.cut == n
    for order in (1, 2):
        model = SmithMultipleScattering(GGX(1.0), min_order=order, max_order=order, seed=7,
                                        analytic_single=False)
        nee = model.walk(wi, wo, rows=2).nee
        assert np.any(nee[:, order - 1] > 0) and np.all(nee[:, 2 - order] == 0.0)


def test_albedo_is_the_mean_escaped_weight_per_range_of_orders(monkeypatch) -> None:
    """``albedo`` written out: with ``CHUNK`` = 700 (2000 walks in three chunks), the same
    seed's walks kept in 6 order rows give per range of orders the mean of the weights
    that escaped within it and the standard error s/√n with the sample variance, to 1e-9
    (the one-pass variance's rounding), for ranges that end below the last one's start."""
    import microsim.analytic.multiple_scattering as ms

    monkeypatch.setattr(ms, "CHUNK", 700)
    n, wi = 2000, direction(0.7, 0.3)
    orders = [(1, 2), (2, 3), (1, None)]
    mean, err = SmithMultipleScattering(GGX(0.9), GOLD, seed=3).albedo(wi, n, orders)
    ref = SmithMultipleScattering(GGX(0.9), GOLD, seed=3)
    wi_n = np.repeat(wi[None], n, axis=0)
    e = np.concatenate([ref.walk(wi_n[s:s + 700], None, rows=6).escaped
                        for s in range(0, n, 700)])
    x = np.stack([e[:, 0:2].sum(axis=1), e[:, 1:3].sum(axis=1), e.sum(axis=1)], axis=1)
    assert mean == pytest.approx(x.mean(axis=0), rel=1e-12)
    assert err == pytest.approx(x.std(axis=0, ddof=1) / math.sqrt(n), rel=1e-9)


def test_random_bin_average_defaults_exact_part_horizon_and_memory(monkeypatch) -> None:
    """``random_bin_average``: φi defaults to 0 (the same seed's numbers as φi = 0
    given); the exact part is left out, so a model holding only an exact order 1 averages
    0 with error 0; a bin on the horizon itself (θo from 90° to 90°) averages 0, f_r
    cos θo being 0 there; the memory guard refuses 160 B × 6 bins × 4 walks over a
    2000 B budget with the documented message (its numbers exactly)."""
    from microsim.errors import InputError

    wi, te, pe = direction(0.5, 0.4), np.radians([0.0, 40.0, 90.0]), np.linspace(0, 6, 4)
    a = SmithMultipleScattering(GGX(0.8), GOLD, samples=6, seed=4, analytic_single=False)
    b = SmithMultipleScattering(GGX(0.8), GOLD, samples=6, seed=4, analytic_single=False)
    for x, y in zip(a.random_bin_average(wi, te, pe), b.random_bin_average(wi, te, pe, 0.0),
                    strict=True):
        assert np.array_equal(x, y)
    exact_only = SmithMultipleScattering(GGX(0.8), GOLD, max_order=1, samples=6)
    for x in exact_only.random_bin_average(wi, te, pe):
        assert x.shape == (2, 3, 3) and np.all(x == 0.0)
    mean, err = a.random_bin_average(wi, np.radians([0.0, 90.0, 90.0]), pe)
    assert np.all(mean[0] > 0) and np.all(err[0] > 0)
    assert np.all(mean[1] == 0.0) and np.all(err[1] == 0.0)
    monkeypatch.setenv("MICROSIM_MEMORY_LIMIT", repr(2000 / 2**30))
    small = SmithMultipleScattering(GGX(0.8), samples=4)
    message = ("model samples = 4: 4 walks in each of 6 bins needs about 3.58e-06 GiB "
               "(estimated), over the 1.86265e-06 GiB limit; lower the model's samples "
               "(default 256), or raise the limit")
    with pytest.raises(InputError, match="^" + re.escape(message)):
        small.random_bin_average(wi, te, pe)


def test_random_bin_average_written_out_from_the_same_seed(monkeypatch) -> None:
    """``random_bin_average`` written out: the same seed's draws (t, p) per bin and walk
    give ωo uniform in u = sin²θo and φo − φi within the bin, the walks run ``CHUNK`` = 5
    at a time (16 walks: chunks of 5, 5, 5, 1), and each bin's mean of f = (f_r cos θo
    estimate)/cos θo and s/√4 are the result, to 1e-12 (rounding)."""
    import microsim.analytic.multiple_scattering as ms

    monkeypatch.setattr(ms, "CHUNK", 5)
    k, phi_i = 4, 0.4
    wi, te, pe = direction(0.5, phi_i), np.radians([10.0, 40.0, 70.0]), np.array([0, 2, 5.0])
    mean, err = SmithMultipleScattering(GGX(0.9), GOLD, samples=k, seed=6).random_bin_average(
        wi, te, pe, phi_i)
    ref = SmithMultipleScattering(GGX(0.9), GOLD, samples=k, seed=6)
    t, p = ref.rng.random((2, 2, 2, k))
    lo, hi = np.sin(te[:-1]) ** 2, np.sin(te[1:]) ** 2
    u = lo[:, None, None] + (hi - lo)[:, None, None] * t
    phi = phi_i + pe[:-1][None, :, None] + np.diff(pe)[None, :, None] * p
    wo = np.stack([np.sqrt(u) * np.cos(phi), np.sqrt(u) * np.sin(phi), np.sqrt(1 - u)],
                  -1).reshape(-1, 3)
    wi_n = np.repeat(wi[None], len(wo), axis=0)
    x = np.concatenate([ref.walk(wi_n[s:s + 5], wo[s:s + 5]).nee[:, 0]
                        for s in range(0, len(wo), 5)])
    f = (x / wo[:, 2:3]).reshape(2, 2, k, 3)
    assert np.all(f.std(axis=2) > 0)
    assert mean == pytest.approx(f.mean(axis=2), rel=1e-12)
    assert err == pytest.approx(f.std(axis=2, ddof=1) / math.sqrt(k), rel=1e-12)


def test_next_event_is_the_phase_function_times_the_masking_at_the_height() -> None:
    """``_next_event`` against p(ωi', ωo) G1(ωo, h) = F(ωi'·h) D(h) / (4 A(ωi')) ·
    C1(h)^Λ(ωo) written out (module docstring), for hits seen from above and from below
    the horizon, to 1e-12; and exactly 0, without a floating-point warning, where no light
    goes that way: ωi' = −ωo (no half vector), ωi' straight down or on the horizon
    (A(ωi') = 0), ωo below the horizon, and ωo on the horizon even at the top of the
    surface (log C1 = 0, where C1^Λ would be 1)."""
    seen = np.array([direction(0.7, 0.2), direction(2.2, 1.0), -direction(0.5, 1.0),
                     [0.0, 0.0, -1.0], [1.0, 0.0, 0.0], direction(0.3, 0.0),
                     direction(0.3, 0.0)])
    wo = np.array([direction(0.5, 2.0), direction(0.4, 1.5), direction(0.5, 1.0),
                   direction(0.6, 0.5), direction(0.6, 0.5), direction(2.0, 0.5),
                   [0.0, 1.0, 0.0]])
    log_c = np.array([-0.3, -1.2, -0.5, -0.5, -0.5, -0.5, 0.0])
    for ndf in (GGX(alpha_x=0.4, alpha_y=0.8), Beckmann(0.6)):
        model = SmithMultipleScattering(ndf, GOLD)
        value = model._next_event(seen, wo, log_c, ndf.Lambda(wo))
        assert value.shape == (7, 3)
        s = seen[:2] + wo[:2]
        h = s / np.linalg.norm(s, axis=1)[:, None]
        cos_h = np.sum(seen[:2] * h, axis=1)
        expected = (model.single.F(cos_h).reshape(2, 3) * (
            ndf.D(h) / (4 * projected_area(ndf, seen[:2]))
            * np.exp(ndf.Lambda(wo[:2]) * log_c[:2]))[:, None])
        assert np.all(expected > 0)
        assert value[:2] == pytest.approx(expected, rel=1e-12)
        assert np.all(value[2:] == 0.0), value


def test_bad_parameters() -> None:
    with pytest.raises(ValueError, match="orders"):
        SmithMultipleScattering(GGX(0.5), min_order=2, max_order=1)
    with pytest.raises(ValueError, match="samples"):
        SmithMultipleScattering(GGX(0.5), samples=1)
    with pytest.raises(TypeError, match="visible-normal sampler for Blinn"):
        from microsim.analytic.ndf import Blinn

        SmithMultipleScattering(Blinn(10.0)).eval(direction(0.5, 0.0), direction(0.5, 3.0))
