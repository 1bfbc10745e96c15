"""Gaussian random height fields by spectral synthesis on a periodic grid.

The height h(x, y) is a stationary Gaussian process with autocorrelation
C(r) = σ² exp(−(x'²/τx² + y'²/τy²)), (x', y') the coordinates rotated by ``rotation``.
Its slopes along x' have variance −∂²C/∂x'²(0) = 2σ²/τx², so Walter et al. 2007's
roughness is α = √2 · RMS slope = 2σ/τ (the Beckmann-Spizzichino m; Beckmann &
Spizzichino 1963, ch. 5). Synthesis is exact for the periodic grid: with C sampled at the
minimum-image displacements (a circulant covariance) and P = DFT(C) its eigenvalues, the
field F⁻¹(√P · F w) of white noise w has covariance exactly C (Dietrich & Newsam 1997,
SIAM J. Sci. Comput. 18(4), circulant embedding). The tile is not rescaled to its target
σ: a finite tile's sample roughness fluctuates, and the tile reports the roughness its
facets really have (``Tile.realised_alpha``).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from dataclasses import replace
from typing import Any

import numpy as np

from microsim.surfaces.facts import GaussianFacts, Roughness
from microsim.surfaces.rules import correlation_lengths
from microsim.surfaces.tile import Tile, grid_faces, height_field_vertices

MIN_CELLS = 4
"""Below this many cells per correlation length the facets under-resolve the slopes."""
MIN_LENGTHS = 30
"""Below this many correlation lengths per tile side the realised NDF is noisy."""


def discretised_alpha_ratio(cells: float) -> float:
    """Expected realised over continuous α when slopes are finite differences over a grid
    step h = τ / cells: E[(Δh/h)²] = 2σ²(1 − exp(−x))/h² with x = (h/τ)², against the
    continuous 2σ²/τ², so α_h/α = √((1 − e^{−x})/x) (0.996 at 8 cells, 0.941 at 2)."""
    x = 1.0 / cells**2
    return math.sqrt(-math.expm1(-x) / x)


def heights(n: int, size: float, sigma: float, tau_x: float, tau_y: float,
            rotation: float, rng: np.random.Generator) -> np.ndarray:
    """Periodic Gaussian random heights on an n × n grid of spacing size / n.

    Parameters
    ----------
    n : int
        Samples per side.
    size : float
        Period.
    sigma, tau_x, tau_y : float
        RMS height and correlation lengths along the rotated axes.
    rotation : float
        Rotation of the axes about +z, radians.
    rng : numpy.random.Generator

    Returns
    -------
    (n, n) float
        ``h[i, j]`` at x = i·size/n, y = j·size/n.
    """
    root = root_power(n, float(size), float(sigma), float(tau_x), float(tau_y),
                      float(rotation))
    noise = rng.standard_normal((n, n))
    return np.fft.ifft2(np.fft.fft2(noise) * root).real


@functools.lru_cache(maxsize=4)
def root_power(n: int, size: float, sigma: float, tau_x: float, tau_y: float,
               rotation: float) -> np.ndarray:
    """√P, P = DFT(C) the eigenvalues of the circulant covariance: the same for every
    realisation of a surface, so made once and kept (read-only) for the last few surfaces.

    Parameters
    ----------
    n, size, sigma, tau_x, tau_y, rotation
        As for ``heights``.

    Returns
    -------
    (n, n) float
        Read-only.
    """
    d = np.arange(n) * (size / n)
    d = np.where(d >= size / 2, d - size, d)  # minimum-image displacement
    dx, dy = np.meshgrid(d, d, indexing="ij")
    c, s = math.cos(rotation), math.sin(rotation)
    xr, yr = c * dx + s * dy, -s * dx + c * dy
    cov = sigma**2 * np.exp(-((xr / tau_x) ** 2 + (yr / tau_y) ** 2))
    # eigenvalues of the circulant covariance; tiny negatives are round-off of zeros
    root = np.sqrt(np.maximum(np.fft.fft2(cov).real, 0.0))
    root.flags.writeable = False
    return root


def build(surface: Mapping[str, Any]) -> Tile:
    """The Gaussian height-field tile of a resolved ``[surface]`` section.

    Parameters
    ----------
    surface : mapping
        Kind ``gaussian``: ``resolution``, ``size``, ``rotation`` (degrees), ``seed`` and
        one of ``alpha``; ``alpha_x`` + ``alpha_y``; ``sigma`` + ``correlation_length``.

    Returns
    -------
    Tile
        (resolution + 1)² vertices (the last row and column repeat the first, so opposite
        edges are equal bit for bit), 2·resolution² faces; ``facts`` holds
        ``alpha_target``, ``alpha_realised`` (and per-axis values when anisotropic),
        ``sigma``, ``correlation_length_x/_y``, ``isotropic``.
    """
    n, size = int(surface["resolution"]), float(surface["size"])
    rotation = math.radians(surface.get("rotation", 0.0))
    sigma, tau_x, tau_y = correlation_lengths(surface)
    h = heights(n, size, sigma, tau_x, tau_y, rotation, np.random.default_rng(surface["seed"]))
    vertices = height_field_vertices(h, size)
    faces = grid_faces(n + 1, n + 1)
    isotropic = math.isclose(tau_x, tau_y)
    tile = Tile(vertices, faces, np.zeros(len(faces), np.int32), ("base",), (size, size),
                facts=GaussianFacts(isotropic=isotropic, sigma=sigma,
                                    correlation_length_x=tau_x, correlation_length_y=tau_y,
                                    rotation_deg=math.degrees(rotation)))
    ax, ay = 2 * sigma / tau_x, 2 * sigma / tau_y
    rx, ry = tile.realised_alpha(rotation)
    if isotropic:
        tile.facts = replace(tile.facts, alpha_target=Roughness(ax),
                             alpha_realised=Roughness(math.sqrt((rx**2 + ry**2) / 2)))
    else:
        tile.facts = replace(tile.facts, alpha_target=Roughness(ax, ay),
                             alpha_realised=Roughness(rx, ry), alpha_target_x=ax,
                             alpha_target_y=ay, alpha_realised_x=rx, alpha_realised_y=ry)
    cell = size / n
    if min(tau_x, tau_y) < MIN_CELLS * cell:
        cells = min(tau_x, tau_y) / cell
        tile.warnings.append(
            f"surface: the correlation length spans {cells:.1f} grid cells (< {MIN_CELLS}): "
            f"facets under-resolve the slopes, so the realised roughness falls "
            f"{100 * (1 - discretised_alpha_ratio(cells)):.0f}% below the target; raise "
            "resolution or correlation_length")
    if size / max(tau_x, tau_y) < MIN_LENGTHS:
        tile.warnings.append(
            f"surface: the tile holds {size / max(tau_x, tau_y):.1f} correlation lengths "
            f"per side (< {MIN_LENGTHS}): few independent slopes, so the realised facet "
            "distribution is noisy; raise resolution or lower correlation_length")
    return tile
