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

from collections.abc import Mapping
from typing import Any

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


class BRDFTable:
    """A binned BRDF with per-bin standard errors.

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
    values, errors : dict of str to (a, b, nt, np, 3) float
        f_r (1/sr) and its standard error per component (``"total"`` and the order
        components; ``"single"`` is read as ``"order1"``); an error is NaN where it is
        undefined (no ray landed in the bin).
    rays : (a, b) int
        Rays launched per incident direction.
    albedo, albedo_err : dict of str to (a, b, 3) float
        Directional albedo ∫ f_r cos θo dωo of the escaping light per component, with
        standard errors (the attributes ``albedo_of`` and ``albedo_err_of``).
    lost_energy : (a, b, 3) float
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
    dof : dict of str to (a, b, 3) float, or None
        Degrees of freedom of each bin's variance estimate per component, incidence and
        colour: (value − truth) / error is Student-t with them (default: rays − 1). The
        albedo's and the harmonics' errors are batch means over the realisations:
        realisations − 1 degrees of freedom (rays − 1 for one).
    inflation : dict of str to (a, b, 3) float, or None
        The pooled ratio of each bin's ensemble variance to its ray variance (NaN where
        not pooled).
    realisation_rays : (K, a, b) int or None
        Rays per realisation and incident direction of a fresh estimate (0: absent).
    ray_errors : dict of str to (a, b, nt, np, 3) float, or None
        The ray noise's share of ``errors`` in a fresh estimate (equal to it for one
        realisation): what more rays per realisation can still remove.
    sums, sums_sq : dict or None
        Raw per-bin sums Σw, Σw² of shape (K, a, b, nt·np, 3), per realisation, when the
        table was estimated here: tables of the same realisations and independent rays
        merge exactly (``microsim.tables.assemble.merge``).
    lost : (K, a, b, 3) float or None
        Raw summed lost weight per realisation.
    sh, sh_err : dict of str to (a, b, (L + 1)², 3) float, or None
        Real spherical-harmonic coefficients of f_r cos θo over ωo per incidence and
        component, and their standard errors (``microsim.tables.sh`` has the convention);
        None when the table was simulated without them.
    sh_sums, sh_sums_sq : dict or None
        Raw sums Σ w Y_k (K, a, b, (L + 1)², 3) and Σ w² Y_K to order 2L
        (K, a, b, (2L + 1)², 3) of fresh estimates, merged alike.
    realisation_albedo : dict of str to (R, a, b, 3) float, or None
        Each realisation's albedo per component of a fresh estimate, per direction in
        the order the realisations were added (index order): slot r of direction (l, k)
        holds the albedo of the (r + 1)-th realisation that traced it, not necessarily
        realisation r, and slots past that direction's ``realisations`` are NaN. R is
        the most realisations of any direction (``microsim.tables.assemble.EnsembleSums``).
    wavelets : Wavelets or None
        Wavelet coefficients of f_r cos θo per incidence and component, kept by magnitude
        (``microsim.tables.wavelets``; ``microsim wavelets TABLE --store``), or None.

    Attributes
    ----------
    components : tuple of str
        The stored component names, ``"total"`` first, then the orders from the lowest
        (``components_for(N)`` for a table simulated with ``orders = N``).
    """

    def __init__(self, bins: HemisphereBins, theta_i: np.ndarray, phi_i: np.ndarray,
                 isotropic: bool, values: Mapping[str, np.ndarray],
                 errors: Mapping[str, np.ndarray], rays: np.ndarray,
                 albedo: Mapping[str, np.ndarray], albedo_err: Mapping[str, np.ndarray],
                 lost_energy: np.ndarray, meta: TableMeta, *,
                 error_model: str = RAYS, realisations: np.ndarray | None = None,
                 dof: Mapping[str, np.ndarray] | None = None,
                 inflation: Mapping[str, np.ndarray] | None = None,
                 realisation_rays: np.ndarray | None = None,
                 ray_errors: Mapping[str, np.ndarray] | None = None,
                 sums: Mapping[str, np.ndarray] | None = None,
                 sums_sq: Mapping[str, np.ndarray] | None = None,
                 lost: np.ndarray | None = None,
                 sh: Mapping[str, np.ndarray] | None = None,
                 sh_err: Mapping[str, np.ndarray] | None = None,
                 sh_sums: Mapping[str, np.ndarray] | None = None,
                 sh_sums_sq: Mapping[str, np.ndarray] | None = None,
                 realisation_albedo: Mapping[str, np.ndarray] | None = None,
                 wavelets: Wavelets | None = None, channels: Channels = RGB) -> None:
        self.bins = bins
        self.channels = channels
        self.theta_i = np.asarray(theta_i, float)
        self.phi_i = np.asarray(phi_i, float)
        self.isotropic = bool(isotropic)
        self.components = components_of(values)
        self.values = by_component(values, self.components, float)
        self.errors = by_component(errors, self.components, float)
        self.rays = np.asarray(rays, np.int64)
        self.albedo_of = by_component(albedo, self.components, float)
        self.albedo_err_of = by_component(albedo_err, self.components, float)
        self.lost_energy = np.asarray(lost_energy, float)
        self.meta = meta
        self.error_model = error_model
        self.realisations = (np.ones(self.rays.shape, np.int64) if realisations is None
                             else np.asarray(realisations, np.int64))
        fallback = np.broadcast_to((self.rays - 1.0)[..., None],
                                   self.rays.shape + (channels.count,))
        self.dof = by_component(dof if dof is not None else dict.fromkeys(
            self.components, fallback), self.components, float)
        self.inflation = None if inflation is None else by_component(
            inflation, self.components, float)
        self.realisation_rays = realisation_rays
        self.ray_errors = None if ray_errors is None else by_component(
            ray_errors, self.components, float)
        self.sums = None if sums is None else by_component(sums, self.components)
        self.sums_sq = None if sums_sq is None else by_component(sums_sq, self.components)
        self.lost = lost
        self.sh = None if sh is None else by_component(sh, self.components, float)
        self.sh_err = None if sh_err is None else by_component(sh_err, self.components,
                                                                float)
        self.sh_sums = None if sh_sums is None else by_component(sh_sums, self.components)
        self.sh_sums_sq = None if sh_sums_sq is None else by_component(sh_sums_sq,
                                                                        self.components)
        self.realisation_albedo = None if realisation_albedo is None else by_component(
            realisation_albedo, self.components, float)
        self.wavelets = wavelets

    # --- derived quantities ------------------------------------------------------------
    @property
    def sh_order(self) -> int:
        """Order L of the stored spherical harmonics (0 when there are none)."""
        if self.sh is None:
            return 0
        return sh.order_of(self.sh["total"].shape[-2])

    @property
    def albedo(self) -> np.ndarray:
        """(a, b, 3) directional albedo of all escaping light (all orders)."""
        return self.albedo_of["total"]

    @property
    def albedo_err(self) -> np.ndarray:
        """(a, b, 3) standard error of ``albedo``."""
        return self.albedo_err_of["total"]

    @property
    def single_albedo(self) -> np.ndarray:
        """(a, b, 3) directional albedo of single scattering."""
        return self.albedo_of["order1"]

    @property
    def single_albedo_err(self) -> np.ndarray:
        """(a, b, 3) standard error of ``single_albedo``."""
        return self.albedo_err_of["order1"]

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
        return lobe_of(self.values[self.component(component)].mean(axis=-1), (2, 3),
                         threshold)

    def median_rel_stderr(self, component: str = "total") -> float:
        """Median relative standard error over the lobe bins of every incidence (NaN
        errors, i.e. empty bins, count as infinitely uncertain)."""
        component = self.component(component)
        f = self.values[component].mean(axis=-1)
        e = self.errors[component].mean(axis=-1)
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
            if self.sh is None:
                raise ValueError("this table holds no spherical harmonics (simulate it with "
                                 "[table] sh_order > 0)")
            return from_harmonics(self.axes, self.sh[self.component(component)], wi, wo)
        if representation != "table":
            raise ValueError(f"representation must be one of {REPRESENTATIONS}, "
                             f"got {representation!r}")
        return interpolate(self.axes, self.values[self.component(component)], wi, wo)

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
        return interpolate_error(self.axes, self.errors[self.component(component)], wi, wo)


def components_of(data: Mapping[str, Any]) -> tuple[str, ...]:
    """The components of a per-component mapping, by stored name: ``"total"`` first, then
    the orders from the lowest (``"single"`` counts as ``"order1"``).

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


def by_component(data: Mapping[str, Any], components: tuple[str, ...],
                  dtype: type | None = None) -> ByComponent:
    """``data`` keyed by stored component names, in the order of ``components``."""
    named = {canonical_component(c): v for c, v in data.items()}
    if dtype is None:
        return ByComponent((c, named[c]) for c in components)
    return ByComponent((c, np.asarray(named[c], dtype)) for c in components)
