"""Velvet: dense short fibres standing on a base (Westin, Arvo & Torrance 1992, fig. 11)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from microsim.analytic.velvet_geometry import VELVET_GEOMETRY
from microsim.errors import InputError
from microsim.geometry import FIBRE_MAX_TILT, section_axes
from microsim.schema import key_field
from microsim.surfaces.base import Surface, seed_key, size_key, smooth_key
from microsim.surfaces.facts import VelvetFacts
from microsim.surfaces.periodic import wrap_into_box
from microsim.surfaces.tile import Tile


def fibre_directions(n: int, tilt: float, tilt_spread: float, azimuth: float,
                     azimuth_spread: float, rng: np.random.Generator) -> np.ndarray:
    """Unit fibre axes: tilt from +z ~ N(tilt, spread) clipped to [0, 80]°, azimuth
    ~ N(azimuth, spread) (uniform when the spread is 360°); angles in degrees.

    Returns
    -------
    (n, 3) float
    """
    theta = np.radians(np.clip(rng.normal(tilt, tilt_spread, n), 0.0, FIBRE_MAX_TILT))
    if azimuth_spread >= 360.0:
        phi = rng.uniform(0.0, 2 * math.pi, n)
    else:
        phi = np.radians(rng.normal(azimuth, azimuth_spread, n))
    s = np.sin(theta)
    return np.column_stack([s * np.cos(phi), s * np.sin(phi), np.cos(theta)])


def jittered_points(n: int, size: float, rng: np.random.Generator) -> np.ndarray:
    """n points, one uniformly inside each of n cells chosen at random from an m × m grid
    (m = ⌈√n⌉) over [0, size)²: jittered sampling, no clumps and no gaps larger than a
    cell (Cook 1986, "Stochastic sampling in computer graphics")."""
    m = math.ceil(math.sqrt(n))
    cells = rng.choice(m * m, size=n, replace=False)
    ij = np.column_stack(np.divmod(cells, m)).astype(float)
    return (ij + rng.random((n, 2))) * (size / m)


def tubes(roots: np.ndarray, axes: np.ndarray, radius: float, start: np.ndarray,
          length: float, sides: int) -> tuple[np.ndarray, np.ndarray]:
    """Closed tubes with cone tips: for fibre k, a prism of ``sides`` faces from
    roots[k] + start[k] axes[k] to roots[k] + length axes[k], a cone of height ``radius``
    on top and a flat cap at the bottom; faces wind outward.

    Returns
    -------
    vertices : (n (2 sides + 2), 3) float
    faces : (n · 4 sides, 3) int
    """
    n = len(roots)
    u, v = section_axes(axes)
    ang = 2 * math.pi * np.arange(sides) / sides
    ring = radius * (np.cos(ang)[None, :, None] * u[:, None] + np.sin(ang)[None, :, None]
                     * v[:, None])  # (n, sides, 3)
    bottom = roots[:, None] + start[:, None, None] * axes[:, None] + ring
    top = roots[:, None] + length * axes[:, None] + ring
    tip = roots + (length + radius) * axes
    base = roots + start[:, None] * axes
    verts = np.concatenate([bottom, top, tip[:, None], base[:, None]], axis=1)
    per = 2 * sides + 2
    a = np.arange(sides)
    b = (a + 1) % sides
    t, c = sides + a, sides + b
    local = np.concatenate([
        np.column_stack([a, b, c]), np.column_stack([a, c, t]),          # sides
        np.column_stack([t, c, np.full(sides, 2 * sides)]),              # cone tip
        np.column_stack([b, a, np.full(sides, 2 * sides + 1)]),          # bottom cap
    ])
    faces = (local[None] + per * np.arange(n)[:, None, None]).reshape(-1, 3)
    return verts.reshape(-1, 3), faces


VELVET_REALISATIONS = 4
"""Default realisations of a velvet tile: its fibres' spread is small against the ray noise
of velvet.toml, and 4 is the fewest with which the moderated error estimates its own
degrees of freedom (docs/ensembles.md; measured by scripts/ensemble_defaults.py)."""


@dataclass(frozen=True, kw_only=True)
class Velvet(Surface):
    """Short fibres standing on a base (``kind = "velvet"``); the fibre keys are the
    sparse-velvet model's (``microsim.analytic.velvet_geometry``)."""

    kind: ClassVar[str] = "velvet"
    doc: ClassVar[str] = (
        "Dense short fibres standing on a flat base (Westin et al. 1992's velvet), placed "
        "by a seeded jittered-grid process, periodic; fibres are closed tubes with tips.")
    parts: ClassVar[tuple[str, ...]] = ("base", "fibre")
    model_keys: ClassVar[tuple[str, ...]] = tuple(VELVET_GEOMETRY)
    fibre_radius: float = key_field(VELVET_GEOMETRY["fibre_radius"])
    fibre_length: float = key_field(VELVET_GEOMETRY["fibre_length"])
    density: float = key_field(VELVET_GEOMETRY["density"])
    tilt: float = key_field(VELVET_GEOMETRY["tilt"])
    tilt_spread: float = key_field(VELVET_GEOMETRY["tilt_spread"])
    azimuth: float = key_field(VELVET_GEOMETRY["azimuth"])
    azimuth_spread: float = key_field(VELVET_GEOMETRY["azimuth_spread"])
    sides: int = key_field(VELVET_GEOMETRY["sides"])
    smooth_normals: bool = smooth_key()
    size: float = size_key()
    seed: int = seed_key()

    def check(self) -> None:
        """Fibres must be small against the tile: the periodic wrap moves a cut piece by
        one period at most, and a fibre's root reaches radius · (tan 80° + 1) below the
        base."""
        if self.fibre_length > 0.5 * self.size:
            raise InputError(f"surface.fibre_length = {self.fibre_length!r}: must be <= half "
                             f"the tile size ({0.5 * self.size:g}); raise size for longer "
                             "fibres")
        if self.fibre_radius > 0.02 * self.size:
            raise InputError(f"surface.fibre_radius = {self.fibre_radius!r}: must be <= 2% "
                             f"of the tile size ({0.02 * self.size:g})")

    def triangles(self) -> float:
        return 2 + 8 * self.sides * self.density * self.size**2

    def realisations(self) -> int:
        return VELVET_REALISATIONS

    def build(self) -> Tile:
        return velvet_tile(self)


