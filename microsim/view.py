"""PyVista views of microgeometry: facets coloured by slope or material, tiles repeated."""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Any

import numpy as np

from microsim.errors import InputError
from microsim.files import atomic_path
from microsim.geometry import direction
from microsim.kernel.packing import FacetMaterials
from microsim.kernel.slots import ESCAPED, O_FATE, O_ORDER, S_DX
from microsim.measurement.scene import PeriodicScene
from microsim.surfaces.tile import Tile

WINDOW = (800, 600)
GLASS = 0.3
"""Opacity of see-through (refracting) parts."""
TILE_BAR = {"vertical": False, "position_x": 0.5, "position_y": 0.82, "width": 0.45,
            "height": 0.1, "title_font_size": 16, "label_font_size": 14}
"""The tile view's colour bar: across the top right, which the iso view leaves empty,
clear of the axis labels it puts at the bottom corner. Titles of horizontal bars end in a
newline, which lifts them clear of the labels VTK puts above the bar."""
LOBE_BAR = {"vertical": False, "position_x": 0.3, "position_y": 0.02, "width": 0.6,
            "height": 0.12, "title_font_size": 16, "label_font_size": 14}
"""The lobe view's colour bar: along the bottom (titles end in a newline, as for
``TILE_BAR``)."""
LOBE_OPACITY = 0.55
"""Opacity of the simulated lobe when a model's wireframe is drawn with it."""
WIRE_STEP = 4
"""The model's wireframe draws every this many lines of the lobe's grid."""
FONT = 14
"""Font size of the 3D views' axis titles, tick labels and corner text (points)."""
REL_ERROR = "(simulated - model) / model"
"""The lobe view's colour, the relative error against the model, clipped to ±50%."""
THIN = 0.1
"""A tile whose height range is below this fraction of its period is drawn with its z axis
stretched to reach it (said in the title): true scale would show a flat sheet."""


def import_pyvista(off_screen: bool) -> Any:
    """PyVista, rendering through EGL when off screen without an X display.

    VTK picks its window class when it is first imported; off screen and with no
    ``DISPLAY`` it is told to use EGL (Debian's libegl1 libegl-mesa0 libgl1-mesa-dri),
    which needs no X server.
    """
    headless = sys.platform.startswith("linux") and not (
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
    if headless and not off_screen:
        raise InputError("view: no display for an interactive window here; render to a "
                         "file with --screenshot PNG")
    if headless:
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    import pyvista as pv

    return pv


def finish(plotter: Any, screenshot: str | Path | None) -> np.ndarray | None:
    """Write the off-screen image (atomically, in the format of its suffix) and return
    it, or open the interactive window."""
    if screenshot is None:
        plotter.show()
        return None
    from PIL import Image  # matplotlib's own image library

    image = plotter.screenshot(None, return_img=True)
    plotter.close()
    suffix = Path(screenshot).suffix.lower()
    with atomic_path(screenshot) as tmp:
        Image.fromarray(image).save(tmp, format="JPEG" if suffix in (".jpg", ".jpeg")
                                    else "PNG")
    return image


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
              color: str = "slope", title: str = "",
              paths: list[tuple[np.ndarray, int]] | None = None,
              translucent: tuple[str, ...] = ()) -> np.ndarray | None:
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
    paths : list of ((k, 3) float, int) or None
        Ray paths (``ray_paths``) to draw, coloured by scattering order.
    translucent : tuple of str
        Parts drawn see-through (light blue, opacity ``GLASS``), e.g. a paint's refracting
        binder, so that what lies inside shows.

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
    glass = np.isin(np.asarray(tile.parts)[mesh.cell_data["material"]], translucent)
    if glass.any() and not glass.all():  # (a tile all glass is drawn as it is)
        plotter.add_mesh(mesh.extract_cells(np.flatnonzero(glass)), color="lightblue",
                         opacity=GLASS, smooth_shading=True)
        mesh = mesh.extract_cells(np.flatnonzero(~glass))
        title = f"{title}  (see-through: {', '.join(translucent)})".strip()
    if color == "material":
        labels = {i: name for i, name in enumerate(tile.parts)}
        # part i gets Set2's colour i, also when see-through parts are drawn apart
        from matplotlib import colormaps
        from matplotlib.colors import ListedColormap

        n = len(tile.parts)
        cmap = ListedColormap(colormaps["Set2"].colors[:max(n, 2)])
        plotter.add_mesh(mesh, scalars="material", cmap=cmap, n_colors=max(n, 2),
                         clim=(-0.5, max(n, 2) - 0.5), annotations=labels,
                         scalar_bar_args={"title": "part", "n_labels": 0, **TILE_BAR})
    else:
        top = float(np.ceil(np.percentile(mesh.cell_data["slope"], 99.5) / 5) * 5)
        plotter.add_mesh(mesh, scalars="slope", cmap="viridis", clim=(0, max(top, 5.0)),
                         scalar_bar_args={"title": "facet slope (deg)\n", **TILE_BAR})
    colours = {0: "black", 1: "gold", 2: "orangered", 3: "magenta"}
    for points, order in paths or []:
        line = pv.lines_from_points(points * [1.0, 1.0, z_scale])
        plotter.add_mesh(line, color=colours[min(order, 3)], line_width=2)
    if paths:
        plotter.add_legend([["single", "gold"], ["double", "orangered"],
                            ["3 or more", "magenta"], ["not escaped", "black"]],
                           bcolor="white", size=(0.18, 0.16), loc="lower left")
    plotter.show_bounds(xtitle="x (tile units)", ytitle="y (tile units)",
                        ztitle="z (drawn)" if z_scale > 1.0 else "z (tile units)",
                        font_size=FONT, bold=False)
    if title:
        plotter.add_text(title, font_size=FONT - 2)
    plotter.camera_position = "iso"
    return finish(plotter, screenshot)


