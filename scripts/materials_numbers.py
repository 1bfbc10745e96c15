"""The measured numbers of docs/materials.md that are neither paint albedos nor the
hierarchy's: a fibre table's frame, a refracting Gaussian slab, a flat clear coat.

Usage::

    python scripts/materials_numbers.py [fibre-axis|refracting-slab|clear-coat ...] [--write]

(default: all). Each part simulates shipped recipes with ``--set`` overrides, as the
commands its section names do, and prints its Markdown; ``--write`` puts it into
docs/materials.md's marked section ``materials-<part>``, opened by the command, machine,
date and load average. Under a minute for all three on 2 cores.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

import microsim
from microsim.analytic.layered import CoatedLambertian
from microsim.files import measured_with, write_section
from microsim.geometry import direction
from microsim.tables.table import BRDFTable

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "materials.md"
SURFACES = ROOT / "surfaces"


def run(recipe: str, overrides: list[str]) -> BRDFTable:
    """``microsim simulate surfaces/RECIPE --set KEY=VALUE ...`` as a table."""
    return microsim.simulate(microsim.load_recipe(SURFACES / recipe, overrides))


def numbers(values, digits: int) -> str:
    """Values joined by commas at a fixed number of decimals."""
    return ", ".join(f"{v:.{digits}f}" for v in values)


def degrees(table: BRDFTable) -> str:
    """The table's incidences, degrees, joined by commas."""
    return ", ".join(f"{t:g}" for t in np.degrees(table.theta_i).round(6))


def rgb_mean(values: np.ndarray) -> np.ndarray:
    """Per incidence (first φi), the mean over R, G and B."""
    return np.asarray(values)[:, 0].mean(axis=-1)


def fibre_axis(load_before: float) -> str:
    """A velvet whose fibres carry a cylinders table, along each fibre and along y."""
    with tempfile.TemporaryDirectory() as folder:
        cylinders = Path(folder) / "cyl.exr"
        microsim.write_table(run("cylinders.toml", ["simulation.rays=20000"]), cylinders)
        albedo, error = {}, {}
        for axis in ("tangent", "y"):
            table = run("velvet.toml", [
                "simulation.rays=20000", "simulation.theta_i=[0,60]",
                "material.fibre.kind=table", f"material.fibre.path={cylinders}",
                f"material.fibre.axis={axis}"])
            albedo[axis] = rgb_mean(table.albedo)
            error[axis] = rgb_mean(table.albedo_err).max()
    return (f"{measured_with(__file__, sys.argv[1:], load_before)}: `microsim simulate "
            "surfaces/cylinders.toml --rays 20000 -o cyl.exr`, then `surfaces/velvet.toml` "
            "with `--rays 20000 --set 'simulation.theta_i=[0,60]' --set "
            "material.fibre.kind=table --set material.fibre.path=cyl.exr --set "
            "material.fibre.axis=AXIS`. Albedo (RGB mean) at θi = 0 / 60°: "
            f"{' / '.join(f'{a:.3f}' for a in albedo['tangent'])} "
            f"(± {error['tangent']:.3f}) with `axis = \"tangent\"`, "
            f"{' / '.join(f'{a:.3f}' for a in albedo['y'])} (± {error['y']:.3f}) "
            "with `axis = \"y\"`.")


def refracting_slab(load_before: float) -> str:
    """A Gaussian height field as a rough dielectric half-space: its energy balance, and
    its single scattering against Torrance-Sparrow with dielectric Fresnel."""
    dielectric = ["material.kind=dielectric", "material.refract=true"]
    small = run("gaussian-0.3.toml", [*dielectric, "surface.resolution=128",
                                      "simulation.rays=20000"])
    transmitted = np.array([d.transmitted for d in small.meta.directions]).mean(axis=-1)
    lost = np.array([d.lost for d in small.meta.directions]).max()
    lines = [f"{measured_with(__file__, sys.argv[1:], load_before)}:", "",
             "- `microsim simulate surfaces/gaussian-0.3.toml --set material.kind=dielectric "
             "--set material.refract=true --set surface.resolution=128 --rays 20000` "
             f"reflects {numbers(rgb_mean(small.albedo), 3)} and transmits "
             f"{numbers(transmitted, 3)} at θi = {degrees(small)}°, "
             + ("nothing lost." if lost == 0 else f"lost at most {lost:.1e}.")]
    for refract in ("true", "false"):
        table = run("gaussian-0.3.toml", ["material.kind=dielectric",
                                          f"material.refract={refract}",
                                          "simulation.rays=200000"])
        comparison = microsim.compare_model(table, "beckmann", component="single")
        rows = comparison.per_theta_i
        lines.append(
            f"- `refract = {refract}`, the 256² tile, `--rays 200000`, then `microsim "
            "compare T.exr --model beckmann --component single`: single-scattering albedo "
            f"{numbers([r.albedo_sim.mean() for r in rows], 4)} against the model's "
            f"{numbers([r.albedo_model.mean() for r in rows], 4)}, z mean "
            f"{comparison.z_mean:.2f} and std {comparison.z_std:.2f} over the lobe bins.")
    return "\n".join(lines)


