"""One realisation's estimates added to an ensemble's running sums, compiled: one pass over
the entries (``RunningEstimate.add`` and ``RunningEstimate.add_sums`` call it for every
realisation and incident direction a run folds).

The arithmetic is the one numpy's masked operations did before, operation for operation,
so the sums (and the tables assembled from them) are the same bit for bit: the
realisation's estimate m = Σx / n and ray variance v = max(Σx² − Σx m, 0) / (n − 1) / n
(``microsim.tables.estimator.realisation_moments``; NaN where Σx² = 0 or n < 2), the shift
c set to the first realisation's m, then Σ (m − c) += m − c, Σ (m − c)² += (m − c)², and
Σ v += v with its count where v is finite (``tests/test_accumulate.py`` compares both on
random sums with absent rows, NaN, infinite and one-ray realisations).

This module imports numba; ``RunningEstimate`` imports it on first use, so reading a table
stays light (docs/architecture.md).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from microsim.jit import JIT


@njit(**JIT)
def _moments(s1: float, s2: float, n: float) -> tuple[float, float]:
    """m and v of one entry from its Σx, Σx² and rays n, as ``realisation_moments``."""
    m = s1 / n if n > 0 else math.nan
    v = s1 * m
    v = s2 - v
    if v < 0.0:  # np.maximum(v, 0): NaN stays NaN, −0 stays −0
        v = 0.0
    v = v / (n - 1.0)
    v = v / n
    if not (s2 > 0 and n >= 2):
        v = math.nan
    return m, v


@njit(**JIT)
def accumulate(a: np.ndarray, b: np.ndarray, n: float, sums: bool, with_v: bool,
               shift: np.ndarray, count: np.ndarray, t1: np.ndarray, t2: np.ndarray,
               tv: np.ndarray, known: np.ndarray, group: np.ndarray,
               present: np.ndarray) -> None:
    """Add one realisation to running sums, in place.

    Parameters
    ----------
    a, b : (p, q) float64
        With ``sums``: Σx and Σx² over the realisation's ``n`` rays per entry (its m and v
        follow as ``realisation_moments`` makes them). Without: its estimates m and (with
        ``with_v``) their ray variances v; ``b`` is not read without ``with_v``.
    n : float
        Rays of the realisation (read only with ``sums``).
    sums, with_v : bool
        What ``a`` and ``b`` hold; ``sums`` implies ``with_v``.
    shift : (p, q) float64
        The shift c of each entry, set to m where a row is first present.
    count, group : (p,) int64
        Realisations added per row, over all groups and in this one.
    t1, t2, tv : (p, q) float64
        The group's Σ (m − c), Σ (m − c)² and Σ v.
    known : (p, q) int64
        Realisations whose v is finite, per entry.
    present : (p,) bool
        Out: whether the realisation has row i (some m not NaN).
    """
    rows, q = a.shape
    for i in range(rows):
        here = False
        for j in range(q):
            m = _moments(a[i, j], b[i, j], n)[0] if sums else a[i, j]
            if not math.isnan(m):
                here = True
                break
        present[i] = here
        if not here:
            continue
        first = count[i] == 0
        for j in range(q):
            if sums:
                m, v = _moments(a[i, j], b[i, j], n)
            else:
                m, v = a[i, j], (b[i, j] if with_v else math.nan)
            if first:
                shift[i, j] = m
            d = m - shift[i, j]
            t1[i, j] += d
            t2[i, j] += d * d
            if (sums or with_v) and math.isfinite(v):
                tv[i, j] += v
                known[i, j] += 1
        group[i] += 1
        count[i] += 1
