"""Fibre models checked independently: the cylinder array's exact single scattering
(specular cone, Lambertian arcs, shadowing), Kay-Kajiya's diffuse claim, and the sparse
velvet quadrature — by mpmath, brute-force geometry and Monte Carlo over the generator's
own fibre axes."""

from __future__ import annotations

import math
import warnings

import mpmath
import numpy as np
import pytest

from microsim.analytic.brdf import KayKajiya, Lambertian
from microsim.analytic.cylinders import CylinderArray
from microsim.analytic.fresnel import ConductorFresnel, DielectricFresnel, fresnel_conductor
from microsim.analytic.velvet import SparseVelvet
from microsim.geometry import direction
from microsim.surfaces.velvet import fibre_directions, tubes

GOLD = ConductorFresnel(np.array([0.2, 0.92, 1.1]), np.array([3.9, 2.45, 2.14]))


def test_mirror_cylinder_cone_follows_marschners_r_lobe_with_fresnel():
    """Normal incidence on gold cylinders too far apart to shadow each other: the cone is
    the plane y = 0, and the power between scattering angles Φa and Φb (θo on either
    side) is (r/s) ∫ F(cos γ) cos γ dγ over γ = Φ/2 ∈ [Φa/2, Φb/2] — N_R(Φ) = ¼ cos(Φ/2) F
    integrated, here by mpmath. Bins agree to the midpoint rule's resolution: a bin edge
    falls between two of the 2¹⁶ impacts, so each of a bin's two edges may misplace one
    impact's share (r/s)(2/2¹⁶) F."""
    r, s = 0.5, 1e4
    model = CylinderArray(r, s, 0.0, GOLD)
    te = np.arcsin(np.sqrt(np.linspace(0, 1, 9)))
    pe = np.linspace(0, 2 * np.pi, 17)
    # φ measured from −0.1 rad: the plane's two halves fall inside bins 0 and 8
    avg = model.singular(np.array([0.0, 0.0, 1.0]), te, pe, phi_i=-0.1)
    omega = 0.5 * np.outer(np.diff(np.sin(te) ** 2), np.diff(pe))
    power = avg * omega[..., None]
    assert np.count_nonzero(power[..., 1]) == 2 * (len(te) - 1)
    for k in range(len(te) - 1):
        for c in range(3):
            def f(g, c=c):
                cos = float(mpmath.cos(g))
                return fresnel_conductor(cos, GOLD.eta[c], GOLD.k[c]) * mpmath.cos(g)
            expect = r / s * float(mpmath.quad(f, [te[k] / 2, te[k + 1] / 2]))
            for side in (0, 8):
                assert power[k, side, c] == pytest.approx(expect, abs=2 * r / s * 2 / 2**16)


def brute_lambertian(model: CylinderArray, wi: np.ndarray, wo: np.ndarray, sink: float,
                     n: int = 20000) -> tuple[float, float]:
    """f_r of the Lambertian cylinders and of the base share, by explicit 2-D geometry:
    points sampled on the arc above the base and on the base, each tested for being lit
    and seen by ray–circle intersections with the neighbours k = −12 … 12 (enough for
    the directions used: within 83° of the zenith, a ray clears every cylinder within 9
    periods). The axes at height r − sink, as the generator places them."""
    r, s, zc = model.r, model.s, model.r - sink

    def clear(p: np.ndarray, d: np.ndarray, skip_own: bool) -> np.ndarray:
        q = np.array([d[0], d[2]]) / math.hypot(d[0], d[2])
        ok = np.ones(len(p), bool)
        for k in range(-12, 13):
            if skip_own and k == 0:
                continue
            c = np.array([k * s, zc]) - p
            b = c @ q
            ok &= ~((b > 0) & (b * b > (c * c).sum(axis=1) - r * r))
        return ok

    psi = -math.pi / 2 + (np.arange(n) + 0.5) * 2 * math.pi / n
    p = np.column_stack([r * np.cos(psi), zc + r * np.sin(psi)])
    nrm = np.column_stack([np.cos(psi), np.zeros(n), np.sin(psi)])
    ci, co = nrm @ wi, nrm @ wo
    keep = (p[:, 1] >= 0) & (ci > 0) & (co > 0) & clear(p, wi, True) & clear(p, wo, True)
    arc = np.sum(ci * co * keep) * r * 2 * math.pi / n
    x = -s / 2 + (np.arange(n) + 0.5) * s / n
    base = np.column_stack([x, np.zeros(n)])
    outside = np.abs(x) >= math.sqrt(max(r * r - zc * zc, 0.0))
    share = np.mean(outside & clear(base, wi, False) & clear(base, wo, False))
    return arc / (math.pi * s * wi[2] * wo[2]), share / math.pi


@pytest.mark.parametrize("sink", [0.0, 0.3])
def test_lambertian_cylinders_and_base_against_brute_force_geometry(sink):
    """The closed-form arc integral with the neighbours' shadow limits, and the base share
    as a union of arcs, against explicit sampling of the arc and the base with ray–circle
    tests, at random direction pairs including grazing ones (spacing 3 r: neighbours
    shadow a lot). Agreement 2e-3 relative (the sampling's resolution)."""
    r, s = 0.5, 1.5
    model = CylinderArray(r, s, sink, Lambertian(1.0), 1.0)
    rng = np.random.default_rng(4)
    checked = 0
    for _ in range(12):
        wi = direction(rng.uniform(0, 1.45), rng.uniform(0, 2 * np.pi))
        wo = direction(rng.uniform(0, 1.45), rng.uniform(0, 2 * np.pi))
        f = model.eval(wi, wo)[0]
        arc, base = brute_lambertian(model, wi, wo, sink)
        assert f == pytest.approx(arc + base, rel=2e-3, abs=1e-6)
        checked += base > 0 and arc > 0
    assert checked >= 4


