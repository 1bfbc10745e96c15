"""Speed against error: reference cases with trusted answers, swept over rays, tile
resolution and table resolution, timed next to bare Embree on the same tiles.

Cases (each returns rows of a CSV):

- ``ts``: Gaussian α = 0.3, mirror facets; error = median relative error of single
  scattering against Torrance-Sparrow + Beckmann + height-correlated Smith at the realised α
  over lobe bins (``compare.compare_table``).
- ``g1``: Gaussian α = 0.5; error = mean |G1 − Smith| at θ = 60, 80, 88° (absolute).
- ``vgroove``: 45° V-grooves; error = mean |G1 − V-cavity G1| across the grooves at
  θ = 30, 60, 80° (absolute; Heitz 2014, sec. 4.1).
- ``furnace``: Gaussian α = 0.5, mirror facets, F = 1, 64 bounces; error = mean
  1 − albedo over θi: the energy that did not come back (leaks, the bounce limit), which
  a closed microsurface of lossless facets does not have.
- ``ms``: Gaussian α = 0.6 (256², where a tenth of the light scatters twice), mirror
  facets, 32 bounces; error = median relative error of all orders (``total``) against
  Heitz et al. 2016's multiple-scattering Smith microsurface (``beckmann-ms``) at the
  realised α over lobe bins; stderr = the median over the same bins of the relative
  standard error of the difference (table and model, whose random walks are drawn once
  per sweep, ``FrozenBins``, so every ray count is scored against the same estimate).

Gaussian tiles keep 32 correlation lengths per side whatever their resolution, so the
resolution sweep changes only how finely each correlation length is tessellated
(2, 4, 8, … cells): the bias floor it sets is what the second plot shows.

Every row also times bare ``EmbreeScene.run`` on the same tile, with the same threads and
chunks, on incoherent rays from the surface (``surface_rays``): ``ratio`` is the traced
segments per second (scene build excluded) over those rays per second.
"""

from __future__ import annotations

import csv
import math
import os
import statistics
import subprocess
import tempfile
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import astuple, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from embreex.mesh_construction import TriangleMesh
from embreex.rtcore_scene import EmbreeScene

from microsim.analytic.multiple_scattering import SmithMultipleScattering
from microsim.analytic.ndf import Beckmann
from microsim.analytic.shadowing import vcavity_G1
from microsim.comparison.metrics import compare_table, lobe_residuals
from microsim.comparison.table_models import microfacet_model
from microsim.files import atomic_path
from microsim.geometry import direction
from microsim.kernel.packing import FacetMaterials
from microsim.materials import Lambertian
from microsim.measurement.masking import measure_g1, sample_faces
from microsim.measurement.scene import PeriodicScene
from microsim.measurement.simulation import simulate
from microsim.plots.layout import save
from microsim.recipe import resolve
from microsim.schema import Toml
from microsim.surfaces import Tile, build_tile

COLUMNS = ("case", "rays", "tile_resolution", "cells_per_correlation", "table_bins",
           "wall_s", "segments", "segments_per_s", "bare_rays_per_s", "ratio", "error",
           "stderr")
LENGTHS = 32
"""Correlation lengths per tile side in every Gaussian case."""
MS_RESOLUTION = 256
"""Tile resolution of the ``ms`` case (8 cells per correlation length)."""
MS_SAMPLES = {True: 4096, False: 16384}
"""Random walks per bin of the ``ms`` case's model, quick and full: its relative error
in a lobe bin stays below the table's at the sweep's most rays."""


