"""The adaptive stop over rays and realisations: when a direction has met its target, and
how one that has not grows its rays per realisation and its realisations.

The error a direction is judged by is the median relative standard error over its lobe
bins (the ensemble's, with several realisations), split into the rays' and the tiles'
shares; docs/ensembles.md describes the rule and its measured constants.
"""

from __future__ import annotations

import math

import numpy as np

from microsim.goniometer import BATCH
from microsim.settings import Simulation
from microsim.tables.table import BRDFTable

MAX_RAYS_FACTOR = 100
"""With ``target_error`` and no ``max_rays``, at most this many times ``rays`` are traced."""
MAX_REALISATIONS_FACTOR = 16
"""With ``target_error`` and no ``max_realisations``, at most this many times
``realisations``."""
GROWTH = 4
"""Per round of the adaptive stop, rays per realisation and realisations grow at most this
many times (the variance split that plans a round is itself an estimate)."""
TILE_COST = 1.0
"""Building a tile and its Embree scene costs about as much as tracing this many rays per
triangle (measured on the shipped 256² tile: 0.11 s against 0.9 M rays per second; docs/
ensembles.md); the adaptive stop weighs new realisations by it."""


def _median(x: np.ndarray) -> float:
    """Median of a lobe's values, NaN for none."""
    return float(np.median(x)) if x.size else math.nan


def direction_errors(table: BRDFTable, component: str = "total"
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Per incident direction: the median relative standard error over its lobe bins (an
    empty bin counts as infinitely uncertain), and the median share of the ray noise in
    the variance of those bins.

    Returns
    -------
    rel_stderr, ray_share : (a, b) float
    """
    f = table.values[component].mean(axis=-1)
    e = table.errors[component].mean(axis=-1)
    u = table.ray_errors[component].mean(axis=-1)
    lobe = table.lobe_mask(component)
    rel, share = np.full(table.rays.shape, np.nan), np.full(table.rays.shape, np.nan)
    for index in np.ndindex(*table.rays.shape):
        sel = lobe[index]
        err = np.where(np.isfinite(e[index]), e[index], np.inf)[sel]
        rel[index] = _median(err / f[index][sel])
        with np.errstate(invalid="ignore", divide="ignore"):
            share[index] = _median(np.nan_to_num((u[index][sel] / err) ** 2, nan=1.0))
    return rel, share


def next_plan(realisations: int, rays: int, rel: float, share: float,
               simulation: Simulation, tile_cost: float) -> tuple[int, int] | str:
    """The next (realisations, rays per realisation) of a direction that missed its target,
    or why it stops (``"max_rays"``, ``"max_realisations"``).

    With one realisation the error is the rays' (∝ 1/n): the rays grow by (rel/target)².
    With K ≥ 2 the variance splits as V = R/(K n) + T/K (ray share ``share``); the rays per
    realisation move towards Cochran's (1977, Sampling Techniques, 3rd ed., sec. 10.6)
    optimum n* = √(R c / T) for a realisation costing c rays, and the realisations grow
    until (R/n + T)/K reaches target². Both grow by at most ``GROWTH`` per round; the
    caps ``max_rays`` (K n) and ``max_realisations`` bound them.
    """
    target = float(simulation.target_error)
    most_rays = int(simulation.max_rays or MAX_RAYS_FACTOR * int(simulation.rays))
    most_real = int(simulation.max_realisations
                    or min(MAX_REALISATIONS_FACTOR * simulation.realisations_or_one, 65536))
    if simulation.realisations_or_one == 1:
        most_real = 1
    k, n = realisations, rays
    v, goal = rel**2, target**2
    if k == 1 or not math.isfinite(v):
        grow = min(GROWTH, v / goal) if math.isfinite(v) else GROWTH
        k1, n1 = k, n * grow
    else:
        r_coef, t_coef = share * v * k * n, (1.0 - share) * v * k
        n1 = min(max(math.sqrt(r_coef * tile_cost / t_coef) if t_coef > 0 else math.inf, n),
                 GROWTH * n)
        k1 = min(max(math.ceil((r_coef / n1 + t_coef) / goal), k + 1), GROWTH * k)
        if k1 > most_real:  # fewer realisations than wished: more rays make up, if they can
            k1 = most_real
            if k1 * goal <= t_coef:  # the tiles' spread alone exceeds the target
                return "max_realisations" if k1 == k else (k1, n)
            n1 = min(max(r_coef / (k1 * goal - t_coef), n), GROWTH * n)
    n1 = n + math.ceil(max(n1 - n, 0.0) / BATCH) * BATCH  # whole batches added
    bound = "max_realisations" if k1 >= most_real and k1 > k else None
    if k1 * n1 > most_rays:
        n1 = max(n, min(n1, most_rays // k1))
        if k1 * n1 > most_rays:
            k1 = max(k, most_rays // n1)
        bound = "max_rays"
    if (k1, n1) == (k, n):
        return bound or ("max_realisations" if k >= most_real else "max_rays")
    return k1, n1
