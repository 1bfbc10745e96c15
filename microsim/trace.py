"""Ray queries on one periodic tile with Embree (``microsim.paths`` builds paths of them).

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
from typing import TypeVar

import numpy as np
from embreex.mesh_construction import TriangleMesh
from embreex.rtcore_scene import EmbreeScene

from microsim.surfaces.tile import Tile

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
        inv = 1.0 / np.where(dirs == 0, 1e-200, dirs)  # 1e200: no overflow times lengths
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
