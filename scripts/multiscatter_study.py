"""How far Smith single scattering and Heitz et al. 2016's multiple scattering lie from
ray-traced Gaussian surfaces, per scattering order and incidence, with error bars.

Usage::

    python scripts/multiscatter_study.py scripts/study/*.toml --out docs/images/multiscatter
        [--set SECTION.KEY=VALUE] [--samples 4096] [--walks 1000000] [--seed 0]
        [--replicates 64] [--save-tables DIR] [--write-docs]

The recipes in scripts/study/ are the published study (docs/compare.md, "Smith and its
multiple scattering against Gaussian surfaces, per order"). Each argument is a recipe
(``.toml``: simulated here, every ``--set`` applied) or a table already simulated
(``.exr``); tables must hold an order split (``[table] orders`` ≥ 2). The references, at
the surface's realised roughness pooled over its realisations and with its facets'
Fresnel (as ``microsim compare`` takes them):

- **Smith**: Torrance-Sparrow + Beckmann + height-correlated Smith (``beckmann``), the
  single-scattering model: compared with order 1, and with the total (what single
  scattering leaves out);
- **walk**: Heitz et al. 2016's multiple-scattering Smith microsurface (``beckmann-ms``),
  compared with every order and the total. Its order 1 is Smith's exactly; its higher
  orders' bin averages are ``--samples`` random walks per bin (the total's random part is
  the sum of the orders', whose errors add in quadrature), its albedos the escape
  statistics of ``--walks`` walks per incidence.

For every table, incidence and component (``total`` and each order):

- **albedo** (∫ f_r cos θo dωo, mean over RGB) simulated and of each reference, and the
  **residual** simulated − reference ± its standard error. For a table simulated here
  the error is the batch-means error over realisations of A_r − γ α_r (A_r: realisation
  r's albedo, α_r its realised roughness, γ = dA/dα of the reference, a central
  difference at α ± ``SLOPE_STEP`` α): the residual is taken at the pooled α, so the part
  of the tiles' spread that their own α explains is not an error of it; with the
  reference's own error in quadrature. A table read from a file holds no realisation
  sums: its error is the table's own albedo error (which counts that part too: larger).
  The RGB mean's errors are the mean of the channels' (they share rays and walks: the
  bound for fully correlated channels).
- **median lobe error**: the median of |sim − model| / model over the model's lobe bins
  (≥ 10% of its peak per channel, as ``compare``), with an error bar (the standard
  deviation of the median over ``--replicates`` parametric replicates: every bin of table
  and model redrawn from a normal with its standard error), the **noise floor** (the
  median noise alone gives: the same medians with the model as the truth) and the **z
  spread** (``compare``'s, 1 for noise alone). Where the model has no lobe bins (an order
  no walk reached), "no lobe".

Writes ``DIR/study.json`` (every row), ``DIR/study.md`` (the tables), ``DIR/albedo.png``
(albedo residual of each order against θi), ``DIR/lobe.png`` (median lobe errors with
their noise floors) and ``DIR/order2-LABEL.png`` (each table's order 2 against the walk's
in the plane of incidence at ``PLANE_THETA``); ``--save-tables DIR2`` also writes the
tables simulated here. ``--write-docs`` puts the Markdown between the
``multiscatter-study`` markers of docs/compare.md.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

import microsim
from microsim.analytic.registry import parse_model_spec
from microsim.compare import (
    LOBE_FRACTION,
    bin_average,
    bin_estimate,
    direction,
    lobe_residuals,
    model_defaults,
)
from microsim.files import replace_marked
from microsim.plots import incidence_plane
from microsim.recipe import load
from microsim.simulation import simulate_recipe
from microsim.tables.components import order_range

ROOT = Path(__file__).resolve().parent.parent
MARKERS = ("<!-- multiscatter-study -->", "<!-- /multiscatter-study -->")
HEADING = "## Smith and its multiple scattering against Gaussian surfaces, per order"
SLOPE_STEP = 0.05
"""Relative step in α of the central difference dA/dα of a reference's albedo: small
against the curvature of A(α), large against the tiles' spread of α (2–3% here)."""
PLANE_THETA = (0.0, 45.0, 70.0)
"""Incidences (degrees; the table's nearest) of the plane-of-incidence figures."""


