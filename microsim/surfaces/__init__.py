"""Surface generators: each turns a resolved ``[surface]`` section into one periodic tile.

Importing this package loads numpy and the generators (an imported mesh loads trimesh when
it is read); their recipe keys are ``microsim.surfaces.params``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from microsim.memory import check_memory
from microsim.surfaces import cylinders, flat, gaussian, mesh, paint, velvet, vgroove, weave
from microsim.surfaces.params import SURFACE_KINDS
from microsim.surfaces.tile import Tile

GENERATORS = {"flat": flat.build, "gaussian": gaussian.build, "vgroove": vgroove.build,
              "cylinders": cylinders.build, "velvet": velvet.build, "weave": weave.build,
              "paint": paint.build, "mesh": mesh.build}
"""The generator of every surface kind (``SURFACE_KINDS``)."""


BYTES_PER_TRIANGLE = 300
"""Working memory per triangle: generation plus the tracer's Embree scene (measured peak
growth 268 B for a 1024² Gaussian tile, rounded up; docs/surfaces.md)."""


def estimate_bytes(surface: Mapping[str, Any]) -> float | None:
    """Estimated working memory of a surface's tile, or None when unknown before building."""
    count = SURFACE_KINDS[surface["kind"]].triangles
    return None if count is None else BYTES_PER_TRIANGLE * float(count(dict(surface)))


def check_tile_memory(surface: Mapping[str, Any], memory_limit_gib: float | None = None,
                      where: str = "") -> None:
    """Refuse (``InputError``, prefixed by ``where``) a tile whose estimated memory exceeds
    the budget (``microsim.memory``); tiles of unknown size pass."""
    need = estimate_bytes(surface)
    if need is not None:
        check_memory(need, f"{where}surface: this tile", "use fewer triangles (a lower "
                     "resolution, density or segment count)", memory_limit_gib)


def build_tile(surface: Mapping[str, Any], memory_limit_gib: float | None = None) -> Tile:
    """Build the periodic tile a resolved ``[surface]`` section describes.

    Parameters
    ----------
    surface : mapping
        ``recipe["surface"]`` of a resolved recipe (``kind`` plus that kind's keys, angles
        in degrees).
    memory_limit_gib : float or None
        Refuse (``InputError``) a tile whose estimated memory exceeds this many GiB
        (default: ``microsim.memory.memory_limit()``).

    Returns
    -------
    Tile
    """
    check_tile_memory(surface, memory_limit_gib)
    return GENERATORS[surface["kind"]](surface)
