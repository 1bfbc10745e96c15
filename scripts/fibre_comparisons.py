"""Fibre surfaces against their models: the figures and numbers of docs/surfaces.md and
docs/compare.md (cylinders, velvet, weaves) and the curved-normal furnace.

Usage: python scripts/fibre_comparisons.py [cylinders|velvet|weaves|furnace ...]
(default: all). Writes PNGs to docs/images/fibres/ and prints the markdown rows the docs
quote, with ray counts and the load average. Several minutes on 2 cores.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from microsim.analytic.registry import parse_model_spec
from microsim.compare import Comparison, compare_table
from microsim.fit import fit_table
from microsim.materials import Lambertian, Mirror
from microsim.plots import incidence_plane
from microsim.recipe import load, resolve
from microsim.settings import Recipe
from microsim.simulation import simulate
from microsim.surfaces import build_tile
from microsim.surfaces.tile import Tile
from microsim.table_models import model_defaults
from microsim.tables.table import BRDFTable

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "docs" / "images" / "fibres"
BLACK = {"kind": "lambertian", "albedo": 0.0}
GOLD = {"kind": "conductor"}


def run(recipe: Recipe, rays: int | None = None) -> tuple[Tile, BRDFTable]:
    """Simulate a resolved recipe (optionally with another ray count)."""
    if rays is not None:
        recipe = replace(recipe, simulation=replace(recipe.simulation, rays=rays))
    tile = build_tile(recipe.surface)
    return tile, simulate(tile, recipe.material, recipe.simulation, recipe.table,
                          recipe=recipe)


def report(name: str, table: BRDFTable, spec: str, component: str, figure: str
           ) -> Comparison:
    """Compare, draw the plane of incidence, print one markdown row."""
    _, params, model = parse_model_spec(spec, model_defaults(table.meta))
    result = compare_table(table, model, component)
    incidence_plane(table, result.model, OUT / figure, component,
                    f"{name}: {component} vs {spec}")
    rays = int(table.rays.max())
    print(f"| {name} | `{spec}` | {component} | {100 * result.median_rel_error:.1f}% | "
          f"{result.z_mean:.2f} ± {result.z_std:.2f} | {rays:,} | {figure} |")
    return result


def cylinders() -> None:
    """The shipped recipe against the exact model and a fitted Kay-Kajiya; widely spaced
    gold and Lambertian cylinders, smooth and faceted."""
    shipped = load(ROOT / "surfaces" / "cylinders.toml")
    _, table = run(shipped, 200_000)
    report("cylinders.toml", table, "cylinders", "single", "cylinders-exact.png")
    fit = fit_table(table, "kay-kajiya", "total")
    print("kay-kajiya fit to cylinders.toml (total):", json.dumps(
        {k: round(v, 4) for k, v in fit.params.items()}), f"chi2/dof {fit.chi2_dof:.1f}",
        f"median {100 * fit.median_rel_error:.1f}%")
    incidence_plane(table, fit.model_bins, OUT / "cylinders-kay-kajiya.png", "total",
                    "cylinders.toml: total vs fitted Kay-Kajiya layer")
    for smooth in (True, False):
        r = resolve({"surface": {"kind": "cylinders", "radius": 0.1, "spacing": 1.0,
                                 "smooth_normals": smooth},
                     "material": {"base": BLACK, "cylinder": GOLD},
                     "simulation": {"theta_i": [0, 30, 60], "phi_i": [0, 60], "rays": 200_000,
                                    "bounces": 4}})
        _, t = run(r)
        report(f"gold cylinders 10 r apart, smooth_normals = {str(smooth).lower()}", t,
               "cylinders", "single", f"cylinders-gold-{'smooth' if smooth else 'faceted'}.png")
    r = resolve({"surface": {"kind": "cylinders", "radius": 0.1, "spacing": 1.0},
                 "material": {"base": BLACK, "cylinder": {"kind": "lambertian",
                                                          "albedo": 0.8}},
                 "simulation": {"theta_i": [0, 30, 60], "phi_i": [0, 60], "rays": 200_000,
                                "bounces": 4}, "table": {"theta_bins": 16, "phi_bins": 32}})
    _, t = run(r)
    report("Lambertian cylinders 10 r apart", t, "cylinders", "single",
           "cylinders-lambertian-exact.png")
    report("Lambertian cylinders 10 r apart", t, "kay-kajiya:ks=0", "single",
           "cylinders-lambertian-kay-kajiya.png")


def velvet() -> None:
    """Sparse velvet against the quadrature model, the departure with density, and the
    shipped velvet at grazing incidence."""
    base = {"kind": "velvet", "fibre_radius": 0.002, "fibre_length": 0.15, "tilt": 30.0,
            "tilt_spread": 10.0, "sides": 24, "size": 5.0}
    fibre = {"kind": "lambertian", "albedo": 0.8}
    thetas = [0.0, 30.0, 60.0, 80.0]
    rows = []
    for density in (20.0, 80.0, 320.0, 1280.0):
        r = resolve({"surface": {**base, "density": density},
                     "material": {"base": BLACK, "fibre": fibre},
                     "simulation": {"theta_i": thetas, "rays": 400_000, "bounces": 1},
                     "table": {"theta_bins": 8, "phi_bins": 16}})
        _, t = run(r)
        spec = "velvet-sparse"
        if density == 20.0:
            result = report("sparse velvet (20 fibres per unit area)", t, spec, "single",
                            "velvet-sparse.png")
        else:
            _, _, model = parse_model_spec(spec, model_defaults(t.meta))
            result = compare_table(t, model, "single")
        ratio = [row.albedo_sim[1] / row.albedo_model[1] for row in result.per_theta_i]
        err = t.albedo_err_of["single"][:, 0, 1] / np.array(
            [row.albedo_model[1] for row in result.per_theta_i])
        rows.append((density, ratio, err))
        print(f"| {density:g} | " + " | ".join(f"{q:.3f} ± {e:.3f}" for q, e in
                                                zip(ratio, err, strict=True)) + " |")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 3.6))
    for k, theta in enumerate(thetas):
        ax.errorbar([d for d, _, _ in rows], [q[k] for _, q, _ in rows],
                    yerr=[e[k] for _, _, e in rows], marker="o", label=f"θi = {theta:g}°")
    ax.set_xscale("log")
    ax.set_xlabel("fibres per unit area")
    ax.set_ylabel("single-scattering albedo / sparse model")
    ax.axhline(1.0, color="grey", lw=0.8)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(OUT / "velvet-density.png", dpi=110)
    plt.close(fig)
    shipped = load(ROOT / "surfaces" / "velvet.toml", [
        "material.base.albedo=0", "simulation.theta_i=[0, 45, 75, 85]"])
    _, t = run(shipped, 200_000)
    report("velvet.toml fibres on a black base", t, "velvet-sparse", "single",
           "velvet-dense.png")
    for k, row in enumerate(compare_table(t, parse_model_spec(
            "velvet-sparse", model_defaults(t.meta))[2], "single").per_theta_i):
        print(f"  θi {row.theta_i:.0f}: albedo sim {row.albedo_sim[0]:.4f} ± "
              f"{t.albedo_err_of['single'][k, 0, 0]:.4f}, sparse model "
              f"{row.albedo_model[0]:.4f}, total {t.albedo_of['total'][k, 0, 0]:.4f}")


def weaves() -> None:
    """The microcylinder model fitted to plain and twill weaves, Lambertian and
    specular (non-refracting dielectric, η = 1.5) yarns."""
    for pattern in ("plain", "twill"):
        for name, material in (("lambertian", None),
                               ("dielectric", {"kind": "dielectric", "eta": 1.5})):
            materials = ({"warp": material, "weft": material} if material else
                         {"warp": {"kind": "lambertian", "albedo": [0.1, 0.2, 0.6]},
                          "weft": {"kind": "lambertian", "albedo": 0.85}})
            recipe = resolve({"surface": {"kind": "weave", "pattern": pattern},
                              "material": materials,
                              "simulation": {"theta_i": [0.0, 30.0, 60.0],
                                             "phi_i": [0.0, 45.0, 90.0],
                                             "rays": 100_000, "bounces": 16},
                              "table": {"theta_bins": 8, "phi_bins": 16}})
            _, t = run(recipe)
            start = time.time()
            fit = fit_table(t, "microcylinder", "single")
            label = f"{pattern} weave, {name} yarns"
            print(f"| {label} | {100 * fit.median_rel_error:.1f}% | "
                  f"{fit.chi2_dof:.1f} | " + ", ".join(
                      f"{k} {v:.3g}" for k, v in fit.params.items()) + " |"
                  f" ({time.time() - start:.0f} s)")
            incidence_plane(t, fit.model_bins, OUT / f"weave-{pattern}-{name}.png",
                            "single", f"{label}: single vs fitted microcylinder model")


def furnace() -> None:
    """Mirror white furnace with and without curved normals (losses per direction)."""
    sys.path.insert(0, str(ROOT / "tests"))
    from tilefixtures import with_floor

    for surface in ({"kind": "velvet", "density": 400, "seed": 3},
                    {"kind": "weave", "pattern": "plain"},
                    {"kind": "weave", "pattern": "twill"},
                    {"kind": "weave", "pattern": "plain", "sides": 12}):
        for smooth in (True, False):
            tile = build_tile(resolve({"surface": {**surface, "smooth_normals": smooth}}
                                      ).surface)
            materials = {p: Mirror() for p in tile.parts}
            if surface["kind"] == "weave":
                tile = with_floor(tile)
                materials["floor"] = Lambertian(albedo=(1.0, 1.0, 1.0))
            r = resolve({"surface": {"kind": "flat"}, "simulation": {
                "theta_i": [0.0, 45.0, 80.0], "phi_i": [0.0, 45.0], "rays": 40_000,
                "bounces": 400}, "table": {"theta_bins": 2, "phi_bins": 2}})
            table = simulate(tile, materials, r.simulation, r.table)
            lost = table.lost_energy[..., 0]
            print(f"| {json.dumps(surface)} | {smooth} | {100 * lost.mean():.3f}% | "
                  f"{100 * lost.max():.3f}% |")


SECTIONS = {"cylinders": cylinders, "velvet": velvet, "weaves": weaves, "furnace": furnace}

if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("sections", nargs="*", metavar="SECTION",
                        help=f"what to measure: {', '.join(SECTIONS)} (default: all)")
    args = parser.parse_args()
    unknown = sorted(set(args.sections) - set(SECTIONS))
    if unknown:
        parser.error(f"unknown section {unknown[0]!r}; choose from {', '.join(SECTIONS)}")
    OUT.mkdir(parents=True, exist_ok=True)
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    for section in args.sections or list(SECTIONS):
        SECTIONS[section]()
