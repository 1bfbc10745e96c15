"""Parallel circular cylinders along y on a base plane: brushed metal, hair-like surfaces."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from microsim.errors import InputError
from microsim.schema import key
from microsim.surfaces.base import Surface, length_key, seed_key, smooth_key
from microsim.surfaces.facts import CylinderFacts
from microsim.surfaces.tile import Tile, grid_faces


def profile(radius: float, spacing: float, sink: float, segments: int
            ) -> tuple[np.ndarray, np.ndarray]:
    """The cross-section (x, z) of one period: base, cylinder arc above the base, base.

    The cylinder's axis lies at x = spacing/2, z = radius − sink. Its points
    (x_c + r cos ψ, z_c + r sin ψ) are above the plane z = 0 for ψ in [a, π − a] with
    a = arcsin(−z_c/r); the arc runs from ψ = π − a over the top to ψ = a, so together with
    the base strips it is one continuous curve from x = 0 to x = spacing (no gap a ray could
    pass through). With sink = 0 the arc is the whole circle, touching the base along a line.

    Parameters
    ----------
    radius, spacing, sink : float
    segments : int
        Facets around a full circumference (the arc gets its share, at least 2).

    Returns
    -------
    points : (k, 2) float
        Profile vertices (x, z) in order.
    part : (k − 1,) int
        0 for base segments, 1 for cylinder segments.
    """
    zc = radius - sink
    a = math.asin(max(-1.0, min(1.0, -zc / radius)))
    cx = spacing / 2
    arc_steps = max(2, math.ceil(segments * (math.pi - 2 * a) / (2 * math.pi)))
    psi = np.linspace(math.pi - a, a, arc_steps + 1)
    arc = np.column_stack([cx + radius * np.cos(psi), zc + radius * np.sin(psi)])
    arc[[0, -1], 1] = 0.0  # exactly on the base plane
    points = [np.array([[0.0, 0.0]]), arc, np.array([[spacing, 0.0]])]
    part = [np.zeros(1, int), np.ones(arc_steps, int), np.zeros(1, int)]
    points, part = np.concatenate(points), np.concatenate(part)
    keep = np.linalg.norm(np.diff(points, axis=0), axis=1) > 1e-12 * spacing
    # drop zero-length base segments (a cylinder as wide as the period)
    return np.concatenate([points[:1], points[1:][keep]]), part[keep]


@dataclass(frozen=True, kw_only=True)
class Cylinders(Surface):
    """Parallel cylinders on a base plane (``kind = "cylinders"``)."""

    kind: ClassVar[str] = "cylinders"
    doc: ClassVar[str] = (
        "Parallel circular cylinders along y lying on (or sunk into) a flat base plane: "
        "brushed metal, hair-like anisotropic surfaces.")
    parts: ClassVar[tuple[str, ...]] = ("base", "cylinder")
    model_keys: ClassVar[tuple[str, ...]] = ("radius", "spacing", "sink")
    radius: float = length_key("Cylinder radius.", 0.5)
    spacing: float = length_key("Distance between cylinder axes (the tile period along x).",
                                1.0)
    sink: float = length_key("Depth the cylinders are sunk into the base plane.", 0.0,
                             zero=True)
    segments: int = key("int", 128, "Facets around a full circumference. A mirror "
                        "reflection turns by twice the facet step, so 128 gives 5.6 degree "
                        "steps: the default phi bin width.", low=6, high=65536)
    length: float = length_key("Tile period along the cylinder axis (y).", 1.0)
    smooth_normals: bool = smooth_key()
    seed: int = seed_key()

    def check(self) -> None:
        if self.spacing < 2 * self.radius:
            raise InputError(f"surface.spacing = {self.spacing!r}: must be >= 2 * radius "
                             f"= {2 * self.radius:g} (cylinders must not overlap)")
        if self.sink >= 2 * self.radius:
            raise InputError(f"surface.sink = {self.sink!r}: must be < 2 * radius "
                             f"= {2 * self.radius:g} (the cylinder would vanish)")

    def triangles(self) -> float:
        return 2 * (self.segments + 2)

    def build(self) -> Tile:
        return cylinder_tile(self)


def cylinder_tile(surface: Cylinders) -> Tile:
    """One cylinder per period along x, extruded along y.

    Facet normals point out of the cylinder and up from the base: with profile edges e
    and the extrusion direction ŷ the face normal is e × ŷ, which is +z on the base and
    radial on the arc (the vertex grid's ordering of ``grid_faces``).

    Parameters
    ----------
    surface : Cylinders
        With ``radius``, ``spacing`` (≥ 2 radius), ``sink`` (< 2 radius),
        ``segments``, ``length``, ``smooth_normals`` (the cylinder faces carry their
        circle in ``Tile.curved``; default true).

    Returns
    -------
    Tile
        Parts ``base`` and ``cylinder``; anisotropic. The surface is open (a sheet, not a
        closed solid): the tracer only needs the boundary that light can reach.
    """
    r, s = float(surface.radius), float(surface.spacing)
    length = float(surface.length)
    points, part = profile(r, s, float(surface.sink), int(surface.segments))
    k = len(points)
    vertices = np.column_stack([np.repeat(points[:, 0], 2), np.tile([0.0, length], k),
                                np.repeat(points[:, 1], 2)])
    faces = grid_faces(k, 2)
    material = np.concatenate([part, part]).astype(np.int32)  # grid_faces: two halves
    curved = None
    if surface.smooth_normals:
        # the circle of radius r about the axis (s/2, ·, r − sink) along y
        tube = np.array([[s / 2, 0.0, r - float(surface.sink)], [1 / r, 0.0, 0.0],
                         [0.0, 0.0, 1 / r]])
        curved = np.where((material == 1)[:, None, None], tube, 0.0)
    return Tile(vertices, faces, material, ("base", "cylinder"), (s, length),
                facts=CylinderFacts(axis=(0.0, 1.0, 0.0)), curved=curved)
