"""Cost of one realisation of a random surface: building its tile and its scene, part by
part, and the tracing speed of a refitted scene against a new one.

Usage::

    python scripts/bench_tiles.py [recipe] [--builds 12] [--rays 60000] [--repeats 7]
                                  [--write]

Builds realisations 1, 2, … of the recipe's tile (default surfaces/gaussian-0.3.toml) one
after the other, as an ensemble table does, and reports the median and range over
``builds`` of each part: ``build_tile`` (generation and facts), of it the Gaussian heights
(``gaussian.heights``) and the face normals, areas and plane constants
(``microsim.surfaces.faces``); the kernel's face table; a new Embree scene and a refit of
one (``microsim.kernel.embree.Scene``, ``Scene.update``); and the whole ``PeriodicScene``,
new (``PeriodicScene(tile, 2)``) or taken over from the previous realisation
(``PeriodicScene.update``), and the sum for a realisation of each. Wall time
(``time.perf_counter``) and CPU time of the process (``time.process_time``: Embree builds
on its own threads) are both reported.

Then it traces the same rays (mirror facets, 16 bounces, θi = 0, 30, 60, 80°, ``rays``
each, from the top of the slab) on one thread in realisation 1's scene built anew and in
realisation 0's scene updated to realisation 1, ``repeats`` times alternating, and reports
the CPU time per Embree query (``time.thread_time``) and how many rays ended differently.
``--write`` puts the results into docs/performance.md (marked section).
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import statistics
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from microsim.files import write_section
from microsim.geometry import direction
from microsim.kernel import slots as ks
from microsim.kernel.embree import Scene
from microsim.kernel.packing import FacetMaterials
from microsim.materials import Mirror
from microsim.measurement.scene import PeriodicScene
from microsim.recipe import load
from microsim.surfaces import build_tile, gaussian
from microsim.surfaces.faces import face_geometry
from microsim.surfaces.realisations import realisation
from microsim.surfaces.tile import Tile

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "performance.md"
NAME = "bench_tiles"
CLOCKS = {"wall": time.perf_counter, "CPU": time.process_time}
T = TypeVar("T")


def timed(fn: Callable[..., T], *args: Any) -> tuple[T, dict[str, float]]:
    """``fn(*args)`` and the milliseconds it took on each clock."""
    start = {k: clock() for k, clock in CLOCKS.items()}
    result = fn(*args)
    return result, {k: 1e3 * (clock() - start[k]) for k, clock in CLOCKS.items()}


def gaussian_heights(surface: gaussian.Gaussian) -> np.ndarray:
    """The heights of a resolved Gaussian ``[surface]``, as its generator draws them."""
    sigma, tau_x, tau_y = surface.correlation_lengths()
    return gaussian.heights(surface.resolution, surface.size, sigma, tau_x, tau_y,
                            math.radians(surface.rotation),
                            np.random.default_rng(surface.seed))


def new_scene(tile: Tile, threads: int | None) -> None:
    """Build ``PeriodicScene(tile, threads)`` and close it."""
    PeriodicScene(tile, threads).close()


def new_embree_scene(tile: Tile) -> None:
    """Build an Embree scene of the tile and close it."""
    Scene(tile.vertices, tile.faces).close()


def parts(surface: gaussian.Gaussian, builds: int) -> dict[str, list[dict[str, float]]]:
    """Each part's times (ms per clock) over ``builds`` realisations, after two warm-ups."""
    out: dict[str, list[dict[str, float]]] = {}
    held = PeriodicScene(build_tile(surface), 2)
    embree = Scene(held.tile.vertices, held.tile.faces)
    for r in range(1, builds + 3):
        s = realisation(surface, r)
        row: dict[str, dict[str, float]] = {}
        if s.kind == "gaussian":
            _, row["Gaussian heights"] = timed(gaussian_heights, s)
        tile, row["build_tile (generation, facts)"] = timed(build_tile, s)
        _, row["face normals, areas, planes"] = timed(face_geometry, tile.vertices,
                                                      tile.faces)
        _, row["face table"] = timed(ks.face_table, tile.face_normals_areas()[0],
                                     tile.face_planes(), tile.material, tile.tangents)
        _, row["Embree scene, new"] = timed(new_embree_scene, tile)
        _, row["Embree scene, refitted"] = timed(embree.update, tile.vertices)
        _, row["PeriodicScene, new"] = timed(new_scene, tile, 2)
        _, row["PeriodicScene.update"] = timed(held.update, tile)
        for total, scene in (("a realisation: build_tile + PeriodicScene, new",
                              "PeriodicScene, new"),
                             ("a realisation: build_tile + PeriodicScene.update",
                              "PeriodicScene.update")):
            row[total] = {k: row["build_tile (generation, facts)"][k] + row[scene][k]
                          for k in CLOCKS}
        if r > 2:
            for k, v in row.items():
                out.setdefault(k, []).append(v)
    embree.close()
    held.close()
    return out


