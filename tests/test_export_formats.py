"""Exact outputs of the export writers on small hand-made tables: the npz file's keys and
arrays, the incident azimuths of an anisotropic RGL file, and how ``rgl_through_mitsuba``
draws, keeps and evaluates its direction pairs (docs/table-format.md)."""

from __future__ import annotations

import functools
import json

import numpy as np
import pytest
from tablefixtures import table_of

from microsim.geometry import direction
from microsim.spectra.channels import Channels
from microsim.tables.binning import HemisphereBins
from microsim.tables.export import (
    merl_directions,
    rgl_fields,
    rgl_phi_i,
    rgl_tensor,
    rgl_through_mitsuba,
    write_merl,
    write_npz,
    write_rgl,
    write_tensor_file,
)
from microsim.tables.meta import TableMeta

RGB = Channels()
"""RGB channels."""


def small_table(channels=RGB, sh=True, sh_err=True, meta=None):
    """A 2 × 1 incidence, 2 × 4 bin table with components total and order1, every array
    filled with distinct seeded values (so a key holding the wrong array shows)."""
    rng = np.random.default_rng(11)
    c = channels.count
    comps = ("total", "order1")

    def draw(*shape):
        return {k: rng.uniform(0.1, 1.0, shape) for k in comps}

    return table_of(
        HemisphereBins(2, 4), np.array([0.0, 0.5]), np.array([0.0]), True,
        draw(2, 1, 2, 4, c), draw(2, 1, 2, 4, c), np.full((2, 1), 1000), draw(2, 1, c),
        draw(2, 1, c), rng.uniform(0, 0.01, (2, 1, c)),
        meta if meta is not None else TableMeta(seed=3),
        sh=draw(2, 1, 4, c) if sh else None, sh_err=draw(2, 1, 4, c) if sh_err else None,
        channels=channels)


# --- npz ---------------------------------------------------------------------------------
def test_npz_has_the_documented_keys_and_arrays(tmp_path):
    """An RGB table with harmonics: exactly the documented keys (no wavelengths or
    channels), each holding the table's array bit for bit; ``isotropic`` a bool,
    ``components`` the names with total first, ``sh_order`` 1 for (1 + 1)² = 4
    coefficients, ``meta`` the metadata's JSON."""
    table = small_table()
    write_npz(table, tmp_path / "t.npz")
    data = np.load(tmp_path / "t.npz")
    per = [f"{p}{c}{s}" for c in ("total", "order1")
           for p, s in (("", ""), ("", "_err"), ("albedo_", ""), ("albedo_", "_err"),
                        ("sh_", ""), ("sh_", "_err"))]
    assert sorted(data.files) == sorted(
        ["theta_i", "phi_i", "theta_o_edges", "phi_o_edges", "components", "albedo",
         "albedo_err", "lost_energy", "isotropic", "meta", "sh_order", *per])
    expect = {"theta_i": table.theta_i, "phi_i": table.phi_i,
              "theta_o_edges": table.bins.theta_edges, "phi_o_edges": table.bins.phi_edges,
              "albedo": table["total"].albedo, "albedo_err": table["total"].albedo_err,
              "lost_energy": table.lost_energy}
    for c in ("total", "order1"):
        expect.update({c: table[c].values, f"{c}_err": table[c].errors,
                       f"albedo_{c}": table[c].albedo,
                       f"albedo_{c}_err": table[c].albedo_err,
                       f"sh_{c}": table[c].sh, f"sh_{c}_err": table[c].sh_err})
    for key, want in expect.items():
        assert data[key].dtype == np.float64, key
        np.testing.assert_array_equal(data[key], want, err_msg=key)
    assert data["isotropic"].dtype == np.bool_ and data["isotropic"].item() is True
    assert data["components"].tolist() == ["total", "order1"]
    assert data["sh_order"].item() == 1
    assert json.loads(str(data["meta"])) == {"seed": 3}


def test_npz_of_a_spectral_table_adds_float_wavelengths_and_channel_names(tmp_path):
    """Wavelengths given as integers are stored as float64 nm (the documented type), the
    channel names as ``400nm`` …, and every value array has one entry per wavelength."""
    table = small_table(Channels((400, 550, 700, 750)), sh=False, sh_err=False)
    write_npz(table, tmp_path / "s.npz")
    data = np.load(tmp_path / "s.npz")
    assert data["wavelengths"].dtype == np.float64
    np.testing.assert_array_equal(data["wavelengths"], [400.0, 550.0, 700.0, 750.0])
    assert data["channels"].tolist() == ["400nm", "550nm", "700nm", "750nm"]
    assert data["total"].shape == (2, 1, 2, 4, 4)
    assert "sh_order" not in data.files and "sh_total" not in data.files