def test_cylinder_array_refuses_bad_geometry_and_facets():
    """radius > 0, spacing ≥ 2 radius (touching allowed), 0 ≤ sink < 2 radius, and a
    specular or Lambertian facet; each refusal says what is allowed. The base is black
    unless given."""
    mirror = None
    for r, s, sink in [(0.0, 1.0, 0.0), (-0.5, 1.0, 0.0), (0.5, 0.99, 0.0), (0.5, 1.5, -0.1),
                       (0.5, 1.5, 1.0), (0.5, 1.5, 1.2)]:
        with pytest.raises(ValueError, match=r"^need radius > 0, spacing >= 2 radius, "
                                             r"0 <= sink < 2 radius$"):
            CylinderArray(r, s, sink, mirror)
    for r, s, sink in [(0.5, 1.0, 0.0), (0.5, 1.5, 0.99), (0.5, np.inf, 0.5), (2.0, 4.0, 3.9)]:
        CylinderArray(r, s, sink, mirror)
    with pytest.raises(ValueError, match=r"^facet must be None \(a mirror\), a "
                                         r"ConductorFresnel or DielectricFresnel "
                                         r"\(microsim.analytic.fresnel\) or a Lambertian "
                                         r"\(microsim.analytic.brdf\), not dict$"):
        CylinderArray(0.5, 1.5, 0.0, {"kind": "mirror"})
    assert CylinderArray(0.5, 1.5, 0.0, mirror).base_albedo.tolist() == [0.0, 0.0, 0.0]


def test_cylinder_array_eval_is_linear_in_the_albedos_and_zero_off_the_hemisphere():
    """f_r is the cylinders' term times their albedo plus the base's times its albedo
    (coloured albedos against grey unit ones, 1e-12); pairs given as a (2, 3) array give
    the (2, 3, 3) result of the pairs one at a time; a direction on (z = 0) or below the
    horizon gives exactly 0 without a warning (RuntimeWarnings are errors in this suite)."""
    rng = np.random.default_rng(9)
    wi = direction(rng.uniform(0, 1.4, 6), rng.uniform(0, 2 * np.pi, 6))
    wo = direction(rng.uniform(0, 1.4, 6), rng.uniform(0, 2 * np.pi, 6))
    a, b = np.array([0.2, 0.5, 0.9]), np.array([0.7, 0.4, 0.1])

    def model(albedo, base):
        return CylinderArray(0.5, 1.5, 0.3, Lambertian(albedo), base)

    f = model(a, b).eval(wi.reshape(2, 3, 3), wo.reshape(2, 3, 3))
    assert f.shape == (2, 3, 3)
    one = np.array([model(a, b).eval(wi[k], wo[k]) for k in range(6)])
    np.testing.assert_allclose(f.reshape(6, 3), one, rtol=1e-12)
    arcs, base = model(1.0, 0.0).eval(wi, wo), model(0.0, 1.0).eval(wi, wo)
    assert np.all(arcs > 0) and base.max() > 0.05     # the base is lit and seen in some
    np.testing.assert_allclose(f.reshape(6, 3), arcs * a + base * b, rtol=1e-12)
    off = model(a, b).eval(np.array([[1.0, 0.0, 0.0], wi[0], [0.6, 0.0, -0.8], wi[1]]),
                           np.array([wo[0], [0.0, 1.0, 0.0], wo[1], [0.0, 0.6, -0.8]]))
    assert np.all(off == 0.0)


def test_cylinder_array_singular_is_zero_where_nothing_is_specular():
    """``singular`` is zeros of the table's (nt, np, 3) shape for Lambertian cylinders and
    for light on (z = 0) or below the horizon, and measures φ from 0 unless told."""
    te, pe = np.radians(np.linspace(0, 90, 7)), np.radians(np.linspace(0, 360, 9))
    lambertian = CylinderArray(0.5, 1.5, 0.0, Lambertian(1.0))
    assert np.all(lambertian.singular(direction(0.5, 0.3), te, pe) == np.zeros((6, 8, 3)))
    mirror = CylinderArray(0.5, 1.5, 0.0, None)
    for wi in ([1.0, 0.0, 0.0], [0.6, 0.0, -0.8]):
        assert np.all(mirror.singular(np.array(wi), te, pe) == np.zeros((6, 8, 3)))
    wi = direction(0.5, 0.3)
    got = mirror.singular(wi, te, pe, impacts=4096)
    assert got.sum() > 0
    assert np.array_equal(got, mirror.singular(wi, te, pe, 0.0, impacts=4096))


