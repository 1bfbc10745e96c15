"""Tracing speed: ``simulate`` against bare Embree queries on the same tile, in the same run.

Usage::

    python scripts/bench_trace.py [--repeats 5] [--rays 100000] [--write]
    python scripts/bench_trace.py --cpu [--write]
    python scripts/bench_trace.py --scaling [--write]
    python scripts/bench_trace.py --target 0.01 [--write]

The first form runs each case (mirror, gold conductor and Lambertian facets on the tile of
surfaces/gaussian-0.3.toml, and the refracting paint of surfaces/paint.toml) ``repeats``
times, alternating ``simulate`` (θi = 0, 10, …, 80°, 2 threads; segments per second of the
tracing, scene build excluded) with bare ``EmbreeScene.run`` on incoherent rays from the
same tile (``microsim.bench.surface_rays``; same threads and chunks) timed right before
and after each run over as many rays as it traced segments, and reports the medians and
the median and range of the per-repeat ratios. ``--cpu`` measures the same cases on one
thread in CPU time (``time.thread_time``: what the process itself spent, whatever else
shares the machine): simulate's CPU time per segment against bare ``run``'s per ray,
timed the same way. ``--scaling`` does the same for Gaussian
tiles of 64² … 1024² (32 correlation lengths per side, mirror facets) with 1 and 2 threads
and draws docs/bench/scaling.png. ``--target`` times ``simulate`` to that median relative
standard error on the lobe bins for θi = 0, 10, …, 80°. ``--write`` puts the tables into
docs/performance.md (marked sections).
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numba
import numpy as np

from microsim.bench import bare_rays_per_second, bare_scene, gaussian, surface_rays
from microsim.files import write_section
from microsim.kernel.beam import CELLS, cell_steps
from microsim.measurement.goniometer import measure_directions
from microsim.measurement.scene import CHUNK, PeriodicScene
from microsim.measurement.simulation import simulate
from microsim.recipe import load, resolve
from microsim.settings import Recipe
from microsim.surfaces import build_tile

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "performance.md"
THETA = [float(t) for t in range(0, 81, 10)]
GOLD = {"kind": "conductor", "eta": [0.2, 0.92, 1.1], "k": [3.9, 2.45, 2.14]}
BARE_RAYS = 400_000


def cases() -> list[tuple[str, Recipe]]:
    """(name, resolved recipe) of each speed case."""
    base = load(ROOT / "surfaces" / "gaussian-0.3.toml")
    out = [("mirror", base)]
    for name, material in (("conductor", GOLD),
                           ("lambertian", {"kind": "lambertian", "albedo": 0.8})):
        out.append((name, resolve({**base.to_json(), "material": material})))
    out.append(("paint (refracting)", load(ROOT / "surfaces" / "paint.toml")))
    return out


def measure(recipe: Recipe, rays: int, repeats: int, threads: int) -> dict[str, Any]:
    """Alternate ``simulate`` and bare Embree on the recipe's tile ``repeats`` times."""
    tile = build_tile(recipe.surface)
    sim = replace(recipe.simulation, theta_i=tuple(THETA), rays=rays, target_error=None)
    table = replace(recipe.table, sh_order=0)
    with PeriodicScene(tile, threads=1) as scene:
        o, d = surface_rays(scene, BARE_RAYS, 0)
    bare = bare_scene(tile.vertices, tile.faces)
    # a first run, not counted, warms up and sizes bare Embree's share: as many rays as
    # the tracing it is set against has segments
    warm = simulate(tile, recipe.material, sim, table, threads=threads)
    passes = max(1, round(warm.meta.segments / BARE_RAYS))
    ours, raw = [], []
    for _ in range(repeats):
        before = bare_rate(bare, o, d, threads, passes)
        result = simulate(tile, recipe.material, sim, table, threads=threads)
        after = bare_rate(bare, o, d, threads, passes)
        ours.append(result.meta.timing.segments_per_second)
        raw.append(0.5 * (before + after))
    ratios = [a / b for a, b in zip(ours, raw, strict=True)]
    return {"faces": len(tile.faces), "ours": ours, "bare": raw,
            "segments_per_ray": result.meta.segments / (rays * len(THETA)),
            "ratio": statistics.median(ratios), "range": (min(ratios), max(ratios))}