class References(NamedTuple):
    """The two references at the pooled realised α, and at α (1 ∓ ``SLOPE_STEP``)."""

    smith: Any
    walk: Any
    shifted: list[tuple[Any, Any]]
    step: float


def table_of(source: str, overrides: list[str]) -> tuple[Any, str]:
    """A table and its label: simulated from a recipe, or read from a file."""
    path = Path(source)
    if path.suffix.lower() == ".exr":
        return microsim.read_table(path), path.stem
    return simulate_recipe(load(path, overrides)), path.stem


def references(table: Any, samples: int, seed: int) -> References:
    """Smith and the walk with the table's realised α and Fresnel (``model_defaults``)."""
    defaults = model_defaults(table.meta)

    def pair(values: dict[str, Any]) -> tuple[Any, Any]:
        return (parse_model_spec("beckmann", values)[2],
                parse_model_spec(f"beckmann-ms:samples={samples},seed={seed}", values)[2])

    smith, walk = pair(defaults)
    alpha = defaults.get("alpha")
    if alpha is None:                       # anisotropic: no slope, no α adjustment
        return References(smith, walk, [], 0.0)
    shifted = [pair({**defaults, "alpha": alpha * s}) for s in (1 - SLOPE_STEP,
                                                                1 + SLOPE_STEP)]
    return References(smith, walk, shifted, 2 * SLOPE_STEP * alpha)


def incidences(table: Any) -> list[tuple[int, int, tuple]]:
    """(a, b, arguments of ``bin_average`` after the model) for every incidence, with
    the azimuth convention of ``compare_table``."""
    return [(a, b, (direction(t, p), table.bins.theta_edges, table.bins.phi_edges,
                    p if table.isotropic else 0.0))
            for a, t in enumerate(table.theta_i) for b, p in enumerate(table.phi_i)]


def model_bins(table: Any, refs: References) -> dict[tuple[str, str], tuple[np.ndarray,
                                                                             np.ndarray]]:
    """Bin averages and their standard errors, (a, b, nt, np, 3), per (component,
    reference): Smith for order 1 and the total, the walk for the orders above 1 (random
    parts) and the total (Smith + the orders' random parts)."""
    shape = table.values["total"].shape
    smith = np.zeros(shape)
    random = {c: (np.zeros(shape), np.zeros(shape)) for c in table.components
              if order_range(c)[0] >= 2}
    for a, b, args in incidences(table):
        smith[a, b] = bin_average(refs.smith, *args)
        for c, (mean, err) in random.items():
            mean[a, b], err[a, b] = bin_estimate(refs.walk.with_orders(*order_range(c)),
                                                 *args)
    zero = np.zeros(shape)
    out = {("order1", "smith"): (smith, zero), ("total", "smith"): (smith, zero),
           ("total", "walk"): (smith + sum(m for m, _ in random.values()),
                               np.sqrt(sum(e**2 for _, e in random.values())))}
    out.update({(c, "walk"): v for c, v in random.items()})
    return out


def lobe_of(model: np.ndarray) -> np.ndarray:
    """(a, b, nt, np, 3) bool: bins where the model holds ≥ ``LOBE_FRACTION`` of its peak,
    per incidence and channel (``compare.lobe_residuals``)."""
    peak = model.max(axis=(2, 3), keepdims=True)
    return model >= LOBE_FRACTION * np.where(peak > 0, peak, np.inf)


def lobe_medians(sim: np.ndarray, model: np.ndarray, lobe: np.ndarray) -> np.ndarray:
    """(a, b) median of |sim − model| / |model| over each incidence's lobe bins; NaN
    where it has none."""
    rel = np.abs(sim - model) / np.where(lobe, np.abs(model), 1.0)
    flat = np.where(lobe, rel, np.nan).reshape(rel.shape[:2] + (-1,))
    some = lobe.reshape(flat.shape).any(axis=-1)
    out = np.full(some.shape, np.nan)
    out[some] = np.nanmedian(flat[some], axis=-1)
    return out


