"""Reading a binned table between its nodes: f_r and its standard error interpolated at
any direction pair, and f_r from a table's spherical harmonics.

The table is a piecewise-linear function of its axes (``microsim.tables.interpolation``):
linear in θi (and periodically in φi for anisotropic tables) between the incidences,
clamped outside them; bilinear in (sin²θo, φo) between bin centres, periodic in φo,
clamped at the horizon, and between the first ring's centres and the pole blended
linearly in sin²θo towards the ring's mean (``pole_share``), so f_r has one value at the
pole. ``BRDFTable.eval`` and ``BRDFTable.stderr`` are
these functions of its arrays.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from microsim.tables import sh
from microsim.tables.binning import TWO_PI, HemisphereBins
from microsim.tables.interpolation import linear_weights

CHUNK = 65536
"""Direction pairs interpolated at once."""
SH_CHUNK = 1 << 22
"""Basis values (pairs × (L + 1)²) evaluated at once from spherical harmonics (32 MB)."""


@dataclass(frozen=True)
class Axes:
    """A table's axes: outgoing bins, incident polar angles and azimuths (radians), and
    whether outgoing azimuths are relative to the incident one."""

    bins: HemisphereBins
    theta_i: np.ndarray
    phi_i: np.ndarray
    isotropic: bool


def stencil(axes: Axes, wi: np.ndarray, wo: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The 16 interpolation nodes of each direction pair: linear in θi and φi between
    incidences, bilinear in (sin²θo, φo) between bin centres (clamped at the pole and
    the horizon, periodic in φo; ``interpolate`` blends the pole's values).

    Parameters
    ----------
    wi, wo : (n, 3) float
        Unit directions, local frame.

    Returns
    -------
    nodes : (n, 16) int
        Flat indices into an (a·b·nt·np, C) view of a table array.
    weights : (n, 16) float
        Interpolation weights, summing to 1; the node with the largest weight is the
        nearest one (the nearest incidence and the bin holding ωo).
    above : (n,) bool
        Both directions strictly above the horizon.
    """
    theta_in = np.arccos(np.clip(wi[:, 2], -1.0, 1.0))
    phi_in = np.arctan2(wi[:, 1], wi[:, 0])
    phi_out = np.arctan2(wo[:, 1], wo[:, 0])
    if axes.isotropic:
        phi_out = phi_out - phi_in
    per_axis = (
        linear_weights(theta_in, axes.theta_i),
        linear_weights(np.mod(phi_in, TWO_PI), axes.phi_i, TWO_PI),
        linear_weights(np.clip(wo[:, 0] ** 2 + wo[:, 1] ** 2, 0.0, 1.0),
                       np.sin(axes.bins.theta_centers) ** 2),
        linear_weights(axes.bins.relative_phi(phi_out), axes.bins.phi_centers,
                       axes.bins.phi_period),
    )
    sizes = (len(axes.theta_i), len(axes.phi_i)) + axes.bins.shape
    nodes = np.zeros((len(wi),) + (1,) * 4, np.int64)
    weights = np.ones((len(wi),) + (1,) * 4)
    for k, ((i0, i1, w1), size) in enumerate(zip(per_axis, sizes, strict=True)):
        at = (slice(None),) + (None,) * k + (slice(None),) + (None,) * (3 - k)
        nodes = nodes * size + np.stack([i0, i1], -1)[at]
        weights = weights * np.stack([1.0 - w1, w1], -1)[at]
    above = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    return nodes.reshape(len(wi), 16), weights.reshape(len(wi), 16), above


