"""Estimates over independent surface realisations: the mean and its standard error.

A table estimates the expectation of a per-ray quantity X (a bin's exit weight, w Y_k(ωo)
for a harmonic, the escaping weight for the albedo) over the rays *and* over the random
geometry the recipe names. Realisation r = 1…K is one tile traced with n_r rays, giving
Σx and Σx² over its rays. With

    m_r = Σx / n_r                          the realisation's estimate,
    v_r = (Σx² − n_r m_r²) / (n_r (n_r − 1))  the ray variance of m_r given its tile,

the model is m_r = μ + δ_r + ε_r: δ_r the tile's own deviation (variance τ² over
realisations), ε_r the ray noise (variance σ_r² / n_r given the tile), all independent.
The ensemble estimate is the plain mean μ̂ = Σ m_r / K, with

    Var(μ̂) = (τ² + mean_r σ_r² / n_r) / K.

Two estimators of it are used (docs/ensembles.md, "Error bars of the ensemble", derives
both and the measurements that choose between them):

- **batch means**, s² = Σ (m_r − μ̂)² / (K (K − 1)): unbiased for Var(μ̂) whatever the
  n_r (E Σ (m_r − μ̂)² = (1 − 1/K) Σ Var m_r for independent m_r of one mean), with
  d = K − 1 degrees of freedom, so (μ̂ − μ)/s is Student-t with K − 1 degrees of freedom.
  It is floored at the ray part u (below), which it exceeds in expectation: realisations
  that tie (equal hit counts in a dim bin) would otherwise report a zero error;
- **moderated** (for families of similar quantities, the bins of one incidence): the
  ratio of s² to the ray part u = Σ v_r / K² (known to many degrees of freedom) is the
  variance inflation the surface adds. Over the bins of one incidence it is nearly one
  number, so it is pooled with the empirical Bayes estimator of Smyth (2004, "Linear
  models and empirical Bayes methods for assessing differential expression in microarray
  experiments", Stat. Appl. Genet. Mol. Biol. 3(1), art. 3, sec. 3 and 6.2): the
  inflations have a scaled inverse-χ² prior with d0 degrees of freedom about ρ0, fitted to
  the bins of a pool, and each bin's variance is the posterior mean

      ṽ = (d0 ρ0 u + d s²) / (d0 + d),   with d0 + d degrees of freedom,

  which is s² when the inflations scatter (d0 → 0) and ρ0 u when they agree (d0 → ∞);
  the degrees of freedom reported also count the error of ρ0 itself (``_moderate``).

A single realisation (K = 1) has no between-tile spread to measure: its error is the ray
error √v (error model ``rays``), conditional on the one tile.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

RAYS = "rays"
ENSEMBLE = "ensemble"
"""Error models: ``rays``, the errors count the ray noise of one tile; ``ensemble``, they
include the spread between surface realisations."""
DOF_MAX = 1e6
"""Degrees of freedom reported for an error known to (practically) infinite precision."""


@dataclass
class Estimate:
    """An ensemble mean with its errors.

    Attributes
    ----------
    mean, stderr : (..., m, c) float
        μ̂ and its standard error (NaN where undefined: no realisation saw a contribution,
        or fewer than two rays).
    ray_stderr : (..., m, c) float
        The ray noise's share of the error, √u (equal to ``stderr`` for one realisation).
    dof : (..., c) float
        Degrees of freedom of the variance estimate: K − 1 for batch means, d0 + K − 1
        when moderated (capped at ``DOF_MAX``), the rays' n − 1 for one realisation.
    inflation : (..., c) float
        The pooled variance inflation ρ0 of a moderated estimate (NaN otherwise).
    realisations : (...) int
        Realisations that entered each estimate.
    """

    mean: np.ndarray
    stderr: np.ndarray
    ray_stderr: np.ndarray
    dof: np.ndarray
    inflation: np.ndarray
    realisations: np.ndarray


def realisation_moments(s1: np.ndarray, s2: np.ndarray, rays: np.ndarray
                        ) -> tuple[np.ndarray, np.ndarray]:
    """Each realisation's estimate m_r and its ray variance v_r.

    Parameters
    ----------
    s1, s2 : (K, ..., m, c) float
        Σx and Σx² over each realisation's rays (x = 0 for rays that did not contribute).
    rays : (K, ...) int
        Rays per realisation; 0 where a realisation is absent.

    Returns
    -------
    m, v : (K, ..., m, c) float
        NaN where the realisation is absent; v is NaN where Σx² = 0 (no ray contributed,
        so the variance is unknown) or n < 2.
    """
    n = np.asarray(rays, float)[..., None, None]
    with np.errstate(invalid="ignore", divide="ignore"):
        m = np.where(n > 0, s1 / n, np.nan)
        # max(s2 − s1 m, 0) / (n − 1) / n, operation by operation, in one array
        v = np.multiply(s1, m)
        np.subtract(s2, v, out=v)
        np.maximum(v, 0.0, out=v)
        np.divide(v, n - 1, out=v)
        np.divide(v, n, out=v)
    v[~((s2 > 0) & (n >= 2))] = np.nan
    return m, v


def inverse_trigamma(x: float) -> float:
    """y with ψ'(y) = x > 0 (``inverse_trigammas`` of one value)."""
    return float(inverse_trigammas(np.array([x], float))[0])


