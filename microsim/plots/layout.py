"""What every figure of a table shares: the panel grid, the signed θo axis, luminance,
the table's colour strip, titles that say what is drawn, and writing the file.

Decisions (docs/compare.md, "Figures"):

- Panels flow into a grid of at most ``MAX_COLUMNS`` columns, ``ceil(sqrt(n))`` of them
  for n panels, so that 1, 4 and 18 incidences give 1 × 1, 2 × 2 and 5 × 4 grids whose
  width and height stay within 3:1 of each other.
- Curves and maps show luminance, not one channel (``microsim.tables.luminance``): of an
  RGB table Y = 0.2126 R + 0.7152 G + 0.0722 B (ITU-R BT.709, the tables' linear sRGB
  primaries), of a spectral table CIE 1931 Y under D65 of its wavelengths; a strip above
  the panels shows the colour that luminance collapses: the directional albedo per θi as
  sRGB (of a spectral table, its spectrum's sRGB under D65,
  ``microsim.spectra.colour.to_srgb_display``).
- Y's standard error is Σ_c w_c σ_c: the channels of a bin are estimated from the same
  rays, so their errors are positively correlated; the sum is exact when the channels are
  proportional (grey facets) and an upper bound otherwise, so a z-score of Y never
  overstates a difference.
"""

from __future__ import annotations

import math
import textwrap
from pathlib import Path
from typing import Any

import numpy as np

from microsim.files import atomic_path
from microsim.spectra.channels import RGB, Channels
from microsim.tables import luminance as lum
from microsim.tables.components import canonical_component, order_range
from microsim.tables.table import BRDFTable

MAX_COLUMNS = 4
PANEL = (3.2, 2.9)
"""Width and height of one panel, inches."""
MIN_WIDTH = 6.0
"""A figure is at least this wide (inches), so that its title fits in a few lines."""
STRIP_HEIGHT = 0.75
"""Height of the colour strip's row, inches."""
DPI = 110
THETA_O_LABEL = "← backscatter    θo (°)    forward →"
"""The signed θo axis of the plane of incidence: negative towards the light."""
Y_NOTE = lum.RGB_NOTE
"""What the luminance of an RGB table's figures is; ``y_note`` gives any table's."""


def pyplot() -> Any:
    """matplotlib.pyplot on the Agg backend (no display needed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def srgb(linear: np.ndarray) -> np.ndarray:
    """The sRGB transfer curve of linear values in [0, 1] (IEC 61966-2-1), clipped."""
    return lum.encode_srgb(linear)


def luminance(values: np.ndarray, channels: Channels = RGB) -> np.ndarray:
    """Y of a table's per-channel values (..., C) → (...): BT.709's of linear RGB, CIE Y
    (D65) of wavelengths (``microsim.tables.luminance``)."""
    return lum.luminance(values, channels)


def luminance_err(err: np.ndarray, channels: Channels = RGB) -> np.ndarray:
    """Standard error of Y from the channels' (..., C) → (...): Σ w_c σ_c (module
    docstring; NaN where a channel's error is undefined)."""
    return lum.luminance_err(err, channels)


def y_note(table: BRDFTable) -> str:
    """What a figure's luminance of ``table`` is, in words: ``luminance Y (Rec. 709)``
    or ``luminance (CIE Y, D65)``."""
    return lum.note(table.channels)


def grid_shape(n: int) -> tuple[int, int]:
    """(rows, columns) of ``n`` panels: ``min(MAX_COLUMNS, ceil(sqrt(n)))`` columns."""
    cols = max(1, min(MAX_COLUMNS, math.ceil(math.sqrt(n))))
    return math.ceil(n / cols), cols


