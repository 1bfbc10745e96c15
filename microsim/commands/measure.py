"""``microsim measure g1|ndf RECIPE``: masking and the facet-normal distribution of a tile."""

from __future__ import annotations

import argparse
import math
import sys
from typing import Any

from microsim import recipe
from microsim.commands.common import (
    Parser,
    add_json_arg,
    add_memory_arg,
    add_realisations_arg,
    add_recipe_args,
    add_seed_arg,
    add_threads_arg,
    error_model_note,
    flag_overrides,
    number_list,
    number_text,
    positive_int,
    print_json,
    roughness_text,
)
from microsim.errors import InputError
from microsim.files import PLOT_SUFFIXES, writable_file
from microsim.surfaces.facts import Roughness, SurfaceFacts

degree_list = number_list(low=0.0, high=90.0,
                          what="a comma-separated list of angles in [0, 90] degrees")


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``measure`` with its sub-commands ``g1`` and ``ndf``."""
    p = sub.add_parser(
        "measure", help="measure a tile's masking G1 or facet-normal distribution",
        description="Measure statistics of a recipe's microsurface and compare them with "
                    "the Beckmann/Smith model at the tile's realised roughness.")
    inner = p.add_subparsers(dest="measure_command", metavar="{g1,ndf}", required=True,
                             parser_class=Parser)
    g = inner.add_parser(
        "g1", help="masking G1 by tracing, against Smith at the realised alpha",
        description="Sample points on the tile with density proportional to area times "
                    "<w, n>+, trace towards w through the periodic tile, and report the "
                    "unoccluded fraction G1(theta), next to Smith's G1 (Beckmann, realised "
                    "alpha pooled over the tiles). Over several surface realisations the "
                    "standard error is the ensemble's (batch means); over one tile it is "
                    "binomial. Angles in degrees.")
    add_recipe_args(g)
    g.add_argument("--theta", type=degree_list, default=[0.0, 30.0, 60.0, 80.0, 89.0],
                   help="polar angles, degrees, comma-separated (default 0,30,60,80,89)")
    g.add_argument("--phi", type=float, default=0.0, help="azimuth, degrees (default 0)")
    g.add_argument("--rays", type=positive_int, default=100_000,
                   help="rays per angle over all realisations (default 100000)")
    add_realisations_arg(g)
    add_threads_arg(g)
    add_seed_arg(g, "simulation")
    add_memory_arg(g)
    add_json_arg(g)
    g.set_defaults(func=run_g1)
    n = inner.add_parser(
        "ndf", help="area-weighted histogram of facet normals, against Beckmann",
        description="The distribution of facet normals as an NDF normalised like the "
                    "analytic D (integral of D cos theta_h over the hemisphere = 1), per "
                    "theta_h bin, against Beckmann at the realised alpha (pooled over the "
                    "tiles). Over several surface realisations: their mean, with the "
                    "ensemble's standard errors; over one tile: errors from 4 x 4 "
                    "sub-tiles.")
    add_recipe_args(n)
    n.add_argument("--bins", type=positive_int, default=30, help="theta_h bins (default 30)")
    n.add_argument("--plot", default=None, metavar="PNG", help="also draw it")
    add_realisations_arg(n)
    add_seed_arg(n, "surface")
    add_memory_arg(n)
    add_json_arg(n)
    n.set_defaults(func=run_ndf)


def smith_model(facts: SurfaceFacts) -> Any:
    """Beckmann at the surface's realised roughness (None when it reports none)."""
    from microsim.analytic.ndf import Beckmann

    alpha = facts.alpha_realised
    return None if alpha is None else Beckmann(**alpha.params())


def roughness_json(facts: SurfaceFacts) -> dict[str, Any]:
    """The surface's realised roughness, its standard error and its target, as JSON."""

    def json_of(value: Roughness | None) -> Any:
        return None if value is None else value.to_json()

    return {"alpha_realised": json_of(facts.alpha_realised),
            "alpha_realised_stderr": json_of(facts.alpha_realised_stderr),
            "alpha_target": json_of(facts.tile.alpha_target)}


