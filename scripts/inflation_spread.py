"""Is the surface's variance inflation one number per incidence? The measurement behind the
moderated ensemble error (docs/ensembles.md).

Usage::

    python scripts/inflation_spread.py [--realisations 8] [--rays 1600000 200000] [--write]

Simulates ``surfaces/gaussian-0.3.toml`` at θi = 0, 45, 75° with ``--realisations`` tiles
sharing each of ``--rays`` rays per direction (32 × 64 bins, no harmonics), and prints for
the single-scattering lobe bins of each incidence the median inflation s² / u and the
variance of log(s² / u): s² the batch-means variance of the ensemble mean over the
realisations, u its ray part. Sampling alone gives var = ψ′((K − 1)/2); a larger variance
means the inflation differs between the bins pooled. ``--write`` puts the table into
docs/ensembles.md (marked section ``inflation-spread``). Seconds on 2 cores.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np
from scipy.special import polygamma

from microsim.files import measured_with, write_section
from microsim.measurement.simulation import Tiles, measure_ensemble, raw_sums
from microsim.recipe import load
from microsim.tables.components import components_for
from microsim.tables.estimator import realisation_moments

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "ensembles.md"
THETAS = (0.0, 45.0, 75.0)


def spread(m: np.ndarray, v: np.ndarray, select: np.ndarray) -> tuple[float, float, int]:
    """Median inflation, variance of its log, count, over the selected quantities."""
    k = len(m)
    s2 = m.var(axis=0, ddof=1) / k
    u = np.nansum(v, axis=0) / k**2
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = (s2 / u)[select]
    ratio = ratio[np.isfinite(ratio) & (ratio > 0)]
    return float(np.median(ratio)), float(np.log(ratio).var()), ratio.size


def lobe_spreads(k: int, rays: int) -> list[tuple[float, float, int]]:
    """Per incidence of ``THETAS``: ``spread`` over the single-scattering lobe bins (green
    channel) of ``k`` realisations sharing ``rays`` rays per direction."""
    recipe = load(ROOT / "surfaces" / "gaussian-0.3.toml",
                  [f"simulation.theta_i={list(THETAS)}", f"simulation.realisations={k}",
                   f"simulation.rays={rays}", "table.sh_order=0"])
    measured = measure_ensemble(Tiles(recipe.surface), recipe.material,
                                recipe.simulation, recipe.table, keep_runs=True)
    raw = raw_sums(measured.runs, range(len(THETAS)), 1,
                   components_for(recipe.table.orders))
    m, v = realisation_moments(raw.sums["order1"]["sums"], raw.sums["order1"]["sums_sq"],
                               raw.realisation_rays)
    out = []
    for l in range(len(THETAS)):
        f = np.nanmean(m[:, l, 0, :, 1], axis=0)
        out.append(spread(m[:, l, 0, :, 1], v[:, l, 0, :, 1], f >= 0.1 * f.max()))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--realisations", type=int, default=8)
    parser.add_argument("--rays", type=int, nargs="+", default=[1_600_000, 200_000])
    parser.add_argument("--write", action="store_true",
                        help="write the table into docs/ensembles.md")
    args = parser.parse_args()
    load_before = os.getloadavg()[0]
    k = args.realisations
    rows = []
    for rays in args.rays:
        cells = [f"{med:.1f}, {var:.3f} ({n})" for med, var, n in lobe_spreads(k, rays)]
        rows.append(f"| {k} × {rays // k:,} | {' | '.join(cells)} |")
        print(rows[-1], flush=True)
    text = "\n".join([
        f"{measured_with(__file__, sys.argv[1:], load_before)}: `surfaces/gaussian-0.3.toml`'s "
        f"256² tiles, single scattering, 32 × 64 bins, green channel; per incidence the "
        "median inflation s²/u over the lobe bins, the variance of log(s²/u) and (the bins). "
        f"Sampling alone gives ψ′({k - 1}/2) = {float(polygamma(1, (k - 1) / 2)):.3f}.", "",
        "| realisations × rays | " + " | ".join(f"θi = {t:g}°" for t in THETAS) + " |",
        "| --- |" + " --- |" * len(THETAS), *rows])
    if args.write:
        write_section(DOC, "inflation-spread", text)


if __name__ == "__main__":
    main()
