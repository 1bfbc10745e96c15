"""PyVista views of microgeometry: facets coloured by slope or material, tiles repeated."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from microsim.surfaces.tile import Tile

WINDOW = (800, 600)
THIN = 0.1
"""A tile whose height range is below this fraction of its period is drawn with its z axis
stretched to reach it (said in the title): true scale would show a flat sheet."""


def import_pyvista(off_screen: bool) -> Any:
    """PyVista, rendering through EGL when off screen without an X display.

    VTK picks its window class when it is first imported; off screen and with no
    ``DISPLAY`` it is told to use EGL (Debian's libegl1 libegl-mesa0 libgl1-mesa-dri),
    which needs no X server.
    """
    if off_screen and not os.environ.get("DISPLAY"):
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import pyvista as pv

    return pv


def tile_polydata(pv: Any, tile: Tile, tiles: int = 1, z_scale: float = 1.0) -> Any:
    """The tile as PolyData, repeated ``tiles`` × ``tiles`` times (copies shifted by whole
    periods: for viewing only), with cell arrays ``slope`` (degrees) and ``material``.

    Parameters
    ----------
    pv : module
        pyvista.
    tile : Tile
    tiles : int
        Copies per side.
    z_scale : float
        Vertical exaggeration of the drawing (slopes are those of the true tile).

    Returns
    -------
    pyvista.PolyData
    """
    normals, _ = tile.face_normals_areas()
    slope = np.degrees(np.arccos(np.clip(normals[:, 2], -1.0, 1.0)))
    lx, ly = tile.period
    shifts = [(i * lx, j * ly) for i in range(tiles) for j in range(tiles)]
    n = len(tile.vertices)
    drawn = tile.vertices * [1.0, 1.0, z_scale]
    points = np.concatenate([drawn + [dx, dy, 0.0] for dx, dy in shifts])
    faces = np.concatenate([tile.faces + k * n for k in range(len(shifts))])
    cells = np.column_stack([np.full(len(faces), 3), faces]).ravel()
    mesh = pv.PolyData(points, cells)
    mesh.cell_data["slope"] = np.tile(slope, len(shifts))
    mesh.cell_data["material"] = np.tile(np.asarray(tile.material), len(shifts))
    return mesh


def show_tile(tile: Tile, screenshot: str | Path | None = None, tiles: int = 3,
              color: str = "slope", title: str = "") -> np.ndarray | None:
    """View a tile interactively, or render it off screen to a PNG.

    Parameters
    ----------
    tile : Tile
    screenshot : str or Path or None
        PNG to write off screen (no window); None opens an interactive window.
    tiles : int
        Copies per side, to show that the tile repeats seamlessly.
    color : str
        ``"slope"`` (facet slope angle, degrees) or ``"material"`` (part).
    title : str
        Text in the corner.

    Returns
    -------
    (h, w, 3) uint8 or None
        The rendered image when ``screenshot`` is given.
    """
    off = screenshot is not None
    pv = import_pyvista(off)
    z0, z1 = tile.z_range
    reach = THIN * max(tile.period)
    z_scale = reach / (z1 - z0) if 0 < z1 - z0 < reach else 1.0
    if z_scale > 1.0:
        title = f"{title}  (z drawn x{z_scale:.3g})".strip()
    mesh = tile_polydata(pv, tile, tiles, z_scale)
    plotter = pv.Plotter(off_screen=off, window_size=WINDOW)
    if color == "material":
        labels = {i: name for i, name in enumerate(tile.parts)}
        plotter.add_mesh(mesh, scalars="material", categories=True, cmap="Set2",
                         annotations=labels, scalar_bar_args={"title": "part"})
    else:
        top = float(np.ceil(np.percentile(mesh.cell_data["slope"], 99.5) / 5) * 5)
        plotter.add_mesh(mesh, scalars="slope", cmap="viridis", clim=(0, max(top, 5.0)),
                         scalar_bar_args={"title": "facet slope (deg)"})
    plotter.show_bounds(xtitle="x (tile units)", ytitle="y (tile units)",
                        ztitle="z (drawn)" if z_scale > 1.0 else "z (tile units)",
                        font_size=10)
    if title:
        plotter.add_text(title, font_size=10)
    plotter.camera_position = "iso"
    if off:
        image = plotter.screenshot(str(screenshot), return_img=True)
        plotter.close()
        return image
    plotter.show()
    return None
