"""``microsim render``: objects and their tangent frames, tables and models as Mitsuba
BSDFs, and renders of tables against Mitsuba's own analytic plugins.

Renders are tiny (at most 64 × 48 pixels) and lit so that their error is known: on the
convex sphere under the sun alone every camera ray sees the light once through next-event
estimation and nothing else, so a render has no noise but the pixel jitter, which the same
seed repeats (the tables' tests compare systematics); under the sky, pixels carry the
standard error of their samples (the Lambertian test compares within that noise).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from microsim.analytic.brdf import Lambertian, OrenNayar, TorranceSparrow
from microsim.analytic.fresnel import ConductorFresnel, DielectricFresnel
from microsim.analytic.ndf import GGX, Beckmann
from microsim.comparison.metrics import model_table
from microsim.geometry import direction
from microsim.render import bsdfs, figure, objects, scene
from microsim.tables.binning import HemisphereBins
from microsim.tables.exr import write_table
from microsim.tables.meta import TableMeta

ETA, K = np.array([0.2, 0.9, 1.1]), np.array([3.9, 2.4, 2.1])  # gold-like, R G B
SUN = [scene.Light("sun", {"elevation": 50.0, "azimuth": -40.0, "irradiance": 3.0})]


@pytest.fixture(scope="module")
def mi():
    pytest.importorskip("mitsuba")
    from microsim.render import backend

    return backend.load("scalar_rgb")


@pytest.fixture(scope="module")
def sphere():
    return objects.sphere()


def small_camera(width=64, height=48):
    return scene.Camera(width, height)


# --- objects and tangent frames (numpy only) ----------------------------------------------
@pytest.mark.parametrize("build", [objects.torus, objects.sphere, objects.sheet])
def test_objects_are_closed_under_their_rule(build):
    """Outward faces, unit normals, bounding radius RADIUS; tangents are unit and in the
    face plane; the torus's and sphere's are horizontal and orthogonal to the radius from
    the z axis (the major circle, the parallels), the sheet's along +x."""
    s = build()
    n, t = objects.face_frames(s)
    vertex_n = s.normals[s.faces].mean(axis=1)
    assert np.all(np.sum(n * vertex_n, axis=1) > 0.9)
    assert np.allclose(np.linalg.norm(s.normals, axis=1), 1.0)
    assert math.isclose(np.linalg.norm(s.vertices, axis=1).max(), objects.RADIUS)
    assert np.allclose(np.linalg.norm(t, axis=1), 1.0) and np.allclose(np.sum(t * n, 1), 0,
                                                                       atol=1e-9)
    c = s.vertices[s.faces].mean(axis=1)
    rule = s.tangents
    if s.name == "sheet":
        assert np.all(rule == [1.0, 0.0, 0.0])
        assert np.all(t[:, 0] > 0.7)  # the sheet's slopes stay under ~45 degrees
    else:
        radial = c * [1, 1, 0]
        ok = np.linalg.norm(radial, axis=1) > 0.2  # away from the poles
        assert np.allclose(np.sum(rule[ok] * radial[ok], axis=1), 0, atol=1e-9)
        assert np.allclose(rule[ok, 2], 0, atol=1e-9)
        # in the flat face's plane the rule turns by less than the faces' angular size
        assert np.all(np.sum(t[ok] * rule[ok], axis=1) > math.cos(math.radians(3)))


def test_corner_uvs_make_dp_du_the_tangent():
    """Solving each face's (u, v) → p map as Mitsuba does (∂p/∂u from two edges and their
    texture-coordinate differences) gives back the face tangent to float32 precision."""
    s = objects.torus(segments=(24, 12))
    p, _, uv, faces = objects.corner_arrays(s)
    _, t = objects.face_frames(s)
    p, uv = p[faces].astype(float), uv[faces].astype(float)
    dp1, dp2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    du1, du2 = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
    det = du1[:, 0] * du2[:, 1] - du1[:, 1] * du2[:, 0]
    dp_du = (du2[:, 1, None] * dp1 - du1[:, 1, None] * dp2) / det[:, None]
    np.testing.assert_allclose(dp_du, t, atol=1e-4)


