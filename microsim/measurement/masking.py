"""Masking G1 measured on a tile, as the virtual goniophotometer measures it.

Points on the microsurface are drawn with density proportional to area times <w, n>+ (the
projected area seen from w), and a ray is sent towards w from each; the fraction that
escapes is Smith's G1(w) = visible projected area / projected area of the front-facing
facets (Heitz 2014, "Understanding the masking-shadowing function", JCGT 3(2), eq. 2 and
8). docs/goniometer.md explains the sampling and the error bars.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from microsim.geometry import direction
from microsim.measurement.scene import ESCAPED, PeriodicScene
from microsim.settings import Recipe
from microsim.surfaces import build_tile
from microsim.surfaces.facts import SurfaceFacts
from microsim.surfaces.realisations import realisation, realisation_seed
from microsim.surfaces.tile import Tile
from microsim.tables.estimator import ENSEMBLE, RAYS, estimate

G1_BYTES_PER_RAY = 200
"""Working memory per ray and angle of ``measure_g1`` (which traces them all at once):
measured 140-160 B (5 angles, 10⁶ and 2 · 10⁶ rays each), rounded up."""


def sample_faces(tile: Tile, weights: np.ndarray, n: int, rng: np.random.Generator
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Uniform points on faces drawn with probability proportional to ``weights``.

    Parameters
    ----------
    tile : Tile
    weights : (m,) float
        Non-negative weight per face, with a positive sum.
    n : int
        Points to draw.
    rng : numpy.random.Generator

    Returns
    -------
    faces : (n,) int
    points : (n, 3) float
        Uniform in each triangle (the folded parallelogram: Pharr, Jakob & Humphreys, PBR
        4th ed., sec. A.5.5 gives the same density).
    """
    faces = rng.choice(len(weights), size=n, p=weights / weights.sum())
    u = rng.random((n, 2))
    fold = u.sum(axis=1) > 1.0
    u[fold] = 1.0 - u[fold]
    v = tile.vertices[tile.faces[faces]]
    points = v[:, 0] + u[:, :1] * (v[:, 1] - v[:, 0]) + u[:, 1:] * (v[:, 2] - v[:, 0])
    return faces, points


def measure_g1(scene: PeriodicScene, theta: Sequence[float] | np.ndarray, phi: float,
               rays: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Masking G1 of the tile towards directions (theta, phi).

    Parameters
    ----------
    scene : PeriodicScene
        The tile, ready to trace.
    theta : (k,) float
        Polar angles, radians, each below pi / 2.
    phi : float
        Azimuth, radians.
    rays : int
        Points (rays) per direction.
    rng : numpy.random.Generator

    Returns
    -------
    g1 : (k,) float
        Fraction of the sampled points that see the direction unoccluded.
    stderr : (k,) float
        Binomial standard error sqrt(g1 (1 - g1) / rays).

    Raises
    ------
    ValueError
        If no face of the tile faces one of the directions.
    """
    omega = direction(np.asarray(theta, float), phi).reshape(-1, 3)
    starts, dirs = [], []
    for w in omega:
        weights = scene.areas * np.maximum(scene.normals @ w, 0.0)
        if not weights.sum() > 0:
            raise ValueError(f"no face of the tile faces theta = "
                             f"{math.degrees(math.acos(w[2])):g} deg")
        faces, points = sample_faces(scene.tile, weights, rays, rng)
        d = np.broadcast_to(w, (rays, 3))
        starts.append(scene.offset(points, scene.normals[faces], d))
        dirs.append(d)
    hits = scene.closest_hit(np.concatenate(starts), np.concatenate(dirs))
    g1 = (hits.status == ESCAPED).reshape(len(omega), rays).mean(axis=1)
    return g1, np.sqrt(g1 * (1.0 - g1) / rays)


@dataclass(frozen=True)
class G1Measurement:
    """Masking G1 of a recipe's surface at some angles, with what a report needs.

    Attributes
    ----------
    theta_deg : list of float
    phi_deg : float
    g1, stderr, ray_stderr : list of float
        G1 per angle, its standard error and the binomial part of it.
    dof : float
        Degrees of freedom of the error.
    error_model : str
        ``ensemble`` over several realisations, ``rays`` for one.
    realisations, rays, seed : int
        Rays per angle over all realisations.
    surface : SurfaceFacts
        The tiles' facts, pooled.
    segments : int
    wall_time : float
    """

    theta_deg: list[float]
    phi_deg: float
    g1: list[float]
    stderr: list[float]
    ray_stderr: list[float]
    dof: float
    error_model: str
    realisations: int
    rays: int
    seed: int
    surface: SurfaceFacts
    segments: int
    wall_time: float


def measure_g1_recipe(recipe: Recipe, thetas_deg: Sequence[float], rays: int,
                      phi_deg: float = 0.0, threads: int | None = None,
                      memory_limit_gib: float | None = None) -> G1Measurement:
    """G1 of a recipe's surface over its realisations, with the numbers a report needs.

    Each of the ``simulation.realisations`` tiles (built one at a time,
    ``microsim.surfaces.realisations``) is sampled with ``rays / realisations`` rays per
    angle (rounded up), realisation r from ``SeedSequence(seed, spawn_key=(r,))``. G1 is
    the mean over realisations and its standard error the batch means' (K − 1 degrees of
    freedom, ``microsim.tables.estimator``; error model ``ensemble``), or for one
    realisation the binomial error (``rays``: conditional on the tile).

    Parameters
    ----------
    recipe : Recipe
        A resolved recipe (``microsim.recipe.resolve``); ``simulation.seed`` seeds the
        sampling.
    thetas_deg : (k,) float
        Polar angles, degrees.
    rays : int
        Rays per angle over all realisations.
    phi_deg : float
        Azimuth, degrees.
    threads : int or None
        Tracing threads (default: every CPU).
    memory_limit_gib : float or None
        The memory guard's budget for each tile (``microsim.memory``); the rays need
        ``G1_BYTES_PER_RAY`` each per angle.

    Returns
    -------
    G1Measurement
    """
    start = time.perf_counter()
    k = recipe.simulation.realisations_or_one
    n = -(-int(rays) // k)
    seed = recipe.simulation.seed
    hits, facts, segments = [], [], 0
    for r in range(k):
        tile = build_tile(realisation(recipe.surface, r), memory_limit_gib)
        with PeriodicScene(tile, threads) as scene:
            g1, _ = measure_g1(scene, np.radians(thetas_deg), math.radians(phi_deg), n,
                               np.random.default_rng(np.random.SeedSequence(
                                   seed, spawn_key=(r,))))
            segments += scene.segments
        hits.append(np.round(g1 * n)[:, None])
        facts.append(tile.facts)
        del tile
    s1 = np.array(hits)                                  # (K, angles, 1); x² = x
    e = estimate(s1, s1, np.full(k, n))
    seeds = [realisation_seed(recipe.surface.seed, r) for r in range(k)]
    return G1Measurement(list(map(float, thetas_deg)), float(phi_deg), e.mean[:, 0].tolist(),
                         e.stderr[:, 0].tolist(), e.ray_stderr[:, 0].tolist(),
                         float(e.dof[0]), ENSEMBLE if k > 1 else RAYS, k, n * k, seed,
                         SurfaceFacts.pool(facts, seeds), segments,
                         time.perf_counter() - start)