@pytest.mark.parametrize("phi", [0.0, 0.6])
def test_dense_mirror_cylinders_reflect_what_tracing_the_section_says(phi):
    """Mirror cylinders 2.2 r apart, sunk 0.2 r, lit at 70° (the neighbours shadow and
    mask): the power ``singular`` bins (Σ value × projected solid angle) against tracing
    each of its impacts in the cross-section independently: the point above the base, its
    ray towards the light and its mirror reflection (going up) clear of the neighbours
    k = −12 … 12 (ray–circle tests). The same 2¹⁴ midpoint impacts, so the two agree to
    an impact's share (1/2¹⁴ of the beam) at each of the ≤ 4 arc ends; the masked share is
    tens of per cent here."""
    r, s, sink, n = 0.5, 1.1, 0.1, 2**14
    model = CylinderArray(r, s, sink, None)
    te, pe = np.radians(np.linspace(0, 90, 10)), np.radians(np.linspace(0, 360, 13))
    omega = 0.5 * np.outer(np.diff(np.sin(te) ** 2), np.diff(pe))
    wi = direction(math.radians(70.0), phi)
    total = (model.singular(wi, te, pe, impacts=n)[..., 0] * omega).sum()
    zc, cos_l = r - sink, math.hypot(wi[0], wi[2])
    h = -1 + (np.arange(n) + 0.5) * 2 / n
    psi = math.atan2(wi[2], wi[0]) + np.arcsin(h)
    p = np.column_stack([r * np.cos(psi), zc + r * np.sin(psi)])
    nrm = np.column_stack([np.cos(psi), np.zeros(n), np.sin(psi)])
    wo = 2 * (nrm @ wi)[:, None] * nrm - wi

    def clear(q):
        q = q / np.linalg.norm(q, axis=1, keepdims=True)
        ok = np.ones(n, bool)
        for k in range(-12, 13):
            if k:
                c = np.array([k * s, zc]) - p
                b = np.sum(c * q, axis=1)
                ok &= ~((b > 0) & (b * b > (c * c).sum(axis=1) - r * r))
        return ok

    keep = ((p[:, 1] >= 0) & (wo[:, 2] > 0) & clear(np.tile([wi[0], wi[2]], (n, 1)))
            & clear(wo[:, [0, 2]]))
    share = r * (2 / n) * cos_l / (s * wi[2])
    assert 0.2 < 1 - keep.mean() < 0.8
    assert total == pytest.approx(keep.sum() * share, abs=4 * share)


def test_cylinder_facet_reflectance_and_bin_values():
    """``facet_reflectance`` is (n, 3): 1 for a mirror, the conductor's and the dielectric's
    Fresnel terms otherwise. ``bin_values`` puts power over projected solid angle into
    [lo, hi) bins: a direction on a θ or φ edge goes to the bin above it, one whose z
    rounds past 1 to the first θ row, one at or below the horizon nowhere, one at φ_ref −
    1e-17 (φ rounding to 2π) to the last φ bin; with the last φ edge at π the bins are
    folded (φ → 2π − φ past π: a direction at φ = π in the last bin, one at 7π/4 in the bin
    of π/4, over twice the solid angle); a full circle of two φ bins is not folded."""
    from microsim.analytic.cylinders import bin_values, facet_reflectance
    from microsim.analytic.fresnel import fresnel_dielectric

    cos = np.array([0.1, 0.5, 0.9])
    assert np.array_equal(facet_reflectance(None, cos), np.ones((3, 3)))
    gold = facet_reflectance(GOLD, cos)
    assert gold.shape == (3, 3)
    np.testing.assert_allclose(gold, fresnel_conductor(cos[:, None], GOLD.eta, GOLD.k),
                               rtol=1e-15)
    glass = facet_reflectance(DielectricFresnel(1.5), cos)
    assert glass.shape == (3, 3)
    np.testing.assert_allclose(glass, fresnel_dielectric(cos, 1.5)[:, None] * np.ones(3),
                               rtol=1e-15)

    te = np.array([0.0, np.arccos(0.5), math.pi / 2])
    pe = np.linspace(0.0, 2 * math.pi, 5)                         # edges 0, π/2, π, 3π/2, 2π
    u = np.sin(te) ** 2
    omega = 0.5 * np.outer(np.diff(u), np.diff(pe))
    s = math.sqrt(0.75)
    wo = np.array([[0.0, s, 0.5],                 # on the θ edge and the φ edge π/2
                   [0.0, 0.0, 1.0 + 2.0**-52],     # straight up, z rounded past 1
                   [0.0, 1.0, 0.0],                # on the horizon
                   [0.6, 0.0, -0.8],               # below it
                   [0.6 * math.cos(-1e-17), 0.6 * math.sin(-1e-17), 0.8]])
    got = bin_values(wo, np.ones((5, 3)), te, pe, 0.0)
    expected = np.zeros((2, 4))
    expected[1, 1] = 1.0
    expected[0, 0] += 1.0
    expected[0, 3] += 1.0
    np.testing.assert_allclose(got, (expected / omega)[..., None] * np.ones(3), rtol=1e-12)

    pf = np.linspace(0.0, math.pi, 3)                             # folded: edges 0, π/2, π
    c = 0.6 * math.sqrt(0.5)
    wo = np.array([[-0.6, 0.0, 0.8], [c, -c, 0.8]])               # φ = π and φ = 7π/4
    got = bin_values(wo, np.ones((2, 3)), te, pf, 0.0)
    omega = np.outer(np.diff(u), np.diff(pf))                     # twice 0.5 ...
    expected = np.zeros((2, 2))
    expected[0, 1] = 1.0      # θ = 36.9°; φ = π in the last bin
    expected[0, 0] = 1.0      # 7π/4 folded onto π/4
    np.testing.assert_allclose(got, (expected / omega)[..., None] * np.ones(3), rtol=1e-12)
    two = bin_values(np.array([[0.0, -0.6, 0.8]]), np.ones((1, 3)), te,
                     np.array([0.0, math.pi, 2 * math.pi]), 0.0)
    assert two[0, 1, 0] > 0 and two[0, 0, 0] == 0


