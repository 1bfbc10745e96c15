"""Fibre surfaces against their models: the figures and numbers of docs/surfaces.md
(cylinders, velvet, weaves) and the curved-normal furnace.

Usage: python scripts/fibre_comparisons.py [cylinders|velvet|weaves|furnace ...] [--write]

(default: all). Writes PNGs to docs/images/fibres/ and prints the Markdown of each part;
``--write`` puts it into docs/surfaces.md's marked sections ``fibre_comparisons-<part>``
(velvet's three: ``-velvet``, ``-velvet-density``, ``-velvet-grazing``), each opened by
the command, machine, date and load average. Minutes per part on 2 cores.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

from microsim.analytic.registry import parse_model_spec
from microsim.comparison.fit import FitResult, family, fit_table
from microsim.comparison.metrics import Comparison, compare_table
from microsim.comparison.table_models import model_defaults
from microsim.files import measured_with, write_section
from microsim.materials import Lambertian, Mirror
from microsim.measurement.simulation import simulate
from microsim.plots import incidence_plane
from microsim.recipe import load, resolve
from microsim.settings import Recipe
from microsim.surfaces import build_tile
from microsim.surfaces.tile import Tile
from microsim.tables.table import BRDFTable

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "surfaces.md"
OUT = ROOT / "docs" / "images" / "fibres"
BLACK = {"kind": "lambertian", "albedo": 0.0}
GOLD = {"kind": "conductor"}
HEAD = "| surface | model | component | rays per direction | median relative error | z mean ± std |"
RULE = "| --- | --- | --- | --- | --- | --- |"


def run(recipe: Recipe, rays: int | None = None) -> tuple[Tile, BRDFTable]:
    """Simulate a resolved recipe (optionally with another ray count)."""
    if rays is not None:
        recipe = replace(recipe, simulation=replace(recipe.simulation, rays=rays))
    tile = build_tile(recipe.surface)
    return tile, simulate(tile, recipe.material, recipe.simulation, recipe.table,
                          recipe=recipe)


def compared(table: BRDFTable, spec: str, component: str) -> Comparison:
    """``compare_table`` against a model spec, its missing parameters from the table."""
    _, _, model = parse_model_spec(spec, model_defaults(table.meta))
    return compare_table(table, model, component)


def report(name: str, table: BRDFTable, spec: str, component: str, figure: str,
           label: str | None = None) -> tuple[Comparison, str]:
    """Compare, draw the plane of incidence; the comparison and its Markdown row."""
    result = compared(table, spec, component)
    incidence_plane(table, result.model, OUT / figure, component,
                    f"{name}: {component} vs {spec}")
    row = (f"| {name} | {label or f'`{spec}`'} | {component} | {int(table.rays.max()):,} | "
           f"{100 * result.median_rel_error:.1f}% | "
           f"{result.z_mean:.2f} ± {result.z_std:.2f} |")
    print(row, flush=True)
    return result, row


def fitted(fit: FitResult, table: BRDFTable, spec: str) -> str:
    """The fitted parameters, a colour parameter's channels in brackets, "(bound)" after
    a value at its bound (within 10⁻⁶ of the range: the optimiser stops on it)."""
    fam = family(spec, model_defaults(table.meta), table.channels.names)[1]
    channels = table.channels.names
    groups: dict[str, list[str]] = {}
    for name, low, high in zip(fam.names, fam.lower, fam.upper, strict=True):
        value = fit.params[name]
        text = (f"{value:,.0f}" if abs(value) >= 1000 else f"{value:.3g}") + (
            " (bound)" if min(value - low, high - value) < 1e-6 * (high - low) else "")
        base, _, channel = name.rpartition("_")
        groups.setdefault(base if channel in channels else name, []).append(text)
    return "; ".join(f"{k} {v[0]}" if len(v) == 1 else f"{k} ({', '.join(v)})"
                     for k, v in groups.items())


def cylinders() -> dict[str, str]:
    """The shipped recipe against the exact model and a fitted Kay-Kajiya; widely spaced
    gold and Lambertian cylinders, smooth and faceted."""
    load_before = os.getloadavg()[0]
    shipped = load(ROOT / "surfaces" / "cylinders.toml")
    _, table = run(shipped, 200_000)
    rows = [report("`surfaces/cylinders.toml` (gold, half sunk in a white base)", table,
                   "cylinders", "single", "cylinders-exact.png")[1]]
    fit = fit_table(table, "kay-kajiya", "total")
    incidence_plane(table, fit.model_bins, OUT / "cylinders-kay-kajiya.png", "total",
                    "cylinders.toml: total vs fitted Kay-Kajiya layer")
    for smooth in (True, False):
        r = resolve({"surface": {"kind": "cylinders", "radius": 0.1, "spacing": 1.0,
                                 "smooth_normals": smooth},
                     "material": {"base": BLACK, "cylinder": GOLD},
                     "simulation": {"theta_i": [0, 30, 60], "phi_i": [0, 60], "rays": 200_000,
                                    "bounces": 4}})
        _, t = run(r)
        name = ("gold cylinders 10 radii apart, black base" if smooth else
                "the same, `smooth_normals = false`")
        rows.append(report(name, t, "cylinders", "single",
                           f"cylinders-gold-{'smooth' if smooth else 'faceted'}.png")[1])
    r = resolve({"surface": {"kind": "cylinders", "radius": 0.1, "spacing": 1.0},
                 "material": {"base": BLACK, "cylinder": {"kind": "lambertian",
                                                          "albedo": 0.8}},
                 "simulation": {"theta_i": [0, 30, 60], "phi_i": [0, 60], "rays": 200_000,
                                "bounces": 4}, "table": {"theta_bins": 16, "phi_bins": 32}})
    _, t = run(r)
    rows.append(report("Lambertian cylinders (ρ = 0.8) 10 radii apart, black base", t,
                       "cylinders", "single", "cylinders-lambertian-exact.png")[1])
    rows.append(report("the same", t, "kay-kajiya:ks=0", "single",
                       "cylinders-lambertian-kay-kajiya.png",
                       "`kay-kajiya:ks=0` (kd = ρ/π², coverage 0.2)")[1])
    rows.append(f"| `surfaces/cylinders.toml` | `kay-kajiya`, fitted (`microsim fit`) | total "
                f"| {int(table.rays.max()):,} | {100 * fit.median_rel_error:.1f}% | "
                f"χ²/dof {fit.chi2_dof:.0f} |")
    text = "\n".join([
        f"{measured_with(__file__, sys.argv[1:], load_before)}: the shipped recipe with its "
        "incidences; the spaced cylinders (radius 0.1, spacing 1) at θi = 0, 30, 60°, "
        "φi = 0, 60°, 4 bounces, the Lambertian ones on 16 × 32 bins.", "", HEAD, RULE,
        *rows, "", "Kay-Kajiya fitted to the shipped table's total: "
        f"{fitted(fit, table, 'kay-kajiya')}."])
    return {"fibre_comparisons-cylinders": text}


def velvet() -> dict[str, str]:
    """Sparse velvet against the quadrature model, the departure with density, and the
    shipped velvet at grazing incidence."""
    load_before = os.getloadavg()[0]
    base = {"kind": "velvet", "fibre_radius": 0.002, "fibre_length": 0.15, "tilt": 30.0,
            "tilt_spread": 10.0, "sides": 24, "size": 5.0}
    fibre = {"kind": "lambertian", "albedo": 0.8}
    thetas = [0.0, 30.0, 60.0, 80.0]
    rows, density_rows, sparse_row = [], [], ""
    for density in (20.0, 80.0, 320.0, 1280.0):
        r = resolve({"surface": {**base, "density": density},
                     "material": {"base": BLACK, "fibre": fibre},
                     "simulation": {"theta_i": thetas, "rays": 400_000, "bounces": 1},
                     "table": {"theta_bins": 8, "phi_bins": 16}})
        _, t = run(r)
        spec = "velvet-sparse"
        if density == 20.0:
            result, sparse_row = report(f"{density:g} fibres per unit area", t, spec,
                                        "single", "velvet-sparse.png")
        else:
            result = compared(t, spec, "single")
        ratio = [row.albedo_sim[1] / row.albedo_model[1] for row in result.per_theta_i]
        err = t["single"].albedo_err[:, 0, 1] / np.array(
            [row.albedo_model[1] for row in result.per_theta_i])
        rows.append((density, ratio, err))
        density_rows.append(f"| {density:g} | " + " | ".join(
            f"{q:.3f} ± {e:.3f}" for q, e in zip(ratio, err, strict=True)) + " |")
        print(density_rows[-1], flush=True)
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
    grazing = [0.0, 45.0, 75.0, 85.0]
    shipped = load(ROOT / "surfaces" / "velvet.toml", [
        "material.base.albedo=0", f"simulation.theta_i={grazing}"])
    _, t = run(shipped, 200_000)
    dense, dense_row = report("`surfaces/velvet.toml`, 400 per unit area, black base", t,
                              "velvet-sparse", "single", "velvet-dense.png")
    single = [row.albedo_sim[0] for row in dense.per_theta_i]
    single_err = t["single"].albedo_err[:, 0, 0]
    sparse = [row.albedo_model[0] for row in dense.per_theta_i]
    total = t["total"].albedo[:, 0, 0]
    what = ("fibres r = 0.002, L = 0.15, tilt 30 ± 10°, 24 sides, tile of side 5, "
            "Lambertian fibres (ρ = 0.8) on a black base, single scattering, 8 × 16 bins")
    opening = measured_with(__file__, sys.argv[1:], load_before)
    degrees = ", ".join(f"{x:g}" for x in thetas)
    sections = {
        "fibre_comparisons-velvet": "\n".join([
            f"{opening}: {what}; the sparse tile at θi = {degrees}°, the shipped velvet "
            f"(its fibres on a black base) at {', '.join(f'{x:g}' for x in grazing)}°.",
            "", HEAD, RULE, sparse_row, dense_row]),
        "fibre_comparisons-velvet-density": "\n".join([
            f"{opening}: {what}, 400,000 rays per incidence: single-scattering albedo over "
            "the sparse model's, ± its standard error.", "",
            "| fibres per unit area | " + " | ".join(
                f"θi = {x:g}°" if k == 0 else f"{x:g}°" for k, x in enumerate(thetas)) + " |",
            "| --- |" + " --- |" * len(thetas), *density_rows]),
        "fibre_comparisons-velvet-grazing": (
            f"{opening}: `surfaces/velvet.toml` over a black base, {int(t.rays.max()):,} "
            "rays per incidence: single-scattered albedo "
            + ", ".join(f"{a:.3f} at {x:g}°" for a, x in zip(single, grazing, strict=True))
            + f" (± {single_err.max():.4f} at most; all orders "
            + ", ".join(f"{a:.3f}" for a in total) + "), against the sparse model's "
            + ", ".join(f"{a:.3g}" for a in sparse) + "."),
    }
    return sections


def weaves() -> dict[str, str]:
    """The microcylinder model fitted to plain and twill weaves, Lambertian and
    specular (non-refracting dielectric, η = 1.5) yarns."""
    load_before = os.getloadavg()[0]
    rows = []
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
            start = time.perf_counter()
            fit = fit_table(t, "microcylinder", "single")
            seconds = time.perf_counter() - start
            weave = "plain" if pattern == "plain" else "2/1 twill"
            yarns = "Lambertian" if material is None else "specular"
            rows.append(f"| {weave}, {yarns} yarns | {100 * fit.median_rel_error:.1f}% | "
                        f"{fit.chi2_dof:.1f} | {fitted(fit, t, 'microcylinder')} | "
                        f"{seconds:.0f} s |")
            print(rows[-1], flush=True)
            incidence_plane(t, fit.model_bins, OUT / f"weave-{pattern}-{name}.png",
                            "single", f"{pattern} weave, {name} yarns: single vs fitted "
                            "microcylinder model")
    text = "\n".join([
        f"{measured_with(__file__, sys.argv[1:], load_before)}: single scattering, 100,000 "
        "rays per direction, θi = 0, 30, 60°, φi = 0, 45, 90°, 8 × 16 bins; Lambertian "
        "yarns blue warp (0.1, 0.2, 0.6) and white weft (0.85), specular yarns a "
        "non-refracting dielectric (η = 1.5). Parameters as `microsim fit` names them "
        "(γ in degrees; A per channel R, G, B).", "",
        "| weave | median relative error | χ²/dof | fitted parameters | fit time |",
        "| --- | --- | --- | --- | --- |", *rows])
    return {"fibre_comparisons-weaves": text}


FURNACE = ({"kind": "velvet", "density": 400, "seed": 3},
           {"kind": "weave", "pattern": "plain"},
           {"kind": "weave", "pattern": "twill"},
           {"kind": "weave", "pattern": "plain", "sides": 12})
FURNACE_NAMES = ("velvet, 400 fibres per unit area", "plain weave (24 sides)",
                 "2/1 twill (24 sides)", "plain weave, 12 sides")


def furnace_table(surface: dict, smooth: bool, bounces: int, theta: list[float],
                  phi: list[float]) -> BRDFTable:
    """A mirror white furnace of one surface: every facet a mirror (a weave over a white
    Lambertian floor), 40,000 rays per direction."""
    if str(ROOT / "tests") not in sys.path:
        sys.path.insert(0, str(ROOT / "tests"))
    from tilefixtures import with_floor

    tile = build_tile(resolve({"surface": {**surface, "smooth_normals": smooth}}).surface)
    materials = {p: Mirror() for p in tile.parts}
    if surface["kind"] == "weave":
        tile = with_floor(tile)
        materials["floor"] = Lambertian(albedo=(1.0, 1.0, 1.0))
    r = resolve({"surface": {"kind": "flat"}, "simulation": {
        "theta_i": theta, "phi_i": phi, "rays": 40_000, "bounces": bounces},
        "table": {"theta_bins": 2, "phi_bins": 2}})
    return simulate(tile, materials, r.simulation, r.table)


def furnace() -> dict[str, str]:
    """Mirror white furnace with and without curved normals (losses per direction), and
    the 12-sided weave's worst direction traced to 3000 bounces."""
    load_before = os.getloadavg()[0]
    rows, fates = [], {}
    for surface, name in zip(FURNACE, FURNACE_NAMES, strict=True):
        for smooth in (True, False):
            table = furnace_table(surface, smooth, 400, [0.0, 45.0, 80.0], [0.0, 45.0])
            lost = table.lost_energy[..., 0]
            for d in table.meta.directions:
                for fate, count in d.fates.items():
                    fates[fate] = fates.get(fate, 0) + count
            rows.append(f"| {name} | {'yes' if smooth else 'no'} | {100 * lost.mean():.3f}% | "
                        f"{100 * lost.max():.3f}% |")
            print(rows[-1], flush=True)
    rays = sum(fates.values())
    ended = ", ".join(f"{fates.get(k, 0):,} {k}" for k in
                      ("bounces", "leaked", "trapped", "backface"))
    noise = 100 * np.sqrt(0.0005 * (1 - 0.0005) / 40_000)
    deep = {b: furnace_table(FURNACE[3], True, b, [45.0], [45.0]).lost_energy[0, 0, 0]
            for b in (400, 3000)}
    text = "\n".join([
        f"{measured_with(__file__, sys.argv[1:], load_before)}: 40,000 rays at θi = 0, 45, "
        "80° and φi = 0, 45°, 400 bounces.", "",
        "| surface | smooth normals | lost, mean over directions | lost, worst direction |",
        "| --- | --- | --- | --- |", *rows, "",
        f"Of the {rays:,} rays: {ended} (the rest escaped). Binomial noise of a lost "
        f"fraction of 0.05%: ± {noise:.3f}%. The 12-sided plain weave with smooth normals "
        f"at θi = φi = 45°: {100 * deep[400]:.2f}% of the rays still bouncing after 400 "
        f"bounces, {100 * deep[3000]:.2f}% after 3000."])
    return {"fibre_comparisons-furnace": text}


SECTIONS: dict[str, Callable[[], dict[str, str]]] = {
    "cylinders": cylinders, "velvet": velvet, "weaves": weaves, "furnace": furnace}

if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("sections", nargs="*", metavar="SECTION",
                        help=f"what to measure: {', '.join(SECTIONS)} (default: all)")
    parser.add_argument("--write", action="store_true",
                        help="write each part's sections into docs/surfaces.md")
    args = parser.parse_args()
    unknown = sorted(set(args.sections) - set(SECTIONS))
    if unknown:
        parser.error(f"unknown section {unknown[0]!r}; choose from {', '.join(SECTIONS)}")
    OUT.mkdir(parents=True, exist_ok=True)
    for section in args.sections or list(SECTIONS):
        for name, text in SECTIONS[section]().items():
            print(text, flush=True)
            if args.write:
                write_section(DOC, name, text)
