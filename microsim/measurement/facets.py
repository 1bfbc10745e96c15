"""The facet-normal distribution of a recipe's surface, over its realisations.

Each realisation's tile gives an NDF histogram with errors from its 4 × 4 sub-tiles
(``Tile.ndf_histogram``: batch means over sub-tiles, which sample the surface's spread when
they are many correlation lengths wide). Over K realisations the histogram is their mean,
and its error the ensemble estimator of ``microsim.tables.estimator.combine`` with the
sub-tile variance in the role of the within-realisation variance: batch means over the
realisations, moderated across the θh bins. docs/ensembles.md has the derivation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from microsim.memory import check_memory
from microsim.settings import Recipe
from microsim.surfaces import build_tile
from microsim.surfaces.facts import SurfaceFacts
from microsim.surfaces.realisations import realisation, realisation_seed
from microsim.tables.estimator import ENSEMBLE, combine

SUB_TILES = 4
"""Sub-tiles per side of each realisation's own error estimate."""
NDF_BYTES_PER_BIN = (240, 160)
"""Memory of an NDF histogram per θh bin: a fixed part (one tile's sub-tile histograms
and their shares) and a part per realisation (its histogram, kept until they are pooled);
measured 216 B per bin for one realisation and 624 B for four (200 000 bins, tracemalloc
peak), rounded up."""
SUB_TILES_MODEL = "sub-tiles"
"""Error model of one realisation's histogram: the scatter of its sub-tiles."""


@dataclass(frozen=True)
class NdfMeasurement:
    """The facet-normal distribution of a recipe's surface.

    Attributes
    ----------
    edges : (bins + 1,) float
        θh bin edges, radians.
    D, stderr : (bins,) float
        The NDF per bin, 1/sr, and its standard error (NaN where no facet fell).
    dof : float
        Degrees of freedom of the variance estimate.
    error_model : str
        ``sub-tiles`` for one realisation, ``ensemble`` for more.
    realisations : int
    surface : SurfaceFacts
        The tiles' facts, pooled.
    """

    edges: np.ndarray
    D: np.ndarray
    stderr: np.ndarray
    dof: float
    error_model: str
    realisations: int
    surface: SurfaceFacts


def measure_ndf_recipe(recipe: Recipe, bins: int, memory_limit_gib: float | None = None
                       ) -> NdfMeasurement:
    """The NDF histogram of a recipe's surface over ``simulation.realisations`` tiles.

    Parameters
    ----------
    recipe : Recipe
        A resolved recipe.
    bins : int
        θh bins, uniform over [0, θmax]: θmax = atan(3.5 α) for the isotropic realised
        roughness α of realisation 0, else 89°.
    memory_limit_gib : float or None
        The memory guard's budget for each tile (``microsim.memory``).

    Returns
    -------
    NdfMeasurement
    """
    k = recipe.simulation.realisations_or_one
    fixed, per_realisation = NDF_BYTES_PER_BIN
    check_memory(bins * (fixed + per_realisation * k), f"--bins {bins}: the NDF histograms "
                 f"of {k} realisation{'s' if k > 1 else ''}", "use fewer bins (30 to 1000 "
                 "resolve any lobe)", memory_limit_gib)
    histograms, facts, theta_max = [], [], None
    for r in range(k):
        tile = build_tile(realisation(recipe.surface, r), memory_limit_gib)
        if theta_max is None:
            alpha = tile.facts.alpha_realised
            theta_max = math.atan(3.5 * alpha.alpha) if alpha is not None and \
                alpha.isotropic else math.radians(89.0)
        histograms.append(tile.ndf_histogram(bins, theta_max, SUB_TILES))
        facts.append(tile.facts)
        del tile
    d = np.array([h["D"] for h in histograms])[..., None]                # (K, bins, 1)
    v = np.array([h["stderr"] for h in histograms])[..., None] ** 2
    e = combine(d, v, SUB_TILES**2 - 1.0, np.isfinite(v).all(axis=0) if k > 1 else None)
    seeds = [realisation_seed(recipe.surface.seed, r) for r in range(k)]
    return NdfMeasurement(histograms[0]["edges"], e.mean[:, 0], e.stderr[:, 0],
                          float(e.dof[0]), ENSEMBLE if k > 1 else SUB_TILES_MODEL, k,
                          SurfaceFacts.pool(facts, seeds))