def test_npz_of_harmonics_without_errors_is_written_without_them(tmp_path):
    """Harmonics need both their values and their errors: a table with values only is
    written with neither (and no ``sh_order``) rather than failing."""
    write_npz(small_table(sh_err=False), tmp_path / "t.npz")
    data = np.load(tmp_path / "t.npz")
    assert not [k for k in data.files if k.startswith("sh_")]
    assert "total" in data.files


def test_npz_meta_writes_what_json_cannot_hold_as_its_text(tmp_path):
    """A seed held as a numpy integer (not a JSON type) is written as its decimal text,
    not refused."""
    write_npz(small_table(meta=TableMeta(seed=np.uint64(12345678901234567890))),
              tmp_path / "t.npz")
    assert json.loads(str(np.load(tmp_path / "t.npz")["meta"])) == {
        "seed": "12345678901234567890"}


# --- MERL -------------------------------------------------------------------------------
@functools.cache
def merl_cells():
    """(ωi, ωo) of every MERL cell (θh, θd, φd) = ((i/90)² π/2, j/90 · π/2, k/180 · π) by
    explicit rotation: the difference vector at (θd, φd), and its mirror about the half
    vector's axis, tilted by θh about y (φh = 0; Rusinkiewicz 1998)."""
    i, j, k = np.meshgrid(np.arange(90.0), np.arange(90.0), np.arange(180.0),
                          indexing="ij")
    th, td, pd = (i / 90) ** 2 * np.pi / 2, j / 90 * np.pi / 2, k / 180 * np.pi
    dx, dy, dz = np.sin(td) * np.cos(pd), np.sin(td) * np.sin(pd), np.cos(td)
    c, s = np.cos(th), np.sin(th)
    wi = np.stack([c * dx + s * dz, dy, -s * dx + c * dz], -1)
    wo = np.stack([-c * dx + s * dz, -dy, s * dx + c * dz], -1)
    return wi, wo


def test_merl_directions_are_the_cells_half_and_difference_angles():
    """Every cell's (ωi, ωo), (90, 90, 180, 3), equals the explicit rotation to float64
    round-off (1e-15)."""
    wi, wo = merl_directions()
    want_i, want_o = merl_cells()
    assert wi.shape == wo.shape == (90, 90, 180, 3)
    np.testing.assert_allclose(wi, want_i, rtol=0, atol=1e-15)
    np.testing.assert_allclose(wo, want_o, rtol=0, atol=1e-15)


def merl_file(path):
    """Header and the three float64 planes of a MERL file, as stored."""
    raw = path.read_bytes()
    assert len(raw) == 12 + 3 * 8 * 90 * 90 * 180
    return raw[:12], np.frombuffer(raw[12:], "<f8").reshape(3, 90, 90, 180)


def check_merl(path, value):
    """The header is int32 90, 90, 180 little-endian; each plane holds value / scale
    (scales 1/1500, 1.15/1500, 1.66/1500) where both cell directions are above the
    horizon and −1 elsewhere (about 346 000 cells), to float64 round-off."""
    header, planes = merl_file(path)
    assert header == bytes([90, 0, 0, 0, 90, 0, 0, 0, 180, 0, 0, 0])
    wi, wo = merl_cells()
    below = (wi[..., 2] <= 0) | (wo[..., 2] <= 0)
    assert 300_000 < below.sum() < 400_000
    for c, scale in enumerate((1.0, 1.15, 1.66)):
        assert np.all(planes[c][below] == -1.0)
        np.testing.assert_allclose(planes[c][~below], value[c] * 1500 / scale, rtol=1e-12)


def test_merl_file_of_a_constant_table(tmp_path):
    """The total by default, ``component`` order1 when asked (``check_merl``)."""
    table = constant_table()
    write_merl(table, tmp_path / "t.binary")
    check_merl(tmp_path / "t.binary", TOTAL)
    write_merl(table, tmp_path / "o.binary", "order1")
    check_merl(tmp_path / "o.binary", ORDER1)


def test_merl_file_of_a_spectral_table_holds_its_linear_srgb(tmp_path):
    """A spectral table's planes hold colour-science's linear sRGB of its channels
    (negatives 0), of the component asked for."""
    from microsim.spectra.colour import to_srgb_linear

    nm = (450.0, 550.0, 650.0)
    table = constant_table(channels=Channels(nm))
    write_merl(table, tmp_path / "s.binary", "order1")
    check_merl(tmp_path / "s.binary", np.maximum(to_srgb_linear(nm, ORDER1), 0))