def inverse_trigammas(x: np.ndarray) -> np.ndarray:
    """y with ψ'(y) = x > 0, elementwise, by Newton's method on 1/ψ', which is nearly
    linear (Smyth 2004, appendix; ψ'(y) ≈ 1/y for large y and 1/y² for small y); each
    element stops when its relative step falls below 1e-12 (after 16 steps at most over
    [1e-6, 1e7], measured at 20 001 log-spaced x). Outside that range no step is taken:
    y is the asymptotic 1/x below it and 1/√x above it, where ψ'(y) = x (1 + x/2 + …)
    and x (1 + π²/(6x) + …), so ψ'(y) is x within 1e-6 relative.

    Parameters
    ----------
    x : (n,) float

    Returns
    -------
    (n,) float
    """
    from scipy.special import polygamma  # here: tables are read without scipy

    x = np.asarray(x, float)
    y = np.where(x > 1e7, 1.0 / np.sqrt(x), np.where(x < 1e-6, 1.0 / x, 0.5 + 1.0 / x))
    active = np.flatnonzero((x <= 1e7) & (x >= 1e-6))
    for _ in range(50):
        if not active.size:
            break
        ya = y[active]
        tri = polygamma(1, ya)
        step = tri * (1.0 - tri / x[active]) / polygamma(2, ya)
        y[active] = ya + step
        active = active[-step / y[active] >= 1e-12]
    return y


def moderation_prior(ratio: np.ndarray, d: int) -> tuple[float, float]:
    """Smyth's (2004, sec. 6.2) prior fitted to sample variances with ``d`` degrees of
    freedom, here variance ratios s²/u.

    A ratio is ρ_b χ²_d / d with the bin's own inflation ρ_b = ρ0 d0 / χ²_d0. With
    e = log(ratio) − ψ(d/2) + log(d/2) (E log(χ²_d / d) = ψ(d/2) − log(d/2)),
    E[e] = E[log ρ_b] = log ρ0 − ψ(d0/2) + log(d0/2) and Var[e] = ψ'(d/2) + ψ'(d0/2): d0
    solves ψ'(d0/2) = var(e) − ψ'(d/2) (infinite when the right side is not positive: the
    ratios scatter no more than sampling alone makes them), then
    ρ0 = exp(mean(e) + ψ(d0/2) − log(d0/2)).

    Parameters
    ----------
    ratio : (g,) float
        Positive finite ratios, g ≥ 2.
    d : int
        Their degrees of freedom.

    Returns
    -------
    rho0, d0 : float
        d0 may be ``math.inf``.
    """
    from scipy.special import polygamma, psi

    e = np.log(ratio) - psi(d / 2) + math.log(d / 2)
    excess = float(e.var(ddof=1)) - float(polygamma(1, d / 2))
    if excess <= 0:
        return math.exp(float(e.mean())), math.inf
    d0 = 2.0 * inverse_trigamma(excess)
    return math.exp(float(e.mean()) + psi(d0 / 2) - math.log(d0 / 2)), d0