def test_kay_kajiya_diffuse_is_the_lambertian_cylinder_averaged_around_the_fibre():
    """Kay-Kajiya's diffuse radiance kd sin(t, ωi) with kd = ρ/π² equals the radiance of
    a Lambertian cylinder averaged over the viewer's azimuth Φ about the fibre — the
    approximation in that term — computed here by brute force: the exact apparent
    radiance, ρ/π ∫ (ωi·n)⁺ (ωo·n)⁺ dψ over the seen width 2 sin(t, ωo), on a grid of
    views all around the fibre. The exact one is brighter towards the light (Φ = 0:
    π²/4 times KK's) and dark opposite it (Φ = π: 0)."""
    rho = 0.7
    t = np.array([0.0, 1.0, 0.0])
    kk = KayKajiya(t, rho / math.pi**2, 0.0, 1.0)
    wi = np.array([math.sin(0.4) * math.cos(0.3), math.sin(0.3), math.cos(0.4) * math.cos(0.3)])
    wi /= np.linalg.norm(wi)
    psi = (np.arange(4000) + 0.5) * 2 * math.pi / 4000
    nrm = np.column_stack([np.cos(psi), np.zeros_like(psi), np.sin(psi)])
    lat = 0.5  # the view's angle from the fibre's normal plane
    views = (np.arange(720) + 0.5) * 2 * math.pi / 720
    radiance = []
    for a in views:
        wo = np.array([math.cos(lat) * math.cos(a), math.sin(lat), math.cos(lat) * math.sin(a)])
        power = np.sum(np.maximum(nrm @ wi, 0) * np.maximum(nrm @ wo, 0)) * 2 * math.pi / 4000
        radiance.append(rho / math.pi * power / (2 * math.cos(lat)))
    radiance = np.array(radiance)
    expect = kk.eval(np.array([wi]), np.array([[0.0, 0.0, 1.0]]))[0]
    assert radiance.mean() == pytest.approx(expect, rel=1e-4)
    alpha_i = math.atan2(wi[2], wi[0])
    back = np.argmin(np.abs(np.angle(np.exp(1j * (views - alpha_i)))))
    assert radiance[back] / expect == pytest.approx(math.pi**2 / 4, rel=1e-3)
    assert radiance.min() / expect < 1e-3


def test_sparse_velvet_fibre_integral_by_surface_sampling():
    """The closed-form side integral (with the base's oblique cut) and the tip against
    explicit sampling of the side surface above z = 0 and the generator's own tip faces
    (``tubes``), at random axes and directions: 1e-4 relative."""
    r, length, sides = 0.01, 0.15, 6
    model = SparseVelvet(r, length, 100, 20, 5, 0, 360, 0.7, sides=sides)
    rng = np.random.default_rng(0)
    for _ in range(8):
        t = rng.normal(size=3)
        t[2] = abs(t[2]) + 0.3
        t /= np.linalg.norm(t)
        wi, wo = (direction(rng.uniform(0, 1.5), rng.uniform(0, 2 * np.pi)) for _ in "io")
        u = np.cross(t, [0, 0, 1.0] if abs(t[2]) < 0.9 else [1.0, 0, 0])
        u /= np.linalg.norm(u)
        v = np.cross(t, u)
        psi = (np.arange(4000) + 0.5) * 2 * np.pi / 4000
        nrm = np.cos(psi)[:, None] * u + np.sin(psi)[:, None] * v
        lo = -r * 8 / t[2]
        sl = lo + (np.arange(2000) + 0.5) * (length - lo) / 2000
        above = (r * nrm[:, None, 2] + sl[None, :] * t[2]) > 0
        g = np.maximum(nrm @ wi, 0) * np.maximum(nrm @ wo, 0)
        side = (g[:, None] * above).sum() * (2 * np.pi / 4000) * r * (length - lo) / 2000
        verts, faces = tubes(np.zeros((1, 3)), t[None], r, np.array([-0.05]), length, sides)
        tri = verts[faces[2 * sides:3 * sides]]
        cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        unit = cross / np.linalg.norm(cross, axis=1, keepdims=True)
        tip = np.sum(0.5 * np.linalg.norm(cross, axis=1) * np.maximum(unit @ wi, 0)
                     * np.maximum(unit @ wo, 0))
        got = model.fibre_integral(t[None], wi[None], wo[None])[0]
        assert got == pytest.approx(side + tip, rel=1e-4)


