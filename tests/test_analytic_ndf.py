"""NDFs: normalisation by quadrature, Smith consistency, stability, mpmath references."""

from __future__ import annotations

import functools
import math
import warnings

import mpmath as mp
import numpy as np
import pytest
from scipy import integrate

from microsim.analytic.ndf import (
    GGX,
    Beckmann,
    Blinn,
    TorranceSparrowGaussian,
    lambda_beckmann,
    lambda_ggx,
    ndf_bin_average,
)
from microsim.analytic.shadowing import vcavity_G1
from microsim.geometry import direction

ALPHAS = [0.01, 0.1, 0.5, 1.0, 3.0]


def slope_normal(p, q):
    """Unit normal of a facet with height gradient (p, q): (-p, -q, 1)/sqrt(1+p²+q²)."""
    n = np.stack(np.broadcast_arrays(-p, -q, np.ones_like(p)), axis=-1)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


def p22(ndf, p, q):
    """Slope density P22 = D(m) cos^4 θm, from the code's D (Heitz 2014, eq. 11)."""
    m = slope_normal(np.asarray(p, float), np.asarray(q, float))
    return ndf.D(m) * m[..., 2] ** 4


@functools.cache
def _leggauss(n):
    return np.polynomial.legendre.leggauss(n)


def legendre(n, lo, hi):
    """Gauss-Legendre nodes and weights on [lo, hi]."""
    x, w = _leggauss(n)
    return lo + (hi - lo) * (x + 1) / 2, w * (hi - lo) / 2


def real_line(scale, n=600):
    """Nodes and weights for ∫_{-∞}^{∞} f(x) dx with x = scale tan(πs/2), s ∈ (-1, 1):
    heavy (x⁻⁴) and light (Gaussian) tails both map to smooth integrands."""
    s, w = legendre(n, -1.0, 1.0)
    x = scale * np.tan(np.pi * s / 2)
    return x, w * scale * (np.pi / 2) / np.cos(np.pi * s / 2) ** 2


def half_line(upper, scale, n=600):
    """Nodes and weights for ∫_{-∞}^{upper} f(x) dx with x = upper - scale t/(1-t)."""
    t, w = legendre(n, 0.0, 1.0)
    return upper - scale * t / (1 - t), w * scale / (1 - t) ** 2


def normalisation(ndf, ax, ay):
    """∫ D cos θ dω = ∫∫ P22(p, q) dp dq (Heitz 2014, eq. 11), by 600² Gauss-Legendre
    nodes on the tan-mapped real line scaled by (αx, αy), so the quadrature sees a
    unit-width integrand whatever α."""
    p, wp = real_line(ax)
    q, wq = real_line(ay)
    return float(np.einsum("i,j,ij->", wp, wq, p22(ndf, p[:, None], q[None, :])))


@pytest.mark.parametrize("alpha", ALPHAS)
@pytest.mark.parametrize("cls", [Beckmann, GGX])
def test_isotropic_normalisation(cls, alpha):
    """Tolerance 1e-6: the mapped Gauss-Legendre rule is exact to ~1e-10 here."""
    assert normalisation(cls(alpha), alpha, alpha) == pytest.approx(1.0, abs=1e-6)


@pytest.mark.parametrize(("ax", "ay"), [(0.01, 0.1), (0.3, 1.0), (3.0, 0.5)])
@pytest.mark.parametrize("cls", [Beckmann, GGX])
def test_anisotropic_normalisation(cls, ax, ay):
    assert normalisation(cls(alpha_x=ax, alpha_y=ay), ax, ay) == pytest.approx(1.0, abs=1e-6)


@pytest.mark.parametrize(("cls", "param"), [(Blinn, 0.0), (Blinn, 20.0), (Blinn, 2000.0),
                                           (TorranceSparrowGaussian, 1.0),
                                           (TorranceSparrowGaussian, 30.0)])
def test_profile_ndfs_are_normalised(cls, param):
    """2π ∫ D(θ) cos θ sin θ dθ = 1, with the peak width resolved by breakpoints. The
    distribution is built in the test, not when the parameters are collected, so the
    numerical normalisation of its constructor is what is checked."""
    ndf = cls(param)
    width = 1.0 / math.sqrt(getattr(ndf, "n", 0.0) + 1) if hasattr(ndf, "n") else 1 / ndf.c
    val, _ = integrate.quad(lambda t: float(ndf.D(direction(t, 0.0))) * math.cos(t)
                            * math.sin(t), 0, math.pi / 2, points=[min(width, 1.5)],
                            limit=200, epsabs=1e-12)
    assert 2 * math.pi * val == pytest.approx(1.0, abs=1e-7)


