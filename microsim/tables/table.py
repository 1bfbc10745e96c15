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

from microsim.tables import sh
from microsim.tables.binning import TWO_PI, HemisphereBins
from microsim.tables.components import (
    ALIASES,
    canonical_component,
    order_components,
    order_range,
)
from microsim.tables.estimator import ENSEMBLE, RAYS, estimate
from microsim.tables.interpolation import linear_weights
from microsim.tables.meta import TableMeta

CHUNK = 65536
"""Direction pairs interpolated at once by ``eval`` and ``stderr``."""
SH_CHUNK = 1 << 22
"""Basis values (pairs × (L + 1)²) evaluated at once from spherical harmonics (32 MB)."""
REPRESENTATIONS = ("table", "sh")
LOBE_FRACTION = 0.1
"""Lobe bins: where f_r (mean over RGB; a table's, or a model's bin average when a table is
compared with it) is at least this fraction of the incidence's peak."""


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
        merge exactly with ``+``.
    lost : (K, a, b, 3) float or None
        Raw summed lost weight per realisation.
    sh, sh_err : dict of str to (a, b, (L + 1)², 3) float, or None
        Real spherical-harmonic coefficients of f_r cos θo over ωo per incidence and
        component, and their standard errors (``microsim.tables.sh`` has the convention);
        None when the table was simulated without them.
    sh_sums, sh_sums_sq : dict or None
        Raw sums Σ w Y_k (K, a, b, (L + 1)², 3) and Σ w² Y_K to order 2L
        (K, a, b, (2L + 1)², 3) of fresh estimates, merged by ``+``.

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
                 sh_sums_sq: Mapping[str, np.ndarray] | None = None) -> None:
        self.bins = bins
        self.theta_i = np.asarray(theta_i, float)
        self.phi_i = np.asarray(phi_i, float)
        self.isotropic = bool(isotropic)
        self.components = _components_of(values)
        self.values = _by_component(values, self.components, float)
        self.errors = _by_component(errors, self.components, float)
        self.rays = np.asarray(rays, np.int64)
        self.albedo_of = _by_component(albedo, self.components, float)
        self.albedo_err_of = _by_component(albedo_err, self.components, float)
        self.lost_energy = np.asarray(lost_energy, float)
        self.meta = meta
        self.error_model = error_model
        self.realisations = (np.ones(self.rays.shape, np.int64) if realisations is None
                             else np.asarray(realisations, np.int64))
        fallback = np.broadcast_to((self.rays - 1.0)[..., None], self.rays.shape + (3,))
        self.dof = _by_component(dof if dof is not None else dict.fromkeys(
            self.components, fallback), self.components, float)
        self.inflation = None if inflation is None else _by_component(
            inflation, self.components, float)
        self.realisation_rays = realisation_rays
        self.ray_errors = None if ray_errors is None else _by_component(
            ray_errors, self.components, float)
        self.sums = None if sums is None else _by_component(sums, self.components)
        self.sums_sq = None if sums_sq is None else _by_component(sums_sq, self.components)
        self.lost = lost
        self.sh = None if sh is None else _by_component(sh, self.components, float)
        self.sh_err = None if sh_err is None else _by_component(sh_err, self.components,
                                                                float)
        self.sh_sums = None if sh_sums is None else _by_component(sh_sums, self.components)
        self.sh_sums_sq = None if sh_sums_sq is None else _by_component(sh_sums_sq,
                                                                        self.components)

    @classmethod
    def from_sums(cls, bins: HemisphereBins, theta_i: np.ndarray, phi_i: np.ndarray,
                  isotropic: bool, rays: np.ndarray, sums: Mapping[str, np.ndarray],
                  sums_sq: Mapping[str, np.ndarray], lost: np.ndarray,
                  meta: TableMeta, *,
                  sh_sums: Mapping[str, np.ndarray] | None = None,
                  sh_sums_sq: Mapping[str, np.ndarray] | None = None) -> BRDFTable:
        """The estimator of one realisation (one tile): ``from_realisations`` with K = 1,
        its arrays without the realisation axis (``rays`` (a, b), ``sums`` (a, b, m, 3),
        ``lost`` (a, b, 3), ...)."""

        def one(x: Mapping[str, np.ndarray] | None) -> dict[str, np.ndarray] | None:
            return None if x is None else {c: np.asarray(v)[None] for c, v in x.items()}

        return cls.from_realisations(bins, theta_i, phi_i, isotropic,
                                     np.asarray(rays)[None], one(sums), one(sums_sq),
                                     np.asarray(lost)[None], meta, sh_sums=one(sh_sums),
                                     sh_sums_sq=one(sh_sums_sq))

    @classmethod
    def from_realisations(cls, bins: HemisphereBins, theta_i: np.ndarray,
                          phi_i: np.ndarray, isotropic: bool, rays: np.ndarray,
                          sums: Mapping[str, np.ndarray], sums_sq: Mapping[str, np.ndarray],
                          lost: np.ndarray, meta: TableMeta, *,
                          sh_sums: Mapping[str, np.ndarray] | None = None,
                          sh_sums_sq: Mapping[str, np.ndarray] | None = None) -> BRDFTable:
        """The goniophotometer's estimator from per-realisation sums of exit weights.

        Each launched ray contributes its exit weight w to at most one bin, so per bin the
        per-ray quantity X = w·1[bin] has mean Σw/N and f_r = (Σw/N) / Ω_proj (Nicodemus
        et al. 1977, NBS Monograph 160, eq. 4: reflected over incident power per
        projected solid angle). The albedo is the mean of the per-ray total exit weight
        W = Σ_bins X, whose Σ W² equals Σ over bins of Σw², because a ray exits once.
        Spherical-harmonic coefficients are the same sample mean of X = w Y_k(ωo), with
        Σ X² from the order-2L sums (``microsim.tables.sh.second_moments``). Over
        realisations every quantity is the mean of the realisations' estimates
        (``microsim.tables.estimator``): the bins' errors are moderated over the lobe bins
        of each incidence (bins of the mean f_r at least ``LOBE_FRACTION`` of its peak),
        the albedo's and the harmonics' are batch means.

        Parameters
        ----------
        bins : HemisphereBins
        theta_i : (a,) float
        phi_i : (b,) float
        isotropic : bool
        rays : (K, a, b) int
            Rays per realisation and incident direction; 0 where a realisation did not
            trace a direction (every direction needs at least one realisation).
        sums, sums_sq : dict of str to (K, a, b, nt·np, 3) float
            Σw and Σw² per bin for every component (``"total"`` and the orders).
        lost : (K, a, b, 3) float
            Summed weight of paths lost (bounce limit, transmission).
        meta : TableMeta
        sh_sums : dict of str to (K, a, b, (L + 1)², 3) float, or None
            Σ w Y_k(ωo) of the escaping rays, per component.
        sh_sums_sq : dict of str to (K, a, b, (2L + 1)², 3) float, or None
            Σ w² Y_K(ωo) to order 2L.

        Returns
        -------
        BRDFTable
            Error model ``ensemble`` when some direction has two realisations or more,
            ``rays`` otherwise.

        Raises
        ------
        ValueError
            If an incidence launched no ray or an array has the wrong shape.
        """
        rays = np.asarray(rays, np.int64)
        a, b = len(theta_i), len(phi_i)
        if rays.ndim != 3 or rays.shape[1:] != (a, b) or np.any(rays < 0) or np.any(
                rays.sum(axis=0) < 1):
            raise ValueError(f"rays must be (K, n_theta_i, n_phi_i) = (K, {a}, {b}) counts "
                             f">= 0, each direction traced, got shape {rays.shape}")
        components = _components_of(sums)
        sums, sums_sq = _by_component(sums, components), _by_component(sums_sq, components)
        expected = rays.shape + (bins.size, 3)
        for c in components:
            if not np.shape(sums[c]) == np.shape(sums_sq[c]) == expected:
                raise ValueError(f"sums[{c!r}] and sums_sq[{c!r}] must have shape {expected}")
        omega = bins.projected_solid_angle.reshape(1, 1, -1, 1)
        shape = (a, b) + bins.shape + (3,)
        values, errors, ray_errors, albedo, albedo_err = {}, {}, {}, {}, {}
        dof, inflation = {}, {}
        for c in components:
            s1, s2 = np.asarray(sums[c], float), np.asarray(sums_sq[c], float)
            with np.errstate(invalid="ignore", divide="ignore"):
                mean = np.nansum(s1 / np.where(rays > 0, rays, np.nan)[..., None, None],
                                 axis=0)
            f = mean.mean(axis=-1)
            lobe = (f >= LOBE_FRACTION * f.max(axis=-1, keepdims=True)) & (f > 0)
            e = estimate(s1, s2, rays, np.broadcast_to(lobe[..., None], mean.shape))
            values[c], errors[c] = (e.mean / omega).reshape(shape), (e.stderr / omega
                                                                      ).reshape(shape)
            ray_errors[c] = (e.ray_stderr / omega).reshape(shape)
            dof[c], inflation[c] = e.dof, e.inflation
            w = estimate(s1.sum(axis=3, keepdims=True), s2.sum(axis=3, keepdims=True), rays)
            albedo[c], albedo_err[c] = w.mean[:, :, 0], w.stderr[:, :, 0]
        sh_values = sh_errors = None
        if sh_sums is not None and sh_sums_sq is not None:
            sh_values, sh_errors = {}, {}
            sh_sums = _by_component(sh_sums, components)
            sh_sums_sq = _by_component(sh_sums_sq, components)
            for c in components:
                s1 = np.asarray(sh_sums[c], float)
                order = sh.order_of(s1.shape[-2])
                if s1.shape != rays.shape + (sh.size(order), 3) or np.shape(
                        sh_sums_sq[c]) != rays.shape + (sh.size(2 * order), 3):
                    raise ValueError(f"sh_sums[{c!r}] and sh_sums_sq[{c!r}] must have shapes "
                                     f"(K, a, b, (L+1)^2, 3) and (K, a, b, (2L+1)^2, 3)")
                e = estimate(s1, sh.second_moments(sh_sums_sq[c], order), rays)
                sh_values[c], sh_errors[c] = e.mean, e.stderr
        lost = np.asarray(lost, float)
        realisations = (rays > 0).sum(axis=0)
        with np.errstate(invalid="ignore", divide="ignore"):
            lost_energy = np.nansum(lost / np.where(rays > 0, rays, np.nan)[..., None],
                                    axis=0) / realisations[..., None]
        return cls(bins, theta_i, phi_i, isotropic, values, errors, rays.sum(axis=0), albedo,
                   albedo_err, lost_energy, meta,
                   error_model=ENSEMBLE if realisations.max() > 1 else RAYS,
                   realisations=realisations, dof=dof, inflation=inflation,
                   realisation_rays=rays, ray_errors=ray_errors,
                   sums={c: np.asarray(sums[c], float) for c in components},
                   sums_sq={c: np.asarray(sums_sq[c], float) for c in components},
                   lost=lost, sh=sh_values, sh_err=sh_errors,
                   sh_sums=sh_sums, sh_sums_sq=sh_sums_sq)

    def __add__(self, other: BRDFTable) -> BRDFTable:
        """Merge two estimates of the same set-up and realisations made with independent
        rays: realisation by realisation, the rays pool."""
        if self.sums is None or other.sums is None:
            raise ValueError("only tables holding raw sums (fresh estimates) merge")
        same = (self.bins.shape == other.bins.shape and self.isotropic == other.isotropic
                and np.array_equal(self.theta_i, other.theta_i)
                and np.array_equal(self.phi_i, other.phi_i)
                and self.realisation_rays.shape == other.realisation_rays.shape)
        if not same:
            raise ValueError("tables with different axes or realisations do not merge")
        if self.components != other.components:
            raise ValueError(f"tables with different components do not merge: "
                             f"{self.components} and {other.components}")
        components = self.components
        harmonics = (self.sh_sums is not None and other.sh_sums is not None
                     and self.sh_order == other.sh_order)

        def merged(a: Mapping[str, np.ndarray] | None, b: Mapping[str, np.ndarray] | None
                   ) -> dict[str, np.ndarray] | None:
            return {c: a[c] + b[c] for c in components} if harmonics else None

        return BRDFTable.from_realisations(
            self.bins, self.theta_i, self.phi_i, self.isotropic,
            self.realisation_rays + other.realisation_rays,
            {c: self.sums[c] + other.sums[c] for c in components},
            {c: self.sums_sq[c] + other.sums_sq[c] for c in components},
            self.lost + other.lost, self.meta, sh_sums=merged(self.sh_sums, other.sh_sums),
            sh_sums_sq=merged(self.sh_sums_sq, other.sh_sums_sq))

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
        f = self.values[self.component(component)].mean(axis=-1)
        peak = f.max(axis=(2, 3), keepdims=True)
        return (f >= threshold * peak) & (peak > 0)

    def median_rel_stderr(self, component: str = "total") -> float:
        """Median relative standard error over the lobe bins of every incidence (NaN
        errors, i.e. empty bins, count as infinitely uncertain)."""
        component = self.component(component)
        f = self.values[component].mean(axis=-1)
        e = self.errors[component].mean(axis=-1)
        lobe = self.lobe_mask(component)
        rel = np.where(np.isfinite(e), e, np.inf)[lobe] / f[lobe]
        return float(np.median(rel)) if rel.size else float("nan")

    # --- evaluation --------------------------------------------------------------------
    def _stencil(self, wi: np.ndarray, wo: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The 16 interpolation nodes of each direction pair: linear in θi and φi between
        incidences, bilinear in (sin²θo, φo) between bin centres (clamped at the pole and
        the horizon, periodic in φo).

        Parameters
        ----------
        wi, wo : (n, 3) float
            Unit directions, local frame.

        Returns
        -------
        nodes : (n, 16) int
            Flat indices into an (a·b·nt·np, 3) view of a table array.
        weights : (n, 16) float
            Interpolation weights, summing to 1; the node with the largest weight is the
            nearest one (the nearest incidence and the bin holding ωo).
        above : (n,) bool
            Both directions strictly above the horizon.
        """
        theta_in = np.arccos(np.clip(wi[:, 2], -1.0, 1.0))
        phi_in = np.arctan2(wi[:, 1], wi[:, 0])
        phi_out = np.arctan2(wo[:, 1], wo[:, 0])
        if self.isotropic:
            phi_out = phi_out - phi_in
        axes = (
            linear_weights(theta_in, self.theta_i),
            linear_weights(np.mod(phi_in, TWO_PI), self.phi_i, TWO_PI),
            linear_weights(np.clip(wo[:, 0] ** 2 + wo[:, 1] ** 2, 0.0, 1.0),
                           np.sin(self.bins.theta_centers) ** 2),
            linear_weights(self.bins.relative_phi(phi_out), self.bins.phi_centers,
                           self.bins.phi_period),
        )
        sizes = (len(self.theta_i), len(self.phi_i)) + self.bins.shape
        nodes = np.zeros((len(wi),) + (1,) * 4, np.int64)
        weights = np.ones((len(wi),) + (1,) * 4)
        for k, ((i0, i1, w1), size) in enumerate(zip(axes, sizes, strict=True)):
            at = (slice(None),) + (None,) * k + (slice(None),) + (None,) * (3 - k)
            nodes = nodes * size + np.stack([i0, i1], -1)[at]
            weights = weights * np.stack([1.0 - w1, w1], -1)[at]
        above = (wi[:, 2] > 0) & (wo[:, 2] > 0)
        return nodes.reshape(len(wi), 16), weights.reshape(len(wi), 16), above

    def _per_pair(self, kernel: Any, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """``kernel(nodes, weights)`` over the direction pairs in chunks of ``CHUNK`` (the
        16-node gathers stay a few tens of MB however many pairs), 0 where either direction
        is at or below the horizon.

        Returns
        -------
        (..., 3) float
        """
        wi, wo = np.broadcast_arrays(np.asarray(wi, float), np.asarray(wo, float))
        shape = wi.shape[:-1]
        wi, wo = wi.reshape(-1, 3), wo.reshape(-1, 3)
        out = np.zeros((len(wi), 3))
        for start in range(0, len(wi), CHUNK):
            sl = slice(start, start + CHUNK)
            nodes, weights, above = self._stencil(wi[sl], wo[sl])
            out[sl] = np.where(above[:, None], kernel(nodes, weights), 0.0)
        return out.reshape(shape + (3,))

    def eval(self, wi: np.ndarray, wo: np.ndarray, component: str = "total",
             representation: str = "table") -> np.ndarray:
        """Interpolated f_r, from the bins (default) or from the spherical harmonics.

        Linear in θi (and periodically in φi for anisotropic tables) between the table's
        incidences, clamped outside them; bilinear in (sin²θo, φo) between bin centres,
        periodic in φo and clamped at the pole and the horizon. An empty bin's value is 0,
        so the result is never NaN.

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
            how much).

        Returns
        -------
        (..., 3) float
            f_r in 1/sr per colour; 0 where either direction is at or below the horizon.

        Raises
        ------
        ValueError
            For an unknown ``representation``, or ``"sh"`` on a table without harmonics.
        """
        if representation == "sh":
            return self._eval_sh(wi, wo, self.component(component))
        if representation != "table":
            raise ValueError(f"representation must be one of {REPRESENTATIONS}, "
                             f"got {representation!r}")
        data = self.values[self.component(component)].reshape(-1, 3)
        return self._per_pair(lambda nodes, w: np.einsum("nk,nkc->nc", w, data[nodes]),
                              wi, wo)

    def _eval_sh(self, wi: np.ndarray, wo: np.ndarray, component: str) -> np.ndarray:
        """f_r from the harmonics (see ``eval``), in chunks of ``SH_CHUNK`` basis values."""
        if self.sh is None:
            raise ValueError("this table holds no spherical harmonics (simulate it with "
                             "[table] sh_order > 0)")
        a, b, n, _ = self.sh[component].shape
        coef = np.moveaxis(self.sh[component], 2, 0).reshape(n, a * b * 3)
        wi, wo = np.broadcast_arrays(np.asarray(wi, float), np.asarray(wo, float))
        shape = wi.shape[:-1]
        wi, wo = wi.reshape(-1, 3), wo.reshape(-1, 3)
        out = np.zeros((len(wi), 3))
        step = max(1, SH_CHUNK // n)
        for start in range(0, len(wi), step):
            i, o = wi[start:start + step], wo[start:start + step]
            phi_in = np.arctan2(i[:, 1], i[:, 0])
            t0, t1, wt = linear_weights(np.arccos(np.clip(i[:, 2], -1.0, 1.0)),
                                        self.theta_i)
            p0, p1, wp = linear_weights(np.mod(phi_in, TWO_PI), self.phi_i, TWO_PI)
            phi_out = np.arctan2(o[:, 1], o[:, 0]) - (phi_in if self.isotropic else 0.0)
            g = (sh.basis(sh.order_of(n), o[:, 2], phi_out) @ coef).reshape(len(i), a * b, 3)
            rows = np.arange(len(i))
            total = np.zeros((len(i), 3))
            for t, w_t in ((t0, 1.0 - wt), (t1, wt)):
                for p, w_p in ((p0, 1.0 - wp), (p1, wp)):
                    total += (w_t * w_p)[:, None] * g[rows, t * b + p]
            above = (i[:, 2] > 0) & (o[:, 2] > 0)
            out[start:start + step] = np.where(
                above[:, None], total / np.where(above, o[:, 2], 1.0)[:, None], 0.0)
        return out.reshape(shape + (3,))

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
        err = self.errors[self.component(component)].reshape(-1, 3)

        def kernel(nodes: np.ndarray, weights: np.ndarray) -> np.ndarray:
            known = np.isfinite(err[nodes])                               # (n, 16, 3)
            w = np.where(known, weights[..., None], 0.0)
            nearest = np.argmax(weights, axis=1)
            undefined = ~np.take_along_axis(known, nearest[:, None, None], axis=1)[:, 0]
            out = (w * np.nan_to_num(err[nodes])).sum(axis=1) / np.where(
                undefined, 1.0, w.sum(axis=1))
            return np.where(undefined, np.nan, out)

        return self._per_pair(kernel, wi, wo)


def _components_of(data: Mapping[str, Any]) -> tuple[str, ...]:
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


def _by_component(data: Mapping[str, Any], components: tuple[str, ...],
                  dtype: type | None = None) -> ByComponent:
    """``data`` keyed by stored component names, in the order of ``components``."""
    named = {canonical_component(c): v for c, v in data.items()}
    if dtype is None:
        return ByComponent((c, named[c]) for c in components)
    return ByComponent((c, np.asarray(named[c], dtype)) for c in components)
