"""``microsim render TABLE [TABLE ...] -o PNG``: tables on an object, rendered by Mitsuba 3."""

from __future__ import annotations

import argparse
import contextlib
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from microsim.commands.common import (
    add_component_arg,
    add_json_arg,
    add_memory_arg,
    add_realisations_arg,
    bounded_int,
    finite_float,
    number_list,
    number_text,
    progress_display,
    table_component,
)
from microsim.errors import InputError
from microsim.files import writable_file

DEFAULT_SPP = 64
MAX_SPP = 1 << 16
"""Most samples per pixel: a 320 x 240 image at 2^16 is 5e9 samples, hours of CPU (and
Mitsuba's sample count is 32-bit)."""
MAX_SEED = 2**32 - 2
"""Largest ``--seed``: Mitsuba's sampler seed is a 32-bit unsigned integer, and a row's
second render (the model's, the live surface's) takes seed + 1."""

LIVE_LIGHTS = ("sun:elevation=50,azimuth=-40,irradiance=3,radius=20", "sky:radiance=0.25")
"""``--live``'s default light: the default sun as a disc of 20° radius (a sampled-only
BSDF cannot see a directional light) and the sky."""


def size(text: str) -> tuple[int, int]:
    """argparse type: ``WIDTHxHEIGHT`` in pixels, each 8 … 4096."""
    w, x, h = text.lower().partition("x")
    try:
        dims = (int(w), int(h)) if x else None
    except ValueError:
        dims = None
    if dims is None or not all(8 <= d <= 4096 for d in dims):
        raise argparse.ArgumentTypeError(f"{text!r} is not WIDTHxHEIGHT (8 to 4096 pixels "
                                         "each), e.g. 320x240")
    return dims


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``render`` command."""
    from microsim.render.backend import VARIANTS
    from microsim.render.scene import DEFAULT_LIGHTS, LIGHTS

    p = sub.add_parser(
        "render", help="render tables on a torus, sphere, draped sheet or mesh (Mitsuba 3)",
        description="Render each table on an object with Mitsuba 3 and write a labelled "
                    "PNG grid. The table's +x axis follows the object's tangent (torus: "
                    "the major circle; sphere: the parallels; sheet: its x axis; mesh: "
                    "circles about the vertical). With --model, each row shows the table, "
                    "the analytic model and their relative difference. Needs Mitsuba 3: "
                    "pip install 'microsim[render]'. Angles in degrees. See docs/render.md.")
    p.add_argument("tables", nargs="+", metavar="TABLE",
                   help="table files (.exr); with --live, one RECIPE (.toml)")
    p.add_argument("-o", "--output", type=Path, required=True, help="PNG file to write")
    p.add_argument("--object", default="torus", metavar="OBJECT",
                   help="torus (default), sphere, sheet, or a mesh file (.ply, .obj, .stl, "
                        "...; +z up)")
    p.add_argument("--light", action="append", default=None, metavar="KIND:KEY=VALUE,...",
                   help="repeatable; kinds: " + ", ".join(
                       f"{k} ({', '.join(v)})" for k, v in LIGHTS.items())
                   + f"; default: {' and '.join(DEFAULT_LIGHTS)} (sun angles in degrees, "
                     "azimuth 0 = from behind the camera)")
    p.add_argument("--spp", type=bounded_int(1, MAX_SPP, "hours of CPU at the top"),
                   default=DEFAULT_SPP,
                   help=f"samples per pixel (default {DEFAULT_SPP}, at most {MAX_SPP})")
    p.add_argument("--size", type=size, default=(320, 240), metavar="WxH",
                   help="image size in pixels (default 320x240)")
    p.add_argument("--camera", type=number_list(2, -360.0, 360.0,
                                                what="ELEVATION,AZIMUTH in degrees"),
                   default=[30.0, -90.0], metavar="ELEV,AZIM",
                   help="camera elevation above the horizon and azimuth about +z, degrees "
                        "(default 30,-90: from -y)")
    p.add_argument("--fov", type=number_list(1, 1.0, 120.0, what="a field of view of 1 to "
                                             "120 degrees"),
                   default=[30.0], metavar="DEG",
                   help="field of view across the shorter side, degrees (default 30)")
    p.add_argument("--rotate", type=finite_float, default=0.0, metavar="DEG",
                   help="turn the material about the normal by DEG degrees, from the "
                        "tangent towards the bitangent (default 0)")
    add_component_arg(p)
    p.add_argument("--model", action="append", default=None, metavar="SPEC",
                   help="also render an analytic model (microsim models lists them; a "
                        "Monte Carlo one, beckmann-ms or ggx-ms, in an llvm variant only), "
                        "its missing parameters from each table, and the relative difference; "
                        "once for every table, or once per table in their order")
    p.add_argument("--seed", type=bounded_int(0, MAX_SEED, "Mitsuba's seeds are 32-bit, "
                                                 "and the model's render takes seed + 1"),
                   default=0, help=f"sampler seed (default 0, at most {MAX_SEED})")
    p.add_argument("--variant", default="scalar_rgb", choices=VARIANTS,
                   help="Mitsuba variant (default scalar_rgb; llvm_* need LLVM >= 16). "
                        "*_spectral render wavelengths: a spectral table (and its model) "
                        "per wavelength, an RGB one upsampled as Mitsuba upsamples RGB; an "
                        "RGB variant renders a spectral table's linear sRGB")
    p.add_argument("--live", action="store_true",
                   help="render RECIPE's microgeometry itself, each BSDF sample a path "
                        "traced through its tile, beside the render of its table and the "
                        "difference (docs/render.md, simulation at render time)")
    p.add_argument("--table", type=Path, default=None, metavar="TABLE",
                   help="with --live: the table to compare with (default: simulate the "
                        "recipe first)")
    add_realisations_arg(p)
    p.add_argument("--set", dest="overrides", action="append", default=[],
                   metavar="SECTION.KEY=VALUE",
                   help="with --live: override a value of RECIPE (repeatable), e.g. --set "
                        "'simulation.theta_i=[0,10,20,30,40,50,60,70,80,89]' for the "
                        "table's incidences")
    add_memory_arg(p)
    add_json_arg(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Render every table (and model), write the grid, report times and differences."""
    import microsim
    from microsim.analytic.registry import parameter_sources, parameters_text, parse_model_spec
    from microsim.commands.common import print_json
    from microsim.comparison.table_models import table_defaults
    from microsim.render import backend, bsdfs, figure, objects, scene, spectral

    writable_file(args.output, "--output", (".png",))
    if args.live:
        return run_live(args)
    for flag, given in (("--table", args.table), ("--realisations", args.realisations),
                        ("--set", args.overrides)):
        if given not in (None, []):
            raise InputError(f"{flag}: only with --live")
    for path in args.tables:
        if not Path(path).is_file():
            raise InputError(f"TABLE {path}: no such file")
    lights = [scene.parse_light(s) for s in (args.light or scene.DEFAULT_LIGHTS)]
    surface = objects.load_object(args.object)
    tables = [microsim.read_table(path) for path in args.tables]
    components = [table_component(t, args.component, path)
                  for t, path in zip(tables, args.tables, strict=True)]
    specs = args.model or []
    if len(specs) not in (0, 1, len(tables)):
        raise InputError(f"--model: given {len(specs)} times; give it once, or once per "
                         f"table ({len(tables)})")
    specs = [specs[min(k, len(specs) - 1)] for k in range(len(tables))] if specs else []
    defaults = [table_defaults(t, c) for t, c in zip(tables, components, strict=True)]
    models = [parse_model_spec(spec, d) for spec, d in zip(specs, defaults, strict=False)]
    for k, (name, _, model) in enumerate(models):
        bsdfs.model_channels(model, tables[k].channels.wavelengths,
                             f"--model {specs[k]} (for {args.tables[k]})")
        if args.variant.startswith("scalar") and hasattr(model, "random_bin_average"):
            # tabulated, its walks would run at every vertex of the tensor (docs/render.md)
            raise InputError(
                f"--model {specs[k]}: a Monte Carlo model is not rendered in {args.variant}: "
                f"tabulated, its {model.samples:,} walks would run at each of the tensor's "
                f"{bsdfs.tensor_pairs(True):,} (isotropic) to {bsdfs.tensor_pairs(False):,} "
                "direction pairs (minutes) and freeze their noise into the image; use "
                f"--variant {args.variant.replace('scalar', 'llvm_ad')} (walks at each "
                f"shading point), --model {name.removesuffix('-ms')} (its single "
                f"scattering, exact) or microsim compare {args.tables[k]} --model {specs[k]}")
    mi = backend.load(args.variant)
    camera = scene.Camera(args.size[0], args.size[1], args.camera[0], args.camera[1],
                          args.fov[0])
    rows, report = [], []
    with tempfile.TemporaryDirectory() as tmp, progress_bar(
            sys.stderr.isatty() and not args.json) as track:
        for k, (path, table) in enumerate(zip(args.tables, tables, strict=True)):
            label = Path(path).stem
            bsdf = bsdfs.table_bsdf(mi, table, Path(tmp) / f"{k}.bsdf", components[k],
                                    args.rotate)
            image = scene.render(mi, surface, bsdf, camera, lights, args.spp, args.seed,
                                 track(f"rendering {label}"))
            entry: dict[str, Any] = {"table": str(path), "seconds": image.seconds,
                                     "noise": _noise(image),
                                     "channels": _channels(table),
                                     "rendered_as": spectral.conversion(
                                         mi, table.channels.wavelengths)}
            panels = [("table" if models else label, figure.display(image))]
            if models:
                name, params, model = models[k]
                # one Python call per direction pair in scalar variants takes minutes:
                # there the model is tabulated like a table (docs/render.md)
                tabulate = Path(tmp) / f"model{k}.bsdf" if args.variant.startswith(
                    "scalar") else None
                bsdf, how = bsdfs.model_bsdf(mi, model, args.rotate, tabulate,
                                             table.channels.wavelengths)
                other = scene.render(mi, surface, bsdf, camera, lights, args.spp,
                                     args.seed + 1, track(f"rendering {name}"))
                diff = figure.difference(image, other)
                sources = parameter_sources(specs[k], params, defaults[k])
                entry.update(model=name, params=params, param_sources=sources,
                             params_text=parameters_text(name, params, sources), mitsuba=how,
                             model_seconds=other.seconds, difference={
                                 "median_abs": diff.median_abs,
                                 "median_abs_noise_alone": diff.median_noise,
                                 "mean": diff.mean, "pixels": diff.pixels})
                panels += [(f"{name} ({how})", figure.display(other)),
                           (f"median |Δ| {100 * diff.median_abs:.1f}% "
                            f"(noise {100 * diff.median_noise:.1f}%)", diff.relative)]
            rows.append(figure.Row(label, panels))
            report.append(entry)
    figure.write_grid(rows, args.output)
    result = {"output": str(args.output), "object": surface.name, "spp": args.spp,
              "size": list(args.size), "variant": args.variant, "rotate": args.rotate,
              "lights": [light.to_json() for light in lights], "tables": report}
    if args.json:
        print_json(result)
        return 0
    for entry in report:
        line = (f"{entry['table']}: {entry['channels']} as {entry['rendered_as']}, "
                f"{entry['seconds']:.2f} s, per-pixel noise "
                f"{number_text(entry['noise'], '.1f', 100, '%')} (median)")
        if "model" in entry:
            d = entry["difference"]
            line += (f"; {entry['model']} ({entry['params_text']}) via {entry['mitsuba']} "
                     f"{entry['model_seconds']:.2f}"
                     f" s; relative difference median "
                     f"{number_text(d['median_abs'], '.1f', 100, '%')} (noise alone "
                     f"{number_text(d['median_abs_noise_alone'], '.1f', 100, '%')}), mean "
                     f"{number_text(d['mean'], '+.1f', 100, '%')} over {d['pixels']} "
                     "pixels")
        print(line)
    print(f"wrote {args.output} ({args.size[0]}x{args.size[1]}, {args.spp} spp, "
          f"{surface.name})")
    return 0