def test_mesh_file_and_degenerate_tangents(tmp_path):
    """A mesh file is centred, scaled and gets circles about +z; faces on the axis fall
    back to an in-plane basis vector (unit, orthogonal to the normal)."""
    import trimesh

    path = tmp_path / "box.ply"
    trimesh.creation.box(extents=(2.0, 1.0, 0.5)).export(path)
    s = objects.load_object(str(path))
    n, t = objects.face_frames(s)
    assert math.isclose(np.linalg.norm(s.vertices, axis=1).max(), objects.RADIUS)
    assert np.allclose(np.linalg.norm(t, axis=1), 1) and np.allclose(np.sum(n * t, 1), 0)
    normals = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
    b = objects.basis(normals)
    np.testing.assert_allclose(np.linalg.norm(b, axis=1), 1)
    np.testing.assert_allclose(np.sum(b * normals, axis=1), 0, atol=1e-15)


def test_mitsuba_shading_frame_follows_the_major_circle(mi):
    """Rays from the camera hit the torus; Mitsuba's shading tangent sh_frame.s there is
    the major-circle direction (−y, x, 0)/r made orthogonal to the shading normal, within
    2°: the tangent is the face's, taken at its centroid, which lies up to half a face
    (1.125° of azimuth) from the hit point, and the face is flat where the torus curves.
    A frame Mitsuba made up itself (no texture coordinates) would be off by up to 90°."""
    surface = objects.torus()
    sc = mi.load_dict({"type": "scene", "object": scene.mesh(
        mi, surface, mi.load_dict({"type": "diffuse"}))})
    origin = np.array(scene.Camera().origin())
    rng = np.random.default_rng(3)
    angles = []
    while len(angles) < 40:
        target = surface.vertices[rng.integers(len(surface.vertices))]
        d = target - origin
        si = sc.ray_intersect(mi.Ray3f(mi.Point3f(*origin), mi.Vector3f(*(d / np.linalg.norm(d)))))
        if not si.is_valid():
            continue
        p, n = np.array(si.p), np.array(si.sh_frame.n)
        expect = np.array([-p[1], p[0], 0.0])
        expect -= n * (expect @ n)
        expect /= np.linalg.norm(expect)
        s = np.array(si.sh_frame.s)
        angles.append(math.degrees(math.acos(min(1.0, abs(s @ expect)))))
        assert s @ expect > 0
    assert max(angles) < 2.0


# --- BSDFs ---------------------------------------------------------------------------------
def mitsuba_eval(bsdf, mi, a, b):
    si = mi.SurfaceInteraction3f()
    si.wi = mi.Vector3f(*a)
    v = bsdf.eval(mi.BSDFContext(), si, mi.Vector3f(*b))
    return np.array([v[0], v[1], v[2]])


def random_pairs(n, seed, max_deg=85.0):
    rng = np.random.default_rng(seed)
    a = direction(np.radians(rng.uniform(0, max_deg, n)), rng.uniform(-np.pi, np.pi, n))
    b = direction(np.radians(rng.uniform(0, max_deg, n)), rng.uniform(-np.pi, np.pi, n))
    return a, b


