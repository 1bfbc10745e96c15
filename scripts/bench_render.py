"""Time `microsim render`'s Mitsuba render of one 320 × 240 image at the default sample count.

Usage: python scripts/bench_render.py [TABLE] [--repeats 5] [--write]

Renders TABLE (default: a smooth gold Beckmann α = 0.3 table made here) on the torus
under the default light, 320 × 240, the command's default samples per pixel, ``repeats``
times with Mitsuba's ``scalar_rgb`` variant, and also the tensor's set-up (resampling the
table, writing and loading it) and the whole command run in this process. Prints a
section for docs/performance.md; ``--write`` replaces the ``bench_render`` section there.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "performance.md"


def smooth_table(path: Path) -> None:
    from microsim.analytic.brdf import TorranceSparrow
    from microsim.analytic.fresnel import ConductorFresnel
    from microsim.analytic.ndf import Beckmann
    from microsim.comparison.metrics import model_table
    from microsim.tables.binning import HemisphereBins
    from microsim.tables.exr import write_table

    model = TorranceSparrow(Beckmann(0.3), fresnel=ConductorFresnel(np.array([0.2, 0.92, 1.1]),
                                                    np.array([3.9, 2.45, 2.14])))
    write_table(model_table(model, np.radians([0, 15, 30, 45, 60, 70, 80, 87]),
                            HemisphereBins(32, 64)), path)


def main() -> None:
    import microsim
    from microsim.cli import main as cli
    from microsim.commands.render import DEFAULT_SPP
    from microsim.files import write_section
    from microsim.render import backend, bsdfs, objects, scene

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("table", nargs="?", default=None)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--write", action="store_true", help="update docs/performance.md")
    args = parser.parse_args()
    load_before = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(args.table) if args.table else Path(tmp) / "gold.exr"
        if args.table is None:
            smooth_table(path)
        mi = backend.load("scalar_rgb")
        table = microsim.read_table(path)
        surface = objects.torus()
        lights = [scene.parse_light(s) for s in scene.DEFAULT_LIGHTS]
        setup, renders, commands = [], [], []
        for k in range(args.repeats):
            start = time.perf_counter()
            bsdf = bsdfs.table_bsdf(mi, table, Path(tmp) / "t.bsdf")
            setup.append(time.perf_counter() - start)
            renders.append(scene.render(mi, surface, bsdf, scene.Camera(), lights,
                                        DEFAULT_SPP, seed=k).seconds)
            start = time.perf_counter()
            assert cli(["render", str(path), "-o", str(Path(tmp) / "x.png")]) == 0
            commands.append(time.perf_counter() - start)
    load_after = os.getloadavg()
    what = "a smooth gold Beckmann α = 0.3 table (8 incidences, 32 × 64 bins)" \
        if args.table is None else f"`{args.table}`"

    def row(name: str, ts: list[float]) -> str:
        return (f"| {name} | {', '.join(f'{t:.2f}' for t in ts)} | "
                f"{statistics.median(ts):.2f} |")

    text = "\n".join([
        "## Rendering a table (`microsim render`)",
        "",
        f"Measured with `python scripts/bench_render.py {' '.join(sys.argv[1:])}`".rstrip()
        + f" on {platform.machine()}, {os.cpu_count()} CPUs, Python "
        f"{platform.python_version()}, Mitsuba {mi.__version__} `scalar_rgb`: {what} on "
        f"the torus (25,600 triangles) under the default light, 320 × 240 pixels, "
        f"{DEFAULT_SPP} samples per pixel (the default), {args.repeats} repeats.",
        "",
        "| step | seconds (per repeat) | median |",
        "| --- | --- | --- |",
        row("tensor: resample the table, write, load", setup),
        row("Mitsuba render", renders),
        row("whole command (read, tensor, render, PNG)", commands),
        "",
        f"Load average (1 min) before and after: {load_before[0]:.1f}, {load_after[0]:.1f} "
        f"on {os.cpu_count()} CPUs.",
    ])
    print(text)
    if args.write:
        write_section(DOC, "bench_render", text)


if __name__ == "__main__":
    main()
