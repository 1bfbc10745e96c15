"""Lambertian V-grooves against Oren-Nayar: deviation per incidence angle.

Usage::

    python scripts/vgroove_oren_nayar.py [--alpha 0.8] [--rays 200000] [--write]

Grooves along y with slopes tan(s) drawn as |N(0, alpha^2 / 2)| (a Beckmann surface's
slope distribution across the grooves), Lambertian facets of albedo 0.8, lit across the
grooves (phi_i = 0). Oren-Nayar's full model (eq. 30 + 39) is evaluated with sigma = the
RMS slope angle of the grooves, averaged over the table's bins. Prints, per theta_i, the
median relative deviation over the lobe, the albedos, and the back/forward ratio at
theta_o = theta_i of simulation and model. ``--write`` puts the table in
docs/goniometer.md (marked section ``vgroove-oren-nayar``).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from pathlib import Path

import numpy as np

from microsim.analytic.brdf import OrenNayar
from microsim.comparison.metrics import bin_average, metrics
from microsim.files import measured_with, write_section
from microsim.geometry import direction
from microsim.measurement.simulation import simulate
from microsim.recipe import resolve
from microsim.surfaces import build_tile

DOC = Path(__file__).resolve().parent.parent / "docs" / "goniometer.md"


def markdown(rows: list[dict], head: str) -> str:
    """The section of docs/goniometer.md: ``head``, then a row per incidence."""
    lines = [head, "", "| θi | median relative deviation (lobe) | albedo sim / model | "
             "back/forward sim / model |", "| --- | --- | --- | --- |"]
    lines += [f"| {r['theta_i']:g}° | {100 * r['median_rel_dev']:.1f} % | "
              f"{r['albedo_sim']:.3f} / {r['albedo_model']:.3f} | "
              f"{r['back_over_forward_sim']:.2f} / {r['back_over_forward_model']:.2f} |"
              for r in rows]
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--alpha", type=float, default=0.8)
    parser.add_argument("--rays", type=int, default=200_000)
    parser.add_argument("--write", action="store_true",
                        help="write the table into docs/goniometer.md")
    args = parser.parse_args()
    load_before = os.getloadavg()[0]
    theta = [0.0, 30.0, 60.0, 75.0]
    recipe = resolve({"surface": {"kind": "vgroove", "alpha": args.alpha, "grooves": 256,
                                  "seed": 1},
                      "material": {"kind": "lambertian", "albedo": 0.8},
                      "simulation": {"theta_i": theta, "rays": args.rays, "seed": 1},
                      "table": {"theta_bins": 8, "phi_bins": 16}})
    tile = build_tile(recipe.surface)
    sigma = math.radians(tile.facts.slopes_deg["rms"])
    table = simulate(tile, recipe.material, recipe.simulation, recipe.table)
    model = OrenNayar(sigma, 0.8, "full")
    rows = []
    for l, t in enumerate(theta):
        wi = direction(np.radians(t), 0.0)
        expected = bin_average(model, wi, table.bins.theta_edges, table.bins.phi_edges)
        sim = table["total"].values[l, 0]
        m = metrics(sim, table["total"].errors[l, 0], expected,
                    table.bins.projected_solid_angle)
        it = min(int(np.sin(np.radians(max(t, 30.0))) ** 2 * 8), 7)
        rows.append({"theta_i": t, "median_rel_dev": m.median_rel_error,
                     "albedo_sim": m.albedo_sim[0], "albedo_model": m.albedo_model[0],
                     "back_over_forward_sim": sim[it, [0, 15], 0].mean()
                     / sim[it, [7, 8], 0].mean(),
                     "back_over_forward_model": expected[it, [0, 15], 0].mean()
                     / expected[it, [7, 8], 0].mean()})
    print(json.dumps({"sigma_rad": sigma, "rows": rows}, indent=2))
    if args.write:
        head = (f"{measured_with(__file__, sys.argv[1:], load_before)}: 256 grooves, α = "
                f"{args.alpha:g}, {args.rays:,} rays per incidence, 8 × 16 bins; σ = "
                f"{sigma:.2f} rad, the grooves' RMS slope angle.")
        write_section(DOC, "vgroove-oren-nayar", markdown(rows, head))


if __name__ == "__main__":
    main()
