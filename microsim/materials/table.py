"""The ``table`` facet: reflection importance-sampled from a simulated BRDF table in the
facet's local frame, weighted by the table's albedo (hierarchies of scale: Westin, Arvo &
Torrance 1992, sec. 3; docs/materials.md).

The kernel reads a table material from the packed arrays ``tab_int`` (a row of ``T_*``
columns per part) and ``tab_f`` (node angles, bin edges, cumulative bin probabilities,
weights) that ``microsim.kernel.tabulated.TabulatedMaterial`` makes of the table file;
``microsim.kernel.tabulated`` derives the sampling and its weights.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from microsim.materials.base import WEIGHTED, Material, kernel
from microsim.materials.optics import TWO_PI
from microsim.schema import key

AXES = ("x", "y", "tangent")
"""What a table material's ``axis`` may name: a world axis, or the per-face tangent a
generator gives (``Tile.tangents``: a velvet fibre's axis)."""

(T_THETA_N, T_THETA_AT, T_PHI_N, T_PHI_AT, T_ISOTROPIC, T_FOLDED, T_THETA_BINS,
 T_PHI_BINS, T_U_EDGES_AT, T_PHI_EDGES_AT, T_CDF_AT, T_WEIGHT_AT, T_AXIS,
 T_TANGENT) = range(14)
"""Columns of a table material's ``tab_int`` row: incidence nodes θi (count, offset in
``tab_f``), φi (count, offset), isotropic, folded, outgoing bins (θo, φo), offsets of the
u = sin²θo edges, of the φo edges, of the cumulative probabilities (node-major, one row of
θo·φo bins per node) and of the weights (one per channel and bin), the world axis of the
frame (0: x, 1: y) and whether the face's tangent replaces it."""
TABLE_COLUMNS = 14
ALONG = 1e-6
"""A frame axis within this of the normal (1 − |n·e|) is replaced (``facet_frame``)."""


@kernel
def _frame_along(nx: float, ny: float, nz: float, axis: int
                 ) -> tuple[float, float, float, float, float, float]:
    """t = (e × n) / r and b = (e − (n·e) n) / r for e the world x (axis 0) or y axis."""
    if axis == 0:
        r = math.sqrt(ny * ny + nz * nz)
        return 0.0, -nz / r, ny / r, (1.0 - nx * nx) / r, -nx * ny / r, -nx * nz / r
    r = math.sqrt(nx * nx + nz * nz)
    return nz / r, 0.0, -nx / r, -ny * nx / r, (1.0 - ny * ny) / r, -ny * nz / r


@kernel
def facet_frame(nx: float, ny: float, nz: float, axis: int, use_tangent: bool, ex: float,
                ey: float, ez: float) -> tuple[float, float, float, float, float, float]:
    """Tangent t and bitangent b of a facet (``microsim.kernel.tabulated``: b is the projection of
    the world axis, or of the face's tangent e, onto the facet plane; t = b × n).

    Where the tangent lies along n the world y axis is used; where the world axis does,
    the other world axis."""
    if use_tangent:
        e_n = ex * nx + ey * ny + ez * nz
        if 1.0 - abs(e_n) >= ALONG:
            bx, by, bz = ex - e_n * nx, ey - e_n * ny, ez - e_n * nz
            r = math.sqrt(bx * bx + by * by + bz * bz)
            bx, by, bz = bx / r, by / r, bz / r
            return by * nz - bz * ny, bz * nx - bx * nz, bx * ny - by * nx, bx, by, bz
        axis = 1
    along = nx if axis == 0 else ny
    if 1.0 - abs(along) < ALONG:
        axis = 1 - axis
    return _frame_along(nx, ny, nz, axis)


@kernel
def _search_right(values: np.ndarray, start: int, count: int, x: float) -> int:
    """``numpy.searchsorted(values[start:start + count], x, side="right")``."""
    lo, hi = 0, count
    while lo < hi:
        mid = (lo + hi) // 2
        if x < values[start + mid]:
            hi = mid
        else:
            lo = mid + 1
    return lo


@kernel
def _pick_node(x: float, nodes: np.ndarray, at: int, m: int, periodic: bool, u: float
               ) -> int:
    """One node of the linear interpolation of x between ``nodes[at:at + m]``, the upper
    one with probability equal to its weight (``microsim.tables.interpolation``: clamped at
    the ends, or periodic over 2π)."""
    if m == 1:
        return 0
    first = nodes[at]
    if not periodic:
        x = min(max(x, first), nodes[at + m - 1])
        i1 = min(max(_search_right(nodes, at, m, x), 1), m - 1)
        lo, hi = nodes[at + i1 - 1], nodes[at + i1]
    else:
        x = first + (x - first) % TWO_PI
        i1 = min(max(_search_right(nodes, at, m, x), 1), m)
        lo = nodes[at + i1 - 1]
        hi = first + TWO_PI if i1 == m else nodes[at + i1]
    w1 = min(max((x - lo) / (hi - lo), 0.0), 1.0)
    return (i1 % m) if u < w1 else i1 - 1


@kernel
def scatter(params: np.ndarray, tab_int: np.ndarray, tab_f: np.ndarray, part: int,
            dx: float, dy: float, dz: float, nx: float, ny: float, nz: float, ex: float,
            ey: float, ez: float, u: tuple, hero: int, fac: np.ndarray
            ) -> tuple[float, float, float, int]:
    """A direction importance-sampled from a BRDF table in the facet's frame, and its
    per-channel weight f_r cos θo / pdf (``microsim.kernel.tabulated`` derives both); nothing is
    transmitted.

    The incidence node is picked with the linear-interpolation weights in θi (and in φi,
    periodic, for anisotropic tables), the bin by its cumulative probability, the direction
    uniformly in projected solid angle inside the bin (u = sin²θo and φo uniform), a
    folded bin's mirror image φo → −φo with probability ½; an isotropic table's azimuths
    are relative to the incidence's."""
    row = tab_int[part]
    u0, u1, u2, u3, u4, u5 = u[0], u[1], u[2], u[3], u[4], u[5]
    tx, ty, tz, bx, by, bz = facet_frame(nx, ny, nz, row[T_AXIS], row[T_TANGENT] != 0,
                                         ex, ey, ez)
    # incidence in the facet frame (ωi = −d)
    x = -(dx * tx + dy * ty + dz * tz)
    y = -(dx * bx + dy * by + dz * bz)
    theta = math.acos(min(max(-(dx * nx + dy * ny + dz * nz), -1.0), 1.0))
    # at the pole the azimuth is 0 (as the goniometer's), whatever the zeros' signs
    phi = math.atan2(y, x) % TWO_PI if x != 0.0 or y != 0.0 else 0.0
    node = _pick_node(theta, tab_f, row[T_THETA_AT], row[T_THETA_N], False, u0)
    isotropic = row[T_ISOTROPIC] != 0
    if not isotropic:
        node = node * row[T_PHI_N] + _pick_node(phi, tab_f, row[T_PHI_AT], row[T_PHI_N],
                                                True, u1)
    n_theta, n_phi = row[T_THETA_BINS], row[T_PHI_BINS]
    size = n_theta * n_phi
    flat = _search_right(tab_f, row[T_CDF_AT] + node * size, size, u2)
    it, ip = flat // n_phi, flat % n_phi
    ue, pe = row[T_U_EDGES_AT], row[T_PHI_EDGES_AT]
    u = tab_f[ue + it] + u3 * (tab_f[ue + it + 1] - tab_f[ue + it])
    po = tab_f[pe + ip] + u4 * (tab_f[pe + ip + 1] - tab_f[pe + ip])
    s = math.sqrt(u)
    lx, ly, lz = s * math.cos(po), s * math.sin(po), math.sqrt(1.0 - u)
    if row[T_FOLDED] != 0 and u5 < 0.5:
        ly = -ly
    if isotropic:
        c, sn = math.cos(phi), math.sin(phi)
        lx, ly = c * lx - sn * ly, sn * lx + c * ly
    channels = fac.shape[1]
    at = row[T_WEIGHT_AT] + channels * (node * size + flat)
    for j in range(channels):
        fac[0, j] = tab_f[at + j]
    return (lx * tx + ly * bx + lz * nx, lx * ty + ly * by + lz * ny,
            lx * tz + ly * bz + lz * nz, WEIGHTED)


@dataclass(frozen=True, kw_only=True)
class Table(Material):
    """Reflection sampled from a simulated BRDF table one scale down."""

    kind: ClassVar[str] = "table"
    doc: ClassVar[str] = (
        "Reflection importance-sampled from a simulated BRDF table in the facet's local "
        "frame, weighted by the table's albedo (hierarchies of scale; docs/materials.md).")
    scatter: ClassVar = scatter
    blocks: ClassVar[int] = 2
    path: str = key("path", doc="BRDF table (.exr, as `microsim simulate` writes it), "
                    "relative to the recipe's folder.")
    component: str = key("str", "total", "The table's component the facets reflect: all "
                         "scattering orders of the lower scale, or single scattering.",
                         choices=("total", "single"))
    axis: str = key("str", "y", "World axis whose projection onto each facet is the table's "
                    "y axis (its x axis, phi = 0, is that projection times the normal), e.g. "
                    "the axis a yarn runs along; or \"tangent\": each face's own direction "
                    "from the generator (a velvet fibre's axis). Matters for anisotropic "
                    "tables only.", choices=AXES)

    def tabulated(self) -> Any:
        """Itself: its ``path``, ``component`` and ``axis``."""
        return self