def run_live(args: argparse.Namespace) -> int:
    """``render RECIPE --live``: the recipe's microgeometry traced at render time beside
    its table's render, and their difference with its standard error."""
    import microsim
    from microsim import recipe
    from microsim.commands.common import flag_overrides, print_json
    from microsim.commands.simulate import simulate_resolved
    from microsim.measurement.simulation import Tiles
    from microsim.render import backend, bsdfs, figure, live, objects, scene

    if len(args.tables) != 1 or Path(args.tables[0]).suffix.lower() != ".toml":
        raise InputError("--live: give one RECIPE (.toml), not tables")
    for flag, given in (("--model", args.model),
                        ("--component", None if args.component == "total" else 1)):
        if given:
            raise InputError(f"{flag}: not with --live (the live surface is every "
                             "scattering order, compared with the table's total)")
    if args.table is not None and not args.table.is_file():
        raise InputError(f"--table {args.table}: no such file")
    resolved = recipe.load(args.tables[0], [*args.overrides, *flag_overrides(
        args, "simulation", "realisations")])
    if args.variant in backend.SPECTRAL:
        raise InputError(f"--variant {args.variant}: not with --live (the live surface "
                         "traces R, G, B: use scalar_rgb or llvm_ad_rgb)")
    if resolved.table.channels.spectral:
        raise InputError(f"--live: {args.tables[0]} has [table] wavelengths; the live "
                         "surface traces R, G, B recipes only (render the spectral table "
                         "itself: microsim render TABLE --variant scalar_spectral)")
    lights = [scene.parse_light(s) for s in (args.light or LIVE_LIGHTS)]
    live.check_lights(lights)
    surface = objects.load_object(args.object)
    mi = backend.load(args.variant)
    k = int(resolved.simulation.realisations)
    threads = 1 if args.variant.startswith("scalar") else None
    show = sys.stderr.isatty() and not args.json
    with live.LiveSurface(resolved, k, Tiles(resolved.surface, memory_limit_gib=args.memory_limit),
                          args.seed, threads, args.memory_limit) as sampler:
        if args.table is None:  # with its own progress bar
            table, table_name = simulate_resolved(resolved, None, show,
                                                  args.memory_limit), "simulated"
        else:
            table, table_name = microsim.read_table(args.table), str(args.table)
        camera = scene.Camera(args.size[0], args.size[1], args.camera[0], args.camera[1],
                              args.fov[0])
        with tempfile.TemporaryDirectory() as tmp, progress_bar(show) as track:
            bsdf = bsdfs.table_bsdf(mi, table, Path(tmp) / "table.bsdf", "total",
                                    args.rotate)
            tabled = scene.render(mi, surface, bsdf, camera, lights, args.spp, args.seed,
                                  track("rendering the table"))
            traced = scene.render(mi, surface, live.live_bsdf(mi, sampler, args.rotate),
                                  camera, lights, args.spp, args.seed + 1,
                                  track("rendering the live surface"))
        samples, segments = sampler.samples, sampler.segments
    diff = figure.difference(traced, tabled)
    label = Path(args.tables[0]).stem
    figure.write_grid([figure.Row(label, [
        ("table", figure.display(tabled)), (f"live ({k} realisations)",
                                            figure.display(traced)),
        (f"mean luminance {100 * diff.total:+.1f}% ± {100 * diff.total_err:.1f}%",
         diff.relative)])],
        args.output, difference="(live − table) / table")
    result = {"output": str(args.output), "recipe": args.tables[0], "object": surface.name,
              "spp": args.spp, "size": list(args.size), "variant": args.variant,
              "rotate": args.rotate, "lights": [light.to_json() for light in lights],
              "table": {"source": table_name, "seconds": tabled.seconds,
                        "noise": _noise(tabled)},
              "live": {"realisations": k, "seconds": traced.seconds,
                       "noise": _noise(traced), "samples": samples, "segments": segments},
              "difference": {"mean": diff.mean, "mean_err": diff.mean_err,
                             "z": _z(diff.mean, diff.mean_err),
                             "total": diff.total, "total_err": diff.total_err,
                             "total_z": _z(diff.total, diff.total_err),
                             "median_abs": diff.median_abs,
                             "median_abs_noise_alone": diff.median_noise,
                             "pixels": diff.pixels}}
    if args.json:
        print_json(result)
        return 0
    d = result["difference"]
    print(f"table ({table_name}): {tabled.seconds:.2f} s, per-pixel noise "
          f"{number_text(result['table']['noise'], '.1f', 100, '%')} (median)")
    print(f"live ({k} realisations, {samples:,} samples, {segments:,} segments): "
          f"{traced.seconds:.2f} s, per-pixel noise "
          f"{number_text(result['live']['noise'], '.1f', 100, '%')} "
          "(median)")
    print(f"live against table over {d['pixels']} pixels: mean luminance "
          f"{number_text(d['total'], '+.2f', 100, '%')} ± "
          f"{number_text(d['total_err'], '.2f', 100, '%')} (z = "
          f"{number_text(d['total_z'], '+.2f')}); mean relative difference "
          f"{number_text(d['mean'], '+.2f', 100, '%')} ± "
          f"{number_text(d['mean_err'], '.2f', 100, '%')} (z = {number_text(d['z'], '+.2f')}); "
          f"median |Δ| {number_text(d['median_abs'], '.1f', 100, '%')} (noise alone "
          f"{number_text(d['median_abs_noise_alone'], '.1f', 100, '%')})")
    print(f"wrote {args.output} ({args.size[0]}x{args.size[1]}, {args.spp} spp, "
          f"{surface.name})")
    return 0


