"""The objects a table is rendered on, and the tangent frame it is laid along.

Every object is a triangle mesh with smooth vertex normals and one unit tangent per face.
A table's local frame on the object is (tangent, normal × tangent, normal): its +x axis,
the axis that anisotropic tables measure φ from, runs along the tangent. The rule per
object (docs/render.md):

- ``torus`` (default, Westin et al. 1992's velvet doughnut): the major circle, i.e. around
  the vertical axis of the ring;
- ``sphere``: the parallels (circles of latitude) about the vertical axis;
- ``sheet``: a cloth draped over a mound; the sheet's own x axis (its warp, as woven);
- a mesh file: circles about the vertical axis through the centre of its bounding box.

All objects stand with +z up, centred at the origin, scaled to a bounding radius of
``RADIUS``. Where a rule degenerates (the poles, a face that looks along its tangent) the
tangent is any direction in the face's plane (Duff et al. 2017's orthonormal basis).

To hand Mitsuba exactly these tangents, ``corner_arrays`` gives every face its own three
vertices and texture coordinates that measure distance along (tangent, bitangent) in the
face's plane: Mitsuba's ∂p/∂u is then the face's tangent, and its shading frame is that
tangent made orthogonal to the interpolated normal.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from microsim.errors import InputError

RADIUS = 1.45
"""Bounding radius of every object (scene units)."""
OBJECTS = ("torus", "sphere", "sheet")
"""Built-in objects; anything else names a mesh file."""
MESH_SUFFIXES = (".ply", ".obj", ".stl", ".off", ".glb", ".gltf")


@dataclass(frozen=True)
class Surface:
    """A triangle mesh with vertex normals and per-face tangents.

    Attributes
    ----------
    vertices, normals : (n, 3) float
        Positions and unit vertex normals.
    faces : (m, 3) int
        Counter-clockwise seen from outside (the normals' side).
    tangents : (m, 3) float
        Unit tangent of each face, in the face's plane.
    name : str
    """

    vertices: np.ndarray
    normals: np.ndarray
    faces: np.ndarray
    tangents: np.ndarray
    name: str


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 0, n, 1.0)


def basis(n: np.ndarray) -> np.ndarray:
    """A unit vector orthogonal to each unit ``n`` (Duff et al. 2017, "Building an
    orthonormal basis, revisited", JCGT 6(1), listing 3), branch-free at every n.

    Parameters
    ----------
    n : (m, 3) float

    Returns
    -------
    (m, 3) float
    """
    sign = np.where(n[:, 2] >= 0, 1.0, -1.0)
    a = -1.0 / (sign + n[:, 2])
    b = n[:, 0] * n[:, 1] * a
    return np.stack([1.0 + sign * n[:, 0] ** 2 * a, sign * b, -sign * n[:, 0]], -1)


def face_frames(surface: Surface) -> tuple[np.ndarray, np.ndarray]:
    """Geometric face normals and the tangents projected into each face's plane.

    Returns
    -------
    normals, tangents : (m, 3) float
        Unit; a tangent that is (nearly) parallel to its face normal is replaced by
        ``basis(normal)``.
    """
    p = surface.vertices[surface.faces]
    n = _unit(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]))
    t = surface.tangents - np.sum(surface.tangents * n, -1, keepdims=True) * n
    length = np.linalg.norm(t, axis=-1, keepdims=True)
    t = np.where(length > 1e-6, t / np.where(length > 0, length, 1.0), basis(n))
    return n, t


def corner_arrays(surface: Surface) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Unshared per-corner arrays whose texture coordinates make ∂p/∂u the face tangent.

    Corner k of face f gets u = (p_k − p_0)·t_f and v = (p_k − p_0)·(n_f × t_f): p is an
    affine function of (u, v) on the face with ∂p/∂u = t_f.

    Returns
    -------
    positions, normals : (3m, 3) float32
    uvs : (3m, 2) float32
    faces : (m, 3) uint32
        ``arange(3m).reshape(m, 3)``.
    """
    n_face, t = face_frames(surface)
    b = np.cross(n_face, t)
    p = surface.vertices[surface.faces]  # (m, 3, 3)
    d = p - p[:, :1]
    uv = np.stack([np.einsum("mkc,mc->mk", d, t), np.einsum("mkc,mc->mk", d, b)], -1)
    m = len(surface.faces)
    return (p.reshape(-1, 3).astype(np.float32),
            surface.normals[surface.faces].reshape(-1, 3).astype(np.float32),
            uv.reshape(-1, 2).astype(np.float32),
            np.arange(3 * m, dtype=np.uint32).reshape(m, 3))


def _grid_faces(nu: int, nv: int, wrap_u: bool, wrap_v: bool) -> np.ndarray:
    """Two triangles per cell of an (nu, nv) vertex grid, counter-clockwise in (u, v)."""
    i, j = np.meshgrid(np.arange(nu if wrap_u else nu - 1), np.arange(nv if wrap_v else nv - 1),
                       indexing="ij")
    i1, j1 = (i + 1) % nu, (j + 1) % nv
    a, b, c, d = i * nv + j, i1 * nv + j, i1 * nv + j1, i * nv + j1
    return np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3),
                           np.stack([a, c, d], -1).reshape(-1, 3)])


