"""``microsim compare TABLE --model SPEC``: a simulated table against an analytic model."""

from __future__ import annotations

import argparse
import sys
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
    number_text,
    print_json,
    progress_steps,
    readable,
    table_component,
)
from microsim.files import atomic_path, replaceable, writable_folder

if TYPE_CHECKING:
    from microsim.comparison.agreement import Agreement
    from microsim.comparison.records import Comparison, IncidenceMetrics

REPORT = "report.md"
"""The report ``--out`` writes beside the figures."""
PLOTS = {
    "incidence_plane": "incidence-plane.png",
    "half_difference": "half-difference.png",
    "z_maps": "z-maps.png",
    "albedo": "albedo.png",
}


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``compare`` command."""
    p = sub.add_parser(
        "compare", help="compare a BRDF table with an analytic model: metrics and plots",
        description="Compare a simulated table with an analytic model. SPEC is NAME or "
                    "NAME:key=value,... (microsim models lists them; angles in degrees); "
                    "parameters it leaves out come from the table: the surface's realised "
                    "roughness, and the facets' Fresnel or albedo. Prints per-incidence "
                    "and overall metrics; with --out writes plots and report.md.")
    p.add_argument("table", metavar="TABLE", help="table file (.exr) from microsim simulate")
    p.add_argument("--model", required=True, metavar="SPEC",
                   help="analytic model, e.g. beckmann or beckmann:alpha=0.31")
    add_component_arg(p)
    p.add_argument("--out", type=Path, default=None, metavar="DIR",
                   help="write plots and report.md into DIR")
    add_memory_arg(p)
    add_json_arg(p)
    p.set_defaults(func=run)


def title_of(table: Any, name: str, component: str) -> str:
    """Surface, material, realised alpha, rays (their range where the directions differ)
    and the component against the model ``name``, for figure titles."""
    from microsim.plots.layout import component_text, rays_text

    meta = table.meta
    materials = set() if meta.recipe is None else {m.kind for m in meta.recipe.material.values()}
    alpha = None if meta.surface is None else meta.surface.alpha_realised
    kind = meta.surface.tile.kind if meta.surface is not None and meta.surface.tile.kind \
        else "surface"
    alpha_text = "" if alpha is None else f", α realised {readable(alpha.to_json(), 3)}"
    facets = f", {'/'.join(sorted(materials))} facets" if materials else ""
    return (f"{kind}{facets}{alpha_text}, {rays_text(table)}; "
            f"{component_text(component)} vs {name}")


def model_albedo(row: IncidenceMetrics) -> str:
    """The model's albedo (mean over the channels: R, G, B or the wavelengths), with its
    standard error if it has one."""
    value, err = channel_mean(row.albedo_model), channel_mean(row.albedo_model_err)
    return f"{value:.4f} ± {err:.4f}" if err > 0 else f"{value:.4f}"


def channel_albedos(names: tuple[str, ...], result: Comparison) -> list[str]:
    """``report.md``'s table of every channel's albedo per incidence, simulated / model
    (a spectral table's: one column per wavelength)."""
    lines = ["| θi (°) | φi (°) | " + " | ".join(names) + " |",
             "| --- | --- | " + " | ".join("---" for _ in names) + " |"]
    for r in result.per_theta_i:
        cells = [f"{s:.4f} / {m:.4f}" for s, m in zip(r.albedo_sim, r.albedo_model,
                                                      strict=True)]
        lines.append(f"| {r.theta_i:.1f} | {r.phi_i:.1f} | " + " | ".join(cells) + " |")
    return lines


def write_report(out: Path, title: str, model: str, params: str,
                 component: str, result: Comparison, check: Agreement,
                 table: Any = None) -> Path:
    """``report.md``: the metrics table and every plot, in one page.

    Parameters
    ----------
    out : Path
        The folder of the plots.
    title : str
    model : str
        The model's name.
    params : str
        Its parameters with their units and sources (``parameters_text``).
    component : str
        The table's component compared.
    result : Comparison
    check : Agreement
        ``result``'s verdict.
    table : BRDFTable or None
        The table compared: a spectral table's report names its wavelengths, says that
        the albedo columns are means over them and adds every wavelength's albedo; an
        RGB table's (or None's) says they are means over R, G and B.

    Returns
    -------
    Path
        ``out / "report.md"``.
    """
    from microsim.comparison.agreement import verdict_text

    lines = [f"# {title}", "", f"Model: `{model}` with parameters "
             f"{params} (component: {component}).", "",
             f"Overall: median relative error against the model "
             f"{number_text(result.median_rel_error, '.2f', 100, '%')} (p90 "
             f"{number_text(result.p90_rel_error, '.2f', 100, '%')}) "
             f"over lobe bins; {verdict_text(result, check)} (a Monte Carlo "
             "model's own error is part of stderr).", "",
             error_model_note(result.error_model, result.realisations) + ".", ""]
    spectral = table is not None and table.channels.spectral
    if spectral:
        names = table.channels.names
        lines += [f"Channels: {channels_words(table)}, {', '.join(names)}; the albedo "
                  f"columns are means over {channels_words(table)}, each wavelength's "
                  "albedo is in the last table; the figures show luminance (CIE Y, D65) "
                  "and the colour of the albedo's spectrum (sRGB under D65).", ""]
    else:
        lines += ["Channels: R, G and B; the albedo columns are means over them (the "
                  "command's --json gives each); the figures show luminance.", ""]
    lines += ["| θi (°) | φi (°) | median err | p90 err | RMS (1/sr) | z mean | z std | "
             "albedo sim | albedo model | multiple scattering |",
             "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for r in result.per_theta_i:
        lines.append(
            f"| {r.theta_i:.1f} | {r.phi_i:.1f} | "
            f"{number_text(r.median_rel_error, '.2f', 100, '%')} | "
            f"{number_text(r.p90_rel_error, '.2f', 100, '%')} | "
            f"{number_text(r.rms_error, '.4g')} | {number_text(r.z_mean, '.2f')} | "
            f"{number_text(r.z_std, '.2f')} | {channel_mean(r.albedo_sim):.4f} | "
            f"{model_albedo(r)} | "
            f"{number_text(r.multiple_scattering_share, '.2f', 100, '%')} |")
    captions = {
        "incidence_plane": "Plane of incidence: simulation (±1 standard error) and model.",
        "half_difference": "θh–θd slices at φd = 90°: simulation, model, log ratio.",
        "z_maps": "z = (simulation − model) / standard error over the outgoing bins.",
        "albedo": "Albedo against θi: all orders, single scattering, model.",
    }
    if spectral:
        captions["albedo"] = ("Albedo against wavelength per θi (simulation with its ±1 "
                              "standard error band, model dashed), and its luminance "
                              "(CIE Y, D65) against θi: all orders, single scattering, "
                              "model.")
    for key, name in PLOTS.items():
        lines += ["", f"## {captions[key]}", "", f"![{key}]({name})"]
    if spectral:
        lines += ["", f"## Albedo per wavelength ({component}): simulated / model", "",
                  *channel_albedos(table.channels.names, result)]
    path = out / REPORT
    with atomic_path(path) as tmp:
        tmp.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def run(args: argparse.Namespace) -> int:
    """Compare, print, and draw."""
    import microsim
    from microsim.analytic.registry import parameter_sources, parameters_text, parse_model_spec
    from microsim.comparison.agreement import agreement, verdict_text
    from microsim.comparison.metrics import check_model_channels, compare_table, model_for
    from microsim.comparison.table_models import table_defaults
    from microsim.plots import albedo_plot, half_difference_slices, incidence_plane, z_maps

    table = microsim.read_table(args.table)
    for warning in table.meta.warnings:
        print(f"warning: {args.table}: {warning}", file=sys.stderr)
    args.component = table_component(table, args.component, args.table)
    defaults = table_defaults(table, args.component)
    check_model_channels(args.model, defaults, table.channels)
    name, params, model = parse_model_spec(args.model, defaults)
    sources = parameter_sources(args.model, params, defaults)
    if args.out is not None:
        writable_folder(args.out, "--out")
        for file in (*PLOTS.values(), REPORT):
            replaceable(args.out / file, "--out")
    with progress_steps(f"{name}: bin averages per incidence", args.json) as show:
        compared = compare_table(table, model, args.component, show)
    check = agreement(compared)
    result = {"model": name, "params": params, "param_sources": sources,
              "component": args.component, "table": str(args.table),
              **channels_json(table), **compared.to_json(), "agreement": check.to_json()}
    if args.out is not None:
        title = title_of(table, name, args.component)
        incidence_plane(table, compared.model, args.out / PLOTS["incidence_plane"],
                        args.component, title)
        if table.isotropic:
            half_difference_slices(table, model_for(model, args.component),
                                   args.out / PLOTS["half_difference"],
                                   args.component, title)
        z_maps(table, compared.model, args.out / PLOTS["z_maps"], args.component, title,
               compared.model_err)
        albedo_plot(table, compared.model, args.out / PLOTS["albedo"], title, args.component)
        result["report"] = str(write_report(args.out, title, name,
                                            parameters_text(name, params, sources),
                                            args.component,
                                            compared, check, table))
    if args.json:
        print_json(result)
        return 0
    print(f"{args.component} of {args.table} vs {name}: {parameters_text(name, params, sources)}")
    print(f"channels: {channels_words(table)}; the albedos are means over them "
          "(--json gives each)")
    print(f"{'theta_i':>8} {'phi_i':>6} {'median err':>11} {'p90 err':>8} {'z mean':>7} "
          f"{'z std':>6} {'albedo sim':>11} {'model':>16} {'multiple':>9}")
    for r in compared.per_theta_i:
        print(f"{r.theta_i:8.1f} {r.phi_i:6.1f} "
              f"{number_text(r.median_rel_error, '10.2f', 100, '%')} "
              f"{number_text(r.p90_rel_error, '7.2f', 100, '%')} "
              f"{number_text(r.z_mean, '7.2f')} {number_text(r.z_std, '6.2f')} "
              f"{channel_mean(r.albedo_sim):11.4f} {model_albedo(r):>16} "
              f"{number_text(r.multiple_scattering_share, '8.2f', 100, '%')}")
    print(f"overall: median relative error against the model "
          f"{number_text(compared.median_rel_error, '.2f', 100, '%')} (err: |sim - model| "
          f"/ model over lobe bins), z mean {number_text(compared.z_mean, '.2f')}, z std "
          f"{number_text(compared.z_std, '.2f')}")
    print(verdict_text(compared, check))
    print(error_model_note(compared.error_model, compared.realisations))
    if "report" in result:
        print(f"wrote {result['report']}")
    return 0
