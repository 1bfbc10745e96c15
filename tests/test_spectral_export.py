"""Exports and renders of spectral tables: the RGL file in Mitsuba 3's spectral layout
(loaded and evaluated per wavelength by Mitsuba itself), its ``rgb`` field and MERL as the
table's linear sRGB, npz with every channel, spectral render variants, RGB upsampling and
a gold sphere that looks gold (docs/table-format.md, docs/render.md)."""

from __future__ import annotations

import json
import struct

import numpy as np
import pytest

import microsim
from microsim.analytic.brdf import Lambertian, TorranceSparrow
from microsim.analytic.fresnel import ConductorFresnel, fresnel_conductor
from microsim.analytic.ndf import Beckmann
from microsim.geometry import direction
from microsim.spectra import measured
from microsim.spectra.colour import to_srgb_display, to_srgb_linear
from microsim.tables.export import LUMINANCE, rgl_through_mitsuba
from microsim.tables.exr import write_table

mitsuba = pytest.importorskip("mitsuba")

NM = [400.0, 450.0, 500.0, 550.0, 600.0, 650.0, 700.0]
"""Seven wavelengths across the visible, nm."""
RECIPE = {"surface": {"kind": "gaussian", "alpha": 0.4, "resolution": 32},
          "table": {"theta_bins": 8, "phi_bins": 16, "sh_order": 2},
          "simulation": {"theta_i": [0, 30, 60], "rays": 20_000}}


@pytest.fixture(scope="module")
def gold():
    """A rough gold table of 7 wavelengths (shipped Johnson & Christy indices), ~1 s."""
    return microsim.simulate(microsim.load_recipe({
        **RECIPE, "material": {"kind": "conductor", "data": "Au"},
        "table": {**RECIPE["table"], "wavelengths": NM}}), threads=1)


@pytest.fixture(scope="module")
def gold_file(gold, tmp_path_factory):
    path = tmp_path_factory.mktemp("spectral") / "gold.exr"
    write_table(gold, path)
    return path


@pytest.fixture(scope="module")
def rgb_file(tmp_path_factory):
    table = microsim.simulate(microsim.load_recipe({
        **RECIPE, "material": {"kind": "conductor", "eta": [0.2, 0.92, 1.1],
                               "k": [3.9, 2.45, 2.14]}}), threads=1)
    path = tmp_path_factory.mktemp("rgb") / "rgb.exr"
    write_table(table, path)
    return path


@pytest.fixture(autouse=True)
def _keep_variant():
    """Mitsuba's variant is global: leave it as the test found it."""
    before = mitsuba.variant()
    yield
    if before is not None:
        mitsuba.set_variant(before)


def read_tensor(path):
    """An RGL tensor file read from its published layout (Mitsuba 3,
    ``TensorFile``): "tensor_file\\0", version u8 u8, u32 field count, per field u16 name
    length, name, u16 rank, u8 type (1 u8, 10 f32), u64 offset, rank × u64 shape."""
    raw = path.read_bytes()
    assert raw[:12] == b"tensor_file\0"
    (count,) = struct.unpack_from("<I", raw, 14)
    pos, fields = 18, {}
    for _ in range(count):
        (n,) = struct.unpack_from("<H", raw, pos)
        name = raw[pos + 2:pos + 2 + n].decode()
        rank, dtype, offset = struct.unpack_from("<HBQ", raw, pos + 2 + n)
        shape = struct.unpack_from(f"<{rank}Q", raw, pos + 2 + n + 11)
        pos += 2 + n + 11 + 8 * rank
        dt = {1: np.uint8, 10: np.float32}[dtype]
        size = int(np.prod(shape)) * np.dtype(dt).itemsize
        fields[name] = np.frombuffer(raw[offset:offset + size], dt).reshape(shape)
    return fields


def srgb(nm, values):
    """The reference colour conversion: colour-science's linear sRGB, negatives 0."""
    return np.maximum(to_srgb_linear(nm, values), 0.0)