def test_sparse_velvet_quadrature_equals_the_mean_over_drawn_fibres():
    """The tilt/azimuth quadrature of the clipped-normal distribution against the plain
    mean over 3 × 10⁴ axes drawn by the generator's own ``fibre_directions``: within 4
    Monte Carlo standard errors plus the quadrature's 0.15%. A spread wide enough that
    the clip at 0° matters (tilt 10 ± 15°)."""
    args = (0.01, 0.15, 100.0, 10.0, 15.0, 0.0, 360.0, 0.8)
    quad = SparseVelvet(*args)
    axes = fibre_directions(30000, 10.0, 15.0, 0.0, 360.0, np.random.default_rng(1))
    rng = np.random.default_rng(2)
    for _ in range(4):
        wi, wo = (direction(rng.uniform(0, 1.4), rng.uniform(0, 2 * np.pi)) for _ in "io")
        per = SparseVelvet(*args, axes=axes).fibre_integral(
            axes, np.repeat(wi[None], len(axes), 0), np.repeat(wo[None], len(axes), 0))
        mean, err = per.mean(), per.std(ddof=1) / math.sqrt(len(per))
        got = quad.fibre_integral(quad.axes, np.repeat(wi[None], len(quad.axes), 0),
                                  np.repeat(wo[None], len(quad.axes), 0)) @ quad.weights
        assert abs(got - mean) < 4 * err + 1.5e-3 * mean
        f = quad.eval(wi, wo)[0]
        assert f == pytest.approx(100.0 * 0.8 * got / (math.pi * wi[2] * wo[2]), rel=1e-12)


def test_sparse_velvet_of_given_fibres_is_their_mean_fibre_integral():
    """With ``axes``, f_r = N_A ⟨∫ (ω_i·n)⁺ (ω_o·n)⁺ dA⟩ ρ / (π cos θ_i cos θ_o), the mean
    over those fibres with equal weights, for pairs in a (2, 4) array (the result (2, 4, 3));
    exactly 0 where a direction is on (z = 0) or below the horizon, without a warning
    (RuntimeWarnings are errors in this suite). 1e-12: the same sums in another order."""
    rng = np.random.default_rng(4)
    axes = fibre_directions(5, 20.0, 10.0, 0.0, 360.0, rng)
    albedo = np.array([0.2, 0.5, 0.9])
    model = SparseVelvet(0.01, 0.15, 80.0, 0.0, 0.0, 0.0, 0.0, albedo, axes=axes)
    wi = direction(rng.uniform(0, 1.4, 8), rng.uniform(0, 2 * np.pi, 8))
    wo = direction(rng.uniform(0, 1.4, 8), rng.uniform(0, 2 * np.pi, 8))
    wi[5], wo[6], wi[7] = [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.6, 0.0, -0.8]
    f = model.eval(wi.reshape(2, 4, 3), wo.reshape(2, 4, 3))
    assert f.shape == (2, 4, 3)
    f = f.reshape(8, 3)
    for k in range(5):
        per = model.fibre_integral(axes, np.repeat(wi[k][None], 5, 0),
                                   np.repeat(wo[k][None], 5, 0))
        expected = 80.0 * per.mean() / (math.pi * wi[k, 2] * wo[k, 2]) * albedo
        np.testing.assert_allclose(f[k], expected, rtol=1e-12)
    assert np.all(f[5:] == 0.0)


def test_sparse_velvet_quadrature_nodes():
    """The tilt and azimuth rules. A spread of 0 is one node, the tilt clipped to
    [0, 80]° as the generator clips it, weight 1. Tilt 75 ± 10° (12 Gauss-Legendre nodes
    and the atoms at 0 and 80°, the upper one P(T > 80°) = 31%): the weights sum to 1 and
    give the clipped normal's mean tilt (scipy quadrature) to 1e-6 (the rule integrates the
    smooth density to ~1e-9). A normal azimuth, 30 ± 0.5° or ± 40°: Gauss-Hermite, exact for
    the mean and variance. The model's defaults are the documented 12 × 32 nodes."""
    from scipy import integrate, stats

    from microsim.analytic.velvet import azimuth_nodes, tilt_nodes

    for tilt, clipped in [(-5.0, 0.0), (30.0, 30.0), (95.0, 80.0)]:
        nodes, weights = tilt_nodes(tilt, 0.0, 12)
        assert nodes.tolist() == [math.radians(clipped)] and weights.tolist() == [1.0]
    nodes, weights = tilt_nodes(75.0, 10.0, 12)
    assert len(nodes) == 14 and nodes[0] == 0.0 and nodes[-1] == math.radians(80.0)
    assert weights.sum() == pytest.approx(1.0, abs=1e-6)
    inner, _ = integrate.quad(lambda t: t * stats.norm.pdf(t, 75.0, 10.0), 0.0, 80.0)
    mean = inner + 80.0 * stats.norm.sf(80.0, 75.0, 10.0)
    assert weights @ nodes == pytest.approx(math.radians(mean), abs=1e-6)
    assert len(tilt_nodes(30.0, 0.5, 12)[0]) == 14
    nodes, weights = azimuth_nodes(30.0, 0.0, 32)
    assert nodes.tolist() == [math.radians(30.0)] and weights.tolist() == [1.0]
    for spread in (0.5, 40.0):
        nodes, weights = azimuth_nodes(30.0, spread, 32)
        assert weights.sum() == pytest.approx(1.0, abs=1e-14)
        assert weights @ nodes == pytest.approx(math.radians(30.0), rel=1e-12)
        assert weights @ (nodes - math.radians(30.0)) ** 2 == pytest.approx(
            math.radians(spread) ** 2, rel=1e-10)
    model = SparseVelvet(0.01, 0.15, 80.0, 20.0, 10.0, 30.0, 20.0, 0.8)
    assert len(model.weights) == 14 * 32 and model.tip_n.shape[1] == 6
    azimuths = np.arctan2(model.axes[:, 1], model.axes[:, 0])
    tilted = model.axes[:, 2] < 1.0
    assert (model.weights[tilted] @ azimuths[tilted] / model.weights[tilted].sum()
            == pytest.approx(math.radians(30.0), rel=1e-10))


