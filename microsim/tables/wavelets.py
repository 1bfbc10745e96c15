"""Wavelets of a table's outgoing hemisphere: an orthonormal basis on the equal-area
square, coefficients kept by magnitude.

Per incidence, component and channel (R, G, B, or one per wavelength of a spectral
table), the function g(ωo) = f_r(ωi, ωo) cos θo (the one
the table's spherical harmonics expand, ``microsim.tables.sh``) is resampled from the bins
onto an n × n grid of the equal-area square (``microsim.tables.equal_area``: Shirley-Chiu
concentric map and the equal-area lift, every pixel 2π / n² sr; the bins' overlaps with
the pixels are exact areas) and transformed with PyWavelets' 2-D discrete wavelet
transform (``wavedec2``) in ``periodization`` mode with an orthogonal wavelet (Haar or
Daubechies): the transform of the n² pixel values is then an orthogonal matrix (Mallat
1989, "A theory for multiresolution signal decomposition", IEEE PAMI 11(7), 674-693;
Daubechies 1988, "Orthonormal bases of compactly supported wavelets", Comm. Pure Appl.
Math. 41, 909-996), so with the pixels' equal solid angle Ω_p it is orthonormal in the
discrete L2(dω) norm: Σ_p Ω_p g_p² = Ω_p Σ_k c_k² (Parseval). Dropping coefficients
changes that norm of g by exactly the energy Ω_p Σ_dropped c_k², which keeping the largest
|c_k| minimises for every count.

Coefficients are ordered as ``pywt.coeffs_to_array`` lays out ``wavedec2``'s list (the
coarse approximation in the top left corner), flattened row by row; a stored set keeps,
per incidence and channel, the fewest largest coefficients whose dropped energy is at most
target² of the total (the relative L2 error on the hemisphere), or a fixed count.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np

from microsim.spectra.channels import RGB_NAMES
from microsim.tables.binning import HemisphereBins
from microsim.tables.equal_area import Resampling, to_square
from microsim.tables.evaluate import CHUNK, Axes, blend_incidences
from microsim.tables.interpolation import linear_weights

FAMILIES = ("haar", "db", "sym", "coif")
"""PyWavelets' families of orthogonal wavelets (the biorthogonal ones are not
orthonormal, so Parseval would not hold)."""
DEFAULT_WAVELET = "haar"
DEFAULT_RESOLUTION = 256
"""Pixels per side of the square: 65 536 pixels of 0.096 × 10⁻³ sr, 32 per bin of the
default 32 × 64 table."""
MODE = "periodization"
VALUE_BYTES = 4
"""A kept coefficient's value: float32."""


def index_bytes(total: int) -> int:
    """Bytes of a kept coefficient's index among ``total``: 2 up to 65 536, else 4."""
    return 2 if total <= 1 << 16 else 4


def wavelet_of(name: str) -> Any:
    """The ``pywt.Wavelet`` of an orthogonal wavelet's name.

    Raises
    ------
    ValueError
        If PyWavelets does not know the name or the wavelet is not orthogonal.
    """
    import pywt

    if name not in pywt.wavelist(kind="discrete"):
        raise ValueError(f"wavelet {name!r}: not a discrete wavelet PyWavelets knows; "
                         "use an orthogonal one: haar, db1..db38, sym2..sym20, coif1..coif17")
    wavelet = pywt.Wavelet(name)
    if wavelet.short_family_name not in FAMILIES or not wavelet.orthogonal:
        raise ValueError(f"wavelet {name!r}: not of the orthogonal families haar, db<N>, "
                         "sym<N>, coif<N> (a biorthogonal transform is not orthonormal)")
    return wavelet


def check_resolution(n: int) -> int:
    """``n`` if it is a power of two from 4 to 1024 (the periodized transform halves the
    grid at every level).

    Raises
    ------
    ValueError
        Otherwise.
    """
    if not 4 <= n <= 1024 or n & (n - 1):
        raise ValueError(f"resolution {n}: must be a power of two from 4 to 1024")
    return n


def levels(n: int, wavelet: str) -> int:
    """Decomposition levels: the most at which no filter is longer than the data
    (``pywt.dwt_max_level``)."""
    import pywt

    return pywt.dwt_max_level(n, wavelet_of(wavelet).dec_len)


