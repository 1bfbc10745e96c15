"""The numbers docs/compare.md gives for ``microsim demo``, measured by running it.

Usage::

    python scripts/demo_numbers.py [--write]

Runs ``microsim demo --json`` as a command (its wall and CPU time, the child's own usage),
times the all-orders reference (``microsim.commands.demo.total_comparison``: the
``beckmann-ms`` walks and the comparison) in this process on the table the demo wrote,
and runs ``microsim fit TABLE --model beckmann --component single --json``. Prints the
two paragraphs; ``--write`` puts them in docs/compare.md between the markers
``demo-comparison`` and ``demo-fit``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import textwrap
import time
from pathlib import Path
from typing import Any

from microsim.bench import run_child
from microsim.commands.demo import MS_SAMPLES, total_comparison
from microsim.effort import EFFORT_ENV, effort
from microsim.files import write_section
from microsim.tables.exr import read_table

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "compare.md"
MICROSIM = str(Path(sys.executable).parent / "microsim")
WIDTH = 90
"""Line width of the written paragraphs, as the docs' prose."""


def measure(folder: Path) -> dict[str, Any]:
    """Run the demo, its reference and the fit; the numbers the paragraphs quote."""
    table_path = folder / "demo.exr"
    load_before = os.getloadavg()[0]
    demo = run_child([MICROSIM, "demo", "--json", "-o", str(table_path)])
    table = read_table(table_path)
    start = time.process_time()
    total_comparison(table)
    reference_cpu = time.process_time() - start
    fit = run_child([MICROSIM, "fit", str(table_path), "--model", "beckmann",
                     "--component", "single", "--json"])
    return {"demo": json.loads(demo.stdout), "demo_wall": demo.wall, "demo_cpu": demo.cpu,
            "reference_cpu": reference_cpu, "fit": json.loads(fit.stdout),
            "load": (load_before, os.getloadavg()[0]), "cpus": os.cpu_count(),
            "date": time.strftime("%Y-%m-%d")}


def _range(values: list[float], digits: int) -> str:
    """``lo–hi`` of values (one value when they round alike)."""
    lo, hi = f"{min(values):.{digits}f}", f"{max(values):.{digits}f}"
    return lo if lo == hi else f"{lo}–{hi}"


def wrap(text: str) -> str:
    """A paragraph at the docs' width, breaking at spaces only (not inside a flag)."""
    return textwrap.fill(text, WIDTH, break_long_words=False, break_on_hyphens=False)


def _signed(values: list[float]) -> str:
    return ", ".join(f"{v:+.2f}" for v in values)