# --- the RGL file ------------------------------------------------------------------------
def test_spectral_rgl_matches_the_table_per_wavelength_in_mitsuba(cli, gold, gold_file,
                                                                  tmp_path):
    """Mitsuba 3's ``measured`` in ``scalar_spectral`` loads the spectral export; its eval
    (cos θo included), asked at chosen ``si.wavelengths``, is within 1% (median over 150
    direction pairs in the lobe) of the table's f_r cos θo at each of its wavelengths, and
    at wavelengths between and beyond them of the table's channels interpolated linearly
    and held at the ends (what the plugin's lookup does). Reason for 1%: the table is
    bilinear in bins of (sin²θo, φo), the file bilinear on a 64² half-vector grid
    resampled from it; measured 0.21–0.24% per wavelength (p90 5%, at the lobe's kinks)."""
    out = tmp_path / "gold.bsdf"
    assert cli("export", str(gold_file), "--format", "rgl", "-o", str(out),
               "--resolution", "64")[0] == 0
    table = microsim.read_table(gold_file)
    ref, got = rgl_through_mitsuba(table, out, 150, np.random.default_rng(3),
                                   variant="scalar_spectral")
    assert ref.shape == (150, len(NM))
    median = np.median(np.abs(got / ref - 1), axis=0)
    assert np.all(median < 0.01), median
    # the wavelengths are the channels: gold reflects red more than blue
    assert np.median(got[:, -1] / got[:, 0]) > 1.5
    between = [380.0, 425.0, 575.0, 690.0, 760.0]
    ref, got = rgl_through_mitsuba(table, out, 60, np.random.default_rng(4),
                                   variant="scalar_spectral", wavelengths=between)
    median = np.median(np.abs(got / ref - 1), axis=0)
    assert np.all(median < 0.01), median


def test_spectral_rgl_layout(cli, gold_file, tmp_path):
    """The file as Mitsuba 3's measured.cpp reads a spectral one: ``wavelengths`` (f32,
    nm), ``spectra`` (f32 [n_phi_i, n_theta_i, n_wavelengths, H, H], the last two axes φm
    and θm of the vertex grid u = 0…1, θm = u² π/2, φm = 2πu − π from φi) holding
    f_r cos θo at the mirror direction of ωi about m, computed here from the table at
    sample vertices; ``rgb`` is colour-science's linear sRGB of the spectra (negatives 0)
    and ``luminance`` positive; float32 round-off (1e-6 relative) is the tolerance."""
    out = tmp_path / "gold.bsdf"
    assert cli("export", str(gold_file), "--format", "rgl", "-o", str(out),
               "--resolution", "16")[0] == 0
    table = microsim.read_table(gold_file)
    f = read_tensor(out)
    h = 16
    assert f["wavelengths"].dtype == np.float32
    np.testing.assert_array_equal(f["wavelengths"], NM)
    assert f["spectra"].shape == (1, 3, len(NM), h, h)
    assert f["rgb"].shape == (1, 3, 3, h, h) and f["luminance"].shape == (1, 3, h, h)
    np.testing.assert_array_equal(f["theta_i"], np.float32(table.theta_i))
    rng = np.random.default_rng(0)
    for a, i, j in zip(rng.integers(0, 3, 20), rng.integers(0, h, 20), rng.integers(0, h, 20),
                       strict=True):
        u_phi, u_theta = i / (h - 1), j / (h - 1)
        m = direction(u_theta**2 * np.pi / 2, 2 * np.pi * u_phi - np.pi)
        wi = direction(table.theta_i[a], 0.0)
        wo = 2 * (m @ wi) * m - wi
        expected = table.eval(wi, wo) * max(wo[2], 0.0)
        np.testing.assert_allclose(f["spectra"][0, a, :, i, j], expected, rtol=1e-6,
                                   atol=1e-7)
    spectra = np.moveaxis(f["spectra"].astype(float), 2, -1)
    np.testing.assert_allclose(np.moveaxis(f["rgb"], 2, -1), srgb(NM, spectra), rtol=1e-5,
                               atol=1e-7)
    assert np.all(f["luminance"] > 0)


def test_rgb_file_of_a_spectral_table_loads_in_rgb_variants(cli, gold_file, tmp_path):
    """Mitsuba 3's RGB variants refuse a file that has ``wavelengths`` (measured.cpp), so
    ``--rgb`` writes an RGB file of the table's linear sRGB: no spectral fields, its
    ``rgb`` the spectral file's, and ``scalar_rgb`` evaluates it within 1% (median) of the
    sRGB of the table's f_r cos θo (same reason as the spectral file's 1%)."""
    spectral, rgb = tmp_path / "s.bsdf", tmp_path / "rgb.bsdf"
    for out, flags in ((spectral, []), (rgb, ["--rgb"])):
        code, _, err = cli("export", str(gold_file), "--format", "rgl", "-o", str(out),
                           "--resolution", "64", *flags)
        assert code == 0, err
    fields, other = read_tensor(rgb), read_tensor(spectral)
    assert "wavelengths" not in fields and "spectra" not in fields
    np.testing.assert_array_equal(fields["rgb"], other["rgb"])
    table = microsim.read_table(gold_file)
    ref, got = rgl_through_mitsuba(table, rgb, 100, np.random.default_rng(5))
    assert np.all(np.median(np.abs(got / ref - 1), axis=0) < 0.01)
    mitsuba.set_variant("scalar_rgb")
    with pytest.raises(RuntimeError, match="spectral variant"):
        mitsuba.load_dict({"type": "measured", "filename": str(spectral)})