@lru_cache(maxsize=16)
def _slices(n: int, wavelet: str) -> Any:
    """``pywt.coeffs_to_array``'s slices of a stack of n × n transforms, (m, n, n)."""
    import pywt

    coeffs = pywt.wavedec2(np.zeros((1, n, n)), wavelet, mode=MODE,
                           level=levels(n, wavelet), axes=(-2, -1))
    slices = pywt.coeffs_to_array(coeffs, axes=(-2, -1))[1]

    def whole_stack(s: tuple[slice, ...]) -> tuple[slice, ...]:
        return (slice(None),) + tuple(s[1:])

    return [whole_stack(slices[0])] + [{k: whole_stack(v) for k, v in d.items()}
                                       for d in slices[1:]]


def forward(grid: np.ndarray, wavelet: str) -> np.ndarray:
    """Orthonormal wavelet coefficients of square grids.

    Parameters
    ----------
    grid : (..., n, n) float
    wavelet : str

    Returns
    -------
    (..., n²) float
    """
    import pywt

    n = grid.shape[-1]
    coeffs = pywt.wavedec2(grid, wavelet_of(wavelet), mode=MODE, level=levels(n, wavelet),
                           axes=(-2, -1))
    return pywt.coeffs_to_array(coeffs, axes=(-2, -1))[0].reshape(grid.shape[:-2] + (n * n,))


def inverse(coefficients: np.ndarray, wavelet: str) -> np.ndarray:
    """Grids of wavelet coefficients (the inverse of ``forward``).

    Parameters
    ----------
    coefficients : (..., n²) float
    wavelet : str

    Returns
    -------
    (..., n, n) float
    """
    import pywt

    n = int(round(np.sqrt(coefficients.shape[-1])))
    array = coefficients.reshape(-1, n, n)
    coeffs = pywt.array_to_coeffs(array, _slices(n, wavelet), output_format="wavedec2")
    grids = pywt.waverec2(coeffs, wavelet_of(wavelet), mode=MODE, axes=(-2, -1))
    return grids.reshape(coefficients.shape[:-1] + (n, n))


def ranks(coefficients: np.ndarray) -> np.ndarray:
    """Each coefficient's rank by magnitude along the last axis (0: the largest; ties in
    index order), so ``ranks < k`` keeps the k largest."""
    order = np.argsort(-np.abs(coefficients), axis=-1, kind="stable")
    out = np.empty_like(order)
    np.put_along_axis(out, order, np.broadcast_to(np.arange(order.shape[-1]), order.shape),
                      axis=-1)
    return out


def kept_for(coefficients: np.ndarray, target: float) -> np.ndarray:
    """The fewest largest coefficients along the last axis whose dropped energy is at most
    ``target``² of the total (relative L2 error ≤ target, by Parseval).

    Parameters
    ----------
    coefficients : (..., m) float
    target : float
        > 0.

    Returns
    -------
    (...) int
        0 where every coefficient is 0.
    """
    energy = np.sort(coefficients ** 2, axis=-1)[..., ::-1]
    total = energy.sum(axis=-1, keepdims=True)
    dropped = total - np.cumsum(energy, axis=-1)          # after keeping 1, 2, …, m
    enough = dropped <= target ** 2 * total * (1.0 + 1e-12)
    return np.where(total[..., 0] > 0, np.argmax(enough, axis=-1) + 1, 0)


def bin_cos(bins: HemisphereBins) -> np.ndarray:
    """(nt·np,) mean cos θ over each bin, Ω_proj / Ω = ½ Δ(sin²θ) / Δ(cos θ): the factor
    from a bin's f_r (a mean per projected solid angle) to its g (a mean per solid
    angle)."""
    ring = 0.5 * np.diff(bins.u_edges) / -np.diff(np.cos(bins.theta_edges))
    return np.repeat(ring, bins.phi_bins)


def table_grids(values: np.ndarray, resampling: Resampling) -> np.ndarray:
    """g on the equal-area grid of every incidence and channel of a table component.

    Parameters
    ----------
    values : (a, b, nt, np, C) float
        The component's f_r.
    resampling : Resampling

    Returns
    -------
    (a, b, C, n, n) float
    """
    a, b = values.shape[:2]
    g = values.reshape(a, b, -1, values.shape[-1]) * bin_cos(resampling.bins)[:, None]
    return resampling.to_grid(np.moveaxis(g, -1, -2))


