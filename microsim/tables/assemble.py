"""A table from the goniophotometer's sums: the estimator of f_r, the albedo and the
spherical harmonics with their errors, over the surface's realisations, and the merge of
two estimates of the same set-up.

Each launched ray contributes its exit weight w to at most one bin, so per bin the per-ray
quantity X = w·1[bin] has mean Σw/N and f_r = (Σw/N) / Ω_proj (Nicodemus et al. 1977, NBS
Monograph 160, eq. 4). Over realisations every quantity is the mean of the realisations'
estimates (``microsim.tables.estimator``).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from microsim.tables import sh
from microsim.tables.binning import HemisphereBins
from microsim.tables.estimator import ENSEMBLE, RAYS, estimate
from microsim.tables.meta import TableMeta
from microsim.tables.table import BRDFTable, by_component, components_of, lobe_of


def from_sums(bins: HemisphereBins, theta_i: np.ndarray, phi_i: np.ndarray,
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

    return from_realisations(bins, theta_i, phi_i, isotropic,
                                 np.asarray(rays)[None], one(sums), one(sums_sq),
                                 np.asarray(lost)[None], meta, sh_sums=one(sh_sums),
                                 sh_sums_sq=one(sh_sums_sq))


def from_realisations(bins: HemisphereBins, theta_i: np.ndarray,
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
    of each incidence (``lobe_of`` the mean f_r over RGB), the albedo's and the
    harmonics' are batch means.

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
    components = components_of(sums)
    sums, sums_sq = by_component(sums, components), by_component(sums_sq, components)
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
        lobe = lobe_of(mean.mean(axis=-1), -1)
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
        sh_sums = by_component(sh_sums, components)
        sh_sums_sq = by_component(sh_sums_sq, components)
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
    return BRDFTable(bins, theta_i, phi_i, isotropic, values, errors, rays.sum(axis=0), albedo,
               albedo_err, lost_energy, meta,
               error_model=ENSEMBLE if realisations.max() > 1 else RAYS,
               realisations=realisations, dof=dof, inflation=inflation,
               realisation_rays=rays, ray_errors=ray_errors,
               sums={c: np.asarray(sums[c], float) for c in components},
               sums_sq={c: np.asarray(sums_sq[c], float) for c in components},
               lost=lost, sh=sh_values, sh_err=sh_errors,
               sh_sums=sh_sums, sh_sums_sq=sh_sums_sq)


def merge(self: BRDFTable, other: BRDFTable) -> BRDFTable:
    """Merge two estimates of the same set-up and realisations made with independent
    rays (``BRDFTable + BRDFTable``): realisation by realisation, the rays pool.

    Raises
    ------
    ValueError
        If either is not a fresh estimate (a read table holds no raw sums), or their axes,
        realisations or components differ.
    """
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

    return from_realisations(
        self.bins, self.theta_i, self.phi_i, self.isotropic,
        self.realisation_rays + other.realisation_rays,
        {c: self.sums[c] + other.sums[c] for c in components},
        {c: self.sums_sq[c] + other.sums_sq[c] for c in components},
        self.lost + other.lost, self.meta, sh_sums=merged(self.sh_sums, other.sh_sums),
        sh_sums_sq=merged(self.sh_sums_sq, other.sh_sums_sq))
