"""Surface generators: realised roughness, NDF, periodicity, seeds, V-groove normals."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from microsim.analytic.ndf import Beckmann, ndf_bin_average
from microsim.recipe import resolve
from microsim.surfaces import build_tile, gaussian
from microsim.surfaces.tile import height_field_vertices


def tile_of(**surface):
    return build_tile(resolve({"surface": surface}).surface)


@pytest.mark.parametrize("alpha", [0.1, 0.3, 1.0])
def test_gaussian_realised_alpha_within_ten_percent(alpha):
    """At the default resolution (256², τ = 8 cells) triangulation lowers the slopes by
    about 3% and a 32-correlation-length tile scatters by a few %: 10% bounds both."""
    t = tile_of(kind="gaussian", alpha=alpha, seed=3)
    assert t.facts.alpha_target.alpha == pytest.approx(alpha)
    assert t.facts.alpha_realised.alpha == pytest.approx(alpha, rel=0.1)
    assert not t.warnings


def test_gaussian_anisotropic_ratio_within_ten_percent():
    t = tile_of(kind="gaussian", alpha_x=0.2, alpha_y=0.5, seed=4, resolution=384)
    ax, ay = t.facts.alpha_realised.axes
    assert (ax / ay) == pytest.approx(0.2 / 0.5, rel=0.1)
    assert t.facts.isotropic is False


def test_rotated_anisotropy_follows_the_rotation():
    t = tile_of(kind="gaussian", alpha_x=0.2, alpha_y=0.5, rotation=90.0, seed=4)
    rx, ry = t.realised_alpha(0.0)  # measured along the unrotated axes
    assert rx > ry


def test_gaussian_ndf_matches_beckmann_at_realised_alpha():
    """Chi-square of the facet histogram against Beckmann at the realised α over bins with
    D > 1% of its peak, with the sub-tile (batch-means) standard errors that account for
    correlated facets: the p-value must exceed 0.001 (a 0.1% false-alarm rate)."""
    t = tile_of(kind="gaussian", alpha=0.3, seed=5, resolution=256)
    alpha = t.facts.alpha_realised.alpha
    m = t.ndf_histogram(16, math.atan(2.5 * alpha))
    model = ndf_bin_average(Beckmann(alpha), m["edges"])
    keep = model > 0.01 * model.max()
    chi2 = np.sum(((m["D"] - model)[keep] / m["stderr"][keep]) ** 2)
    assert stats.chi2.sf(chi2, keep.sum()) > 1e-3


def test_gaussian_is_periodic_and_seeded():
    a = tile_of(kind="gaussian", alpha=0.3, seed=7, resolution=64)
    v = a.vertices.reshape(65, 65, 3)
    assert np.array_equal(v[0, :, 2], v[-1, :, 2]) and np.array_equal(v[:, 0, 2], v[:, -1, 2])
    b = tile_of(kind="gaussian", alpha=0.3, seed=7, resolution=64)
    c = tile_of(kind="gaussian", alpha=0.3, seed=8, resolution=64)
    assert a.vertices.tobytes() == b.vertices.tobytes()
    assert a.vertices.tobytes() != c.vertices.tobytes()
    assert (a.face_normals_areas()[0][:, 2] > 0).all()


def test_gaussian_sigma_and_correlation_length():
    t = tile_of(kind="gaussian", sigma=0.01, correlation_length=0.05, resolution=128)
    assert t.facts.alpha_target.alpha == pytest.approx(2 * 0.01 / 0.05)


def test_gaussian_warns_about_coarse_and_small_tiles():
    """At τ = 2 cells finite-difference slopes lose a known share of the roughness,
    α_h/α = √((1 − e^{−1/4})·4) = 0.9406; a 64-correlation-length tile estimates α to
    ~1.1% (4096 independent areas), so the realised value is within 3% of 0.9406 α."""
    coarse = tile_of(kind="gaussian", alpha=0.3, correlation_length=2 / 128, resolution=128)
    assert any("grid cells" in w and "6% below" in w for w in coarse.warnings)
    expected = 0.3 * math.sqrt(-math.expm1(-0.25) / 0.25)
    assert coarse.facts.alpha_realised.alpha == pytest.approx(expected, rel=0.03)
    small = tile_of(kind="gaussian", alpha=0.3, resolution=64)
    assert any("correlation lengths per side" in w for w in small.warnings)


@pytest.mark.parametrize("slope", [10.0, 45.0, 80.0])
def test_vgroove_normals_exactly_at_the_slope(slope):
    t = tile_of(kind="vgroove", slope=slope, grooves=8)
    n, _ = t.face_normals_areas()
    s = math.radians(slope)
    np.testing.assert_allclose(np.abs(n[:, 0]), math.sin(s), atol=1e-12)
    np.testing.assert_allclose(n[:, 1], 0.0, atol=1e-12)
    np.testing.assert_allclose(n[:, 2], math.cos(s), atol=1e-12)


def test_vgroove_periodic_and_inside_its_box():
    t = tile_of(kind="vgroove", alpha=0.4, grooves=32, seed=2)
    v = t.vertices
    lx, ly = t.period
    assert v[:, 0].min() == 0 and v[:, 0].max() == pytest.approx(lx)
    assert v[:, 1].min() == 0 and v[:, 1].max() == ly
    ends = v[v[:, 0] == 0, 2], v[np.isclose(v[:, 0], lx), 2]
    np.testing.assert_array_equal(*ends)  # both ends are peaks at z = 0
    assert t.facts.slopes_deg["count"] == 32
    assert 0 < t.facts.slopes_deg["min"] <= t.facts.slopes_deg["max"] < 90


def test_vgroove_beckmann_slopes():
    """tan s = |N(0, α²/2)| per groove: the realised α across the grooves of 4000 grooves
    is within 5% of the target (the sample RMS of 4000 values scatters by ~1.1%)."""
    t = tile_of(kind="vgroove", alpha=0.5, grooves=4000, seed=1)
    assert t.facts.alpha_realised_x == pytest.approx(0.5, rel=0.05)


def test_flat_tile():
    t = tile_of(kind="flat", size=2.0)
    assert t.period == (2.0, 2.0) and t.z_range == (0.0, 0.0)
    assert (t.face_normals_areas()[0] == [0, 0, 1]).all()


@pytest.mark.parametrize("sink", [0.0, 0.25, 0.5, 0.99])
def test_cylinders_profile_is_closed_outward_and_inside_the_box(sink):
    """Cylinder facets face away from the axis, base facets up; every face lies in the
    period box; no zero-area faces; both parts present; the profile is one continuous
    curve from x = 0 to x = spacing (no gap a ray could slip through)."""
    r, s = 0.5, 1.1
    t = tile_of(kind="cylinders", radius=r, spacing=s, sink=sink, segments=32)
    n, a = t.face_normals_areas()
    assert a.min() > 0 and set(np.unique(t.material)) == {0, 1}
    cyl = t.material == 1
    centre = t.vertices[t.faces].mean(axis=1)
    radial = centre - [s / 2, 0.0, r - sink]
    radial[:, 1] = 0
    assert (np.sum(n[cyl] * radial[cyl], axis=1) > 0).all()
    assert np.allclose(n[~cyl], [0, 0, 1])
    v = t.vertices
    assert v[:, 0].min() == 0 and v[:, 0].max() == s and v[:, 1].max() == t.period[1]
    # the polygon's top lies within the sagitta r (1 - cos(pi/32)) below the circle's
    top = 2 * r - sink
    assert t.z_range[0] == 0.0 and top - r * (1 - np.cos(np.pi / 32)) <= t.z_range[1] <= top
    from microsim.surfaces.cylinders import profile
    points, part = profile(r, s, sink, 32)
    # one curve: base from x = 0, the arc, base to x = spacing, each vertex on the circle
    assert points[0, 0] == 0 and points[-1, 0] == s and part[0] == part[-1] == 0
    on_arc = points[1:-1]
    np.testing.assert_allclose(np.hypot(on_arc[:, 0] - s / 2, on_arc[:, 1] - (r - sink)), r,
                               rtol=1e-12)


def test_cylinder_facet_normals_sample_the_circle_evenly():
    """The arc's normals are the exact circle normals at evenly spaced angles: their
    angles differ by 360/segments degrees (the tessellation docs/surfaces.md discusses)."""
    t = tile_of(kind="cylinders", radius=0.5, spacing=1.0, sink=0.0, segments=64)
    n, _ = t.face_normals_areas()
    ang = np.degrees(np.arctan2(n[t.material == 1][:64, 2], n[t.material == 1][:64, 0]))
    steps = np.abs(np.diff(ang))
    steps = np.minimum(steps, 360 - steps)
    np.testing.assert_allclose(steps, 360 / 64, rtol=1e-9)


def test_cylinders_reject_overlap_and_vanishing():
    from microsim.errors import InputError
    with pytest.raises(InputError, match="spacing"):
        tile_of(kind="cylinders", radius=0.5, spacing=0.9)
    with pytest.raises(InputError, match="sink"):
        tile_of(kind="cylinders", radius=0.5, spacing=1.0, sink=1.0)
    with pytest.raises(InputError, match="radius"):
        tile_of(kind="cylinders", radius=-0.5)


def test_velvet_fibres_are_closed_outward_tubes():
    """Each tube's signed volume (divergence theorem, Σ v0·(v1×v2)/6) equals the prism
    plus cone it encloses, which holds only for closed, outward-wound tubes:
    polygon area (k/2) r² sin(2π/k) times its height, plus a third of it times r."""
    from microsim.surfaces.velvet import tubes
    rng = np.random.default_rng(0)
    axes = rng.normal(size=(5, 3)) * [0.3, 0.3, 1] + [0, 0, 3]
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    r, k, start, length = 0.02, 6, np.full(5, -0.03), 0.2
    v, f = tubes(rng.random((5, 3)), axes, r, start, length, k)
    t = v[f].reshape(5, -1, 3, 3)
    vol = np.einsum("nfi,nfi->nf", t[:, :, 0], np.cross(t[:, :, 1], t[:, :, 2])).sum(1) / 6
    area = k / 2 * r**2 * np.sin(2 * np.pi / k)
    np.testing.assert_allclose(vol, area * (length - start) + area * r / 3, rtol=1e-9)


def test_velvet_tile_is_periodic_inside_its_box_and_closed():
    """All faces inside the box, both parts, no zero-area faces; the fibres that cross a
    side are cut and wrapped, so a mirror white furnace loses nothing through gaps:
    every ray escapes (albedo exactly 1 with 200 bounces)."""
    from microsim.measurement.simulation import simulate
    t = tile_of(kind="velvet", density=200, seed=3)
    v = t.vertices
    assert v[:, 0].min() >= 0 and v[:, 0].max() <= 1 and v[:, 1].min() >= 0
    assert v[:, 1].max() <= 1 and set(np.unique(t.material)) == {0, 1}
    assert t.face_normals_areas()[1].min() > 0
    crossing = (v[:, 0] == 0) | (v[:, 0] == 1)
    assert crossing[t.faces[t.material == 1]].any()  # some fibre was cut at a side
    r = resolve({"surface": {"kind": "velvet"}, "material": {"kind": "mirror"},
                 "simulation": {"theta_i": [0.0, 70.0], "rays": 4000, "bounces": 200},
                 "table": {"theta_bins": 4, "phi_bins": 4}})
    table = simulate(t, r.material, r.simulation, r.table, threads=1)
    np.testing.assert_array_equal(table.albedo, 1.0)
    assert table.lost_energy.max() == 0


@pytest.mark.parametrize("kind", ["gaussian", "vgroove", "cylinders", "velvet", "weave"])
def test_screenshots_are_not_blank(kind, tmp_path):
    """Rendered off screen through EGL: the image has structure (pixel std > 10 of 255)
    and many colours."""
    from microsim.view import show_tile
    params = {"gaussian": {"alpha": 0.3, "resolution": 64}, "vgroove": {"slope": 30.0},
              "cylinders": {}, "velvet": {"density": 100}, "weave": {}}[kind]
    img = show_tile(tile_of(kind=kind, **params), tmp_path / "s.png", tiles=2)
    assert (tmp_path / "s.png").stat().st_size > 5000
    assert img.std() > 10 and len(np.unique(img.reshape(-1, 3), axis=0)) > 50


@pytest.mark.parametrize("pattern", [{"pattern": "plain"}, {"pattern": "twill", "float": [2, 1]},
                                     {"pattern": "twill", "float": [2, 2]}])
def test_weave_yarns_are_outward_tubes_that_do_not_intersect(pattern):
    """(1) Each yarn is a closed periodic tube wound outward: the flux of F = (x, 0, 0)
    (warp, along y) or (0, y, 0) (weft) through its faces equals the section polygon's area
    times the period — its volume (the open ends carry no flux of F). (2) Crossing yarns do
    not intersect: a ray cast down from inside the upper yarn at a crossing first meets
    that same yarn's underside."""
    from microsim.measurement.scene import PeriodicScene
    t = tile_of(kind="weave", sides=8, segments=8, **pattern)
    n, area = t.face_normals_areas()
    centre = t.vertices[t.faces].mean(axis=1)
    w, th, k = 0.8, 0.3, 8
    section = k / 2 * (w / 2) * (th / 2) * np.sin(2 * np.pi / k)
    repeat = t.facts.repeat
    per_yarn = len(t.faces) // (2 * repeat)
    for y in range(2 * repeat):
        sl = slice(y * per_yarn, (y + 1) * per_yarn)
        axis = 1 if t.material[sl][0] == 0 else 0
        flux = np.sum(centre[sl, 1 - axis] * n[sl, 1 - axis] * area[sl])
        assert flux == pytest.approx(section * t.period[0], rel=1e-9)
    from microsim.surfaces.weave import over, path_heights
    top = over(repeat, 1 if pattern["pattern"] == "plain" else int(pattern["float"][0]))
    amp = t.facts.crimp_amplitude
    i, j = np.argwhere(top)[0]
    rng = np.random.default_rng(0)
    a, b = rng.uniform(-0.85, 0.85, (2, 400))  # offsets across / along, in half-widths
    x = (i + 0.5) + a * w / 2
    yy = (j + 0.5) + b * w / 2
    heights = np.where(top[i], amp, -amp)
    z = path_heights(yy, heights, 1.0)
    with PeriodicScene(t, threads=1) as scene:
        hits = scene.closest_hit(np.column_stack([x, yy, z]), np.tile([0.0, 0.0, -1.0],
                                                                      (400, 1)))
    assert np.all(hits.face >= 0) and np.all(t.material[hits.face] == 0)