@pytest.mark.parametrize(("model", "plugin", "rtol"), [
    (Lambertian([0.7, 0.5, 0.3]), "diffuse", 1e-6),
    # GGX's Smith G1 is closed-form on both sides: float32 round-off
    (TorranceSparrow(GGX(alpha_x=0.2, alpha_y=0.5), shadowing="smith-separable"),
     "roughconductor", 1e-4),
    # Mitsuba's Beckmann G1 is Walter et al. 2007's rational fit (eq. 27), within 0.35% of
    # the exact one per direction, so G1(wi) G1(wo) within 0.7%
    (TorranceSparrow(Beckmann(0.3), fresnel=ConductorFresnel(ETA, K),
                     shadowing="smith-separable"), "roughconductor", 7e-3),
    (TorranceSparrow(Beckmann(0.4), fresnel=DielectricFresnel(1.5),
                     shadowing="smith-separable"), "roughplastic", 7e-3),
])
def test_mitsuba_equivalents_compute_the_model(mi, model, plugin, rtol):
    """At 200 random direction pairs Mitsuba's plugin returns the model's f_r cos θ_light
    (lobe values above 1% of the largest; the model's own code, independent of Mitsuba's)."""
    spec = bsdfs.mitsuba_equivalent(model)
    assert spec is not None and spec["type"] == plugin
    bsdf = mi.load_dict(spec)
    a, b = random_pairs(200, 1)
    got = np.array([mitsuba_eval(bsdf, mi, x, y) for x, y in zip(a, b, strict=True)])
    ref = np.broadcast_to(np.asarray(model.eval(b, a)).reshape(200, -1), (200, 3)) * b[:, 2:]
    big = ref > 0.01 * ref.max()
    np.testing.assert_allclose(got[big], ref[big], rtol=rtol)


def test_models_without_an_equivalent_go_through_python(mi):
    """Height-correlated Smith, Oren-Nayar and an anisotropic model turned by 30° have no
    Mitsuba plugin; the Python BSDF evaluates the model (swapped into microsim's order and
    rotated) to float32 precision, and its sample weight is eval / pdf."""
    aniso = TorranceSparrow(Beckmann(alpha_x=0.2, alpha_y=0.5), shadowing="smith-separable")
    assert bsdfs.mitsuba_equivalent(TorranceSparrow(Beckmann(0.3))) is None
    assert bsdfs.mitsuba_equivalent(aniso, 30.0) is None
    assert bsdfs.mitsuba_equivalent(aniso, 90.0)["alpha_u"] == 0.5
    for model, rotation in ((OrenNayar(math.radians(20), [0.8, 0.6, 0.4]), 0.0),
                            (aniso, 30.0)):
        bsdf, how = bsdfs.model_bsdf(mi, model, rotation)
        assert how == "python"
        a, b = random_pairs(20, 2)
        r = bsdfs.rotation_z(-rotation)
        for x, y in zip(a, b, strict=True):
            ref = np.broadcast_to(model.eval(r @ y, r @ x), (3,)) * y[2]
            np.testing.assert_allclose(mitsuba_eval(bsdf, mi, x, y), ref, rtol=1e-5,
                                       atol=1e-7)
        si = mi.SurfaceInteraction3f()
        si.wi = mi.Vector3f(*a[0])
        bs, weight = bsdf.sample(mi.BSDFContext(), si, 0.5, mi.Point2f(0.3, 0.7))
        wo = np.array(bs.wo)
        np.testing.assert_allclose(np.array(weight), mitsuba_eval(bsdf, mi, a[0], wo) / bs.pdf,
                                   rtol=1e-5)


