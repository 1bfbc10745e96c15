"""How far Smith single scattering and Heitz et al. 2016's multiple scattering lie from
ray-traced Gaussian surfaces, per scattering order and incidence, with error bars.

Usage::

    python scripts/multiscatter_study.py RECIPE_OR_TABLE [...] --out DIR
        [--set SECTION.KEY=VALUE] [--samples 256] [--walks 200000] [--seed 0]
        [--replicates 64] [--write-docs]

Each argument is a recipe (``.toml``: simulated here, every ``--set`` applied, e.g.
``table.orders=4``) or a table already simulated (``.exr``, e.g. an ensemble table from
``microsim batch``). Tables must hold an order split (``[table] orders``). For every table,
incidence and component (``total`` and each order), against the Beckmann models at the
surface's realised roughness with the facets' Fresnel (as ``microsim compare``):

- **albedo**: simulated ± its standard error; Torrance-Sparrow + height-correlated Smith
  (``beckmann``, order 1 and total: it holds no other order); Heitz et al.'s walk
  (``SmithMultipleScattering.albedo``, ``--walks`` walks: escape statistics) ± its error;
- **median lobe error** of the simulated bins against each model's bin averages
  (``compare_table``: lobe = bins where the model holds ≥ 10% of its peak), with an
  error bar: the standard deviation of the median over ``--replicates`` parametric
  replicates (every bin of table and model redrawn from a normal with its standard error),
  and the median a table of noise alone would show (``noise_floor``: the same medians
  with the model as the truth).

Writes ``DIR/study.json`` (every row), ``DIR/study.md`` (the tables) and ``DIR/study.png``
(albedo per order against θi: one panel per table; simulation with error bars, the walk's
orders as lines with ±1σ bands, Torrance-Sparrow's single scattering dashed). With
``--write-docs`` the Markdown also replaces the section between the ``multiscatter-study``
markers in docs/compare.md.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import numpy as np

import microsim
from microsim.analytic.registry import parse_model_spec
from microsim.compare import LOBE_FRACTION, compare_table, direction, model_defaults
from microsim.files import replace_marked
from microsim.recipe import load
from microsim.simulation import simulate_recipe
from microsim.tables.components import order_range

ROOT = Path(__file__).resolve().parent.parent
MARKERS = ("<!-- multiscatter-study -->", "<!-- /multiscatter-study -->")


def table_of(source: str, overrides: list[str]) -> tuple[Any, str]:
    """A table and its label: simulated from a recipe, or read from a file."""
    path = Path(source)
    if path.suffix.lower() == ".exr":
        return microsim.read_table(path), path.stem
    return simulate_recipe(load(path, overrides)), path.stem


def median_with_error(table: Any, component: str, model_bins: np.ndarray,
                      model_err: np.ndarray, rng: np.random.Generator, replicates: int
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per incidence: the median relative lobe error, its replicate standard deviation,
    and the median noise alone gives (``module docstring``).

    Returns
    -------
    median, error, floor : (a, b) float
    """
    sim = table.values[component]
    sim_err = np.nan_to_num(table.errors[component])
    peak = model_bins.max(axis=(2, 3), keepdims=True)
    lobe = model_bins >= LOBE_FRACTION * np.where(peak > 0, peak, np.inf)

    def medians(s: np.ndarray, m: np.ndarray) -> np.ndarray:
        rel = np.where(lobe, np.abs(s - m) / np.where(lobe, m, 1.0), np.nan)
        return np.nanmedian(rel.reshape(rel.shape[:2] + (-1,)), axis=-1)

    def redraw(x: np.ndarray, e: np.ndarray) -> np.ndarray:
        return x + rng.standard_normal(x.shape) * e

    median = medians(sim, model_bins)
    spread = np.std([medians(redraw(sim, sim_err), redraw(model_bins, model_err))
                     for _ in range(replicates)], axis=0, ddof=1)
    floor = np.mean([medians(redraw(model_bins, np.hypot(sim_err, model_err)), model_bins)
                     for _ in range(replicates)], axis=0)
    return median, spread, floor


def study(table: Any, label: str, samples: int, walks: int, seed: int, replicates: int
          ) -> list[dict[str, Any]]:
    """The rows of one table: one per incidence and component."""
    if table.orders is None:
        raise SystemExit(f"{label}: the table holds no order split (simulate it with "
                         "[table] orders)")
    defaults = model_defaults(table.meta)
    _, _, smith = parse_model_spec("beckmann", defaults)
    _, _, walk = parse_model_spec(f"beckmann-ms:samples={samples},seed={seed}", defaults)
    rng = np.random.default_rng(seed)
    rows: dict[tuple[int, int, str], dict[str, Any]] = {}
    ranges = [order_range(c) for c in table.components]
    albedo = {(a, b): walk.albedo(direction(t, p), walks, ranges)
              for a, t in enumerate(table.theta_i) for b, p in enumerate(table.phi_i)}
    for j, component in enumerate(table.components):
        models = {"multiple": walk}
        if order_range(component)[1] == 1 or component == "total":
            models["smith"] = smith
        for key, model in models.items():
            compared = compare_table(table, model, component)
            median, spread, floor = median_with_error(
                table, component, compared["model"], compared["model_err"], rng, replicates)
            for (a, b), _ in np.ndenumerate(median):
                row = rows.setdefault((a, b, component), {
                    "table": label,
                    "alpha_realised": table.meta.surface.alpha_realised.to_json(),
                    "theta_i": float(np.degrees(table.theta_i[a])),
                    "phi_i": float(np.degrees(table.phi_i[b])), "component": component,
                    "albedo_sim": float(table.albedo_of[component][a, b].mean()),
                    "albedo_sim_err": float(table.albedo_err_of[component][a, b].mean())})
                per = compared["per_theta_i"][a * len(table.phi_i) + b]
                row[f"median_rel_{key}"] = float(median[a, b])
                row[f"median_rel_{key}_err"] = float(spread[a, b])
                row[f"noise_floor_{key}"] = float(floor[a, b])
                if key == "smith":
                    row["albedo_smith"] = float(np.mean(per["albedo_model"]))
        for (a, b), (mean, err) in albedo.items():
            rows[(a, b, component)].update(albedo_multiple=float(mean[j].mean()),
                                           albedo_multiple_err=float(err[j].mean()))
    return list(rows.values())