def lobe_surface(pv: Any, f: np.ndarray, theta: np.ndarray, phi: np.ndarray,
                 radius: str, log: bool) -> Any:
    """A radial surface r(ωo) ωo over a (θo, φo) grid.

    Parameters
    ----------
    pv : module
    f : (nt, np) float
        f_r on the grid, 1/sr.
    theta, phi : (nt,), (np,) float
        Grid angles, radians.
    radius : str
        ``"fr_cos"``: r = f_r cos θo (the reflected radiance lobe under unit irradiance);
        ``"fr"``: r = f_r.
    log : bool
        r = log10(1 + r / r_max · 1000) / 3: shows faint tails next to a strong peak.

    Returns
    -------
    pyvista.StructuredGrid
    """
    t, p = np.meshgrid(theta, phi, indexing="ij")
    r = f * np.cos(t) if radius == "fr_cos" else f.copy()
    if log:
        r = np.log10(1.0 + 1000.0 * r / max(float(r.max()), 1e-300)) / 3.0
    w = direction(t, p) * r[..., None]
    return pv.StructuredGrid(w[..., 0], w[..., 1], w[..., 2])


def show_lobe(table: Any, theta_i: float, model: Any = None,
              screenshot: str | Path | None = None, radius: str = "fr_cos",
              log: bool = False, component: str = "total", title: str = "",
              n: int = 64, phi_i: float = 0.0) -> np.ndarray | None:
    """A table's BRDF lobe for one incidence as a radial surface over the hemisphere.

    The lobe is of one number per direction: the mean of an RGB table's channels, the
    luminance (CIE Y under D65, ``microsim.tables.luminance``) of a spectral table's.
    Colour is the relative error against ``model`` (clipped to ±50%) when one is given,
    else f_r; the model's lobe is drawn as an opaque wireframe through the see-through
    simulated lobe (``LOBE_OPACITY``), so it shows also where it lies inside, and the
    incident direction as an arrow pointing at the surface.

    Parameters
    ----------
    table : BRDFTable
    theta_i : float
        Incident polar angle, radians.
    model : Model or None
    screenshot : str or Path or None
        PNG to render off screen; None opens a window.
    radius : str
        ``"fr_cos"`` or ``"fr"`` (see ``lobe_surface``).
    log : bool
        Logarithmic radius.
    component : str
    title : str
    n : int
        Grid resolution in θo (2n in φo).
    phi_i : float
        Incident azimuth, radians (an anisotropic table's lobe depends on it; an
        isotropic one turns with it).

    Returns
    -------
    (h, w, 3) uint8 or None
    """
    off = screenshot is not None
    pv = import_pyvista(off)
    theta = np.radians(np.linspace(0.0, 89.5, n))
    phi = np.linspace(0.0, 2 * np.pi, 2 * n + 1)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    wi = direction(theta_i, phi_i)
    wo = direction(t, p)
    channels = table.channels
    f = one_value(table.eval(wi, wo, component), channels)
    surf = lobe_surface(pv, f, theta, phi, radius, log)
    plotter = pv.Plotter(off_screen=off, window_size=WINDOW)
    if model is not None:
        g = np.asarray(model.eval(np.broadcast_to(wi, wo.shape), wo), float)
        if g.ndim == 3:
            from microsim.comparison.metrics import channels_of

            g = one_value(channels_of(g, channels.count), channels)
        rel = np.where(g > 0, (f - g) / np.where(g > 0, g, 1.0), 0.0)
        surf.point_data[REL_ERROR] = np.clip(rel, -0.5, 0.5).ravel(order="F")
        # the simulated lobe see-through and the model's wireframe opaque (every
        # WIRE_STEP-th grid line): where the model lies inside the lobe it still shows
        plotter.add_mesh(surf, scalars=REL_ERROR, cmap="RdBu_r", clim=(-0.5, 0.5),
                         opacity=LOBE_OPACITY,
                         scalar_bar_args={"title": f"{REL_ERROR}\n", **LOBE_BAR})
        coarse = (slice(None, None, WIRE_STEP), slice(None, None, WIRE_STEP))
        plotter.add_mesh(lobe_surface(pv, g[coarse], theta[coarse[0]], phi[coarse[1]],
                                      radius, log), style="wireframe", color="black",
                         line_width=1.0)
    else:
        name = "f_r (1/sr), CIE Y" if channels.spectral else "f_r (1/sr)"
        surf.point_data[name] = f.ravel(order="F")
        plotter.add_mesh(surf, scalars=name, cmap="viridis",
                         scalar_bar_args={"title": f"{name}\n", **LOBE_BAR})
    size = max(float(np.abs(surf.points).max()), 1e-9)
    plotter.add_mesh(pv.Arrow(start=wi * 1.3 * size, direction=-wi, scale=0.5 * size),
                     color="orange")
    plotter.add_mesh(pv.Disc(inner=0.0, outer=size, c_res=48), color="lightgrey",
                     opacity=0.3)
    plotter.add_text(title or f"theta_i = {np.degrees(theta_i):.0f} deg", font_size=FONT - 2)
    plotter.camera_position = [(2.5 * size, -2.5 * size, 1.8 * size), (0, 0, 0.2 * size),
                               (0, 0, 1)]
    return finish(plotter, screenshot)


