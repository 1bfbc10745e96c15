"""Is the surface's variance inflation one number per incidence? The measurement behind the
moderated ensemble error (docs/ensembles.md).

Usage::

    python scripts/inflation_spread.py [--realisations 8] [--rays 200000]

Simulates ``surfaces/gaussian-0.3.toml`` at θi = 0, 45, 75° with ``--realisations`` tiles
sharing ``--rays`` rays per direction (32 × 64 bins, harmonics to order 16), and prints
for the single-scattering lobe bins of each incidence, and for the harmonic coefficients
by degree band, the spread of log(s² / u): s² the batch-means variance of the ensemble
mean over the realisations, u its ray part. Sampling alone gives var = ψ′((K − 1)/2);
a larger variance means the inflation s² / u differs between the quantities pooled.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from scipy.special import polygamma

from microsim.recipe import load
from microsim.simulation import Tiles, measure_ensemble, raw_sums
from microsim.tables.components import components_for
from microsim.tables.estimator import realisation_moments
from microsim.tables.sh import second_moments

ROOT = Path(__file__).resolve().parent.parent
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--realisations", type=int, default=8)
    parser.add_argument("--rays", type=int, default=200_000)
    args = parser.parse_args()
    k = args.realisations
    recipe = load(ROOT / "surfaces" / "gaussian-0.3.toml",
                  [f"simulation.theta_i={list(THETAS)}", f"simulation.realisations={k}",
                   f"simulation.rays={args.rays}", "table.sh_order=16"])
    measured = measure_ensemble(Tiles(recipe.surface), recipe.material,
                                recipe.simulation, recipe.table, keep_runs=True)
    raw = raw_sums(measured.runs, range(len(THETAS)), 1,
                   components_for(recipe.table.orders))
    rays = raw["realisation_rays"]
    m, v = realisation_moments(raw["sums"]["order1"], raw["sums_sq"]["order1"], rays)
    sm, sv = realisation_moments(raw["sh_sums"]["order1"],
                                 second_moments(raw["sh_sums_sq"]["order1"], 16), rays)
    degree = np.floor(np.sqrt(np.arange(sm.shape[-2]))).astype(int)
    print(f"{k} realisations, {args.rays:,} rays per direction; sampling alone: var log = "
          f"{float(polygamma(1, (k - 1) / 2)):.3f}")
    for l, theta in enumerate(THETAS):
        f = np.nanmean(m[:, l, 0, :, 0], axis=0)
        lobe = f >= 0.1 * f.max()
        med, var, n = spread(m[:, l, 0, :, 0], v[:, l, 0, :, 0], lobe)
        print(f"theta_i {theta:4.0f}: lobe bins: median inflation {med:5.2f}, var log "
              f"{var:.3f} over {n}")
        for lo, hi in ((1, 2), (3, 6), (7, 16)):
            med, var, n = spread(sm[:, l, 0, :, 0], sv[:, l, 0, :, 0],
                                 (degree >= lo) & (degree <= hi))
            print(f"              harmonics of degree {lo}-{hi}: median inflation {med:6.1f}, "
                  f"var log {var:.3f} over {n}")


if __name__ == "__main__":
    main()
