"""The velvet doughnut figure: simulated tables on a torus beside Mitsuba's analytic
equivalents, made with the commands a user runs.

Usage: python scripts/render_figure.py [--rays 400000] [--spp 128] [--out docs/images]
                                      [--write]

(``--rays`` per incidence of the isotropic tables; the anisotropic ones, with 12 times the
incidences, get a quarter of it.)

Simulates (into tables/figure/) the shipped velvet, the 2/1 twill weave and the brushed
gold cylinders with incidences every 30° of azimuth (so the anisotropic tables interpolate
between close φi), and the rough Gaussian height field with gold conductor facets; then
`microsim render` puts each on the torus beside its analytic counterpart through
Mitsuba's own plugins:

- velvet, twill: ``lambertian`` with the table's albedo at normal incidence (``diffuse``);
- cylinders: anisotropic Beckmann, α_x = 0.9 across the cylinders and α_y = 0.05 along
  them, with gold's indices (``roughconductor``): a stand-in for the brushed look, not a
  fit (the white base shows between the cylinders);
- Gaussian metal: Beckmann at the tile's realised α with gold's indices, separable Smith
  (``roughconductor``).

Writes docs/images/render.png and prints the command's report (times, differences).
The tables are kept in tables/figure/ and reused when they exist; ``--write`` simulates
them afresh and puts the report into docs/render.md (marked section ``render_figure``).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import microsim
from microsim.files import measured_with, write_section
from microsim.recipe import MATERIAL_KINDS

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "render.md"
THETA = "[0,15,30,45,60,70,80,87]"
THETA_ANISO = "[0,20,40,60,75,85]"
PHI = "[" + ",".join(str(p) for p in range(0, 360, 30)) + "]"
GOLD = ",".join(f"{key}=[{','.join(map(str, MATERIAL_KINDS['conductor'][key].default))}]"
                for key in ("eta", "k"))
"""The recipes' default conductor (gold), as model parameters."""
TABLES = {
    "velvet": ("surfaces/velvet.toml", [f"simulation.theta_i={THETA}"]),
    "twill": ("surfaces/weave-twill.toml", [f"simulation.theta_i={THETA_ANISO}",
                                            f"simulation.phi_i={PHI}"]),
    "cylinders": ("surfaces/cylinders.toml", [f"simulation.theta_i={THETA_ANISO}",
                                              f"simulation.phi_i={PHI}"]),
    "gaussian-gold": ("surfaces/gaussian-0.3.toml", [f"simulation.theta_i={THETA}",
                                                     "material.kind=conductor"]),
}


def run(*argv: str) -> str:
    """``microsim ARGV`` in the checkout; its standard output."""
    return subprocess.run(["microsim", *argv], cwd=ROOT, check=True, stdout=subprocess.PIPE,
                          text=True).stdout


def models(paths: dict[str, Path]) -> list[str]:
    """One model spec per table (module docstring)."""
    out = []
    for name, path in paths.items():
        table = microsim.read_table(path)
        if name in ("velvet", "twill"):
            albedo = ",".join(f"{a:.4f}" for a in table.albedo[0, 0])
            out.append(f"lambertian:albedo=[{albedo}]")
        elif name == "cylinders":
            # half-sunk cylinders along y: normals tilt across x only; a wide lobe across
            # the axis, a narrow one along it
            out.append(f"beckmann:alpha_x=0.9,alpha_y=0.05,shadowing=smith-separable,{GOLD}")
        else:
            out.append("beckmann:shadowing=smith-separable")
    return out


def section(report: dict, rays: dict[str, int], spp: int, load: float) -> str:
    """The ``render_figure`` section: a row per table of the command's JSON report."""
    lines = [f"{measured_with(__file__, sys.argv[1:], load)}: the torus, {spp} samples per "
             f"pixel, {report['size'][0]} × {report['size'][1]} pixels, `{report['variant']}`;"
             " the per-pixel noise is the median over the object's pixels, the differences "
             "those of \"The difference image\" below.", "",
             "| table | rays per incidence | model (Mitsuba plugin) | per-pixel noise | "
             "median \\|Δ\\| (noise alone) | mean difference | table's render |",
             "| --- | --- | --- | --- | --- | --- | --- |"]
    for (name, n), entry in zip(rays.items(), report["tables"], strict=True):
        d = entry["difference"]
        lines.append(f"| {name} | {n:,} | `{entry['model']}` ({entry['mitsuba']}) | "
                     f"{100 * entry['noise']:.1f}% | {100 * d['median_abs']:.1f}% "
                     f"({100 * d['median_abs_noise_alone']:.1f}%) | {100 * d['mean']:+.1f}% | "
                     f"{entry['seconds']:.1f} s |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rays", type=int, default=400_000)
    parser.add_argument("--spp", type=int, default=128)
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "images")
    parser.add_argument("--write", action="store_true",
                        help="simulate the tables afresh and write the report into "
                             "docs/render.md")
    args = parser.parse_args()
    load = os.getloadavg()[0]
    folder = ROOT / "tables" / "figure"
    folder.mkdir(parents=True, exist_ok=True)
    paths, rays = {}, {}
    for name, (recipe, sets) in TABLES.items():
        paths[name] = folder / f"{name}.exr"
        rays[name] = args.rays // 4 if any("phi_i" in s for s in sets) else args.rays
        if args.write or not paths[name].exists():
            run("simulate", recipe, "-o", str(paths[name]), "--rays", str(rays[name]),
                *[a for s in sets for a in ("--set", s)])
    specs = [a for m in models(paths) for a in ("--model", m)]
    report = json.loads(run("render", *map(str, paths.values()), "-o",
                            str(args.out / "render.png"), "--spp", str(args.spp), "--json",
                            *specs))
    text = section(report, rays, args.spp, load)
    print(text)
    if args.write:
        write_section(DOC, "render_figure", text)


if __name__ == "__main__":
    main()