def comparison_text(m: dict[str, Any]) -> str:
    """The paragraphs of docs/compare.md's "What the comparison of the shipped Gaussian
    surface shows"."""
    d = m["demo"]
    single, total = d["comparison"], d["comparison_total"]
    rows, rows_total = single["per_theta_i"], total["per_theta_i"]
    thetas = d["simulation"]["theta_i"]
    ratio = [abs(r["albedo_sim"][1] / r["albedo_model"][1] - 1) for r in rows]
    up_to_60 = max(x for x, t in zip(ratio, thetas, strict=True) if t <= 60)
    grazing = max(x for x, t in zip(ratio, thetas, strict=True) if t > 60)
    orders = d["simulation"]["order_albedo"]
    multiple = [1 - o1[1] / a[1] for o1, a, t in zip(orders["order1"], d["simulation"]["albedo"],
                                                     thetas, strict=True) if t >= 60]
    z_std = [r["z_std"] for r in rows]
    noise = single["agreement"]["z_std_max"]
    beyond = max(z_std) > noise
    why = ("; larger than noise at some incidences: a finite tile's facets are not an exact "
           "Beckmann ensemble — its slope distribution has lighter tails, see "
           "[surfaces.md](surfaces.md) — and Smith's masking is close to but not exactly "
           "the tile's") if beyond else ""
    k = single["realisations"]
    degrees = ", ".join(f"{t:g}" for t in thetas) + "°"
    first = (
        f"`microsim demo` and the example report compare the single scattering of "
        f"`surfaces/gaussian-0.3.toml` (α realised {single['alpha_realised']:.4f} ± "
        f"{single['alpha_realised_stderr']:.4f} over its {k} tiles, target "
        f"{single['alpha_target']:g}) with Torrance-Sparrow + Beckmann + height-correlated "
        f"Smith at that α. The albedos agree to {100 * up_to_60:.1f}% up to 60° and to "
        f"{100 * grazing:.1f}% beyond; per incidence z has mean "
        f"{_signed([r['z_mean'] for r in rows])} at θi = {degrees} and spread "
        f"{_range(z_std, 2)} "
        f"(noise alone gives up to {noise:.2f} at significance "
        f"{single['agreement']['significance']:g}{why}), and "
        f"{_range([100 * x for x in multiple], 1)}% of the escaping energy at 60–80° is "
        "multiply scattered, which the model leaves out. "
        "[goniometer.md](goniometer.md) quantifies these biases on larger tiles.")
    pulled = (": the missing orders pull it down at grazing incidence"
              if rows[-1]["z_mean"] < rows_total[-1]["z_mean"] - 0.1 else "")
    albedos = ", ".join(f"{r['albedo_model'][1]:.4f} ± {r['albedo_model_err'][1]:.4f}"
                        for r in rows_total)
    second = (
        f"Beside it the demo compares **all orders** with Heitz et al.'s multiple-scattering "
        f"Smith microsurface (`beckmann-ms` at the realised α, {MS_SAMPLES} walks per bin — "
        f"`MS_SAMPLES` in `microsim/commands/demo.py`, {m['reference_cpu']:.1f} s of CPU, "
        f"its comparison included, for the recipe's {len(thetas)} incidences; the whole demo took "
        f"{m['demo_cpu']:.1f} s of CPU and {m['demo_wall']:.1f} s wall on {m['cpus']} CPUs, "
        f"load average {m['load'][0]:.1f} before and {m['load'][1]:.1f} after, "
        f"{m['date']}): the model's albedo is {albedos} at θi = {degrees} against the simulation's "
        f"{_range([a[1] for a in d['simulation']['albedo']], 4)} (mirror facets lose "
        f"nothing); z has mean {_signed([r['z_mean'] for r in rows_total])} (single against "
        f"Torrance-Sparrow: {_signed([r['z_mean'] for r in rows])}{pulled}) and spread "
        f"{_range([r['z_std'] for r in rows_total], 2)}, the realisations' own, as for "
        "single scattering.")
    note = ("(`python scripts/demo_numbers.py --write` measures and writes these two "
            "paragraphs.)")
    return "\n\n".join(wrap(p) for p in (first, second, note))


def fit_text(m: dict[str, Any]) -> str:
    """The sentence of docs/compare.md's "Checked" on fitting the demo's table."""
    alpha = m["fit"]["params"]["alpha"]
    realised = m["demo"]["comparison"]["alpha_realised"]
    return wrap(f"Fitted to the demo's table (`microsim fit tables/demo.exr --model beckmann "
                f"--component single`), α = {alpha:.4f} against the realised {realised:.4f}, "
                f"{100 * (alpha / realised - 1):+.1f}% (`python scripts/demo_numbers.py --write`).")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--write", action="store_true",
                        help="write the paragraphs into docs/compare.md")
    args = parser.parse_args()
    if args.write and effort() < 1:
        parser.error(f"--write: ${EFFORT_ENV} is {effort():g}; the docs hold the full "
                     "demo's numbers (unset it)")
    with tempfile.TemporaryDirectory() as folder:
        m = measure(Path(folder))
    comparison, fit = comparison_text(m), fit_text(m)
    print(comparison, fit, sep="\n\n")
    if args.write:
        write_section(DOC, "demo-comparison", comparison)
        write_section(DOC, "demo-fit", fit)


if __name__ == "__main__":
    main()