def bare_rate(scene: Any, origins: np.ndarray, dirs: np.ndarray, threads: int,
              passes: int) -> float:
    """Bare Embree's rays per second over ``passes`` passes of the rays (total rays over
    total time)."""
    return passes / sum(1.0 / bare_rays_per_second(scene, origins, dirs, threads)
                        for _ in range(passes))


def bare_cpu(scene: Any, o32: np.ndarray, d32: np.ndarray, passes: int) -> float:
    """Bare ``run``'s CPU time per ray on this thread over ``passes`` passes of the rays."""
    spent = 0.0
    for _ in range(passes):
        dists = np.full(len(o32), 1e30, np.float32)
        start = time.thread_time()
        scene.run(o32, d32, dists=dists)
        spent += time.thread_time() - start
    return spent / (passes * len(o32))


def cpu_section(args: argparse.Namespace) -> str:
    """CPU time per segment on one thread, against bare Embree's per ray."""
    head = machine()
    rows = []
    for name, recipe in cases():
        tile = build_tile(recipe.surface)
        sim = replace(recipe.simulation, theta_i=tuple(THETA), rays=args.rays,
                      target_error=None, realisations=1, max_realisations=None)
        table = replace(recipe.table, sh_order=0)
        with PeriodicScene(tile, threads=1) as scene:
            o, d = surface_rays(scene, BARE_RAYS, 0)
            # a first run, not counted, warms up and sizes bare Embree's share
            warm = measure_directions(tile, recipe.material, sim, table, scene=scene)
        rays32 = (o.astype(np.float32), d.astype(np.float32))
        # the same rays in the order simulate traces its beam: cells of their start points
        u = np.mod(o[:, :2] / tile.period, 1.0)
        ordered = tuple(a[np.argsort(cell_steps(u, CELLS), kind="stable")] for a in rays32)
        bare = bare_scene(tile.vertices, tile.faces)
        passes = max(1, round(warm.segments / BARE_RAYS))
        ours, raw, raw_ordered = [], [], []
        for _ in range(args.repeats):
            before = bare_cpu(bare, *rays32, passes), bare_cpu(bare, *ordered, passes)
            with PeriodicScene(tile, threads=1) as scene:
                start = time.thread_time()
                traced = measure_directions(tile, recipe.material, sim, table, scene=scene)
                ours.append((time.thread_time() - start) / traced.segments)
            raw.append(0.5 * (before[0] + bare_cpu(bare, *rays32, passes)))
            raw_ordered.append(0.5 * (before[1] + bare_cpu(bare, *ordered, passes)))
        ratios = [b / a for a, b in zip(ours, raw, strict=True)]
        ratios_ordered = [b / a for a, b in zip(ours, raw_ordered, strict=True)]
        rows.append(f"| {name} | {statistics.median(ours) * 1e9:.0f} | "
                    f"{statistics.median(raw) * 1e9:.0f} | "
                    f"**{statistics.median(ratios):.2f}** | "
                    f"{min(ratios):.2f}–{max(ratios):.2f} | "
                    f"{statistics.median(raw_ordered) * 1e9:.0f} | "
                    f"{statistics.median(ratios_ordered):.2f} |")
        print(rows[-1], flush=True)
    return "\n".join([
        "## Tracing cost in CPU time", "",
        f"Measured with `python scripts/bench_trace.py --cpu --repeats {args.repeats} --rays "
        f"{args.rays} --write` on {head}: the cases above on one thread, in the CPU time the "
        "process spent (`time.thread_time`, so other work on the machine weighs less): "
        "the tracing of every direction per segment (`measure_directions` in a built scene: "
        "origins, kernel, binning) against bare `EmbreeScene.run` per incoherent ray, timed "
        "right before and right after each run over as many rays as it traced segments; "
        "medians over the repeats, the median of the per-repeat ratios and their range. The "
        "last two columns time bare Embree on the same rays sorted as simulate orders its "
        "beam (by the cell of their start point, `microsim.kernel.beam`): the part of "
        "simulate's speed that comes from that order, which bare Embree gets as well.", "",
        "| case | simulate, ns of CPU per segment | bare Embree, ns of CPU per ray | ratio "
        "| range | bare, rays in cell order | ratio to it |",
        "| --- | --- | --- | --- | --- | --- | --- |", *rows])


