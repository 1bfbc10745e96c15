"""Shading normals of curved surfaces meshed as flat faces (cylinders, fibres, yarns).

A tube is meshed as a prism whose faces are chords of the smooth surface: a mirror prism
reflects into a fan of discrete directions, one per face. Scattering at a face that
approximates a tube (``Tile.curved``) uses instead the tube itself, where the ray enters
it: the hit point p lies on a chord, inside the tube, so the ray crossed the tube's surface
a little earlier, at p' = p − λ d. There the surface normal n is exact, the ray arrives
from the front of it (d · n < 0), and the tube is convex, so any direction leaving p' into
the half-space n · x > n · p' never meets the tube (nor its prism) again: the standard
shading-normal pitfalls — an incident ray behind the shading normal, a scattered ray below
the triangle it left, light leaking through the mesh — do not arise for a convex tube. The
next ray starts at p' offset along n (not along the face normal), on the side it goes.

**The algorithm** (``shade_one``, inlined into the transport kernel at every hit on the
front of a face; per hit, f the face, d the unit direction of travel, n_g the unit face
normal, (c, u, v) = row f of ``curved_table`` as ``Tile.curved`` defines them):

1. u = v = 0: a flat face; the normal is n_g and the point p (status ``FLAT``).
2. q = p − c; with a_u = u·q, a_v = v·q, b_u = u·d, b_v = v·d:
   A = b_u² + b_v², B = a_u b_u + a_v b_v, C = a_u² + a_v² − 1, D = B² − A C.
   The points p − λ d on the tube satisfy A λ² − 2 B λ + C = 0.
3. A ≤ 0 (d along the axis) or D < 0 (the line misses the tube): fall back to n_g, p
   (status ``FALLBACK``; neither happens for a ray that hit a face of the prism, up to
   round-off).
4. λ = C / (B − √D) where B < 0, else (B + √D) / A: the larger root, the distance back to
   where the ray entered (p inside: C ≤ 0, one root ≥ 0; the first form avoids
   cancellation when |AC| ≪ B²). λ = max(λ, 0) (p outside the tube by round-off).
   λ > ℓ, the distance the ray travelled from its origin to p (ℓ = (p_z − o_z) / d_z,
   from heights, which the periodic wrap leaves alone; ∞ where d_z = 0): the ray started
   inside the tube, between a chord and its arc (off the base where a fibre stands in
   it), where the smooth surface has no outside: fall back to n_g, p (status
   ``FALLBACK``), the faceted geometry, which is closed. So p' always lies on the
   segment the ray really travelled, in free space.
5. p' = p − λ d, q' = q − λ d, m = u (u·q') + v (v·q'), n = m / |m|.
6. d · n ≥ 0 or n · n_g ≤ 0 (round-off at tangency; for an exact entry point d · n < 0,
   and p' lies on the arc over the face hit, so n · n_g ≥ cos(half the facet angle)):
   fall back to n_g, p (status ``FALLBACK``). Otherwise n, p' (status ``CURVED``).

The kernel then scatters about the returned normal and offsets the next origin along it
(``microsim.kernel.transport``, step 4 and 5); the medium bookkeeping uses n_g, and
refracting parts are made flat (``curved_table``).

What is approximated: the silhouette stays the prism's (a ray passing between a chord and
its arc misses: a k-sided tube's mean projected width is k sin(π/k)/π of the circle's,
0.955 at k = 6, 0.9999 at k = 128); a face's tube is the one its own chord belongs to (a
yarn's bent centre line is followed segment by segment, so a yarn is convex only
segment by segment); rays that start inside a tube keep the facet. The mirror white
furnace measures what is lost (docs/surfaces.md).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from microsim.jit import INLINE, JIT

FLAT, CURVED, FALLBACK = range(3)
"""Per hit: a flat face (facet normal), the tube's normal at the entry point, or a curved
face whose entry point could not be found (facet normal)."""
CURVED_FLOATS = 9
"""Columns of ``curved_table``: c, u, v (``Tile.curved``'s rows, flattened)."""


def curved_table(curved: np.ndarray | None, flat: np.ndarray) -> np.ndarray:
    """The per-face tubes the kernel reads: (m, 9) rows (c, u, v), zeros for flat faces and
    for the faces ``flat`` marks (refracting parts: a ray inside a medium meets their faces
    from behind, where the entry-point construction does not apply); (0, 9) when no face is
    curved, which the kernel takes as "all flat".

    Parameters
    ----------
    curved : (m, 3, 3) float or None
        ``Tile.curved``.
    flat : (m,) bool

    Returns
    -------
    (m, 9) or (0, 9) float
    """
    if curved is None:
        return np.zeros((0, CURVED_FLOATS))
    rows = np.where(flat[:, None, None], 0.0, np.asarray(curved, float))
    return np.ascontiguousarray(rows.reshape(len(rows), CURVED_FLOATS))


@njit(**INLINE)
def shade_one(curved: np.ndarray, f: int, hx: float, hy: float, hz: float, dx: float,
              dy: float, dz: float, nx: float, ny: float, nz: float, z0: float
              ) -> tuple[float, float, float, float, float, float, int]:
    """The normal and point a hit on the front of face f scatters at (the module
    docstring's algorithm): (normal, point, status)."""
    ux, uy, uz = curved[f, 3], curved[f, 4], curved[f, 5]
    vx, vy, vz = curved[f, 6], curved[f, 7], curved[f, 8]
    if ux == 0.0 and uy == 0.0 and uz == 0.0 and vx == 0.0 and vy == 0.0 and vz == 0.0:
        return nx, ny, nz, hx, hy, hz, FLAT
    qx, qy, qz = hx - curved[f, 0], hy - curved[f, 1], hz - curved[f, 2]
    a_u, a_v = ux * qx + uy * qy + uz * qz, vx * qx + vy * qy + vz * qz
    b_u, b_v = ux * dx + uy * dy + uz * dz, vx * dx + vy * dy + vz * dz
    a = b_u * b_u + b_v * b_v
    b = a_u * b_u + a_v * b_v
    c = a_u * a_u + a_v * a_v - 1.0
    disc = b * b - a * c
    if a <= 0.0 or disc < 0.0:
        return nx, ny, nz, hx, hy, hz, FALLBACK
    root = math.sqrt(disc)
    lam = c / (b - root) if b < 0.0 else (b + root) / a
    lam = max(lam, 0.0)
    reach = (hz - z0) / dz if dz != 0.0 else math.inf
    if lam > reach:
        return nx, ny, nz, hx, hy, hz, FALLBACK
    qx, qy, qz = qx - lam * dx, qy - lam * dy, qz - lam * dz
    su, sv = ux * qx + uy * qy + uz * qz, vx * qx + vy * qy + vz * qz
    mx, my, mz = ux * su + vx * sv, uy * su + vy * sv, uz * su + vz * sv
    norm = math.sqrt(mx * mx + my * my + mz * mz)
    if norm == 0.0:
        return nx, ny, nz, hx, hy, hz, FALLBACK
    mx, my, mz = mx / norm, my / norm, mz / norm
    if dx * mx + dy * my + dz * mz >= 0.0 or mx * nx + my * ny + mz * nz <= 0.0:
        return nx, ny, nz, hx, hy, hz, FALLBACK
    return mx, my, mz, hx - lam * dx, hy - lam * dy, hz - lam * dz, CURVED


@njit(**JIT)
def shade(curved: np.ndarray, faces: np.ndarray, points: np.ndarray, d: np.ndarray,
          n_g: np.ndarray, z0: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``shade_one`` over arrays of hits (for tests and drawings).

    Parameters
    ----------
    curved : (m, 9) float
        ``curved_table`` (no rows: every face flat).
    faces : (k,) int
    points : (k, 3) float
        Hit points, on the faces' planes.
    d : (k, 3) float
        Unit directions of travel (hits on the front of the faces).
    n_g : (k, 3) float
        Unit face normals.
    z0 : (k,) float
        Heights of the origins of the segments that hit.

    Returns
    -------
    normals : (k, 3) float
    points : (k, 3) float
    status : (k,) int
        ``FLAT``, ``CURVED`` or ``FALLBACK``.
    """
    k = len(faces)
    normals, moved = n_g.copy(), points.copy()
    status = np.zeros(k, np.int64)
    if curved.shape[0] == 0:
        return normals, moved, status
    for j in range(k):
        (normals[j, 0], normals[j, 1], normals[j, 2], moved[j, 0], moved[j, 1], moved[j, 2],
         status[j]) = shade_one(curved, faces[j], points[j, 0], points[j, 1], points[j, 2],
                                d[j, 0], d[j, 1], d[j, 2], n_g[j, 0], n_g[j, 1], n_g[j, 2],
                                z0[j])
    return normals, moved, status