def test_weave_inside_box_and_seamless():
    t = tile_of(kind="weave", pattern="twill")
    v = t.vertices
    lx, ly = t.period
    assert v[:, 0].min() >= 0 and v[:, 0].max() <= lx + 1e-12
    assert v[:, 1].min() >= 0 and v[:, 1].max() <= ly + 1e-12
    assert t.face_normals_areas()[1].min() > 0 and set(np.unique(t.material)) == {0, 1}
    # warp ends: the ring at y = 0 equals the ring at y = Ly (the path is periodic)
    ends = v[(v[:, 1] == 0) | (v[:, 1] == ly)]
    start, end = ends[ends[:, 1] == 0], ends[ends[:, 1] == ly]
    np.testing.assert_allclose(np.sort(start[:, [0, 2]], axis=0),
                               np.sort(end[:, [0, 2]], axis=0), atol=1e-12)


def test_weave_bad_width():
    from microsim.errors import InputError
    with pytest.raises(InputError, match="yarn_width"):
        tile_of(kind="weave", yarn_width=1.0, spacing=1.0)


def reference_geometry(t):
    """Normals, areas and plane constants as numpy computes them (np.cross, norm, einsum)."""
    v = t.vertices[t.faces]
    cross = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    norm = np.linalg.norm(cross, axis=1)
    normals = np.divide(cross, norm[:, None], out=np.zeros_like(cross),
                        where=norm[:, None] > 0)
    return normals, 0.5 * norm, np.einsum("ij,ij->i", normals, v[:, 0])