def lobe_errors(table: Any, component: str, model: np.ndarray, model_err: np.ndarray,
                rng: np.random.Generator, replicates: int) -> dict[str, np.ndarray]:
    """Per incidence (a, b): ``median`` lobe error, its replicate standard deviation
    ``median_err``, the ``noise_floor`` and the ``z_std`` (module docstring); NaN where
    the model has no lobe."""
    sim = table.values[component]
    sim_err = np.nan_to_num(table.errors[component])
    lobe = lobe_of(model)

    def redraw(x: np.ndarray, e: np.ndarray) -> np.ndarray:
        return x + rng.standard_normal(x.shape) * e

    median = lobe_medians(sim, model, lobe)
    spread = np.std([lobe_medians(redraw(sim, sim_err), redraw(model, model_err), lobe)
                     for _ in range(replicates)], axis=0, ddof=1)
    noise = np.hypot(sim_err, model_err)
    floor = np.mean([lobe_medians(redraw(model, noise), model, lobe)
                     for _ in range(replicates)], axis=0)
    z_std = np.full(median.shape, np.nan)
    for a, b, _ in incidences(table):
        _, z, _ = lobe_residuals(sim[a, b], table.errors[component][a, b], model[a, b],
                                 model_err[a, b], table.dof[component][a, b])
        if z.size > 1:
            z_std[a, b] = z.std(ddof=1)
    return {"median": median, "median_err": spread, "noise_floor": floor, "z_std": z_std}


def realisation_albedos(table: Any) -> tuple[np.ndarray, np.ndarray] | None:
    """Per component, each realisation's albedo (RGB mean, (K, a, b), NaN where it traced
    nothing) and realised α (K,); None for a table without realisation sums (one read
    from a file) or without a scalar α per realisation."""
    per = table.meta.get("surface", {}).get("per_realisation")
    if table.sums is None or not per or not all(
            isinstance(r.get("alpha_realised"), int | float) for r in per):
        return None
    rays = table.realisation_rays.astype(float)
    with np.errstate(invalid="ignore", divide="ignore"):
        albedo = {c: table.sums[c].sum(axis=3).mean(axis=-1) / np.where(rays > 0, rays,
                                                                        np.nan)
                  for c in table.components}
    return albedo, np.array([r["alpha_realised"] for r in per])


