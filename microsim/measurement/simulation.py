"""Tables of the surface: a recipe's realisations traced one at a time, the adaptive stop
over rays and realisations, and the assembled table.

A recipe with random geometry names a surface, not a tile: its table is the mean over
``simulation.realisations`` independent tiles (``microsim.surfaces.realisations``), each
traced by the goniometer (``microsim.measurement.goniometer.measure_directions``) with
``rays / realisations`` rays per incident direction, its errors the ensemble's
(``microsim.tables.estimator``). Tiles are built and traced one at a time, so the memory
is that of one tile. docs/ensembles.md explains the error bars and the adaptive stop.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import replace
from operator import attrgetter
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits

from microsim.materials import Material
from microsim.measurement.adaptive import direction_errors, next_plan
from microsim.measurement.goniometer import (
    BATCH,
    Direction,
    Energies,
    Incidences,
    Measurement,
    Part,
    Progress,
    Run,
    RunKey,
    Sums,
    fold,
    lost_energy_warnings,
    trace_realisations,
)
from microsim.measurement.scene import PeriodicScene
from microsim.pages import keep_pages
from microsim.settings import Recipe, Simulation, TableSettings
from microsim.surfaces import Surface, build_tile
from microsim.surfaces.facts import SurfaceFacts
from microsim.surfaces.realisations import realisation, realisation_seed
from microsim.surfaces.tile import Tile
from microsim.tables.assemble import RawSums, from_ensemble
from microsim.tables.meta import DirectionRecord, TableInput, TableMeta, Timing
from microsim.tables.table import BRDFTable
from microsim.version import __version__


class Tiles:
    """The tiles of a surface's realisations, built when asked for.

    Parameters
    ----------
    surface : Surface or None
        A resolved ``[surface]`` section: realisation r is built from
        ``microsim.surfaces.realisations.realisation(surface, r)``.
    tile : Tile or None
        Instead of ``surface``: one given tile, realisation 0 and the only one.
    memory_limit_gib : float or None
        The memory guard's budget for each tile (``microsim.memory``).
    """

    def __init__(self, surface: Surface | None = None, tile: Tile | None = None,
                 memory_limit_gib: float | None = None) -> None:
        self.surface, self.tile, self.memory_limit_gib = surface, tile, memory_limit_gib

    def __call__(self, r: int) -> Tile:
        """Realisation r's tile."""
        if self.surface is None:
            if r != 0:
                raise ValueError("a given tile is one realisation; build the others from "
                                 "the surface section (simulate_surface)")
            return self.tile
        return build_tile(realisation(self.surface, r), self.memory_limit_gib)


