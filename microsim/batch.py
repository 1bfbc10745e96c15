"""Batch runs of a sweep on Dask: jobs, merging, the manifest, resuming.

A sweep point is one table; its incident polar angles are cut into jobs of
``Sweep.thetas_per_job`` angles, and each job traces one realisation of the surface
(``microsim.measurement.goniometer.measure_directions``), so the realisations of one
table run on as many workers as there are. With ``simulation.target_error`` a job traces
its angles over all the realisations its adaptive stop asks for
(``microsim.measurement.simulation.measure_ensemble``).
The client merges a table's jobs with ``assemble_table`` and writes it. Direction (l, k) of
realisation r draws its batches from ``SeedSequence(seed, spawn_key=(l, k, r, b))``
whichever job traces it, and the merge combines realisations in index order, so a table is
the same, bit for bit, whatever the number of workers, the job size or the order of
completion, and equals ``simulate_recipe`` of the point's recipe (without the timings,
which go to the manifest).

``DIR/manifest.json`` records every table (status, recipe hash, seed, rays, times, error
metrics, error message) and is replaced atomically after every change; tables are written
atomically too. docs/batch.md describes the format and the resuming rules.
"""

from __future__ import annotations

import contextlib
import fcntl
import functools
import json
import os
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from microsim.errors import InputError
from microsim.files import atomic_path, remove_stale_temporaries, replaceable
from microsim.measurement.goniometer import Measurement, measure_directions
from microsim.measurement.scene import PeriodicScene
from microsim.measurement.simulation import Tiles, assemble_table, measure_ensemble
from microsim.pages import keep_pages
from microsim.settings import Recipe
from microsim.surfaces import Surface, build_tile
from microsim.surfaces.realisations import realisation as realisation_of
from microsim.surfaces.tile import Tile
from microsim.sweep import Point, Sweep
from microsim.tables.exr import read_table, write_table
from microsim.version import __version__

if TYPE_CHECKING:
    from distributed import Client

MANIFEST = "manifest.json"
LOCK = ".batch.lock"
RETRIES = 1
"""Times a job that raised is run again before its table is marked failed."""


TILES_KEPT = 2
"""Tiles a worker process keeps (the most recently used), so that a surface is generated
once per worker while its tables run."""
_scenes = threading.local()


@functools.lru_cache(maxsize=TILES_KEPT)
def _tile(surface: Surface) -> Tile:
    """The tile of a surface section (a frozen record, so a key), built once per worker
    process."""
    return build_tile(surface)


def _scene(surface: Surface, realisation: int, threads: int
           ) -> tuple[Tile, PeriodicScene]:
    """Realisation ``realisation``'s tile of a surface section and an open Embree scene
    of it, kept per worker thread (a scene is used by one job at a time) until another
    surface needs one. As in ``microsim.measurement.simulation.Opener``, the scene is built for
    realisation 0's tile and updated (its BVH refitted) to the others, so a job traces
    exactly what one ``simulate`` of all realisations does."""
    base = realisation_of(surface, 0)
    key = (base, threads)
    kept = getattr(_scenes, "kept", None)
    if kept is not None and kept[0] != key:
        kept[2].close()
        kept = _scenes.kept = None
    if kept is None:
        first = _tile(base)
        kept = _scenes.kept = [key, first, PeriodicScene(first, threads)]
    tile = _tile(realisation_of(surface, realisation))
    if kept[1] is not tile:
        kept[2].update(tile)
        kept[1] = tile
    return tile, kept[2]


