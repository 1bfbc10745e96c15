"""Refracting dielectric facets: Snell's law, the Fresnel choice, total internal reflection,
Beer-Lambert absorption, and layered tiles against closed forms."""

from __future__ import annotations

import mpmath
import numpy as np
import pytest
from scipy import integrate

from microsim.analytic.layered import CoatedLambertian
from microsim.analytic.registry import parse_model_spec
from microsim.geometry import direction
from microsim.kernel.packing import FacetMaterials
from microsim.materials import material_from_json
from microsim.materials.optics import reflect, refract
from microsim.measurement.paths import trace_paths
from microsim.measurement.scene import PeriodicScene
from microsim.surfaces.facts import TileFacts
from microsim.surfaces.tile import Tile

Z_MAX = 4.0
"""Two-sided z bound per comparison: with at most a dozen comparisons per test the chance
of a false alarm is below 12 x 6.3e-5 < 1e-3."""
ETA = 1.5


def fresnel_reference(cos_i: float, eta: float) -> float:
    """Unpolarised Fresnel reflectance with complex arithmetic in mpmath (Born & Wolf,
    sec. 1.5.2): beyond the critical angle cos_t is imaginary and |r| = 1 by itself, so
    total internal reflection needs no special case. Independent of microsim's code."""
    cos_i = mpmath.mpf(cos_i)
    cos_t = mpmath.sqrt(1 - (1 - cos_i**2) / mpmath.mpf(eta) ** 2 + 0j)
    r_s = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    r_p = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    return float((abs(r_s) ** 2 + abs(r_p) ** 2) / 2)


def hemispherical_reflectance(eta: float) -> float:
    """Cosine-weighted hemispherical reflectance ∫ F(θ) 2 cos θ sin θ dθ by adaptive
    quadrature (split at the critical angle when eta < 1)."""
    points = [np.arcsin(eta)] if eta < 1 else None
    value, _ = integrate.quad(lambda t: fresnel_reference(np.cos(t), eta) * np.sin(2 * t),
                              0.0, np.pi / 2, points=points, epsabs=1e-12)
    return value


def refract_rows(d: np.ndarray, n: np.ndarray, eta: float) -> tuple[np.ndarray, np.ndarray]:
    """The kernel's ``refract`` of each row: directions (k, 3) and TIR flags (k,)."""
    rows = [refract(*d[i], *n[i], eta) for i in range(len(d))]
    return np.array([r[:3] for r in rows]), np.array([r[3] for r in rows])