# --- renders -------------------------------------------------------------------------------
def test_lambertian_table_renders_like_diffuse(mi, sphere, tmp_path):
    """A Lambertian table (albedo 0.7, 0.5, 0.3) and Mitsuba's ``diffuse`` with the same
    albedo on the sphere under sun and sky, 32 samples per pixel, independent seeds. Per
    pixel z = (T − D) / √(σ_T² + σ_D²), from each render's own standard error of the
    pixel mean (√((E[Y²] − E[Y]²)/32), about 12% of a pixel here). Noise alone gives z of
    mean 0 and mean square 1 (a little more: each σ is estimated from 32 samples, a
    t-like spread, measured 1.10). Over the P ≈ 1380 covered pixels the mean of z must lie
    within 4/√P (4 standard errors; it flags a relative bias above 4/√P × 12% × √2 ≈ 1.8%
    of the image) and the mean square within [0.8, 1.4]. Measured over three seed pairs:
    mean z −0.009 … +0.001, mean square 1.10 … 1.11."""
    table = model_table(Lambertian([0.7, 0.5, 0.3]), np.radians(np.linspace(0, 85, 6)),
                        HemisphereBins(16, 32))
    lights = SUN + [scene.Light("sky", {"radiance": 0.25})]
    cam = small_camera()
    t = scene.render(mi, sphere, bsdfs.table_bsdf(mi, table, tmp_path / "l.bsdf"), cam,
                     lights, 32, seed=0)
    d = scene.render(mi, sphere, mi.load_dict(bsdfs.mitsuba_equivalent(
        Lambertian([0.7, 0.5, 0.3]))), cam, lights, 32, seed=1)
    ok = (t.alpha > 0.999) & (d.alpha > 0.999)
    z = (t.luminance - d.luminance)[ok] / np.hypot(t.luminance_err, d.luminance_err)[ok]
    assert ok.sum() > 1000
    assert abs(z.mean()) < 4 / math.sqrt(ok.sum()), z.mean()
    assert 0.8 < np.mean(z**2) < 1.4, np.mean(z**2)


def test_beckmann_table_renders_like_roughconductor(mi, sphere, tmp_path):
    """A noise-free table of a Beckmann α = 0.3 gold conductor (bin averages of the model,
    32 × 64 bins, θi every 9.4° to 85°) against ``roughconductor`` with the same α, η, k,
    under the sun, same pixel jitter. Tolerance: median |Δ| < 3% and mean Δ within ±6%.
    Reason: pointwise the table differs from the model by 1.3% (median) and +1.4% (mean)
    over the lobe, growing to +5–7% where the camera looks at the sphere from more than
    75° (the last θo bin spans 10°), which the silhouette pixels of a 64 × 48 sphere
    sample; Mitsuba's measured tensor adds 0.25% (median), roughconductor 0.2%
    (Walter's G1 fit). Measured here: median 1.5%, mean +3.1%."""
    model = TorranceSparrow(Beckmann(0.3), fresnel=ConductorFresnel(ETA, K),
                            shadowing="smith-separable")
    table = model_table(model, np.radians(np.linspace(0, 85, 10)), HemisphereBins(32, 64))
    cam = small_camera()
    t = scene.render(mi, sphere, bsdfs.table_bsdf(mi, table, tmp_path / "b.bsdf"), cam,
                     SUN, 4)
    bsdf, how = bsdfs.model_bsdf(mi, model)
    assert how == "roughconductor"
    m = scene.render(mi, sphere, bsdf, cam, SUN, 4)
    diff = figure.difference(t, m)
    assert diff.pixels > 300
    assert diff.median_abs < 0.03 and abs(diff.mean) < 0.06, (diff.median_abs, diff.mean)