PARTS = (("microsim.measurement.scene", "trace_chunk", "the kernel (trace_chunk)"),
         ("microsim.measurement.paths", "summarise", "summaries of outcomes"),
         ("microsim.measurement.goniometer", "bin_escapes", "binning"),
         ("microsim.measurement.goniometer", "gather_rows", "rays grouped by order row"),
         ("microsim.tables.sh", "_distinct", "equal weight columns found"),
         ("microsim.tables.sh", "_reduced", "principal components"),
         ("microsim.tables.sh", "_transform", "harmonic transforms (ducc0)"),
         ("microsim.measurement.goniometer.Sums", "tally", "a batch's tally in all"),
         ("microsim.measurement.goniometer", "beam_origins", "start points of the beam"),
         ("microsim.measurement.goniometer.Sums", "add_tally", "adding tallies"),
         ("microsim.measurement.goniometer.Measurement", "fold", "folding realisations"),
         ("microsim.measurement.simulation.Opener", "_build", "tiles and scenes (beside)"),
         ("microsim.measurement.simulation", "assemble_table", "assembling tables"))
"""The parts ``part_times`` times: (module or class, function, label)."""
_SPENT: dict[str, float] | None = None


def part_times() -> dict[str, float]:
    """CPU time (``time.thread_time`` of the thread that ran it) of each of ``PARTS``,
    summed over the threads, from this call on: every part's function is wrapped once per
    process (a module's, or a module's class's, capitalised), and the dict returned is
    the one they add to (``timed_run`` sets it to zero before its run)."""
    global _SPENT
    if _SPENT is not None:
        return _SPENT
    import importlib
    import threading

    spent: dict[str, float] = dict.fromkeys((label for _, _, label in PARTS), 0.0)
    lock = threading.Lock()

    def timed(fn: Any, label: str) -> Any:
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            start = time.thread_time()
            try:
                return fn(*args, **kwargs)
            finally:
                with lock:
                    spent[label] += time.thread_time() - start
        return wrapper

    for where, name, label in PARTS:
        names = where.split(".")
        owner: Any = importlib.import_module(".".join(n for n in names if n[0].islower()))
        for n in names:
            if n[0].isupper():
                owner = getattr(owner, n)
        setattr(owner, name, timed(getattr(owner, name), label))
    _SPENT = spent
    return spent


def timed_run(recipe: Any, threads: int) -> tuple[dict[str, float], float, float, Any]:
    """One in-process ``simulate_recipe``: the CPU time of each of ``PARTS`` in it
    (``part_times``, from zero), its wall and CPU time (s), and its table."""
    from microsim.measurement.simulation import simulate_recipe

    spent = part_times()
    spent.update(dict.fromkeys(spent, 0.0))
    cpu, start = time.process_time(), time.perf_counter()
    table = simulate_recipe(recipe, threads=threads)
    wall, cpu = time.perf_counter() - start, time.process_time() - cpu
    return dict(spent), wall, cpu, table


def bare_scene(vertices: np.ndarray, faces: np.ndarray) -> Any:
    """A bare Embree scene of the mesh, committed (the first query builds the BVH)."""
    scene = EmbreeScene()
    TriangleMesh(scene, np.ascontiguousarray(vertices, np.float32),
                 np.ascontiguousarray(faces, np.int32))
    scene.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32))
    return scene


