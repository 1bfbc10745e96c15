"""Recipes: one TOML file describes one simulation.

A recipe has the sections ``[surface]``, ``[material]``, ``[simulation]`` and ``[table]``
(and an optional top-level ``description`` string). This module holds the complete schema,
validates a recipe strictly (unknown keys are errors with a did-you-mean, types and ranges
are checked, NaN and infinities are refused), fills in defaults, and applies command-line
overrides ``--set section.key=value``.

It imports nothing heavy, so ``microsim check`` and ``microsim --help`` start fast. Angles
are degrees in recipes (``unit = "deg"``); the engine converts them to radians.

The resolved recipe always has the form::

    {"description": str,
     "surface": {"kind": ..., <every key of that kind with its default>},
     "material": {<part>: {"kind": ..., <material keys>} for every part of the surface},
     "simulation": {...}, "table": {...}}
"""

from __future__ import annotations

import copy
import math
import os
import stat
import tomllib
import warnings
from collections.abc import Iterable, Mapping
from dataclasses import replace
from pathlib import Path
from typing import Any

from microsim.effort import scaled_simulation
from microsim.errors import InputError, InputWarning
from microsim.materials import MATERIALS, Material, parse_material
from microsim.schema import (
    REQUIRED,
    TOML_LIMITS,
    Key,
    Value,
    check_section,
    parse_value,
    suggest,
    unknown_key,
)
from microsim.settings import (
    SIMULATION,
    TABLE,
    Recipe,
    Simulation,
    TableSettings,
)
from microsim.spectra.channels import Channels
from microsim.surfaces import SURFACES, Surface, parse_surface

# --- materials --------------------------------------------------------------------------
MATERIAL_KINDS: dict[str, dict[str, Key]] = {kind: cls.keys() for kind, cls in MATERIALS.items()}
"""The keys of every material kind (``microsim.materials``), by kind."""

SECTIONS = ("surface", "material", "simulation", "table")
TOP_KEYS = ("description",) + SECTIONS


def _table(raw: Any, name: str) -> Mapping[str, Any]:
    if not isinstance(raw, Mapping):
        raise InputError(f"{name}: must be a table ([{name}]), got {raw!r}")
    return raw


def _materials(raw: Any, parts: tuple[str, ...]) -> dict[str, Material]:
    """Resolve ``[material]``: one material for every part, or one sub-table per part."""
    raw = _table(raw, "material")
    if not raw:
        return {part: MATERIALS["mirror"]() for part in parts}
    if "kind" in raw or not all(isinstance(v, Mapping) for v in raw.values()):
        one = parse_material(raw, "material.")
        return dict.fromkeys(parts, one)
    for name in raw:
        if name not in parts:
            raise InputError(f"material.{name}: not a part of this surface"
                             f"{suggest(name, parts)}; parts: {', '.join(parts)}")
    missing = [p for p in parts if p not in raw]
    if missing:
        raise InputError(f"material.{missing[0]}: missing; give [material.{missing[0]}] "
                         f"(parts of this surface: {', '.join(parts)}) or one [material] "
                         "for all parts")
    return {p: parse_material(_table(raw[p], f"material.{p}"), f"material.{p}.")
            for p in parts}


def _check_media(surface: Surface, materials: Mapping[str, Material]) -> None:
    """A refracting part encloses a medium with air on its faces' front side: nested media
    (a refracting part inside another's medium) are not modelled. In paint only the
    binder may refract, and a dielectric binder must (else no light reaches the
    pigment)."""
    if surface.kind != "paint":
        return
    for part in ("pigment", "substrate"):
        if materials[part].encloses_medium:
            raise InputError(f"material.{part}.refract = true: only the binder of a paint "
                             "may refract (nested media are not modelled)")
    binder = materials["binder"]
    if binder.kind == "dielectric" and not binder.encloses_medium:
        raise InputError("material.binder.refract = false: a paint's dielectric binder "
                         "must refract (set refract = true), else no light enters it")


def resolve(raw: Mapping[str, Any]) -> Recipe:
    """Validate a whole recipe and fill in every default.

    Parameters
    ----------
    raw : mapping
        The parsed TOML (after overrides).

    Returns
    -------
    Recipe
        The resolved recipe (``microsim.settings``).

    Raises
    ------
    InputError
        For the first problem found, naming the key and what is allowed.
    """
    for name in raw:
        if name not in TOP_KEYS:
            raise unknown_key("", name, TOP_KEYS)
    description = raw.get("description", "")
    if not isinstance(description, str):
        raise InputError(f"description = {description!r}: must be a string")
    if "surface" not in raw:
        raise InputError("surface: missing; a recipe needs a [surface] table with kind = "
                         + " | ".join(repr(k) for k in SURFACES))
    surface = parse_surface(_table(raw["surface"], "surface"))
    materials = _materials(raw.get("material", {}), surface.parts)
    _check_media(surface, materials)
    table = TableSettings(**check_section(_wavelength_range(_table(raw.get("table", {}),
                                                                   "table")), TABLE,
                                          "table."))
    _check_channels(materials, table.channels)
    return Recipe(description, surface, materials,
                  _simulation(raw.get("simulation", {}), surface), table)


