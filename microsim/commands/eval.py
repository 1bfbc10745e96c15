"""``microsim eval TABLE --wi THETA,PHI --wo THETA,PHI``: a table's f_r at one direction
pair, from its bins, its spherical harmonics or its stored wavelets."""

from __future__ import annotations

import argparse

from microsim.commands.common import (
    add_component_arg,
    add_direction_args,
    add_json_arg,
    channels_json,
    channels_words,
    print_json,
    readable,
    table_component,
)
from microsim.errors import InputError

BASES = ("table", "sh", "wavelet")
"""``microsim.tables.table.REPRESENTATIONS``, spelled out so that ``--help`` does not
import numpy."""


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``eval`` command."""
    p = sub.add_parser(
        "eval", help="evaluate a table's f_r (1/sr) at one direction pair",
        description="Evaluate f_r (1/sr, not times cos) of a table at one direction pair, "
                    "from the bins (interpolated as table.eval does), the spherical "
                    "harmonics, or the wavelets stored by `microsim wavelets TABLE "
                    "--store`. Directions are THETA,PHI in degrees, pointing away from "
                    "the surface: --wi towards the light, --wo towards the viewer. Prints "
                    "one value per channel: R, G, B, or each wavelength of a spectral "
                    "table (with its luminance, CIE Y under D65).")
    p.add_argument("table", metavar="TABLE", help="table file (.exr)")
    add_direction_args(p)
    p.add_argument("--basis", choices=BASES, default="table",
                   help="what to evaluate: table (the bins, default), sh (the spherical "
                        "harmonics) or wavelet (the stored wavelets)")
    add_component_arg(p)
    add_json_arg(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Read the table and evaluate it."""
    import numpy as np

    import microsim
    from microsim.geometry import direction

    table = microsim.read_table(args.table, require_sh=args.basis == "sh")
    component = table_component(table, args.component, args.table)
    if args.basis == "sh" and not table.has_sh:
        raise InputError(f"--basis sh: {args.table} holds no spherical harmonics "
                         "(simulate it with [table] sh_order > 0)")
    if args.basis == "wavelet" and table.wavelets is None:
        raise InputError(f"--basis wavelet: {args.table} holds no wavelets (store them "
                         "with microsim wavelets TABLE --store TABLE)")
    wi = direction(*np.radians(args.wi))
    wo = direction(*np.radians(args.wo))
    values = table.eval(wi, wo, component, args.basis)
    f = values.tolist()
    spectral = {}
    if table.channels.spectral:
        from microsim.tables.luminance import luminance

        spectral = {**channels_json(table), "luminance": float(luminance(values,
                                                                         table.channels))}
    if args.json:
        print_json({"table": str(args.table), "basis": args.basis, "component": component,
                    "wi": list(args.wi), "wo": list(args.wo), "f_r": f, **spectral})
    elif spectral:
        print(f"{args.table} ({component}, {args.basis}): f_r = {readable(f, 6)} 1/sr at "
              f"{channels_words(table)}; luminance (CIE Y, D65) "
              f"{readable(spectral['luminance'], 6)} 1/sr")
    else:
        print(f"{args.table} ({component}, {args.basis}): f_r = {readable(f, 6)} 1/sr")
    return 0