def random_units(rng: np.random.Generator, n: int) -> np.ndarray:
    v = rng.standard_normal((n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


@pytest.mark.parametrize("eta", [ETA, 1 / ETA])
def test_refract_obeys_snell_in_the_plane_of_incidence(eta: float) -> None:
    rng = np.random.default_rng(1)
    n = random_units(rng, 5000)
    d = random_units(rng, 5000)
    mirrored = np.array([reflect(*d[i], *n[i]) for i in range(len(d))])
    d = np.where((np.einsum("ij,ij->i", d, n) < 0)[:, None], d, mirrored)
    t, tir = refract_rows(d, n, eta)
    cos_i = -np.einsum("ij,ij->i", d, n)
    sin_i = np.sqrt(1 - cos_i**2)
    assert np.array_equal(tir, sin_i > eta)  # TIR exactly beyond the critical angle
    assert tir.any() == (eta < 1)
    ok = ~tir & (sin_i < eta - 1e-6)
    t, d, n = t[ok], d[ok], n[ok]
    sin_t = np.linalg.norm(np.cross(t, n), axis=1)
    np.testing.assert_allclose(eta * sin_t, sin_i[ok], atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(t, axis=1), 1.0, atol=1e-14)
    assert np.all(np.einsum("ij,ij->i", t, n) < 0)  # goes through the interface
    assert np.abs(np.einsum("ij,ij->i", np.cross(d, n), t)).max() < 1e-12  # coplanar
    # reversibility: from behind, with 1 / eta, the path runs back
    back, back_tir = refract_rows(-t, -n, 1 / eta)
    assert not back_tir.any()
    np.testing.assert_allclose(back, -d, atol=1e-10)


def test_fresnel_choice_reflects_with_probability_f_from_either_side() -> None:
    """The kernel's event at a refracting facet (``FacetMaterials.scatter``): reflection
    with probability F(θ, η) from the front, F(θ, 1/η) from inside, weight 1 either way."""
    k = 40_000
    facets = FacetMaterials(np.zeros(1, np.int64), ("base",), {"base": material_from_json(BINDER)})
    n = np.tile([0.0, 0.0, 1.0], (k, 1))
    faces = np.zeros(k, np.int64)
    for seed, (theta, side, eta) in enumerate(((0.0, 1, ETA), (60.0, 1, ETA),
                                               (30.0, -1, ETA), (40.0, -1, ETA))):
        d = -side * direction(np.radians(np.full(k, theta)), np.zeros(k))
        out, factor, into = facets.scatter(faces, d, n, np.random.SeedSequence(seed))
        refracted = out[:, 2] * d[:, 2] > 0  # through the interface
        f = fresnel_reference(np.cos(np.radians(theta)), eta if side > 0 else 1 / eta)
        sigma = np.sqrt(f * (1 - f) / k)
        assert abs((~refracted).mean() - f) < Z_MAX * sigma
        mirror = d * [1, 1, -1]
        assert np.abs(out[~refracted] - mirror[~refracted]).max() < 1e-15
        assert np.all(factor == 1.0) and np.all(into == 0.0)
    # inside beyond the critical angle (41.8 deg): total internal reflection, always
    d = direction(np.radians(np.full(k, 42.0)), np.zeros(k))
    out, _, _ = facets.scatter(faces, d, n, np.random.SeedSequence(9))
    assert np.all(out[:, 2] < 0)


def test_internal_reflectance_quadrature_is_consistent() -> None:
    """The two quadratures obey 1 - r_i = (1 - r_e) / eta^2 (the radiance theorem:
    Walter et al. 2007, eq. 11 integrated; Kelemen & Szirmay-Kalos 2001), a check
    of the reference itself, since the closed-form test below rests on r_i."""
    r_e, r_i = hemispherical_reflectance(ETA), hemispherical_reflectance(1 / ETA)
    assert abs((1 - r_i) - (1 - r_e) / ETA**2) < 1e-9
    assert 0.59 < r_i < 0.61  # the textbook figure for eta = 1.5 (0.596)


def layer_tile(thickness: float, size: float = 1.0, bottom: str = "substrate") -> Tile:
    """A flat binder top at z = thickness (part 0) over a flat substrate at z = 0 (part 1,
    normal up), or, with ``bottom = "slab"``, over the binder's own bottom face (normal
    down): a free-standing slab."""
    corners = np.array([[0, 0], [size, 0], [size, size], [0, size]], float)
    vertices = np.concatenate([np.column_stack([corners, np.full(4, thickness)]),
                               np.column_stack([corners, np.zeros(4)])])
    up = np.array([[0, 1, 2], [0, 2, 3]])
    low = up + 4 if bottom == "substrate" else up[:, ::-1] + 4
    material = [0, 0, 1, 1] if bottom == "substrate" else [0, 0, 0, 0]
    return Tile(vertices, np.concatenate([up, low]), np.array(material),
                ("binder", "substrate"), (size, size), facts=TileFacts(isotropic=True))


def layer_paths(tile: Tile, materials: dict, theta_deg: float, rays: int, bounces: int,
                seed: int = 0):
    wi = direction(np.radians(theta_deg), 0.0)
    ss = np.random.SeedSequence(seed)
    rng = np.random.default_rng(ss)
    facets = FacetMaterials(tile.material, tile.parts,
                            {p: material_from_json(m) for p, m in materials.items()})
    with PeriodicScene(tile, threads=1) as scene:
        origins = np.column_stack([rng.random((rays, 2)) * tile.period,
                                   np.full(rays, scene.z_top)])
        paths = trace_paths(scene, facets, origins, np.broadcast_to(-wi, (rays, 3)),
                            bounces, ss)
    return wi, paths


def budget(paths, rays: int) -> np.ndarray:
    """Escaped + absorbed + transmitted + lost per ray, RGB: must be 1."""
    return (paths.weight.sum(axis=0) + paths.absorbed + paths.transmitted
            + paths.lost) / rays


BINDER = {"kind": "dielectric", "eta": ETA, "refract": True}


@pytest.mark.parametrize("theta_deg", [0.0, 60.0])
def test_flat_binder_over_black_reflects_exactly_fresnel(theta_deg: float) -> None:
    rays = 20_000
    tile = layer_tile(0.2)
    wi, paths = layer_paths(tile, {"binder": BINDER,
                                   "substrate": {"kind": "lambertian", "albedo": 0.0}},
                            theta_deg, rays, bounces=8)
    escaped = paths.weight[:, 0] > 0  # paths off the black substrate carry weight 0
    assert np.all(paths.order[escaped] == 1)
    assert np.abs(paths.direction[escaped] - wi * [-1, -1, 1]).max() < 1e-12
    f = fresnel_reference(np.cos(np.radians(theta_deg)), ETA)
    assert abs(escaped.mean() - f) < Z_MAX * np.sqrt(f * (1 - f) / rays)
    # the refracted rest is absorbed by the substrate: accounted to rounding
    np.testing.assert_allclose(paths.absorbed / rays, 1 - escaped.mean(), atol=1e-12)
    np.testing.assert_allclose(budget(paths, rays), 1.0, atol=1e-12)
    assert paths.fate_counts["backface"] == 0 and not paths.lost.any()


def test_white_furnace_under_a_flat_binder_conserves_energy() -> None:
    """White substrate, no absorption: every path escapes in the end; with 200 bounces
    the weight still inside is r_i^100 ~ 1e-22 (none), so escaped = 1 exactly per path."""
    rays = 10_000
    _, paths = layer_paths(layer_tile(0.2), {"binder": BINDER, "substrate": {
        "kind": "lambertian", "albedo": 1.0}}, 45.0, rays, bounces=200)
    assert np.all(paths.weight == 1.0) and np.all(paths.order > 0)
    assert not paths.lost.any() and not paths.absorbed.any()
    assert paths.fate_counts["escaped"] == rays


@pytest.mark.parametrize("theta_deg", [30.0, 70.0])
def test_lambertian_under_a_smooth_layer_matches_the_closed_form(theta_deg: float) -> None:
    """Albedo rho under a smooth dielectric layer (Weidlich & Wilkie 2007, "Arbitrarily
    layered micro-facet surfaces"; Kelemen & Szirmay-Kalos 2001): light enters
    with 1 - F(theta_i), the substrate turns it diffuse, a fraction 1 - r_i of diffuse
    light leaves, r_i returns to the substrate, so

        A = F(theta_i) + (1 - F(theta_i)) rho (1 - r_i) / (1 - rho r_i)

    and the diffuse light leaves with f_r(theta_o) = rho (1 - F_i)(1 - F(theta_o)) /
    (pi eta^2 (1 - rho r_i)). r_i comes from the mpmath Fresnel by quadrature. Compared
    within Z_MAX standard errors: the albedo, and the diffuse part in 6 theta_o bins
    (chi-square over the bins below its 0.999 quantile, 22.5 for 6 degrees of freedom)."""
    rays, rho = 40_000, 0.5
    _, paths = layer_paths(layer_tile(0.2), {"binder": BINDER, "substrate": {
        "kind": "lambertian", "albedo": rho}}, theta_deg, rays, bounces=60)
    assert paths.lost.max() < 1e-10  # (r_i rho)^30: nothing left at the bounce limit
    np.testing.assert_allclose(budget(paths, rays), 1.0, atol=1e-12)
    r_i = hemispherical_reflectance(1 / ETA)
    f_i = fresnel_reference(np.cos(np.radians(theta_deg)), ETA)
    albedo = f_i + (1 - f_i) * rho * (1 - r_i) / (1 - rho * r_i)
    w = paths.weight[:, 0]
    assert abs(w.mean() - albedo) < Z_MAX * w.std(ddof=1) / np.sqrt(rays)
    # the diffuse part (order >= 3) per theta_o bin, against the integral of f_r cos
    edges = np.radians([0, 15, 30, 45, 60, 75, 90])
    theta_o = np.arccos(np.clip(paths.direction[:, 2], -1, 1))
    diffuse = np.where(paths.order >= 3, w, 0.0)
    z2 = 0.0
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):
        x = diffuse * ((theta_o >= lo) & (theta_o < hi))
        integral, _ = integrate.quad(lambda t: (1 - fresnel_reference(np.cos(t), ETA))
                                     * np.sin(2 * t) / 2, lo, hi, epsabs=1e-12)
        expected = 2 * rho * (1 - f_i) * integral / (ETA**2 * (1 - rho * r_i))
        z2 += ((x.mean() - expected) / (x.std(ddof=1) / np.sqrt(rays))) ** 2
    assert z2 < 22.5


def test_beer_lambert_weights_follow_the_path_length_inside() -> None:
    """A mirror substrate under an absorbing flat binder, oblique light on a small tile
    (the inside path crosses the tile's sides): a path of order k >= 3 crossed the layer
    k - 1 times, each at the refracted angle, so its weight is
    exp(-sigma (k - 1) h / cos theta_t), up to the secondary-ray offsets (each segment
    starts eps off its face, so the length -ln(w) / sigma is short by up to
    2 eps / cos theta_t per crossing; a length wrong by one wrap or a missed segment would
    be off by 0.1 or more). The budget closes to rounding."""
    rays, h, theta = 4000, 0.3, 50.0
    sigma = np.array([0.5, 1.0, 2.0])
    binder = {**BINDER, "absorption": sigma.tolist()}
    _, paths = layer_paths(layer_tile(h, size=0.1), {"binder": binder,
                                                     "substrate": {"kind": "mirror"}},
                           theta, rays, bounces=40)
    cos_t = np.sqrt(1 - (np.sin(np.radians(theta)) / ETA) ** 2)
    inner = paths.order >= 3
    assert inner.sum() > 0.8 * rays
    crossings = paths.order[inner] - 1
    length = -np.log(paths.weight[inner]) / sigma
    with PeriodicScene(layer_tile(h, size=0.1)) as scene:
        eps = scene.eps
    short = (crossings * h / cos_t)[:, None] - length
    assert np.all((short > -1e-12) & (short <= (crossings * 2 * eps / cos_t)[:, None]))
    np.testing.assert_allclose(budget(paths, rays), 1.0, atol=1e-12)
    assert paths.absorbed.min() > 0.1


def test_free_standing_slab_transmits_what_it_does_not_reflect() -> None:
    """A non-absorbing slab at normal incidence reflects R = F + (1-F)^2 F / (1 - F^2) =
    2F / (1 + F) (incoherent multiple reflections; Born & Wolf sec. 1.6.4 summed without
    phase); the rest leaves through the bottom and is reported as transmitted."""
    rays = 40_000
    _, paths = layer_paths(layer_tile(0.2, bottom="slab"), {"binder": BINDER,
                                                            "substrate": BINDER},
                           0.0, rays, bounces=40)
    f = fresnel_reference(1.0, ETA)
    r = 2 * f / (1 + f)
    escaped = (paths.order > 0).mean()
    assert abs(escaped - r) < Z_MAX * np.sqrt(r * (1 - r) / rays)
    np.testing.assert_allclose(paths.transmitted / rays, 1 - escaped, atol=1e-12)
    assert paths.fate_counts["transmitted"] == rays - paths.fate_counts["escaped"]
    assert not paths.lost.any()


def test_coated_lambertian_model_agrees_with_the_quadrature() -> None:
    """The registered model: its r_i equals the mpmath quadrature, and its diffuse f_r
    integrated over the hemisphere (scipy quad) plus the specular F is the albedo of the
    closed form above, for a scalar and an RGB albedo."""
    _, _, spec_model = parse_model_spec("coated-lambertian:albedo=0.5,eta=1.5")
    model = CoatedLambertian(0.5, ETA)
    assert abs(model.r_i - hemispherical_reflectance(1 / ETA)) < 1e-10
    wi, wo = direction(np.radians(30.0), 0.0), direction(np.radians(50.0), 2.0)
    assert np.allclose(spec_model.eval(wi, wo), model.eval(wi, wo))  # RGB from the spec
    rgb = CoatedLambertian([0.2, 0.5, 1.0], ETA)
    for theta_i in (0.0, 45.0, 80.0):
        wi = direction(np.radians(theta_i), 0.0)

        def projected(t: float, m=model, wi=wi) -> float:
            return float(m.eval(wi, direction(t, 1.0))) * np.sin(2 * t) * np.pi

        diffuse, _ = integrate.quad(projected, 0.0, np.pi / 2, epsabs=1e-12)
        f_i = fresnel_reference(np.cos(np.radians(theta_i)), ETA)
        r_i = hemispherical_reflectance(1 / ETA)
        closed = f_i + (1 - f_i) * 0.5 * (1 - r_i) / (1 - 0.5 * r_i)
        assert abs(f_i + diffuse - closed) < 1e-9
        assert abs(float(model.directional_albedo(wi[2])) - closed) < 1e-9
        rho = np.array([0.2, 0.5, 1.0])
        np.testing.assert_allclose(rgb.directional_albedo(wi[2]),
                                   f_i + (1 - f_i) * rho * (1 - r_i) / (1 - rho * r_i),
                                   atol=1e-9)
    assert np.all(model.eval(wi, direction(np.radians(95.0), 0.0)) == 0)


def test_dielectric_columns_medium_and_dispersion_are_what_the_kernel_reads() -> None:
    """The kernel's columns of a dielectric: η per channel (shipped ``data`` in its place:
    N-BK7's n_d = 1.5168 at 587.56 nm and n_F = 1.5224 at 486.13 nm, SCHOTT's data sheet
    to its 4 decimals, hence 1e-4), then 1 to refract, 0 not to; the medium's absorption
    only behind refracting faces (None else); its events' directions depend on the
    wavelength only when it refracts, in a table of more than one channel: always under a
    coating, at refractions where η varies between channels."""
    from microsim.materials import Dielectric
    from microsim.materials.base import DISPERSION_ALWAYS, DISPERSION_NONE, DISPERSION_REFRACTED
    from microsim.materials.coating import Coating
    from microsim.spectra.channels import RGB, Channels
    from microsim.spectra.spectrum import Spectrum

    assert Dielectric().parameters(RGB) == ((1.5,) * 3, (0.0,) * 3)
    assert Dielectric(eta=1.3, refract=True).parameters(RGB) == ((1.3,) * 3, (1.0,) * 3)
    eta, refracts = Dielectric(data="BK7", refract=True).parameters(Channels((587.56, 486.13)))
    assert abs(eta[0] - 1.5168) < 1e-4 and abs(eta[1] - 1.5224) < 1e-4 and refracts == (1.0, 1.0)
    assert Dielectric(absorption=(0.0, 0.0, 0.0)).medium(RGB) is None
    assert Dielectric(refract=True, absorption=(0.1, 0.2, 0.3)).medium(RGB) == (0.1, 0.2, 0.3)

    two, one = Channels((450.0, 600.0)), Channels((450.0,))
    index = Spectrum((400.0, 700.0), (1.6, 1.5), "an index of the test")
    film = Coating(120.0, 2.0)
    cases = [  # (material, channels, dispersion)
        (Dielectric(eta=index, refract=True), two, DISPERSION_REFRACTED),
        (Dielectric(eta=index), two, DISPERSION_NONE),
        (Dielectric(eta=index, refract=True), one, DISPERSION_NONE),
        (Dielectric(eta=1.5, refract=True), two, DISPERSION_NONE),
        (Dielectric(eta=1.5, refract=True, coating=film), two, DISPERSION_ALWAYS),
        (Dielectric(eta=1.5, refract=True, coating=film), one, DISPERSION_NONE),
        (Dielectric(eta=1.5, coating=film), two, DISPERSION_NONE),
        (Dielectric(eta=1.5, refract=True), RGB, DISPERSION_NONE),
    ]
    for material, channels, dispersion in cases:
        assert material.dispersion(channels) == dispersion, (material, channels)


def test_a_hero_paths_absorbed_weight_is_what_its_hero_lost() -> None:
    """What a path absorbed is found at its end, 1 less its final weight, what it
    transmitted and what ended at a dispersive event (``slots.add_energy``), not added up
    event by event. A dispersive binder (BK7, absorbing inside) over a mirror at normal
    incidence: a ray that refracts is left its hero h (weight × C), the other channels'
    weights end there, absorbing nothing, and the hero's C is absorbed in the binder down
    to the weight the path ends with; a ray reflected at the top keeps every channel
    with weight F_c / F_h and counts 1 − F_c / F_h as absorbed (an event's loss
    w (1 − F), of either sign here). So the run's absorbed weight in channel c is
    Σ (C − w_final) over the rays that refracted with hero c plus Σ (1 − w_final,c) over
    those reflected, to rounding (1e-12 of it), and nothing is transmitted: the paths'
    sums (``trace_paths``) against the final weights of the raw outcomes of the same rays
    and key, which the accounting does not touch. Counting the ended
    channels as absorbed, or not crediting the hero's gain, is off by about C times the
    refracted rays."""
    from microsim.kernel.slots import O_W
    from microsim.spectra.channels import Channels

    channels = Channels((450.0, 550.0, 650.0))
    count, rays = channels.count, 6000
    tile = layer_tile(0.3)
    binder = {"kind": "dielectric", "data": "BK7", "refract": True, "absorption": 0.8}
    facets = FacetMaterials(tile.material, tile.parts,
                            {"binder": material_from_json(binder),
                             "substrate": material_from_json({"kind": "mirror"})},
                            channels=channels)
    rng = np.random.default_rng(3)
    with PeriodicScene(tile, threads=1) as scene:
        origins = np.column_stack([rng.random((rays, 2)), np.full(rays, scene.z_top)])
        down = np.broadcast_to([0.0, 0.0, -1.0], (rays, 3))
        out = scene.run(origins, down, facets, 40, np.random.SeedSequence(4))
        paths = trace_paths(scene, facets, origins, down, 40, np.random.SeedSequence(4))
    final = out.floats[:, O_W:]
    hero = np.arange(rays) % count
    others = np.ones((rays, count), bool)
    others[np.arange(rays), hero] = False
    refracted = np.all(final[others].reshape(rays, count - 1) == 0.0, axis=1)
    assert 0.8 * rays < refracted.sum() < rays            # F ≈ 4% reflect at the top
    assert np.all(final[~refracted] > 0.0)
    expected = np.array([np.sum(count - final[refracted & (hero == c), c])
                         + np.sum(1.0 - final[~refracted, c]) for c in range(count)])
    assert np.all(expected > 0.1 * rays / count)          # the binder absorbs much
    np.testing.assert_allclose(paths.absorbed, expected, rtol=1e-12)
    assert not paths.transmitted.any()
