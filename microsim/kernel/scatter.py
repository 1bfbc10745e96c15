"""Facet scattering events, compiled: what one path does where it hits a face.

Every function works on one ray, with vectors as scalar triples. A material is a row of the
arrays ``microsim.materials.FacetMaterials`` packs:

- ``kind``: ``MIRROR``, ``CONDUCTOR``, ``DIELECTRIC`` (reflection with weight F; 1 − F is
  transmitted and leaves the simulation), ``REFRACTING`` (a dielectric with
  ``refract = true``), ``LAMBERTIAN`` or ``TABLE``;
- ``params`` (12,) float: η per RGB channel (a dielectric's scalar η in all three), k per
  channel, the Lambertian albedo per channel, the Beer-Lambert absorption per channel;
- for ``TABLE``, a row of ``tab_int`` (``T_*`` columns) with offsets into ``tab_f`` (node
  angles, bin edges, cumulative bin probabilities, weights; ``microsim.tabulated``).

An event returns the new direction of travel, the factor (RGB) the path weight is
multiplied by, and the fraction transmitted into a non-refracting dielectric; the rest,
1 − factor − transmitted, is absorbed. Random numbers come from ``rng.uniforms`` keyed by
(ray, event): the event never depends on which thread traces the ray.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from microsim.kernel.rng import uniforms

MIRROR, CONDUCTOR, DIELECTRIC, REFRACTING, LAMBERTIAN, TABLE = range(6)
"""Material kinds."""
P_ETA, P_K, P_ALBEDO, P_ABSORPTION = 0, 3, 6, 9
"""Offsets of the RGB triples in a material's ``params`` row."""
(T_THETA_N, T_THETA_AT, T_PHI_N, T_PHI_AT, T_ISOTROPIC, T_FOLDED, T_THETA_BINS,
 T_PHI_BINS, T_U_EDGES_AT, T_PHI_EDGES_AT, T_CDF_AT, T_WEIGHT_AT, T_AXIS,
 T_TANGENT) = range(14)
"""Columns of a table material's ``tab_int`` row: incidence nodes θi (count, offset in
``tab_f``), φi (count, offset), isotropic, folded, outgoing bins (θo, φo), offsets of the
u = sin²θo edges, of the φo edges, of the cumulative probabilities (node-major, one row of
θo·φo bins per node) and of the weights (3 per bin), the world axis of the frame (0: x,
1: y) and whether the face's tangent replaces it."""
TABLE_COLUMNS = 14
TWO_PI = 2.0 * math.pi
ALONG = 1e-6
"""A frame axis within this of the normal (1 − |n·e|) is replaced (``facet_frame``)."""

JIT = {"cache": True, "nogil": True, "error_model": "numpy"}
"""Compilation options of every kernel function: cached on disk, without the GIL, IEEE
floating-point semantics (a division by zero gives inf, not an exception)."""
INLINE = {**JIT, "inline": "always"}
"""The same, inlined into the caller (small functions on the per-segment path)."""


@njit(**INLINE)
def reflect(dx: float, dy: float, dz: float, nx: float, ny: float, nz: float
            ) -> tuple[float, float, float]:
    """Mirror a direction of travel about a plane: d − 2 (d·n) n."""
    s = 2.0 * (dx * nx + dy * ny + dz * nz)
    return dx - s * nx, dy - s * ny, dz - s * nz


@njit(**INLINE)
def fresnel_dielectric(cos_i: float, eta: float) -> float:
    """Exact unpolarised Fresnel reflectance of a dielectric interface, relative index η.

    F = ½ (r_s² + r_p²), r_s = (c_i − η c_t)/(c_i + η c_t), r_p = (η c_i − c_t)/(η c_i + c_t),
    sin θt = sin θi / η; F = 1 under total internal reflection (Born & Wolf, Principles of
    Optics, 7th ed., sec. 1.5.2, eq. 21a-b; ``microsim.analytic.fresnel``)."""
    c = min(max(cos_i, 0.0), 1.0)
    sin2_t = (1.0 - c * c) / (eta * eta)
    if sin2_t >= 1.0:
        return 1.0
    cos_t = math.sqrt(1.0 - sin2_t)
    den_s = c + eta * cos_t
    den_p = eta * c + cos_t
    r_s = (c - eta * cos_t) / den_s if den_s > 0.0 else 1.0
    r_p = (eta * c - cos_t) / den_p if den_p > 0.0 else 1.0
    return 0.5 * (r_s * r_s + r_p * r_p)