def median_time(fn: Callable[[], object], repeats: int) -> float:
    """Median wall time in seconds of ``repeats`` calls of ``fn`` (the machine is shared:
    the median, not the mean, resists the odd slow run)."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def bare_rays_per_second(scene: Any, origins: np.ndarray, dirs: np.ndarray,
                         threads: int) -> float:
    """Closest-hit queries per second of bare ``EmbreeScene.run`` on float32 rays: one call
    per thread on its share of the rays, the distances made beforehand (Embree's best case:
    no Python between queries)."""
    o32, d32 = origins.astype(np.float32), dirs.astype(np.float32)
    share = -(-len(o32) // threads)
    starts = range(0, len(o32), share)
    dists = [np.full(len(o32[i:i + share]), 1e30, np.float32) for i in starts]
    with ThreadPoolExecutor(threads) as pool:
        start = time.perf_counter()
        list(pool.map(lambda k: scene.run(o32[starts[k]:starts[k] + share],
                                          d32[starts[k]:starts[k] + share], dists=dists[k]),
                      range(len(starts))))
        return len(o32) / (time.perf_counter() - start)


@dataclass(frozen=True)
class ChildRun:
    """A command run to its end (``run_child``): its standard output, wall and CPU
    seconds (user + system) and peak resident memory in GiB."""

    stdout: str
    wall: float
    cpu: float
    peak_gib: float


def run_child(argv: list[str]) -> ChildRun:
    """Run a command as a child process and measure it (``os.wait4``'s usage of that
    child alone).

    Raises
    ------
    RuntimeError
        If it exits with a non-zero status (with the last line it wrote to stderr).
    """
    start = time.perf_counter()
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        process = subprocess.Popen(argv, stdout=out, stderr=err)
        _, status, usage = os.wait4(process.pid, 0)
        wall = time.perf_counter() - start
        if status != 0:
            err.seek(0)
            said = err.read().decode(errors="replace").strip().splitlines()
            raise RuntimeError(f"{' '.join(argv)} failed with wait status {status}"
                               + (f": {said[-1]}" if said else ""))
        out.seek(0)
        return ChildRun(out.read().decode(), wall, usage.ru_utime + usage.ru_stime,
                        usage.ru_maxrss / 2**20)


def surface_rays(scene: PeriodicScene, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Incoherent rays from the surface, the reference bare Embree is timed on: points
    uniform over the faces' area, offset ``eps`` off their face, towards directions
    cosine-distributed about the face's normal (the rays a Lambertian surface sends, drawn
    by the kernel's own Lambertian event).

    Parameters
    ----------
    scene : PeriodicScene
    n : int
        Rays.
    seed : int

    Returns
    -------
    origins, dirs : (n, 3) float
    """

    faces, points = sample_faces(scene.tile, scene.areas, n, np.random.default_rng(seed))
    lambert = FacetMaterials(np.zeros(len(scene.areas), np.int64), ("surface",),
                             {"surface": Lambertian(albedo=(1.0, 1.0, 1.0))})
    normals = scene.normals[faces]
    dirs, _, _ = lambert.scatter(faces, -normals, normals, np.random.SeedSequence(seed))
    return scene.offset(points, normals, dirs), dirs


def gaussian(alpha: float, resolution: int, seed: int) -> dict[str, Toml]:
    """A Gaussian ``[surface]`` with ``LENGTHS`` correlation lengths per side."""
    return {"kind": "gaussian", "alpha": alpha, "resolution": resolution, "seed": seed,
            "correlation_length": 1.0 / LENGTHS}


@dataclass(frozen=True)
class Run:
    """One run of a case, scored (``run_tables``, ``g1_rows``).

    Attributes
    ----------
    case : str
        ``"ts"``, ``"g1"``, ``"vgroove"``, ``"furnace"`` or ``"ms"``.
    rays : int
        Rays over all incident directions.
    tile_resolution : int
        Cells per side of a Gaussian tile (0: the V-grooves).
    table_bins : int
        θo bins of the table (0: a G1 case, no table).
    wall_s : float
        Wall time of the trace, seconds.
    segments : int
        Ray segments traced.
    segments_per_s : float
        Of the trace (a table's: scene build excluded).
    error, stderr : float
        The case's error and standard error (the module's list of cases).
    """

    case: str
    rays: int
    tile_resolution: int
    table_bins: int
    wall_s: float
    segments: int
    segments_per_s: float
    error: float
    stderr: float


@dataclass(frozen=True)
class Row(Run):
    """A run with bare Embree timed on its tile: a row of the CSV (``COLUMNS``).

    Attributes
    ----------
    bare_rays_per_s : float
        Closest-hit queries per second of bare Embree on rays from the same tile
        (``bare_rays_per_second``, median of 3).
    """

    bare_rays_per_s: float

    @property
    def ratio(self) -> float:
        """Traced segments per second over bare Embree's rays per second."""
        return self.segments_per_s / self.bare_rays_per_s

    @property
    def cells_per_correlation(self) -> float:
        """Tile cells per correlation length (``LENGTHS`` per side)."""
        return self.tile_resolution / LENGTHS