def grid_bins(grids: np.ndarray, resampling: Resampling) -> np.ndarray:
    """f_r per bin, (a, b, nt, np, C), of g on the grid, (a, b, C, n, n): the inverse of
    ``table_grids`` where the grid is constant over each bin."""
    g = np.moveaxis(resampling.to_bins(grids), -2, -1)
    f = g / bin_cos(resampling.bins)[:, None]
    return f.reshape(grids.shape[:2] + resampling.bins.shape + (grids.shape[2],))


@dataclass(frozen=True)
class Wavelets:
    """Wavelet coefficients kept per incidence and channel, for every component.

    Parameters
    ----------
    wavelet : str
    resolution : int
        n, pixels per side of the square.
    values : dict of str to (a, b, K, C) float
        Kept coefficients per component (K the most kept at any incidence and channel;
        the rest of a row is padding of value 0).
    indices : dict of str to (a, b, K, C) int
        Their flat indices in [0, n²).
    target_error : float or None
        The relative L2 error they were kept to (None: a fixed count).
    keep : int or None
        The fixed count they were kept to (None: a target error).
    channels : tuple of str
        The names of the C channels (``Channels.names``: R, G, B, or ``550nm`` …), the
        suffixes of the file's channels.
    """

    wavelet: str
    resolution: int
    values: Mapping[str, np.ndarray]
    indices: Mapping[str, np.ndarray]
    target_error: float | None = None
    keep: int | None = None
    channels: tuple[str, ...] = RGB_NAMES

    def coefficients(self, component: str) -> np.ndarray:
        """(a, b, C, n²) dense coefficients of a component (dropped ones 0)."""
        values = np.moveaxis(self.values[component], -1, -2)          # (a, b, C, K)
        indices = np.moveaxis(self.indices[component], -1, -2).astype(np.int64)
        out = np.zeros(values.shape[:-1] + (self.resolution ** 2,))
        rows = np.arange(out[..., 0].size).reshape(out.shape[:-1] + (1,))
        # added, not assigned: padding (value 0) may share index 0 with a kept value
        np.add.at(out.reshape(-1, out.shape[-1]), (np.broadcast_to(rows, indices.shape),
                                                   indices), values)
        return out

    def grids(self, component: str) -> np.ndarray:
        """(a, b, C, n, n) g = f_r cos θo on the grid, from the kept coefficients."""
        return inverse(self.coefficients(component), self.wavelet)

    def kept(self, component: str) -> np.ndarray:
        """(a, b, C) coefficients kept per incidence and channel (non-zero values)."""
        return np.count_nonzero(self.values[component], axis=-2)


def encode(values: Mapping[str, np.ndarray], bins: HemisphereBins, resolution: int,
           wavelet: str, target_error: float | None = None, keep: int | None = None,
           channels: tuple[str, ...] = RGB_NAMES) -> Wavelets:
    """The wavelets of every component of a table, kept to a target error or a count.

    Parameters
    ----------
    values : dict of str to (a, b, nt, np, C) float
        f_r per component (``BRDFTable.values``).
    bins : HemisphereBins
    resolution : int
        A power of two (``check_resolution``).
    wavelet : str
        An orthogonal wavelet (``wavelet_of``).
    target_error : float or None
        Keep the fewest largest coefficients with relative L2 error ≤ this (> 0), per
        incidence and channel.
    keep : int or None
        Or keep this many (≥ 1) per incidence and channel. Exactly one of the two.
    channels : tuple of str
        The names of the C channels (``BRDFTable.channels.names``).

    Returns
    -------
    Wavelets

    Raises
    ------
    ValueError
        For a bad target or count, or values whose last axis is not one per channel.
    """
    if (target_error is None) == (keep is None):
        raise ValueError("give one of target_error and keep")
    if target_error is not None and not target_error > 0:
        raise ValueError(f"target error {target_error}: must be > 0")
    if keep is not None and keep < 1:
        raise ValueError(f"keep {keep}: must be >= 1")
    resampling = Resampling(check_resolution(resolution), bins)
    wavelet_of(wavelet)
    kept_values, kept_indices = {}, {}
    for c, v in values.items():
        if np.shape(v)[-1] != len(channels):
            raise ValueError(f"values[{c!r}] have {np.shape(v)[-1]} channels, the names "
                             f"{len(channels)}")
        coeffs = forward(table_grids(np.asarray(v, float), resampling), wavelet)
        count = (kept_for(coeffs, target_error) if target_error is not None
                 else np.full(coeffs.shape[:-1], min(keep, coeffs.shape[-1])))
        width = max(1, int(count.max()))
        order = np.argsort(-np.abs(coeffs), axis=-1, kind="stable")[..., :width]
        top = np.take_along_axis(coeffs, order, axis=-1)
        top = np.where(np.arange(width) < count[..., None], top, 0.0)
        kept_values[c] = np.moveaxis(top, -2, -1)
        kept_indices[c] = np.moveaxis(np.where(top != 0, order, 0), -2, -1)
    return Wavelets(wavelet, resolution, kept_values, kept_indices, target_error, keep,
                    tuple(channels))


