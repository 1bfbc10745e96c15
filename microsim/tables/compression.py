"""Error against kept coefficients: a table's spherical harmonics and its wavelets, each
kept by magnitude, measured on the table's lobe bins.

Both bases expand g = f_r cos θo over ωo per incidence, component and channel (R, G, B, or
one per wavelength), and both are
orthonormal in L2(dω) (the harmonics on the sphere, ``microsim.tables.sh``; the wavelets
on the equal-area grid of the hemisphere, ``microsim.tables.wavelets``), so keeping the k
largest |c| is the best k-term choice in that norm for either. A count k means k
coefficients per incidence and channel.

Each truncation is read back as bin averages of g and compared with the table's: the
harmonics' bin average is Σ_k c_k ∫_bin Y_k dω / Ω_bin (``sh_error.bin_integrals``), the
wavelets' is the area-weighted mean of the pixels over the bin
(``equal_area.Resampling.to_bins``). The error of a bin and channel is |ĝ − g| / g, and a
curve gives its median over the lobe bins (``BRDFTable.lobe_mask``) and channels where
g > 0, per incidence and pooled over all of them. With every coefficient kept the
harmonics still differ from the bins by the rays' noise above their order (they were
projected from the rays, not from the bins) and the wavelets by the resampling between
bins and pixels: the last point of each curve is that floor.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from microsim.tables import wavelets
from microsim.tables.equal_area import Resampling
from microsim.tables.sh_error import bin_integrals
from microsim.tables.table import BRDFTable

STEPS_PER_OCTAVE = 2
"""Kept counts per doubling in the default sweep."""


def sweep(total: int, steps_per_octave: int = STEPS_PER_OCTAVE) -> list[int]:
    """Kept counts 1, …, ``total``, geometric with ``steps_per_octave`` per doubling,
    ``total`` last."""
    steps = int(math.ceil(math.log2(total) * steps_per_octave)) if total > 1 else 0
    counts = np.unique(np.round(2.0 ** (np.arange(steps + 1) / steps_per_octave)))
    return sorted({int(c) for c in counts if c < total} | {total})


def keep_largest(coefficients: np.ndarray, rank: np.ndarray, k: int) -> np.ndarray:
    """``coefficients`` with all but the ``k`` of lowest ``rank`` (``wavelets.ranks``) set
    to 0."""
    return np.where(rank < k, coefficients, 0.0)


def median_errors(g: np.ndarray, g_table: np.ndarray, lobe: np.ndarray
                  ) -> tuple[np.ndarray, float]:
    """Median relative error of ``g`` against ``g_table`` over the lobe bins and channels
    where g_table > 0.

    Parameters
    ----------
    g, g_table : (a, b, m, C) float
    lobe : (a, b, m) bool

    Returns
    -------
    per_incidence : (a, b) float
        NaN where an incidence has no lobe bin.
    pooled : float
    """
    where = lobe[..., None] & (g_table > 0)
    rel = np.abs(g - g_table) / np.where(where, g_table, 1.0)
    a, b = where.shape[:2]
    per = np.array([[np.median(rel[i, j][where[i, j]]) if where[i, j].any() else math.nan
                     for j in range(b)] for i in range(a)])
    return per, float(np.median(rel[where])) if where.any() else math.nan


def curves(table: BRDFTable, component: str = "total",
           resolution: int = wavelets.DEFAULT_RESOLUTION,
           wavelet: str = wavelets.DEFAULT_WAVELET,
           steps_per_octave: int = STEPS_PER_OCTAVE) -> dict[str, Any]:
    """Median relative error on the lobe bins against kept coefficients, both bases.

    Parameters
    ----------
    table : BRDFTable
        A table with harmonics.
    component : str
    resolution : int
        Pixels per side of the wavelets' square (a power of two).
    wavelet : str
        An orthogonal wavelet.
    steps_per_octave : int
        Kept counts per doubling (``sweep``).

    Returns
    -------
    dict
        ``sh`` and ``wavelet``: [[kept, median relative error], …] pooled over the
        incidences; ``per_incidence``: per incidence its ``theta_i``, ``phi_i`` (degrees)
        and the same two curves; ``bytes``: per basis the bytes of each count's kept
        coefficients over every incidence and channel (a float32 value and an index
        each); ``bytes_per_coefficient``; ``coefficients``: each basis' total per incidence
        and channel; the ``component``, ``sh_order``, ``wavelet_name``, ``resolution`` and
        ``levels``; ``median_rel_stderr``, the table's own noise on the lobe bins.

    Raises
    ------
    ValueError
        If the table holds no harmonics.
    """
    if not table.has_sh:
        raise ValueError("the table holds no spherical harmonics")
    component = table.component(component)
    a, b = table.rays.shape
    count = table.channels.count
    cos_bin = wavelets.bin_cos(table.bins)[:, None]
    g_table = table[component].values.reshape(a, b, -1, count) * cos_bin
    lobe = table.lobe_mask(component).reshape(a, b, -1)

    integrals, omega = bin_integrals(table.sh_order, table.bins)
    c_sh = np.moveaxis(table[component].sh, -2, -1)                   # (a, b, C, n_sh)

    def sh_bins(c: np.ndarray) -> np.ndarray:
        g = (c.reshape(-1, c.shape[-1]) @ integrals.T) / omega
        return np.moveaxis(g.reshape(a, b, count, -1), -2, -1)

    resampling = Resampling(wavelets.check_resolution(resolution), table.bins)
    c_wv = wavelets.forward(wavelets.table_grids(table[component].values, resampling),
                            wavelet)                                   # (a, b, C, n²)

    def wv_bins(c: np.ndarray) -> np.ndarray:
        return wavelets.grid_bins(wavelets.inverse(c, wavelet), resampling).reshape(
            a, b, -1, count) * cos_bin

    out: dict[str, Any] = {"component": component, "sh_order": table.sh_order,
                           "median_rel_stderr": table.median_rel_stderr(component),
                           "wavelet_name": wavelet, "resolution": resolution,
                           "levels": wavelets.levels(resolution, wavelet)}
    per: list[dict[str, Any]] = [{"theta_i": math.degrees(t), "phi_i": math.degrees(p),
                                  "sh": [], "wavelet": []}
                                 for t in table.theta_i for p in table.phi_i]
    for name, c, to_bins in (("sh", c_sh, sh_bins), ("wavelet", c_wv, wv_bins)):
        total = c.shape[-1]
        rank = wavelets.ranks(c)
        width = wavelets.VALUE_BYTES + wavelets.index_bytes(total)
        pooled, sizes = [], []
        for k in sweep(total, steps_per_octave):
            each, over = median_errors(to_bins(keep_largest(c, rank, k)), g_table, lobe)
            pooled.append([k, over])
            sizes.append(k * width * count * a * b)
            for row, e in zip(per, each.ravel(), strict=True):
                row[name].append([k, float(e)])
        out[name] = pooled
        out.setdefault("bytes", {})[name] = sizes
        out.setdefault("bytes_per_coefficient", {})[name] = width
        out.setdefault("coefficients", {})[name] = total
    out["per_incidence"] = per
    return out


def needed(curve: list[list[float]], target: float) -> int | None:
    """The fewest kept coefficients from which the error stays at or below ``target``
    through the rest of the curve (None if its last point is above it): the median
    relative error is not monotone in the count, so a first crossing could be a
    fluctuation."""
    count = None
    for k, e in reversed(curve):
        if not (e is not None and e <= target):
            break
        count = int(k)
    return count