def test_merl_refuses_an_anisotropic_table(tmp_path):
    """The refusal's whole message (the format holds isotropic BRDFs only), and no file
    left behind."""
    with pytest.raises(ValueError) as e:
        write_merl(constant_table(isotropic=False), tmp_path / "a.binary")
    assert str(e.value) == "MERL files hold isotropic BRDFs; this table is anisotropic"
    assert not (tmp_path / "a.binary").exists()


# --- the RGL tensor file ----------------------------------------------------------------
def test_tensor_file_bytes_follow_the_published_layout(tmp_path):
    """Two fields written out byte by byte from Mitsuba 3's ``TensorFile`` layout:
    "tensor_file\\0", version 1 0 (u8 u8), field count (u32), per field its name length
    (u16), name, rank (u16), type (u8: 1 uint8, 10 float32), data offset (u64) and shape
    (u64 each); the data at offsets rounded up to 8 (header 18 + 23 + 30 = 71 bytes, so
    72; then 72 + 8 = 80, already aligned, so 80), zeros between."""
    ab = np.arange(1, 9, dtype=np.uint8)
    x = np.array([[1.5], [-2.0]], np.float32)
    write_tensor_file({"ab": ab, "x": x}, tmp_path / "t.bsdf")
    want = (b"tensor_file\0" + bytes([1, 0]) + (2).to_bytes(4, "little")
            + (2).to_bytes(2, "little") + b"ab" + (1).to_bytes(2, "little") + bytes([1])
            + (72).to_bytes(8, "little") + (8).to_bytes(8, "little")
            + (1).to_bytes(2, "little") + b"x" + (2).to_bytes(2, "little") + bytes([10])
            + (80).to_bytes(8, "little") + (2).to_bytes(8, "little")
            + (1).to_bytes(8, "little")
            + bytes(1) + bytes(range(1, 9))
            + np.array([1.5, -2.0], "<f4").tobytes())
    assert (tmp_path / "t.bsdf").read_bytes() == want


def read_tensor(path):
    """An RGL tensor file read from its published layout (as in the test above)."""
    raw = path.read_bytes()
    assert raw[:14] == b"tensor_file\0\1\0"
    count = int.from_bytes(raw[14:18], "little")
    pos, fields = 18, {}
    for _ in range(count):
        n = int.from_bytes(raw[pos:pos + 2], "little")
        name = raw[pos + 2:pos + 2 + n].decode()
        pos += 2 + n
        rank = int.from_bytes(raw[pos:pos + 2], "little")
        dt = {1: np.uint8, 10: np.float32}[raw[pos + 2]]
        offset = int.from_bytes(raw[pos + 3:pos + 11], "little")
        shape = [int.from_bytes(raw[pos + 11 + 8 * r:pos + 19 + 8 * r], "little")
                 for r in range(rank)]
        pos += 11 + 8 * rank
        size = int(np.prod(shape)) * np.dtype(dt).itemsize
        fields[name] = np.frombuffer(raw[offset:offset + size], dt).reshape(shape)
    return fields


TOTAL, ORDER1 = np.array([0.1, 0.2, 0.3]), np.array([0.05, 0.07, 0.11])


def constant_table(isotropic=True, channels=RGB, meta=None):
    """f_r constant over the hemisphere: TOTAL in ``total``, ORDER1 in ``order1`` (the
    first channels of each, for more than three), θi 0, 30 and 60°; anisotropic at φi
    0, 90, 180 and 270°."""
    c = channels.count
    phi_i = np.array([0.0]) if isotropic else np.radians([0.0, 90.0, 180.0, 270.0])
    a, b = 3, len(phi_i)

    def fill(v):
        return np.broadcast_to(np.resize(v, c), (a, b, 4, 8, c)).copy()

    zeros = {k: np.zeros((a, b, c)) for k in ("total", "order1")}
    return table_of(
        HemisphereBins(4, 8), np.radians([0.0, 30.0, 60.0]), phi_i, isotropic,
        {"total": fill(TOTAL), "order1": fill(ORDER1)},
        {"total": fill(0.0), "order1": fill(0.0)}, np.full((a, b), 1000), zeros, zeros,
        np.zeros((a, b, c)), meta if meta is not None else TableMeta(), channels=channels)


