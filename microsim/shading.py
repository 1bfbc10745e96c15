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

**The algorithm** (``shade``; per hit, f the face, d the unit direction of travel, n_g the
unit face normal, (c, u, v) = ``curved[f]`` as ``Tile.curved`` defines them):

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

What is approximated: the silhouette stays the prism's (a ray passing between a chord and
its arc misses: a k-sided tube's mean projected width is k sin(π/k)/π of the circle's,
0.955 at k = 6, 0.9999 at k = 128); a face's tube is the one its own chord belongs to (a
yarn's bent centre line is followed segment by segment, so a yarn is convex only
segment by segment); rays that start inside a tube keep the facet. The mirror white
furnace measures what is lost (docs/surfaces.md).
"""

from __future__ import annotations

import numpy as np

FLAT, CURVED, FALLBACK = range(3)
"""Per hit: a flat face (facet normal), the tube's normal at the entry point, or a curved
face whose entry point could not be found (facet normal)."""


def shade(curved: np.ndarray | None, faces: np.ndarray, points: np.ndarray, d: np.ndarray,
          n_g: np.ndarray, z0: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The normal and point a hit scatters at (the module docstring's algorithm).

    Parameters
    ----------
    curved : (m, 3, 3) float or None
        ``Tile.curved``: per face (c, u, v); None when every face is flat.
    faces : (k,) int
        Faces hit.
    points : (k, 3) float
        Hit points, on the faces' planes.
    d : (k, 3) float
        Unit directions of travel (d · n_g < 0: hits on the front of the faces).
    n_g : (k, 3) float
        Unit face normals.
    z0 : (k,) float
        Heights of the rays' origins (of the segment that hit).

    Returns
    -------
    normals : (k, 3) float
        Unit normals to scatter about (n_g exactly where the status is not ``CURVED``).
    points : (k, 3) float
        Where to scatter (the input point exactly where the status is not ``CURVED``).
    status : (k,) int8
        ``FLAT``, ``CURVED`` or ``FALLBACK`` per hit.
    """
    if curved is None:
        return n_g, points, np.zeros(len(faces), np.int8)
    cuv = np.take(curved, faces, axis=0)
    c, u, v = cuv[:, 0], cuv[:, 1], cuv[:, 2]
    tube = np.any(u != 0.0, axis=1) | np.any(v != 0.0, axis=1)
    q = points - c
    a_u, a_v = np.einsum("ij,ij->i", u, q), np.einsum("ij,ij->i", v, q)
    b_u, b_v = np.einsum("ij,ij->i", u, d), np.einsum("ij,ij->i", v, d)
    a = b_u * b_u + b_v * b_v
    b = a_u * b_u + a_v * b_v
    cc = a_u * a_u + a_v * a_v - 1.0
    disc = b * b - a * cc
    ok = tube & (a > 0.0) & (disc >= 0.0)
    root = np.sqrt(np.where(ok, disc, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = np.where(b < 0.0, cc / (b - root), (b + root) / np.where(ok, a, 1.0))
    lam = np.where(ok, np.maximum(lam, 0.0), 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        reach = np.where(d[:, 2] != 0.0, (points[:, 2] - z0) / d[:, 2], np.inf)
    ok &= lam <= reach
    moved = points - lam[:, None] * d
    q = q - lam[:, None] * d
    m = (u * np.einsum("ij,ij->i", u, q)[:, None] + v * np.einsum("ij,ij->i", v, q)[:, None])
    norm = np.linalg.norm(m, axis=1)
    n = np.divide(m, norm[:, None], out=np.zeros_like(m), where=norm[:, None] > 0)
    ok &= (np.einsum("ij,ij->i", d, n) < 0.0) & (np.einsum("ij,ij->i", n, n_g) > 0.0)
    status = np.where(ok, CURVED, np.where(tube, FALLBACK, FLAT)).astype(np.int8)
    return (np.where(ok[:, None], n, n_g), np.where(ok[:, None], moved, points), status)
