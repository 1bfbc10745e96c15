"""Make the README figure from the commands a user runs.

Usage: python scripts/readme_figure.py
Runs `microsim demo` (table tables/demo.exr), `microsim compare` against Torrance-Sparrow
with Beckmann and Smith at the realised alpha (report in docs/images/compare/), and
`microsim view` of the 60-degree lobe against the same model, then puts the comparison's
plane-of-incidence figure and the lobe side by side in docs/images/readme.png.
"""

from __future__ import annotations

import subprocess
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.image as mpimg  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
IMAGES = ROOT / "docs" / "images"


def run(*argv: str) -> None:
    subprocess.run(["microsim", *argv], cwd=ROOT, check=True)


if __name__ == "__main__":
    table = "tables/demo.exr"
    run("demo", "-o", table)
    run("compare", table, "--model", "beckmann", "--component", "single", "--out",
        str(IMAGES / "compare"))
    run("view", table, "--theta-i", "60", "--model", "beckmann", "--screenshot",
        str(IMAGES / "lobe.png"))
    plane = mpimg.imread(IMAGES / "compare" / "incidence-plane.png")
    lobe = mpimg.imread(IMAGES / "lobe.png")
    width = plane.shape[1] / plane.shape[0] + lobe.shape[1] / lobe.shape[0]
    fig, axes = plt.subplots(1, 2, figsize=(3.2 * width, 3.2), gridspec_kw={
        "width_ratios": [plane.shape[1] / plane.shape[0], lobe.shape[1] / lobe.shape[0]]})
    for ax, img in zip(axes, (plane, lobe), strict=True):
        ax.imshow(img)
        ax.axis("off")
    fig.tight_layout(pad=0.2)
    fig.savefig(IMAGES / "readme.png", dpi=150)
    print(f"wrote {IMAGES / 'readme.png'}")