def run_tables(case: str, surface: dict[str, Toml], material: str, theta: list[float],
               rays: int, bins: int, bounces: int, seed: int,
               score: Callable[[Any], tuple[float, float]]) -> tuple[Run, Tile]:
    """Simulate one table and score it: the run and its tile."""
    r = resolve({"surface": surface, "material": {"kind": material},
                 "simulation": {"theta_i": theta, "rays": rays, "bounces": bounces,
                                "seed": seed},
                 # the bins only: the harmonics' cost is measured by scripts/sh_cost.py
                 "table": {"theta_bins": bins, "phi_bins": 2 * bins, "sh_order": 0}})
    tile = build_tile(r.surface)
    start = time.perf_counter()
    table = simulate(tile, r.material, r.simulation, r.table, recipe=r)
    wall = time.perf_counter() - start
    error, stderr = score(table)
    return Run(case, rays * len(theta), surface.get("resolution", 0), bins, wall,
               table.meta.segments, table.meta.timing.segments_per_second, error,
               stderr), tile


def score_ts(table: Any) -> tuple[float, float]:
    """Median relative lobe error against the microfacet model; median relative stderr."""
    result = compare_table(table, microfacet_model(table.meta), "single")
    return result.median_rel_error, table.median_rel_stderr("single")


class FrozenBins:
    """A Monte Carlo model whose bin averages, once drawn, are kept: every table of a
    sweep is scored against the same estimate (``compare.bin_estimate`` takes it as it
    takes the model).

    Parameters
    ----------
    model : SmithMultipleScattering
        Holding every order (its exact part is order 1).
    """

    def __init__(self, model: Any) -> None:
        self.model, self.exact = model, model.exact
        self.drawn: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}

    def eval(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """The model's f_r (fresh walks), 1/sr."""
        return self.model.eval(wi, wo)

    def random_bin_average(self, wi: np.ndarray, theta_edges: np.ndarray,
                           phi_edges: np.ndarray, phi_i: float = 0.0
                           ) -> tuple[np.ndarray, np.ndarray]:
        """``SmithMultipleScattering.random_bin_average``, drawn at the first call with
        these arguments and returned as drawn after."""
        key = (tuple(np.asarray(wi, float)), tuple(theta_edges), tuple(phi_edges), phi_i)
        if key not in self.drawn:
            self.drawn[key] = self.model.random_bin_average(wi, theta_edges, phi_edges,
                                                            phi_i)
        return self.drawn[key]


def score_ms(table: Any, model: FrozenBins) -> tuple[float, float]:
    """Median relative lobe error of the total against the model; the median over the
    same bins of √(σ_table² + σ_model²) / model."""
    result = compare_table(table, model, "total")
    noise = []
    for (a, b), _ in np.ndenumerate(table.rays):
        avg, avg_err = result.model[a, b], result.model_err[a, b]
        err = np.nan_to_num(table["total"].errors[a, b], nan=np.inf)
        _, _, lobe = lobe_residuals(table["total"].values[a, b], err, avg, avg_err)
        noise.append(np.hypot(err, avg_err)[lobe] / avg[lobe])
    return result.median_rel_error, float(np.median(np.concatenate(noise)))


def score_furnace(table: Any) -> tuple[float, float]:
    """Mean 1 − albedo over θi (the lost energy of a lossless furnace); mean albedo
    standard error."""
    return float((1.0 - table.albedo).mean()), float(np.nanmean(table.albedo_err))


def g1_rows(case: str, tile: Tile, resolution: int, theta: list[float], rays: int,
            reference: np.ndarray, seed: int) -> tuple[Run, Tile]:
    """Trace G1 at ``theta`` (degrees, φ = 0) and score it against ``reference``: the run
    and its tile."""
    with PeriodicScene(tile) as scene:
        start = time.perf_counter()
        g1, err = measure_g1(scene, np.radians(theta), 0.0, rays,
                             np.random.default_rng(seed))
        wall = time.perf_counter() - start
        segments = scene.segments
    return Run(case, rays * len(theta), resolution, 0, wall, segments, segments / wall,
               float(np.abs(g1 - reference).mean()), float(err.mean())), tile


def vcavity_reference(slope: float, theta: np.ndarray) -> np.ndarray:
    """G1 of symmetric V-grooves across the grooves: the V-cavity G1 of each facet
    (``analytic.shadowing.vcavity_G1``) averaged with weight area · ⟨ω, m⟩⁺."""

    w = direction(theta, 0.0)
    num = den = 0.0
    for sign in (1.0, -1.0):
        m = np.array([sign * math.sin(slope), 0.0, math.cos(slope)])
        proj = np.maximum(w @ m, 0.0)
        num = num + proj * vcavity_G1(w, np.broadcast_to(m, w.shape))
        den = den + proj
    return num / den


def sweep(quick: bool, seed: int = 1, threads: int = 2,
          progress: Callable[[int, int], None] | None = None) -> list[Row]:
    """Run every case over the sweep; each row also times bare Embree on its tile
    (``surface_rays``, median of 3). ``progress(done, total)``, where given, is called
    as each tile resolution, the V-grooves and the bare-Embree timings end.

    Quick: rays 10³…10⁵ per direction (5 points), tile resolutions 64, 128, 256 (2, 4, 8
    cells per correlation length), tables of 8 and 16 θo bins. Full: rays 10⁴…10⁶, tile
    resolutions 64…512, tables of 16 and 32 θo bins. The ``ms`` case runs at
    ``MS_RESOLUTION`` with the smaller tables only.
    """

    rays = np.geomspace(1e3, 1e5, 5) if quick else np.geomspace(1e4, 1e6, 5)
    rays = [int(round(r, -2)) for r in rays]
    resolutions = [64, 128, 256] if quick else [64, 128, 256, 512]
    table_bins = [8, 16] if quick else [16, 32]
    runs = []
    steps = len(resolutions) + 2
    for step, res in enumerate(resolutions, 1):
        for bins in table_bins:
            for n in rays if bins == table_bins[0] else rays[-1:]:
                runs.append(run_tables("ts", gaussian(0.3, res, seed), "mirror",
                                       [0.0, 45.0, 75.0], n, bins, 16, seed, score_ts))
        g1_theta = [60.0, 80.0, 88.0]
        tile = build_tile(resolve({"surface": gaussian(0.5, res, seed)}).surface)
        w = direction(np.radians(g1_theta), 0.0)
        smith = Beckmann(tile.facts.alpha_realised.alpha).G1(w)
        runs += [g1_rows("g1", tile, res, g1_theta, n, smith, seed) for n in rays]
        runs.append(run_tables("furnace", gaussian(0.5, res, seed), "mirror",
                               [0.0, 60.0, 85.0], rays[2], table_bins[0], 64, seed,
                               score_furnace))
        if res == MS_RESOLUTION:
            surface = gaussian(0.6, res, seed)
            alpha = build_tile(resolve({"surface": surface}).surface).facts.alpha_realised.alpha
            model = FrozenBins(SmithMultipleScattering(Beckmann(alpha),
                                                       samples=MS_SAMPLES[quick], seed=seed))
            runs += [run_tables("ms", surface, "mirror", [0.0, 45.0, 75.0], n,
                                table_bins[0], 32, seed, lambda t, m=model: score_ms(t, m))
                     for n in rays]
        if progress is not None:
            progress(step, steps)
    vg = build_tile(resolve({"surface": {"kind": "vgroove", "slope": 45.0,
                                         "grooves": 16}}).surface)
    vg_theta = [30.0, 60.0, 80.0]
    reference = vcavity_reference(math.radians(45.0), np.radians(vg_theta))
    runs += [g1_rows("vgroove", vg, 0, vg_theta, n, reference, seed) for n in rays]
    if progress is not None:
        progress(steps - 1, steps)
    rows = []
    for run, tile in runs:
        with PeriodicScene(tile, threads=1) as scene:
            o, d = surface_rays(scene, 100_000, seed)
        bare = bare_scene(tile.vertices, tile.faces)
        rows.append(Row(*astuple(run), statistics.median(
            bare_rays_per_second(bare, o, d, threads) for _ in range(3))))
    if progress is not None:
        progress(steps, steps)
    return rows


CSV = "bench.csv"
"""The sweep's file in the output folder."""
PLOTS = ("error_vs_time.png", "bias_floor.png")
"""The figures ``plot`` writes in the output folder."""


def write_csv(rows: list[Row], path: Path) -> None:
    """The sweep as CSV (``COLUMNS``), atomically."""
    with atomic_path(path) as tmp, tmp.open("w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=COLUMNS)
        writer.writeheader()
        for row in rows:
            writer.writerow({k: getattr(row, k) for k in COLUMNS})


def plot(rows: list[Row], out: Path) -> list[Path]:
    """``error_vs_time.png`` (log-log, case ts, one line per tile resolution, with the
    1/√t noise slope, and case ms) and ``bias_floor.png`` (the error at the most rays
    against cells per correlation length, for ts and g1)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ts = [r for r in rows if r.case == "ts"]
    bins0 = min(r.table_bins for r in ts)
    fig, ax = plt.subplots(figsize=(6, 4.2))
    for res in sorted({r.tile_resolution for r in ts}):
        sel = sorted((r for r in ts if r.tile_resolution == res and
                      r.table_bins == bins0), key=lambda r: r.wall_s)
        t = np.array([r.wall_s for r in sel])
        ax.loglog(t, [r.error for r in sel], "o-",
                  label=f"{res}² ({res // LENGTHS} cells per τ)")
        ax.loglog(t, [r.stderr for r in sel], ":", color=ax.lines[-1].get_color())
    ms = sorted((r for r in rows if r.case == "ms"), key=lambda r: r.wall_s)
    if ms:
        t = np.array([r.wall_s for r in ms])
        ax.loglog(t, [r.error for r in ms], "s-", color="k", ms=4,
                  label=f"ms: α = 0.6, all orders vs beckmann-ms ({MS_RESOLUTION}²)")
        ax.loglog(t, [r.stderr for r in ms], ":", color="k")
    t0 = min(r.wall_s for r in ts)
    e0 = max(r.stderr for r in ts)
    tt = np.array([t0, max(r.wall_s for r in ts)])
    ax.loglog(tt, e0 * np.sqrt(t0 / tt), "k--", lw=1, label="1/√t (noise)")
    ax.set_xlabel("wall time (s)")
    ax.set_ylabel("median relative error over lobe bins")
    ax.set_title("ts: Gaussian α = 0.3, single scattering vs Torrance-Sparrow + Smith\n"
                 "solid: against the model; dotted: relative standard error (reported)",
                 fontsize=9)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    fig.tight_layout()
    paths = [out / name for name in PLOTS]
    save(fig, paths[0], dpi=110)
    fig, ax = plt.subplots(figsize=(6, 4.2))
    for case, label in (("ts", "ts: median relative error against the model"),
                        ("g1", "g1: mean |G1 − Smith|")):
        sel = [r for r in rows if r.case == case and r.table_bins in (0, bins0)]
        most = max(r.rays for r in sel)
        pts = sorted((r.cells_per_correlation, r.error, r.stderr) for r in sel
                     if r.rays == most)
        ax.errorbar([p[0] for p in pts], [p[1] for p in pts], yerr=[p[2] for p in pts],
                    fmt="o-", label=label, capsize=3)
    ax.set_xscale("log", base=2)
    ax.set_yscale("log")
    ax.set_xlabel("grid cells per correlation length")
    ax.set_ylabel("error at the largest ray count")
    ax.set_title("Bias floor against tile resolution (±1 reported standard error)",
                 fontsize=9)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    fig.tight_layout()
    save(fig, paths[1], dpi=110)
    return paths
