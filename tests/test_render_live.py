"""Simulation at render time (``microsim.render.live``, ``render RECIPE --live``).

A small gold Gaussian recipe (64² tile, α = 0.3, two realisations, incidences every 10°
and 89°) is traced sample by sample and compared with what the table of the same recipe
says: the samples' mean weight with the table's albedo, and a render of the live surface
with a render of the table, by the relative difference of their mean luminance over the
lit pixels, whose standard error comes from the renders' own per-pixel errors
(``figure.Difference.total_err``). The renders use the LLVM variant (one kernel call per
wavefront; the README installs the LLVM it needs); one tiny render checks the scalar
variant's one-sample-per-call path.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from microsim.measurement.simulation import Tiles, simulate_recipe
from microsim.recipe import load
from microsim.render import live

RECIPE = """description = "small gold Gaussian"
[surface]
kind = "gaussian"
alpha = {alpha}
resolution = 64
seed = 1
[material]
kind = "conductor"
eta = [0.2, 0.92, 1.1]
k = [3.9, 2.45, 2.14]
[simulation]
theta_i = [0, 10, 20, 30, 40, 50, 60, 70, 80, 89]
rays = 200000
bounces = 16
seed = 1
realisations = 2
[table]
theta_bins = 32
phi_bins = 64
"""
LIGHTS = ["--light", "sun:radius=25", "--light", "sky:radiance=0.25"]
"""A sun of 25° radius: large enough that BSDF sampling finds it often (the live surface
cannot be sampled towards a light), so its render's noise allows a test of 1% of the
mean luminance at 64 × 48 pixels and 64 samples."""


@pytest.fixture(scope="module")
def recipe_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("live") / "gold.toml"
    path.write_text(RECIPE.format(alpha=0.3), encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def llvm():
    pytest.importorskip("mitsuba")
    from microsim.render import backend

    mi = backend.load("llvm_ad_rgb")
    yield mi
    backend.load("scalar_rgb")


def test_live_samples_carry_the_tables_albedo(recipe_file):
    """The mean weight of 50,000 samples from ωi is the directional albedo, which the
    table of the same two tiles measures: per colour channel and incidence (0°, 40°, 70°,
    89°, table incidences), z = (mean − albedo) / √(se² + se_table²) within ±4 (12
    comparisons: a false alarm once in ~1,300 runs). A sample started from the wrong
    side, off the tile, or read from the wrong columns of the kernel's outcomes fails."""
    recipe = load(recipe_file)
    table = simulate_recipe(recipe, threads=2)
    rng = np.random.default_rng(7)
    n = 50_000
    with live.LiveSurface(recipe, 2, Tiles(recipe.surface), seed=3, threads=2) as surface:
        for theta in (0, 40, 70, 89):
            wi = np.array([math.sin(math.radians(theta)), 0.0, math.cos(math.radians(theta))])
            wo, w = surface.sample(np.repeat(wi[None], n, axis=0), rng.random((n, 3)))
            escaped = (w > 0).any(axis=1)
            assert np.allclose(np.linalg.norm(wo[escaped], axis=1), 1.0)
            assert (wo[escaped, 2] > 0).all()
            row = list(recipe.simulation.theta_i).index(theta)
            albedo, err = table.albedo[row, 0], table.albedo_err[row, 0]
            z = (w.mean(axis=0) - albedo) / np.hypot(w.std(axis=0) / math.sqrt(n), err)
            assert np.all(np.abs(z) < 4), (theta, z, w.mean(axis=0), albedo)


def test_samples_are_keyed_by_their_uniform_numbers(recipe_file):
    """The same uniform numbers give the same paths (whatever called before), another
    seed other paths (Lambertian facets: the paths draw random numbers of the kernel); a
    direction below the horizon gives no path."""
    recipe = load(recipe_file, ["material.kind=lambertian", "material.albedo=0.5"])
    u = np.random.default_rng(1).random((500, 3))
    wi = np.tile([0.3, 0.2, math.sqrt(1 - 0.13)], (500, 1))
    with live.LiveSurface(recipe, 2, Tiles(recipe.surface), seed=5) as a, \
            live.LiveSurface(recipe, 2, Tiles(recipe.surface), seed=6) as b:
        first = a.sample(wi, u)
        a.sample(wi[:7], u[:7])
        again = a.sample(wi, u)
        other = b.sample(wi, u)
        below = a.sample(wi * [1, 1, -1], u)
    for x, y in zip(first, again, strict=True):
        np.testing.assert_array_equal(x, y)
    assert not np.array_equal(first[0], other[0])
    assert not below[1].any()


