"""What a table says about how it was made: its metadata as typed records.

``TableMeta`` is a table's ``meta``: the recipe (``microsim.settings.Recipe``), the
surface's facts over its realisations (``microsim.surfaces.facts.SurfaceFacts``), the
tables its facet materials read (``TableInput``), one ``DirectionRecord`` per incident
direction (rays, realisations, energy balance, why tracing stopped, errors), the error
model, warnings and timings. ``to_json``/``from_json`` are the one place its JSON form in
a table file (``microsim.tables.exr``) is made and read; tables written by earlier
versions read with absent fields empty (format 1's ``rel_error`` is ``rel_stderr``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from microsim.settings import Recipe
from microsim.surfaces.facts import SurfaceFacts


def _per_channel(value: Any) -> tuple[float, ...]:
    """A per-channel list of a table file (null: NaN) as floats."""
    return tuple(float("nan") if v is None else float(v) for v in value)


@dataclass(frozen=True)
class TableInput:
    """A table file a facet material read: its part, path, SHA-256 and component."""

    part: str
    path: str
    sha256: str
    component: str

    def to_json(self) -> dict[str, Any]:
        """As a table file holds it."""
        return {"part": self.part, "path": self.path, "sha256": self.sha256,
                "component": self.component}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> TableInput:
        """Inverse of ``to_json``."""
        return cls(data["part"], data["path"], data["sha256"], data["component"])


@dataclass(frozen=True)
class DirectionRecord:
    """One incident direction of a table: how it was traced and what became of its rays.

    Attributes
    ----------
    theta_i, phi_i : float
        Degrees.
    rays : int
        Rays launched, over its realisations.
    realisations : int
    rays_per_realisation : tuple of int
    lost, transmitted, absorbed : (C,) float
        Mean over the realisations of each one's fraction of the incident energy (per
        channel) lost (paths ended by the simulation), transmitted, absorbed.
    fates : mapping of str to int
        Paths per ending (``microsim.kernel.slots.FATES``).
    stop : str
        Why tracing stopped: ``"rays"`` (the planned count), ``"target_error"``,
        ``"max_rays"`` or ``"max_realisations"``.
    rel_stderr : float
        Median relative standard error over its lobe bins.
    ray_share : float
        Median share of the ray noise in the variance of those bins.
    albedo : (C,) float
        Its directional albedo (all orders).
    """

    theta_i: float
    phi_i: float
    rays: int
    realisations: int
    rays_per_realisation: tuple[int, ...]
    lost: tuple[float, ...]
    transmitted: tuple[float, ...]
    absorbed: tuple[float, ...]
    fates: Mapping[str, int]
    stop: str
    rel_stderr: float
    ray_share: float
    albedo: tuple[float, ...]

    def to_json(self) -> dict[str, Any]:
        """As a table file holds it."""
        return {"theta_i": self.theta_i, "phi_i": self.phi_i, "rays": self.rays,
                "realisations": self.realisations,
                "rays_per_realisation": list(self.rays_per_realisation),
                "lost": list(self.lost), "transmitted": list(self.transmitted),
                "absorbed": list(self.absorbed), "fates": dict(self.fates),
                "stop": self.stop, "rel_stderr": self.rel_stderr,
                "ray_share": self.ray_share, "albedo": list(self.albedo)}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> DirectionRecord:
        """Inverse of ``to_json`` (``rel_error`` of tables of format 1)."""
        nan = float("nan")

        def number(name: str) -> float:
            value = data.get(name)
            return nan if value is None else float(value)

        rays = int(data.get("rays", 0))
        return cls(number("theta_i"), number("phi_i"), rays,
                   int(data.get("realisations", 1)),
                   tuple(data.get("rays_per_realisation", [rays])),
                   _per_channel(data.get("lost", [nan] * 3)),
                   _per_channel(data.get("transmitted", [nan] * 3)),
                   _per_channel(data.get("absorbed", [nan] * 3)), dict(data.get("fates", {})),
                   data.get("stop", "rays"),
                   number("rel_stderr") if "rel_stderr" in data else number("rel_error"),
                   number("ray_share"), _per_channel(data.get("albedo", [nan] * 3)))


@dataclass(frozen=True)
class Timing:
    """How long a simulation took: wall-clock seconds in all and building tiles and
    scenes, and the tracing's rays and Embree queries per second."""

    wall_time: float
    scene_time: float
    rays_per_second: float
    segments_per_second: float


