"""The periodic tile: the one mesh every generator makes and the tracer reads.

A tile is a triangle mesh inside the box [0, Lx] x [0, Ly] x [z_min, z_max] that repeats
seamlessly with period (Lx, Ly): geometry that would cross a side is cut there and its
remainder re-enters on the opposite side, so no face leaves the box. The tracer never
replicates it; rays leaving a side re-enter at the other.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from microsim.surfaces.facts import TileFacts


@dataclass
class Tile:
    """A periodic triangle mesh with a material id per face.

    Parameters
    ----------
    vertices : (n, 3) float
        Vertex positions; x in [0, Lx], y in [0, Ly].
    faces : (m, 3) int
        Vertex indices per triangle, counter-clockwise seen from outside (normals point
        away from the material, i.e. up on a height field).
    material : (m,) int
        Material id per face: an index into ``parts``.
    parts : tuple of str
        Part names (``[material.<part>]`` in recipes).
    period : tuple of float
        (Lx, Ly).
    facts : TileFacts
        What the generator reports about the tile (its subclass of
        ``microsim.surfaces.facts.TileFacts``: realised roughness, ...).
    warnings : list of str
        Things the user should know (e.g. a correlation length of too few grid cells).
    tangents : (m, 3) float or None
        A unit direction per face that a generator knows (a velvet fibre's axis), for
        facet materials whose frame follows it; None where the generator gives none.
    curved : (m, 3, 3) float or None
        The curved surface each face approximates, for shading normals
        (``microsim.kernel.shading``): rows (c, u, v), a point c on the axis of a tube and two
        section vectors u, v; the tube is the quadric {x : (u·q)² + (v·q)² = 1},
        q = x − c, which is constant along its axis u × v, and its outward normal at x
        is ∝ u (u·q) + v (v·q) (the gradient). A circular cylinder of radius r has u, v
        orthonormal and perpendicular to its axis, divided by r; a yarn of elliptical
        section has the sheared pair its generator documents (``weave.yarn``). The face's
        vertices lie on the quadric, so the face lies inside it (the tube is convex).
        Rows with u = v = 0 are flat faces. None: every face is flat.

    Notes
    -----
    The face normals, areas and plane constants are computed once, on first use, and kept
    (read-only) for as long as ``vertices`` and ``faces`` are the same arrays: give a tile
    new geometry by assigning new arrays, not by writing into them.
    """

    vertices: np.ndarray
    faces: np.ndarray
    material: np.ndarray
    parts: tuple[str, ...]
    period: tuple[float, float]
    facts: TileFacts = field(default_factory=TileFacts)
    warnings: list[str] = field(default_factory=list)
    tangents: np.ndarray | None = None
    curved: np.ndarray | None = None
    _geometry: tuple[np.ndarray, ...] | None = field(default=None, init=False, repr=False,
                                                      compare=False)

    def with_facts(self, facts: TileFacts, warnings: Sequence[str] = ()) -> Tile:
        """This tile with ``facts`` in place of its own and ``warnings`` added to its own:
        a new tile of the same arrays, which shares their face geometry if it has been
        computed (a generator reports what it measured on the tile it built)."""
        out = replace(self, facts=facts, warnings=[*self.warnings, *warnings])
        out._geometry = self._geometry
        return out

    @property
    def z_range(self) -> tuple[float, float]:
        """(z_min, z_max) of the vertices."""
        z = self.vertices[:, 2]
        return float(z.min()), float(z.max())

    def _face_geometry(self) -> tuple[np.ndarray, ...]:
        """(vertices, faces, normals, areas, plane) of the current arrays, computed once."""
        kept = self._geometry
        if kept is None or kept[0] is not self.vertices or kept[1] is not self.faces:
            # compiled (numba): imported on first use so that importing the surfaces
            # package, as recipe validation does, does not load numba
            from microsim.surfaces.faces import face_geometry

            computed = face_geometry(np.ascontiguousarray(self.vertices, float),
                                     np.ascontiguousarray(self.faces))
            for array in computed:
                array.flags.writeable = False
            kept = self._geometry = (self.vertices, self.faces, *computed)
        return kept

    def face_normals_areas(self) -> tuple[np.ndarray, np.ndarray]:
        """Unit face normals and face areas (``microsim.surfaces.faces``), read-only.

        Returns
        -------
        normals : (m, 3) float
            Unit normals (zero rows for degenerate faces).
        areas : (m,) float
            Triangle areas.
        """
        _, _, normals, areas, _ = self._face_geometry()
        return normals, areas

    def face_planes(self) -> np.ndarray:
        """Plane constant of every face, read-only: face f lies in {x : n_f · x = c_f}.

        Returns
        -------
        (m,) float
            n_f · (first vertex of f), n_f the unit normal (0 for degenerate faces).
        """
        return self._face_geometry()[4]

    def realised_alpha(self, rotation: float = 0.0) -> tuple[float, float]:
        """Roughness of the facets along two axes rotated by ``rotation`` about +z.

        The height gradient of a facet is g = (−n_x/n_z, −n_y/n_z); over the macro-surface
        (facets weighted by projected area, a_f n_z) Walter et al. 2007's roughness is
        α = √(2 E[(g · e)²]) along a unit axis e (Beckmann slopes have per-axis variance
        α²/2). Facets with n_z ≤ 0 (overhangs, vertical walls) have no height gradient
        and are left out.

        Parameters
        ----------
        rotation : float
            Angle of the first axis from +x, radians.

        Returns
        -------
        alpha_x, alpha_y : float
            Along the rotated x and y axes.
        """
        from microsim.surfaces.faces import slope_terms  # compiled: see _face_geometry

        weight, along_x, along_y = slope_terms(*self.face_normals_areas(),
                                               float(np.cos(rotation)),
                                               float(np.sin(rotation)))
        total = weight.sum()
        return (float(np.sqrt(2 * along_x.sum() / total)),
                float(np.sqrt(2 * along_y.sum() / total)))

    def ndf_histogram(self, bins: int, theta_max: float, blocks: int = 4
                      ) -> dict[str, np.ndarray]:
        """Facet-normal histogram as an NDF estimate, with sub-tile standard errors.

        A facet of area a and unit normal n covers the macro-surface's projected area
        a n_z; the share of it with normals in a θ bin B, divided by ∫_B cos θ dω =
        π (sin²θ_b − sin²θ_a), estimates the bin average of D (an NDF's normalisation
        ∫ D cos θ dω = 1; Walter et al. 2007, eq. 4). Facets are correlated over a
        correlation length, so the standard error comes from the scatter of the estimate
        over ``blocks`` × ``blocks`` sub-tiles (batch means), not from a multinomial count.

        Parameters
        ----------
        bins : int
            Bins uniform in θ over [0, theta_max].
        theta_max : float
            Radians.
        blocks : int
            Sub-tiles per side for the error estimate.

        Returns
        -------
        dict
            ``edges`` (bins + 1,) radians, ``D`` (bins,) 1/sr, ``stderr`` (bins,) (NaN
            for a bin without facets).
        """
        normals, areas = self.face_normals_areas()
        weight = areas * np.maximum(normals[:, 2], 0.0)
        theta = np.arccos(np.clip(normals[:, 2], -1.0, 1.0))
        edges = np.linspace(0.0, theta_max, bins + 1)
        index = np.clip(np.searchsorted(edges, theta, side="right") - 1, 0, bins)
        index = np.where(theta >= theta_max, bins, index)  # bin ``bins``: beyond the range
        solid = np.pi * np.diff(np.sin(edges) ** 2)
        centroid = self.vertices[self.faces].mean(axis=1)[:, :2]
        cell = np.clip(np.floor(centroid / np.asarray(self.period) * blocks).astype(int),
                       0, blocks - 1)
        hist = np.zeros((blocks * blocks, bins + 1))
        np.add.at(hist, (cell[:, 0] * blocks + cell[:, 1], index), weight)
        # sub-tiles that hold facets (a tile of a few large faces leaves some empty)
        hist_filled = hist[hist.sum(axis=1) > 0]
        share = hist_filled[:, :bins] / hist_filled.sum(axis=1, keepdims=True)
        total = hist.sum(axis=0)[:bins]
        n = len(hist_filled)
        err = (share.std(axis=0, ddof=1) / np.sqrt(n) / solid if n > 1
               else np.full(bins, np.nan))
        # a bin no facet falls in has value 0 and an undefined error, not a zero one
        return {"edges": edges, "D": total / hist.sum() / solid,
                "stderr": np.where(total > 0, err, np.nan)}


def height_field_tile(h: np.ndarray, size: float, facts: TileFacts) -> Tile:
    """The tile of a periodic height field on [0, size]²: one part ``base``.

    Parameters
    ----------
    h : (n, n) float
        ``h[i, j]`` at x = i·size/n, y = j·size/n.
    size : float
        Period along x and y.
    facts : TileFacts
        What the generator reports of it.

    Returns
    -------
    Tile
        (n + 1)² vertices (``height_field_vertices``), 2n² faces (``grid_faces``, shared by
        every field on the grid).
    """
    n = len(h)
    faces = grid_faces(n + 1, n + 1)
    return Tile(height_field_vertices(h, size), faces, np.zeros(len(faces), np.int32),
                ("base",), (size, size), facts=facts)


def height_field_vertices(h: np.ndarray, size: float) -> np.ndarray:
    """Vertices of a periodic height field on [0, size]², indexed as ``grid_faces`` expects.

    Parameters
    ----------
    h : (n, n) float
        ``h[i, j]`` at x = i·size/n, y = j·size/n.
    size : float
        Period.

    Returns
    -------
    ((n + 1)², 3) float
        Vertex i·(n + 1) + j at (x_i, y_j, h[i mod n, j mod n]), x_i = y_i the
        ``linspace(0, size, n + 1)`` nodes: the last row and column repeat the first, so
        opposite edges are equal bit for bit.
    """
    n = len(h)
    vertices = np.empty((n + 1, n + 1, 3))
    vertices[..., :2] = _grid_xy(n, float(size))
    z = vertices[..., 2]
    z[:n, :n] = h
    z[n, :n] = h[0]
    z[:, n] = z[:, 0]
    return vertices.reshape(-1, 3)


@functools.lru_cache(maxsize=4)
def _grid_xy(n: int, size: float) -> np.ndarray:
    """(n + 1, n + 1, 2) read-only: (x_i, y_j) of the height-field grid."""
    g = np.linspace(0.0, size, n + 1)
    xy = np.stack(np.meshgrid(g, g, indexing="ij"), axis=-1)
    xy.flags.writeable = False
    return xy


@functools.lru_cache(maxsize=8)
def grid_faces(nx: int, ny: int) -> np.ndarray:
    """Triangles of a vertex grid indexed ``i * ny + j``, two per cell, counter-clockwise
    seen from +z when x grows with i and y with j.

    Made once per grid size and shared, read-only: every realisation of a height field on
    one grid holds the same faces array, so a tracer can tell that their topology is the
    same (and refit rather than rebuild its acceleration structure).

    Parameters
    ----------
    nx, ny : int
        Vertices along x and y.

    Returns
    -------
    (2 (nx − 1)(ny − 1), 3) int64
    """
    i, j = np.meshgrid(np.arange(nx - 1), np.arange(ny - 1), indexing="ij")
    v00 = (i * ny + j).ravel()
    v10, v01 = v00 + ny, v00 + 1
    v11 = v10 + 1
    faces = np.concatenate([np.column_stack([v00, v10, v11]),
                            np.column_stack([v00, v11, v01])]).astype(np.int64)
    faces.flags.writeable = False
    return faces
