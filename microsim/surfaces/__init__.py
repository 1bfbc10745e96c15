"""Surface generators: each turns a resolved ``[surface]`` section into one periodic tile.

Importing this package is light; ``build_tile`` imports the generator it needs.
"""

from __future__ import annotations

import importlib
import os
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from microsim.errors import InputError
from microsim.surfaces.params import SURFACE_KINDS

if TYPE_CHECKING:
    from microsim.surfaces.tile import Tile


BYTES_PER_TRIANGLE = 300
"""Working memory per triangle: generation plus the tracer's Embree scene (measured peak
growth 268 B for a 1024² Gaussian tile, rounded up; docs/surfaces.md)."""
DEFAULT_LIMIT_GIB = 2.0
LIMIT_ENV = "MICROSIM_MEMORY_LIMIT"


def memory_limit(flag: float | None = None) -> float:
    """The memory budget in GiB: the ``--memory-limit`` flag, else $MICROSIM_MEMORY_LIMIT,
    else 2."""
    if flag is not None:
        return flag
    text = os.environ.get(LIMIT_ENV)
    if text is None:
        return DEFAULT_LIMIT_GIB
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not value > 0 or value == float("inf"):
        raise InputError(f"${LIMIT_ENV} = {text!r}: must be a positive number of GiB")
    return value


def estimate_bytes(surface: Mapping[str, Any]) -> float | None:
    """Estimated working memory of a surface's tile, or None when unknown before building."""
    count = SURFACE_KINDS[surface["kind"]].triangles
    return None if count is None else BYTES_PER_TRIANGLE * float(count(dict(surface)))


def build_tile(surface: Mapping[str, Any], memory_limit_gib: float | None = None) -> Tile:
    """Build the periodic tile a resolved ``[surface]`` section describes.

    Parameters
    ----------
    surface : mapping
        ``recipe["surface"]`` of a resolved recipe (``kind`` plus that kind's keys, angles
        in degrees).
    memory_limit_gib : float or None
        Refuse (``InputError``) a tile whose estimated memory exceeds this many GiB
        (default: ``memory_limit()``).

    Returns
    -------
    Tile
    """
    limit = memory_limit(memory_limit_gib)
    need = estimate_bytes(surface)
    if need is not None and need > limit * 2**30:
        raise InputError(
            f"surface: this tile needs about {need / 2**30:.1f} GiB (estimated from its "
            f"parameters), over the {limit:g} GiB limit; lower the resolution or raise the "
            f"limit with --memory-limit GIB or ${LIMIT_ENV}")
    module = importlib.import_module(f"microsim.surfaces.{surface['kind']}")
    return module.build(surface)
