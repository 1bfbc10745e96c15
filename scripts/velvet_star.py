"""The star on a velvet sphere where it faces the camera is the noise of the table's first
θo rings (docs/render.md, "Stars and notches").

Usage::

    python scripts/velvet_star.py [--write]

Simulates ``surfaces/velvet.toml`` as ``microsim simulate`` does and prints, per
incidence, the median relative standard error of the lobe bins and, for each of the first
three θo rings (the wedges that meet where the sphere faces the camera), the χ²/dof of
the ring's bins against the ring's own mean with the bins' errors (the mean over R, G and
B of values and errors): about 1 when the spread around a ring is the bins' noise.
``--write`` puts the figures into docs/render.md (marked section ``velvet-star``).
Seconds on 2 cores.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

import microsim
from microsim.files import measured_with, write_section

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "render.md"
RINGS = 3


def ring_chi2(values: np.ndarray, errors: np.ndarray) -> float:
    """χ²/dof of one ring's bins (φ bins, RGB means) against their error-weighted mean."""
    weight = 1.0 / errors**2
    mean = np.sum(weight * values) / np.sum(weight)
    return float(np.sum(weight * (values - mean) ** 2) / (values.size - 1))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--write", action="store_true",
                        help="write the figures into docs/render.md")
    args = parser.parse_args()
    load_before = os.getloadavg()[0]
    table = microsim.simulate(microsim.load_recipe(ROOT / "surfaces" / "velvet.toml"))
    f = table["total"].values[:, 0].mean(axis=-1)          # (θi, θo bins, φo bins)
    e = table["total"].errors[:, 0].mean(axis=-1)
    lobe = table.lobe_mask("total")[:, 0]
    rows = []
    for a, theta in enumerate(np.degrees(table.theta_i)):
        rel = np.median(e[a][lobe[a]] / f[a][lobe[a]])
        chi2 = [ring_chi2(f[a, r], e[a, r]) for r in range(RINGS)]
        rows.append(f"| {theta:g}° | {100 * rel:.0f}% | "
                    + " | ".join(f"{c:.2f}" for c in chi2) + " |")
        print(rows[-1], flush=True)
    rays = max(d.rays for d in table.meta.directions)
    text = "\n".join([
        f"{measured_with(__file__, sys.argv[1:], load_before)}: `microsim simulate "
        f"surfaces/velvet.toml` ({rays:,} rays per incidence, "
        f"{int(table.realisations.max())} realisations, {table.bins.theta_bins} × "
        f"{table.bins.phi_bins} bins); per incidence the median relative standard error "
        "of the lobe bins, and the χ²/dof of each of the first three θo rings' bins "
        "against the ring's own mean (RGB means; about 1 for noise alone).", "",
        "| θi | median relative error (lobe) | ring 1 | ring 2 | ring 3 |",
        "| --- | --- | --- | --- | --- |", *rows])
    if args.write:
        write_section(DOC, "velvet-star", text)


if __name__ == "__main__":
    main()