def model_albedos(table: Any, refs: References, bins: dict, walks: int
                  ) -> dict[tuple[str, str], tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Per (component, reference) the reference's albedo (RGB mean, (a, b)), its error
    and its slope dA/dα (NaN without a scalar α): Smith's from its bin averages
    (Σ f_r Ω_proj: exact), the walk's from escapes."""
    omega = table.bins.projected_solid_angle[..., None]
    shape = table.albedo_of["total"].shape[:2]
    ranges = [order_range(c) for c in table.components]
    out: dict[tuple[str, str], tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
    smith = (bins[("order1", "smith")][0] * omega).sum(axis=(2, 3)).mean(axis=-1)
    walk = {c: (np.zeros(shape), np.zeros(shape), np.full(shape, np.nan))
            for c in table.components}
    smith_slope = np.full(shape, np.nan)
    for a, b, args in incidences(table):
        mean, err = refs.walk.albedo(args[0], walks, ranges)
        ends = [model.albedo(args[0], walks, ranges)[0] for _, model in refs.shifted]
        for j, c in enumerate(table.components):
            walk[c][0][a, b], walk[c][1][a, b] = mean[j].mean(), err[j].mean()
            if ends:
                walk[c][2][a, b] = (ends[1][j] - ends[0][j]).mean() / refs.step
        if refs.shifted:
            lo, hi = ((bin_average(s, *args) * omega).sum(axis=(0, 1)).mean()
                      for s, _ in refs.shifted)
            smith_slope[a, b] = (hi - lo) / refs.step
    for c in ("order1", "total"):
        out[(c, "smith")] = (smith, np.zeros(shape), smith_slope)
    out.update({(c, "walk"): v for c, v in walk.items()})
    return out


def study(table: Any, label: str, samples: int, walks: int, seed: int, replicates: int,
          plane: Path | None = None) -> list[dict[str, Any]]:
    """The rows of one table: one per incidence and component; with ``plane``, the
    plane of incidence of its order 2 against the walk's written there (PNG)."""
    if table.orders is None or table.orders < 2:
        raise SystemExit(f"error: {label}: the table holds no order split (simulate it "
                         "with [table] orders >= 2)")
    refs = references(table, samples, seed)
    bins = model_bins(table, refs)
    albedos = model_albedos(table, refs, bins, walks)
    per_realisation = realisation_albedos(table)
    if plane is not None:
        degrees = np.degrees(table.theta_i)
        chosen = sorted({int(np.argmin(np.abs(degrees - t))) for t in PLANE_THETA})
        incidence_plane(table, bins[("order2", "walk")][0], plane, "order2",
                        f"{label} (α {alpha_text(table.meta.get('surface', {}))}): "
                        "order 2, simulated (±1 standard error) and Heitz et al. 2016's "
                        "walk", "walk", chosen)
    rng = np.random.default_rng(seed)
    surface = table.meta.get("surface", {})
    material = table.meta.get("recipe", {}).get("material", {})
    rows: dict[tuple[int, int, str], dict[str, Any]] = {}
    for a, b, _ in incidences(table):
        for c in table.components:
            rows[(a, b, c)] = {
                "table": label, "alpha_realised": surface.get("alpha_realised"),
                "alpha_realised_stderr": surface.get("alpha_realised_stderr"),
                "material": sorted({m.get("kind") for m in material.values()}),
                "realisations": int(table.realisations[a, b]),
                "rays": int(table.rays[a, b]), "error_model": table.error_model,
                "theta_i": float(np.degrees(table.theta_i[a])),
                "phi_i": float(np.degrees(table.phi_i[b])), "component": c,
                "albedo_sim": float(table.albedo_of[c][a, b].mean()),
                "albedo_sim_err": float(table.albedo_err_of[c][a, b].mean())}
    for (c, ref), (model, model_err) in bins.items():
        lobe = lobe_errors(table, c, model, model_err, rng, replicates)
        albedo, albedo_err, slope = albedos[(c, ref)]
        for (a, b), median in np.ndenumerate(lobe["median"]):
            row = rows[(a, b, c)]
            residual = row["albedo_sim"] - albedo[a, b]
            sim_err, kind = row["albedo_sim_err"], "table"
            if per_realisation is not None and np.isfinite(slope[a, b]):
                r = per_realisation[0][c][:, a, b] - slope[a, b] * per_realisation[1]
                r = r[np.isfinite(r)]
                if r.size > 1:
                    sim_err, kind = float(r.std(ddof=1) / np.sqrt(r.size)), "alpha-adjusted"
            finite = np.isfinite(median)
            row.update({
                f"albedo_{ref}": float(albedo[a, b]),
                f"albedo_{ref}_err": float(albedo_err[a, b]),
                f"albedo_{ref}_slope": float(slope[a, b]),
                f"residual_{ref}": residual,
                f"residual_{ref}_err": float(np.hypot(sim_err, albedo_err[a, b])),
                f"residual_{ref}_error_model": kind,
                f"median_rel_{ref}": float(median) if finite else None,
                f"median_rel_{ref}_err": float(lobe["median_err"][a, b]) if finite else None,
                f"noise_floor_{ref}": float(lobe["noise_floor"][a, b]) if finite else None,
                f"z_std_{ref}": float(lobe["z_std"][a, b]) if finite else None})
    for (c, ref), (albedo, albedo_err, _) in albedos.items():   # the walk's order 1 too
        for (a, b), value in np.ndenumerate(albedo):
            rows[(a, b, c)].setdefault(f"albedo_{ref}", float(value))
            rows[(a, b, c)].setdefault(f"albedo_{ref}_err", float(albedo_err[a, b]))
    return list(rows.values())


def alpha_text(facts: dict[str, Any]) -> str:
    """The realised roughness ± its error of a row or a table's ``meta["surface"]``
    (the same keys): αx, αy when anisotropic."""
    alpha, err = facts.get("alpha_realised"), facts.get("alpha_realised_stderr")
    if alpha is None:
        return "unknown"
    if isinstance(alpha, list):
        return ", ".join(f"{x:.3f}" for x in alpha)
    return f"{alpha:.3f}" + ("" if err is None else f" ± {err:.3f}")


def _digits(error: float) -> int:
    """Decimals that show an error to one significant figure (at least 4)."""
    return max(4, -math.floor(math.log10(error))) if error > 0 else 4


def _pm(row: dict[str, Any], key: str) -> str:
    """``value ± error`` of a row's key, "—" where the row has none."""
    if key not in row:
        return "—"
    digits = _digits(row[key + "_err"])
    return f"{row[key]:+.{digits}f} ± {row[key + '_err']:.{digits}f}"


def _lobe(row: dict[str, Any], ref: str) -> str:
    """``median ± error (floor)`` in percent."""
    key = f"median_rel_{ref}"
    if key not in row:
        return "—"
    if row[key] is None:
        return "no lobe"
    return (f"{100 * row[key]:.1f} ± {100 * row[key + '_err']:.1f} "
            f"({100 * row[f'noise_floor_{ref}']:.1f})")


def markdown(rows: list[dict[str, Any]], header: str) -> str:
    """Two Markdown tables (albedo residuals, median lobe errors): one row per table and
    incidence, a column pair per component."""
    orders = [c for c in dict.fromkeys(r["component"] for r in rows) if c != "total"]
    by = {(r["table"], r["theta_i"], r["phi_i"], r["component"]): r for r in rows}
    keys = list(dict.fromkeys((r["table"], r["theta_i"], r["phi_i"]) for r in rows))
    alpha = {r["table"]: alpha_text(r) for r in rows}

    def incidence(key: tuple) -> str:
        return f"{key[1]:.0f}°" + (f", φi {key[2]:.0f}°" if key[2] else "")

    lines = [MARKERS[0], "", header, "",
             "**Albedo**: simulated, and the residual simulated − reference ± its "
             "standard error (order 1 against Smith, the others against the walk).", "",
             "| surface (α realised) | θi | " + " | ".join(
                 f"{c} sim | {c} − {'Smith' if c == 'order1' else 'walk'}"
                 for c in orders + ["total"]) + " |",
             "| --- | --- |" + " --- | --- |" * (len(orders) + 1)]
    for key in keys:
        cells = []
        for c in orders + ["total"]:
            r = by[key + (c,)]
            ref = "smith" if c == "order1" else "walk"
            digits = _digits(r[f"residual_{ref}_err"])
            cells += [f"{r['albedo_sim']:.{digits}f}", _pm(r, f"residual_{ref}")]
        lines.append(f"| {key[0]} ({alpha[key[0]]}) | {incidence(key)} | "
                     + " | ".join(cells) + " |")
    lines += ["", "**Median lobe error** (%) ± its replicate spread (noise floor: what "
              "the two estimates' noise alone gives).", "",
              "| surface | θi | order1 vs Smith | " + " | ".join(
                  f"{c} vs walk" for c in orders[1:]) + " | total vs walk | total vs "
              "Smith |", "| --- | --- |" + " --- |" * (len(orders) + 2)]
    for key in keys:
        cells = [_lobe(by[key + ("order1",)], "smith")]
        cells += [_lobe(by[key + (c,)], "walk") for c in orders[1:]]
        cells += [_lobe(by[key + ("total",)], "walk"), _lobe(by[key + ("total",)], "smith")]
        lines.append(f"| {key[0]} | {incidence(key)} | " + " | ".join(cells) + " |")
    lines += ["", MARKERS[1]]
    return "\n".join(lines)


def _panels(rows: list[dict[str, Any]]) -> tuple[Any, Any, list[str]]:
    """A figure with one panel per table (three per row)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    labels = list(dict.fromkeys(r["table"] for r in rows))
    ncols = min(3, len(labels))
    nrows = -(-len(labels) // ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(4.4 * ncols, 3.4 * nrows),
                             squeeze=False, sharex=True)
    for ax in axes.flat[len(labels):]:
        ax.set_visible(False)
    return fig, axes, labels


def figures(rows: list[dict[str, Any]], out: Path) -> list[Path]:
    """``albedo.png`` (albedo residual per component against θi, ±1 standard error) and
    ``lobe.png`` (median lobe errors ± their spread, noise floors dotted), one panel per
    table."""
    import matplotlib.pyplot as plt

    components = list(dict.fromkeys(r["component"] for r in rows))
    components = components[1:] + components[:1]                  # total last
    series = {"albedo": [(c, "smith" if c == "order1" else "walk") for c in components],
              "lobe": [("order1", "smith")] + [(c, "walk") for c in components[1:]]
              + [("total", "smith")]}
    paths = []
    for name, pairs in series.items():
        fig, axes, labels = _panels(rows)
        for ax, label in zip(axes.flat, labels, strict=False):
            mine = [r for r in rows if r["table"] == label]
            for k, (c, ref) in enumerate(pairs):
                rs = sorted((r for r in mine if r["component"] == c),
                            key=lambda r: r["theta_i"])
                key = f"residual_{ref}" if name == "albedo" else f"median_rel_{ref}"
                rs = [r for r in rs if r.get(key) is not None]
                theta = [r["theta_i"] for r in rs]
                ax.errorbar(theta, [r[key] for r in rs], yerr=[r[key + "_err"] for r in rs],
                            fmt="o-", ms=3, lw=1, capsize=2, color=f"C{k}",
                            label=f"{c} − {ref}" if name == "albedo" else f"{c} vs {ref}")
                if name == "lobe":
                    ax.plot(theta, [r[f"noise_floor_{ref}"] for r in rs], ":",
                            color=f"C{k}", lw=1)
            if name == "albedo":
                ax.axhline(0.0, color="k", lw=0.6)
            else:
                ax.set_yscale("log")
            ax.set_title(f"{label} (α {alpha_text(mine[0])})", fontsize=9)
            ax.grid(alpha=0.3, which="both")
        for ax in axes[-1]:
            ax.set_xlabel("θi (°)")
        axes[0, 0].set_ylabel("albedo: simulated − reference" if name == "albedo" else
                              "median relative lobe error\n(dotted: noise floor)")
        axes[0, 0].legend(fontsize=7)
        fig.tight_layout()
        paths.append(out / f"{name}.png")
        fig.savefig(paths[-1], dpi=100)
        plt.close(fig)
    return paths


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("sources", nargs="+", metavar="RECIPE_OR_TABLE")
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--set", dest="overrides", action="append", default=[])
    parser.add_argument("--samples", type=int, default=4096,
                        help="random walks per bin of the multiple-scattering model")
    parser.add_argument("--walks", type=int, default=1_000_000,
                        help="random walks per incidence for its albedo per order")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--replicates", type=int, default=64)
    parser.add_argument("--save-tables", type=Path, metavar="DIR",
                        help="also write the tables simulated here")
    parser.add_argument("--write-docs", action="store_true")
    args = parser.parse_args(argv)
    load_before, start, cpu = os.getloadavg()[0], time.perf_counter(), time.process_time()
    rows, timings = [], []
    for source in args.sources:
        t0 = time.perf_counter()
        table, label = table_of(source, args.overrides)
        t1 = time.perf_counter()
        if args.save_tables is not None and source.lower().endswith(".toml"):
            args.save_tables.mkdir(parents=True, exist_ok=True)
            table.write(args.save_tables / f"{label}.exr")
        args.out.mkdir(parents=True, exist_ok=True)
        rows += study(table, label, args.samples, args.walks, args.seed, args.replicates,
                      args.out / f"order2-{label}.png")
        timings.append((label, t1 - t0, time.perf_counter() - t1))
        print(f"{label}: table {t1 - t0:.0f} s, references {timings[-1][2]:.0f} s",
              file=sys.stderr)
    wall, cpu = time.perf_counter() - start, time.process_time() - cpu
    (args.out / "study.json").write_text(json.dumps(rows, indent=1), encoding="utf-8")
    first = rows[0]
    header = (
        f"`python scripts/multiscatter_study.py {' '.join(args.sources)}` "
        f"({first['realisations']} realisations, {first['rays']:,} rays per incidence; "
        f"{args.samples} walks per bin, {args.walks:,} per incidence for the albedos, "
        f"{args.replicates} replicates; {time.strftime('%Y-%m-%d')}, {os.cpu_count()} "
        f"CPUs, load average {load_before:.1f} before and {os.getloadavg()[0]:.1f} "
        f"after: {wall / 60:.1f} min wall, {cpu / 60:.1f} min CPU; per table, simulation "
        f"and references: " + ", ".join(f"{t:.0f} + {r:.0f} s" for _, t, r in timings)
        + ").")
    text = markdown(rows, header)
    (args.out / "study.md").write_text(text + "\n", encoding="utf-8")
    paths = figures(rows, args.out)
    print(text)
    if args.write_docs:
        replace_marked(ROOT / "docs" / "compare.md", text, *MARKERS, heading=HEADING)
    print(f"wrote {args.out / 'study.json'}, study.md, "
          + ", ".join(p.name for p in paths), file=sys.stderr)


if __name__ == "__main__":
    main()