class _Tracker:
    """Callbacks of one rich progress bar per render (``scene.render``'s ``progress``)."""

    def __init__(self, bar: Any) -> None:
        self.bar = bar

    def __call__(self, label: str) -> Any:
        if self.bar is None:
            return None
        task = self.bar.add_task(label, total=None)
        return lambda done, total: self.bar.update(task, completed=done, total=total)


@contextlib.contextmanager
def progress_bar(enabled: bool) -> Iterator[_Tracker]:
    """A rich progress display on stderr (one bar per render: samples per pixel done,
    elapsed time and ETA) where ``enabled``; its tracker gives each render's callback (None
    without a display)."""
    if not enabled:
        yield _Tracker(None)
        return
    with progress_display() as bar:
        yield _Tracker(bar)


def _channels(table: Any) -> str:
    """A table's channels in words: ``"RGB"`` or ``"16 wavelengths 400-700 nm"``."""
    nm = table.channels.wavelengths
    if nm is None:
        return "RGB"
    return f"{len(nm)} wavelengths {nm[0]:g}-{nm[-1]:g} nm"


def _z(value: float, err: float) -> float | None:
    """value / err, None where the error is not positive (no pixels, or none noisy)."""
    return value / err if err > 0 else None


def _noise(image: Any) -> float:
    """Median relative standard error of the covered, lit pixels' luminance."""
    import numpy as np

    lit = (image.alpha > 0.999) & (image.luminance > 0)
    if not lit.any():
        return float("nan")
    return float(np.median(image.luminance_err[lit] / image.luminance[lit]))