def per_pair(axes: Axes, kernel: Callable[[np.ndarray, np.ndarray], np.ndarray],
             wi: np.ndarray, wo: np.ndarray, channels: int = 3) -> np.ndarray:
    """``kernel(nodes, weights)`` over the direction pairs in chunks of ``CHUNK`` (the
    16-node gathers stay a few tens of MB however many pairs), 0 where either direction
    is at or below the horizon.

    Parameters
    ----------
    axes : Axes
    kernel : callable
        ``kernel(nodes (n, 16) int, weights (n, 16) float) -> (n, C) float``.
    wi, wo : (..., 3) float
        Unit directions, local frame.
    channels : int
        C, the channels the kernel gives (3: RGB; one per wavelength).

    Returns
    -------
    (..., C) float
    """
    wi, wo = np.broadcast_arrays(np.asarray(wi, float), np.asarray(wo, float))
    shape = wi.shape[:-1]
    wi, wo = wi.reshape(-1, 3), wo.reshape(-1, 3)
    out = np.zeros((len(wi), channels))
    for start in range(0, len(wi), CHUNK):
        sl = slice(start, start + CHUNK)
        nodes, weights, above = stencil(axes, wi[sl], wo[sl])
        out[sl] = np.where(above[:, None], kernel(nodes, weights), 0.0)
    return out.reshape(shape + (channels,))


def interpolate(axes: Axes, values: np.ndarray, wi: np.ndarray, wo: np.ndarray
                ) -> np.ndarray:
    """Interpolated f_r (``BRDFTable.eval``); an empty bin's value is 0, so the result is
    never NaN.

    Parameters
    ----------
    axes : Axes
    values : (a, b, nt, np, C) float
        C channels: R, G, B or one per wavelength.
    wi, wo : (..., 3) float
        Unit directions towards the light and the viewer, local frame.

    Returns
    -------
    (..., C) float
        0 where either direction is at or below the horizon.
    """
    def at(data: np.ndarray) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
        return lambda nodes, w: np.einsum("nk,nkc->nc", w, data[nodes])

    count = values.shape[-1]
    f = per_pair(axes, at(values.reshape(-1, count)), wi, wo, count)
    wi, wo = np.broadcast_arrays(np.asarray(wi, float), np.asarray(wo, float))
    q = pole_share(axes.bins, wo)
    near = q > 0
    if near.any():
        # inside the first ring's centres every node is on the ring: subtract the share q
        # of its departure from the ring's mean, so f → that mean at the pole
        ring = values[:, :, 0]
        delta = np.zeros_like(values)
        delta[:, :, 0] = ring - ring.mean(axis=2, keepdims=True)
        f[near] -= q[near][:, None] * per_pair(axes, at(delta.reshape(-1, count)),
                                               wi[near], wo[near], count)
    return f


def pole_share(bins: HemisphereBins, wo: np.ndarray) -> np.ndarray:
    """How far inside the first θo ring's bin centres ``wo`` lies: 1 − sin²θo / sin²θ₁
    there (θ₁ the ring's centre; 1 at the pole), 0 beyond.

    Between the pole and the ring's centres ``interpolate`` blends the ring's bins
    linearly in sin²θo towards their mean: at the pole every azimuth is the same
    direction, so f_r has one value there (the mean of the ring, which covers it
    symmetrically); clamping would keep each bin's own value up to the pole and make f_r
    depend on the direction a path approaches the normal from (a star of the ring's
    bins where a render looks straight at a surface, docs/render.md).

    Parameters
    ----------
    bins : HemisphereBins
    wo : (..., 3) float
        Unit directions.

    Returns
    -------
    (...,) float
        In [0, 1].
    """
    s = np.clip(wo[..., 0] ** 2 + wo[..., 1] ** 2, 0.0, 1.0)
    return np.clip(1.0 - s / np.sin(bins.theta_centers[0]) ** 2, 0.0, 1.0)