@threadpool_limits.wrap(limits=1, user_api="blas")
def measure_ensemble(tiles: Callable[[int], Tile], materials: Mapping[str, Material],
                     simulation: Simulation, table: TableSettings,
                     thetas: Sequence[int] | None = None, *, threads: int | None = None,
                     progress: Callable[[Progress], None] | None = None,
                     keep_runs: bool = False) -> Measurement:
    """Trace the incident directions of some polar angles over the surface's realisations,
    one tile at a time, until each direction's plan (and adaptive stop) is done.

    With realisations (``simulation.realisations_or_one`` > 1) each tile is traced once,
    for every direction that plans it, and its runs are folded into running sums
    (``Measurement.fold``), so the memory does not grow with the realisations; the
    adaptive stop adds realisations (``microsim.measurement.adaptive.next_plan``). With one
    realisation its rays grow in place.

    Parameters
    ----------
    tiles : callable
        Realisation index → its tile (``Tiles``).
    materials, simulation, table, threads, progress
        As for ``simulate``.
    thetas : sequence of int or None
        Indices into ``simulation.theta_i`` (default: all), each with every incident
        azimuth. Directions are measured independently (their own plans and random
        streams), so measurements of disjoint index sets assemble into the table of one
        measurement of all.
    keep_runs : bool
        Keep every realisation's run instead of folding it (for studies of the
        realisations themselves; the memory then grows with them).

    The BLAS library runs on one thread of the calling thread meanwhile: the tracer's
    threads use the cores, and the products of one BLAS thread (``microsim.tables.
    principal``) are the same bit for bit on whatever thread calls them. The limit is the
    process's: where measurements run at once on threads of one process (a Dask worker of
    several threads), the first to end gives the library its threads back for the others.

    Returns
    -------
    Measurement
        The folded (or kept) realisations of every direction, and the directions' stop
        reasons when ``simulation.target_error`` is set.
    """
    keep_pages()  # each page of the run's peak touched once (``microsim.pages``)
    chosen = list(range(len(simulation.theta_i)) if thetas is None else thetas)
    k0, n0 = simulation.realisations_or_one, simulation.rays_per_realisation
    ensemble = k0 > 1
    target = simulation.target_error
    done = Measurement({}, {}, [], Incidences.of(simulation, table, False))
    held: tuple[int, Tile, PeriodicScene] | None = None
    opener = Opener(tiles, threads, done)
    plan: dict[Direction, tuple[int, int]] = {}   # (realisations, rays of each new one)
    traced: dict[Direction, list[int]] = {}       # rays of each realisation traced
    batches = [0, 0]                              # of the measurement: done, planned
    try:
        while True:
            if not plan:  # the first round: the tile says whether it is isotropic
                held = opener.open(0)
                faces = len(held[1].faces)
                done.axes = Incidences.of(simulation, table, bool(held[1].facts.isotropic))
                plan = {(l, k): (k0, n0) for l in chosen
                        for k in range(len(done.axes.phi_deg))}
                traced = {d: [] for d in plan}
            work: dict[int, dict[Direction, int]] = {}
            for d, (k, n) in plan.items():
                if d in done.stops:
                    continue
                if ensemble:
                    for r in range(len(traced[d]), k):
                        work.setdefault(r, {})[d] = n
                elif n > sum(traced[d]):
                    work.setdefault(0, {})[d] = n - sum(traced[d])
            held = _trace_round(held, opener, sorted(work), work, materials, simulation,
                                table, done, plan, progress,
                                fold=ensemble and not keep_runs, traced=traced,
                                batches=batches)
            if target is None:
                break
            current = assemble_table([done], materials, simulation, table, thetas=chosen)
            rel, share = direction_errors(current)
            cost = _tile_cost(done, sum(d not in done.stops for d in plan), faces)
            for d in plan:
                if d in done.stops:
                    continue
                index = (chosen.index(d[0]), d[1])
                if rel[index] <= target:
                    done.stops[d] = "target_error"
                    continue
                nxt = next_plan(traced[d], float(rel[index]), float(share[index]),
                                simulation, cost)
                if isinstance(nxt, str):
                    done.stops[d] = nxt
                else:
                    plan[d] = nxt
            if len(done.stops) == len(plan):
                break
    finally:
        if held is not None:
            opener.release(held[2])
        opener.close()
    return done


TILE_SEGMENTS_PER_FACE = 0.34
"""The cost of opening a realisation (its tile's generation and facts, its scene's refit)
per face of the tile, in Embree segments traced: 8.6 ms for the 131,072 faces of the
shipped 256² Gaussian tile against 196 ns a segment of the kernel on the machine of
docs/performance.md (65.6 ns a face / 196 ns). A fixed ratio instead of this run's
seconds, so that the adaptive plan, and with it the table, does not depend on the
machine's speed or load."""


def _tile_cost(done: Measurement, directions: int, faces: int) -> float:
    """What a new realisation costs a direction, in rays of that direction: its tile's
    faces at ``TILE_SEGMENTS_PER_FACE`` over the segments a ray of this run has taken so
    far (counted, not timed), shared by the ``directions`` traced on each tile."""
    segments_per_ray = done.segments / max(done.rays, 1)
    return TILE_SEGMENTS_PER_FACE * faces / max(segments_per_ray, 1e-9) / max(directions, 1)


