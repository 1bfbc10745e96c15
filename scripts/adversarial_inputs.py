"""Adversarial inputs: about a thousand bad or extreme inputs to every command, each run in
a process of its own, judged by the command line's rule.

    python scripts/adversarial_inputs.py [--only COMMAND ...] [--jobs 1] [--write]
    python scripts/adversarial_inputs.py --interrupt
    python scripts/adversarial_inputs.py --list

The rule (microsim/cli.py, docs/testing.md): a case **passes** when it exits 0 and every
file it wrote reads back finite (tables, exports, images, meshes, JSON, text without a
``nan``), with nothing printed as NaN and no stray line on stderr but ``warning:`` lines;
or when it exits 2 with exactly one line on stderr, besides ``warning:`` lines, that starts
with ``error:``, having written no file. ``microsim batch`` exiting 1 with its summary of a
failed table is its documented outcome of a point that fails at run time (listed apart).
Anything else **fails**: a traceback, another exit status, a NaN in an output or on stdout,
an error of several lines, a temporary file left behind, or a run over its time limit.

The inputs: every recipe key of every surface kind, material kind, ``[simulation]`` and
``[table]`` given values of the wrong type, NaN, infinities, negative, zero, huge, tiny,
empty strings, unknown keys; values at the schema's bounds simulated to tables; malformed
TOML; bad ``--set`` syntax; every command's flags with bad values; edited tables (header
JSON fields removed or of another type, NaN/inf/negative pixels, channels removed) and
truncated ones, through every command that reads tables; model specs (unknown models,
repeated keys, values out of range, units); meshes that are not meshes; output paths that
are folders, under files, unwritable, immutable, or longer than the file system takes;
sweep files, batch folders whose state paths are folders, scheduler addresses that are
wrong, refuse connections or never answer; export formats, render options, environment
variables. Each case runs with ``MICROSIM_EFFORT=0.01`` (docs/goniometer.md) and small
tables, in a fresh folder under ``--work`` (its working directory), under a time limit
(``TIMEOUT`` seconds, more for the few that start a cluster or a JIT).

``--interrupt`` re-checks interruption and determinism instead: ``simulate`` and ``batch``
killed with SIGKILL and stopped with SIGINT at several moments (nothing partial at the
output path, a previous output untouched, temporary files removed by the next run, SIGINT
one ``error: interrupted`` line with status 130), a resumed batch byte-identical to an
uninterrupted one, and a few recipes identical with ``--threads 1`` and 2.

``--write`` puts the inputs' summary, or with ``--interrupt`` its checks, in docs/testing.md
(a marked section each). Run it under
``nice -n 19``: with ``--jobs 1`` (the default) one case runs at a time.
"""

from __future__ import annotations

import argparse
import collections
import concurrent.futures
import contextlib
import dataclasses
import json
import math
import os
import re
import shutil
import signal
import socket
import stat
import struct
import subprocess
import sys
import time
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from microsim.files import TEMPORARY, measured_with, write_section

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "testing.md"
SURFACES = ROOT / "surfaces"
TIMEOUT = 120.0
"""Seconds a case may take: none of them needs a tenth of it on two shared cores."""
SLOW_TIMEOUT = 300.0
"""Seconds for the cases that start a Dask cluster, Mitsuba's LLVM JIT or a bench."""
EFFORT = "0.01"
"""``$MICROSIM_EFFORT`` of every case that does not set its own."""
COMMANDS = ("check", "models", "generate", "measure", "view", "simulate", "compare", "fit",
            "sh", "export", "render", "bench", "batch", "demo", "wavelets", "eval", "cli")
"""The commands (``cli``: ``microsim`` itself, no command or an unknown one)."""
RECIPES = {"flat": "flat-lambertian.toml", "gaussian": "gaussian-0.3.toml",
           "vgroove": "vgroove-30.toml", "cylinders": "cylinders.toml",
           "velvet": "velvet.toml", "weave": "weave-twill.toml", "paint": "paint.toml",
           "mesh": "mesh-example.toml"}
"""A shipped recipe of each surface kind."""
SMALL = ("--set", "surface.resolution=32", "--set", "simulation.theta_i=[0, 60]",
         "--set", "table.theta_bins=8", "--set", "table.phi_bins=16",
         "--set", "table.sh_order=4")
"""Overrides that make a Gaussian recipe's table small (32² tile, 2 incidences)."""
LIGHT = ("--set", "simulation.theta_i=[0, 60]", "--set", "table.theta_bins=8",
         "--set", "table.phi_bins=16", "--set", "table.sh_order=2")
"""Overrides that make any recipe's table small."""
LONG_NAME = "n" * 300
"""A file name longer than any Linux file system takes (255 bytes)."""
BASE_FILES = ("afile",)
BASE_FOLDERS = ("adir", "adir.exr", "adir.png", "adir.npz", "adir.ply", "adir.toml")
"""Made in every case's folder: a file to put paths under, folders to give as files."""


@dataclasses.dataclass(frozen=True)
class Case:
    """One input: ``microsim ARGV`` run in a fresh folder.

    Parameters
    ----------
    command : str
        Of ``COMMANDS``: the summary's row.
    name : str
        What is wrong with the input, in words.
    argv : tuple of str
        The arguments; ``@FX@`` is the fixtures' folder, ``@HERE@`` the case's folder,
        ``@ROOT@`` the repository, ``@SILENT@`` / ``@CLOSED@`` the ports of a listener
        that never speaks and of none.
    env : tuple of (str, str or None)
        Environment changes (None: unset).
    setup : str or None
        ``prepare``'s ``KIND:ARGUMENT`` spec, run in the case's folder first.
    limit : float
        Seconds allowed.
    """

    command: str
    name: str
    argv: tuple[str, ...]
    env: tuple[tuple[str, str | None], ...] = ()
    setup: str | None = None
    limit: float = TIMEOUT

    @property
    def key(self) -> tuple:
        """What makes a case distinct."""
        return (self.argv, self.env, self.setup)


def case(command: str, name: str, *argv: str, env: dict[str, str | None] | None = None,
         setup: str | None = None, limit: float = TIMEOUT) -> Case:
    """A ``Case`` from its arguments."""
    return Case(command, name, tuple(argv), tuple(sorted((env or {}).items())), setup, limit)


# --- fixtures --------------------------------------------------------------------------------
SMALL_BASE = """\
[base.surface]
kind = "gaussian"
alpha = 0.3
resolution = 32

[base.simulation]
theta_i = [0, 60]
rays = 2000

[base.table]
theta_bins = 8
phi_bins = 16
sh_order = 2
"""
"""An inline sweep base of small tables."""


def in_process(*argv: str) -> None:
    """``microsim ARGV`` in this process at full effort (fixtures); raise if it fails."""
    from microsim.cli import main

    before = os.environ.pop("MICROSIM_EFFORT", None)
    try:
        with open(os.devnull, "w") as null, contextlib.redirect_stdout(null):
            code = main(list(argv))
    finally:
        if before is not None:
            os.environ["MICROSIM_EFFORT"] = before
    if code != 0:
        raise RuntimeError(f"fixture: microsim {' '.join(argv)} exited {code}")


def exr_parts(path: Path) -> list[tuple[str, dict, dict[str, np.ndarray]]]:
    """(name, header, channels) of every part of an OpenEXR file."""
    import OpenEXR

    with OpenEXR.File(str(path), separate_channels=True) as f:
        return [(p.name(), dict(p.header), {n: np.array(c.pixels) for n, c in p.channels.items()})
                for p in f.parts]


def edited_table(source: Path, target: Path,
                 header: Callable[[dict], dict | None] | None = None,
                 pixels: Callable[[dict[str, np.ndarray]], None] | None = None,
                 sh_header: Callable[[dict], dict | None] | None = None,
                 raw: str | None = None) -> None:
    """``source`` rewritten to ``target`` with its ``microsim`` header JSON edited (in place,
    or replaced by what ``header`` returns), replaced by the text ``raw``, its bins'
    channels edited by ``pixels`` and its harmonics' ``microsim_sh`` JSON by
    ``sh_header``."""
    import OpenEXR

    out = []
    for name, head, channels in exr_parts(source):
        head = {k: v for k, v in head.items()
                if k in ("compression", "type", "displayWindow", "microsim", "microsim_sh")}
        for attribute, edit in (("microsim", header), ("microsim_sh", sh_header)):
            if attribute in head and (edit is not None or (raw and attribute == "microsim")):
                info = json.loads(head[attribute])
                if edit is not None:
                    replaced = edit(info)
                    info = info if replaced is None else replaced
                head[attribute] = raw if raw and attribute == "microsim" else json.dumps(info)
        if "microsim" in head and pixels is not None:
            pixels(channels)
        out.append(OpenEXR.Part(head, {n: np.ascontiguousarray(c) for n, c in channels.items()},
                                name))
    OpenEXR.File(out).write(str(target))


def header_edits(info: dict) -> dict[str, Callable[[dict], dict | None]]:
    """Edits of a table's header JSON by name: each top-level field and each field of
    ``meta`` removed, made a string, null, a negative number, a list, a huge integer."""
    edits: dict[str, Callable[[dict], dict | None]] = {}
    junk = {"removed": None, "a string": "x", "null": None, "negative": -1,
            "a list": [1, 2], "huge": 10**30, "NaN": math.nan, "nested": {"a": {"b": []}}}
    fields = [(k,) for k in info] + [("meta", k) for k in info.get("meta", {})]
    for i, path in enumerate(fields):
        # every field removed, and given one of the other values in turn
        hows = ["removed", list(junk)[1 + i % (len(junk) - 1)]]
        for how in hows:
            def edit(h: dict, path: tuple = path, how: str = how) -> None:
                node = h
                for k in path[:-1]:
                    node = node[k]
                if how == "removed":
                    del node[path[-1]]
                else:
                    node[path[-1]] = junk[how]
            edits[f"header {'.'.join(path)} {how}"] = edit
    edits["header empty"] = lambda h: {}
    edits["header a list"] = lambda h: [h]
    edits["header format_version 99"] = lambda h: {**h, "format_version": 99}
    edits["header axes.theta_o.edges reversed"] = lambda h: h["axes"]["theta_o"].update(
        edges=h["axes"]["theta_o"]["edges"][::-1])
    edits["header axes.theta_i.values past 90"] = lambda h: h["axes"]["theta_i"].update(
        values=[0.0, 3.0])
    edits["header layout.shape zero"] = lambda h: h["layout"].update(shape=[0, 0, 0, 0])
    edits["header rays 2^63"] = lambda h: h.update(rays=[[2**63], [2**63]])
    edits["header albedo inf"] = lambda h: h.update(albedo=[[[1e309] * 3], [[1, 1, 1]]])
    return edits


def pixel_edits() -> dict[str, Callable[[dict[str, np.ndarray]], None]]:
    """Edits of a table's bins' channels by name."""
    def put(channel: str, value: float, cell: tuple[int, int] = (1, 2)
            ) -> Callable[[dict[str, np.ndarray]], None]:
        def edit(ch: dict[str, np.ndarray]) -> None:
            data = ch[channel].copy()
            data[cell] = value
            ch[channel] = data
        return edit

    def drop(channel: str) -> Callable[[dict[str, np.ndarray]], None]:
        return lambda ch: ch.pop(channel)

    def fill(channel: str, value: float) -> Callable[[dict[str, np.ndarray]], None]:
        def edit(ch: dict[str, np.ndarray]) -> None:
            ch[channel] = np.full_like(ch[channel], value)
        return edit

    edits = {}
    for channel in ("total.R", "order1.G", "order3+.B", "total_err.R", "order2_err.G"):
        for label, value in (("NaN", np.nan), ("inf", np.inf), ("-inf", -np.inf),
                             ("negative", -1.0), ("float16 max", 65504.0)):
            edits[f"pixel {channel} {label}"] = put(channel, value)
    for channel in ("total.R", "order1_err.B", "order2.G"):
        edits[f"channel {channel} removed"] = drop(channel)
    edits["channel total.G all NaN"] = fill("total.G", np.nan)
    edits["channel total.R all zero"] = fill("total.R", 0.0)
    edits["channel total_err.R all zero"] = fill("total_err.R", 0.0)
    edits["channel order1.R all 1e30"] = fill("order1.R", 1e30)
    edits["channel extra"] = lambda ch: ch.update({"bogus.R": ch["total.R"].copy()})
    return edits


def sh_edits() -> dict[str, Callable[[dict], dict | None]]:
    """Edits of a table's harmonics header by name."""
    return {"sh order 99": lambda h: h.update(order=99),
            "sh order -1": lambda h: h.update(order=-1),
            "sh order a string": lambda h: h.update(order="4"),
            "sh coefficients 0": lambda h: h.update(coefficients=0),
            "sh shape wrong": lambda h: h.update(shape=[9, 9]),
            "sh channels removed": lambda h: h.pop("channels"),
            "sh header empty": lambda h: {}}


