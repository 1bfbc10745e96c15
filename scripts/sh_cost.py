"""What projecting the escaping rays on spherical harmonics costs per batch.

Usage::

    python scripts/sh_cost.py [RECIPE] [--repeats 7] [--write]

Traces one batch (``microsim.measurement.goniometer.BATCH`` rays) of the recipe's tile (default
surfaces/gaussian-0.3.toml) at θi = 30°, then times ``Sums.add`` on it without harmonics
and with orders 8, 16, 32, 64 (median of the repeats), for the recipe's grey mirror
facets (RGB weights equal: per scattering order of the table's default three, one
transform over that order's rays) and for a gold conductor (RGB weights differ: 3 per
order), as an ensemble's run makes them (first moments only) and as a single
realisation's (with the order-2L transforms of w² for its ray errors: 1 for mirror
weights, which are their own squares, 3 + 3 for gold), next to the time of tracing the
batch, and for comparison the
direct method (the explicit (n, (L + 1)²) basis and a matrix product per moment). With
``--write``
the Markdown replaces the section between the ``sh-cost`` markers in
docs/performance.md.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import time
from pathlib import Path

import numpy as np

from microsim.bench import median_time
from microsim.files import write_section
from microsim.geometry import direction
from microsim.kernel.beam import CELLS, beam_origins
from microsim.kernel.packing import FacetMaterials
from microsim.materials import Conductor, Mirror
from microsim.measurement.goniometer import BATCH, Sums
from microsim.measurement.paths import trace_paths
from microsim.measurement.scene import PeriodicScene
from microsim.recipe import load
from microsim.surfaces import build_tile
from microsim.tables import sh
from microsim.tables.binning import HemisphereBins

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "performance.md"
ORDERS = (0, 8, 16, 32, 64)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("recipe", nargs="?", default=str(ROOT / "surfaces/gaussian-0.3.toml"))
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--write", action="store_true")
    args = parser.parse_args()
    loadavg = os.getloadavg()[0]
    recipe = load(args.recipe)
    tile = build_tile(recipe.surface)
    bins = HemisphereBins(recipe.table.theta_bins, recipe.table.phi_bins)
    wi = direction(math.radians(30.0), 0.0)
    gold = Conductor()
    rows = []
    with PeriodicScene(tile, None) as scene:
        for name, material in (("mirror", Mirror()), ("gold conductor", gold)):
            facets = FacetMaterials(tile.material, tile.parts,
                                    {p: material for p in tile.parts})
            seed = np.random.SeedSequence(1)
            u = np.random.default_rng(seed).random((BATCH, 2))
            origins = beam_origins(u, scene.period, scene.z_top, CELLS)

            def trace(facets=facets, origins=origins, seed=seed):
                return trace_paths(scene, facets, origins, np.broadcast_to(-wi, (BATCH, 3)),
                                   16, seed)

            t_trace = median_time(trace, args.repeats)
            paths = trace()
            index = np.where(paths.order > 0, bins.index(paths.direction), -1)
            for order in ORDERS:
                def accumulate(single: bool, order=order, paths=paths) -> None:
                    Sums(bins.size, order, sh_ray_variance=single).add(paths, bins, 0.0,
                                                                       scene.map)

                rows.append((name, order, median_time(lambda: accumulate(False),
                                                      args.repeats),
                             median_time(lambda: accumulate(True), args.repeats), t_trace))
        loc = sh.angles(paths.direction[index >= 0])
        w = paths.weight[index >= 0]
        w = np.concatenate([w, 0.5 * w], axis=1)           # six different columns

        def explicit(order: int = 32) -> None:
            y = sh.basis(order, np.cos(loc[:, 0]), loc[:, 1])
            y.T @ w, (y * y).T @ (w * w)

        def fast(order: int = 32) -> None:
            sh.moments(loc, w, order)

        direct = [(order, median_time(lambda o=order: explicit(o), 3),
                   median_time(lambda o=order: fast(o), args.repeats)) for order in (16, 32)]
    base = {name: t for name, order, t, _, _ in rows if order == 0}
    lines = [
             f"`python scripts/sh_cost.py --write` ({platform.machine()}, "
             f"{time.strftime('%Y-%m-%d')}, load average {loadavg:.1f} on {os.cpu_count()} "
             f"CPUs before the run): one batch of {BATCH} rays of "
             f"`{Path(args.recipe).name}` at θi = 30°, 16 bounces; median of "
             f"{args.repeats}. `add` is the per-batch accumulation (bins, and the harmonics "
             "when the order is > 0), as an ensemble's run makes it (first moments) and as "
             "a single realisation's (with the order-2L second moments); the extra is over "
             "the bins alone; tracing is `trace_paths` on every core.", "",
             "| facets | order | `add` per batch, ensemble | extra for the harmonics "
             "| extra / tracing | one realisation: extra | extra / tracing "
             "| tracing the batch |", "| --- | --- | --- | --- | --- | --- | --- | --- |"]
    for name, order, t, t_single, t_trace in rows:
        extra, single = t - base[name], t_single - base[name]
        lines.append(f"| {name} | {order} | {1000 * t:.1f} ms | {1000 * extra:.1f} ms | "
                     f"{100 * extra / t_trace:.0f}% | {1000 * single:.1f} ms | "
                     f"{100 * single / t_trace:.0f}% | {1000 * t_trace:.1f} ms |")
    lines += ["", "Projecting the same batch (escaping rays, six weight columns, RGB all "
              "different) with the first and second moments:", "",
              "| order | explicit basis + matrix products "
              "| ducc0 (`sh.moments`, orders L and 2L, one thread) |",
              "| --- | --- | --- |"]
    lines += [f"| {order} | {1000 * te:.0f} ms | {1000 * tf:.0f} ms |"
              for order, te, tf in direct]
    text = "\n".join(lines)
    print(text)
    if args.write:
        write_section(DOC, "sh-cost", text, heading="## Spherical harmonics: cost per batch")
        print(f"wrote {DOC}")


if __name__ == "__main__":
    main()
