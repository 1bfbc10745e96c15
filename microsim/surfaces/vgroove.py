"""Symmetric V-grooves along y: Torrance & Sparrow's (1967) cavities as a periodic tile."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from microsim.surfaces.tile import Tile, grid_faces


def build(surface: Mapping[str, Any]) -> Tile:
    """V-grooves of equal width across x, each with its own slope.

    Every groove spans width w = size / grooves: its first face falls from the peak to
    the valley with slope angle s and its second face rises back, so facet normals are
    exactly (± sin s, 0, cos s). Peaks lie at z = 0 and a groove's depth is (w/2) tan s, so grooves
    of different slopes have different depths (equal widths keep every slope equally
    represented in the projected area). With ``alpha``, tan s of each groove is
    |N(0, α²/2)|: the per-axis slope distribution of a Beckmann surface of roughness α
    across the grooves (Walter et al. 2007: Beckmann slopes have per-axis variance α²/2).

    Parameters
    ----------
    surface : mapping
        Kind ``vgroove``: ``slope`` (degrees) or ``alpha``, ``grooves``, ``size``, ``seed``.

    Returns
    -------
    Tile
        Anisotropic (``info["isotropic"] = False``); ``info["slopes_deg"]`` per groove.
    """
    size, grooves = float(surface["size"]), int(surface["grooves"])
    if "slope" in surface:
        tan_s = np.full(grooves, math.tan(math.radians(surface["slope"])))
    else:
        rng = np.random.default_rng(surface["seed"])
        tan_s = np.abs(rng.normal(0.0, surface["alpha"] / math.sqrt(2.0), grooves))
    width = size / grooves
    x = np.arange(2 * grooves + 1) * (width / 2)
    z = np.zeros(2 * grooves + 1)
    z[1::2] = -0.5 * width * tan_s
    # vertex i * 2 + j: x[i], y = j * size (j = 0, 1), the ordering grid_faces expects
    vertices = np.column_stack([np.repeat(x, 2), np.tile([0.0, size], len(x)),
                                np.repeat(z, 2)])
    faces = grid_faces(len(x), 2)
    tile = Tile(vertices, faces, np.zeros(len(faces), np.int32), ("base",),
                (size, size), info={"kind": "vgroove", "isotropic": False,
                                    "slopes_deg": np.degrees(np.arctan(tan_s)).tolist()})
    if "alpha" in surface:
        rx, ry = tile.realised_alpha()
        tile.info.update(alpha_target=surface["alpha"], alpha_realised_x=rx)
    return tile