class Opener:
    """Opens the realisations a measurement traces and records them in it: the tile and
    scene of each, the next one prepared (``ahead``) on a thread of its own while the
    current one is traced, so that building it keeps no tracing thread waiting.

    Scenes are reused (``release`` hands one back): a scene's Embree BVH is built once,
    for realisation 0's tile, and refitted to each later realisation of the same topology
    (``PeriodicScene.update``; a Gaussian height field on its grid), so a realisation
    costs its tile and a refit, and its outcomes depend on nothing but its index (the
    BVH of any scene is realisation 0's, refitted). The tiles alive are realisation 0's,
    those of the scenes in use and the one prepared.

    Parameters
    ----------
    tiles : callable
        Realisation index → its tile (``Tiles``).
    threads : int or None
        Tracing threads of the scenes.
    done : Measurement
        Where each opened realisation is recorded (build time, tile count, facts,
        warnings, isotropy, the ray offset of realisation 0).
    """

    def __init__(self, tiles: Callable[[int], Tile], threads: int | None,
                 done: Measurement) -> None:
        self._tiles, self._threads, self._done = tiles, threads, done
        self._pool = ThreadPoolExecutor(1, thread_name_prefix="microsim-tiles")
        self._ahead: tuple[int, Future[tuple[Tile, PeriodicScene, float]]] | None = None
        self._first: Tile | None = None
        self._spare: list[PeriodicScene] = []

    def _build(self, r: int) -> tuple[Tile, PeriodicScene, float]:
        start = time.perf_counter()
        tile = self._tiles(r)
        if r == 0:
            self._first = tile
        if self._spare:
            scene = self._spare.pop()
            scene.update(tile)
        else:
            if self._first is None:
                self._first = self._tiles(0)
            scene = PeriodicScene(self._first, self._threads)
            if r != 0:
                scene.update(tile)
        return tile, scene, time.perf_counter() - start

    def open(self, r: int) -> tuple[int, Tile, PeriodicScene]:
        """Realisation r's tile and open scene (the one prepared, if it is r); hand the
        scene back with ``release``."""
        if self._ahead is not None and self._ahead[0] == r:
            tile, scene, seconds = self._ahead[1].result()
            self._ahead = None
        else:
            self._discard()
            tile, scene, seconds = self._build(r)
        done = self._done
        done.scene_time += seconds
        done.tiles += 1
        done.surfaces.setdefault(r, tile.facts)
        done.warnings += [w for w in tile.warnings if w not in done.warnings]
        if r == 0:
            done.offset = scene.eps
        return r, tile, scene

    def release(self, scene: PeriodicScene) -> None:
        """Take back a scene no longer traced in, for a later realisation (it lets go of
        its tile)."""
        scene.set_aside()
        self._spare.append(scene)

    def ahead(self, r: int) -> None:
        """Start preparing realisation r (the next ``open``)."""
        if self._ahead is None or self._ahead[0] != r:
            self._discard()
            self._ahead = (r, self._pool.submit(self._build, r))

    def _discard(self) -> None:
        """Take back a prepared realisation nobody opened."""
        if self._ahead is not None:
            future, self._ahead = self._ahead[1], None
            if not future.cancel() and future.exception() is None:
                self.release(future.result()[1])

    def close(self) -> None:
        """Close every scene it holds and stop the thread."""
        self._discard()
        self._pool.shutdown()
        for scene in self._spare:
            scene.close()
        self._spare, self._first = [], None


