"""Sweeps: one TOML file names a base recipe and axes over its keys; each point is a table.

A sweep file (docs/batch.md)::

    base = "gaussian-0.3.toml"        # relative to this file, or absolute; or a [base] table
    mode = "product"                  # or "zip"
    seed = 7                          # optional: the sweep seed
    thetas_per_job = 1                # incident polar angles per job

    [sweep]
    "surface.alpha" = [0.1, 0.2, 0.4]
    "material.kind" = ["mirror", "conductor"]

Every point is resolved (``microsim.recipe.resolve_in``) when the file is loaded, so a bad
key or value is an ``InputError`` before any work starts. Pure Python, imports nothing heavy.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from microsim.errors import InputError
from microsim.files import file_digest
from microsim.recipe import SECTIONS, path_keys, read_toml, resolve_in
from microsim.schema import Key, Toml, check_section, unknown_key
from microsim.settings import Recipe
from microsim.version import __version__

OPTIONS: dict[str, Key] = {
    "description": Key("str", None, "What the sweep is for."),
    "mode": Key("str", "product", "How axes combine: every combination (product) or the "
                "i-th value of every axis together (zip).", choices=("product", "zip")),
    "seed": Key("int", None, "Sweep seed; each table's simulation.seed derives from it and "
                "the point (default: the base recipe's simulation.seed).", low=0,
                high=2**63 - 1),
    "thetas_per_job": Key("int", 1, "Incident polar angles (with all their azimuths) per "
                          "job; smaller jobs spread one table over more workers.", low=1),
}
"""Top-level keys of a sweep file besides ``base`` and ``[sweep]``."""
TOP_KEYS = ("base", "sweep", *OPTIONS)
MAX_POINTS = 1_000_000
"""Points one sweep may have: more are refused before they are enumerated (the product
of ten axes of ten values held memory until the kernel killed the batch)."""


def canonical(obj: Any) -> str:
    """Canonical JSON of ``obj``: sorted keys, no spaces; the same value gives the same text."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), ensure_ascii=True)


def recipe_hash(recipe: Recipe) -> str:
    """SHA-256 (hex) of what a table is made from.

    The canonical JSON of the resolved recipe, of the contents (SHA-256) of every file it
    names (a mesh, a table material's table; None for a file that is missing now), and of
    the microsim version: a table is recomputed when any of them changes.
    """
    inputs = {where: file_digest(path) if Path(path).is_file() else None
              for where, path in path_keys(recipe)}
    made_of = {"recipe": recipe.to_json(), "inputs": inputs, "microsim_version": __version__}
    return hashlib.sha256(canonical(made_of).encode()).hexdigest()


def point_seed(seed: int, values: Mapping[str, Toml]) -> int:
    """The seed of one sweep point: ``SeedSequence(seed, spawn_key=key)``, first 63 bits.

    Parameters
    ----------
    seed : int
        The sweep seed.
    values : mapping of str to Toml
        The point's axis values; the key is the first 128 bits of the SHA-256 of their
        canonical JSON as four 32-bit words (stable across runs and machines, unlike
        Python's salted ``hash``).

    Returns
    -------
    int
        In [0, 2**63).
    """
    digest = hashlib.sha256(canonical(dict(values)).encode()).digest()
    key = tuple(int(w) for w in np.frombuffer(digest[:16], "<u4"))
    state = np.random.SeedSequence(seed, spawn_key=key).generate_state(1, np.uint64)
    return int(state[0] >> np.uint64(1))


@dataclass(frozen=True)
class Point:
    """One table of a sweep.

    Attributes
    ----------
    name : str
        The file stem, readable: ``alpha=0.1_kind=mirror``.
    values : dict of str to Toml
        Axis key to value, as the sweep file gives it.
    recipe : Recipe
        The resolved recipe, ``simulation.seed`` set to the point's seed.
    hash : str
        ``recipe_hash(recipe)``: a table whose recipe changed is recomputed.
    """

    name: str
    values: dict[str, Toml]
    recipe: Recipe
    hash: str


@dataclass(frozen=True)
class Sweep:
    """A loaded sweep file.

    Attributes
    ----------
    path : Path
        The sweep file.
    points : list of Point
        In axis order (the last axis varies fastest in product mode).
    seed : int or None
        The sweep seed as given.
    thetas_per_job : int
    description : str
    """

    path: Path
    points: list[Point]
    seed: int | None
    thetas_per_job: int
    description: str = ""


def _label(value: Toml) -> str:
    """A value as it appears in a table's name."""
    if isinstance(value, list):
        return ",".join(_label(v) for v in value)
    if isinstance(value, bool):
        return str(value).lower()
    return repr(value) if isinstance(value, float) else str(value)


