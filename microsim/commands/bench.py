"""``microsim bench``: speed against error on reference cases (docs/performance.md)."""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from microsim.commands.common import add_json_arg, add_seed_arg, print_json, progress_steps
from microsim.files import replaceable, writable_folder

if TYPE_CHECKING:
    from microsim.bench import Row


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``bench`` command."""
    p = sub.add_parser(
        "bench", help="speed against error on reference cases; CSV and plots",
        description="Run the reference cases (Torrance-Sparrow single scattering, Smith G1, "
                    "V-groove G1, white furnace, all orders against Heitz et al.'s multiple "
                    "scattering) over ray counts, tile resolutions and table "
                    "resolutions; time bare Embree on the same tiles; write bench.csv, "
                    "error_vs_time.png and bias_floor.png into --out. --quick takes about a "
                    "minute; the full sweep is timed in docs/performance.md.")
    p.add_argument("--quick", action="store_true", help="the small sweep (about a minute)")
    p.add_argument("--out", type=Path, default=Path("bench"), metavar="DIR",
                   help="output folder (default: bench)")
    add_seed_arg(p, "surface and simulation")
    add_json_arg(p)
    p.set_defaults(func=run)


def summary(rows: list[Row], wall: float) -> dict[str, Any]:
    """Best error per case and the speed ratio to bare Embree, as ``--json`` prints them
    (before the files written)."""
    cases: dict[str, Any] = {}
    for row in rows:
        c = cases.setdefault(row.case, {"runs": 0, "best_error": float("inf")})
        c["runs"] += 1
        c["best_error"] = min(c["best_error"], row.error)
    # traced tables at their largest ray count, where per-direction overheads weigh least
    most = max(r.rays for r in rows if r.case == "ts")
    ratios = [r.ratio for r in rows if r.case == "ts" and r.rays == most]
    return {"cases": cases, "ratio_to_bare_embree": statistics.median(ratios),
            "wall_s": wall}


def run(args: argparse.Namespace) -> int:
    """Sweep, write, summarise."""
    from microsim.bench import CSV, PLOTS, plot, sweep, write_csv

    writable_folder(args.out, "--out")
    for name in (CSV, *PLOTS):
        replaceable(args.out / name, "--out")
    start = time.perf_counter()
    with progress_steps("bench: tile resolutions", args.json) as show:
        rows = sweep(args.quick, seed=1 if args.seed is None else args.seed, progress=show)
    write_csv(rows, args.out / CSV)
    plots = plot(rows, args.out)
    result = {**summary(rows, time.perf_counter() - start),
              "csv": str(args.out / CSV), "plots": [str(p) for p in plots]}
    if args.json:
        print_json(result)
        return 0
    for case, c in result["cases"].items():
        print(f"{case:>8}: {c['runs']} runs, best error {c['best_error']:.4g}")
    print(f"simulate traces {result['ratio_to_bare_embree']:.2f}x the segments per second "
          f"of bare Embree on incoherent rays from the same tiles (median); "
          f"{result['wall_s']:.0f} s in all")
    print(f"wrote {result['csv']} and {', '.join(result['plots'])}")
    return 0
