"""The tabulated BRDF: binned f_r with standard errors, its estimator and its evaluation.

Axes are (θi, φi, θo, φo): incident directions are the product of ``theta_i`` and
``phi_i``; outgoing bins are ``HemisphereBins``. For an isotropic surface ``phi_i`` is
``[0]`` and the outgoing azimuth is relative, φo − φi. Arrays of values and errors have
shape (n_theta_i, n_phi_i, theta_bins, phi_bins, 3) (RGB).

Components split the escaping light by scattering order (bounces before escaping): a
table simulated with ``orders = N`` holds ``"total"`` (all orders) and ``"order1"``, …,
``"order{N-1}"`` and ``"order{N}+"`` (N and above), which add up to the total.
``"single"`` is another name for ``"order1"`` (single scattering).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, replace
from functools import partial
from typing import Any, TypeVar

import numpy as np

from microsim.spectra.channels import RGB, Channels
from microsim.tables import sh
from microsim.tables.binning import HemisphereBins
from microsim.tables.components import (
    ALIASES,
    canonical_component,
    order_components,
    order_range,
)
from microsim.tables.estimator import RAYS
from microsim.tables.evaluate import Axes, from_harmonics, interpolate, interpolate_error
from microsim.tables.meta import TableMeta
from microsim.tables.wavelets import Wavelets
from microsim.tables.wavelets import evaluate as evaluate_wavelets

V = TypeVar("V")
REPRESENTATIONS = ("table", "sh", "wavelet")
LOBE_FRACTION = 0.1
"""Lobe bins: where f_r (mean over RGB; a table's, or a model's bin average when a table is
compared with it) is at least this fraction of the incidence's peak."""


def lobe_of(f: np.ndarray, axis: int | tuple[int, ...],
              threshold: float = LOBE_FRACTION) -> np.ndarray:
    """Lobe bins: where ``f`` is at least ``threshold`` times its peak over ``axis`` (the
    bins of one incidence), none where that peak is not positive (nothing landed).

    Parameters
    ----------
    f : (...) float
        Bin values (a table's f_r, or a model's bin averages).
    axis : int or tuple of int
        The bin axes of ``f``.
    threshold : float
        The fraction of the peak (``LOBE_FRACTION``).

    Returns
    -------
    (...) bool
        The shape of ``f``.
    """
    peak = f.max(axis=axis, keepdims=True)
    return (f >= threshold * peak) & (peak > 0)


@dataclass(frozen=True, eq=False)
class ComponentEstimate:
    """One component of a table (the total, or a scattering order): its f_r per bin with
    standard errors, its albedo, and its harmonics and raw sums where the table has them.

    Arrays are converted to float64 on construction, the raw sums kept as given; fields
    that are None are absent for every component of a table alike.

    Parameters
    ----------
    values, errors : (a, b, nt, np, C) float
        f_r (1/sr) and its standard error; an error is NaN where it is undefined (no ray
        landed in the bin).
    albedo, albedo_err : (a, b, C) float
        Directional albedo ∫ f_r cos θo dωo of the escaping light, with its standard error.
    dof : (a, b, C) float or None
        Degrees of freedom of each bin's variance estimate per incidence and colour:
        (value − truth) / error is Student-t with them (None: the table's rays − 1). The
        albedo's and the harmonics' errors are batch means over the realisations:
        realisations − 1 degrees of freedom (rays − 1 for one).
    inflation : (a, b, C) float or None
        The pooled ratio of each bin's ensemble variance to its ray variance (NaN where
        not pooled).
    ray_errors : (a, b, nt, np, C) float or None
        The ray noise's share of ``errors`` in a fresh estimate (equal to it for one
        realisation): what more rays per realisation can still remove.
    sh, sh_err : (a, b, (L + 1)², C) float or None
        Real spherical-harmonic coefficients of f_r cos θo over ωo per incidence, and
        their standard errors (``microsim.tables.sh`` has the convention).
    sums, sums_sq : (K, a, b, nt·np, C) float or None
        Raw per-bin sums Σw, Σw² per realisation, when the table was estimated here:
        tables of the same realisations and independent rays merge exactly
        (``microsim.tables.assemble.merge``).
    sh_sums, sh_sums_sq : (K, a, b, (L + 1)², C) and (K, a, b, (2L + 1)², C) float, or None
        Raw sums Σ w Y_k and Σ w² Y_K to order 2L of a fresh estimate, merged alike.
    realisation_albedo : (R, a, b, C) float or None
        Each realisation's albedo of a fresh estimate, per direction in the order the
        realisations were added (index order): slot r of direction (l, k) holds the albedo
        of the (r + 1)-th realisation that traced it, not necessarily realisation r, and
        slots past that direction's ``realisations`` are NaN. R is the most realisations
        of any direction (``microsim.tables.assemble.EnsembleSums``).
    """

    values: np.ndarray
    errors: np.ndarray
    albedo: np.ndarray
    albedo_err: np.ndarray
    dof: np.ndarray | None = None
    inflation: np.ndarray | None = None
    ray_errors: np.ndarray | None = None
    sh: np.ndarray | None = None
    sh_err: np.ndarray | None = None
    sums: np.ndarray | None = None
    sums_sq: np.ndarray | None = None
    sh_sums: np.ndarray | None = None
    sh_sums_sq: np.ndarray | None = None
    realisation_albedo: np.ndarray | None = None

    def __post_init__(self) -> None:
        for name in _FLOAT_FIELDS:
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, np.asarray(value, float))


