"""The adaptive stop over rays and realisations: when a direction has met its target, and
how one that has not grows its rays per realisation and its realisations.

The error a direction is judged by is the median relative standard error over its lobe
bins (the ensemble's, with several realisations), split into the rays' and the tiles'
shares; docs/ensembles.md describes the rule and its measured constants.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from microsim.measurement.goniometer import BATCH
from microsim.settings import Simulation
from microsim.tables.table import BRDFTable

MAX_RAYS_FACTOR = 100
"""With ``target_error`` and no ``max_rays``, at most this many times ``rays`` are traced."""
MAX_REALISATIONS_FACTOR = 64
"""With ``target_error`` and no ``max_realisations``, at most this many times
``realisations``."""
GROWTH = 4
"""Per round of the adaptive stop, rays per realisation and realisations grow at most this
many times (the variance split that plans a round is itself an estimate)."""
MIN_RAYS = 8192
"""Fewest rays a new realisation gets per direction: below it a batch's fixed costs (its
start, binning and harmonic transforms) outweigh its rays."""


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
    f = table[component].values.mean(axis=-1)
    e = table[component].errors.mean(axis=-1)
    u = table[component].ray_errors.mean(axis=-1)
    lobe = table.lobe_mask(component)
    rel, share = np.full(table.rays.shape, np.nan), np.full(table.rays.shape, np.nan)
    for index in np.ndindex(*table.rays.shape):
        sel = lobe[index]
        err = np.where(np.isfinite(e[index]), e[index], np.inf)[sel]
        rel[index] = _median(err / f[index][sel])
        with np.errstate(invalid="ignore", divide="ignore"):
            share[index] = _median(np.nan_to_num((u[index][sel] / err) ** 2, nan=1.0))
    return rel, share


def next_plan(rays: Sequence[int], rel: float, share: float, simulation: Simulation,
              tile_cost: float) -> tuple[int, int] | str:
    """The next (realisations, rays) of a direction that missed its target, or why it stops
    (``"max_rays"``, ``"max_realisations"``).

    With one realisation (deterministic geometry) the error is the rays' (∝ 1/n): its rays
    grow by (rel/target)², and the plan is (1, its rays in all). With realisations, those
    traced keep their rays and new ones are added, each with n rays: the plan is (K', n),
    the realisations in all and the rays of each new one. The variance of the mean of K
    realisations of n_r rays is V = (R Σ 1/n_r + K T) / K² (ray variance R per ray and
    tile variance T, from ``rel`` and the ray share ``share``); new realisations get
    Cochran's (1977, Sampling Techniques, 3rd ed., sec. 10.6) optimum n* = √(R c / T) for
    a realisation costing c rays (``tile_cost``, counted on the run: faces and
    segments, ``microsim.measurement.simulation.TILE_SEGMENTS_PER_FACE``), at least
    ``MIN_RAYS``, and K' is the least count with V ≤ target². K' grows by at most
    ``GROWTH`` per round (the variance split is itself an estimate); the caps
    ``max_rays`` (rays in all) and ``max_realisations`` bound the plan.

    Parameters
    ----------
    rays : sequence of int
        Rays of each realisation traced so far.
    rel, share : float
        The direction's median relative standard error over its lobe bins and the ray
        noise's share of its variance (``direction_errors``).
    simulation : Simulation
    tile_cost : float
        What a new realisation costs, in rays of this direction.
    """
    target = float(simulation.target_error)
    most_rays = int(simulation.max_rays or MAX_RAYS_FACTOR * int(simulation.rays))
    most_real = int(simulation.max_realisations
                    or min(MAX_REALISATIONS_FACTOR * simulation.realisations_or_one, 65536))
    v, goal = rel**2, target**2
    k, total = len(rays), int(sum(rays))
    if simulation.realisations_or_one == 1:
        grow = min(GROWTH, v / goal) if math.isfinite(v) else GROWTH
        n1 = total + math.ceil(max(total * grow - total, 0.0) / BATCH) * BATCH
        n1 = min(n1, most_rays)
        return (1, n1) if n1 > total else "max_rays"
    if k >= most_real:
        return "max_realisations"
    if not math.isfinite(v):
        return min(GROWTH * k, most_real), max(rays)
    inverse = float(np.sum(1.0 / np.asarray(rays, float)))
    r_coef = share * v * k * k / inverse          # R
    t_coef = (1.0 - share) * v * k                # T
    n = max(MIN_RAYS, max(rays) * GROWTH) if t_coef <= 0 else min(
        max(MIN_RAYS, math.ceil(math.sqrt(r_coef * tile_cost / t_coef))), GROWTH * max(rays))
    # least K' with goal K'² − (T + R/n) K' − R (Σ 1/n_r − K/n) ≥ 0
    b = t_coef + r_coef / n
    c = r_coef * (inverse - k / n)
    k1 = math.ceil((b + math.sqrt(b * b + 4.0 * goal * c)) / (2.0 * goal))
    k1 = min(max(k1, k + 1), GROWTH * k)
    bound = None
    if k1 >= most_real:
        k1, bound = most_real, "max_realisations"
    if total + (k1 - k) * n > most_rays:
        k1, bound = k + (most_rays - total) // n, "max_rays"
    if k1 <= k:
        return bound or "max_rays"
    return k1, n