def _scaled(vertices: np.ndarray) -> np.ndarray:
    """Centre on the bounding box and scale to a bounding radius of ``RADIUS``."""
    centre = (vertices.min(axis=0) + vertices.max(axis=0)) / 2
    v = vertices - centre
    return v * (RADIUS / np.linalg.norm(v, axis=1).max())


def torus(minor: float = 0.45, segments: tuple[int, int] = (160, 80)) -> Surface:
    """A ring about the z axis, major radius 1 and tube radius ``minor`` (before scaling),
    tangents along the major circle, (−sin u, cos u, 0) at azimuth u."""
    nu, nv = segments
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, nu, endpoint=False),
                       np.linspace(0, 2 * np.pi, nv, endpoint=False), indexing="ij")
    normal = np.stack([np.cos(v) * np.cos(u), np.cos(v) * np.sin(u), np.sin(v)], -1)
    ring = np.stack([np.cos(u), np.sin(u), np.zeros_like(u)], -1)
    vertices = _scaled((ring + minor * normal).reshape(-1, 3))
    faces = _grid_faces(nu, nv, True, True)
    return Surface(vertices, normal.reshape(-1, 3), faces, _around_z(vertices, faces), "torus")


def sphere(segments: tuple[int, int] = (128, 64)) -> Surface:
    """A UV sphere about the z axis, tangents along the parallels."""
    nu, nv = segments
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, nu, endpoint=False),
                       np.linspace(0, np.pi, nv), indexing="ij")
    normal = np.stack([np.sin(v) * np.cos(u), np.sin(v) * np.sin(u), -np.cos(v)], -1)
    faces = _grid_faces(nu, nv, True, False)
    p = normal.reshape(-1, 3)
    keep = np.linalg.norm(np.cross(p[faces[:, 1]] - p[faces[:, 0]],
                                   p[faces[:, 2]] - p[faces[:, 0]]), axis=1) > 1e-12
    faces = faces[keep]  # the cells at the poles are triangles
    vertices = p * RADIUS
    return Surface(vertices, p, faces, _around_z(vertices, faces), "sphere")


def sheet(segments: int = 160) -> Surface:
    """A square cloth draped over a mound: height z(x, y) = 0.55 exp(−(r/0.75)²) with
    folds 0.09 (r/1.2)^1.5 sin 7φ that deepen towards the hem; tangents along +x."""
    x, y = np.meshgrid(np.linspace(-1.2, 1.2, segments), np.linspace(-1.2, 1.2, segments),
                       indexing="ij")
    r, phi = np.hypot(x, y), np.arctan2(y, x)
    z = 0.55 * np.exp(-(r / 0.75) ** 2) + 0.09 * (r / 1.2) ** 1.5 * np.sin(7 * phi)
    step = 2.4 / (segments - 1)
    zx, zy = np.gradient(z, step, step)
    normal = _unit(np.stack([-zx, -zy, np.ones_like(z)], -1)).reshape(-1, 3)
    vertices = _scaled(np.stack([x, y, z], -1).reshape(-1, 3))
    faces = _grid_faces(segments, segments, False, False)
    tangents = np.tile([1.0, 0.0, 0.0], (len(faces), 1))
    return Surface(vertices, normal, faces, tangents, "sheet")


def _around_z(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Tangents of circles about the z axis at each face's centroid: ẑ × c (unit; zero on
    the axis, where ``face_frames`` falls back to ``basis``)."""
    c = vertices[faces].mean(axis=1)
    return _unit(np.stack([-c[:, 1], c[:, 0], np.zeros(len(c))], -1))


def mesh_file(path: str | Path) -> Surface:
    """A mesh file read by trimesh (PLY, OBJ, STL, OFF, glTF), +z up, with smooth vertex
    normals; tangents along circles about the vertical axis through its bounding box's
    centre. Texture coordinates in the file are not used."""
    import trimesh

    path = Path(path)
    if not path.is_file():
        raise InputError(f"--object {path}: no such file; objects: {', '.join(OBJECTS)} "
                         f"or a mesh file ({', '.join(MESH_SUFFIXES)})")
    try:
        mesh = trimesh.load(path, force="mesh")
    except Exception as exc:  # trimesh raises many types for unreadable files
        raise InputError(f"--object {path}: cannot read it as a mesh ({exc})") from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise InputError(f"--object {path}: holds no triangles")
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        vertices = _scaled(np.asarray(mesh.vertices, float))
    if not np.isfinite(vertices).all():
        raise InputError(f"--object {path}: its vertices span no extent, or more than a "
                         "float holds; nothing to scale to the scene")
    faces = np.asarray(mesh.faces, np.int64)
    return Surface(vertices, np.asarray(mesh.vertex_normals, float), faces,
                   _around_z(vertices, faces), path.stem)


def load_object(name: str) -> Surface:
    """A built-in object by name (``OBJECTS``) or a mesh file by path."""
    builders = {"torus": torus, "sphere": sphere, "sheet": sheet}
    if name in builders:
        return builders[name]()
    if Path(name).suffix.lower() not in MESH_SUFFIXES:
        raise InputError(f"--object {name}: unknown; objects: {', '.join(OBJECTS)} or a mesh "
                         f"file ({', '.join(MESH_SUFFIXES)})")
    return mesh_file(name)
