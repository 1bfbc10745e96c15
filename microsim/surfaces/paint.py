"""Paint: a dielectric binder layer with pigment particles inside, over a substrate
(Gondek, Meyer & Newman 1994, "Wavelength dependent reflectance functions", SIGGRAPH).

The tile holds three parts: the binder's top interface (flat, or a Gaussian random height
field made by ``microsim.surfaces.gaussian``), the pigment particles (closed spheres or
thin discs, "flakes") and the flat substrate at z = 0. The binder is the medium between
the top and the substrate: give it a refracting dielectric material (``refract = true``)
so light enters, meets the particles and the substrate, and leaves again.

Particles are placed by random sequential addition (Widom 1966; Feder 1980): each
particle's shape (radius, flake tilt) is drawn, then positions uniform in the binder's
volume are tried until one clears the substrate, the top and every particle already
placed (by a gap of 1% of its radius); retrying the same particle keeps the size and tilt
distributions unbiased (skipping to a new one would favour small, flat particles). It
goes on until the pigment volume reaches ``pigment_fraction`` of the binder's. Near
jamming a particle may find no place in ``PER_PARTICLE`` tries: it is given up and the
next one drawn (a warning says how many, since the placed ones then lean to small, flat
shapes); when the positions run out, a warning gives the fraction reached. When
``JAMMED`` particles in a row are given up the packing has jammed and placement stops;
short of ``INFEASIBLE`` of the target, the fraction cannot be had: an error. Spheres keep
their centres ≥ r1 + r2 apart; flakes keep their vertical bounding cylinders disjoint,
so they may stack as in metallic paint. Distances are minimum-image, and particles
crossing a side are cut there and continue from the opposite side: the tile is periodic.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np

from microsim.errors import InputError
from microsim.geometry import orthonormal_basis
from microsim.schema import key
from microsim.surfaces.base import (
    DEFAULT_CELLS,
    SURFACE_ALPHA_MIN,
    Surface,
    check_correlation,
    length_key,
    seed_key,
    size_key,
)
from microsim.surfaces.facts import PaintFacts
from microsim.surfaces.gaussian import MIN_LENGTHS, heights
from microsim.surfaces.periodic import wrap_into_box
from microsim.surfaces.tile import Tile, grid_faces, height_field_vertices

GAP = 0.01
"""Clearance between a particle and anything else, as a fraction of its radius: no two
surfaces come closer than the tracer's offsets can resolve."""
MAX_TILT = 80.0
"""Flake tilts are clipped to this many degrees."""
ATTEMPTS = 200
"""Positions drawn per particle the target fraction asks for (the most tried in all)."""
PER_PARTICLE = 1000
"""Positions tried for one particle before it is given up (and the next one drawn)."""
JAMMED = 10
"""Particles given up in a row that end the placement: the packing has jammed (random
sequential addition saturates; Feder 1980), and going on would try every remaining
position against every placed particle for nothing (a flake paint at pigment_fraction
0.4 ran for minutes)."""
INFEASIBLE = 0.9
"""A jammed placement short of this share of ``pigment_fraction`` is an error (the
fraction cannot be had); closer to it, a warning gives the fraction reached."""


def uv_sphere(sides: int) -> tuple[np.ndarray, np.ndarray]:
    """A closed unit sphere: ``sides`` meridians, ``sides // 2`` bands, outward winding.

    Returns
    -------
    vertices : (sides (sides // 2 - 1) + 2, 3) float
    faces : (2 sides (sides // 2 - 1), 3) int
    """
    bands = max(sides // 2, 2)
    theta = np.pi * np.arange(1, bands) / bands
    phi = 2 * np.pi * np.arange(sides) / sides
    t, p = np.meshgrid(theta, phi, indexing="ij")
    ring = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1)
    vertices = np.concatenate([[[0.0, 0.0, 1.0]], ring.reshape(-1, 3), [[0.0, 0.0, -1.0]]])
    south = len(vertices) - 1
    j = np.arange(sides)
    k = (j + 1) % sides
    faces = [np.column_stack([np.zeros(sides, int), 1 + j, 1 + k])]
    for b in range(bands - 2):
        a0, a1 = 1 + b * sides, 1 + (b + 1) * sides
        faces += [np.column_stack([a0 + j, a1 + j, a1 + k]),
                  np.column_stack([a0 + j, a1 + k, a0 + k])]
    last = 1 + (bands - 2) * sides
    faces.append(np.column_stack([last + j, np.full(sides, south), last + k]))
    return vertices, np.concatenate(faces)


