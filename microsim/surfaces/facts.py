"""What a tile reports about itself, and what a table's surface reports over its
realisations: typed records, one per generator, with their JSON form.

A generator measures its tile (realised roughness, particle fractions, fibre counts, ...)
and returns the facts as a ``TileFacts`` subclass (``Tile.facts``); the ensemble's facts
(``SurfaceFacts``, a table's ``meta.surface``) pool them over the realisations: the mean
of each numeric fact that differs between them (of squares for root-mean-square facts,
whose field says ``pool = "rms"``) with its standard error, the others as realisation 0
gives them. ``to_json``/``from_json`` are the one place their JSON form is made and read
(table files, ``--json`` outputs); ``from_json`` reads tables written before a fact
existed (absent facts are None) and a kind it does not know as plain ``TileFacts``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from microsim.schema import record_from_json, record_json


@dataclass(frozen=True)
class Roughness:
    """Walter et al. 2007's α of a surface: one value (isotropic) or one per axis.

    Parameters
    ----------
    x : float
        α, or α along the first axis.
    y : float or None
        α along the second axis; None for one isotropic value.
    """

    x: float
    y: float | None = None

    @property
    def isotropic(self) -> bool:
        """One value for every direction."""
        return self.y is None

    @property
    def alpha(self) -> float:
        """The isotropic value.

        Raises
        ------
        ValueError
            For an anisotropic roughness.
        """
        if self.y is not None:
            raise ValueError(f"an anisotropic roughness ({self.x:g}, {self.y:g}) has no "
                             "single alpha")
        return self.x

    def __float__(self) -> float:
        """``float(roughness)``: the isotropic value (``alpha``; an anisotropic roughness
        raises ValueError)."""
        return self.alpha

    @property
    def axes(self) -> tuple[float, float]:
        """(αx, αy), equal for an isotropic roughness."""
        return (self.x, self.x if self.y is None else self.y)

    def params(self) -> dict[str, float]:
        """As a model spec takes it: ``alpha``, or ``alpha_x`` and ``alpha_y``."""
        return {"alpha": self.x} if self.y is None else {"alpha_x": self.x,
                                                         "alpha_y": self.y}

    def to_json(self) -> float | list[float]:
        """A number, or [αx, αy]."""
        return self.x if self.y is None else [self.x, self.y]

    @classmethod
    def from_json(cls, value: float | Sequence[float]) -> Roughness:
        """Inverse of ``to_json``."""
        if isinstance(value, int | float):
            return cls(float(value))
        x, y = value
        return cls(float(x), float(y))


FACTS: dict[str, type[TileFacts]] = {}
"""The facts record of every generator, by ``kind`` (each registers itself: a generator's
``TileFacts`` subclass with its ``KIND``, in the generator's module or here)."""


def _fact(pool: str = "mean", roughness: bool = False) -> Any:
    """An optional fact (None: not reported); ``pool`` is how realisations pool it:
    ``"mean"``, or ``"rms"`` for root-mean-square quantities over the tile's area (α² is
    twice the mean square slope, so the averaged table's facets have α² = mean α_r²);
    ``roughness``: a ``Roughness``."""
    return field(default=None, metadata={"pool": pool, "roughness": roughness})


@dataclass(frozen=True, kw_only=True)
class TileFacts:
    """The facts every tile may report; a generator's subclass adds its own.

    Attributes
    ----------
    kind : str
        The generator (or a label such as ``"analytic"`` for a model's table).
    isotropic : bool
        Whether one incident azimuth describes the surface.
    alpha_target, alpha_realised : Roughness or None
        The roughness asked for and the one measured from the facet slopes
        (``Tile.realised_alpha``).
    alpha_target_x, alpha_target_y, alpha_realised_x, alpha_realised_y : float or None
        Their values along the (rotated) axes, where the generator reports them.
    """

    KIND: ClassVar[str] = ""
    kind: str = ""
    isotropic: bool = False
    alpha_target: Roughness | None = _fact(roughness=True)
    alpha_realised: Roughness | None = _fact("rms", roughness=True)
    alpha_target_x: float | None = _fact()
    alpha_target_y: float | None = _fact()
    alpha_realised_x: float | None = _fact("rms")
    alpha_realised_y: float | None = _fact("rms")

    def __init_subclass__(cls, **kwargs: Any) -> None:
        """Register a generator's facts record by its ``KIND`` (for ``from_json``)."""
        super().__init_subclass__(**kwargs)
        if cls.KIND:
            FACTS[cls.KIND] = cls

    def __post_init__(self) -> None:
        if not self.kind and self.KIND:
            object.__setattr__(self, "kind", self.KIND)

    def to_json(self) -> dict[str, Any]:
        """Every reported fact (None left out), roughness as numbers or pairs."""
        return record_json(self)

    @staticmethod
    def from_json(data: Mapping[str, Any]) -> TileFacts:
        """The facts of the generator ``data["kind"]`` names (unknown facts ignored)."""
        cls = FACTS.get(data.get("kind", ""), TileFacts)
        return record_from_json(cls, data, _field_value)


def _field_value(f: dataclasses.Field, value: Any) -> Any:
    """A fact read from JSON (roughness fields as ``Roughness``, lists as tuples)."""
    if value is None:
        return None
    if f.metadata.get("roughness"):
        return Roughness.from_json(value)
    if isinstance(value, list):
        return tuple(value)
    return value


@dataclass(frozen=True, kw_only=True)
class FlatFacts(TileFacts):
    """A flat tile."""

    KIND: ClassVar[str] = "flat"


@dataclass(frozen=True, kw_only=True)
class GaussianFacts(TileFacts):
    """A Gaussian height field: its RMS height, correlation lengths and rotation."""

    KIND: ClassVar[str] = "gaussian"
    sigma: float | None = _fact()
    correlation_length_x: float | None = _fact()
    correlation_length_y: float | None = _fact()
    rotation_deg: float | None = _fact()


@dataclass(frozen=True, kw_only=True)
class VGrooveFacts(TileFacts):
    """V-grooves: their slopes (``count``, ``min``, ``mean``, ``rms``, ``max``, degrees),
    and with micro-roughness its target, correlation length and realised α in the
    faces' frame."""

    KIND: ClassVar[str] = "vgroove"
    slopes_deg: Mapping[str, float] | None = _fact()
    micro_alpha_target: float | None = _fact()
    micro_correlation_length: float | None = _fact()
    micro_alpha_realised: Roughness | None = _fact("rms", roughness=True)


@dataclass(frozen=True, kw_only=True)
class FaceRoughnessFacts(TileFacts):
    """The micro-roughness of one V-groove face laid flat (``vgroove.face_roughness_tile``)."""

    KIND: ClassVar[str] = "vgroove-face-roughness"
    correlation_length: float | None = _fact()


@dataclass(frozen=True, kw_only=True)
class CylinderFacts(TileFacts):
    """Parallel cylinders: the unit vector of their axis."""

    KIND: ClassVar[str] = "cylinders"
    axis: tuple[float, float, float] | None = _fact()


@dataclass(frozen=True, kw_only=True)
class VelvetFacts(TileFacts):
    """Velvet: the fibres placed on the tile."""

    KIND: ClassVar[str] = "velvet"
    fibres: int | None = _fact()


@dataclass(frozen=True, kw_only=True)
class WeaveFacts(TileFacts):
    """A weave: yarns per pattern repeat and the crimp amplitude of their paths."""

    KIND: ClassVar[str] = "weave"
    repeat: int | None = _fact()
    crimp_amplitude: float | None = _fact()


@dataclass(frozen=True, kw_only=True)
class PaintFacts(TileFacts):
    """Paint: the binder, its particles (realised against asked for) and its top."""

    KIND: ClassVar[str] = "paint"
    binder_thickness: float | None = _fact()
    binder_volume: float | None = _fact()
    particles: int | None = _fact()
    pigment_shape: str | None = _fact()
    pigment_fraction_target: float | None = _fact()
    pigment_fraction_realised: float | None = _fact()
    pigment_radius_mean: float | None = _fact()
    top_alpha_target: float | None = _fact()
    top_alpha_realised: float | None = _fact("rms")
    top_correlation_length: float | None = _fact()
    flake_tilt_rms_target_deg: float | None = _fact()
    flake_tilt_rms_deg: float | None = _fact("rms")
    flake_tilt_rms_stderr_deg: float | None = _fact()


@dataclass(frozen=True, kw_only=True)
class MeshFacts(TileFacts):
    """An imported mesh: the file it came from."""

    KIND: ClassVar[str] = "mesh"
    source: str | None = _fact()


@dataclass(frozen=True)
class SurfaceFacts:
    """The facts of a surface over the realisations a table averages (``meta.surface``).

    Attributes
    ----------
    tile : TileFacts
        Realisation 0's facts where all realisations agree; every numeric fact that
        differs pooled (``pool``); a fact that differs and is not a number left out.
    realisations : int
        Realisations pooled.
    stderr : dict of str to Any
        The standard error of each pooled fact, by name (the delta method for RMS facts:
        se(√q) = se(q) / (2 √q); NaN for one realisation).
    per_realisation : tuple of dict
        Per realisation, its surface ``seed`` (None where unknown) and the facts that
        differ, in JSON form (empty for one realisation).
    """

    tile: TileFacts
    realisations: int = 1
    stderr: Mapping[str, Any] = field(default_factory=dict)
    per_realisation: tuple[Mapping[str, Any], ...] = ()

    @property
    def alpha_realised(self) -> Roughness | None:
        """The pooled realised roughness (None when the surface reports none)."""
        return self.tile.alpha_realised

    @property
    def alpha_realised_stderr(self) -> Roughness | None:
        """Its standard error over the realisations (None for one realisation)."""
        value = self.stderr.get("alpha_realised")
        return None if value is None else Roughness.from_json(value)

    @classmethod
    def pool(cls, facts: Sequence[TileFacts], seeds: Sequence[int | None]) -> SurfaceFacts:
        """The facts of an ensemble of tiles.

        Parameters
        ----------
        facts : sequence of TileFacts
            Of realisations 0, 1, ... in order.
        seeds : sequence of int or None
            Their surface seeds.
        """
        if len(facts) == 1:
            return cls(facts[0])
        infos = [f.to_json() for f in facts]
        varying = [k for k, v in infos[0].items()
                   if any(info.get(k) != v for info in infos[1:])]
        numeric = [k for k in varying if all(_is_number(info.get(k)) for info in infos)]
        rms = {f.name for f in dataclasses.fields(facts[0]) if f.metadata.get("pool") == "rms"}
        pooled, stderr = dict(infos[0]), {}
        for key in numeric:
            pooled[key], stderr[key] = _pool([info[key] for info in infos], key in rms)
        for key in varying:
            if key not in numeric:
                pooled.pop(key)
        per = tuple({"seed": seed, **{k: info.get(k) for k in varying}}
                    for seed, info in zip(seeds, infos, strict=True))
        return cls(TileFacts.from_json(pooled), len(facts), stderr, per)

    def to_json(self) -> dict[str, Any]:
        """``tile``'s facts, ``realisations``, ``<fact>_stderr`` of each pooled fact and
        ``per_realisation`` (for more than one realisation)."""
        out = {**self.tile.to_json(), "realisations": self.realisations}
        out.update({f"{k}_stderr": v for k, v in self.stderr.items()})
        if self.per_realisation:
            out["per_realisation"] = [dict(r) for r in self.per_realisation]
        return out

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> SurfaceFacts:
        """Inverse of ``to_json`` (a table written by any version)."""
        names = {f.name for f in dataclasses.fields(FACTS.get(data.get("kind", ""),
                                                              TileFacts))}
        stderr = {k[:-len("_stderr")]: v for k, v in data.items()
                  if k.endswith("_stderr") and k[:-len("_stderr")] in names}
        return cls(TileFacts.from_json(data), int(data.get("realisations", 1)), stderr,
                   tuple(data.get("per_realisation", ())))


def _pool(values: Sequence[Any], rms: bool) -> tuple[Any, Any]:
    """Pooled value and its standard error over realisations.

    The mean (of squares, for ``rms``) over realisations, its standard error the batch
    means' √(s² / K); for an RMS value the delta method, se(√q) = se(q) / (2 √q).
    """
    x = np.asarray(values, float)
    q = x**2 if rms else x
    mean = q.mean(axis=0)
    se = q.std(axis=0, ddof=1) / math.sqrt(len(q))
    if rms:
        root = np.sqrt(mean)
        with np.errstate(invalid="ignore", divide="ignore"):
            mean, se = root, np.where(root > 0, se / (2 * root), 0.0)
    return mean.tolist(), se.tolist()


def _is_number(x: Any) -> bool:
    """A real number or a non-empty list of them (bools excluded)."""
    if isinstance(x, list):
        return bool(x) and all(_is_number(v) for v in x)
    return isinstance(x, int | float) and not isinstance(x, bool)
