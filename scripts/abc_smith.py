"""Does Smith's masking hold for a K-correlation (``abc``) surface? Measured against the
``gaussian`` kind at the same realised α and grid.

Usage: python scripts/abc_smith.py [--write] [--g1-rays N] [--azimuth-rays N] [--sim-rays N]

Prints Markdown for docs/surfaces.md; ``--write`` puts it between the markers
``<!-- abc_smith: begin -->`` and ``<!-- abc_smith: end -->``. The surfaces are
``surfaces/abc-polished.toml`` (α = 0.2, B = 8 grid cells, 256²) at exponents C = 1.5, 2, 3
and 5 (``--set surface.exponent=C``), and ``surfaces/gaussian-0.3.toml`` (τ = 8 grid cells,
256²) with its ``alpha`` scaled so that its 32 tiles' pooled realised α equals that of
the ``abc`` recipe's own 32 (a tile's slopes are proportional to its σ, so one scale
makes them equal exactly). Every surface is measured over the same 32 realisations:

- **facet slopes** of each tile: the correlation ρ between a facet's x- and y-slopes, and
  the roughness α_φ = √(2 E[s_φ²]) of the slope s_φ = s_x cos φ + s_y sin φ along the
  azimuths φ = 0, 45, 135° (every facet of a grid has the same projected area, so these
  are plain means over the facets). Smith's Λ depends only on the distribution of the
  slope along the ray's azimuth, Gaussian here, so Smith's G1 at azimuth φ is Beckmann's
  at α_φ;
- **G1**, traced exactly as ``microsim measure g1 RECIPE --theta 60,80,85 --realisations
  32 --rays N [--phi φ]`` traces it (the same tiles, ``realisation(surface, r)``, and the
  same random streams, ``SeedSequence(simulation.seed, spawn_key=(r,))``, through
  ``microsim.measurement.masking.measure_g1``), so that each tile's own G1 is at hand: the
  mean over tiles minus Smith's G1 at the pooled realised α (what the command prints) ±
  the ensemble standard error, and the mean over tiles of each tile's G1 minus Smith's at
  that tile's own α_φ ± its standard error (paired: the spread of the tiles' α drops out).
  At φ = 45 and 135° only θ = 80 and 85°;
- **per scattering order**: ``microsim simulate`` of each surface with conductor (gold)
  facets at θi = 0, 60, 80°, then ``microsim compare TABLE --model beckmann --component
  order1 --json`` and ``--model beckmann-ms --component order2 --json``: per incidence the
  median relative error, the z mean and spread, the verdict's rule (compare.md,
  significance 0.001) applied to that incidence's lobe bins, and the order's albedo over
  the model's; and the command's overall verdict.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from microsim.files import measured_with, write_section

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "surfaces.md"
ABC = "surfaces/abc-polished.toml"
GAUSSIAN = "surfaces/gaussian-0.3.toml"
EXPONENTS = (1.5, 2.0, 3.0, 5.0)
REALISATIONS = 32
G1_THETA = (60.0, 80.0, 85.0)
AZIMUTHS = (0.0, 45.0, 135.0)
AZIMUTH_THETA = (80.0, 85.0)
"""Polar angles of the runs at φ = 45 and 135° (at 60° G1 differs from 1 by ~1e-6)."""
SIM_THETA = (0, 60, 80)
SIGNIFICANCE = 0.001
"""As ``microsim.comparison.agreement.AGREEMENT_SIGNIFICANCE`` (docs/compare.md)."""


def cli(*args: str) -> dict:
    """Run ``microsim ARGS --json`` from the project root and return its JSON."""
    out = subprocess.run([sys.executable, "-m", "microsim.cli", *args, "--json"],
                         capture_output=True, text=True, check=True, cwd=ROOT).stdout
    return json.loads(out)


def load(recipe: str, sets: list[str]):
    """The resolved recipe with ``simulation.realisations = REALISATIONS``."""
    from microsim.recipe import load as load_recipe

    return load_recipe(ROOT / recipe, [*sets, f"simulation.realisations={REALISATIONS}"])


def tiles(recipe) -> list:
    """The recipe's tiles, as ``measure g1`` and ``simulate`` build them."""
    from microsim.surfaces import build_tile
    from microsim.surfaces.realisations import realisation

    return [build_tile(realisation(recipe.surface, r)) for r in range(REALISATIONS)]


