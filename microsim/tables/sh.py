"""Real spherical harmonics of outgoing lobes: basis, Monte Carlo projection, windows.

Convention (docs/table-format.md, "Spherical harmonics"): real, orthonormal on the sphere,
flat index k = l² + l + m for order l = 0…L and m = −l…l, so an expansion of order L has
(L + 1)² coefficients. With the fully normalised associated Legendre function
P̄_l^m(x) = √((2l + 1)/(4π) · (l − m)!/(l + m)!) P_l^m(x), whose P_l^m includes the
Condon-Shortley phase (−1)^m (as scipy's ``lpmv`` and ``sph_harm_y``),

    Y_l0 = P̄_l^0(cos θ),  Y_lm = √2 P̄_l^m(cos θ) cos mφ,  Y_l,−m = √2 P̄_l^m(cos θ) sin mφ

for m > 0, so Y_lm = √2 Re Y_l^m and Y_l,−m = √2 Im Y_l^m of the complex harmonics
Y_l^m = P̄_l^m(cos θ) e^{imφ} (DLMF 14.30.1, whose Ferrers function P_l^m carries the
Condon-Shortley phase, DLMF 14.6.1). Some graphics papers drop that phase (Ramamoorthi &
Hanrahan 2001, "An efficient representation for irradiance environment maps", eq. 3:
Y_11 = +0.488603 x): their Y_lm is (−1)^m times this one, whose Y_11 = −√(3/4π) x.

The coefficients of a goniophotometer lobe are those of g(ωo) = f_r(ωi, ωo) cos θo over
the whole sphere (g = 0 below the horizon): an escaping ray of exit weight w estimates
E[w Y_k(ωo)] = ∫ f_r cos θo Y_k dωo without bias and with finite variance, whereas f_r
itself would need the weight w / cos θo, whose variance is infinite for a diffuse lobe.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import lru_cache
from typing import Any

import numpy as np

from microsim.tables.principal import principal

WINDOWS = ("none", "lanczos", "hanning")
EPSILON = 1e-7
"""Relative accuracy asked of ducc0's non-uniform transform (its error, measured at ~5e-10
of the coefficient vector's norm at 65 536 samples, is far below any Monte Carlo error;
1e-10 costs 1.6 times as much at order 32 and 3 times at order 64)."""
PRINCIPAL_CHANNELS = 8
"""Weights of more distinct channels than this (spectral tables) are transformed through
their principal components where they have few (``microsim.tables.principal``); RGB's
are transformed
channel by channel."""
PRINCIPAL_TOLERANCE = EPSILON
"""Relative Frobenius residual of the principal components kept
(``microsim.tables.principal``), the
accuracy asked of ducc0's transform itself: the sums are off by at most this fraction of
‖w‖ ‖Y_k‖. Not much lower: the Gram matrix's rounding (~1e-16 of its trace) is a
residual of ~1e-8."""


def size(order: int) -> int:
    """Coefficients of an expansion of order L: (L + 1)²."""
    return (order + 1) ** 2


def order_of(n: int) -> int:
    """The order L of an expansion with ``n`` = (L + 1)² coefficients.

    Raises
    ------
    ValueError
        If ``n`` is not a square.
    """
    order = math.isqrt(n) - 1
    if order < 0 or size(order) != n:
        raise ValueError(f"{n} coefficients is not (L + 1)^2 for an order L")
    return order


def degrees(order: int) -> tuple[np.ndarray, np.ndarray]:
    """(l, m) of every flat index k = l² + l + m, each of shape ((L + 1)²,) int."""
    l = np.repeat(np.arange(order + 1), 2 * np.arange(order + 1) + 1)
    return l, np.arange(size(order)) - l * l - l


def legendre(order: int, x: np.ndarray) -> np.ndarray:
    """The θ factor of every real harmonic: P̄_l^|m|(x), times √2 for m ≠ 0.

    Evaluated by the standard three-term recurrence in l at fixed m, started from the
    sectoral P̄_m^m = −√((2m + 1)/(2m)) sin θ P̄_{m−1}^{m−1}, which is stable to high
    orders (the standard forward-column recursion; Holmes & Featherstone 2002, "A unified
    approach to the Clenshaw summation and the recursive computation of very high degree
    and order normalised associated Legendre functions", J. Geodesy 76, 279-299).

    Parameters
    ----------
    order : int
        L ≥ 0.
    x : (n,) float
        cos θ in [−1, 1].

    Returns
    -------
    (n, (L + 1)²) float
        Column l² + l + m holds the factor of Y_lm.
    """
    x = np.asarray(x, float)
    s = np.sqrt(np.maximum(1.0 - x * x, 0.0))
    out = np.empty((len(x), size(order)))
    pmm = np.full(len(x), math.sqrt(1.0 / (4.0 * math.pi)))
    for m in range(order + 1):
        if m:
            pmm = -math.sqrt((2 * m + 1) / (2 * m)) * s * pmm
        scale = math.sqrt(2.0) if m else 1.0
        prev, cur = np.zeros_like(x), pmm
        a_prev = 0.0
        for l in range(m, order + 1):
            if l == m + 1:
                prev, cur = cur, math.sqrt(2 * m + 3) * x * cur
                a_prev = math.sqrt(2 * m + 3)
            elif l > m + 1:
                a = math.sqrt((4 * l * l - 1) / (l * l - m * m))
                prev, cur = cur, a * (x * cur - prev / a_prev)
                a_prev = a
            out[:, l * l + l + m] = scale * cur
            out[:, l * l + l - m] = scale * cur
    return out


def basis(order: int, cos_theta: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Real harmonics Y_k at directions (θ, φ).

    Parameters
    ----------
    order : int
    cos_theta, phi : (n,) float
        cos θ and φ (radians) of each direction.

    Returns
    -------
    (n, (L + 1)²) float
    """
    _, m = degrees(order)
    phi = np.asarray(phi, float)[:, None]
    trig = np.where(m > 0, np.cos(m * phi), np.where(m < 0, np.sin(-m * phi), 1.0))
    return legendre(order, cos_theta) * trig


def angles(directions: np.ndarray, phi_ref: float = 0.0) -> np.ndarray:
    """(n, 2) colatitude and azimuth (relative to ``phi_ref``, wrapped to [0, 2π)) of unit
    ``directions`` (n, 3), C-contiguous float64 as ducc0 takes them."""
    theta = np.arccos(np.clip(directions[:, 2], -1.0, 1.0))
    phi = np.mod(np.arctan2(directions[:, 1], directions[:, 0]) - phi_ref, 2.0 * math.pi)
    return np.ascontiguousarray(np.column_stack([theta, phi]))


@lru_cache(maxsize=8)
def _from_healpy(order: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Index into ducc0's complex a_lm (healpy layout, m ≥ 0) and the factors that turn
    Re and Im into the real coefficient of each flat index."""
    l, m = degrees(order)
    am = np.abs(m)
    source = am * (2 * order + 1 - am) // 2 + l
    root2 = math.sqrt(2.0)
    return source, np.where(m > 0, root2, np.where(m == 0, 1.0, 0.0)), np.where(
        m < 0, -root2, 0.0)


Mapper = Callable[[Callable[[int], np.ndarray], range], list[np.ndarray]]
"""``mapper(fn, range(n))`` returns ``[fn(0), …, fn(n − 1)]``, in any schedule (e.g.
``PeriodicScene.map`` on the tracer's worker threads)."""


def _in_order(fn: Callable[[int], np.ndarray], jobs: range) -> list[np.ndarray]:
    return [fn(j) for j in jobs]


def _transform(loc: np.ndarray, w: np.ndarray, order: int) -> np.ndarray:
    """Σ_i w_i Y_k(ω_i), ((L + 1)²,): one call of ducc0's adjoint non-uniform SHT.

    ``ducc0.sht.adjoint_synthesis_general`` returns Σ_i w_i conj(Y_l^m(ω_i)) for m ≥ 0
    (healpy's complex harmonics, Condon-Shortley phase), from which Y_lm = √2 Re Y_l^m and
    Y_l,−m = √2 Im Y_l^m give the real sums. It runs on one thread: its result is the same
    bit for bit whatever thread calls it (with two threads ducc0's last bits vary).
    """
    import ducc0

    source, f_re, f_im = _from_healpy(order)
    if len(loc) == 0:
        return np.zeros(size(order))
    alm = ducc0.sht.adjoint_synthesis_general(
        map=np.ascontiguousarray(w[None, :], float), spin=0, lmax=order, loc=loc,
        epsilon=EPSILON, nthreads=1)[0]
    return alm.real[source] * f_re + alm.imag[source] * f_im


def _distinct(columns: np.ndarray) -> tuple[list[int], list[int]]:
    """The first of every group of equal rows of ``columns`` ((c, n): the weight columns,
    e.g. the RGB weights of a grey material), and for every row the position of its
    group's first in that list.

    Equal rows have equal sums (the same additions of the same numbers), so only rows of
    equal sums are compared element by element: one pass over the weights, where
    comparing every pair of a spectral table's 32 channels took 496 passes.
    """
    sums = columns.sum(axis=1)
    first: list[int] = []
    which = []
    for j in range(len(columns)):
        same = next((p for p, k in enumerate(first)
                     if sums[k] == sums[j] and np.array_equal(columns[k], columns[j])), None)
        if same is None:
            first.append(j)
        which.append(len(first) - 1 if same is None else same)
    return first, which


def project(loc: np.ndarray, weights: np.ndarray, order: int,
            mapper: Mapper | None = None) -> np.ndarray:
    """Σ_i w_i Y_k(ω_i) for every real harmonic and weight column (``_transform``); a
    column equal to an earlier one reuses its transform.

    Parameters
    ----------
    loc : (n, 2) float
        Colatitude and azimuth of each sample (``angles``).
    weights : (n, c) float
    order : int
        L ≥ 0.
    mapper : Mapper or None
        Runs the transforms (default: one after the other).

    Returns
    -------
    ((L + 1)², c) float
    """
    return moments(loc, weights, order, mapper, second=False)[0]


def _reduced(rows: np.ndarray) -> tuple[list[np.ndarray], np.ndarray | None]:
    """The rows to transform instead of ``rows`` ((k, n)) and the mix that turns their
    transforms into the rows' (``microsim.tables.principal``; None: the rows themselves),
    principal components only of more than ``PRINCIPAL_CHANNELS`` rows."""
    if len(rows) <= PRINCIPAL_CHANNELS:
        return list(rows), None
    found = principal(rows, PRINCIPAL_TOLERANCE)
    return (list(rows), None) if found is None else (list(found[0]), found[1])


def _mixed(done: list[np.ndarray], mix: np.ndarray | None) -> list[np.ndarray]:
    """Transforms of the rows ``_reduced`` gave, as the transforms of the rows it was
    given: (c, K) = M (r, K) for the mix M."""
    return done if mix is None else list(mix @ np.stack(done))


def moments(loc: np.ndarray, weights: np.ndarray, order: int, mapper: Mapper | None = None,
            second: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
    """Σ w Y_k to order L and Σ w² Y_K to order 2L (``second_moments`` turns the latter
    into Σ (w Y_k)²), one transform per distinct column and moment, run by ``mapper``;
    a column equal to its square (weights 0 or 1) takes Σ w Y_k from its order-2L
    transform (one transform instead of two, to ducc0's accuracy, ``EPSILON``). More than
    ``PRINCIPAL_CHANNELS`` distinct columns (a spectral table's) are transformed through
    their principal components where they have few (``microsim.tables.principal``: to
    ``PRINCIPAL_TOLERANCE`` of the weights' norm).

    Parameters
    ----------
    loc : (n, 2) float
    weights : (n, c) float
        Taken as they are where each column's entries are adjacent in memory (the
        transpose of a channel-major (c, n) array: ``w[:, a:b].T``), else copied once.
    order : int
    mapper : Mapper or None
    second : bool
        Also the order-2L sums of w².

    Returns
    -------
    sums : ((L + 1)², c) float
    sums_sq_wide : ((2L + 1)², c) float, or None without ``second``
    """
    columns = np.asarray(weights, float).T
    if columns.strides[-1] != columns.itemsize:  # a column's entries apart: one copy
        columns = np.ascontiguousarray(columns)
    first, which = _distinct(columns)
    squares = columns[first] ** 2 if second else columns[:0]
    # weights that are their own squares (0 or 1: mirror facets) take their first moments
    # from the order-2L transform of w² = w, whose first (L + 1)² coefficients they are
    own = [second and np.array_equal(squares[i], columns[j]) for i, j in enumerate(first)]
    kept = [j for i, j in enumerate(first) if not own[i]]
    narrow, narrow_mix = _reduced(columns if kept == list(range(len(columns)))
                                  else columns[kept])
    wide, wide_mix = _reduced(squares)
    jobs = [(w, order) for w in narrow] + [(w2, 2 * order) for w2 in wide]
    done = (mapper or _in_order)(lambda i: _transform(loc, *jobs[i]), range(len(jobs)))
    wide_sums = _mixed(done[len(narrow):], wide_mix)
    narrow_sums = iter(_mixed(done[:len(narrow)], narrow_mix))
    columns = [wide_sums[i][:size(order)] if own[i] else next(narrow_sums)
               for i in range(len(first))]
    sums = np.stack(columns, axis=1)[:, which]
    return sums, np.stack(wide_sums, axis=1)[:, which] if second else None


@lru_cache(maxsize=8)
def square_matrix(order: int) -> Any:
    """Sparse ((L + 1)², (2L + 1)²) matrix G with Y_k² = Σ_K G[k, K] Y_K.

    Y_k² has degree 2l ≤ 2L, so the expansion is exact, and Σ_i w_i² Y_k(ω_i)² =
    G · (Σ_i w_i² Y_K(ω_i)): one order-2L projection of w² gives the second moment of every
    coefficient. G[k, K] = ∫ Y_k² Y_K dω (Gaunt coefficients); the azimuthal integral
    of t_m² t_M (t the cos/sin/1 factor) is 2π δ_M0 for m = 0 and π δ_M0 ± (π/2) δ_M,2|m|
    otherwise (+ for cosines), and the polar one is done with Gauss-Legendre in cos θ,
    exact for the polynomial of degree ≤ 4L with 2L + 2 nodes.

    Returns
    -------
    scipy.sparse.csr_matrix
    """
    import scipy.sparse

    wide = 2 * order
    x, wx = np.polynomial.legendre.leggauss(wide + 2)
    p = legendre(order, x) ** 2                         # (q, (L+1)²)
    pw = legendre(wide, x) * wx[:, None]                # (q, (2L+1)²)
    l, m = degrees(order)
    big_l, big_m = degrees(wide)
    rows, cols, vals = [], [], []
    zonal = np.flatnonzero(big_m == 0)
    polar = p.T @ pw[:, zonal]                          # ∫ p_k² p_K, K zonal
    phi0 = np.where(m == 0, 2.0 * math.pi, math.pi)
    rows.append(np.repeat(np.arange(len(l)), len(zonal)))
    cols.append(np.tile(zonal, len(l)))
    vals.append((polar * phi0[:, None]).ravel())
    for k in np.flatnonzero(m != 0):
        ks = np.flatnonzero(big_m == 2 * abs(m[k]))
        sign = 1.0 if m[k] > 0 else -1.0
        rows.append(np.full(len(ks), k))
        cols.append(ks)
        vals.append(sign * 0.5 * math.pi * (p[:, k] @ pw[:, ks]))
    g = scipy.sparse.coo_matrix((np.concatenate(vals), (np.concatenate(rows),
                                                         np.concatenate(cols))),
                                shape=(size(order), size(wide))).tocsr()
    g.data[np.abs(g.data) < 1e-14] = 0.0
    g.eliminate_zeros()
    return g


def second_moments(sums_sq_wide: np.ndarray, order: int) -> np.ndarray:
    """Σ_i w_i² Y_k(ω_i)² from the order-2L sums Σ_i w_i² Y_K(ω_i) (``square_matrix``).

    Parameters
    ----------
    sums_sq_wide : (..., (2L + 1)², c) float
    order : int

    Returns
    -------
    (..., (L + 1)², c) float
    """
    s = np.moveaxis(np.asarray(sums_sq_wide, float), -2, 0)
    flat = square_matrix(order) @ s.reshape(s.shape[0], -1)
    return np.moveaxis(flat.reshape((size(order),) + s.shape[1:]), 0, -2)


def window(order: int, kind: str) -> np.ndarray:
    """Per-coefficient factors of a smoothing window over l, ((L + 1)²,) float.

    ``"lanczos"``: Lanczos σ-factors sinc(l / (L + 1)) = sin(πl/(L+1)) / (πl/(L+1))
    (Lanczos 1956, Applied Analysis, on σ-factors; Sloan 2008, "Stupid spherical harmonics
    (SH) tricks", on windowing). ``"hanning"``: ½ (1 + cos(πl / (L + 1))). Both
    are 1 at l = 0, so the albedo is kept; ``"none"``: ones.

    Raises
    ------
    ValueError
        For another ``kind``.
    """
    l, _ = degrees(order)
    t = l / (order + 1)
    if kind == "none":
        return np.ones(len(l))
    if kind == "lanczos":
        return np.sinc(t)
    if kind == "hanning":
        return 0.5 * (1.0 + np.cos(math.pi * t))
    raise ValueError(f"window must be one of {WINDOWS}, got {kind!r}")


def truncate(coefficients: np.ndarray, order: int) -> np.ndarray:
    """The first (order + 1)² coefficients along axis −2 of (..., n, c) ``coefficients``.

    Raises
    ------
    ValueError
        If the expansion is of a lower order.
    """
    have = order_of(np.shape(coefficients)[-2])
    if order > have:
        raise ValueError(f"order {order} exceeds the stored order {have}")
    return coefficients[..., : size(order), :]