MAX_WAVELENGTHS = 1000
"""Most wavelengths a ``{ start, stop, step }`` range may give (a table's memory grows with
its channels)."""


def _wavelength_range(table: Mapping[str, Any]) -> Mapping[str, Any]:
    """``[table]`` with ``wavelengths = { start, stop, step }`` (nm) written out as the list
    start, start + step, …, up to stop (included when a whole number of steps away)."""
    given = table.get("wavelengths")
    if not isinstance(given, Mapping):
        return table
    where = "table.wavelengths"
    if set(given) != {"start", "stop", "step"}:
        raise InputError(f"{where} = {dict(given)!r}: a range is {{ start = <nm>, stop = "
                         "<nm>, step = <nm> }, or give a list of wavelengths")
    for name in ("start", "stop", "step"):
        v = given[name]
        if isinstance(v, bool) or not isinstance(v, int | float) or not 0 < v < math.inf:
            raise InputError(f"{where}.{name} = {v!r}: must be a number of nm > 0")
    start, stop, step = (float(given[k]) for k in ("start", "stop", "step"))
    if stop < start:
        raise InputError(f"{where}.stop = {stop:g}: must be >= start = {start:g}")
    count = int(math.floor((stop - start) / step * (1 + 1e-12))) + 1
    if count > MAX_WAVELENGTHS:
        raise InputError(f"{where}: {count} wavelengths; at most {MAX_WAVELENGTHS} (a "
                         "larger step)")
    return {**table, "wavelengths": [start + k * step for k in range(count)]}


def _check_channels(materials: Mapping[str, Material], channels: Channels) -> None:
    """Every material's keys fit the table's channels: spectra (and shipped data) in a
    spectral table sampled inside their ranges, RGB triples in an RGB one."""
    shared = len({id(m) for m in materials.values()}) == 1
    for part, material in materials.items():
        where = "material." if shared else f"material.{part}."
        material.parameters(channels, where)
        material.medium(channels, where)


def _simulation(raw: Any, surface: Surface) -> Simulation:
    """Resolve ``[simulation]``; ``realisations`` defaults to the generator's choice for
    random geometry and must be 1 for deterministic geometry (every realisation would be
    the same tile: more rays, not more tiles, lower its error)."""
    sim = check_section(_table(raw, "simulation"), SIMULATION, "simulation.")
    default = surface.realisations()
    given = sim.get("realisations")
    if default is None and given is not None and given > 1:
        raise InputError(f"simulation.realisations = {given!r}: must be 1 for this "
                         f"{surface.kind} surface, whose geometry has nothing random "
                         "(every realisation would be the same tile); raise "
                         "simulation.rays instead")
    sim["realisations"] = given if given is not None else (default or 1)
    _check_rays_per_realisation(sim, given is None and default is not None)
    if sim.get("max_realisations", sim["realisations"]) < sim["realisations"]:
        raise InputError(f"simulation.max_realisations = {sim['max_realisations']!r}: must "
                         f"be >= simulation.realisations = {sim['realisations']}")
    if default is None and sim.get("max_realisations", 1) > 1:
        raise InputError(f"simulation.max_realisations = {sim['max_realisations']!r}: must "
                         f"be 1 for this {surface.kind} surface, whose geometry has "
                         "nothing random")
    return Simulation.from_json(sim)


MIN_RAYS_PER_REALISATION = 2
"""Rays each realisation traces at least: the ray variance of a bin within a realisation
(the ray share of its error, and a table of one realisation's error) is estimated from
them, with rays − 1 degrees of freedom; one ray per realisation would leave every error
undefined (NaN)."""


def _check_rays_per_realisation(sim: dict[str, Value], default: bool) -> None:
    """Refuse ``simulation.rays`` below ``MIN_RAYS_PER_REALISATION`` per realisation; when
    the realisations are the generator's default (``default``), lower them instead, with
    a warning."""
    rays, k = sim["rays"], sim["realisations"]
    least = MIN_RAYS_PER_REALISATION * k
    if rays >= least:
        return
    if default and rays >= MIN_RAYS_PER_REALISATION:
        lowered = rays // MIN_RAYS_PER_REALISATION
        warnings.warn(f"simulation.realisations: {lowered} instead of the generator's "
                      f"default {k}, so that simulation.rays = {rays} gives each realisation "
                      f"{MIN_RAYS_PER_REALISATION} rays or more (fewer leave its ray variance "
                      "undefined)", InputWarning, stacklevel=2)
        sim["realisations"] = lowered
        return
    raise InputError(f"simulation.rays = {rays}: must be >= {least} "
                     f"({MIN_RAYS_PER_REALISATION} per realisation, simulation.realisations "
                     f"= {k}; fewer leave the errors undefined)"
                     + ("; raise the rays or lower the realisations" if k > 1 else ""))


