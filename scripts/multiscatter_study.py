"""How far Smith single scattering and Heitz et al. 2016's multiple scattering lie from
ray-traced Gaussian surfaces, per scattering order and incidence, with error bars.

Usage::

    python scripts/multiscatter_study.py scripts/study/*.toml --out docs/images/multiscatter
        [--set SECTION.KEY=VALUE] [--samples 4096] [--walks 1000000] [--seed 0]
        [--replicates 64] [--save-tables DIR] [--write]

The recipes in scripts/study/ are the published study (docs/compare.md, "Smith and its
multiple scattering against Gaussian surfaces, per order"). Each argument is a recipe
(``.toml``: simulated here, every ``--set`` applied) or a table already simulated
(``.exr``); tables must hold an order split (``[table] orders`` ≥ 2). The references and
estimators are ``microsim.comparison.orders``'s: Smith (``beckmann``) for order 1 and the
total, Heitz et al.'s walk (``beckmann-ms``) for every order and the total, at the
realised α pooled over the surface's realisations; albedo residuals with α-adjusted
batch-means errors (a table read from a file: its own albedo error), median lobe errors
with their replicate spread, noise floor and z spread ("no lobe" where a model has no
lobe bins).

Writes ``DIR/study.json`` (every row), ``DIR/study.md`` (the tables), ``DIR/albedo.png``
(albedo residual of each order against θi), ``DIR/lobe.png`` (median lobe errors with
their noise floors) and ``DIR/order2-LABEL.png`` (each table's order 2 against the walk's
in the plane of incidence at ``PLANE_THETA``); ``--save-tables DIR2`` also writes the
tables simulated here. ``--write`` puts the Markdown between the
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
from typing import Any

import numpy as np

import microsim
from microsim.comparison.orders import compare_orders
from microsim.files import write_section
from microsim.measurement.simulation import simulate_recipe
from microsim.plots import incidence_plane
from microsim.recipe import load

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "compare.md"
HEADING = "## Smith and its multiple scattering against Gaussian surfaces, per order"
PLANE_THETA = (0.0, 45.0, 70.0)
"""Incidences (degrees; the table's nearest) of the plane-of-incidence figures."""


def table_of(source: str, overrides: list[str]) -> tuple[Any, str]:
    """A table and its label: simulated from a recipe, or read from a file."""
    path = Path(source)
    if path.suffix.lower() == ".exr":
        return microsim.read_table(path), path.stem
    return simulate_recipe(load(path, overrides)), path.stem


def alpha_text(facts: dict[str, Any]) -> str:
    """The realised roughness ± its error of a row or a table's surface facts in JSON
    form (the same keys): αx, αy when anisotropic."""
    alpha, err = facts.get("alpha_realised"), facts.get("alpha_realised_stderr")
    if alpha is None:
        return "unknown"
    if isinstance(alpha, list):
        return ", ".join(f"{x:.3f}" for x in alpha)
    return f"{alpha:.3f}" + ("" if err is None else f" ± {err:.3f}")


def plane(table: Any, label: str, walk: np.ndarray, path: Path) -> None:
    """The table's order 2 against the walk's bin averages ``walk`` in the plane of
    incidence, at the incidences nearest ``PLANE_THETA``."""
    degrees = np.degrees(table.theta_i)
    chosen = sorted({int(np.argmin(np.abs(degrees - t))) for t in PLANE_THETA})
    incidence_plane(table, walk, path, "order2",
                    f"{label} (α {alpha_text(table.meta.surface.to_json())}): order 2, "
                    "simulated (±1 standard error) and Heitz et al. 2016's walk", "walk",
                    chosen)


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

    lines = [header, "",
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
    parser.add_argument("--write", action="store_true")
    args = parser.parse_args(argv)
    load_before, start, cpu = os.getloadavg()[0], time.perf_counter(), time.process_time()
    rows, timings = [], []
    for source in args.sources:
        t0 = time.perf_counter()
        table, label = table_of(source, args.overrides)
        t1 = time.perf_counter()
        if args.save_tables is not None and source.lower().endswith(".toml"):
            args.save_tables.mkdir(parents=True, exist_ok=True)
            microsim.write_table(table, args.save_tables / f"{label}.exr")
        try:
            mine, bins = compare_orders(table, label, args.samples, args.walks, args.seed,
                                        args.replicates)
        except ValueError as exc:
            parser.exit(2, f"error: {exc}\n")
        args.out.mkdir(parents=True, exist_ok=True)
        plane(table, label, bins[("order2", "walk")][0], args.out / f"order2-{label}.png")
        rows += mine
        timings.append((label, t1 - t0, time.perf_counter() - t1))
        print(f"{label}: table {t1 - t0:.0f} s, references {timings[-1][2]:.0f} s",
              file=sys.stderr)
    wall, cpu = time.perf_counter() - start, time.process_time() - cpu
    (args.out / "study.json").write_text(json.dumps(rows, indent=1), encoding="utf-8")
    first = rows[0]
    given = sys.argv[1:] if argv is None else argv
    header = (
        f"`python scripts/multiscatter_study.py {' '.join(given)}` "
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
    if args.write:
        write_section(DOC, "multiscatter-study", text, heading=HEADING)
    print(f"wrote {args.out / 'study.json'}, study.md, "
          + ", ".join(p.name for p in paths), file=sys.stderr)


if __name__ == "__main__":
    main()