def disc(sides: int) -> tuple[np.ndarray, np.ndarray]:
    """A closed unit disc of thickness 1 (a prism over a regular polygon, z in
    [-1/2, 1/2]), outward winding: the flake's two faces have normals ±z.

    Returns
    -------
    vertices : (2 sides + 2, 3) float
    faces : (4 sides, 3) int
    """
    phi = 2 * np.pi * np.arange(sides) / sides
    ring = np.column_stack([np.cos(phi), np.sin(phi)])
    vertices = np.concatenate([np.column_stack([ring, np.full(sides, 0.5)]),
                               np.column_stack([ring, np.full(sides, -0.5)]),
                               [[0.0, 0.0, 0.5], [0.0, 0.0, -0.5]]])
    j = np.arange(sides)
    k = (j + 1) % sides
    top, bottom = 2 * sides, 2 * sides + 1
    faces = np.concatenate([
        np.column_stack([np.full(sides, top), j, k]),
        np.column_stack([np.full(sides, bottom), sides + k, sides + j]),
        np.column_stack([j, sides + j, sides + k]),
        np.column_stack([j, sides + k, k]),
    ])
    return vertices, faces


def flake_axes(n: int, tilt_rms_deg: float, rng: np.random.Generator) -> np.ndarray:
    """Unit flake normals: the tilt vector θ (cos φ, sin φ) has independent Gaussian
    components of variance tilt_rms² / 2 (so the RMS tilt is ``tilt_rms``, the azimuth
    uniform and θ Rayleigh-distributed), θ clipped to ``MAX_TILT``.

    Returns
    -------
    (n, 3) float
    """
    g = rng.normal(0.0, math.radians(tilt_rms_deg) / math.sqrt(2), (n, 2))
    theta = np.minimum(np.hypot(g[:, 0], g[:, 1]), math.radians(MAX_TILT))
    phi = np.arctan2(g[:, 1], g[:, 0])
    s = np.sin(theta)
    return np.column_stack([s * np.cos(phi), s * np.sin(phi), np.cos(theta)])