def test_rotated_anisotropic_table_renders_as_the_rotated_model(mi, sphere, tmp_path):
    """An anisotropic Beckmann gold table (α_x = 0.3, α_y = 0.7; φi every 30°, θi to 85°)
    on the sphere, tangents along the parallels, under the sun. Turned by 90° about the
    normal it renders differently from unturned and from the unturned model (median
    |Δ| > 50%; measured 92% and 91%), and like roughconductor with α_u and α_v swapped
    (median |Δ| < 10%; measured 5.7%), as the unturned table renders like the unturned
    model (measured 6.1%). Reason for 10%: the table is not its model: linear
    interpolation between incidences 30° apart in φi and 32 × 64 bins put it 3.1%
    (median) from the model over the lobe, more on the lobe's flanks that the lit pixels
    see, and the resampled tensor adds 0.9%."""
    model = TorranceSparrow(Beckmann(alpha_x=0.3, alpha_y=0.7), fresnel=ConductorFresnel(ETA, K),
                            shadowing="smith-separable")
    table = model_table(model, np.radians([0, 20, 40, 60, 75, 85]), HemisphereBins(32, 64),
                        phi_i=np.radians(np.arange(0, 360, 30)))
    cam = small_camera()
    t0 = scene.render(mi, sphere, bsdfs.table_bsdf(mi, table, tmp_path / "a.bsdf"), cam,
                      SUN, 4)
    t90 = scene.render(mi, sphere, bsdfs.table_bsdf(mi, table, tmp_path / "b.bsdf",
                                                    rotation=90.0), cam, SUN, 4)
    swapped = {"type": "roughconductor", "distribution": "beckmann", "alpha_u": 0.7,
               "alpha_v": 0.3, "eta": {"type": "rgb", "value": ETA.tolist()},
               "k": {"type": "rgb", "value": K.tolist()}}
    assert bsdfs.mitsuba_equivalent(model, 90.0) == swapped | {
        "eta": bsdfs.rgb_spectrum(ETA), "k": bsdfs.rgb_spectrum(K)}
    m90 = scene.render(mi, sphere, mi.load_dict(swapped), cam, SUN, 4)
    m0 = scene.render(mi, sphere, bsdfs.model_bsdf(mi, model)[0], cam, SUN, 4)
    assert figure.difference(t90, t0).median_abs > 0.5
    assert figure.difference(t90, m0).median_abs > 0.5
    assert figure.difference(t90, m90).median_abs < 0.1
    assert figure.difference(t0, m0).median_abs < 0.1


# --- command line --------------------------------------------------------------------------
@pytest.fixture(scope="module")
def table_file(tmp_path_factory):
    model = TorranceSparrow(Beckmann(0.3), fresnel=ConductorFresnel(ETA, K))
    table = model_table(model, np.radians([0, 30, 60, 80]), HemisphereBins(16, 32),
                        meta=TableMeta.from_json({"surface": {"kind": "analytic",
                                                               "alpha_realised": 0.3}}))
    path = tmp_path_factory.mktemp("render") / "gold.exr"
    write_table(table, path)
    return path


def test_render_command_writes_the_grid(cli, mi, table_file, tmp_path):
    """Two tables and a model: the PNG exists with three panels per row; the JSON reports
    the plugin (α from the table's metadata), times and the difference."""
    out = tmp_path / "grid.png"
    code, stdout, err = cli("render", str(table_file), str(table_file), "-o", str(out),
                            "--size", "32x24", "--spp", "2", "--object", "sphere",
                            "--model", "beckmann:shadowing=smith-separable", "--json")
    assert code == 0, err
    import json

    result = json.loads(stdout)
    assert out.stat().st_size > 1000
    assert [t["mitsuba"] for t in result["tables"]] == ["roughconductor"] * 2
    assert result["tables"][0]["params"]["alpha"] == 0.3
    assert result["tables"][0]["param_sources"] == {"alpha": "the table's realised alpha",
                                                    "shadowing": "given"}
    assert result["tables"][0]["difference"]["pixels"] > 50


@pytest.mark.parametrize(("argv", "needle"), [
    (["-o", "x.jpg"], "--output"),
    (["-o", "x.png", "--size", "4x4"], "--size"),
    (["-o", "x.png", "--light", "moon"], "--light 'moon'"),
    (["-o", "x.png", "--light", "sun:elevation=100"], "elevation"),
    (["-o", "x.png", "--light", "envmap"], "file=PATH"),
    (["-o", "x.png", "--light", f"envmap:file={Path(__file__).parent.parent / 'README.md'}"],
     "is not an image"),
    (["-o", "x.png", "--object", "cube"], "--object cube"),
    (["-o", "x.png", "--object", "nothere.ply"], "no such file"),
    (["-o", "x.png", "--model", "bekmann"], "model 'bekmann'"),
    (["-o", "x.png", "--camera", "30"], "--camera"),
    (["-o", "x.png", "--variant", "cuda"], "--variant"),
])
def test_bad_render_input_exits_2(cli, table_file, tmp_path, argv, needle):
    code, _, err = cli("render", str(table_file), *argv)
    assert code == 2 and err.startswith("error: ") and needle in err, err
    assert len(err.strip().splitlines()) == 1