def moderation_priors(ratio: np.ndarray, d: np.ndarray) -> np.ndarray:
    """ρ0 of ``moderation_prior`` for each row of ratios at once.

    Parameters
    ----------
    ratio : (g, n) float
        Per row its ratios, NaN where a row has none (at least two per row).
    d : (g,) int
        Their degrees of freedom per row.

    Returns
    -------
    (g,) float
    """
    from scipy.special import polygamma, psi

    d = np.asarray(d, float)
    e = np.log(ratio) - (psi(d / 2) - np.log(d / 2))[:, None]
    mean = np.nanmean(e, axis=1)
    excess = np.nanvar(e, axis=1, ddof=1) - polygamma(1, d / 2)
    prior = excess > 0
    d0 = 2.0 * inverse_trigammas(np.where(prior, excess, 1.0))
    return np.where(prior, np.exp(mean + psi(d0 / 2) - np.log(d0 / 2)), np.exp(mean))


GROUPS = 32
"""Groups of realisations whose sums ``RunningEstimate`` keeps apart for the jackknife of the
pooled inflation: realisation r joins group r mod ``GROUPS``, so up to ``GROUPS``
realisations it is the delete-one jackknife and beyond it the delete-a-group jackknife
(Kott 2001, "The delete-a-group jackknife", J. Official Statistics 17(4), 521), and the
memory stays that of ``GROUPS`` realisations however many are averaged."""
ROUNDOFF = 1e-12
"""A sum of squared deviations below this fraction of the squared deviations from the
shift it was computed about is round-off of an exact zero (realisations that tie)."""


def estimate(s1: np.ndarray, s2: np.ndarray, rays: np.ndarray,
             pool: np.ndarray | None = None) -> Estimate:
    """The ensemble mean of realisations' sums and its standard error.

    Parameters
    ----------
    s1, s2 : (K, ..., m, c) float
        Σx and Σx² over each realisation's rays.
    rays : (K, ...) int
        Rays per realisation (0: absent from that estimate).
    pool : (..., m, c) bool or None
        Where the moderated estimator fits its prior: for each leading index and column
        c, the entries of the m axis marked True (at least two, each with a defined
        ratio, else that group falls back to batch means). None: batch means everywhere.

    Returns
    -------
    Estimate
        A single realisation's variance has its rays − 1 degrees of freedom.
    """
    rays = np.asarray(rays, np.int64)
    m, v = realisation_moments(np.asarray(s1, float), np.asarray(s2, float), rays)
    return combine(m, v, np.where(rays > 0, rays, 0).sum(axis=0) - 1.0, pool)


def combine(m: np.ndarray, v: np.ndarray, dof_one: np.ndarray | float,
            pool: np.ndarray | None = None) -> Estimate:
    """The ensemble mean of realisations' estimates and its standard error
    (``RunningEstimate`` fed realisation by realisation).

    Parameters
    ----------
    m, v : (K, ..., m, c) float
        Each realisation's estimate and its within-realisation variance (the ray part, or
        any variance estimate given the realisation); NaN rows of ``m`` mark absent
        realisations, NaN in ``v`` an unknown variance.
    dof_one : (...) float
        Degrees of freedom of ``v`` where one realisation is present.
    pool : (..., m, c) bool or None
        As for ``estimate``.

    Returns
    -------
    Estimate
    """
    running = RunningEstimate(m.shape[1:], GROUPS)
    for r in range(len(m)):
        running.add(r, m[r], v[r])
    return running.estimate(pool, dof_one)


