"""``microsim view RECIPE|TILE``: look at a microsurface in 3D (PyVista)."""

from __future__ import annotations

import argparse
from pathlib import Path

from microsim import recipe
from microsim.cli import add_seed_arg, number_list, positive_int, seed_override
from microsim.commands.generate import add_memory_arg
from microsim.errors import InputError

MESHES = (".ply", ".obj", ".stl")


period_pair = number_list(2, low=0.0, low_open=True, what="LX,LY (two positive numbers)")


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``view`` command."""
    p = sub.add_parser(
        "view", help="3D view of a recipe's tile or a mesh file (PyVista)",
        description="Show the facet geometry of a recipe's tile (.toml) or of a mesh file "
                    "(.ply, .obj, .stl, with --period), coloured by facet slope (degrees) "
                    "or by material part, with a few tiles repeated to show periodicity. "
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
    add_memory_arg(p)
    add_seed_arg(p, "surface")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Build or load the tile and show it."""
    from microsim.surfaces import build_tile
    from microsim.view import show_tile

    source = Path(args.source)
    suffix = source.suffix.lower()
    if suffix in MESHES:
        if args.period is None:
            raise InputError(f"--period: required for a mesh file ({source.name}); give "
                             "LX,LY")
        surface = recipe.resolve({"surface": {"kind": "mesh", "path": str(source.resolve()),
                                              "period": args.period}})["surface"]
        title = source.name
    elif suffix == ".toml":
        surface = recipe.load(source, [*args.overrides, *seed_override(args, "surface")])[
            "surface"]
        title = f"{source.name}: {surface['kind']}"
    else:
        raise InputError(f"{source}: must be a recipe (.toml) or a mesh (.ply, .obj, .stl)")
    tile = build_tile(surface, args.memory_limit)
    show_tile(tile, args.screenshot, args.tiles, args.color, title)
    if args.screenshot is not None:
        print(f"wrote {args.screenshot}")
    return 0