def slopes(tile) -> tuple[np.ndarray, np.ndarray]:
    """Height gradients (s_x, s_y) = (−n_x/n_z, −n_y/n_z) of a tile's facets."""
    v, f = tile.vertices, tile.faces
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    n = np.cross(b - a, c - a)
    return -n[:, 0] / n[:, 2], -n[:, 1] / n[:, 2]


def alpha_along(sx: np.ndarray, sy: np.ndarray, phi_deg: float) -> float:
    """√(2 E[s_φ²]) of the slopes along azimuth φ."""
    c, s = math.cos(math.radians(phi_deg)), math.sin(math.radians(phi_deg))
    return math.sqrt(2.0 * float(np.mean((c * sx + s * sy) ** 2)))


def slope_facts(ts: list) -> dict:
    """Per tile: realised α and α_φ for ``AZIMUTHS``; pooled: α (RMS, as tables pool it),
    α_φ (RMS) and ρ(s_x, s_y)."""
    per_tile, sxx, syy, sxy = [], [], [], []
    for t in ts:
        sx, sy = slopes(t)
        per_tile.append({"alpha": t.facts.alpha_realised.alpha,
                         "alpha_phi": {p: alpha_along(sx, sy, p) for p in AZIMUTHS}})
        sxx.append(np.mean(sx**2))
        syy.append(np.mean(sy**2))
        sxy.append(np.mean(sx * sy))
    return {"tiles": per_tile, "alpha": rms([t["alpha"] for t in per_tile]),
            "alpha_phi": {p: rms([t["alpha_phi"][p] for t in per_tile]) for p in AZIMUTHS},
            "rho": float(np.mean(sxy) / math.sqrt(np.mean(sxx) * np.mean(syy)))}


def rms(xs) -> float:
    """Root mean square."""
    return math.sqrt(float(np.mean(np.square(xs))))


def sem(xs) -> float:
    """Standard error of the mean."""
    return float(np.std(xs, ddof=1) / math.sqrt(len(xs)))


def signed(x: float) -> str:
    """``x`` to 5 decimals with its sign, a zero as +0.00000."""
    return f"{round(x, 5) + 0.0:+.5f}"


def smith(alpha: float, theta_deg: float) -> float:
    """Smith's G1 of isotropic Beckmann at ``alpha``."""
    from microsim.analytic.ndf import Beckmann
    from microsim.geometry import direction

    return float(Beckmann(alpha).G1(direction(math.radians(theta_deg), 0.0)))