class RunningEstimate:
    """Running sums over realisations from which ``estimate`` follows: the memory of at
    most ``groups`` realisations, whatever their number.

    Realisation r's estimates m_r and ray variances v_r are added as Σ (m_r − c) and
    Σ (m_r − c)² about a shift c, the first realisation's m (so realisations that tie sum
    to exactly zero deviation, and the one-pass variance does not cancel: Chan, Golub &
    LeVeque 1983, "Algorithms for computing the sample variance", Am. Stat. 37(3), 242),
    and Σ v_r, kept per group r mod ``groups`` for the jackknife of the moderated
    estimator. Each leading index (an incident direction, a component) counts its own
    realisations: an entry is added only where the realisation has it.

    Parameters
    ----------
    shape : tuple of int
        (..., m, c) of one realisation's estimates.
    groups : int
        Groups kept apart (``GROUPS`` for families the moderated estimator pools; 1 for
        batch means alone).
    ray_variance : bool
        Whether realisations bring their ray variances v_r. Without them (``add`` with
        ``v`` None) the error is batch means alone, not floored, and needs K ≥ 2: NaN for
        a single realisation.
    """

    def __init__(self, shape: tuple[int, ...], groups: int = 1,
                 ray_variance: bool = True) -> None:
        self.shape, self.groups = tuple(shape), int(groups)
        self.ray_variance = bool(ray_variance)
        lead = self.shape[:-2]
        self.count = np.zeros(lead, np.int64)
        self.shift = np.full(self.shape, np.nan)
        self.known = np.zeros(self.shape, np.int64)    # realisations whose v is defined
        self.dof_one = np.zeros(lead)                  # their rays − 1 (one realisation)
        self._sums: dict[int, tuple[np.ndarray, ...]] = {}
        self._cached: tuple[np.ndarray, ...] | None = None

    def add(self, r: int, m: np.ndarray, v: np.ndarray | None,
            rays: np.ndarray | int | None = None, at: tuple[int, ...] = ()) -> None:
        """Add realisation ``r``'s estimates.

        Parameters
        ----------
        r : int
            Its index (it decides the group).
        m, v : (..., m, c) float
            Its estimates and their ray variances (of the entries ``at`` selects); NaN
            rows of ``m`` where it is absent, NaN in ``v`` where the variance is unknown.
            ``v`` is None exactly when the sums were made without ``ray_variance``.
        rays : (...) int, int or None
            Its rays, whose sum less one are the degrees of freedom of one realisation.
        at : tuple of int
            A leading index the arrays belong to (default: all of ``shape``).
        """
        if (v is None) == self.ray_variance:
            raise ValueError("ray variances are given exactly when the sums keep them "
                             f"(ray_variance={self.ray_variance})")
        self._add(r, m, v, None, rays, at)

    def add_sums(self, r: int, s1: np.ndarray, s2: np.ndarray, rays: int,
                 at: tuple[int, ...] = ()) -> None:
        """Add realisation ``r`` from its sums over its ``rays`` (≥ 1) rays: ``add`` of
        ``realisation_moments(s1, s2, rays)``, in one pass without either array.

        Parameters
        ----------
        r : int
        s1, s2 : (..., m, c) float
            Σx and Σx² over its rays (of the entries ``at`` selects).
        rays : int
        at : tuple of int
        """
        if not self.ray_variance:
            raise ValueError("sums bring ray variances; these running sums keep none")
        self._add(r, s1, s2, int(rays), rays, at)

    def _add(self, r: int, a: np.ndarray, b: np.ndarray | None, n: int | None,
             rays: np.ndarray | int | None, at: tuple[int, ...]) -> None:
        """``add`` (``n`` None: ``a``, ``b`` are m and v) or ``add_sums`` (``a``, ``b`` are
        Σx and Σx² over ``n`` rays), by ``microsim.tables.accumulate``."""
        from microsim.tables.accumulate import accumulate

        self._cached = None
        ix = (*at, Ellipsis)  # views, also of 0-d leading shapes
        g = r % self.groups
        if g not in self._sums:
            self._sums[g] = (np.zeros(self.shape), np.zeros(self.shape),
                             np.zeros(self.shape), np.zeros(self.shape[:-2], np.int64))
        lead = self.count[ix].shape
        rows = math.prod(lead)

        def flat(x: np.ndarray) -> np.ndarray:
            """x[ix] as (rows, entries) or, for counts, (rows,): a view, which writes
            go through (the running sums are C-contiguous)."""
            view = x[ix]
            if not view.flags.c_contiguous:
                raise ValueError("running sums must be C-contiguous")
            return view.reshape(rows, -1) if view.ndim > len(lead) else view.reshape(rows)

        m_or_s1 = np.ascontiguousarray(a, float).reshape(rows, -1)
        v_or_s2 = m_or_s1 if b is None else np.ascontiguousarray(b, float).reshape(rows, -1)
        present = np.empty(rows, bool)
        s1, s2, sv, group = (flat(x) for x in self._sums[g])
        accumulate(m_or_s1, v_or_s2, 0.0 if n is None else float(n), n is not None,
                   b is not None, flat(self.shift), flat(self.count), s1, s2, sv,
                   flat(self.known), group, present)
        if rays is not None:
            self.dof_one[ix] += np.where(present.reshape(lead), rays, 0)

    def absorb(self, other: RunningEstimate) -> None:
        """Add ``other``'s sums, of the same shape, whose leading indices (directions)
        hold no realisation here."""
        if other.ray_variance != self.ray_variance:
            raise ValueError("sums with and without ray variances do not add")
        self._cached = None
        theirs = other.count > 0
        self.shift = np.where(theirs[..., None, None], other.shift, self.shift)
        self.count += other.count
        self.known += other.known
        self.dof_one += other.dof_one
        for g, sums in other._sums.items():
            mine = self._sums.get(g)
            self._sums[g] = tuple(x.copy() for x in sums) if mine is None else tuple(
                x + y for x, y in zip(mine, sums, strict=True))

    def take(self, rows: Sequence[int]) -> RunningEstimate:
        """The sums of the leading indices ``rows`` of the first axis (copies)."""
        out = RunningEstimate(self.shape, self.groups, self.ray_variance)
        out.shape = (len(rows),) + self.shape[1:]
        rows = list(rows)
        out.count, out.shift = self.count[rows], self.shift[rows]
        out.known, out.dof_one = self.known[rows], self.dof_one[rows]
        out._sums = {g: tuple(x[rows] for x in sums) for g, sums in self._sums.items()}
        out._cached = None
        return out

    @property
    def mean(self) -> np.ndarray:
        """(..., m, c) the mean of the realisations added (NaN where none)."""
        s1 = self._totals()[0]
        with np.errstate(invalid="ignore", divide="ignore"):
            return self.shift + s1 / self.count[..., None, None]

    def _totals(self) -> tuple[np.ndarray, ...]:
        """Σ (m − c), Σ (m − c)², Σ v and the counts over the groups, in group order
        (kept until the next ``add`` or ``absorb``)."""
        if self._cached is None:
            parts = [x for _, x in sorted(self._sums.items())]
            self._cached = tuple(sum(x[j] for x in parts) for j in range(4))
        return self._cached

    def estimate(self, pool: np.ndarray | None = None,
                 dof_one: np.ndarray | float | None = None) -> Estimate:
        """The ensemble mean so far and its errors, as ``estimate`` defines them.

        Parameters
        ----------
        pool : (..., m, c) bool or None
            As for ``estimate``.
        dof_one : (...) float or None
            Degrees of freedom where one realisation is present (default: the rays
            added, less one).

        Returns
        -------
        Estimate
        """
        k = self.count
        s1, s2, sv, _ = self._totals()
        mean = self.mean
        with np.errstate(invalid="ignore", divide="ignore"):
            kk = k[..., None, None].astype(float)
            ray_var = np.where(self.known > 0, sv / kk**2, np.nan)
            spread = _deviations(s1, s2, kk) / (kk * (kk - 1))
        # batch means floored at the ray variance: realisations that tie (equal hit counts
        # in a dim bin) must not report a zero error; E[s²] is never below the ray part
        one = (k == 1)[..., None, None]
        stderr_sq = np.where(one, ray_var, np.fmax(spread, ray_var))
        dof_one = self.dof_one - 1.0 if dof_one is None else dof_one
        dof = np.where(k == 1, np.minimum(dof_one, DOF_MAX), k - 1).astype(float)
        dof = np.broadcast_to(dof[..., None], mean.shape[:-2] + mean.shape[-1:]).copy()
        inflation = np.full(dof.shape, np.nan)
        if pool is not None:
            if not self.ray_variance:
                raise ValueError("the moderated estimator needs the ray variances")
            self._moderate(stderr_sq, spread, ray_var, np.asarray(pool, bool), dof,
                           inflation)
        # without ray variances batch means stand alone (fmax above ignores the NaN)
        undefined = (np.isnan(ray_var) if self.ray_variance else one) | (
            k[..., None, None] < 1)
        stderr = np.where(undefined, np.nan, np.sqrt(stderr_sq))
        return Estimate(mean, stderr, np.sqrt(ray_var), dof, inflation, k.copy())

    def _moderate(self, var: np.ndarray, spread: np.ndarray, ray_var: np.ndarray,
                  pool: np.ndarray, dof: np.ndarray, inflation: np.ndarray) -> None:
        """Replace the variances ``var`` (..., m, c) by Smyth's posterior variances from
        the batch means ``spread`` (not floored: the fit needs their χ² scatter) where a
        group (leading index, column) has K ≥ 3 and at least two pooled ratios; ``dof``
        and ``inflation`` (..., c) are filled in for those groups.

        The degrees of freedom combine the prior's and the sample's, d0 + d, with the
        uncertainty of the pooled ρ0 itself: the bins of one incidence share their tiles,
        so their ratios are not independent, and ρ0 is known to ν_ρ = 2 / Var_J(log ρ0)
        degrees of freedom, Var_J the jackknife variance over realisations (Efron & Stein
        1981, Ann. Stat. 9(3), 586), deleting one group of realisations at a time (one
        realisation each up to ``groups``). The posterior variance w ρ0 u + (1 − w) s²,
        w = d0 / (d0 + d), then has relative variance 2 / (d0 + d) + w² 2 / ν_ρ
        (Satterthwaite 1946, Biometrics Bull. 2(6), 110), i.e. 1/ν = 1/(d0 + d) + w²/ν_ρ.
        A replicate that keeps fewer than two realisations, or fewer than two bins with
        s² and u > 0, leaves Var_J undefined: it is taken as infinite, so ν = 0.
        """
        totals = self._totals()
        for index in np.ndindex(*var.shape[:-2]):
            kk = int(self.count[index])
            if kk < 3:
                continue
            d = kk - 1
            groups = [g for g in sorted(self._sums) if self._sums[g][3][index] > 0]
            # every group left out at once: (groups, m', c) sums of the others, over the
            # m' bins some column pools (the only ones the jackknife reads)
            pooled = pool[index].any(axis=1)
            left = [totals[j][index][pooled][None] - np.stack(
                [self._sums[g][j][index][pooled] for g in groups]) for j in range(3)]
            rest = np.array([kk - self._sums[g][3][index] for g in groups], float)
            for c in range(var.shape[-1]):
                s2, u = spread[index][:, c], ray_var[index][:, c]
                use = pool[index][:, c] & np.isfinite(s2 / np.where(u > 0, u, np.nan)) & (
                    s2 > 0)
                if use.sum() < 2:
                    continue
                rho0, d0 = moderation_prior(s2[use] / u[use], d)
                t1, t2, tv = (x[:, use[pooled], c] for x in left)
                with np.errstate(invalid="ignore", divide="ignore"):
                    s2_g = _deviations(t1, t2, rest[:, None]) / ((rest - 1) * rest)[:, None]
                    u_g = tv / rest[:, None] ** 2
                    ok = (s2_g > 0) & (u_g > 0)
                    ratios = np.where(ok, s2_g / u_g, np.nan)
                valid = (rest >= 2) & (ok.sum(axis=1) >= 2)
                logs = np.log(moderation_priors(ratios[valid], rest[valid] - 1))
                jack = (len(groups) - 1) / len(groups) * float(
                    np.sum((logs - logs.mean()) ** 2)) if valid.all() else math.inf
                w = 1.0 if math.isinf(d0) else d0 / (d0 + d)
                prior = 0.0 if math.isinf(d0) else 1.0 / (d0 + d)
                dof[index][c] = min(1.0 / max(prior + w * w * jack / 2, 1.0 / DOF_MAX),
                                    DOF_MAX)
                var[index][:, c] = w * rho0 * u + (1.0 - w) * s2
                inflation[index][c] = rho0


def _deviations(s1: np.ndarray, s2: np.ndarray, k: np.ndarray | float) -> np.ndarray:
    """Σ (m − m̄)² from Σ (m − c) and Σ (m − c)² of k values: s2 − s1²/k, zero where it is
    round-off of zero (``ROUNDOFF``)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        dev = s2 - s1 * s1 / k
    return np.where(dev > ROUNDOFF * s2, dev, 0.0)
