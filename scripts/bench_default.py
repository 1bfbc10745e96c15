"""What users run: the whole ``microsim simulate`` of shipped recipes with their defaults,
against bare Embree on the same tile in the same run.

Usage::

    python scripts/bench_default.py [--repeats 3] [--write]

Sections (``--only`` picks some):

- ``recipes``: ``microsim simulate`` of ``surfaces/gaussian-0.3.toml``, ``velvet.toml`` and
  ``paint.toml`` as they are (their realisations, harmonics and orders), run as a command
  ``repeats`` times, each run between two timings of bare ``EmbreeScene.run`` on
  incoherent rays from the recipe's own tile (``microsim.bench.surface_rays``, 2 threads,
  one call per thread). Two ratios per run: segments over ``simulate``'s own wall time
  (``wall_s``: tiles, scenes, tracing) and over the whole command's (start-up, assembly
  and writing included), each against the mean bare rays per second around it; medians
  and ranges over the repeats, with the command's CPU time and peak memory.
- ``heavy``: a tile-heavy ensemble (256² Gaussian, α = 0.5, 32 realisations, 400 000 rays
  per direction, θi = 0, 20, 40, 60, 80°) with mirror and with gold facets, the same way.
- ``target``: ``microsim simulate surfaces/gaussian-0.3.toml --target-error 0.01``: wall
  and CPU time, peak resident memory, realisations and rays per direction.
- ``breakdown``: the CPU time of each part of one in-process ``simulate`` of
  ``surfaces/gaussian-0.3.toml``, of the tile-heavy gold ensemble and of the target run
  (the kernel, the tally, tiles and scenes, ...).
- ``beam``: the kernel's CPU time per segment on the tile-heavy gold tile against the rays a
  batch puts on the tile: one direction's 12 500 rays (what the tile-heavy ensemble
  traces per realisation and direction), the five directions' 62 500 rays as one beam
  (cell-ordered origins, the directions dealt in turn, so a chunk holds every direction
  from neighbouring origins) and one direction's 65 536 (the demo's batches); medians
  over interleaved rounds.
- ``tile``: the cost of one realisation of the 256² Gaussian tile, as ``simulate`` opens
  one (``microsim.measurement.simulation.Opener.open``, one after the other: the tile's
  generation and facts, then the refit of a scene built for realisation 0), mean of 16
  after realisation 0, with the medians of the two parts.

``--write`` puts the figures at the head of docs/performance.md (marked section).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from microsim.bench import (
    PARTS,
    bare_rays_per_second,
    bare_scene,
    run_child,
    surface_rays,
    timed_run,
)
from microsim.files import write_section
from microsim.geometry import direction
from microsim.kernel.beam import CELLS, Runs, beam_origins
from microsim.kernel.packing import FacetMaterials
from microsim.kernel.rng import key_of
from microsim.measurement.goniometer import Incidences, Measurement
from microsim.measurement.scene import PeriodicScene
from microsim.measurement.simulation import Opener, Tiles
from microsim.recipe import load, resolve, to_toml
from microsim.surfaces import build_tile

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "performance.md"
RECIPES = ("gaussian-0.3.toml", "velvet.toml", "paint.toml")
GOLD = {"kind": "conductor", "eta": [0.2, 0.92, 1.1], "k": [3.9, 2.45, 2.14]}
BARE_RAYS = 400_000
"""Rays per pass of bare Embree."""
BARE_MOST = 4_000_000
"""Most rays bare Embree is timed on around one run (passes of ``BARE_RAYS``)."""
THREADS = 2


def command() -> list[str]:
    """``microsim`` as the installed command runs it."""
    return [sys.executable, "-m", "microsim.cli"]


def heavy_recipe(material: dict[str, Any]) -> str:
    """The tile-heavy case as a recipe (TOML)."""
    base = load(ROOT / "surfaces" / "gaussian-0.3.toml").to_json()
    base["description"] = "tile-heavy ensemble"
    base["surface"] = {"kind": "gaussian", "alpha": 0.5, "resolution": 256, "seed": 1}
    base["material"] = material
    base["simulation"] = {"theta_i": [0, 20, 40, 60, 80], "rays": 400_000, "bounces": 16,
                          "seed": 1, "realisations": 32}
    return to_toml(resolve(base))


def bare_rate(scene: Any, rays: tuple[np.ndarray, np.ndarray], total: int) -> float:
    """Bare Embree's rays per second over about ``total`` rays (passes of the rays)."""
    passes = max(1, min(BARE_MOST, total) // BARE_RAYS)
    return passes / sum(1.0 / bare_rays_per_second(scene, *rays, THREADS)
                        for _ in range(passes))


def timed_case(path: Path, repeats: int) -> dict[str, Any]:
    """``repeats`` runs of ``microsim simulate PATH`` between bare Embree timings on the
    recipe's tile (realisation 0)."""
    recipe = load(path)
    tile = build_tile(recipe.surface)
    with PeriodicScene(tile, threads=1) as scene:
        rays = surface_rays(scene, BARE_RAYS, 0)
    bare = bare_scene(tile.vertices, tile.faces)
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        out = str(Path(folder) / "t.exr")
        argv = command() + ["simulate", str(path), "-o", out, "--json",
                            "--threads", str(THREADS)]
        run_child(argv)  # warm: compiled code, file caches
        for _ in range(repeats):
            guess = rows[-1]["segments"] if rows else BARE_MOST
            before = bare_rate(bare, rays, guess)
            child = run_child(argv)
            after = bare_rate(bare, rays, guess)
            result = json.loads(child.stdout)
            embree = 0.5 * (before + after)
            rows.append({"segments": result["segments"], "wall_s": result["wall_s"],
                         "command_s": child.wall, "cpu_s": child.cpu,
                         "peak_gib": child.peak_gib, "bare": embree,
                         "simulate": result["segments"] / result["wall_s"] / embree,
                         "whole": result["segments"] / child.wall / embree,
                         "realisations": result["realisations"]})
            print(json.dumps(rows[-1]), flush=True)
    return {"faces": len(tile.faces), "rows": rows}


def median_range(values: list[float]) -> str:
    return f"**{statistics.median(values):.2f}** ({min(values):.2f}–{max(values):.2f})"


def case_rows(name: str, case: dict[str, Any]) -> str:
    rows = case["rows"]

    def med(key: str) -> float:
        return statistics.median(r[key] for r in rows)

    return (f"| {name} | {case['faces']:,} | {rows[0]['realisations']} | "
            f"{med('segments') / 1e6:.1f} M | {med('wall_s'):.2f} s | "
            f"{med('command_s'):.2f} s | {med('cpu_s'):.1f} s | {med('peak_gib'):.2f} GiB | "
            f"{med('bare') / 1e6:.2f} | {median_range([r['simulate'] for r in rows])} | "
            f"{median_range([r['whole'] for r in rows])} |")


TABLE_HEAD = ("| recipe | faces | realisations | segments | simulate's wall | command | "
              "CPU | peak memory | bare Embree, 10⁶ rays/s | segments/s over bare, "
              "simulate | the whole command |\n"
              "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")


def recipes_section(repeats: int) -> str:
    rows = [case_rows(f"`{name}`", timed_case(ROOT / "surfaces" / name, repeats))
            for name in RECIPES]
    return "\n".join([TABLE_HEAD, *rows])


def heavy_section(repeats: int) -> str:
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for name, material in (("mirror", {"kind": "mirror"}), ("gold", GOLD)):
            path = Path(folder) / f"heavy-{name}.toml"
            path.write_text(heavy_recipe(material), encoding="utf-8")
            rows.append(case_rows(f"tile-heavy, {name}", timed_case(path, repeats)))
    return "\n".join([TABLE_HEAD, *rows])


TARGET = 0.01
"""The target run's median relative standard error over the lobe bins."""


def target_section() -> str:
    with tempfile.TemporaryDirectory() as folder:
        child = run_child(command() + [
            "simulate", str(ROOT / "surfaces" / "gaussian-0.3.toml"), "--target-error",
            str(TARGET), "-o", str(Path(folder) / "t.exr"), "--json", "--threads",
            str(THREADS)])
    result = json.loads(child.stdout)
    per = ", ".join(f"{k} / {r / 1e6:.1f} M" for k, r in zip(
        result["realisations_per_direction"], result["rays_per_direction"], strict=True))
    return (f"`microsim simulate surfaces/gaussian-0.3.toml --target-error {TARGET}`: "
            f"**{child.wall:.1f} s** wall, {child.cpu:.1f} s CPU, "
            f"**{child.peak_gib:.2f} GiB** peak resident memory; "
            f"{result['segments'] / 1e6:.0f} M segments; realisations / rays per "
            f"incidence (θi = 0, 30, 60, 80°): {per}; stop: {', '.join(result['stop'])}; "
            f"median relative standard error {100 * result['median_rel_stderr']:.2f}%.")


HEAVY_THETA = (0, 20, 40, 60, 80)
"""Incident polar angles of the tile-heavy case, degrees."""
BEAM_ROUNDS = 8
"""Interleaved rounds of each beam (``beam``)."""


def beam_section() -> str:
    """The kernel's CPU time per segment (``time.process_time`` around ``PeriodicScene.run``,
    2 threads) on the tile-heavy gold tile for three beams, one round of each in turn."""
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "heavy-gold.toml"
        path.write_text(heavy_recipe(GOLD), encoding="utf-8")
        recipe = load(path)
    tile = build_tile(recipe.surface)
    facets = FacetMaterials(tile.material, tile.parts, recipe.material, tile.tangents,
                            tile.curved, recipe.table.channels)
    travel = np.array([-direction(np.radians(t), 0.0) for t in HEAVY_THETA])
    per_direction = 400_000 // 32
    beams = {"one direction, 12,500 rays": (per_direction, False),
             "five directions in one beam, 62,500 rays (a realisation of `simulate`)":
                 (per_direction, True),
             "one direction, 65,536 rays": (65_536, False)}
    spent: dict[str, list[float]] = {name: [] for name in beams}
    with PeriodicScene(tile, THREADS) as scene:
        def trace(rays: int, together: bool, seed: int) -> float:
            """CPU per segment of ``rays`` rays per direction, the directions traced in
            one beam of as many runs (``Runs``, as ``simulate`` does) or one by one."""
            keys = [key_of(np.random.SeedSequence(seed, spawn_key=(d,)))
                    for d in range(len(travel))]
            u = np.random.default_rng(seed).random((rays * len(travel), 2))
            starts = np.arange(0, len(u) + 1, rays)
            if together:
                origins, rows, run = beam_origins(u, starts, scene.period, scene.z_top,
                                                  CELLS)
                calls = [(origins, travel[run], Runs(rows, run, starts, np.stack(keys)))]
            else:
                calls = [(beam_origins(u[a:a + rays], starts[:2], scene.period,
                                       scene.z_top, CELLS)[0],
                          np.broadcast_to(d, (rays, 3)), Runs.one(rays, key))
                         for a, d, key in zip(starts[:-1], travel, keys, strict=True)]
            before, cpu = scene.segments, time.process_time()
            for origins, dirs, runs in calls:
                scene.run(origins, dirs, facets, 16, runs)
            return (time.process_time() - cpu) / (scene.segments - before)

        trace(65_536, False, 0)  # warm: compiled code, caches
        for seed in range(1, BEAM_ROUNDS + 1):
            for name, (rays, dealt) in beams.items():
                spent[name].append(trace(rays, dealt, seed))
    cells = CELLS * CELLS
    rows = [f"| {name} | {rays * (len(travel) if together else 1) / cells:.1f} | "
            f"{1e9 * statistics.median(spent[name]):.0f} "
            f"({1e9 * min(spent[name]):.0f}–{1e9 * max(spent[name]):.0f}) |"
            for name, (rays, together) in beams.items()]
    return "\n".join([
        f"The kernel alone (`PeriodicScene.run`, {THREADS} threads, CPU time per segment, "
        f"median (range) of {BEAM_ROUNDS} interleaved rounds) on the tile-heavy gold tile "
        f"(131,072 faces), per beam of one call, θi = "
        f"{', '.join(map(str, HEAVY_THETA))}°:", "",
        "| beam | rays per cell of the beam | ns per segment |", "| --- | --- | --- |",
        *rows])


def tile_section() -> str:
    recipe = load(ROOT / "surfaces" / "gaussian-0.3.toml")
    tiles = Tiles(recipe.surface)
    build, refit = [], []
    with PeriodicScene(tiles(0), THREADS) as scene:
        for r in range(1, 17):
            start = time.perf_counter()
            tile = tiles(r)
            built = time.perf_counter()
            scene.update(tile)
            refit.append(time.perf_counter() - built)
            build.append(built - start)
    done = Measurement({}, {}, [], Incidences.of(recipe.simulation, recipe.table, True))
    opener = Opener(tiles, THREADS, done)
    opener.release(opener.open(0)[2])
    start = time.perf_counter()
    for r in range(1, 17):
        opener.release(opener.open(r)[2])
    whole = (time.perf_counter() - start) / 16
    opener.close()
    first, wall, cpu = tiles(0), [], []
    for _ in range(8):  # a scene built anew: what the first realisations in flight pay
        start, used = time.perf_counter(), time.process_time()
        PeriodicScene(first, THREADS).close()
        wall.append(time.perf_counter() - start)
        cpu.append(time.process_time() - used)
    return (f"One realisation of the 256² Gaussian tile (131,072 faces) as `simulate` "
            f"opens it (`microsim.measurement.simulation.Opener`, one after the other, nothing "
            f"traced beside): **{1e3 * whole:.1f} ms** (mean of 16), of which the tile's "
            f"generation and facts {1e3 * statistics.median(build):.1f} ms and the refit "
            f"of its scene {1e3 * statistics.median(refit):.1f} ms (medians of 16). "
            "`simulate` prepares the next realisation on a thread of its own while one "
            "is traced. A scene built anew (`PeriodicScene` of realisation 0's tile, its "
            f"full BVH): {1e3 * statistics.median(wall):.1f} ms of wall and "
            f"{1e3 * statistics.median(cpu):.1f} ms of CPU (medians of 8); a run builds "
            "one for each realisation in flight, three, and refits them to the others.")


def breakdown_section() -> str:
    """CPU time (``time.thread_time`` of the thread that ran it) of each part of one
    in-process ``simulate_recipe`` of ``surfaces/gaussian-0.3.toml``, of the tile-heavy
    gold ensemble and of the former with ``--target-error 0.01`` (each recipe file after
    one run not counted, which the target run shares with the demo), against the
    process's CPU time and the wall time."""
    from microsim.measurement.simulation import simulate_recipe

    columns, totals = [], []
    with tempfile.TemporaryDirectory() as folder:
        heavy = Path(folder) / "heavy-gold.toml"
        heavy.write_text(heavy_recipe(GOLD), encoding="utf-8")
        demo = ROOT / "surfaces" / "gaussian-0.3.toml"
        warmed: set[Path] = set()
        for path, overrides in ((demo, []), (heavy, []),
                                (demo, [f"simulation.target_error={TARGET}"])):
            recipe = load(path, overrides)
            if path not in warmed:  # compiled code loaded, caches filled: once a recipe
                simulate_recipe(recipe, threads=THREADS)
                warmed.add(path)
            parts, wall, cpu, table = timed_run(recipe, THREADS)
            columns.append((parts, table.meta.segments))
            totals.append(f"{wall:.2f} s wall and {cpu:.2f} s of CPU in all "
                          f"({table.meta.segments / 1e6:.1f} M segments)")
    rows = [f"| {label} | " + " | ".join(
        f"{parts[label]:.2f} s | {1e9 * parts[label] / segments:.0f}"
        for parts, segments in columns) + " |" for _, _, label in PARTS]
    return "\n".join([
        f"One `simulate_recipe` in this process, {THREADS} threads, of "
        f"`surfaces/gaussian-0.3.toml`: {totals[0]}; of the tile-heavy ensemble with gold "
        f"facets (above): {totals[1]}; of the demo to {100 * TARGET:g}% ensemble error "
        f"(`simulation.target_error = {TARGET}`, above): {totals[2]}. The CPU time of "
        "each part, summed over the threads that ran it (the tally includes the binning "
        "and the transforms):", "",
        "| part | demo, CPU | ns per segment | tile-heavy gold, CPU | ns per segment "
        "| to 1%, CPU | ns per segment |",
        "| --- | --- | --- | --- | --- | --- | --- |", *rows])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--only", nargs="+",
                        choices=("recipes", "heavy", "target", "tile", "breakdown", "beam"),
                        default=("recipes", "heavy", "target", "tile", "breakdown", "beam"))
    parser.add_argument("--write", action="store_true",
                        help="write the results into docs/performance.md")
    args = parser.parse_args()
    for name in args.only:
        load_before = os.getloadavg()[0]
        text = {"recipes": lambda: recipes_section(args.repeats),
                "heavy": lambda: heavy_section(args.repeats),
                "target": target_section, "tile": tile_section,
                "breakdown": breakdown_section, "beam": beam_section}[name]()
        print(text, flush=True)
        if args.write:
            repeats = f" --repeats {args.repeats}" if name in ("recipes", "heavy") else ""
            head = (f"Measured with `python scripts/bench_default.py --only {name}{repeats} "
                    f"--write` on {platform.machine()}, {os.cpu_count()} CPUs, Python "
                    f"{platform.python_version()}, {time.strftime('%Y-%m-%d')}; load "
                    f"average (1 min) {load_before:.1f} before, {os.getloadavg()[0]:.1f} "
                    f"after.")
            write_section(DOC, f"bench_default-{name}",
                          "\n".join([f"### {TITLES[name]}", "", head, "", INTROS.get(name, ""),
                                      text]).replace("\n\n\n", "\n\n"),
                          heading="# Performance")


TITLES = {"recipes": "The shipped recipes, as they are", "heavy": "A tile-heavy ensemble",
          "target": "To 1% ensemble error", "tile": "The cost of a realisation",
          "breakdown": "Where the time goes", "beam": "Rays per batch and the kernel"}
INTROS = {"heavy": "256² Gaussian, α = 0.5, 32 realisations, 400,000 rays per direction, "
                   "θi = 0, 20, 40, 60, 80°, harmonics of order 32:\n"}


if __name__ == "__main__":
    main()
