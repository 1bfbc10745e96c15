"""The shipped lower-level table, tables/reference/gaussian-0.3-facets.exr: what remaking it
costs, and how it compares with its analytic model (docs/materials.md).

Usage: python scripts/reference_facets.py [--write]

Runs ``microsim simulate surfaces/gaussian-0.3-facets.toml`` as a command (into a
temporary folder: the shipped table is left as it is) for its wall and CPU time and peak
memory, and ``microsim compare tables/reference/gaussian-0.3-facets.exr --model
beckmann --json`` (the table's total against Torrance-Sparrow + Beckmann +
height-correlated Smith at its realised α) for the median relative error over the lobe,
the z spread and the multiply scattered share per incidence, and the shipped table's own
median relative standard error over its lobe. ``--write`` puts them into
docs/materials.md (marked section ``reference_facets``).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from pathlib import Path

from microsim.bench import run_child
from microsim.files import measured_with, write_section
from microsim.tables.exr import read_table

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "materials.md"
RECIPE = "surfaces/gaussian-0.3-facets.toml"
TABLE = "tables/reference/gaussian-0.3-facets.exr"


def microsim(*argv: str) -> list[str]:
    """``microsim ARGV`` as the installed command runs it."""
    return [sys.executable, "-m", "microsim.cli", *argv]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true",
                        help="write the figures into docs/materials.md")
    args = parser.parse_args()
    before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as folder:
        made = run_child(microsim("simulate", str(ROOT / RECIPE), "-o",
                                  str(Path(folder) / "t.exr"), "--json"))
    run = json.loads(made.stdout)
    compared = json.loads(run_child(microsim("compare", str(ROOT / TABLE), "--model",
                                             "beckmann", "--json")).stdout)
    rows = [f"| {r['theta_i']:g}° | {100 * r['median_rel_error']:.1f}% | {r['z_std']:.2f} | "
            f"{100 * r['multiple_scattering_share']:.1f}% |" for r in compared["per_theta_i"]]
    text = "\n".join([
        f"{measured_with(__file__, sys.argv[1:], before)}. `microsim simulate {RECIPE}`: "
        f"{made.wall:.1f} s wall, {made.cpu:.1f} s of CPU, peak memory "
        f"{made.peak_gib:.2f} GiB ({run['realisations']} realisations, "
        f"{len(run['theta_i'])} incidences, {max(run['rays_per_direction']):,} rays per "
        f"incidence). `microsim compare {TABLE} --model beckmann` (the "
        f"{compared['component']} against Torrance-Sparrow + Beckmann + height-correlated "
        f"Smith at α {compared['params']['alpha']:.4f}), per incidence (the table's own "
        "median relative standard error over its lobe is "
        f"{100 * read_table(ROOT / TABLE).median_rel_stderr():.1f}%):", "",
        "| θi | median relative error (lobe) | z spread | multiply scattered share |",
        "| --- | --- | --- | --- |", *rows])
    print(text)
    if args.write:
        write_section(DOC, "reference_facets", text)


if __name__ == "__main__":
    main()
