"""Symmetric V-grooves along y: Torrance & Sparrow's (1967) cavities as a periodic tile.

With ``micro_alpha`` every groove face also carries a Gaussian random micro-roughness,
displaced along the face's own normal, so that in each face's frame the roughness is the
same stationary field a flat ``gaussian`` surface has: the direct (one-level) geometry of
a two-level hierarchy of scale (docs/materials.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np

from microsim.errors import InputError
from microsim.schema import key
from microsim.surfaces.base import (
    DEFAULT_CELLS,
    Surface,
    check_correlation,
    length_key,
    roughness_key,
    seed_key,
    size_key,
)
from microsim.surfaces.facts import FaceRoughnessFacts, Roughness, VGrooveFacts
from microsim.surfaces.gaussian import heights
from microsim.surfaces.tile import Tile, grid_faces

MICRO_RESOLUTION = 512
"""Default grid of a ``vgroove`` tile with micro-roughness (columns and rows)."""
VGROOVE_REALISATIONS = 8
"""Default realisations of V-grooves with random slopes or micro-roughness: balances them
for vgroove-rough-direct.toml."""


@dataclass(frozen=True, kw_only=True)
class VGroove(Surface):
    """Symmetric V-grooves along y (``kind = "vgroove"``)."""

    kind: ClassVar[str] = "vgroove"
    doc: ClassVar[str] = (
        "Symmetric V-grooves along y (Torrance-Sparrow cavities): one slope angle for "
        "every groove, or slopes drawn from a Beckmann distribution of roughness alpha; "
        "with slope, optionally Gaussian micro-roughness on every face (micro_alpha).")
    slope: float | None = key("float", None, "Slope angle of every groove face (give slope "
                              "or alpha).", unit="deg", low=0.0, low_open=True, high=89.0)
    alpha: float | None = roughness_key("Draw each groove's slope from a Beckmann slope "
                                        "distribution of this roughness (give slope or "
                                        "alpha).")
    grooves: int = key("int", 64, "Grooves per tile.", low=1, high=1_000_000)
    micro_alpha: float | None = roughness_key(
        "Gaussian micro-roughness alpha of every groove face, displaced along the face's "
        "normal (with slope); optional.", high=2.0)
    micro_resolution: int | None = key(
        "int", None, "Grid columns (and rows) of a tile with micro_alpha; a multiple of 2 * "
        f"grooves. Default: {MICRO_RESOLUTION}.", low=8, high=8192)
    micro_correlation: float | None = length_key(
        "Correlation length of the micro-roughness along a face. Default: 8 grid cells "
        "measured along the face.")
    size: float = size_key()
    seed: int = seed_key()

    @property
    def grid(self) -> int:
        """Grid columns (and rows) of a tile with micro-roughness."""
        return MICRO_RESOLUTION if self.micro_resolution is None else self.micro_resolution

    def check(self) -> None:
        if self.given("slope") == self.given("alpha"):
            raise InputError("surface: a vgroove surface takes exactly one of slope, alpha")
        if self.micro_alpha is None:
            return
        if self.slope is None:
            raise InputError("surface.micro_alpha: needs slope (one slope for every "
                             "groove), not alpha")
        n = self.grid
        if n % (2 * self.grooves):
            raise InputError(f"surface.micro_resolution = {n!r}: must be a multiple of 2 * "
                             f"grooves = {2 * self.grooves} (whole grid columns per groove "
                             "face)")
        if self.micro_correlation is not None:
            check_correlation("micro_correlation", self.micro_correlation,
                              self.micro_correlation, self.size / n, self.size)

    def triangles(self) -> float:
        return 2 * self.grid**2 if self.micro_alpha is not None else 4 * self.grooves

    def realisations(self) -> int | None:
        """Random slopes (``alpha``) or micro-roughness make the grooves random."""
        random = self.alpha is not None or self.micro_alpha is not None
        return VGROOVE_REALISATIONS if random else None

    def build(self) -> Tile:
        return groove_tile(self)


def groove_tile(surface: VGroove) -> Tile:
    """V-grooves of equal width across x, each with its own slope.

    Every groove spans width w = size / grooves: its first face falls from the peak to
    the valley with slope angle s and its second face rises back, so facet normals are
    exactly (± sin s, 0, cos s). Peaks lie at z = 0 and a groove's depth is (w/2) tan s, so grooves
    of different slopes have different depths (equal widths keep every slope equally
    represented in the projected area). With ``alpha``, tan s of each groove is
    |N(0, α²/2)|: the per-axis slope distribution of a Beckmann surface of roughness α
    across the grooves (Walter et al. 2007: Beckmann slopes have per-axis variance α²/2).
    With ``micro_alpha`` (and ``slope``) the faces are rough: see ``rough_faces``.

    Parameters
    ----------
    surface : VGroove
        ``slope`` (degrees) or ``alpha``, ``grooves``, ``size``, ``seed``,
        optionally ``micro_alpha``, ``micro_resolution``, ``micro_correlation``.

    Returns
    -------
    Tile
        Anisotropic (``facts.isotropic`` False); ``facts.slopes_deg`` summarises
        the grooves' slopes (``slope_facts``).
    """
    size, grooves = float(surface.size), int(surface.grooves)
    if surface.micro_alpha is not None:
        return rough_faces(surface)
    if surface.slope is not None:
        tan_s = np.full(grooves, math.tan(math.radians(surface.slope)))
        slopes = np.full(grooves, float(surface.slope))
    else:
        rng = np.random.default_rng(surface.seed)
        tan_s = np.abs(rng.normal(0.0, surface.alpha / math.sqrt(2.0), grooves))
        slopes = np.degrees(np.arctan(tan_s))
    width = size / grooves
    x = np.arange(2 * grooves + 1) * (width / 2)
    z = np.zeros(2 * grooves + 1)
    z[1::2] = -0.5 * width * tan_s
    # vertex i * 2 + j: x[i], y = j * size (j = 0, 1), the ordering grid_faces expects
    vertices = np.column_stack([np.repeat(x, 2), np.tile([0.0, size], len(x)),
                                np.repeat(z, 2)])
    faces = grid_faces(len(x), 2)
    tile = Tile(vertices, faces, np.zeros(len(faces), np.int32), ("base",),
                (size, size), facts=VGrooveFacts(slopes_deg=slope_facts(slopes)))
    if surface.alpha is not None:
        rx, ry = tile.realised_alpha()
        return tile.with_facts(replace(tile.facts, alpha_target=Roughness(surface.alpha),
                                       alpha_realised_x=rx))
    return tile


def slope_facts(slopes_deg: np.ndarray) -> dict[str, float | int]:
    """What a tile reports about its grooves' slopes: a summary, not one number per
    groove (a tile may have a million grooves).

    Parameters
    ----------
    slopes_deg : (grooves,) float
        Slope angle of each groove, degrees.

    Returns
    -------
    dict
        ``count``, ``min``, ``mean``, ``rms`` and ``max`` of the angles, degrees.
    """
    return {"count": len(slopes_deg), "min": float(slopes_deg.min()),
            "mean": float(slopes_deg.mean()),
            "rms": float(np.sqrt(np.mean(slopes_deg**2))), "max": float(slopes_deg.max())}


def _face_field(surface: VGroove) -> tuple[int, float, float, np.ndarray]:
    """The micro-roughness of a rough V-groove tile: grid size n, slope s (radians),
    correlation length τ along a face, and the heights h (n, n) (see ``rough_faces``)."""
    size = float(surface.size)
    n = surface.grid
    s = math.radians(surface.slope)
    tau = (surface.micro_correlation if surface.micro_correlation is not None
           else DEFAULT_CELLS * size / n / math.cos(s))
    h = heights(n, size, surface.micro_alpha * tau / 2, tau * math.cos(s), tau, 0.0,
                np.random.default_rng(surface.seed))
    return n, s, tau, h


def face_roughness_tile(surface: VGroove) -> Tile:
    """The micro-roughness a rough V-groove tile lays on its faces, laid flat instead.

    The lower level of the matching two-level hierarchy of scale: the same heights h on
    the grid x' = i·size/(n cos s), y = j·size/n (distances along a face), so the table
    of this tile is the reflectance of exactly the roughness the faces carry
    (docs/materials.md).

    Parameters
    ----------
    surface : VGroove
        A section with ``micro_alpha`` (see ``rough_faces``).

    Returns
    -------
    Tile
        Period (size / cos s, size); isotropic; ``facts.alpha_realised``.
    """
    size = float(surface.size)
    n, s, tau, h = _face_field(surface)
    g = np.linspace(0.0, size, n + 1)
    x, y = np.meshgrid(g / math.cos(s), g, indexing="ij")
    z = np.pad(h, ((0, 1), (0, 1)), mode="wrap")
    faces = grid_faces(n + 1, n + 1)
    tile = Tile(np.column_stack([x.ravel(), y.ravel(), z.ravel()]), faces,
                np.zeros(len(faces), np.int32), ("base",), (size / math.cos(s), size),
                facts=FaceRoughnessFacts(isotropic=True,
                                         alpha_target=Roughness(surface.micro_alpha),
                                         correlation_length=tau))
    return tile.with_facts(replace(tile.facts,
                                   alpha_realised=Roughness(*tile.realised_alpha())))


def rough_faces(surface: VGroove) -> Tile:
    """V-grooves of one slope s whose faces carry Gaussian micro-roughness.

    An n × n grid (n = ``micro_resolution``, columns x_i = i·size/n) follows the grooves;
    a periodic Gaussian field h (``microsim.surfaces.gaussian.heights``, autocorrelation
    σ² exp(−(x'² + y²)/τ²) in the face's coordinates, σ = micro_alpha·τ/2) displaces
    every vertex of a face by h along that face's normal. Distances along a face are
    x' = x / cos s, so the field is synthesised with correlation length τ cos s along x.
    Vertices on a ridge or valley line, shared by two faces, move by h / cos s along +z
    (the bisector of the two normals), which keeps the mesh closed; a few facets there
    may overhang.

    Parameters
    ----------
    surface : VGroove
        With ``slope`` (degrees), ``micro_alpha``, optional
        ``micro_resolution`` (a multiple of 2·grooves; default ``MICRO_RESOLUTION``) and
        ``micro_correlation``, ``grooves``, ``size``, ``seed``.

    Returns
    -------
    Tile
        2 n² faces; ``facts`` add ``micro_alpha_target`` and ``micro_alpha_realised``
        (from the facet normals in their face's frame, x' and y; see
        ``Tile.realised_alpha``).
    """
    size, grooves = float(surface.size), int(surface.grooves)
    n, s, tau, h = _face_field(surface)
    cell = size / n
    m = n // (2 * grooves)  # grid columns per face
    k = np.arange(n) % (2 * m)
    junction = (k == 0) | (k == m)
    # face of each column: +1 falling (normal (sin s, 0, cos s)), -1 rising, 0 on a line
    side = np.where(junction, 0.0, np.where(k < m, 1.0, -1.0))
    shift_x = h * (side * math.sin(s))[:, None]
    shift_z = h * np.where(junction, 1.0 / math.cos(s), math.cos(s))[:, None]
    z0 = -math.tan(s) * cell * np.minimum(k, 2 * m - k)
    g = np.linspace(0.0, size, n + 1)
    x, y = np.meshgrid(g, g, indexing="ij")
    x = x + np.pad(shift_x, ((0, 1), (0, 1)), mode="wrap")
    z = np.pad(z0[:, None] + shift_z, ((0, 1), (0, 1)), mode="wrap")
    faces = grid_faces(n + 1, n + 1)
    tile = Tile(np.column_stack([x.ravel(), y.ravel(), z.ravel()]), faces,
                np.zeros(len(faces), np.int32), ("base",), (size, size),
                facts=VGrooveFacts(
                    slopes_deg=slope_facts(np.full(grooves, float(surface.slope))),
                    micro_alpha_target=surface.micro_alpha, micro_correlation_length=tau))
    # facet normals in their face's frame (face of the grid column a facet starts in)
    normals, areas = tile.face_normals_areas()
    face_side = np.where(k < m, 1.0, -1.0)[faces[:, 0] // (n + 1)]
    sin_f, cos_f = face_side * math.sin(s), math.cos(s)
    nz = normals[:, 0] * sin_f + normals[:, 2] * cos_f
    nx = normals[:, 0] * cos_f - normals[:, 2] * sin_f
    up = nz > 0
    weight = areas[up] * nz[up]
    ax, ay = (math.sqrt(2 * np.sum(weight * (c[up] / nz[up]) ** 2) / weight.sum())
              for c in (nx, normals[:, 1]))
    return tile.with_facts(replace(tile.facts, micro_alpha_realised=Roughness(ax, ay)))
