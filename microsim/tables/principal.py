"""Principal components of a batch's weight rows, for harmonics of many channels
(``microsim.tables.sh.moments``), compiled.

The harmonics are linear in the weights, so with X ≈ M B (X the (c, n) weight rows,
B (r, n) and M (c, r)), Σ_i X_ci Y_k(ω_i) = Σ_j M_cj Σ_i B_ji Y_k(ω_i): r transforms of
B instead of c of X, and a channel's sums are off by at most ‖R_c‖ ‖Y_k‖ for its residual
row R_c = (X − M B)_c. The weights of a spectral table's paths are products of smooth
spectra (a conductor's Fresnel factor at each bounce), so their c channels span few
dimensions: 3 to 13 of 32 in a gold table's batches at ``PRINCIPAL_TOLERANCE``. M holds the
leading eigenvectors of the Gram matrix X Xᵀ (the right singular vectors of Xᵀ; Golub &
Van Loan 2013, Matrix Computations, 4th ed., §8.6), B = Mᵀ X.

The products are compiled loops on the calling thread, in a fixed order, so the sums are
the same bit for bit whatever thread computes them (numpy's matrix products would start
the BLAS library's own threads beside the tracer's, which measured slower end to end than
transforming every channel). This module imports numba; ``microsim.tables.sh`` imports it
only for weights of many channels.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from microsim.jit import JIT

BLOCK = 512
"""Samples summed per block of the Gram matrix (the block of every row stays in cache)."""


@njit(**JIT)
def _gram(x: np.ndarray) -> np.ndarray:
    """X Xᵀ, (c, c), summed block by block over the samples in a fixed order."""
    c, n = x.shape
    out = np.zeros((c, c))
    for start in range(0, n, BLOCK):
        stop = min(start + BLOCK, n)
        for i in range(c):
            for j in range(i + 1):
                s = 0.0
                for t in range(start, stop):
                    s += x[i, t] * x[j, t]
                out[i, j] += s
    for i in range(c):
        for j in range(i):
            out[j, i] = out[i, j]
    return out


@njit(**JIT)
def _project(x: np.ndarray, mix: np.ndarray) -> tuple[np.ndarray, float]:
    """B = Mᵀ X, (r, n), and ‖X − M B‖²_F."""
    c, n = x.shape
    r = mix.shape[1]
    basis = np.zeros((r, n))
    for j in range(r):
        for i in range(c):
            m = mix[i, j]
            for t in range(n):
                basis[j, t] += m * x[i, t]
    residual = 0.0
    row = np.empty(n)
    for i in range(c):
        row[:] = x[i]
        for j in range(r):
            m = mix[i, j]
            for t in range(n):
                row[t] -= m * basis[j, t]
        for t in range(n):
            residual += row[t] * row[t]
    return basis, residual


@njit(**JIT)
def mixed(done: np.ndarray, mix: np.ndarray) -> np.ndarray:
    """The channels' sums from their components': (c, K) = M (r, K), for ``done`` (r, K)
    the components' transforms and ``mix`` M (c, r)."""
    c, r = mix.shape
    out = np.zeros((c, done.shape[1]))
    for i in range(c):
        for j in range(r):
            m = mix[i, j]
            for k in range(done.shape[1]):
                out[i, k] += m * done[j, k]
    return out


def principal(rows: np.ndarray, tolerance: float) -> tuple[np.ndarray, np.ndarray] | None:
    """The principal components of weight rows: rows B and a mix M with X ≈ M B, as few as
    leave a relative Frobenius residual ‖X − M B‖ ≤ ``tolerance`` ‖X‖, checked.

    Parameters
    ----------
    rows : (c, n) float
        The weight rows X, one per channel, C-contiguous.
    tolerance : float
        The relative residual allowed (``microsim.tables.sh.PRINCIPAL_TOLERANCE``); below
        ~1e-8 the Gram matrix's rounding (~1e-16 of its trace) does not allow it.

    Returns
    -------
    basis : (r, n) float
        B, r ≤ c // 2.
    mix : (c, r) float
        M, orthonormal columns.
    None
        Where more than c // 2 components are needed (no transform would be saved), the
        weights are all zero, or the residual check fails: transform the rows themselves.
    """
    rows = np.ascontiguousarray(rows, float)
    gram = _gram(rows)
    total = float(np.trace(gram))
    if not total > 0.0:
        return None
    values, vectors = np.linalg.eigh(gram)                  # ascending
    tail = np.cumsum(np.maximum(values, 0.0))               # tail[j]: the j + 1 smallest
    r = len(values) - int(np.searchsorted(tail, (0.5 * tolerance) ** 2 * total,
                                          side="right"))
    if r > len(values) // 2:
        return None
    mix = np.ascontiguousarray(vectors[:, ::-1][:, :max(r, 1)])
    basis, residual = _project(rows, mix)
    if residual > tolerance ** 2 * total:
        return None
    return basis, mix