@pytest.mark.parametrize("sides", [6, 24])
def test_sparse_velvet_tip_faces_point_outwards_and_tile_the_cone(sides):
    """The tip's faces from the ring of ``sides`` corners to the apex (in units of r):
    normals pointing away from the axis and up it, of length twice the face's area, the
    areas summing to the pyramid's lateral area sides · ½ · 2 sin(π/sides) · √(1 + cos²(π/sides))
    (base edge times slant height), to 1e-12."""
    from microsim.analytic.velvet import tip_faces
    from microsim.surfaces.velvet import section_axes

    t = fibre_directions(20, 30.0, 20.0, 0.0, 360.0, np.random.default_rng(6))
    u, v = section_axes(t)
    n, lengths = tip_faces(u, v, t, sides)
    a = 2 * np.pi * np.arange(sides + 1) / sides
    ring = np.cos(a)[None, :, None] * u[:, None] + np.sin(a)[None, :, None] * v[:, None]
    assert np.all(np.einsum("mkj,mkj->mk", n, ring[:, 1:] + ring[:, :-1]) > 0)
    assert np.all(np.einsum("mkj,mj->mk", n, t) > 0)
    np.testing.assert_allclose(lengths, np.linalg.norm(n, axis=2), rtol=1e-15)
    half = math.pi / sides
    area = sides * 0.5 * 2 * math.sin(half) * math.sqrt(1 + math.cos(half) ** 2)
    np.testing.assert_allclose(0.5 * lengths.sum(axis=1), area, rtol=1e-12)


def test_microcylinder_thread_reduces_to_the_exact_cylinder_reflection():
    """Limiting case of the cloth model: one family of straight threads (no crimp),
    no shadowing, no volume scattering, a narrow surface lobe (γ_s = 0.5°): its bin
    averages equal the exact reflection of dielectric cylinders (η = 1.5, coverage
    2r/s, too far apart to shadow) to within the lobe's smearing — directional albedo
    within 0.5%, L1 distance over the bins within 3% — at incidences whose cone does not
    run along a bin edge."""
    from microsim.analytic.cloth import MicrocylinderCloth
    from microsim.comparison.metrics import bin_average

    r, s = 0.5, 1e4
    exact = CylinderArray(r, s, 0.0, DielectricFresnel(1.5))
    cloth = MicrocylinderCloth([2 * r / s, 0.0], 1.5, math.radians(0.5), 0.1, 0.0,
                               np.zeros((2, 3)), 0.0, 1.0, masking=False)
    te = np.arcsin(np.sqrt(np.linspace(0, 1, 9)))
    pe = np.linspace(0, 2 * np.pi, 17)
    omega = 0.5 * np.outer(np.diff(np.sin(te) ** 2), np.diff(pe))
    for theta, phi in ((0.7, 0.5), (0.3, 1.2), (1.1, 2.0)):
        wi = direction(theta, phi)
        a = bin_average(cloth, wi, te, pe, 0.0, n=32)[..., 0]
        b = exact.singular(wi, te, pe, 0.0)[..., 0]
        total = (b * omega).sum()
        assert (a * omega).sum() == pytest.approx(total, rel=5e-3)
        assert (np.abs(a - b) * omega).sum() < 0.03 * total


def test_microcylinder_cloth_is_reciprocal():
    """Every term of the cloth model is symmetric in ω_i and ω_o (θ_h, |θ_d|, cos(φ_d/2),
    the correlated masking, the layer projections, cos θ_i + cos θ_r), with crimped
    tangents and masking on: f(ω_i, ω_o) = f(ω_o, ω_i) to round-off at random pairs."""
    from microsim.analytic.cloth import MicrocylinderCloth

    cloth = MicrocylinderCloth([0.7, 0.6], 1.6, 0.15, 0.3, 0.4,
                               np.array([[0.2, 0.3, 0.8], [0.9, 0.8, 0.7]]), 0.55, 0.3)
    rng = np.random.default_rng(3)
    wi = direction(rng.uniform(0, 1.5, 200), rng.uniform(0, 2 * np.pi, 200))
    wo = direction(rng.uniform(0, 1.5, 200), rng.uniform(0, 2 * np.pi, 200))
    np.testing.assert_allclose(cloth.eval(wi, wo), cloth.eval(wo, wi), rtol=1e-10,
                               atol=1e-14)


def test_cloth_tangents_of_a_straight_thread_are_one():
    """A thread without crimp (slope 0) or all floats (flat 1) has the one tangent along its
    family, weight 1 (``tangents``' docstring); a crimped one has 2 count + 1 unit tangents,
    the flat one first with weight ``flat`` and the others (1 − flat) / (2 count) each."""
    from microsim.analytic.cloth import tangents

    for slope, flat in [(0.0, 0.3), (0.55, 1.0)]:
        t, w = tangents([0.0, 1.0, 0.0], slope, flat, 8)
        assert t.tolist() == [[0.0, 1.0, 0.0]] and w.tolist() == [1.0]
    t, w = tangents([1.0, 0.0, 0.0], 0.55, 0.3, 8)
    assert t.shape == (17, 3)
    np.testing.assert_allclose(np.linalg.norm(t, axis=1), 1.0, rtol=1e-15)
    assert w[0] == 0.3
    np.testing.assert_allclose(w[1:], 0.7 / 16, rtol=1e-15)


