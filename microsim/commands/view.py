"""``microsim view RECIPE|TILE``: look at a microsurface in 3D (PyVista)."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from microsim import recipe
from microsim.commands.common import (
    add_memory_arg,
    add_seed_arg,
    flag_overrides,
    number_list,
    positive_int,
)
from microsim.errors import InputError
from microsim.files import SCREENSHOT_SUFFIXES, writable_file
from microsim.memory import check_memory

MESHES = (".ply", ".obj", ".stl")
PATH_BYTES = 128_000
"""Memory per drawn ray path (its tracing and its line in the 3D view): measured 105 kB
(20 000 paths over a 64² tile, peak resident memory less the view without paths),
rounded up. The memory guard bounds ``--rays`` with it before anything is traced."""
FACE_BYTES = 200
"""Memory per drawn triangle (the repeated tile's points, cells and cell arrays, and VTK's
copies for drawing): measured 146 B (a 64² tile drawn 20 × 20 times, peak resident
memory less that of one copy), rounded up. The memory guard bounds ``--tiles`` with it."""


period_pair = number_list(2, low=0.0, low_open=True, what="LX,LY (two positive numbers)")


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``view`` command."""
    p = sub.add_parser(
        "view", help="3D view of a tile (recipe or mesh), ray paths, or a table's lobe",
        description="Show the facet geometry of a recipe's tile (.toml) or of a mesh file "
                    "(.ply, .obj, .stl, with --period), coloured by facet slope (degrees) "
                    "or by material part, with a few tiles repeated to show periodicity, "
                    "optionally with traced ray paths (--rays); or the BRDF lobe of a "
                    "table (.exr) at one incidence (--theta-i), optionally against a model. "
                    "Interactive, or rendered off screen to a PNG with --screenshot "
                    "(no X server needed: EGL).")
    p.add_argument("source", metavar="RECIPE|TILE", help="recipe (.toml) or mesh file")
    p.add_argument("--set", dest="overrides", action="append", default=[],
                   metavar="SECTION.KEY=VALUE", help="override a recipe value (repeatable)")
    p.add_argument("--screenshot", type=Path, default=None, metavar="PNG",
                   help="render off screen to this PNG instead of opening a window")
    p.add_argument("--tiles", type=positive_int, default=3,
                   help="copies of the tile per side (default 3)")
    p.add_argument("--color", choices=("slope", "material"), default="slope",
                   help="colour facets by slope angle (degrees) or by material part")
    p.add_argument("--period", type=period_pair, default=None, metavar="LX,LY",
                   help="period of a mesh file (required for .ply/.obj/.stl)")
    p.add_argument("--rays", type=positive_int, default=None,
                   help="recipe: also draw this many traced ray paths, coloured by "
                        "scattering order (light from the recipe's first theta_i)")
    p.add_argument("--theta-i", type=float, default=None, metavar="DEG",
                   help="table: the incidence whose lobe to show, degrees (default: the "
                        "table's first); recipe with --rays: the light's polar angle")
    p.add_argument("--phi-i", type=float, default=None, metavar="DEG",
                   help="table: the incident azimuth, degrees (anisotropic tables: "
                        "interpolated between the table's; default: its first); recipe "
                        "with --rays: the light's azimuth (default 0)")
    p.add_argument("--model", default=None, metavar="SPEC",
                   help="table: draw this analytic model's lobe as a wireframe and colour "
                        "the table's lobe by the relative error (defaults from the table)")
    p.add_argument("--radius", choices=("fr_cos", "fr"), default="fr_cos",
                   help="table: lobe radius f_r cos(theta_o) (default) or f_r")
    p.add_argument("--log", action="store_true", help="table: logarithmic lobe radius")
    add_memory_arg(p)
    add_seed_arg(p, "surface")
    p.set_defaults(func=run)


def check_theta(theta: float) -> None:
    """--theta-i must be an angle in [0, 90) degrees."""
    if not (math.isfinite(theta) and 0 <= theta < 90):
        raise InputError(f"--theta-i {theta}: must be in [0, 90) degrees")


def check_phi(phi: float) -> None:
    """--phi-i must be a finite angle within ±360 degrees."""
    if not (math.isfinite(phi) and -360 <= phi <= 360):
        raise InputError(f"--phi-i {phi}: must be in [-360, 360] degrees")


def incidence_note(measured_deg: list[float], theta: float) -> str:
    """How a table's lobe at ``theta`` (degrees) is drawn when ``theta`` is none of its
    measured incidences: interpolated linearly between its neighbours, or the nearest one
    (the table clamps outside its range); ``""`` when it was measured."""
    if any(math.isclose(theta, t, abs_tol=1e-6) for t in measured_deg):
        return ""
    below = [t for t in measured_deg if t < theta]
    above = [t for t in measured_deg if t > theta]
    if below and above:
        return (f"not measured: interpolated between the table's theta_i {max(below):g} "
                f"and {min(above):g} deg")
    nearest = max(below) if below else min(above)
    return f"not measured: the table's nearest theta_i, {nearest:g} deg, is drawn"