def run_job(recipe: Recipe, thetas: tuple[int, ...], threads: int = 1,
            realisation: int | None = 0) -> tuple[Measurement, list[str], float]:
    """Trace some incident polar angles of a resolved recipe (runs on a worker).

    Parameters
    ----------
    recipe : Recipe
        A resolved recipe.
    thetas : tuple of int
        Indices into ``recipe.simulation.theta_i``.
    threads : int
        Tracing threads.
    realisation : int or None
        The surface realisation to trace, with ``rays / realisations`` rays per direction;
        None: every realisation the recipe's adaptive stop asks for, tile after tile.

    Returns
    -------
    measurement : Measurement
    warnings : list of str
        The tiles' warnings.
    seconds : float
        Wall-clock time of the job on the worker, building the tiles included.
    """
    start = time.perf_counter()
    keep_pages()  # as ``measure_ensemble`` does (``microsim.pages``)
    sim = recipe.simulation
    if realisation is None:
        measured = measure_ensemble(Tiles(recipe.surface), recipe.material, sim,
                                    recipe.table, thetas, threads=threads)
        return measured, measured.warnings, time.perf_counter() - start
    tile, scene = _scene(recipe.surface, realisation, threads)
    measured = measure_directions(tile, recipe.material, sim, recipe.table, thetas,
                                  realisation=realisation, scene=scene)
    return measured, list(tile.warnings), time.perf_counter() - start


@dataclass(frozen=True)
class Job:
    """One unit of work: a table's name, the indices of the polar angles it traces, and the
    realisation (None: all of them, adaptively)."""

    table: str
    thetas: tuple[int, ...]
    realisation: int | None = 0


def jobs_of(point: Point, thetas_per_job: int) -> list[Job]:
    """A point's jobs: its incident polar angles in chunks of ``thetas_per_job``, for each
    realisation (one job per chunk for all of them with an adaptive stop)."""
    sim = point.recipe.simulation
    n = len(sim.theta_i)
    chunks = [tuple(range(i, min(i + thetas_per_job, n))) for i in range(0, n, thetas_per_job)]
    if sim.target_error is not None:
        return [Job(point.name, chunk, None) for chunk in chunks]
    return [Job(point.name, chunk, r) for r in range(sim.realisations_or_one)
            for chunk in chunks]


_locked: set[Path] = set()
"""Folders whose lock this process holds (``output_lock`` nests)."""


@contextlib.contextmanager
def output_lock(folder: Path) -> Iterator[None]:
    """Hold ``folder/.batch.lock``: one batch at a time writes a folder. The command line
    takes it before it starts a cluster; ``run_batch`` inside it holds it already.

    A run that fails (a refused scheduler, an interruption) removes the lock it made: a
    refused batch leaves no file behind. A batch that opened a lock file removed
    meanwhile finds another file (or none) at the path and is refused as if the folder
    were locked."""
    folder.mkdir(parents=True, exist_ok=True)
    key = folder.resolve()
    if key in _locked:
        yield
        return
    path = folder / LOCK
    made_lock = not path.exists()
    with open(path, "a") as handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
            if os.stat(path).st_ino != os.fstat(handle.fileno()).st_ino:
                raise BlockingIOError
        except (BlockingIOError, FileNotFoundError):
            raise InputError(f"{folder}: another batch is writing this folder") from None
        _locked.add(key)
        try:
            yield
        except BaseException:
            if made_lock:
                path.unlink(missing_ok=True)
            raise
        finally:
            _locked.discard(key)


def read_manifest(folder: Path) -> dict[str, Any]:
    """The manifest's table entries by name (empty when there is none)."""
    path = folder / MANIFEST
    if not path.exists():
        return {}
    try:
        tables = json.loads(path.read_text(encoding="utf-8"))["tables"]
        if not isinstance(tables, dict) or not all(isinstance(t, dict)
                                                   for t in tables.values()):
            raise TypeError
        return tables
    except (json.JSONDecodeError, KeyError, TypeError, UnicodeDecodeError, RecursionError):
        raise InputError(f"{path}: not a batch manifest; move it away or use "
                         "--no-resume") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read: {exc.strerror or exc}") from None


def check_folder(folder: Path, sweep: Sweep, resume: bool, flag: str = "--output") -> None:
    """Refuse, before a cluster starts, a batch folder it could not finish in: its lock,
    its manifest and every point's table must be files that can be replaced where they
    exist (``microsim.files.replaceable``; a folder or an immutable file under one of
    those names stopped the run when the first table was done), and when resuming, the
    manifest must read as one (``read_manifest``).

    Raises
    ------
    InputError
    """
    for name in (LOCK, MANIFEST, *(f"{p.name}.exr" for p in sweep.points)):
        replaceable(folder / name, flag)
    if resume:
        read_manifest(folder)