def test_the_memory_guard_counts_every_open_realisation(recipe_file, monkeypatch):
    recipe = load(recipe_file)
    faces = 2 * 64 * 64
    monkeypatch.setenv("MICROSIM_MEMORY_LIMIT", str(live.memory_bytes(faces, 3) / 2**30))
    with live.LiveSurface(recipe, 3, Tiles(recipe.surface)):
        pass
    from microsim.errors import InputError
    with pytest.raises(InputError, match="4 open realisations"):
        live.LiveSurface(recipe, 4, Tiles(recipe.surface))


def live_json(cli, recipe_file, tmp_path, *extra):
    code, out, err = cli("render", str(recipe_file), "--live", "-o", str(tmp_path / "l.png"),
                         "--object", "sphere", "--size", "64x48", "--spp", "64",
                         "--variant", "llvm_ad_rgb", *LIGHTS, "--json", *extra)
    assert code == 0, err
    assert (tmp_path / "l.png").stat().st_size > 0
    return json.loads(out)


def test_live_render_agrees_with_its_table(cli, llvm, recipe_file, tmp_path):
    """The live render and the render of the recipe's table agree in mean luminance over
    the lit pixels within 3 standard errors (two-sided, a false alarm once in 370 runs).
    Measured: −0.5% ± 0.8% (z = −0.7)."""
    d = live_json(cli, recipe_file, tmp_path)
    diff = d["difference"]
    assert d["live"]["realisations"] == 2 and d["live"]["samples"] > 50_000
    assert diff["pixels"] > 1000 and 0 < diff["total_err"] < 0.02
    assert abs(diff["total_z"]) < 3, diff


def test_a_wrong_table_is_detected(cli, llvm, recipe_file, tmp_path):
    """The table of the same surface at α = 0.45 instead of 0.3 (a wider, dimmer
    highlight) fails the same test: measured −5.2% ± 0.7% (z = −7.4)."""
    wrong = tmp_path / "wrong.toml"
    wrong.write_text(RECIPE.format(alpha=0.45), encoding="utf-8")
    code, _, err = cli("simulate", str(wrong), "-o", str(tmp_path / "wrong.exr"), "--json")
    assert code == 0, err
    diff = live_json(cli, recipe_file, tmp_path, "--table",
                     str(tmp_path / "wrong.exr"))["difference"]
    assert diff["total_z"] < -3, diff


def test_the_scalar_variant_traces_one_sample_per_call(cli, recipe_file, tmp_path):
    pytest.importorskip("mitsuba")
    code, out, err = cli("render", str(recipe_file), "--live", "-o", str(tmp_path / "s.png"),
                         "--object", "sphere", "--size", "16x12", "--spp", "2", *LIGHTS,
                         "--realisations", "1", "--json")
    assert code == 0, err
    d = json.loads(out)
    assert d["variant"] == "scalar_rgb" and d["live"]["samples"] > 100
    assert math.isfinite(d["difference"]["total"])


def test_a_sun_disc_lights_like_the_directional_sun(recipe_file, tmp_path):
    """A uniform disc of angular radius ρ and radiance E / (π sin²ρ) gives irradiance
    E cos θ on any face that sees all of it (a spherical cap's projected solid angle), so
    a white ``diffuse`` sphere under a 5° disc matches the directional sun of the same E
    but near the terminator: mean luminance over pixels lit by both within 1% (next-event
    estimation of the disc: its render's noise is well under 0.1%)."""
    pytest.importorskip("mitsuba")
    from microsim.render import backend, objects, scene

    mi = backend.load("scalar_rgb")
    sphere, cam = objects.sphere(), scene.Camera(48, 36)
    white = mi.load_dict({"type": "diffuse", "reflectance": {"type": "rgb",
                                                             "value": [1.0, 1.0, 1.0]}})
    sun = {"elevation": 50.0, "azimuth": -40.0, "irradiance": 3.0}
    point = scene.render(mi, sphere, white, cam, [scene.Light("sun", sun | {"radius": 0.0})], 16)
    disc = scene.render(mi, sphere, white, cam, [scene.Light("sun", sun | {"radius": 5.0})], 16)
    lit = (point.alpha > 0.999) & (point.luminance > 0.2 * point.luminance.max())
    ratio = disc.luminance[lit].sum() / point.luminance[lit].sum()
    assert lit.sum() > 300 and abs(ratio - 1) < 0.01, ratio


