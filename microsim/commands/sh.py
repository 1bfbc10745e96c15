"""``microsim sh TABLE --orders 2,4,8,16,32``: what truncated spherical harmonics lose."""

from __future__ import annotations

import argparse
from pathlib import Path

from microsim.commands.common import (
    add_component_arg,
    add_json_arg,
    number_text,
    print_json,
    table_component,
)
from microsim.errors import InputError
from microsim.files import PLOT_SUFFIXES, writable_file

WINDOWS = ("none", "lanczos", "hanning")
"""``microsim.tables.sh.WINDOWS``, spelled out so that ``--help`` does not import numpy."""
DEFAULT_ORDERS = (2, 4, 8, 16, 32)
MATRIX_MAX_ORDER = 32
"""``microsim.tables.sh_matrix.MAX_ORDER``, likewise."""


def order_list(text: str) -> list[int]:
    """argparse type: comma-separated integers >= 0, increasing order not required."""
    try:
        orders = [int(t) for t in text.split(",") if t.strip()]
    except ValueError:
        orders = []
    if not orders or min(orders) < 0:
        raise argparse.ArgumentTypeError(f"{text!r} is not a comma-separated list of "
                                         "integers >= 0")
    return sorted(set(orders))


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``sh`` command."""
    p = sub.add_parser(
        "sh", help="error, negativity and size of the table's spherical harmonics per order",
        description="Truncate the spherical harmonics stored in a table (projected from the "
                    "escaping rays during the simulation; [table] sh_order) at each order "
                    "and compare them with the binned table: relative L2 error of "
                    "f_r cos theta_o over the hemisphere and over the lobe bins, the noise "
                    "floors of both, the most negative value, and the size in bytes. See "
                    "docs/table-format.md.")
    p.add_argument("table", metavar="TABLE", help="table file (.exr) with harmonics")
    p.add_argument("--orders", type=order_list, default=None, metavar="L,L,...",
                   help="orders to report, each at most the stored order (default "
                        "2,4,8,16,32 below the stored order, and the stored order)")
    p.add_argument("--window", choices=WINDOWS, default="none",
                   help="smoothing window against ringing: none (default), lanczos "
                        "(sigma factors) or hanning; the unwindowed error is reported too")
    add_component_arg(p)
    p.add_argument("--plot", type=Path, default=None, metavar="PNG",
                   help="draw the error against the order, and the plane of incidence of "
                        "the last incidence: table against the series at each order")
    p.add_argument("--matrix", type=Path, default=None, metavar="NPZ",
                   help="also write Westin's BRDF matrix b_ij (reciprocity enforced) at the "
                        "highest of --orders as .npz (isotropic tables only), and report "
                        "its asymmetry before symmetrisation (JSON: matrix_asymmetry in "
                        "the row of that order)")
    add_json_arg(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Compare and report."""
    import microsim
    from microsim.tables.sh_error import order_errors

    table = microsim.read_table(args.table, require_sh=True)
    args.component = table_component(table, args.component, args.table)
    if not table.has_sh:
        raise InputError(f"{args.table}: holds no spherical harmonics (simulate it with "
                         "[table] sh_order > 0)")
    if args.orders is None:
        args.orders = [o for o in DEFAULT_ORDERS if o < table.sh_order] + [table.sh_order]
    if max(args.orders) > table.sh_order:
        raise InputError(f"--orders {max(args.orders)}: {args.table} stores order "
                         f"{table.sh_order}; each order must be 0..{table.sh_order}")
    if args.matrix is not None and not table.isotropic:
        raise InputError(f"--matrix: Westin's matrix is built for isotropic tables; "
                         f"{args.table} is anisotropic")
    if args.matrix is not None:
        writable_file(args.matrix, "--matrix", (".npz",))
    if args.plot is not None:
        writable_file(args.plot, "--plot", PLOT_SUFFIXES)
    if args.matrix is not None and max(args.orders) > MATRIX_MAX_ORDER:
        raise InputError(f"--matrix: built up to order {MATRIX_MAX_ORDER} (a dense "
                         f"(L+1)^4 x {table.channels.count} array); the highest of --orders "
                         f"is {max(args.orders)}")
    rows = order_errors(table, args.orders, args.window, args.component)
    if args.matrix is not None:
        from microsim.tables.sh_matrix import brdf_matrix, write_matrix

        matrix, asymmetry = brdf_matrix(table, max(args.orders), args.component)
        write_matrix(args.matrix, matrix, asymmetry, table.channels.wavelengths)
        # the row of the matrix's order (the highest) carries it
        rows[-1].update(matrix=str(args.matrix), matrix_asymmetry=asymmetry.tolist())
    if args.plot is not None:
        from microsim.plots import sh_error_plot

        sh_error_plot(rows, table, args.plot, args.component,
                      f"{args.table}: {args.component}")
    if args.json:
        print_json(rows)
        return 0
    print(f"spherical harmonics of {args.table} ({args.component}, window {args.window}) "
          f"against the table; noise floors: table "
          f"{number_text(rows[0]['table_noise'], '.2f', 100, '%')}")
    print(f"{'order':>5} {'hemisphere':>10} {'lobe':>8} {'unwindowed':>10} "
          f"{'SH noise':>8} {'min f cos':>10} {'min/max':>8} {'bytes':>9}")
    for r in rows:
        print(f"{r['order']:5d} {number_text(r['rel_l2_error'], '9.2f', 100, '%')} "
              f"{number_text(r['rel_l2_error_lobe'], '7.2f', 100, '%')} "
              f"{number_text(r['rel_l2_error_unwindowed'], '9.2f', 100, '%')} "
              f"{number_text(r['sh_noise'], '7.2f', 100, '%')} "
              f"{number_text(r['min_value'], '10.4g')} "
              f"{number_text(r['min_relative'], '8.3f')} {r['bytes']:9d}")
    if table.channels.spectral:
        last = rows[-1]
        print(f"per wavelength at order {last['order']} (hemisphere, lobe): " + ", ".join(
            f"{name} {number_text(e, '.2f', 100, '%')} {number_text(f, '.2f', 100, '%')}"
            for name, e, f in zip(
                last["channels"], last["rel_l2_error_per_channel"],
                last["rel_l2_error_lobe_per_channel"], strict=True)))
    if args.plot is not None:
        print(f"wrote {args.plot}")
    if args.matrix is not None:
        print(f"wrote {args.matrix}: Westin's matrix at order {max(args.orders)}, asymmetry "
              "before symmetrisation "
              f"{number_text(max(rows[-1]['matrix_asymmetry']), '.2f', 100, '%')} "
              "(the theta_i interpolation error)")
    return 0