def g1_per_tile(recipe, ts: list, thetas: tuple[float, ...], phi_deg: float,
                rays: int) -> np.ndarray:
    """(tiles, angles) G1 of each tile, traced as ``measure_g1_recipe`` traces it."""
    from microsim.measurement.masking import measure_g1
    from microsim.measurement.scene import PeriodicScene

    n = -(-int(rays) // REALISATIONS)
    seed = recipe.simulation.seed
    out = []
    for r, tile in enumerate(ts):
        with PeriodicScene(tile, None) as scene:
            g1, _ = measure_g1(scene, np.radians(thetas), math.radians(phi_deg), n,
                               np.random.default_rng(np.random.SeedSequence(
                                   seed, spawn_key=(r,))))
        out.append(g1)
    return np.array(out)


def g1_cell(g: np.ndarray, facts: dict, theta: float, phi: float, k: int,
            show_g1: bool) -> str:
    """G1 − Smith at the pooled α ± the ensemble error; G1 − Smith at each tile's α_φ,
    paired, ± its error."""
    col = g[:, k]
    pooled = float(col.mean()) - smith(facts["alpha"], theta)
    own = col - np.array([smith(t["alpha_phi"][phi], theta) for t in facts["tiles"]])
    head = f"{col.mean():.5f}: " if show_g1 else ""
    return (f"{head}{signed(pooled)} ± {sem(col):.5f}; "
            f"{signed(float(own.mean()))} ± {sem(own):.5f}")


def per_incidence_verdict(row: dict) -> str:
    """The verdict's rule (docs/compare.md) on one incidence's lobe bins."""
    from scipy.stats import chi2, norm

    n = row["lobe_bins"]
    if n < 2 or row["z_mean"] is None:
        return "—"
    mean_max = norm.ppf(1 - SIGNIFICANCE / 2) / math.sqrt(n)
    std_max = math.sqrt(chi2.ppf(1 - SIGNIFICANCE, n - 1) / (n - 1))
    ok = abs(row["z_mean"]) <= mean_max and row["z_std"] <= std_max
    return "agrees" if ok else "differs"


def order_cell(row: dict) -> str:
    """A per-incidence comparison as one table cell."""
    if not row["lobe_bins"]:
        return "no lobe"
    sim, model = np.mean(row["albedo_sim"]), np.mean(row["albedo_model"])
    err = np.sqrt(np.mean(np.square(row["albedo_model_err"])))
    ratio = f"{sim / model:.3f}" + (f" ± {err / model:.3f}" if err > 0 else "")
    return (f"{100 * row['median_rel_error']:.1f}%, z {row['z_mean']:+.2f} ± "
            f"{row['z_std']:.2f} ({row['lobe_bins']} bins): {per_incidence_verdict(row)}; "
            f"albedo {ratio}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--write", action="store_true",
                        help="write the section into docs/surfaces.md")
    parser.add_argument("--g1-rays", type=int, default=4_000_000,
                        help="rays per angle of each G1 at phi = 0, over the 32 tiles "
                             "(default 4000000)")
    parser.add_argument("--azimuth-rays", type=int, default=2_000_000,
                        help="rays per angle of each G1 at phi = 45 and 135 "
                             "(default 2000000)")
    parser.add_argument("--sim-rays", type=int, default=1_600_000,
                        help="rays per incident direction of each simulation "
                             "(default 1600000)")
    args = parser.parse_args()
    load_before = os.getloadavg()[0]

    # the surfaces, the gaussian scaled to the abc recipe's pooled realised alpha
    sets = {f"abc, C = {c:g}": (ABC, [f"surface.exponent={c:g}"]) for c in EXPONENTS}
    reference = slope_facts(tiles(load(ABC, [])))["alpha"]
    gauss = slope_facts(tiles(load(GAUSSIAN, ["surface.alpha=0.2"])))["alpha"]
    g_alpha = f"{0.2 * reference / gauss:.6f}"
    sets["gaussian"] = (GAUSSIAN, [f"surface.alpha={g_alpha}"])

    facts, g1 = {}, {}
    for name, (path, overrides) in sets.items():
        recipe = load(path, overrides)
        ts = tiles(recipe)
        facts[name] = slope_facts(ts)
        for phi in AZIMUTHS:
            thetas, rays = ((G1_THETA, args.g1_rays) if phi == 0
                            else (AZIMUTH_THETA, args.azimuth_rays))
            g1[name, phi] = g1_per_tile(recipe, ts, thetas, phi, rays)
        del ts
        print(f"g1 {name}: rho {facts[name]['rho']:+.3f}, mean G1 at phi = 0: "
              f"{g1[name, 0.0].mean(axis=0).round(5).tolist()}", file=sys.stderr, flush=True)

    # per order
    orders = {}
    theta_i = ",".join(map(str, SIM_THETA))
    with tempfile.TemporaryDirectory() as tmp:
        for name, (path, overrides) in sets.items():
            table = str(Path(tmp) / "table.exr")
            flags = [a for s in overrides for a in ("--set", s)]
            if path == GAUSSIAN:
                flags += ["--set", "material.kind=conductor"]
            cli("simulate", path, *flags, "--set", f"simulation.theta_i=[{theta_i}]",
                "--realisations", str(REALISATIONS), "--rays", str(args.sim_rays),
                "-o", table)
            orders[name] = (cli("compare", table, "--model", "beckmann",
                                "--component", "order1"),
                            cli("compare", table, "--model", "beckmann-ms",
                                "--component", "order2"))
            print(f"orders {name}: {orders[name][0]['agreement']['agrees']} "
                  f"{orders[name][1]['agreement']['agrees']}", file=sys.stderr, flush=True)

    thetas = ",".join(f"{t:g}" for t in G1_THETA)
    az = ",".join(f"{t:g}" for t in AZIMUTH_THETA)
    lines = [
        f"{measured_with(__file__, sys.argv[1:], load_before)}.", "",
        f"**G1 at φ = 0**, with the tiles and random streams of `microsim measure g1 {ABC} "
        f"--set surface.exponent=C --theta {thetas} --realisations {REALISATIONS} --rays "
        f"{args.g1_rays}` (the baseline: `microsim measure g1 {GAUSSIAN} --set "
        f"surface.alpha={g_alpha} …`, its 32 tiles' pooled realised α made equal to the abc "
        "recipe's). Each cell: G1; "
        "G1 − Smith's G1 at the pooled realised α (what the command prints) ± the ensemble "
        "standard error (32 tiles); the mean over tiles of G1 − Smith's G1 at the tile's "
        "own α along the ray's azimuth ± its standard error. ρ is the correlation of a "
        "facet's x- and y-slopes.", "",
        "| surface | realised α | ρ(s_x, s_y) | "
        + " | ".join(f"θ = {t:g}°" for t in G1_THETA) + " |",
        "| --- | --- | --- | " + " | ".join("---" for _ in G1_THETA) + " |"]
    for name in sets:
        f = facts[name]
        cells = [g1_cell(g1[name, 0.0], f, t, 0.0, k, True) for k, t in enumerate(G1_THETA)]
        lines.append(f"| {name} | {f['alpha']:.4f} | {f['rho']:+.3f} | "
                     + " | ".join(cells) + " |")
    lines += [
        "", f"**Along the diagonals** (the same with `--phi 45` or `--phi 135 --theta {az} "
        f"--rays {args.azimuth_rays}`): α_φ is the facets' roughness along the ray's azimuth "
        "(RMS over the tiles); each cell as above without G1.", "",
        "| surface | φ | α_φ | " + " | ".join(f"θ = {t:g}°" for t in AZIMUTH_THETA) + " |",
        "| --- | --- | --- | " + " | ".join("---" for _ in AZIMUTH_THETA) + " |"]
    for name in sets:
        f = facts[name]
        for phi in AZIMUTHS[1:]:
            cells = [g1_cell(g1[name, phi], f, t, phi, k, False)
                     for k, t in enumerate(AZIMUTH_THETA)]
            lines.append(f"| {name} | {phi:g}° | {f['alpha_phi'][phi]:.4f} | "
                         + " | ".join(cells) + " |")
    lines += [
        "", f"**Per scattering order**: `microsim simulate RECIPE --set "
        f"simulation.theta_i=[{theta_i}] --realisations {REALISATIONS} --rays "
        f"{args.sim_rays}` (the same `--set` as above; the gaussian with `--set "
        "material.kind=conductor`, gold as the recipe's), then `microsim compare TABLE "
        "--model beckmann --component order1` and `--model beckmann-ms --component "
        "order2` (at the table's realised α). Each cell: the median relative error, z "
        "mean ± spread over that incidence's lobe bins, and the verdict's rule applied to "
        "them; the albedo of the order, simulated over the model's (mean over R, G, B; ± "
        "the Monte Carlo model's own error); the last column is the command's own verdict "
        "over all incidences.", "",
        "| surface | order | " + " | ".join(f"θi = {t}°" for t in SIM_THETA)
        + " | verdict |", "| --- | --- | " + " | ".join("---" for _ in SIM_THETA)
        + " | --- |"]
    for name in sets:
        for label, res in zip(("1 vs beckmann", "2 vs beckmann-ms"), orders[name],
                              strict=True):
            verdict = "agrees" if res["agreement"]["agrees"] else "differs"
            lines.append(f"| {name} | {label} | "
                         + " | ".join(order_cell(row) for row in res["per_theta_i"])
                         + f" | {verdict} (z {res['z_mean']:+.2f} ± {res['z_std']:.2f}) |")
    text = "\n".join(lines)
    print(text)
    if args.write:
        write_section(DOC, "abc_smith", text)


if __name__ == "__main__":
    main()