def machine() -> str:
    """The machine, software and load, for the record."""
    return (f"{platform.machine()}, {os.cpu_count()} CPUs, Python "
            f"{platform.python_version()}, numpy {np.__version__}, numba {numba.__version__}"
            f"; load average (1 min) {os.getloadavg()[0]:.1f} at the start")


def speed_section(args: argparse.Namespace) -> str:
    """The per-case speed table."""
    head = machine()
    rows = []
    for name, recipe in cases():
        m = measure(recipe, args.rays, args.repeats, args.threads)
        rows.append(f"| {name} | {m['faces']:,} | {m['segments_per_ray']:.2f} | "
                    f"{statistics.median(m['ours']) / 1e6:.2f} | "
                    f"{statistics.median(m['bare']) / 1e6:.2f} | **{m['ratio']:.2f}** | "
                    f"{m['range'][0]:.2f}–{m['range'][1]:.2f} |")
        print(rows[-1], flush=True)
    return "\n".join([
        "## Tracing speed against bare Embree", "",
        f"Measured with `python scripts/bench_trace.py --repeats {args.repeats} --rays "
        f"{args.rays} --write` on {head}. Each case alternates {args.repeats} runs of "
        f"`simulate` (θi = 0, 10, …, 80°, {args.rays:,} rays each, {args.threads} threads, "
        f"chunks of {CHUNK:,} rays; segments per second of the tracing, scene build "
        f"excluded) with bare `EmbreeScene.run` on incoherent rays from the same tile "
        f"(points uniform over the faces, cosine-distributed directions; the same threads, "
        f"one call per thread on passes over {BARE_RAYS:,} rays: Embree's best case), "
        "timed right before and right after each run of `simulate` over as many rays as "
        "that run traced segments, so both see the same state of the shared machine. "
        "Ratio: simulate's segments per second over the mean of the bare rays per second "
        "before and after; the median over the repeats, and their range.", "",
        "| case | faces | segments per ray | simulate, 10⁶ segments/s | bare Embree, 10⁶ "
        "rays/s | ratio | range |", "| --- | --- | --- | --- | --- | --- | --- |", *rows])


