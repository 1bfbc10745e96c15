"""``microsim fit TABLE --model NAME``: fit an analytic model to a simulated table."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from microsim.commands.common import (
    add_component_arg,
    add_json_arg,
    add_memory_arg,
    channel_mean,
    channels_json,
    channels_words,
    error_model_note,
    print_json,
    roughness_text,
    table_component,
    with_error,
)

if TYPE_CHECKING:
    from microsim.comparison.fit import FitProgress


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``fit`` command."""
    p = sub.add_parser(
        "fit", help="fit beckmann, ggx, oren-nayar, lafortune[:K], phong, kay-kajiya or "
                    "microcylinder to a table",
        description="Fit an analytic model's parameters to a BRDF table by weighted least "
                    "squares in log space, using the per-bin standard errors (bins without "
                    "an error are skipped); see microsim/comparison/fit.py and docs/compare.md. "
                    "Prints "
                    "the parameters with 1-sigma uncertainties, chi^2/dof, the median "
                    "relative error and the albedo of fit and table per incidence.")
    p.add_argument("table", metavar="TABLE", help="table file (.exr)")
    p.add_argument("--model", required=True, metavar="NAME",
                   help="beckmann, ggx (alpha and Schlick F0 per channel: R, G, B, or "
                        "each wavelength of a spectral table), oren-nayar "
                        "(sigma in radians, albedo per channel), phong (n, ks per channel), "
                        "lafortune[:K] (K isotropic lobes: Cxy, Cz, n), kay-kajiya (kd, ks "
                        "per channel, n; the fibre axis and coverage from the table), "
                        "microcylinder (cloth: coverages, eta, lobe widths in radians, kd, "
                        "albedo per yarn family and channel)")
    add_component_arg(p)
    p.add_argument("--plot", type=Path, default=None, metavar="PNG",
                   help="draw the plane of incidence, table against the fit")
    add_memory_arg(p)
    add_json_arg(p)
    p.set_defaults(func=run)


def progress_printer(enabled: bool) -> Callable[[FitProgress], None] | None:
    """A ``fit_table`` progress callback rewriting one line on stderr, or None."""
    if not enabled:
        return None

    def show(state: FitProgress) -> None:
        print(f"\rfitting: {state.evaluations:4d} evaluations of the model over the "
              f"table, chi^2/dof {state.chi2_dof:.4g}   ", end="", file=sys.stderr,
              flush=True)

    return show


def run(args: argparse.Namespace) -> int:
    """Fit and report."""
    import microsim
    from microsim.analytic.registry import parameter_units, parameters_text
    from microsim.comparison.fit import family, fit_table
    from microsim.files import PLOT_SUFFIXES, writable_file

    family(args.model)  # a bad name fails before the table is read
    if args.plot is not None:
        writable_file(args.plot, "--plot", PLOT_SUFFIXES)
    table = microsim.read_table(args.table)
    args.component = table_component(table, args.component, args.table)
    show = sys.stderr.isatty() and not args.json
    result = fit_table(table, args.model, args.component, progress=progress_printer(show))
    if show:
        print(file=sys.stderr)
    surface = table.meta.surface
    alpha = None if surface is None else surface.alpha_realised
    out: dict[str, Any] = {**result.to_json(), "error_model": table.error_model,
                           "realisations": int(table.realisations.max()),
                           "alpha_realised": None if alpha is None else alpha.to_json(),
                           "units": parameter_units(result.model), **channels_json(table)}
    if args.plot is not None:
        from microsim.commands.compare import title_of
        from microsim.plots import incidence_plane

        incidence_plane(table, result.model_bins, args.plot, args.component,
                        f"{args.table}: " + title_of(table, f"fitted {result.model}",
                                                     args.component),
                        model_label=f"fit: {result.model}")
        out["plot"] = str(args.plot)
    if args.json:
        print_json(out)
        return 0
    print(f"{result.model} fitted to the {args.component} of {args.table}:")
    for name, value in result.params.items():
        print(f"  {name:>10} = {with_error(value, result.uncertainty[name])}"
              f"{out['units'].get(name, '')}")
    if result.held:
        print("  held: " + parameters_text(result.model.partition(":")[0], result.held,
                                           result.held_sources))
    print(f"  chi^2/dof {result.chi2_dof:.3g}, median relative error against the fit "
          "over lobe bins "
          f"{100 * result.median_rel_error:.2f}%")
    for row in result.per_theta_i:
        print(f"  theta_i {row.theta_i:5.1f}, phi_i {row.phi_i:5.1f}: albedo fit "
              f"{channel_mean(row.albedo_fit.tolist()):.4f}, "
              f"table {channel_mean(row.albedo_table.tolist()):.4f}")
    print(f"  (albedos: means over {channels_words(table)}; --json gives each)")
    roughness = "" if surface is None else roughness_text(surface)
    if roughness:
        print(f"  surface: {roughness}")
    print("  " + error_model_note(table.error_model, out["realisations"],
                                  "chi^2 and the parameter uncertainties"))
    return 0