def projected_area(ndf, wo, g1=None):
    """∫ G1(ωo, m) ⟨ωo, m⟩⁺ D(m) dm in slopes: D dω = P22 dp dq / cos θm and
    ⟨ωo, m⟩ = (oz − p ox − q oy) cos θm, so the integrand is
    G1 · max(0, oz − p ox) · P22(p, q) for ωo in the xz-plane (ox ≥ 0). The positive part
    is p < oz/ox, an exact integration limit, so the kink sits on the boundary."""
    ox, oz = wo[0], wo[2]
    a = ndf.alpha
    p, wp = half_line(oz / ox, a) if ox > 1e-12 else real_line(a)
    q, wq = real_line(a)
    P, Q = p[:, None], q[None, :]
    f = (oz - P * ox) * p22(ndf, P, Q)
    if g1 is not None:
        f = f * g1(wo, slope_normal(P, Q))
    return float(np.einsum("i,j,ij->", wp, wq, f))


@pytest.mark.parametrize("theta_deg", [0.0, 30.0, 60.0, 80.0, 89.5])
@pytest.mark.parametrize(("cls", "alpha"), [(Beckmann, 0.3), (Beckmann, 1.0), (GGX, 0.3),
                                            (GGX, 1.0)])
def test_smith_consistency(cls, alpha, theta_deg):
    """G1(ωo) ∫ ⟨ωo, m⟩⁺ D dm = cos θo (Heitz 2014, eq. 2): 1e-6 absolute, a bound the
    same integrals also meet with scipy's adaptive dblquad at 1e-9 requested accuracy."""
    ndf = cls(alpha)
    wo = direction(math.radians(theta_deg), 0.0)
    lhs = float(ndf.G1(wo)) * projected_area(ndf, wo)
    assert lhs == pytest.approx(math.cos(math.radians(theta_deg)), abs=1e-6)


@pytest.mark.parametrize("theta_deg", [0.0, 45.0, 80.0, 89.5])
def test_vcavity_consistency(theta_deg):
    """The V-cavity G1 conserves projected area for a symmetric NDF (Heitz 2014,
    sec. 4.1): the integral of its masked projected area is cos θo. The integrand has a
    kink inside the domain where the min saturates, which Gauss-Legendre resolves only to
    about 1e-5 with 600² nodes: that is the tolerance."""
    ndf = Beckmann(0.5)
    wo = direction(math.radians(theta_deg), 0.0)
    lhs = projected_area(ndf, wo, g1=vcavity_G1)
    assert lhs == pytest.approx(math.cos(math.radians(theta_deg)), abs=1e-5)


def lambda_mp(a):
    """Beckmann Λ(a) = (exp(-a²)/(a√π) - erfc(a))/2 at 50 digits (Heitz 2014, eq. 83)."""
    with mp.workdps(50):
        a = mp.mpf(a)
        return (mp.exp(-a * a) / (a * mp.sqrt(mp.pi)) - mp.erfc(a)) / 2


def test_beckmann_lambda_matches_mpmath():
    """1e-10 relative wherever Λ > 1e-300 (a ≲ 26), across 12 decades of a."""
    a = np.concatenate([np.logspace(-8, 1.4, 300), [7.99, 8.0, 8.01, 25.0, 26.0]])
    ours = lambda_beckmann(a)
    ref = np.array([float(lambda_mp(x)) for x in a])
    keep = ref > 1e-300
    np.testing.assert_allclose(ours[keep], ref[keep], rtol=1e-10)


HARD_THETAS = np.radians([0.0, 45.0, 89.0, 89.999, 90.0, 90.001, 120.0, 180.0])


@pytest.mark.parametrize(("cls", "alphas"), [
    (Beckmann, {"alpha": 1e-4}), (Beckmann, {"alpha": 10.0}), (GGX, {"alpha": 1e-4}),
    (GGX, {"alpha": 10.0}), (Beckmann, {"alpha_x": 1e-4, "alpha_y": 10.0}),
    (GGX, {"alpha_x": 10.0, "alpha_y": 1e-4})])
def test_hard_cases_are_finite_and_bounded(cls, alphas):
    ndf = cls(**alphas)
    w = direction(HARD_THETAS[:, None], np.linspace(0, 2 * np.pi, 7)[None, :])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        lam, g1, d = ndf.Lambda(w), ndf.G1(w), ndf.D(w)
    for x in (lam, g1, d):
        assert np.isfinite(x).all()
    assert (lam >= 0).all() and ((g1 >= 0) & (g1 <= 1)).all() and (d >= 0).all()
    assert (g1[w[..., 2] <= 0] == 0).all() and (d[w[..., 2] <= 0] == 0).all()
    assert np.all(ndf.G1(direction(0.0, 0.0)) == 1.0)


