"""Independent realisations of a surface with random geometry, and their pooled facts.

A recipe names a random surface (a Gaussian process, a fibre or particle placement); one
tile is one sample of it. Realisation 0 is the tile of the recipe's own ``surface.seed``
(what ``microsim generate`` and ``view`` show); realisation r ≥ 1 is built from
``SeedSequence(seed, spawn_key=(r,))``'s first 63 bits, so the realisations are
independent streams and the same recipe always gives the same tiles. Facts a tile
measures on itself (its realised roughness, its pigment fraction, ...) are pooled over the
realisations as the ensemble table sees them (``pool_info``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

RMS_POOLED = ("alpha_realised", "alpha_realised_x", "alpha_realised_y", "top_alpha_realised",
              "flake_tilt_rms_deg")
"""Realised facts that are root-mean-square quantities over the tile's area: the ensemble's
value is the root of the mean square over equal-area realisations (α² is twice the mean
square slope, so the averaged table's facets have α² = mean α_r²)."""


def realisation_seed(seed: int, r: int) -> int:
    """The surface seed of realisation ``r`` (``seed`` itself for r = 0).

    Parameters
    ----------
    seed : int
        The recipe's ``surface.seed``.
    r : int
        Realisation index, ≥ 0.

    Returns
    -------
    int
        In [0, 2⁶³ − 1], a valid ``surface.seed``.
    """
    if r == 0:
        return int(seed)
    state = np.random.SeedSequence(int(seed), spawn_key=(r,)).generate_state(1, np.uint64)
    return int(state[0] >> np.uint64(1))


def realisation(surface: Mapping[str, Any], r: int) -> dict[str, Any]:
    """The resolved ``[surface]`` section of realisation ``r`` (its seed replaced)."""
    return {**surface, "seed": realisation_seed(surface.get("seed", 0), r)}


def _pool(values: Sequence[Any], rms: bool) -> tuple[Any, Any]:
    """Pooled value and its standard error over realisations (NaN error for one).

    The mean (of squares, for ``rms``) over realisations, its standard error the batch
    means' √(s² / K); for an RMS value the delta method, se(√q) = se(q) / (2 √q).
    """
    x = np.asarray(values, float)
    q = x**2 if rms else x
    mean = q.mean(axis=0)
    se = q.std(axis=0, ddof=1) / math.sqrt(len(q)) if len(q) > 1 else np.full_like(mean, np.nan)
    if rms:
        root = np.sqrt(mean)
        with np.errstate(invalid="ignore", divide="ignore"):
            mean, se = root, np.where(root > 0, se / (2 * root), 0.0)
    return mean.tolist(), se.tolist()


def pool_info(infos: Sequence[Mapping[str, Any]], seeds: Sequence[int]) -> dict[str, Any]:
    """The facts of an ensemble of tiles, from each realisation's ``Tile.info``.

    Parameters
    ----------
    infos : sequence of dict
        ``Tile.info`` of realisations 0, 1, ... in order.
    seeds : sequence of int or None
        Their surface seeds (None where unknown).

    Returns
    -------
    dict
        Realisation 0's info where all agree; every numeric fact that differs between
        realisations pooled (the mean, or the root mean square for ``RMS_POOLED``) with its
        standard error as ``<key>_stderr``; ``realisations`` (the count) and
        ``per_realisation``: one dict per realisation with its ``seed`` and the facts that
        differ. One realisation: its info as it is, plus ``realisations`` = 1.
    """
    out: dict[str, Any] = dict(infos[0])
    out["realisations"] = len(infos)
    if len(infos) == 1:
        return out
    varying = [k for k, v in infos[0].items()
               if any(info.get(k) != v for info in infos[1:])]
    numeric = [k for k in varying if all(_is_number(info.get(k)) for info in infos)]
    for key in numeric:
        out[key], out[f"{key}_stderr"] = _pool([info[key] for info in infos],
                                               key in RMS_POOLED)
    for key in varying:
        if key not in numeric:
            out.pop(key)
    out["per_realisation"] = [{"seed": seed, **{k: info.get(k) for k in varying}}
                              for seed, info in zip(seeds, infos, strict=True)]
    return out


def _is_number(x: Any) -> bool:
    """A real number or a non-empty list of them (bools excluded)."""
    if isinstance(x, list):
        return bool(x) and all(_is_number(v) for v in x)
    return isinstance(x, int | float) and not isinstance(x, bool)
