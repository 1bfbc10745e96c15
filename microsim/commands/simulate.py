"""``microsim simulate RECIPE``: trace a recipe's surface and write its BRDF table."""

from __future__ import annotations

import argparse
import contextlib
import math
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from microsim import recipe
from microsim.commands.common import (
    add_json_arg,
    add_memory_arg,
    add_realisations_arg,
    add_recipe_args,
    add_seed_arg,
    add_threads_arg,
    channels_json,
    error_model_note,
    flag_overrides,
    positive_int,
    print_json,
    progress_display,
    roughness_text,
    wavelengths_words,
)
from microsim.files import writable_file
from microsim.memory import check_memory
from microsim.settings import Recipe
from microsim.surfaces.facts import SurfaceFacts
from microsim.tables.exr import write_table

if TYPE_CHECKING:
    from microsim.measurement.goniometer import Progress
    from microsim.tables.table import BRDFTable

TABLE_BYTES_PER_BIN = 450
"""Memory per table bin and incident direction while a table is estimated and written:
measured 407 B (512 x 1024 bins, 4 incidences, peak resident memory), rounded up."""
REALISATION_BYTES_PER_BIN_ROW = 48
"""Memory per table bin, incident direction, realisation and component row of the
per-realisation sums kept until the table is assembled (Σw and Σw², RGB float64)."""


def check_table_memory(resolved: Recipe, isotropic: bool, memory_limit_gib: float | None,
                       where: str = "") -> None:
    """Refuse (``InputError``) a table whose bins would need more memory than the budget:
    ``theta_bins`` x ``phi_bins`` per incident direction (every ``phi_i`` unless the
    surface is isotropic)."""
    table, simulation = resolved.table, resolved.simulation
    directions = len(simulation.theta_i) * (1 if isotropic else len(simulation.phi_i))
    bins = table.theta_bins * table.phi_bins
    realisations = simulation.realisations_or_one
    kept = REALISATION_BYTES_PER_BIN_ROW * (table.orders + 1) * realisations
    check_memory((TABLE_BYTES_PER_BIN + kept) * bins * directions,
                 f"{where}table: {bins:,} bins x {directions} incident directions x "
                 f"{realisations} realisations",
                 "use fewer bins, incidences or realisations", memory_limit_gib)


def add_tracing_args(p: argparse.ArgumentParser) -> None:
    """Flags shared by the commands that run the goniophotometer."""
    p.add_argument("--rays", type=positive_int, default=None,
                   help="rays per incident direction over all realisations (overrides "
                        "simulation.rays)")
    add_realisations_arg(p)
    p.add_argument("--target-error", type=float, default=None, metavar="E",
                   help="adaptive stop: add rays and realisations until the median "
                        "relative standard error over lobe bins (of the ensemble) is <= E "
                        "(1e-6 <= E <= 1), or --max-rays or --max-realisations")
    p.add_argument("--max-rays", type=positive_int, default=None,
                   help="adaptive stop: at most this many rays per incident direction")
    p.add_argument("--max-realisations", type=positive_int, default=None,
                   help="adaptive stop: at most this many realisations per incident "
                        "direction")
    add_threads_arg(p)
    add_seed_arg(p, "simulation")
    add_memory_arg(p)


TRACING_FLAGS = ("rays", "realisations", "target_error", "max_rays", "max_realisations",
                 "seed")
"""The flags of ``add_tracing_args`` that override the ``[simulation]`` key of their name."""


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


@contextlib.contextmanager
def progress_bar(enabled: bool) -> Iterator[Callable[[Progress], None] | None]:
    """A rich progress bar on stderr and its goniometer callback, or None: the
    realisation and incidence being traced, the share of the batches planned so far that
    are done, the time spent and what remains at the rate so far (an adaptive stop plans
    more batches as it goes, so its bar can step back)."""
    if not enabled:
        yield None
        return
    with progress_display() as bar:
        task = bar.add_task("simulating", total=None)

        def show(state: Progress) -> None:
            bar.update(task, total=state.batches_planned or None,
                       completed=state.batches_done,
                       description=f"realisation {state.realisation + 1} of "
                                   f"{state.realisations}, θi {state.theta_i:4.1f}°")

        yield show


def summary(table: Any, output: Path | None) -> dict[str, Any]:
    """The numbers ``simulate --json`` prints (a spectral table's with its ``channels`` and
    ``wavelengths``, which its per-channel lists follow)."""
    meta = table.meta
    count = table.channels.count
    return {
        "output": None if output is None else str(output),
        "theta_i": [d.theta_i for d in meta.directions],
        "phi_i": [d.phi_i for d in meta.directions],
        "rays": int(table.rays.sum()),
        "rays_per_direction": [d.rays for d in meta.directions],
        "segments": meta.segments,
        "wall_s": meta.timing.wall_time,
        "segments_per_s": meta.timing.segments_per_second,
        "albedo": table.albedo.reshape(-1, count),
        "albedo_err": table.albedo_err.reshape(-1, count),
        "single_albedo": table["single"].albedo.reshape(-1, count),
        "orders": table.orders,
        "order_albedo": {c: table[c].albedo.reshape(-1, count)
                         for c in table.components[1:]},
        "order_albedo_err": {c: table[c].albedo_err.reshape(-1, count)
                             for c in table.components[1:]},
        "lost_energy": table.lost_energy.reshape(-1, count),
        "median_rel_stderr": table.median_rel_stderr("total"),
        "sh_order": table.sh_order,
        "stop": [d.stop for d in meta.directions],
        "realisations_per_direction": [d.realisations for d in meta.directions],
        "ray_share": [d.ray_share for d in meta.directions],
        "error_model": table.error_model,
        "realisations": int(table.realisations.max()),
        "surface": meta.surface.to_json(),
        **channels_json(table),
    }