def alpha_text(row: dict[str, Any]) -> str:
    """The realised roughness of a row's surface: one number, or αx, αy."""
    alpha = row["alpha_realised"]
    if alpha is None:
        return "unknown"
    return ", ".join(f"{a:.3f}" for a in alpha) if isinstance(alpha, list) else f"{alpha:.3f}"


def markdown(rows: list[dict[str, Any]], header: str) -> str:
    """The rows as one Markdown table per source table."""
    def pm(row: dict[str, Any], key: str, scale: float = 1.0, digits: int = 4) -> str:
        if key not in row:
            return "—"
        return f"{scale * row[key]:.{digits}f} ± {scale * row[key + '_err']:.{digits}f}"

    lines = [MARKERS[0], "", header, ""]
    for label in dict.fromkeys(r["table"] for r in rows):
        mine = [r for r in rows if r["table"] == label]
        lines += [f"**{label}** (α realised {alpha_text(mine[0])})", "",
                  "| θi | component | albedo sim | Smith | multiple (walk) | median lobe "
                  "error vs Smith (%) | vs multiple (%) | noise floor (%) |",
                  "| --- | --- | --- | --- | --- | --- | --- | --- |"]
        for r in mine:
            smith = f"{r['albedo_smith']:.4f}" if "albedo_smith" in r else "—"
            lines.append(
                f"| {r['theta_i']:.0f}° | {r['component']} | {pm(r, 'albedo_sim')} | "
                f"{smith} | {pm(r, 'albedo_multiple')} | "
                f"{pm(r, 'median_rel_smith', 100, 1)} | {pm(r, 'median_rel_multiple', 100, 1)}"
                f" | {100 * r['noise_floor_multiple']:.1f} |")
        lines.append("")
    lines.append(MARKERS[1])
    return "\n".join(lines)


def figure(rows: list[dict[str, Any]], path: Path) -> None:
    """Albedo per order against θi, one panel per table."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    labels = list(dict.fromkeys(r["table"] for r in rows))
    fig, axes = plt.subplots(1, len(labels), figsize=(4.2 * len(labels), 3.6), squeeze=False)
    for ax, label in zip(axes[0], labels, strict=True):
        mine = [r for r in rows if r["table"] == label]
        for k, component in enumerate(dict.fromkeys(r["component"] for r in mine)):
            rs = [r for r in mine if r["component"] == component]
            theta = [r["theta_i"] for r in rs]
            colour = f"C{k}"
            ax.errorbar(theta, [r["albedo_sim"] for r in rs],
                        yerr=[r["albedo_sim_err"] for r in rs], fmt="o", ms=4,
                        color=colour, label=f"{component} simulated")
            mean = np.array([r["albedo_multiple"] for r in rs])
            err = np.array([r["albedo_multiple_err"] for r in rs])
            ax.plot(theta, mean, "-", color=colour, lw=1)
            ax.fill_between(theta, mean - err, mean + err, color=colour, alpha=0.2)
            if component == "order1":
                ax.plot(theta, [r["albedo_smith"] for r in rs], "--", color=colour, lw=1,
                        label="Torrance-Sparrow + Smith")
        ax.set_title(f"{label} (α {alpha_text(mine[0])})", fontsize=9)
        ax.set_xlabel("θi (°)")
        ax.set_yscale("log")
        ax.grid(alpha=0.3)
    axes[0, 0].set_ylabel("albedo (lines: Heitz et al. 2016's walk, ±1σ)")
    axes[0, 0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("sources", nargs="+", metavar="RECIPE_OR_TABLE")
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--set", dest="overrides", action="append", default=[])
    parser.add_argument("--samples", type=int, default=256,
                        help="random walks per bin of the multiple-scattering model")
    parser.add_argument("--walks", type=int, default=200_000,
                        help="random walks per incidence for its albedo per order")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--replicates", type=int, default=64)
    parser.add_argument("--write-docs", action="store_true")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    rows = []
    for source in args.sources:
        table, label = table_of(source, args.overrides)
        rows += study(table, label, args.samples, args.walks, args.seed, args.replicates)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "study.json").write_text(json.dumps(rows, indent=1), encoding="utf-8")
    header = (f"`python scripts/multiscatter_study.py {' '.join(args.sources)}` "
              f"({args.samples} walks per bin, {args.walks} per incidence for the albedo, "
              f"{args.replicates} replicates; {time.perf_counter() - start:.0f} s). Albedo "
              "± standard error; median relative error over the model's lobe bins ± its "
              "replicate spread; the noise floor is the median noise alone gives.")
    text = markdown(rows, header)
    (args.out / "study.md").write_text(text + "\n", encoding="utf-8")
    figure(rows, args.out / "study.png")
    print(text)
    if args.write_docs:
        replace_marked(ROOT / "docs" / "compare.md", text, *MARKERS,
                       heading="## Smith and its multiple scattering against Gaussian "
                               "surfaces, per order")
    print(f"wrote {args.out / 'study.json'}, study.md, study.png")


if __name__ == "__main__":
    main()