def scaling_section(args: argparse.Namespace) -> str:
    """Segments per second against tile size and threads, and the plot."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    head = machine()
    sizes = [64, 128, 256, 512, 1024]
    rows, series = [], {}
    for res in sizes:
        recipe = resolve({"surface": gaussian(0.3, res, 1), "material": {"kind": "mirror"}})
        for threads in (1, 2):
            m = measure(recipe, args.rays, args.repeats, threads)
            ours, bare = statistics.median(m["ours"]), statistics.median(m["bare"])
            series.setdefault(threads, []).append((ours, bare))
            rows.append(f"| {res}² | {m['faces']:,} | {threads} | {ours / 1e6:.2f} | "
                        f"{bare / 1e6:.2f} | {m['ratio']:.2f} |")
            print(rows[-1], flush=True)
    fig, ax = plt.subplots(figsize=(6, 4.2))
    faces = [2 * s * s for s in sizes]
    for threads, style in ((1, "o"), (2, "s")):
        pts = np.array(series[threads]) / 1e6
        line = ax.loglog(faces, pts[:, 0], style + "-", label=f"simulate, {threads} thread"
                         + ("s" if threads > 1 else ""))[0]
        ax.loglog(faces, pts[:, 1], style + "--", color=line.get_color(),
                  label=f"bare Embree, {threads} thread" + ("s" if threads > 1 else ""))
    ax.set_xlabel("faces of the tile")
    ax.set_ylabel("10⁶ segments (rays) per second")
    ax.set_title("Gaussian α = 0.3, mirror facets: simulate against bare Embree\n"
                 "on incoherent rays from the same tile", fontsize=9)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    fig.tight_layout()
    out = ROOT / "docs" / "bench" / "scaling.png"
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return "\n".join([
        "## Scaling with tile size and threads", "",
        f"Measured with `python scripts/bench_trace.py --scaling --repeats {args.repeats} "
        f"--rays {args.rays} --write` on {head}: Gaussian tiles of 32 correlation lengths "
        f"per side, α = 0.3, mirror facets, otherwise as above.", "",
        "| tile | faces | threads | simulate, 10⁶ segments/s | bare Embree, 10⁶ rays/s "
        "| ratio |", "| --- | --- | --- | --- | --- | --- |", *rows, "",
        "![segments per second against tile size](bench/scaling.png)"])


def target_section(args: argparse.Namespace) -> str:
    """Time to a median relative standard error of ``args.target`` on the lobe bins."""
    head = machine()
    recipe = load(ROOT / "surfaces" / "gaussian-0.3.toml")
    tile = build_tile(recipe.surface)
    # one tile, starting from 200 000 rays per direction as this measurement always has
    sim = replace(recipe.simulation, theta_i=tuple(THETA), rays=200_000,
                  target_error=args.target)
    start = time.perf_counter()
    table = simulate(tile, recipe.material, sim, replace(recipe.table, sh_order=0),
                     threads=args.threads)
    wall = time.perf_counter() - start
    rays = [d.rays for d in table.meta.directions]
    return "\n".join([
        "## Time to a target error", "",
        f"Measured with `python scripts/bench_trace.py --target {args.target} --write` on "
        f"{head}: `surfaces/gaussian-0.3.toml` (mirror, 16 bounces), θi = 0, 10, …, 80°, "
        f"{args.threads} threads, adaptive stop at a median relative standard error of "
        f"{args.target:.0%} on the lobe bins of each incidence (batches of 65,536 rays), "
        "harmonics off.", "",
        f"**{wall:.1f} s** wall ({sum(rays) / 1e6:.1f} M rays; per incidence "
        f"{', '.join(f'{r / 1e6:.1f}' for r in rays)} M; stop: "
        f"{', '.join(table.meta.stop)}; "
        f"{table.meta.timing.segments_per_second / 1e6:.2f} × 10⁶ segments/s)."])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--rays", type=int, default=100_000,
                        help="rays per incident direction in the speed runs")
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--cpu", action="store_true",
                        help="CPU time per segment on one thread against bare Embree")
    parser.add_argument("--scaling", action="store_true",
                        help="tile sizes 64² … 1024², 1 and 2 threads")
    parser.add_argument("--target", type=float, default=None,
                        help="time simulate to this median relative standard error")
    parser.add_argument("--write", action="store_true",
                        help="write the results into docs/performance.md")
    args = parser.parse_args()
    if args.target is not None:
        name, text = "bench_trace-target", target_section(args)
    elif args.scaling:
        name, text = "bench_trace-scaling", scaling_section(args)
    elif args.cpu:
        name, text = "bench_trace-cpu", cpu_section(args)
    else:
        name, text = "bench_trace-speed", speed_section(args)
    print(text)
    if args.write:
        write_section(DOC, name, text, heading="# Performance")


if __name__ == "__main__":
    main()
