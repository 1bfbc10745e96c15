"""What the multiple-scattering reference (Heitz et al. 2016's random walk) costs.

Usage::

    python scripts/bench_multiple_scattering.py [--repeats 5] [--write]

Times (median of the repeats, one thread: the walk is numpy) the walks per second of
``SmithMultipleScattering`` run until they leave (``albedo``) for Beckmann and GGX at
α = 0.3 and 1.0, θi = 30°, F = 1, with the mean scattering order; and the bin averages of
``microsim demo``'s comparison (α = 0.29, 32 × 64 bins, 64 walks per bin, one incidence).
With ``--write`` the Markdown replaces the section between the
``multiple-scattering-cost`` markers in docs/performance.md.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import time
from pathlib import Path

import numpy as np

from microsim.analytic.multiple_scattering import SmithMultipleScattering
from microsim.analytic.ndf import GGX, Beckmann
from microsim.bench import median_time
from microsim.files import write_section
from microsim.geometry import direction
from microsim.tables.binning import HemisphereBins

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "performance.md"
WALKS = 100_000


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--write", action="store_true")
    args = parser.parse_args()
    loadavg = os.getloadavg()[0]
    wi = direction(math.radians(30.0), 0.0)
    rows = []
    for name, cls in (("Beckmann", Beckmann), ("GGX", GGX)):
        for alpha in (0.3, 1.0):
            model = SmithMultipleScattering(cls(alpha), seed=1)
            t = median_time(lambda m=model: m.albedo(wi, WALKS, [(1, None)]), args.repeats)
            walks = model.walk(np.broadcast_to(wi, (WALKS, 3)), None, rows=64).escaped
            mean_order = float((walks[..., 0] * np.arange(1, 65)).sum() / WALKS)
            rows.append((name, alpha, WALKS / t, mean_order))
    bins = HemisphereBins(32, 64)
    demo = SmithMultipleScattering(Beckmann(0.291), samples=64, seed=1)
    t_demo = median_time(lambda: demo.random_bin_average(wi, bins.theta_edges,
                                                         bins.phi_edges), args.repeats)
    lines = [
             f"`python scripts/bench_multiple_scattering.py --write` "
             f"({platform.machine()}, {time.strftime('%Y-%m-%d')}, load average "
             f"{loadavg:.1f} on {os.cpu_count()} CPUs before the run; median of "
             f"{args.repeats}; one thread): walks of `SmithMultipleScattering` from θi = 30°, "
             "F = 1, until they leave.", "",
             "| NDF | α | walks per second | mean scattering order |",
             "| --- | --- | --- | --- |"]
    lines += [f"| {name} | {alpha} | {rate:,.0f} | {order:.2f} |"
              for name, alpha, rate, order in rows]
    lines += ["", f"`microsim demo`'s comparison of one incidence with `beckmann-ms` "
              f"(α = 0.291, 32 × 64 bins, 64 walks per bin: {bins.size * 64:,} walks with "
              f"next-event estimates): {t_demo:.2f} s."]
    text = "\n".join(lines)
    print(text)
    if args.write:
        write_section(DOC, "multiple-scattering-cost", text,
                      heading="## Multiple-scattering reference: cost")
        print(f"wrote {DOC}")


if __name__ == "__main__":
    main()
