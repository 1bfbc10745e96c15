"""Tracing speed: ``simulate`` against bare Embree queries on the same tile.

Usage::

    python scripts/bench_trace.py [RECIPE] [--repeats 5] [--threads 2] [--target 0.01]

Prints, for the recipe's tile (default surfaces/gaussian-0.3.toml):

- scene build time of ``PeriodicScene`` and of a bare Embree scene of the same mesh;
- traced segments per second of ``simulate`` (median of the repeats) and rays per second
  of bare ``EmbreeScene.run`` on the primary rays of the same incidences with the same
  threads and chunks (median), and their ratio;
- with ``--target``, the time ``simulate`` needs to reach that median relative error on
  the lobe bins for theta_i = 0, 10, ..., 80 deg.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import statistics
import time
from pathlib import Path

import numpy as np

from microsim.bench import bare_rays_per_second, bare_scene
from microsim.compare import direction
from microsim.goniometer import simulate
from microsim.recipe import load
from microsim.surfaces import build_tile
from microsim.trace import CHUNK, PeriodicScene

ROOT = Path(__file__).resolve().parent.parent


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("recipe", nargs="?", default=str(ROOT / "surfaces/gaussian-0.3.toml"))
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--target", type=float, default=None,
                        help="also time the adaptive stop to this median relative error")
    args = parser.parse_args()
    recipe = load(args.recipe)
    tile = build_tile(recipe["surface"])
    # tracing speed: the bins only (docs/performance.md times the harmonics separately)
    sim, table = recipe["simulation"], {**recipe["table"], "sh_order": 0}

    start = time.perf_counter()
    bare = bare_scene(tile.vertices, tile.faces)
    build_bare = time.perf_counter() - start
    start = time.perf_counter()
    PeriodicScene(tile, threads=1).close()
    build_scene = time.perf_counter() - start

    rng = np.random.default_rng(0)
    n = int(sim["rays"])
    z_top = tile.z_range[1]
    origins = [np.column_stack([rng.random((n, 2)) * tile.period, np.full(n, z_top)])
               for _ in sim["theta_i"]]
    dirs = [np.broadcast_to(-direction(math.radians(t), 0.0), (n, 3)) for t in sim["theta_i"]]
    o32 = np.concatenate(origins).astype(np.float32)
    d32 = np.concatenate(dirs).astype(np.float32)

    ours, raw = [], []
    for _ in range(args.repeats):
        result = simulate(tile, recipe["material"], sim, table, threads=args.threads)
        ours.append(result.meta["segments_per_second"])
        raw.append(bare_rays_per_second(bare, o32, d32, args.threads))
    report = {
        "machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs",
        "recipe": args.recipe, "faces": len(tile.faces), "threads": args.threads,
        "chunk": CHUNK, "repeats": args.repeats,
        "build_s": {"PeriodicScene": build_scene, "bare": build_bare},
        "simulate_segments_per_s": statistics.median(ours),
        "bare_run_rays_per_s": statistics.median(raw),
        "ratio": statistics.median(ours) / statistics.median(raw),
    }
    if args.target is not None:
        adaptive = dict(sim, theta_i=list(range(0, 81, 10)), target_error=args.target)
        result = simulate(tile, recipe["material"], adaptive, table, threads=args.threads)
        report["target"] = {
            "target_error": args.target, "wall_s": result.meta["wall_time"],
            "stop": result.meta["stop"],
            "rays": [d["rays"] for d in result.meta["directions"]],
            "rel_stderr": [d["rel_stderr"] for d in result.meta["directions"]]}
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
