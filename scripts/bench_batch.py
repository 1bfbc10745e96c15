"""Batch speed-up: a sweep on a local Dask cluster of 2 workers against 1.

Usage::

    python scripts/bench_batch.py [SWEEP] [--repeats 3] [--rays 200000] [--realisations 1]
                                  [--write]

Runs the sweep (default: the first 4 points of scripts/sweep-roughness.toml, i.e. 4
tables of 256² Gaussian tiles, 4 incident angles each, 200 000 rays per angle on one
realisation, one angle per job) with
``run_batch`` on a fresh ``LocalCluster`` of 1 and of 2 worker processes (one thread
each, one tracing thread per job), alternating, ``--repeats`` times. The time is
``run_batch``'s wall time (cluster start-up excluded, reported apart); the workers'
occupancy comes from Dask's task stream. Every run writes
tables of identical bytes, which the script checks. Prints the times, the speed-up per
repeat (pairs run back to back) with its mean and range, and the load average; with
``--write`` it replaces the batch section of docs/performance.md.
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import logging
import os
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path

from distributed import Client, LocalCluster, get_task_stream

from microsim.batch import run_batch
from microsim.files import write_section
from microsim.sweep import load_sweep, recipe_hash

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "performance.md"


def digest(folder: Path) -> str:
    """SHA-256 over every table of a folder, in name order."""
    h = hashlib.sha256()
    for path in sorted(folder.glob("*.exr")):
        h.update(path.name.encode() + path.read_bytes())
    return h.hexdigest()


def timed_run(sweep, workers: int) -> tuple[float, float, float, str, int]:
    """(cluster start-up s, run_batch wall s, worker occupancy, tables digest, rays) on
    ``workers``. Occupancy: the jobs' summed compute time over workers × the span from the
    first job's start to the last one's end (Dask's task stream)."""
    start = time.perf_counter()
    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                      dashboard_address=None, silence_logs=logging.CRITICAL) as cluster, \
            Client(cluster) as client, tempfile.TemporaryDirectory() as folder:
        up = time.perf_counter() - start
        with get_task_stream(client) as stream:
            summary = run_batch(sweep, folder, client, resume=False)
        assert not summary.failed, summary.failed
        spans = [(s["start"], s["stop"]) for task in stream.data
                 for s in task["startstops"] if s["action"] == "compute"]
        busy = sum(b - a for a, b in spans)
        span = max(b for _, b in spans) - min(a for a, _ in spans)
        return up, summary.wall_s, busy / (workers * span), digest(Path(folder)), \
            summary.rays


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("sweep", nargs="?", default=str(ROOT / "scripts/sweep-roughness.toml"))
    parser.add_argument("--tables", type=int, default=4, help="first N points of the sweep")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--rays", type=int, default=200_000,
                        help="simulation.rays of every table (default 200000)")
    parser.add_argument("--realisations", type=int, default=1,
                        help="simulation.realisations of every table (default 1: one job "
                             "per angle, the workload this benchmark has always measured)")
    parser.add_argument("--write", action="store_true", help="update docs/performance.md")
    args = parser.parse_args()
    sweep = load_sweep(args.sweep)
    points = []
    for p in sweep.points[:args.tables]:
        recipe = dataclasses.replace(p.recipe, simulation=dataclasses.replace(
            p.recipe.simulation, rays=args.rays, realisations=args.realisations))
        points.append(dataclasses.replace(p, recipe=recipe, hash=recipe_hash(recipe)))
    sweep = dataclasses.replace(sweep, points=points)
    load_before = os.getloadavg()
    times: dict[int, list[float]] = {1: [], 2: []}
    busy: dict[int, list[float]] = {1: [], 2: []}
    ups, digests, rays = [], set(), 0
    for _ in range(args.repeats):
        for workers in (1, 2):
            up, wall, occupancy, dig, rays = timed_run(sweep, workers)
            times[workers].append(wall)
            busy[workers].append(occupancy)
            ups.append(up)
            digests.add(dig)
            print(f"{workers} worker(s): {wall:.2f} s (cluster start {up:.2f} s)", flush=True)
    assert len(digests) == 1, "tables differ between runs"
    ratios = [a / b for a, b in zip(times[1], times[2], strict=True)]
    load_after = os.getloadavg()
    cpus = os.cpu_count()
    lines = [
        "## Batch runs: 2 workers against 1",
        "",
        f"Measured with `python scripts/bench_batch.py {' '.join(sys.argv[1:])}`".rstrip()
        + f" on {platform.machine()}, {cpus} CPUs, Python {platform.python_version()}: "
        f"{len(points)} tables ({', '.join(p.name for p in points)}) of "
        f"`{Path(args.sweep).name}`, {rays:,} rays in all, one incident angle per job "
        f"({sum(len(p.recipe.simulation.theta_i) for p in points) * args.realisations}"
        " jobs), a fresh "
        "`LocalCluster` per run (processes, one thread each), runs alternating.",
        "",
        "| workers | `run_batch` wall time, s (per repeat) | median | worker occupancy |",
        "| --- | --- | --- | --- |",
        *[f"| {w} | {', '.join(f'{t:.2f}' for t in ts)} | {statistics.median(ts):.2f} | "
          f"{min(busy[w]):.2f}–{max(busy[w]):.2f} |" for w, ts in times.items()],
        "",
        "Worker occupancy: the jobs' summed compute time over (workers × the span from the "
        "first job's start to the last one's end), from Dask's task stream; near 1 means "
        "no worker waited for work, whatever the load of the machine.",
        "",
        f"Speed-up of 2 workers over 1, per repeat: {', '.join(f'{r:.2f}' for r in ratios)} "
        f"(mean {statistics.mean(ratios):.2f}, range {min(ratios):.2f}–{max(ratios):.2f}). "
        f"Cluster start-up: {min(ups):.1f}–{max(ups):.1f} s, not included. Every run wrote "
        "the same table bytes.",
        "",
        f"Load average (1 min) before and after: {load_before[0]:.1f}, {load_after[0]:.1f} "
        f"on {cpus} CPUs.",
    ]
    text = "\n".join(lines)
    print(text)
    if args.write:
        write_section(DOC, "bench_batch", text)


if __name__ == "__main__":
    main()
