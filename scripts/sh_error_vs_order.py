"""Spherical harmonics against the table, per order, for rough and smoother Gaussian surfaces.

Usage::

    python scripts/sh_error_vs_order.py [--rays 4000000] [--alphas 0.5,0.2]
        [--resolution 1024] [--write]

Simulates a Gaussian height field (default 1024², correlation length 8 cells: 128 per
side, so that the tile's own NDF realisation, which gives a 256² tile's lobe a fine
speckle of ~10% that no smooth series follows, stays small) with mirror facets at
θi = 0, 30, 60, 80° with harmonics of order 32 and a 32 × 64 table, and reports per
order the relative L2 error of f_r cos θo over the hemisphere and the lobe
(``microsim.tables.sh_error``), pooled over the incidences and per incidence, with the
table's noise floor, and the lowest order that reaches 5% (with no window and with
Lanczos σ-factors). With ``--write`` the Markdown
replaces the section between the ``sh-error-vs-order`` markers in docs/performance.md.
"""

from __future__ import annotations

import argparse
import platform
import time
from pathlib import Path

import numpy as np

from microsim.files import write_section
from microsim.measurement.simulation import simulate
from microsim.recipe import resolve
from microsim.surfaces import build_tile
from microsim.tables.sh_error import order_errors
from microsim.tables.table import BRDFTable, ComponentEstimate

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "performance.md"
THETA_I = [0.0, 30.0, 60.0, 80.0]
ORDERS = list(range(1, 33))
TARGET = 0.05


def incidence(table: BRDFTable, l: int) -> BRDFTable:
    """The table of incidence ``l`` alone."""
    rows = slice(l, l + 1)
    return BRDFTable(table.bins, table.theta_i[rows], table.phi_i, table.isotropic,
                     {c: ComponentEstimate(e.values[rows], e.errors[rows], e.albedo[rows],
                                           e.albedo_err[rows], sh=e.sh[rows],
                                           sh_err=e.sh_err[rows])
                      for c, e in table.estimates.items()},
                     table.rays[rows], table.lost_energy[rows], table.meta)


def needed(rows: list[dict], key: str) -> str:
    """The lowest order whose ``key`` is at most TARGET, or '> 32'."""
    hit = [r["order"] for r in rows if r[key] <= TARGET]
    return str(hit[0]) if hit else f"> {ORDERS[-1]}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--rays", type=int, default=4_000_000)
    parser.add_argument("--alphas", default="0.5,0.2")
    parser.add_argument("--resolution", type=int, default=1024)
    parser.add_argument("--write", action="store_true")
    args = parser.parse_args()
    lines = [
             f"`python scripts/sh_error_vs_order.py --rays {args.rays} --resolution "
             f"{args.resolution} --write` ({platform.machine()}, "
             f"{time.strftime('%Y-%m-%d')}): Gaussian {args.resolution}² tile, "
             f"mirror facets, θi = {', '.join(f'{t:g}' for t in THETA_I)}°, "
             f"{args.rays:,} rays per incidence, 32 × 64 bins, order-32 harmonics of the "
             "total. Relative L2 error of f_r cos θo against the bins, pooled over the "
             "incidences (per incidence: the order that reaches 5% over the hemisphere).",
             ""]
    for alpha in (float(a) for a in args.alphas.split(",")):
        surface = {"kind": "gaussian", "alpha": alpha, "resolution": args.resolution,
                   "seed": 1}
        recipe = resolve({"surface": surface,
                          "simulation": {"theta_i": THETA_I, "rays": args.rays, "seed": 1},
                          "table": {"theta_bins": 32, "phi_bins": 64, "sh_order": 32}})
        start = time.perf_counter()
        table = simulate(build_tile(recipe.surface), recipe.material,
                         recipe.simulation, recipe.table, recipe=recipe)
        wall = time.perf_counter() - start
        rows = order_errors(table, ORDERS)
        lanczos = order_errors(table, ORDERS, "lanczos")
        per = [needed(order_errors(incidence(table, l), ORDERS), "rel_l2_error")
               for l in range(len(THETA_I))]
        realised = table.meta.surface.alpha_realised.to_json()
        lines += [f"**α = {alpha:g}** (realised {realised:.3f}; simulated in {wall:.0f} s; "
                  f"table noise {100 * rows[0]['table_noise']:.2f}%): 5% over the "
                  f"hemisphere at order **{needed(rows, 'rel_l2_error')}** "
                  f"(lobe: {needed(rows, 'rel_l2_error_lobe')}; with Lanczos: "
                  f"{needed(lanczos, 'rel_l2_error')}); per incidence "
                  + ", ".join(f"{t:g}°: {o}" for t, o in zip(THETA_I, per, strict=True))
                  + ".", "",
                  "| order | hemisphere | lobe | Lanczos | SH noise | min f_r cos θo "
                  "(min/max) | Lanczos min/max | bytes |",
                  "| --- | --- | --- | --- | --- | --- | --- | --- |"]
        for r, w in zip(rows, lanczos, strict=True):
            if r["order"] in (1, 2, 4, 8, 12, 16, 20, 24, 28, 32):
                lines.append(
                    f"| {r['order']} | {100 * r['rel_l2_error']:.2f}% | "
                    f"{100 * r['rel_l2_error_lobe']:.2f}% | {100 * w['rel_l2_error']:.2f}% | "
                    f"{100 * r['sh_noise']:.2f}% | {r['min_value']:.3g} "
                    f"({r['min_relative']:.3f}) | {w['min_relative']:.4f} | {r['bytes']} |")
        lines.append("")
        print("\n".join(lines[-16:]), flush=True)
    text = "\n".join(lines).rstrip("\n")
    if args.write:
        write_section(DOC, "sh-error-vs-order", text,
                      heading="## Spherical harmonics: error against order")
        print(f"wrote {DOC}")


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
