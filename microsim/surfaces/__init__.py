"""Surface kinds: one record class per kind, in a module of its own, registered here once.

Each kind (``microsim.surfaces.base.Surface``) holds its ``[surface]`` keys, the rules
between them, its default realisations, its memory estimate and its generator, which
builds the periodic tile (``microsim.surfaces.tile.Tile``) with its facts record.
Importing this package loads numpy but nothing heavier (an imported mesh loads trimesh
when it is read; a tile's face geometry compiles with numba on first use): ``microsim
check`` validates recipes with it.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from microsim.memory import check_memory
from microsim.schema import kind_from_json, parse_kind
from microsim.surfaces.base import Surface
from microsim.surfaces.cylinders import Cylinders
from microsim.surfaces.flat import Flat
from microsim.surfaces.gaussian import Gaussian
from microsim.surfaces.kcorrelation import ABC
from microsim.surfaces.mesh import Mesh
from microsim.surfaces.paint import Paint
from microsim.surfaces.tile import Tile
from microsim.surfaces.velvet import Velvet
from microsim.surfaces.vgroove import VGroove
from microsim.surfaces.weave import Weave

__all__ = ["ABC", "KINDS", "SURFACES", "Cylinders", "Flat", "Gaussian", "Mesh", "Paint",
           "Surface", "Tile", "VGroove", "Velvet", "Weave", "build_tile", "check_tile_memory",
           "parse_surface", "surface_from_json"]

KINDS: tuple[type[Surface], ...] = (Flat, Gaussian, ABC, VGroove, Cylinders, Velvet, Weave,
                                    Paint, Mesh)
"""Every surface kind, in the order docs/recipes.md lists them."""
SURFACES: dict[str, type[Surface]] = {cls.kind: cls for cls in KINDS}
"""The kinds by recipe name."""


def parse_surface(raw: Mapping[str, Any], where: str = "surface.") -> Surface:
    """A ``[surface]`` section (``kind`` and its keys) validated into its kind's record.

    Raises
    ------
    InputError
        For a missing or unknown kind, or a bad key of the kind (naming ``where`` + key).
    """
    return parse_kind(SURFACES, raw, where)


def surface_from_json(data: Mapping[str, Any]) -> Surface:
    """A surface from the recipe JSON a table file holds (``Surface.to_json``)."""
    return kind_from_json(SURFACES, data, "surface")


BYTES_PER_TRIANGLE = 300
"""Working memory per triangle: generation plus the tracer's Embree scene (measured peak
growth 268 B for a 1024² Gaussian tile, rounded up; docs/surfaces.md)."""


def estimate_bytes(surface: Surface) -> float | None:
    """Estimated working memory of a surface's tile, or None when unknown before building."""
    count = surface.triangles()
    return None if count is None else BYTES_PER_TRIANGLE * float(count)


def check_tile_memory(surface: Surface, memory_limit_gib: float | None = None,
                      where: str = "") -> None:
    """Refuse (``InputError``, prefixed by ``where``) a tile whose estimated memory exceeds
    the budget (``microsim.memory``); tiles of unknown size pass."""
    need = estimate_bytes(surface)
    if need is not None:
        check_memory(need, f"{where}surface: this tile", "use fewer triangles (a lower "
                     "resolution, density or segment count)", memory_limit_gib)


def build_tile(surface: Surface, memory_limit_gib: float | None = None) -> Tile:
    """Build the periodic tile a resolved ``[surface]`` section describes.

    Parameters
    ----------
    surface : Surface
        ``recipe.surface`` of a resolved recipe.
    memory_limit_gib : float or None
        Refuse (``InputError``) a tile whose estimated memory exceeds this many GiB
        (default: ``microsim.memory.memory_limit()``).

    Returns
    -------
    Tile
    """
    check_tile_memory(surface, memory_limit_gib)
    return surface.build()
