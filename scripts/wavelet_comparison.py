"""Spherical harmonics against wavelets on simulated tables: the coefficients and bytes each
basis needs to reach 10 %, 5 % and 2 % median relative error on the lobe bins.

Usage::

    python scripts/wavelet_comparison.py [--tables DIR] [--write]

Each case's table is made with ``microsim simulate`` (under ``nice -n 19``; skipped when
``DIR/<case>.exr`` exists), then measured with ``microsim wavelets TABLE --json`` at a fine
sweep of kept counts. ``--write`` puts the comparison into docs/table-format.md (marked
section) and draws docs/images/wavelets.png.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path
from typing import Any

from microsim.files import atomic_path, write_section
from microsim.tables.compression import needed

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "table-format.md"
FIGURE = ROOT / "docs" / "images" / "wavelets.png"
SECTION = "wavelet-comparison"
HEADING = "## Wavelets (part `wavelet`)"
TARGETS = (0.10, 0.05, 0.02)
GOLD = ["--set", "material.kind=conductor", "--set", "material.eta=[0.2,0.92,1.1]",
        "--set", "material.k=[3.9,2.45,2.14]"]
GAUSSIAN = ["surfaces/gaussian-0.3.toml", "--set", "simulation.theta_i=[0,30,60]",
            "--rays", "6400000", "--realisations", "32"]
"""The Gaussian cases: 32 realisations of the recipe's 256² tile (its default ensemble),
200 000 rays each per direction; one tile's table carries that tile's fine angular
structure (docs/ensembles.md), which is not the surface's BRDF."""
CASES: dict[str, tuple[str, list[str]]] = {
    "mirror-0.05": ("Gaussian mirror α = 0.05",
                    [*GAUSSIAN, "--set", "surface.alpha=0.05"]),
    "mirror-0.2": ("Gaussian mirror α = 0.2", [*GAUSSIAN, "--set", "surface.alpha=0.2"]),
    "mirror-0.5": ("Gaussian mirror α = 0.5", [*GAUSSIAN, "--set", "surface.alpha=0.5"]),
    "gold-0.2": ("Gaussian gold α = 0.2", [*GAUSSIAN, "--set", "surface.alpha=0.2", *GOLD]),
    "velvet-80": ("velvet, θi = 80°", ["surfaces/velvet.toml", "--set",
                                       "simulation.theta_i=[80]", "--rays", "20000000"]),
    "twill": ("2/1 twill weave", ["surfaces/weave-twill.toml", "--set",
                                  "simulation.theta_i=[0,60]", "--set",
                                  "simulation.phi_i=[0,90]", "--rays", "8000000"]),
    "cylinders": ("gold cylinders", ["surfaces/cylinders.toml", "--rays", "4000000"]),
}
"""Case name: (label, ``microsim simulate`` arguments)."""


def microsim() -> list[str]:
    """``microsim`` as the installed command runs it."""
    return [sys.executable, "-m", "microsim.cli"]


def make_table(name: str, folder: Path) -> Path:
    """The case's table, simulated under ``nice -n 19`` unless it exists."""
    path = folder / f"{name}.exr"
    if not path.exists():
        folder.mkdir(parents=True, exist_ok=True)
        subprocess.run(["nice", "-n", "19", *microsim(), "simulate", *CASES[name][1],
                        "-o", str(path)], cwd=ROOT, check=True)
    return path


WAVELETS = ("haar", "db4")
"""The wavelets compared with the harmonics."""


def measure(path: Path, wavelet: str, steps: int) -> dict[str, Any]:
    """``microsim wavelets TABLE --json`` under ``nice -n 19``."""
    out = subprocess.run(["nice", "-n", "19", *microsim(), "wavelets", str(path), "--json",
                          "--wavelet", wavelet, "--steps", str(steps)], cwd=ROOT,
                         check=True, capture_output=True, text=True).stdout
    return json.loads(out)


def cost(result: dict[str, Any], basis: str, target: float) -> tuple[int, int] | None:
    """Coefficients per incidence and colour, and bytes for the whole table, to reach
    ``target`` (None where it is not reached)."""
    k = needed(result[basis], target)
    if k is None:
        return None
    return k, result["bytes"][basis][[c for c, _ in result[basis]].index(k)]


def cell(result: dict[str, Any], basis: str, target: float) -> str:
    """``kept / bytes`` to reach ``target``, or the floor where it is not reached."""
    reached = cost(result, basis, target)
    if reached is None:
        return f"— (floor {100 * result[basis][-1][1]:.1f} %)"
    return f"{reached[0]} / {reached[1] / 1024:.1f} KiB"


def fewest_bytes(by_wavelet: dict[str, dict[str, Any]], target: float) -> str:
    """The basis that reaches ``target`` in the fewest bytes ("none" if none does)."""
    first = by_wavelet[WAVELETS[0]]
    costs = {"harmonics": cost(first, "sh", target)} | {
        w: cost(by_wavelet[w], "wavelet", target) for w in WAVELETS}
    reached = {name: c[1] for name, c in costs.items() if c is not None}
    return min(reached, key=reached.get) if reached else "none"