class Manifest:
    """``DIR/manifest.json``: the sweep and one entry per table, replaced atomically.

    Parameters
    ----------
    folder : Path
    sweep : Sweep
    entries : dict of str to dict
        The table entries to start from.
    """

    def __init__(self, folder: Path, sweep: Sweep, entries: dict[str, Any]) -> None:
        self.path = folder / MANIFEST
        self.head = {"sweep": str(sweep.path.resolve()), "description": sweep.description,
                     "seed": sweep.seed,
                     "thetas_per_job": sweep.thetas_per_job,
                     "microsim_version": __version__}
        self.tables = entries

    def update(self, name: str, **fields: Any) -> None:
        """Change a table's entry and rewrite the file."""
        self.tables[name] = {**self.tables.get(name, {}), **fields}
        self.write()

    def write(self) -> None:
        """Replace the file with the current state (temporary file + rename)."""
        with atomic_path(self.path) as tmp:
            tmp.write_text(json.dumps({**self.head, "tables": self.tables}, indent=1,
                                      allow_nan=False, default=float) + "\n",
                           encoding="utf-8")


def _finite(x: float) -> float | None:
    """``x``, or None where it is not finite (the manifest is strict JSON)."""
    return x if x == x and abs(x) != float("inf") else None


def _reads(path: Path) -> bool:
    """Whether ``path`` is a table ``read_table`` reads whole (harmonics included): a
    table the manifest calls done but whose file was truncated or edited is made again."""
    try:
        read_table(path, require_sh=True)
    except InputError:
        return False
    return True


@dataclass(frozen=True)
class BatchProgress:
    """How far a batch is, after one more finished job (``run_batch``'s ``progress``).

    Attributes
    ----------
    tables_done, tables : int
        Tables done (kept from the manifest, computed or failed), of the sweep's.
    jobs_done, jobs : int
        Jobs finished (or cancelled with their table), of those submitted.
    rays : int
        Rays traced in this run.
    elapsed : float
        Seconds since the run started.
    """

    tables_done: int
    tables: int
    jobs_done: int
    jobs: int
    rays: int
    elapsed: float


@dataclass(frozen=True)
class BatchSummary:
    """What a batch did (``run_batch``).

    Attributes
    ----------
    output : str
        The batch folder.
    tables : int
        Tables of the sweep.
    computed, skipped : list of str
        Names of the tables computed in this run, in the order they were done, and of
        those the manifest held as done, sorted.
    failed : dict of str to str
        Per table that failed, its error.
    jobs : int
        Jobs submitted.
    rays : int
        Rays traced in this run.
    wall_s : float
        Seconds the run took.
    """

    output: str
    tables: int
    computed: list[str]
    skipped: list[str]
    failed: dict[str, str]
    jobs: int
    rays: int
    wall_s: float

    def to_json(self) -> dict[str, Any]:
        """As ``microsim batch --json`` prints it: ``failed`` a list of ``table`` and
        ``error``."""
        return {"output": self.output, "tables": self.tables, "computed": self.computed,
                "skipped": self.skipped, "failed": [{"table": n, "error": e}
                                                    for n, e in self.failed.items()],
                "jobs": self.jobs, "rays": self.rays, "wall_s": self.wall_s}


