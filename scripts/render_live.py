"""Live renders against the renders of their tables: the figures of docs/render.md,
"Simulation at render time".

For each case (the demo recipe ``surfaces/gaussian-0.3.toml``, the shipped velvet, and
the demo recipe with gold facets), ``microsim render RECIPE --live`` twice: with the
recipe's own incidences, and with incidences every 10° to 80° and 89° (``--set
simulation.theta_i=...``), so that what the table's interpolation between coarse
incidences costs shows apart from the rest. Torus, 160 × 120 pixels, 64 samples per
pixel, the LLVM variant, ``--live``'s default light. ``--write`` puts the table into
docs/render.md (marked section).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

from microsim.bench import run_child

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "render.md"
DENSE = "simulation.theta_i=[0,10,20,30,40,50,60,70,80,89]"
GOLD = ["material.kind=conductor", "material.eta=[0.2,0.92,1.1]",
        "material.k=[3.9,2.45,2.14]"]
CASES = (("`gaussian-0.3.toml` (mirror)", "gaussian-0.3.toml", []),
         ("`velvet.toml`", "velvet.toml", []),
         ("`gaussian-0.3.toml`, gold facets", "gaussian-0.3.toml", GOLD))
RENDER = ["--size", "160x120", "--spp", "64", "--variant", "llvm_ad_rgb", "--json"]


def run(recipe: str, sets: list[str], folder: str) -> dict:
    """One ``render --live`` as a child process; its JSON report and wall time."""
    argv = [sys.executable, "-m", "microsim.cli", "render", str(ROOT / "surfaces" / recipe),
            "--live", "-o", str(Path(folder) / "live.png"), *RENDER]
    for s in sets:
        argv += ["--set", s]
    child = run_child(argv)
    return {**json.loads(child.stdout), "command_s": child.wall}


def row(name: str, incidences: str, r: dict) -> str:
    d = r["difference"]
    return (f"| {name} | {incidences} | {r['live']['realisations']} | "
            f"{100 * d['total']:+.2f}% ± {100 * d['total_err']:.2f}% | {d['total_z']:+.1f} | "
            f"{100 * d['median_abs']:.1f}% ({100 * d['median_abs_noise_alone']:.1f}%) | "
            f"{100 * r['table']['noise']:.1f}% / {100 * r['live']['noise']:.1f}% | "
            f"{r['table']['seconds']:.1f} s | {r['live']['seconds']:.1f} s | "
            f"{r['live']['samples'] / 1e6:.2f} M | {r['command_s']:.0f} s |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--write", action="store_true",
                        help="write the table into docs/render.md")
    args = parser.parse_args()
    load_before = os.getloadavg()[0]
    lines = ["| case | table's incidences | realisations | mean luminance, live − table "
             "| z | median \\|Δ\\| (noise alone) | per-pixel noise, table / live "
             "| table's render | live render | samples | command |",
             "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    with tempfile.TemporaryDirectory() as folder:
        for name, recipe, sets in CASES:
            for incidences, extra in (("the recipe's", []), ("every 10°, and 89°", [DENSE])):
                report = run(recipe, [*sets, *extra], folder)
                lines.append(row(name, incidences, report))
                print(lines[-1], flush=True)
    text = "\n".join(lines)
    if args.write:
        from microsim.files import write_section

        head = (f"Measured with `python scripts/render_live.py --write` on "
                f"{platform.machine()}, {os.cpu_count()} CPUs, Python "
                f"{platform.python_version()}, {time.strftime('%Y-%m-%d')}; load average "
                f"(1 min) {load_before:.1f} before, {os.getloadavg()[0]:.1f} after "
                "(the renders' times are wall times on a shared machine).")
        write_section(DOC, "render_live", "\n".join([head, "", text]),
                      heading="## Simulation at render time")


if __name__ == "__main__":
    main()