def test_lambda_arguments_up_to_1e8():
    a = np.array([0.0, 1e-300, 1e-8, 1.0, 8.0, 26.0, 27.0, 1e3, 1e8, np.inf])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        lam = lambda_beckmann(a)
    assert np.isfinite(lam).all() and (lam >= 0).all()
    assert np.all(np.diff(lam) <= 0)  # Λ falls monotonically with a


def lambda_ggx_mp(a):
    """GGX Λ(a) = (−1 + √(1 + 1/a²))/2 (Walter et al. 2007, eq. 34), with enough digits
    that 1 + 1/a² keeps 1/a² at every a given."""
    a = mp.mpf(a)
    with mp.workdps(40 + int(2 * abs(mp.log10(a)))):
        return (-1 + mp.sqrt(1 + 1 / (a * a))) / 2


def test_ggx_lambda_matches_mpmath_from_1e_minus_300_to_1e160():
    """2e-15 relative (a few rounding errors: the code's cancellation-free form) over
    a = 1e-300 ... 1e160, through the branch Λ = s/2 (s = 1/a > 1e150, where s² would
    overflow) and both sides of its switch; a = 0 is a = 1e-300 and a = ∞ gives 0; no
    floating-point warning."""
    a = np.concatenate([[1e-300, 1e-200, 1e-151, 1e-150, 1e-149], np.logspace(-20, 160, 37)])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ours = lambda_ggx(a)
        ends = lambda_ggx(np.array([0.0, np.inf]))
    ref = np.array([float(lambda_ggx_mp(x)) for x in a])
    np.testing.assert_allclose(ours, ref, rtol=2e-15, atol=0)
    assert ends[0] == pytest.approx(0.5e300, rel=1e-15) and ends[1] == 0.0


def test_ndf_bin_average_is_the_closed_form_bin_integral():
    """Over a θ bin [a, b] (all azimuths) ∫ D cos θ dω has a closed form with u = tan²θ
    (D cos θ sin θ dθ = D cos⁴θ du/2): e^{−u_a/α²} − e^{−u_b/α²} for Beckmann (Walter et
    al. 2007, eq. 25) and 1/(1 + u_a/α²) − 1/(1 + u_b/α²) for GGX (eq. 33); ∫ cos θ dω =
    π (sin²b − sin²a). Relative 1e-10: doubling the 16 Gauss-Legendre nodes changes the
    averages by < 4e-13 on these bins (up to 80°, where Beckmann 0.5 is 9e-6 of its
    peak)."""
    edges = np.radians([0.0, 4.0, 12.0, 25.0, 40.0, 60.0, 80.0])
    u = np.tan(edges) ** 2
    for cls, alpha in ((Beckmann, 0.5), (Beckmann, 1.0), (GGX, 0.3), (GGX, 1.5)):
        p = np.exp(-u / alpha**2) if cls is Beckmann else 1.0 / (1.0 + u / alpha**2)
        expect = (p[:-1] - p[1:]) / (math.pi * np.diff(np.sin(edges) ** 2))
        np.testing.assert_allclose(ndf_bin_average(cls(alpha), edges), expect, rtol=1e-10)


def test_ndfs_vanish_on_and_below_the_horizon():
    """D and G1 are exactly 0 for a normal or direction on the horizon (m_z = 0, not just
    the 6e-17 that θ = 90° rounds to) and below it, for every distribution, with no
    floating-point warning (a division by m_z = 0 would warn, and a fractional Blinn
    exponent of a negative cosine would be NaN); Λ there is finite and a float array. A
    normal whose m_z rounds past 1 has the density of the pole."""
    w = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.6, 0.0, -0.8], [0.0, 0.0, -1.0]])
    analytic = [Beckmann(0.3), GGX(0.3), Beckmann(alpha_x=0.2, alpha_y=0.6),
                GGX(alpha_x=0.6, alpha_y=0.2)]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for ndf in analytic:
            assert np.array_equal(ndf.D(w), np.zeros(4))
            assert np.array_equal(ndf.G1(w), np.zeros(4))
            assert np.isfinite(ndf.Lambda(w)).all() and ndf.Lambda(w).dtype == np.float64
        pole, past = np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, 1.0 + 2.0**-52])
        for ndf in (Blinn(0.0), Blinn(20.0), Blinn(2.5), TorranceSparrowGaussian(2.0)):
            d = ndf.D(w)
            assert d.dtype == float and np.array_equal(d, np.zeros(4))
            assert ndf.D(past) == ndf.D(pole) > 0


