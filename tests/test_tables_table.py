"""The binned estimator, interpolation, merging and the OpenEXR file."""

from __future__ import annotations

import dataclasses
import json
import math
import warnings

import numpy as np
import OpenEXR
import pytest
from tablefixtures import changed, table_of

import microsim
from microsim.errors import InputError, InputWarning
from microsim.geometry import direction
from microsim.surfaces.facts import GaussianFacts, Roughness, SurfaceFacts
from microsim.tables import exr, validation
from microsim.tables.assemble import from_sums, merge
from microsim.tables.binning import HemisphereBins
from microsim.tables.exr import write_table
from microsim.tables.meta import DirectionRecord, TableInput, TableMeta, Timing
from microsim.tables.table import lobe_of

LAMBERT = 1 / np.pi


def lambertian_sums(rng, bins, n, albedo=(1.0, 0.5, 0.25)):
    """Sums a goniophotometer would record for a Lambertian surface: cosine-weighted
    exit directions, each ray carrying the RGB albedo as its weight."""
    u1, u2 = rng.random(n), rng.random(n)
    wo = direction(np.arcsin(np.sqrt(u1)), 2 * np.pi * u2)
    idx = bins.index(wo)
    w = np.broadcast_to(np.asarray(albedo), (n, 3))
    s1 = np.stack([np.bincount(idx, w[:, k], bins.size) for k in range(3)], -1)
    s2 = np.stack([np.bincount(idx, w[:, k] ** 2, bins.size) for k in range(3)], -1)
    return s1, s2


def make_table(seed=1, n=100_000, bins=None, theta_i=(0.0,)):
    rng = np.random.default_rng(seed)
    bins = bins or HemisphereBins(6, 12)
    s = [lambertian_sums(rng, bins, n) for _ in theta_i]
    s1 = np.stack([a for a, _ in s])[:, None]
    s2 = np.stack([b for _, b in s])[:, None]
    rays = np.full((len(theta_i), 1), n)
    return from_sums(bins, np.array(theta_i), np.zeros(1), True, rays,
                               {"total": s1, "single": s1}, {"total": s2, "single": s2},
                               np.zeros((len(theta_i), 1, 3)), TableMeta(seed=seed))


def test_lambertian_estimate_is_unbiased_within_its_errors():
    """z = (f - albedo/pi)/stderr over 72 bins x 3 channels: the mean of 216 unit normals
    lies within 4/sqrt(216) of 0 and their spread within 4/sqrt(2*216) of 1 (4 sigma)."""
    t = make_table()
    truth = np.array([1.0, 0.5, 0.25]) * LAMBERT
    z = ((t["total"].values - truth) / t["total"].errors).ravel()
    assert abs(z.mean()) < 4 / np.sqrt(z.size)
    assert abs(z.std() - 1) < 4 / np.sqrt(2 * z.size)
    np.testing.assert_allclose(t.albedo[0, 0], [1.0, 0.5, 0.25], rtol=1e-12)
    np.testing.assert_allclose(t.albedo_err[0, 0], 0.0, atol=1e-12)  # every ray exits


def test_reported_error_matches_scatter_over_seeds():
    """The stderr predicts the spread of independent estimates: over K = 40 seeds, per
    bin, the ratio of the sample variance of the value to the mean reported variance
    (both unbiased for the true variance, so the ratio's expectation is 1 up to the
    O(1/K) bias of a ratio), averaged over the 72 bins. Its sampling error: each
    per-bin ratio is ~ χ²(39)/39 for Gaussian values, relative spread √(2/39) = 0.23, so
    the mean of 72 has 0.23/√72 = 0.027; the few-count bins near the horizon may spread
    more, so the larger of that and the ratios' own standard error of the mean is used.
    Asserted |ratio − 1| < 4 standard errors (a false alarm with probability 6e-5; the
    old bound was ±0.35); errors too large or small by 15% fail (z ≈ 5)."""
    k = 40
    runs = [make_table(seed=s, n=20_000) for s in range(k)]
    vals = np.stack([t["total"].values[..., 0] for t in runs]).reshape(k, -1)
    errs = np.stack([t["total"].errors[..., 0] for t in runs]).reshape(k, -1)
    ratio = vals.var(axis=0, ddof=1) / (errs**2).mean(axis=0)
    assert ratio.size == 72
    se = max(ratio.std(ddof=1), np.sqrt(2 / (k - 1))) / np.sqrt(ratio.size)
    assert abs(ratio.mean() - 1) < 4 * se, (ratio.mean(), se)


def test_empty_bins_have_undefined_error_and_eval_stays_finite():
    bins = HemisphereBins(4, 4)
    s1 = np.zeros((1, 1, bins.size, 3))
    s1[0, 0, 5] = 10.0
    s2 = np.zeros_like(s1)
    s2[0, 0, 5] = 10.0
    t = from_sums(bins, [0.0], [0.0], True, np.array([[100]]),
                            {"total": s1, "single": s1}, {"total": s2, "single": s2},
                            np.zeros((1, 1, 3)), TableMeta())
    err = t["total"].errors.reshape(-1, 3)
    assert np.isnan(err[0]).all() and np.isfinite(err[5]).all()
    wo = direction(np.linspace(0, np.pi / 2, 50), np.linspace(0, 6, 50))
    f = t.eval(np.array([0.0, 0.0, 1.0]), wo)
    assert np.isfinite(f).all()


def test_eval_at_bin_centres_returns_bin_values_and_is_zero_below_horizon():
    t = make_table(theta_i=(0.0, 0.6))
    b = t.bins
    th, ph = np.meshgrid(b.theta_centers, b.phi_centers, indexing="ij")
    wo = direction(th, ph)
    for k, ti in enumerate(t.theta_i):
        wi = direction(ti, 0.0)
        np.testing.assert_allclose(t.eval(wi, wo), t["total"].values[k, 0], rtol=1e-12)
    below = np.array([0.0, 0.6, -0.8])
    assert np.all(t.eval(direction(0.3, 0.0), below) == 0)
    assert np.all(t.eval(below, direction(0.3, 0.0)) == 0)


