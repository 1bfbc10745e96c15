"""Gaussian random height fields with the K-correlation ("ABC") power spectrum of polished
surfaces, on a periodic grid whose band sets their roughness.

The K-correlation model of Church & Takacs (E. L. Church, P. Z. Takacs, "The optimal
estimation of finish parameters", Proc. SPIE 1530, 1991) writes a finish's 2-D isotropic
power spectral density as S(f) = A / (1 + (B f)²)^((C+1)/2), f the spatial frequency in
cycles per unit length, A the low-frequency level, B the correlation length (the knee at
f = 1/B) and C the fall-off exponent: a profile across it has the 1-D spectrum
∫ S(√(fx² + fy²)) dfy ∝ (1 + (B fx)²)^(−C/2), so C is the power law of the profile
spectrum beyond the knee. Its continuum height variance σ² = ∫ S(f) 2πf df =
2πA / (B²(C − 1)) is finite for C > 1, and its continuum slope variance per axis,
½ ∫ (2πf)² S(f) 2πf df = 8π³A / (B⁴(C − 1)(C − 3)), only for C > 3; then Walter et al.
2007's roughness α = √2 · RMS slope per axis has α / σ = 2√2 π / (B √(C − 3))
(``continuum_alpha_per_sigma``). For C ≤ 3 the slopes are carried by the finest
wavelengths present, so the roughness of a sampled surface is a property of its band:
``alpha_per_sigma`` gives it exactly for the tile's grid, and a target α sets σ through it.

The heights are the band-limited periodic field whose spectrum is S sampled on the DFT
grid, f = (kx, ky) / size for |kx|, |ky| ≤ n/2 (``np.fft.fftfreq`` order): these samples
are the eigenvalues P of its circulant covariance, and the field F⁻¹(√P · F w) of white
noise w has that covariance exactly (Dietrich & Newsam 1997, SIAM J. Sci. Comput. 18(4),
circulant embedding; ``microsim.surfaces.gaussian`` samples the covariance instead). As
in ``gaussian``, the tile is not rescaled to its target: it reports the roughness its
facets really have (``Tile.realised_alpha``).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np

from microsim.errors import InputError
from microsim.schema import REQUIRED, key
from microsim.surfaces.base import (
    DEFAULT_CELLS,
    SURFACE_ALPHA_MIN,
    Surface,
    area_realisations,
    check_correlation,
    length_key,
    seed_key,
    size_key,
)
from microsim.surfaces.facts import Roughness, TileFacts, _fact
from microsim.surfaces.gaussian import synthesis
from microsim.surfaces.tile import Tile, height_field_tile

EXPONENT_MIN = 1.0
"""The fall-off exponent C must exceed this: at C ≤ 1 the continuum height variance
2πA / (B²(C − 1)) diverges at high frequency, so even σ would be set by the grid, not by
the surface (in a 256² grid with B = 8 cells, the frequencies above half the Nyquist
frequency hold 47% of the height variance at C = 1, 29% at C = 2)."""
EXPONENT_MAX = 10.0
"""Largest fall-off exponent C: beyond it the power-law tail past the knee carries under a
quarter of the continuum slope variance and under 5% of the height variance, and the
spectrum tends to a Gaussian one ((1 + (Bf)²)^(−(C+1)/2) → exp(−(C+1)(Bf)²/2)): the
``gaussian`` kind is that surface, with a correlation length that means what it says."""
ALPHA_MAX = 10.0
"""Largest target roughness, as for ``gaussian``."""


@dataclass(frozen=True, kw_only=True)
class ABCFacts(TileFacts):
    """A K-correlation height field: its RMS height on the grid, correlation length B and
    fall-off exponent C (``alpha_target`` and ``alpha_realised`` as for every tile), and
    the facets' realised roughness along the cells' diagonals (x = y, the one every
    cell is split along, and x = −y; ``DIAGONAL_SPREAD``)."""

    KIND: ClassVar[str] = "abc"
    sigma: float | None = _fact()
    correlation_length: float | None = _fact()
    exponent: float | None = _fact()
    alpha_realised_45: float | None = _fact("rms")
    alpha_realised_135: float | None = _fact("rms")


DIAGONAL_SPREAD = 0.10
"""Largest relative difference between the facets' roughness along the two cell diagonals
before the tile warns. Heights rough at the grid's scale (the band's finest wavelengths
carry the slopes for C < 3) make a triangle's two edge slopes anticorrelated, and every
cell is split along x = y, so the facets are smoother along that diagonal than across it
(0.168 against 0.226, 35%, at C = 2 with 8 cells per B; 12% at C = 5; docs/surfaces.md):
an isotropic Beckmann model at one α then misfits single scattering. 10% is four times
the seed-to-seed standard deviation of the difference on a 256² tile (2.5%: six seeds of
the ``gaussian`` default, whose facets are smooth over a cell, and of C = 10 with 12
cells per B)."""


def check(n: int, size: float, alpha: float, correlation_length: float,
          exponent: float, name: str = "correlation_length") -> None:
    """The rules of an ``abc`` surface's keys.

    Parameters
    ----------
    n : int
        Samples per side (``resolution``).
    size : float
        Period.
    alpha : float
        Target roughness.
    correlation_length : float
        B, tile units.
    exponent : float
        C.
    name : str
        The key that set B (``resolution`` for the default of 8 grid cells), which a
        correlation length outside the tile's range is named by.

    Raises
    ------
    InputError
        A roughness outside [``SURFACE_ALPHA_MIN``, ``ALPHA_MAX``], an exponent outside
        (``EXPONENT_MIN``, ``EXPONENT_MAX``], or a correlation length shorter than one grid
        cell or longer than the tile.
    """
    if not SURFACE_ALPHA_MIN <= alpha <= ALPHA_MAX:
        raise InputError(f"surface.alpha = {alpha!r}: must be in [{SURFACE_ALPHA_MIN:g}, "
                         f"{ALPHA_MAX:g}]")
    if not EXPONENT_MIN < exponent <= EXPONENT_MAX:
        raise InputError(f"surface.exponent = {exponent!r}: must be in ({EXPONENT_MIN:g}, "
                         f"{EXPONENT_MAX:g}] (at or below {EXPONENT_MIN:g} the height variance "
                         f"is the grid's, not the surface's; above {EXPONENT_MAX:g} use kind "
                         "gaussian)")
    given = correlation_length if name == "correlation_length" else n
    check_correlation(name, given, correlation_length, size / n, size)


@functools.lru_cache(maxsize=4)
def power(n: int, size: float, correlation_length: float, exponent: float) -> np.ndarray:
    """P, the eigenvalues of the circulant covariance of unit-variance heights: S(f) of
    Church & Takacs 1991 sampled at the DFT frequencies and scaled to mean 1. The same for
    every realisation of a surface, so made once and kept (read-only) for the last few.

    Heights h = F⁻¹(√P · F w) of white standard normal noise w on N = n² points have
    covariance E[h_x h_{x+d}] = F⁻¹(P)_d (Dietrich & Newsam 1997), so Var h = F⁻¹(P)_0 =
    mean(P) = 1 (Parseval): σ multiplies them to any RMS height.

    Parameters
    ----------
    n : int
        Samples per side.
    size : float
        Period.
    correlation_length : float
        B.
    exponent : float
        C.

    Returns
    -------
    (n, n) float
        ``P[i, j]`` at f = (fftfreq(n, size/n)[i], fftfreq(n, size/n)[j]); read-only.
    """
    f = np.fft.fftfreq(n, size / n)
    fx, fy = np.meshgrid(f, f, indexing="ij")
    s = (1.0 + correlation_length**2 * (fx**2 + fy**2)) ** (-(exponent + 1.0) / 2.0)
    p = s / s.mean()
    p.flags.writeable = False
    return p


@functools.lru_cache(maxsize=4)
def root_power(n: int, size: float, correlation_length: float, exponent: float
               ) -> np.ndarray:
    """√P of ``power``, kept (read-only) as it is.

    Returns
    -------
    (n, n) float
        Read-only.
    """
    root = np.sqrt(power(n, size, correlation_length, exponent))
    root.flags.writeable = False
    return root


def alpha_per_sigma(n: int, size: float, correlation_length: float, exponent: float
                    ) -> float:
    """The expected realised roughness of the tile's facets per unit RMS height.

    The two triangles of a grid cell (``grid_faces``) have x-slopes (h_{i+1,j} − h_{i,j})/δ
    and (h_{i+1,j+1} − h_{i,j+1})/δ, δ = size / n, and equal projected areas δ²/2, so over
    the tile the area-weighted mean square x-slope is the grid mean of (Δx h)²/δ² and
    ``Tile.realised_alpha`` gives α_x² = 2 mean (Δx h)²/δ². With covariance σ² F⁻¹(P),
    E[(Δx h)²] = 2σ²(F⁻¹(P)_0 − F⁻¹(P)_{(1,0)}) = σ² mean_k(P_k |1 − e^{2πi kx/n}|²), so
    E[α_x²] = (2σ²/δ²) mean_k(P_k · 4 sin²(π kx/n)), and likewise along y (equal: P is
    symmetric in kx and ky). A target α with σ = α / ``alpha_per_sigma`` therefore has
    E[α_realised²] = α², α the RMS of the realised α over realisations (their mean is
    slightly lower: E √q ≤ √E q).

    Parameters
    ----------
    n, size, correlation_length, exponent
        As for ``power``.

    Returns
    -------
    float
        √((E[α_x²] + E[α_y²]) / 2) / σ, per unit length (1 / tile units).
    """
    p = power(n, float(size), float(correlation_length), float(exponent))
    gain = 4.0 * np.sin(np.pi * np.fft.fftfreq(n)) ** 2  # |1 − e^{2πik/n}|²
    delta = size / n
    along_x = 2.0 * float(np.mean(p * gain[:, None])) / delta**2
    along_y = 2.0 * float(np.mean(p * gain[None, :])) / delta**2
    return math.sqrt((along_x + along_y) / 2.0)


def continuum_alpha_per_sigma(correlation_length: float, exponent: float) -> float:
    """α / σ of the continuum K-correlation surface, 2√2 π / (B √(C − 3)), the limit of
    ``alpha_per_sigma`` on ever finer grids of ever larger tiles; finite only for C > 3.

    From σ² = 2πA / (B²(C − 1)) and a slope variance per axis of
    8π³A / (B⁴(C − 1)(C − 3)) (the module's integrals of S(f) of Church & Takacs 1991):
    α² = 2 · slope variance = 8π²σ² / (B²(C − 3)).

    Parameters
    ----------
    correlation_length : float
        B.
    exponent : float
        C > 3.

    Returns
    -------
    float
        inf for C ≤ 3.
    """
    if exponent <= 3.0:
        return math.inf
    return 2.0 * math.sqrt(2.0) * math.pi / (correlation_length * math.sqrt(exponent - 3.0))


def heights(n: int, size: float, sigma: float, correlation_length: float, exponent: float,
            rng: np.random.Generator) -> np.ndarray:
    """Periodic K-correlation heights on an n × n grid of spacing size / n.

    Parameters
    ----------
    n : int
        Samples per side.
    size : float
        Period.
    sigma : float
        RMS height on the grid.
    correlation_length, exponent : float
        B and C of Church & Takacs 1991.
    rng : numpy.random.Generator

    Returns
    -------
    (n, n) float
        ``h[i, j]`` at x = i·size/n, y = j·size/n.
    """
    return sigma * synthesis(root_power(n, float(size), float(correlation_length),
                                        float(exponent)), rng)


def abc_tile(n: int, size: float, alpha: float, correlation_length: float,
             exponent: float, seed: int) -> Tile:
    """The K-correlation height-field tile of target roughness ``alpha``.

    Parameters
    ----------
    n : int
        Samples per side (``resolution``).
    size : float
        Period.
    alpha : float
        Target α: σ = alpha / ``alpha_per_sigma``, so E[α_realised²] = alpha².
    correlation_length, exponent : float
        B and C.
    seed : int
        Of the white noise.

    Returns
    -------
    Tile
        (n + 1)² vertices (the last row and column repeat the first), 2n² faces; ``facts``
        an ``ABCFacts`` with ``alpha_target``, ``alpha_realised`` (the RMS of the two axes'
        realised α), ``sigma``, ``correlation_length``, ``exponent``.

    Raises
    ------
    InputError
        As ``check``.
    """
    check(n, size, alpha, correlation_length, exponent)
    sigma = alpha / alpha_per_sigma(n, size, correlation_length, exponent)
    h = heights(n, size, sigma, correlation_length, exponent, np.random.default_rng(seed))
    tile = height_field_tile(h, size, ABCFacts(isotropic=True, sigma=sigma,
                                               correlation_length=correlation_length,
                                               exponent=exponent))
    rx, ry = tile.realised_alpha()
    along, across = tile.realised_alpha(math.pi / 4)
    facts = replace(tile.facts, alpha_target=Roughness(alpha),
                    alpha_realised=Roughness(math.sqrt((rx**2 + ry**2) / 2)),
                    alpha_realised_45=along, alpha_realised_135=across)
    warnings = []
    if abs(across - along) > DIAGONAL_SPREAD * min(along, across):
        warnings.append(
            "surface: the facets' roughness differs by more than "
            f"{100 * DIAGONAL_SPREAD:g}% between the cell diagonals (the table's "
            "alpha_realised_45 and alpha_realised_135): heights rough at the grid's scale "
            "make the triangles anisotropic, so an isotropic Beckmann model misfits single "
            "scattering (docs/surfaces.md); a higher exponent or a longer "
            "correlation_length smooths them")
    return tile.with_facts(facts, warnings)


@dataclass(frozen=True, kw_only=True)
class ABC(Surface):
    """A K-correlation height field (``kind = "abc"``)."""

    kind: ClassVar[str] = "abc"
    doc: ClassVar[str] = (
        "A Gaussian random height field with the K-correlation (ABC) power spectrum of "
        "polished surfaces, A / (1 + (B f)^2)^((C+1)/2) (Church & Takacs 1991), made by "
        "spectral synthesis on a periodic grid. Below C = 3 its slopes are carried by the "
        "finest wavelengths, so its roughness belongs to the grid's band: alpha is the "
        "RMS realised roughness of the tile's facets (docs/surfaces.md).")
    alpha: float = key("float", REQUIRED, "Target roughness: the RMS over "
                       "realisations of the facets' realised alpha.",
                       low=SURFACE_ALPHA_MIN, high=ALPHA_MAX)
    correlation_length: float | None = length_key(
        "Correlation length B (the spectrum's knee at f = 1/B). Default: 8 grid cells.")
    exponent: float = key("float", 2.0, "Fall-off exponent C of the spectrum beyond the "
                          "knee (a profile falls as f^-C).", low=EXPONENT_MIN, low_open=True,
                          high=EXPONENT_MAX)
    resolution: int = key("int", 256, "Vertices per tile side.", low=4, high=8192)
    size: float = size_key()
    seed: int = seed_key()

    @property
    def knee(self) -> float:
        """B, tile units (the default: ``DEFAULT_CELLS`` grid cells)."""
        return (self.correlation_length if self.correlation_length is not None
                else DEFAULT_CELLS * self.size / self.resolution)

    def check(self) -> None:
        check(self.resolution, self.size, self.alpha, self.knee, self.exponent,
              "resolution" if self.correlation_length is None else "correlation_length")

    def triangles(self) -> float:
        return 2 * self.resolution**2

    def realisations(self) -> int:
        """As for ``gaussian``: ``ENSEMBLE_AREAS`` correlation areas B²."""
        return area_realisations(self.size**2, self.knee**2)

    def build(self) -> Tile:
        return abc_tile(self.resolution, self.size, self.alpha, self.knee, self.exponent,
                        self.seed)
