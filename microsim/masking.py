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
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from microsim.compare import direction
from microsim.surfaces.tile import Tile
from microsim.trace import ESCAPED, PeriodicScene

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


def measure_g1_recipe(recipe: Mapping[str, Any], thetas_deg: Sequence[float], rays: int,
                      phi_deg: float = 0.0, threads: int | None = None,
                      memory_limit_gib: float | None = None) -> dict[str, Any]:
    """G1 of a recipe's surface, with the numbers a report needs.

    Parameters
    ----------
    recipe : mapping
        A resolved recipe (``microsim.recipe.resolve``); its surface is built, and
        ``simulation.seed`` seeds the sampling.
    thetas_deg : (k,) float
        Polar angles, degrees.
    rays : int
        Rays per angle.
    phi_deg : float
        Azimuth, degrees.
    threads : int or None
        Tracing threads (default: every CPU).
    memory_limit_gib : float or None
        The memory guard's budget for the tile (``microsim.memory``); the rays need
        ``G1_BYTES_PER_RAY`` each per angle.

    Returns
    -------
    dict
        ``theta_deg``, ``phi_deg``, ``g1``, ``stderr`` (lists), ``rays``, ``seed``,
        ``surface`` (the tile's info), ``segments``, ``wall_time``.
    """
    from microsim.surfaces import build_tile

    start = time.perf_counter()
    tile = build_tile(dict(recipe["surface"]), memory_limit_gib)
    seed = recipe["simulation"]["seed"]
    with PeriodicScene(tile, threads) as scene:
        g1, err = measure_g1(scene, np.radians(thetas_deg), math.radians(phi_deg), rays,
                             np.random.default_rng(seed))
        segments = scene.segments
    return {"theta_deg": list(map(float, thetas_deg)), "phi_deg": float(phi_deg),
            "g1": g1.tolist(), "stderr": err.tolist(), "rays": rays, "seed": seed,
            "surface": dict(tile.info), "segments": segments,
            "wall_time": time.perf_counter() - start}