def velvet_tile(surface: Velvet) -> Tile:
    """A velvet tile: a flat base at z = 0 and closed fibres rooted in it.

    Fibres are placed by jittered sampling at ``density`` per unit area; each is a tube of
    ``fibre_radius`` with ``sides`` faces, rising ``fibre_length`` along its axis from the
    base and ending in a cone; its root reaches below the base (by radius · (tan tilt + 1)
    along the axis) so the tube meets the base without a gap. Fibres crossing a tile side
    are cut there and continue from the opposite side.

    Parameters
    ----------
    surface : Velvet
        With ``fibre_radius``, ``fibre_length``, ``density``, ``tilt``,
        ``tilt_spread``, ``azimuth``, ``azimuth_spread`` (degrees), ``sides``, ``size``,
        ``seed``, ``smooth_normals`` (the fibres' side faces carry their cylinder in
        ``Tile.curved``; default true).

    Returns
    -------
    Tile
        Parts ``base`` and ``fibre``; isotropic when the azimuth spread is 360°.
    """
    size = float(surface.size)
    rng = np.random.default_rng(surface.seed)
    n = max(1, round(surface.density * size * size))
    radius, length, sides = surface.fibre_radius, surface.fibre_length, surface.sides
    roots = np.column_stack([jittered_points(n, size, rng), np.zeros(n)])
    axes = fibre_directions(n, surface.tilt, surface.tilt_spread, surface.azimuth,
                            surface.azimuth_spread, rng)
    tan_tilt = np.sqrt(1 - axes[:, 2] ** 2) / axes[:, 2]
    start = -radius * (tan_tilt + 1.0)
    fv, ff = tubes(roots, axes, radius, start, length, sides)
    base_v = np.array([[0, 0, 0], [size, 0, 0], [size, size, 0], [0, size, 0]], float)
    vertices = np.concatenate([base_v, fv])
    faces = np.concatenate([[[0, 1, 2], [0, 2, 3]], ff + 4])
    # groups: 0 the base, 1 + 2k the sides of fibre k, 2 + 2k its tip and bottom cap
    ends = np.tile(np.repeat([0, 1], 2 * sides), n)
    groups = np.concatenate([[0, 0], 1 + 2 * np.repeat(np.arange(n), 4 * sides) + ends])
    # the cut carries one integer per face: the material (0 base, 1 fibre) and the group,
    # as material + 2 group, so cut pieces keep their fibre
    label = np.minimum(groups, 1) + 2 * groups
    vertices, faces, label = wrap_into_box(vertices, faces, label, (size, size), groups)
    material, group = label % 2, label // 2
    fibre = np.maximum(group - 1, 0) // 2
    # per face: the base's +y, a fibre's axis (its side faces contain it)
    tangents = np.where((group > 0)[:, None], axes[fibre], [0.0, 1.0, 0.0])
    curved = None
    if surface.smooth_normals:
        curved = _fibre_tubes(vertices, faces, (group > 0) & (group % 2 == 1), roots[fibre]
                              + 0.5 * length * axes[fibre], axes[fibre], radius, size)
    isotropic = surface.azimuth_spread >= 360.0 or surface.tilt == 0
    return Tile(vertices, faces, material, ("base", "fibre"), (size, size),
                facts=VelvetFacts(isotropic=bool(isotropic), fibres=n),
                tangents=tangents, curved=curved)


def _fibre_tubes(vertices: np.ndarray, faces: np.ndarray, side: np.ndarray,
                 middle: np.ndarray, axes: np.ndarray, radius: float, size: float
                 ) -> np.ndarray:
    """``Tile.curved`` of a velvet tile: each side face's fibre cylinder (its axis through
    the fibre's middle, moved by whole periods to the copy nearest the face, which is the
    copy the face belongs to: no face lies more than 0.41 size from its fibre's middle,
    by the limits on length and radius), u and v its section axes over the radius; tips,
    caps and base flat."""
    centroid = vertices[faces].mean(axis=1)
    c = middle.copy()
    c[:, :2] += size * np.round((centroid[:, :2] - middle[:, :2]) / size)
    u, v = section_axes(axes)
    curved = np.stack([c, u / radius, v / radius], axis=1)
    return np.where(side[:, None, None], curved, 0.0)
