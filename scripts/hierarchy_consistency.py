"""Two tables of the same surface against each other: a hierarchy of scale and its
one-level reference (docs/materials.md).

Usage::

    microsim simulate surfaces/gaussian-0.3-facets.toml
    microsim simulate surfaces/vgroove-rough-facets.toml
    microsim simulate surfaces/vgroove-rough-direct.toml
    python scripts/hierarchy_consistency.py tables/vgroove-rough-facets.exr \\
        tables/vgroove-rough-direct.exr [--json] [--write]

Prints per incidence the albedos (mean over RGB) and their difference with its standard
error, the share of reflected energy the first table places differently from the second
(L1), the L1 that noise alone gives, and the RMS z of the bin differences.
``--write`` puts the table of L1 and RMS z per incidence (the shipped two-level
example against its one-level reference, as the usage above makes them) in
docs/materials.md (marked section ``hierarchy-consistency``).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections import defaultdict
from pathlib import Path

from microsim.comparison.difference import table_difference
from microsim.files import measured_with, write_section
from microsim.tables.exr import read_table

DOC = Path(__file__).resolve().parent.parent / "docs" / "materials.md"


def markdown(rows: list[dict], head: str) -> str:
    """docs/materials.md's section: ``head``, then per theta_i L1, its noise and RMS z at
    each phi_i."""
    by_theta: dict[float, list[dict]] = defaultdict(list)
    for r in rows:
        by_theta[r["theta_i"]].append(r)

    def joined(group: list[dict], fmt: str, key: str) -> str:
        texts = [fmt.format(r[key]) for r in group]
        return texts[0] if len(set(texts)) == 1 else ", ".join(texts)

    lines = [head, "", "| θi | φi | L1 | L1 of noise alone | RMS z |",
             "| --- | --- | --- | --- | --- |"]
    for theta, group in by_theta.items():
        phis = ", ".join(f"{r['phi_i']:g}°" for r in group)
        lines.append(f"| {theta:g}° | {phis} | {joined(group, '{:.1%}', 'l1')} | "
                     f"{joined(group, '{:.1%}', 'l1_noise')} | "
                     f"{joined(group, '{:.1f}', 'z_rms')} |")

    def albedos(key: str) -> str:
        values = [sum(r[key]) / len(r[key]) for r in rows]
        return f"{min(values):.4f}–{max(values):.4f}"

    lines += ["", f"Albedos (mean over the channels), over the incidences: {albedos('albedo_a')} "
              f"in the first table, {albedos('albedo_b')} in the second."]
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("a", help="table (.exr), e.g. the two-level simulation")
    parser.add_argument("b", help="table (.exr) with the same axes, e.g. the one-level one")
    parser.add_argument("--component", choices=("total", "single"), default="total")
    parser.add_argument("--json", action="store_true", help="print JSON")
    parser.add_argument("--write", action="store_true",
                        help="write the L1 table into docs/materials.md")
    args = parser.parse_args()
    load_before = os.getloadavg()[0]
    a, b = read_table(args.a), read_table(args.b)
    rows = table_difference(a, b, args.component)
    if args.write:
        head = (f"{measured_with(__file__, sys.argv[1:], load_before)}: {args.component}, "
                + "; ".join(f"`{path}` {int(t.rays.max()):,} rays per incidence, "
                            f"{int(t.realisations.max())} realisation"
                            f"{'s' if t.realisations.max() > 1 else ''}, {t.bins.theta_bins} × "
                            f"{t.bins.phi_bins} bins" for path, t in ((args.a, a), (args.b, b)))
                + ".")
        write_section(DOC, "hierarchy-consistency", markdown(rows, head))
    if args.json:
        print(json.dumps(rows, indent=2))
        return
    print(f"{'theta_i':>7} {'phi_i':>6} {'albedo a':>9} {'albedo b':>9} "
          f"{'a - b':>18} {'L1':>7} {'noise L1':>9} {'z rms':>6}")
    for r in rows:
        diff = sum(r["albedo_difference"]) / 3
        err = sum(r["albedo_difference_err"]) / 3
        print(f"{r['theta_i']:7.1f} {r['phi_i']:6.1f} {sum(r['albedo_a']) / 3:9.5f} "
              f"{sum(r['albedo_b']) / 3:9.5f} {diff:+9.5f} ± {err:.5f} "
              f"{100 * r['l1']:6.2f}% {100 * r['l1_noise']:8.2f}% {r['z_rms']:6.2f}")


if __name__ == "__main__":
    main()