def _trace_round(held: tuple[int, Tile, PeriodicScene] | None, opener: Opener,
                 order: Sequence[int], work: Mapping[int, Mapping[Direction, int]],
                 materials: Mapping[str, Material], simulation: Simulation,
                 table: TableSettings, done: Measurement,
                 plan: Mapping[Direction, tuple[int, int]],
                 progress: Callable[[Progress], None] | None, *, fold: bool,
                 traced: dict[Direction, list[int]], batches: list[int]
                 ) -> tuple[int, Tile, PeriodicScene] | None:
    """Trace one round: realisations ``order`` with their ``work``, through one pipeline
    (``trace_realisations``), each realisation opened when its batches are first needed
    and the one after it prepared at once; each realisation's runs folded (``fold``) and
    its scene handed back when its last batch has been added. The scenes in use are those
    of the realisations with batches under way (one or two; up to ``DEPTH`` when
    realisations have fewer batches than the pipeline holds) and the one prepared.
    ``batches`` counts the measurement's batches done and planned (its two entries grow:
    by the round's batches when it starts, by one after each batch).

    Returns
    -------
    tuple or None
        The realisation still open: ``held`` when the round traced only it again (one
        realisation, whose rays grow in place), else None.
    """
    opened: dict[int, tuple[int, Tile, PeriodicScene]] = {}
    keep = held if held is not None and list(order) == [held[0]] and not fold else None
    pending = deque(order)

    def parts() -> Iterator[Part]:
        nonlocal held
        while pending:
            r = pending.popleft()
            if held is not None and held[0] == r:
                opened[r], held = held, None
            else:
                opened[r] = opener.open(r)
            if pending:
                opener.ahead(pending[0])
            yield Part(r, opened[r][2], work[r])

    def ended(part: Part, segments: int, inputs: list[TableInput]) -> None:
        r = part.realisation
        done.segments += segments
        done.inputs = inputs
        for d, n in work[r].items():
            if fold:
                traced[d].append(n)
                done.fold(RunKey(*d, r))
            elif len(traced[d]) <= r:
                traced[d].append(n)
            else:
                traced[d][r] += n
        if opened[r] is not keep:
            opener.release(opened.pop(r)[2])

    batches[1] += sum(-(-n // BATCH) for w in work.values() for n in w.values())

    def report(state: Progress) -> None:
        batches[0] += 1
        progress(replace(state, realisations=max(k for k, _ in plan.values()),
                         batches_done=batches[0], batches_planned=batches[1]))

    if held is not None and held[0] not in order:
        opener.release(held[2])
        held = None
    start = time.perf_counter()
    try:
        trace_realisations(parts(), materials, simulation, table, done.axes, done.runs,
                           progress=None if progress is None else report, ended=ended)
    except BaseException:
        for _, _, scene in opened.values():
            scene.close()
        raise
    done.trace_time += time.perf_counter() - start
    return keep


def assemble_table(parts: Sequence[Measurement], materials: Mapping[str, Material],
                   simulation: Simulation, table: TableSettings, *,
                   recipe: Recipe | None = None, wall_time: float | None = None,
                   thetas: Sequence[int] | None = None) -> BRDFTable:
    """The table of measurements that together trace every direction's realisations once.

    Parameters
    ----------
    parts : sequence of Measurement
        Of the same recipe, in any order (``measure_ensemble``, or
        ``measure_directions`` of single realisations, e.g. batch jobs). They are not
        changed.
    materials, simulation, table, recipe
        As for ``simulate``.
    wall_time : float or None
        Seconds the whole measurement took. Given, the metadata holds the timings
        (``wall_time``, ``scene_time``, ``rays_per_second``, ``segments_per_second``);
        None leaves them out, so the table depends on nothing but the recipe.
    thetas : sequence of int or None
        The polar angle indices the table holds (default: all of the parts' axes).

    Returns
    -------
    BRDFTable
        As ``simulate`` returns it. The same runs give the same table bit for bit, however
        they were split into parts: each direction's realisations are added in index
        order.

    Raises
    ------
    ValueError
        If a run appears twice, a polar angle is missing, or a direction's realisations
        are not 0, 1, ..., K − 1.
    """
    first = parts[0]
    axes = first.axes
    if any(part.axes != axes for part in parts):
        raise ValueError("the measurements do not share their incident directions and bins")
    summed = [part for part in parts if part.ensemble is not None]
    if len(summed) == 1 and not any(part.runs for part in parts):
        ensemble, energies = summed[0].ensemble, summed[0].energies  # read, not changed
    else:
        ensemble, energies = axes.new_ensemble(), {}
        for part in summed:
            ensemble.absorb(part.ensemble)
            energies.update({d: Energies(e.energy.copy(), dict(e.fates))
                             for d, e in part.energies.items()})
    runs: dict[RunKey, Run] = {}
    for part in parts:
        for key, run in part.runs.items():
            if key in runs:
                raise ValueError(f"direction {key[:2]} of realisation {key[2]} was traced "
                                 "twice")
            runs[key] = run
    surfaces = {r: facts for part in parts for r, facts in part.surfaces.items()}
    stops = {d: stop for part in parts for d, stop in part.stops.items()}
    theta_all, phi_deg = axes.theta_deg, axes.phi_deg
    chosen = list(range(len(theta_all)) if thetas is None else thetas)
    directions = [(l, k) for l in chosen for k in range(len(phi_deg))]
    folded = {d: len(ensemble.realisation_rays.get(d, ())) for d in directions}
    open_runs = {d: sorted(key.realisation for key in runs if key[:2] == d)
                 for d in directions}
    if any(open_runs[d] != list(range(folded[d], folded[d] + len(open_runs[d])))
           or folded[d] + len(open_runs[d]) < 1 for d in directions) or len(runs) != sum(
            map(len, open_runs.values())) or set(ensemble.realisation_rays) - set(directions):
        raise ValueError("the measurements do not trace every incident polar angle once "
                         "with realisations 0 .. K-1")
    for key in sorted(runs, key=lambda key: (key.realisation, key.theta, key.phi)):
        fold(ensemble, energies.setdefault(key[:2], Energies()), key, runs[key].sums)
    single = not any(folded.values()) and all(len(r) == 1 for r in open_runs.values())
    raw = raw_sums(runs, chosen, len(phi_deg), ensemble.components) if single else None
    result = from_ensemble(axes.bins, axes.theta_i[chosen], axes.phi_i, axes.isotropic,
                           ensemble.take(chosen),
                           TableMeta(), raw, table.channels)
    surface = None if recipe is None else recipe.surface
    seeds = [None if surface is None else realisation_seed(surface.seed, r)
             for r in sorted(surfaces)]
    rel, share = direction_errors(result)
    rays = int(result.rays.sum())
    segments = sum(part.segments for part in parts)
    records = tuple(_direction_record(ensemble.realisation_rays[d], energies[d],
                                      theta_all[d[0]], phi_deg[d[1]], stops.get(d, "rays"),
                                      rel[i, d[1]], share[i, d[1]], result.albedo[i, d[1]])
                    for i, l in enumerate(chosen) for d in directions if d[0] == l)
    timing = None
    if wall_time is not None:
        traced = sum(part.trace_time for part in parts)
        timing = Timing(wall_time, sum(part.scene_time for part in parts), rays / traced,
                        segments / traced)
    return replace(result, meta=TableMeta(
        recipe=recipe if recipe is not None else Recipe("", None, dict(materials),
                                                        simulation, table),
        microsim_version=__version__,
        surface=SurfaceFacts.pool([surfaces[r] for r in sorted(surfaces)], seeds),
        inputs=tuple(first.inputs), seed=int(simulation.seed), isotropic=axes.isotropic,
        error_model=result.error_model, realisations=int(result.realisations.max()),
        directions=records, stop=tuple(sorted({stops.get(d, "rays") for d in directions})),
        segments=segments, batch=BATCH,
        offset=next((p.offset for p in parts if 0 in p.surfaces), first.offset),
        tile_warnings=tuple(dict.fromkeys(w for part in parts for w in part.warnings)),
        warnings=tuple(lost_energy_warnings(records)), timing=timing,
        sources={} if not table.channels.spectral else {
            f"material.{part}.{k}": source for part, m in materials.items()
            for k, source in m.sources().items()}))


def raw_sums(runs: Mapping[RunKey, Run], chosen: Sequence[int], azimuths: int,
             components: Sequence[str]) -> RawSums:
    """The raw per-realisation sums of runs, as ``BRDFTable`` keeps them for a table of
    one realisation per direction (so that tables of independent rays merge:
    ``microsim.tables.assemble.merge``) and as studies of the realisations read them
    (``measure_ensemble(..., keep_runs=True)``): (K, a, b, ...) arrays, zero where a
    realisation did not trace a direction.

    Parameters
    ----------
    runs : mapping of RunKey to Run
    chosen : sequence of int
        The polar angle indices of the rows.
    azimuths : int
        Incident azimuths.
    components : sequence of str
        The components of the rows of the runs' sums.

    Returns
    -------
    RawSums
        ``realisation_rays`` (K, a, b) int, ``lost`` (K, a, b, C), per component
        ``sums`` and ``sums_sq`` (K, a, b, m, C), ``sh_sums`` and ``sh_sums_sq`` (or None).
    """
    rows = {l: i for i, l in enumerate(chosen)}
    some = next(iter(runs.values())).sums
    k = 1 + max(key.realisation for key in runs)

    def stacked(get: Callable[[Sums], Any]) -> np.ndarray:
        like = np.asarray(get(some))
        out = np.zeros((k, len(chosen), azimuths) + like.shape, like.dtype)
        for (l, kk, r), run in runs.items():
            out[r, rows[l], kk] = get(run.sums)
        return out

    harmonics = some.sh_order > 0
    names = ("sums", "sums_sq", "sh_sums", "sh_sums_sq")
    stacks = {name: stacked(attrgetter(name))                # (K, a, b, N + 1, ...)
              for name in names[:4 if harmonics else 2]}
    return RawSums(stacked(lambda acc: np.int64(acc.rays)),
                   stacked(lambda acc: acc.lost_energy),
                   {c: {name: stacks[name][:, :, :, j] if name in stacks else None
                        for name in names} for j, c in enumerate(components)})


def _direction_record(rays: Sequence[int], energies: Energies, theta: float, phi: float,
                      stop: str, rel: float, share: float, albedo: np.ndarray
                      ) -> DirectionRecord:
    """One direction's record from its realisations' rays and energies; energies are the
    mean over its realisations of each one's fraction per ray."""
    k = len(rays)
    lost, transmitted, absorbed = (tuple((row / k).tolist()) for row in energies.energy)
    return DirectionRecord(theta, phi, int(sum(rays)), k, tuple(rays), lost, transmitted,
                           absorbed, dict(energies.fates), stop, float(rel), float(share),
                           tuple(albedo.tolist()))


def simulate(tile: Tile, materials: Mapping[str, Material], simulation: Simulation,
             table: TableSettings, *, recipe: Recipe | None = None,
             threads: int | None = None, progress: Callable[[Progress], None] | None = None
             ) -> BRDFTable:
    """Measure one tile's BRDF table with the virtual goniophotometer.

    Parameters
    ----------
    tile : Tile
        The surface. ``tile.facts.isotropic`` says whether one incident azimuth (0)
        suffices; otherwise every ``simulation.phi_i`` is measured.
    materials : mapping
        Resolved ``[material]``: one section per part of the tile.
    simulation : mapping
        Resolved ``[simulation]``: ``theta_i``, ``phi_i`` (degrees), ``rays``,
        ``bounces``, ``seed``, and optionally ``target_error`` and ``max_rays``.
        ``realisations`` is taken as 1: the table is that of the given tile, all
        ``rays`` on it (``simulate_surface`` averages realisations).
    table : mapping
        Resolved ``[table]``: ``theta_bins``, ``phi_bins``, and optionally ``sh_order``
        (spherical-harmonic order of the escaping rays' moments; 0 or absent: none).
    recipe : mapping or None
        The full resolved recipe, stored in the table's metadata (default: the three
        sections given).
    threads : int or None
        Tracing threads (default: every CPU). The result does not depend on it.
    progress : callable or None
        Called after every batch with a dict: ``theta_i``, ``phi_i`` (degrees),
        ``realisation``, ``realisations`` (planned so far), ``rays`` (so far, this
        direction and realisation).

    Returns
    -------
    BRDFTable
        Sums per bin for the components ``"total"`` and ``"single"`` (first-order
        scattering), error model ``rays``, with metadata (see docs/goniometer.md; the
        stored recipe says ``realisations = 1``).
    """
    one = replace(simulation, realisations=1, max_realisations=None)
    if recipe is not None:
        recipe = replace(recipe, simulation=one)
    return _simulate(Tiles(tile=tile), materials, one, table, recipe, threads, progress)


def simulate_surface(surface: Surface, materials: Mapping[str, Material],
                     simulation: Simulation, table: TableSettings, *,
                     recipe: Recipe | None = None, threads: int | None = None,
                     progress: Callable[[Progress], None] | None = None,
                     memory_limit_gib: float | None = None) -> BRDFTable:
    """The table of a surface: the mean over ``simulation.realisations`` tiles.

    As ``simulate``, with ``surface`` a resolved ``[surface]`` section whose realisations
    are built one at a time (each under the memory guard's ``memory_limit_gib``).
    Direction (l, k) of realisation r runs batches of ``BATCH`` rays; batch b draws from
    ``SeedSequence(seed, spawn_key=(l, k, r, b))``, so the numbers depend on neither the
    thread count nor the order of work. With
    ``target_error``, rounds of rays and realisations are added until every direction's
    median relative error over its lobe bins is at most the target or a cap is reached
    (``measure_ensemble``; the metadata says which).
    """
    if recipe is None:
        recipe = Recipe("", surface, dict(materials), simulation, table)
    return _simulate(Tiles(surface, memory_limit_gib=memory_limit_gib), materials, simulation,
                     table, recipe, threads, progress)


def _simulate(tiles: Tiles, materials: Mapping[str, Material], simulation: Simulation,
              table: TableSettings, recipe: Recipe | None, threads: int | None,
              progress: Callable[[Progress], None] | None) -> BRDFTable:
    """Measure every realisation ``tiles`` builds and assemble the table, timed."""
    start = time.perf_counter()
    measured = measure_ensemble(tiles, materials, simulation, table, threads=threads,
                                progress=progress)
    return assemble_table([measured], materials, simulation, table, recipe=recipe,
                          wall_time=time.perf_counter() - start)


def simulate_recipe(recipe: Recipe, progress: Callable[[Progress], None] | None = None,
                    threads: int | None = None,
                    memory_limit_gib: float | None = None) -> BRDFTable:
    """Measure a resolved recipe's surface (all its realisations; see
    ``simulate_surface``)."""
    return simulate_surface(recipe.surface, recipe.material, recipe.simulation,
                            recipe.table, recipe=recipe, threads=threads,
                            progress=progress, memory_limit_gib=memory_limit_gib)
