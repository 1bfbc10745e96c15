"""How much a truncated spherical-harmonic lobe loses against the binned table.

Both representations are compared where the table is defined: as averages over its bins
of g = f_r cos θo per unit solid angle. The table's bin value is the projected-solid-angle
average f̄ = ∫_bin f_r cos θo dω / Ω_proj, so ∫_bin g dω = f̄ Ω_proj; the harmonics'
integral ∫_bin g dω = Σ_k c_k ∫_bin Y_k dω is computed by quadrature (``bin_integrals``).
The relative L2 error is then

    ‖G_sh − G_table‖ / ‖G_table‖,   ‖G‖² = Σ_bins Ω_bin G²  (G = ∫_bin g dω / Ω_bin),

the discrete form of the L2(dω) norm of g, over every bin (the hemisphere) or over the
lobe bins (``BRDFTable.lobe_mask``), pooled over incidences and channels (R, G, B, or one
per wavelength), and per channel (``rel_l2_error_per_channel``). Both sides carry Monte
Carlo noise; the report gives each side's expected share (``table_noise``, ``sh_noise``),
below which the error cannot fall.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from microsim.tables import sh
from microsim.tables.binning import HemisphereBins
from microsim.tables.evaluate import SH_CHUNK
from microsim.tables.table import BRDFTable

NODES = 8
"""Gauss-Legendre nodes in cos θ per θo ring for the bin integrals."""
GRID = 2
"""Points per bin and axis (in sin²θo and φo) where the most negative value is sought."""


def bin_integrals(order: int, bins: HemisphereBins) -> tuple[np.ndarray, np.ndarray]:
    """∫_bin Y_k dω of every bin and harmonic, and the bins' solid angles.

    The polar integral over each θo ring is Gauss-Legendre in x = cos θ with ``NODES``
    nodes; the azimuthal one is exact: ∫ cos mφ = (sin mφb − sin mφa)/m,
    ∫ sin mφ = (cos mφa − cos mφb)/m. A folded table's bin also covers its mirror image
    φ → −φ, over which the sines cancel and the rest doubles.

    Parameters
    ----------
    order : int
    bins : HemisphereBins

    Returns
    -------
    integrals : (nt·np, (L + 1)²) float
        Rows in the table's flat bin order ``it * phi_bins + ip``.
    solid_angle : (nt·np,) float
        Ω_bin = Δ(cos θ) Δφ (doubled when folded), sr.
    """
    x_edges = np.sqrt(1.0 - bins.u_edges)                  # cos θ, decreasing
    t, wt = np.polynomial.legendre.leggauss(NODES)
    lo, hi = x_edges[1:], x_edges[:-1]
    x = 0.5 * (hi - lo)[:, None] * t + 0.5 * (hi + lo)[:, None]
    w = 0.5 * (hi - lo)[:, None] * wt
    rings = np.einsum("rq,rqk->rk", w, sh.legendre(order, x.ravel()).reshape(
        bins.theta_bins, NODES, -1))
    _, m = sh.degrees(order)
    a, b = bins.phi_edges[:-1, None], bins.phi_edges[1:, None]
    mu = np.maximum(np.abs(m), 1)
    azimuth = np.where(m > 0, (np.sin(mu * b) - np.sin(mu * a)) / mu,
                       np.where(m < 0, (np.cos(mu * a) - np.cos(mu * b)) / mu, b - a))
    mirror = 2.0 if bins.folded else 1.0
    if bins.folded:
        azimuth = np.where(m < 0, 0.0, azimuth)
    integrals = mirror * rings[:, None, :] * azimuth[None, :, :]
    solid_angle = mirror * np.outer(hi - lo, np.diff(bins.phi_edges))
    return integrals.reshape(bins.size, -1), solid_angle.ravel()


def _grid(bins: HemisphereBins) -> tuple[np.ndarray, np.ndarray]:
    """cos θ and φ of ``GRID``² points per bin (uniform in sin²θ and φ)."""
    u = (np.arange(GRID * bins.theta_bins) + 0.5) / (GRID * bins.theta_bins)
    phi = (np.arange(GRID * bins.phi_bins) + 0.5) * bins.phi_period / (GRID * bins.phi_bins)
    uu, pp = np.meshgrid(u, phi, indexing="ij")
    return np.sqrt(1.0 - uu.ravel()), pp.ravel()


def _extremes(order: int, cos_theta: np.ndarray, phi: np.ndarray, c: np.ndarray
              ) -> tuple[float, float]:
    """Smallest and largest value of the series ``c`` (a, b, (L + 1)², C) at the points,
    with the basis evaluated ``SH_CHUNK`` values at a time."""
    step = max(1, SH_CHUNK // sh.size(order))
    low, high = np.inf, -np.inf
    for start in range(0, len(phi), step):
        y = sh.basis(order, cos_theta[start:start + step], phi[start:start + step])
        g = np.einsum("pk,abkc->abpc", y, c)
        low, high = min(low, float(g.min())), max(high, float(g.max()))
    return low, high


def order_errors(table: BRDFTable, orders: list[int], window: str = "none",
                 component: str = "total") -> list[dict[str, Any]]:
    """Error, negativity and size of the table's harmonics truncated at each order.

    Parameters
    ----------
    table : BRDFTable
        A table with harmonics (``table.has_sh``).
    orders : list of int
        Orders L, each at most ``table.sh_order``.
    window : str
        ``"none"``, ``"lanczos"`` or ``"hanning"`` (``sh.window``), applied to each
        truncation.
    component : str
        A component of the table (``"total"``, ``"single"``, ``"order2"``, …).

    Returns
    -------
    list of dict
        Per order: ``order``, ``window``, ``coefficients``; ``rel_l2_error`` (over the
        hemisphere) and ``rel_l2_error_lobe`` (over the lobe bins), with the window;
        ``rel_l2_error_unwindowed`` and ``rel_l2_error_lobe_unwindowed`` without it (the
        window's cost); for a spectral table also its ``channels`` (names) and
        ``rel_l2_error_per_channel`` and ``rel_l2_error_lobe_per_channel``, the two
        windowed errors of each channel alone (C of them); ``table_noise`` and
        ``sh_noise``, the relative L2 size of each side's standard errors (the noise
        floor of the error: ``sh_noise`` by Parseval over the sphere, an upper bound);
        ``min_value``, the most negative f_r cos θo (1/sr) at ``GRID``² points per bin
        over every incidence and channel (0 if none), and ``min_relative``, it over the
        largest value (ratios are NaN for a table without reflected light); ``bytes``,
        the float32 size of the coefficients of one component (all incidences and
        channels).

    Raises
    ------
    ValueError
        If the table holds no harmonics or an order exceeds the stored one.
    """
    if not table.has_sh:
        raise ValueError("the table holds no spherical harmonics")
    component = table.component(component)
    a, b = table.rays.shape
    count = table.channels.count
    # Ω_proj over the same region as Ω: a folded bin's solid angle (bin_integrals) covers
    # its mirror image too, HemisphereBins.projected_solid_angle one side only
    omega_proj = table.bins.projected_solid_angle.ravel() * (2.0 if table.bins.folded
                                                             else 1.0)
    integrals, omega = bin_integrals(max(orders), table.bins)
    scale = (omega_proj / omega)[None, None, :, None]
    g_table = table[component].values.reshape(a, b, -1, count) * scale
    e_table = np.nan_to_num(table[component].errors.reshape(a, b, -1, count)) * scale
    lobe = np.broadcast_to(table.lobe_mask(component).reshape(a, b, -1, 1), g_table.shape)
    w = np.broadcast_to(omega[None, None, :, None], g_table.shape)
    cos_theta, phi = _grid(table.bins)

    def ratio(num: float, den: float) -> float:
        """num / den, NaN for an empty table (no reflected light: nothing to compare)."""
        return num / den if den > 0 else math.nan

    def rel(g: np.ndarray, where: np.ndarray | None = None) -> float:
        sel = np.ones(g.shape, bool) if where is None else where
        return math.sqrt(ratio(float((w * (g - g_table) ** 2)[sel].sum()),
                               float((w * g_table ** 2)[sel].sum())))

    def rel_per_channel(g: np.ndarray, where: np.ndarray | None = None) -> list[float]:
        """``rel`` of each channel alone (the last axis)."""
        sel = np.ones(g.shape, bool) if where is None else where
        num = np.where(sel, w * (g - g_table) ** 2, 0.0).sum(axis=(0, 1, 2))
        den = np.where(sel, w * g_table ** 2, 0.0).sum(axis=(0, 1, 2))
        return [math.sqrt(ratio(float(n), float(d))) for n, d in zip(num, den, strict=True)]

    norm = float((w * g_table ** 2).sum())
    rows = []
    for order in orders:
        n = sh.size(order)
        plain = sh.truncate(table[component].sh, order)
        errors = sh.truncate(table[component].sh_err, order)
        factors = sh.window(order, window)[:, None]

        def bins_of(c: np.ndarray, n: int = n) -> np.ndarray:
            return np.einsum("jk,abkc->abjc", integrals[:, :n], c) / omega[:, None]

        windowed = plain * factors
        g = bins_of(windowed)
        low, high = _extremes(order, cos_theta, phi, windowed)
        g_plain = bins_of(plain)
        per_channel = {} if not table.channels.spectral else {
            "channels": list(table.channels.names),
            "rel_l2_error_per_channel": rel_per_channel(g),
            "rel_l2_error_lobe_per_channel": rel_per_channel(g, lobe)}
        rows.append({
            "order": order, "window": window, "coefficients": n,
            "rel_l2_error": rel(g), "rel_l2_error_lobe": rel(g, lobe),
            "rel_l2_error_unwindowed": rel(g_plain),
            "rel_l2_error_lobe_unwindowed": rel(g_plain, lobe), **per_channel,
            "table_noise": math.sqrt(ratio(float((w * e_table ** 2).sum()), norm)),
            "sh_noise": math.sqrt(ratio(float((np.nan_to_num(errors * factors) ** 2).sum()),
                                        norm)),
            "min_value": min(low, 0.0),
            "min_relative": ratio(min(low, 0.0), high),
            "bytes": n * a * b * count * 4,
        })
    return rows
