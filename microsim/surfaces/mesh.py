"""A user's periodic tile, imported from PLY, OBJ or STL through trimesh."""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import ClassVar

import numpy as np

from microsim.errors import InputError
from microsim.schema import LENGTH_MAX, LENGTH_MIN, REQUIRED, key
from microsim.surfaces.base import Surface, seed_key
from microsim.surfaces.facts import MeshFacts, Roughness
from microsim.surfaces.tile import Tile

TOLERANCE = 1e-6
"""Vertices may lie this far (relative to the period) outside [0, L]: export round-off."""


@dataclass(frozen=True, kw_only=True)
class Mesh(Surface):
    """A user's tile read from a mesh file (``kind = "mesh"``)."""

    kind: ClassVar[str] = "mesh"
    doc: ClassVar[str] = (
        "A user tile (PLY, OBJ or STL, read by trimesh) with its period given here. The "
        "mesh must lie within [0, period_x] x [0, period_y] and tile seamlessly.")
    path: str = key("path", REQUIRED, "Mesh file (relative to the recipe's folder).")
    period: tuple[float, float] = key("pair", REQUIRED, "Tile period [Lx, Ly].",
                                      unit="length", low=LENGTH_MIN, high=LENGTH_MAX)
    seed: int = seed_key()

    def build(self) -> Tile:
        return mesh_tile(self)


def mesh_tile(surface: Mesh) -> Tile:
    """Load and check a tile.

    The mesh must load, have faces, finite vertices and a non-zero area, and lie within
    [0, Lx] × [0, Ly] (to ``TOLERANCE`` of the period; it is then clipped onto the box).
    Zero-area faces are dropped with a warning. Periodicity itself (that the edges meet
    their opposite edges) is the user's promise: it is not checked.

    Parameters
    ----------
    surface : Mesh
        With ``path`` (absolute after recipe loading), ``period`` [Lx, Ly].

    Returns
    -------
    Tile
        Part ``base``; ``facts.isotropic`` False (unknown); ``facts.alpha_realised``
        from the facet slopes (``Tile.realised_alpha``), as for generated surfaces.
    """
    import trimesh

    path = Path(surface.path)
    if not path.is_file():
        raise InputError(f"surface.path = {str(path)!r}: no such file")
    try:
        mesh = trimesh.load(path, process=False, force="mesh")
    except Exception as exc:  # trimesh raises many kinds for unreadable files
        raise InputError(f"surface.path = {str(path)!r}: cannot read it as a mesh "
                         f"(PLY, OBJ or STL): {exc}") from None
    vertices = np.asarray(mesh.vertices, float)
    faces = np.asarray(mesh.faces, np.int64)
    if len(faces) == 0:
        raise InputError(f"surface.path = {str(path)!r}: the mesh has no faces")
    if not np.isfinite(vertices).all():
        raise InputError(f"surface.path = {str(path)!r}: vertices contain NaN or inf")
    lx, ly = surface.period
    for axis, (name, length) in enumerate((("x", lx), ("y", ly))):
        lo, hi = vertices[:, axis].min(), vertices[:, axis].max()
        slack = TOLERANCE * length
        if lo < -slack or hi > length + slack:
            raise InputError(
                f"surface.period = {[lx, ly]}: the mesh spans {name} in [{lo:g}, {hi:g}], "
                f"outside [0, {length:g}]; a tile must lie within its period")
        vertices[:, axis] = np.clip(vertices[:, axis], 0.0, length)
    material = np.zeros(len(faces), np.int32)
    _, areas = Tile(vertices, faces, material, ("base",), (lx, ly)).face_normals_areas()
    if not areas.sum() > 0:
        raise InputError(f"surface.path = {str(path)!r}: the mesh has zero area")
    kept = areas > 1e-12 * areas.max()
    tile = Tile(vertices, faces[kept], material[kept], ("base",), (lx, ly),
                facts=MeshFacts(isotropic=False, source=str(path)),
                warnings=[] if kept.all() else [
                    f"surface: dropped {int((~kept).sum())} zero-area faces of {len(faces)}"])
    rx, ry = tile.realised_alpha()
    return tile.with_facts(replace(
        tile.facts, alpha_realised=Roughness(float(np.sqrt((rx**2 + ry**2) / 2))),
        alpha_realised_x=rx, alpha_realised_y=ry))
