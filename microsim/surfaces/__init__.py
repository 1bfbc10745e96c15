"""Surface generators: each turns a resolved ``[surface]`` section into one periodic tile.

Importing this package is light; ``build_tile`` imports the generator it needs.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from microsim.surfaces.tile import Tile


def build_tile(surface: Mapping[str, Any]) -> Tile:
    """Build the periodic tile a resolved ``[surface]`` section describes.

    Parameters
    ----------
    surface : mapping
        ``recipe["surface"]`` of a resolved recipe (``kind`` plus that kind's keys, angles
        in degrees).

    Returns
    -------
    Tile
    """
    module = importlib.import_module(f"microsim.surfaces.{surface['kind']}")
    return module.build(surface)