def test_missing_mitsuba_names_the_extra(cli, table_file, tmp_path, monkeypatch):
    """Without Mitsuba the command stops with one line naming the ``render`` extra."""
    monkeypatch.setitem(sys.modules, "mitsuba", None)
    code, _, err = cli("render", str(table_file), "-o", str(tmp_path / "x.png"))
    assert code == 2 and err.startswith("error: ") and "microsim[render]" in err


def test_a_tabulated_model_renders_like_its_plugin(mi, sphere, tmp_path):
    """What ``render --model`` does in scalar variants for a model without a Mitsuba
    plugin: the model tabulated through ``measured`` as tables are. Checked on models that
    do have a plugin (gold Beckmann α = 0.3, and anisotropic α 0.3 / 0.7 turned by 90°,
    which ``roughconductor`` takes with α_u and α_v swapped), under the sun, same pixel
    jitter, so the difference is the tensor's. Pointwise over 300 random direction pairs
    in the lobe the tensor differs from the model by 0.14% (median |Δ|) and +0.4% (mean)
    when isotropic (32 θi nodes, 64² grid), 0.55% and +1.4% when anisotropic (16 θi
    nodes, 48² grid, φi every 15°), and ``roughconductor`` by 0.2% (Walter's G1 fit).
    Tolerance, about twice that plus the silhouette pixels where the last θ node (89°) is
    extrapolated: median |Δ| < 1% and |mean Δ| < 2% (isotropic), < 2% and < 4%
    (anisotropic). Measured: 0.26% and +0.5%; 0.84% and +1.8%."""
    for model, rotation, limits in (
            (TorranceSparrow(Beckmann(0.3), fresnel=ConductorFresnel(ETA, K),
                             shadowing="smith-separable"), 0.0, (0.01, 0.02)),
            (TorranceSparrow(Beckmann(alpha_x=0.3, alpha_y=0.7), fresnel=ConductorFresnel(ETA, K),
                             shadowing="smith-separable"), 90.0, (0.02, 0.04))):
        assert bsdfs.isotropic(model.eval) == (rotation == 0.0)
        cam = small_camera()
        tabulated = bsdfs.tensor_bsdf(mi, model.eval, bsdfs.isotropic(model.eval),
                                      tmp_path / "m.bsdf", rotation, "test")
        t = scene.render(mi, sphere, tabulated, cam, SUN, 4)
        bsdf, how = bsdfs.model_bsdf(mi, model, rotation)
        assert how == "roughconductor"
        m = scene.render(mi, sphere, bsdf, cam, SUN, 4)
        diff = figure.difference(t, m)
        assert diff.pixels > 300
        assert diff.median_abs < limits[0] and abs(diff.mean) < limits[1], (
            diff.median_abs, diff.mean)


def test_render_tabulates_a_model_without_a_plugin(mi, tmp_path):
    """``model_bsdf`` with a path tabulates a model Mitsuba has no plugin for (height-
    correlated Smith) and keeps the plugin where there is one; an anisotropic model is
    tabulated with its φi slices (``isotropic`` tells them apart)."""
    correlated = TorranceSparrow(Beckmann(0.3))
    aniso = TorranceSparrow(Beckmann(alpha_x=0.2, alpha_y=0.5))
    assert bsdfs.isotropic(correlated.eval) and not bsdfs.isotropic(aniso.eval)
    assert bsdfs.model_bsdf(mi, correlated, 0.0, tmp_path / "a.bsdf")[1] == "tabulated"
    assert bsdfs.model_bsdf(mi, aniso, 30.0, tmp_path / "b.bsdf")[1] == "tabulated"
    assert bsdfs.model_bsdf(mi, Lambertian(0.5), 0.0, tmp_path / "c.bsdf")[1] == "diffuse"


