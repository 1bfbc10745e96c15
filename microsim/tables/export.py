"""Exports of a BRDF table to formats other tools read: numpy ``.npz``, MERL ``.binary``
and the RGL tensor file ``.bsdf`` that Mitsuba 3's ``measured`` material loads.

Every writer evaluates the table with ``BRDFTable.eval`` (interpolated, 0 below the
horizon) at the format's own sample points and writes atomically.

A spectral table (``table.channels.spectral``: one channel per wavelength) keeps all its
channels in ``.npz`` and in the RGL file's ``spectra`` field (Mitsuba 3's spectral
layout); formats that hold R, G, B only (MERL, the RGL file's ``rgb`` field) get its
linear sRGB (``srgb_linear``). An RGB table's files are what they always were, byte for
byte.
"""

from __future__ import annotations

import json
import struct
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from microsim.files import atomic_path
from microsim.geometry import direction, half_difference
from microsim.tables.table import BRDFTable


def srgb_linear(nm: tuple[float, ...] | np.ndarray, values: np.ndarray) -> np.ndarray:
    """Linear sRGB of spectral BRDF values, negative components set to 0.

    ``microsim.spectra.colour.to_srgb_linear``: CIE 1931 2° XYZ under D65 (the spectrum
    linear between the samples, constant beyond the first and last; CIE 015:2018 sec.
    7.1), then IEC 61966-2-1's XYZ→RGB matrix, so a spectrally flat value v gives
    (v, v, v) to 2e-4. A spectrum outside the sRGB gamut has a negative component, which
    no RGB renderer can use as a reflectance: it is set to 0 (the colour desaturates a
    little; the other two are kept).

    Parameters
    ----------
    nm : (C,) float
        The wavelengths, nm, increasing.
    values : (..., C) float
        f_r (or f_r cos θo) per wavelength.

    Returns
    -------
    (..., 3) float
    """
    from microsim.spectra.colour import to_srgb_linear  # colour-science: slow to import

    return np.maximum(to_srgb_linear(np.asarray(nm, float), values), 0.0)


MERL_SHAPE = (90, 90, 180)
MERL_SCALE = np.array([1.0 / 1500, 1.15 / 1500, 1.66 / 1500])
"""What MERL readers multiply the stored R, G, B values by (Matusik et al. 2003)."""


def write_npz(table: BRDFTable, path: str | Path) -> None:
    """Axes, values, errors and albedo as plain numpy arrays.

    Keys: ``theta_i``, ``phi_i`` (radians), ``theta_o_edges``, ``phi_o_edges`` (radians),
    ``components`` (the component names, ``"total"`` first), and per component X (e.g.
    ``total``, ``order1``, ``order2``, ``order3+``) ``X``, ``X_err`` ((n_theta_i, n_phi_i,
    theta_bins, phi_bins, C), f_r in 1/sr and standard errors, NaN where undefined) and
    ``albedo_X``, ``albedo_X_err`` ((n_theta_i, n_phi_i, C)); ``albedo``, ``albedo_err``
    (of the total) and ``lost_energy`` ((n_theta_i, n_phi_i, C)), ``isotropic`` (bool),
    and ``meta`` (the table's metadata as a JSON string); with spherical harmonics also
    ``sh_order`` and ``sh_X``, ``sh_X_err`` ((n_theta_i, n_phi_i, (L + 1)², C),
    docs/table-format.md). C is 3 (R, G, B) for an RGB table; a spectral table has one
    channel per wavelength, in increasing order, and also the keys ``wavelengths`` ((C,)
    float, nm) and ``channels`` (the channel names, ``"550nm"`` …). An RGB table's file
    has no such keys (it is byte for byte what it was before spectral tables).
    """
    arrays = {"theta_i": table.theta_i, "phi_i": table.phi_i,
              "theta_o_edges": table.bins.theta_edges, "phi_o_edges": table.bins.phi_edges,
              "components": np.array(table.components),
              "albedo": table.albedo, "albedo_err": table.albedo_err,
              "lost_energy": table.lost_energy, "isotropic": np.array(table.isotropic),
              "meta": np.array(json.dumps(table.meta.to_json(), default=str))}
    if table.channels.spectral:
        arrays["wavelengths"] = np.array(table.channels.wavelengths, float)
        arrays["channels"] = np.array(table.channels.names)
    for c in table.components:
        arrays[c], arrays[f"{c}_err"] = table[c].values, table[c].errors
        arrays[f"albedo_{c}"], arrays[f"albedo_{c}_err"] = (table[c].albedo,
                                                            table[c].albedo_err)
        if table.has_sh:
            arrays[f"sh_{c}"], arrays[f"sh_{c}_err"] = table[c].sh, table[c].sh_err
            arrays["sh_order"] = np.array(table.sh_order)
    with atomic_path(path) as tmp, tmp.open("wb") as f:
        np.savez(f, **arrays)


