"""Speed against error, the full sweep: CSV, plots and the table in docs/performance.md.

Usage: python scripts/bench_speed_error.py [--quick] [--out docs/bench]
Runs ``microsim.bench.sweep`` (the same as ``microsim bench``), writes bench.csv and the
plots into --out, and prints Markdown: per tile resolution, the rays and wall time the
Torrance-Sparrow case needed to reach each median relative error, or the floor it stopped
at; the G1, V-groove, furnace and multiple-scattering errors at the most rays; and the
speed ratio to bare Embree.
"""

from __future__ import annotations

import argparse
import platform
import statistics
import time
from pathlib import Path

from microsim.bench import plot, sweep, write_csv

TARGETS = (0.10, 0.05, 0.02)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--out", type=Path, default=Path("docs/bench"))
    args = parser.parse_args()
    start = time.perf_counter()
    rows = sweep(args.quick)
    wall = time.perf_counter() - start
    args.out.mkdir(parents=True, exist_ok=True)
    write_csv(rows, args.out / "bench.csv")
    plot(rows, args.out)
    ts = [r for r in rows if r.case == "ts"]
    bins0 = min(r.table_bins for r in ts)
    print(f"Sweep: {wall:.0f} s on {platform.machine()}, "
          f"{'quick' if args.quick else 'full'}.\n")
    print("| tile | " + " | ".join(f"to {100 * t:.0f}%" for t in TARGETS)
          + " | floor (most rays) |")
    print("| --- |" + " --- |" * (len(TARGETS) + 1))
    for res in sorted({r.tile_resolution for r in ts}):
        sel = sorted((r for r in ts if r.tile_resolution == res
                      and r.table_bins == bins0), key=lambda r: r.rays)
        cells = []
        for target in TARGETS:
            hit = next((r for r in sel if r.error <= target), None)
            cells.append("not reached" if hit is None else
                         f"{hit.rays // 3:,} rays/θi, {hit.wall_s:.2f} s")
        last = sel[-1]
        print(f"| {res}² ({res // 32} cells/τ) | " + " | ".join(cells)
              + f" | {100 * last.error:.1f}% ± {100 * last.stderr:.1f}% |")
    print()
    for case in ("g1", "vgroove", "furnace", "ms"):
        sel = [r for r in rows if r.case == case]
        most = max(r.rays for r in sel)
        for r in sel:
            if r.rays == most:
                print(f"- {case}, tile {r.tile_resolution or '-'}: error "
                      f"{r.error:.4f} ± {r.stderr:.4f} with {r.rays:,} rays")
    most = max(r.rays for r in ts)
    ratios = [r.ratio for r in ts if r.rays == most]
    print(f"\nsimulate / bare Embree segments per second: median "
          f"{statistics.median(ratios):.2f} (range {min(ratios):.2f}–{max(ratios):.2f})")


if __name__ == "__main__":
    main()