def one_value(values: np.ndarray, channels: Any) -> np.ndarray:
    """A lobe's one number per direction of per-channel values (..., C): the mean over an
    RGB table's channels, CIE Y (D65) of a spectral table's."""
    if not channels.spectral:
        return values.mean(axis=-1)
    from microsim.tables.luminance import luminance

    return luminance(values, channels)


def ray_paths(tile: Tile, materials: Any, theta_i: float, rays: int, bounces: int,
              seed: int, phi_i: float = 0.0) -> list[tuple[np.ndarray, int]]:
    """Polylines of a few rays scattered by the tile, for drawing.

    The paths are traced by the same transport kernel as ``simulate``
    (``PeriodicScene.run``), which keeps each path's hit points unwrapped: a path that
    crosses a side continues into the neighbouring copy instead of jumping back.

    Parameters
    ----------
    tile : Tile
    materials : mapping of str to Material
        The material of every part.
    theta_i : float
        Incident polar angle, radians.
    rays, bounces, seed : int
    phi_i : float
        Incident azimuth, radians.

    Returns
    -------
    list of ((k, 3) float, int)
        Each path's vertices (a point on the incoming ray 0.3 periods before the tile, the
        entry into the slab, the hit points, and 0.3 periods along the escaping ray) and
        its scattering order (0: it did not escape).
    """
    rng = np.random.default_rng(seed)
    facets = FacetMaterials(tile.material, tile.parts, materials, tile.tangents,
                            tile.curved)
    lx, ly = tile.period
    d = np.broadcast_to(-direction(theta_i, phi_i), (rays, 3))
    reach = 0.3 * max(lx, ly)  # drawn length of the incoming and escaping legs
    with PeriodicScene(tile, threads=1) as scene:
        o = np.column_stack([(0.25 + 0.5 * rng.random((rays, 2))) * [lx, ly],
                             np.full(rays, scene.z_top)])
        out = scene.run(o, d, facets, bounces, np.random.SeedSequence(seed),
                        vertices=bounces + 1)
    paths = []
    for k in range(rays):
        hits = out.vertices[k][~np.isnan(out.vertices[k, :, 0])]
        points = [o[k] - reach * d[k], o[k], *hits]
        escaped = out.ints[k, O_FATE] == ESCAPED
        if escaped:
            points.append(points[-1] + reach * out.floats[k, S_DX:S_DX + 3])
        paths.append((np.array(points), int(out.ints[k, O_ORDER]) if escaped else 0))
    return paths