def merl_directions() -> tuple[np.ndarray, np.ndarray]:
    """(ωi, ωo) at every MERL cell (θh, θd, φd) = ((i/90)² π/2, j/90 · π/2, k/180 · π), with
    φh = 0 (Rusinkiewicz 1998; the cell layout of Matusik et al. 2003's reader).

    Returns
    -------
    wi, wo : (90, 90, 180, 3) float
    """
    i, j, k = (np.arange(n, dtype=float) for n in MERL_SHAPE)
    theta_h = (i / 90.0) ** 2 * (np.pi / 2)
    theta_d = j / 90.0 * (np.pi / 2)
    phi_d = k / 180.0 * np.pi
    th, td, pd = np.meshgrid(theta_h, theta_d, phi_d, indexing="ij")
    return half_difference(th, td, pd)


def write_merl(table: BRDFTable, path: str | Path, component: str = "total") -> None:
    """MERL ``.binary``: int32 dims (90, 90, 180), then float64 R, G, B planes over
    (θh, θd, φd), little-endian. Stored values are f_r / scale per channel, so readers
    that multiply by 1/1500, 1.15/1500, 1.66/1500 get f_r back; cells with either
    direction at or below the horizon hold −1. Isotropic tables only (the format is).

    A spectral table's R, G, B are the linear sRGB of its f_r (``srgb_linear``: CIE 1931
    2°, D65, negative components 0), evaluated one θh row of cells at a time (the
    C-channel grid at once would need C/3 times an RGB table's memory)."""
    if not table.isotropic:
        raise ValueError("MERL files hold isotropic BRDFs; this table is anisotropic")
    wi, wo = merl_directions()
    if table.channels.spectral:
        nm = table.channels.wavelengths
        f = np.stack([srgb_linear(nm, table.eval(wi[i], wo[i], component))
                      for i in range(MERL_SHAPE[0])]) / MERL_SCALE
    else:
        f = table.eval(wi, wo, component) / MERL_SCALE
    below = (wi[..., 2] <= 0) | (wo[..., 2] <= 0)
    f[below] = -1.0
    planes = np.ascontiguousarray(np.moveaxis(f, -1, 0), dtype="<f8")
    with atomic_path(path) as tmp, tmp.open("wb") as out:
        out.write(struct.pack("<3i", *MERL_SHAPE))
        out.write(planes.tobytes())


def _tensor_file(fields: dict[str, np.ndarray]) -> bytes:
    """The RGL tensor file: magic ``tensor_file\\0``, version (1, 0), the field count,
    then per field its name, rank, type code, data offset and shape, then the data at
    8-byte aligned offsets, all little-endian (Mitsuba 3, ``TensorFile``)."""
    codes = {np.dtype(np.uint8): 1, np.dtype(np.float32): 10}
    header = [b"tensor_file\0", struct.pack("<BBI", 1, 0, len(fields))]
    size = sum(len(h) for h in header) + sum(
        2 + len(name.encode()) + 2 + 1 + 8 + 8 * a.ndim for name, a in fields.items())
    blobs, offsets = [], []
    for a in fields.values():
        size = (size + 7) // 8 * 8
        offsets.append(size)
        blobs.append(a.tobytes())
        size += len(blobs[-1])
    for (name, a), offset in zip(fields.items(), offsets, strict=True):
        label = name.encode()
        header.append(struct.pack("<H", len(label)) + label
                      + struct.pack("<HBQ", a.ndim, codes[a.dtype], offset)
                      + struct.pack(f"<{a.ndim}Q", *a.shape))
    out = bytearray(b"".join(header))
    for blob, offset in zip(blobs, offsets, strict=True):
        out += bytes(offset - len(out)) + blob
    return bytes(out)


LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
"""Rec. 709 luminance weights of linear R, G, B (what the RGL sampling map holds)."""
SAMPLING_FLOOR = 0.01
"""Share of the mean that every node of the sampling map keeps, so the sampling density
is positive wherever the interpolated BRDF is (the estimate stays unbiased)."""


def rgl_phi_i(step_deg: float = 15.0) -> np.ndarray:
    """Incident azimuths of an anisotropic RGL file: −π … π in ``step_deg`` steps, both
    ends included (Mitsuba 3's ``measured`` reads more than two φi values as anisotropic and
    folds none of them when they span 2π)."""
    n = int(round(360.0 / step_deg))
    return np.linspace(-np.pi, np.pi, n + 1)


def rgl_tensor(f: Any, theta_i: np.ndarray, phi_i: np.ndarray | None, resolution: int,
               description: str, wavelengths: Sequence[float] | None = None
               ) -> dict[str, np.ndarray]:
    """The fields of an RGL ``.bsdf`` (Dupuy & Jakob 2018) sampling any BRDF.

    The colour grid is the plain vertex grid a uniform VNDF gives: axes (φm, θm) with
    u = 0…1 in ``resolution`` steps, θm = u² π/2 and φm = 2πu − π, measured from φi when
    isotropic and from the tangent (absolute) otherwise; each value is f_r(ωi, ωo) cos θo
    at the mirror direction ωo of ωi about m, which Mitsuba 3's ``measured`` plugin returns
    as its ``eval`` (it includes the cosine). NDF, σ and VNDF are uniform (ones). The
    ``luminance`` map, which Mitsuba samples before the VNDF, holds the integrand of the
    albedo in these coordinates, Y(f_r cos θo) · 2π² u sin θm · 4 ⟨ωi, m⟩ (the Jacobian
    of u → ωo that the plugin divides by), plus ``SAMPLING_FLOOR`` of its mean: sampling
    follows the lobe, and every sample's weight is close to the albedo.

    With ``wavelengths`` the file is spectral, as Mitsuba 3 reads one (src/bsdfs/
    measured.cpp, ``Measured::Measured``: a file with a ``wavelengths`` field is spectral
    and needs a spectral variant; its ``spectra`` field has shape [φi, θi, wavelengths,
    H, H], the same order as ``rgb``, and is interpolated linearly in wavelength between
    the fields' wavelengths and clamped beyond them, ``Marginal2D``'s parameter lookup):
    ``wavelengths`` (f32, nm), ``spectra`` (the C channels of f), and ``rgb``, the linear
    sRGB of the spectra (``srgb_linear``; a reader of RGB files finds its field, though
    Mitsuba 3's RGB variants refuse any file that has ``wavelengths``); Y is then CIE's
    under D65 (``microsim.spectra.colour.luminance``).

    Parameters
    ----------
    f : callable
        ``f(wi, wo) -> (..., C)`` f_r in 1/sr for (..., 3) unit directions: C = 3 (R, G, B)
        without ``wavelengths``, one per wavelength with.
    theta_i : (a,) float
        Incident polar angles of the grid, radians, increasing.
    phi_i : (b,) float or None
        None: isotropic (one slice at φi = 0). Otherwise incident azimuths spanning
        [−π, π] (``rgl_phi_i``).
    resolution : int
        Grid vertices per axis, H ≥ 2.
    description : str
    wavelengths : (C,) float or None
        nm, increasing: the channels of f are these wavelengths.

    Returns
    -------
    dict of str to ndarray
        ``description``, ``jacobian``, ``theta_i``, ``phi_i``, ``ndf``, ``sigma`` (H, H),
        ``vndf``, ``luminance`` (b, a, H, H), ``rgb`` (b, a, 3, H, H); spectral also
        ``wavelengths`` (C,) and ``spectra`` (b, a, C, H, H).
    """
    h = resolution
    u = np.linspace(0.0, 1.0, h)
    theta_m = u**2 * (np.pi / 2)
    phi_m = 2 * np.pi * u - np.pi
    m = direction(theta_m[None, :], phi_m[:, None])  # (φm, θm, 3)
    jac = 2 * np.pi**2 * u[None, :] * np.sin(theta_m)[None, :]  # (1, θm)
    azimuths = np.zeros(1) if phi_i is None else np.asarray(phi_i, float)
    nm = None if wavelengths is None else tuple(float(w) for w in wavelengths)
    rgb = np.zeros((len(azimuths), len(theta_i), 3, h, h), np.float32)
    spectra = None if nm is None else np.zeros(
        (len(azimuths), len(theta_i), len(nm), h, h), np.float32)
    lum = np.zeros((len(azimuths), len(theta_i), h, h), np.float32)
    for b, phi in enumerate(azimuths):
        for a, theta in enumerate(theta_i):
            wi = direction(theta, phi)
            cos_d = m @ wi
            wo = 2 * cos_d[..., None] * m - wi
            value = np.asarray(f(np.broadcast_to(wi, wo.shape), wo)) * np.maximum(
                wo[..., 2:3], 0.0)
            if spectra is None:
                rgb[b, a] = np.moveaxis(value, -1, 0)
                y = value @ LUMINANCE
            else:
                from microsim.spectra.colour import luminance

                spectra[b, a] = np.moveaxis(value, -1, 0)
                rgb[b, a] = np.moveaxis(srgb_linear(nm, value), -1, 0)
                y = luminance(nm, value)
            density = y.clip(0.0) * jac * 4 * np.maximum(cos_d, 0.0)
            lum[b, a] = density + SAMPLING_FLOOR * density.mean() + 1e-30
    ones = np.ones((h, h), np.float32)
    fields = {
        "description": np.frombuffer(description.encode(), np.uint8),
        "jacobian": np.zeros(1, np.uint8),
        "theta_i": np.asarray(theta_i, np.float32),
        "phi_i": azimuths.astype(np.float32),
        "ndf": ones, "sigma": ones,
        "vndf": np.ones(lum.shape, np.float32),
        "luminance": lum,
    }
    if spectra is not None:
        fields["wavelengths"] = np.asarray(nm, np.float32)
        fields["spectra"] = spectra
    fields["rgb"] = rgb
    return fields


