"""A resolved recipe as typed records: what the engine is asked to do, and what a table
stores of how it was made (``meta.recipe``).

``Simulation`` and ``TableSettings`` are the ``[simulation]`` and ``[table]`` sections: their
fields are the recipe keys (each with its ``schema.Key``, so docs/recipes.md and the
validator read the same definition). The ``[surface]`` section is its kind's record
(``microsim.surfaces``) and the materials are ``microsim.materials`` records.
``microsim.recipe`` makes a ``Recipe`` of a TOML file; ``to_json``/``from_json`` are the
JSON form a table file and ``microsim check --json`` hold (a table written before a key
existed reads with its default).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from microsim.materials import Material, material_from_json
from microsim.schema import key, record_from_json, record_json, schema_of
from microsim.spectra.channels import Channels
from microsim.surfaces import Surface, surface_from_json

DEFAULT_ORDERS = 3
"""Order components a table holds by default (``table.orders``): orders 1, 2 and
3-and-above."""


@dataclass(frozen=True, kw_only=True)
class Simulation:
    """The ``[simulation]`` section: incidences (degrees), rays, realisations, bounces,
    seed and the adaptive stop."""

    theta_i: tuple[float, ...] = key("floats", [0.0, 30.0, 60.0, 80.0],
                                     "Incident polar angles.", unit="deg", low=0.0,
                                     high=90.0, high_open=True, increasing=True)
    phi_i: tuple[float, ...] = key("floats", [0.0], "Incident azimuths (used for "
                                   "anisotropic surfaces).", unit="deg", low=0.0,
                                   high=360.0, high_open=True, increasing=True)
    rays: int = key("int", 200_000, "Rays launched per incident direction, over all "
                    "realisations (each traces rays / realisations, rounded up).", low=1,
                    high=10**10)
    realisations: int | None = key(
        "int", None, "Independent realisations of a surface with random geometry (tiles "
        "from seeds derived from surface.seed) the table averages; its errors then include "
        "their spread. Default: the generator's (docs/ensembles.md); 1 for deterministic "
        "geometry, which allows no more.", low=1, high=4096)
    bounces: int = key("int", 16, "Maximum scattering order; paths alive after it are "
                       "reported as lost energy.", low=1, high=10_000)
    seed: int = key("int", 0, "Seed of the tracer's random numbers.", low=0,
                    high=2**63 - 1)
    target_error: float | None = key(
        "float", None, "Adaptive stop: add rays and realisations until the median relative "
        "standard error over lobe bins is at most this (at least 1e-6: max_rays' 10^11 "
        "rays in a single bin still leave 3e-6).", low=1e-6, high=1.0)
    max_rays: int | None = key("int", None, "Adaptive stop: upper limit of rays per "
                               "incident direction (over all realisations).", low=1,
                               high=10**11)
    max_realisations: int | None = key(
        "int", None, "Adaptive stop: upper limit of realisations per incident direction "
        "(default: 64 x realisations).", low=1, high=65536)

    @property
    def realisations_or_one(self) -> int:
        """``realisations``, 1 where unset (a section not made by the recipe parser)."""
        return 1 if self.realisations is None else int(self.realisations)

    @property
    def rays_per_realisation(self) -> int:
        """``rays`` split over the realisations, rounded up."""
        return -(-int(self.rays) // self.realisations_or_one)

    def to_json(self) -> dict[str, Any]:
        """The section as a recipe holds it (unset keys left out)."""
        return record_json(self)

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Simulation:
        """Inverse of ``to_json``."""
        return record_from_json(cls, data)


@dataclass(frozen=True, kw_only=True)
class TableSettings:
    """The ``[table]`` section: outgoing bins, harmonics and order components."""

    theta_bins: int = key("int", 32, "Bins in theta_o, equal in projected solid angle "
                          "(uniform in cos^2 theta_o).", low=1, high=2048)
    phi_bins: int = key("int", 64, "Bins in phi_o - phi_i over [0, 360) degrees.", low=1,
                        high=4096)
    sh_order: int = key("int", 32, "Order L of the real spherical harmonics projected from "
                        "the escaping rays ((L+1)^2 coefficients of f_r cos theta_o per "
                        "incidence, with standard errors; docs/table-format.md); 0: none.",
                        low=0, high=64)
    orders: int = key("int", DEFAULT_ORDERS, "Scattering orders kept apart: N gives the "
                      "components order1, ..., order<N-1> and order<N>+ (N or more "
                      "scattering events) besides total, which they add up to "
                      "(docs/table-format.md).", low=2, high=32)
    wavelengths: tuple[float, ...] | None = key(
        "floats", None, "Wavelengths in nm (in vacuum) of a spectral table: one channel per "
        "wavelength instead of R, G, B, each material key sampled from its spectrum there "
        "(docs/spectral.md), or a range { start, stop, step }; absent: an RGB table.",
        low=200.0, high=5000.0,
        increasing=True)

    @property
    def channels(self) -> Channels:
        """The table's channels: RGB, or one per wavelength."""
        return Channels(None if self.wavelengths is None else tuple(self.wavelengths))

    def to_json(self) -> dict[str, Any]:
        """The section as a recipe holds it."""
        return record_json(self)

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> TableSettings:
        """Inverse of ``to_json`` (a table written before ``orders`` existed: 2, its total
        and single scattering)."""
        return record_from_json(cls, {"orders": 2, **data})


SIMULATION = schema_of(Simulation)
"""The ``[simulation]`` keys."""
TABLE = schema_of(TableSettings)
"""The ``[table]`` keys."""


@dataclass(frozen=True)
class Recipe:
    """A resolved recipe: every section validated, every default filled in.

    Attributes
    ----------
    description : str
    surface : Surface or None
        None in a table of a given tile (``microsim.measurement.simulation.simulate`` without a
        recipe).
    material : mapping of str to Material
        The material of every part of the surface.
    simulation : Simulation
    table : TableSettings
    """

    description: str
    surface: Surface | None
    material: Mapping[str, Material]
    simulation: Simulation = field(default_factory=Simulation)
    table: TableSettings = field(default_factory=TableSettings)

    def to_json(self) -> dict[str, Any]:
        """The recipe as a table's metadata and ``microsim check --json`` hold it."""
        surface = {} if self.surface is None else {"surface": self.surface.to_json()}
        return {"description": self.description, **surface,
                "material": {p: m.to_json() for p, m in self.material.items()},
                "simulation": self.simulation.to_json(), "table": self.table.to_json()}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Recipe:
        """Inverse of ``to_json`` (a table file's recipe; no validation)."""
        surface = data.get("surface")
        return cls(data.get("description", ""),
                   None if surface is None else surface_from_json(surface),
                   {p: material_from_json(m) for p, m in data.get("material", {}).items()},
                   Simulation.from_json(data.get("simulation", {})),
                   TableSettings.from_json(data.get("table", {})))