@pytest.mark.parametrize(("argv", "needle"), [
    (["--live"], "one RECIPE"),
    (["--live", "--model", "beckmann"], "--model"),
    (["--live", "--component", "single"], "--component"),
    (["--live", "--light", "sun"], "radius"),
    (["--live", "--table", "nothere.exr"], "--table"),
    (["--realisations", "2"], "only with --live"),
])
def test_bad_live_input_exits_2(cli, recipe_file, tmp_path, argv, needle):
    first = str(tmp_path / "x.exr") if argv == ["--live"] else str(recipe_file)
    if argv == ["--live"]:
        (tmp_path / "x.exr").write_bytes(b"")
    code, _, err = cli("render", first, "-o", str(tmp_path / "x.png"), *argv)
    assert code == 2 and err.startswith("error: ") and needle in err, err
    assert len(err.strip().splitlines()) == 1


def test_live_refuses_what_does_not_fit_the_memory_guard(cli, recipe_file, tmp_path,
                                                         monkeypatch):
    pytest.importorskip("mitsuba")
    monkeypatch.setenv("MICROSIM_MEMORY_LIMIT", "0.001")
    code, _, err = cli("render", str(recipe_file), "--live", "-o", str(tmp_path / "x.png"),
                       *LIGHTS)
    assert code == 2 and err.startswith("error: ") and "GiB" in err, err


def test_a_render_reports_its_passes():
    """A render of 40 samples per pixel is taken in passes of 16, 16 and 8, each reported
    with the samples done; the image is their mean (its per-pixel error from all 40:
    tests/test_render.py checks that error's calibration)."""
    pytest.importorskip("mitsuba")
    from microsim.render import backend, objects, scene

    mi = backend.load("scalar_rgb")
    white = mi.load_dict({"type": "diffuse", "reflectance": {"type": "rgb",
                                                             "value": [1.0, 1.0, 1.0]}})
    seen: list[tuple[int, int]] = []
    image = scene.render(mi, objects.sphere(), white, scene.Camera(16, 12),
                         [scene.Light("sky", {"radiance": 0.25})], 40, 0,
                         lambda done, total: seen.append((done, total)))
    assert seen == [(16, 40), (32, 40), (40, 40)]
    lit = image.alpha > 0.999
    # a white diffuse convex object under a constant sky of radiance 0.25 reflects 0.25:
    # the lit pixels' mean within 4 standard errors from their own errors
    y, err = image.luminance[lit], image.luminance_err[lit]
    assert abs(y.mean() - 0.25) < 4 * np.sqrt(np.sum(err**2)) / lit.sum(), y.mean()


def test_the_bsdf_turns_the_surface_as_render_rotate_does(recipe_file):
    """The Mitsuba BSDF traces ``R(−ρ) ωi`` and returns ``R(ρ) ωo`` (ρ = ``--rotate``, the
    material's +x turned towards the bitangent), as ``bsdfs.oriented`` turns a table: at
    ρ = 90° a sample equals the surface's own for the turned direction, turned back, and
    its weight is the path's throughput."""
    pytest.importorskip("mitsuba")
    from microsim.render import backend
    from microsim.render.bsdfs import rotation_z

    mi = backend.load("scalar_rgb")
    recipe = load(recipe_file)
    wi = np.array([0.6, 0.0, 0.8])
    with live.LiveSurface(recipe, 2, Tiles(recipe.surface), seed=0) as surface:
        bsdf = live.live_bsdf(mi, surface, 90.0)
        si = mi.SurfaceInteraction3f()
        si.wi = mi.Vector3f(*wi)
        bs, weight = bsdf.sample(mi.BSDFContext(), si, 0.25, mi.Point2f(0.5, 0.75))
        wo, w = surface.sample((rotation_z(-90.0) @ wi)[None], np.array([[0.25, 0.5, 0.75]]))
    np.testing.assert_allclose(np.array(bs.wo), rotation_z(90.0) @ wo[0], atol=1e-6)
    np.testing.assert_allclose(np.array(weight), w[0], rtol=1e-6)
    assert bs.pdf == 1.0 and w[0].max() > 0
