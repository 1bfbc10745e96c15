"""The hemisphere as an equal-area square, and a table's bins resampled onto it.

**The map.** A point (a, b) of the square [−1, 1]² goes to the unit disk by Shirley &
Chiu's concentric map (Shirley & Chiu 1997, "A low distortion map between disk and
square", J. Graphics Tools 2(3), 45-52, eq. 4): in the sector |a| ≥ |b|, a > 0,

    r = a,   φ = (π/4) (b / a),

and the other three sectors are the same turned by multiples of 90°, so concentric squares
go to concentric circles and rays from the centre to rays. Its Jacobian is the constant
π/4 (area of the disk over that of the square). The disk goes to the hemisphere by the
equal-area (Lambert azimuthal) lift

    z = cos θ = 1 − r²,   sin θ = r √(2 − r²),

whose Jacobian is 2 (dω = sin θ dθ dφ = |dz| dφ = 2 r dr dφ; Clarberg 2008, "Fast
equal-area mapping of the (hemi)sphere using SIMD", J. Graphics Tools 13(3), 53-68,
eq. 3, composes the two likewise). So dω = (π/2) da db: an N × N grid of square pixels
has pixels of equal solid angle 2π / N², and a sum over pixels times 2π / N² is the
integral over the hemisphere. Azimuths follow the local frame (φ from +x towards +y);
pixel (i, j) has its centre at a = −1 + (2j + 1)/N, b = −1 + (2i + 1)/N.

**The bins on the square.** A table bin, u = sin²θ ∈ [u₀, u₁] and φ ∈ [φ₀, φ₁], is an
annular sector of the disk, r ∈ [√(1 − cos θ₀), √(1 − cos θ₁)]; in each sector of the
concentric map that is the polygon {x ∈ [r₀, r₁], t₀ x ≤ y ≤ t₁ x} (t = 4φ/π in the
sector's own frame). Its overlap with a pixel [x_a, x_b] × [y_a, y_b] is the integral
over x of a piecewise-linear width, max(0, min(y_b, t₁x) − max(y_a, t₀x)), exact by the
trapezoid rule on its breakpoints. ``overlaps`` gives Ω(pixel ∩ bin) for every pair, so
resampling is exact area weighting: a pixel's value is the solid-angle-weighted mean of
the bins it overlaps (the table read as constant over each bin), and a bin's value back
from the grid is the solid-angle-weighted mean of the pixels it overlaps.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from microsim.tables.binning import HemisphereBins

QUARTER = 0.5 * math.pi
"""The angle between the centres of two sectors of the concentric map."""


def pixel_solid_angle(n: int) -> float:
    """Ω of one pixel of an n × n grid: 2π / n², sr."""
    return 2.0 * math.pi / (n * n)


def to_hemisphere(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Unit directions of square points (concentric map, then the equal-area lift).

    Parameters
    ----------
    a, b : (...) float
        Square coordinates in [−1, 1] (a along +x, b along +y).

    Returns
    -------
    (..., 3) float
    """
    a, b = np.broadcast_arrays(np.asarray(a, float), np.asarray(b, float))
    r = np.maximum(np.abs(a), np.abs(b))
    along_a = np.abs(a) >= np.abs(b)
    with np.errstate(divide="ignore", invalid="ignore"):
        phi = np.where(along_a, 0.25 * math.pi * b / a + np.where(a < 0, math.pi, 0.0),
                       QUARTER - 0.25 * math.pi * a / b + np.where(b < 0, math.pi, 0.0))
    phi = np.where(r > 0, phi, 0.0)
    s = r * np.sqrt(np.maximum(2.0 - r * r, 0.0))
    return np.stack([s * np.cos(phi), s * np.sin(phi), 1.0 - r * r], axis=-1)


def to_square(w: np.ndarray, phi_ref: float | np.ndarray = 0.0
              ) -> tuple[np.ndarray, np.ndarray]:
    """Square coordinates of unit directions on or above the horizon (the inverse of
    ``to_hemisphere``): r = √(1 − z), then the sector's line through the centre.

    Parameters
    ----------
    w : (..., 3) float
    phi_ref : float or (...) float
        Azimuth subtracted from each direction's (φi for an isotropic table).

    Returns
    -------
    a, b : (...) float
    """
    w = np.asarray(w, float)
    r = np.sqrt(np.clip(1.0 - w[..., 2], 0.0, 1.0))
    phi = np.arctan2(w[..., 1], w[..., 0]) - phi_ref
    sector = np.round(phi / QUARTER)
    t = (phi - sector * QUARTER) / (0.25 * math.pi)          # in [−1, 1]
    x, y = r, r * t
    turn = np.mod(sector, 4).astype(np.int64)
    a = np.choose(turn, [x, -y, -x, y])
    b = np.choose(turn, [y, x, -y, -x])
    return a, b


