"""Gondek's pearlescent paint reproduced: the colour of surfaces/paint-pearlescent.toml's
spectral table against θi and θo, and a spectral render of it.

Usage::

    python scripts/pearlescent.py [--rays 200000] [--table tables/pearlescent.exr] [--write]

Simulates the recipe (skipped when ``--table`` exists), then draws, for every incidence
(rows) and outgoing polar angle in the plane of incidence (columns: the back side at
φo − φi = 0 on the left, the specular side at 180° on the right), the sRGB (D65, CIE 1931
2°: ``microsim.spectra.colour``) of the reflected radiance factor π f_r cos θo in the bins
either side of the plane: once at its brightness (one exposure for the whole figure) and
once at equal luminance, which shows the hue alone. It reports the CIE chromaticity
(x, y) of the directional albedo per incidence with its standard error (propagated from
the albedo's per-wavelength errors through the linear map to XYZ; the wavelengths' errors
taken as independent, so a bound only up to their correlation), and renders the table on a
sphere in ``scalar_spectral``. ``--write`` saves docs/images/pearlescent.png and
docs/images/pearlescent-render.png and puts the numbers into docs/spectral.md (marked
section ``spectral-pearlescent``).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import numpy as np

from microsim.files import atomic_path, write_section
from microsim.spectra import colour
from microsim.tables.exr import read_table

ROOT = Path(__file__).resolve().parent.parent
RECIPE = ROOT / "surfaces" / "paint-pearlescent.toml"
DOC = ROOT / "docs" / "spectral.md"
FIGURE = ROOT / "docs" / "images" / "pearlescent.png"
RENDER = ROOT / "docs" / "images" / "pearlescent-render.png"
MICROSIM = str(Path(sys.executable).with_name("microsim"))
BAND = 17.0
"""Degrees of φo either side of the plane of incidence averaged into each cell."""


def plane(table, which: str = "values") -> tuple[np.ndarray, np.ndarray]:
    """π f_r cos θo near the plane of incidence, (a, 2 nt, C): back side (θo decreasing
    from the horizon to the pole), then the specular side, each the mean of the φ bins
    within ``BAND`` of the plane (the flakes' glints are sparse: one bin is noise)
    (``which = "errors"``: its standard error, the bins' errors taken as independent);
    and the signed θo of the columns (degrees)."""
    data = getattr(table, which)["total"][:, 0]  # (a, nt, np, C)
    if which == "errors":
        data = np.nan_to_num(data) ** 2
    bins = table.bins
    n_phi = bins.phi_bins
    k = max(1, round(np.radians(BAND) / (2 * np.pi / n_phi)))
    back = data[:, :, [(j + n_phi) % n_phi for j in range(-k, k)]].mean(axis=2)
    front = data[:, :, [n_phi // 2 + j for j in range(-k, k)]].mean(axis=2)
    if which == "errors":
        back, front = np.sqrt(back / (2 * k)), np.sqrt(front / (2 * k))
    centres = 0.5 * (bins.theta_edges[:-1] + bins.theta_edges[1:])
    cos = np.cos(centres)[None, :, None]
    rows = np.concatenate([(back * cos)[:, ::-1], front * cos], axis=1) * np.pi
    theta = np.degrees(np.concatenate([-centres[::-1], centres]))
    return rows, theta


def chromaticity(table) -> list[tuple[float, float, float, float, float]]:
    """Per incidence: θi, and the CIE (x, y) of the directional albedo with their standard
    errors (first-order propagation through XYZ = albedo @ W, the wavelengths'
    errors taken as independent)."""
    nm = np.asarray(table.channels.wavelengths)
    w = colour.xyz_weights(nm)
    out = []
    for a, theta in enumerate(np.degrees(table.theta_i)):
        albedo = table["total"].albedo[a, 0]
        err = table["total"].albedo_err[a, 0]
        xyz = albedo @ w
        s = xyz.sum()
        # d(x)/d(albedo_c) = (W_cX s − X Σ_k W_ck) / s², likewise y
        dx = (w[:, 0] * s - xyz[0] * w.sum(axis=1)) / s**2
        dy = (w[:, 1] * s - xyz[1] * w.sum(axis=1)) / s**2
        out.append((float(theta), float(xyz[0] / s), float(np.sqrt(((dx * err) ** 2).sum())),
                    float(xyz[1] / s), float(np.sqrt(((dy * err) ** 2).sum()))))
    return out


def draw(table, path: Path) -> None:
    """The two colour maps of ``plane``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    nm = np.asarray(table.channels.wavelengths)
    rows, theta = plane(table)
    linear = colour.to_srgb_linear(nm, rows)
    # one exposure: the 90th percentile of the cells at white (the clear top's mirror
    # reflection, a few cells, clips), so the flakes' and the base's colours show
    exposure = 1.0 / max(np.percentile(linear.max(axis=-1), 90.0), 1e-12)
    bright = colour.to_srgb_display(nm, rows * exposure)
    albedo = table["total"].albedo[:, 0]
    y = colour.luminance(nm, albedo)
    hue = colour.to_srgb_display(nm, albedo * (0.35 / np.maximum(y, 1e-12))[:, None])
    thetas = np.degrees(table.theta_i)
    fig, axes = plt.subplots(2, 1, figsize=(9.0, 6.0), layout="constrained",
                             height_ratios=(3, 1))
    axes[0].imshow(bright, extent=(theta[0], theta[-1], len(thetas) - 0.5, -0.5),
                   aspect="auto", interpolation="nearest")
    axes[0].set_yticks(range(len(thetas)), [f"{t:g}°" for t in thetas])
    axes[0].set_ylabel("θi")
    axes[0].set_xlabel("θo near the plane of incidence (°): back side < 0 < specular side")
    axes[0].set_title(f"sRGB of π f_r cos θo, φo within {BAND:g}° of the plane (one "
                      "exposure; the clear top's mirror reflection clips)", fontsize=10)
    axes[1].imshow(hue[None], aspect="auto", interpolation="nearest")
    axes[1].set_xticks(range(len(thetas)), [f"{t:g}°" for t in thetas])
    axes[1].set_yticks([])
    axes[1].set_xlabel("θi")
    axes[1].set_title("the directional albedo's colour at equal luminance: the hue alone "
                      "(chromaticity ± 0.002, docs/spectral.md)", fontsize=10)
    fig.suptitle("Pearlescent paint (surfaces/paint-pearlescent.toml): colour against θi "
                 "and θo, CIE 1931 2°, D65", fontsize=11)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--rays", type=int, default=200_000)
    parser.add_argument("--table", type=Path, default=ROOT / "tables" / "pearlescent.exr")
    parser.add_argument("--write", action="store_true")
    args = parser.parse_args()
    if not args.table.exists():
        subprocess.run(["nice", "-n", "19", MICROSIM, "simulate", str(RECIPE), "--rays",
                        str(args.rays), "-o", str(args.table)], check=True)
    table = read_table(args.table)
    rows = ["| θi | x | y |", "| --- | --- | --- |"]
    rows += [f"| {t:g}° | {x:.4f} ± {ex:.4f} | {y:.4f} ± {ey:.4f} |"
             for t, x, ex, y, ey in chromaticity(table)]
    rays = int(table.rays[:, 0].min())
    text = "\n".join([
        "## Gondek's pearlescent paint",
        "",
        "surfaces/paint-pearlescent.toml: mica flakes under a 156 nm TiO₂ film in a clear "
        "binder over a black base, 16 wavelengths. Its colour against θi and θo near "
        f"the plane of incidence (φo within {BAND:g}° of it; `python scripts/pearlescent.py "
        f"--rays {args.rays} --write`; {rays:,} rays per direction): around the specular "
        "direction the flakes' interference green (the film's second reflection maximum, "
        "4 n d / 3, lies at 541 nm at normal incidence) over the black base; towards "
        "grazing the film's phase 2π d η_f cos θ_f / λ shrinks, its maximum moves to "
        "shorter wavelengths and the colour turns blue-green, the flop of a pearlescent "
        "paint, and paler, as the clear top's colourless Fresnel reflection grows; the "
        "chromaticity of the directional albedo below follows it (y falling with θi).",
        "",
        "![Pearlescent paint: sRGB against theta_i and theta_o](images/pearlescent.png)",
        "",
        "The chromaticity (CIE 1931 x, y under D65) of its directional albedo per "
        "incidence, ± one standard error (propagated from the albedo's per-wavelength "
        "errors as if independent):",
        "",
        *rows,
        "",
        "Rendered on a sphere in Mitsuba's `scalar_spectral` variant (`microsim render "
        "--variant scalar_spectral --object sphere`); the rings are the table's "
        f"{len(table.theta_i)} incidences, between which the render interpolates the "
        "flakes' narrow glints linearly in θi (docs/render.md):",
        "",
        "![Pearlescent paint rendered per wavelength](images/pearlescent-render.png)"])
    print(text)
    if args.write:
        draw(table, FIGURE)
        subprocess.run([MICROSIM, "render", str(args.table), "-o", str(RENDER), "--object",
                        "sphere", "--variant", "scalar_spectral"], check=True)
        write_section(DOC, "spectral-pearlescent", text)


if __name__ == "__main__":
    main()
