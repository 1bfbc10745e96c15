"""The velvet doughnut figure: simulated tables on a torus beside Mitsuba's analytic
equivalents, made with the commands a user runs.

Usage: python scripts/render_figure.py [--rays 400000] [--spp 128] [--out docs/images]

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
"""

from __future__ import annotations

import argparse
import subprocess
from pathlib import Path

import microsim
from microsim.recipe import MATERIAL_KINDS

ROOT = Path(__file__).resolve().parent.parent
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


def run(*argv: str) -> None:
    subprocess.run(["microsim", *argv], cwd=ROOT, check=True)


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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rays", type=int, default=400_000)
    parser.add_argument("--spp", type=int, default=128)
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "images")
    args = parser.parse_args()
    folder = ROOT / "tables" / "figure"
    folder.mkdir(parents=True, exist_ok=True)
    paths = {}
    for name, (recipe, sets) in TABLES.items():
        paths[name] = folder / f"{name}.exr"
        if not paths[name].exists():
            rays = args.rays // 4 if any("phi_i" in s for s in sets) else args.rays
            run("simulate", recipe, "-o", str(paths[name]), "--rays", str(rays),
                *[a for s in sets for a in ("--set", s)])
    specs = [a for m in models(paths) for a in ("--model", m)]
    run("render", *map(str, paths.values()), "-o", str(args.out / "render.png"),
        "--spp", str(args.spp), *specs)


if __name__ == "__main__":
    main()
