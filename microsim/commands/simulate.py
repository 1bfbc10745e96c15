"""``microsim simulate RECIPE``: trace a recipe's surface and write its BRDF table."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from microsim import recipe
from microsim.cli import (
    add_json_arg,
    add_recipe_args,
    add_seed_arg,
    add_threads_arg,
    positive_int,
    print_json,
)
from microsim.errors import InputError


def add_tracing_args(p: argparse.ArgumentParser) -> None:
    """Flags shared by the commands that run the goniophotometer."""
    p.add_argument("--rays", type=positive_int, default=None,
                   help="rays per incident direction (overrides simulation.rays)")
    p.add_argument("--target-error", type=float, default=None, metavar="E",
                   help="adaptive stop: add batches until the median relative standard "
                        "error over lobe bins is <= E (0 < E <= 1), or --max-rays")
    p.add_argument("--max-rays", type=positive_int, default=None,
                   help="adaptive stop: at most this many rays per incident direction")
    add_threads_arg(p)
    add_seed_arg(p, "simulation")


def tracing_overrides(args: argparse.Namespace) -> list[str]:
    """``--set`` strings for the tracing flags that were given (validated by the schema)."""
    out = []
    for flag, key in (("rays", "rays"), ("target_error", "target_error"),
                      ("max_rays", "max_rays"), ("seed", "seed")):
        value = getattr(args, flag)
        if value is not None:
            out.append(f"simulation.{key}={value!r}")
    return out


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``simulate`` command."""
    p = sub.add_parser(
        "simulate",
        help="trace a recipe's microsurface and write its BRDF table (OpenEXR)",
        description="Build the recipe's periodic tile, trace it with Embree as a virtual "
                    "goniophotometer (every incident direction of simulation.theta_i, "
                    "degrees), and write the BRDF table with per-bin standard errors to an "
                    "OpenEXR file (docs/table-format.md), atomically.",
    )
    add_recipe_args(p)
    p.add_argument("-o", "--output", type=Path, default=None,
                   help="table file (default: tables/<recipe name>.exr)")
    add_tracing_args(p)
    add_json_arg(p)
    p.set_defaults(func=run)


def progress_printer(enabled: bool):
    """A goniometer progress callback printing one line per batch to stderr, or None."""
    if not enabled:
        return None

    def show(state: dict[str, Any]) -> None:
        err = state["rel_error"]
        err_text = "" if err is None else f", lobe error {100 * err:.2f}%"
        print(f"\rtheta_i {state['theta_i']:5.1f} deg: {state['rays']:>11,} rays{err_text}",
              end="", file=sys.stderr, flush=True)

    return show


def summary(table: Any, output: Path | None) -> dict[str, Any]:
    """The numbers ``simulate --json`` prints."""
    meta = table.meta
    return {
        "output": None if output is None else str(output),
        "theta_i": [d["theta_i"] for d in meta["directions"]],
        "phi_i": [d["phi_i"] for d in meta["directions"]],
        "rays": int(table.rays.sum()),
        "rays_per_direction": [d["rays"] for d in meta["directions"]],
        "segments": meta["segments"],
        "wall_s": meta["wall_time"],
        "segments_per_s": meta["segments_per_second"],
        "albedo": table.albedo.reshape(-1, 3),
        "albedo_err": table.albedo_err.reshape(-1, 3),
        "single_albedo": table.albedo_of["single"].reshape(-1, 3),
        "orders": table.orders,
        "order_albedo": {c: table.albedo_of[c].reshape(-1, 3) for c in table.components[1:]},
        "order_albedo_err": {c: table.albedo_err_of[c].reshape(-1, 3)
                             for c in table.components[1:]},
        "lost_energy": table.lost_energy.reshape(-1, 3),
        "median_rel_error": table.median_rel_error("total"),
        "sh_order": table.sh_order,
        "stop": [d["stop"] for d in meta["directions"]],
        "surface": meta["surface"],
    }


def print_summary(s: dict[str, Any]) -> None:
    """Aligned text for people."""
    orders = s["order_albedo"]
    print(f"{'theta_i':>8} {'phi_i':>6} {'rays':>11} {'albedo':>17} "
          + "".join(f"{c:>9}" for c in orders) + f" {'lost':>9}  stop")
    for k, theta in enumerate(s["theta_i"]):
        a, e = s["albedo"][k].mean(), s["albedo_err"][k].mean()
        print(f"{theta:8.1f} {s['phi_i'][k]:6.1f} {s['rays_per_direction'][k]:11,d} "
              f"{a:9.5f} ± {e:.5f} "
              + "".join(f"{v[k].mean():9.5f}" for v in orders.values())
              + f" {s['lost_energy'][k].mean():9.2e}  {s['stop'][k]}")
    surface = s["surface"]
    if "alpha_realised" in surface:
        print(f"surface: alpha target {surface['alpha_target']}, realised "
              f"{surface['alpha_realised']} (from facet slopes)")
    print(f"{s['rays']:,} rays, {s['segments']:,} segments in {s['wall_s']:.1f} s "
          f"({s['segments_per_s']:,.0f} segments/s); median relative error over lobe "
          f"bins {100 * s['median_rel_error']:.2f}%")
    if s["sh_order"]:
        print(f"spherical harmonics to order {s['sh_order']} stored beside the bins "
              "(microsim sh TABLE: their error against the bins)")
    if s["output"]:
        print(f"wrote {s['output']}")


def simulate_resolved(resolved: dict[str, Any], threads: int | None, show_progress: bool):
    """Build the tile (warnings to stderr) and run the goniophotometer."""
    from microsim.goniometer import simulate
    from microsim.surfaces import build_tile

    tile = build_tile(resolved["surface"])
    for warning in tile.warnings:
        print(f"warning: {warning}", file=sys.stderr)
    progress = progress_printer(show_progress)
    table = simulate(tile, resolved["material"], resolved["simulation"], resolved["table"],
                     recipe=resolved, threads=threads, progress=progress)
    if progress is not None:
        print(file=sys.stderr)
    return table


def run(args: argparse.Namespace) -> int:
    """Simulate, write the table, print the summary."""
    resolved = recipe.load(args.recipe, [*args.overrides, *tracing_overrides(args)])
    output = args.output or Path("tables") / (Path(args.recipe).stem + ".exr")
    if output.suffix.lower() != ".exr":
        raise InputError(f"--output {output}: must end in .exr (an OpenEXR table)")
    table = simulate_resolved(resolved, args.threads, sys.stderr.isatty() and not args.json)
    table.write(output)
    s = summary(table, output)
    print_json(s) if args.json else print_summary(s)
    return 0
