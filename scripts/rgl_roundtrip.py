"""How closely Mitsuba 3 reproduces a table exported as an RGL ``.bsdf`` file.

Usage: python scripts/rgl_roundtrip.py [rgb] [spectral] [--pairs 500]
                                      [--anisotropic-pairs 300] [--resolutions 32,64]
                                      [--write]

Writes two smooth tables, a conductor Beckmann α = 0.45 lobe averaged over 32 × 64 bins
at θi = 0, 20, 40, 60, 75° (as tests/test_export.py does) and the same conductor with an
anisotropic Beckmann lobe (α_x = 0.2, α_y = 0.5) at those θi and φi every 30°, exports
each at every resolution H, loads it with Mitsuba's ``measured`` plugin (``scalar_rgb``)
and prints the relative difference of Mitsuba's eval to ``read_table().eval · cos θo`` at
random direction pairs in the lobe, at the tables' own incidences
(``microsim.tables.export.rgl_through_mitsuba``). ``spectral`` simulates two gold tables
instead (the 16-wavelength one of docs/render.md, 8 realisations of 200,000 rays, and the
7-wavelength one of tests/test_spectral_export.py, 20,000 rays), exports them in Mitsuba's
spectral layout and evaluates them in ``scalar_spectral`` at their own wavelengths
(between and beyond them, tests/test_spectral_export.py holds Mitsuba's lookup to 1%, but
the medians there changed from one process to the next in this script, 0.16–0.79%, so
they are not written). ``--write`` puts the figures into docs/table-format.md (marked sections
``rgl_roundtrip`` and ``rgl_roundtrip-spectral``). Both parts by default; under a minute
on 2 cores.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import sys
import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

import microsim
from microsim.analytic.brdf import TorranceSparrow
from microsim.analytic.fresnel import ConductorFresnel
from microsim.analytic.ndf import Beckmann
from microsim.comparison.metrics import model_table
from microsim.files import measured_with, write_section
from microsim.tables.binning import HemisphereBins
from microsim.tables.export import rgl_through_mitsuba, write_rgl
from microsim.tables.exr import read_table, write_table
from microsim.tables.table import BRDFTable

DOC = Path(__file__).resolve().parent.parent / "docs" / "table-format.md"
THETA_I = np.radians([0.0, 20.0, 40.0, 60.0, 75.0])
PHI_I = np.radians(np.arange(0.0, 360.0, 30.0))
FRESNEL = ConductorFresnel(np.array([0.2, 0.9, 1.1]), np.array([3.9, 2.4, 2.1]))
GOLD_16 = {"surface": {"kind": "gaussian", "alpha": 0.3, "resolution": 128},
           "material": {"kind": "conductor", "data": "Au"},
           "table": {"wavelengths": list(range(400, 701, 20)), "theta_bins": 16,
                     "phi_bins": 32},
           "simulation": {"theta_i": [0, 30, 60], "rays": 200_000, "realisations": 8}}
"""docs/render.md's spectral gold recipe."""
GOLD_7 = {"surface": {"kind": "gaussian", "alpha": 0.4, "resolution": 32},
          "material": {"kind": "conductor", "data": "Au"},
          "table": {"wavelengths": list(range(400, 701, 50)), "theta_bins": 8,
                    "phi_bins": 16, "sh_order": 2},
          "simulation": {"theta_i": [0, 30, 60], "rays": 20_000}}
"""tests/test_spectral_export.py's gold recipe."""


def smooth_table(anisotropic: bool) -> BRDFTable:
    """The analytic conductor Beckmann lobe, bin-averaged: α = 0.45, or α_x = 0.2,
    α_y = 0.5 with φi every 30°."""
    if anisotropic:
        model = TorranceSparrow(Beckmann(alpha_x=0.2, alpha_y=0.5), fresnel=FRESNEL)
        return model_table(model, THETA_I, HemisphereBins(32, 64), phi_i=PHI_I)
    return model_table(TorranceSparrow(Beckmann(0.45), fresnel=FRESNEL), THETA_I,
                       HemisphereBins(32, 64))


def differences(table: BRDFTable, folder: Path, h: int, pairs: int, seed: int,
                variant: str = "scalar_rgb") -> np.ndarray:
    """|Mitsuba / table − 1| at ``pairs`` direction pairs: (pairs, channels), the
    channels R, G, B (``scalar_rgb``) or the table's wavelengths (``scalar_spectral``)."""
    folder = Path(tempfile.mkdtemp(dir=folder))  # a file name of its own for each export
    path = folder / "t.exr"
    write_table(table, path)
    table = read_table(path)
    out = folder / f"t{h}.bsdf"
    write_rgl(table, out, resolution=h)
    ref, got = rgl_through_mitsuba(table, out, pairs, np.random.default_rng(seed),
                                   variant=variant)
    return np.abs(got / ref - 1)


