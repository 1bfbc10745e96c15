"""Albedo per scattering order of ray-traced Gaussian tiles against Heitz et al. 2016.

For each surface seed, simulates a Gaussian tile with mirror facets (``[table] orders``
components) and compares the albedo of every order with the random walk's at the tile's
realised roughness (``SmithMultipleScattering.albedo``, escape statistics). Prints one row
per tile and incidence (simulated albedo ± ray error, reference ± its error, residual), then
per incidence and order the mean residual over tiles with its standard error and the
spread between tiles: what a test of one tile must allow (tests/test_orders.py cites it).

    python scripts/order_albedo_residual.py --alpha 0.6 --theta 0,30 --seeds 8 [--write]

``--write`` puts the summary into docs/compare.md: a run at one incidence into the marked
section ``order_albedo_residual-offset`` (the order-2 offset, the test's), a run at several
into ``order_albedo_residual-orders`` (a table of every order per incidence).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from pathlib import Path

import numpy as np

from microsim.analytic.multiple_scattering import SmithMultipleScattering
from microsim.analytic.ndf import Beckmann
from microsim.files import measured_with, write_section
from microsim.geometry import direction
from microsim.measurement.simulation import simulate
from microsim.recipe import resolve
from microsim.surfaces import build_tile
from microsim.tables.components import order_range

DOC = Path(__file__).resolve().parent.parent / "docs" / "compare.md"


def residuals(alpha: float, thetas: list[float], seed: int, resolution: int, rays: int,
              orders: int, walks: int) -> list[dict]:
    """One tile's rows: per incidence, simulated and reference albedo of each order."""
    recipe = resolve({
        "surface": {"kind": "gaussian", "alpha": alpha, "resolution": resolution,
                    "seed": seed},
        "simulation": {"theta_i": thetas, "rays": rays, "seed": seed},
        "table": {"theta_bins": 8, "phi_bins": 16, "sh_order": 0, "orders": orders}})
    tile = build_tile(recipe.surface)
    table = simulate(tile, recipe.material, recipe.simulation, recipe.table)
    realised = tile.facts.alpha_realised.alpha
    reference = SmithMultipleScattering(Beckmann(realised), seed=seed)
    rows = []
    for k, theta in enumerate(thetas):
        ref, ref_err = reference.albedo(direction(math.radians(theta), 0.0), walks,
                                        [order_range(c) for c in table.components[1:]])
        for j, c in enumerate(table.components[1:]):
            sim, err = table[c].albedo[k, 0, 1], table[c].albedo_err[k, 0, 1]
            rows.append({"seed": seed, "alpha_realised": realised, "theta_i": theta,
                         "component": c, "sim": sim, "sim_err": err, "ref": ref[j, 0],
                         "ref_err": ref_err[j, 0], "residual": sim - ref[j, 0]})
    return rows


def setup(args: argparse.Namespace, rows: list[dict]) -> str:
    """What was simulated and against what, for a section's opening sentence."""
    ref_err = max(r["ref_err"] for r in rows)
    return (f"Gaussian tiles of α = {args.alpha:g} (target), mirror facets, "
            f"{args.resolution}², {args.rays:,} rays, θi = "
            f"{', '.join(f'{t:g}' for t in sorted({r['theta_i'] for r in rows}))}°, surface "
            f"seeds 0–{args.seeds - 1}; reference: {args.walks:,} walks at each tile's "
            f"realised α (its error at most {ref_err:.4f})")


def offset_section(args: argparse.Namespace, rows: list[dict], summary: list[dict],
                   load: float) -> str:
    """The order-2 residual at one incidence: mean ± its error, spread, ray noise."""
    s = next(x for x in summary if x["component"] == "order2")
    two = [r for r in rows if r["component"] == "order2"]
    alphas = [r["alpha_realised"] for r in two]
    sims = [r["sim"] for r in two]
    ref = float(np.mean([r["ref"] for r in two]))
    return (f"{measured_with(__file__, sys.argv[1:], load)}: {setup(args, rows)}. The "
            f"order-2 albedo ({min(sims):.3f}–{max(sims):.3f}; the realised α varies "
            f"{min(alphas):.2f}–{max(alphas):.2f} between these small tiles) lies "
            f"**{s['mean_residual']:+.4f} ± {s['mean_residual_err']:.4f}** from the "
            f"reference on average ({100 * s['mean_residual'] / ref:+.0f}% of it), with a "
            f"spread of {s['spread']:.4f} between tiles (ray noise {s['ray_noise']:.4f} of "
            "it).")