def panel_grid(n: int, strip: bool = False, panel: tuple[float, float] = PANEL,
               extra_width: float = 0.0, columns: int | None = None,
               **subplot_kw: Any) -> tuple[Any, list[Any], Any]:
    """A constrained-layout figure of ``n`` panels in ``grid_shape(n)`` (or one row of
    ``columns``), unused cells left out, optionally with a full-width row on top for
    ``colour_strip``.

    Parameters
    ----------
    n : int
        Panels.
    strip : bool
        Reserve the top row for the colour strip.
    panel : (float, float)
        Size of a panel, inches.
    extra_width : float
        Inches added for a colour bar.
    columns : int or None
        Columns instead of ``grid_shape``'s (at most ``MAX_COLUMNS``).
    subplot_kw
        Passed to ``add_subplot`` (e.g. ``projection``).

    Returns
    -------
    fig, axes, strip_axes
        ``axes`` row by row (length ``n``); ``strip_axes`` is None without a strip.
    """
    plt = pyplot()
    rows, cols = grid_shape(n)
    if columns is not None:
        cols = min(columns, MAX_COLUMNS)
        rows = math.ceil(n / cols)
    width = max(cols * panel[0], MIN_WIDTH) + extra_width
    height = rows * panel[1] + (STRIP_HEIGHT if strip else 0.0) + 0.6
    fig = plt.figure(figsize=(width, height), layout="constrained")
    ratios = ([STRIP_HEIGHT / panel[1]] if strip else []) + [1.0] * rows
    gs = fig.add_gridspec(len(ratios), cols, height_ratios=ratios)
    top = 1 if strip else 0
    axes = [fig.add_subplot(gs[top + k // cols, k % cols], **subplot_kw) for k in range(n)]
    return fig, axes, (fig.add_subplot(gs[0, :]) if strip else None)


def outer_labels(axes: list[Any], xlabel: str, ylabel: str, fontsize: float = 8) -> None:
    """Axis labels on the outside of a grid only: ``xlabel`` under every panel with no
    panel below it, ``ylabel`` left of the first column."""
    specs = [ax.get_subplotspec() for ax in axes]
    for ax, spec in zip(axes, specs, strict=True):
        below = any(s.colspan.start == spec.colspan.start and s.rowspan.start > spec.rowspan.start
                    for s in specs)
        if not below:
            ax.set_xlabel(xlabel, fontsize=fontsize)
        if spec.colspan.start == 0:
            ax.set_ylabel(ylabel, fontsize=fontsize)


def strip_colours(table: BRDFTable, component: str) -> np.ndarray:
    """(a, 3) display sRGB in [0, 1] of the table's directional albedo of ``component``
    per θi (mean over φi): linear RGB through the sRGB curve, or a spectral table's
    spectrum through ``microsim.spectra.colour.to_srgb_display`` (D65)."""
    albedo = np.asarray(table[component].albedo, float).mean(axis=1)   # (a, C)
    return lum.display_srgb(albedo, table.channels)


def colour_strip(ax: Any, table: BRDFTable, component: str,
                 label_colours: list[Any] | None = None) -> None:
    """The table's colour: its directional albedo of ``component`` per θi
    (``strip_colours``), one patch per incidence, labelled with θi (each label in its
    colour of ``label_colours``, the curves' of a figure that draws one per incidence)."""
    ax.imshow(strip_colours(table, component)[None], aspect="auto",
              interpolation="nearest")
    theta = np.degrees(table.theta_i)
    step = max(1, math.ceil(len(theta) / 10))
    ax.set_xticks(np.arange(len(theta))[::step],
                  [f"{t:.0f}°" for t in theta[::step]], fontsize=7)
    if label_colours is not None:
        for label, colour in zip(ax.get_xticklabels(), label_colours[::step], strict=True):
            label.set_color(colour)
    ax.set_yticks([])
    ax.tick_params(axis="x", length=0, pad=1)
    how = "sRGB of its spectrum under D65" if table.channels.spectral else "sRGB"
    ax.set_title(f"colour of the table ({component_text(component)}): directional "
                 f"albedo per θi, {how}", fontsize=8)


def component_text(component: str) -> str:
    """A component in words: ``single scattering``, ``all orders``, ``order 2``,
    ``orders 3 and above``."""
    if component == "total":
        return "all orders"
    low, high = order_range(canonical_component(component))
    if low == 1 and high == 1:
        return "single scattering"
    return f"order {low}" if high == low else f"orders {low} and above"


def compact(n: int) -> str:
    """A ray count in few characters: 3,000 · 200k · 9.19M."""
    if n >= 10**6:
        return f"{n / 10**6:.3g}M"
    return f"{n / 1000:.3g}k" if n >= 10**4 else f"{n:,}"


def rays_text(table: BRDFTable) -> str:
    """The rays per incident direction: one count, or the range an adaptive run used."""
    lo, hi = int(table.rays.min()), int(table.rays.max())
    if lo == hi:
        return f"{hi:,} rays per direction"
    return f"{lo:,} to {hi:,} rays per direction (each panel gives its own)"


def panel_title(table: BRDFTable, k: int, j: int = 0) -> str:
    """``θi = 30°`` (with ``, φi = …`` for an anisotropic table, and the direction's own
    ray count when the table's directions differ in rays)."""
    text = f"θi = {np.degrees(table.theta_i[k]):.0f}°"
    if not table.isotropic:
        text += f", φi = {np.degrees(table.phi_i[j]):.0f}°"
    if table.rays.min() != table.rays.max():
        text += f", {compact(int(table.rays[k, j]))} rays"
    return text


def wrapped(title: str, fig: Any, fontsize: float) -> str:
    """``title`` in lines that fit the figure's width at ``fontsize`` points (a character
    of DejaVu Sans is at most about 0.6 em wide on average), broken at spaces only, so a
    name such as ``oren-nayar`` stays whole."""
    width_pt = fig.get_figwidth() * 72
    return textwrap.fill(title, max(20, int(width_pt / (0.6 * fontsize))),
                         break_on_hyphens=False, break_long_words=False)


def suptitle(fig: Any, title: str, note: str = "", fontsize: float = 10) -> None:
    """The figure's title, wrapped, and a smaller second line ``note`` saying what is
    drawn (component, channel, errors)."""
    text = wrapped(title, fig, fontsize) if title else ""
    if note:
        text = (text + "\n" if text else "") + wrapped(note, fig, fontsize - 1)
    if text:
        fig.suptitle(text, fontsize=fontsize)


def save(fig: Any, path: str | Path, dpi: int = DPI) -> None:
    """Write ``fig`` atomically in the format of ``path``'s suffix (PNG by default) and
    close it."""
    plt = pyplot()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi, format=Path(path).suffix.lstrip(".").lower() or "png")
    plt.close(fig)