def test_an_rgb_tables_rgl_file_keeps_its_fields(cli, rgb_file, tmp_path):
    """An RGB table's file has the nine fields it always had, in their order (the bytes
    are unchanged: checked against files written before spectral tables)."""
    out = tmp_path / "rgb.bsdf"
    assert cli("export", str(rgb_file), "--format", "rgl", "-o", str(out), "--rgb")[0] == 0
    assert list(read_tensor(out)) == ["description", "jacobian", "theta_i", "phi_i", "ndf",
                                      "sigma", "vndf", "luminance", "rgb"]


def test_srgb_of_an_out_of_gamut_spectrum_clips_its_negative_channel():
    """A spectrum peaked at 500 nm lies outside the sRGB gamut (colour-science gives it a
    negative red); the exports' conversion sets that channel to 0 and keeps the others."""
    from microsim.tables.export import srgb_linear

    nm, v = [480.0, 500.0, 520.0], np.array([[0.0, 1.0, 0.0], [0.2, 0.5, 0.9]])
    exact = to_srgb_linear(nm, v)
    assert exact[0, 0] < -0.1 and np.all(exact[1] > 0)
    got = srgb_linear(nm, v)
    assert got[0, 0] == 0.0
    np.testing.assert_array_equal(got[0, 1:], exact[0, 1:])
    np.testing.assert_array_equal(got[1], exact[1])


# --- npz and MERL ------------------------------------------------------------------------
def test_npz_round_trip_keeps_every_channel(cli, gold_file, rgb_file, tmp_path):
    """Every component's values, errors, albedo and harmonics come back with all seven
    channels, with the wavelengths and channel names; an RGB table's file has neither
    key."""
    out = tmp_path / "g.npz"
    assert cli("export", str(gold_file), "--format", "npz", "-o", str(out))[0] == 0
    data = np.load(out)
    table = microsim.read_table(gold_file)
    np.testing.assert_array_equal(data["wavelengths"], NM)
    assert list(data["channels"]) == ["400nm", "450nm", "500nm", "550nm", "600nm", "650nm",
                                      "700nm"]
    for c in table.components:
        assert data[c].shape[-1] == len(NM)
        np.testing.assert_array_equal(data[c], table[c].values)
        np.testing.assert_array_equal(data[f"{c}_err"], table[c].errors)
        np.testing.assert_array_equal(data[f"albedo_{c}"], table[c].albedo)
        np.testing.assert_array_equal(data[f"sh_{c}"], table[c].sh)
    np.testing.assert_array_equal(data["lost_energy"], table.lost_energy)
    assert json.loads(str(data["meta"]))["recipe"]["table"]["wavelengths"] == NM
    rgb = tmp_path / "r.npz"
    assert cli("export", str(rgb_file), "--format", "npz", "-o", str(rgb))[0] == 0
    assert "wavelengths" not in np.load(rgb) and "channels" not in np.load(rgb)


