"""``microsim generate RECIPE -o tile.ply``: build a recipe's periodic tile and save it."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from microsim import recipe
from microsim.commands.common import (
    add_json_arg,
    add_memory_arg,
    add_recipe_args,
    add_seed_arg,
    flag_overrides,
    print_json,
    readable,
)
from microsim.files import atomic_path, writable_file

FORMATS = (".ply", ".obj")


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``generate`` command."""
    p = sub.add_parser(
        "generate", help="build a recipe's periodic tile and write it as PLY or OBJ",
        description="Build the recipe's periodic microsurface tile and write it (PLY keeps "
                    "each face's material id as the face property 'material'; OBJ has "
                    "geometry only), atomically. Prints the tile's facts: triangles, period, "
                    "height range, memory, and for Gaussian surfaces the target and "
                    "realised roughness.")
    add_recipe_args(p)
    p.add_argument("-o", "--output", type=Path, required=True,
                   help="mesh file, .ply or .obj")
    add_memory_arg(p)
    add_seed_arg(p, "surface")
    add_json_arg(p)
    p.set_defaults(func=run)


def tile_facts(tile: Any) -> dict[str, Any]:
    """What ``generate`` reports about a tile."""
    z0, z1 = tile.z_range
    facts = {"kind": tile.facts.kind, "triangles": len(tile.faces),
             "vertices": len(tile.vertices), "period": list(tile.period),
             "height_range": [z0, z1], "parts": list(tile.parts),
             "memory_bytes": int(tile.vertices.nbytes + tile.faces.nbytes
                                 + tile.material.nbytes)}
    # everything else the generator reports (realised roughness, paint fractions, ...)
    facts.update({k: v for k, v in tile.facts.to_json().items() if k not in facts})
    facts["warnings"] = list(tile.warnings)
    return facts


def write_mesh(tile: Any, path: Path) -> None:
    """Write the tile with trimesh, atomically (temporary file + rename)."""
    import numpy as np
    import trimesh

    mesh = trimesh.Trimesh(tile.vertices, tile.faces, process=False)
    if path.suffix.lower() == ".ply":
        mesh.face_attributes["material"] = np.asarray(tile.material, np.int32)
        data = trimesh.exchange.ply.export_ply(mesh, encoding="binary",
                                               include_attributes=True)
    else:
        data = trimesh.exchange.obj.export_obj(mesh).encode()
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def run(args: argparse.Namespace) -> int:
    """Build, write, report."""
    from microsim.surfaces import build_tile

    writable_file(args.output, "--output", FORMATS)
    resolved = recipe.load(args.recipe, [*args.overrides, *flag_overrides(args, "surface", "seed")])
    tile = build_tile(resolved.surface, args.memory_limit)
    for warning in tile.warnings:
        print(f"warning: {warning}", file=sys.stderr)
    write_mesh(tile, args.output)
    facts = {"output": str(args.output), **tile_facts(tile)}
    if args.json:
        print_json(facts)
        return 0
    for key, value in facts.items():
        if key != "warnings":
            print(f"{key:>20}: {readable(value)}")
    return 0