def expected_rgl(value, theta_i, phi_i, h, isotropic):
    """f_r cos θo at the mirror direction of ωi about each grid vertex m (u = 0…1 in h
    steps, θm = u² π/2, φm = 2πu − π, from φi when isotropic), written out per vertex;
    0 where ωo is below the horizon. Shape (φi, θi, channels, φm, θm)."""
    out = np.zeros((len(phi_i), len(theta_i), len(value), h, h))
    for b, p in enumerate(phi_i):
        for a, t in enumerate(theta_i):
            wi = np.array([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)])
            for i in range(h):
                for j in range(h):
                    tm = (j / (h - 1)) ** 2 * np.pi / 2
                    pm = 2 * np.pi * i / (h - 1) - np.pi + (p if isotropic else 0.0)
                    m = np.array([np.sin(tm) * np.cos(pm), np.sin(tm) * np.sin(pm),
                                  np.cos(tm)])
                    wo = 2 * np.dot(m, wi) * m - wi
                    out[b, a, :, i, j] = np.asarray(value) * wo[2] if wo[2] > 0 else 0.0
    return out


def test_rgl_fields_of_an_isotropic_table_by_default():
    """Defaults: the total, a 32² grid, the table's incidences, one φi slice at 0, the
    description "microsim table"; ``rgb`` is TOTAL · cos θo at each vertex's mirror
    direction (float32: 1e-6 relative)."""
    table = constant_table()
    f = rgl_fields(table)
    assert bytes(f["description"]) == b"microsim table"
    np.testing.assert_array_equal(f["theta_i"], np.float32(np.radians([0.0, 30.0, 60.0])))
    np.testing.assert_array_equal(f["phi_i"], [0.0])
    assert f["rgb"].shape == (1, 3, 3, 32, 32)
    np.testing.assert_allclose(f["rgb"], expected_rgl(TOTAL, table.theta_i, [0.0], 32, True),
                               rtol=1e-6, atol=1e-8)


def test_rgl_fields_takes_the_component_incidences_and_description():
    """``component`` order1, ``theta_i`` 10 and 50°, a 5² grid and a description are all
    used."""
    table = constant_table()
    theta = np.radians([10.0, 50.0])
    f = rgl_fields(table, 5, "order1", "mine", theta_i=theta)
    assert bytes(f["description"]) == b"mine"
    np.testing.assert_array_equal(f["theta_i"], np.float32(theta))
    np.testing.assert_allclose(f["rgb"], expected_rgl(ORDER1, theta, [0.0], 5, True),
                               rtol=1e-6, atol=1e-8)


def test_rgl_fields_of_an_anisotropic_table_slice_every_15_degrees():
    """An anisotropic table: φi −180° … 180° every 15° by default (25 slices; 45°: 9),
    φm absolute (from the tangent), the values TOTAL · cos θo there."""
    table = constant_table(isotropic=False)
    f = rgl_fields(table, 4)
    phi = np.radians(np.arange(-180.0, 181.0, 15.0))
    np.testing.assert_allclose(f["phi_i"], np.float32(phi), rtol=0, atol=1e-6)
    assert f["rgb"].shape == (25, 3, 3, 4, 4)
    np.testing.assert_allclose(f["rgb"], expected_rgl(TOTAL, table.theta_i, phi, 4, False),
                               rtol=1e-6, atol=1e-7)
    assert rgl_fields(table, 4, phi_step=45.0)["phi_i"].shape == (9,)


def test_rgl_fields_of_a_spectral_table_are_spectral_unless_rgb():
    """A spectral table's fields carry ``wavelengths`` and ``spectra`` (its channels ·
    cos θo) by default; with ``rgb`` neither, and ``rgb`` is then the same as the spectral
    file's (both the linear sRGB of the channels)."""
    table = constant_table(channels=Channels((450.0, 550.0, 650.0)))
    spectral, rgb = rgl_fields(table, 4), rgl_fields(table, 4, rgb=True)
    np.testing.assert_array_equal(spectral["wavelengths"], [450.0, 550.0, 650.0])
    np.testing.assert_allclose(spectral["spectra"],
                               expected_rgl(TOTAL, table.theta_i, [0.0], 4, True),
                               rtol=1e-6, atol=1e-8)
    assert "wavelengths" not in rgb and "spectra" not in rgb
    np.testing.assert_allclose(rgb["rgb"], spectral["rgb"], rtol=1e-6, atol=1e-8)