_FLOAT_FIELDS = ("values", "errors", "albedo", "albedo_err", "dof", "inflation",
                 "ray_errors", "sh", "sh_err", "realisation_albedo")


@dataclass(frozen=True, eq=False)
class BRDFTable:
    """A binned BRDF with per-bin standard errors, one ``ComponentEstimate`` per component.

    Immutable: ``dataclasses.replace`` makes a changed copy (``with_estimate`` for one
    component's fields).

    Parameters
    ----------
    bins : HemisphereBins
        Outgoing bins.
    theta_i : (a,) float
        Incident polar angles, radians, increasing.
    phi_i : (b,) float
        Incident azimuths, radians, increasing (``[0]`` when isotropic).
    isotropic : bool
        Outgoing azimuths are relative to the incident one.
    estimates : mapping of str to ComponentEstimate
        Per component (``"total"`` and the order components; ``"single"`` is read as
        ``"order1"``); stored by stored name in the order of ``components``, a missing
        ``dof`` filled in as rays − 1.
    rays : (a, b) int
        Rays launched per incident direction.
    lost_energy : (a, b, C) float
        The energy of paths still alive after the bounce limit or absorbed by
        transmission (per unit incident power).
    meta : TableMeta
        How the table was made (``microsim.tables.meta``: recipe, surface facts,
        directions, error model, timings).
    error_model : str
        ``"rays"``: the errors count the ray noise of one tile (one realisation, or
        deterministic geometry); ``"ensemble"``: they include the spread between the
        surface realisations the table averages (``microsim.tables.estimator``).
    realisations : (a, b) int or None
        Realisations per incident direction (default: 1).
    realisation_rays : (K, a, b) int or None
        Rays per realisation and incident direction of a fresh estimate (0: absent).
    lost : (K, a, b, C) float or None
        Raw summed lost weight per realisation of a fresh estimate.
    wavelets : Wavelets or None
        Wavelet coefficients of f_r cos θo per incidence and component, kept by magnitude
        (``microsim.tables.wavelets``; ``microsim wavelets TABLE --store``), or None.
    channels : Channels
        The channels of the arrays' last axis C (RGB, or one per wavelength).

    Attributes
    ----------
    components : tuple of str
        The stored component names, ``"total"`` first, then the orders from the lowest
        (``components_for(N)`` for a table simulated with ``orders = N``).
    """

    bins: HemisphereBins
    theta_i: np.ndarray
    phi_i: np.ndarray
    isotropic: bool
    estimates: Mapping[str, ComponentEstimate]
    rays: np.ndarray
    lost_energy: np.ndarray
    meta: TableMeta
    error_model: str = field(default=RAYS, kw_only=True)
    realisations: np.ndarray | None = field(default=None, kw_only=True)
    realisation_rays: np.ndarray | None = field(default=None, kw_only=True)
    lost: np.ndarray | None = field(default=None, kw_only=True)
    wavelets: Wavelets | None = field(default=None, kw_only=True)
    channels: Channels = field(default=RGB, kw_only=True)
    components: tuple[str, ...] = field(init=False)

    def __post_init__(self) -> None:
        put = partial(object.__setattr__, self)
        put("theta_i", np.asarray(self.theta_i, float))
        put("phi_i", np.asarray(self.phi_i, float))
        put("isotropic", bool(self.isotropic))
        put("rays", np.asarray(self.rays, np.int64))
        put("lost_energy", np.asarray(self.lost_energy, float))
        put("realisations", np.ones(self.rays.shape, np.int64) if self.realisations is None
            else np.asarray(self.realisations, np.int64))
        components = components_of(self.estimates)
        fallback = np.broadcast_to((self.rays - 1.0)[..., None],
                                   self.rays.shape + (self.channels.count,))
        put("components", components)
        put("estimates", ByComponent(
            (c, e if e.dof is not None else replace(e, dof=fallback))
            for c, e in by_component(self.estimates, components).items()))

    def __getitem__(self, name: str) -> ComponentEstimate:
        """One component's estimate, by any of its names (``"single"`` is ``"order1"``).

        Raises
        ------
        ValueError
            If the name is not a component, or not one this table holds.
        """
        return self.estimates[self.component(name)]

    def with_estimate(self, name: str, **fields: np.ndarray | None) -> BRDFTable:
        """A copy with fields of one component's estimate replaced
        (``ComponentEstimate``'s names)."""
        name = self.component(name)
        return replace(self, estimates={**self.estimates,
                                        name: replace(self.estimates[name], **fields)})

    @property
    def has_sh(self) -> bool:
        """Whether the table holds spherical harmonics with their errors."""
        total = self.estimates["total"]
        return total.sh is not None and total.sh_err is not None

    @property
    def fresh(self) -> bool:
        """Whether the table holds the raw sums of its estimate (it was estimated here,
        not read from a file)."""
        return self.estimates["total"].sums is not None

    # --- derived quantities ------------------------------------------------------------
    @property
    def sh_order(self) -> int:
        """Order L of the stored spherical harmonics (0 when there are none)."""
        if not self.has_sh:
            return 0
        return sh.order_of(self.estimates["total"].sh.shape[-2])

    @property
    def albedo(self) -> np.ndarray:
        """(a, b, 3) directional albedo of all escaping light (all orders)."""
        return self.estimates["total"].albedo

    @property
    def albedo_err(self) -> np.ndarray:
        """(a, b, 3) standard error of ``albedo``."""
        return self.estimates["total"].albedo_err

    @property
    def single_albedo(self) -> np.ndarray:
        """(a, b, 3) directional albedo of single scattering."""
        return self["order1"].albedo

    @property
    def single_albedo_err(self) -> np.ndarray:
        """(a, b, 3) standard error of ``single_albedo``."""
        return self["order1"].albedo_err

    @property
    def orders(self) -> int | None:
        """N when the table splits all of its light into ``order_components(N)``; None
        when it holds first-order scattering alone besides the total (format 1 files)."""
        n = len(self.components) - 1
        return n if n and self.components[1:] == order_components(n) else None

    def component(self, name: str) -> str:
        """The stored name of one of this table's components (``"single"`` →
        ``"order1"``).

        Raises
        ------
        ValueError
            If the name is not a component, or not one this table holds.
        """
        canonical = canonical_component(name)
        if canonical not in self.components:
            raise ValueError(f"component {name!r}: this table holds "
                             + ", ".join(self.components))
        return canonical

    def lobe_mask(self, component: str = "total",
                  threshold: float = LOBE_FRACTION) -> np.ndarray:
        """(a, b, nt, np) bool: bins whose f_r (mean over RGB) is at least ``threshold``
        times the peak of their incidence."""
        return lobe_of(self[component].values.mean(axis=-1), (2, 3),
                         threshold)

    def median_rel_stderr(self, component: str = "total") -> float:
        """Median relative standard error over the lobe bins of every incidence (NaN
        errors, i.e. empty bins, count as infinitely uncertain)."""
        f = self[component].values.mean(axis=-1)
        e = self[component].errors.mean(axis=-1)
        lobe = self.lobe_mask(component)
        rel = np.where(np.isfinite(e), e, np.inf)[lobe] / f[lobe]
        return float(np.median(rel)) if rel.size else float("nan")

    # --- evaluation (microsim.tables.evaluate) --------------------------------------------
    @property
    def axes(self) -> Axes:
        """The table's axes."""
        return Axes(self.bins, self.theta_i, self.phi_i, self.isotropic)

    def eval(self, wi: np.ndarray, wo: np.ndarray, component: str = "total",
             representation: str = "table") -> np.ndarray:
        """Interpolated f_r, from the bins (default) or from the spherical harmonics.

        Linear in θi (and periodically in φi for anisotropic tables) between the table's
        incidences, clamped outside them; bilinear in (sin²θo, φo) between bin centres,
        periodic in φo and clamped at the horizon; inside the first ring's centres blended
        linearly in sin²θo towards the ring's mean, its value at the pole
        (``microsim.tables.evaluate.pole_share``). An empty bin's value is 0, so the
        result is never NaN.

        Parameters
        ----------
        wi, wo : (..., 3) float
            Unit directions towards the light and the viewer, local frame.
        component : str
            A component of the table (``components``; ``"single"`` is ``"order1"``).
        representation : str
            ``"table"`` (the bins, as above) or ``"sh"``: f_r = Σ_k c_k Y_k(ωo) / cos θo
            from the coefficients of f_r cos θo, interpolated linearly in θi (and φi) as
            the bins are; the truncated series may be negative (``microsim sh`` reports
            how much); or ``"wavelet"``: from the stored wavelet coefficients
            (``microsim.tables.wavelets.evaluate``).

        Returns
        -------
        (..., 3) float
            f_r in 1/sr per colour; 0 where either direction is at or below the horizon.

        Raises
        ------
        ValueError
            For an unknown ``representation``, or ``"sh"`` (``"wavelet"``) on a table
            without harmonics (wavelets).
        """
        if representation == "wavelet":
            if self.wavelets is None:
                raise ValueError("this table holds no wavelets (store them with microsim "
                                 "wavelets TABLE --store)")
            return evaluate_wavelets(self.axes, self.wavelets, self.component(component),
                                     wi, wo)
        if representation == "sh":
            if not self.has_sh:
                raise ValueError("this table holds no spherical harmonics (simulate it with "
                                 "[table] sh_order > 0)")
            return from_harmonics(self.axes, self[component].sh, wi, wo)
        if representation != "table":
            raise ValueError(f"representation must be one of {REPRESENTATIONS}, "
                             f"got {representation!r}")
        return interpolate(self.axes, self[component].values, wi, wo)

    def stderr(self, wi: np.ndarray, wo: np.ndarray, component: str = "total") -> np.ndarray:
        """Interpolated standard error of f_r, with the nodes of ``eval``.

        Nodes whose error is undefined (empty bins) are left out and the other weights
        renormalised; the result is NaN only where the nearest node (the nearest incidence
        and the bin holding ωo) is itself undefined. 0 at or below the horizon, where f_r
        is 0 by definition.

        Parameters
        ----------
        wi, wo : (..., 3) float
            Unit directions, local frame.
        component : str
            A component of the table (``components``; ``"single"`` is ``"order1"``).

        Returns
        -------
        (..., 3) float
            Standard error of f_r in 1/sr per colour.
        """
        return interpolate_error(self.axes, self[component].errors, wi, wo)