@njit(**INLINE)
def fresnel_conductor(cos_i: float, eta: float, k: float) -> float:
    """Exact unpolarised Fresnel reflectance of a conductor of complex index η + ik, in
    real arithmetic: with a² + b² = √((η² − k² − sin²θ)² + 4η²k²) and
    a = √((a² + b² + η² − k² − sin²θ) / 2),
    R_s = (a² + b² + cos²θ − 2a cos θ) / (a² + b² + cos²θ + 2a cos θ),
    R_p = R_s (cos²θ (a² + b²) + sin⁴θ − 2a cos θ sin²θ)
            / (cos²θ (a² + b²) + sin⁴θ + 2a cos θ sin²θ), F = (R_s + R_p) / 2
    (pbrt-v3, sec. 8.2.1, ``FrConductor``; the same function as Born & Wolf's complex form,
    sec. 14.2, which ``microsim.analytic.fresnel`` evaluates and the tests compare)."""
    c = min(max(cos_i, 0.0), 1.0)
    c2 = c * c
    s2 = 1.0 - c2
    e2, k2 = eta * eta, k * k
    t0 = e2 - k2 - s2
    a2b2 = math.sqrt(t0 * t0 + 4.0 * e2 * k2)
    a = math.sqrt(max(0.5 * (a2b2 + t0), 0.0))
    t1 = a2b2 + c2
    t2 = 2.0 * c * a
    r_s = (t1 - t2) / (t1 + t2)
    t3 = c2 * a2b2 + s2 * s2
    t4 = t2 * s2
    r_p = r_s * (t3 - t4) / (t3 + t4)
    return min(max(0.5 * (r_s + r_p), 0.0), 1.0)


@njit(**INLINE)
def refract(dx: float, dy: float, dz: float, nx: float, ny: float, nz: float, eta: float
            ) -> tuple[float, float, float, bool]:
    """Snell's law in vector form for d·n < 0, relative index η = n_t / n_i:
    t = d / η + (c / η − cos θt) n with c = −d·n, cos θt = √(1 − (1 − c²) / η²) (Walter et
    al. 2007, "Microfacet models for refraction through rough surfaces", eq. 40 with their
    η = n_i / n_t; PBR 4th ed., sec. 9.3). Returns the unit direction and whether total
    internal reflection forbids it."""
    c = min(max(-(dx * nx + dy * ny + dz * nz), 0.0), 1.0)
    sin2_t = (1.0 - c * c) / (eta * eta)
    if sin2_t >= 1.0:
        return dx, dy, dz, True
    cos_t = math.sqrt(1.0 - sin2_t)
    s = c / eta - cos_t
    tx, ty, tz = dx / eta + s * nx, dy / eta + s * ny, dz / eta + s * nz
    norm = math.sqrt(tx * tx + ty * ty + tz * tz)  # unit exactly; this is round-off only
    return tx / norm, ty / norm, tz / norm, False


@njit(**INLINE)
def orthonormal_basis(nx: float, ny: float, nz: float
                      ) -> tuple[float, float, float, float, float, float]:
    """Unit t, s with t × s = n (Duff et al. 2017, "Building an orthonormal basis,
    revisited", JCGT 6(1), listing 3; ``microsim.geometry``)."""
    sign = math.copysign(1.0, nz)
    a = -1.0 / (sign + nz)
    b = nx * ny * a
    return (1.0 + sign * nx * nx * a, sign * b, -sign * nx,
            b, sign + ny * ny * a, -ny)


@njit(**INLINE)
def cosine_about(nx: float, ny: float, nz: float, u1: float, u2: float
                 ) -> tuple[float, float, float]:
    """A direction with pdf cos θ / π about n: Malley's method, a uniform point of the unit
    disc lifted to the hemisphere (PBR 4th ed., sec. A.5.3)."""
    tx, ty, tz, sx, sy, sz = orthonormal_basis(nx, ny, nz)
    r = math.sqrt(u1)
    phi = TWO_PI * u2
    a, b = r * math.cos(phi), r * math.sin(phi)
    z = math.sqrt(max(1.0 - u1, 0.0))
    return a * tx + b * sx + z * nx, a * ty + b * sy + z * ny, a * tz + b * sz + z * nz


@njit(**INLINE)
def _frame_along(nx: float, ny: float, nz: float, axis: int
                 ) -> tuple[float, float, float, float, float, float]:
    """t = (e × n) / r and b = (e − (n·e) n) / r for e the world x (axis 0) or y axis."""
    if axis == 0:
        r = math.sqrt(ny * ny + nz * nz)
        return 0.0, -nz / r, ny / r, (1.0 - nx * nx) / r, -nx * ny / r, -nx * nz / r
    r = math.sqrt(nx * nx + nz * nz)
    return nz / r, 0.0, -nx / r, -ny * nx / r, (1.0 - ny * ny) / r, -ny * nz / r


