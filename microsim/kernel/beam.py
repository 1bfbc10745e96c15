"""The incident beam of a batch: origins uniform over the top of the tile, in cell order.

A batch's origins are uniform random points over the tile (drawn from the batch's own
stream). They are traced in the order of a grid of ``CELLS`` × ``CELLS`` cells visited row
by row, alternately left to right and right to left, so consecutive rays — a chunk's —
start close together: their queries meet the same nodes of Embree's BVH and the same rows
of the face table, which then stay in the core's caches (about a fifth less CPU time per
segment on the shipped Gaussian tile: docs/performance.md). The order is a fixed
permutation of the points drawn, so the beam is as uniform as the points are.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from microsim.jit import JIT

CELLS = 64
"""Cells per side of the ordering grid (64: as fast as 256 or 1024 and a Morton order on
the shipped tile, where a cell then holds 4 × 4 of its grid points and about 16 rays of a
batch)."""


@njit(**JIT)
def cell_steps(u: np.ndarray, cells: int) -> np.ndarray:
    """Place of each point's cell on the boustrophedon path through the ``cells`` ×
    ``cells`` grid of the unit square (row y; x rising on even rows, falling on odd ones).

    Parameters
    ----------
    u : (n, 2) float
        Points in [0, 1)².
    cells : int
        Cells per side of the grid.

    Returns
    -------
    (n,) int
        In [0, cells²).
    """
    step = np.empty(len(u), np.int64)
    for i in range(len(u)):
        cx = min(int(u[i, 0] * cells), cells - 1)
        cy = min(int(u[i, 1] * cells), cells - 1)
        step[i] = cy * cells + (cells - 1 - cx if cy % 2 == 1 else cx)
    return step


@njit(**JIT)
def beam_origins(u: np.ndarray, period: np.ndarray, z: float, cells: int) -> np.ndarray:
    """Origins at height ``z`` over the tile, from uniform points, in cell order: a
    stable counting sort of the points by ``cell_steps``.

    Parameters
    ----------
    u : (n, 2) float
        Uniform points in [0, 1)².
    period : (2,) float
        The tile's periods along x and y.
    z : float
        Height of the origins (the top of the slab).
    cells : int
        Cells per side of the grid.

    Returns
    -------
    (n, 3) float
        ``(u_x · period_x, u_y · period_y, z)``, reordered.
    """
    step = cell_steps(u, cells)
    start = np.zeros(cells * cells + 1, np.int64)
    for i in range(len(u)):
        start[step[i] + 1] += 1
    for c in range(cells * cells):
        start[c + 1] += start[c]
    out = np.empty((len(u), 3))
    for i in range(len(u)):
        j = start[step[i]]
        start[step[i]] += 1
        out[j, 0] = u[i, 0] * period[0]
        out[j, 1] = u[i, 1] * period[1]
        out[j, 2] = z
    return out
