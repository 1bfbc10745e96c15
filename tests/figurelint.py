"""Figure lint: the faults of a drawn matplotlib figure that make it hard to read.

A text (suptitle, panel titles, axis labels, tick labels inside the axis range, legend
entries, colour-bar labels, free texts) is at fault when its bounding box sticks out of
the figure, lies on another panel, or overlaps another text (of its own panel too: tick
labels run into each other); a figure is at fault when its width and height differ by more than
``MAX_ASPECT`` times.
"""

from __future__ import annotations

from typing import Any

MAX_ASPECT = 3.0
SLACK = 1.0
"""Pixels a text may reach past the figure's edge (antialiasing of the last glyph)."""


def drawn_texts(fig: Any) -> list[tuple[Any, Any]]:
    """(text, its panel or None) of what a figure shows: the suptitle and free figure
    texts (panel None), and per panel (colour bars included) its titles, axis labels,
    tick labels inside the axis range, legend and free texts."""
    texts = [(fig._suptitle, None)] if fig._suptitle is not None else []
    texts += [(t, None) for t in fig.texts if t is not fig._suptitle]
    for ax in fig.axes:
        own = [ax.title, ax._left_title, ax._right_title, ax.xaxis.label, ax.yaxis.label,
               *ax.texts]
        for axis, (lo, hi) in ((ax.xaxis, sorted(ax.get_xlim())),
                               (ax.yaxis, sorted(ax.get_ylim()))):
            own += [tick.label1 for tick in axis.get_major_ticks()
                    if tick.label1.get_visible() and lo <= tick.get_loc() <= hi]
            own += [tick.label2 for tick in axis.get_major_ticks()
                    if tick.label2.get_visible() and lo <= tick.get_loc() <= hi]
        if ax.get_legend() is not None:
            own += ax.get_legend().get_texts()
        texts += [(t, ax) for t in own]
    return [(t, ax) for t, ax in texts if t.get_visible() and t.get_text().strip()]


def figure_layout_faults(fig: Any) -> list[str]:
    """Every fault of ``fig`` (module docstring), as readable lines; empty if none."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    box = fig.bbox
    faults = []
    width, height = fig.get_size_inches()
    if max(width / height, height / width) > MAX_ASPECT:
        faults.append(f"aspect {width:.1f} x {height:.1f} in is beyond {MAX_ASPECT:g}:1")
    panels = list(fig.axes)
    texts = drawn_texts(fig)
    extents = [t.get_window_extent(renderer) for t, _ in texts]
    for i, ((text, owner), ext) in enumerate(zip(texts, extents, strict=True)):
        if ext.x0 < box.x0 - SLACK or ext.x1 > box.x1 + SLACK or \
                ext.y0 < box.y0 - SLACK or ext.y1 > box.y1 + SLACK:
            faults.append(f"clipped by the figure's edge: {text.get_text()!r}")
        for ax in panels:
            if ax is not owner and ext.overlaps(ax.get_window_extent(renderer)):
                faults.append(f"{text.get_text()!r} lies on another panel")
        for (other, _), other_ext in zip(texts[:i], extents[:i], strict=True):
            if ext.overlaps(other_ext):
                faults.append(f"{text.get_text()!r} overlaps {other.get_text()!r}")
    return faults