def mirror_bin(table: BRDFTable, theta: float, excess: np.ndarray) -> int:
    """The flat bin index holding a smooth interface's mirror reflection at incidence
    ``theta``: of the bins in the θo ring of the mirror direction, the one where the
    simulation exceeds the model most (at normal incidence the mirror ray is the pole,
    whose azimuth is the rounding's)."""
    wi = direction(theta, 0.0)
    ring = table.bins.index(np.array([[-wi[0], -wi[1], wi[2]]]))[0] // table.bins.phi_bins
    first = ring * table.bins.phi_bins
    return first + int(np.argmax(excess[first:first + table.bins.phi_bins]))


def clear_coat(load_before: float) -> str:
    """A flat clear coat over the white substrate against ``coated-lambertian``: the
    albedo against the closed form (diffuse part plus the specular F), and the per-bin z
    of every bin but the mirror one (where the model's Dirac peak is not in its bins)."""
    table = run("paint.toml", ["simulation.rays=200000", "surface.pigment_fraction=0",
                               "surface.top_alpha=0", "material.binder.absorption=0"])
    spec = "coated-lambertian:albedo=0.9,eta=1.5"
    comparison = microsim.compare_model(table, spec)
    albedo, error = rgb_mean(table.albedo), rgb_mean(table.albedo_err)
    closed = CoatedLambertian(0.9, 1.5).directional_albedo(np.cos(table.theta_i))
    rms, counted = [], set()
    for a, theta in enumerate(table.theta_i):
        sim = table["total"].values[a, 0].reshape(table.bins.size, -1)
        err = table["total"].errors[a, 0].reshape(table.bins.size, -1)
        model = comparison.model[a, 0].reshape(table.bins.size, -1)
        keep = np.isfinite(err) & (err > 0)
        keep[mirror_bin(table, theta, (sim - model).mean(axis=-1))] = False
        z = (sim - model)[keep] / err[keep]
        rms.append(np.sqrt(np.mean(z**2)))
        counted.add(int(keep.any(axis=-1).sum()))
    return (f"{measured_with(__file__, sys.argv[1:], load_before)}: `microsim simulate "
            "surfaces/paint.toml --rays 200000 --set surface.pigment_fraction=0 --set "
            "surface.top_alpha=0 --set material.binder.absorption=0` (a flat clear coat "
            "over the white substrate, ρ = 0.9), then `microsim compare TABLE --model "
            f"{spec}`. Simulated albedo (RGB mean) {numbers(albedo, 4)} ± "
            f"{error.max():.4f} at θi = {degrees(table)}° against the closed form's "
            f"{numbers(closed, 4)} (diffuse part plus F; differences "
            f"{numbers(np.abs(albedo - closed) / rgb_mean(table.albedo_err), 1)} standard "
            f"errors). Per-bin z over the {'/'.join(str(c) for c in sorted(counted))} bins "
            f"besides the mirror bin: RMS {numbers(rms, 2)} (1 for noise alone); compare's "
            f"pooled z std, the mirror bin included: {comparison.z_std:.1f}.")


PARTS: dict[str, Callable[[float], str]] = {
    "fibre-axis": fibre_axis, "refracting-slab": refracting_slab, "clear-coat": clear_coat}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("parts", nargs="*", metavar="PART",
                        help=f"what to measure: {', '.join(PARTS)} (default: all)")
    parser.add_argument("--write", action="store_true",
                        help="write each part's section into docs/materials.md")
    args = parser.parse_args()
    unknown = sorted(set(args.parts) - set(PARTS))
    if unknown:
        parser.error(f"unknown part {unknown[0]!r}; choose from {', '.join(PARTS)}")
    for part in args.parts or list(PARTS):
        text = PARTS[part](os.getloadavg()[0])
        print(text, flush=True)
        if args.write:
            write_section(DOC, f"materials-{part}", text)


if __name__ == "__main__":
    main()
