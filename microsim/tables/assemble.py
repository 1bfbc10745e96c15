"""A table from the goniophotometer's sums: the estimator of f_r, the albedo and the
spherical harmonics with their errors, over the surface's realisations, and the merge of
two estimates of the same set-up.

Each launched ray contributes its exit weight w to at most one bin, so per bin the per-ray
quantity X = w·1[bin] has mean Σw/N and f_r = (Σw/N) / Ω_proj (Nicodemus et al. 1977, NBS
Monograph 160, eq. 4). Over realisations every quantity is the mean of the realisations'
estimates (``microsim.tables.estimator``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from microsim.spectra.channels import RGB, Channels
from microsim.tables import sh
from microsim.tables.binning import HemisphereBins
from microsim.tables.estimator import (
    ENSEMBLE,
    GROUPS,
    RAYS,
    RunningEstimate,
)
from microsim.tables.meta import TableMeta
from microsim.tables.table import (
    BRDFTable,
    ComponentEstimate,
    by_component,
    components_of,
    lobe_of,
)


def from_sums(bins: HemisphereBins, theta_i: np.ndarray, phi_i: np.ndarray,
              isotropic: bool, rays: np.ndarray, sums: Mapping[str, np.ndarray],
              sums_sq: Mapping[str, np.ndarray], lost: np.ndarray,
              meta: TableMeta, *,
              sh_sums: Mapping[str, np.ndarray] | None = None,
              sh_sums_sq: Mapping[str, np.ndarray] | None = None,
              channels: Channels = RGB) -> BRDFTable:
    """The estimator of one realisation (one tile): ``from_realisations`` with K = 1,
    its arrays without the realisation axis (``rays`` (a, b), ``sums`` (a, b, m, C),
    ``lost`` (a, b, C), ...)."""

    def one(x: Mapping[str, np.ndarray] | None) -> dict[str, np.ndarray] | None:
        return None if x is None else {c: np.asarray(v)[None] for c, v in x.items()}

    return from_realisations(bins, theta_i, phi_i, isotropic,
                                 np.asarray(rays)[None], one(sums), one(sums_sq),
                                 np.asarray(lost)[None], meta, sh_sums=one(sh_sums),
                                 sh_sums_sq=one(sh_sums_sq), channels=channels)


class EnsembleSums:
    """Running sums of a table's estimates over the surface's realisations, per incident
    direction: what ``from_ensemble`` makes the table of, in the memory of at most
    ``microsim.tables.estimator.GROUPS`` realisations however many are added.

    Parameters
    ----------
    directions : (int, int)
        (a, b): incident polar angles and azimuths.
    components : tuple of str
        The components, in the order of the rows of the sums added.
    bins : int
        Outgoing bins m.
    sh_order : int
        Order L of the harmonics added (0: none).
    channels : int
        C, the colour channels (3: RGB; one per wavelength).
    sh_ray_variance : bool
        Whether the harmonics' order-2L sums of w² are added (``add``'s ``sh_sums_sq``):
        the ray variance of every coefficient, which one realisation's error is and which
        floors batch means. Without them the harmonics' errors are batch means alone
        (``microsim.measurement.goniometer.harmonic_ray_variance`` says when a run needs them).

    Attributes
    ----------
    bins, albedo, sh : RunningEstimate
        Per direction and component: the bins' Σw / N ((a, b, rows, m, C); their errors
        moderated), the albedo's ((a, b, rows, 1, C)) and the harmonics' ((a, b, rows,
        (L + 1)², C), or None).
    rays : (a, b) int
        Rays added per direction.
    lost : (a, b, C) float
        Σ over realisations of each one's lost weight per ray.
    realisation_rays : dict of (int, int) to list of int
        Per direction, each added realisation's rays, in the order added.
    realisation_albedo : dict of (int, int) to list of (rows, C) float
        Per direction, each added realisation's albedo per component (a few numbers a
        realisation, for studies of the spread between tiles).
    """

    def __init__(self, directions: tuple[int, int], components: tuple[str, ...],
                 bins: int, sh_order: int = 0, channels: int = 3,
                 sh_ray_variance: bool = True) -> None:
        a, b = directions
        rows = len(components)
        self.components, self.sh_order = tuple(components), int(sh_order)
        c = int(channels)
        self.bins = RunningEstimate((a, b, rows, bins, c), GROUPS)
        self.albedo = RunningEstimate((a, b, rows, 1, c))
        self.sh = RunningEstimate((a, b, rows, sh.size(sh_order), c),
                                  ray_variance=sh_ray_variance) if sh_order else None
        self.rays = np.zeros((a, b), np.int64)
        self.lost = np.zeros((a, b, c))
        self.realisation_rays: dict[tuple[int, int], list[int]] = {}
        self.realisation_albedo: dict[tuple[int, int], list[np.ndarray]] = {}

    def add(self, at: tuple[int, int], r: int, rays: int, sums: np.ndarray,
            sums_sq: np.ndarray, lost: np.ndarray, sh_sums: np.ndarray | None = None,
            sh_sums_sq: np.ndarray | None = None) -> None:
        """Add realisation ``r`` of direction ``at``: its ``rays`` (≥ 1), per component
        row its sums Σw and Σw² per bin ((rows, m, C)), its lost weight (C,) and, with
        harmonics, Σ w Y_k ((rows, (L + 1)², C)) and Σ w² Y_K to order 2L ((rows,
        (2L + 1)², C); None without ``sh_ray_variance``). Realisations are added in index
        order (the sums then do not depend on how the work was split)."""
        self.bins.add_sums(r, sums, sums_sq, rays, at)
        albedo = sums.sum(axis=-2, keepdims=True)
        self.albedo.add_sums(r, albedo, sums_sq.sum(axis=-2, keepdims=True), rays, at)
        self.realisation_albedo.setdefault(at, []).append(albedo[:, 0] / rays)
        if self.sh is not None:
            if sh_sums_sq is None:
                self.sh.add(r, sh_sums / rays, None, rays, at)
            else:
                self.sh.add_sums(r, sh_sums, sh.second_moments(sh_sums_sq, self.sh_order),
                                 rays, at)
        self.rays[at] += rays
        self.lost[at] += lost / rays
        self.realisation_rays.setdefault(at, []).append(int(rays))

    def take(self, rows: Sequence[int]) -> EnsembleSums:
        """The sums of the incident polar angles ``rows`` (copies; these sums themselves
        for all of them in order)."""
        rows = list(rows)
        if rows == list(range(len(self.rays))):
            return self
        out = EnsembleSums((0, 0), self.components, 0, 0, self.lost.shape[-1])
        out.sh_order = self.sh_order
        out.bins, out.albedo = self.bins.take(rows), self.albedo.take(rows)
        out.sh = None if self.sh is None else self.sh.take(rows)
        out.rays, out.lost = self.rays[rows], self.lost[rows]
        out.realisation_rays, out.realisation_albedo = ({
            (i, k): list(per[(l, k)]) for i, l in enumerate(rows)
            for k in range(self.rays.shape[1]) if (l, k) in per}
            for per in (self.realisation_rays, self.realisation_albedo))
        return out

    def absorb(self, other: EnsembleSums) -> None:
        """Take over ``other``'s directions (of the same table; none of them added here).

        Raises
        ------
        ValueError
            If a direction has realisations in both.
        """
        if set(self.realisation_rays) & set(other.realisation_rays):
            raise ValueError("the same incident direction was measured twice")
        for mine, theirs in ((self.bins, other.bins), (self.albedo, other.albedo),
                             (self.sh, other.sh)):
            if mine is not None:
                mine.absorb(theirs)
        self.rays += other.rays
        self.lost += other.lost
        self.realisation_rays.update(other.realisation_rays)
        self.realisation_albedo.update(other.realisation_albedo)


def from_ensemble(bins: HemisphereBins, theta_i: np.ndarray, phi_i: np.ndarray,
                  isotropic: bool, ensemble: EnsembleSums, meta: TableMeta,
                  raw: RawSums | None = None, channels: Channels = RGB
                  ) -> BRDFTable:
    """The goniophotometer's estimator from running sums over realisations.

    Each launched ray contributes its exit weight w to at most one bin, so per bin the
    per-ray quantity X = w·1[bin] has mean Σw/N and f_r = (Σw/N) / Ω_proj (Nicodemus
    et al. 1977, NBS Monograph 160, eq. 4: reflected over incident power per
    projected solid angle). The albedo is the mean of the per-ray total exit weight
    W = Σ_bins X, whose Σ W² equals Σ over bins of Σw², because a ray exits once.
    Spherical-harmonic coefficients are the same sample mean of X = w Y_k(ωo), with
    Σ X² from the order-2L sums (``microsim.tables.sh.second_moments``) where the run
    kept them. Over realisations every quantity is the mean of the realisations'
    estimates (``microsim.tables.estimator``): the bins' errors are moderated over the
    lobe bins of each incidence (``lobe_of`` the mean f_r over RGB), the albedo's and the
    harmonics' are batch means (the harmonics' floored at their ray variance only where
    the sums hold it: an ensemble run does not make it, ``EnsembleSums``).

    Parameters
    ----------
    bins : HemisphereBins
    theta_i : (a,) float
    phi_i : (b,) float
    isotropic : bool
    ensemble : EnsembleSums
        Of (a, b) directions, each with at least one realisation.
    meta : TableMeta
    raw : RawSums or None
        The raw per-realisation sums, for the table to keep, when the caller has them.
    channels : Channels
        The channels of the sums' last axis (RGB, or one per wavelength).

    Returns
    -------
    BRDFTable
        Error model ``ensemble`` when some direction has two realisations or more,
        ``rays`` otherwise.

    Raises
    ------
    ValueError
        If a direction launched no ray.
    """
    a, b = len(theta_i), len(phi_i)
    if ensemble.rays.shape != (a, b) or np.any(ensemble.rays < 1):
        raise ValueError(f"every one of the ({a}, {b}) incident directions needs rays, got "
                         f"{ensemble.rays.tolist()}")
    omega = bins.projected_solid_angle.reshape(1, 1, -1, 1)
    count = ensemble.lost.shape[-1]
    if count != channels.count:
        raise ValueError(f"the sums have {count} channels, the table {channels.count}")
    shape = (a, b) + bins.shape + (count,)
    lobe = lobe_of(ensemble.bins.mean.mean(axis=-1), -1)
    e = ensemble.bins.estimate(np.broadcast_to(lobe[..., None], ensemble.bins.shape))
    w = ensemble.albedo.estimate()
    s = None if ensemble.sh is None else ensemble.sh.estimate()
    realisations = e.realisations[:, :, 0]
    per = np.full((int(realisations.max()), a, b, len(ensemble.components), count), np.nan)
    for (l, k), albedos in ensemble.realisation_albedo.items():
        per[:len(albedos), l, k] = albedos
    sums = raw.sums if raw is not None else {}
    estimates = {c: ComponentEstimate(
        values=(e.mean[:, :, j] / omega).reshape(shape),
        errors=(e.stderr[:, :, j] / omega).reshape(shape),
        albedo=w.mean[:, :, j, 0], albedo_err=w.stderr[:, :, j, 0],
        dof=e.dof[:, :, j], inflation=e.inflation[:, :, j],
        ray_errors=(e.ray_stderr[:, :, j] / omega).reshape(shape),
        sh=None if s is None else s.mean[:, :, j],
        sh_err=None if s is None else s.stderr[:, :, j],
        realisation_albedo=per[:, :, :, j], **sums.get(c, {}))
        for j, c in enumerate(ensemble.components)}
    return BRDFTable(bins, theta_i, phi_i, isotropic, estimates, ensemble.rays.copy(),
                     ensemble.lost / realisations[..., None], meta,
                     error_model=ENSEMBLE if realisations.max() > 1 else RAYS,
                     realisations=realisations,
                     realisation_rays=None if raw is None else raw.realisation_rays,
                     lost=None if raw is None else raw.lost, channels=channels)


@dataclass(frozen=True, eq=False)
class RawSums:
    """The raw per-realisation sums of an estimate, which a fresh table keeps so that
    tables of the same realisations and independent rays merge (``merge``).

    Parameters
    ----------
    realisation_rays : (K, a, b) int
        Rays per realisation and incident direction (0: absent).
    lost : (K, a, b, C) float
        Summed lost weight per realisation.
    sums : dict of str to dict of str to array
        Per component, its ``ComponentEstimate`` fields ``sums``, ``sums_sq`` and, with
        harmonics, ``sh_sums`` and ``sh_sums_sq`` ((K, a, b, ...) arrays).
    """

    realisation_rays: np.ndarray
    lost: np.ndarray
    sums: Mapping[str, Mapping[str, np.ndarray | None]]


def from_realisations(bins: HemisphereBins, theta_i: np.ndarray,
                      phi_i: np.ndarray, isotropic: bool, rays: np.ndarray,
                      sums: Mapping[str, np.ndarray], sums_sq: Mapping[str, np.ndarray],
                      lost: np.ndarray, meta: TableMeta, *,
                      sh_sums: Mapping[str, np.ndarray] | None = None,
                      sh_sums_sq: Mapping[str, np.ndarray] | None = None,
                      channels: Channels = RGB) -> BRDFTable:
    """``from_ensemble`` of per-realisation sums, which the table keeps (tables of the
    same realisations and independent rays then merge: ``merge``).

    Parameters
    ----------
    bins, theta_i, phi_i, isotropic
        As for ``from_ensemble``.
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
    channels : Channels
        The channels of the arrays' last axis (RGB: 3; one per wavelength).

    Returns
    -------
    BRDFTable

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
    count = np.shape(sums["total"])[-1]
    expected = rays.shape + (bins.size, count)
    for c in components:
        if not np.shape(sums[c]) == np.shape(sums_sq[c]) == expected:
            raise ValueError(f"sums[{c!r}] and sums_sq[{c!r}] must have shape {expected}")
    order = 0
    if sh_sums is not None and sh_sums_sq is not None:
        sh_sums = by_component(sh_sums, components)
        sh_sums_sq = by_component(sh_sums_sq, components)
        order = sh.order_of(np.shape(sh_sums["total"])[-2])
        for c in components:
            if np.shape(sh_sums[c]) != rays.shape + (sh.size(order), count) or np.shape(
                    sh_sums_sq[c]) != rays.shape + (sh.size(2 * order), count):
                raise ValueError(f"sh_sums[{c!r}] and sh_sums_sq[{c!r}] must have shapes "
                                 f"(K, a, b, (L+1)^2, C) and (K, a, b, (2L+1)^2, C)")
    else:
        sh_sums = sh_sums_sq = None
    ensemble = EnsembleSums((a, b), components, bins.size, order, count)
    lost = np.asarray(lost, float)

    def rows(x: Mapping[str, np.ndarray] | None, r: int, at: tuple[int, int]
             ) -> np.ndarray | None:
        return None if x is None else np.stack([np.asarray(x[c], float)[(r, *at)]
                                                for c in components])

    for r, l, k in zip(*np.nonzero(rays), strict=True):
        at = (int(l), int(k))
        ensemble.add(at, int(r), int(rays[r, l, k]), rows(sums, r, at),
                     rows(sums_sq, r, at), lost[r, l, k], rows(sh_sums, r, at),
                     rows(sh_sums_sq, r, at))
    raw = RawSums(rays, lost, {c: {
        "sums": np.asarray(sums[c], float), "sums_sq": np.asarray(sums_sq[c], float),
        "sh_sums": None if sh_sums is None else sh_sums[c],
        "sh_sums_sq": None if sh_sums_sq is None else sh_sums_sq[c]} for c in components})
    return from_ensemble(bins, theta_i, phi_i, isotropic, ensemble, meta, raw, channels)


def merge(self: BRDFTable, other: BRDFTable) -> BRDFTable:
    """Merge two estimates of the same set-up and realisations made with independent
    rays: realisation by realisation, the rays pool.

    Raises
    ------
    ValueError
        If either is not a fresh estimate (a read table holds no raw sums), or their axes,
        realisations, components or channels differ.
    """
    if not (self.fresh and other.fresh):
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
    if self.channels != other.channels:
        raise ValueError(f"tables of different channels do not merge: "
                         f"{', '.join(self.channels.names)} and "
                         f"{', '.join(other.channels.names)}")
    components = self.components
    harmonics = (self["total"].sh_sums is not None and other["total"].sh_sums is not None
                 and self.sh_order == other.sh_order)

    def merged(name: str) -> dict[str, np.ndarray]:
        return {c: getattr(self[c], name) + getattr(other[c], name) for c in components}

    return from_realisations(
        self.bins, self.theta_i, self.phi_i, self.isotropic,
        self.realisation_rays + other.realisation_rays, merged("sums"), merged("sums_sq"),
        self.lost + other.lost, self.meta,
        sh_sums=merged("sh_sums") if harmonics else None,
        sh_sums_sq=merged("sh_sums_sq") if harmonics else None, channels=self.channels)