def reference_alpha(t, rotation):
    """``Tile.realised_alpha`` in plain numpy: masked arrays, then sums."""
    normals, areas, _ = reference_geometry(t)
    up = normals[:, 2] > 0
    n, weight = normals[up], areas[up] * normals[up, 2]
    gx, gy = -n[:, 0] / n[:, 2], -n[:, 1] / n[:, 2]
    c, s = np.cos(rotation), np.sin(rotation)
    return tuple(float(np.sqrt(2 * np.sum(weight * slope**2) / weight.sum()))
                 for slope in (c * gx + s * gy, -s * gx + c * gy))


TILES = {"gaussian": {"kind": "gaussian", "alpha_x": 0.2, "alpha_y": 0.6, "rotation": 30.0,
                      "resolution": 64, "correlation_length": 1 / 16, "seed": 2},
         "velvet": {"kind": "velvet", "seed": 1},  # tubes: faces with n_z <= 0
         "paint": {"kind": "paint", "seed": 1}}


@pytest.mark.parametrize("kind", sorted(TILES))
def test_face_geometry_is_numpys_bit_for_bit(kind):
    """The compiled normals, areas, plane constants and realised roughness equal the numpy
    reference exactly (a degenerate face gets a zero normal and area)."""
    t = tile_of(**TILES[kind])
    t.faces = np.concatenate([t.faces, [[0, 0, 1]]])
    normals, areas = t.face_normals_areas()
    ref_n, ref_a, ref_c = reference_geometry(t)
    assert np.array_equal(normals, ref_n) and np.array_equal(areas, ref_a)
    assert np.array_equal(t.face_planes(), ref_c)
    assert not normals[-1].any() and areas[-1] == 0
    rotation = math.radians(30.0)
    assert t.realised_alpha(rotation) == reference_alpha(t, rotation)