def view_table(args: argparse.Namespace, source: Path) -> int:
    """The lobe of a table at one incidence, optionally against a model."""
    import numpy as np

    import microsim
    from microsim.view import show_lobe

    table = microsim.read_table(source)
    theta = args.theta_i if args.theta_i is not None else math.degrees(table.theta_i[0])
    check_theta(theta)
    phi = args.phi_i if args.phi_i is not None else math.degrees(table.phi_i[0])
    check_phi(phi)
    model = None
    title = f"{source.name}: theta_i = {theta:g} deg"
    if not table.isotropic:
        title += f", phi_i = {phi:g} deg"

    note = incidence_note([math.degrees(t) for t in table.theta_i], theta)
    if note:
        title += f" ({note})"
        print(f"warning: --theta-i {theta:g}: {note}", file=sys.stderr)
    if args.model is not None:
        from microsim.analytic.registry import (
            parameter_sources,
            parameters_text,
            parse_model_spec,
        )
        from microsim.comparison.metrics import check_model_channels, singular_albedo
        from microsim.comparison.table_models import model_defaults
        from microsim.geometry import direction

        defaults = model_defaults(table.meta)
        check_model_channels(args.model, defaults, table.channels)
        name, params, model = parse_model_spec(args.model, defaults)
        if singular_albedo(model, direction(*np.radians([theta, phi]))) > 0:
            raise InputError(f"--model {args.model}: its specular cone is a delta, which a "
                             "lobe has no value for; compare it over the table's bins "
                             "(microsim compare)")
        title += f" (wireframe: {name}; colour: relative error against it)"
        sources = parameter_sources(args.model, params, defaults)
        print(f"wireframe: {name}: {parameters_text(name, params, sources)}")
    if table.channels.spectral:
        nm = table.channels.wavelengths
        # a second line: the first is already as wide as the window holds
        title += (f"\nf_r: luminance (CIE Y, D65) of {len(nm)} wavelengths, "
                  f"{nm[0]:g}-{nm[-1]:g} nm")
    show_lobe(table, float(np.radians(theta)), model, args.screenshot, args.radius,
              args.log, title=title, phi_i=float(np.radians(phi)))
    if args.screenshot is not None:
        print(f"wrote {args.screenshot}")
    return 0


def run(args: argparse.Namespace) -> int:
    """Build or load the tile and show it."""
    from microsim.surfaces import build_tile
    from microsim.view import show_tile

    source = Path(args.source)
    suffix = source.suffix.lower()
    if args.screenshot is not None:
        writable_file(args.screenshot, "--screenshot", SCREENSHOT_SUFFIXES)
    if suffix in MESHES:
        if args.period is None:
            raise InputError(f"--period: required for a mesh file ({source.name}); give "
                             "LX,LY")
        surface = recipe.resolve({"surface": {"kind": "mesh", "path": str(source.resolve()),
                                              "period": args.period}}).surface
        title = source.name
        resolved = None
    elif suffix == ".toml":
        resolved = recipe.load(source, [*args.overrides, *flag_overrides(args, "surface", "seed")])
        surface = resolved.surface
        title = f"{source.name}: {surface.kind}"
    elif suffix == ".exr":
        return view_table(args, source)
    else:
        raise InputError(f"{source}: must be a recipe (.toml), a mesh (.ply, .obj, .stl) "
                         "or a table (.exr)")
    tile = build_tile(surface, args.memory_limit)
    check_memory(FACE_BYTES * len(tile.faces) * args.tiles**2, f"--tiles {args.tiles}: "
                 f"drawing {args.tiles}² copies of the tile's {len(tile.faces):,} triangles",
                 "draw fewer copies (3, the default, shows the periodicity)", args.memory_limit)
    paths = None
    if args.rays is not None:
        from microsim.view import ray_paths

        if resolved is None:
            raise InputError("--rays: needs a recipe (its materials scatter the rays)")
        check_memory(PATH_BYTES * args.rays, f"--rays {args.rays}: drawing the paths",
                     "draw fewer (a few hundred show the scattering)", args.memory_limit)
        sim = resolved.simulation
        theta = args.theta_i if args.theta_i is not None else sim.theta_i[0]
        check_theta(theta)
        phi = args.phi_i if args.phi_i is not None else 0.0
        check_phi(phi)
        paths = ray_paths(tile, resolved.material, math.radians(theta), args.rays,
                          sim.bounces, sim.seed, math.radians(phi))
    # refracting parts enclose a medium: drawn see-through so their contents show
    glass = () if resolved is None else tuple(
        part for part, m in resolved.material.items() if m.encloses_medium)
    show_tile(tile, args.screenshot, args.tiles, args.color, title, paths, glass)
    if args.screenshot is not None:
        print(f"wrote {args.screenshot}")
    return 0
