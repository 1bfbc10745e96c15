"""Time and peak memory of tile generation, and what the Gaussian defaults cost.

Usage: python scripts/bench_surfaces.py [--write]

Prints Markdown for docs/surfaces.md; ``--write`` puts it into its marked sections:

- ``bench_surfaces-alpha``: realised over target α of Gaussian tiles of 32 correlation
  lengths per side (α = 0.3, seeds 0, 1, 2) against grid cells per correlation length,
  beside what the discretisation alone predicts
  (``microsim.surfaces.gaussian.discretised_alpha_ratio``);
- ``bench_surfaces-g1``: ``microsim measure g1`` of one tile of
  ``surfaces/gaussian-0.3.toml`` at 128² (16 correlation lengths) and at its own 256²
  (32) at θ = 80°, against Smith's G1 at the tile's realised α;
- ``bench_surfaces-speed``: the time and memory of building a 1024² Gaussian tile and a
  velvet tile, each in fresh Python processes: the process's peak resident memory, and
  the build's own peak allocation (``tracemalloc``, which numpy reports to).

The cylinders' facet steps in docs/surfaces.md are arithmetic (360° / segments), not
measured, and are not written here.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

from microsim.files import measured_with, write_section

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "surfaces.md"
CHILD = """
import json, resource, sys, time, tracemalloc
from microsim.recipe import resolve
from microsim.surfaces import build_tile
surface = resolve({{"surface": {surface}}}).surface
if sys.argv[1] == "traced":
    tracemalloc.start()
    build_tile(surface, memory_limit_gib=64)
    print(json.dumps({{"traced_mib": tracemalloc.get_traced_memory()[1] / 2**20}}))
else:
    start = time.perf_counter()
    tile = build_tile(surface, memory_limit_gib=64)
    seconds = time.perf_counter() - start
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    print(json.dumps({{"seconds": seconds, "peak_mib": peak / 1024,
                      "triangles": len(tile.faces)}}))
"""
"""One build of a tile in a fresh process: timed (with the process's peak resident memory)
or, with the argument ``traced``, under ``tracemalloc`` (the peak of what numpy and
Python allocated during the build, the import's memory apart; slower)."""

CASES = {
    "gaussian 1024², alpha 0.3": {"kind": "gaussian", "alpha": 0.3, "resolution": 1024},
    "velvet, 10 000 fibres (size 5, density 400)": {"kind": "velvet", "size": 5.0,
                                                     "density": 400.0},
}
SEEDS = (0, 1, 2)
CELLS = (2, 4, 8, 16)
G1_THETA = 80.0
G1_RAYS = 1_000_000
"""Rays of one ``measure g1`` (binomial error ≈ 0.0003 at G1 ≈ 0.9)."""


def timings() -> list[str]:
    """One Markdown row per ``CASES`` entry: triangles, seconds, the process's peak
    resident memory and the build's own peak allocation (MiB)."""
    rows = ["| tile | triangles | time (s) | peak resident memory of the process (MiB) | "
            "peak allocated by the build (MiB) |", "| --- | --- | --- | --- | --- |"]
    for name, surface in CASES.items():
        r = {}
        for mode in ("timed", "traced"):
            out = subprocess.run([sys.executable, "-c", CHILD.format(surface=repr(surface)),
                                  mode], capture_output=True, text=True, check=True).stdout
            r.update(json.loads(out))
        rows.append(f"| {name} | {r['triangles']:,} | {r['seconds']:.2f} | "
                    f"{r['peak_mib']:.0f} | {r['traced_mib']:.0f} |")
    return rows


def gaussian_resolution() -> list[str]:
    """Realised over target alpha against grid cells per correlation length, and the
    seeds' spread at 8 cells and more."""
    from microsim.recipe import resolve
    from microsim.surfaces import build_tile
    from microsim.surfaces.gaussian import discretised_alpha_ratio

    rows = ["| cells per correlation length | resolution | realised / target "
            f"({len(SEEDS)} seeds) | expected from discretisation |", "| --- | --- | --- | --- |"]
    fine = []
    for cells in CELLS:
        res = 32 * cells  # 32 correlation lengths per side whatever the cells
        ratios = []
        for seed in SEEDS:
            surface = resolve({"surface": {"kind": "gaussian", "alpha": 0.3, "seed": seed,
                                           "resolution": res,
                                           "correlation_length": cells / res}}).surface
            ratios.append(build_tile(surface).facts.alpha_realised.alpha / 0.3)
        if cells >= 8:
            fine += ratios
        rows.append(f"| {cells} | {res} | {', '.join(f'{r:.3f}' for r in ratios)} | "
                    f"{discretised_alpha_ratio(cells):.3f} |")
    rows += ["", f"At 8 and 16 cells the {len(fine)} tiles' ratios scatter by ± "
             f"{100 * statistics.stdev(fine):.1f}% (standard deviation) about their mean "
             f"{statistics.mean(fine):.3f}."]
    return rows


def g1_sentence() -> str:
    """One tile's G1 at ``G1_THETA`` against Smith's, at 128² and 256²."""
    parts = []
    for resolution, lengths in ((128, 16), (256, 32)):
        out = subprocess.run(
            [sys.executable, "-m", "microsim.cli", "measure", "g1",
             str(ROOT / "surfaces" / "gaussian-0.3.toml"), "--set",
             f"surface.resolution={resolution}", "--theta", f"{G1_THETA:g}",
             "--realisations", "1", "--rays", str(G1_RAYS), "--json"],
            capture_output=True, text=True, check=True).stdout
        r = json.loads(out)
        g1, err, smith = r["g1"][0], r["g1_stderr"][0], r["smith"][0]
        parts.append(f"one {resolution}² tile ({lengths} correlation lengths per side, "
                     f"realised α {r['alpha_realised']:.3f}) has G1 = {g1:.4f} ± {err:.4f}, "
                     f"Smith's {smith:.4f}: {g1 - smith:+.4f}")
    return (f"`microsim measure g1 surfaces/gaussian-0.3.toml --theta {G1_THETA:g} "
            f"--realisations 1 --rays {G1_RAYS}` (with `--set surface.resolution=128` for "
            "the smaller tile): " + "; ".join(parts) + ".")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--write", action="store_true",
                        help="write the sections into docs/surfaces.md")
    args = parser.parse_args()
    load = os.getloadavg()[0]
    alpha = "\n".join([
        f"{measured_with(__file__, sys.argv[1:], load)}: 32 correlation lengths per side, "
        f"α = 0.3, seeds {', '.join(map(str, SEEDS))}.", "", *gaussian_resolution()])
    print(alpha, flush=True)
    load = os.getloadavg()[0]
    g1 = g1_sentence()
    g1 = f"{measured_with(__file__, sys.argv[1:], load)}: {g1}"
    print(g1, flush=True)
    load = os.getloadavg()[0]
    rows = timings()
    speed = "\n".join([
        f"{measured_with(__file__, sys.argv[1:], load)}: each case built by `build_tile` "
        "in a fresh process, once timed (with the process's peak resident memory, the "
        "import of microsim included) and once under `tracemalloc` (the peak of what the "
        "build itself allocated).", "",
        *rows])
    print(speed)
    if args.write:
        write_section(DOC, "bench_surfaces-alpha", alpha)
        write_section(DOC, "bench_surfaces-g1", g1)
        write_section(DOC, "bench_surfaces-speed", speed)


if __name__ == "__main__":
    main()
