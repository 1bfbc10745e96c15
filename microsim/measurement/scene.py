"""The periodic tile in Embree, and the driver of the compiled transport kernel.

The tile is put into one Embree scene as it is (no replicated neighbours). Rays are traced
in chunks on a thread pool; each chunk is one call of the compiled transport kernel
(``microsim.kernel.transport.trace_chunk``, ``nogil``), which follows every path of the
chunk to its end, asking Embree for each segment's closest hit through Embree's C API
(``microsim.kernel.embree``: the Embree 4 library ``embreex`` installs). Each query is
clipped at the first side of the tile's box the ray reaches; a ray that reaches a side
without a hit re-enters at the opposite side. A path
ends when it escapes through the top of the slab, leaves through the bottom, exceeds the
side crossings its direction allows within the slab (trapped), hits the wrong side of a
face, or reaches the bounce limit; docs/goniometer.md explains it.

Embree works in float32. Hit points are recomputed in float64 on the plane of the face hit,
and secondary rays start ``eps`` (a fixed fraction of the scene's size) off the face, on
the side their direction goes, so a ray never re-hits the face it left through round-off.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from typing import TypeVar

import numpy as np

from microsim.kernel import slots as ks
from microsim.kernel.beam import Runs
from microsim.kernel.embree import Scene, rayhit_buffer
from microsim.kernel.packing import FacetMaterials
from microsim.kernel.rng import key_of
from microsim.kernel.shading import curved_table
from microsim.kernel.transport import trace_chunk
from microsim.surfaces.tile import Tile

EPS_REL = 1e-6
"""Secondary-ray offset as a fraction of the scene's extent: 8 float32 ulps of the largest
coordinate. Measured (docs/goniometer.md): no self-hit on rough tiles down to 1e-8; at a
concave edge sharper than 90 deg an origin within about eps of the edge can lie behind the
neighbouring face, so a larger offset loses more rays there (1e-5 lost ten times more)."""
CHUNK = 4096
"""Rays per worker task: a chunk is traced whole (every query and bounce) on one thread;
small enough that its slots stay in a core's cache and the threads share a batch evenly
(chosen by measurement: docs/performance.md)."""
HIT = ks.BOUNCES
"""A first-hit query's (``closest_hit``) ray that met a face it can reach (the front; the
back of a refracting face for a ray inside its medium): a path of no bounces ends at its
first hit by the bounce limit. Its other outcomes are the kernel's fates of the same
names (``microsim.kernel.slots``): ``ESCAPED`` out through the top, ``LEAKED`` out
through the bottom, ``TRAPPED`` out of side crossings, ``BACKFACE`` a hit on the other
side (numerical leakage); a query has no materials, so no ray is ``TRANSMITTED``."""
ESCAPED, LEAKED, TRAPPED, BACKFACE = ks.ESCAPED, ks.LEAKED, ks.TRAPPED, ks.BACKFACE
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


@dataclass
class Outcomes:
    """How each ray of a run ended (``PeriodicScene.run``).

    Attributes
    ----------
    floats : (n, out_floats(C)) float
        Per ray at its end (``microsim.kernel.slots``' ``O_W`` layout): position (wrapped
        into the box), direction, then per channel its weight.
    ints : (n, OUT_INTS) int
        Its fate (``FATES``), bounces, and the last face it hit (-1: none).
    energy : (energy_blocks(n), b, 2, C) float
        Per block of ``ENERGY_BLOCK`` rays of the beam (``microsim.kernel.slots``) and per
        run (``Runs``; one without), per channel, the weight its paths transmitted (1 − F
        at non-refracting dielectrics) and that ended at a dispersive event (row 0), and
        the transmitted alone (row 1); what they absorbed is 1 less their final weights
        and row 0 (``slots.add_energy``).
    vertices : (n, v, 3) float
        Its first v hit points, unwrapped (NaN where it had fewer).
    starts : (b + 1,) int
        Run r's rows are ``starts[r]`` … ``starts[r + 1] − 1`` (``Runs.starts``).
    segments : int
        Embree queries made.
    """

    floats: np.ndarray
    ints: np.ndarray
    energy: np.ndarray
    vertices: np.ndarray
    starts: np.ndarray
    segments: int


class Tracing:
    """Paths on their way through the worker threads (``PeriodicScene.start``).

    Parameters
    ----------
    scene : PeriodicScene
        The scene tracing them (its ``segments`` count grows when they are collected).
    floats, ints, energy, vertices : arrays
        The outcome arrays the chunks fill (``Outcomes``).
    starts : (b + 1,) int
        The rows of each run (``Runs.starts``).
    chunks : list of Future of int
        Each chunk's task; its result is the Embree queries it made.
    """

    def __init__(self, scene: PeriodicScene, floats: np.ndarray, ints: np.ndarray,
                 energy: np.ndarray, vertices: np.ndarray, starts: np.ndarray,
                 chunks: list[Future[int]]) -> None:
        self._scene, self._chunks = scene, chunks
        self._arrays = (floats, ints, energy, vertices, starts)
        self._outcomes: Outcomes | None = None
        self._lock = threading.Lock()

    def then(self, fn: Callable[[Outcomes], T]) -> Future[T]:
        """``fn(outcomes)`` on a worker thread, queued when the last chunk has ended (at
        once, in this thread, without workers or chunks); the returned future holds its
        result, or the error of a chunk or of ``fn``. Each call queues its own task (a
        beam's runs are tallied side by side)."""
        pool = self._scene._pool
        out: Future[T] = Future()
        left = [len(self._chunks)]
        lock = threading.Lock()

        def run() -> None:
            try:
                out.set_result(fn(self.result()))
            except Exception as error:  # noqa: BLE001 (handed to the future's reader)
                out.set_exception(error)

        if pool is None or not self._chunks:
            run()
            return out

        def ended(_: Future[int]) -> None:
            with lock:
                left[0] -= 1
                last = left[0] == 0
            if last:
                pool.submit(run)

        for chunk in self._chunks:
            chunk.add_done_callback(ended)
        return out

    def result(self) -> Outcomes:
        """Wait for every chunk; the outcomes (the same object on later calls, from any
        thread)."""
        with self._lock:
            if self._outcomes is None:
                segments = sum(chunk.result() for chunk in self._chunks)
                self._scene.segments += segments
                self._outcomes = Outcomes(*self._arrays, segments)
                self._chunks = []  # their callbacks refer to this: no cycle outlives it
            return self._outcomes


def _done(value: T) -> Future[T]:
    """A future that already holds ``value``."""
    future: Future[T] = Future()
    future.set_result(value)
    return future


class PeriodicScene:
    """One tile in Embree, traced with periodic wrap on a thread pool; ``update`` moves it
    to another tile (the next realisation of a surface) without building anew what it can
    keep.

    Parameters
    ----------
    tile : Tile
        The periodic mesh.
    threads : int or None
        Worker threads (default: the number of CPUs).
    chunk : int
        Rays per worker task, a multiple of ``microsim.kernel.slots.ENERGY_BLOCK``.

    Attributes
    ----------
    tile : Tile
        The tile traced.
    normals : (m, 3) float
        Unit face normals (away from the material), the tile's (read-only).
    areas : (m,) float
        Face areas, the tile's (read-only).
    eps : float
        Offset of secondary-ray origins off their face.
    box : (7,) float
        The periods, the bottom and top of the slab, ``eps`` and the inverse periods, for
        the kernel (``microsim.kernel.slots.B_*``).
    segments : int
        Rays sent to Embree so far (a ray crossing k sides counts k + 1).
    """

    def __init__(self, tile: Tile, threads: int | None = None, chunk: int = CHUNK) -> None:
        if chunk <= 0 or chunk % ks.ENERGY_BLOCK:
            raise ValueError(f"chunk {chunk}: a positive multiple of {ks.ENERGY_BLOCK} rays "
                             "(microsim.kernel.slots.ENERGY_BLOCK) is needed")
        self._faces: np.ndarray | None = None
        self._take(tile)
        self._scene = Scene(tile.vertices, tile.faces)
        self.threads = threads or os.cpu_count() or 1
        self.chunk = chunk
        self._pool = ThreadPoolExecutor(self.threads) if self.threads > 1 else None
        self._local = threading.local()
        self.segments = 0

    def update(self, tile: Tile) -> None:
        """Trace ``tile`` from now on, keeping the worker threads and, when the tile has
        the same faces as the current one (another realisation of a height field on the
        same grid: ``faces`` the same array, or equal), the Embree scene, whose BVH is
        then refitted to the new vertices instead of built anew
        (``microsim.kernel.embree.Scene.update``). Outcomes are as a new
        ``PeriodicScene(tile)``'s; ``segments`` keeps counting.

        Call it only when no tracing is under way (every ``Tracing`` collected).

        Parameters
        ----------
        tile : Tile
            The new tile, of any topology.
        """
        self._take(tile)
        held = self._scene
        if len(tile.vertices) == held.vertex_count and (
                tile.faces is held.faces or np.array_equal(tile.faces, held.faces)):
            held.update(tile.vertices)
        else:
            held.close()
            self._scene = Scene(tile.vertices, tile.faces)

    def set_aside(self) -> None:
        """Let go of the tile (its arrays), keeping the threads, the Embree scene and the
        face table's memory for the next ``update``, the only call valid until then."""
        self.tile = self.normals = self.areas = None

    def _take(self, tile: Tile) -> None:
        """Make ``tile`` the scene's: its face table and slab (not its Embree scene)."""
        self.tile = tile
        self.period = np.array(tile.period, dtype=float)
        self.normals, self.areas = tile.face_normals_areas()
        self._faces = ks.face_table(self.normals, tile.face_planes(), tile.material,
                                    tile.tangents, self._faces)
        z_min, z_max = tile.z_range
        extent = max(float(np.abs(tile.vertices).max()), *tile.period, z_max - z_min)
        self.eps = EPS_REL * extent
        # the slab reaches a few eps past the geometry so offset origins always lie inside
        self.z_top = z_max + 4 * self.eps
        self.z_bottom = z_min - 4 * self.eps
        self.box = np.array([*self.period, self.z_bottom, self.z_top, self.eps,
                             *(1.0 / self.period)])

    def close(self) -> None:
        """Stop the worker threads and release the Embree scene."""
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None
        self._scene.close()

    def __enter__(self) -> PeriodicScene:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def map(self, fn: Callable[[int], T], starts: range) -> list[T]:
        """``fn`` over chunk starts, on the worker threads when there are several."""
        if self._pool is None or len(starts) < 2:
            return [fn(i) for i in starts]
        return list(self._pool.map(fn, starts))

    def submit(self, fn: Callable[[int], T], starts: range) -> list[Future[T]]:
        """``fn`` over chunk starts, queued on the worker threads (done at once, in this
        thread, without them)."""
        if self._pool is None:
            return [_done(fn(i)) for i in starts]
        return [self._pool.submit(fn, i) for i in starts]

    def run(self, origins: np.ndarray, dirs: np.ndarray, materials: FacetMaterials | None,
            bounces: int, seed: np.random.SeedSequence | Runs | None = None,
            media: np.ndarray | None = None, vertices: int = 0) -> Outcomes:
        """Trace paths with up to ``bounces`` scattering events each and wait for them:
        ``start(...).result()``, with the same parameters."""
        return self.start(origins, dirs, materials, bounces, seed, media, vertices).result()

    def start(self, origins: np.ndarray, dirs: np.ndarray, materials: FacetMaterials | None,
              bounces: int, seed: np.random.SeedSequence | Runs | None = None,
              media: np.ndarray | None = None, vertices: int = 0) -> Tracing:
        """Start tracing paths with up to ``bounces`` scattering events each: the chunks are
        queued on the worker threads and this returns at once, so the caller can queue
        more work (the next batch) before it waits for these (``Tracing.result``).

        Ray i draws its random numbers from the counter (i, event, ...) under the key of
        ``seed`` (``microsim.kernel.rng``), so the outcomes depend on neither the number of
        threads nor the chunk size. A beam of several runs (``seed`` a ``Runs``) gives
        each run the outcomes it has traced alone, in its own rows.

        Parameters
        ----------
        origins : (n, 3) float
            Start points within the slab; x and y may lie outside the box (wrapped).
        dirs : (n, 3) float
            Unit directions of travel.
        materials : FacetMaterials or None
            Scattering per face (None: no scattering, ``bounces`` must be 0).
        bounces : int
            Scattering events before a path is ended (0: a first-hit query).
        seed : numpy.random.SeedSequence, Runs or None
            Key of the materials' random numbers (None: zeros; nothing random is drawn
            without bounces), or the runs of the beam: each ray's row, run and key
            (``origins`` and ``dirs`` then in beam order).
        media : (n,) int or None
            Per ray, the part (material id) whose medium it starts in, -1 for air
            (default): the back faces of that part are hits for it, their fronts leakage.
        vertices : int
            Hit points to keep per ray (for drawing paths).

        Returns
        -------
        Tracing
        """
        n = len(origins)
        if materials is None:
            if bounces:
                raise ValueError("scattering needs materials")
            count = int(self.tile.material.max(initial=0)) + 1
            kind, params = ks.empty_params(count)
            tab_int, tab_f = ks.empty_tables(count)
            curved = curved_table(None, np.zeros(0, bool))
        else:
            kind, params, tab_int, tab_f, curved = (materials.kind, materials.params,
                                                    materials.tab_int, materials.tab_f,
                                                    materials.curved)
        runs = seed if isinstance(seed, Runs) else Runs.one(
            n, np.zeros(2, np.uint64) if seed is None else key_of(seed))
        origins = np.ascontiguousarray(origins, float)
        dirs = np.ascontiguousarray(dirs, float)
        media = np.full(n, -1, np.int64) if media is None else np.ascontiguousarray(
            media, np.int64)
        channels = params.shape[2]
        out_f = np.empty((n, ks.out_floats(channels)))  # every ray ends once: fills its row
        out_i = np.full((n, ks.OUT_INTS), ks.NO_FACE, np.int64)
        energy = np.zeros((ks.energy_blocks(n), len(runs), 2, channels))
        path = np.full((n, vertices, 3), np.nan)
        c = self.chunk

        def chunk(a: int) -> int:
            b = min(a + c, n)
            rayhit, slots_f, slots_i, live, near, prim = self._buffers(channels)
            return trace_chunk(a, origins[a:b], dirs[a:b], media[a:b], runs.rows[a:b],
                               runs.run[a:b], runs.starts, self._scene.handle,
                               self._scene.intersect, rayhit, slots_f, slots_i, live, near,
                               prim, self.box, self._faces, kind, params, tab_int, tab_f,
                               bounces, runs.keys, out_f, out_i, energy, path, curved)

        return Tracing(self, out_f, out_i, energy, path, runs.starts,
                       self.submit(chunk, range(0, n, c)))

    def _buffers(self, channels: int) -> tuple[np.ndarray, ...]:
        """The calling thread's ``RTCRayHit`` record, path slots (``CHUNK`` rows, for
        ``channels`` channels), queries, faces gathered and answers, made once per thread
        and channel count."""
        work = getattr(self._local, "work", None)
        if work is None or work[1].shape[1] != ks.slot_floats(channels):
            c = self.chunk
            work = (rayhit_buffer(), np.empty((c, ks.slot_floats(channels))),
                    np.empty((c, ks.SLOT_INTS), np.int64), np.empty(c, np.int64),
                    np.empty((c, 5)), np.empty(c, np.int64))
            self._local.work = work
        return work

    def closest_hit(self, origins: np.ndarray, dirs: np.ndarray,
                    inside: np.ndarray | None = None) -> Hits:
        """First face each ray meets in the periodic continuation of the tile.

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
        out = self.run(origins, dirs, None, 0, media=inside)
        return Hits(out.ints[:, ks.O_FATE].astype(np.int8), out.ints[:, ks.O_FACE],
                    out.floats[:, ks.S_PX:ks.S_PZ + 1])

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