def test_display_tone_maps_without_clipping():
    """Reinhard's global operator on luminance (docs/render.md, "Display"): the shown
    luminance is exactly L / (1 + L) of the linear luminance L, so it stays below 1 and
    keeps the order of any two pixels however bright (linear radiances from 1e-4 to 1e4);
    no channel leaves [0, 1]; a colour that fits is only scaled (its channel ratios kept),
    and one that would not is moved towards grey at the same luminance. A highlight at
    50 and one at 100 stay apart on screen (clipping at 1 showed both white)."""
    from microsim.tables.export import LUMINANCE

    rng = np.random.default_rng(3)
    rgb = rng.lognormal(0.0, 3.0, (4000, 3))
    out = figure.tone_map(rgb)
    y = rgb @ LUMINANCE
    np.testing.assert_allclose(out @ LUMINANCE, y / (1 + y), rtol=1e-12)
    assert out.min() >= 0.0 and out.max() <= 1.0 + 1e-12
    order = np.argsort(y)
    assert np.all(np.diff((out @ LUMINANCE)[order]) > 0)
    fits = (rgb / (1 + y)[:, None]).max(axis=1) < 1.0
    assert fits.sum() > 500 and (~fits).sum() > 500        # both cases are exercised
    np.testing.assert_allclose(out[fits] * (1 + y[fits])[:, None], rgb[fits], rtol=1e-12)
    grey = (y / (1 + y))[~fits, None]
    chroma = (out[~fits] - grey) / (rgb[~fits] / (1 + y[~fits])[:, None] - grey)
    np.testing.assert_allclose(chroma, chroma[:, :1] * np.ones((1, 3)), rtol=1e-9)
    image = scene.Image(np.array([[[50.0] * 3, [100.0] * 3]]), np.ones((1, 2)),
                        np.zeros((1, 2)), np.zeros((1, 2)), 0.0)
    shown = figure.display(image)
    assert shown[0, 0].max() < shown[0, 1].max() < 1.0


def test_the_star_where_a_sphere_faces_the_camera_is_the_bins_noise():
    """The velvet sphere's star (docs/render.md, "Stars and notches"): around the point
    that faces the camera, the pixels on a small circle see the surface from θo = 10° at
    every azimuth, so the noise of the bins of the first θo rings (64 wedges of 5.6° each)
    becomes wedges meeting at that point. Not a tangent frame: an isotropic table's value
    does not change when both directions turn about the normal. A noiseless table of the
    velvet's fibre colour as a Lambertian is the same all around the circle; with the
    shipped velvet's ~20% noise per bin (its first rings' azimuthal spread is that noise:
    χ²/dof 0.6–1.2 at θi ≤ 45°) it varies by more than 5%."""
    from microsim.analytic.registry import parse_model_spec
    from microsim.tables.export import LUMINANCE

    _, _, model = parse_model_spec("lambertian:albedo=[0.6,0.1,0.1]")
    theta, bins = np.radians([0.0, 15.0, 30.0, 45.0, 60.0]), HemisphereBins(32, 64)
    clean = model_table(model, theta, bins)
    noisy = model_table(model, theta, bins, 0.2, np.random.default_rng(5))
    phi = np.linspace(0.0, 2 * np.pi, 256, endpoint=False)
    light = direction(np.full(256, np.radians(40.0)), 0.0)
    view = direction(np.full(256, np.radians(10.0)), phi)

    def spread(t):
        y = t.eval(light, view) @ LUMINANCE
        return y.std() / y.mean()

    assert spread(clean) < 1e-9 and spread(noisy) > 0.05, (spread(clean), spread(noisy))
    turn = bsdfs.rotation_z(73.0)
    np.testing.assert_allclose(noisy.eval(light @ turn.T, view @ turn.T),
                               noisy.eval(light, view), rtol=1e-12)
