"""The incident beam of a batch: origins uniform over the top of the tile, in cell order.

A batch's origins are uniform random points over the tile (drawn from the batch's own
stream). They are traced in the order of a grid of ``CELLS`` × ``CELLS`` cells visited row
by row, alternately left to right and right to left, so consecutive rays — a chunk's —
start close together: their queries meet the same nodes of Embree's BVH and the same rows
of the face table, which then stay in the core's caches (about a fifth less CPU time per
segment on the shipped Gaussian tile: docs/performance.md). The order is a fixed
permutation of the points drawn, so the beam is as uniform as the points are.

A beam may hold several batches of one tile (``Runs``; a realisation's incident
directions, each with few rays on a large tile): their points are sorted together, so a
cell holds the rays of every direction and the kernel's chunks share more of the BVH and
the face table, while each batch keeps its own rows, its own order and its own random
numbers.
"""

from __future__ import annotations

from dataclasses import dataclass

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
def beam_origins(u: np.ndarray, starts: np.ndarray, period: np.ndarray, z: float,
                 cells: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Origins at height ``z`` over the tile, from uniform points, in cell order: a
    stable counting sort of the points by ``cell_steps``, the points of several runs
    sorted together.

    Parameters
    ----------
    u : (n, 2) float
        Uniform points in [0, 1)², run after run.
    starts : (b + 1,) int
        Run r's points are ``u[starts[r]:starts[r + 1]]``.
    period : (2,) float
        The tile's periods along x and y.
    z : float
        Height of the origins (the top of the slab).
    cells : int
        Cells per side of the grid.

    Returns
    -------
    origins : (n, 3) float
        ``(u_x · period_x, u_y · period_y, z)``, reordered.
    rows : (n,) int
        Each origin's row among its run's (``starts[r]`` + its place in the run's own
        cell order: the sort is stable, so a run's rays keep that order in the beam).
    run : (n,) int
        Each origin's run.
    """
    n = len(u)
    step = cell_steps(u, cells)
    start = np.zeros(cells * cells + 1, np.int64)
    for i in range(n):
        start[step[i] + 1] += 1
    for c in range(cells * cells):
        start[c + 1] += start[c]
    owner = np.empty(n, np.int64)
    for r in range(len(starts) - 1):
        owner[starts[r]:starts[r + 1]] = r
    out = np.empty((n, 3))
    run = np.empty(n, np.int64)
    for i in range(n):
        j = start[step[i]]
        start[step[i]] += 1
        out[j, 0] = u[i, 0] * period[0]
        out[j, 1] = u[i, 1] * period[1]
        out[j, 2] = z
        run[j] = owner[i]
    rows = np.empty(n, np.int64)
    following = starts[:-1].copy()
    for j in range(n):
        rows[j] = following[run[j]]
        following[run[j]] += 1
    return out, rows, run


@dataclass(frozen=True)
class Runs:
    """The runs whose rays one beam traces together (``PeriodicScene.start``).

    A run is what one random key makes: the rays of one batch of one incident direction.
    Its rays take its rows of the outcomes, in the order of its own beam, and draw their
    random numbers from its key with their index in it as counter, so that a run's
    outcomes are the same bit for bit whether its beam holds it alone or others with it.

    Attributes
    ----------
    rows : (n,) int
        Each ray of the beam, in beam order: its row of the outcomes.
    run : (n,) int
        Each ray's run.
    starts : (b + 1,) int
        Run r's rows are ``starts[r]`` … ``starts[r + 1] − 1``.
    keys : (b, 2) uint64
        Each run's Philox key (``microsim.kernel.rng``).
    """

    rows: np.ndarray
    run: np.ndarray
    starts: np.ndarray
    keys: np.ndarray

    @classmethod
    def one(cls, n: int, key: np.ndarray) -> Runs:
        """A beam of one run of ``n`` rays, in row order, under ``key`` ((2,) uint64)."""
        return cls(np.arange(n), np.zeros(n, np.int64), np.array([0, n]),
                   np.ascontiguousarray(np.reshape(key, (1, 2)), np.uint64))

    def __len__(self) -> int:
        """Runs (b)."""
        return len(self.keys)