def section(results: dict[str, dict[str, dict[str, Any]]], steps: int) -> str:
    """The Markdown comparison."""
    head = ("| case | θi (φi) | table noise | target | harmonics | "
            + " | ".join(WAVELETS) + " | fewest bytes |")
    lines = [head, "|" + " --- |" * (6 + len(WAVELETS))]
    for name, by_wavelet in results.items():
        first = by_wavelet[WAVELETS[0]]
        angles = ", ".join(sorted({f"{r['theta_i']:.0f}" for r in first["per_incidence"]},
                                  key=float))
        azimuths = sorted({f"{r['phi_i']:.0f}" for r in first["per_incidence"]}, key=float)
        if len(azimuths) > 1:
            angles += f" ({', '.join(azimuths)})"
        for j, target in enumerate(TARGETS):
            label = (CASES[name][0], angles, f"{100 * first['median_rel_stderr']:.2f} %") \
                if j == 0 else ("", "", "")
            cells = [cell(first, "sh", target)] + [cell(by_wavelet[w], "wavelet", target)
                                                   for w in WAVELETS]
            lines.append(f"| {' | '.join(label)} | {100 * target:g} % | "
                         + " | ".join(cells) + f" | {fewest_bytes(by_wavelet, target)} |")
    first = next(iter(results.values()))[WAVELETS[0]]
    return "\n".join([
        f"Measured by `python scripts/wavelet_comparison.py --write` (each table made with "
        f"the `microsim simulate` arguments in the script's `CASES`, then `microsim "
        f"wavelets TABLE --json --steps {steps} --wavelet W`). Each cell: coefficients "
        f"kept per incidence and colour / bytes for the whole table (every incidence, "
        f"RGB; {first['bytes_per_coefficient']['sh']} bytes a harmonic coefficient, "
        f"{first['bytes_per_coefficient']['wavelet']} a wavelet one: a float32 value and "
        f"its index), the fewest from which the median relative error on the lobe bins "
        f"stays at or below the target, in a sweep of {steps} counts per doubling; "
        f"harmonics of order {first['sh_order']} ({(first['sh_order'] + 1) ** 2} "
        f"coefficients), wavelets on {first['resolution']}² pixels. A dash: not reached "
        f"with every coefficient (the floor, in brackets). Table noise: the table's "
        "median relative standard error on the lobe bins.",
        "", *lines, "", "![error against bytes](images/wavelets.png)"])


def figure(results: dict[str, dict[str, dict[str, Any]]], path: Path) -> None:
    """Error against bytes, one panel per case."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 4, figsize=(16, 7.5), sharey=True)
    for ax, (name, by_wavelet) in zip(axes.ravel(), results.items(), strict=False):
        first = by_wavelet[WAVELETS[0]]
        curves = [("harmonics", first["sh"], first["bytes"]["sh"])] + [
            (w, by_wavelet[w]["wavelet"], by_wavelet[w]["bytes"]["wavelet"])
            for w in WAVELETS]
        for label, curve, sizes in curves:
            ax.loglog(sizes, [max(e, 1e-4) for _, e in curve], label=label)
        for target in TARGETS:
            ax.axhline(target, color="grey", lw=0.6, ls=":")
        ax.set_title(CASES[name][0])
        ax.set_xlabel("bytes (whole table)")
        ax.grid(True, which="major", alpha=0.3)
    for ax in axes[:, 0]:
        ax.set_ylabel("median relative error, lobe bins")
    axes.ravel()[0].legend()
    for ax in axes.ravel()[len(results):]:
        ax.axis("off")
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=90, format="png")
    plt.close(fig)


def main() -> None:
    """Make the tables, measure them, and write the docs section and the figure."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--tables", type=Path, default=ROOT / "tables" / "wavelets",
                        help="folder of the cases' tables (made where missing)")
    parser.add_argument("--only", nargs="*", choices=list(CASES), default=list(CASES))
    parser.add_argument("--steps", type=int, default=8, help="kept counts per doubling")
    parser.add_argument("--make-only", action="store_true", help="only make the tables")
    parser.add_argument("--write", action="store_true",
                        help="write docs/table-format.md's section and the figure")
    args = parser.parse_args()
    paths = {name: make_table(name, args.tables) for name in args.only}
    if args.make_only:
        return
    results = {name: {w: measure(path, w, args.steps) for w in WAVELETS}
               for name, path in paths.items()}
    text = section(results, args.steps)
    print(text)
    if args.write:
        write_section(DOC, SECTION, text, heading=HEADING)
        figure(results, FIGURE)
        print(f"wrote {DOC} and {FIGURE}")


if __name__ == "__main__":
    main()