# --- loading and overrides --------------------------------------------------------------
def parse_override(text: str) -> tuple[list[str], Any]:
    """Split ``section.key=value`` into a key path and a TOML-parsed value.

    The value is read as a TOML value (``0.3``, ``[0, 45]``, ``"gold"``, ``true``); a bare
    word that is not valid TOML is taken as a string, so ``--set material.kind=mirror``
    works without quotes.

    Parameters
    ----------
    text : str
        The argument of ``--set``.

    Returns
    -------
    path : list of str
        The dotted key split at the dots, e.g. ``["surface", "alpha"]``.
    value : Any
        The parsed value.
    """
    name, sep, value = text.partition("=")
    name = name.strip()
    path = name.split(".")
    if not sep or len(path) < 2 or not all(path):
        raise InputError(f"--set {text!r}: must be section.key=value, e.g. "
                         "--set surface.alpha=0.3")
    return path, parse_value(value, f"--set {name}")


def apply_overrides(raw: dict, overrides: Iterable[str]) -> dict:
    """Return a copy of ``raw`` with every ``--set`` override applied in order."""
    out = copy.deepcopy(raw)
    for text in overrides:
        path, value = parse_override(text)
        node = out
        for i, part in enumerate(path[:-1]):
            child = node.setdefault(part, {})
            if not isinstance(child, dict):
                raise InputError(f"--set {text!r}: {'.'.join(path[:i + 1])} is not a table")
            node = child
        if path[0] == "material" and path[-1] == "kind":
            # switching a material's kind drops the old kind's parameters
            node.clear()
        node[path[-1]] = value
    return out


MAX_BYTES = 1 << 20
"""A recipe or sweep is a text file of a few kB: more than this (an endless device such as
/dev/zero, a file given by mistake) is refused before it fills the memory."""


def read_toml(path: str | Path) -> dict:
    """Parse a TOML file, turning a missing, unreadable, oversized or non-UTF-8 file or a
    syntax error into ``InputError``."""
    path = Path(path)
    try:
        # a FIFO without a writer would block the open for good: opened without waiting,
        # it reads as empty; one with a writer (a shell's <(...)) reads what it writes
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
        os.set_blocking(fd, True)
        with os.fdopen(fd, "rb") as f:
            data = f.read(MAX_BYTES + 1)
            if not data and stat.S_ISFIFO(os.fstat(f.fileno()).st_mode):
                raise InputError(f"{path}: a FIFO that nothing writes to; give a recipe "
                                 "file")
    except FileNotFoundError:
        raise InputError(f"{path}: no such file") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read: {exc.strerror or exc}") from None
    if len(data) > MAX_BYTES:
        raise InputError(f"{path}: larger than {MAX_BYTES >> 20} MiB; a recipe is a short "
                         "TOML text file")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: not UTF-8 text (byte {exc.start}); a recipe is a TOML "
                         "text file") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: not valid TOML: {exc}") from None
    except (ValueError, RecursionError):
        raise InputError(f"{path}: cannot be read: {TOML_LIMITS}") from None


def load(path: str | Path, overrides: Iterable[str] = ()) -> Recipe:
    """Read, override and resolve a recipe file.

    Parameters
    ----------
    path : str or Path
        The recipe (TOML).
    overrides : iterable of str
        ``section.key=value`` strings, applied in order.

    Returns
    -------
    Recipe
        The resolved recipe. Relative ``path`` keys (``surface.path`` of a ``mesh``
        surface, ``material.<part>.path`` of a ``table`` material) are made absolute
        against the recipe's folder.

    Raises
    ------
    InputError
        Also when a material's ``path`` names no file.
    """
    path = Path(path)
    return resolve_in(read_toml(path), path.parent, overrides)


