"""What a spectral table costs against an RGB one: the same recipe, the same rays.

Usage::

    python scripts/bench_spectral.py [--rays N] [--repeats 3] [--write]
    python scripts/bench_spectral.py --breakdown [--write]

Two comparisons, each ``microsim simulate --json`` in a child process (its wall time
inside simulate, ``wall_s``, the whole command's, and its peak resident memory), with
each recipe's own rays unless ``--rays`` says otherwise, alternating the cases ``repeats``
times; medians:

- **conductor**: surfaces/gaussian-0.3.toml with gold facets, RGB (``material.kind =
  "conductor"``, the default R, G, B indices) against 32 wavelengths 390-700 nm of the
  shipped measured gold (``data = "Au"``), with the default order-32 harmonics and without
  them (``table.sh_order = 0``). The paths are the same (a conductor's directions do not
  depend on the wavelength); the difference is carrying 32 weights, and the harmonics'
  transforms, one per channel and moment.
- **dielectric**: a rough refracting glass (α 0.4) at the same rays: RGB with one index
  (1.517, BK7's at 587.6 nm: no dispersion) against the dispersive BK7 at 16 wavelengths,
  whose paths follow one hero wavelength from their first event (docs/spectral.md). Each
  channel then has 1/C of the paths, so its error is larger: the cost at equal error per
  channel is the time times (median relative error, spectral / RGB)², each error the
  median over the channels of the channel's median relative standard error over the
  lobe bins.

- **the shipped spectral recipe**, surfaces/paint-pearlescent.toml, as it is.

``--breakdown``: where the time of the gold RGB and 32-wavelength tables goes, in this
process (``simulate_recipe``, 2 threads, each after one run not counted): the CPU time of
each part (``microsim.bench.part_times``), summed over the threads that ran it.

``--write`` puts the table into docs/performance.md (marked section ``bench_spectral``,
or ``bench_spectral-breakdown``).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from microsim.files import measured_with, write_section
from microsim.tables.exr import read_table

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "performance.md"
RECIPE = ROOT / "surfaces" / "gaussian-0.3.toml"
PEARL = ROOT / "surfaces" / "paint-pearlescent.toml"
MICROSIM = str(Path(sys.executable).with_name("microsim"))
"""The command of this environment (``microsim`` beside its Python)."""
NM32 = [float(x) for x in np.linspace(390.0, 700.0, 32)]
NM16 = [float(x) for x in np.linspace(400.0, 700.0, 16)]


def _list(values: list[float]) -> str:
    return "[" + ",".join(f"{v:g}" for v in values) + "]"


GOLD = ["material.kind=conductor"]
SPECTRAL_GOLD = GOLD + ["material.data=Au", f"table.wavelengths={_list(NM32)}"]


def command(case: tuple[Path, list[str]], rays: int, out: Path) -> list[str]:
    """``microsim simulate`` of a case (recipe, ``--set`` overrides), with ``rays`` per
    direction (0: the recipe's own)."""
    recipe, sets = case
    argv = [MICROSIM, "simulate", str(recipe), "-o", str(out)]
    if rays:
        argv += ["--rays", str(rays)]
    for s in sets:
        argv += ["--set", s]
    return argv


def run(case: tuple[Path, list[str]], rays: int, folder: Path) -> dict[str, float]:
    """One ``microsim simulate``: its wall time inside simulate and of the whole command
    (s), and ``channel_error`` of the table it wrote."""
    start = time.perf_counter()
    out = subprocess.run(command(case, rays, folder / "t.exr") + ["--json"], check=True,
                         capture_output=True, text=True).stdout
    whole = time.perf_counter() - start
    return {"wall": float(json.loads(out)["wall_s"]), "whole": whole,
            "error": channel_error(read_table(folder / "t.exr"))}


def channel_error(table) -> float:
    """The median over the channels of each channel's median relative standard error over
    the lobe bins (an empty bin's error, NaN, counted as infinite)."""
    lobe = table.lobe_mask("total")
    medians = []
    for c in range(table.channels.count):
        f, e = table["total"].values[..., c], table["total"].errors[..., c]
        rel = np.where(np.isfinite(e), e, np.inf)[lobe] / f[lobe]
        medians.append(float(np.median(rel)))
    return float(np.median(medians))


def measure(cases: dict[str, tuple[Path, list[str]]], rays: int, repeats: int
            ) -> dict[str, dict]:
    """Each case ``repeats`` times, alternating; medians of the times and errors, and the
    peak memory of a fresh child per case (measured in a process of its own)."""
    got: dict[str, list[dict[str, float]]] = {c: [] for c in cases}
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(repeats):
            for name, case in cases.items():
                got[name].append(run(case, rays, Path(tmp)))
    return {name: {**{k: statistics.median(r[k] for r in got[name])
                      for k in ("wall", "whole", "error")},
                   "gib": peak_of(cases[name], rays)} for name in cases}


def peak_of(case: tuple[Path, list[str]], rays: int) -> float:
    """Peak resident memory (GiB) of one simulate, in a process of its own (so the
    figure is that run's alone)."""
    code = ("import resource, subprocess, sys; subprocess.run(sys.argv[1:], check=True, "
            "stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL); print(resource."
            "getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)")
    with tempfile.TemporaryDirectory() as tmp:
        argv = [sys.executable, "-c", code, *command(case, rays, Path(tmp) / "t.exr")]
        out = subprocess.run(argv, check=True, capture_output=True, text=True).stdout
    return int(out.split()[-1]) / 2**20


def breakdown() -> str:
    """The CPU time of each part of one in-process ``simulate_recipe`` of the gold RGB and
    32-wavelength tables (``microsim.bench.part_times``), with their wall and CPU time."""
    from microsim.bench import PARTS, timed_run
    from microsim.measurement.simulation import simulate_recipe
    from microsim.recipe import load

    columns, totals, load_before = [], [], os.getloadavg()[0]
    for name, sets in (("gold RGB", GOLD), ("gold 32 wavelengths", SPECTRAL_GOLD)):
        recipe = load(RECIPE, sets)
        simulate_recipe(recipe, threads=2)          # compiled code loaded, caches filled
        parts, wall, cpu, _ = timed_run(recipe, 2)
        columns.append(parts)
        totals.append(f"{name} {wall:.2f} s wall and {cpu:.2f} s of CPU")
    rows = [f"| {label} | " + " | ".join(f"{parts[label]:.2f} s" for parts in columns)
            + f" | {columns[1][label] - columns[0][label]:+.2f} s |"
            for _, _, label in PARTS]
    return "\n".join([
        "### Where a spectral table's time goes",
        "",
        f"{measured_with(__file__, sys.argv[1:], load_before)}: one `simulate_recipe` in this "
        f"process, 2 threads, of surfaces/gaussian-0.3.toml with gold facets: {totals[0]}; "
        f"{totals[1]}. The CPU time of each part, summed over the threads that ran it (the "
        "tally includes the binning, the principal components and the transforms):", "",
        "| part | gold RGB, CPU | gold 32 wavelengths, CPU | difference |",
        "| --- | --- | --- | --- |", *rows])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--rays", type=int, default=0,
                        help="rays per direction (default 0: each recipe's own)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--breakdown", action="store_true",
                        help="where the time goes, in this process, instead")
    parser.add_argument("--write", action="store_true")
    args = parser.parse_args()
    if args.breakdown:
        text = breakdown()
        print(text)
        if args.write:
            write_section(DOC, "bench_spectral-breakdown", text)
        return
    glass = ["material.kind=dielectric", "material.refract=true", "surface.alpha=0.4"]
    cases = {
        "gold RGB": (RECIPE, GOLD),
        "gold 32 wavelengths": (RECIPE, SPECTRAL_GOLD),
        "gold RGB, no harmonics": (RECIPE, GOLD + ["table.sh_order=0"]),
        "gold 32 wavelengths, no harmonics": (RECIPE, SPECTRAL_GOLD + ["table.sh_order=0"]),
        "glass RGB (eta 1.517)": (RECIPE, glass + ["material.eta=1.517",
                                                   "table.sh_order=0"]),
        "glass BK7, 16 wavelengths (hero)": (RECIPE, glass + [
            "material.data=BK7", f"table.wavelengths={_list(NM16)}", "table.sh_order=0"]),
        "surfaces/paint-pearlescent.toml as shipped": (PEARL, []),
    }
    got = measure(cases, args.rays, args.repeats)
    rows = ["| case | simulate wall time, s | whole command, s | ratio to RGB | peak "
            "memory, GiB | median relative error | time at the RGB's error, ratio |",
            "| --- | --- | --- | --- | --- | --- | --- |"]
    pairs = [("gold RGB", "gold 32 wavelengths"),
             ("gold RGB, no harmonics", "gold 32 wavelengths, no harmonics"),
             ("glass RGB (eta 1.517)", "glass BK7, 16 wavelengths (hero)")]
    for rgb, spectral in pairs:
        a, b = got[rgb], got[spectral]
        rows.append(f"| {rgb} | {a['wall']:.1f} | {a['whole']:.1f} | 1 | {a['gib']:.2f} | "
                    f"{100 * a['error']:.2f}% | 1 |")
        equal = b["wall"] / a["wall"] * (b["error"] / a["error"]) ** 2
        rows.append(f"| {spectral} | {b['wall']:.1f} | {b['whole']:.1f} | "
                    f"**{b['wall'] / a['wall']:.2f}** | {b['gib']:.2f} | "
                    f"{100 * b['error']:.2f}% | {equal:.1f} |")
    p = got["surfaces/paint-pearlescent.toml as shipped"]
    rows.append(f"| surfaces/paint-pearlescent.toml as shipped (16 wavelengths, coated "
                f"flakes) | {p['wall']:.1f} | {p['whole']:.1f} | — | {p['gib']:.2f} | "
                f"{100 * p['error']:.2f}% | — |")
    rays = f"{args.rays:,} rays per direction" if args.rays else "the recipes' own rays"
    load = os.getloadavg()[0]
    text = "\n".join([
        "## Spectral tables against RGB",
        "",
        f"Measured with `python scripts/bench_spectral.py"
        f"{f' --rays {args.rays}' if args.rays else ''} --repeats {args.repeats} --write` "
        f"on {platform.machine()}, {os.cpu_count()} CPUs; load average (1 min) {load:.1f} "
        f"at the end: surfaces/gaussian-0.3.toml (its 32 realisations, order-32 harmonics "
        f"unless said) with {rays}, `microsim simulate`'s own wall time (`wall_s`), the "
        "whole command's (start-up, tiles, writing), medians of the repeats, and the peak "
        "resident memory of one run; the shipped spectral recipe as it is. The last column "
        "is the time times (error ratio)²: what the spectral table costs at the RGB "
        "table's median relative error per channel.",
        "",
        *rows,
        "",
        "Where the spectral conductor's time goes: its paths are the RGB table's, so the "
        "tracing is the same; carrying 32 weights per path costs the difference without "
        "harmonics, and the harmonics one transform per principal component of a "
        "batch's channels, order row and batch (Σ w Y_k to order L, "
        "`microsim.tables.sh.moments`: 3 to 13 components of gold's 32 channels, "
        "`microsim.tables.principal`; an ensemble's harmonic errors are batch means, so "
        "it makes no transform of w², docs/ensembles.md) where a gold RGB table makes "
        "three. The "
        "memory grows with the channels "
        "through the ensemble estimator, which keeps per group of realisations (`GROUPS` = "
        "32 in `microsim.tables.estimator`) its sums for every direction, component, bin "
        "and channel: about 8 MiB an array at 32 wavelengths for this recipe, against "
        "0.75 MiB for RGB (estimated from its shapes). A dispersive glass's "
        "reflections keep every wavelength and only its refractions follow one "
        "(docs/spectral.md), so its lobe's error per channel is the RGB table's."])
    print(text)
    if args.write:
        write_section(DOC, "bench_spectral", text)


if __name__ == "__main__":
    main()