def evaluate(axes: Axes, wavelets: Wavelets, component: str, wi: np.ndarray,
             wo: np.ndarray) -> np.ndarray:
    """f_r from a component's wavelets (``BRDFTable.eval`` with
    ``representation="wavelet"``).

    Per incidence the grid's f_r per pixel, g_p / c_p with c_p the pixel's mean cos θ as
    the resampling reads it (the bins' mean cos θ, ``bin_cos``, resampled by the same
    overlaps, so a table of constant f_r gives it back exactly), is read bilinearly between
    pixel centres in the square's coordinates (clamped at its edges, the horizon), then
    interpolated linearly in θi (and φi) as the bins are.

    Parameters
    ----------
    axes : Axes
    wavelets : Wavelets
    component : str
        A stored component name.
    wi, wo : (..., 3) float

    Returns
    -------
    (..., C) float
        0 where either direction is at or below the horizon.
    """
    n = wavelets.resolution
    cos = Resampling(n, axes.bins).to_grid(bin_cos(axes.bins))     # (n, n)
    f = wavelets.grids(component) / cos                           # (a, b, C, n, n)
    a, b, count = f.shape[:3]
    pixels = np.moveaxis(f, 2, -1).reshape(a * b, n * n, count)
    wi, wo = np.broadcast_arrays(np.asarray(wi, float), np.asarray(wo, float))
    shape = wi.shape[:-1]
    wi, wo = wi.reshape(-1, 3), wo.reshape(-1, 3)
    out = np.zeros((len(wi), count))
    centres = np.arange(n, dtype=float)
    for start in range(0, len(wi), CHUNK):
        i, o = wi[start:start + CHUNK], wo[start:start + CHUNK]
        phi_in = np.arctan2(i[:, 1], i[:, 0]) if axes.isotropic else 0.0
        x, y = to_square(o, phi_in)
        j0, j1, wx = linear_weights(0.5 * (x + 1.0) * n - 0.5, centres)
        i0, i1, wy = linear_weights(0.5 * (y + 1.0) * n - 0.5, centres)
        g = np.zeros((len(i), a * b, count))
        for row, w_row in ((i0, 1.0 - wy), (i1, wy)):
            for col, w_col in ((j0, 1.0 - wx), (j1, wx)):
                g += (w_row * w_col)[:, None, None] * np.moveaxis(
                    pixels[:, row * n + col], 0, 1)
        above = (i[:, 2] > 0) & (o[:, 2] > 0)
        out[start:start + CHUNK] = np.where(above[:, None], blend_incidences(axes, i, g),
                                            0.0)
    return out.reshape(shape + (count,))


COLOURS = RGB_NAMES
"""The channel suffixes of an RGB table's file (a spectral table's are its wavelengths',
``Wavelets.channels``)."""


def part_header(wavelets: Wavelets, shape: tuple[int, int]) -> dict[str, Any]:
    """The ``microsim_wavelet`` attribute of a table file's ``wavelet`` part.

    Parameters
    ----------
    wavelets : Wavelets
    shape : (int, int)
        (n_theta_i, n_phi_i).
    """
    n = wavelets.resolution
    return {"wavelet": wavelets.wavelet, "resolution": n, "mode": MODE,
            "levels": levels(n, wavelets.wavelet),
            "target_error": wavelets.target_error, "keep": wavelets.keep,
            "function": "f_r(wi, wo) cos(theta_o) averaged over each pixel of the square",
            "map": "Shirley-Chiu concentric map of [-1, 1]^2 to the disk, then z = 1 - r^2, "
                   "sin(theta) = r sqrt(2 - r^2); pixel (i, j) centred at a = -1 + (2j+1)/n "
                   "(along +x), b = -1 + (2i+1)/n (along +y); each pixel 2 pi / n^2 sr",
            "azimuth": "as the table's: phi_o - phi_i when isotropic, else phi_o",
            "index": "flat (row-major) index into pywt.coeffs_to_array(pywt.wavedec2("
                     "grid, wavelet, mode, levels)) of the n x n grid",
            "rows": "i_theta_i * n_phi_i + i_phi_i", "shape": list(shape),
            "columns": "kept coefficients, largest first; value 0 (index 0) pads a row",
            "channels": [f"{c}{s}.{k}" for c in wavelets.values for s in ("", "_index")
                         for k in wavelets.channels]}