def run_g1(args: argparse.Namespace) -> int:
    """Trace G1 and print it next to Smith's."""
    import numpy as np

    from microsim.geometry import direction
    from microsim.measurement.masking import G1_BYTES_PER_RAY, measure_g1_recipe
    from microsim.memory import check_memory

    if not math.isfinite(args.phi):
        raise InputError(f"--phi {args.phi}: must be a finite angle in degrees")
    resolved = recipe.load(args.recipe, [*args.overrides, *flag_overrides(
        args, "simulation", "seed", "realisations")])
    inside = [part for part, m in resolved.material.items() if m.encloses_medium]
    if inside:
        print(f"warning: part {inside[0]!r} refracts: G1 samples every face, also those "
              "inside its medium (particles, substrate), so it is not the masking of the "
              "surface light meets first", file=sys.stderr)
    realisations = resolved.simulation.realisations_or_one
    per_tile = -(-args.rays // realisations)
    check_memory(G1_BYTES_PER_RAY * per_tile * len(args.theta), f"--rays {args.rays} at "
                 f"{len(args.theta)} angles over {realisations} realisations",
                 "use fewer rays", args.memory_limit)
    result = measure_g1_recipe(resolved, args.theta, args.rays, args.phi, args.threads,
                               args.memory_limit)
    info = result.surface
    model = smith_model(info)
    smith = None
    if model is not None:
        local_phi = math.radians(args.phi - (getattr(info.tile, "rotation_deg", None) or 0.0))
        smith = model.G1(direction(np.radians(args.theta), local_phi)).tolist()
    out = {"theta": result.theta_deg, "phi": result.phi_deg, "g1": result.g1,
           "g1_stderr": result.stderr, "g1_ray_stderr": result.ray_stderr,
           "dof": result.dof, "error_model": result.error_model,
           "realisations": result.realisations, "smith": smith, **roughness_json(info),
           "rays": result.rays, "seed": result.seed, "segments": result.segments,
           "wall_s": result.wall_time}
    if args.json:
        print_json(out)
        return 0
    print(f"{'theta':>6} {'G1':>9} {'stderr':>9} {'Smith':>9} {'diff/err':>9}")
    for k, theta in enumerate(out["theta"]):
        g, e = out["g1"][k], out["g1_stderr"][k]
        s = "" if smith is None else f"{smith[k]:9.5f}"
        # undefined where no spread was seen (one ray per realisation, G1 = 0 at 90°)
        z = "" if smith is None or e == 0 else number_text((g - smith[k]) / e, "9.2f")
        print(f"{theta:6.1f} {g:9.5f} {number_text(e, '9.5f')} {s:>9} {z:>9}")
    print(f"{roughness_text(info) or 'no roughness reported'}; {out['rays']:,} rays per "
          f"angle, {out['wall_s']:.1f} s")
    print(error_model_note(out["error_model"], out["realisations"])
          + (f"; diff/err is Student-t with {out['dof']:.0f} degrees of freedom"
             if out["error_model"] == "ensemble" else ""))
    return 0


def run_ndf(args: argparse.Namespace) -> int:
    """Histogram the facet normals and compare with Beckmann."""
    import numpy as np

    from microsim.analytic.ndf import Beckmann, ndf_bin_average
    from microsim.measurement.facets import measure_ndf_recipe

    resolved = recipe.load(args.recipe, [*args.overrides, *flag_overrides(args, "surface", "seed"),
                                         *flag_overrides(args, "simulation", "realisations")])
    if args.plot:
        writable_file(args.plot, "--plot", PLOT_SUFFIXES)
    m = measure_ndf_recipe(resolved, args.bins, args.memory_limit)
    info = m.surface
    alpha = info.alpha_realised
    iso = alpha.alpha if alpha is not None and alpha.isotropic else None
    model = None if iso is None else ndf_bin_average(Beckmann(iso), m.edges)
    centres = np.degrees(0.5 * (m.edges[1:] + m.edges[:-1]))
    out = {"theta_h": centres, "D": m.D, "stderr": m.stderr, "dof": m.dof,
           "error_model": m.error_model, "realisations": m.realisations,
           "beckmann": model, **roughness_json(info), "bins": args.bins}
    if args.plot:
        from microsim.plots import ndf_plot

        ndf_plot(centres, m.D, m.stderr, model, args.plot,
                 title=f"{resolved.surface.kind} surface, "
                       f"{roughness_text(info) or 'no roughness reported'}")
        out["plot"] = args.plot
    if args.json:
        print_json(out)
        return 0
    print(f"{'theta_h':>8} {'D':>11} {'stderr':>10} {'Beckmann':>11} {'ratio':>7}")
    for k, c in enumerate(centres):
        b = "" if model is None else f"{model[k]:11.5g}"
        r = "" if model is None or model[k] == 0 else f"{m.D[k] / model[k]:7.3f}"
        e = m.stderr[k]
        e_text = f"{e:10.3g}" if np.isfinite(e) else f"{'n/a':>10}"
        print(f"{c:8.2f} {m.D[k]:11.5g} {e_text} {b:>11} {r:>7}")
    print(roughness_text(info) or "no roughness reported: no Beckmann reference")
    print("errors: from 4 x 4 sub-tiles of one tile" if m.error_model != "ensemble"
          else error_model_note(m.error_model, m.realisations))
    return 0