def test_face_geometry_is_kept_until_the_arrays_change():
    t = tile_of(kind="gaussian", alpha=0.3, seed=7, resolution=32)
    normals, areas = t.face_normals_areas()
    assert t.face_normals_areas()[0] is normals and not normals.flags.writeable
    with pytest.raises(ValueError):
        areas[0] = 1.0
    t.vertices = t.vertices * [1.0, 1.0, 2.0]
    steeper, _ = t.face_normals_areas()
    assert steeper is not normals and np.array_equal(steeper, reference_geometry(t)[0])


def test_gaussian_heights_and_vertices_are_the_direct_synthesis():
    """Heights from the kept √P equal a fresh synthesis (covariance, FFT) bit for bit, and
    the vertices equal the padded grid; a second realisation reuses √P and the faces."""
    n, size, sigma, tau_x, tau_y, rotation = 32, 1.0, 0.01, 0.05, 0.08, 0.4
    d = np.arange(n) * (size / n)
    d = np.where(d >= size / 2, d - size, d)
    dx, dy = np.meshgrid(d, d, indexing="ij")
    c, s = math.cos(rotation), math.sin(rotation)
    cov = sigma**2 * np.exp(-(((c * dx + s * dy) / tau_x) ** 2
                              + ((-s * dx + c * dy) / tau_y) ** 2))
    noise = np.random.default_rng(3).standard_normal((n, n))
    power = np.maximum(np.fft.fft2(cov).real, 0.0)
    expected = np.fft.ifft2(np.fft.fft2(noise) * np.sqrt(power)).real
    h = gaussian.heights(n, size, sigma, tau_x, tau_y, rotation, np.random.default_rng(3))
    assert np.array_equal(h, expected)
    assert gaussian.root_power(n, size, sigma, tau_x, tau_y, rotation) is \
        gaussian.root_power(n, size, sigma, tau_x, tau_y, rotation)
    g = np.linspace(0.0, size, n + 1)
    x, y = np.meshgrid(g, g, indexing="ij")
    z = np.pad(h, ((0, 1), (0, 1)), mode="wrap")
    assert np.array_equal(height_field_vertices(h, size),
                          np.column_stack([x.ravel(), y.ravel(), z.ravel()]))
    a, b = (tile_of(kind="gaussian", alpha=0.3, seed=seed, resolution=32) for seed in (1, 2))
    assert a.faces is b.faces and not a.faces.flags.writeable
