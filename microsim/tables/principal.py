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
SAMPLE = 8
"""The Gram matrix is first made of every ``SAMPLE``-th sample alone (an eighth of its
products): the weights' few dimensions are those of any large share of their samples, and
the residual of every sample is checked all the same; where that check fails, the Gram
matrix of every sample is used."""
SAMPLED = 64
"""Samples per channel below which the Gram matrix is made of every sample at once."""


def principal(rows: np.ndarray, tolerance: float) -> tuple[np.ndarray, np.ndarray] | None:
    """The principal components of weight rows: rows B and a mix M with X ≈ M B, as few as
    leave a relative Frobenius residual ‖X − M B‖ ≤ ``tolerance`` ‖X‖, checked.

    M holds the leading eigenvectors of the Gram matrix of every ``SAMPLE``-th sample (of
    every sample where the rows have fewer than ``SAMPLED`` per channel, or where the
    check fails), as many as leave at most half the tolerance in the Gram matrix's
    discarded eigenvalues (None at once where the sample needs more than c // 2);
    B = Mᵀ X, and the residual X − M B is computed sample by sample, so its check has
    none of the cancellation of ‖X‖² − ‖B‖².

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
    if rows.shape[1] >= SAMPLED * len(rows):
        sample = np.ascontiguousarray(rows[:, ::SAMPLE])
        mix = _leading(sample, tolerance)
        if mix is None and sample.any():
            return None  # the sample alone needs more than c // 2: so do all samples
        found = None if mix is None else _checked(rows, mix, tolerance)
        if found is not None:
            return found
    mix = _leading(rows, tolerance)
    return None if mix is None else _checked(rows, mix, tolerance)


def _leading(rows: np.ndarray, tolerance: float) -> np.ndarray | None:
    """The leading eigenvectors of ``rows``' Gram matrix X Xᵀ ((c, r), orthonormal
    columns), as many as leave at most (tolerance / 2)² of its trace in the discarded
    eigenvalues; None for zero rows or more than c // 2 of them."""
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
    return np.ascontiguousarray(vectors[:, ::-1][:, :max(r, 1)])


def _checked(rows: np.ndarray, mix: np.ndarray, tolerance: float
             ) -> tuple[np.ndarray, np.ndarray] | None:
    """B = Mᵀ X and M where ‖X − M B‖ ≤ ``tolerance`` ‖X‖, else None; block by block over
    the samples, the residual's entries computed as they are."""
    n = rows.shape[1]
    basis = np.empty((mix.shape[1], n))
    across = np.ascontiguousarray(mix.T)
    residual = total = 0.0
    for start in range(0, n, BLOCK):
        x = rows[:, start:start + BLOCK]
        part = across @ x
        basis[:, start:start + BLOCK] = part
        rest = mix @ part
        rest -= x
        residual += float(np.vdot(rest, rest))
        total += float(np.einsum("ij,ij->", x, x))     # ‖X‖², the block still in cache
    if not residual <= tolerance ** 2 * total:
        return None
    return basis, mix