def orders_section(args: argparse.Namespace, rows: list[dict], summary: list[dict],
                   load: float) -> str:
    """A row per incidence: each order's mean simulated and reference albedo over the
    tiles and the mean residual ± its standard error."""
    components = list(dict.fromkeys(r["component"] for r in rows))
    thetas = list(dict.fromkeys(r["theta_i"] for r in rows))
    lines = [f"{measured_with(__file__, sys.argv[1:], load)}: {setup(args, rows)}; per "
             "incidence and order the mean over tiles, and the mean residual simulated − "
             "reference ± its standard error.", "",
             "| θi | " + " | ".join(f"{c}: sim / walk | residual" for c in components) + " |",
             "| --- |" + " --- | --- |" * len(components)]
    ratio = {c: [] for c in components}
    for theta in thetas:
        cells = []
        for c in components:
            mine = [r for r in rows if r["theta_i"] == theta and r["component"] == c]
            sim, ref = np.mean([r["sim"] for r in mine]), np.mean([r["ref"] for r in mine])
            s = next(x for x in summary if x["theta_i"] == theta and x["component"] == c)
            digits = 3 if ref > 0.05 else 4
            cells += [f"{sim:.{digits}f} / {ref:.{digits}f}",
                      f"{s['mean_residual']:+.4f} ± {s['mean_residual_err']:.4f}"]
            ratio[c].append(sim / ref)
        lines.append(f"| {theta:g}° | " + " | ".join(cells) + " |")
    lines += ["", "Simulated over reference, from the lowest to the highest incidence: "
              + "; ".join(f"{c} " + ", ".join(f"{q:.2f}" for q in ratio[c])
                          for c in components) + "."]
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--alpha", type=float, default=0.6)
    parser.add_argument("--theta", default="0,30", help="incidences, degrees")
    parser.add_argument("--seeds", type=int, default=8)
    parser.add_argument("--resolution", type=int, default=128)
    parser.add_argument("--rays", type=int, default=65536)
    parser.add_argument("--orders", type=int, default=3)
    parser.add_argument("--walks", type=int, default=400_000)
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--write", action="store_true",
                        help="write the summary into docs/compare.md")
    args = parser.parse_args()
    load = os.getloadavg()[0]
    thetas = [float(t) for t in args.theta.split(",")]
    rows = [r for s in range(args.seeds) for r in residuals(
        args.alpha, thetas, s, args.resolution, args.rays, args.orders, args.walks)]
    summary = []
    for theta in thetas:
        for c in dict.fromkeys(r["component"] for r in rows):
            res = np.array([r["residual"] for r in rows
                            if r["theta_i"] == theta and r["component"] == c])
            noise = np.array([math.hypot(r["sim_err"], r["ref_err"]) for r in rows
                              if r["theta_i"] == theta and r["component"] == c])
            summary.append({"theta_i": theta, "component": c, "tiles": len(res),
                            "mean_residual": res.mean(),
                            "mean_residual_err": res.std(ddof=1) / math.sqrt(len(res)),
                            "spread": res.std(ddof=1), "ray_noise": float(noise.mean())})
    if args.write:
        name, text = (("order_albedo_residual-offset", offset_section(args, rows, summary, load))
                      if len(thetas) == 1 else
                      ("order_albedo_residual-orders", orders_section(args, rows, summary, load)))
        write_section(DOC, name, text)
    if args.json:
        print(json.dumps({"rows": rows, "summary": summary}, indent=2, default=float))
        return
    print(f"Gaussian tiles alpha {args.alpha} (target), {args.resolution}^2, "
          f"{args.rays} rays; reference: {args.walks} walks at the realised alpha")
    for r in rows:
        print(f"seed {r['seed']:2d} alpha {r['alpha_realised']:.4f} theta_i "
              f"{r['theta_i']:4.0f} {r['component']:>8}: sim {r['sim']:.4f} ± "
              f"{r['sim_err']:.4f}  ref {r['ref']:.4f} ± {r['ref_err']:.4f}  "
              f"residual {r['residual']:+.4f}")
    print("per incidence and order, over tiles: mean residual ± its standard error; "
          "spread between tiles; mean ray noise of one tile")
    for s in summary:
        print(f"theta_i {s['theta_i']:4.0f} {s['component']:>8}: "
              f"{s['mean_residual']:+.4f} ± {s['mean_residual_err']:.4f}; spread "
              f"{s['spread']:.4f}; ray noise {s['ray_noise']:.4f}")


if __name__ == "__main__":
    main()
