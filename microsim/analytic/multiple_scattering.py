"""All scattering orders of a Smith microsurface: Heitz, Hanika, d'Eon & Dachsbacher 2016.

"Multiple-scattering microfacet BSDFs with the Smith model" (ACM TOG 35(4), SIGGRAPH 2016)
treats the Smith microsurface as a volume whose free paths and phase function give, at
first order, exactly Torrance-Sparrow with height-correlated Smith masking, and at higher
orders the light that scatters between facets before it escapes. The BRDF has no closed
form; it is estimated by a random walk (their supplemental code: ``sampleHeight``,
``evalPhaseFunction``, ``samplePhaseFunction``, ``eval``), which is what this module does,
vectorised over walks, for reflecting facets (a conductor, a mirror, or a dielectric
whose transmitted light is lost) with Beckmann or GGX slopes, isotropic or anisotropic.

The walk in one state (a travel direction ω_r, a height h) per step:

- **Height.** The surface's heights enter only through their CDF C1(h), so the walk keeps
  c = C1(h) (1 above the surface) and never needs the height distribution itself: the
  BRDF does not depend on it (the Smith model's assumption). Travelling up, the ray
  escapes with probability G1(ω_r, c) = c^Λ(ω_r), else hits at c' = c (1 − U)^(−1/Λ(ω_r));
  travelling down it always hits, at c' = c (1 − U)^(1/(1 + Λ(−ω_r))) (the code's
  ``sampleHeight`` with Λ(−ω) = −1 − Λ(ω), in C1-space).
- **Next-event estimation.** At the k-th hit, seen from ωi' = −ω_r, the light that leaves
  towards ωo next is the phase function times the masking of ωo at that height,
  p(ωi', ωo) G1(ωo, c) with p = F(ωi'·h) D_ωi'(h) / (4 ωi'·h) = F D(h) / (4 A(ωi')),
  h = (ωi' + ωo)/|ωi' + ωo| (``microsim.analytic.visible_normals``); the sum over hits is
  an unbiased estimate of f_r(ωi, ωo) cos θo, the k-th term of order k.
- **Phase function.** The next direction reflects ωi' about a normal drawn from D_ωi', and
  the path's weight takes the facet's Fresnel factor F(ωi'·m).

The expected first term is D G2 F / (4 cos θi) with the height-correlated
G2 = 1/(1 + Λi + Λo): Torrance-Sparrow (tested). So the first order can be taken exactly
from ``TorranceSparrow`` (``analytic_single``, the default), which leaves only the
higher orders to chance; with F = 1 all orders together integrate to 1 (energy is
conserved: tested).

Every estimate comes with its standard error from the sample variance over independent
walks; the walks draw from one ``numpy.random.Generator`` seeded explicitly, so the same
seed and the same sequence of calls give the same numbers.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from microsim.analytic.brdf import TorranceSparrow
from microsim.analytic.fresnel import Fresnel
from microsim.analytic.visible_normals import projected_area, sample_visible
from microsim.memory import check_memory

CHUNK = 1 << 16
"""Walks run at once."""
BIN_WALK_BYTES = 160
"""Memory per walk of ``random_bin_average`` (every bin's outgoing directions drawn at
once, and the walks' results): measured 118 B with scalar Fresnel and 145 B with RGB
(12 × 24 bins × 2000 walks, tracemalloc peak), rounded up."""
MAX_ORDER = 10_000
"""A walk still on the surface after this many scattering events is cut (with F = 1 the
mean order is below 4 at α = 1; none is cut in any test)."""


@dataclass
class Walks:
    """What a batch of random walks returns.

    Attributes
    ----------
    nee : (n, rows, c) float
        Per walk, the next-event estimates of f_r(ωi, ωo) cos θo by order row (row k − 1:
        order k; the last row: orders ``rows`` and above); zero where not computed.
    escaped : (n, rows, c) float
        Per walk, its weight when it left the surface, in the row of its order.
    cut : int
        Walks stopped at ``MAX_ORDER``.
    """

    nee: np.ndarray
    escaped: np.ndarray
    cut: int


def _mean_error(x: np.ndarray, axis: int) -> tuple[np.ndarray, np.ndarray]:
    """Sample mean and its standard error √(s²/n) along ``axis``."""
    n = x.shape[axis]
    return x.mean(axis=axis), x.std(axis=axis, ddof=1) / math.sqrt(n)


class SmithMultipleScattering:
    """The BRDF of a reflecting Smith microsurface, every order or a range of them.

    Parameters
    ----------
    ndf : Beckmann or GGX
        ``microsim.analytic.ndf`` distribution, isotropic or anisotropic.
    fresnel : Fresnel or None
        As ``TorranceSparrow``: None (F = 1, a mirror), or a record of
        ``microsim.analytic.fresnel`` (a ``DielectricFresnel`` reflects only: the transmitted
        light leaves the walk).
    min_order, max_order : int, int or None
        The scattering orders the model holds, inclusive (``max_order`` None: no limit).
        Default: all.
    samples : int
        Walks per estimate: per direction pair in ``estimate``/``eval``, per bin in
        ``random_bin_average``.
    seed : int
        Seed of the generator every estimate draws from.
    analytic_single : bool
        Take the first order from ``TorranceSparrow`` with height-correlated Smith (its
        expectation) instead of the walk's estimate of it.

    Attributes
    ----------
    exact : TorranceSparrow or None
        The deterministic part of the model (order 1 when held and ``analytic_single``).
    """

    def __init__(self, ndf: object, fresnel: Fresnel | None = None, *, min_order: int = 1,
                 max_order: int | None = None, samples: int = 256, seed: int = 0,
                 analytic_single: bool = True) -> None:
        if min_order < 1 or (max_order is not None and max_order < min_order):
            raise ValueError(f"orders must satisfy 1 <= min_order <= max_order, got "
                             f"{min_order}..{max_order}")
        if samples < 2:
            raise ValueError("samples must be >= 2 (the error is a sample variance)")
        self.ndf, self.fresnel = ndf, fresnel
        self.single = TorranceSparrow(ndf, fresnel=fresnel, shadowing="smith-correlated")
        self.min_order, self.max_order = int(min_order), max_order
        self.samples, self.seed = int(samples), int(seed)
        self.analytic_single = bool(analytic_single)
        self.rng = np.random.default_rng(seed)
        self.exact = self.single if analytic_single and min_order == 1 else None

    def with_orders(self, min_order: int, max_order: int | None) -> SmithMultipleScattering:
        """The same model holding other orders; it draws from the same generator."""
        other = SmithMultipleScattering(self.ndf, self.fresnel, min_order=min_order,
                                        max_order=max_order, samples=self.samples,
                                        seed=self.seed, analytic_single=self.analytic_single)
        other.rng = self.rng
        return other

    @property
    def channels(self) -> int:
        """1 for a scalar Fresnel factor, 3 for RGB."""
        return int(np.size(self.single.F(np.ones(1))[0]))

    # --- the walk ------------------------------------------------------------------------
    def walk(self, wi: np.ndarray, wo: np.ndarray | None, rows: int = 1) -> Walks:
        """Random walks from ωi, one per row of ``wi``, with next-event estimates of the
        held orders towards ``wo``.

        Parameters
        ----------
        wi : (n, 3) float
            Incident directions (towards the light), above the horizon.
        wo : (n, 3) float or None
            Outgoing direction of each walk; None: escapes only (the walks then run until
            they leave, whatever orders the model holds).
        rows : int
            Order rows kept apart (the last: ``rows`` and above).

        Returns
        -------
        Walks
            With ``wo``, a walk stops after ``max_order`` scattering events; the first
            order's estimate is left out when it is ``exact``.
        """
        n, c = len(wi), self.channels
        nee = np.zeros((n, rows, c))
        escaped = np.zeros((n, rows, c))
        stop = math.inf if wo is None or self.max_order is None else self.max_order
        lam_o = None if wo is None else self.ndf.Lambda(wo)
        idx = np.arange(n)
        travel = -np.asarray(wi, float)
        log_c = np.zeros(n)                                   # log C1(h): above the surface
        weight = np.ones((n, c))
        order, cut = 0, 0
        while len(idx):
            if order >= MAX_ORDER:
                cut = len(idx)
                break
            # next height along the travel direction (C1-space; module docstring)
            lam = self.ndf.Lambda(travel)
            log_v = np.log(1.0 - self.rng.random(len(idx)))      # log of U' in (0, 1]
            up = travel[:, 2] > 0
            # both branches are evaluated everywhere; the other branch's overflow is moot
            with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
                gone = up & (log_v <= lam * log_c)
                log_c = np.where(up, log_c - log_v / np.where(gone, 1.0, lam),
                                 log_c + log_v / (1.0 + lam))
            if order > 0 and gone.any():
                escaped[idx[gone], min(order, rows) - 1] = weight[gone]
            keep = ~gone
            idx, travel, weight = idx[keep], travel[keep], weight[keep]
            log_c = np.minimum(log_c[keep], 0.0)
            order += 1
            if order > stop or not len(idx):
                break
            seen = -travel                                         # ωi' at this hit
            if (wo is not None and order >= self.min_order
                    and not (order == 1 and self.exact is not None)):
                nee[idx, min(order, rows) - 1] += weight * self._next_event(
                    seen, wo[idx], log_c, lam_o[idx])
            m = sample_visible(self.ndf, seen, self.rng.random(len(idx)),
                               self.rng.random(len(idx)))
            cos_m = np.sum(seen * m, axis=-1)
            weight = weight * self._fresnel(np.clip(cos_m, 0.0, 1.0))
            travel = 2.0 * cos_m[:, None] * m - seen
        return Walks(nee, escaped, cut)

    def _fresnel(self, cos: np.ndarray) -> np.ndarray:
        """(n, c) facet reflectance."""
        return self.single.F(cos).reshape(len(cos), -1)

    def _next_event(self, seen: np.ndarray, wo: np.ndarray, log_c: np.ndarray,
                    lam_o: np.ndarray) -> np.ndarray:
        """(n, c) p(ωi', ωo) G1(ωo, h): the phase function of a hit seen from ``seen``
        towards ``wo`` times the masking of ``wo`` at the hit's height (log C1(h) =
        ``log_c``)."""
        s = seen + wo
        norm = np.linalg.norm(s, axis=-1)
        h = s / np.where(norm > 0, norm, 1.0)[:, None]
        h[norm == 0] = (0.0, 0.0, 1.0)          # ωi' = −ωo: no half vector, masked below
        cos_h = np.sum(seen * h, axis=-1)
        area = projected_area(self.ndf, seen)
        ok = (norm > 0) & (cos_h > 0) & (h[:, 2] > 0) & (area > 0) & (wo[:, 2] > 0)
        phase = self.ndf.D(h) / (4.0 * np.where(ok, area, 1.0))
        with np.errstate(over="ignore"):                  # Λ ≈ 1e299 at the horizon
            shadow = np.exp(lam_o * log_c)
        return np.where(ok, phase * shadow, 0.0)[:, None] * self._fresnel(
            np.clip(cos_h, 0.0, 1.0))

    def _per_walk(self, wi: np.ndarray, wo: np.ndarray, exact: bool = True) -> np.ndarray:
        """(n, c) one estimate of the held orders' f_r cos θo per direction pair (in
        chunks of ``CHUNK`` walks), with the exact part unless ``exact`` is False."""
        out = np.zeros((len(wi), self.channels))
        for start in range(0, len(wi), CHUNK):
            part = slice(start, start + CHUNK)
            out[part] = self.walk(wi[part], wo[part]).nee[:, 0]
        if exact and self.exact is not None:
            out += self.exact.eval(wi, wo).reshape(len(wi), -1) * wo[:, 2:3]
        return out

    # --- estimates -----------------------------------------------------------------------
    def estimate(self, wi: np.ndarray, wo: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """f_r of the held orders and its standard error, from ``samples`` walks per pair.

        The walks of all pairs (``samples`` per pair, pair after pair) run ``CHUNK`` at a
        time, so memory does not grow with ``samples``; each chunk's sample means and sums
        of squared deviations per pair are merged into the running ones (Chan, Golub &
        LeVeque 1979, eq. 2.1), which gives the two-pass sample variance to rounding.

        Parameters
        ----------
        wi, wo : (..., 3) float
            Unit directions towards the light and the viewer.

        Returns
        -------
        f, stderr : (...) or (..., 3) float
            1/sr; 0 (and 0) where either direction is at or below the horizon.
        """
        wi, wo = np.broadcast_arrays(np.asarray(wi, float), np.asarray(wo, float))
        shape = wi.shape[:-1]
        wi, wo = wi.reshape(-1, 3), wo.reshape(-1, 3)
        above = (wi[:, 2] > 0) & (wo[:, 2] > 0)
        k, pairs, c = self.samples, int(above.sum()), self.channels
        wi_up, wo_up = wi[above], wo[above]
        count = np.zeros(pairs)
        mean, m2 = np.zeros((pairs, c)), np.zeros((pairs, c))
        for start in range(0, pairs * k, CHUNK):
            pair = np.arange(start, min(start + CHUNK, pairs * k)) // k
            x = self._per_walk(wi_up[pair], wo_up[pair])
            n_b = np.bincount(pair, minlength=pairs).astype(float)
            seen = n_b > 0
            sums = np.stack([np.bincount(pair, x[:, j], pairs) for j in range(c)], axis=1)
            mean_b = sums / np.where(seen, n_b, 1.0)[:, None]
            dev = x - mean_b[pair]
            m2_b = np.stack([np.bincount(pair, dev[:, j] ** 2, pairs) for j in range(c)],
                            axis=1)
            total = count + n_b
            delta = mean_b - mean
            share = np.where(seen, n_b / np.where(total > 0, total, 1.0), 0.0)[:, None]
            mean = mean + delta * share
            m2 = m2 + m2_b + delta**2 * (count * share[:, 0])[:, None]
            count = total
        err = np.sqrt(m2 / (k - 1) / k)
        f, e = np.zeros((len(wi), c)), np.zeros((len(wi), c))
        f[above], e[above] = mean / wo[above, 2:3], err / wo[above, 2:3]
        return self._shaped(f, shape), self._shaped(e, shape)

    def eval(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """f_r of the held orders (``estimate`` without its error), 1/sr."""
        return self.estimate(wi, wo)[0]

    def random_bin_average(self, wi: np.ndarray, theta_edges: np.ndarray,
                           phi_edges: np.ndarray, phi_i: float = 0.0
                           ) -> tuple[np.ndarray, np.ndarray]:
        """Projected-solid-angle averages of the random part over outgoing bins.

        Each of ``samples`` walks per bin takes its own ωo uniform in the bin's projected
        solid angle (uniform in u = sin²θo and φo), so the mean is an unbiased estimate of
        the bin average, with no quadrature error, and its sample variance gives the
        standard error. The exact part (``exact``) is not included.

        Parameters
        ----------
        wi : (3,) float
            Incident direction.
        theta_edges : (nt + 1,) float
            Bin edges in θo, radians.
        phi_edges : (np + 1,) float
            Bin edges in φo − φi, radians.
        phi_i : float
            Incident azimuth added to the bins' relative φ.

        Returns
        -------
        mean, stderr : (nt, np, c) float
            1/sr.
        """
        nt, nph, k = len(theta_edges) - 1, len(phi_edges) - 1, self.samples
        check_memory(BIN_WALK_BYTES * nt * nph * k, f"model samples = {k}: {k:,} walks in "
                     f"each of {nt * nph:,} bins", "lower the model's samples (default "
                     "256)")
        u_lo, u_hi = np.sin(theta_edges[:-1]) ** 2, np.sin(theta_edges[1:]) ** 2
        t, p = self.rng.random((2, nt, nph, k))
        u = u_lo[:, None, None] + (u_hi - u_lo)[:, None, None] * t
        phi = phi_i + phi_edges[:-1][None, :, None] + np.diff(phi_edges)[None, :, None] * p
        s, z = np.sqrt(np.clip(u, 0.0, 1.0)), np.sqrt(np.clip(1.0 - u, 0.0, 1.0))
        wo = np.stack([s * np.cos(phi), s * np.sin(phi), z], -1).reshape(-1, 3)
        x = self._per_walk(np.broadcast_to(np.asarray(wi, float), wo.shape), wo, exact=False)
        f = np.where(wo[:, 2:3] > 0, x / np.where(wo[:, 2:3] > 0, wo[:, 2:3], 1.0), 0.0)
        mean, err = _mean_error(f.reshape(nt, nph, k, -1), axis=2)
        return mean, err

    def albedo(self, wi: np.ndarray, walks: int,
               orders: Sequence[tuple[int, int | None]]) -> tuple[np.ndarray, np.ndarray]:
        """Directional albedo of ranges of orders, from where the walks leave the surface.

        An estimator independent of the next-event estimates: the mean weight of the walks
        that escape after a number of scattering events within each range. The ranges
        share the walks, so each range's error is its own sample error (ranges that
        overlap are correlated).

        Parameters
        ----------
        wi : (3,) float
            Incident direction.
        walks : int
            Walks to run (each until it leaves).
        orders : sequence of (int, int or None)
            Ranges (lowest, highest) of orders, inclusive; None: no limit. (1, None) is
            every order.

        Returns
        -------
        albedo, stderr : (len(orders), c) float
        """
        rows = max(lo if hi is None else hi + 1 for lo, hi in orders)
        take = [slice(lo - 1, None if hi is None else hi) for lo, hi in orders]
        wi = np.broadcast_to(np.asarray(wi, float), (walks, 3))
        sums = np.zeros((len(orders), self.channels))
        sums_sq = np.zeros_like(sums)
        for start in range(0, walks, CHUNK):
            e = self.walk(wi[start:start + CHUNK], None, rows).escaped
            x = np.stack([e[:, t].sum(axis=1) for t in take], axis=1)   # (n, ranges, c)
            sums += x.sum(axis=0)
            sums_sq += (x * x).sum(axis=0)
        mean = sums / walks
        var = np.maximum(sums_sq / walks - mean * mean, 0.0) * walks / (walks - 1)
        return mean, np.sqrt(var / walks)

    def _shaped(self, f: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
        """(m, c) → shape (scalar Fresnel) or shape + (3,)."""
        return f.reshape(shape) if f.shape[-1] == 1 else f.reshape(shape + (3,))