def rgb_section(args: argparse.Namespace, folder: Path, load: float) -> str:
    """The smooth Beckmann tables through ``scalar_rgb``, as Markdown."""
    rows = []
    for anisotropic, name, pairs in (
            (False, "isotropic, α = 0.45", args.pairs),
            (True, "anisotropic, α_x = 0.2, α_y = 0.5, φi every 30°", args.anisotropic_pairs)):
        table = smooth_table(anisotropic)
        for h in (int(r) for r in args.resolutions.split(",")):
            rel = differences(table, folder, h, pairs, args.seed).ravel()
            rows.append(f"| {name} | {h} | {pairs} | {100 * np.median(rel):.2f}% | "
                        f"{100 * np.percentile(rel, 90):.2f}% | {100 * rel.max():.1f}% |")
            print(rows[-1], flush=True)
    import mitsuba

    return "\n".join([
        f"{measured_with(__file__, sys.argv[1:], load)}, Mitsuba {mitsuba.__version__} "
        "`scalar_rgb`: smooth conductor Beckmann tables (32 × 64 bins, θi = 0, 20, 40, 60, "
        "75°) exported at H × H half-vector nodes; relative difference of Mitsuba's `eval` "
        "to `read_table().eval · cos θo` at random direction pairs in the lobe (where f_r "
        "cos θo is at least a tenth of its mirror-direction value), at the table's own "
        "incidences, over R, G, B.", "",
        "| table | H | pairs | median | p90 | largest |", "| --- | --- | --- | --- | --- | --- |",
        *rows])


def spectral_differences(path: str, h: int, seed: int) -> np.ndarray:
    """``differences`` of the table file at ``path`` in ``scalar_spectral``."""
    return differences(read_table(path), Path(path).parent, h, 100, seed, "scalar_spectral")


def in_a_fresh_process(path: Path, h: int, seed: int) -> np.ndarray:
    """``spectral_differences`` in a new Python process of its own. Mitsuba 3.9.1's
    ``scalar_spectral`` evaluates a 7-wavelength file differently after other files were
    loaded in the same process, and differently from one process to the next (medians of
    0.05% or 0.22% at H = 64); in a fresh process every run gives the same figures."""
    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
        return pool.submit(spectral_differences, str(path), h, seed).result()


def spectral_section(args: argparse.Namespace, folder: Path, load: float) -> str:
    """The simulated gold tables through ``scalar_spectral``, as Markdown."""
    rows = []
    for name, recipe, resolutions in (
            ("16 wavelengths, α 0.3, 128² tiles, 8 × 25,000 rays", GOLD_16, (64,)),
            ("7 wavelengths, α 0.4, 32² tile, 20,000 rays", GOLD_7, (32, 64, 128))):
        path = Path(tempfile.mkdtemp(dir=folder)) / "gold.exr"
        write_table(microsim.simulate(microsim.load_recipe(recipe)), path)
        for h in resolutions:
            own = in_a_fresh_process(path, h, args.seed)
            medians = np.median(own, axis=0)
            low, high = (f"{100 * m:.2f}%" for m in (medians.min(), medians.max()))
            rows.append(f"| {name} | {h} | {low if low == high else f'{low}–{high}'} "
                        f"| {100 * np.percentile(own, 90):.2f}% |")
            print(rows[-1], flush=True)
    import mitsuba

    return "\n".join([
        f"{measured_with(__file__, sys.argv[1:], load)}, Mitsuba {mitsuba.__version__} "
        "`scalar_spectral`: simulated gold tables (Johnson & Christy indices, θi = 0, 30, "
        "60°) exported in the spectral layout at H × H half-vector nodes; relative "
        "difference of Mitsuba's `eval` asked at chosen `si.wavelengths` to `read_table()"
        ".eval · cos θo` at 100 random direction pairs in the lobe, at the table's own "
        "wavelengths (the range of the per-wavelength medians, and the 90th percentile "
        "over all); each export is evaluated in a Python process of its own (in one "
        "process, Mitsuba's figures for a file depend on the files loaded before it).", "",
        "| table | H | median per wavelength | p90 |", "| --- | --- | --- | --- |", *rows])


PARTS = {"rgb": ("rgl_roundtrip", rgb_section),
         "spectral": ("rgl_roundtrip-spectral", spectral_section)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("parts", nargs="*", metavar="PART",
                        help=f"{', '.join(PARTS)} (default: both)")
    parser.add_argument("--pairs", type=int, default=500)
    parser.add_argument("--anisotropic-pairs", type=int, default=300)
    parser.add_argument("--resolutions", default="32,64")
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--write", action="store_true",
                        help="write the figures into docs/table-format.md")
    args = parser.parse_args()
    unknown = sorted(set(args.parts) - set(PARTS))
    if unknown:
        parser.error(f"unknown part {unknown[0]!r}; choose from {', '.join(PARTS)}")
    with tempfile.TemporaryDirectory() as tmp:
        for part in args.parts or list(PARTS):
            name, section = PARTS[part]
            text = section(args, Path(tmp), os.getloadavg()[0])
            if args.write:
                write_section(DOC, name, text)


if __name__ == "__main__":
    main()