def components_of(data: Iterable[str]) -> tuple[str, ...]:
    """The components of a per-component mapping (its keys), by stored name: ``"total"``
    first, then the orders from the lowest (``"single"`` counts as ``"order1"``).

    Raises
    ------
    ValueError
        If ``"total"`` is missing or a name is not a component, or two names are the same
        component.
    """
    names = [canonical_component(c) for c in data]
    if "total" not in names or len(set(names)) != len(names):
        raise ValueError(f"components must include 'total', each once; got {list(data)}")
    orders = sorted((c for c in names if c != "total"),
                    key=lambda c: (order_range(c)[0], order_range(c)[1] is None))
    return ("total", *orders)


class ByComponent(dict):
    """Per-component arrays keyed by stored names that also answer to the other names
    (``ALIASES``): ``values["single"]`` is ``values["order1"]``. Iteration gives the
    stored names."""

    def __getitem__(self, key: str) -> Any:
        return super().__getitem__(ALIASES.get(key, key))

    def __contains__(self, key: object) -> bool:
        return super().__contains__(ALIASES.get(key, key) if isinstance(key, str) else key)

    def get(self, key: str, default: Any = None) -> Any:
        """``self[key]`` if present, else ``default``."""
        return self[key] if key in self else default


def by_component(data: Mapping[str, V], components: tuple[str, ...],
                  dtype: type | None = None) -> ByComponent:
    """``data`` keyed by stored component names, in the order of ``components``."""
    named = {canonical_component(c): v for c, v in data.items()}
    if dtype is None:
        return ByComponent((c, named[c]) for c in components)
    return ByComponent((c, np.asarray(named[c], dtype)) for c in components)