def write_mesh_fixtures(fx: Path) -> None:
    """Meshes that are not meshes, and recipes naming them."""
    import trimesh

    mesh = trimesh.load(SURFACES / "tile-gaussian-64.ply", process=False, force="mesh")
    shutil.copy(SURFACES / "tile-gaussian-64.ply", fx / "tile.ply")
    mesh.export(fx / "tile.obj")
    mesh.export(fx / "tile.stl")
    (fx / "garbage.ply").write_bytes(np.random.default_rng(0).integers(
        0, 256, 4096, np.uint8).tobytes())
    (fx / "empty.ply").write_bytes(b"")
    (fx / "text.ply").write_text("ply\nformat ascii 1.0\nelement vertex 3\nend_header\n1 2\n")
    nan = mesh.vertices.copy()
    nan[5] = np.nan
    trimesh.Trimesh(nan, mesh.faces, process=False).export(fx / "nonfinite.ply")
    huge = mesh.vertices.copy()
    huge[:, 2] *= 1e300
    with np.errstate(over="ignore"):  # PLY's float32 makes them infinite: the fixture's point
        trimesh.Trimesh(huge, mesh.faces, process=False).export(fx / "huge.ply")
    (fx / "points.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    (fx / "degenerate.obj").write_text("v 0 0 0\nv 0 0 0\nv 0 0 0\nf 1 2 3\n")
    (fx / "outside.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n")
    half = trimesh.Trimesh(mesh.vertices, mesh.faces[: len(mesh.faces) // 2], process=False)
    half.export(fx / "half.ply")
    for name in ("garbage.ply", "empty.ply", "text.ply", "nonfinite.ply", "huge.ply", "points.obj",
                 "degenerate.obj", "outside.obj", "half.ply", "tile.obj", "tile.stl"):
        (fx / f"mesh-{Path(name).stem}-{Path(name).suffix[1:]}.toml").write_text(
            f'[surface]\nkind = "mesh"\npath = "{name}"\nperiod = [1.0, 1.0]\n'
            "[simulation]\ntheta_i = [0, 60]\n[table]\ntheta_bins = 8\nphi_bins = 16\n"
            "sh_order = 2\n", encoding="utf-8")


MALFORMED = {
    "empty file": "",
    "only a comment": "# nothing\n",
    "unterminated string": '[surface]\nkind = "gaussian\n',
    "duplicate key": '[surface]\nkind = "gaussian"\nalpha = 0.3\nalpha = 0.4\n',
    "duplicate table": '[surface]\nkind = "gaussian"\n[surface]\nalpha = 0.3\n',
    "invalid escape": '[surface]\nkind = "gauss\\qian"\n',
    "bare words": "this is not toml\n",
    "array of tables": '[[surface]]\nkind = "gaussian"\n',
    "surface a number": "surface = 3\n",
    "surface a string": 'surface = "gaussian"\n',
    "kind missing": "[surface]\nalpha = 0.3\n",
    "kind a number": "[surface]\nkind = 3\n",
    "kind empty": '[surface]\nkind = ""\n',
    "kind unknown": '[surface]\nkind = "fractal"\n',
    "kind unicode": '[surface]\nkind = "gaüssian"\n',
    "a date": '[surface]\nkind = "gaussian"\nalpha = 1979-05-27\n',
    "a time": '[surface]\nkind = "gaussian"\nalpha = 07:32:00\n',
    "an inline table": '[surface]\nkind = "gaussian"\nalpha = { a = 1 }\n',
    "dotted keys": 'surface.kind = "gaussian"\nsurface.alpha.x = 1\n',
    "unknown section": '[surface]\nkind = "gaussian"\n[tabel]\ntheta_bins = 8\n',
    "unknown top key": 'descripton = "x"\n[surface]\nkind = "gaussian"\n',
    "description a number": 'description = 3\n[surface]\nkind = "gaussian"\n',
    "material a list": '[surface]\nkind = "gaussian"\n[material]\nkind = ["mirror"]\n',
    "material part unknown": '[surface]\nkind = "gaussian"\n[material.lid]\nkind = "mirror"\n',
    "material empty table": '[surface]\nkind = "gaussian"\n[material]\n',
    "simulation a list": '[surface]\nkind = "gaussian"\nsimulation = [1]\n',
    "nested 5000 deep": "a = " + "[" * 5000 + "]" * 5000 + "\n",
    "integer of 5000 digits": '[surface]\nkind = "gaussian"\nalpha = ' + "9" * 5000 + "\n",
    "float of 5000 digits": '[surface]\nkind = "gaussian"\nalpha = 0.' + "3" * 5000 + "\n",
    "a NUL byte": '[surface]\nkind = "gaussian\x00"\n',
    "a very long line": "# " + "x" * 500_000 + '\n[surface]\nkind = "gaussian"\n',
    "a long string value": '[surface]\nkind = "' + "g" * 100_000 + '"\n',
    "hex integer": '[surface]\nkind = "gaussian"\nresolution = 0x20\n',
    "nan literal": '[surface]\nkind = "gaussian"\nalpha = nan\n',
    "-inf literal": '[surface]\nkind = "gaussian"\nalpha = -inf\n',
    "60 000 unknown top-level keys": "".join(f"k{i} = {i}\n" for i in range(60_000)),
    "crlf and tabs": '[surface]\r\n\tkind = "gaussian"\r\n\talpha\t=\t0.3\r\n',
}
"""Recipe files that are not recipes (``check`` and ``simulate`` read them)."""
BINARY = {
    "UTF-16 with a BOM": '[surface]\nkind = "gaussian"\n'.encode("utf-16"),
    "latin-1": '[surface]\nkind = "gaußian"\n'.encode("latin-1"),
    "random bytes": np.random.default_rng(1).integers(0, 256, 512, np.uint8).tobytes(),
    "a PNG": b"\x89PNG\r\n\x1a\n" + bytes(64),
}


SWEEPS = {
    "fine": f"{SMALL_BASE}\n[sweep]\n\"surface.alpha\" = [0.2, 0.4]\n",
    "base missing": 'base = "nowhere.toml"\n[sweep]\n"surface.alpha" = [0.2]\n',
    "base a folder": 'base = "."\n[sweep]\n"surface.alpha" = [0.2]\n',
    "base a number": 'base = 3\n[sweep]\n"surface.alpha" = [0.2]\n',
    "base and inline base": (f'base = "{SURFACES}/gaussian-0.3.toml"\n{SMALL_BASE}'
                             '[sweep]\n"surface.alpha" = [0.2]\n'),
    "no base": '[sweep]\n"surface.alpha" = [0.2]\n',
    "no sweep": SMALL_BASE,
    "sweep empty": f"{SMALL_BASE}[sweep]\n",
    "axis empty": f'{SMALL_BASE}[sweep]\n"surface.alpha" = []\n',
    "axis a number": f'{SMALL_BASE}[sweep]\n"surface.alpha" = 0.2\n',
    "axis a table": f'{SMALL_BASE}[sweep]\n"surface.alpha" = {{ a = 1 }}\n',
    "axis unknown key": f'{SMALL_BASE}[sweep]\n"surface.alhpa" = [0.2]\n',
    "axis unknown section": f'{SMALL_BASE}[sweep]\n"lighting.sun" = [0.2]\n',
    "axis not dotted": f'{SMALL_BASE}[sweep]\nalpha = [0.2]\n',
    "axis too deep": f'{SMALL_BASE}[sweep]\n"surface.alpha.x.y.z" = [0.2]\n',
    "axis value NaN": f'{SMALL_BASE}[sweep]\n"surface.alpha" = [0.2, nan]\n',
    "axis value a string": f'{SMALL_BASE}[sweep]\n"surface.alpha" = ["x"]\n',
    "axis values mixed": f'{SMALL_BASE}[sweep]\n"surface.alpha" = [0.2, "x", true]\n',
    "duplicate points": f'{SMALL_BASE}[sweep]\n"surface.alpha" = [0.2, 0.2]\n',
    "equal names": f'{SMALL_BASE}[sweep]\n"surface.alpha" = [0.2, 0.20000000000000001]\n',
    "zip unequal": (f'{SMALL_BASE}mode = "zip"\n[sweep]\n"surface.alpha" = [0.2, 0.4]\n'
                    '"surface.seed" = [1]\n'),
    "mode unknown": f'{SMALL_BASE}mode = "cartesian"\n[sweep]\n"surface.alpha" = [0.2]\n',
    "seed negative": f'seed = -1\n{SMALL_BASE}[sweep]\n"surface.alpha" = [0.2]\n',
    "seed a string": f'seed = "x"\n{SMALL_BASE}[sweep]\n"surface.alpha" = [0.2]\n',
    "seed a float": f'seed = 1.5\n{SMALL_BASE}[sweep]\n"surface.alpha" = [0.2]\n',
    "seed 2^64": f'seed = 18446744073709551615\n{SMALL_BASE}[sweep]\n"surface.alpha" = [0.2]\n',
    "seed and seed axis": f'seed = 1\n{SMALL_BASE}[sweep]\n"simulation.seed" = [1, 2]\n',
    "thetas_per_job 0": f'thetas_per_job = 0\n{SMALL_BASE}[sweep]\n"surface.alpha" = [0.2]\n',
    "thetas_per_job huge": (f'thetas_per_job = 10000000000\n{SMALL_BASE}[sweep]\n'
                            '"surface.alpha" = [0.2]\n'),
    "thetas_per_job a string": (f'thetas_per_job = "1"\n{SMALL_BASE}[sweep]\n'
                                '"surface.alpha" = [0.2]\n'),
    "description a list": f'description = [1]\n{SMALL_BASE}[sweep]\n"surface.alpha" = [0.2]\n',
    "unknown top key": f'workers = 4\n{SMALL_BASE}[sweep]\n"surface.alpha" = [0.2]\n',
    "point out of range": f'{SMALL_BASE}[sweep]\n"surface.alpha" = [0.2, -1]\n',
    "kind axis drops keys": f'{SMALL_BASE}[sweep]\n"surface.kind" = ["gaussian", "vgroove"]\n',
    "material kind axis": (f'{SMALL_BASE}[sweep]\n"material.kind" = ["mirror", "conductor", '
                           '"nosuch"]\n'),
    "10^10 points": SMALL_BASE + "[sweep]\n" + "".join(
        f'"{key}" = {values}\n' for key, values in [
            ("surface.alpha", [round(0.1 + 0.01 * j, 2) for j in range(10)]),
            ("surface.seed", list(range(10))), ("simulation.seed", list(range(10))),
            ("simulation.rays", [1000 + j for j in range(10)]),
            ("simulation.bounces", list(range(1, 11))),
            ("table.theta_bins", list(range(4, 14))), ("table.phi_bins", list(range(4, 14))),
            ("table.sh_order", list(range(10))), ("table.orders", list(range(2, 12))),
            ("surface.rotation", list(range(10)))]),
    "name longer than 255 bytes": (f'{SMALL_BASE}[sweep]\n"surface.kind" = '
                                   f'["gaussian"]\n"material.kind" = ["mirror"]\n'
                                   f'"simulation.theta_i" = [{list(range(89))}]\n'),
    "mesh missing at run time": ('[base.surface]\nkind = "mesh"\npath = "gone.ply"\n'
                                 'period = [1.0, 1.0]\n[sweep]\n"surface.seed" = [1]\n'),
    "nested 5000 deep": "a = " + "[" * 5000 + "]" * 5000 + "\n",
    "not UTF-8": None,
}
"""Sweep files (``batch``); None: written as bytes by ``write_fixtures``."""


def write_fixtures(fx: Path) -> None:
    """Tables (and edited, truncated, damaged copies), meshes, recipes, sweeps and
    scheduler files the cases read, in ``fx``."""
    fx.mkdir(parents=True, exist_ok=True)
    gaussian = str(SURFACES / "gaussian-0.3.toml")
    tables = fx / "tables"
    tables.mkdir(exist_ok=True)
    in_process("simulate", gaussian, *SMALL, "--rays", "2000", "-o", str(tables / "small.exr"),
               "--json")
    in_process("simulate", gaussian, *SMALL, "--set", "table.sh_order=0", "--rays", "2000",
               "-o", str(tables / "nosh.exr"), "--json")
    in_process("simulate", gaussian, *SMALL, "--set", "material.kind=lambertian", "--set",
               "material.albedo=0", "--rays", "2000", "-o", str(tables / "black.exr"), "--json")
    in_process("simulate", gaussian, *SMALL, "--set", "simulation.theta_i=[0]", "--rays",
               "2000", "-o", str(tables / "one.exr"), "--json")
    in_process("simulate", gaussian, *SMALL, "--set", "table.wavelengths=[450, 550, 650]",
               "--rays", "2000", "-o", str(tables / "spectral.exr"), "--json")
    in_process("simulate", str(SURFACES / "vgroove-30.toml"), *LIGHT, "--set",
               "simulation.phi_i=[0, 90]", "--rays", "2000", "-o", str(tables / "aniso.exr"),
               "--json")
    in_process("simulate", str(SURFACES / "weave-twill.toml"), *LIGHT, "--rays", "2000",
               "-o", str(tables / "weave.exr"), "--json")
    in_process("simulate", gaussian, *SMALL, "--set", "table.theta_bins=1", "--set",
               "table.phi_bins=1", "--rays", "2000", "-o", str(tables / "onebin.exr"),
               "--json")
    in_process("wavelets", str(tables / "small.exr"), "--keep", "20", "--store",
               str(tables / "wavelet.exr"), "--json")
    small = tables / "small.exr"
    edited = fx / "edited"
    edited.mkdir(exist_ok=True)
    info = json.loads(exr_parts(small)[0][1]["microsim"])
    for name, edit in header_edits(info).items():
        with contextlib.suppress(KeyError, TypeError, IndexError, AttributeError):
            edited_table(small, edited / f"{slug(name)}.exr", header=edit)
    for name, edit in pixel_edits().items():
        edited_table(small, edited / f"{slug(name)}.exr", pixels=edit)
    for name, edit in sh_edits().items():
        edited_table(small, edited / f"{slug(name)}.exr", sh_header=edit)
    for name, raw in (("raw not json", "{not json"), ("raw nested", "[" * 5000 + "]" * 5000),
                      ("raw long number", '{"format_version": 2, "rays": ' + "9" * 5000 + "}")):
        edited_table(small, edited / f"{slug(name)}.exr", raw=raw)
    data = small.read_bytes()
    for fraction in (0.0, 0.001, 0.05, 0.2, 0.4, 0.5, 0.6, 0.8, 0.9, 0.97, 0.995):
        (edited / f"cut-{fraction:g}.exr").write_bytes(data[: int(len(data) * fraction)])
    (edited / "garbage.exr").write_bytes(np.random.default_rng(2).integers(
        0, 256, 8192, np.uint8).tobytes())
    (edited / "text.exr").write_text("not a table\n")
    flipped = bytearray(data)
    for k in range(len(data) // 3, len(data) // 3 + 64):
        flipped[k] ^= 0xFF
    (edited / "bytes-flipped.exr").write_bytes(bytes(flipped))
    import OpenEXR

    plain = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    OpenEXR.File(plain, {"RGB": np.zeros((4, 4, 3), np.float32)}).write(
        str(edited / "plain-image.exr"))
    write_mesh_fixtures(fx)
    recipes = fx / "recipes"
    recipes.mkdir(exist_ok=True)
    for name, text in MALFORMED.items():
        (recipes / f"{slug(name)}.toml").write_text(text, encoding="utf-8")
    for name, data_ in BINARY.items():
        (recipes / f"{slug(name)}.toml").write_bytes(data_)
    sweeps = fx / "sweeps"
    sweeps.mkdir(exist_ok=True)
    for name, text in SWEEPS.items():
        path = sweeps / f"{slug(name)}.toml"
        if text is None:
            path.write_bytes(BINARY["latin-1"] + b"\n[sweep]\n")
        else:
            path.write_text(text, encoding="utf-8")
    for name, text in (("not-json", "{"), ("no-address", '{"id": 1}'),
                       ("address-number", '{"address": 3}'), ("list", "[1]"),
                       ("closed", '{"address": "tcp://127.0.0.1:@CLOSED@"}'),
                       ("empty", "")):
        (fx / f"scheduler-{name}.json").write_text(text, encoding="utf-8")


def slug(text: str) -> str:
    """``text`` as a file name."""
    return re.sub(r"[^A-Za-z0-9.=+-]+", "-", text).strip("-")


# --- the cases -------------------------------------------------------------------------------
def toml_bad_values(kind: str) -> list[str]:
    """Values (TOML, as ``--set`` reads them) that a key of this kind must refuse or carry."""
    numbers = ["nan", "inf", "-inf", "-1", "0", "1e300", "-1e300", "1e-300",
               "18446744073709551616", '"0.3"', "true", "[0.3]", '""', "{ a = 1 }", "1e-9"]
    return {
        "float": numbers, "int": numbers + ["2.5", "1e3"],
        "bool": ['"yes"', "1", "0.5", "[]", '""'],
        "str": ['""', '"nosuch"', "3", '["a"]', '"' + "x" * 10_000 + '"', "nan"],
        "path": ['""', '"missing.ply"', '"/"', "3", f'"{LONG_NAME}"', '"/dev/zero"',
                 '"../README.md"', '"."'],
        "floats": ["[]", "[nan]", "[inf]", "[-1]", "[1e300]", '"x"', "5", "[[1]]",
                   "[" + ", ".join(["1"] * 5000) + "]", "[1, 1]", '["a"]', "[30, 20]"],
        "pair": ["[]", "[1]", "[1, 2, 3]", "[nan, 1]", "[0, 1]", "[-1, 1]", "[1e300, 1]",
                 '"x"', "1"],
        "rgb": ["[nan, 0, 0]", "[1, 2]", "[-1, -1, -1]", '"x"', "[1e300, 0, 0]", "[]"],
    }.get(kind, ["[nan, 0, 0]", "[1, 2]", "[-1, -1, -1]", '"x"', "[]", "[1e300, 1, 1]",
                 "{ nm = [500], value = [nan] }", "{ nm = [], value = [] }",
                 "{ nm = [500, 400], value = [1, 1] }", "{ nm = [500], value = [1, 2] }",
                 "{ thickness = -1, eta = 1.5 }", "{ thickness = nan, eta = 1.5 }",
                 "{ thickness = 100 }", "{ }", "{ thickness = 1e300, eta = 1e300 }"])


def key_cases() -> list[Case]:
    """Every recipe key of every surface kind, material kind and section, given bad values:
    ``check`` reads most, every fifth goes through ``simulate`` or ``generate``."""
    from microsim.recipe import MATERIAL_KINDS, SIMULATION, TABLE
    from microsim.surfaces import SURFACES

    keys: list[tuple[str, str, str, tuple[str, ...]]] = []
    for kind, recipe in RECIPES.items():
        for name, key in SURFACES[kind].keys().items():
            keys.append((recipe, f"surface.{name}", key.kind, ()))
    for material, names in MATERIAL_KINDS.items():
        for name, key in names.items():
            keys.append(("gaussian-0.3.toml", f"material.{name}", key.kind,
                         ("--set", f"material.kind={material}")))
    for name, key in MATERIAL_KINDS["dielectric"].items():
        keys.append(("paint.toml", f"material.binder.{name}", key.kind, ()))
    for section, names in (("simulation", SIMULATION), ("table", TABLE)):
        for name, key in names.items():
            keys.append(("vgroove-30.toml", f"{section}.{name}", key.kind, ()))
    out = []
    n = 0
    for recipe, key, kind, extra in keys:
        values = toml_bad_values(kind)
        # every key: its first three values, and three more in turn
        picks = values[:3] + [values[3 + (n + j) % (len(values) - 3)] for j in range(3)]
        for value in dict.fromkeys(picks):
            n += 1
            source = f"@ROOT@/surfaces/{recipe}"
            sets = (*extra, "--set", f"{key}={value}")
            label = f"{key} = {value[:40]}"
            if n % 5 == 0:
                out.append(case("simulate", label, "simulate", source, *LIGHT, *sets,
                                "--rays", "500", "-o", "@HERE@/t.exr"))
            elif n % 5 == 3 and key.startswith("surface."):
                out.append(case("generate", label, "generate", source, *sets, "-o",
                                "@HERE@/t.ply", "--memory-limit", "0.5"))
            else:
                out.append(case("check", label, "check", source, *sets))
    for recipe in sorted(set(RECIPES.values())):
        for key in ("surface.nosuch", "material.nosuch", "simulation.alpha", "table.rays",
                    "nosection.key", "description.x"):
            out.append(case("check", f"{recipe}: unknown key {key}", "check",
                            f"@ROOT@/surfaces/{recipe}", "--set", f"{key}=1"))
    return out


WORK_KEYS = {"rays", "max_rays", "realisations", "max_realisations", "bounces", "resolution",
             "micro_resolution", "grooves", "density", "segments", "sides", "theta_bins",
             "phi_bins", "sh_order", "orders", "seed"}
"""Keys whose upper bound asks for much work: only their lower bound is simulated."""


def bound_cases() -> list[Case]:
    """Every numeric surface, simulation and table key at its schema bounds, simulated to a
    table (tightly budgeted): accepted extremes must give finite tables or one error."""
    from microsim.recipe import SIMULATION, TABLE
    from microsim.surfaces import SURFACES

    out = []
    groups = [(RECIPES[kind], "surface", SURFACES[kind].keys()) for kind in RECIPES]
    groups += [("gaussian-0.3.toml", "simulation", SIMULATION),
               ("gaussian-0.3.toml", "table", TABLE)]
    for recipe, section, keys in groups:
        for name, key in keys.items():
            if key.kind not in ("float", "int", "floats", "pair"):
                continue
            ends = []
            if key.low is not None:
                ends.append(("low", key.low * (1 + 1e-12) if key.low_open and key.low
                             else (1e-300 if key.low_open else key.low)))
            if key.high is not None and name not in WORK_KEYS:
                ends.append(("high", key.high * (1 - 1e-12) if key.high_open else key.high))
            for end, value in ends:
                v = int(value) if key.kind == "int" else float(value)
                text = repr(v) if key.kind in ("float", "int") else (
                    f"[{v!r}, {v!r}]" if key.kind == "pair" else f"[{v!r}]")
                if name == "theta_i" and end == "high":
                    text = "[0, 89.999999]"
                sets = ["--set", f"{section}.{name}={text}"]
                small = SMALL if recipe == "gaussian-0.3.toml" and section != "surface" else LIGHT
                if section in ("simulation", "table"):
                    small = tuple(a for a in small if not a.startswith(f"{section}.{name}="))
                out.append(case("simulate", f"{recipe} {section}.{name} at its {end} bound "
                                f"{text}", "simulate", f"@ROOT@/surfaces/{recipe}", *small,
                                *sets, "--rays", "400", "--memory-limit", "0.3", "-o",
                                "@HERE@/t.exr", "--json"))
    return out


def recipe_file_cases() -> list[Case]:
    """Recipe files that are not recipes, paths that are not files, bad ``--set``."""
    out = []
    for name in [*MALFORMED, *BINARY]:
        out.append(case("check", f"recipe: {name}", "check", f"@FX@/recipes/{slug(name)}.toml"))
    for name in ("unterminated string", "kind unknown", "nested 5000 deep", "a NUL byte",
                 "random bytes", "surface a string"):
        out.append(case("simulate", f"recipe: {name}", "simulate",
                        f"@FX@/recipes/{slug(name)}.toml", "-o", "@HERE@/t.exr"))
    paths = {"missing": "@HERE@/missing.toml", "a folder": "@HERE@/adir",
             "under a file": "@HERE@/afile/r.toml", "/dev/null": "/dev/null",
             "/dev/zero": "/dev/zero", "a mesh": "@FX@/tile.ply", "a table":
             "@FX@/tables/small.exr", "a long name": f"@HERE@/{LONG_NAME}.toml",
             "empty": "", "a dash": "-", "/proc/self/mem": "/proc/self/mem",
             "a FIFO": "@HERE@/fifo.toml"}
    for name, path in paths.items():
        setup = "fifo:fifo.toml" if name == "a FIFO" else None
        for command in ("check", "simulate", "generate", "measure", "view"):
            argv = {"check": ["check", path],
                    "simulate": ["simulate", path, "-o", "@HERE@/t.exr"],
                    "generate": ["generate", path, "-o", "@HERE@/t.ply"],
                    "measure": ["measure", "ndf", path],
                    "view": ["view", path, "--screenshot", "@HERE@/v.png"]}[command]
            if command != "check" and name not in ("missing", "a folder", "a FIFO",
                                                   "/dev/zero", "a table", "empty"):
                continue
            out.append(case(command, f"recipe path {name}", *argv, setup=setup))
    gaussian = "@ROOT@/surfaces/gaussian-0.3.toml"
    for text in ("surface.alpha", "=3", "surface.=3", ".alpha=3", "surface..alpha=3",
                 "surface.alpha=", "surface.alpha=[1,", "surface.alpha==3", " surface.alpha=0.3",
                 "surface.alpha=0.3 # comment", "surface.alpha=0.3\nsurface.seed=1",
                 "surface.alpha=\"0.3", "surface.alpha='a'", "surface=3", "surface.kind=",
                 "surface.kind=nosuch", "surface.alpha=" + "[" * 3000 + "]" * 3000,
                 "surface.alpha=" + "9" * 5000, "material.kind=table",
                 "material.base.kind=mirror", "material.kind={ a = 1 }",
                 "simulation.theta_i=[0, 30, 30]", "simulation.theta_i=[90]",
                 "simulation.phi_i=[360]", "simulation.theta_i=[" + ", ".join(
                     f"{x / 100:.2f}" for x in range(9000)) + "]", "table.wavelengths=[]",
                 "table.wavelengths={ start = 400, stop = 300, step = 10 }",
                 "table.wavelengths={ start = 200, stop = 5000, step = 0.001 }",
                 "table.wavelengths={ start = 400, stop = 700 }",
                 "table.wavelengths={ start = 400, stop = 700, step = -10 }",
                 "table.wavelengths={ start = nan, stop = 700, step = 10 }",
                 "table.wavelengths=[550, 550]", "surface.alpha=0.3 extra"):
        out.append(case("check", f"--set {text[:50]!r}", "check", gaussian, "--set", text))
    return out


def simulate_cases() -> list[Case]:
    """``simulate``'s flags, output paths and environment."""
    gaussian = "@ROOT@/surfaces/gaussian-0.3.toml"
    base = ("simulate", gaussian, *SMALL)
    out = []
    flags = {
        "--rays": ["0", "-3", "abc", "1e30", "2.5", "nan", "inf", "", "1e2", "99999999999999999999",
                   "1"],
        "--realisations": ["0", "-1", "1e9", "x", "4097", "4096"],
        "--target-error": ["0", "-1", "2", "nan", "inf", "x", "1e-300", "1"],
        "--max-rays": ["0", "x", "1e40", "1"],
        "--max-realisations": ["0", "1", "1e9", "x"],
        "--threads": ["0", "-1", "100000", "x", "1.5"],
        "--seed": ["-1", "x", "18446744073709551616", "1e3", "9223372036854775807"],
        "--memory-limit": ["0", "-1", "nan", "inf", "x", "1e-9", "1e300", ""],
    }
    for flag, values in flags.items():
        for value in values:
            rays = () if flag == "--rays" else ("--rays", "300")
            out.append(case("simulate", f"{flag} {value!r}", *base, *rays, flag, value,
                            "-o", "@HERE@/t.exr"))
    out.append(case("simulate", "--target-error without a bound", *base, "--target-error",
                    "0.5", "-o", "@HERE@/t.exr"))
    out.append(case("simulate", "--max-rays below --rays", *base, "--rays", "1000",
                    "--target-error", "0.5", "--max-rays", "10", "-o", "@HERE@/t.exr"))
    out.append(case("simulate", "--rays fewer than realisations", *base, "--rays", "10",
                    "--realisations", "64", "-o", "@HERE@/t.exr"))
    outputs = {"a folder": "@HERE@/adir.exr", "under a file": "@HERE@/afile/t.exr",
               "wrong suffix": "@HERE@/t.txt", "no suffix": "@HERE@/t",
               "upper-case suffix": "@HERE@/T.EXR", "a long name": f"@HERE@/{LONG_NAME}.exr",
               "240-byte name": "@HERE@/" + "a" * 236 + ".exr",
               "unicode and spaces": "@HERE@/ünï cödé.exr", "/proc": "/proc/microsim/t.exr",
               "a device": "@HERE@/full.exr", "a FIFO": "@HERE@/fifo.exr", "empty": "",
               "a dash": "-",
               "an immutable target": "@HERE@/locked.exr",
               "in an immutable folder": "@HERE@/lockeddir/t.exr",
               "new folders": "@HERE@/a/b/c/t.exr", "a trailing slash": "@HERE@/t.exr/",
               "the recipe itself": "@HERE@/r.toml", "/": "/"}
    setups = {"an immutable target": "immutable:locked.exr",
              "in an immutable folder": "immutable-folder:lockeddir",
              "a device": "device:full.exr", "a FIFO": "fifo:fifo.exr",
              "the recipe itself": "copy:@ROOT@/surfaces/gaussian-0.3.toml:r.toml"}
    for name, path in outputs.items():
        source = "@HERE@/r.toml" if name == "the recipe itself" else gaussian
        out.append(case("simulate", f"-o {name}", "simulate", source, *SMALL, "--rays",
                        "300", "-o", path, setup=setups.get(name)))
    out.append(case("simulate", "no -o: the default tables/ folder is a file", "simulate",
                    gaussian, *SMALL, "--rays", "300", setup="file:tables"))
    for value in ("0", "-1", "2", "x", "nan", "inf", "1e-300", " "):
        out.append(case("simulate", f"$MICROSIM_EFFORT {value!r}", *base, "-o",
                        "@HERE@/t.exr", env={"MICROSIM_EFFORT": value}))
    for value in ("0", "-1", "x", "nan", "inf", "1e-12", ""):
        out.append(case("simulate", f"$MICROSIM_MEMORY_LIMIT {value!r}", *base, "--rays",
                        "300", "-o", "@HERE@/t.exr", env={"MICROSIM_MEMORY_LIMIT": value}))
    for name in sorted(set(RECIPES.values()) | {"gaussian-0.3-facets.toml", "paint-metallic.toml",
                                                "paint-pearlescent.toml",
                                                "vgroove-rough-direct.toml",
                                                "vgroove-rough-facets.toml"}):
        out.append(case("simulate", f"shipped {name} at 1% effort", "simulate",
                        f"@ROOT@/surfaces/{name}", "-o", "@HERE@/t.exr", "--json",
                        limit=SLOW_TIMEOUT))
    for name in ("garbage-ply", "empty-ply", "text-ply", "nonfinite-ply", "huge-ply", "points-obj",
                 "degenerate-obj", "outside-obj", "half-ply", "tile-obj", "tile-stl"):
        out.append(case("simulate", f"mesh {name}", "simulate", f"@FX@/mesh-{name}.toml",
                        "--rays", "300", "-o", "@HERE@/t.exr"))
    table = "@FX@/tables/small.exr"
    for name, sets in {
        "table material": ["material.kind=table", f"material.path={json.dumps(table)}"],
        "table material missing": ["material.kind=table", 'material.path="gone.exr"'],
        "table material a folder": ["material.kind=table", 'material.path="/tmp"'],
        "table material damaged": ["material.kind=table",
                                   'material.path="@FX@/edited/cut-0.5.exr"'],
        "table material spectral in RGB": ["material.kind=table",
                                           'material.path="@FX@/tables/spectral.exr"'],
        "table material without sh": ["material.kind=table",
                                      'material.path="@FX@/tables/nosh.exr"'],
        "table material black": ["material.kind=table",
                                 'material.path="@FX@/tables/black.exr"'],
        "table material itself": ["material.kind=table", 'material.path="@HERE@/t.exr"'],
        "conductor data unknown": ["material.kind=conductor", 'material.data="Unobtainium"'],
        "conductor data and eta": ["material.kind=conductor", 'material.data="Au"',
                                   "material.eta=1.5"],
        "dielectric refract absorbing": ["material.kind=dielectric", "material.refract=true",
                                         "material.absorption=1e300"],
        "spectral gold": ["material.kind=conductor", 'material.data="Au"',
                          "table.wavelengths=[400, 500, 600, 700]"],
        "spectral lambertian out of data": ["material.kind=lambertian",
                                            'material.data="colorchecker_red"',
                                            "table.wavelengths=[200, 5000]"],
        "spectral 1000 wavelengths": ["table.wavelengths={ start = 300, stop = 1299, step = 1 }"],
        "spectral 1001 wavelengths": ["table.wavelengths={ start = 300, stop = 1300, step = 1 }"],
        "spectral eta of three": ["material.kind=dielectric", "material.eta=[1.4, 1.5, 1.6]",
                                  "table.wavelengths=[400, 500]"],
        "bounces 1 dielectric refract": ["material.kind=dielectric", "material.refract=true",
                                         "simulation.bounces=1"],
        "coating on a conductor": ["material.kind=conductor",
                                   "material.coating={ thickness = 300, eta = 1.4 }"],
        "coating thickness 0": ["material.kind=conductor",
                                "material.coating={ thickness = 0, eta = 1.4 }"],
        "coating eta spectrum wrong": ["material.kind=conductor",
                                       "material.coating={ thickness = 100, eta = [1, 2] }"],
        "phi_i on isotropic": ["simulation.phi_i=[0, 45, 90]"],
        "theta_i 89.99": ["simulation.theta_i=[89.99]"],
        "theta_bins 1 phi_bins 1": ["table.theta_bins=1", "table.phi_bins=1"],
        "orders 32": ["table.orders=32", "simulation.bounces=2"],
        "alpha 10": ["surface.alpha=10"],
        "alpha 0.001": ["surface.alpha=0.001"],
        "anisotropic extreme": ["surface.alpha_x=10", "surface.alpha_y=0.001"],
        "sigma and alpha": ["surface.sigma=0.1"],
        "rotation 360": ["surface.rotation=360", "surface.alpha_x=0.1", "surface.alpha_y=0.5"],
    }.items():
        args = [a for s in sets for a in ("--set", s)]
        out.append(case("simulate", name, *base, *args, "--rays", "400", "-o",
                        "@HERE@/t.exr", "--json"))
    return out


def generate_cases() -> list[Case]:
    """``generate``: outputs, seeds, memory, and extreme surfaces."""
    out = []
    gaussian = "@ROOT@/surfaces/gaussian-0.3.toml"
    for name, path in {"ply": "@HERE@/t.ply", "obj": "@HERE@/t.obj", "stl": "@HERE@/t.stl",
                       "png": "@HERE@/t.png", "no suffix": "@HERE@/t", "a folder":
                       "@HERE@/adir.ply", "under a file": "@HERE@/afile/t.ply",
                       "a long name": f"@HERE@/{LONG_NAME}.ply", "empty": "",
                       "an immutable target": "@HERE@/locked.ply", "a device": "@HERE@/full.ply",
                       "upper case": "@HERE@/T.PLY"}.items():
        setup = {"an immutable target": "immutable:locked.ply",
                 "a device": "device:full.ply"}.get(name)
        out.append(case("generate", f"-o {name}", "generate", gaussian, "--set",
                        "surface.resolution=32", "-o", path, setup=setup))
    for flag, value in (("--seed", "-1"), ("--seed", "x"), ("--seed", "1e30"),
                        ("--memory-limit", "0"), ("--memory-limit", "1e-6"),
                        ("--memory-limit", "nan"), ("--nosuch", "1")):
        out.append(case("generate", f"{flag} {value}", "generate", gaussian, flag, value,
                        "-o", "@HERE@/t.ply"))
    out.append(case("generate", "no -o", "generate", gaussian))
    for recipe, sets in (("vgroove-30.toml", "surface.grooves=1000000"),
                         ("velvet.toml", "surface.density=1e9"),
                         ("velvet.toml", "surface.fibre_length=1e9"),
                         ("cylinders.toml", "surface.segments=65536"),
                         ("weave-twill.toml", "surface.segments=1024"),
                         ("paint.toml", "surface.pigment_fraction=0.4"),
                         ("paint.toml", "surface.pigment_radius=1e-9"),
                         ("gaussian-0.3.toml", "surface.resolution=8192"),
                         ("vgroove-rough-facets.toml", "surface.micro_resolution=8192"),
                         ("velvet.toml", "surface.tilt=89"),
                         ("cylinders.toml", "surface.sink=1e9"),
                         ("weave-twill.toml", "surface.float=[16, 16]"),
                         ("paint.toml", "surface.binder_thickness=1e-9"),
                         ("mesh-example.toml", "surface.period=[1e-9, 1e-9]"),
                         ("mesh-example.toml", "surface.period=[1e9, 1e9]")):
        out.append(case("generate", f"{recipe} {sets}", "generate",
                        f"@ROOT@/surfaces/{recipe}", "--set", sets, "-o", "@HERE@/t.ply",
                        "--json"))
    for name in ("garbage-ply", "nonfinite-ply", "points-obj", "degenerate-obj", "outside-obj"):
        out.append(case("generate", f"mesh {name}", "generate", f"@FX@/mesh-{name}.toml",
                        "-o", "@HERE@/t.ply"))
    return out


def measure_cases() -> list[Case]:
    """``measure g1`` and ``measure ndf``."""
    gaussian = "@ROOT@/surfaces/gaussian-0.3.toml"
    g1 = ("measure", "g1", gaussian, "--set", "surface.resolution=32")
    ndf = ("measure", "ndf", gaussian, "--set", "surface.resolution=32")
    out = []
    for value in ("", ",", "0,,60", "91", "-1", "nan", "inf", "x", "0,90", "90", "89.9999",
                  ",".join(str(t) for t in range(90)), "0;60", "1e300", "0,0"):
        out.append(case("measure", f"g1 --theta {value[:30]!r}", *g1, "--theta", value,
                        "--rays", "300"))
    for value in ("nan", "inf", "-720", "1e300", "x", "", "0,90"):
        out.append(case("measure", f"g1 --phi {value!r}", *g1, "--phi", value, "--rays", "300"))
    for value in ("0", "-1", "x", "1e12", "1"):
        out.append(case("measure", f"g1 --rays {value}", *g1, "--rays", value))
    for value in ("0", "1", "-2", "x", "100000000", "2.5", "3"):
        out.append(case("measure", f"ndf --bins {value}", *ndf, "--bins", value))
    for name, path in (("a folder", "@HERE@/adir.png"), ("under a file", "@HERE@/afile/n.png"),
                       ("wrong suffix", "@HERE@/n.txt"), ("pdf", "@HERE@/n.pdf"),
                       ("svg", "@HERE@/n.svg"), ("a long name", f"@HERE@/{LONG_NAME}.png"),
                       ("an immutable target", "@HERE@/locked.png")):
        setup = "immutable:locked.png" if name == "an immutable target" else None
        out.append(case("measure", f"ndf --plot {name}", *ndf, "--plot", path, setup=setup))
    for flag, value in (("--memory-limit", "0"), ("--memory-limit", "1e-9"), ("--seed", "-1"),
                        ("--threads", "0")):
        out.append(case("measure", f"g1 {flag} {value}", *g1, flag, value, "--rays", "300"))
    out.append(case("measure", "no subcommand", "measure"))
    out.append(case("measure", "unknown subcommand", "measure", "brdf", gaussian))
    for recipe in ("flat-lambertian.toml", "cylinders.toml", "velvet.toml", "mesh-example.toml",
                   "weave-twill.toml", "paint.toml"):
        out.append(case("measure", f"ndf of {recipe}", "measure", "ndf",
                        f"@ROOT@/surfaces/{recipe}", "--json"))
        out.append(case("measure", f"g1 of {recipe}", "measure", "g1",
                        f"@ROOT@/surfaces/{recipe}", "--rays", "500", "--json"))
    for name in ("garbage-ply", "nonfinite-ply", "half-ply", "huge-ply"):
        out.append(case("measure", f"g1 of mesh {name}", "measure", "g1",
                        f"@FX@/mesh-{name}.toml", "--rays", "300"))
    return out


MODEL_SPECS = [
    "", ":", "nosuchmodel", "Beckmann", " beckmann ", "beckmann:", "beckmann:alpha",
    "beckmann:=0.3", "beckmann:alpha=", "beckmann:alpha=0.3,", "beckmann:alpha=0.3,,n=2",
    "beckmann:alpha=0.3,alpha=0.4", "beckmann:alpha=0", "beckmann:alpha=-1",
    "beckmann:alpha=nan", "beckmann:alpha=inf", "beckmann:alpha=1e-300", "beckmann:alpha=11",
    "beckmann:alpha=x", "beckmann:alpha=\"0.3\"", "beckmann:alpha=[0.3]", "beckmann:alpha=true",
    "beckmann:alpha_x=0.3", "beckmann:alpha_x=0.3,alpha_y=1e-4", "beckmann:nosuch=1",
    "beckmann:shadowing=nosuch", "beckmann:shadowing=1", "beckmann:eta=[1, 2]",
    "beckmann:eta=0", "beckmann:eta=1e300", "beckmann:k=-1", "beckmann:eta=[nan,1,1]",
    "beckmann:eta=" + "[" * 3000 + "]" * 3000, "beckmann:alpha=" + "9" * 5000,
    "ggx:alpha=0.3deg", "oren-nayar:sigma=20deg", "oren-nayar:sigma=0.35rad",
    "oren-nayar:sigma=91", "oren-nayar:sigma=-1", "oren-nayar:model=nosuch",
    "oren-nayar:albedo=2", "oren-nayar:albedo=[0.5, 0.5]", "lambertian:albedo=-0.1",
    "lambertian:albedo=nan", "phong:n=1e300", "phong:normalized=2", "blinn-phong:n=-1",
    "lafortune:n=1e7", "lafortune:cx=nan", "kay-kajiya:tangent_theta=200",
    "kay-kajiya:coverage=0", "kay-kajiya:coverage=2", "torrance-sparrow:ndf=nosuch",
    "torrance-sparrow:c=0", "beckmann-ms:samples=1", "beckmann-ms:samples=100000001",
    "beckmann-ms:samples=100000000", "beckmann-ms:seed=-1", "beckmann-ms:seed=1.5",
    "ggx-ms:samples=2.5", "coated-lambertian:eta=1", "cylinders:radius=0",
    "cylinders:spacing=-1", "cylinders:kind=nosuch", "microcylinder:nosuch=1", "velvet:x=1",
    "beckmann:alpha=0.3:ggx", "beckmann;alpha=0.3", "béckmann", "beckmann:alpha=0.3\n",
    "x" * 100_000,
]
"""Model specs: unknown models, malformed syntax, repeated keys, values out of range or of
another type, units a number does not take."""


def models_cases() -> list[Case]:
    """``models`` and ``models eval``."""
    out = [case("models", "list", "models"), case("models", "list --json", "models", "--json"),
           case("models", "eval without a spec", "models", "eval"),
           case("models", "unknown subcommand", "models", "fit")]
    for spec in MODEL_SPECS:
        out.append(case("models", f"eval {spec[:40]!r}", "models", "eval", spec, "--wi", "30,0",
                        "--wo", "30,180"))
    for wi, wo in (("", "30,0"), ("30", "30,0"), ("30,0,0", "30,0"), ("nan,0", "30,0"),
                   ("inf,0", "30,0"), ("90,0", "30,0"), ("91,0", "30,0"), ("-1,0", "30,0"),
                   ("30,1e300", "30,0"), ("x,y", "30,0"), ("30;0", "30,0"), ("0,0", "0,0"),
                   ("89.999999,0", "89.999999,180"), ("30,0", "90,180"), ("30,0", "-0,0")):
        out.append(case("models", f"eval --wi {wi!r} --wo {wo!r}", "models", "eval",
                        "beckmann", "--wi", wi, "--wo", wo))
    from microsim.analytic.registry import MODELS

    for name in MODELS:  # every model at a grazing pair: finite or refused
        out.append(case("models", f"eval {name} at grazing", "models", "eval", name, "--wi",
                        "89.9,0", "--wo", "89.9,180", "--json"))
    return out


TABLE_READERS = {
    "compare": ("compare", "{t}", "--model", "beckmann", "--json"),
    "fit": ("fit", "{t}", "--model", "beckmann", "--json"),
    "sh": ("sh", "{t}", "--json"),
    "export": ("export", "{t}", "--format", "rgl", "--resolution", "8", "-o", "@HERE@/t.bsdf"),
    "view": ("view", "{t}", "--screenshot", "@HERE@/v.png"),
    "render": ("render", "{t}", "-o", "@HERE@/r.png", "--size", "16x16", "--spp", "2"),
    "wavelets": ("wavelets", "{t}", "--resolution", "16", "--json"),
    "eval": ("eval", "{t}", "--wi", "30,0", "--wo", "30,180", "--basis", "sh", "--json"),
}
"""A command that reads a table, by name (``{t}``: the table)."""


def damaged_table_cases(fx: Path) -> list[Case]:
    """Every edited or truncated table through a reading command, in turn."""
    out = []
    readers = list(TABLE_READERS)
    names = sorted(p.name for p in (fx / "edited").glob("*.exr"))
    for i, name in enumerate(names):
        command = readers[i % len(readers)]  # each damaged table through one reader
        argv = [a.replace("{t}", f"@FX@/edited/{name}") for a in TABLE_READERS[command]]
        out.append(case(command, f"table {name[:-4]}", *argv))
    for command, argv in TABLE_READERS.items():
        for name, path in (("missing", "@HERE@/gone.exr"), ("a folder", "@HERE@/adir.exr"),
                           ("a recipe", "@ROOT@/surfaces/gaussian-0.3.toml"),
                           ("/dev/zero", "/dev/zero"), ("empty", ""),
                           ("a FIFO", "@HERE@/fifo.exr")):
            setup = "fifo:fifo.exr" if name == "a FIFO" else None
            out.append(case(command, f"table path {name}",
                            *[a.replace("{t}", path) for a in argv], setup=setup))
        for table in ("black", "one", "onebin", "nosh", "spectral", "aniso", "weave",
                      "wavelet"):
            out.append(case(command, f"table {table}.exr",
                            *[a.replace("{t}", f"@FX@/tables/{table}.exr") for a in argv],
                            limit=SLOW_TIMEOUT if command == "render" else TIMEOUT))
    return out


def compare_cases() -> list[Case]:
    """``compare``: model specs, components, report folders."""
    table = "@FX@/tables/small.exr"
    out = []
    for spec in MODEL_SPECS[::2] + ["oren-nayar", "lambertian", "cylinders", "kay-kajiya",
                                    "microcylinder", "velvet", "ggx-ms:samples=4"]:
        out.append(case("compare", f"--model {spec[:40]!r}", "compare", table, "--model", spec,
                        "--json"))
    for component in ("order9", "bogus", "order0", "order1+", "single", "order3+", "order2",
                      "", "TOTAL", "order-1", "order99999999999999999999"):
        out.append(case("compare", f"--component {component!r}", "compare", table, "--model",
                        "beckmann", "--component", component))
    for name, path in (("a file", "@HERE@/afile"), ("under a file", "@HERE@/afile/r"),
                       ("report.md a folder", "@HERE@/rep"), ("a plot a folder", "@HERE@/rep2"),
                       ("a long name", f"@HERE@/{LONG_NAME}"),
                       ("an immutable report", "@HERE@/rep3"), ("an immutable folder",
                                                               "@HERE@/lockeddir"),
                       ("new folders", "@HERE@/x/y/z"), ("/proc", "/proc/r")):
        setup = {"report.md a folder": "folder:rep/report.md",
                 "a plot a folder": "folder:rep2/incidence_plane.png",
                 "an immutable report": "immutable:rep3/report.md",
                 "an immutable folder": "immutable-folder:lockeddir"}.get(name)
        out.append(case("compare", f"--out {name}", "compare", table, "--model", "beckmann",
                        "--out", path, setup=setup))
    out.append(case("compare", "--out with a spectral table", "compare",
                    "@FX@/tables/spectral.exr", "--model", "beckmann", "--out", "@HERE@/rep"))
    out.append(case("compare", "spectral table, RGB eta", "compare", "@FX@/tables/spectral.exr",
                    "--model", "beckmann:eta=[1,2,3],k=[1,1,1]"))
    out.append(case("compare", "spectral table, eta of another count", "compare",
                    "@FX@/tables/spectral.exr", "--model", "beckmann:eta=[1,2],k=0"))
    out.append(case("compare", "no --model", "compare", table))
    out.append(case("compare", "two tables", "compare", table, table, "--model", "beckmann"))
    out.append(case("compare", "--memory-limit 1e-9 with a walk", "compare", table, "--model",
                    "beckmann-ms", "--memory-limit", "1e-9"))
    out.append(case("compare", "$MICROSIM_MEMORY_LIMIT tiny with a walk", "compare", table,
                    "--model", "beckmann-ms", env={"MICROSIM_MEMORY_LIMIT": "1e-6"}))
    return out


def fit_cases() -> list[Case]:
    """``fit``: model names, components, plots, hard tables."""
    table = "@FX@/tables/small.exr"
    out = []
    for model in ("nosuch", "", "lambertian", "beckmann-ms", "beckmann:alpha=0.3", "lafortune:0",
                  "lafortune:-1", "lafortune:100", "lafortune:x", "lafortune:", "lafortune:2",
                  "lafortune:1e9", "ggx", "oren-nayar", "phong", "kay-kajiya", "microcylinder",
                  "BECKMANN", "beckmann,ggx", "lafortune:3"):
        out.append(case("fit", f"--model {model!r}", "fit", table, "--model", model, "--json"))
    for model in ("beckmann", "oren-nayar", "lafortune:2", "phong", "kay-kajiya",
                  "microcylinder"):
        for t in ("black", "onebin", "one", "weave"):
            out.append(case("fit", f"{model} to {t}.exr", "fit", f"@FX@/tables/{t}.exr",
                            "--model", model, "--json"))
    for component in ("order2", "order9", "bogus", "single"):
        out.append(case("fit", f"--component {component}", "fit", table, "--model", "ggx",
                        "--component", component))
    for name, path in (("a folder", "@HERE@/adir.png"), ("under a file", "@HERE@/afile/f.png"),
                       ("wrong suffix", "@HERE@/f.txt"), ("an immutable target",
                                                          "@HERE@/locked.png"),
                       ("a long name", f"@HERE@/{LONG_NAME}.png"), ("pdf", "@HERE@/f.pdf")):
        setup = "immutable:locked.png" if name == "an immutable target" else None
        out.append(case("fit", f"--plot {name}", "fit", table, "--model", "beckmann", "--plot",
                        path, setup=setup))
    for value in ("0", "-1", "x", "1e-9"):
        out.append(case("fit", f"--memory-limit {value}", "fit", table, "--model", "beckmann",
                        "--memory-limit", value))
    return out


def sh_cases() -> list[Case]:
    """``sh``: orders, windows, plots and matrices."""
    table = "@FX@/tables/small.exr"
    out = []
    for orders in ("", ",", "0", "-1", "99", "x", "1,1", "4,2", "nan", "1e9", "4", "0,4",
                   "1.5", "5", ",".join(["1"] * 1000)):
        out.append(case("sh", f"--orders {orders[:20]!r}", "sh", table, "--orders", orders,
                        "--json"))
    for window in ("nosuch", "", "Hanning", "lanczos", "hanning"):
        out.append(case("sh", f"--window {window!r}", "sh", table, "--window", window,
                        "--json"))
    for component in ("order2", "order9", "bogus"):
        out.append(case("sh", f"--component {component}", "sh", table, "--component",
                        component))
    for flag, suffix in (("--plot", "png"), ("--matrix", "npz")):
        for name, path in (("a folder", f"@HERE@/adir.{suffix}"),
                           ("under a file", f"@HERE@/afile/x.{suffix}"),
                           ("wrong suffix", "@HERE@/x.txt"),
                           ("an immutable target", f"@HERE@/locked.{suffix}"),
                           ("a long name", f"@HERE@/{LONG_NAME}.{suffix}"),
                           ("fine", f"@HERE@/x.{suffix}")):
            setup = f"immutable:locked.{suffix}" if name == "an immutable target" else None
            out.append(case("sh", f"{flag} {name}", "sh", table, flag, path, setup=setup))
    out.append(case("sh", "--matrix of an anisotropic table", "sh", "@FX@/tables/aniso.exr",
                    "--matrix", "@HERE@/m.npz"))
    return out


def export_cases() -> list[Case]:
    """``export``: formats, suffixes, resolutions, components."""
    table = "@FX@/tables/small.exr"
    out = []
    for fmt, path in (("png", "@HERE@/t.png"), ("", "@HERE@/t.npz"), ("NPZ", "@HERE@/t.npz"),
                      ("merl", "@HERE@/t.npz"), ("rgl", "@HERE@/t.binary"),
                      ("npz", "@HERE@/t.bsdf"), ("npz", "@HERE@/t"), ("merl", "@HERE@/t.binary"),
                      ("rgl", "@HERE@/t.bsdf"), ("npz", "@HERE@/t.npz")):
        out.append(case("export", f"--format {fmt!r} -o {Path(path).name}", "export", table,
                        "--format", fmt, "-o", path, "--resolution", "8"))
    for value in ("0", "1", "2", "3", "-1", "x", "1e9", "100000", "2.5", "4"):
        out.append(case("export", f"rgl --resolution {value}", "export", table, "--format",
                        "rgl", "--resolution", value, "-o", "@HERE@/t.bsdf"))
    for component in ("single", "order2", "order9", "bogus", "order3+"):
        out.append(case("export", f"merl --component {component}", "export", table,
                        "--format", "merl", "--component", component, "-o", "@HERE@/t.binary"))
    for name, path in (("a folder", "@HERE@/adir.npz"), ("under a file", "@HERE@/afile/t.npz"),
                       ("an immutable target", "@HERE@/locked.npz"),
                       ("a long name", f"@HERE@/{LONG_NAME}.npz"), ("a device", "@HERE@/full.npz"),
                       ("240-byte name", "@HERE@/" + "a" * 236 + ".npz")):
        setup = {"an immutable target": "immutable:locked.npz",
                 "a device": "device:full.npz"}.get(name)
        out.append(case("export", f"-o {name}", "export", table, "--format", "npz", "-o", path,
                        setup=setup))
    for fmt, suffix in (("merl", "binary"), ("rgl", "bsdf"), ("npz", "npz")):
        for t in ("spectral", "aniso", "black", "onebin", "one", "nosh"):
            out.append(case("export", f"{fmt} of {t}.exr", "export", f"@FX@/tables/{t}.exr",
                            "--format", fmt, "--resolution", "8", "-o", f"@HERE@/t.{suffix}"))
    out.append(case("export", "--rgb of an RGB table", "export", table, "--format", "rgl",
                    "--rgb", "-o", "@HERE@/t.bsdf"))
    out.append(case("export", "--rgb with npz", "export", "@FX@/tables/spectral.exr", "--format",
                    "npz", "--rgb", "-o", "@HERE@/t.npz"))
    out.append(case("export", "--memory-limit 1e-9", "export", table, "--format", "merl",
                    "--memory-limit", "1e-9", "-o", "@HERE@/t.binary"))
    return out


def view_cases() -> list[Case]:
    """``view``: recipes, meshes and tables, its flags, screenshots."""
    gaussian = "@ROOT@/surfaces/gaussian-0.3.toml"
    table = "@FX@/tables/small.exr"
    shot = ("--screenshot", "@HERE@/v.png")
    out = []
    for flag, values in (("--tiles", ("0", "-1", "1000", "x", "1")),
                         ("--color", ("nosuch", "material")),
                         ("--rays", ("0", "-1", "x", "1000000000", "20")),
                         ("--seed", ("-1", "x")), ("--memory-limit", ("0", "1e-9")),
                         ("--period", ("1,1", "x"))):
        for value in values:
            out.append(case("view", f"recipe {flag} {value}", "view", gaussian, "--set",
                            "surface.resolution=32", *shot, flag, value))
    for flag, values in (("--theta-i", ("nan", "inf", "-1", "91", "90", "x", "30", "1e300")),
                         ("--phi-i", ("nan", "-720", "x", "90")),
                         ("--model", ("nosuch", "beckmann:alpha=nan", "beckmann-ms:samples=2",
                                      "oren-nayar:sigma=20deg")),
                         ("--radius", ("nosuch", "fr")), ("--log", ()),
                         ("--tiles", ("3",)), ("--rays", ("10",))):
        for value in values or (None,):
            extra = (flag,) if value is None else (flag, value)
            out.append(case("view", f"table {' '.join(extra)}", "view", table, *shot, *extra))
    out.append(case("view", "--log of a black table", "view", "@FX@/tables/black.exr", *shot,
                    "--log"))
    for name, path in (("a folder", "@HERE@/adir.png"), ("under a file", "@HERE@/afile/v.png"),
                       ("wrong suffix", "@HERE@/v.txt"), ("jpg", "@HERE@/v.jpg"),
                       ("an immutable target", "@HERE@/locked.png"),
                       ("a long name", f"@HERE@/{LONG_NAME}.png"), ("a device", "@HERE@/full.png")):
        setup = {"an immutable target": "immutable:locked.png",
                 "a device": "device:full.png"}.get(name)
        out.append(case("view", f"--screenshot {name}", "view", table, "--screenshot", path,
                        setup=setup))
    out.append(case("view", "no --screenshot without a display", "view", table,
                    env={"DISPLAY": None, "WAYLAND_DISPLAY": None}))
    for name, mesh in (("ply", "@FX@/tile.ply"), ("obj", "@FX@/tile.obj"),
                       ("garbage", "@FX@/garbage.ply"), ("empty", "@FX@/empty.ply"),
                       ("nan", "@FX@/nonfinite.ply"), ("points", "@FX@/points.obj")):
        for period in ("1,1", None, "0,1", "nan,1", "-1,1", "1"):
            if period not in ("1,1", None) and name != "ply":
                continue
            extra = () if period is None else ("--period", period)
            out.append(case("view", f"mesh {name} --period {period}", "view", mesh, *shot,
                            *extra))
    return out


def render_cases() -> list[Case]:
    """``render``: objects, lights, sizes, cameras, models, variants, ``--live``."""
    table = "@FX@/tables/small.exr"
    base = ("render", table, "-o", "@HERE@/r.png", "--size", "16x16", "--spp", "2")
    out = []
    for name, obj in (("cube", "cube"), ("missing mesh", "@HERE@/gone.ply"),
                      ("garbage mesh", "@FX@/garbage.ply"), ("a folder", "@HERE@/adir"),
                      ("empty", ""), ("nan mesh", "@FX@/nonfinite.ply"),
                      ("points", "@FX@/points.obj"),
                      ("a mesh", "@FX@/tile.ply"), ("sphere", "sphere"), ("sheet", "sheet"),
                      ("huge mesh", "@FX@/huge.ply")):
        out.append(case("render", f"--object {name}", *base, "--object", obj))
    for light in ("sun:elevation=nan", "sun:elevation=100", "sun:elevation=-10", "sky:radiance=-1",
                  "point", ":", "sun:irradiance=1e300", "sun:elevation=30,elevation=40",
                  "sun:nosuch=1", "sky", "sun", "sun:radius=0", "sun:radius=90",
                  "sky:radiance=inf", "sun:azimuth=1e300", "", "sun:elevation=x",
                  "sun:irradiance=0"):
        out.append(case("render", f"--light {light!r}", *base, "--light", light))
    for value in ("0", "-1", "x", "1000000000", "1e9"):
        out.append(case("render", f"--spp {value}", "render", table, "-o", "@HERE@/r.png",
                        "--size", "16x16", "--spp", value))
    for value in ("7x7", "4097x8", "x", "8x", "8X8", "-8x8", "8x8x8", "", "1e3x8", "100000x100000"):
        out.append(case("render", f"--size {value!r}", "render", table, "-o", "@HERE@/r.png",
                        "--spp", "2", "--size", value))
    for flag, values in (("--camera", ("nan,0", "361,0", "1", "x", "90,0", "-90,0", "inf,inf")),
                         ("--fov", ("0", "121", "nan", "1", "120")),
                         ("--rotate", ("nan", "inf", "1e300", "x", "-720")),
                         ("--seed", ("-1", "x", "18446744073709551616")),
                         ("--component", ("order9", "bogus", "single")),
                         ("--variant", ("nosuch", "scalar_spectral"))):
        for value in values:
            out.append(case("render", f"{flag} {value}", *base, flag, value))
    out.append(case("render", "--variant llvm_ad_rgb", *base, "--variant", "llvm_ad_rgb",
                    limit=SLOW_TIMEOUT))
    for models in (("beckmann",), ("beckmann", "ggx"), ("beckmann", "ggx", "phong"),
                   ("nosuch",), ("beckmann-ms",), ("oren-nayar:sigma=nan",),
                   ("lambertian:albedo=[1,1]",)):
        args = [a for m in models for a in ("--model", m)]
        out.append(case("render", f"--model {' '.join(models)}", *base, *args))
    out.append(case("render", "two tables, two models", "render", table,
                    "@FX@/tables/black.exr", "-o", "@HERE@/r.png", "--size", "16x16", "--spp",
                    "2", "--model", "beckmann", "--model", "lambertian"))
    out.append(case("render", "a table twice", "render", table, table, "-o", "@HERE@/r.png",
                    "--size", "16x16", "--spp", "2"))
    for name, path in (("a folder", "@HERE@/adir.png"), ("under a file", "@HERE@/afile/r.png"),
                       ("wrong suffix", "@HERE@/r.jpg"), ("an immutable target",
                                                          "@HERE@/locked.png"),
                       ("a long name", f"@HERE@/{LONG_NAME}.png")):
        setup = "immutable:locked.png" if name == "an immutable target" else None
        out.append(case("render", f"-o {name}", "render", table, "--size", "16x16", "--spp", "2",
                        "-o", path, setup=setup))
    gaussian = "@ROOT@/surfaces/gaussian-0.3.toml"
    live = ("render", "--live", "-o", "@HERE@/r.png", "--size", "8x8", "--spp", "2")
    for name, extra in (("a table", (table,)), ("two recipes", (gaussian, gaussian)),
                        ("spectral recipe", ("@ROOT@/surfaces/paint-pearlescent.toml",)),
                        ("--model", (gaussian, "--model", "beckmann")),
                        ("--component single", (gaussian, "--component", "single")),
                        ("--variant scalar_spectral", (gaussian, "--variant", "scalar_spectral")),
                        ("--table missing", (gaussian, "--table", "@HERE@/gone.exr")),
                        ("--table damaged", (gaussian, "--table", "@FX@/edited/cut-0.5.exr")),
                        ("--realisations 0", (gaussian, "--realisations", "0")),
                        ("--realisations 100000", (gaussian, "--realisations", "100000")),
                        ("--set bad", (gaussian, "--set", "surface.alpha=-1")),
                        ("--light sun only", (gaussian, "--light", "sun")),
                        ("missing recipe", ("@HERE@/gone.toml",))):
        out.append(case("render", f"--live {name}", *live, *extra))
    for flag, value in (("--table", table), ("--realisations", "2"),
                        ("--set", "surface.alpha=0.3")):
        out.append(case("render", f"{flag} without --live", *base, flag, value))
    out.append(case("render", "no table", "render", "-o", "@HERE@/r.png"))
    return out


def bench_cases() -> list[Case]:
    """``bench``: output folders, seeds; one quick sweep at 1% effort."""
    out = []
    for name, path in (("a file", "@HERE@/afile"), ("under a file", "@HERE@/afile/b"),
                       ("a long name", f"@HERE@/{LONG_NAME}"), ("/proc", "/proc/b"),
                       ("an immutable folder", "@HERE@/lockeddir"),
                       ("a CSV that is a folder", "@HERE@/b")):
        setup = {"an immutable folder": "immutable-folder:lockeddir",
                 "a CSV that is a folder": "folder:b/bench.csv"}.get(name)
        out.append(case("bench", f"--out {name}", "bench", "--quick", "--out", path,
                        setup=setup, limit=SLOW_TIMEOUT))
    for value in ("-1", "x", "1e30", "18446744073709551616"):
        out.append(case("bench", f"--seed {value}", "bench", "--quick", "--seed", value,
                        "--out", "@HERE@/b"))
    out.append(case("bench", "--quick at 1% effort", "bench", "--quick", "--out", "@HERE@/b",
                    "--json", limit=SLOW_TIMEOUT))
    out.append(case("bench", "unknown flag", "bench", "--fast"))
    out.append(case("bench", "$MICROSIM_EFFORT 2", "bench", "--quick", "--out", "@HERE@/b",
                    env={"MICROSIM_EFFORT": "2"}))
    return out


def batch_cases() -> list[Case]:
    """``batch``: sweep files, output folders and their state paths, schedulers, flags."""
    fine = "@FX@/sweeps/fine.toml"
    out = []
    for name in SWEEPS:
        if name == "fine":
            continue
        out.append(case("batch", f"sweep: {name}", "batch", f"@FX@/sweeps/{slug(name)}.toml",
                        "-o", "@HERE@/out", "--workers", "1", limit=SLOW_TIMEOUT))
    for name, path in (("missing", "@HERE@/gone.toml"), ("a folder", "@HERE@/adir"),
                       ("a recipe", "@ROOT@/surfaces/gaussian-0.3.toml"),
                       ("a table", "@FX@/tables/small.exr"), ("/dev/zero", "/dev/zero"),
                       ("a FIFO", "@HERE@/fifo.toml")):
        setup = "fifo:fifo.toml" if name == "a FIFO" else None
        out.append(case("batch", f"sweep path {name}", "batch", path, "-o", "@HERE@/out",
                        "--workers", "1", setup=setup, limit=SLOW_TIMEOUT))
    states = {"manifest.json a folder": "folder:out/manifest.json",
              ".batch.lock a folder": "folder:out/.batch.lock",
              "a table a folder": "folder:out/alpha=0.2.exr",
              "an immutable table": "immutable:out/alpha=0.4.exr",
              "an immutable manifest": "immutable:out/manifest.json",
              "an immutable lock": "immutable:out/.batch.lock",
              "a manifest not JSON": "text:out/manifest.json:{",
              "a manifest a list": "text:out/manifest.json:[1]",
              "a manifest with tables a list": 'text:out/manifest.json:{"tables": [1]}',
              "a manifest with NaN": 'text:out/manifest.json:{"tables": {"alpha=0.2": NaN}}',
              "a manifest entry a string": 'text:out/manifest.json:{"tables": {"alpha=0.2": "x"}}',
              "a manifest claiming a missing table":
                  'text:out/manifest.json:{"tables": {"alpha=0.2": {"status": "done", '
                  '"recipe_hash": 3, "file": "../../etc/passwd"}}}',
              "a done table truncated": "text:out/alpha=0.2.exr:partial",
              "the folder immutable": "immutable-folder:out"}
    for name, setup in states.items():
        out.append(case("batch", f"state: {name}", "batch", fine, "-o", "@HERE@/out",
                        "--workers", "1", setup=setup, limit=SLOW_TIMEOUT))
    out.append(case("batch", "state: manifest.json a folder, --no-resume", "batch", fine, "-o",
                    "@HERE@/out", "--workers", "1", "--no-resume",
                    setup="folder:out/manifest.json", limit=SLOW_TIMEOUT))
    for name, path in (("a file", "@HERE@/afile"), ("under a file", "@HERE@/afile/out"),
                       ("a long name", f"@HERE@/{LONG_NAME}"), ("/proc", "/proc/out"),
                       ("empty", "")):
        out.append(case("batch", f"-o {name}", "batch", fine, "-o", path, "--workers", "1",
                        limit=SLOW_TIMEOUT))
    for address in ("tcp://127.0.0.1:@CLOSED@", "tcp://nosuchhost.invalid:8786", "garbage", "",
                    "tcp://[::1", "inproc://x", "tcp://127.0.0.1:99999", "tcp://127.0.0.1:-1",
                    "@HERE@/adir", "@FX@/scheduler-not-json.json",
                    "@FX@/scheduler-no-address.json", "@FX@/scheduler-address-number.json",
                    "@FX@/scheduler-list.json", "@FX@/scheduler-empty.json",
                    "tcp://127.0.0.1:@SILENT@", "ucx://127.0.0.1:1", "tls://127.0.0.1:@CLOSED@"):
        out.append(case("batch", f"--scheduler {address!r}", "batch", fine, "-o", "@HERE@/out",
                        "--scheduler", address, limit=SLOW_TIMEOUT))
    for flag, value in (("--workers", "0"), ("--workers", "-1"), ("--workers", "x"),
                        ("--workers", "100000"), ("--threads", "0"), ("--threads", "x"),
                        ("--memory-limit", "0"), ("--memory-limit", "nan"),
                        ("--memory-limit", "1e-9")):
        out.append(case("batch", f"{flag} {value}", "batch", fine, "-o", "@HERE@/out", flag,
                        value, limit=SLOW_TIMEOUT))
    out.append(case("batch", "--workers with --scheduler", "batch", fine, "-o", "@HERE@/out",
                    "--workers", "1", "--scheduler", "tcp://127.0.0.1:@CLOSED@"))
    out.append(case("batch", "fine, one worker", "batch", fine, "-o", "@HERE@/out",
                    "--workers", "1", "--json", limit=SLOW_TIMEOUT))
    out.append(case("batch", "no -o", "batch", fine))
    return out


def demo_cases() -> list[Case]:
    """``demo``: outputs, plots, flags."""
    out = [case("demo", "at 1% effort", "demo", "-o", "@HERE@/d.exr", "--json",
                limit=SLOW_TIMEOUT)]
    for name, path in (("a folder", "@HERE@/adir.exr"), ("under a file", "@HERE@/afile/d.exr"),
                       ("wrong suffix", "@HERE@/d.txt"), ("an immutable target",
                                                          "@HERE@/locked.exr"),
                       ("a long name", f"@HERE@/{LONG_NAME}.exr")):
        setup = "immutable:locked.exr" if name == "an immutable target" else None
        out.append(case("demo", f"-o {name}", "demo", "-o", path, setup=setup))
    for name, path in (("a folder", "@HERE@/adir.png"), ("under a file", "@HERE@/afile/p.png"),
                       ("wrong suffix", "@HERE@/p.txt"), ("an immutable target",
                                                          "@HERE@/locked.png")):
        setup = "immutable:locked.png" if name == "an immutable target" else None
        out.append(case("demo", f"--plot {name}", "demo", "-o", "@HERE@/d.exr", "--plot", path,
                        setup=setup))
    for flag, value in (("--rays", "0"), ("--rays", "x"), ("--rays", "1e30"), ("--rays", "1"),
                        ("--threads", "0"), ("--seed", "-1"), ("--seed", "x"),
                        ("--memory-limit", "0"), ("--set", "surface.alpha=0.5")):
        out.append(case("demo", f"{flag} {value}", "demo", "-o", "@HERE@/d.exr", flag, value))
    out.append(case("demo", "no -o: tables/ is a file", "demo", setup="file:tables"))
    for value in ("0", "x", "-1"):
        out.append(case("demo", f"$MICROSIM_EFFORT {value}", "demo", "-o", "@HERE@/d.exr",
                        env={"MICROSIM_EFFORT": value}))
    return out


def wavelets_cases() -> list[Case]:
    """``wavelets``: wavelet names, resolutions, steps, storing."""
    table = "@FX@/tables/small.exr"
    base = ("wavelets", table, "--json")
    out = []
    for name in ("x", "db0", "db100", "sym1", "coif0", "bior2.2", "dmey", "haar2", "", "DB2",
                 "db2", "sym4", "coif1", "db38", "db" + "9" * 30):
        out.append(case("wavelets", f"--wavelet {name!r}", *base, "--wavelet", name,
                        "--resolution", "16"))
    for value in ("0", "1", "3", "1048576", "-4", "x", "2", "4", "16.0", "65536"):
        out.append(case("wavelets", f"--resolution {value}", *base, "--resolution", value))
    for value in ("0", "-1", "1000000000", "x", "1"):
        out.append(case("wavelets", f"--steps {value}", *base, "--steps", value, "--resolution",
                        "16"))
    for flag, values in (("--target-error", ("0", "-1", "2", "nan", "0.1")),
                         ("--keep", ("0", "-1", "1000000000", "x", "1"))):
        for value in values:
            out.append(case("wavelets", f"{flag} {value} without --store", *base, flag, value,
                            "--resolution", "16"))
            out.append(case("wavelets", f"{flag} {value} --store", *base, flag, value,
                            "--resolution", "16", "--store", "@HERE@/w.exr"))
    out.append(case("wavelets", "--keep and --target-error", *base, "--keep", "5",
                    "--target-error", "0.1", "--store", "@HERE@/w.exr"))
    for name, path in (("a folder", "@HERE@/adir.exr"), ("under a file", "@HERE@/afile/w.exr"),
                       ("wrong suffix", "@HERE@/w.npz"), ("the table itself", "@HERE@/t.exr"),
                       ("an immutable target", "@HERE@/locked.exr")):
        setup = {"the table itself": "copy:@FX@/tables/small.exr:t.exr",
                 "an immutable target": "immutable:locked.exr"}.get(name)
        source = "@HERE@/t.exr" if name == "the table itself" else table
        out.append(case("wavelets", f"--store {name}", "wavelets", source, "--keep", "10",
                        "--resolution", "16", "--store", path, setup=setup))
    for component in ("order9", "bogus", "single"):
        out.append(case("wavelets", f"--component {component}", *base, "--component", component,
                        "--resolution", "16"))
    return out


def eval_cases() -> list[Case]:
    """``eval``: directions, bases, components."""
    table = "@FX@/tables/small.exr"
    out = []
    for wi, wo in (("", "30,0"), ("30", "30,0"), ("30,0,0", "30,0"), ("nan,0", "30,0"),
                   ("inf,0", "30,0"), ("90,0", "30,0"), ("91,0", "30,0"), ("-1,0", "30,0"),
                   ("30,1e300", "30,0"), ("x,y", "30,0"), ("30;0", "30,0"), ("0,0", "0,0"),
                   ("89.99,0", "89.99,180"), ("30,0", "90,0"), ("30,-1e-300", "30,0"),
                   ("1e-300,0", "30,0"), ("30,0", "30,nan"), ("30,0", "30,-720")):
        for basis in ("table", "sh"):
            out.append(case("eval", f"--basis {basis} --wi {wi!r} --wo {wo!r}", "eval", table,
                            "--wi", wi, "--wo", wo, "--basis", basis, "--json"))
    for basis in ("x", "wavelet", "", "SH"):
        out.append(case("eval", f"--basis {basis!r}", "eval", table, "--wi", "30,0", "--wo",
                        "30,180", "--basis", basis))
    for t, basis in (("nosh", "sh"), ("wavelet", "wavelet"), ("black", "sh"),
                     ("aniso", "table"), ("spectral", "sh"), ("onebin", "table")):
        out.append(case("eval", f"{t}.exr --basis {basis}", "eval", f"@FX@/tables/{t}.exr",
                        "--wi", "30,0", "--wo", "30,180", "--basis", basis, "--json"))
    for component in ("order9", "bogus", "order3+"):
        out.append(case("eval", f"--component {component}", "eval", table, "--wi", "30,0",
                        "--wo", "30,180", "--component", component))
    out.append(case("eval", "no --wo", "eval", table, "--wi", "30,0"))
    return out


def cli_cases() -> list[Case]:
    """``microsim`` itself, and every command without its arguments or with an unknown
    flag."""
    out = [case("cli", "no command", ), case("cli", "unknown command", "simulte"),
           case("cli", "--version", "--version"), case("cli", "--help", "--help"),
           case("cli", "an empty command", ""), case("cli", "a flag only", "--json"),
           case("cli", "$MICROSIM_EFFORT x with check", "check",
                "@ROOT@/surfaces/gaussian-0.3.toml", env={"MICROSIM_EFFORT": "x"})]
    for command in COMMANDS[:-1]:
        out.append(case(command, "no arguments", command))
        out.append(case(command, "an unknown flag", command, "--no-such-flag"))
        out.append(case(command, "--help", command, "--help"))
    return out


def all_cases(fx: Path) -> list[Case]:
    """Every case, distinct, in a fixed order."""
    groups: list[Iterable[Case]] = [
        key_cases(), bound_cases(), recipe_file_cases(), simulate_cases(), generate_cases(),
        measure_cases(), models_cases(), damaged_table_cases(fx), compare_cases(), fit_cases(),
        sh_cases(), export_cases(), view_cases(), render_cases(), bench_cases(), batch_cases(),
        demo_cases(), wavelets_cases(), eval_cases(), cli_cases()]
    seen: dict[tuple, Case] = {}
    for group in groups:
        for c in group:
            seen.setdefault(c.key, c)
    return list(seen.values())


# --- running and judging -----------------------------------------------------------------------
def prepare(spec: str, here: Path) -> list[Path]:
    """Make what a case's ``setup`` names in its folder ``here``; return the paths made
    immutable (to free after the case).

    ``file:P`` a file, ``folder:P`` a folder, ``text:P:TEXT`` a file holding TEXT,
    ``copy:SRC:P`` a copy, ``fifo:P`` a named pipe, ``device:P`` a character device
    like ``/dev/full`` (never the real one: a command that replaces its output would
    replace the device), ``immutable:P`` a file that cannot be
    replaced or removed (``chattr +i``), ``immutable-folder:P`` a folder nothing can be
    created in.
    """
    kind, _, rest = spec.partition(":")
    locked = []
    if kind == "copy":
        source, _, name = rest.rpartition(":")
        target = here / name
        shutil.copy(source, target)
        return locked
    name, _, text = rest.partition(":")
    path = here / name
    path.parent.mkdir(parents=True, exist_ok=True)
    if kind == "file":
        path.write_text("x")
    elif kind == "folder":
        path.mkdir(parents=True, exist_ok=True)
    elif kind == "text":
        path.write_text(text, encoding="utf-8")
    elif kind == "fifo":
        os.mkfifo(path)
    elif kind == "device":  # a character device like /dev/full (1, 7), replaceable here
        os.mknod(path, stat.S_IFCHR | 0o666, os.makedev(1, 7))
    elif kind in ("immutable", "immutable-folder"):
        if kind == "immutable":
            path.write_bytes(b"earlier contents")
        else:
            path.mkdir(parents=True, exist_ok=True)
        subprocess.run(["chattr", "+i", str(path)], check=True)
        locked.append(path)
    else:
        raise ValueError(f"unknown setup {spec!r}")
    return locked


def unlock(paths: Iterable[Path]) -> None:
    """Free what ``prepare`` made immutable."""
    for path in paths:
        subprocess.run(["chattr", "-i", str(path)], check=False, capture_output=True)


def snapshot(folder: Path) -> dict[str, tuple[int, int]]:
    """Every file under ``folder``: relative path to (size, modification time in ns)."""
    out = {}
    for path in folder.rglob("*"):
        with contextlib.suppress(OSError):
            if path.is_file() and not path.is_symlink():
                st = path.stat()
                out[str(path.relative_to(folder))] = (st.st_size, st.st_mtime_ns)
    return out


NAN_WORD = re.compile(r"(?i)(?<![A-Za-z_])[-+]?(nan|inf|infinity)(?![A-Za-z_])")
"""A NaN or infinity written as a number in text."""


def strict_json(text: str) -> Any:
    """JSON that holds no NaN or infinity."""
    def refuse(name: str) -> None:
        raise ValueError(f"{name} in JSON")
    return json.loads(text, parse_constant=refuse)


def read_tensor_file(data: bytes) -> dict[str, np.ndarray]:
    """The fields of a Mitsuba tensor file (the RGL ``.bsdf`` format: ``tensor_file``,
    version, field count, then per field its name, dimensions, type, offset and shape)."""
    if not data.startswith(b"tensor_file\x00"):
        raise ValueError("not a tensor file")
    count = struct.unpack_from("<I", data, 14)[0]
    pos, fields = 18, {}
    types = {1: "u1", 2: "i1", 3: "u2", 4: "i2", 5: "u4", 6: "i4", 7: "u8", 8: "i8",
             9: "f2", 10: "f4", 11: "f8"}
    for _ in range(count):
        (length,) = struct.unpack_from("<H", data, pos)
        name = data[pos + 2: pos + 2 + length].decode()
        pos += 2 + length
        ndim, dtype, offset = struct.unpack_from("<HBQ", data, pos)
        pos += 11
        shape = struct.unpack_from(f"<{ndim}Q", data, pos)
        pos += 8 * ndim
        size = int(np.prod(shape))
        fields[name] = np.frombuffer(data, types[dtype], size, offset).reshape(shape)
    return fields


def check_file(path: Path) -> str | None:
    """Why a written file is not a whole, finite output of its kind (None: it is)."""
    suffix = path.suffix.lower()
    try:
        if path.name in (".batch.lock",):
            return None
        if suffix == ".exr":
            import microsim

            table = microsim.read_table(path)
            for c in table.components:
                v, e = table[c].values, table[c].errors
                if not (np.isfinite(v).all() and np.isfinite(table[c].albedo).all()):
                    return f"{c}: values or albedo not finite"
                if (np.isnan(e) & (v != 0)).any() or np.isinf(e).any():
                    return f"{c}: errors not finite where a ray landed"
        elif suffix == ".npz":
            with np.load(path, allow_pickle=False) as data:
                for key in data.files:
                    a = data[key]
                    if a.dtype.kind == "f" and (np.isinf(a).any() or (
                            "err" not in key and np.isnan(a).any())):
                        return f"array {key} not finite"
        elif suffix in (".png", ".jpg", ".jpeg"):
            from PIL import Image

            with Image.open(path) as image:
                image.load()
        elif suffix == ".pdf":
            data = path.read_bytes()
            if not data.startswith(b"%PDF") or b"%%EOF" not in data[-1024:]:
                return "not a whole PDF"
        elif suffix == ".svg":
            import xml.etree.ElementTree as ElementTree

            ElementTree.parse(path)
        elif suffix == ".json":
            strict_json(path.read_text(encoding="utf-8"))
        elif suffix in (".ply", ".obj", ".stl"):
            import trimesh

            mesh = trimesh.load(path, process=False, force="mesh")
            if len(mesh.faces) == 0 or not np.isfinite(mesh.vertices).all():
                return "no faces or vertices not finite"
        elif suffix == ".binary":
            data = path.read_bytes()
            dims = struct.unpack_from("<3i", data)
            values = np.frombuffer(data, "<f8", offset=12)
            if values.size != 3 * int(np.prod(dims)) or not np.isfinite(values).all():
                return "MERL file of the wrong size or not finite"
        elif suffix == ".bsdf":
            for name, a in read_tensor_file(path.read_bytes()).items():
                if a.dtype.kind == "f" and not np.isfinite(a).all():
                    return f"field {name} not finite"
        elif suffix in (".md", ".csv", ".txt", ""):
            text = path.read_text(encoding="utf-8")
            if NAN_WORD.search(text):
                return f"{NAN_WORD.search(text).group(0)!r} in the text"
        return None
    except Exception as exc:  # whatever a reader raises is the finding
        return f"unreadable: {type(exc).__name__}: {str(exc)[:200]}"


@dataclasses.dataclass
class Result:
    """A case's outcome: ``ok``, ``refused`` or ``table failed`` pass; the rest fail."""

    case: Case
    outcome: str
    code: int | None
    seconds: float
    detail: str = ""
    error: str = ""

    @property
    def passed(self) -> bool:
        return self.outcome in PASSING


PASSING = ("ok", "refused", "table failed")


def expand(text: str, here: Path, fx: Path, ports: dict[str, int]) -> str:
    """A case's argument with its placeholders filled in."""
    return (text.replace("@FX@", str(fx)).replace("@HERE@", str(here))
            .replace("@ROOT@", str(ROOT)).replace("@SILENT@", str(ports["silent"]))
            .replace("@CLOSED@", str(ports["closed"])))


def judge(c: Case, code: int | None, out: str, err: str, written: dict[str, str | None],
          leftovers: list[str], timed_out: bool, paths: Iterable[str] = ()
          ) -> tuple[str, str]:
    """(outcome, detail) by the command line's rule; ``paths``, the case's arguments
    that name files, are words on stdout, not numbers (a fixture named ``…-NaN.exr``)."""
    lines = [line for line in err.splitlines() if line.strip()]
    others = [line for line in lines if not line.startswith("warning:")]
    if timed_out:
        return "timeout", f"over {c.limit:g} s"
    if "Traceback (most recent call last)" in err:
        return "traceback", next((line for line in reversed(lines) if line.strip()), "")
    if leftovers:
        return "temporary left", ", ".join(leftovers)
    if code == 0:
        bad = {p: why for p, why in written.items() if why}
        if bad:
            return "bad output", "; ".join(f"{p}: {w}" for p, w in bad.items())
        if others:
            return "stray stderr", others[0][:300]
        if "--json" in c.argv and "--help" not in c.argv:
            try:
                strict_json(out)
            except ValueError as exc:
                return "bad output", f"stdout: {exc}"
        else:
            printed = out
            for path in sorted(paths, key=len, reverse=True):
                printed = printed.replace(path, "")
            if NAN_WORD.search(printed):
                return "bad output", f"stdout holds {NAN_WORD.search(printed).group(0)!r}"
        return "ok", ""
    if code == 2:
        if len(others) != 1 or not others[0].startswith("error: "):
            return "not one error line", " | ".join(others)[:400]
        if written:
            return "output of a refused run", ", ".join(written)
        return "refused", ""
    if code == 1 and c.command == "batch" and "failed: " in out:
        return "table failed", next(line for line in out.splitlines()
                                    if line.startswith("failed: "))[:300]
    return f"exit {code}", " | ".join(others)[:400]


def run_case(c: Case, index: int, work: Path, fx: Path, ports: dict[str, int]) -> Result:
    """Run one case in a fresh folder and judge it."""
    here = work / "cases" / f"{index:04d}-{slug(c.command)}"
    if here.exists():
        subprocess.run(["chattr", "-R", "-i", str(here)], check=False, capture_output=True)
        shutil.rmtree(here)
    here.mkdir(parents=True)
    for name in BASE_FILES:
        (here / name).write_text("x")
    for name in BASE_FOLDERS:
        (here / name).mkdir()
    locked = prepare(expand(c.setup, here, fx, ports), here) if c.setup else []
    before = snapshot(here)
    env = {**os.environ, "MICROSIM_EFFORT": EFFORT, "PYTHONUNBUFFERED": "1"}
    for k, v in c.env:
        if v is None:
            env.pop(k, None)
        else:
            env[k] = v
    args = [expand(a, here, fx, ports) for a in c.argv]
    argv = [sys.executable, "-m", "microsim.cli", *args]
    start = time.perf_counter()
    proc = subprocess.Popen(argv, cwd=here, env=env, stdin=subprocess.DEVNULL,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            start_new_session=True)
    timed_out = False
    try:
        out_b, err_b = proc.communicate(timeout=c.limit)
    except subprocess.TimeoutExpired:
        timed_out = True
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        out_b, err_b = proc.communicate()
    seconds = time.perf_counter() - start
    with contextlib.suppress(ProcessLookupError):
        os.killpg(proc.pid, signal.SIGKILL)  # workers a killed cluster left behind
    unlock(locked)
    out, err = out_b.decode(errors="replace"), err_b.decode(errors="replace")
    after = snapshot(here)
    changed = [p for p, stamp in after.items() if before.get(p) != stamp]
    leftovers = [p for p in after if TEMPORARY.match(Path(p).name)
                 or Path(p).name.startswith(".microsim-probe")]
    written = {p: check_file(here / p) for p in changed if p not in leftovers}
    outcome, detail = judge(c, proc.returncode if not timed_out else None, out, err, written,
                            leftovers, timed_out, [a for a in args if "/" in a])
    error = next((line for line in err.splitlines() if line.startswith("error:")), "")
    if outcome in PASSING:
        subprocess.run(["chattr", "-R", "-i", str(here)], check=False, capture_output=True)
        shutil.rmtree(here, ignore_errors=True)
    return Result(c, outcome, proc.returncode, seconds, detail, error)


@contextlib.contextmanager
def listening_ports() -> Iterator[dict[str, int]]:
    """A port that accepts connections and never speaks (``silent``) and one nothing
    listens on (``closed``), for the scheduler cases."""
    silent = socket.socket()
    silent.bind(("127.0.0.1", 0))
    silent.listen(64)
    probe = socket.socket()
    probe.bind(("127.0.0.1", 0))
    closed = probe.getsockname()[1]
    probe.close()
    try:
        yield {"silent": silent.getsockname()[1], "closed": closed}
    finally:
        silent.close()


def fixtures(work: Path) -> Path:
    """The fixtures' folder under ``work``, made once (``.done`` marks it whole)."""
    fx = work / "fixtures"
    if not (fx / ".done").exists():
        shutil.rmtree(fx, ignore_errors=True)
        write_fixtures(fx)
        (fx / ".done").write_text("")
    return fx


def run_cases(cases: list[Case], work: Path, fx: Path, jobs: int,
              progress: Callable[[int, Result], None] | None = None) -> list[Result]:
    """Run ``cases`` (``jobs`` at a time) and return their results in order."""
    results: list[Result | None] = [None] * len(cases)
    with listening_ports() as ports, concurrent.futures.ThreadPoolExecutor(jobs) as pool:
        futures = {pool.submit(run_case, c, i, work, fx, ports): i for i, c in enumerate(cases)}
        for future in concurrent.futures.as_completed(futures):
            i = futures[future]
            results[i] = future.result()
            if progress is not None:
                progress(i, results[i])
    return [r for r in results if r is not None]


def sample(cases: list[Case], n: int, seed: int = 0) -> list[Case]:
    """``n`` cases drawn with ``seed`` from those that start neither a cluster, a renderer,
    a bench, a full simulation nor a fit of the cloth model (tens of seconds): the fast
    subset the tests run. They are spread over their commands: the commands in turn give
    one case each, drawn at random from theirs, until ``n`` are drawn (so a few cases
    reach every command, not mostly ``check``'s)."""
    quick = [c for c in cases if c.command not in ("batch", "render", "bench", "demo", "view")
             and c.limit == TIMEOUT and "shipped" not in c.name and "bound" not in c.name
             and not (c.command == "fit" and "microcylinder" in c.name)]
    rng = np.random.default_rng(seed)
    pools: dict[str, list[int]] = {}
    for i, c in enumerate(quick):
        pools.setdefault(c.command, []).append(i)
    pools = {command: list(rng.permutation(pool)) for command, pool in pools.items()}
    picks: list[int] = []
    while len(picks) < min(n, len(quick)):
        for pool in pools.values():
            if pool and len(picks) < n:
                picks.append(int(pool.pop()))
    return [quick[i] for i in sorted(picks)]


# --- the summary -------------------------------------------------------------------------------
def summary(results: list[Result]) -> str:
    """Counts per command and outcome, and every failure (Markdown)."""
    outcomes = sorted({r.outcome for r in results},
                      key=lambda o: (o not in PASSING, PASSING.index(o) if o in PASSING else o))
    by = collections.Counter((r.case.command, r.outcome) for r in results)
    commands = [c for c in COMMANDS if any(r.case.command == c for r in results)]
    lines = ["| command | cases | " + " | ".join(outcomes) + " |",
             "| --- | --- | " + " | ".join("---" for _ in outcomes) + " |"]
    for command in commands:
        total = sum(by[(command, o)] for o in outcomes)
        lines.append(f"| `{command}` | {total} | "
                     + " | ".join(str(by[(command, o)]) for o in outcomes) + " |")
    totals = collections.Counter(r.outcome for r in results)
    lines.append(f"| **all** | {len(results)} | "
                 + " | ".join(str(totals[o]) for o in outcomes) + " |")
    failed = [r for r in results if not r.passed]
    lines += ["", f"{len(results) - len(failed)} of {len(results)} cases pass, "
              f"{len(failed)} fail."]
    if failed:
        lines += ["", "Failures:", ""]
        lines += [f"- `{r.case.command}` {r.case.name}: **{r.outcome}** {r.detail[:240]}"
                  for r in failed]
    batch_failed = [r for r in results if r.outcome == "table failed"]
    if batch_failed:
        lines += ["", "Tables a batch reported failed at run time (exit 1, documented):", ""]
        lines += [f"- {r.case.name}: {r.detail}" for r in batch_failed]
    return "\n".join(lines)


# --- interruption and determinism --------------------------------------------------------------
def _default_sigint() -> None:
    """SIGINT at its default action (in a child before it runs the command)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _cli(*argv: str, env: dict[str, str] | None = None, cwd: Path | None = None
         ) -> subprocess.Popen:
    """``microsim ARGV`` started in a session of its own (so its cluster can be ended),
    with SIGINT at its default: a shell's background job starts with SIGINT ignored, an
    ignored signal stays ignored across exec, and a command that ignores it would pass
    every SIGINT check by running to its end."""
    return subprocess.Popen([sys.executable, "-m", "microsim.cli", *argv], cwd=cwd,
                            env={**os.environ, **(env or {})}, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, start_new_session=True,
                            preexec_fn=_default_sigint)


def _finish(proc: subprocess.Popen, timeout: float = 600) -> tuple[int, str, str]:
    out, err = proc.communicate(timeout=timeout)
    with contextlib.suppress(ProcessLookupError):
        os.killpg(proc.pid, signal.SIGKILL)
    return proc.returncode, out.decode(errors="replace"), err.decode(errors="replace")


def _stop(proc: subprocess.Popen, sig: int, after: float) -> tuple[int, str, str]:
    """Send ``sig`` to ``proc`` after ``after`` seconds (if it still runs); its outcome.
    Its group is killed after it exits (the workers of a killed batch's cluster)."""
    try:
        proc.wait(after)
    except subprocess.TimeoutExpired:
        proc.send_signal(sig)
    code, out, err = _finish(proc)
    return code, out, err


def _temporaries(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.rglob("*") if TEMPORARY.match(p.name))


def _same_table(a: Path, b: Path) -> bool:
    """Two tables hold the same bins, errors, albedos and harmonics bit for bit."""
    import microsim

    ta, tb = microsim.read_table(a), microsim.read_table(b)
    same = all(np.array_equal(ta[c].values, tb[c].values, equal_nan=True)
               and np.array_equal(ta[c].errors, tb[c].errors, equal_nan=True)
               and np.array_equal(ta[c].albedo, tb[c].albedo) for c in ta.components)
    if ta.has_sh:
        same &= all(np.array_equal(ta[c].sh, tb[c].sh) for c in ta.components)
    return same and ta.components == tb.components


STARTUP_SIGINT = (0.1, 0.25, 0.5)
"""Seconds after ``simulate`` starts at which a SIGINT lands in its start-up: the command
line's guard is in place once ``microsim.cli`` is imported, 20 ms after the interpreter's
own start-up (on this machine a SIGINT at 0.03 s fell within that, at 0.06 s after it),
before the commands' imports and numba's load of its cached code, which take the first
0.7 s of a run. A SIGINT within the interpreter's own start-up, before any of microsim
runs, ends in Python's KeyboardInterrupt traceback."""


def interrupt_checks(work: Path) -> list[tuple[str, bool, str]]:
    """Kill and interrupt ``simulate`` and ``batch`` at several moments, resume batches,
    compare threads: (check, held, what was seen)."""
    folder = work / "interrupt"
    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir(parents=True)
    checks: list[tuple[str, bool, str]] = []
    recipe = str(SURFACES / "gaussian-0.3.toml")
    sim = ("simulate", recipe, "--set", "surface.resolution=64", "--rays", "400000",
           "--threads", "1")
    full = {"MICROSIM_EFFORT": "1"}
    earlier = folder / "earlier.exr"
    in_process("simulate", recipe, *SMALL, "--rays", "500", "-o", str(earlier), "--json")
    start = time.perf_counter()
    code, _, err = _finish(_cli(*sim, "-o", str(folder / "whole.exr"), env=full))
    whole = time.perf_counter() - start
    checks.append(("simulate runs uninterrupted", code == 0, f"{whole:.1f} s, exit {code}"))
    for sig in (signal.SIGKILL, signal.SIGINT):
        for share in (0.1, 0.5, 0.9, 0.97):
            target = folder / f"{sig.name}-{share:g}.exr"
            shutil.copy(earlier, target)
            original = target.read_bytes()
            code, _, err = _stop(_cli(*sim, "-o", str(target), env=full), sig, share * whole)
            lines = [line for line in err.splitlines() if not line.startswith("warning:")]
            kept = target.read_bytes() == original
            finished = code == 0 and _same_table(target, folder / "whole.exr")
            if sig == signal.SIGINT:
                clean = not _temporaries(folder) and (finished or (
                    code == 130 and lines == ["error: interrupted"] and kept))
            else:
                clean = finished or (code == -9 and kept)
            left = _temporaries(folder)
            # the next write of the target removes a killed writer's temporary file
            in_process("simulate", recipe, *SMALL, "--rays", "500", "-o", str(target), "--json")
            checks.append((f"simulate {sig.name} at {100 * share:g}% of its run: the earlier "
                           "table untouched (or the whole new one)", clean,
                           f"exit {code}, {'kept' if kept else 'replaced'}, temporaries "
                           f"{left or 'none'}, after the next run "
                           f"{_temporaries(folder) or 'none'}"))
    for name in _temporaries(folder):
        checks.append(("temporary removed by the next run", False, name))
    for after in STARTUP_SIGINT:
        target = folder / f"startup-{after:g}.exr"
        shutil.copy(earlier, target)
        original = target.read_bytes()
        code, _, err = _stop(_cli(*sim, "-o", str(target), env=full), signal.SIGINT, after)
        lines = [line for line in err.splitlines() if not line.startswith("warning:")]
        checks.append((f"simulate SIGINT {after:g} s after its start (imports, numba's load): "
                       "one error line, the earlier table untouched",
                       code == 130 and lines == ["error: interrupted"]
                       and target.read_bytes() == original,
                       f"exit {code}, stderr {lines[-1][:60] if lines else 'empty'}"))
    sweep = folder / "sweep.toml"
    sweep.write_text(SMALL_BASE.replace("rays = 2000", "rays = 40000") + "\n[sweep]\n"
                     '"surface.alpha" = [0.2, 0.3, 0.4, 0.5]\n"surface.seed" = [1, 2]\n',
                     encoding="utf-8")
    reference = folder / "reference"
    start = time.perf_counter()
    code, _, err = _finish(_cli("batch", str(sweep), "-o", str(reference), "--workers", "2",
                                env=full))
    whole = time.perf_counter() - start
    checks.append(("batch runs uninterrupted", code == 0, f"{whole:.1f} s, exit {code}"))
    names = sorted(p.name for p in reference.glob("*.exr"))
    for sig in (signal.SIGKILL, signal.SIGINT):
        for share in (0.3, 0.6, 0.9):
            out = folder / f"batch-{sig.name}-{share:g}"
            code, _, err = _stop(_cli("batch", str(sweep), "-o", str(out), "--workers", "2",
                                      env=full), sig, share * whole)
            lines = [line for line in err.splitlines() if not line.startswith("warning:")]
            done = sorted(p.name for p in out.glob("*.exr"))
            readable = all(check_file(out / n) is None for n in done)
            first = (f"exit {code}, {len(done)} of {len(names)} tables written, all "
                     f"{'readable' if readable else 'NOT readable'}")
            interrupted_ok = readable and (
                code == 0 or (sig == signal.SIGKILL and code == -9)
                or (sig == signal.SIGINT and code == 130 and lines == ["error: interrupted"]))
            code2, _, err2 = _finish(_cli("batch", str(sweep), "-o", str(out), "--workers", "2",
                                          env=full))
            identical = sorted(p.name for p in out.glob("*.exr")) == names and all(
                (out / n).read_bytes() == (reference / n).read_bytes() for n in names)
            left = _temporaries(out)
            checks.append((f"batch {sig.name} at {100 * share:g}% of its run, then resumed: "
                           "byte-identical tables", interrupted_ok and code2 == 0 and identical
                           and not left,
                           f"{first}; resumed: exit {code2}, "
                           f"{'identical' if identical else 'DIFFERENT'}, temporaries "
                           f"{left or 'none'}"))
    for name in ("gaussian-0.3.toml", "vgroove-30.toml", "weave-twill.toml", "paint.toml",
                 "velvet.toml"):
        paths = []
        for threads in (1, 2):
            path = folder / f"threads-{threads}-{name}.exr"
            code, _, err = _finish(_cli("simulate", str(SURFACES / name), *LIGHT, "--rays",
                                        "20000", "--threads", str(threads), "-o", str(path),
                                        env=full))
            paths.append(path if code == 0 else None)
        same = None not in paths and _same_table(*paths)
        checks.append((f"{name}: --threads 1 and 2 give the same table", same,
                       "bit for bit" if same else "DIFFERENT or failed"))
    return checks


def interrupt_text(checks: list[tuple[str, bool, str]]) -> str:
    """The checks as Markdown."""
    held = sum(ok for _, ok, _ in checks)
    lines = ["| check | held | seen |", "| --- | --- | --- |"]
    lines += [f"| {what} | {'yes' if ok else '**no**'} | {seen} |" for what, ok, seen in checks]
    return "\n".join(lines + ["", f"{held} of {len(checks)} checks hold."])


def measured_line(argv: list[str], load_before: float) -> str:
    """How and where the figures were measured (``measured_with``, run under ``nice``)."""
    return f"{measured_with(__file__, argv, load_before)}, under `nice -n 19`."


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--only", nargs="+", choices=COMMANDS, default=None,
                        help="run only the cases of these commands")
    parser.add_argument("--jobs", type=int, default=1, help="cases run at a time (default 1)")
    parser.add_argument("--work", type=Path, default=Path("/tmp/microsim-adversarial"),
                        help="folder of the fixtures and the cases (failed cases are kept)")
    parser.add_argument("--list", action="store_true", help="list the cases and stop")
    parser.add_argument("--sample", type=int, default=None, metavar="N",
                        help="run N quick cases drawn with a fixed seed (what the tests run)")
    parser.add_argument("--interrupt", action="store_true",
                        help="check interruption and determinism instead of the inputs")
    parser.add_argument("--write", action="store_true",
                        help="write the results into docs/testing.md")
    args = parser.parse_args()
    load_before = os.getloadavg()[0]
    args.work.mkdir(parents=True, exist_ok=True)
    if args.interrupt:
        text = interrupt_text(interrupt_checks(args.work))
        print(text)
        if args.write:
            write_section(DOC, "adversarial-interrupt", "\n".join([
                "### Interruption and determinism", "",
                measured_line(["--interrupt", "--write"], load_before), "", text]),
                heading="## Adversarial inputs")
        return
    fx = fixtures(args.work)
    cases = all_cases(fx)
    if args.only:
        cases = [c for c in cases if c.command in args.only]
    if args.sample is not None:
        cases = sample(cases, args.sample)
    if args.list:
        for c in cases:
            print(f"{c.command:9} {c.name}")
        print(f"{len(cases)} cases")
        return

    def show(i: int, r: Result) -> None:
        mark = "  " if r.passed else "!!"
        print(f"{mark} {r.seconds:6.1f} s {r.case.command:9} {r.outcome:22} {r.case.name[:70]}"
              + (f"  {r.detail[:200]}" if not r.passed else ""), flush=True)

    start = time.perf_counter()
    results = run_cases(cases, args.work, fx, args.jobs, show)
    with (args.work / "results.jsonl").open("w", encoding="utf-8") as f:
        for r in results:
            f.write(json.dumps({"command": r.case.command, "name": r.case.name,
                                "argv": r.case.argv, "env": r.case.env, "setup": r.case.setup,
                                "outcome": r.outcome, "code": r.code,
                                "seconds": round(r.seconds, 2), "detail": r.detail,
                                "error": r.error}) + "\n")
    text = summary(results)
    print(text)
    print(f"{time.perf_counter() - start:.0f} s in all")
    if args.write:
        argv = (["--only", *args.only] if args.only else []) + ["--write"]
        write_section(DOC, "adversarial-inputs", "\n".join([
            "### The campaign", "", measured_line(argv, load_before), "", text]),
            heading="## Adversarial inputs")


if __name__ == "__main__":
    main()
