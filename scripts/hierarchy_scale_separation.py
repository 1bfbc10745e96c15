"""What the scale separation of a hierarchy of scale costs: rough V-grooves simulated in
one level against the same grooves whose facets carry the table of their own roughness.

Usage::

    python scripts/hierarchy_scale_separation.py [--resolution 256] [--cells 4]
        [--grooves 4] [--slope 30] [--alpha 0.3] [--rays 60000] [--seed 11] [--json]
    python scripts/hierarchy_scale_separation.py --write

The one-level tile is ``vgroove`` with ``micro_alpha`` (gold facets); the lower level is
``microsim.surfaces.vgroove.face_roughness_tile``, the very field the faces carry laid
flat, simulated every 5 degrees from 0 to 85 (16 x 32 bins, ``--rays`` / 1.5 rays per
node); both upper tables have 8 x 16 bins and ``--rays`` rays per incidence (0, 30, 60
degrees, across the grooves). Prints ``microsim.comparison.difference.table_difference``
per incidence (docs/materials.md explains the figures). ``--write`` runs the defaults and
the variations of ``VARIATIONS`` instead (each flag changed alone; under a minute on 2
cores) and puts their table into docs/materials.md (marked section ``hierarchy-scale-separation``).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
from pathlib import Path

from microsim.comparison.difference import table_difference
from microsim.files import measured_with, write_section
from microsim.materials import Table, material_from_json
from microsim.measurement.simulation import simulate
from microsim.recipe import resolve
from microsim.settings import Simulation, TableSettings
from microsim.surfaces import build_tile
from microsim.surfaces.vgroove import face_roughness_tile
from microsim.tables.exr import write_table

DOC = Path(__file__).resolve().parent.parent / "docs" / "materials.md"
GOLD = {"kind": "conductor", "eta": [0.2, 0.92, 1.1], "k": [3.9, 2.45, 2.14]}
VARIATIONS = ((), ("--seed", "21"), ("--grooves", "1"), ("--grooves", "16"), ("--cells", "8"),
              ("--resolution", "512", "--rays", "160000"))
"""The flags of each row of the written table (the first, none: the defaults)."""


def parser() -> argparse.ArgumentParser:
    """The options of one measurement, and ``--json`` and ``--write``."""
    options = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    options.add_argument("--resolution", type=int, default=256)
    options.add_argument("--cells", type=float, default=4.0,
                         help="correlation length in grid steps along a face")
    options.add_argument("--grooves", type=int, default=4)
    options.add_argument("--slope", type=float, default=30.0, help="degrees")
    options.add_argument("--alpha", type=float, default=0.3)
    options.add_argument("--rays", type=int, default=60_000)
    options.add_argument("--seed", type=int, default=11)
    options.add_argument("--json", action="store_true")
    options.add_argument("--write", action="store_true",
                         help="measure VARIATIONS and write them into docs/materials.md")
    return options


def measure(args: argparse.Namespace) -> list[dict]:
    """``table_difference`` of the two-level table from the one-level one, per incidence,
    for one set of options."""
    n, s = args.resolution, math.radians(args.slope)
    surface = resolve({"surface": {
        "kind": "vgroove", "slope": args.slope, "grooves": args.grooves,
        "micro_alpha": args.alpha, "micro_resolution": n,
        "micro_correlation": args.cells / n / math.cos(s), "seed": args.seed}}).surface
    direct_tile = build_tile(surface)
    gold = {"base": material_from_json(GOLD)}
    low = simulate(face_roughness_tile(surface), gold,
                   Simulation(theta_i=tuple(range(0, 90, 5)), phi_i=(0.0,),
                              rays=int(args.rays / 1.5), bounces=16, seed=args.seed + 1),
                   TableSettings(theta_bins=16, phi_bins=32, sh_order=0))
    sim = Simulation(theta_i=(0.0, 30.0, 60.0), phi_i=(0.0,), rays=args.rays, bounces=16,
                     seed=args.seed + 2)
    grid = TableSettings(theta_bins=8, phi_bins=16, sh_order=0)
    direct = simulate(direct_tile, gold, sim, grid)
    plain = resolve({"surface": {"kind": "vgroove", "slope": args.slope,
                                 "grooves": args.grooves}}).surface
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "faces.exr"
        write_table(low, path)
        hier = simulate(build_tile(plain), {"base": Table(path=str(path))}, sim, grid)
    return table_difference(hier, direct)


def row(flags: tuple[str, ...], rows: list[dict]) -> str:
    """One line of the written table: per incidence the largest albedo difference over R,
    G, B, the L1 and the L1 of noise alone."""
    cells = [f"{max(abs(d) for d in r['albedo_difference']):.4f}, {100 * r['l1']:.1f}% "
             f"({100 * r['l1_noise']:.1f}%)" for r in rows]
    return f"| {'`' + ' '.join(flags) + '`' if flags else '(defaults)'} | {' | '.join(cells)} |"


def write() -> None:
    """Measure ``VARIATIONS`` and write their table into docs/materials.md."""
    before = os.getloadavg()[0]
    lines = []
    for flags in VARIATIONS:
        rows = measure(parser().parse_args(list(flags)))
        lines.append(row(flags, rows))
        print(lines[-1], flush=True)
    degrees = [f"θi = {r['theta_i']:g}°" for r in rows]
    text = "\n".join([
        f"{measured_with(__file__, sys.argv[1:], before)}; each row changes the defaults' "
        "flags as it says (seed 11, 4 grooves, 256² grid, τ = 4 grid steps, 60,000 rays):",
        "", f"| flags | {' | '.join(degrees)} |", f"| --- |{' --- |' * len(degrees)}",
        *lines])
    write_section(DOC, "hierarchy-scale-separation", text)


def main() -> None:
    args = parser().parse_args()
    if args.write:
        write()
        return
    rows = measure(args)
    if args.json:
        print(json.dumps(rows, indent=2))
        return
    print(f"{'theta_i':>7} {'max |albedo diff|':>18} {'L1':>7} {'noise L1':>9} {'z rms':>6}")
    for r in rows:
        worst = max(abs(d) for d in r["albedo_difference"])
        print(f"{r['theta_i']:7.1f} {worst:18.5f} {100 * r['l1']:6.2f}% "
              f"{100 * r['l1_noise']:8.2f}% {r['z_rms']:6.2f}")


if __name__ == "__main__":
    main()
