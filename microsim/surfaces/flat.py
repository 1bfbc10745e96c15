"""The flat tile: two triangles at z = 0, the trivial reference."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from microsim.surfaces.base import Surface, seed_key, size_key
from microsim.surfaces.facts import FlatFacts
from microsim.surfaces.tile import Tile


@dataclass(frozen=True, kw_only=True)
class Flat(Surface):
    """A flat square tile (``kind = "flat"``)."""

    kind: ClassVar[str] = "flat"
    doc: ClassVar[str] = "A flat square tile at z = 0: the trivial reference."
    size: float = size_key()
    seed: int = seed_key()

    def triangles(self) -> float:
        return 2

    def build(self) -> Tile:
        return flat_tile(self)


def flat_tile(surface: Flat) -> Tile:
    """A square of side ``surface.size`` at z = 0, normal +z.

    Parameters
    ----------
    surface : Flat

    Returns
    -------
    Tile
        Two faces, part ``base``; isotropic.
    """
    size = float(surface.size)
    vertices = np.array([[0, 0, 0], [size, 0, 0], [size, size, 0], [0, size, 0]], float)
    faces = np.array([[0, 1, 2], [0, 2, 3]], np.int64)
    return Tile(vertices, faces, np.zeros(2, np.int32), ("base",), (size, size),
                facts=FlatFacts(isotropic=True))