def test_rgb_models_refuse_other_channel_counts_by_name():
    """The fibre models are RGB only: a colour parameter of one number is every channel,
    of three values each one, and of two (or four) values a ValueError naming the
    parameter, from the constructor rather than numpy's broadcasting later."""
    from microsim.analytic.cloth import MicrocylinderCloth

    two = [0.2, 0.4]
    cases = [
        ("base_albedo", lambda: CylinderArray(0.5, 1.5, 0.0, None, two)),
        ("facet albedo", lambda: CylinderArray(0.5, 1.5, 0.0, Lambertian(two))),
        ("facet k", lambda: CylinderArray(0.5, 1.5, 0.0,
                                          ConductorFresnel(0.2, [3.9, 2.4, 2.1, 2.0]))),
        ("albedo", lambda: SparseVelvet(0.01, 0.2, 0.1, 0.3, 0.2, 0.0, 0.5, two)),
        ("albedo", lambda: MicrocylinderCloth([0.5, 0.5], 1.6, 0.15, 0.3, 0.4,
                                              [two, two], 0.55, 0.3)),
    ]
    for name, build in cases:
        with pytest.raises(ValueError, match=rf"^{name} takes one number or 3 values \(RGB\)"):
            build()
    assert CylinderArray(0.5, 1.5, 0.0, None, 0.25).base_albedo.tolist() == [
        0.25] * 3
    cloth = MicrocylinderCloth([0.5, 0.5], 1.6, 0.15, 0.3, 0.4, [0.2, 0.3, 0.8], 0.55, 0.3)
    assert cloth.albedo.tolist() == [[0.2, 0.3, 0.8]] * 2


def test_microcylinder_cloth_refuses_other_than_two_families():
    """``coverage`` has one entry per thread family (warp, weft): three, or one, are refused
    with a ValueError when evaluated, not cut to the families there are."""
    from microsim.analytic.cloth import MicrocylinderCloth

    albedo = np.array([[0.2, 0.3, 0.8], [0.9, 0.8, 0.7]])
    for coverage in ([0.5, 0.5, 0.5], [0.5]):
        cloth = MicrocylinderCloth(coverage, 1.6, 0.15, 0.3, 0.4, albedo, 0.55, 0.3)
        with pytest.raises(ValueError, match="zip"):
            cloth.eval(direction(0.5, 0.0), direction(0.6, 2.0))


def cloth_by_the_paper(wi, wo, coverage, eta, gamma_s, gamma_v, kd, albedo, slope, flat,
                       masking=True, count=8):
    """Sadeghi et al. 2013's microcylinder cloth for one direction pair, written from the
    module docstring of ``microsim.analytic.cloth`` with scalar arithmetic, independently
    of the code: the tangent curve of each family (slope ±slope · sin(πτ) at the
    midpoints τ of ``count`` equal steps, weight (1 − flat)/(2 count) each, and the flat
    tangent, weight ``flat``), the thread frame, the unpolarised dielectric Fresnel term,
    f_s = (f_R + f_V)/cos²θ_d, the correlated masking (σ = 20°) and the layer sum."""
    def fresnel(c):
        s2 = (1 - c * c) / eta**2
        if s2 >= 1:
            return 1.0
        ct = math.sqrt(1 - s2)
        rs, rp = (c - eta * ct) / (c + eta * ct), (eta * c - ct) / (eta * c + ct)
        return (rs * rs + rp * rp) / 2

    def g(gamma, x):
        return math.exp(-0.5 * (x / gamma) ** 2) / (gamma * math.sqrt(2 * math.pi))

    if wi[2] <= 0 or wo[2] <= 0:
        return np.zeros(3)
    total = np.zeros(3)
    for j, along in enumerate(([0.0, 1.0, 0.0], [1.0, 0.0, 0.0])):
        if slope == 0 or flat >= 1:
            curve = [(0.0, 1.0)]
        else:
            rise = [slope * math.sin(math.pi * (k + 0.5) / count) for k in range(count)]
            step = (1 - flat) / (2 * count)
            curve = [(0.0, flat)] + [(s, step) for s in rise] + [(-s, step) for s in rise]
        for s, weight in curve:
            t = np.array(along) + s * np.array([0.0, 0.0, 1.0])
            t /= np.linalg.norm(t)
            ti = math.asin(max(-1.0, min(1.0, float(wi @ t))))
            to = math.asin(max(-1.0, min(1.0, float(wo @ t))))
            th, td = (ti + to) / 2, (to - ti) / 2
            n = np.array([0.0, 0.0, 1.0]) - t[2] * t
            n /= np.linalg.norm(n)
            b = np.cross(t, n)
            phi_i, phi_o = math.atan2(wi @ b, wi @ n), math.atan2(wo @ b, wo @ n)
            pd = (phi_o - phi_i + math.pi) % (2 * math.pi) - math.pi
            f = fresnel(math.cos(td) * math.cos(pd / 2))
            surface = f * 0.25 * math.cos(pd / 2) * g(gamma_s, 2 * th)
            volume = (1 - f) ** 2 * ((1 - kd) * g(gamma_v, th) + kd) / (
                math.cos(ti) + math.cos(to)) * np.asarray(albedo[j], float)
            mi, mo = max(math.cos(phi_i), 0.0), max(math.cos(phi_o), 0.0)
            if masking:
                u = math.exp(-0.5 * (pd / math.radians(20.0)) ** 2)
                m = (1 - u) * mi * mo + u * min(mi, mo)
            else:
                m = 1.0
            total += coverage[j] * weight * (surface + volume) / math.cos(td) ** 2 * m * (
                math.cos(ti) * math.cos(to))
    return total / (wi[2] * wo[2])


