"""The flat tile: two triangles at z = 0, the trivial reference."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from microsim.surfaces.facts import FlatFacts
from microsim.surfaces.tile import Tile


def build(surface: Mapping[str, Any]) -> Tile:
    """A square of side ``surface["size"]`` at z = 0, normal +z.

    Parameters
    ----------
    surface : mapping
        Resolved ``[surface]`` with ``size``.

    Returns
    -------
    Tile
        Two faces, part ``base``; isotropic.
    """
    size = float(surface["size"])
    vertices = np.array([[0, 0, 0], [size, 0, 0], [size, size, 0], [0, size, 0]], float)
    faces = np.array([[0, 1, 2], [0, 2, 3]], np.int64)
    return Tile(vertices, faces, np.zeros(2, np.int32), ("base",), (size, size),
                facts=FlatFacts(isotropic=True))
