"""Principal components of a batch's weight rows, for harmonics of many channels
(``microsim.tables.sh.moments``).

The harmonics are linear in the weights, so with X ≈ M B (X the (c, n) weight rows,
B (r, n) and M (c, r)), Σ_i X_ci Y_k(ω_i) = Σ_j M_cj Σ_i B_ji Y_k(ω_i): r transforms of
B instead of c of X, and a channel's sums are off by at most ‖R_c‖ ‖Y_k‖ for its residual
row R_c = (X − M B)_c. The weights of a spectral table's paths are products of smooth
spectra (a conductor's Fresnel factor at each bounce), so their c channels span few
dimensions: 3 to 13 of 32 in a gold table's batches at ``PRINCIPAL_TOLERANCE``. M holds the
leading eigenvectors of the Gram matrix X Xᵀ (the right singular vectors of Xᵀ; Golub &
Van Loan 2013, Matrix Computations, 4th ed., §8.6), B = Mᵀ X.

The products are the BLAS library's (numpy's ``@``), which a measurement keeps to one
thread (``microsim.measurement.simulation.measure_ensemble``): its threads beside the
tracer's measured slower end to end than transforming every channel, and one thread's
products are the same bit for bit whatever thread calls them.
"""

from __future__ import annotations

import numpy as np

BLOCK = 4096
"""Samples per block of the components' products (a block's coefficients stay in
cache)."""


def principal(rows: np.ndarray, tolerance: float) -> tuple[np.ndarray, np.ndarray] | None:
    """The principal components of weight rows: rows B and a mix M with X ≈ M B, as few as
    leave a relative Frobenius residual ‖X − M B‖ ≤ ``tolerance`` ‖X‖, checked.

    Parameters
    ----------
    rows : (c, n) float
        The weight rows X, one per channel, each row's entries adjacent in memory (a
        slice of the columns of a C-contiguous array is taken as it is).
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
    rows = np.asarray(rows, float)
    if rows.strides[-1] != rows.itemsize:
        rows = np.ascontiguousarray(rows)
    gram = rows @ rows.T
    total = float(np.trace(gram))
    if not total > 0.0:
        return None
    values, vectors = np.linalg.eigh(gram)                  # ascending
    tail = np.cumsum(np.maximum(values, 0.0))               # tail[j]: the j + 1 smallest
    r = len(values) - int(np.searchsorted(tail, (0.5 * tolerance) ** 2 * total,
                                          side="right"))
    if r > len(values) // 2:
        return None
    # every eigenvector's coefficients, block by block over the samples: the first r rows
    # are B, the others the residual's coefficients in the orthogonal complement of M's
    # columns, so ‖X − M B‖² is their sum of squares, free of the cancellation in
    # ‖X‖² − ‖B‖²
    r = max(r, 1)
    full = np.ascontiguousarray(vectors[:, ::-1].T)
    n = rows.shape[1]
    basis = np.empty((r, n))
    block = np.empty((len(full), min(BLOCK, n)))
    residual = 0.0
    for start in range(0, n, BLOCK):
        part = block[:, :min(BLOCK, n - start)]
        np.matmul(full, rows[:, start:start + BLOCK], out=part)
        basis[:, start:start + BLOCK] = part[:r]
        rest = part[r:]
        residual += float(np.vdot(rest, rest))
    if residual > tolerance ** 2 * total:
        return None
    return basis, np.ascontiguousarray(full[:r].T)