def test_ndf_parameters_are_checked():
    """The roughness is given as α or as both αx and αy, finite and > 0; ``alpha`` is then
    √(αx αy) (the isotropic-equivalent roughness). Blinn's n ≥ 0 (0 and 0.5 allowed),
    Torrance-Sparrow's c > 0 (0.5 allowed); the messages name what is allowed."""
    for cls in (Beckmann, GGX):
        for kwargs in ({}, {"alpha": 0.3, "alpha_x": 0.2, "alpha_y": 0.4},
                       {"alpha": 0.3, "alpha_y": 0.4}, {"alpha_x": 0.2}, {"alpha_y": 0.2}):
            with pytest.raises(ValueError, match="^give alpha, or both alpha_x and alpha_y$"):
                cls(**kwargs)
        for kwargs in ({"alpha": 0.0}, {"alpha": -0.1}, {"alpha": math.inf},
                       {"alpha": math.nan}, {"alpha_x": 0.0, "alpha_y": 0.3},
                       {"alpha_x": 0.3, "alpha_y": 0.0}, {"alpha_x": math.inf, "alpha_y": 0.3},
                       {"alpha_x": 0.3, "alpha_y": math.inf}):
            with pytest.raises(ValueError, match="^roughness must be finite and > 0$"):
                cls(**kwargs)
        ndf = cls(alpha_x=0.2, alpha_y=0.8)
        assert (ndf.alpha_x, ndf.alpha_y, ndf.alpha) == (0.2, 0.8, pytest.approx(0.4, rel=1e-15))
        assert cls(0.3).alpha == 0.3
    for n in (-1.0, math.nan):
        with pytest.raises(ValueError, match="^Blinn exponent n must be >= 0$"):
            Blinn(n)
    assert Blinn(0.0).n == 0.0 and Blinn(0.5).n == 0.5
    for c in (0.0, -1.0, math.nan):
        with pytest.raises(ValueError, match="^c must be > 0$"):
            TorranceSparrowGaussian(c)
    assert TorranceSparrowGaussian(0.5).c == 0.5


def test_frozen_reference_values():
    """Points computed with mpmath from the papers' formulas (Walter et al. 2007,
    eq. 25 and 33), not with the code under test."""
    with mp.workdps(30):
        t = mp.mpf("0.4")
        beck = mp.exp(-mp.tan(t) ** 2 / mp.mpf("0.09")) / (mp.pi * mp.mpf("0.09")
                                                         * mp.cos(t) ** 4)
        a2 = mp.mpf("0.25")
        ggx = a2 / (mp.pi * ((a2 - 1) * mp.cos(t) ** 2 + 1) ** 2)
    m = direction(0.4, 1.1)
    assert float(Beckmann(0.3).D(m)) == pytest.approx(float(beck), rel=1e-13)
    assert float(GGX(0.5).D(m)) == pytest.approx(float(ggx), rel=1e-13)
    # anisotropic Beckmann at φ = 0 only feels alpha_x
    assert float(Beckmann(alpha_x=0.3, alpha_y=0.9).D(direction(0.4, 0.0))) == pytest.approx(
        float(beck) * 0.3 / 0.9, rel=1e-13)


def g1_by_quadrature(density, theta: float) -> float:
    """Smith's G1 of an isotropic NDF with the normalised profile ``density``(θm), from
    the definition (1 + Λ) cos θ = ∫ ⟨ω, m⟩⁺ D(m) dm (Heitz 2014, eq. 6), independently
    of the code: the azimuthal integral of max(0, a cos φ + b), a = sin θ sin θm,
    b = cos θ cos θm, is 2π b where b ≥ a and 2 (b φ₀ + a sin φ₀), φ₀ = arccos(−b/a),
    elsewhere; the polar one by adaptive quadrature, split at the kink θm = π/2 − θ."""
    from scipy.integrate import quad

    def ring(tm: float) -> float:
        a, b = math.sin(theta) * math.sin(tm), math.cos(theta) * math.cos(tm)
        if b >= a:
            return 2 * math.pi * b
        phi0 = math.acos(-b / a)
        return 2 * (b * phi0 + a * math.sin(phi0))

    def integrand(tm: float) -> float:
        return density(tm) * math.sin(tm) * ring(tm)

    kink = math.pi / 2 - theta
    total = sum(quad(integrand, lo, hi, epsabs=1e-14, epsrel=1e-12, limit=200)[0]
                for lo, hi in ((0.0, kink), (kink, math.pi / 2)))
    return math.cos(theta) / total


