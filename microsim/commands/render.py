"""``microsim render TABLE [TABLE ...] -o PNG``: tables on an object, rendered by Mitsuba 3."""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path
from typing import Any

from microsim.commands.common import (
    add_component_arg,
    add_json_arg,
    finite_float,
    nonnegative_int,
    number_list,
    positive_int,
    table_component,
)
from microsim.errors import InputError
from microsim.files import writable_file

DEFAULT_SPP = 64


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
    from microsim.render.scene import DEFAULT_LIGHTS, LIGHTS

    p = sub.add_parser(
        "render", help="render tables on a torus, sphere, draped sheet or mesh (Mitsuba 3)",
        description="Render each table on an object with Mitsuba 3 and write a labelled "
                    "PNG grid. The table's +x axis follows the object's tangent (torus: "
                    "the major circle; sphere: the parallels; sheet: its x axis; mesh: "
                    "circles about the vertical). With --model, each row shows the table, "
                    "the analytic model and their relative difference. Needs Mitsuba 3: "
                    "pip install 'microsim[render]'. Angles in degrees. See docs/render.md.")
    p.add_argument("tables", nargs="+", metavar="TABLE", help="table files (.exr)")
    p.add_argument("-o", "--output", type=Path, required=True, help="PNG file to write")
    p.add_argument("--object", default="torus", metavar="OBJECT",
                   help="torus (default), sphere, sheet, or a mesh file (.ply, .obj, .stl, "
                        "...; +z up)")
    p.add_argument("--light", action="append", default=None, metavar="KIND:KEY=VALUE,...",
                   help="repeatable; kinds: " + ", ".join(
                       f"{k} ({', '.join(v)})" for k, v in LIGHTS.items())
                   + f"; default: {' and '.join(DEFAULT_LIGHTS)} (sun angles in degrees, "
                     "azimuth 0 = from behind the camera)")
    p.add_argument("--spp", type=positive_int, default=DEFAULT_SPP,
                   help=f"samples per pixel (default {DEFAULT_SPP})")
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
                   help="also render an analytic model (microsim models lists them), its "
                        "missing parameters from each table, and the relative difference; "
                        "once for every table, or once per table in their order")
    p.add_argument("--seed", type=nonnegative_int, default=0,
                   help="sampler seed (default 0)")
    p.add_argument("--variant", default="scalar_rgb", choices=("scalar_rgb", "llvm_ad_rgb"),
                   help="Mitsuba variant (default scalar_rgb; llvm_ad_rgb needs LLVM >= 16)")
    add_json_arg(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Render every table (and model), write the grid, report times and differences."""
    import microsim
    from microsim.analytic.registry import parse_model_spec
    from microsim.commands.common import print_json
    from microsim.render import backend, bsdfs, figure, objects, scene
    from microsim.table_models import model_defaults

    writable_file(args.output, "--output", (".png",))
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
    models = [parse_model_spec(specs[min(k, len(specs) - 1)], model_defaults(t.meta))
              for k, t in enumerate(tables)] if specs else []
    mi = backend.load(args.variant)
    camera = scene.Camera(args.size[0], args.size[1], args.camera[0], args.camera[1],
                          args.fov[0])
    rows, report = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for k, (path, table) in enumerate(zip(args.tables, tables, strict=True)):
            label = Path(path).stem
            bsdf = bsdfs.table_bsdf(mi, table, Path(tmp) / f"{k}.bsdf", components[k],
                                    args.rotate)
            image = scene.render(mi, surface, bsdf, camera, lights, args.spp, args.seed)
            entry: dict[str, Any] = {"table": str(path), "seconds": image.seconds,
                                     "noise": _noise(image)}
            panels = [("table" if models else label, figure.display(image))]
            if models:
                name, params, model = models[k]
                # one Python call per direction pair in scalar variants takes minutes:
                # there the model is tabulated like a table (docs/render.md)
                tabulate = Path(tmp) / f"model{k}.bsdf" if args.variant.startswith(
                    "scalar") else None
                bsdf, how = bsdfs.model_bsdf(mi, model, args.rotate, tabulate)
                other = scene.render(mi, surface, bsdf, camera, lights, args.spp,
                                     args.seed + 1)
                diff = figure.difference(image, other)
                entry.update(model=name, params=params, mitsuba=how,
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
              "lights": [{"kind": k, **p} for k, p in lights], "tables": report}
    if args.json:
        print_json(result)
        return 0
    for entry in report:
        line = (f"{entry['table']}: {entry['seconds']:.2f} s, per-pixel noise "
                f"{100 * entry['noise']:.1f}% (median)")
        if "model" in entry:
            d = entry["difference"]
            line += (f"; {entry['model']} via {entry['mitsuba']} {entry['model_seconds']:.2f}"
                     f" s; relative difference median {100 * d['median_abs']:.1f}% (noise "
                     f"alone {100 * d['median_abs_noise_alone']:.1f}%), mean "
                     f"{100 * d['mean']:+.1f}% over {d['pixels']} pixels")
        print(line)
    print(f"wrote {args.output} ({args.size[0]}x{args.size[1]}, {args.spp} spp, "
          f"{surface.name})")
    return 0


def _noise(image: Any) -> float:
    """Median relative standard error of the covered, lit pixels' luminance."""
    import numpy as np

    lit = (image.alpha > 0.999) & (image.luminance > 0)
    if not lit.any():
        return float("nan")
    return float(np.median(image.luminance_err[lit] / image.luminance[lit]))
