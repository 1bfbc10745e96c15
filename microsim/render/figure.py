"""Rendered images as a labelled PNG grid, and the relative difference of two renders.

Display: linear radiance is shown as is (exposure 1) through the sRGB transfer curve
(IEC 61966-2-1), clipped at 1, over a grey background where no ray hit the object.
The difference of a table's render T from a model's M is (T − M) / M in luminance, on
pixels the object covers fully in both and where M is above ``DARK`` of its 99th
percentile (elsewhere the ratio is noise over nothing); each pixel's noise is
σ = √(σ_T² + σ_M²) / M from the renders' own per-pixel standard errors.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from microsim.files import atomic_path
from microsim.render.scene import Image

BACKGROUND = 0.2
"""Linear grey behind the object."""
DARK = 0.02
"""Pixels darker than this fraction of the model's 99th percentile get no difference."""
DIFF_RANGE = 0.5
"""The difference colour scale spans ±50%."""


def srgb(linear: np.ndarray) -> np.ndarray:
    """The sRGB transfer curve of linear values in [0, 1] (IEC 61966-2-1)."""
    x = np.clip(linear, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)


def display(image: Image) -> np.ndarray:
    """(h, w, 3) sRGB in [0, 1]: the render over the grey background."""
    return srgb(image.rgb + (1.0 - image.alpha[..., None]) * BACKGROUND)


@dataclass(frozen=True)
class Difference:
    """(T − M) / M per pixel and its summary.

    Attributes
    ----------
    relative : (h, w) float
        NaN where it is not defined (background, edges, dark pixels).
    noise : (h, w) float
        Standard error of ``relative`` from the renders' per-pixel errors; NaN likewise.
    median_abs : float
        Median |relative| over the defined pixels.
    median_noise : float
        What noise alone would give for that median: 0.674 × the median σ (the median of
        |N(0, σ²)| is 0.674 σ).
    mean : float
        Mean of ``relative`` (a bias: noise alone averages to 0).
    mean_err : float
        Its standard error from the pixels' own, √(Σ σ²) / n: the pixels' samples are
        independent (Mitsuba's ``independent`` sampler), so are their errors.
    total : float
        Σ T / Σ M − 1 over the same pixels: the relative difference of their mean
        luminance, which rare bright samples in dim pixels (a sampled-only BSDF that finds
        a small light now and then) move far less than ``mean``.
    total_err : float
        Its standard error, √(Σ σ_T² + σ_M²) / Σ M (first order in the errors).
    pixels : int
    """

    relative: np.ndarray
    noise: np.ndarray
    median_abs: float
    median_noise: float
    mean: float
    mean_err: float
    total: float
    total_err: float
    pixels: int


def difference(table: Image, model: Image) -> Difference:
    """The relative luminance difference of ``table`` from ``model`` (module docstring)."""
    m = model.luminance
    covered = (table.alpha > 0.999) & (model.alpha > 0.999)
    floor = DARK * np.percentile(m[covered], 99) if covered.any() else 0.0
    ok = covered & (m > floor) & (m > 0)
    safe = np.where(ok, m, 1.0)
    rel = np.where(ok, (table.luminance - m) / safe, np.nan)
    noise = np.where(ok, np.hypot(table.luminance_err, model.luminance_err) / safe, np.nan)
    n = int(ok.sum())
    if n == 0:
        nan = float("nan")
        return Difference(rel, noise, nan, nan, nan, nan, nan, nan, 0)
    sum_m = float(np.sum(m[ok]))
    return Difference(rel, noise, float(np.median(np.abs(rel[ok]))),
                      0.6745 * float(np.median(noise[ok])), float(np.mean(rel[ok])),
                      float(np.sqrt(np.sum(noise[ok] ** 2))) / n,
                      float(np.sum(table.luminance[ok])) / sum_m - 1.0,
                      float(np.sqrt(np.sum(table.luminance_err[ok] ** 2
                                           + model.luminance_err[ok] ** 2))) / sum_m, n)


@dataclass(frozen=True)
class Row:
    """One table's row of the grid: its name and its panels (titles and images)."""

    label: str
    panels: Sequence[tuple[str, np.ndarray]]
    """(title, (h, w, 3) sRGB image or (h, w) relative difference)."""


def write_grid(rows: Sequence[Row], path: str | Path, columns: int | None = None,
               difference: str = "(table − model) / model") -> None:
    """Write the grid as a PNG, atomically.

    Without a model every row has one panel, and the panels flow into ``columns`` columns
    (default: up to 4) with the table names as titles. With a model each row is
    (table, model, difference) with the row's name on the left; difference panels get a
    shared colour bar of ±``DIFF_RANGE``, labelled ``difference``.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    h, w = next(p for _, p in rows[0].panels).shape[:2]
    single = all(len(r.panels) == 1 for r in rows)
    if single:
        panels = [(r.label, r.panels[0][1]) for r in rows]
        ncol = columns or min(4, len(panels))
        grid = [panels[i:i + ncol] for i in range(0, len(panels), ncol)]
    else:
        ncol = max(len(r.panels) for r in rows)
        grid = [list(r.panels) for r in rows]
    scale = 2.6 / max(h, w) * max(w, 1)
    fig, axes = plt.subplots(len(grid), ncol, squeeze=False,
                             figsize=(scale * ncol, scale * h / w * len(grid) + 0.35),
                             layout="constrained")
    image = None
    for i, line in enumerate(grid):
        for j in range(ncol):
            ax = axes[i, j]
            ax.set_xticks([])
            ax.set_yticks([])
            if j >= len(line):
                ax.set_axis_off()
                continue
            title, data = line[j]
            if data.ndim == 2:
                shown = np.ma.masked_invalid(data)
                cmap = plt.get_cmap("RdBu_r").with_extremes(bad=(0.5, 0.5, 0.5))
                image = ax.imshow(shown, cmap=cmap, vmin=-DIFF_RANGE, vmax=DIFF_RANGE)
            else:
                ax.imshow(data)
            ax.set_title(title, fontsize=8)
            if not single and j == 0:
                ax.set_ylabel(rows[i].label, fontsize=9)
    if image is not None:
        bar = fig.colorbar(image, ax=axes[:, -1].tolist(), shrink=0.8,
                           format=lambda x, _: f"{100 * x:+.0f}%")
        bar.set_label(difference, fontsize=8)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=150, format="png")
    plt.close(fig)