def test_merl_of_a_spectral_table_is_its_linear_srgb(cli, gold_file, tmp_path):
    """300 random MERL cells (read from the published layout, directions by explicit
    rotations) hold colour-science's linear sRGB of the table's f_r there, to float64
    round-off."""
    out = tmp_path / "g.binary"
    assert cli("export", str(gold_file), "--format", "merl", "-o", str(out))[0] == 0
    raw = out.read_bytes()
    dims = struct.unpack("<3i", raw[:12])
    data = np.frombuffer(raw[12:], "<f8").reshape(3, *dims) * np.array(
        [1.0, 1.15, 1.66])[:, None, None, None] / 1500.0
    rng = np.random.default_rng(6)
    i, j, k = (rng.integers(0, n, 300) for n in dims)
    th, td, pd = (i / 90.0) ** 2 * np.pi / 2, j / 90.0 * np.pi / 2, k / 180.0 * np.pi
    d = np.stack([np.sin(td) * np.cos(pd), np.sin(td) * np.sin(pd), np.cos(td)], -1)
    c, s = np.cos(th), np.sin(th)
    rot = np.array([[c, 0 * c, s], [0 * c, 1 + 0 * c, 0 * c], [-s, 0 * c, c]]).transpose(2, 0, 1)
    wi = np.einsum("nij,nj->ni", rot, d)
    wo = np.einsum("nij,nj->ni", rot, d * [-1, -1, 1])
    above = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    table = microsim.read_table(gold_file)
    expected = srgb(NM, table.eval(wi[above], wo[above]))
    np.testing.assert_allclose(data[:, i, j, k].T[above], expected, rtol=1e-12, atol=1e-15)
    assert above.sum() > 100


# --- upsampling and per-wavelength plugins -----------------------------------------------
def test_upsampled_rgb_comes_back_as_its_colour():
    """Mitsuba's RGB upsampling as the renderer tabulates it (every 5 nm, scaled by twice
    the largest channel): 500 random colours of any brightness come back through
    colour-science's CIE 1931 / D65 integration within 0.2% of their largest channel
    (Jakob & Hanika's model reproduces sRGB to ~0.1%, measured 0.08% max), and the
    spectrum equals Mitsuba's own ``srgb_model_eval`` to float32 precision."""
    from microsim.render import spectral

    mitsuba.set_variant("scalar_spectral")
    rng = np.random.default_rng(1)
    rgb = rng.uniform(0, 1, (500, 3)) * rng.uniform(0.01, 30, (500, 1))
    s = spectral.upsample(mitsuba, rgb)
    back = to_srgb_linear(spectral.UPSAMPLE_NM, s)
    assert np.max(np.abs(back - rgb).max(axis=1) / rgb.max(axis=1)) < 2e-3
    coeff, scale = spectral.coefficients(mitsuba, rgb[:5])
    lam = [380.0, 455.0, 610.0, 800.0]
    for c, k, want in zip(coeff, scale, spectral.upsampled(coeff, scale, np.array(lam)),
                          strict=True):
        got = np.array(mitsuba.srgb_model_eval(c.tolist(), mitsuba.Spectrum(*lam))) * k
        np.testing.assert_allclose(want, got, rtol=1e-5)


def _mitsuba_eval(bsdf, wi, wo, lam):
    si = mitsuba.SurfaceInteraction3f()
    si.wi = mitsuba.Vector3f(*wi)
    si.wavelengths = mitsuba.Spectrum(*lam)
    v = bsdf.eval(mitsuba.BSDFContext(), si, mitsuba.Vector3f(*wo))
    return np.array([v[i] for i in range(4)])


def test_per_wavelength_models_reach_mitsuba_per_wavelength():
    """In ``scalar_spectral`` a per-wavelength model's BSDFs give its own f_r cos θ_light
    at the rays' wavelengths: ``roughconductor`` with gold's η(λ), k(λ) as Mitsuba spectra
    at the table's wavelengths (float32 and Walter's G1 fit: 1%), the Python BSDF and
    ``diffuse`` also between them (linear in λ, held beyond the ends; the model's
    interpolated values computed here by np.interp), to float32 round-off."""
    from microsim.render import bsdfs

    mitsuba.set_variant("scalar_spectral")
    eta, k = measured.conductor("Au")
    model = TorranceSparrow(Beckmann(0.3), fresnel=ConductorFresnel(eta.at(NM), k.at(NM)),
                            shadowing="smith-separable")
    rng = np.random.default_rng(2)
    pairs = [(direction(np.radians(rng.uniform(0, 70)), rng.uniform(-np.pi, np.pi)),
              direction(np.radians(rng.uniform(0, 70)), rng.uniform(-np.pi, np.pi)))
             for _ in range(30)]
    plugin, how = bsdfs.model_bsdf(mitsuba, model, wavelengths=NM)
    assert how == "roughconductor"
    python = bsdfs.python_bsdf(mitsuba, model, wavelengths=NM)
    for a, b in pairs:
        ref = model.eval(b, a).ravel() * b[2]  # Mitsuba's order: a camera, b light
        if ref.max() < 1e-3:
            continue
        for lam in (NM[:4], NM[3:]):
            want = np.interp(lam, NM, ref)
            np.testing.assert_allclose(_mitsuba_eval(plugin, a, b, lam), want, rtol=1e-2)
        lam = [390.0, 473.0, 642.5, 790.0]
        np.testing.assert_allclose(_mitsuba_eval(python, a, b, lam), np.interp(lam, NM, ref),
                                   rtol=1e-5)
    albedo = np.linspace(0.2, 0.8, len(NM))
    diffuse, how = bsdfs.model_bsdf(mitsuba, Lambertian(albedo), wavelengths=NM)
    assert how == "diffuse"
    a, b = pairs[0]
    lam = [390.0, 473.0, 642.5, 790.0]
    np.testing.assert_allclose(_mitsuba_eval(diffuse, a, b, lam),
                               np.interp(lam, NM, albedo) / np.pi * b[2], rtol=1e-5)