def _pieces(bins: HemisphereBins) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every bin's azimuth range (with its mirror image when folded) cut at the sector
    boundaries of the concentric map: the sector, t₀ and t₁ in its frame, and the bin's
    φ index, one entry per piece."""
    lo, hi, which = bins.phi_edges[:-1], bins.phi_edges[1:], np.arange(bins.phi_bins)
    if bins.folded:
        lo, hi, which = (np.concatenate([lo, -hi]), np.concatenate([hi, -lo]),
                         np.concatenate([which, which]))
    # sector k covers φ ∈ [(k − ½)·90°, (k + ½)·90°]; every range is cut where it crosses
    first = np.floor(lo / QUARTER + 0.5).astype(np.int64)
    last = np.ceil(hi / QUARTER + 0.5).astype(np.int64) - 1
    sectors, t0, t1, index = [], [], [], []
    for k in range(int(first.min()), int(last.max()) + 1):
        has = (first <= k) & (last >= k)
        centre = k * QUARTER
        a = np.maximum(lo[has], centre - 0.5 * QUARTER)
        b = np.minimum(hi[has], centre + 0.5 * QUARTER)
        keep = b > a
        sectors.append(np.full(int(keep.sum()), k % 4))
        t0.append((a[keep] - centre) / (0.25 * math.pi))
        t1.append((b[keep] - centre) / (0.25 * math.pi))
        index.append(which[has][keep])
    return (np.concatenate(sectors), np.concatenate(t0), np.concatenate(t1),
            np.concatenate(index))


def _width(x: np.ndarray, ya: np.ndarray, yb: np.ndarray, t0: np.ndarray, t1: np.ndarray
           ) -> np.ndarray:
    """Length of [y_a, y_b] ∩ [t₀x, t₁x] at each x."""
    return np.maximum(0.0, np.minimum(yb, t1 * x) - np.maximum(ya, t0 * x))


@lru_cache(maxsize=8)
def overlaps(n: int, theta_bins: int, phi_bins: int, phi_period: float):
    """Ω(pixel ∩ bin) for every pixel of an n × n grid and every bin of
    ``HemisphereBins(theta_bins, phi_bins, phi_period)`` (a folded bin covers its mirror
    image too), exact (module docstring).

    Parameters
    ----------
    n : int
        Pixels per side (even, so the grid is symmetric about the centre).
    theta_bins, phi_bins : int
    phi_period : float

    Returns
    -------
    scipy.sparse.csr_matrix
        (n², nt·np), sr; rows in pixel order ``i * n + j``, columns in the table's flat
        bin order ``it * phi_bins + ip``. Every row sums to 2π / n², every column to the
        bin's solid angle.
    """
    import scipy.sparse

    if n < 2 or n % 2:
        raise ValueError(f"resolution {n}: must be even and >= 2")
    bins = HemisphereBins(theta_bins, phi_bins, phi_period)
    sector, t0, t1, ip = _pieces(bins)
    edges = np.linspace(-1.0, 1.0, n + 1)
    radii = np.sqrt(1.0 - np.cos(bins.theta_edges))
    rows, cols, vals = [], [], []
    for it in range(bins.theta_bins):
        r0, r1 = radii[it], radii[it + 1]
        jj = np.flatnonzero((edges[1:] > r0) & (edges[:-1] < r1))      # x columns
        ii = np.flatnonzero((edges[1:] > -r1) & (edges[:-1] < r1))     # y rows
        p, j, i = (g.ravel() for g in np.meshgrid(np.arange(len(t0)), jj, ii,
                                                  indexing="ij"))
        lo, hi = np.maximum(edges[j], r0), np.minimum(edges[j + 1], r1)
        ya, yb, a0, a1 = edges[i], edges[i + 1], t0[p], t1[p]
        with np.errstate(divide="ignore", invalid="ignore"):
            kinks = [np.where(t != 0, y / t, lo) for t in (a0, a1) for y in (ya, yb)]
        x = np.sort(np.stack([lo, hi, *(np.clip(k, lo, hi) for k in kinks)]), axis=0)
        width = _width(x, ya, yb, a0, a1)
        area = 0.5 * (np.diff(x, axis=0) * (width[1:] + width[:-1])).sum(axis=0)
        keep = area > 0
        # the sector's frame turned back: (x, y) → (−y, x) per quarter turn
        s, j, i = sector[p][keep], j[keep], i[keep]
        col = np.choose(s, [j, n - 1 - i, n - 1 - j, i])
        row = np.choose(s, [i, j, n - 1 - i, n - 1 - j])
        rows.append(row * n + col)
        cols.append(it * bins.phi_bins + ip[p][keep])
        vals.append(0.5 * math.pi * area[keep])
    return scipy.sparse.coo_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
        shape=(n * n, bins.size)).tocsr()


class Resampling:
    """A table's bins and an n × n equal-area grid, each read as piecewise constant, and
    the area-weighted means between them (``overlaps``).

    Values on both sides are means per unit solid angle of g = f_r cos θo (so a table's
    bin value f̄, a mean per projected solid angle, is f̄ Ω_proj / Ω on this side).

    Parameters
    ----------
    n : int
        Pixels per side (even).
    bins : HemisphereBins
    """

    def __init__(self, n: int, bins: HemisphereBins) -> None:
        self.n = int(n)
        self.bins = bins
        self.matrix = overlaps(self.n, bins.theta_bins, bins.phi_bins, bins.phi_period)
        self.bin_solid_angle = np.asarray(self.matrix.sum(axis=0)).ravel()
        self.pixel_solid_angle = pixel_solid_angle(self.n)

    def to_grid(self, g_bins: np.ndarray) -> np.ndarray:
        """Pixel means of bin means.

        Parameters
        ----------
        g_bins : (..., nt·np) float

        Returns
        -------
        (..., n, n) float
        """
        flat = np.asarray(g_bins, float)
        out = (self.matrix @ flat.reshape(-1, flat.shape[-1]).T).T / self.pixel_solid_angle
        return out.reshape(flat.shape[:-1] + (self.n, self.n))

    def to_bins(self, grid: np.ndarray) -> np.ndarray:
        """Bin means of pixel means.

        Parameters
        ----------
        grid : (..., n, n) float

        Returns
        -------
        (..., nt·np) float
        """
        flat = np.asarray(grid, float).reshape(grid.shape[:-2] + (-1,))
        out = (self.matrix.T @ flat.reshape(-1, flat.shape[-1]).T).T / self.bin_solid_angle
        return out.reshape(flat.shape[:-1] + (self.bins.size,))