def part_channels(wavelets: Wavelets) -> dict[str, np.ndarray]:
    """The ``wavelet`` part's channels: float32 ``{c}.{R,G,B}`` (values) and uint32
    ``{c}_index.{R,G,B}`` of every component (a spectral table's: ``{c}.550nm`` …, one per
    wavelength), rows over incidences, columns over kept coefficients (padded to the
    widest component: a part's channels share one size)."""
    width = max(v.shape[2] for v in wavelets.values.values())
    out = {}
    for c, values in wavelets.values.items():
        a, b, k, _ = values.shape
        pad = ((0, 0), (0, 0), (0, width - k), (0, 0))
        padded = np.pad(values, pad), np.pad(wavelets.indices[c], pad)
        for j, colour in enumerate(wavelets.channels):
            out[f"{c}.{colour}"] = np.ascontiguousarray(
                padded[0][..., j].reshape(a * b, width), np.float32)
            out[f"{c}_index.{colour}"] = np.ascontiguousarray(
                padded[1][..., j].reshape(a * b, width), np.uint32)
    return out


def from_part(info: Any, pixels: Mapping[str, np.ndarray], components: tuple[str, ...],
              shape: tuple[int, int], channels: tuple[str, ...] = RGB_NAMES) -> Wavelets:
    """A table file's ``wavelet`` part, checked (the file is untrusted input).

    Parameters
    ----------
    info : Any
        The parsed ``microsim_wavelet`` attribute.
    pixels : dict of str to (a·b, K) array
    components : tuple of str
        The table's components.
    shape : (int, int)
    channels : tuple of str
        The table's channel names (``Channels.names``).

    Raises
    ------
    ValueError
        Naming the key or channel that is not as ``part_header`` and ``part_channels``
        write it.
    """
    if not isinstance(info, dict):
        raise ValueError("the wavelet attribute is not a JSON object")
    name, n = info.get("wavelet"), info.get("resolution")
    if not isinstance(name, str):
        raise ValueError(f"wavelet {name!r}: must be the name of an orthogonal wavelet")
    wavelet_of(name)
    if not isinstance(n, int) or isinstance(n, bool):
        raise ValueError(f"resolution {n!r}: must be a power of two from 4 to 1024")
    check_resolution(n)
    if info.get("mode") != MODE or info.get("levels") != levels(n, name):
        raise ValueError(f"mode {info.get('mode')!r}, levels {info.get('levels')!r}: this "
                         f"microsim reads mode {MODE!r} with {levels(n, name)} levels")
    if list(info.get("shape", [])) != list(shape):
        raise ValueError(f"shape {info.get('shape')!r}: must be the table's incidences "
                         f"{list(shape)}")
    target, keep = info.get("target_error"), info.get("keep")
    names = "/".join(channels)
    values, indices = {}, {}
    for c in components:
        stack = []
        for suffix in ("", "_index"):
            planes = [pixels.get(f"{c}{suffix}.{k}") for k in channels]
            if any(p is None or p.ndim != 2 or p.shape[0] != shape[0] * shape[1]
                   or p.shape != planes[0].shape for p in planes):
                raise ValueError(f"channels {c}{suffix}.{names}: missing, or not "
                                 f"{shape[0] * shape[1]} rows of one width")
            stack.append(np.stack(planes, axis=-1).reshape(shape + (-1, len(channels))))
        value, index = stack
        if index.dtype.kind not in "ui" or not np.isfinite(value).all():
            raise ValueError(f"channels {c}.{names} must be finite floats and "
                             f"{c}_index.{names} unsigned integers")
        if index.size and int(index.max()) >= n * n:
            raise ValueError(f"channel {c}_index: holds {int(index.max())}, must be below "
                             f"{n * n} (n² coefficients)")
        values[c], indices[c] = value.astype(float), index.astype(np.int64)
    return Wavelets(name, n, values, indices,
                    float(target) if isinstance(target, int | float) else None,
                    int(keep) if isinstance(keep, int) else None, tuple(channels))
