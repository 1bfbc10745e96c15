"""How closely Mitsuba 3 reproduces a table exported as an RGL ``.bsdf`` file.

Usage: python scripts/rgl_roundtrip.py [--pairs 500] [--resolutions 32,64]

Writes a smooth table (a conductor Beckmann α = 0.45 lobe averaged over 32 × 64 bins at
θi = 0, 20, 40, 60, 75°, as tests/test_export.py does), exports it at each resolution,
loads it with Mitsuba's ``measured`` plugin and prints the relative difference of
Mitsuba's eval to ``read_table().eval · cos θo`` at random direction pairs in the lobe
(docs/table-format.md quotes the figures).
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from microsim.analytic.brdf import TorranceSparrow
from microsim.analytic.ndf import Beckmann
from microsim.compare import model_table
from microsim.tables.binning import HemisphereBins
from microsim.tables.export import rgl_through_mitsuba, write_rgl
from microsim.tables.exr import read_table, write_table
from microsim.tables.table import BRDFTable

THETA_I = np.radians([0.0, 20.0, 40.0, 60.0, 75.0])


def smooth_table() -> BRDFTable:
    """The analytic conductor Beckmann α = 0.45 lobe, bin-averaged."""
    model = TorranceSparrow(Beckmann(0.45), fresnel=("conductor", np.array([0.2, 0.9, 1.1]),
                                                     np.array([3.9, 2.4, 2.1])))
    return model_table(model, THETA_I, HemisphereBins(32, 64))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=500)
    parser.add_argument("--resolutions", default="32,64")
    parser.add_argument("--seed", type=int, default=7)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "t.exr"
        write_table(smooth_table(), path)
        table = read_table(path)
        print(f"{'H':>4} {'pairs':>6} {'median':>8} {'p90':>8} {'max':>8}")
        for h in (int(r) for r in args.resolutions.split(",")):
            out = Path(tmp) / f"t{h}.bsdf"
            write_rgl(table, out, resolution=h)
            ref, got = rgl_through_mitsuba(table, out, args.pairs,
                                           np.random.default_rng(args.seed))
            rel = np.abs(got / ref - 1).ravel()
            print(f"{h:4d} {args.pairs:6d} {100 * np.median(rel):7.2f}% "
                  f"{100 * np.percentile(rel, 90):7.2f}% {100 * rel.max():7.2f}%")


if __name__ == "__main__":
    main()
