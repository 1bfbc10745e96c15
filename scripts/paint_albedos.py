"""The shipped paint recipes' albedos, as ``microsim simulate RECIPE --rays N`` gives them.

Usage::

    python scripts/paint_albedos.py [--rays 20000] [--threads 2] [--write]

Simulates ``surfaces/paint.toml`` and ``surfaces/paint-metallic.toml`` as the command does
with ``--rays N`` (the recipes' own seeds, realisations and incidences) and prints, per
recipe and incidence, the albedo (the mean over R, G and B, as ``simulate`` prints it), its
standard error and the weight lost. ``--write`` puts the numbers in docs/materials.md
(marked section ``paint-albedos``).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import numpy as np

import microsim
from microsim.files import measured_with, write_section

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "materials.md"
RECIPES = ("paint.toml", "paint-metallic.toml")


def measure(name: str, rays: int, threads: int | None) -> dict:
    """One recipe's incidences (degrees), RGB-mean albedo, its standard error (the
    channels' mean) and lost weight (the channels' mean), per incidence."""
    table = microsim.simulate(microsim.load_recipe(ROOT / "surfaces" / name,
                                                   [f"simulation.rays={rays}"]),
                              threads=threads)
    return {"recipe": name, "theta_i": np.degrees(table.theta_i).round(6).tolist(),
            "albedo": table.albedo[:, 0].mean(axis=-1).tolist(),
            "albedo_err": table.albedo_err[:, 0].mean(axis=-1).tolist(),
            "lost": table.lost_energy[:, 0].mean(axis=-1).tolist()}


def sentence(r: dict, rays: int) -> str:
    """``microsim simulate surfaces/NAME --rays N``: its albedos, errors and loss."""
    albedos = ", ".join(f"{a:.3f}" for a in r["albedo"])
    degrees = ", ".join(f"{t:g}" for t in r["theta_i"])
    return (f"`microsim simulate surfaces/{r['recipe']} --rays {rays}`: albedo {albedos} "
            f"(RGB mean, ± {min(r['albedo_err']):.3f}–{max(r['albedo_err']):.3f}) at "
            f"{degrees}°, lost weight at most {max(r['lost']):.1e}.")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--rays", type=int, default=20_000)
    parser.add_argument("--threads", type=int, default=None)
    parser.add_argument("--write", action="store_true",
                        help="write the numbers into docs/materials.md")
    args = parser.parse_args()
    load_before = os.getloadavg()[0]
    rows = [measure(name, args.rays, args.threads) for name in RECIPES]
    print(json.dumps(rows, indent=2))
    if args.write:
        text = "\n".join([f"{measured_with(__file__, sys.argv[1:], load_before)}:", "",
                          *(f"- {sentence(r, args.rays)}" for r in rows)])
        write_section(DOC, "paint-albedos", text)


if __name__ == "__main__":
    main()
