"""``microsim check RECIPE``: validate a recipe and print it fully resolved."""

from __future__ import annotations

import argparse
from pathlib import Path

from microsim import recipe
from microsim.commands.common import add_json_arg, add_recipe_args, print_json
from microsim.errors import InputError


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``check`` command."""
    p = sub.add_parser(
        "check",
        help="validate a recipe and print it resolved (defaults filled in)",
        description="Validate a recipe strictly (unknown keys, types, ranges; angles in "
                    "degrees) and print it fully resolved with every default filled in. "
                    "Exit 0 when valid, 2 with the first problem otherwise.",
    )
    add_recipe_args(p)
    add_json_arg(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Print the resolved recipe as TOML (or JSON with ``--json``); a surface file (a
    mesh) that does not exist is an error here, as building the tile would find."""
    resolved = recipe.load(args.recipe, args.overrides)
    surface = resolved.surface
    for name, key in surface.keys().items():
        given = surface.value(name)
        if key.kind == "path" and given is not None and not Path(given).is_file():
            raise InputError(f"surface.{name} = {given!r}: no such file")
    if args.json:
        print_json(resolved.to_json())
    else:
        print(recipe.to_toml(resolved), end="")
    return 0