def test_eval_interpolates_linearly_in_theta_i():
    t = make_table(theta_i=(0.0, 0.6))
    wo = direction(t.bins.theta_centers[2], t.bins.phi_centers[3])
    mid = t.eval(direction(0.3, 0.0), wo)
    np.testing.assert_allclose(mid, 0.5 * (t["total"].values[0, 0, 2, 3]
                                           + t["total"].values[1, 0, 2, 3]), rtol=1e-12)


def test_isotropic_eval_uses_relative_azimuth():
    t = make_table()
    wo = direction(0.7, 1.0)
    a = t.eval(direction(0.2, 0.4), wo)
    b = t.eval(direction(0.2, 0.0), direction(0.7, 0.6))
    np.testing.assert_allclose(a, b, rtol=1e-12)


def test_merge_equals_one_big_estimate():
    bins = HemisphereBins(3, 4)
    rng = np.random.default_rng(0)
    parts = [lambertian_sums(rng, bins, 1000) for _ in range(2)]

    def table(s1, s2, n):
        return from_sums(bins, [0.0], [0.0], True, np.array([[n]]),
                                   {"total": s1[None, None], "single": s1[None, None]},
                                   {"total": s2[None, None], "single": s2[None, None]},
                                   np.zeros((1, 1, 3)), TableMeta())

    merged = merge(table(*parts[0], 1000), table(*parts[1], 1000))
    whole = table(parts[0][0] + parts[1][0], parts[0][1] + parts[1][1], 2000)
    np.testing.assert_array_equal(merged["total"].values, whole["total"].values)
    np.testing.assert_array_equal(merged["total"].errors, whole["total"].errors)


def test_exr_round_trip(tmp_path):
    t = make_table(theta_i=(0.0, 0.5, 1.2))
    path = tmp_path / "t.exr"
    write_table(t, path)
    r = microsim.read_table(path)
    for c in ("total", "single"):
        np.testing.assert_array_equal(r[c].values, t[c].values.astype(np.float32))
        np.testing.assert_array_equal(r[c].errors, t[c].errors.astype(np.float32))
    np.testing.assert_array_equal(r.albedo, t.albedo)  # exact, through JSON
    np.testing.assert_array_equal(r.theta_i, t.theta_i)
    assert r.meta == TableMeta(seed=1) and r.isotropic
    assert not list(tmp_path.glob(".*tmp"))


def test_file_readable_with_plain_openexr_as_documented(tmp_path):
    """Read the file the way docs/table-format.md tells a reader to, without microsim."""
    t = make_table(theta_i=(0.0, 0.5))
    path = tmp_path / "t.exr"
    write_table(t, path)
    with OpenEXR.File(str(path), separate_channels=True) as f:
        info = json.loads(f.header()["microsim"])
        red = np.array(f.channels()["total.R"].pixels)
    a, b, nt, nphi = info["layout"]["shape"]
    f_r = red.reshape(a, b, nt, nphi)
    theta_o = np.asarray(info["axes"]["theta_o"]["edges"])
    assert f_r.shape == (2, 1, 6, 12) and theta_o.size == 7
    np.testing.assert_array_equal(f_r, t["total"].values[..., 0].astype(np.float32))
    assert info["parameterisation"] == "theta_i,theta_o,phi_o-phi_i"


def test_write_is_atomic(tmp_path, monkeypatch):
    t = make_table()
    path = tmp_path / "t.exr"
    write_table(t, path)
    before = path.read_bytes()

    def fail(self, name):
        with open(name, "wb") as fh:
            fh.write(b"partial")
        raise OSError("disk full")

    monkeypatch.setattr(OpenEXR.File, "write", fail)
    with pytest.raises(OSError, match="disk full"):
        write_table(make_table(seed=2), path)
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.exr"]


