"""``microsim demo``: simulate the shipped Gaussian surface and compare it with theory."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

import microsim
from microsim import recipe
from microsim.commands.common import (
    add_json_arg,
    add_memory_arg,
    add_seed_arg,
    add_threads_arg,
    channel_mean,
    error_model_note,
    flag_overrides,
    number_text,
    positive_int,
    print_json,
)
from microsim.commands.measure import roughness_json
from microsim.files import PLOT_SUFFIXES, writable_file
from microsim.schema import Value
from microsim.tables.exr import write_table

if TYPE_CHECKING:
    from microsim.comparison.agreement import Agreement
    from microsim.comparison.records import Comparison
    from microsim.tables.table import BRDFTable

RECIPE = Path(microsim.__file__).resolve().parent.parent / "surfaces" / "gaussian-0.3.toml"
SINGLE_MODEL = "torrance-sparrow:ndf=beckmann,shadowing=smith-correlated"
"""The single-scattering model of the demo, as a model spec."""
MS_SAMPLES = 64
"""Random walks per bin of the multiple-scattering reference in the demo: about a second
for the recipe's 4 incidences × 32 × 64 bins (docs/compare.md)."""


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``demo`` command."""
    p = sub.add_parser(
        "demo",
        help="simulate surfaces/gaussian-0.3.toml and compare with Torrance-Sparrow + Smith "
             "and with Heitz et al.'s multiple scattering",
        description="Simulate the shipped recipe surfaces/gaussian-0.3.toml (a Gaussian "
                    "height field, alpha = 0.3, mirror facets), write its table, and print "
                    "per incidence how far the simulated single scattering lies from "
                    "Torrance-Sparrow with a Beckmann NDF and height-correlated Smith "
                    "masking, and all orders from the multiple-scattering Smith "
                    "microsurface (beckmann-ms, Heitz et al. 2016; "
                    f"{MS_SAMPLES} random walks per bin), both at the surface's realised "
                    "roughness.",
    )
    p.add_argument("-o", "--output", type=Path, default=Path("tables") / "demo.exr",
                   help="table file (default: tables/demo.exr)")
    p.add_argument("--rays", type=positive_int, default=None,
                   help="rays per incident direction over all realisations (default: the "
                        "recipe's)")
    p.add_argument("--plot", type=Path, default=None, metavar="PNG",
                   help="also draw the plane of incidence, simulation against model")
    add_threads_arg(p)
    add_seed_arg(p, "simulation")
    add_memory_arg(p)
    add_json_arg(p)
    p.set_defaults(func=run)


def comparison(table: BRDFTable) -> tuple[str, dict[str, Value], Comparison, Agreement]:
    """Simulated single scattering against ``SINGLE_MODEL`` with the table's parameters
    (its realised alpha, its facets' Fresnel: ``microsim.comparison.table_models.model_defaults``):
    the model's name and parameters, the comparison and its verdict."""
    from microsim.analytic.registry import parse_model_spec
    from microsim.comparison.agreement import agreement
    from microsim.comparison.metrics import compare_table
    from microsim.comparison.table_models import model_defaults

    name, params, model = parse_model_spec(SINGLE_MODEL, model_defaults(table.meta))
    result = compare_table(table, model, "single")
    return name, params, result, agreement(result)


def sources_of(table: BRDFTable, spec: str, params: dict[str, Value]) -> dict[str, str]:
    """Where each of a model's parameters came from, as ``compare`` says it
    (``microsim.analytic.registry.parameter_sources``)."""
    from microsim.analytic.registry import parameter_sources
    from microsim.comparison.table_models import model_defaults

    return parameter_sources(spec, params, model_defaults(table.meta))


def total_comparison(table: BRDFTable
                     ) -> tuple[str, dict[str, Value], Comparison, Agreement]:
    """All simulated orders against the multiple-scattering Smith microsurface at the
    realised alpha (``MS_SAMPLES`` walks per bin, seeded with the table's seed): the
    model's spec and parameters, the comparison and its verdict."""
    from microsim.analytic.registry import parse_model_spec
    from microsim.comparison.agreement import agreement
    from microsim.comparison.metrics import compare_table
    from microsim.comparison.table_models import model_defaults

    spec = f"beckmann-ms:samples={MS_SAMPLES},seed={table.meta.seed}"
    _, params, model = parse_model_spec(spec, model_defaults(table.meta))
    result = compare_table(table, model, "total")
    return spec, params, result, agreement(result)


def run(args: argparse.Namespace) -> int:
    """Simulate, write, compare, print."""
    from microsim.analytic.registry import parameters_text
    from microsim.commands.simulate import print_summary, simulate_resolved, summary
    from microsim.comparison.agreement import verdict_text

    resolved = recipe.load(RECIPE, flag_overrides(args, "simulation", "seed", "rays"))
    writable_file(args.output, "--output", (".exr",))
    if args.plot is not None:
        writable_file(args.plot, "--plot", PLOT_SUFFIXES)
    table = simulate_resolved(resolved, args.threads, sys.stderr.isatty() and not args.json,
                              args.memory_limit)
    write_table(table, args.output)
    single_name, single_params, single, single_check = comparison(table)
    single_sources = sources_of(table, SINGLE_MODEL, single_params)
    roughness = roughness_json(table.meta.surface)
    simulated = summary(table, args.output)
    spec, params, total, total_check = total_comparison(table)
    sources = sources_of(table, spec, params)
    result = {"simulation": simulated,
              "comparison": {"model": SINGLE_MODEL, "params": single_params,
                             "param_sources": single_sources, **roughness,
                             **single.to_json(), "agreement": single_check.to_json()},
              "comparison_total": {"model": spec, "params": params, "param_sources": sources,
                                   **total.to_json(), "agreement": total_check.to_json()}}
    if args.plot is not None:
        from microsim.commands.compare import title_of
        from microsim.plots import incidence_plane

        incidence_plane(table, single.model, args.plot,
                        title=title_of(table, "Torrance-Sparrow + Smith", "single"))
        result["plot"] = str(args.plot)
    if args.json:
        print_json(result)
        return 0
    print_summary(simulated)
    print(f"\nBeckmann models at the realised alpha {roughness['alpha_realised']:.4f} "
          f"(target {roughness['alpha_target']:.4f}):")
    print(f"  single scattering against Torrance-Sparrow with height-correlated Smith "
          f"({SINGLE_MODEL}): "
          f"{parameters_text(single_name, single_params, single_sources)}")
    print(f"  all orders against Heitz et al. 2016's multiple scattering ({spec}): "
          f"{parameters_text(spec.partition(':')[0], params, sources)}")
    print(f"{'':8} {'single vs Torrance-Sparrow':^40}   "
          f"{'all orders vs multiple-scattering Smith':^48}")
    print(f"{'theta_i':>8} {'median err':>11} {'z mean':>7} {'z std':>6} {'albedo sim':>11} "
          f"{'model':>7}   {'median err':>11} {'z mean':>7} {'z std':>6} {'albedo sim':>11} "
          f"{'model':>16}")
    for r, q in zip(single.per_theta_i, total.per_theta_i, strict=True):
        print(f"{r.theta_i:8.1f} {number_text(r.median_rel_error, '10.2f', 100, '%')} "
              f"{number_text(r.z_mean, '7.2f')} {number_text(r.z_std, '6.2f')} "
              f"{channel_mean(r.albedo_sim):11.4f} {channel_mean(r.albedo_model):7.4f}   "
              f"{number_text(q.median_rel_error, '10.2f', 100, '%')} "
              f"{number_text(q.z_mean, '7.2f')} {number_text(q.z_std, '6.2f')} "
              f"{channel_mean(q.albedo_sim):11.4f} "
              f"{channel_mean(q.albedo_model):9.4f} ± {channel_mean(q.albedo_model_err):.4f}")
    print("(err: relative error against the model, |sim - model| / model, over lobe bins "
          "where the model reaches 10% of its peak; z = (sim - model) / stderr, standard "
          f"normal if the two differ by noise alone, the model's own Monte Carlo error "
          f"({MS_SAMPLES} walks per bin) included; Torrance-Sparrow leaves out the light "
          "scattered more than once, the multiple-scattering model holds it; albedos: "
          "means over R, G and B, --json gives each)")
    print(verdict_text(single, single_check, "single scattering vs Torrance-Sparrow"))
    print(verdict_text(total, total_check, "all orders vs multiple-scattering Smith"))
    print(error_model_note(single.error_model, single.realisations))
    if "plot" in result:
        print(f"wrote {result['plot']}")
    return 0