def print_summary(s: dict[str, Any]) -> None:
    """Aligned text for people."""
    orders = s["order_albedo"]
    print(f"{'theta_i':>8} {'phi_i':>6} {'rays':>11} {'tiles':>5} {'albedo':>17} "
          + "".join(f"{c:>9}" for c in orders) + f" {'lost':>9} {'ray share':>9}  stop")
    for k, theta in enumerate(s["theta_i"]):
        a, e = s["albedo"][k].mean(), s["albedo_err"][k].mean()
        # no escaping ray: the albedo is 0 and its standard error unknown
        e_text = f"{e:.5f}" if math.isfinite(e) else "n/a".ljust(7)
        print(f"{theta:8.1f} {s['phi_i'][k]:6.1f} {s['rays_per_direction'][k]:11,d} "
              f"{s['realisations_per_direction'][k]:5d} {a:9.5f} ± {e_text} "
              + "".join(f"{v[k].mean():9.5f}" for v in orders.values())
              + f" {s['lost_energy'][k].mean():9.2e} {_percent(s['ray_share'][k]):>9}  "
              f"{s['stop'][k]}")
    over = wavelengths_words(s.get("wavelengths"))
    print(f"(tiles: surface realisations averaged; albedo, orders and lost: means over "
          f"{over}, --json gives each; ray share: the rays' part of the variance of the "
          "lobe bins, the rest is the spread between tiles, above 100% where the tiles "
          "spread less than their rays' noise predicts, a ratio of two noisy variances)")
    roughness = roughness_text(SurfaceFacts.from_json(s["surface"]))
    if roughness:
        print(f"surface: {roughness}")
    print(error_model_note(s["error_model"], s["realisations"]))
    stderr = s["median_rel_stderr"]
    stderr_text = (f"{100 * stderr:.2f}%" if math.isfinite(stderr)
                   else "n/a (no lobe bin holds a ray)")
    print(f"{s['rays']:,} rays, {s['segments']:,} segments in {s['wall_s']:.1f} s "
          f"({s['segments_per_s']:,.0f} segments/s); median relative standard error over "
          f"lobe bins {stderr_text}")
    if s["sh_order"]:
        print(f"spherical harmonics to order {s['sh_order']} stored beside the bins "
              "(microsim sh TABLE: their error against the bins)")
    if s["output"]:
        print(f"wrote {s['output']}")


def _percent(x: float) -> str:
    """``x`` as a whole percentage, ``n/a`` where undefined (no lobe bin holds a ray)."""
    return f"{100 * x:.0f}%" if math.isfinite(x) else "n/a"


def simulate_resolved(resolved: Recipe, threads: int | None, show_progress: bool,
                      memory_limit_gib: float | None = None) -> BRDFTable:
    """Run the goniophotometer over the recipe's realisations, one tile at a time. The
    first tile is built beforehand for the memory guard and its warnings (to stderr); the
    others' warnings follow the run."""
    from microsim.measurement.simulation import simulate_recipe
    from microsim.surfaces import build_tile

    tile = build_tile(resolved.surface, memory_limit_gib)
    check_table_memory(resolved, tile.facts.isotropic, memory_limit_gib)
    first = list(tile.warnings)
    for warning in first:
        print(f"warning: {warning}", file=sys.stderr)
    del tile
    with progress_bar(show_progress) as progress:
        table = simulate_recipe(resolved, progress, threads, memory_limit_gib)
    later = [w for w in table.meta.tile_warnings if w not in first]
    for warning in [*later, *table.meta.warnings]:  # recorded in the table too
        print(f"warning: {warning}", file=sys.stderr)
    return table


def run(args: argparse.Namespace) -> int:
    """Simulate, write the table, print the summary."""
    resolved = recipe.load(args.recipe, [*args.overrides,
                                         *flag_overrides(args, "simulation", *TRACING_FLAGS)])
    output = writable_file(args.output or Path("tables") / (Path(args.recipe).stem + ".exr"),
                           "--output", (".exr",))
    table = simulate_resolved(resolved, args.threads, sys.stderr.isatty() and not args.json,
                              args.memory_limit)
    write_table(table, output)
    s = summary(table, output)
    print_json(s) if args.json else print_summary(s)
    return 0