def test_bad_files(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        microsim.read_table(tmp_path / "missing.exr")
    junk = tmp_path / "junk.exr"
    junk.write_text("not an image")
    with pytest.raises(InputError, match="not an OpenEXR file"):
        microsim.read_table(junk)
    plain = tmp_path / "plain.exr"
    OpenEXR.File({"type": OpenEXR.scanlineimage},
                 {"R": np.zeros((2, 2), np.float32)}).write(str(plain))
    with pytest.raises(InputError, match="not a microsim table"):
        microsim.read_table(plain)
    assert exr.FORMAT_VERSION == 2 and validation.READ_VERSIONS == (1, 2)


def test_eval_is_continuous_across_bins_and_the_azimuth_seam():
    """Along a fine path crossing every θo bin boundary and φo = 0 = 2π, consecutive f_r
    differ by at most (largest jump between neighbouring nodes) × (step / node spacing):
    piecewise-linear interpolation is Lipschitz with that constant; a jump at a boundary
    would break it by orders of magnitude. The factor 2 absorbs the sin² stretch of u.
    The path's end points are left out: at the pole the azimuth is undefined (f_r is the
    first ring's mean there, test_eval_has_one_value_at_the_pole) and on the horizon f_r
    is 0 by definition."""
    t = make_table()
    b = t.bins
    s = np.linspace(0.0, 1.0, 4001)
    theta = np.arcsin(np.sqrt(s))                         # u = sin²θ from 0 to 1
    phi = -1.0 + 2.0 * s                                  # crosses the seam at s = 0.5
    f = t.eval(direction(0.0, 0.0), direction(theta, phi))[..., 0]
    v = t["total"].values[0, 0, ..., 0]
    jump = max(np.abs(np.diff(v, axis=0)).max(), np.abs(v - np.roll(v, 1, axis=1)).max())
    du, dphi = 1.0 / b.theta_bins, 2 * np.pi / b.phi_bins
    step = max(np.diff(s).max() / du, 2.0 * np.diff(phi).max() / dphi)
    assert np.abs(np.diff(f[1:-1])).max() <= 2 * jump * step


def test_stderr_is_nan_only_where_the_nearest_bin_is_empty():
    bins = HemisphereBins(4, 4)
    s1 = np.zeros((1, 1, bins.size, 3))
    s1[0, 0, 5] = 10.0
    s2 = s1.copy()
    t = from_sums(bins, [0.0], [0.0], True, np.array([[100]]),
                            {"total": s1, "single": s1}, {"total": s2, "single": s2},
                            np.zeros((1, 1, 3)), TableMeta())
    wi = direction(0.0, 0.0)
    it, ip = divmod(5, 4)
    centre = direction(bins.theta_centers[it], bins.phi_centers[ip])
    # inside bin 5 but off its centre: the empty neighbours are left out
    off = direction(np.arcsin(np.sqrt((it + 0.8) / 4)), bins.phi_centers[ip] + 0.3)
    np.testing.assert_allclose(t.stderr(wi, centre), t["total"].errors[0, 0, it, ip])
    np.testing.assert_allclose(t.stderr(wi, off), t["total"].errors[0, 0, it, ip])
    assert np.isnan(t.stderr(wi, direction(0.1, 0.1))).all()      # bin 0 is empty
    assert (t.stderr(wi, np.array([0.6, 0.0, -0.8])) == 0).all()    # below the horizon


def test_from_sums_refuses_bad_input():
    bins = HemisphereBins(2, 2)
    s = np.zeros((1, 1, bins.size, 3))
    with pytest.raises(ValueError, match="rays"):
        from_sums(bins, [0.0], [0.0], True, np.array([[0]]),
                            {"total": s, "single": s}, {"total": s, "single": s},
                            np.zeros((1, 1, 3)), TableMeta())
    with pytest.raises(ValueError, match="shape"):
        from_sums(bins, [0.0], [0.0], True, np.array([[5]]),
                            {"total": s[..., :2, :], "single": s},
                            {"total": s, "single": s}, np.zeros((1, 1, 3)), TableMeta())


def test_attribute_that_is_not_json(tmp_path):
    path = tmp_path / "bad.exr"
    OpenEXR.File({"type": OpenEXR.scanlineimage, "microsim": "{oops"},
                 {"R": np.zeros((2, 2), np.float32)}).write(str(path))
    with pytest.raises(InputError, match="not JSON"):
        microsim.read_table(path)


def test_lobe_of_is_the_fraction_of_each_incidences_peak():
    # two incidences over three bins: a lobe and an empty incidence (no lobe at all)
    f = np.array([[1.0, 0.1, 0.099], [0.0, 0.0, 0.0]])
    lobe = lobe_of(f, -1)
    assert lobe.tolist() == [[True, True, False], [False, False, False]]
    # the bin axes may be any: the same values along axis 0 give the transpose
    assert np.array_equal(lobe_of(f.T, 0), lobe.T)
    assert lobe_of(f, -1, threshold=0.05).tolist()[0] == [True, True, True]


def test_eval_has_one_value_at_the_pole():
    """Towards θo = 0, f_r tends to the mean of the first ring's bins from every azimuth
    (at the pole all azimuths are one direction; clamping kept each bin's own value, the
    star a render shows where it looks straight at a surface, docs/render.md); halfway
    between the pole and the ring's centres in sin²θo it is halfway between that mean and
    the bin; from the ring's centres outwards eval is the bilinear interpolation as before
    (every bin centre returns its bin)."""
    t = make_table(theta_i=(0.0, 0.5))
    b = t.bins
    v = t["total"].values[:, 0]                                    # (2, nt, np, 3)
    assert np.ptp(v[:, 0], axis=1).min() > 0                        # the ring's bins differ
    wi = direction(np.full(b.phi_bins, 0.25), 0.3)
    mean = 0.5 * (v[0, 0] + v[1, 0]).mean(axis=0)                   # θi = 0.25: halfway
    f = t.eval(wi, direction(np.full(b.phi_bins, 1e-6), 0.3 + b.phi_centers))
    np.testing.assert_allclose(f, np.broadcast_to(mean, f.shape), rtol=1e-9)
    half = np.arcsin(np.sqrt(0.5) * np.sin(b.theta_centers[0]))
    f = t.eval(wi, direction(np.full(b.phi_bins, half), 0.3 + b.phi_centers))
    ring = 0.5 * (v[0, 0] + v[1, 0])
    np.testing.assert_allclose(f, 0.5 * ring + 0.5 * mean, rtol=1e-9)
    it, ip = np.meshgrid(np.arange(b.theta_bins), np.arange(b.phi_bins), indexing="ij")
    wo = direction(b.theta_centers[it.ravel()], b.phi_centers[ip.ravel()])
    f = t.eval(direction(np.zeros(len(wo)), 0.0), wo)
    np.testing.assert_allclose(f, v[0].reshape(-1, 3), rtol=1e-9)


def _full_meta():
    """A TableMeta with every field set, none to its default, and every number distinct
    (so that a field written or read under another's key shows)."""
    recipe = microsim.load_recipe({"surface": {"kind": "vgroove", "slope": 30},
                                   "material": {"kind": "mirror"},
                                   "simulation": {"theta_i": [0, 30], "rays": 1000}})
    surface = SurfaceFacts(GaussianFacts(alpha_target=Roughness(0.3),
                                         alpha_realised=Roughness(0.29), sigma=0.5),
                           2, {"alpha_realised": 0.01},
                           ({"seed": 1, "alpha_realised": 0.28},
                            {"seed": 2, "alpha_realised": 0.30}))
    inputs = (TableInput("base", "tables/a.exr", "ab" * 32, "total"),
              TableInput("coat", "b.exr", "cd" * 32, "order1"))
    directions = (
        DirectionRecord(0.0, 0.0, 3000, 2, (1000, 2000), (0.125, 0.25, 0.375),
                        (0.5, 0.625, 0.75), (0.0625, 0.03125, 0.015625),
                        {"escaped": 2900, "bounces": 100}, "target_error", 0.02, 0.7,
                        (0.8, 0.7, 0.6)),
        DirectionRecord(30.0, 45.0, 5000, 3, (1000, 2000, 2000), (1.5, 2.5, 3.5),
                        (4.5, 5.5, 6.5), (7.5, 8.5, 9.5), {"escaped": 5000}, "max_rays",
                        0.04, 0.9, (0.5, 0.4, 0.3)))
    return TableMeta(recipe=recipe, microsim_version="9.8.7", surface=surface,
                     inputs=inputs, seed=17, isotropic=False, error_model="ensemble",
                     realisations=3, directions=directions, stop=("max_rays", "target_error"),
                     segments=123456, batch=4096, offset=1.5e-6,
                     tile_warnings=("tile warned",), warnings=("lost energy", "second"),
                     timing=Timing(12.5, 2.25, 1e5, 3e5),
                     sources={"material.base.data": "Johnson & Christy 1972"})


def test_table_meta_json_has_the_documented_keys_and_reads_back_field_by_field():
    """The ``meta`` entry of a table file (docs/table-format.md) of a TableMeta with every
    field set: exactly these keys with these values, and read back (through a JSON text,
    as a file holds it) every field equal, the records' too."""
    meta = _full_meta()
    out = meta.to_json()
    first, second = meta.directions
    assert out == {
        "recipe": meta.recipe.to_json(), "microsim_version": "9.8.7",
        "surface": meta.surface.to_json(), "seed": 17, "isotropic": False,
        "error_model": "ensemble", "realisations": 3,
        "inputs": [{"part": "base", "path": "tables/a.exr", "sha256": "ab" * 32,
                    "component": "total"},
                   {"part": "coat", "path": "b.exr", "sha256": "cd" * 32,
                    "component": "order1"}],
        "directions": [
            {"theta_i": 0.0, "phi_i": 0.0, "rays": 3000, "realisations": 2,
             "rays_per_realisation": [1000, 2000], "lost": [0.125, 0.25, 0.375],
             "transmitted": [0.5, 0.625, 0.75], "absorbed": [0.0625, 0.03125, 0.015625],
             "fates": {"escaped": 2900, "bounces": 100}, "stop": "target_error",
             "rel_stderr": 0.02, "ray_share": 0.7, "albedo": [0.8, 0.7, 0.6]},
            second.to_json()],
        "stop": ["max_rays", "target_error"], "segments": 123456, "batch": 4096,
        "offset": 1.5e-6, "tile_warnings": ["tile warned"],
        "warnings": ["lost energy", "second"],
        "sources": {"material.base.data": "Johnson & Christy 1972"},
        "wall_time": 12.5, "scene_time": 2.25, "rays_per_second": 1e5,
        "segments_per_second": 3e5}
    assert out["surface"]["alpha_realised_stderr"] == 0.01
    assert out["surface"]["per_realisation"][1] == {"seed": 2, "alpha_realised": 0.30}
    # lists, not tuples: what json writes and reads back
    assert all(type(v) is list for v in (out["stop"], out["tile_warnings"],
                                          out["warnings"], out["inputs"]))
    assert all(type(v) is list for d in out["directions"] for v in (
        d["rays_per_realisation"], d["lost"], d["transmitted"], d["absorbed"], d["albedo"]))
    back = TableMeta.from_json(json.loads(json.dumps(out)))
    for f in dataclasses.fields(TableMeta):
        assert getattr(back, f.name) == getattr(meta, f.name), f.name
    for got, want in zip(back.directions, meta.directions, strict=True):
        for f in dataclasses.fields(want):
            assert getattr(got, f.name) == getattr(want, f.name), f.name
            assert type(getattr(got, f.name)) is type(getattr(want, f.name)), f.name
    assert back == meta and back.directions[0] == first
    assert back.surface.alpha_realised_stderr == Roughness(0.01)


def test_table_meta_json_leaves_out_absent_fields_and_keeps_falsy_ones():
    """Absent (None or empty) fields are left out of the JSON and read back absent; 0,
    False and 0.0 are values, kept; ``inputs`` is written (empty) whenever there is a
    recipe, ``stop`` and ``tile_warnings`` with the directions, ``warnings`` with either
    the directions or warnings of its own."""
    assert TableMeta().to_json() == {}
    assert TableMeta.from_json({}) == TableMeta()
    falsy = TableMeta(seed=0, isotropic=False, realisations=0, segments=0, batch=0,
                      offset=0.0, microsim_version="", error_model="")
    assert falsy.to_json() == {"seed": 0, "isotropic": False, "realisations": 0,
                               "segments": 0, "batch": 0, "offset": 0.0,
                               "microsim_version": "", "error_model": ""}
    assert TableMeta.from_json(falsy.to_json()) == falsy
    full = _full_meta()
    assert TableMeta(recipe=full.recipe).to_json() == {"recipe": full.recipe.to_json(),
                                                       "inputs": []}
    assert TableMeta(inputs=full.inputs).to_json() == {
        "inputs": [i.to_json() for i in full.inputs]}
    assert TableMeta(directions=full.directions[:1]).to_json() == {
        "directions": [full.directions[0].to_json()], "stop": [], "tile_warnings": [],
        "warnings": []}
    assert TableMeta(warnings=("w",), tile_warnings=("t",), stop=("rays",)).to_json() == {
        "warnings": ["w"]}
    assert TableMeta(surface=full.surface).to_json() == {"surface": full.surface.to_json()}
    assert TableMeta(sources={"a": "b"}).to_json() == {"sources": {"a": "b"}}
    assert TableMeta(timing=Timing(1.0, 0.0, 2.0, 3.0)).to_json() == {
        "wall_time": 1.0, "scene_time": 0.0, "rays_per_second": 2.0,
        "segments_per_second": 3.0}
    for meta in (TableMeta(recipe=full.recipe), TableMeta(directions=full.directions),
                 TableMeta(surface=full.surface), TableMeta(timing=full.timing)):
        assert TableMeta.from_json(json.loads(json.dumps(meta.to_json()))) == meta


def test_table_meta_reads_tables_of_earlier_versions():
    """What earlier tables hold: a recipe without materials (read as none), a null
    surface or sources, a wall time without the other timings (NaN), sources as other
    JSON values (as strings), and directions of format 1 — ``rel_error`` for
    ``rel_stderr``, and no realisations, energies, fates, stop, share or albedo (one
    realisation of all the rays, NaN per channel, no fates, stop ``"rays"``)."""
    meta = TableMeta.from_json({"recipe": {"description": "old"}, "surface": None,
                                "sources": None, "wall_time": 4})
    assert meta.recipe is None and meta.surface is None and meta.sources == {}
    assert meta.timing.wall_time == 4.0 and type(meta.timing.wall_time) is float
    assert all(math.isnan(getattr(meta.timing, k)) for k in (
        "scene_time", "rays_per_second", "segments_per_second"))
    assert TableMeta.from_json({"sources": {"k": 1, 2: "v"}}).sources == {"k": "1",
                                                                          "2": "v"}
    assert TableMeta.from_json({"sources": {}}).sources == {}
    old = TableMeta.from_json({"directions": [{"theta_i": 10, "phi_i": 0, "rays": 500.0,
                                               "rel_error": 0.05}]}).directions[0]
    assert (old.theta_i, old.phi_i, old.rays, old.realisations) == (10.0, 0.0, 500, 1)
    assert type(old.theta_i) is float and type(old.rays) is int
    assert old.rays_per_realisation == (500,) and old.fates == {} and old.stop == "rays"
    assert old.rel_stderr == 0.05 and math.isnan(old.ray_share)
    for name in ("lost", "transmitted", "absorbed", "albedo"):
        value = getattr(old, name)
        assert len(value) == 3 and all(math.isnan(v) for v in value), name
    # rel_stderr wins over rel_error; nulls are NaN; no rays: 0 of one realisation
    new = DirectionRecord.from_json({"rel_stderr": 0.5, "rel_error": 0.25,
                                     "theta_i": None, "lost": [None, 1, 2],
                                     "albedo": [0.5, None, 0.25], "ray_share": None})
    assert new.rel_stderr == 0.5 and math.isnan(new.theta_i) and math.isnan(new.phi_i)
    assert math.isnan(new.ray_share) and new.rays == 0 and new.rays_per_realisation == (0,)
    assert math.isnan(new.lost[0]) and new.lost[1:] == (1.0, 2.0)
    assert type(new.lost[1]) is float
    assert new.albedo[::2] == (0.5, 0.25) and math.isnan(new.albedo[1])
    assert math.isnan(DirectionRecord.from_json({}).rel_stderr)


def test_table_input_json_is_its_four_fields_and_refuses_a_missing_one():
    """A TableInput's JSON is exactly part, path, SHA-256 and component, read back equal;
    a record without one of them raises KeyError naming it."""
    record = TableInput("base", "t.exr", "0f" * 32, "order2")
    assert record.to_json() == {"part": "base", "path": "t.exr", "sha256": "0f" * 32,
                                "component": "order2"}
    assert TableInput.from_json(record.to_json()) == record
    for key in ("part", "path", "sha256", "component"):
        data = {k: v for k, v in record.to_json().items() if k != key}
        with pytest.raises(KeyError, match=key):
            TableInput.from_json(data)


def test_table_meta_survives_a_table_file(tmp_path):
    """Written into a table file and read by ``read_table``, a TableMeta with every field
    set is equal to the one written, and the header's ``meta`` is its JSON."""
    t = dataclasses.replace(make_table(n=2000), meta=_full_meta())
    path = tmp_path / "t.exr"
    write_table(t, path)
    assert microsim.read_table(path).meta == t.meta
    with OpenEXR.File(str(path)) as f:
        assert json.loads(f.header()["microsim"])["meta"] == t.meta.to_json()


# --- the table file, key by key and part by part (docs/table-format.md) -------------------
SPECTRAL_NM = (400.0, 552.5, 700.0, 810.0)
SPECTRAL_NAMES = ("400nm", "552p5nm", "700nm", "810nm")  # the decimal point written p
FILE_CASES = {  # isotropic, spectral, harmonics, stored wavelets
    "isotropic RGB": (True, False, False, False),
    "isotropic spectral with harmonics and wavelets": (True, True, True, True),
    "anisotropic RGB with harmonics": (False, False, True, False),
    "anisotropic spectral with wavelets": (False, True, False, True),
}
COMPONENTS = ["total", "order1", "order2", "order3+"]
LINE = "f_r in 1/sr (never times cos theta_o); *_err: standard error, NaN where undefined " \
       "(no ray landed in the bin)"
SH_FUNCTION = "f_r(wi, wo) cos(theta_o) over wo on the whole sphere (0 below the horizon)"
SH_BASIS = ("real orthonormal spherical harmonics, Condon-Shortley phase in P_l^m; "
            "Y_l0 = N P_l^0, Y_lm = sqrt2 N P_l^m cos(m phi), "
            "Y_l,-m = sqrt2 N P_l^m sin(m phi) for m > 0")
OPENEXR_ATTRIBUTES = {"channels", "compression", "dataWindow", "displayWindow", "lineOrder",
                      "pixelAspectRatio", "screenWindowCenter", "screenWindowWidth", "type",
                      "name"}
"""The attributes OpenEXR writes in every part of a file (``chunkCount`` too in a
multi-part file), beside which a table's part holds only its JSON attribute."""


def file_table(isotropic: bool, spectral: bool, harmonics: bool, stored: bool):
    """A table with every field of the file set and every number distinct (drawn at
    random): three incidences, one φi (isotropic) or two, 3 × 4 bins, RGB or four
    wavelengths, an ensemble's error model with realisations, dof and inflation (one
    inflation null: not pooled), harmonics of order 2 and wavelets kept on 8² pixels."""
    from microsim.spectra.channels import Channels
    from microsim.tables import wavelets
    from microsim.tables.components import components_for

    rng = np.random.default_rng(23)
    bins = HemisphereBins(3, 4)
    theta_i = np.array([0.0, 0.4, 1.1])
    phi_i = np.zeros(1) if isotropic else np.array([0.0, 2.0])
    channels = Channels(SPECTRAL_NM) if spectral else Channels()
    a, b, n = len(theta_i), len(phi_i), channels.count

    def per(shape, low, high):
        return {c: rng.uniform(low, high, shape) for c in components_for(3)}

    values = per((a, b, 3, 4, n), 0.1, 2.0)
    inflation = per((a, b, n), 1.0, 3.0)
    inflation["order2"][1, 0, 0] = np.nan
    return table_of(
        bins, theta_i, phi_i, isotropic, values, per((a, b, 3, 4, n), 0.01, 0.1),
        rng.integers(100, 1000, (a, b)), per((a, b, n), 0.2, 0.9), per((a, b, n), 1e-3, 0.01),
        rng.uniform(0.0, 0.01, (a, b, n)), TableMeta(seed=29), error_model="ensemble",
        realisations=rng.integers(2, 9, (a, b)), dof=per((a, b, n), 1.0, 40.0),
        inflation=inflation,
        sh={c: rng.normal(size=(a, b, 9, n)) for c in components_for(3)} if harmonics else None,
        sh_err=per((a, b, 9, n), 1e-3, 0.01) if harmonics else None,
        wavelets=wavelets.encode(values, bins, 8, "haar", keep=5, channels=channels.names)
        if stored else None, channels=channels)


def listed(x) -> list:
    """An array as the header's JSON holds it: nested lists, NaN as null."""
    x = np.asarray(x)
    if x.dtype.kind != "f":
        return x.tolist()
    out = x.astype(object)
    out[np.isnan(x)] = None
    return out.tolist()


def documented_headers(t) -> tuple[dict, dict | None]:
    """The ``microsim`` and ``microsim_sh`` attributes docs/table-format.md describes for
    the ``file_table`` ``t``, written out key by key (the bin edges apart: compared to
    their formulas separately)."""
    names = SPECTRAL_NAMES if t.channels.spectral else ("R", "G", "B")
    channels = [f"{c}{s}.{k}" for c in COMPONENTS for s in ("", "_err") for k in names]
    a, b = len(t.theta_i), len(t.phi_i)
    header = {
        "format_version": 2,
        "parameterisation": ("theta_i,theta_o,phi_o-phi_i" if t.isotropic
                             else "theta_i,phi_i,theta_o,phi_o"),
        "isotropic": t.isotropic,
        "axes": {"theta_i": {"values": listed(t.theta_i), "unit": "rad"},
                 "phi_i": {"values": listed(t.phi_i), "unit": "rad"},
                 "theta_o": {"unit": "rad", "spacing": "uniform in sin^2(theta_o)"},
                 "phi_o": {"unit": "rad", "folded": False}},
        "layout": {"rows": ["theta_i", "phi_i", "theta_o"], "columns": ["phi_o"],
                   "shape": [a, b, 3, 4],
                   "row": "(i_theta_i * n_phi_i + i_phi_i) * n_theta_o + i_theta_o",
                   "channels": channels, "value": LINE},
        "components": COMPONENTS, "orders": 3,
        "rays": listed(t.rays),
        "albedo": listed(t["total"].albedo), "albedo_err": listed(t["total"].albedo_err),
        "order_albedo": {c: listed(t[c].albedo) for c in COMPONENTS[1:]},
        "order_albedo_err": {c: listed(t[c].albedo_err) for c in COMPONENTS[1:]},
        "lost_energy": listed(t.lost_energy),
        "error_model": "ensemble",
        "realisations": listed(t.realisations),
        "dof": {c: listed(t[c].dof) for c in COMPONENTS},
        "inflation": {c: listed(t[c].inflation) for c in COMPONENTS},
        "meta": {"seed": 29},
    }
    if t.channels.spectral:
        header["wavelengths"] = list(SPECTRAL_NM)
    sh = None if not t.has_sh else {
        "order": 2, "coefficients": 9, "function": SH_FUNCTION, "basis": SH_BASIS,
        "index": "l * l + l + m", "azimuth": "phi_o - phi_i" if t.isotropic else "phi_o",
        "rows": "i_theta_i * n_phi_i + i_phi_i", "shape": [a, b], "channels": channels,
        "value": "*_err: standard error of the coefficient"}
    return header, sh


def parts_of(path) -> list[tuple[str, dict, dict]]:
    """(name, header, channels) of every part of an OpenEXR file."""
    with OpenEXR.File(str(path), separate_channels=True) as f:
        return [(p.name(), dict(p.header), {k: np.array(c.pixels) for k, c in p.channels.items()})
                for p in f.parts]


@pytest.mark.parametrize("case", sorted(FILE_CASES))
def test_the_headers_of_a_table_file_are_the_documented_json(tmp_path, case):
    """The ``microsim`` attribute of part 0 and the ``microsim_sh`` attribute of the ``sh``
    part, read with OpenEXR alone, are exactly the JSON docs/table-format.md lists: every
    key, the fixed strings (units, spacing, layout, parameterisation, the harmonics'
    function, basis, index, azimuth), the channel names in the documented order, a
    spectral table's wavelengths (absent for RGB), every number exact (float64; NaN as
    null), and nothing more; the θo edges are arcsin √(k / theta_bins) and the φo edges
    uniform over [0, 2π), to 1e-15 rad (float64 round-off of the formulas)."""
    t = file_table(*FILE_CASES[case])
    path = tmp_path / "t.exr"
    write_table(t, path)
    parts = {name: header for name, header, _ in parts_of(path)}
    info = json.loads(parts["table"]["microsim"])
    theta_o = info["axes"]["theta_o"].pop("edges")
    phi_o = info["axes"]["phi_o"].pop("edges")
    np.testing.assert_allclose(theta_o, np.arcsin(np.sqrt(np.arange(4) / 3)), rtol=0,
                               atol=1e-15)
    np.testing.assert_allclose(phi_o, 2 * np.pi * np.arange(5) / 4, rtol=0, atol=1e-15)
    header, sh = documented_headers(t)
    assert info == header
    if not t.channels.spectral:
        assert info["layout"]["channels"][:7] == ["total.R", "total.G", "total.B", "total_err.R",
                                                  "total_err.G", "total_err.B", "order1.R"]
    assert ("sh" in parts) == (sh is not None)
    if sh is not None:
        assert json.loads(parts["sh"]["microsim_sh"]) == sh


@pytest.mark.parametrize("case", sorted(FILE_CASES))
def test_every_field_of_a_table_survives_its_file(tmp_path, case):
    """``read_table`` gives back every field written: the axes and bins, the channels (a
    spectral table's wavelengths), values, errors and harmonics to float32, rays, albedos,
    lost energy, error model, realisations, dof and inflation exactly (NaN where not
    pooled), the metadata, and the stored wavelets (values to float32, indices exact);
    and it reads the whole file without a warning (a multi-part file of bins and wavelets
    alone has no harmonics to miss)."""
    t = file_table(*FILE_CASES[case])
    path = tmp_path / "t.exr"
    write_table(t, path)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        r = microsim.read_table(path)
    assert [str(w.message) for w in caught] == []
    assert (r.bins.theta_bins, r.bins.phi_bins, r.bins.folded) == (3, 4, False)
    np.testing.assert_array_equal(r.theta_i, t.theta_i)
    np.testing.assert_array_equal(r.phi_i, t.phi_i)
    assert r.isotropic == t.isotropic and r.components == tuple(COMPONENTS)
    assert r.channels == t.channels and r.error_model == "ensemble" and r.meta == t.meta
    np.testing.assert_array_equal(r.rays, t.rays)
    np.testing.assert_array_equal(r.realisations, t.realisations)
    np.testing.assert_array_equal(r.lost_energy, t.lost_energy)
    for c in COMPONENTS:
        for field in ("values", "errors"):
            np.testing.assert_array_equal(getattr(r[c], field),
                                          getattr(t[c], field).astype(np.float32))
        for field in ("albedo", "albedo_err", "dof", "inflation"):
            np.testing.assert_array_equal(getattr(r[c], field), getattr(t[c], field))
        assert (r[c].sh is None) == (t[c].sh is None)
        assert (r[c].sh_err is None) == (t[c].sh_err is None)
    assert np.isnan(r["order2"].inflation[1, 0, 0])
    if t.has_sh:
        assert r.sh_order == 2
        for c in COMPONENTS:
            np.testing.assert_array_equal(r[c].sh, t[c].sh.astype(np.float32))
            np.testing.assert_array_equal(r[c].sh_err, t[c].sh_err.astype(np.float32))
    assert (r.wavelets is None) == (t.wavelets is None)
    if t.wavelets is not None:
        w, v = r.wavelets, t.wavelets
        assert (w.wavelet, w.resolution, w.keep, w.channels) == ("haar", 8, 5, v.channels)
        for c in COMPONENTS:
            np.testing.assert_array_equal(w.values[c], v.values[c].astype(np.float32))
            np.testing.assert_array_equal(w.indices[c], v.indices[c])


@pytest.mark.parametrize("case", sorted(FILE_CASES))
def test_a_table_file_has_the_documented_parts(tmp_path, case):
    """Part 0 is named ``table``, then ``sh`` with harmonics and ``wavelet`` with stored
    wavelets; a file of the bins alone is a single-part file (the multi-part bit of the
    version field unset). Every part is a ZIP-compressed scanline image whose attributes
    are OpenEXR's own and its one JSON attribute; every part has part 0's display window,
    which is its data window: φo bins wide, n_theta_i · n_phi_i · theta_bins rows."""
    t = file_table(*FILE_CASES[case])
    path = tmp_path / "t.exr"
    write_table(t, path)
    parts = parts_of(path)
    names = ["table"] + ["sh"] * t.has_sh + ["wavelet"] * (t.wavelets is not None)
    assert [name for name, _, _ in parts] == names
    multi = int.from_bytes(path.read_bytes()[4:8], "little") & 0x1000
    assert bool(multi) == (len(names) > 1)
    attribute = {"table": "microsim", "sh": "microsim_sh", "wavelet": "microsim_wavelet"}
    rows = len(t.theta_i) * len(t.phi_i) * 3
    for name, header, _ in parts:
        assert set(header) == OPENEXR_ATTRIBUTES | {attribute[name]} | (
            {"chunkCount"} if multi else set()), (name, sorted(header))
        assert header["compression"] == OpenEXR.ZIP_COMPRESSION
        assert header["type"] == OpenEXR.scanlineimage
        window = [w.tolist() for w in header["displayWindow"]]
        assert window == [[0, 0], [3, rows - 1]], name
    assert [w.tolist() for w in parts[0][1]["dataWindow"]] == [[0, 0], [3, rows - 1]]


def test_harmonics_without_their_errors_are_not_written(tmp_path):
    """The ``sh`` part needs every coefficient's error: a table holding coefficients but no
    errors is written as the single-part file of its bins, read back without harmonics."""
    t = file_table(True, False, True, False)
    t = changed(t, sh_err=lambda e: None)
    path = tmp_path / "t.exr"
    write_table(t, path)
    assert [name for name, _, _ in parts_of(path)] == ["table"]
    r = microsim.read_table(path)
    assert not r.has_sh and r.sh_order == 0
    np.testing.assert_array_equal(r["order1"].values, t["order1"].values.astype(np.float32))


def test_harmonics_that_read_table_would_refuse_are_not_written(tmp_path):
    """A coefficient that is not finite is refused with the file and the channel that
    holds it (docs/table-format.md: ``not written``), and nothing is written."""
    t = file_table(False, False, True, False)
    t["order1"].sh[1, 1, 4, 1] = np.nan
    path = tmp_path / "t.exr"
    with pytest.raises(InputError) as info:
        write_table(t, path)
    assert str(info.value).startswith(f"{path}: not written: harmonics channel order1.G holds "
                                      "nan at row 3, column 4"), str(info.value)
    assert not path.exists()


# --- damaged and edited files: the messages a user reads ---------------------------------
def first_chunks(data: bytes) -> list[int]:
    """The offset of the first chunk of each part of a multi-part OpenEXR file, from its
    layout (OpenEXR's file layout: the magic number and version, then each part's header —
    attributes ``name\\0type\\0`` int32 size, value — ended by a null byte, one more null
    byte after the last header, then each part's offset table of ``chunkCount`` uint64)."""
    pos, counts = 8, []
    while data[pos] != 0:
        count = 0
        while data[pos] != 0:
            name_end = data.index(b"\0", pos)
            type_end = data.index(b"\0", name_end + 1)
            size = int.from_bytes(data[type_end + 1:type_end + 5], "little")
            if data[pos:name_end] == b"chunkCount":
                count = int.from_bytes(data[type_end + 5:type_end + 9], "little")
            pos = type_end + 5 + size
        counts.append(count)
        pos += 1
    pos += 1
    firsts = []
    for count in counts:
        firsts.append(int.from_bytes(data[pos:pos + 8], "little"))
        pos += 8 * count
    return firsts


def test_a_damaged_file_is_one_message_naming_it(tmp_path):
    """A file whose header is cut, a single-part file whose bins are cut and a two-part
    file whose bins are corrupt (its harmonics intact) are each refused with the file's
    name and what cannot be read (docs/table-format.md: one ``error:`` line naming the
    file)."""
    single = tmp_path / "single.exr"
    write_table(file_table(True, False, False, False), single)
    data = single.read_bytes()
    damaged = "damaged (truncated or corrupt) OpenEXR file"
    header_cut = tmp_path / "header-cut.exr"
    header_cut.write_bytes(data[:16])
    bins_cut = tmp_path / "bins-cut.exr"
    bins_cut.write_bytes(data[:-1])
    double = tmp_path / "double.exr"
    write_table(file_table(True, False, True, False), double)
    corrupt = bytearray(double.read_bytes())
    bins = first_chunks(bytes(corrupt))[0]
    corrupt[bins + 8:bins + 12] = (2**31 - 1).to_bytes(4, "little")  # part 0's chunk size
    bins_corrupt = tmp_path / "bins-corrupt.exr"
    bins_corrupt.write_bytes(bytes(corrupt))
    for path, what in ((header_cut, "its header cannot be read"),
                       (bins_cut, "the bins cannot be read"),
                       (bins_corrupt, "the bins cannot be read")):
        with pytest.raises(InputError) as info:
            microsim.read_table(path)
        assert str(info.value) == f"{path}: {damaged}: {what}"


def test_damaged_harmonics_are_a_warning_or_with_require_sh_an_error(tmp_path):
    """A two-part file cut inside its harmonics reads as its bins with one
    ``InputWarning`` naming the file and the damaged part, attributed to the caller of
    ``exr.read_table`` (docs/table-format.md: a ``warning:`` line); with ``require_sh`` the
    same words are the error."""
    t = file_table(True, False, True, False)
    whole = tmp_path / "t.exr"
    write_table(t, whole)
    data = whole.read_bytes()
    path = tmp_path / "cut.exr"
    path.write_bytes(data[:first_chunks(data)[1] + 16])
    message = (f"{path}: damaged (truncated or corrupt) OpenEXR file: its "
               "spherical-harmonics part cannot be read (the bins can)")
    with pytest.warns(InputWarning) as caught:
        r = exr.read_table(path)
    assert [str(w.message) for w in caught] == [f"{message}; reading the bins only"]
    assert [type(w.message) for w in caught] == [InputWarning]
    assert caught[0].filename == __file__
    assert not r.has_sh
    np.testing.assert_array_equal(r["total"].values, t["total"].values.astype(np.float32))
    with pytest.raises(InputError) as info:
        exr.read_table(path, require_sh=True)
    assert str(info.value) == message


def rewritten(source, target, edit):
    """``source`` written again to ``target``, each part's (name, header, channels) handed
    to ``edit`` first (the header with its compression, type, display window and JSON)."""
    keep = ("compression", "type", "displayWindow", "microsim", "microsim_sh",
            "microsim_wavelet")
    parts = []
    for name, header, channels in parts_of(source):
        header = {k: v for k, v in header.items() if k in keep}
        edit(name, header, channels)
        parts.append(OpenEXR.Part(header, channels, name))
    OpenEXR.File(parts).write(str(target))
    return target


@pytest.mark.parametrize("attribute", ["microsim", "microsim_sh", "microsim_wavelet"])
def test_a_json_attribute_that_does_not_parse_is_one_message(tmp_path, attribute):
    """Each JSON attribute of a table file that is not JSON is refused naming the file and
    the attribute, with what this microsim reads."""
    source = tmp_path / "t.exr"
    write_table(file_table(True, True, True, True), source)

    def edit(name, header, channels):
        if attribute in header:
            header[attribute] = "{oops"

    path = rewritten(source, tmp_path / "edited.exr", edit)
    with pytest.raises(InputError) as info:
        microsim.read_table(path)
    assert str(info.value) == (f"{path}: the '{attribute}' attribute is not JSON that this "
                               "microsim reads (malformed, nested too deeply or with a number "
                               "too long)")


def test_a_bad_harmonics_or_wavelet_part_is_refused_naming_the_file(tmp_path):
    """The ``sh`` part's header and pixels and the ``wavelet`` part are checked like the
    bins: each refusal names the file, then the key or channel."""
    source = tmp_path / "t.exr"
    write_table(file_table(True, True, True, True), source)

    def sh_header(name, header, channels):
        if name == "sh":
            info = json.loads(header["microsim_sh"])
            info["coefficients"] = 10
            header["microsim_sh"] = json.dumps(info)

    def sh_pixel(name, header, channels):
        if name == "sh":
            channels["order2.552p5nm"][2, 3] = np.inf

    def wavelet_header(name, header, channels):
        if name == "wavelet":
            info = json.loads(header["microsim_wavelet"])
            info["levels"] = 1
            header["microsim_wavelet"] = json.dumps(info)

    for edit, start in ((sh_header, "header sh.coefficients = 10: must be 9"),
                        (sh_pixel, "harmonics channel order2.552p5nm holds inf at row 2, "
                                   "column 3"),
                        (wavelet_header, "wavelet part: mode ")):
        path = rewritten(source, tmp_path / "edited.exr", edit)
        with pytest.raises(InputError) as info:
            microsim.read_table(path)
        assert str(info.value).startswith(f"{path}: {start}"), str(info.value)
