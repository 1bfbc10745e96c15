"""Woven cloth: the microcylinder model of Sadeghi, Bisker, De Deken & Jensen 2013, "A
practical microcylinder appearance model for cloth rendering", ACM TOG 32(2), 14.

The cloth is two families of threads (j = 1: warp along y, j = 2: weft along x) covering
fractions a_1, a_2 of the surface (the rest, gaps, reflects nothing). Each family's thread
tangent t turns as the thread goes over and under the other (its tangent curve, sec. 5);
each tangent scatters with the thread scattering function f_s of sec. 4, and threads
shadow and mask each other (sec. 5.2). In the thread's frame (t, and the normal plane with
azimuths measured from the cloth normal's projection): the longitudinal angles
sin θ_i = ω_i·t, sin θ_r = ω_o·t, θ_h = (θ_i + θ_r)/2, θ_d = (θ_r − θ_i)/2; the
azimuths φ_i, φ_r of the projections and φ_d = φ_r − φ_i ∈ [−π, π]. Then

- surface reflection f_R = F(η, cos ι) ¼ cos(φ_d/2) g(γ_s, 2θ_h), cos ι = cos θ_d
  cos(φ_d/2): a specular lobe about the cone θ_h = 0 of longitudinal width γ_s (in θ_r),
  with the azimuthal distribution of the R lobe of Marschner et al. 2003 (eq. 9 with
  p = 0). The normalisation is chosen so that a smooth thread (γ_s → 0) reflects exactly
  the power it intercepts, as the exact cylinder does (tested): the Gaussian has unit
  area over θ_r (one of unit area over θ_h integrates to 2 over θ_r) and the ¼ is
  Marschner's; Sadeghi et al.'s fitted parameters absorb such factors;
- volume scattering f_V = (1 − F)² A [(1 − k_d) g(γ_v, θ_h) + k_d] / (cos θ_i + cos θ_r):
  light entering the thread and leaving it, peaked on the cone (width γ_v) or
  isotropic, as Sadeghi et al. write it (the two transmissions as (1 − F)², F at the
  surface term's angle). A is a fitted scale, not an albedo: with A = 1, k_d = 1 and
  F → 0 a closed layer of flat threads, no masking, "reflects" 3.0 of the light at
  normal incidence, 3.9 at 40° and 17 at 80° (quadrature: the term is not normalised);
- f_s = (f_R + f_V) / cos² θ_d,

g(γ, x) the unit-area Gaussian of standard deviation γ. Shadowing and masking by the
neighbouring threads: M(ω) = max(cos φ, 0), correlated by
M = (1 − u) M_i M_o + u min(M_i, M_o), u = exp(−φ_d² / (2 σ²)), σ = 20° (sec. 5.2).

**Combination.** A layer of cylinders of coverage a whose tangents are t intercepts
a cos θ_Li / cos θ_i of the macro-surface's irradiance per unit area and is seen over
a cos θ_Lo / cos θ_o of its projected area (cos θ_L = cos of the longitudinal angle, the
sine of the angle to the tangent), so

    f_r(ω_i, ω_o) = Σ_j a_j ⟨ f_s(t) M(t) cos θ_Li cos θ_Lo ⟩_{t ∈ T_j} / (cos θ_i cos θ_o),

the mean over each family's tangent samples. For threads lying flat in a closed layer,
cos θ_L cos φ = cos θ (the macro cosine) and M's uncorrelated part cancels the
projections: f_r = Σ_j a_j ⟨f_s⟩, Sadeghi et al.'s combination of the two threads'
radiances (their weighting of inclined tangents by apparent length is what the
projections do here).

**Tangent curves** of the ``weave`` generator's yarns (heights ±A at the crossings of
spacing s joined by half cosines): on a crossing-to-crossing interval where the yarn
changes side, the slope is ±(Aπ/s) sin(πτ), τ uniform in (0, 1); on the others (floats)
it is 0. The share of changing intervals is 2/n per repeat of n yarns (1 for plain
weave). ``tangents`` samples these for each family.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from microsim.analytic.brdf import flat_pairs, rgb
from microsim.analytic.fresnel import fresnel_dielectric

CORRELATION = math.radians(20.0)
"""σ of the shadowing-masking correlation u(φ_d) (Sadeghi et al. 2013, sec. 5.2)."""


def tangents(along: Sequence[float], slope: float, flat: float, count: int
             ) -> tuple[np.ndarray, np.ndarray]:
    """One thread family's tangent samples and weights.

    Parameters
    ----------
    along : (3,) float
        Unit direction the family runs along (horizontal).
    slope : float
        Largest slope of the yarn's centre line, A π / s.
    flat : float
        Share of the thread's length that is flat (floats), in [0, 1].
    count : int
        Samples of τ over a rising (and as many over a falling) interval.

    Returns
    -------
    t : (2 count + 1, 3) float
        Unit tangents (one when the thread is straight).
    w : (2 count + 1,) float
        Weights (sum 1): the flat tangent carries ``flat``.
    """
    a = np.asarray(along, float)
    if slope == 0 or flat >= 1:
        return a[None] / np.linalg.norm(a), np.ones(1)
    tau = (np.arange(count) + 0.5) / count
    k = np.concatenate([[0.0], slope * np.sin(math.pi * tau), -slope * np.sin(math.pi * tau)])
    t = a[None] + k[:, None] * np.array([0.0, 0.0, 1.0])
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    w = np.concatenate([[flat], np.full(2 * count, (1.0 - flat) / (2 * count))])
    return t, w


def gaussian(gamma: float, x: np.ndarray) -> np.ndarray:
    """The unit-area Gaussian g(γ, x) of standard deviation γ."""
    return np.exp(-0.5 * (x / gamma) ** 2) / (gamma * math.sqrt(2 * math.pi))


class MicrocylinderCloth:
    """The cloth BRDF of the module docstring.

    Parameters
    ----------
    coverage : (2,) float
        a_1 (warp), a_2 (weft).
    eta : float
        The threads' index of refraction (Fresnel).
    gamma_s, gamma_v : float
        Widths of the surface and volume lobes, radians.
    kd : float
        Isotropic share of the volume scattering.
    albedo : (2, 3) float
        Volume albedo A per family and colour.
    slope, flat : float
        The families' tangent curves (``tangents``).
    masking : bool
        Apply M (False: no shadowing, for limiting cases).
    count : int
        Tangent samples per rising or falling interval.
    """

    def __init__(self, coverage: Sequence[float], eta: float, gamma_s: float,
                 gamma_v: float, kd: float, albedo: np.ndarray, slope: float, flat: float,
                 masking: bool = True, count: int = 8) -> None:
        self.coverage = np.asarray(coverage, float)
        self.eta, self.gamma_s, self.gamma_v, self.kd = float(eta), float(gamma_s), float(
            gamma_v), float(kd)
        self.albedo = rgb(albedo, "albedo", rows=2)
        self.masking = masking
        self.families = [tangents([0.0, 1.0, 0.0], slope, flat, count),
                         tangents([1.0, 0.0, 0.0], slope, flat, count)]

    def thread(self, t: np.ndarray, wi: np.ndarray, wo: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """f_R / cos² θ_d, f_V / (A cos² θ_d) and M cos θ_Li cos θ_Lo for each tangent.

        Parameters
        ----------
        t : (m, 3) float
            Unit tangents (not vertical).
        wi, wo : (n, 3) float

        Returns
        -------
        surface, volume, weight : (n, m) float
        """
        si, so = wi @ t.T, wo @ t.T
        ti, to = np.arcsin(np.clip(si, -1, 1)), np.arcsin(np.clip(so, -1, 1))
        th, td = 0.5 * (ti + to), 0.5 * (to - ti)
        # the normal plane's frame: n = the cloth normal's projection, b = t × n
        n = np.array([0.0, 0.0, 1.0]) - t[:, 2:3] * t
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        b = np.cross(t, n)
        pi_, po = np.arctan2(wi @ b.T, wi @ n.T), np.arctan2(wo @ b.T, wo @ n.T)
        pd = np.mod(po - pi_ + math.pi, 2 * math.pi) - math.pi
        cos_half = np.cos(0.5 * pd)
        f = fresnel_dielectric(np.cos(td) * cos_half, self.eta)
        inv = 1.0 / np.maximum(np.cos(td) ** 2, 1e-12)
        surface = f * 0.25 * cos_half * gaussian(self.gamma_s, 2 * th) * inv
        phase = (1 - self.kd) * gaussian(self.gamma_v, th) + self.kd
        volume = (1 - f) ** 2 * phase / np.maximum(np.cos(ti) + np.cos(to), 1e-12) * inv
        mi, mo = np.maximum(np.cos(pi_), 0.0), np.maximum(np.cos(po), 0.0)
        if self.masking:
            u = np.exp(-0.5 * (pd / CORRELATION) ** 2)
            m = (1 - u) * mi * mo + u * np.minimum(mi, mo)
        else:
            m = 1.0
        return surface, volume, m * np.cos(ti) * np.cos(to)

    def eval(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """f_r, 1/sr: (..., 3)."""
        wi, wo, shape = flat_pairs(wi, wo)
        above = (wi[:, 2] > 0) & (wo[:, 2] > 0)
        f = np.zeros((len(wi), 3))
        for a, albedo, (ts, ws) in zip(self.coverage, self.albedo, self.families,
                                       strict=True):
            if a == 0:
                continue
            surface, volume, weight = self.thread(ts, wi, wo)
            f += a * ((surface * weight) @ ws)[:, None] + a * ((volume * weight) @ ws)[
                :, None] * albedo
        den = np.where(above, wi[:, 2] * wo[:, 2], 1.0)
        return np.where(above[:, None], f / den[:, None], 0.0).reshape(*shape, 3)