def test_write_rgl_names_the_component_and_the_surface(tmp_path):
    """The file of ``write_rgl``: by default the total on a 32² grid, described as
    "microsim total BRDF of a gaussian surface" (the surface's kind), or with an empty
    kind for a table without a surface; ``component`` order1 is named and written; a
    spectral table's file is spectral by default and RGB with ``rgb``."""
    meta = TableMeta.from_json({"surface": {"kind": "gaussian"}})
    table = constant_table(meta=meta)
    write_rgl(table, tmp_path / "t.bsdf")
    f = read_tensor(tmp_path / "t.bsdf")
    assert bytes(f["description"]) == b"microsim total BRDF of a gaussian surface"
    np.testing.assert_allclose(f["rgb"], expected_rgl(TOTAL, table.theta_i, [0.0], 32, True),
                               rtol=1e-6, atol=1e-8)
    write_rgl(table, tmp_path / "o.bsdf", 4, "order1")
    f = read_tensor(tmp_path / "o.bsdf")
    assert bytes(f["description"]) == b"microsim order1 BRDF of a gaussian surface"
    np.testing.assert_allclose(f["rgb"], expected_rgl(ORDER1, table.theta_i, [0.0], 4, True),
                               rtol=1e-6, atol=1e-8)
    write_rgl(constant_table(), tmp_path / "n.bsdf", 4)
    assert bytes(read_tensor(tmp_path / "n.bsdf")["description"]) == (
        b"microsim total BRDF of a  surface")
    spectral = constant_table(channels=Channels((450.0, 550.0, 650.0)), meta=meta)
    write_rgl(spectral, tmp_path / "s.bsdf", 4)
    assert "spectra" in read_tensor(tmp_path / "s.bsdf")
    write_rgl(spectral, tmp_path / "r.bsdf", 4, rgb=True)
    assert "spectra" not in read_tensor(tmp_path / "r.bsdf")


def lobe_f(wi, wo):
    """A BRDF that depends on both directions and differs per channel."""
    d = np.sum(wi * wo, axis=-1)
    return np.stack([1.0 + d**2, 2.0 + wo[..., 0], 0.5 + wi[..., 1] ** 2], axis=-1)


def expected_tensor(theta_i, phi_i, h, f=lobe_f):
    """rgb and luminance of ``f`` vertex by vertex: f_r cos θo at the mirror
    direction of ωi about m (u = 0…1 in h steps, θm = u² π/2, φm = 2πu − π), and the
    albedo integrand Y(f_r cos θo) · 2π² u sin θm · 4 max(⟨ωi, m⟩, 0) with Rec. 709's
    Y = 0.2126 R + 0.7152 G + 0.0722 B, plus 1% of its mean over the grid (and 1e-30)."""
    rgb = np.zeros((len(phi_i), len(theta_i), 3, h, h))
    lum = np.zeros((len(phi_i), len(theta_i), h, h))
    for b, p in enumerate(phi_i):
        for a, t in enumerate(theta_i):
            wi = np.array([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)])
            for i in range(h):
                for j in range(h):
                    u = j / (h - 1)
                    tm, pm = u**2 * np.pi / 2, 2 * np.pi * i / (h - 1) - np.pi
                    m = np.array([np.sin(tm) * np.cos(pm), np.sin(tm) * np.sin(pm),
                                  np.cos(tm)])
                    wo = 2 * np.dot(m, wi) * m - wi
                    v = f(wi, wo) * max(wo[2], 0.0)
                    rgb[b, a, :, i, j] = v
                    y = 0.2126 * v[0] + 0.7152 * v[1] + 0.0722 * v[2]
                    lum[b, a, i, j] = (max(y, 0.0) * 2 * np.pi**2 * u * np.sin(tm) * 4
                                       * max(np.dot(m, wi), 0.0))
            lum[b, a] += 0.01 * lum[b, a].mean() + 1e-30
    return rgb, lum


