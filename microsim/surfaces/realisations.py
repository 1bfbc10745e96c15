"""Independent realisations of a surface with random geometry, and their pooled facts.

A recipe names a random surface (a Gaussian process, a fibre or particle placement); one
tile is one sample of it. Realisation 0 is the tile of the recipe's own ``surface.seed``
(what ``microsim generate`` and ``view`` show); realisation r ≥ 1 is built from
``SeedSequence(seed, spawn_key=(r,))``'s first 63 bits, so the realisations are
independent streams and the same recipe always gives the same tiles. Facts a tile
measures on itself (its realised roughness, its pigment fraction, ...) are pooled over the
realisations as the ensemble table sees them (``microsim.surfaces.facts.SurfaceFacts``).
"""

from __future__ import annotations

from typing import TypeVar

import numpy as np

from microsim.surfaces.base import Surface

S = TypeVar("S", bound=Surface)


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


def realisation(surface: S, r: int) -> S:
    """The resolved ``[surface]`` section of realisation ``r`` (its seed replaced)."""
    return surface.with_seed(realisation_seed(surface.seed, r))