# --- renders -----------------------------------------------------------------------------
@pytest.fixture(scope="module")
def sphere_renders(gold, tmp_path_factory):
    """The gold table on the sphere under the default sun and sky, 96 × 72 pixels, 32
    samples: its total in ``scalar_spectral`` and ``scalar_rgb``, its single scattering
    in ``scalar_spectral``."""
    from microsim.render import backend, bsdfs, objects, scene

    tmp = tmp_path_factory.mktemp("renders")
    camera = scene.Camera(96, 72)
    lights = [scene.parse_light(s) for s in scene.DEFAULT_LIGHTS]
    sphere = objects.sphere()
    images = {}
    before = mitsuba.variant()
    for variant, component in (("scalar_spectral", "total"), ("scalar_rgb", "total"),
                               ("scalar_spectral", "order1")):
        mi = backend.load(variant)
        bsdf = bsdfs.table_bsdf(mi, gold, tmp / f"{variant}-{component}.bsdf", component)
        images[variant, component] = scene.render(mi, sphere, bsdf, camera, lights, 32,
                                                  seed=0)
    if before is not None:
        mitsuba.set_variant(before)
    return images


def _highlight_colour(img, reference):
    """The mean linear RGB of the brightest 3% of the covered pixels (the sun's
    highlight), scaled to the luminance of ``reference``."""
    covered = img.alpha > 0.999
    bright = covered & (img.luminance >= np.percentile(img.luminance[covered], 97))
    assert bright.sum() > 80
    mean = img.rgb[bright].mean(axis=0)
    return mean * (reference @ LUMINANCE) / (mean @ LUMINANCE)


def test_a_gold_sphere_looks_gold(sphere_renders):
    """The sun's highlight on the spectral render has the colour of gold: scaled to the
    luminance of gold's normal-incidence reflectance F0(λ) (exact Fresnel of the shipped
    indices at the table's wavelengths), the single-scattering render's highlight is
    within 5% per channel of F0's linear sRGB, and encoded for display within 0.015 of
    ``to_srgb_display(F0)`` (4 of 255). Reason: the highlight is at θd ≈ 18°, where F's
    colour is F0's to 0.02%, and the sky adds light of the same colour; what is left is
    the render's colour noise (four sampled wavelengths a ray), whose spread over seeds at
    this size is 1.4% in blue (0.1% in red and green), so 5% is 3.5σ; measured: within
    0.3% at 320 × 240 and 128 samples. The total's highlight is gold too, within 6%: its
    multiply scattered light has the colour of F0², more saturated (blue measured 2.6%
    below F0's at 320 × 240)."""
    eta, k = measured.conductor("Au")
    f0 = np.asarray(fresnel_conductor(np.ones(1), eta.at(NM), k.at(NM))).ravel()
    gold_rgb = to_srgb_linear(NM, f0)
    assert gold_rgb[0] > 1.5 * gold_rgb[2]  # gold: red well above blue
    single = _highlight_colour(sphere_renders["scalar_spectral", "order1"], gold_rgb)
    np.testing.assert_allclose(single, gold_rgb, rtol=0.05)
    from colour.models import eotf_inverse_sRGB

    shown = eotf_inverse_sRGB(np.clip(single, 0.0, 1.0))
    np.testing.assert_allclose(shown, to_srgb_display(NM, f0), atol=0.015)
    total = _highlight_colour(sphere_renders["scalar_spectral", "total"], gold_rgb)
    np.testing.assert_allclose(total, gold_rgb, rtol=0.06)