def test_microcylinder_cloth_is_the_papers_formula():
    """The model against ``cloth_by_the_paper`` at 32 random direction pairs, some below
    the horizon (0 there) and one on it, directions along a thread's tangent (ω·t rounds
    past ±1: no warning), for crimped weaves with floats, both families or
    one (coverage 0 and 1), the isotropic and the peaked volume term, masking on and off:
    1e-10 relative (round-off: the two evaluate the same formulas in different order)."""
    from microsim.analytic.cloth import MicrocylinderCloth

    albedo = np.array([[0.2, 0.3, 0.8], [0.9, 0.8, 0.7]])
    rng = np.random.default_rng(11)
    theta_i, theta_o = rng.uniform(0, 1.55, 32), rng.uniform(0, 1.55, 32)
    theta_i[:6] = rng.uniform(1.6, 3.0, 6)  # light below the horizon
    theta_o[6:12] = rng.uniform(1.6, 3.0, 6)
    wi = direction(theta_i, rng.uniform(0, 2 * np.pi, 32))
    wo = direction(theta_o, rng.uniform(0, 2 * np.pi, 32))
    t = np.array([0.0, 1.0, 0.55 * math.sin(math.pi / 16)])
    t /= np.linalg.norm(t)  # ω·t rounds to 1 + 2⁻⁵² for this warp tangent
    wi[12], wi[13], wo[13], wi[14], wo[14], wi[15], wo[15] = [1.0, 0.0, 0.0], t, t, -t, t, t, -t
    wo[16] = [-1.0, 0.0, 0.0]
    # grazing behind a steep tangent's normal plane: azimuths about the thread ~±170°,
    # so φ_r − φ_i leaves [−π, π] and has to be wrapped (seen with masking off)
    wi[17], wo[17] = np.array([0.5, 0.85, 0.17]), np.array([-0.5, 0.85, 0.17])
    wi[17:18] /= np.linalg.norm(wi[17])
    wo[17:18] /= np.linalg.norm(wo[17])
    configs = [
        ((0.7, 0.6), 1.6, 0.15, 0.3, 0.4, 0.55, 0.3, True),
        ((0.0, 0.8), 1.4, 0.1, 0.5, 1.0, 0.4, 0.0, True),
        ((1.0, 0.0), 1.5, 0.2, 0.25, 0.0, 1.0, 0.6, False),
        ((0.5, 0.5), 1.3, 0.3, 0.2, 0.2, 0.0, 0.0, True),
    ]
    for coverage, eta, gs, gv, kd, slope, flat, masking in configs:
        cloth = MicrocylinderCloth(coverage, eta, gs, gv, kd, albedo, slope, flat,
                                   **({} if masking else {"masking": False}))
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            got = cloth.eval(wi, wo)
        expect = np.array([cloth_by_the_paper(a, b, coverage, eta, gs, gv, kd, albedo, slope,
                                              flat, masking) for a, b in zip(wi, wo, strict=True)])
        np.testing.assert_allclose(got, expect, rtol=1e-10, atol=1e-300)
        assert np.all(got[[*range(13), 14, 15, 16]] == 0) and np.all(expect[18:] > 0)


def test_one_cylinder_over_a_lit_base_is_the_bases_lambertian_limit():
    """Spacing ∞ (one cylinder, of no area share) is the limit of wide spacings: the base
    covers the whole surface, f_r = ρ_b/π, and a spacing of 10⁸ radii agrees with it to
    within the share its cylinder covers: at most its footprint 2r and its shadow and
    hidden strip 2r / sin α along each direction (α its elevation in the x-z plane)."""
    rng = np.random.default_rng(5)
    wi, wo = (d / np.linalg.norm(d, axis=1, keepdims=True)
              for d in (rng.normal(size=(200, 3)) * [1, 1, 0.5] + [0, 0, 1.2]
                        for _ in range(2)))
    base = [0.2, 0.5, 0.8]
    mirror = None  # its reflection is ``singular``'s: eval is the base's alone
    one = CylinderArray(0.5, math.inf, 0.3, mirror, base).eval(wi, wo)
    above = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    np.testing.assert_array_equal(one[above], np.broadcast_to(np.array(base) / math.pi,
                                                              (above.sum(), 3)))
    spacing = 0.5e8
    wide = CylinderArray(0.5, spacing, 0.3, mirror, base).eval(wi, wo)
    strips = sum(1.0 / (d[:, 2] / np.hypot(d[:, 0], d[:, 2])) for d in (wi, wo))
    bound = (1.0 + strips[above]) / spacing  # r = 0.5: 2r = 1
    assert np.all(np.abs(wide[above] - one[above]) <= bound[:, None] * one[above])
