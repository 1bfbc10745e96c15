"""Westin's BRDF matrix: spherical harmonics over both the incident and outgoing direction.

Westin, Arvo & Torrance 1992 ("Predicting reflectance functions from complex surfaces",
Computer Graphics 26(2), SIGGRAPH '92) expand the reflectance as a double series
h(ωi, ωo) = Σ_ij b_ij Y_i(ωi) Y_j(ωo). Here h = f_r cos θi cos θo, which Helmholtz
reciprocity makes symmetric, h(ωi, ωo) = h(ωo, ωi), so b_ij = b_ji in one basis for both
directions (``microsim.tables.sh``'s real harmonics).

From the per-incidence coefficients a_k(θi) of g = f_r cos θo (azimuths relative to φi,
``BRDFTable.sh``), b_ij = ∫ cos θi Y_i(ωi) C_j(ωi) dωi, where C_j(θi, φi) are the
coefficients in absolute azimuth: rotating Y_l,±μ(θ, φ − φi) by φi mixes (l, μ) and
(l, −μ) with cos μφi and sin μφi. The φi integral is exact and leaves only |m_i| = |m_j|
(isotropy makes the matrix block-sparse): with x = cos θi and the θ factor P̃ of
``sh.legendre`` (√2 P̄ for μ > 0),

    μ = 0:               b_ij = 2π ∫ x P̃_{l_i}^0 a_{l_j,0} dx
    m_i = m_j = ±μ:      b_ij =  π ∫ x P̃_{l_i}^μ a_{l_j,μ} dx
    m_i = μ, m_j = −μ:   b_ij =  π ∫ x P̃_{l_i}^μ a_{l_j,−μ} dx
    m_i = −μ, m_j = μ:   b_ij = −π ∫ x P̃_{l_i}^μ a_{l_j,−μ} dx.

The table knows a_k only at its incidences θi; between them a_k is interpolated linearly
in θi and clamped outside, as ``BRDFTable.eval`` does, and the θi integral of that
interpolant is done by Gauss-Legendre in θi on each interval between incidences (exact to
round-off for the interpolant; the error is the interpolation's, which the asymmetry
‖B − Bᵀ‖ / ‖B‖ measures: a reciprocal BRDF gives a symmetric matrix only if θi is
resolved). Reciprocity is then enforced by B ← (B + Bᵀ)/2, the nearest symmetric matrix in
the Frobenius norm.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from microsim.files import atomic_path
from microsim.tables import sh
from microsim.tables.interpolation import linear_weights
from microsim.tables.table import BRDFTable

MAX_ORDER = 32
"""Highest order of the (dense) matrix: (L + 1)⁴ × C float64 (C channels), 28 MB at 32 for
RGB (150 MB for 16 wavelengths), 430 MB at 64."""


def _theta_quadrature(theta_i: np.ndarray, nodes: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre nodes and weights over θi ∈ [0, π/2], ``nodes`` per interval
    between the breakpoints 0, the table's incidences and π/2."""
    breaks = np.unique(np.concatenate([[0.0], theta_i, [0.5 * math.pi]]))
    t, w = np.polynomial.legendre.leggauss(nodes)
    lo, hi = breaks[:-1, None], breaks[1:, None]
    return (0.5 * (hi - lo) * t + 0.5 * (hi + lo)).ravel(), (0.5 * (hi - lo) * w).ravel()