def polyhedron_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Volume enclosed by a closed, outward-wound triangle mesh (divergence theorem:
    the sum of signed tetrahedra from the origin)."""
    t = vertices[faces]
    return float(np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2])).sum() / 6)


class _Top:
    """The binder's top surface: heights on a periodic grid (or flat), and the lowest
    height over a square window, which bounds the triangulated surface from below."""

    def __init__(self, surface: Paint, rng: np.random.Generator) -> None:
        self.size = float(surface.size)
        self.thickness = float(surface.binder_thickness)
        alpha = float(surface.top_alpha)
        self.n = int(surface.resolution) if alpha > 0 else 1
        self.cell = self.size / self.n
        self.h = np.full((self.n, self.n), self.thickness)
        self.tau = 0.0
        if alpha > 0:
            self.tau = (surface.top_correlation_length if surface.top_correlation_length is not None
                        else DEFAULT_CELLS * self.cell)
            sigma = alpha * self.tau / 2
            self.h += heights(self.n, self.size, sigma, self.tau, self.tau, 0.0, rng)

    def lowest(self, x: float, y: float, reach: float) -> float:
        """Lowest grid height over the cells a disc of radius ``reach`` at (x, y) touches
        (periodic)."""
        if self.n == 1:
            return self.thickness
        i = np.arange(math.floor((x - reach) / self.cell), math.ceil((x + reach) / self.cell)
                      + 1) % self.n
        j = np.arange(math.floor((y - reach) / self.cell), math.ceil((y + reach) / self.cell)
                      + 1) % self.n
        return float(self.h[np.ix_(i, j)].min())

    def mesh(self) -> tuple[np.ndarray, np.ndarray]:
        """Vertices and faces (normals up) of the top, spanning the whole box."""
        return height_field_vertices(self.h, self.size), grid_faces(self.n + 1, self.n + 1)


def _place(surface: Paint, top: _Top, unit_volume: float,
           rng: np.random.Generator
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, int, bool]:
    """Random sequential addition of particles (see the module docstring).

    ``unit_volume`` is the volume of the particle mesh at radius (and thickness) 1, so
    the fraction counts the volume of the facetted particles the tracer sees.

    Returns
    -------
    centres : (n, 3) float
    radii : (n,) float
    axes : (n, 3) float
        Flake normals (+z for spheres).
    target_volume : float
        Pigment volume the fraction asks for.
    skipped : int
        Particles given up after ``PER_PARTICLE`` positions (the placed ones are then
        biased towards small, flat shapes).
    jammed : bool
        ``JAMMED`` particles in a row were given up, which ended the placement.
    """
    size = top.size
    flakes = surface.pigment_shape == "flake"
    r0, spread = float(surface.pigment_radius), float(surface.radius_spread)
    thick = float(surface.flake_thickness)

    def volume(r: float) -> float:
        return unit_volume * (r * r * thick if flakes else r**3)

    binder_volume = size * size * float(top.h.mean())
    target = float(surface.pigment_fraction) * binder_volume
    tries = int(ATTEMPTS * max(target / volume(r0), 1)) if target > 0 else 0
    # every random number is drawn up front, in a fixed order: the same seed gives the
    # same tile whatever the acceptance pattern; the radius is lognormal (median r0,
    # log-standard deviation ``spread``) clipped at two standard deviations
    radii = r0 * np.exp(np.clip(rng.normal(0.0, 1.0, tries), -2.0, 2.0) * spread)
    axes = flake_axes(tries, surface.flake_tilt_spread, rng) if flakes else \
        np.tile([0.0, 0.0, 1.0], (tries, 1))
    u = rng.random((tries, 3))
    z_max = float(top.h.max())
    sin_t = np.sqrt(np.maximum(1 - axes[:, 2] ** 2, 0.0))
    # vertical half extent and horizontal reach of each candidate
    half = radii * sin_t + thick / 2 * axes[:, 2] if flakes else radii
    reach = radii + (thick / 2 * sin_t if flakes else 0.0)
    gap = GAP * radii
    chosen: list[int] = []
    placed = 0.0
    xy = np.empty((0, 2))
    zs, halves, reaches = np.empty(0), np.empty(0), np.empty(0)
    k = fails = skipped = streak = 0  # particle k, its failed positions, given up in a row
    for c in range(tries):  # position c
        if placed >= target or k == tries or streak == JAMMED:
            break
        if fails == PER_PARTICLE:  # no room for this one: the next, and say so
            k, fails, skipped, streak = k + 1, 0, skipped + 1, streak + 1
            continue
        lo, hi = half[k] + gap[k], z_max - half[k] - gap[k]
        if hi <= lo:  # taller than the binder anywhere: the next particle
            k += 1
            continue
        x, y = u[c, 0] * size, u[c, 1] * size
        z = lo + u[c, 2] * (hi - lo)
        clash = z + half[k] + gap[k] > top.lowest(x, y, reach[k])
        if len(chosen) and not clash:
            dxy = xy - (x, y)
            dxy -= np.round(dxy / size) * size  # minimum image
            dist = np.hypot(dxy[:, 0], dxy[:, 1])
            if flakes:
                clash = bool(np.any((dist < reaches + reach[k] + gap[k])
                                    & (np.abs(zs - z) < halves + half[k] + gap[k])))
            else:
                clash = bool(np.any(np.hypot(dist, zs - z) < reaches + reach[k] + gap[k]))
        if clash:
            fails += 1
            continue
        chosen.append(k)
        placed += volume(radii[k])
        xy = np.vstack([xy, (x, y)])
        zs, halves, reaches = np.append(zs, z), np.append(halves, half[k]), np.append(
            reaches, reach[k])
        k, fails, streak = k + 1, 0, 0
    idx = np.array(chosen, int)
    centres = np.column_stack([xy, zs]) if len(idx) else np.empty((0, 3))
    return centres, radii[idx], axes[idx], target, skipped, streak == JAMMED


PAINT_REALISATIONS = 8
"""Default realisations of a paint tile with particles or a rough top: balances the
realisations' and the rays' variance of paint.toml at grazing incidence."""


@dataclass(frozen=True, kw_only=True)
class Paint(Surface):
    """A pigmented coating over a substrate (``kind = "paint"``)."""

    kind: ClassVar[str] = "paint"
    doc: ClassVar[str] = (
        "A pigmented coating (Gondek, Meyer & Newman 1994): a dielectric binder layer with "
        "a flat or Gaussian rough top, pigment spheres or thin flakes inside it (seeded "
        "random sequential addition, no overlaps, periodic), over a flat substrate at "
        "z = 0. Give the binder a dielectric material with refract = true.")
    parts: ClassVar[tuple[str, ...]] = ("binder", "pigment", "substrate")
    binder_thickness: float = length_key("Mean thickness of the binder layer.", 0.2)
    top_alpha: float = key("float", 0.0, "Roughness alpha of the binder's top (a Gaussian "
                           "height field); 0 = flat.", low=0.0, high=2.0)
    top_correlation_length: float | None = length_key(
        "Correlation length of the top's heights. Default: 8 grid cells.")
    resolution: int = key("int", 256, "Vertices per tile side of a rough top.", low=4,
                          high=8192)
    pigment_fraction: float = key("float", 0.1, "Pigment volume over binder volume (pigment "
                                  "included); 0 = none.", low=0.0, high=0.4)
    pigment_shape: str = key("str", "sphere", "Particle shape: spheres, or thin discs "
                             "(flakes) with tilted normals.", choices=("sphere", "flake"))
    pigment_radius: float = length_key("Median particle radius (a flake's disc radius).",
                                       0.03)
    radius_spread: float = key("float", 0.2, "Log-standard deviation of the lognormal radius "
                               "(clipped at 2 standard deviations); 0 = all equal.", low=0.0,
                               high=1.0)
    flake_thickness: float = length_key("Thickness of a flake.", 0.002)
    flake_tilt_spread: float = key("float", 10.0, "RMS tilt of the flake normals from +z "
                                   "(tilt vector Gaussian, azimuth uniform).", unit="deg",
                                   low=0.0, high=60.0)
    sides: int = key("int", 12, "Facets around a particle (sphere meridians, disc edges).",
                     low=4, high=256)
    size: float = size_key()
    seed: int = seed_key()

    def check(self) -> None:
        """Particles must fit in the binder (by ``GAP`` of their radius on both sides) and
        be small against the tile (the periodic wrap moves a cut piece by one period at
        most)."""
        r_max = self.pigment_radius * math.exp(2 * self.radius_spread)  # radii clip there
        flake = self.pigment_shape == "flake"
        height = self.flake_thickness if flake else 2 * r_max
        if self.pigment_fraction > 0 and height * (1 + 2 * GAP) >= self.binder_thickness:
            raise InputError(f"surface.binder_thickness = {self.binder_thickness!r}: must "
                             f"exceed the largest particle's height {height:g} "
                             "(pigment_radius e^(2 radius_spread), doubled for spheres); "
                             "raise it or lower pigment_radius")
        if r_max > 0.25 * self.size:
            raise InputError(f"surface.pigment_radius = {self.pigment_radius!r}: the largest "
                             f"radius {r_max:g} must be <= a quarter of the tile size "
                             f"({0.25 * self.size:g}); raise size")
        if 0 < self.top_alpha < SURFACE_ALPHA_MIN:
            raise InputError(f"surface.top_alpha = {self.top_alpha!r}: must be 0 (flat) or "
                             f"at least {SURFACE_ALPHA_MIN:g}")
        if self.top_alpha > 0 and self.top_correlation_length is not None:
            check_correlation("top_correlation_length", self.top_correlation_length,
                              self.top_correlation_length, self.size / self.resolution,
                              self.size)
        if flake and self.flake_thickness >= self.pigment_radius:
            raise InputError(f"surface.flake_thickness = {self.flake_thickness!r}: must be "
                             f"below pigment_radius = {self.pigment_radius!r} (a flake is "
                             "thin)")

    def triangles(self) -> float:
        """Top grid, substrate, and the particles the fraction asks for at the smallest
        radius (each cut by the wrap into at most a few pieces: times 2)."""
        top = 2 * self.resolution**2 if self.top_alpha > 0 else 2
        r = self.pigment_radius * math.exp(-2 * self.radius_spread)
        flake = self.pigment_shape == "flake"
        volume = (math.pi * r * r * self.flake_thickness if flake
                  else 4 / 3 * math.pi * r**3)
        count = self.pigment_fraction * self.size**2 * self.binder_thickness / volume
        per = 4 * self.sides if flake else 2 * self.sides * (self.sides // 2 - 1)
        return top + 2 + 2 * count * per

    def realisations(self) -> int | None:
        """Particles or a rough top make a paint random."""
        random = self.pigment_fraction > 0 or self.top_alpha > 0
        return PAINT_REALISATIONS if random else None

    def build(self) -> Tile:
        return paint_tile(self)


def paint_tile(surface: Paint) -> Tile:
    """The paint tile of a resolved ``[surface]`` section.

    Parameters
    ----------
    surface : Paint
        With ``size``, ``binder_thickness``, ``top_alpha``,
        ``top_correlation_length`` (optional), ``resolution``, ``pigment_fraction``,
        ``pigment_shape``, ``pigment_radius``, ``radius_spread``, ``flake_thickness``,
        ``flake_tilt_spread`` (degrees), ``sides``, ``seed``.

    Returns
    -------
    Tile
        Parts ``binder`` (the top), ``pigment``, ``substrate``; ``facts`` hold the top's
        roughness (target and realised), the particle count, the target and realised
        pigment volume fractions, the mean radius, and for flakes the realised RMS tilt
        with its standard error as an estimate of the tilt distribution's.
    """
    size = float(surface.size)
    rng = np.random.default_rng(surface.seed)
    top = _Top(surface, rng)
    if top.h.min() <= GAP * top.thickness:
        raise InputError(f"surface.top_alpha = {surface.top_alpha!r}: the rough top "
                         f"reaches down to the substrate (lowest height "
                         f"{top.h.min():.3g}); lower top_alpha or top_correlation_length, "
                         "or raise binder_thickness")
    flakes = surface.pigment_shape == "flake"
    sides = int(surface.sides)
    unit_v, unit_f = disc(sides) if flakes else uv_sphere(sides)
    centres, radii, axes, target, skipped, jammed = _place(surface, top, polyhedron_volume(
        unit_v, unit_f), rng)
    thick = float(surface.flake_thickness)
    u, v = orthonormal_basis(axes)
    scale = np.column_stack([radii, radii, np.full(len(radii), thick) if flakes else radii])
    local = unit_v[None] * scale[:, None]  # (n, p, 3)
    pv = (centres[:, None] + local[..., :1] * u[:, None] + local[..., 1:2] * v[:, None]
          + local[..., 2:] * axes[:, None])
    pigment_volume = sum(polyhedron_volume(p, unit_f) for p in pv)
    top_v, top_f = top.mesh()
    sub_v = np.array([[0, 0, 0], [size, 0, 0], [size, size, 0], [0, size, 0]], float)
    sub_f = np.array([[0, 1, 2], [0, 2, 3]])
    n_top, n_part = len(top_v), len(radii)
    per = len(unit_v)
    part_f = (unit_f[None] + per * np.arange(n_part)[:, None, None]).reshape(-1, 3)
    vertices = np.concatenate([top_v, sub_v, pv.reshape(-1, 3)])
    faces = np.concatenate([top_f, sub_f + n_top, part_f + n_top + 4])
    material = np.concatenate([np.zeros(len(top_f), int), np.full(2, 2),
                               np.ones(len(part_f), int)])
    groups = np.concatenate([np.zeros(len(top_f) + 2, int),
                             1 + np.repeat(np.arange(n_part), len(unit_f))])
    vertices, faces, material = wrap_into_box(vertices, faces, material, (size, size), groups)
    binder_volume = size * size * float(top.h.mean())
    if jammed and pigment_volume < INFEASIBLE * target:
        raise InputError(
            f"surface.pigment_fraction = {surface.pigment_fraction:g}: the particles "
            f"jam at {100 * pigment_volume / binder_volume:.1f}% of the binder ({JAMMED} "
            f"particles in a row found no room in {PER_PARTICLE} positions each); lower "
            f"pigment_fraction to at most {pigment_volume / binder_volume:.3g}, or lower "
            "pigment_radius" + (" or flake_tilt_spread" if flakes else "")
            + ", or raise binder_thickness")
    facts = PaintFacts(
        isotropic=True, binder_thickness=float(surface.binder_thickness),
        binder_volume=binder_volume, particles=int(n_part),
        pigment_shape=surface.pigment_shape,
        pigment_fraction_target=float(surface.pigment_fraction),
        pigment_fraction_realised=pigment_volume / binder_volume,
        pigment_radius_mean=float(radii.mean()) if n_part else 0.0)
    if top.n > 1:
        top_tile = Tile(top_v, top_f, np.zeros(len(top_f), int), ("binder",), (size, size))
        ax, ay = top_tile.realised_alpha()
        facts = replace(facts, top_alpha_target=float(surface.top_alpha),
                        top_alpha_realised=math.sqrt((ax**2 + ay**2) / 2),
                        top_correlation_length=top.tau)
    else:
        facts = replace(facts, top_alpha_target=0.0, top_alpha_realised=0.0)
    warnings = []
    if top.n > 1 and size / top.tau < MIN_LENGTHS:
        warnings.append(
            f"surface: the top holds {size / top.tau:.1f} correlation lengths per side "
            f"(< {MIN_LENGTHS}): few independent slopes, so its realised roughness "
            "scatters about top_alpha (see top_alpha_realised); raise resolution or lower "
            "top_correlation_length")
    if flakes and n_part:
        tilt = np.arccos(np.clip(axes[:, 2], -1.0, 1.0))
        area = radii**2
        mean_sq = float(np.sum(area * tilt**2) / area.sum())
        rms = math.sqrt(mean_sq)
        # delta method: se(RMS) = se(mean of theta^2) / (2 RMS), the mean's se from the
        # flakes' scatter (area weights: Kish's effective count)
        n_eff = area.sum() ** 2 / np.sum(area**2)
        spread = float(np.sqrt(np.sum(area * (tilt**2 - mean_sq) ** 2) / area.sum()))
        se = spread / math.sqrt(n_eff) / (2 * rms) if rms > 0 else 0.0
        facts = replace(facts, flake_tilt_rms_target_deg=float(surface.flake_tilt_spread),
                        flake_tilt_rms_deg=math.degrees(rms),
                        flake_tilt_rms_stderr_deg=math.degrees(se))
    if skipped:
        warnings.append(
            f"surface: {skipped} particles found no room in {PER_PARTICLE} tries each and "
            "were left out: the placed ones lean to smaller radii (and flatter flakes) "
            "than drawn; see pigment_radius_mean (and flake_tilt_rms_deg)")
    if pigment_volume < (1 - 1e-9) * target:  # the unit volumes scale exactly
        warnings.append(
            f"surface: {n_part} particles fill {100 * pigment_volume / binder_volume:.1f}% "
            f"of the binder, short of pigment_fraction = {surface.pigment_fraction:g} "
            f"(the pigment's target volume {target:.4g}); random sequential addition "
            "jams near 38% for spheres, less in a thin layer: lower pigment_fraction or "
            "pigment_radius, or raise binder_thickness")
    return Tile(vertices, faces, material, ("binder", "pigment", "substrate"), (size, size),
                facts=facts, warnings=warnings)
