"""A gold sphere looks gold: the colour of the sun's highlight on a spectral gold table's
render against gold's normal-incidence reflectance (docs/render.md).

Usage::

    python scripts/gold_highlight.py [--size 320x240] [--spp 64] [--write]

Simulates docs/render.md's spectral gold recipe (Gaussian α 0.3, 128² tiles, 16
wavelengths, 8 realisations sharing 200,000 rays per incidence, θi 0, 30, 60°), renders
it on the sphere under the default sun and sky in ``scalar_spectral`` (all orders, and the
single scattering alone) and ``scalar_rgb`` (all orders, the table's sRGB), and prints the
mean linear RGB of the brightest 2% of the covered pixels (the sun's highlight) scaled to
the luminance of F0(λ), gold's normal-incidence reflectance (exact Fresnel of the shipped
Johnson & Christy indices), beside F0's own linear sRGB and display encoding, and the two
variants' mean colour over the sphere. ``--write`` puts the figures into docs/render.md
(marked section ``gold-highlight``). About a minute on 2 cores.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

import microsim
from microsim.analytic.fresnel import fresnel_conductor
from microsim.files import measured_with, write_section
from microsim.spectra import measured
from microsim.spectra.colour import to_srgb_display, to_srgb_linear
from microsim.tables.export import LUMINANCE

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "render.md"
NM = list(range(400, 701, 20))
RECIPE = {"surface": {"kind": "gaussian", "alpha": 0.3, "resolution": 128},
          "material": {"kind": "conductor", "data": "Au"},
          "table": {"wavelengths": NM, "theta_bins": 16, "phi_bins": 32},
          "simulation": {"theta_i": [0, 30, 60], "rays": 200_000, "realisations": 8}}
"""docs/render.md's ``gold-spectral.toml``."""
RENDERS = (("scalar_spectral", "total"), ("scalar_spectral", "order1"), ("scalar_rgb", "total"))


def highlight(image, reference: np.ndarray) -> np.ndarray:
    """The mean linear RGB of the brightest 2% of the covered pixels, scaled to the
    luminance of ``reference``."""
    covered = image.alpha > 0.999
    bright = covered & (image.luminance >= np.percentile(image.luminance[covered], 98))
    mean = image.rgb[bright].mean(axis=0)
    return mean * (reference @ LUMINANCE) / (mean @ LUMINANCE)


def triple(values: np.ndarray, digits: int = 3) -> str:
    """``(a, b, c)`` at a fixed number of decimals."""
    return "(" + ", ".join(f"{v:.{digits}f}" for v in values) + ")"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--size", default="320x240", help="WIDTHxHEIGHT")
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--write", action="store_true",
                        help="write the figures into docs/render.md")
    args = parser.parse_args()
    from colour.models import eotf_inverse_sRGB

    from microsim.render import backend, bsdfs, objects, scene

    load_before = os.getloadavg()[0]
    width, height = (int(x) for x in args.size.split("x"))
    table = microsim.simulate(microsim.load_recipe(RECIPE))
    eta, k = measured.conductor("Au")
    f0 = np.asarray(fresnel_conductor(np.ones(1), eta.at(NM), k.at(NM))).ravel()
    gold = to_srgb_linear(NM, f0)
    camera = scene.Camera(width, height)
    lights = [scene.parse_light(s) for s in scene.DEFAULT_LIGHTS]
    images = {}
    with tempfile.TemporaryDirectory() as folder:
        for variant, component in RENDERS:
            mi = backend.load(variant)
            bsdf = bsdfs.table_bsdf(mi, table, Path(folder) / f"{variant}-{component}.bsdf",
                                    component)
            images[variant, component] = scene.render(mi, objects.sphere(), bsdf, camera,
                                                      lights, args.spp, seed=0)
    colour = {key: highlight(image, gold) for key, image in images.items()}
    off = {key: 100 * np.abs(c / gold - 1).max() for key, c in colour.items()}
    shown = eotf_inverse_sRGB(np.clip(colour["scalar_spectral", "total"], 0.0, 1.0))
    means = {v: images[v, "total"].rgb[images[v, "total"].alpha > 0.999].mean(axis=0)
             for v in ("scalar_spectral", "scalar_rgb")}
    agree = 100 * np.abs(means["scalar_rgb"] / means["scalar_spectral"] - 1).max()
    text = (
        f"{measured_with(__file__, sys.argv[1:], load_before)}: docs/render.md's "
        "`gold-spectral.toml` (16 wavelengths, α 0.3, 8 realisations sharing 200,000 rays "
        f"per incidence, θi 0, 30, 60°) on the sphere under the default sun and sky, "
        f"{width} × {height} pixels, {args.spp} samples per pixel, seed 0. Highlight (the "
        "brightest 2% of the covered pixels, mean linear RGB scaled to F0's luminance) in "
        f"`scalar_spectral`: {triple(colour['scalar_spectral', 'total'])}, against F0's "
        f"linear sRGB {triple(gold)}: within {off['scalar_spectral', 'total']:.1f}% per "
        "channel; displayed (sRGB-encoded) within "
        f"{np.abs(shown - to_srgb_display(NM, f0)).max():.3f} of `to_srgb_display(F0)` = "
        f"{triple(to_srgb_display(NM, f0), 2)}. Its single scattering alone: "
        f"{triple(colour['scalar_spectral', 'order1'])}, within "
        f"{off['scalar_spectral', 'order1']:.1f}%. `scalar_rgb` (the table's sRGB): "
        f"{triple(colour['scalar_rgb', 'total'])}, within {off['scalar_rgb', 'total']:.1f}%. "
        f"The two variants' mean colours over the sphere agree within {agree:.2f}% per "
        "channel.")
    print(text)
    if args.write:
        write_section(DOC, "gold-highlight", text)


if __name__ == "__main__":
    main()
