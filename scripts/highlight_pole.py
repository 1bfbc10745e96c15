"""The gold sphere's highlight where the surface faces the camera: the pole of the table's
outgoing bins (docs/render.md, "Stars and notches").

Usage: python scripts/highlight_pole.py [--rays 400000] [--realisations 4] [--write]

Simulates ``surfaces/gaussian-0.3.toml`` with gold facets (the conductor's default), its
incidences, ``--realisations`` tiles and ``--rays`` rays per incidence, renders the table
on the sphere (400 × 300 pixels, 32 samples per pixel, seed 0, the default sun and sky,
``scalar_rgb``) and measures the luminance smoothed by a Gaussian of σ = 2 pixels around
the image's centre, where the sphere faces the camera (the camera aims at the sphere's
centre, so the surface there looks along the camera's axis, θo = 0): its profile along
the image row through that point, and the largest step between neighbouring pixels within
8 pixels of it against the steps in the ring from 8 to 40 pixels around it.
``--write`` puts them into docs/render.md (marked section ``highlight_pole``).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy.ndimage import gaussian_filter

from microsim.files import measured_with, write_section
from microsim.measurement.simulation import simulate_recipe
from microsim.recipe import load
from microsim.render import backend, bsdfs, objects, scene

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "render.md"
SIZE = (400, 300)
SPP = 32
SIGMA = 2.0
NEAR = 8
"""Pixels from the camera-facing point that count as near it."""
AROUND = 40
"""Outer radius (pixels) of the ring about it that near is compared with."""
OFFSETS = (-8, -6, -4, -2, 0, 2, 4, 6, 8)


def steps(y: np.ndarray) -> np.ndarray:
    """|Y| difference of each pixel to its right and lower neighbours, (h, w): the larger
    of the two (0 on the last row and column)."""
    right = np.zeros_like(y)
    down = np.zeros_like(y)
    right[:, :-1] = np.abs(np.diff(y, axis=1))
    down[:-1] = np.abs(np.diff(y, axis=0))
    return np.maximum(right, down)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rays", type=int, default=400_000)
    parser.add_argument("--realisations", type=int, default=4)
    parser.add_argument("--write", action="store_true",
                        help="write the profile into docs/render.md")
    args = parser.parse_args()
    before = os.getloadavg()[0]
    recipe = load(ROOT / "surfaces" / "gaussian-0.3.toml", [
        "material.kind=conductor", f"simulation.rays={args.rays}",
        f"simulation.realisations={args.realisations}"])
    table = simulate_recipe(recipe)
    mi = backend.load("scalar_rgb")
    lights = [scene.parse_light(s) for s in scene.DEFAULT_LIGHTS]
    with tempfile.TemporaryDirectory() as tmp:
        bsdf = bsdfs.table_bsdf(mi, table, Path(tmp) / "gold.bsdf")
        image = scene.render(mi, objects.sphere(), bsdf, scene.Camera(*SIZE), lights, SPP,
                             seed=0)
    y = gaussian_filter(image.luminance, SIGMA)
    height, width = y.shape
    row, col = height // 2, width // 2  # the pixel at the image's centre (its lower right)
    profile = [float(y[row, col + k]) for k in OFFSETS]
    rr, cc = np.mgrid[0:height, 0:width]
    distance = np.hypot(rr - row, cc - col)
    near = distance <= NEAR
    step = steps(y)
    elsewhere = step[(distance > NEAR) & (distance <= AROUND) & (image.alpha > 0.999)]
    text = (
        f"{measured_with(__file__, sys.argv[1:], before)}: `surfaces/gaussian-0.3.toml` "
        f"with gold facets, its incidences, {args.realisations} realisations, "
        f"{args.rays:,} rays per incidence; the sphere, {SIZE[0]} × {SIZE[1]} pixels, "
        f"{SPP} samples per pixel, seed 0; luminance smoothed by a Gaussian of σ = "
        f"{SIGMA:g} pixels (its largest {y.max():.2f}). Along the image row through the "
        "point where the sphere faces the camera, at "
        f"{', '.join(f'{k:+d}' for k in OFFSETS)} pixels from it: "
        + ", ".join(f"{v:.3f}" for v in profile)
        + f". Largest step between neighbouring pixels within {NEAR} pixels of that point: "
        f"{step[near].max():.4f}; from {NEAR} to {AROUND} pixels around it the steps' "
        f"median is {np.median(elsewhere):.4f}, their 99th percentile "
        f"{np.percentile(elsewhere, 99):.4f} and their largest {elsewhere.max():.4f}.")
    print(text)
    if args.write:
        write_section(DOC, "highlight_pole", text)


if __name__ == "__main__":
    main()