@dataclass(frozen=True, kw_only=True)
class TableMeta:
    """A table's metadata. Every field may be absent (None or empty): a table of an
    analytic model (``microsim.comparison.metrics.model_table``) holds little but its surface's
    kind.

    Attributes
    ----------
    recipe : Recipe or None
        The resolved recipe the table was simulated from.
    microsim_version : str or None
    surface : SurfaceFacts or None
        The surface's facts over its realisations.
    inputs : tuple of TableInput
        The tables its facet materials read.
    seed : int or None
        The tracer's seed.
    isotropic : bool or None
    error_model : str or None
        ``"rays"`` or ``"ensemble"`` (``microsim.tables.estimator``).
    realisations : int or None
        The most realisations of any incident direction.
    directions : tuple of DirectionRecord
        One per incident direction, in table order.
    stop : tuple of str
        The distinct stop reasons of the directions.
    segments : int or None
        Embree queries traced.
    batch : int or None
        Rays per batch of random streams.
    offset : float or None
        The secondary-ray offset of realisation 0's scene.
    tile_warnings, warnings : tuple of str
        The tiles' warnings; the table's own (lost energy).
    sources : dict of str to str
        A spectral table's: where each material spectrum it sampled comes from, by key
        (``material.<part>.data``, ``material.<part>.eta``, …: the shipped data's
        citation, a given spectrum's ``source``); empty for an RGB table.
    timing : Timing or None
        Absent from tables assembled from parts (``microsim batch``), so that they depend
        on the recipe alone.
    """

    recipe: Recipe | None = None
    microsim_version: str | None = None
    surface: SurfaceFacts | None = None
    inputs: tuple[TableInput, ...] = ()
    seed: int | None = None
    isotropic: bool | None = None
    error_model: str | None = None
    realisations: int | None = None
    directions: tuple[DirectionRecord, ...] = ()
    stop: tuple[str, ...] = ()
    segments: int | None = None
    batch: int | None = None
    offset: float | None = None
    tile_warnings: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()
    timing: Timing | None = field(default=None)
    sources: Mapping[str, str] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        """The ``meta`` entry of a table file's JSON (absent fields left out)."""
        out: dict[str, Any] = {}
        if self.recipe is not None:
            out["recipe"] = self.recipe.to_json()
        scalars = {"microsim_version": self.microsim_version, "seed": self.seed,
                   "isotropic": self.isotropic, "error_model": self.error_model,
                   "realisations": self.realisations}
        if self.surface is not None:
            out["surface"] = self.surface.to_json()
        out.update({k: v for k, v in scalars.items() if v is not None})
        if self.inputs or self.recipe is not None:
            out["inputs"] = [i.to_json() for i in self.inputs]
        if self.directions:
            out["directions"] = [d.to_json() for d in self.directions]
            out["stop"] = list(self.stop)
        for name in ("segments", "batch", "offset"):
            if getattr(self, name) is not None:
                out[name] = getattr(self, name)
        if self.directions:
            out["tile_warnings"] = list(self.tile_warnings)
        if self.directions or self.warnings:
            out["warnings"] = list(self.warnings)
        if self.sources:
            out["sources"] = dict(self.sources)
        if self.timing is not None:
            out.update(wall_time=self.timing.wall_time, scene_time=self.timing.scene_time,
                       rays_per_second=self.timing.rays_per_second,
                       segments_per_second=self.timing.segments_per_second)
        return out

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> TableMeta:
        """Inverse of ``to_json``, for a table written by any version."""
        timing = None
        if "wall_time" in data:
            timing = Timing(*(float(data.get(k, math.nan)) for k in (
                "wall_time", "scene_time", "rays_per_second", "segments_per_second")))
        recipe = data.get("recipe")
        return cls(
            recipe=None if recipe is None or "material" not in recipe
            else Recipe.from_json(recipe),
            microsim_version=data.get("microsim_version"),
            surface=None if data.get("surface") is None
            else SurfaceFacts.from_json(data["surface"]),
            inputs=tuple(TableInput.from_json(i) for i in data.get("inputs", [])),
            seed=data.get("seed"), isotropic=data.get("isotropic"),
            error_model=data.get("error_model"), realisations=data.get("realisations"),
            directions=tuple(DirectionRecord.from_json(d)
                             for d in data.get("directions", [])),
            stop=tuple(data.get("stop", ())), segments=data.get("segments"),
            batch=data.get("batch"), offset=data.get("offset"),
            tile_warnings=tuple(data.get("tile_warnings", ())),
            warnings=tuple(data.get("warnings", ())), timing=timing,
            sources={str(k): str(v) for k, v in (data.get("sources") or {}).items()})
