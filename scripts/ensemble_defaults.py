"""How much the surface's realisations add to a shipped recipe's error: the data behind the
default ``simulation.realisations`` of each random generator.

Usage::

    python scripts/ensemble_defaults.py [RECIPE ...] [--probe 8] [--write]

Each recipe (default: every shipped recipe with random geometry other than the Gaussian
ones, whose default follows the accuracy study of ``scripts/ensemble_accuracy.py``) is
simulated with ``--probe`` realisations sharing its ``rays`` (harmonics off). Per
direction the table's pooled variance inflation ρ (ensemble variance of a lobe bin over
its ray variance, ``microsim.tables.estimator``) at n = rays / probe rays per realisation
gives the inflation one tile with all the rays would have, ρ₁ = 1 + probe (ρ − 1) (the
tile part τ² does not depend on n, the ray part scales as 1/n). ρ₁ − 1 realisations make
the realisations' share of the variance equal to the rays' at the recipe's rays: the
default is the power of two at or above the largest over directions, and at least
``MIN_REALISATIONS``. A direction whose lobe shows no spread at all (ρ undefined, e.g. a
flat top's mirror peak) is left out. With ``--write``
the Markdown replaces the section between the ``ensemble-defaults`` markers in
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

from microsim.files import write_section
from microsim.measurement.simulation import simulate_recipe
from microsim.recipe import load

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "performance.md"
MIN_REALISATIONS = 4
"""Fewest realisations a default gives a random surface: the moderated ensemble error needs
three to estimate its own degrees of freedom (``microsim.tables.estimator``)."""
RECIPES = ("velvet.toml", "paint.toml", "paint-metallic.toml", "vgroove-rough-direct.toml")


def probe(path: Path, k: int) -> dict:
    """Inflation per direction of a recipe simulated with ``k`` realisations."""
    recipe = load(path, [f"simulation.realisations={k}", "table.sh_order=0"])
    start = time.perf_counter()
    table = simulate_recipe(recipe)
    seconds = time.perf_counter() - start
    inflation = table["total"].inflation
    rho = np.array([np.median(x[np.isfinite(x)]) if np.isfinite(x).any() else np.nan
                    for x in inflation.reshape(-1, 3)])
    one = 1 + k * (rho - 1)
    need = float(np.nanmax(one - 1))
    default = recipe.surface.realisations()
    return {"recipe": path.name, "rays": int(recipe.simulation.rays),
            "directions": [f"{d.theta_i:g}/{d.phi_i:g}" for d in
                           table.meta.directions],
            "rho": rho, "rho_one": one, "need": need,
            "suggested": max(MIN_REALISATIONS, 2 ** math.ceil(math.log2(max(need, 1.0)))),
            "default": default, "seconds": seconds}


def markdown(rows: list[dict], k: int) -> str:
    lines = [f"`python scripts/ensemble_defaults.py --probe {k} --write` "
             f"({platform.machine()}, {time.strftime('%Y-%m-%d')}, load average "
             f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs): each recipe with {k} "
             "realisations sharing its rays; ρ is the pooled inflation of the total's lobe "
             "bins (ensemble over ray variance, median over RGB) at rays / "
             f"{k} rays per realisation, ρ₁ = 1 + {k} (ρ − 1) that of one tile with all the "
             "rays.", "",
             "| recipe | rays | directions (θi/φi) | ρ per direction | ρ₁ per direction | "
             "realisations balancing rays (largest ρ₁ − 1) | suggested | default |",
             "| --- | --- | --- | --- | --- | --- | --- | --- |"]
    for r in rows:
        lines.append(f"| `{r['recipe']}` | {r['rays']:,} | {', '.join(r['directions'])} | "
                     f"{', '.join(f'{x:.2f}' for x in r['rho'])} | "
                     f"{', '.join(f'{x:.1f}' for x in r['rho_one'])} | {r['need']:.1f} | "
                     f"{r['suggested']} | {r['default']} |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("recipes", nargs="*", default=[str(ROOT / "surfaces" / r)
                                                       for r in RECIPES])
    parser.add_argument("--probe", type=int, default=8)
    parser.add_argument("--write", action="store_true")
    args = parser.parse_args()
    rows = []
    for path in args.recipes:
        row = probe(Path(path), args.probe)
        print(f"{row['recipe']}: rho {np.round(row['rho'], 2)}, rho_1 "
              f"{np.round(row['rho_one'], 1)}, balancing K {row['need']:.1f} -> "
              f"{row['suggested']} (default {row['default']}), {row['seconds']:.0f} s",
              flush=True)
        rows.append(row)
    text = markdown(rows, args.probe)
    print(text)
    if args.write:
        write_section(DOC, "ensemble-defaults", text,
                      heading="### The default count per generator")


if __name__ == "__main__":
    main()
