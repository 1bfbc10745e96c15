"""Woven cloth, one pattern repeat: warp yarns along y, weft yarns along x (Westin et al.
1992, fig. 13; the yarn paths of Irawan & Marschner 2012 without fibre twist)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from microsim.errors import InputError
from microsim.schema import key
from microsim.surfaces.base import Surface, length_key, seed_key, smooth_key
from microsim.surfaces.facts import WeaveFacts
from microsim.surfaces.tile import Tile


def over(n: int, float_over: int) -> np.ndarray:
    """(n, n) bool: warp i passes over weft j where (j − i) mod n < float_over (a twill
    whose float line steps by one yarn; plain weave is the 1/1 twill)."""
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    return (j - i) % n < float_over


def crimp_amplitude(width: float, thickness: float, spacing: float) -> float:
    """Smallest height ± A of the yarn centres at a crossing for which crossing yarns do
    not intersect, with 2% margin.

    Near a crossing the warp centre lies at A cos(π d/s) at distance d along it (the
    cosine path to the next crossing of opposite height, the tightest case: plain weave)
    and its elliptical section reaches (t/2)√(1 − a²) below it at a fraction a of its
    half-width across; likewise the weft. Over the overlap square (a, b) ∈ [0, 1]² the
    warp's bottom must stay above the weft's top:
    A (cos(π b w/2s) + cos(π a w/2s)) ≥ (t/2)(√(1 − a²) + √(1 − b²)).
    """
    a = np.linspace(0.0, 1.0, 201)
    a, b = np.meshgrid(a, a)
    need = 0.5 * thickness * (np.sqrt(1 - a**2) + np.sqrt(1 - b**2))
    room = np.cos(math.pi * b * width / (2 * spacing)) + np.cos(math.pi * a * width
                                                              / (2 * spacing))
    return 1.02 * float(np.max(need / np.maximum(room, 1e-9)))


def path_heights(t: np.ndarray, heights: np.ndarray, spacing: float) -> np.ndarray:
    """Centre height along a yarn: ``heights[j]`` at the crossings t = (j + ½) s, joined by
    half cosines (C¹, periodic over len(heights) · s)."""
    n = len(heights)
    u = t / spacing - 0.5
    j0 = np.floor(u).astype(int)
    tau = u - j0
    h0, h1 = heights[j0 % n], heights[(j0 + 1) % n]
    return h0 + (h1 - h0) * 0.5 * (1 - np.cos(math.pi * tau))


def yarn(position: float, heights: np.ndarray, spacing: float, width: float,
         thickness: float, samples: int, sides: int, along_x: bool
         ) -> tuple[np.ndarray, np.ndarray]:
    """One yarn as a tube of elliptical section, closed around and open at the tile's
    sides (where it meets its own copy: the path is periodic).

    The section lies in the plane across the yarn's direction of travel (vertical), so its
    ends are exactly the tile's sides. Faces wind outward.

    The faces between path samples t_j and t_(j+1) are chords of one elliptic
    cylinder: with the centre c_j = (t_j, position, z_j) (in travel, across, up
    coordinates), the chord slope k = (z_(j+1) − z_j) / (t_(j+1) − t_j) and unit vectors
    ê_t (travel), ê_a (across), ê_z, the points x with ((x − c_j)·ê_a / (w/2))² +
    (((x − c_j)·(ê_z − k ê_t)) / (h/2))² = 1 (h the thickness) are the vertical
    ellipse swept along the chord of the centre line, and every vertex of the segment
    lies on it. ``curved`` holds (c_j, ê_a / (w/2), (ê_z − k ê_t) / (h/2)) per face
    (``Tile.curved``).

    Returns
    -------
    vertices : ((samples + 1) sides, 3) float
    faces : (2 samples sides, 3) int
    curved : (2 samples sides, 3, 3) float
    """
    period = len(heights) * spacing
    t = np.linspace(0.0, period, samples + 1)
    z = path_heights(t, heights, spacing)
    phi = 2 * math.pi * np.arange(sides) / sides
    across = position + 0.5 * width * np.cos(phi) * (-1 if along_x else 1)
    up = 0.5 * thickness * np.sin(phi)
    T, A = np.meshgrid(t, across, indexing="ij")
    Z = z[:, None] + up[None, :]
    xyz = (T, A, Z) if along_x else (A, T, Z)
    vertices = np.stack(xyz, axis=-1).reshape(-1, 3)
    k, l = np.meshgrid(np.arange(samples), np.arange(sides), indexing="ij")
    a = (k * sides + l).ravel()
    b = (k * sides + (l + 1) % sides).ravel()
    c, d = a + sides, b + sides
    faces = np.concatenate([np.column_stack([a, c, d]), np.column_stack([a, d, b])])
    slope = np.diff(z) / np.diff(t)
    travel, side = (0, 1) if along_x else (1, 0)
    centre = np.zeros((samples, 3))
    centre[:, travel], centre[:, side], centre[:, 2] = t[:-1], position, z[:-1]
    u = np.zeros((samples, 3))
    u[:, side] = 2.0 / width
    v = np.zeros((samples, 3))
    v[:, travel], v[:, 2] = -slope * 2.0 / thickness, 2.0 / thickness
    curved = np.stack([centre, u, v], axis=1)[np.tile(k.ravel(), 2)]
    return vertices, faces, curved


@dataclass(frozen=True, kw_only=True)
class Weave(Surface):
    """Woven cloth, one pattern repeat (``kind = "weave"``)."""

    kind: ClassVar[str] = "weave"
    doc: ClassVar[str] = (
        "Woven cloth, one pattern repeat: warp yarns along y and weft yarns along x as "
        "swept tubes of elliptical cross-section on crimped (sinusoidal) paths.")
    parts: ClassVar[tuple[str, ...]] = ("warp", "weft")
    model_keys: ClassVar[tuple[str, ...]] = ("spacing",)
    pattern: str = key("str", "plain", "Weave pattern.", choices=("plain", "twill"))
    float: tuple[float, float] = key("floats", [2.0, 1.0], "Twill float: yarns passed "  # noqa: A003
                                     "over, then under (e.g. [2, 1] for 2/1 twill, [2, 2] "
                                     "for 2/2).", low=1, high=16, length=2)
    yarn_width: float = length_key("Yarn cross-section width.", 0.8)
    yarn_thickness: float = length_key("Yarn cross-section thickness.", 0.3)
    spacing: float = length_key("Distance between neighbouring yarns (warp and weft).", 1.0)
    segments: int = key("int", 16, "Path samples per yarn crossing.", low=4, high=1024)
    sides: int = key("int", 24, "Facets around each yarn's cross-section (with smooth "
                     "normals, 12 trap mirror light between crossing yarns: "
                     "docs/surfaces.md).", low=4, high=256)
    smooth_normals: bool = smooth_key()
    seed: int = seed_key()

    def check(self) -> None:
        if self.yarn_width > 0.95 * self.spacing:
            raise InputError(f"surface.yarn_width = {self.yarn_width!r}: must be <= 0.95 * "
                             f"spacing = {0.95 * self.spacing:g} (neighbouring yarns would "
                             "touch)")
        if any(v != int(v) for v in self.float):
            raise InputError(f"surface.float = {list(self.float)!r}: must be whole numbers "
                             "of yarns")

    def triangles(self) -> float:
        up, down = self.float
        return 4 * self.segments * self.sides * (up + down) ** 2

    def build(self) -> Tile:
        return weave_tile(self)


def weave_tile(surface: Weave) -> Tile:
    """One repeat of a plain or twill weave.

    Parameters
    ----------
    surface : Weave
        With ``pattern``, ``float`` ([over, under] for twill), ``yarn_width``,
        ``yarn_thickness``, ``spacing``, ``segments`` (path samples per crossing),
        ``sides``, ``smooth_normals`` (the yarn faces carry their elliptic cylinders in
        ``Tile.curved``; default true).

    Returns
    -------
    Tile
        Parts ``warp`` and ``weft``; period n · spacing with n = 2 (plain) or over + under
        (twill). There is nothing below the cloth: light passing through the gaps between
        yarns leaves downwards and is reported as lost energy (transmission).
    """
    if surface.pattern == "plain":
        up, down = 1, 1
    else:
        up, down = (int(v) for v in surface.float)
    n = up + down
    s, w, th = float(surface.spacing), float(surface.yarn_width), float(
        surface.yarn_thickness)
    amp = crimp_amplitude(w, th, s)
    top = over(n, up)  # top[i, j]: warp i over weft j
    samples = n * int(surface.segments)
    sides = int(surface.sides)
    verts, faces, material, curved = [], [], [], []
    count = 0
    for k in range(n):
        for part, along_x, heights in ((0, False, np.where(top[k], amp, -amp)),
                                       (1, True, np.where(top[:, k], -amp, amp))):
            v, f, c = yarn((k + 0.5) * s, heights, s, w, th, samples, sides, along_x)
            verts.append(v)
            faces.append(f + count)
            material.append(np.full(len(f), part, np.int32))
            curved.append(c)
            count += len(v)
    return Tile(np.concatenate(verts), np.concatenate(faces).astype(np.int64),
                np.concatenate(material), ("warp", "weft"), (n * s, n * s),
                facts=WeaveFacts(repeat=n, crimp_amplitude=amp),
                curved=np.concatenate(curved) if surface.smooth_normals
                else None)