def tracing(surface: gaussian.Gaussian, rays: int, repeats: int) -> dict[str, object]:
    """CPU ns per query in a new and in a refitted scene of realisation 1, and the rays
    whose outcome differs between them."""
    first, tile = (build_tile(realisation(surface, r)) for r in range(2))
    fresh, refitted = PeriodicScene(tile, threads=1), PeriodicScene(first, threads=1)
    refitted.update(tile)
    rng = np.random.default_rng(5)
    mirror = FacetMaterials(np.zeros(len(tile.faces), np.int64), ("s",), {"s": Mirror()})
    start = np.c_[rng.random((rays, 2)), np.full(rays, fresh.z_top - fresh.eps)]
    dirs = [np.tile(-direction(np.radians(t), 0.0), (rays, 1)) for t in (0, 30, 60, 80)]
    times: dict[str, list[float]] = {"new": [], "refitted": []}
    ends = {}
    for _ in range(repeats):
        for name, scene in (("new", fresh), ("refitted", refitted)):
            begin, segments, outs = time.thread_time(), 0, []
            for d in dirs:
                out = scene.run(start, d, mirror, 16, seed=np.random.SeedSequence(1))
                segments += out.segments
                outs.append(np.c_[out.floats, out.ints])
            times[name].append(1e9 * (time.thread_time() - begin) / segments)
            ends[name] = np.concatenate(outs)
    fresh.close()
    refitted.close()
    differ = int((~np.all(ends["new"] == ends["refitted"], axis=1)).sum())
    return {"times": times, "differ": differ, "rays": 4 * rays, "faces": len(tile.faces)}


def section(recipe: str, builds: int, rays: int, repeats: int) -> str:
    """The Markdown of the measurement."""
    load_avg = os.getloadavg()[0]
    surface = load(recipe).surface
    table = parts(surface, builds)
    trace = tracing(surface, rays, repeats)
    lines = [f"Measured with `python scripts/bench_tiles.py {recipe} --builds {builds} "
             f"--rays {rays} --repeats {repeats} --write` on {platform.machine()}, "
             f"{os.cpu_count()} CPUs, Python {platform.python_version()}, numpy "
             f"{np.__version__}; load average (1 min) {load_avg:.1f} at the start: "
             f"realisations 1–{builds} of the tile ({trace['faces']:,} faces) built one "
             "after the other, each part's median (and range) in ms.", "",
             "| part | wall | CPU |", "| --- | --- | --- |"]
    for name, rows in table.items():
        cells = []
        for clock in CLOCKS:
            v = [row[clock] for row in rows]
            cells.append(f"{statistics.median(v):.2f} ({min(v):.2f}–{max(v):.2f})")
        lines.append(f"| {name} | {' | '.join(cells)} |")
    new, refit = (statistics.median(trace["times"][k]) for k in ("new", "refitted"))
    lines += ["", f"Tracing realisation 1 (mirror facets, 16 bounces, θi = 0, 30, 60, 80°, "
              f"{rays:,} rays each, one thread; medians of {repeats} alternating runs): "
              f"{new:.0f} ns of CPU per query in a new scene, {refit:.0f} ns in realisation "
              f"0's scene refitted to it ({100 * (refit / new - 1):+.1f}%); "
              f"{trace['differ']} of {trace['rays']:,} rays ended differently."]
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("recipe", nargs="?", default="surfaces/gaussian-0.3.toml")
    parser.add_argument("--builds", type=int, default=12)
    parser.add_argument("--rays", type=int, default=60_000,
                        help="rays per incident direction in the tracing comparison")
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--write", action="store_true",
                        help="write the results into docs/performance.md")
    args = parser.parse_args()
    text = section(args.recipe, args.builds, args.rays, args.repeats)
    print(text)
    if args.write:
        write_section(DOC, NAME, text, heading="# Performance")


if __name__ == "__main__":
    main()