def test_spectral_and_rgb_variants_render_a_spectral_table_alike(sphere_renders):
    """The RGB variant renders the table's sRGB, the spectral one its spectra: the mean
    colour of the sphere agrees within 1.5% per channel. Reason: colour is linear in the
    spectra for single scattering off the object (the film integrates what the sRGB
    conversion integrates); the renders differ by their noise (independent wavelength
    samples; ~0.5% on the mean of ~3800 pixels) and by light that bounces twice on the
    object (spectrum products, not sRGB products); measured 0.3% here, 0.02% for a
    16-wavelength gold table at 320 × 240."""
    a = sphere_renders["scalar_spectral", "total"]
    b = sphere_renders["scalar_rgb", "total"]
    ok = (a.alpha > 0.999) & (b.alpha > 0.999)
    np.testing.assert_allclose(a.rgb[ok].mean(axis=0), b.rgb[ok].mean(axis=0), rtol=0.015)


def test_render_command_reports_the_conversion(cli, gold_file, rgb_file, tmp_path):
    """``render --variant scalar_spectral`` of a spectral and an RGB table with a model:
    the report names what each became (spectral, upsampled) and the model's plugin."""
    code, out, err = cli("render", str(gold_file), str(rgb_file), "-o",
                         str(tmp_path / "r.png"), "--variant", "scalar_spectral", "--size",
                         "32x24", "--spp", "4", "--object", "sphere", "--model",
                         "torrance-sparrow:shadowing=smith-separable", "--json")
    assert code == 0, err
    report = json.loads(out)["tables"]
    assert [t["rendered_as"] for t in report] == ["spectral", "upsampled"]
    assert report[0]["channels"] == "7 wavelengths 400-700 nm"
    # a spectral conductor is roughconductor with η(λ), k(λ); an RGB one's Fresnel is
    # not Mitsuba's of upsampled η, k: tabulated and upsampled like the table
    assert [t["mitsuba"] for t in report] == ["roughconductor", "tabulated"]
    assert (tmp_path / "r.png").stat().st_size > 1000


# --- bad input ---------------------------------------------------------------------------
def test_a_variant_missing_from_mitsuba_is_one_error(cli, gold_file, tmp_path,
                                                     monkeypatch):
    monkeypatch.setattr(mitsuba, "variants", lambda: ["scalar_rgb", "llvm_ad_rgb"])
    code, _, err = cli("render", str(gold_file), "-o", str(tmp_path / "r.png"),
                       "--variant", "scalar_spectral")
    assert code == 2 and err.startswith("error: ") and err.count("\n") == 1
    assert "--variant scalar_spectral" in err and "scalar_rgb, llvm_ad_rgb" in err


@pytest.mark.parametrize(("argv", "needle"), [
    (["--model", "torrance-sparrow:eta=[0.2,0.9,1.1],k=[3,2,2]"], "7 wavelengths"),
    (["--model", "torrance-sparrow:eta=[0.2,0.9,1.1]"], "eta has 3 values, k has 7 values"),
])
def test_a_model_that_does_not_fit_a_spectral_table_is_one_error(cli, gold_file, tmp_path,
                                                                  argv, needle):
    code, _, err = cli("render", str(gold_file), "-o", str(tmp_path / "r.png"), *argv)
    assert code == 2 and err.startswith("error: ") and err.count("\n") == 1
    assert needle in err


@pytest.mark.parametrize(("recipe", "argv", "needle"), [
    ({}, ["--variant", "scalar_spectral"], "not with --live"),
    ({"wavelengths": NM}, [], "[table] wavelengths"),
])
def test_live_rendering_refuses_spectra(cli, tmp_path, recipe, argv, needle):
    path = tmp_path / "r.toml"
    table = {"theta_bins": 4, "phi_bins": 4, **recipe}
    path.write_text('[surface]\nkind = "gaussian"\nalpha = 0.4\nresolution = 16\n[table]\n'
                    + "".join(
        f"{k} = {json.dumps(v)}\n" for k, v in table.items()))
    code, _, err = cli("render", str(path), "--live", "-o", str(tmp_path / "r.png"), *argv)
    assert code == 2 and err.startswith("error: ") and err.count("\n") == 1
    assert needle in err


def test_rgb_flag_is_for_rgl_only(cli, gold_file, tmp_path):
    code, _, err = cli("export", str(gold_file), "--format", "merl", "-o",
                       str(tmp_path / "g.binary"), "--rgb")
    assert code == 2 and err.startswith("error: --rgb") and err.count("\n") == 1