def test_rgl_tensor_fields_of_a_given_brdf():
    """Every field of an anisotropic file of ``lobe_f`` (φi −π, 0 and π/2, θi 0, 35 and
    70°, a 6² grid), in the documented order: the description's bytes, a zero uint8
    ``jacobian``, float32 θi and φi, NDF and σ ones (H, H), VNDF ones (φi, θi, H, H), and
    ``luminance`` and ``rgb`` as written out vertex by vertex (float32: 1e-6 relative)."""
    theta, phi, h = np.radians([0.0, 35.0, 70.0]), [-np.pi, 0.0, np.pi / 2], 6
    f = rgl_tensor(lobe_f, theta, phi, h, "a lobe")
    assert list(f) == ["description", "jacobian", "theta_i", "phi_i", "ndf", "sigma",
                       "vndf", "luminance", "rgb"]
    assert f["description"].dtype == np.uint8 and bytes(f["description"]) == b"a lobe"
    assert f["jacobian"].dtype == np.uint8 and f["jacobian"].tolist() == [0]
    for key, want in (("theta_i", theta), ("phi_i", phi)):
        assert f[key].dtype == np.float32
        np.testing.assert_array_equal(f[key], np.float32(want))
    for key, shape in (("ndf", (h, h)), ("sigma", (h, h)), ("vndf", (3, 3, h, h))):
        assert f[key].dtype == np.float32 and f[key].shape == shape
        assert np.all(f[key] == 1.0)
    rgb, lum = expected_tensor(theta, phi, h)
    assert f["rgb"].dtype == np.float32 and f["luminance"].dtype == np.float32
    np.testing.assert_allclose(f["rgb"], rgb, rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(f["luminance"], lum, rtol=1e-6, atol=1e-30)


def test_rgl_tensor_sampling_map_of_a_brdf_negative_somewhere_or_zero():
    """Where Y(f_r cos θo) is negative (a truncated series can be) the map holds only the
    floor: the integrand is taken as 0 there; a BRDF that is 0 everywhere gives the
    positive 1e-30 at every node (float32 holds it), so the map stays a density."""
    def signed(wi, wo):
        return lobe_f(wi, wo) * np.sign(wo[..., :1] + 0.1)

    theta = np.radians([0.0, 45.0])
    f = rgl_tensor(signed, theta, None, 6, "")
    rgb, lum = expected_tensor(theta, [0.0], 6, signed)
    assert rgb.min() < 0
    np.testing.assert_allclose(f["rgb"], rgb, rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(f["luminance"], lum, rtol=1e-6, atol=1e-30)
    zero = rgl_tensor(lambda wi, wo: np.zeros(wo.shape), theta, None, 4, "")
    assert np.all(zero["luminance"] == np.float32(1e-30))


def test_rgl_tensor_isotropic_is_one_slice_at_phi_0():
    """Without φi: one slice, φi 0 (float32 zero), the same values as φi = 0 given."""
    theta = np.radians([10.0, 60.0])
    f = rgl_tensor(lobe_f, theta, None, 5, "")
    assert f["phi_i"].dtype == np.float32 and f["phi_i"].tolist() == [0.0]
    rgb, lum = expected_tensor(theta, [0.0], 5)
    np.testing.assert_allclose(f["rgb"], rgb, rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(f["luminance"], lum, rtol=1e-6, atol=1e-30)
    assert bytes(f["description"]) == b""


def test_rgl_tensor_spectral_fields():
    """With wavelengths: ``wavelengths`` (float32) and ``spectra`` (the channels of f
    times cos θo) before ``rgb``, which is colour-science's linear sRGB of the spectra
    with negatives 0; ``luminance`` CIE's Y under D65 of the spectra
    (``microsim.spectra.colour.luminance``) in the same integrand (1e-5: float32 and the
    conversion's sums)."""
    from microsim.spectra.colour import luminance, to_srgb_linear

    nm, theta, h = (450, 550, 650), np.radians([20.0, 50.0]), 4
    f = rgl_tensor(lobe_f, theta, None, h, "s", wavelengths=nm)
    assert list(f)[-3:] == ["wavelengths", "spectra", "rgb"]
    assert f["wavelengths"].dtype == np.float32
    np.testing.assert_array_equal(f["wavelengths"], [450.0, 550.0, 650.0])
    spectra, _ = expected_tensor(theta, [0.0], h)
    np.testing.assert_allclose(f["spectra"], spectra, rtol=1e-6, atol=1e-7)
    s = np.moveaxis(spectra, 2, -1)
    np.testing.assert_allclose(np.moveaxis(f["rgb"], 2, -1),
                               np.maximum(to_srgb_linear([450.0, 550.0, 650.0], s), 0),
                               rtol=1e-5, atol=1e-7)
    y = np.clip(luminance((450.0, 550.0, 650.0), s), 0, None)[0]
    u = np.linspace(0, 1, h)
    tm = u**2 * np.pi / 2
    for a, t in enumerate(theta):
        wi = np.array([np.sin(t), 0.0, np.cos(t)])
        pm = 2 * np.pi * u - np.pi
        m = np.stack([np.sin(tm)[None, :] * np.cos(pm)[:, None],
                      np.sin(tm)[None, :] * np.sin(pm)[:, None],
                      np.broadcast_to(np.cos(tm), (h, h))], -1)
        dens = y[a] * 2 * np.pi**2 * u * np.sin(tm) * 4 * np.maximum(m @ wi, 0)
        np.testing.assert_allclose(f["luminance"][0, a], dens + 0.01 * dens.mean() + 1e-30,
                                   rtol=1e-5)


# --- RGL incident azimuths ---------------------------------------------------------------
def test_rgl_phi_i_spans_minus_pi_to_pi_with_both_ends():
    """−180° … 180° in the given step, both ends included and exactly ±π (15° by
    default: 25 values; 90°: 5; 1°: 361), to float64 round-off of the degrees."""
    for step, args in ((15, ()), (90, (90.0,)), (1, (1.0,))):
        got = rgl_phi_i(*args)
        want = np.radians(np.arange(-180, 181, step, dtype=float))
        assert got.shape == want.shape
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-14)
        assert got[0] == -np.pi and got[-1] == np.pi


# --- rgl_through_mitsuba -----------------------------------------------------------------
class Lobe:
    """A stand-in table: f_r = weights · exp(−|ωo − ωr|² / 0.2) within 40° of the mirror
    direction ωr = (−x, −y, z) of ωi, 0 beyond; every ``eval`` call is recorded."""

    def __init__(self, theta_i, phi_i, wavelengths=None, weights=(1.0, 2.0, 3.0)):
        self.theta_i = np.asarray(theta_i, float)
        self.phi_i = np.asarray(phi_i, float)
        self.channels = Channels(wavelengths)
        self.weights = np.asarray(weights, float)
        self.calls = []

    def f(self, wi, wo):
        """The lobe, written out."""
        wr = np.array([-wi[0], -wi[1], wi[2]])
        cos = float(np.dot(wo, wr))
        v = np.exp(-np.sum((wo - wr) ** 2) / 0.2) if cos > np.cos(np.radians(40)) else 0.0
        return v * self.weights

    def eval(self, wi, wo, component="total"):
        wi, wo = np.asarray(wi, float), np.asarray(wo, float)
        self.calls.append((wi.copy(), wo.copy()))
        return self.f(wi, wo)


@pytest.fixture
def mi():
    """Mitsuba 3, its variant left as the test found it."""
    mitsuba = pytest.importorskip("mitsuba")
    before = mitsuba.variant()
    yield mitsuba
    if before is not None:
        mitsuba.set_variant(before)


@pytest.fixture
def rgb_file(tmp_path):
    """A small RGB RGL file (8² grid) of a constant f_r: Mitsuba only has to load it."""
    path = tmp_path / "c.bsdf"
    write_tensor_file(rgl_tensor(lambda wi, wo: np.full(wo.shape[:-1] + (3,), 0.3),
                                 np.radians([0.0, 40.0, 80.0]), None, 8, "c"), path)
    return path


def _theta_deg(w):
    return np.degrees(np.arccos(np.clip(w[2], -1, 1)))


def test_rgl_through_mitsuba_keeps_exactly_the_pairs_in_the_lobe(mi, rgb_file):
    """Each drawn pair (the table is asked f_r at it, then in the mirror direction) is
    kept exactly when f_r cos θo, averaged over the channels, is at least
    ``lobe_fraction`` × that of the mirror direction (−x, −y, z) times cos θi, recomputed
    here from the lobe's formula; the reference returned is f_r cos θo of the kept pairs
    in order (to float64 round-off). ωi is one of the table's incidences."""
    table = Lobe(np.radians([10.0, 40.0, 70.0]), [0.3, 1.9])
    ref, got = rgl_through_mitsuba(table, rgb_file, 120, np.random.default_rng(1),
                                   lobe_fraction=0.3)
    draws = table.calls[0::2]
    incidences = [direction(t, p) for t in table.theta_i for p in table.phi_i]
    kept = []
    for wi, wo in draws:
        assert min(np.abs(wi - d).max() for d in incidences) < 1e-15
        r = table.f(wi, wo) * wo[2]
        wr = np.array([-wi[0], -wi[1], wi[2]])
        if r.mean() >= 0.3 * table.f(wi, wr).mean() * wi[2]:
            kept.append(r)
    assert 120 < len(draws) and len(kept) == 120
    assert ref.shape == (120, 3) and got.shape == (120, 3)
    np.testing.assert_allclose(ref, kept, rtol=1e-12, atol=0)


def test_rgl_through_mitsuba_keeps_pairs_at_the_lobe_fraction_itself(mi, rgb_file):
    """"At least" the fraction: with ``lobe_fraction`` 0 every pair is kept, those where
    f_r is 0 (outside the lobe) too."""
    table = Lobe(np.radians([30.0]), [0.0])
    ref, _ = rgl_through_mitsuba(table, rgb_file, 200, np.random.default_rng(2),
                                 lobe_fraction=0.0)
    assert len(table.calls) == 2 * 200
    assert (ref == 0).all(axis=1).sum() > 20


def test_rgl_through_mitsuba_draws_the_documented_directions(mi, rgb_file):
    """Over 2000 drawn pairs (all kept: ``lobe_fraction`` 0): θo lies in [0, 85°] (float
    round-off 1e-6°) and comes within 1° of both ends (a uniform draw misses a 1° end in
    2000 tries with probability (84/85)^2000 = 5e-11); φo − φi − π has mean 0 and
    standard deviation 0.5 within 4 of their standard errors (0.5/√2000 = 0.011 and
    0.5/√4000 = 0.0079)."""
    table = Lobe(np.radians([20.0, 50.0]), [0.0, 1.0])
    n = 2000
    rgl_through_mitsuba(table, rgb_file, n, np.random.default_rng(3), lobe_fraction=0.0)
    draws = table.calls[0::2]
    assert len(draws) == n
    theta = np.array([_theta_deg(wo) for _, wo in draws])
    assert theta.max() <= 85 + 1e-6 and theta.min() >= 0
    assert theta.min() < 1 and theta.max() > 84
    dphi = np.array([np.arctan2(wo[1], wo[0]) - np.arctan2(wi[1], wi[0]) - np.pi
                     for wi, wo in draws])
    dphi = np.angle(np.exp(1j * dphi))
    assert abs(dphi.mean()) < 4 * 0.5 / np.sqrt(n)
    assert abs(dphi.std() - 0.5) < 4 * 0.5 / np.sqrt(2 * n)


def test_rgl_through_mitsuba_refuses_a_spectral_variant_for_an_rgb_table(mi, rgb_file):
    """The refusal's whole message: a spectral variant reads spectral files only."""
    with pytest.raises(ValueError) as e:
        rgl_through_mitsuba(Lobe([0.3], [0.0]), rgb_file, 1, np.random.default_rng(0),
                            variant="scalar_spectral")
    assert str(e.value) == "a spectral variant reads spectral files: the table is RGB"


NM = (450.0, 550.0, 650.0)
QUERY = [400.0, 425.0, 450.0, 500.0, 550.0, 600.0, 650.0, 675.0, 700.0]
"""Nine wavelengths: three groups of Mitsuba's four (the last padded), at, between and
beyond both ends of the table's wavelengths."""


def test_rgl_through_mitsuba_asks_mitsuba_at_the_given_wavelengths(mi, tmp_path):
    """In ``scalar_spectral`` with chosen wavelengths: the reference is the table's
    channels (1, 2, 3 × the lobe at 450, 550, 650 nm) interpolated linearly there and held
    beyond the ends, (1, 1, 1, 1.5, 2, 2.5, 3, 3, 3) × f cos θo; Mitsuba's values, from a file whose
    spectra are 1, 2, 3 × one shape, are in the same ratios at each pair (its lookup is
    linear in wavelength; float32: 1e-5)."""
    path = tmp_path / "s.bsdf"
    write_tensor_file(rgl_tensor(
        lambda wi, wo: np.ones(wo.shape[:-1] + (1,)) * [1.0, 2.0, 3.0],
        np.radians([0.0, 40.0, 80.0]), None, 8, "s", wavelengths=NM), path)
    table = Lobe(np.radians([20.0, 45.0]), [0.0], wavelengths=NM)
    ref, got = rgl_through_mitsuba(table, path, 30, np.random.default_rng(4),
                                   variant="scalar_spectral", wavelengths=QUERY)
    ratio = np.array([1.0, 1.0, 1.0, 1.5, 2.0, 2.5, 3.0, 3.0, 3.0])
    assert ref.shape == (30, 9) and got.shape == (30, 9)
    base = np.array([table.f(wi, wo)[0] * wo[2] for wi, wo in table.calls[0::2]
                     if table.f(wi, wo).mean() * wo[2]
                     >= 0.1 * table.f(wi, wi * [-1, -1, 1]).mean() * wi[2]])
    np.testing.assert_allclose(ref, base[:, None] * ratio, rtol=1e-12)
    assert np.all(got[:, 0] > 0)
    np.testing.assert_allclose(got / got[:, :1], np.broadcast_to(ratio, got.shape),
                               rtol=1e-5)


def test_rgl_through_mitsuba_defaults_to_the_tables_wavelengths(mi, tmp_path):
    """Without chosen wavelengths the spectral reference is the table's own channels."""
    path = tmp_path / "s.bsdf"
    write_tensor_file(rgl_tensor(
        lambda wi, wo: np.ones(wo.shape[:-1] + (1,)) * [1.0, 2.0, 3.0],
        np.radians([0.0, 40.0, 80.0]), None, 8, "s", wavelengths=NM), path)
    table = Lobe(np.radians([20.0]), [0.0], wavelengths=NM)
    ref, got = rgl_through_mitsuba(table, path, 10, np.random.default_rng(5),
                                   variant="scalar_spectral")
    assert ref.shape == (10, 3) and got.shape == (10, 3)
    np.testing.assert_allclose(ref / ref[:, :1], np.broadcast_to([1.0, 2.0, 3.0], (10, 3)),
                               rtol=1e-12)
    np.testing.assert_allclose(got / got[:, :1], np.broadcast_to([1.0, 2.0, 3.0], (10, 3)),
                               rtol=1e-5)