def blinn_g1_by_quadrature(n: float, theta: float) -> float:
    """``g1_by_quadrature`` of the Blinn NDF, D = (n + 2)/(2π) cos^n θm."""
    return g1_by_quadrature(lambda tm: (n + 2) / (2 * math.pi) * math.cos(tm) ** n, theta)


def test_blinn_g1_matches_an_independent_quadrature_and_its_beckmann_equivalent():
    """Blinn's G1 (Λ tabulated by the code's own quadrature) against the definition
    integrated independently (``blinn_g1_by_quadrature``), at angles where it masks
    little and much (30° ... 85°: G1 from 1 to 0.754). Tolerance 1e-5: the code's cubic
    spline of log(1 + Λ) over 129 nodes in θ interpolates a smooth function (its error is
    O(h⁴) away from grazing; it grows past 85°, where Λ ∝ cot θ⁻¹ steepens, so 87°+ is not
    asserted); a G1 ≡ 1 fails by 0.011 at 75° and 0.25 at 85°. Walter et al. 2007 (after
    eq. 30) match Blinn n to Beckmann α = √(2/(n+2)); the shapes differ, so their G1
    differ by 2e-3 (75°) to 7e-3 (85°): asserted within 0.02 where masking is strong
    (80-85°, G1 0.94-0.75), a check that the two share a scale, not an identity. Then
    the grazing range, the pole and the horizon (comments below)."""
    n = 40.0
    ndf = Blinn(n)
    theta = np.radians([30.0, 60.0, 75.0, 80.0, 85.0])
    g1 = ndf.G1(direction(theta, 0.0))
    reference = np.array([blinn_g1_by_quadrature(n, t) for t in theta])
    np.testing.assert_allclose(g1, reference, rtol=0, atol=1e-5)
    assert reference[-1] < 0.76
    beckmann = Beckmann(math.sqrt(2 / (n + 2))).G1(direction(theta, 0.0))
    np.testing.assert_allclose(g1[3:], beckmann[3:], atol=0.02)
    # Past 85° the spline and, past its last node (89.30°), the continuation Λ ∝ tan θ
    # are coarser: within 1.5% relative at 86-89° (measured 1.2%, at 89°) and 12% at
    # 89.5-89.95° (measured 9.6%, at 89.95°, G1 = 0.015); a table one node short or a
    # continuation off by its scale misses by 15% to 7×.
    for grazing, rtol in (([86.0, 87.0, 88.0, 89.0], 0.015), ([89.5, 89.8, 89.95], 0.12)):
        theta = np.radians(grazing)
        reference = np.array([blinn_g1_by_quadrature(n, t) for t in theta])
        np.testing.assert_allclose(ndf.G1(direction(theta, 0.0)), reference, rtol=rtol)
    # exactly 1 at the pole, also for a unit vector rounded to z = 1 + 2⁻⁵², 0 on and
    # below the horizon, without a floating-point warning
    w = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0 + 2.0**-52], [1.0, 0.0, 0.0],
                  [0.0, 0.0, -1.0 - 2.0**-52]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert np.array_equal(ndf.G1(w), [1.0, 1.0, 0.0, 0.0])


def test_torrance_sparrow_gaussian_g1_matches_an_independent_quadrature():
    """The Gaussian in the half-angle, c = 3 (a width of 19°, rough enough that Λ matters
    from 40° on: 4e-5 at 45°), normalised and masked from the definition in the test
    (``g1_by_quadrature`` with its own quadrature of the normalisation): within 1e-6 from
    0 to 80° (measured 1.2e-7, at 80°; a Λ dropped below 1 rad changes 45° by 4.4e-5),
    and 1e-5 at 85° (measured 1.3e-6)."""
    from scipy.integrate import quad

    c = 3.0
    norm = quad(lambda t: math.exp(-((c * t) ** 2)) * math.cos(t) * math.sin(t), 0.0,
                math.pi / 2, epsabs=1e-15, epsrel=1e-13)[0]

    def density(tm: float) -> float:
        return math.exp(-((c * tm) ** 2)) / (2 * math.pi * norm)

    ndf = TorranceSparrowGaussian(c)
    theta = np.radians([0.0, 20.0, 45.0, 60.0, 70.0, 80.0, 85.0])
    g1 = ndf.G1(direction(theta, 0.0))
    reference = np.array([g1_by_quadrature(density, t) for t in theta])
    np.testing.assert_allclose(g1[:-1], reference[:-1], rtol=0, atol=1e-6)
    assert g1[-1] == pytest.approx(reference[-1], abs=1e-5)
    assert g1[0] == 1.0 and reference[2] < 1 - 4e-5