def rgl_fields(table: BRDFTable, resolution: int = 32, component: str = "total",
               description: str = "", theta_i: np.ndarray | None = None,
               phi_step: float = 15.0, rgb: bool = False) -> dict[str, np.ndarray]:
    """The fields of an RGL ``.bsdf`` of a table (``rgl_tensor`` of ``table.eval``).

    Isotropic tables give one φi slice with φm relative to φi; anisotropic ones a slice
    every ``phi_step`` degrees over [−180°, 180°] with absolute φm (the table's local x
    axis is the tangent), ``table.eval`` interpolating between the table's own φi.
    ``theta_i`` (radians) resamples the incidences (default: the table's). A spectral
    table gives a spectral file (``spectra``, ``wavelengths`` and its sRGB as ``rgb``),
    or with ``rgb`` an RGB file of its linear sRGB (``srgb_linear``), the only kind
    Mitsuba 3's RGB variants load; ``rgb`` changes nothing for an RGB table.
    """
    nm = table.channels.wavelengths

    def f(wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        value = table.eval(wi, wo, component)
        return srgb_linear(nm, value) if nm is not None and rgb else value

    return rgl_tensor(f, table.theta_i if theta_i is None else theta_i,
                      None if table.isotropic else rgl_phi_i(phi_step), resolution,
                      description or "microsim table", None if rgb else nm)


def write_rgl(table: BRDFTable, path: str | Path, resolution: int = 32,
              component: str = "total", rgb: bool = False) -> None:
    """Write an RGL tensor file ``.bsdf`` (see ``rgl_fields``)."""
    kind = "" if table.meta.surface is None else table.meta.surface.tile.kind
    fields = rgl_fields(table, resolution, component,
                        f"microsim {component} BRDF of a {kind} surface", rgb=rgb)
    write_tensor_file(fields, path)


def write_tensor_file(fields: dict[str, np.ndarray], path: str | Path) -> None:
    """Write RGL fields (``rgl_tensor``) as a tensor file, atomically."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(_tensor_file(fields))


MITSUBA_SPECTRUM = 4
"""Wavelengths a Mitsuba 3 spectral variant carries per ray (``si.wavelengths``)."""


def rgl_through_mitsuba(table: BRDFTable, path: str | Path, pairs: int,
                        rng: np.random.Generator, lobe_fraction: float = 0.1,
                        variant: str = "scalar_rgb",
                        wavelengths: Sequence[float] | None = None
                        ) -> tuple[np.ndarray, np.ndarray]:
    """Evaluate an RGL file with Mitsuba 3's ``measured`` plugin against the table.

    Direction pairs are drawn around the mirror direction (θi among the table's
    incidences (θi, φi), θo uniform in [0, 85°], φo − φi
    normal about π with σ = 0.5) and kept where
    f_r cos θo is at least ``lobe_fraction`` of its value in the mirror direction.
    Needs the ``mitsuba`` package (a development dependency); sets ``variant``.

    In ``scalar_rgb`` the file is an RGB one: the reference is the table's R, G, B, or a
    spectral table's ``srgb_linear``. In ``scalar_spectral`` the file is spectral and
    Mitsuba's ``eval`` is asked at chosen wavelengths (``si.wavelengths``, four at a
    time): ``wavelengths`` (default the table's own), the reference being the table's
    channels interpolated linearly in wavelength there and held constant beyond its
    first and last, as the plugin's lookup does.

    Parameters
    ----------
    table : BRDFTable
        The table the file was written from.
    path : str or Path
        The ``.bsdf`` file.
    pairs : int
        Direction pairs to keep.
    rng : numpy.random.Generator
    lobe_fraction : float
    variant : str
        ``"scalar_rgb"`` or ``"scalar_spectral"``.
    wavelengths : (W,) float or None
        nm; spectral variant only.

    Returns
    -------
    reference, mitsuba : (pairs, 3) or (pairs, W) float
        ``table.eval · cos θo`` and Mitsuba's ``eval`` (which includes cos θo).
    """
    import mitsuba as mi

    mi.set_variant(variant)
    spectral = bool(mi.is_spectral)
    nm = table.channels.wavelengths
    if spectral and nm is None:
        raise ValueError("a spectral variant reads spectral files: the table is RGB")
    query = (np.asarray(nm if wavelengths is None else wavelengths, float) if spectral
             else None)
    bsdf = mi.load_dict({"type": "measured", "filename": str(path)})
    rows: list[tuple[np.ndarray, np.ndarray]] = []
    while len(rows) < pairs:
        phi = rng.choice(table.phi_i)
        wi = direction(rng.choice(table.theta_i), phi)
        wo = direction(np.radians(rng.uniform(0, 85)), phi + np.pi + rng.normal(0, 0.5))
        ref = table.eval(wi, wo) * wo[2]
        if ref.mean() < lobe_fraction * table.eval(wi, wi * [-1, -1, 1]).mean() * wi[2]:
            continue
        si = mi.SurfaceInteraction3f()
        si.wi = mi.Vector3f(*wi)
        if query is None:
            value = bsdf.eval(mi.BSDFContext(), si, mi.Vector3f(*wo))
            got = np.array([value[0], value[1], value[2]])
            if nm is not None:
                ref = srgb_linear(nm, ref)
        else:
            got = np.empty(len(query))
            for start in range(0, len(query), MITSUBA_SPECTRUM):
                group = query[start:start + MITSUBA_SPECTRUM]
                padded = np.resize(group, MITSUBA_SPECTRUM)
                si.wavelengths = mi.Spectrum(*(float(x) for x in padded))
                value = bsdf.eval(mi.BSDFContext(), si, mi.Vector3f(*wo))
                got[start:start + len(group)] = [value[i] for i in range(len(group))]
            ref = np.array([np.interp(query, nm, ref)]).ravel()
        rows.append((ref, got))
    return np.array([r for r, _ in rows]), np.array([g for _, g in rows])
