"""Accuracy of Gaussian tables against Torrance-Sparrow + Smith, over surface realisations.

Usage::

    python scripts/ensemble_accuracy.py demo [--write]
    python scripts/ensemble_accuracy.py targets [--realisations 128] [--rays 100000]
                                                [--write]
    python scripts/ensemble_accuracy.py smith [--realisations 16] [--rays 200000]
                                              [--write]

``demo`` runs ``microsim demo`` with its defaults in a subprocess and records its per-
incidence median relative lobe error against Torrance-Sparrow + Beckmann + height-
correlated Smith at the pooled realised α, the z spread, the wall time and the peak memory
(the child's maximum resident set).

``targets`` measures what reaches 2% and 1% median lobe error at θi = 0, 45, 75° on the
shipped Gaussian surface (α = 0.3, 256² tiles of 32 correlation lengths, mirror facets,
16 × 32 bins): one ensemble of ``--realisations`` tiles with ``--rays`` rays each per
direction; the first K realisations of it are exactly the table a recipe with
``realisations = K`` and ``rays = K × rays`` makes (realisation r's tile and rays do not
depend on K), so every K is read off one run. For the smallest K reaching each target the
recipe is then run on its own in a subprocess for its wall time and peak memory.

``smith`` measures the single-scattering albedo of Gaussian surfaces (α = 0.3, 0.7, 1.0)
against Torrance-Sparrow + height-correlated Smith's at θi = 0, 30, 60, 75, 85°, with the
ensemble's standard error: what Smith itself, not the simulation, leaves.

With ``--write`` each part replaces its marked section of docs/performance.md. The
load average before and after is recorded: timings are only comparable on a quiet machine.
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
from microsim.comparison.metrics import compare_table
from microsim.comparison.table_models import microfacet_model
from microsim.files import write_section
from microsim.measurement.simulation import Tiles, assemble_table, measure_ensemble
from microsim.recipe import load, to_toml

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "performance.md"
RECIPE = ROOT / "surfaces" / "gaussian-0.3.toml"
THETAS = (0.0, 45.0, 75.0)
TARGETS = (0.02, 0.01)


def load_average() -> float:
    """The 1-minute load average."""
    return os.getloadavg()[0]


def header(command: str, before: float) -> str:
    return (f"`python scripts/ensemble_accuracy.py {command} --write` ({platform.machine()}, "
            f"{os.cpu_count()} CPUs, Python {platform.python_version()}, "
            f"{time.strftime('%Y-%m-%d')}; load average {before:.1f} before, "
            f"{load_average():.1f} after)")


# --- demo -------------------------------------------------------------------------------
def demo() -> str:
    before = load_average()
    with tempfile.TemporaryDirectory() as folder:
        child = run_child([sys.executable, "-m", "microsim.cli", "demo", "--json", "-o",
                           str(Path(folder) / "demo.exr")])
    text, wall, memory = child.stdout, child.wall, child.peak_gib
    result = json.loads(text)
    s, c = result["simulation"], result["comparison"]
    lines = [header("demo", before) + f": `microsim demo` with its defaults "
             f"({s['realisations']} realisations of `surfaces/gaussian-0.3.toml`, "
             f"{s['rays_per_direction'][0]:,} rays per direction), single scattering "
             "against Torrance-Sparrow + Beckmann + height-correlated Smith at the realised "
             f"α pooled over the tiles ({c['alpha_realised']:.4f} ± "
             f"{c['alpha_realised_stderr']:.4f}). Wall time {wall:.1f} s (the command, "
             f"start-up included), peak memory {memory:.2f} GiB.", "",
             "| θi | median relative error | z mean | z spread | single albedo sim / model |",
             "| --- | --- | --- | --- | --- |"]
    for r in c["per_theta_i"]:
        lines.append(f"| {r['theta_i']:g}° | {100 * r['median_rel_error']:.2f}% | "
                     f"{r['z_mean']:.2f} | {r['z_std']:.2f} | "
                     f"{r['albedo_sim'][0]:.4f} / {r['albedo_model'][0]:.4f} |")
    lines += ["", f"Over all incidences: median {100 * c['median_rel_error']:.2f}%, z spread "
              f"{c['z_std']:.2f}."]
    return "\n".join(lines)


# --- targets ----------------------------------------------------------------------------
def recipe_for(k: int, rays: int) -> dict:
    """The shipped Gaussian recipe at θi = 0, 45, 75°, 16 × 32 bins, k realisations of
    ``rays`` rays per direction (harmonics off: the bins are measured)."""
    return load(RECIPE, [f"simulation.theta_i={list(THETAS)}", f"simulation.rays={k * rays}",
                         f"simulation.realisations={k}", "table.theta_bins=16",
                         "table.phi_bins=32", "table.sh_order=0"])


def errors_of(table) -> list[dict]:
    """Per incidence: median relative lobe error and z spread against the model."""
    result = compare_table(table, microfacet_model(table.meta), "single")
    return [{"median": r.median_rel_error, "z_std": r.z_std} for r in result.per_theta_i]


def targets(most: int, rays: int) -> str:
    before = load_average()
    recipe = recipe_for(most, rays)
    start = time.perf_counter()
    measured = measure_ensemble(Tiles(recipe.surface), recipe.material,
                                recipe.simulation, recipe.table, keep_runs=True)
    seconds = time.perf_counter() - start
    counts = sorted({k for k in (4, 8, 16, 24, 32, 48, 64, 96, 128, 192, 256) if k <= most}
                    | {most})
    rows, reached = [], {}
    for k in counts:
        part = type(measured)({key: run for key, run in measured.runs.items() if key[2] < k},
                              {r: i for r, i in measured.surfaces.items() if r < k},
                              measured.inputs, measured.isotropic)
        sub = recipe_for(k, rays)
        table = assemble_table([part], sub.material, sub.simulation, sub.table,
                               recipe=sub)
        errs = errors_of(table)
        worst = max(e["median"] for e in errs)
        rows.append((k, errs, table.meta.surface.alpha_realised.alpha))
        for target in TARGETS:
            if worst <= target and target not in reached:
                reached[target] = k
        print(f"K={k}: " + ", ".join(f"{100 * e['median']:.2f}% (z {e['z_std']:.2f})"
                                     for e in errs), flush=True)
    lines = [header(f"targets --realisations {most} --rays {rays}", before) + ": "
             f"`surfaces/gaussian-0.3.toml` (α = 0.3, 256² tiles of 32 correlation lengths, "
             f"mirror facets) at θi = 0, 45, 75°, 16 × 32 bins, {rays:,} rays per direction "
             "and realisation; median relative error of the single scattering over the "
             "lobe bins against Torrance-Sparrow + Beckmann + height-correlated Smith at "
             "the pooled realised α, and the z spread against the table's own errors (1 "
             f"for noise alone). One run of {most} realisations ({seconds:.0f} s); the "
             "first K of them are the table of `realisations = K`.", "",
             "| realisations K | rays per direction | 0° | 45° | 75° | z spread 0 / 45 / 75° |",
             "| --- | --- | --- | --- | --- | --- |"]
    for k, errs, _ in rows:
        lines.append(f"| {k} | {k * rays:,} | "
                     + " | ".join(f"{100 * e['median']:.2f}%" for e in errs)
                     + " | " + " / ".join(f"{e['z_std']:.2f}" for e in errs) + " |")
    lines += ["", "| median error at every θi | recipe | wall time | peak memory |",
              "| --- | --- | --- | --- |"]
    for target in TARGETS:
        k = reached.get(target)
        if k is None:
            lines.append(f"| {100 * target:g}% | not reached with {most} realisations | — "
                         "| — |")
            continue
        sub = recipe_for(k, rays)
        with tempfile.TemporaryDirectory() as folder:
            path = Path(folder) / "r.toml"
            path.write_text(to_toml(sub), encoding="utf-8")
            child = run_child([sys.executable, "-m", "microsim.cli", "simulate", str(path),
                               "-o", str(Path(folder) / "t.exr"), "--json"])
        wall, memory = child.wall, child.peak_gib
        lines.append(f"| {100 * target:g}% | `--set simulation.realisations={k} --set "
                     f"simulation.rays={k * rays}` (16 × 32 bins) | {wall:.1f} s | "
                     f"{memory:.2f} GiB |")
    return "\n".join(lines)


# --- smith ------------------------------------------------------------------------------
def smith(k: int, rays: int) -> str:
    before = load_average()
    thetas = [0.0, 30.0, 60.0, 75.0, 85.0]
    lines = [header(f"smith --realisations {k} --rays {rays}", before) + ": Gaussian "
             f"surfaces (256² tiles, 32 correlation lengths, mirror facets), {k} "
             f"realisations of {rays:,} rays per direction, 32 × 64 bins; single-scattering "
             "albedo of the simulation over the model's (Torrance-Sparrow + Beckmann + "
             "height-correlated Smith at the pooled realised α, integrated over the same "
             "bins), minus 1, ± the ensemble standard error of the simulated albedo.", "",
             "| α | " + " | ".join(f"θi = {t:g}°" for t in thetas) + " |",
             "| --- | " + " | ".join("---" for _ in thetas) + " |"]
    for alpha in (0.3, 0.7, 1.0):
        recipe = load(RECIPE, [f"surface.alpha={alpha}", f"simulation.theta_i={thetas}",
                               f"simulation.realisations={k}", f"simulation.rays={k * rays}",
                               "table.sh_order=0"])
        measured = measure_ensemble(Tiles(recipe.surface), recipe.material,
                                    recipe.simulation, recipe.table)
        table = assemble_table([measured], recipe.material, recipe.simulation,
                               recipe.table, recipe=recipe)
        result = compare_table(table, microfacet_model(table.meta), "single")
        cells = []
        for i, r in enumerate(result.per_theta_i):
            sim, model = r.albedo_sim[0], r.albedo_model[0]
            err = float(table["single"].albedo_err[i, 0, 0])
            cells.append(f"{100 * (sim / model - 1):+.2f} ± {100 * err / model:.2g}%")
        realised = table.meta.surface.alpha_realised.alpha
        lines.append(f"| {alpha} (realised {realised:.3f}) | " + " | ".join(cells) + " |")
        print(lines[-1], flush=True)
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("part", choices=("demo", "targets", "smith"))
    parser.add_argument("--realisations", type=int, default=None)
    parser.add_argument("--rays", type=int, default=None)
    parser.add_argument("--write", action="store_true")
    args = parser.parse_args()
    if args.part == "demo":
        text, heading = demo(), "### `microsim demo`"
    elif args.part == "targets":
        text = targets(args.realisations or 128, args.rays or 100_000)
        heading = "### What reaches 2% and 1%"
    else:
        text = smith(args.realisations or 16, args.rays or 200_000)
        heading = "### Where Smith limits the agreement"
    print(text)
    if args.write:
        write_section(DOC, f"ensemble-{args.part}", text, heading=heading)


if __name__ == "__main__":
    main()
