"""Small periodic tiles made directly in the tests (independent of the generators)."""

from __future__ import annotations

from typing import Any

import numpy as np

from microsim.materials import Material, material_from_json
from microsim.measurement.simulation import simulate
from microsim.settings import Simulation, TableSettings
from microsim.surfaces.facts import TileFacts
from microsim.surfaces.tile import Tile
from microsim.tables.table import BRDFTable


def height_field_tile(h: np.ndarray, size: float = 1.0, isotropic: bool = False) -> Tile:
    """A periodic tile from heights on an nx x ny grid (the last row and column wrap).

    Parameters
    ----------
    h : (nx, ny) float
        Heights at x = i size / nx (axis 0) and y = j size / ny (axis 1).
    size : float
        Tile period along x and y.
    info : dict or None
        The tile's ``info``.

    Returns
    -------
    Tile
    """
    nx, ny = h.shape
    x, y = np.meshgrid(np.arange(nx + 1) * (size / nx), np.arange(ny + 1) * (size / ny),
                       indexing="ij")
    z = np.pad(h, ((0, 1), (0, 1)), mode="wrap")
    vertices = np.stack([x, y, z], axis=-1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    a = (i * (ny + 1) + j).ravel()
    b, c, d = a + (ny + 1), a + 1, a + ny + 2
    faces = np.concatenate([np.stack([a, b, d], 1), np.stack([a, d, c], 1)])
    return Tile(vertices, faces, np.zeros(len(faces), np.int64), ("base",), (size, size),
                facts=TileFacts(isotropic=isotropic))


def flat_tile(n: int = 4) -> Tile:
    """A flat tile at z = 0 on an n x n grid."""
    return height_field_tile(np.zeros((n, n)), isotropic=True)


def random_tile(n: int = 64, rms_slope: float = 0.35, cells: float = 4.0,
                seed: int = 0) -> Tile:
    """A smooth periodic random height field (Gaussian spectrum filtered white noise).

    Parameters
    ----------
    n : int
        Grid points per side.
    rms_slope : float
        RMS slope per axis of the continuous field (approximately realised).
    cells : float
        Correlation length in grid cells.
    seed : int
        Seed of the noise.
    """
    rng = np.random.default_rng(seed)
    k = np.fft.fftfreq(n) * 2 * np.pi
    kx, ky = np.meshgrid(k, k, indexing="ij")
    spectrum = np.exp(-(kx**2 + ky**2) * cells**2 / 8)
    h = np.fft.ifft2(np.fft.fft2(rng.standard_normal((n, n))) * spectrum).real
    slope = np.gradient(h, axis=0) * n
    h *= rms_slope / slope.std()
    return height_field_tile(h, isotropic=True)


def bump_tile(height: float = 0.05, half: float = 0.1) -> Tile:
    """A flat unit tile at z = 0 with one square pyramid centred at (0.5, 0.5).

    Face 16 is the pyramid face towards -x.
    """
    g = [0.0, 0.5 - half, 0.5 + half, 1.0]
    vertices = [(x, y, 0.0) for x in g for y in g] + [(0.5, 0.5, height)]

    def v(i: int, j: int) -> int:
        return 4 * i + j

    faces = []
    for i in range(3):
        for j in range(3):
            if (i, j) != (1, 1):
                faces += [(v(i, j), v(i + 1, j), v(i + 1, j + 1)),
                          (v(i, j), v(i + 1, j + 1), v(i, j + 1))]
    apex = 16
    faces += [(v(1, 2), v(1, 1), apex), (v(1, 1), v(2, 1), apex),
              (v(2, 1), v(2, 2), apex), (v(2, 2), v(1, 2), apex)]
    faces_arr = np.array(faces)
    return Tile(np.array(vertices, float), faces_arr, np.zeros(len(faces_arr), np.int64),
                ("base",), (1.0, 1.0))


def vgroove_tile(slope_deg: float | np.ndarray, grooves: int = 8) -> Tile:
    """Symmetric V-grooves along y with peaks at z = 0.

    Two grid points per groove along x (peak, valley), so each groove face is one row of
    facets.

    Parameters
    ----------
    slope_deg : float or (grooves,) float
        Slope of the faces of every groove, or of each groove.
    grooves : int
        Grooves per tile.
    """
    n = 2 * grooves
    depth = np.tan(np.radians(np.broadcast_to(slope_deg, (grooves,)))) / n
    h = np.zeros((n, 2))
    h[1::2] = -depth[:, None]
    return height_field_tile(h, isotropic=False)


def beckmann_vgroove_tile(alpha: float, grooves: int = 256, seed: int = 0) -> Tile:
    """V-grooves whose slopes tan(s) are |N(0, alpha^2 / 2)|: the per-axis slope
    distribution of a Beckmann surface of roughness alpha across the grooves."""
    slopes = np.abs(np.random.default_rng(seed).normal(0.0, alpha / np.sqrt(2), grooves))
    return vgroove_tile(np.degrees(np.arctan(slopes)), grooves)


def cosine_directions(n: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Cosine-distributed unit directions about unit normals ``n`` (k, 3) from uniform
    numbers ``u`` (k, 2): sin θ = √u1, φ = 2π u2 in a Gram-Schmidt frame of n (made here,
    apart from the tracer's own sampling)."""
    helper = np.where(np.abs(n[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    t = helper - np.sum(helper * n, axis=1, keepdims=True) * n
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    s = np.cross(n, t)
    sin_t, phi = np.sqrt(u[:, :1]), 2 * np.pi * u[:, 1:]
    return sin_t * (np.cos(phi) * t + np.sin(phi) * s) + np.sqrt(1 - sin_t**2) * n


def with_floor(t: Tile) -> Tile:
    """The tile over a white Lambertian floor (part ``floor``) just below it: a closed
    furnace for a weave, whose gaps otherwise let light through."""
    (lx, ly), z = t.period, t.z_range[0] - 0.05
    k = len(t.vertices)
    verts = np.concatenate([t.vertices, [[0, 0, z], [lx, 0, z], [lx, ly, z], [0, ly, z]]])
    faces = np.concatenate([t.faces, [[k, k + 1, k + 2], [k, k + 2, k + 3]]])
    material = np.concatenate([t.material, [len(t.parts)] * 2])
    curved = None if t.curved is None else np.concatenate([t.curved, np.zeros((2, 3, 3))])
    return Tile(verts, faces, material, (*t.parts, "floor"), t.period, facts=t.facts,
                curved=curved)


def sections(materials: dict, simulation: dict, table: dict
             ) -> tuple[dict[str, Material], Simulation, TableSettings]:
    """Sections written as a recipe's TOML holds them (dicts) as the records the engine
    takes; a table without ``sh_order`` holds no harmonics."""
    return ({p: material_from_json(m) for p, m in materials.items()},
            Simulation.from_json(simulation), TableSettings(**{"sh_order": 0, **table}))


def simulate_sections(tile: Tile, materials: dict, simulation: dict, table: dict,
                      **kw: Any) -> BRDFTable:
    """``microsim.measurement.simulation.simulate`` of sections written as dicts (``sections``)."""
    return simulate(tile, *sections(materials, simulation, table), **kw)
