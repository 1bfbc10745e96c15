"""What every surface kind is: its recipe keys, the rules between them, its generator and
what it tells the rest of the simulator before a tile is built.

A kind is a frozen dataclass subclass of ``Surface`` in a module of its own under
``microsim.surfaces``, registered once in the package; its fields are its ``[surface]``
keys (each with its ``schema.Key``: type, default, range, meaning), an optional key not
given is None, and its class attributes and methods say the rest:

- ``kind``, ``doc``, ``parts``: the recipe name, what it builds (docs/recipes.md), and its
  material part names (face material id ``i`` is ``parts[i]``);
- ``model_keys``: the keys that models of its geometry take as defaults of their
  parameters of the same name (``microsim.comparison.table_models``);
- ``check``: rules between keys; ``triangles``: the memory guard's estimate;
  ``realisations``: the default number of independent realisations of random geometry;
- ``build``: the periodic tile (``microsim.surfaces.tile.Tile``) with its facts record.

Lengths are in tile units (any consistent unit: the BRDF is scale-free, only ratios
matter). Angles are degrees. Importing the surface kinds loads numpy but nothing heavier:
the recipe validator reads their keys.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, TypeVar

from microsim.errors import InputError
from microsim.schema import (
    Key,
    check_section,
    key,
    key_field,
    length,
    record_from_json,
    record_json,
    schema_of,
)

if TYPE_CHECKING:
    from microsim.surfaces.tile import Tile

S = TypeVar("S", bound="Surface")

SPAN = 1e4
"""Largest ratio between two lengths of one tile (the period, heights, radii,
thicknesses, correlation lengths): the tracer offsets secondary rays by 1e-6 of the
tile's extent (microsim.measurement.scene.EPS_REL), so the smallest feature stays 100
offsets wide."""
SURFACE_ALPHA_MIN = 1e-3
"""Smallest roughness a recipe asks for: below it a surface is a mirror at every bin
resolution a table has (its lobe is narrower than 0.06 degrees)."""
DEFAULT_CELLS = 8
"""Default correlation length in grid cells (docs/conventions.md: τ = 8 cells gives G1
within 0.005 of Smith)."""


@dataclass(frozen=True, kw_only=True)
class Surface:
    """A resolved ``[surface]`` section: one subclass per kind (its fields are its keys)."""

    kind: ClassVar[str]
    doc: ClassVar[str]
    parts: ClassVar[tuple[str, ...]] = ("base",)
    model_keys: ClassVar[tuple[str, ...]] = ()
    """Keys that models of this geometry take as defaults of their parameters of the same
    name (each a key of the kind and a parameter of a model: tested)."""

    @classmethod
    def keys(cls) -> dict[str, Key]:
        """The kind's ``[surface]`` keys besides ``kind`` (its fields' ``Key``)."""
        return schema_of(cls)

    @classmethod
    def parse(cls: type[S], raw: Mapping[str, Any], where: str = "surface.") -> S:
        """Validate a section without ``kind`` against the kind's keys and its rules
        (``InputError`` naming ``where`` + the key).

        Parameters
        ----------
        raw : mapping
            The user's table, ``kind`` left out.
        where : str
            Prefix of error messages.
        """
        values = check_section(raw, cls.keys(), where)
        surface = cls(**{k: tuple(v) if isinstance(v, list) else v
                         for k, v in values.items()})
        surface.check()
        check_span(surface)
        return surface

    def check(self) -> None:
        """Rules between keys; raises ``InputError`` naming the key (none by default)."""

    def triangles(self) -> float | None:
        """Upper estimate of the tile's triangle count, for the memory guard (None:
        unknown before building, e.g. an imported mesh)."""
        return None

    def realisations(self) -> int | None:
        """For a section whose geometry is random, the default number of independent
        realisations a table averages (chosen by measurement, docs/ensembles.md); None
        for deterministic geometry."""
        return None

    def build(self) -> Tile:
        """The periodic tile this section describes."""
        raise NotImplementedError(f"surface kind {self.kind!r} has no generator")

    def value(self, name: str) -> Any:
        """The value of key ``name`` (None: an optional key not given)."""
        return getattr(self, name)

    def given(self, name: str) -> bool:
        """Whether key ``name`` has a value (given, or a default)."""
        return getattr(self, name) is not None

    def with_seed(self: S, seed: int) -> S:
        """The same section with ``seed`` replaced (a realisation's)."""
        return dataclasses.replace(self, seed=int(seed))

    def to_json(self) -> dict[str, Any]:
        """``kind`` and every key given or defaulted, as a recipe holds them (lists for
        tuples)."""
        return {"kind": self.kind, **record_json(self)}

    @classmethod
    def from_json(cls: type[S], data: Mapping[str, Any]) -> S:
        """Inverse of ``to_json`` (a table file's recipe; no validation: keys it lacks
        take their defaults, keys this kind does not know are ignored)."""
        return record_from_json(cls, data)


# --- keys more than one kind has ------------------------------------------------------
def seed_key() -> Any:
    """The ``seed`` key: the last of every kind's."""
    return key("int", 0, "Seed of the generator's random numbers.", low=0, high=2**63 - 1)


def size_key() -> Any:
    """The ``size`` key: the tile's side."""
    return key_field(length("Tile side length (period along x and y).", 1.0))


def smooth_key() -> Any:
    """The ``smooth_normals`` key of kinds whose faces approximate curved tubes."""
    return key("bool", True, "Scatter at the curved surface the faces approximate (its "
               "normal where the ray enters it: docs/surfaces.md); false keeps the flat "
               "facets.")


def roughness_key(doc: str, high: float = 10.0) -> Any:
    """An optional roughness key, alpha in [SURFACE_ALPHA_MIN, high]."""
    return key("float", None, doc, low=SURFACE_ALPHA_MIN, high=high)


def length_key(doc: str, default: Any = None, zero: bool = False) -> Any:
    """A length key's field (``schema.length``)."""
    return key_field(length(doc, default, zero))


# --- rules more than one kind has ---------------------------------------------------
def check_span(surface: Surface, where: str = "surface.") -> None:
    """The lengths of a resolved section (zeros aside) lie within a factor ``SPAN`` of
    each other; ``InputError`` names the smallest and the largest otherwise."""
    lengths = {}
    for name, spec in surface.keys().items():
        value = surface.value(name)
        if spec.unit != "length" or value is None:
            continue
        many = isinstance(value, tuple)
        for i, v in enumerate(value if many else (value,)):
            if v > 0:
                lengths[f"{name}[{i}]" if many else name] = v
    if len(lengths) < 2:
        return
    low, high = min(lengths, key=lengths.get), max(lengths, key=lengths.get)
    if lengths[high] > SPAN * lengths[low]:
        raise InputError(f"{where}{low} = {lengths[low]!r}: at most {SPAN:g} times smaller "
                         f"than {where}{high} = {lengths[high]!r} (the tracer resolves "
                         "features down to 1e-4 of the tile); rescale one of them")


def check_correlation(name: str, given: Any, tau: float, cell: float, extent: float
                      ) -> None:
    """A correlation length ``tau`` (set by key ``name``, whose value is ``given``) spans
    at least one grid cell and at most the tile's ``extent``: outside, the heights are
    white noise or one bump."""
    if not cell <= tau <= extent:
        raise InputError(f"surface.{name} = {given!r}: gives a correlation length of "
                         f"{tau:.3g}, which must lie between one grid cell ({cell:.3g}) and "
                         f"the tile ({extent:.3g})")


ENSEMBLE_AREAS = 32 * 32**2
"""Correlation areas a random height field's realisations hold together by default: 32
tiles of 32 × 32 correlation lengths (the shipped 256² tile), with which the shipped
recipe's lobe lies within 3% (median) of Torrance-Sparrow + Smith at 0-60°
(docs/performance.md)."""
MAX_DEFAULT_REALISATIONS = 64
"""The default never asks for more realisations than this (tiny tiles)."""


def area_realisations(area: float, correlation_area: float) -> int:
    """Enough realisations of tiles of ``area`` for ``ENSEMBLE_AREAS`` correlation areas
    (each ``correlation_area``), at most ``MAX_DEFAULT_REALISATIONS``."""
    areas = area / correlation_area
    return max(1, min(MAX_DEFAULT_REALISATIONS, math.ceil(ENSEMBLE_AREAS / areas - 1e-9)))
