"""``microsim wavelets TABLE``: error against kept coefficients, wavelets beside the
table's spherical harmonics; ``--store`` keeps the wavelets in the table file."""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

from microsim.commands.common import (
    add_component_arg,
    add_json_arg,
    bounded_int,
    channels_json,
    finite_float,
    number_text,
    positive_int,
    print_json,
    table_component,
)
from microsim.errors import InputError

DEFAULT_WAVELET = "haar"
"""``microsim.tables.wavelets.DEFAULT_WAVELET``, spelled out so that ``--help`` does not
import numpy; likewise the resolution and the sweep."""
DEFAULT_RESOLUTION = 256
STEPS_PER_OCTAVE = 2
MAX_STEPS = 64
"""Most ``--steps``: each step is one more reconstruction of the table per doubling (a
billion allocated the sweep's counts at once, 35 GiB)."""
DEFAULT_TARGET = 0.01
"""What ``--store`` keeps without ``--target-error`` or ``--keep``."""
TARGETS = (0.10, 0.05, 0.02)
"""The median relative errors the text report gives the counts for."""


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``wavelets`` command."""
    p = sub.add_parser(
        "wavelets", help="wavelets of the table's outgoing hemisphere against its spherical "
                         "harmonics: error against kept coefficients and bytes",
        description="Resample each incidence's f_r cos theta_o from the bins onto an "
                    "equal-area square of the hemisphere (Shirley-Chiu concentric map), "
                    "take its orthonormal wavelet transform (PyWavelets, periodization), "
                    "and keep the largest coefficients; the table's spherical harmonics "
                    "are kept by magnitude alike. Reports the median relative error on "
                    "the lobe bins against the kept coefficients per incidence and channel "
                    "(colour, or wavelength of a spectral table), "
                    "and their bytes, for both bases. --store writes the wavelets into a "
                    "table file so that eval reads them. See docs/table-format.md.")
    p.add_argument("table", metavar="TABLE", help="table file (.exr)")
    add_component_arg(p)
    p.add_argument("--wavelet", default=DEFAULT_WAVELET, metavar="NAME",
                   help="orthogonal wavelet: haar (default), db<N>, sym<N> or coif<N>")
    p.add_argument("--resolution", type=positive_int, default=DEFAULT_RESOLUTION,
                   metavar="N", help="pixels per side of the equal-area square, a power "
                                     "of two from 4 to 1024 (default 256)")
    p.add_argument("--steps", type=bounded_int(1, MAX_STEPS, "one reconstruction each per "
                                                        "doubling"),
                   default=STEPS_PER_OCTAVE, metavar="S",
                   help=f"kept counts per doubling in the sweep, 1 to {MAX_STEPS} (default 2)")
    p.add_argument("--store", type=Path, default=None, metavar="EXR",
                   help="write the table with its wavelets (every component, kept to "
                        "--target-error or --keep) to this file, atomically (it may be "
                        "TABLE itself)")
    keep = p.add_mutually_exclusive_group()
    keep.add_argument("--target-error", type=finite_float, default=None, metavar="E",
                      help="with --store: per incidence and colour the fewest largest "
                           "coefficients whose relative L2 error over the hemisphere is "
                           "<= E (> 0; default 0.01)")
    keep.add_argument("--keep", type=positive_int, default=None, metavar="K",
                      help="with --store: keep K coefficients per incidence and colour")
    add_json_arg(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Measure, report, and store."""
    import microsim
    from microsim.files import writable_file
    from microsim.tables import wavelets
    from microsim.tables.compression import curves, needed

    if args.target_error is not None and not args.target_error > 0:
        raise InputError(f"--target-error {args.target_error}: must be > 0 (a relative L2 "
                         "error, e.g. 0.01)")
    if args.store is None and (args.target_error is not None or args.keep is not None):
        raise InputError("--target-error and --keep choose what --store keeps; give "
                         "--store EXR")
    try:
        wavelets.wavelet_of(args.wavelet)
        wavelets.check_resolution(args.resolution)
    except ValueError as exc:  # "wavelet NAME: ..." or "resolution N: ..."
        raise InputError(f"--{exc}") from None
    if args.store is not None:
        writable_file(args.store, "--store", (".exr",))
    table = microsim.read_table(args.table)
    args.component = table_component(table, args.component, args.table)
    if not table.has_sh:
        raise InputError(f"{args.table}: holds no spherical harmonics to compare with "
                         "(simulate it with [table] sh_order > 0)")
    result = curves(table, args.component, args.resolution, args.wavelet, args.steps)
    if args.store is not None:
        target = args.target_error if args.target_error is not None else (
            None if args.keep is not None else DEFAULT_TARGET)
        table = replace(table, wavelets=wavelets.encode(
            {c: e.values for c, e in table.estimates.items()}, table.bins, args.resolution,
            args.wavelet, target_error=target, keep=args.keep,
            channels=table.channels.names))
        microsim.write_table(table, args.store)
        kept = {c: table.wavelets.kept(c) for c in table.components}
        result["stored"] = {"path": str(args.store),
                            "target_error": table.wavelets.target_error,
                            "keep": table.wavelets.keep,
                            "kept": {c: k.tolist() for c, k in kept.items()}}
    result.update(channels_json(table))
    if args.json:
        print_json(result)
        return 0
    each = "wavelength" if table.channels.spectral else "colour"
    print(f"{args.table} ({result['component']}): median relative error on the lobe bins "
          f"against coefficients kept per incidence and {each}; harmonics of order "
          f"{result['sh_order']}, {result['wavelet_name']} wavelets on {args.resolution}² "
          f"equal-area pixels ({result['levels']} levels)")
    for name in ("sh", "wavelet"):
        counts = ", ".join(
            f"{100 * t:g}%: " + (str(k) if (k := needed(result[name], t)) is not None
                                  else "not reached (floor "
                                  f"{number_text(result[name][-1][1], '.2f', 100, '%')})")
            for t in TARGETS)
        print(f"  {name:>7} needs {counts}")
    print(f"{'kept':>6} {'SH':>8} {'SH bytes':>10} {'wavelet':>8} {'bytes':>10}")
    rows = {k: [k] for k, _ in result["sh"] + result["wavelet"]}
    for name in ("sh", "wavelet"):
        for (k, e), size in zip(result[name], result["bytes"][name], strict=True):
            rows[k].append((name, e, size))
    for k in sorted(rows):
        cells = {name: (e, size) for name, e, size in rows[k][1:]}
        line = f"{k:6d}"
        for name in ("sh", "wavelet"):
            e, size = cells.get(name, (None, None))
            line += (f" {number_text(e, '7.2f', 100, '%')} {size:10d}" if e is not None
                     else f" {'':8} {'':10}")
        print(line)
    if args.store is not None:
        print(f"wrote {args.store}: wavelets of every component, at most "
              f"{max(int(k.max()) for k in kept.values())} coefficients per incidence and "
              f"{each}")
    return 0