def from_harmonics(axes: Axes, coefficients: np.ndarray, wi: np.ndarray, wo: np.ndarray
                   ) -> np.ndarray:
    """f_r = Σ_k c_k Y_k(ωo) / cos θo from a table's coefficients of f_r cos θo
    (``BRDFTable.eval`` with ``representation="sh"``), interpolated linearly in θi (and φi)
    as the bins are, in chunks of ``SH_CHUNK`` basis values.

    Parameters
    ----------
    axes : Axes
    coefficients : (a, b, (L + 1)², C) float
    wi, wo : (..., 3) float

    Returns
    -------
    (..., C) float
        0 where either direction is at or below the horizon.
    """
    a, b, n, count = coefficients.shape
    coef = np.moveaxis(coefficients, 2, 0).reshape(n, a * b * count)
    wi, wo = np.broadcast_arrays(np.asarray(wi, float), np.asarray(wo, float))
    shape = wi.shape[:-1]
    wi, wo = wi.reshape(-1, 3), wo.reshape(-1, 3)
    out = np.zeros((len(wi), count))
    step = max(1, SH_CHUNK // n)
    for start in range(0, len(wi), step):
        i, o = wi[start:start + step], wo[start:start + step]
        phi_in = np.arctan2(i[:, 1], i[:, 0])
        phi_out = np.arctan2(o[:, 1], o[:, 0]) - (phi_in if axes.isotropic else 0.0)
        g = (sh.basis(sh.order_of(n), o[:, 2], phi_out) @ coef).reshape(len(i), a * b,
                                                                        count)
        total = blend_incidences(axes, i, g)
        above = (i[:, 2] > 0) & (o[:, 2] > 0)
        out[start:start + step] = np.where(
            above[:, None], total / np.where(above, o[:, 2], 1.0)[:, None], 0.0)
    return out.reshape(shape + (count,))


def blend_incidences(axes: Axes, wi: np.ndarray, g: np.ndarray) -> np.ndarray:
    """Values known at every incidence of the table, interpolated linearly in θi (and
    periodically in φi) at each pair's own incidence, as the bins are.

    Parameters
    ----------
    axes : Axes
    wi : (n, 3) float
        Unit directions towards the light.
    g : (n, a·b, C) float
        Each pair's value at every incidence, rows ``i_theta_i * n_phi_i + i_phi_i``.

    Returns
    -------
    (n, C) float
    """
    b = len(axes.phi_i)
    t0, t1, wt = linear_weights(np.arccos(np.clip(wi[:, 2], -1.0, 1.0)), axes.theta_i)
    p0, p1, wp = linear_weights(np.mod(np.arctan2(wi[:, 1], wi[:, 0]), TWO_PI), axes.phi_i,
                                TWO_PI)
    rows = np.arange(len(wi))
    total = np.zeros((len(wi), g.shape[-1]))
    for t, w_t in ((t0, 1.0 - wt), (t1, wt)):
        for p, w_p in ((p0, 1.0 - wp), (p1, wp)):
            total += (w_t * w_p)[:, None] * g[rows, t * b + p]
    return total


def interpolate_error(axes: Axes, errors: np.ndarray, wi: np.ndarray, wo: np.ndarray
                      ) -> np.ndarray:
    """The interpolated standard error of ``BRDFTable.stderr`` (which says how undefined
    errors are left out), with the nodes of ``interpolate``.

    Parameters
    ----------
    axes : Axes
    errors : (a, b, nt, np, C) float
        The table's standard errors (NaN where undefined).
    wi, wo : (..., 3) float
        Unit directions, local frame.

    Returns
    -------
    (..., C) float
    """
    count = errors.shape[-1]
    err = errors.reshape(-1, count)

    def kernel(nodes: np.ndarray, weights: np.ndarray) -> np.ndarray:
        known = np.isfinite(err[nodes])                               # (n, 16, C)
        w = np.where(known, weights[..., None], 0.0)
        nearest = np.argmax(weights, axis=1)
        undefined = ~np.take_along_axis(known, nearest[:, None, None], axis=1)[:, 0]
        out = (w * np.nan_to_num(err[nodes])).sum(axis=1) / np.where(
            undefined, 1.0, w.sum(axis=1))
        return np.where(undefined, np.nan, out)

    return per_pair(axes, kernel, wi, wo, count)
