"""Time and peak memory of tile generation, and what tessellation defaults cost.

Usage: python scripts/bench_surfaces.py
Prints Markdown tables (copied into docs/surfaces.md). Each timing runs in a fresh Python
process, so its peak resident memory is its own.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys

CHILD = """
import json, resource, time
from microsim.recipe import resolve
from microsim.surfaces import build_tile
surface = resolve({{"surface": {surface}}}).surface
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
start = time.perf_counter()
tile = build_tile(surface, memory_limit_gib=64)
seconds = time.perf_counter() - start
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(json.dumps({{"seconds": seconds, "peak_mib": peak / 1024, "growth_mib": (peak - base) / 1024,
                  "triangles": len(tile.faces)}}))
"""

CASES = {
    "gaussian 1024², alpha 0.3": {"kind": "gaussian", "alpha": 0.3, "resolution": 1024},
    "velvet, 10 000 fibres (size 5, density 400)": {"kind": "velvet", "size": 5.0,
                                                     "density": 400.0},
}


def timings() -> list[str]:
    rows = ["| tile | triangles | time (s) | peak memory (MiB) | growth (MiB) |",
            "| --- | --- | --- | --- | --- |"]
    for name, surface in CASES.items():
        out = subprocess.run([sys.executable, "-c", CHILD.format(surface=repr(surface))],
                             capture_output=True, text=True, check=True).stdout
        r = json.loads(out)
        rows.append(f"| {name} | {r['triangles']:,} | {r['seconds']:.2f} | "
                    f"{r['peak_mib']:.0f} | {r['growth_mib']:.0f} |")
    return rows


def gaussian_resolution() -> list[str]:
    """Realised over target alpha against grid cells per correlation length."""
    from microsim.recipe import resolve
    from microsim.surfaces import build_tile
    from microsim.surfaces.gaussian import discretised_alpha_ratio

    rows = ["| cells per correlation length | resolution | realised / target (3 seeds) | "
            "expected from discretisation |", "| --- | --- | --- | --- |"]
    for cells in (2, 4, 8, 16):
        res = 32 * cells  # 32 correlation lengths per side whatever the cells
        ratios = []
        for seed in range(3):
            surface = resolve({"surface": {"kind": "gaussian", "alpha": 0.3, "seed": seed,
                                           "resolution": res,
                                           "correlation_length": cells / res}}).surface
            ratios.append(build_tile(surface).facts.alpha_realised.alpha / 0.3)
        rows.append(f"| {cells} | {res} | {', '.join(f'{r:.3f}' for r in ratios)} | "
                    f"{discretised_alpha_ratio(cells):.3f} |")
    return rows


def cylinder_segments() -> list[str]:
    rows = ["| segments | facet step (deg) | mirror reflection step (deg) |",
            "| --- | --- | --- |"]
    for seg in (32, 64, 128, 256):
        rows.append(f"| {seg} | {360 / seg:.2f} | {720 / seg:.2f} |")
    return rows


if __name__ == "__main__":
    print("\n".join(timings()))
    print()
    print("\n".join(gaussian_resolution()))
    print()
    print("\n".join(cylinder_segments()))
    print(f"\n(default table phi bin: {360 / 64:.2f} deg; pi = {math.pi:.4f})")