def run_batch(sweep: Sweep, folder: str | Path, client: Client, *, resume: bool = True,
              threads: int = 1, progress: Callable[[BatchProgress], None] | None = None
              ) -> BatchSummary:
    """Run a sweep on a Dask client; write ``folder/<point>.exr`` and the manifest.

    Parameters
    ----------
    sweep : Sweep
        A loaded sweep (every point resolved).
    folder : str or Path
        Output folder, created if missing.
    client : distributed.Client
        Where jobs run; workers must be able to import microsim.
    resume : bool
        Skip tables the manifest lists as done with the same recipe hash whose file
        reads as a whole table; False recomputes every table.
    threads : int
        Tracing threads per job.
    progress : callable or None
        Called after every finished job with a ``BatchProgress``.

    Returns
    -------
    BatchSummary
    """
    from distributed import as_completed

    folder = Path(folder)
    start = time.perf_counter()
    with output_lock(folder):
        remove_stale_temporaries(folder)
        old = read_manifest(folder) if resume else {}
        keep = {p.name: old[p.name] for p in sweep.points
                if p.name in old and old[p.name].get("status") == "done"
                and old[p.name].get("recipe_hash") == p.hash
                and _reads(folder / f"{p.name}.exr")}
        todo = [p for p in sweep.points if p.name not in keep]
        manifest = Manifest(folder, sweep, {
            p.name: keep.get(p.name) or {
                "file": f"{p.name}.exr", "status": "pending", "recipe_hash": p.hash,
                "seed": p.recipe.simulation.seed, "point": p.values}
            for p in sweep.points})
        manifest.write()
        points = {p.name: p for p in todo}
        jobs = {p.name: jobs_of(p, sweep.thetas_per_job) for p in todo}
        futures = {}
        for name, table_jobs in jobs.items():
            for job in table_jobs:
                key = (f"microsim-{name}-{job.thetas[0]}-{job.realisation}-"
                       f"{os.urandom(4).hex()}")
                future = client.submit(run_job, points[name].recipe, job.thetas, threads,
                                       job.realisation, key=key, pure=False,
                                       retries=RETRIES)
                futures[future] = job
        parts: dict[str, list[Any]] = {name: [] for name in jobs}
        warnings: dict[str, list[str]] = {name: [] for name in jobs}
        job_time = dict.fromkeys(jobs, 0.0)
        failed: dict[str, str] = {}
        computed: list[str] = []
        rays = jobs_done = 0
        for future in as_completed(list(futures)):
            job = futures[future]
            jobs_done += 1
            if job.table in failed:
                pass  # cancelled with its table
            elif future.status != "finished":
                exc = future.exception()
                failed[job.table] = f"{type(exc).__name__}: {exc}"
                manifest.update(job.table, status="failed", error=failed[job.table])
                for other, other_job in futures.items():
                    if other_job.table == job.table:
                        other.cancel()
            else:
                measured, tile_warnings, seconds = future.result()
                future.release()
                parts[job.table].append(measured)
                warnings[job.table] = list(dict.fromkeys(warnings[job.table]
                                                         + tile_warnings))
                job_time[job.table] += seconds
                rays += measured.rays
                if len(parts[job.table]) == len(jobs[job.table]):
                    computed.append(job.table)
                    _finish(folder, manifest, points[job.table], parts.pop(job.table),
                            warnings[job.table], job_time[job.table])
            if progress is not None:
                progress(BatchProgress(len(keep) + len(computed) + len(failed),
                                       len(sweep.points), jobs_done, len(futures), rays,
                                       time.perf_counter() - start))
    return BatchSummary(str(folder), len(sweep.points), computed, sorted(keep), failed,
                        len(futures), rays, time.perf_counter() - start)


def _finish(folder: Path, manifest: Manifest, point: Point, parts: list[Measurement],
            warnings: list[str], seconds: float) -> None:
    """Merge a table's jobs, write the table, then record it as done (``seconds``: the
    jobs' summed wall-clock time on the workers)."""
    recipe = point.recipe
    table = assemble_table(parts, recipe.material, recipe.simulation, recipe.table,
                           recipe=recipe)
    write_table(table, folder / f"{point.name}.exr")
    manifest.update(
        point.name, status="done", error=None, rays=int(table.rays.sum()),
        segments=int(table.meta.segments), jobs=len(parts), wall_s=seconds,
        trace_s=sum(p.trace_time for p in parts),
        median_rel_stderr=_finite(table.median_rel_stderr("total")),
        error_model=table.error_model, realisations=int(table.realisations.max()),
        albedo=table.albedo.reshape(-1, table.channels.count).mean(axis=1).tolist(),
        albedo_err=table.albedo_err.reshape(-1, table.channels.count).mean(axis=1).tolist(),
        warnings=[*warnings, *table.meta.warnings])
