"""Face normals, areas and plane constants of a triangle mesh, compiled: one pass over the
faces (``Tile`` computes them once per tile and keeps them).

The arithmetic is the one numpy's ``np.cross``, ``np.linalg.norm`` and
``np.einsum("ij,ij->i", ...)`` did before, operation for operation, so the results (and the
tables traced with them) are the same bit for bit: the edge vectors e = v1 − v0,
f = v2 − v0, the cross product c = e × f component by component (``e_y f_z − e_z f_y``,
...), |c| = √((c_x² + c_y²) + c_z²), n = c / |c| (zero for a degenerate face), area |c| / 2,
and the plane constant n · v0 summed as (n_x x + n_z z) + n_y y, the order numpy's
``einsum`` adds three products in (checked by ``tests/test_surfaces.py``).

This module imports numba; ``Tile`` imports it on first use, so recipe validation, which
imports the surfaces package, stays light (docs/architecture.md).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from microsim.jit import JIT


@njit(**JIT)
def face_geometry(vertices: np.ndarray, faces: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit normals, areas and plane constants of every face.

    Parameters
    ----------
    vertices : (n, 3) float64
        Vertex positions.
    faces : (m, 3) int
        Vertex indices per triangle, counter-clockwise seen from the side the normal
        points to.

    Returns
    -------
    normals : (m, 3) float64
        Unit normals, (e × f) / |e × f| (zero rows for degenerate faces).
    areas : (m,) float64
        Triangle areas, |e × f| / 2.
    plane : (m,) float64
        n · v0: the face's plane is {x : n · x = plane}.
    """
    m = len(faces)
    normals = np.zeros((m, 3))
    areas = np.empty(m)
    plane = np.empty(m)
    for i in range(m):
        a, b, c = faces[i, 0], faces[i, 1], faces[i, 2]
        x0, y0, z0 = vertices[a, 0], vertices[a, 1], vertices[a, 2]
        ex, ey, ez = vertices[b, 0] - x0, vertices[b, 1] - y0, vertices[b, 2] - z0
        fx, fy, fz = vertices[c, 0] - x0, vertices[c, 1] - y0, vertices[c, 2] - z0
        cx = ey * fz - ez * fy
        cy = ez * fx - ex * fz
        cz = ex * fy - ey * fx
        norm = math.sqrt((cx * cx + cy * cy) + cz * cz)
        if norm > 0.0:
            normals[i, 0] = cx / norm
            normals[i, 1] = cy / norm
            normals[i, 2] = cz / norm
        areas[i] = 0.5 * norm
        plane[i] = (normals[i, 0] * x0 + normals[i, 2] * z0) + normals[i, 1] * y0
    return normals, areas, plane


@njit(**JIT)
def slope_terms(normals: np.ndarray, areas: np.ndarray, c: float, s: float
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per facet with n_z > 0, in face order: its projected area w = a n_z and w (g · e)²
    for its height gradient g = (−n_x/n_z, −n_y/n_z) along e = (c, s) and e' = (−s, c)
    (``Tile.realised_alpha`` sums them; the arithmetic is numpy's of before, element by
    element, so the sums are the same bit for bit).

    Parameters
    ----------
    normals : (m, 3) float64
        Unit face normals.
    areas : (m,) float64
        Face areas.
    c, s : float
        Cosine and sine of the first axis's angle from +x.

    Returns
    -------
    weight, along_x, along_y : (k,) float64
        k the number of facets with n_z > 0.
    """
    m = len(areas)
    weight = np.empty(m)
    along_x = np.empty(m)
    along_y = np.empty(m)
    k = 0
    for i in range(m):
        nz = normals[i, 2]
        if nz > 0.0:
            gx = -normals[i, 0] / nz
            gy = -normals[i, 1] / nz
            w = areas[i] * nz
            sx = c * gx + s * gy
            sy = -s * gx + c * gy
            weight[k] = w
            along_x[k] = w * (sx * sx)
            along_y[k] = w * (sy * sy)
            k += 1
    return weight[:k], along_x[:k], along_y[:k]
