"""Ray queries on one periodic tile with Embree, and multi-bounce paths over it.

The tile is put into one Embree scene as it is (no replicated neighbours). A ray is traced
inside the tile's box: each Embree query is clipped at the first side of the box the ray
reaches; a ray that reaches a side without a hit re-enters at the opposite side (its origin
shifted by one period) and goes on. It ends when it hits a face, leaves the height slab
upwards (escaped) or downwards (leaked: only a surface with holes lets that happen), or
exceeds the number of side crossings its direction allows within the slab (trapped). The
whole loop is vectorised over the rays still active; docs/goniometer.md explains it.

Embree works in float32. Hit points are recomputed in float64 on the plane of the face hit,
and secondary rays start ``eps`` (a fixed fraction of the scene's size) off the face, on
the side their direction goes, so a ray never re-hits the face it left through round-off.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import TYPE_CHECKING, TypeVar

import numpy as np
from embreex.mesh_construction import TriangleMesh
from embreex.rtcore_scene import EmbreeScene

from microsim.refraction import attenuation, next_medium
from microsim.surfaces.tile import Tile

if TYPE_CHECKING:
    from microsim.materials import FacetMaterials

EPS_REL = 1e-6
"""Secondary-ray offset as a fraction of the scene's extent: 8 float32 ulps of the largest
coordinate. Measured (docs/goniometer.md): no self-hit on rough tiles down to 1e-8; at a
concave edge sharper than 90 deg an origin within about eps of the edge can lie behind the
neighbouring face, so a larger offset loses more rays there (1e-5 lost ten times more)."""
CHUNK = 32768
"""Rays per worker task: a chunk is traced whole (wrap loop, bounces) on one thread
(chosen by measurement: docs/performance.md)."""
MAX_SEGMENTS = 10_000
"""Upper bound of queries for one ray: a direction so nearly horizontal that it would need
more side crossings to cross the slab is reported as trapped."""

HIT, ESCAPED, LEAKED, TRAPPED, BACKFACE = range(5)
"""Outcomes of a query: a hit on the side of a face the ray can reach (the front; the back
of a refracting face for a ray inside its medium), out through the top, out through the
bottom, out of side crossings, or a hit on the other side (numerical leakage)."""
FATES = ("hit", "escaped", "leaked", "trapped", "backface")
T = TypeVar("T")


@dataclass
class Hits:
    """Result of one closest-hit query per ray.

    Attributes
    ----------
    status : (n,) int8
        ``HIT``, ``ESCAPED``, ``LEAKED``, ``TRAPPED`` or ``BACKFACE``.
    face : (n,) int64
        Face hit (``-1`` unless ``status`` is ``HIT`` or ``BACKFACE``).
    point : (n, 3) float
        Hit point inside the tile's box (meaningful where a face was hit).
    """

    status: np.ndarray
    face: np.ndarray
    point: np.ndarray


class PeriodicScene:
    """One tile in Embree, traced with periodic wrap on a thread pool.

    Parameters
    ----------
    tile : Tile
        The periodic mesh.
    threads : int or None
        Worker threads (default: the number of CPUs).
    chunk : int
        Rays per worker task.

    Attributes
    ----------
    normals : (m, 3) float
        Unit face normals (away from the material).
    areas : (m,) float
        Face areas.
    eps : float
        Offset of secondary-ray origins off their face.
    segments : int
        Rays sent to Embree so far (a ray crossing k sides counts k + 1).
    """

    def __init__(self, tile: Tile, threads: int | None = None, chunk: int = CHUNK) -> None:
        self.tile = tile
        self.period = np.array(tile.period, dtype=float)
        self.normals, self.areas = tile.face_normals_areas()
        # plane of each face: n . x = c
        self._plane = np.einsum("ij,ij->i", self.normals, tile.vertices[tile.faces[:, 0]])
        z_min, z_max = tile.z_range
        extent = max(float(np.abs(tile.vertices).max()), *tile.period, z_max - z_min)
        self.eps = EPS_REL * extent
        # the slab reaches a few eps past the geometry so offset origins always lie inside
        self.z_top = z_max + 4 * self.eps
        self.z_bottom = z_min - 4 * self.eps
        self._scene = EmbreeScene()
        TriangleMesh(self._scene, np.ascontiguousarray(tile.vertices, np.float32),
                     np.ascontiguousarray(tile.faces, np.int32))
        # the first query builds the BVH: do it here, so scene set-up is timed as such
        self._scene.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32))
        self.threads = threads or os.cpu_count() or 1
        self.chunk = chunk
        self._pool = ThreadPoolExecutor(self.threads) if self.threads > 1 else None
        self.segments = 0

    def close(self) -> None:
        """Stop the worker threads."""
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None

    def __enter__(self) -> PeriodicScene:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def map(self, fn: Callable[[int], T], starts: range) -> list[T]:
        """``fn`` over chunk starts, on the worker threads when there are several."""
        if self._pool is None or len(starts) < 2:
            return [fn(i) for i in starts]
        return list(self._pool.map(fn, starts))

    def wrap(self, points: np.ndarray) -> np.ndarray:
        """Points moved by whole periods into [0, Lx) x [0, Ly).

        Parameters
        ----------
        points : (n, 3) float

        Returns
        -------
        (n, 3) float
        """
        out = points.copy()
        for axis, length in enumerate(self.period):  # column by column: much faster
            column = out[:, axis]
            column -= np.floor(column / length) * length
        return out

    def _budget(self, dirs: np.ndarray) -> np.ndarray:
        """Most queries a ray may need: a straight path across the slab (length at most
        height / |dz|) crosses each pair of sides at most length |d_axis| / L + 1 times;
        the bound is doubled for slack and capped at ``MAX_SEGMENTS``."""
        a = np.abs(dirs)
        reach = (a[:, 0] / self.period[0] + a[:, 1] / self.period[1]) * (
            self.z_top - self.z_bottom)
        crossings = reach / np.maximum(a[:, 2], 1e-300)
        return np.minimum(2 * np.ceil(crossings) + 8, MAX_SEGMENTS).astype(np.int64)

    def closest_hit(self, origins: np.ndarray, dirs: np.ndarray,
                    inside: np.ndarray | None = None) -> Hits:
        """First face each ray meets in the periodic continuation of the tile.

        Chunks of ``chunk`` rays are traced on the worker threads; the result does not
        depend on the chunking.

        Parameters
        ----------
        origins : (n, 3) float
            Ray origins, within the slab; x and y may lie outside the box (wrapped).
        dirs : (n, 3) float
            Unit directions of travel.
        inside : (n,) int or None
            Per ray, the part (material id) whose medium it travels in, -1 for none: the
            back faces of that part are hits for it, their fronts leakage.

        Returns
        -------
        Hits
        """
        c = self.chunk
        parts = self.map(lambda i: self._closest_hit(
            origins[i:i + c], dirs[i:i + c], None if inside is None else inside[i:i + c]),
            range(0, len(origins), c))
        self.segments += sum(seg for _, seg in parts)
        return Hits(*(np.concatenate([getattr(h, f) for h, _ in parts])
                      for f in ("status", "face", "point")))

    def _closest_hit(self, origins: np.ndarray, dirs: np.ndarray,
                     inside: np.ndarray | None = None) -> tuple[Hits, int]:
        """``closest_hit`` in the calling thread; also returns the Embree queries made."""
        n = len(origins)
        status = np.full(n, -1, np.int8)
        face = np.full(n, -1, np.int64)
        point = self.wrap(origins)
        budget = self._budget(dirs)
        dirs32 = dirs.astype(np.float32)
        # per ray and axis: the box side it runs towards, and 1 / d (huge where d = 0, so
        # that side is never the nearest; d = 0 runs towards the upper side, not behind)
        target = np.column_stack([np.where(dirs[:, i] >= 0, hi, lo) for i, (lo, hi) in
                                  enumerate(zip((0.0, 0.0, self.z_bottom),
                                                (*self.period, self.z_top), strict=True))])
        inv = 1.0 / np.where(dirs == 0, 1e-300, dirs)
        active = np.arange(n)
        queries = segments = 0
        while active.size:
            full = active.size == n
            o = point if full else np.take(point, active, axis=0)
            d = dirs if full else np.take(dirs, active, axis=0)
            # distance to each side of the box along the ray
            t_side = (target if full else np.take(target, active, axis=0)) - o
            t_side *= inv if full else np.take(inv, active, axis=0)
            np.maximum(t_side, 0.0, out=t_side)
            t_exit = np.minimum(np.minimum(t_side[:, 0], t_side[:, 1]), t_side[:, 2])
            prim = self._scene.run(o.astype(np.float32),
                                   dirs32 if full else np.take(dirs32, active, axis=0),
                                   dists=(t_exit + self.eps).astype(np.float32))
            segments += len(o)
            queries += 1
            got = np.flatnonzero(prim >= 0)
            # hit point in float64 on the face's plane (Embree's t is float32)
            idx, p = active[got], prim[got].astype(np.int64)
            n_f = np.take(self.normals, p, axis=0)
            d_g, o_g = np.take(d, got, axis=0), np.take(o, got, axis=0)
            den = np.einsum("ij,ij->i", d_g, n_f)
            num = self._plane[p] - np.einsum("ij,ij->i", o_g, n_f)
            t_hit = np.divide(num, den, out=np.zeros(len(p)), where=den != 0)
            point[idx] = o_g + np.maximum(t_hit, 0.0)[:, None] * d_g
            face[idx] = p
            back = den >= 0
            # the side a ray can reach: the back of its own medium's faces, else the front
            real = back == (False if inside is None else
                            np.take(self.tile.material, p) == np.take(inside, idx))
            status[idx] = np.where(real, HIT, BACKFACE)
            # a face hit from the wrong side whose plane the origin lies just beyond (at
            # most 2 eps: where an offset crossed a neighbour's plane at a concave edge) is
            # the offset's artefact: the ray goes on through it
            again = np.flatnonzero(~real & (np.where(back, num, -num) <= 2 * self.eps))
            resume = idx[again]
            status[resume] = -1
            point[resume] = self.wrap(self.offset(point[resume], n_f[again], d_g[again]))
            # no hit: out through the top or bottom, or on into the neighbouring tile
            miss = np.flatnonzero(prim < 0)
            axis = np.argmin(t_side[miss], axis=1)
            vertical = axis == 2
            ends = miss[vertical]
            status[active[ends]] = np.where(d[ends, 2] > 0, ESCAPED, LEAKED)
            on, axis = miss[~vertical], axis[~vertical]
            idx = active[on]
            moved = np.take(o, on, axis=0) + t_exit[on, None] * np.take(d, on, axis=0)
            rows = np.arange(len(on))
            # enter at the opposite side exactly; the other coordinate stays in the box
            entry = np.where(d[on, axis] > 0, 0.0, self.period[axis])
            moved[:, :2] = np.clip(moved[:, :2], 0.0, self.period)
            moved[rows, axis] = entry
            point[idx] = moved
            going = np.concatenate([idx, resume])
            status[going[budget[going] <= queries]] = TRAPPED
            active = np.sort(going[budget[going] > queries])
        return Hits(status, face, point), segments

    def offset(self, points: np.ndarray, n_f: np.ndarray, dirs: np.ndarray) -> np.ndarray:
        """Origins of secondary rays: ``eps`` off the face on the side ``dirs`` goes.

        Parameters
        ----------
        points : (n, 3) float
            Points on the faces.
        n_f : (n, 3) float
            The faces' unit normals.
        dirs : (n, 3) float
            Directions the new rays will take.

        Returns
        -------
        (n, 3) float
        """
        side = np.where(np.einsum("ij,ij->i", dirs, n_f) >= 0, 1.0, -1.0)
        return points + (self.eps * side)[:, None] * n_f


@dataclass
class Paths:
    """Fates of rays traced with bounces.

    Attributes
    ----------
    direction : (n, 3) float
        Exit direction of escaped rays (zero rows for the others).
    weight : (n, 3) float
        RGB weight of escaped rays (zero for the others).
    order : (n,) int
        Scattering order of escaped rays (bounces before escaping; 0: not escaped, or
        escaped without touching the surface, which a closed surface does not allow).
    lost : (3,) float
        Summed RGB weight of paths ended by the simulation: alive after the last bounce,
        leaked (without having refracted), trapped, or through a back face.
    transmitted : (3,) float
        Summed RGB weight transmitted: 1 - F at non-refracting dielectric facets, and paths
        that left through the bottom of the slab after refracting.
    absorbed : (3,) float
        Summed RGB weight absorbed by conductor and lambertian facets and inside
        absorbing media (Beer-Lambert).
    fate_counts : dict of str to int
        Paths per ending (``"escaped"``, ``"bounces"``, ``"transmitted"``, and the
        ``FATES`` of lost paths).
    """

    direction: np.ndarray
    weight: np.ndarray
    order: np.ndarray
    lost: np.ndarray
    transmitted: np.ndarray
    absorbed: np.ndarray
    fate_counts: dict[str, int]


def trace_paths(scene: PeriodicScene, materials: FacetMaterials, origins: np.ndarray,
                dirs: np.ndarray, bounces: int, seed: np.random.SeedSequence) -> Paths:
    """Trace rays with up to ``bounces`` scattering events each.

    Chunks of ``scene.chunk`` rays are traced on the worker threads, chunk c drawing its
    random numbers from the child ``seed`` spawn key + (c,); the result depends on the
    chunk size but not on the number of threads.

    Parameters
    ----------
    scene : PeriodicScene
    materials : FacetMaterials
        Scattering per face material.
    origins : (n, 3) float
        Start points within the slab.
    dirs : (n, 3) float
        Unit directions of travel.
    bounces : int
        Maximum scattering order; paths still alive afterwards are lost.
    seed : numpy.random.SeedSequence
        Root of the random streams of the materials that need them.

    Returns
    -------
    Paths
    """
    c = scene.chunk

    def run(i: int) -> tuple[Paths, int]:
        rng = np.random.default_rng(np.random.SeedSequence(
            seed.entropy, spawn_key=(*seed.spawn_key, i // c)))
        return _trace_paths(scene, materials, origins[i:i + c], dirs[i:i + c], bounces, rng)

    parts = scene.map(run, range(0, len(origins), c))
    scene.segments += sum(seg for _, seg in parts)
    fates = {k: sum(p.fate_counts[k] for p, _ in parts) for k in parts[0][0].fate_counts}
    return Paths(*(np.concatenate([getattr(p, f) for p, _ in parts])
                   for f in ("direction", "weight", "order")),
                 *(sum(getattr(p, f) for p, _ in parts)
                   for f in ("lost", "transmitted", "absorbed")), fates)


def _trace_paths(scene: PeriodicScene, materials: FacetMaterials, origins: np.ndarray,
                 dirs: np.ndarray, bounces: int, rng: np.random.Generator
                 ) -> tuple[Paths, int]:
    """``trace_paths`` of one chunk in the calling thread, and the Embree queries made."""
    n = len(origins)
    direction = np.zeros((n, 3))
    weight = np.zeros((n, 3))
    order = np.zeros(n, np.int64)
    lost, transmitted, absorbed = np.zeros(3), np.zeros(3), np.zeros(3)
    counts = dict.fromkeys(("escaped", "bounces", "transmitted") + FATES[2:], 0)
    # the paths still alive: their rows, weights, origins and directions
    alive, w, o, d = np.arange(n), np.ones((n, 3)), origins, dirs
    # with refracting facets: the medium each path is in (its part, -1: air) and whether
    # it has refracted (then leaving through the bottom is transmission, not leakage)
    refracting = bool(materials.refracting.any())
    medium = np.full(n, -1, np.int64) if refracting else None
    crossed = np.zeros(n, bool)
    segments = 0
    for bounce in range(bounces + 1):
        if alive.size == 0:
            break
        hits, seg = scene._closest_hit(o, d, medium)
        segments += seg
        if medium is not None:
            w, lose = _absorb(scene, materials, hits, o, d, w, medium)
            absorbed += lose
        out = np.flatnonzero(hits.status == ESCAPED)
        direction[alive[out]] = np.take(d, out, axis=0)
        weight[alive[out]] = np.take(w, out, axis=0)
        order[alive[out]] = bounce
        counts["escaped"] += out.size
        hit = np.flatnonzero(hits.status == HIT)
        for code in (LEAKED, TRAPPED, BACKFACE) if out.size + hit.size < alive.size else ():
            ended = hits.status == code
            if code == LEAKED:  # through the bottom after refracting: transmitted
                through = ended & crossed
                transmitted += w[through].sum(axis=0)
                counts["transmitted"] += int(through.sum())
                ended &= ~crossed
            lost += w[ended].sum(axis=0)
            counts[FATES[code]] += int(ended.sum())
        alive, face, crossed = alive[hit], hits.face[hit], crossed[hit]
        w, d, point = (np.take(a, hit, axis=0) for a in (w, d, hits.point))
        if bounce == bounces:
            lost += w.sum(axis=0)
            counts["bounces"] += alive.size
            break
        n_f = np.take(scene.normals, face, axis=0)
        d_in = d
        d, factor, into = materials.scatter(face, d, n_f, rng)
        transmitted += (w * into).sum(axis=0)
        absorbed += (w * (1.0 - factor - into)).sum(axis=0)
        w = w * factor
        o = scene.offset(point, n_f, d)
        if medium is not None:
            part = np.take(materials.face_material, face)
            medium, through = next_medium(part, np.take(materials.refracting, part), n_f,
                                          d_in, d, medium[hit])
            crossed |= through
    return Paths(direction, weight, order, lost, transmitted, absorbed, counts), segments


def _absorb(scene: PeriodicScene, materials: FacetMaterials, hits: Hits, o: np.ndarray,
            d: np.ndarray, w: np.ndarray, medium: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Beer-Lambert attenuation of one query's segments travelled inside a medium.

    A segment's length is its height change over |d_z| (``_closest_hit`` wraps x and y,
    not z), from the origin to the face hit, or to the top or bottom of the slab.

    Returns
    -------
    w : (k, 3) float
        Weights after the segment.
    absorbed : (3,) float
        Weight absorbed on the way.
    """
    sigma = np.take(materials.absorption, medium, axis=0)
    sel = np.flatnonzero((sigma > 0).any(axis=1) & (hits.status != TRAPPED))
    if sel.size == 0:
        return w, np.zeros(3)
    status = hits.status[sel]
    z_end = np.where(status == ESCAPED, scene.z_top,
                     np.where(status == LEAKED, scene.z_bottom, hits.point[sel, 2]))
    dz = np.abs(z_end - o[sel, 2])
    d_z = np.abs(d[sel, 2])
    # a segment exactly parallel to the slab has no length from heights: it is taken as
    # never leaving the medium (a set of measure zero)
    length = np.divide(dz, d_z, out=np.full(sel.size, np.inf), where=d_z > 0)
    before = w[sel]
    w = w.copy()
    w[sel] = before * attenuation(sigma[sel], length)
    return w, (before - w[sel]).sum(axis=0)