def brdf_matrix(table: BRDFTable, order: int | None = None, component: str = "total",
                nodes: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Westin's matrix b_ij of h = f_r cos θi cos θo, reciprocity enforced.

    Parameters
    ----------
    table : BRDFTable
        An isotropic table with harmonics.
    order : int or None
        Order L of both bases (default: the stored order, at most ``MAX_ORDER``).
    component : str
        A component of the table (``"total"``, ``"single"``, ``"order2"``, …).
    nodes : int or None
        Gauss-Legendre nodes in θi per interval between incidences (default L + 8: the
        integrand x P̃_l(x) sin θi is a trigonometric polynomial of degree ≤ L + 2 in θi
        on each interval, where a_k is linear).

    Returns
    -------
    matrix : ((L + 1)², (L + 1)², C) float
        b_ij per channel (rows: incident harmonic i, columns: outgoing j), symmetric.
    asymmetry : (C,) float
        ‖B − Bᵀ‖_F / ‖B‖_F before symmetrisation (0 for an exactly reciprocal estimate).

    Raises
    ------
    ValueError
        If the table is anisotropic, holds no harmonics, or ``order`` exceeds the stored
        one or ``MAX_ORDER``.
    """
    if not table.isotropic:
        raise ValueError("Westin's matrix is built for isotropic tables only")
    if not table.has_sh:
        raise ValueError("the table holds no spherical harmonics")
    order = min(table.sh_order, MAX_ORDER) if order is None else order
    if order > MAX_ORDER:
        raise ValueError(f"order {order}: the dense matrix is built up to order {MAX_ORDER}")
    a = sh.truncate(table[component].sh, order)[:, 0]   # (n_theta_i, n, C)
    theta, w = _theta_quadrature(table.theta_i, order + 8 if nodes is None else nodes)
    i0, i1, w1 = linear_weights(theta, table.theta_i)
    interp = np.zeros((len(theta), len(table.theta_i)))
    np.add.at(interp, (np.arange(len(theta)), i0), 1.0 - w1)
    np.add.at(interp, (np.arange(len(theta)), i1), w1)
    x = np.cos(theta)
    kernel = sh.legendre(order, x).T @ ((w * x * np.sin(theta))[:, None] * interp)
    moments = np.einsum("it,tjc->ijc", kernel, a)                # ∫ x P̃_{l_i} a_j
    l, m = sh.degrees(order)
    mi, mj = m[:, None], m[None, :]
    same_mu = np.abs(mi) == np.abs(mj)
    # the coefficient a_{l_j, ±μ} each pair integrates: +μ when m_i = m_j, else −μ
    src_m = np.where(mi == mj, np.abs(mj), -np.abs(mj))
    src = (l * l + l)[None, :] + src_m
    factor = np.where(mi == 0, 2.0 * math.pi, np.where((mi < 0) & (mj > 0), -math.pi,
                                                       math.pi))
    rows = np.broadcast_to(np.arange(len(l))[:, None], src.shape)
    matrix = np.where(same_mu[..., None], factor[..., None] * moments[rows, src], 0.0)
    skew = matrix - matrix.transpose(1, 0, 2)
    norm = np.sqrt((matrix ** 2).sum(axis=(0, 1)))
    asymmetry = np.sqrt((skew ** 2).sum(axis=(0, 1))) / np.where(norm > 0, norm, 1.0)
    return 0.5 * (matrix + matrix.transpose(1, 0, 2)), asymmetry


def matrix_eval(matrix: np.ndarray, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """f_r from Westin's matrix: Σ_ij b_ij Y_i(ωi) Y_j(ωo) / (cos θi cos θo).

    Parameters
    ----------
    matrix : (n, n, C) float
    wi, wo : (k, 3) float
        Unit directions, local frame, above the horizon.

    Returns
    -------
    (k, C) float
        f_r in 1/sr; 0 where either direction is at or below the horizon.
    """
    order = sh.order_of(matrix.shape[0])
    yi = sh.basis(order, wi[:, 2], np.arctan2(wi[:, 1], wi[:, 0]))
    yo = sh.basis(order, wo[:, 2], np.arctan2(wo[:, 1], wo[:, 0]))
    h = np.einsum("kjc,kj->kc", np.einsum("ki,ijc->kjc", yi, matrix), yo)
    above = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    cos = np.where(above, wi[:, 2] * wo[:, 2], 1.0)
    return np.where(above[:, None], h / cos[:, None], 0.0)


def write_matrix(path: str | Path, matrix: np.ndarray, asymmetry: np.ndarray,
                 wavelengths: tuple[float, ...] | None = None) -> None:
    """Write Westin's matrix as ``.npz``, atomically.

    Keys: ``matrix`` ((L + 1)², (L + 1)², C) b_ij (rows: incident harmonic), ``order``,
    ``asymmetry`` (C,) before symmetrisation, and ``convention`` (a string: the function,
    the basis and the index); for a spectral table also ``wavelengths`` (C,) nm, the
    channels of the last axis (without it they are R, G, B).
    """

    convention = ("f_r cos(theta_i) cos(theta_o) = sum_ij b_ij Y_i(wi) Y_j(wo); real "
                  "orthonormal spherical harmonics, Condon-Shortley phase, index l*l + l + m "
                  "(docs/table-format.md)")
    with atomic_path(path) as tmp, tmp.open("wb") as f:
        extra = {} if wavelengths is None else {"wavelengths": np.asarray(wavelengths, float)}
        np.savez(f, matrix=matrix, order=np.array(sh.order_of(matrix.shape[0])),
                 asymmetry=asymmetry, convention=np.array(convention), **extra)
