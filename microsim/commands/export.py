"""``microsim export TABLE --format npz|merl|rgl -o OUT``: tables for other tools."""

from __future__ import annotations

import argparse
from pathlib import Path

from microsim.commands.common import (
    add_component_arg,
    add_memory_arg,
    positive_int,
    table_component,
)
from microsim.errors import InputError
from microsim.files import writable_file
from microsim.memory import check_memory

SUFFIXES = {"npz": ".npz", "merl": ".binary", "rgl": ".bsdf"}
RGL_BYTES = (200, 60)
"""Memory of an RGL export per grid vertex: a fixed part (evaluating the table there) and
a part per incidence (the tensor and its copies in the file's bytes); measured 387 B per
vertex with 4 incidences (resolution 512 to 1024), rounded up. A spectral file's part per
incidence is (C + 3) / 3 times larger (C channels of ``spectra`` and three of ``rgb``):
estimated 1340 B per vertex for 16 wavelengths and 3 incidences, measured 1036 B
(tracemalloc peak, resolution 1024)."""
MERL_BYTES = 256 * 2**20
"""Memory of a MERL export (its fixed 90 × 90 × 180 grid evaluated, three float64 planes):
measured 211 MiB (tracemalloc peak, a table of 2 incidences and 8 × 16 bins), rounded
up."""


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``export`` command."""
    p = sub.add_parser(
        "export", help="write a table as .npz, MERL .binary or RGL .bsdf (Mitsuba 3)",
        description="Export a BRDF table: npz (axes, values, errors, albedo for numpy), "
                    "merl (MERL .binary, 90 x 90 x 180 half/difference cells, BRDF Explorer "
                    "and many tools read it), or rgl (RGL tensor file .bsdf, loaded by "
                    "Mitsuba 3's 'measured' material). A spectral table keeps its "
                    "wavelengths in npz and in rgl (Mitsuba's spectral layout, for its "
                    "spectral variants; --rgb for its RGB variants); merl holds its linear "
                    "sRGB. See docs/table-format.md.")
    p.add_argument("table", metavar="TABLE", help="table file (.exr)")
    p.add_argument("--format", required=True, choices=tuple(SUFFIXES), help="output format")
    p.add_argument("-o", "--output", type=Path, required=True,
                   help="output file (.npz, .binary or .bsdf to match --format)")
    add_component_arg(p)
    p.add_argument("--resolution", type=positive_int, default=32,
                   help="rgl: grid vertices per axis of the colour tensor (default 32)")
    p.add_argument("--rgb", action="store_true",
                   help="rgl: write a spectral table's linear sRGB (CIE 1931 2 deg, D65) as "
                        "an RGB file, which Mitsuba 3's RGB variants load (they refuse a "
                        "spectral file); no effect on an RGB table. merl always holds a "
                        "spectral table's linear sRGB; npz all its wavelengths")
    add_memory_arg(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Read, convert, write."""
    import microsim
    from microsim.tables import export

    want = SUFFIXES[args.format]
    if args.output.suffix.lower() != want:
        raise InputError(f"--output {args.output}: a {args.format} file must end in {want}")
    writable_file(args.output, "--output")
    if args.format == "rgl" and args.resolution < 2:
        raise InputError(f"--resolution {args.resolution}: must be >= 2")
    if args.rgb and args.format != "rgl":
        raise InputError(f"--rgb: only with --format rgl ({args.format} files hold "
                         + ("every channel" if args.format == "npz" else "R, G, B")
                         + " already)")
    table = microsim.read_table(args.table)
    args.component = table_component(table, args.component, args.table)
    if args.format == "merl" and not table.isotropic:
        raise InputError(f"--format {args.format}: writes isotropic tables; {args.table} is "
                         "anisotropic (use --format npz or rgl)")
    if args.format == "rgl":
        from microsim.tables.export import rgl_phi_i

        fixed, per_incidence = RGL_BYTES
        incidences = len(table.theta_i) * (1 if table.isotropic else len(rgl_phi_i()))
        if table.channels.spectral and not args.rgb:
            # a spectral file holds C channels (spectra) besides the three of rgb
            per_incidence *= (table.channels.count + 3) / 3
        check_memory(args.resolution**2 * (fixed + per_incidence * incidences),
                     f"--resolution {args.resolution}: the RGL grid", "lower --resolution "
                     "(32 to 256 is usual)", args.memory_limit)
    if args.format == "merl":
        check_memory(MERL_BYTES, "--format merl: the MERL grid of 90 x 90 x 180 directions",
                     "use --format npz, or rgl with a low --resolution", args.memory_limit)
    if args.format == "npz":
        export.write_npz(table, args.output)
    elif args.format == "merl":
        export.write_merl(table, args.output, args.component)
    else:
        export.write_rgl(table, args.output, args.resolution, args.component, args.rgb)
    print(f"wrote {args.output}")
    return 0
