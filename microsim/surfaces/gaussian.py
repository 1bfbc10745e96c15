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
from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np

from microsim.errors import InputError
from microsim.schema import key
from microsim.surfaces.base import (
    DEFAULT_CELLS,
    SURFACE_ALPHA_MIN,
    Surface,
    area_realisations,
    check_correlation,
    length_key,
    roughness_key,
    seed_key,
    size_key,
)
from microsim.surfaces.facts import GaussianFacts, Roughness
from microsim.surfaces.tile import Tile, height_field_tile

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
    return synthesis(root_power(n, float(size), float(sigma), float(tau_x), float(tau_y),
                                float(rotation)), rng)


def synthesis(root: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """F⁻¹(root · F w) of white standard normal noise w: the periodic Gaussian field whose
    circulant covariance has eigenvalues root² (Dietrich & Newsam 1997).

    Parameters
    ----------
    root : (n, n) float
        √ of the eigenvalues, symmetric under k → −k (so the field is real).
    rng : numpy.random.Generator

    Returns
    -------
    (n, n) float
    """
    noise = rng.standard_normal(root.shape)
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


@dataclass(frozen=True, kw_only=True)
class Gaussian(Surface):
    """A Gaussian random height field (``kind = "gaussian"``)."""

    kind: ClassVar[str] = "gaussian"
    doc: ClassVar[str] = (
        "A Gaussian random height field with autocorrelation sigma^2 exp(-r^2/tau^2), made "
        "by spectral (FFT) synthesis on a periodic grid. Roughness alpha = 2 sigma / tau "
        "(Walter et al. 2007's alpha, the lecture's m). Anisotropic: alpha_x, alpha_y set "
        "different correlation lengths along the rotated x and y axes.")
    alpha: float | None = roughness_key("Target roughness (isotropic).")
    alpha_x: float | None = roughness_key("Target roughness along the (rotated) x axis.")
    alpha_y: float | None = roughness_key("Target roughness along the (rotated) y axis.")
    sigma: float | None = length_key("RMS height (with correlation_length instead of "
                                     "alpha).")
    correlation_length: float | None = length_key(
        "Correlation length tau (of the larger roughness axis when anisotropic). Default: "
        "8 grid cells.")
    rotation: float = key("float", 0.0, "Rotation of the anisotropy axes about +z.",
                          unit="deg", low=-360.0, high=360.0)
    resolution: int = key("int", 256, "Vertices per tile side.", low=4, high=8192)
    size: float = size_key()
    seed: int = seed_key()

    def correlation_lengths(self) -> tuple[float, float, float]:
        """(σ, τx, τy): RMS height and the correlation lengths along the rotated axes
        (tile units) from whichever of alpha / alpha_x, alpha_y / sigma the section
        gives; α = 2σ/τ."""
        tau = (self.correlation_length if self.correlation_length is not None
               else DEFAULT_CELLS * self.size / self.resolution)
        if self.sigma is not None:
            return self.sigma, tau, tau
        if self.alpha is not None:
            return self.alpha * tau / 2, tau, tau
        ax, ay = self.alpha_x, self.alpha_y
        sigma = max(ax, ay) * tau / 2  # the rougher axis gets tau, the smoother a longer one
        return sigma, 2 * sigma / ax, 2 * sigma / ay

    def check(self) -> None:
        """Exactly one of: ``alpha``; ``alpha_x`` and ``alpha_y``; ``sigma`` (with
        ``correlation_length``); correlation lengths between a grid cell and the tile."""
        given = [k for k in ("alpha", "alpha_x", "alpha_y", "sigma") if self.given(k)]
        if given not in (["alpha"], ["alpha_x", "alpha_y"], ["sigma"]):
            raise InputError("surface: a gaussian surface takes exactly one of: alpha; "
                             "alpha_x and alpha_y; sigma (with correlation_length); got "
                             + (", ".join(given) or "none of them"))
        if self.sigma is not None and self.correlation_length is None:
            raise InputError("surface.correlation_length: missing; sigma needs it "
                             "(alpha = 2 sigma / correlation_length)")
        sigma, tau_x, tau_y = self.correlation_lengths()
        cell = self.size / self.resolution
        if self.sigma is not None and not SURFACE_ALPHA_MIN <= 2 * sigma / tau_x <= 10:
            raise InputError(f"surface.sigma = {sigma!r}: gives alpha = 2 sigma / "
                             f"correlation_length = {2 * sigma / tau_x:.3g}; must be in "
                             f"[{SURFACE_ALPHA_MIN:g}, 10]")
        base = "correlation_length" if self.correlation_length is not None else "resolution"
        for axis, tau in (("x", tau_x), ("y", tau_y)):
            # the smoother axis of an anisotropic surface gets the longer correlation length
            name = f"alpha_{axis}" if self.alpha_x is not None and tau > self.size else base
            check_correlation(name, self.value(name), tau, cell, self.size)

    def triangles(self) -> float:
        return 2 * self.resolution**2

    def realisations(self) -> int:
        """Enough realisations for ``ENSEMBLE_AREAS`` correlation areas."""
        _, tau_x, tau_y = self.correlation_lengths()
        return area_realisations(self.size**2, tau_x * tau_y)

    def build(self) -> Tile:
        """The Gaussian height-field tile.

        Returns
        -------
        Tile
            (resolution + 1)² vertices (the last row and column repeat the first, so
            opposite edges are equal bit for bit), 2·resolution² faces; ``facts`` holds
            ``alpha_target``, ``alpha_realised`` (and per-axis values when anisotropic),
            ``sigma``, ``correlation_length_x/_y``, ``isotropic``.
        """
        n, size = int(self.resolution), float(self.size)
        rotation = math.radians(self.rotation)
        sigma, tau_x, tau_y = self.correlation_lengths()
        h = heights(n, size, sigma, tau_x, tau_y, rotation, np.random.default_rng(self.seed))
        isotropic = math.isclose(tau_x, tau_y)
        tile = height_field_tile(h, size, GaussianFacts(
            isotropic=isotropic, sigma=sigma, correlation_length_x=tau_x,
            correlation_length_y=tau_y, rotation_deg=math.degrees(rotation)))
        ax, ay = 2 * sigma / tau_x, 2 * sigma / tau_y
        rx, ry = tile.realised_alpha(rotation)
        if isotropic:
            facts = replace(tile.facts, alpha_target=Roughness(ax),
                            alpha_realised=Roughness(math.sqrt((rx**2 + ry**2) / 2)))
        else:
            facts = replace(tile.facts, alpha_target=Roughness(ax, ay),
                            alpha_realised=Roughness(rx, ry), alpha_target_x=ax,
                            alpha_target_y=ay, alpha_realised_x=rx, alpha_realised_y=ry)
        cell = size / n
        warnings = []
        if min(tau_x, tau_y) < MIN_CELLS * cell:
            cells = min(tau_x, tau_y) / cell
            warnings.append(
                f"surface: the correlation length spans {cells:.1f} grid cells (< {MIN_CELLS}): "
                f"facets under-resolve the slopes, so the realised roughness falls "
                f"{100 * (1 - discretised_alpha_ratio(cells)):.0f}% below the target; raise "
                "resolution or correlation_length")
        if size / max(tau_x, tau_y) < MIN_LENGTHS:
            warnings.append(
                f"surface: the tile holds {size / max(tau_x, tau_y):.1f} correlation lengths "
                f"per side (< {MIN_LENGTHS}): few independent slopes, so the realised facet "
                "distribution is noisy; raise resolution or lower correlation_length")
        return tile.with_facts(facts, warnings)