def resolve_in(raw: Mapping[str, Any], folder: str | Path, overrides: Iterable[str] = ()
               ) -> Recipe:
    """Override and resolve a parsed recipe whose relative paths start at ``folder``.

    Parameters
    ----------
    raw : mapping
        The parsed TOML.
    folder : str or Path
        Where relative ``path`` keys point from (the recipe file's folder).
    overrides : iterable of str
        ``section.key=value`` strings, applied in order.

    Returns
    -------
    Recipe
        The resolved recipe, ``path`` keys absolute, its ``[simulation]`` at the effort
        ``$MICROSIM_EFFORT`` asks for (``microsim.effort``; unchanged when unset).

    Raises
    ------
    InputError
        Also when a material's ``path`` names no file.
    """
    raw = apply_overrides(dict(raw), overrides)
    recipe = resolve(raw)
    one = "kind" in raw.get("material", {})  # one [material] for every part

    def absolute(given: str, where: str, name: str) -> str:
        path = str((Path(folder) / given).resolve())
        if where.startswith("material") and not Path(path).is_file():
            raise InputError(f"{'material.' if one else where}{name} = {given!r}: no such "
                             f"file ({path})")
        return path

    keys = recipe.surface.keys()
    surface = replace(recipe.surface, **{k: absolute(recipe.surface.value(k), "surface.", k)
                                         for k in keys if _is_path(keys, k)})
    materials = {part: replace(m, **{k: absolute(getattr(m, k), f"material.{part}.", k)
                                     for k in m.keys() if _is_path(m.keys(), k)})
                 for part, m in recipe.material.items()}
    return replace(recipe, surface=surface, material=materials,
                   simulation=scaled_simulation(recipe.simulation, MIN_RAYS_PER_REALISATION))


def _is_path(keys: Mapping[str, Key], name: str) -> bool:
    """Whether key ``name`` of a section names a file."""
    return name in keys and keys[name].kind == "path"


def path_keys(recipe: Recipe) -> list[tuple[str, str]]:
    """The files a resolved recipe names (a mesh, a table material's table).

    Returns
    -------
    list of (where, path)
        The key's dotted name (``"surface.path"``, ``"material.<part>.path"``) and the file.
    """
    keys = recipe.surface.keys()
    out = [(f"surface.{k}", recipe.surface.value(k)) for k in keys if _is_path(keys, k)]
    out += [(f"material.{part}.{k}", getattr(m, k)) for part, m in recipe.material.items()
            for k in m.keys() if _is_path(m.keys(), k)]
    return out


def to_toml(recipe: Recipe) -> str:
    """Write a resolved recipe back as TOML (the output of ``microsim check``)."""

    def value(v: Any) -> str:
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, str):
            return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
        if isinstance(v, list):
            return "[" + ", ".join(value(x) for x in v) + "]"
        if isinstance(v, dict):  # a spectrum or a coating, as an inline table
            return "{ " + ", ".join(f"{k} = {value(x)}" for k, x in v.items()) + " }"
        return repr(v)

    data = recipe.to_json()
    lines = []
    if data["description"]:
        lines.append(f"description = {value(data['description'])}")
    for section in SECTIONS:
        body = data[section]
        if section == "material":
            for part, mat in body.items():
                lines.append(f"\n[material.{part}]")
                lines += [f"{k} = {value(v)}" for k, v in mat.items()]
            continue
        lines.append(f"\n[{section}]")
        lines += [f"{k} = {value(v)}" for k, v in body.items()]
    return "\n".join(lines).lstrip("\n") + "\n"


def schema_markdown() -> str:
    """The schema as Markdown tables: the generated part of docs/recipes.md."""

    def default(key: Key) -> str:
        if key.default is REQUIRED:
            return "required"
        if key.default is None:
            return "optional"
        if isinstance(key.default, bool):  # as TOML writes it
            return "`true`" if key.default else "`false`"
        return f"`{key.default}`"

    def rows(keys: Mapping[str, Key]) -> list[str]:
        out = ["| key | default | allowed | meaning |", "| --- | --- | --- | --- |"]
        out += [f"| `{n}` | {default(k)} | {k.allowed()} | {k.doc} |" for n, k in keys.items()]
        return out

    lines = ["## `[surface]`", "",
             "`kind` (required) chooses the generator: "
             + ", ".join(f"`{k}`" for k in SURFACES) + ".", ""]
    for kind, spec in SURFACES.items():
        lines += [f"### `kind = \"{kind}\"`", "", spec.doc, "",
                  "Parts (for `[material.<part>]`): "
                  + ", ".join(f"`{p}`" for p in spec.parts) + ".", ""]
        lines += rows(spec.keys()) + [""]
    lines += ["## `[material]`", "",
              "Either one material for every part (`[material]` with `kind`), or one "
              "sub-table per part (`[material.<part>]`). Without `[material]` every part "
              "is a `mirror`.", ""]
    for kind, cls in MATERIALS.items():
        lines += [f"### `kind = \"{kind}\"`", "", cls.doc, ""]
        lines += (rows(cls.keys()) if cls.keys() else ["No parameters."]) + [""]
    lines += ["## `[simulation]`", ""] + rows(SIMULATION) + [""]
    lines += ["## `[table]`", ""] + rows(TABLE) + [""]
    return "\n".join(lines)