@njit(**INLINE)
def facet_frame(nx: float, ny: float, nz: float, axis: int, use_tangent: bool, ex: float,
                ey: float, ez: float) -> tuple[float, float, float, float, float, float]:
    """Tangent t and bitangent b of a facet (``microsim.tabulated``: b is the projection of
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


@njit(**INLINE)
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


@njit(**INLINE)
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


@njit(**JIT)
def sample_table(tab_int: np.ndarray, part: int, tab_f: np.ndarray, dx: float, dy: float,
                 dz: float, nx: float, ny: float, nz: float, ex: float, ey: float, ez: float,
                 key: np.ndarray, ray: int, event: int
                 ) -> tuple[float, float, float, float, float, float]:
    """A direction importance-sampled from a BRDF table in the facet's frame, and its RGB
    weight f_r cos θo / pdf (``microsim.tabulated`` derives both).

    The incidence node is picked with the linear-interpolation weights in θi (and in φi,
    periodic, for anisotropic tables), the bin by its cumulative probability, the direction
    uniformly in projected solid angle inside the bin (u = sin²θo and φo uniform), a
    folded bin's mirror image φo → −φo with probability ½; an isotropic table's azimuths
    are relative to the incidence's."""
    row = tab_int[part]
    u0, u1, u2, u3 = uniforms(key, ray, event, 0)
    u4, u5, _, _ = uniforms(key, ray, event, 1)
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
    at = row[T_WEIGHT_AT] + 3 * (node * size + flat)
    return (lx * tx + ly * bx + lz * nx, lx * ty + ly * by + lz * ny,
            lx * tz + ly * bz + lz * nz, tab_f[at], tab_f[at + 1], tab_f[at + 2])


@njit(**JIT)
def scatter_event(kind: int, params: np.ndarray, tab_int: np.ndarray, part: int,
                  tab_f: np.ndarray, dx: float, dy: float, dz: float, nx: float, ny: float,
                  nz: float, ex: float, ey: float, ez: float, key: np.ndarray, ray: int, event: int
                  ) -> tuple[float, float, float, float, float, float, float, float, float]:
    """One scattering event at a facet of unit normal n (``d·n < 0``, except at a
    refracting facet, which is hit from either side).

    Parameters
    ----------
    kind : int
        The material's kind.
    params : (p, 12) float
        Every material's parameters.
    tab_int : (p, TABLE_COLUMNS) int
        Every material's table layout (``TABLE`` only).
    part : int
        The material's row.
    tab_f : (q,) float
        Packed table data.
    dx, dy, dz : float
        Unit direction of travel.
    nx, ny, nz : float
        Unit facet normal.
    ex, ey, ez : float
        The face's tangent (``TABLE`` with ``T_TANGENT`` only).
    key : (2,) uint64
        The run's random key.
    ray, event : int
        The ray's index in its run and the event's number (its bounce, from 1).

    Returns
    -------
    tuple of 9 float
        New unit direction (3), factor (RGB), transmitted fraction (RGB).
    """
    if kind == LAMBERTIAN:
        # the cosine pdf cancels the BRDF's cosine: weight = albedo (PBR 4th ed.,
        # sec. 13.6.3 and 4.5.1)
        u1, u2, _, _ = uniforms(key, ray, event, 0)
        ox, oy, oz = cosine_about(nx, ny, nz, u1, u2)
        return (ox, oy, oz, params[part, P_ALBEDO], params[part, P_ALBEDO + 1],
                params[part, P_ALBEDO + 2], 0.0, 0.0, 0.0)
    if kind == TABLE:
        ox, oy, oz, f0, f1, f2 = sample_table(tab_int, part, tab_f, dx, dy, dz, nx, ny, nz,
                                              ex, ey, ez, key, ray, event)
        return ox, oy, oz, f0, f1, f2, 0.0, 0.0, 0.0
    if kind == REFRACTING:
        # a Fresnel-weighted choice between reflection and refraction, weight 1 either
        # way: an unbiased estimate of both (PBR 4th ed., sec. 9.5); from inside the
        # medium the ray sees 1 / η about the flipped normal. No 1/η² on crossing: a path
        # carries power (importance), not radiance (Veach 1997, thesis, sec. 5.2)
        u, _, _, _ = uniforms(key, ray, event, 0)
        eta = params[part, P_ETA]
        if dx * nx + dy * ny + dz * nz >= 0.0:
            nx, ny, nz, eta = -nx, -ny, -nz, 1.0 / eta
        f = fresnel_dielectric(-(dx * nx + dy * ny + dz * nz), eta)
        if u >= f:
            tx, ty, tz, tir = refract(dx, dy, dz, nx, ny, nz, eta)
            if not tir:
                return tx, ty, tz, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0
        ox, oy, oz = reflect(dx, dy, dz, nx, ny, nz)
        return ox, oy, oz, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0
    ox, oy, oz = reflect(dx, dy, dz, nx, ny, nz)
    if kind == MIRROR:
        return ox, oy, oz, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0
    c = -(dx * nx + dy * ny + dz * nz)
    if kind == CONDUCTOR:
        return (ox, oy, oz, fresnel_conductor(c, params[part, P_ETA], params[part, P_K]),
                fresnel_conductor(c, params[part, P_ETA + 1], params[part, P_K + 1]),
                fresnel_conductor(c, params[part, P_ETA + 2], params[part, P_K + 2]),
                0.0, 0.0, 0.0)
    f = fresnel_dielectric(c, params[part, P_ETA])
    return ox, oy, oz, f, f, f, 1.0 - f, 1.0 - f, 1.0 - f