def _names(keys: list[str], combos: list[tuple[Toml, ...]]) -> list[str]:
    """Readable, file-safe names: ``<last key part>=<value>`` joined by ``_`` (the whole
    dotted key where two axes end alike)."""
    ends = [k.rsplit(".", 1)[-1] for k in keys]
    labels = [end if ends.count(end) == 1 else key for key, end in zip(keys, ends, strict=True)]
    return [re.sub(r"[^A-Za-z0-9.,=+_-]", "-", "_".join(
        f"{label}={_label(v)}" for label, v in zip(labels, combo, strict=True)))
        for combo in combos]


def _axes(raw: Any, where: str) -> dict[str, list[Toml]]:
    """Check the ``[sweep]`` table: dotted recipe keys to non-empty arrays of values."""
    if not isinstance(raw, Mapping) or not raw:
        raise InputError(f"{where}sweep: missing or empty; give a [sweep] table of axes, e.g. "
                         '"surface.alpha" = [0.1, 0.2]')
    axes = {}
    for key, values in raw.items():
        section, dot, rest = key.partition(".")
        if isinstance(values, Mapping):
            raise InputError(f'{where}sweep: "{key}" is a table; quote dotted axis keys, '
                             f'e.g. "{key}.key" = [...]')
        if not dot or not rest or section not in SECTIONS:
            raise InputError(f"{where}sweep.{key!r}: an axis must be a recipe key "
                             f"'section.key' with section one of {', '.join(SECTIONS)}")
        if not isinstance(values, list):
            raise InputError(f"{where}sweep.{key!r} = {values!r}: must be an array of values")
        if not values:
            raise InputError(f"{where}sweep.{key!r}: empty axis; give at least one value")
        for v in values:
            if isinstance(v, Mapping):
                raise InputError(f"{where}sweep.{key!r}: values must be numbers, strings, "
                                 f"booleans or arrays, got a table {v!r}")
        axes[key] = values
    return axes


def load_sweep(path: str | Path) -> Sweep:
    """Read a sweep file and resolve every point.

    Parameters
    ----------
    path : str or Path
        The sweep (TOML).

    Returns
    -------
    Sweep

    Raises
    ------
    InputError
        For the first problem: unknown key, bad option, empty axis, zip of unequal
        lengths, duplicate point, or any point whose recipe does not resolve (named).
    """
    path = Path(path)
    raw = read_toml(path)
    where = f"{path}: "
    for name in raw:
        if name not in TOP_KEYS:
            raise InputError(where + str(unknown_key("", name, TOP_KEYS)))
    options = check_section({k: v for k, v in raw.items() if k in OPTIONS}, OPTIONS, "")
    base = raw.get("base")
    if isinstance(base, str) and base:
        base_path = path.parent / base
        base_raw, folder = read_toml(base_path), base_path.parent
    elif isinstance(base, Mapping):
        base_raw, folder = dict(base), path.parent
    else:
        raise InputError(f"{where}base = {base!r}: must be a recipe file (relative to the "
                         "sweep file, or absolute) or a [base] table")
    axes = _axes(raw.get("sweep"), where)
    if "seed" in options and "simulation.seed" in axes:
        raise InputError(f"{where}seed: unused when simulation.seed is an axis (the tables "
                         "take the axis' seeds); remove one of them")
    keys = list(axes)
    if options["mode"] == "zip":
        lengths = {len(v) for v in axes.values()}
        if len(lengths) > 1:
            raise InputError(f"{where}mode = 'zip': axes have unequal lengths: "
                             + ", ".join(f"{k} {len(v)}" for k, v in axes.items()))
        combos = list(zip(*axes.values(), strict=True))
    else:
        count = math.prod(len(v) for v in axes.values())
        if count > MAX_POINTS:
            raise InputError(f"{where}sweep: {count:,} points ("
                             + " × ".join(str(len(v)) for v in axes.values())
                             + f"); at most {MAX_POINTS:,}: split it into several sweep "
                             "files")
        combos = list(itertools.product(*axes.values()))
    names = _names(keys, combos)
    seen: dict[str, int] = {}
    for i, name in enumerate(names):
        if name in seen:
            raise InputError(f"{where}sweep: points {seen[name] + 1} and {i + 1} are both "
                             f"{name!r}; every point must differ")
        seen[name] = i
    points = []
    for name, combo in zip(names, combos, strict=True):
        values = dict(zip(keys, combo, strict=True))
        overrides = [f"{k}={json.dumps(v)}" for k, v in values.items()]
        try:
            recipe = resolve_in(base_raw, folder, overrides)
        except InputError as exc:
            raise InputError(f"{where}point {name}: {exc}") from None
        if "simulation.seed" not in values:
            sweep_seed = options.get("seed", recipe.simulation.seed)
            recipe = replace(recipe, simulation=replace(
                recipe.simulation, seed=point_seed(sweep_seed, values)))
        points.append(Point(name, values, recipe, recipe_hash(recipe)))
    return Sweep(path, points, options.get("seed"), options["thetas_per_job"],
                 options.get("description", ""))
