"""Rendered images as a labelled PNG grid, and the relative difference of two renders.

Display (docs/render.md, "Display"): the linear render over a grey background where no
ray hit the object, at exposure ``EXPOSURE``, tone-mapped by Reinhard et al. 2002's global
operator on luminance (eq. 3, L_d = L / (1 + L)), which never reaches 1, so no highlight
clips; every channel is scaled by L_d / L, which keeps the hue, and a colour whose
brightest channel would still exceed 1 is moved towards grey at the same luminance; then
the sRGB transfer curve (IEC 61966-2-1). The operator uses no statistic of the image, so
tables, models and separate runs are shown alike.
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

from microsim.plots.layout import MAX_COLUMNS, grid_shape, pyplot, save, srgb
from microsim.render.scene import Image
from microsim.tables.export import LUMINANCE

BACKGROUND = 0.2
"""Linear grey behind the object."""
EXPOSURE = 1.0
"""Scale of linear radiance before the tone curve: under the default sun and sky a white
Lambertian face towards the sun (radiance 3/π + 0.25 ≈ 1.2) shows at L_d ≈ 0.55, leaving
the upper half of the display range to highlights."""
DARK = 0.02
"""Pixels darker than this fraction of the model's 99th percentile get no difference."""
DIFF_RANGE = 0.5
"""The difference colour scale spans ±50%."""


def tone_map(rgb: np.ndarray, exposure: float = EXPOSURE) -> np.ndarray:
    """Reinhard et al. 2002's global operator (eq. 3) on luminance, hue kept.

    Parameters
    ----------
    rgb : (..., 3) float
        Linear radiance (negative values count as 0).
    exposure : float

    Returns
    -------
    (..., 3) float
        Display-linear RGB in [0, 1): luminance L_d = L / (1 + L) of the exposed
        luminance L, every channel scaled by L_d / L = 1 / (1 + L); where a channel would
        still exceed 1 the colour is blended towards the grey L_d (same luminance) until
        its brightest channel is 1.
    """
    x = np.maximum(np.asarray(rgb, float) * exposure, 0.0)
    y = x @ LUMINANCE
    out = x / (1.0 + y)[..., None]
    grey = (y / (1.0 + y))[..., None]
    top = out.max(axis=-1, keepdims=True)
    t = np.where(top > 1.0, (1.0 - grey) / np.where(top > 1.0, top - grey, 1.0), 1.0)
    return grey + t * (out - grey)


def display(image: Image) -> np.ndarray:
    """(h, w, 3) sRGB in [0, 1]: the render over the grey background, tone-mapped
    (``tone_map``) and through the sRGB curve."""
    return srgb(tone_map(image.rgb + (1.0 - image.alpha[..., None]) * BACKGROUND))


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
    (default ``microsim.plots.layout.grid_shape``'s, at most 4) with the table names as
    titles. With a model each table is a column (at most ``columns``, default 4) of its
    panels (table, model, difference) top to bottom, titled with the table's name first;
    more tables start another block of rows. Difference panels get a shared colour bar of
    ±``DIFF_RANGE``, labelled ``difference``. Either way the figure stays within 3:1.
    """
    h, w = next(p for _, p in rows[0].panels).shape[:2]
    if all(len(r.panels) == 1 for r in rows):
        ncol = columns or grid_shape(len(rows))[1]
        cells = [(r.label, r.panels[0][1]) for r in rows]
    else:
        ncol = min(columns or MAX_COLUMNS, len(rows))
        cells = []
        for start in range(0, len(rows), ncol):
            block = list(rows[start:start + ncol])
            for i in range(max(len(r.panels) for r in block)):
                line: list[tuple[str, np.ndarray] | None] = [
                    (_panel_title(r, i), r.panels[i][1]) if i < len(r.panels) else None
                    for r in block]
                cells += line + [None] * (ncol - len(line))
    nrow = -(-len(cells) // ncol)
    scale = 2.6 / max(h, w) * max(w, 1)
    plt = pyplot()
    fig, axes = plt.subplots(nrow, ncol, squeeze=False,
                             figsize=(scale * ncol + 0.6, (scale * h / w + 0.22) * nrow + 0.15),
                             layout="constrained")
    image = None
    for ax, cell in zip(axes.ravel(), cells + [None] * (axes.size - len(cells)),
                        strict=True):
        ax.set_xticks([])
        ax.set_yticks([])
        if cell is None:
            ax.set_axis_off()
            continue
        title, data = cell
        if data.ndim == 2:
            shown = np.ma.masked_invalid(data)
            cmap = plt.get_cmap("RdBu_r").with_extremes(bad=(0.5, 0.5, 0.5))
            image = ax.imshow(shown, cmap=cmap, vmin=-DIFF_RANGE, vmax=DIFF_RANGE)
        else:
            ax.imshow(data)
        ax.set_title(title, fontsize=8)
    if image is not None:
        bar = fig.colorbar(image, ax=axes.ravel().tolist(), shrink=0.6,
                           format=lambda x, _: f"{100 * x:+.0f}%")
        bar.set_label(difference, fontsize=8)
    save(fig, path, dpi=150)


def _panel_title(row: Row, i: int) -> str:
    """Panel ``i``'s title in a table's column: the first names the table."""
    title = row.panels[i][0]
    return (row.label if title == row.label else f"{row.label}: {title}") if i == 0 else title
