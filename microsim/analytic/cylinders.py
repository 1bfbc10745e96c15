"""Exact single scattering of parallel cylinders on a base: the reflection geometry of a
circle, with the shadowing and masking of the neighbours and the base done exactly.

The surface: circular cylinders of radius r along y, one per period s along x, their axes
at height z_c = r − sink over a base plane z = 0 (the ``cylinders`` generator's geometry,
its smooth limit). Everything is decided in the (x, z) cross-section, because a ray's
intersections with infinite cylinders along y are those of its projection: a direction ω
projects to the unit vector p = (ω_x, ω_z) / cos θ_L at the angle α = atan2(ω_z, ω_x),
cos θ_L = √(ω_x² + ω_z²) = sin(t, ω) (θ_L: the angle between ω and the normal plane, the
longitudinal angle of Marschner et al. 2003).

**Lit and seen arcs.** A point at angle ψ on the circle (outward normal n = (cos ψ, sin ψ))
faces p when ψ ∈ (α − π/2, α + π/2). Its ray towards p is blocked by the neighbour on the
side p leans to when |(P − C₁) × p| < r; with c = s sin α / r and β = arcsin(min(c − 1, 1))
this leaves ψ ∈ [α − β, α + π/2] for p_x > 0 and [α − π/2, α + β] for p_x < 0 (farther
neighbours shadow a subset: no ray passes under a cylinder that touches or enters the
base). The base keeps ψ ∈ [a₀, π − a₀], a₀ = arcsin(−z_c / r). Lit and seen is the
intersection of three intervals.

**Specular cylinders** (mirror, conductor, dielectric facets; ``singular``). A collimated
beam meets a cylinder at impact parameter h ∈ (−1, 1), uniformly distributed across the
beam, at ψ = α_i + γ, γ = arcsin h; the ray reflects about n into ω_o = −ω_i + 2 (ω_i·n) n,
which keeps ω_o·ŷ = −ω_i·ŷ (the specular cone) and turns the projection by
2γ: its azimuth about the axis is Φ = 2γ from the backscatter direction, distributed as
dh / 2 = ¼ cos(Φ/2) dΦ: Marschner et al. 2003's R lobe with zero longitudinal width,
N_R(Φ) = ¼ cos(Φ/2) F(cos θ_Li cos(Φ/2)) (their eq. 9 with p = 0, the exact Fresnel at
the true incidence angle cos ι = ω_i·n = cos θ_Li cos γ instead of their 2-D indices). Of
the power falling on one period (per unit length along y: s cos θ_i per unit irradiance
normal to the beam), an impact interval dh carries r dh cos θ_Li / (s cos θ_i). Each
impact whose point is lit and whose reflection is seen (ω_o above the horizon, its ray
clear of the neighbours) puts F × that share into the bin of ω_o; the bin's value is the
share over its projected solid angle (what the goniometer estimates). ``singular`` does
this with a midpoint rule over h (2¹⁶ impacts: a bin's share is exact to ~1e-5 of the
period's power).

**Lambertian cylinders and base** (``eval``). A Lambertian cylinder element r dψ lit at
(ω_i·n) and seen at (ω_o·n) gives f_r = ρ r / (π s cos θ_i cos θ_o) ∫ (ω_i·n)(ω_o·n) dψ
over the lit-and-seen arc, with ω·n = cos θ_L cos(ψ − α), in closed form:
∫ cos(ψ − α_i) cos(ψ − α_o) dψ = ½ [(ψ_b − ψ_a) cos(α_i − α_o) + ½ (sin(2ψ_b − α_i − α_o)
− sin(2ψ_a − α_i − α_o))]; unshadowed, ψ_b − ψ_a = π − Φ and the integral is
½ [(π − Φ) cos Φ + sin Φ], Φ the angle between the projections (the Lambertian-cylinder
phase function). A Lambertian base of albedo ρ_b adds ρ_b / π times the share of the base
that is lit and seen: per period, the base minus the footprint of the cylinder and the
shadows the cylinders cast along p_i and p_o (each an interval of length 2r / sin α on the
line z = 0, the same interval modulo s for every cylinder), a union of three arcs on a
circle of circumference s.

These are exact for the smooth geometry and single scattering (the table's ``single``
component); the generator's prism of ``segments`` faces differs by its silhouette (a mean
projected width k sin(π/k)/π of the circle's: 0.9999 at the default 128) and, for
``smooth_normals = false``, by its facet normals.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from microsim.analytic.brdf import Lambertian, flat_pairs, rgb
from microsim.analytic.fresnel import ConductorFresnel, DielectricFresnel

IMPACTS = 2**16
"""Impact parameters per incidence in ``singular`` (midpoint rule)."""
Specular = ConductorFresnel | DielectricFresnel | None
"""A specular cylinder's facets: a conductor, a non-refracting dielectric, or None (a
mirror, F = 1)."""


def facet_reflectance(facet: Specular, cos: np.ndarray) -> np.ndarray:
    """RGB reflectance of a specular facet at incidence cosines ``cos``: 1 (a mirror,
    None), or its Fresnel record's factor (a ``DielectricFresnel``'s transmitted part
    absorbed, as a non-refracting ``dielectric`` facet does).

    Parameters
    ----------
    facet : ConductorFresnel, DielectricFresnel or None
    cos : (n,) float

    Returns
    -------
    (n, 3) float
    """
    cos = np.clip(cos, 0.0, 1.0)
    if facet is None:
        return np.ones((len(cos), 3))
    f = facet.factor(cos)
    return np.broadcast_to(f[:, None] if f.ndim == 1 else f, (len(cos), 3))


def bin_values(wo: np.ndarray, weight: np.ndarray, theta_edges: np.ndarray,
               phi_edges: np.ndarray, phi_ref: float) -> np.ndarray:
    """Power landing in each outgoing bin over the bin's projected solid angle.

    Parameters
    ----------
    wo : (n, 3) float
        Unit outgoing directions (those at or below the horizon are dropped).
    weight : (n, 3) float
        Share of the incident power each carries (RGB).
    theta_edges, phi_edges : (nt + 1,), (np + 1,) float
        Bin edges (radians); φ relative to ``phi_ref``, folded by φ → −φ when the last
        φ edge is π (a folded bin stands for itself and its mirror image).
    phi_ref : float
        Azimuth the bins' φ is measured from.

    Returns
    -------
    (nt, np, 3) float
        1/sr.
    """
    nt, nphi = len(theta_edges) - 1, len(phi_edges) - 1
    up = wo[:, 2] > 0
    wo, weight = wo[up], weight[up]
    it = np.clip(np.searchsorted(theta_edges, np.arccos(np.clip(wo[:, 2], -1, 1)),
                                 side="right") - 1, 0, nt - 1)
    phi = np.mod(np.arctan2(wo[:, 1], wo[:, 0]) - phi_ref, 2 * math.pi)
    folded = phi_edges[-1] < 4.0
    if folded:
        phi = np.minimum(phi, 2 * math.pi - phi)
    ip = np.clip(np.searchsorted(phi_edges, phi, side="right") - 1, 0, nphi - 1)
    flat = it * nphi + ip
    total = np.stack([np.bincount(flat, weight[:, c], minlength=nt * nphi)
                      for c in range(3)], axis=1).reshape(nt, nphi, 3)
    u = np.sin(theta_edges) ** 2
    omega = 0.5 * np.outer(np.diff(u), np.diff(phi_edges)) * (2.0 if folded else 1.0)
    return total / omega[..., None]


def _union_length(starts: np.ndarray, lengths: np.ndarray, period: float) -> np.ndarray:
    """Total length covered by arcs on a circle of circumference ``period``.

    Parameters
    ----------
    starts, lengths : (n, k) float
        Arcs [start, start + length) (lengths in [0, period]).

    Returns
    -------
    (n,) float
    """
    a = np.mod(starts, period)
    end = a + lengths
    wrap = np.maximum(end - period, 0.0)  # the part past the period re-enters at 0
    s = np.concatenate([a, np.zeros_like(a)], axis=1)
    e = np.concatenate([np.minimum(end, period), wrap], axis=1)
    order = np.argsort(s, axis=1)
    s, e = np.take_along_axis(s, order, 1), np.take_along_axis(e, order, 1)
    reach = np.maximum.accumulate(e, axis=1)
    before = np.concatenate([np.full((len(s), 1), -np.inf), reach[:, :-1]], axis=1)
    return np.maximum(e - np.maximum(s, before), 0.0).sum(axis=1)


class CylinderArray:
    """Single scattering of parallel cylinders along y on a base (module docstring).

    Parameters
    ----------
    radius, spacing, sink : float
        As the ``cylinders`` generator's (spacing ≥ 2 radius; sink < 2 radius); spacing
        may be ``inf`` (one cylinder: no neighbour shadows).
    facet : ConductorFresnel, DielectricFresnel, Lambertian or None
        The cylinders' material: specular with the Fresnel record's factor
        (``microsim.analytic.fresnel``; a dielectric does not refract), None for a mirror
        (F = 1), or diffuse with a ``microsim.analytic.brdf.Lambertian``'s albedo.
    base_albedo : float or (3,) float
        Albedo of a Lambertian base (0: black).
    """

    def __init__(self, radius: float, spacing: float, sink: float,
                 facet: Specular | Lambertian = None, base_albedo: float | Any = 0.0
                 ) -> None:
        if not (radius > 0 and spacing >= 2 * radius and 0 <= sink < 2 * radius):
            raise ValueError("need radius > 0, spacing >= 2 radius, 0 <= sink < 2 radius")
        if not isinstance(facet, Specular | Lambertian):
            raise ValueError("facet must be None (a mirror), a ConductorFresnel or "
                             "DielectricFresnel (microsim.analytic.fresnel) or a Lambertian "
                             f"(microsim.analytic.brdf), not {type(facet).__name__}")
        self.r, self.s, self.zc = float(radius), float(spacing), float(radius - sink)
        for name, value in vars(facet).items() if facet is not None else ():
            rgb(value, f"facet {name}")
        self.facet = facet
        self.base_albedo = rgb(base_albedo, "base_albedo")
        self.a0 = math.asin(max(-1.0, min(1.0, -self.zc / self.r)))

    def _arc(self, alpha: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Lit (or seen) arc [lo, hi] of the circle from projected directions at angles
        ``alpha`` ∈ (0, π), the neighbours' shadows and the base removed."""
        c = self.s * np.sin(alpha) / self.r
        beta = np.arcsin(np.clip(c - 1.0, -1.0, 1.0))
        right = np.cos(alpha) > 0
        left = np.cos(alpha) < 0
        lo = np.where(right, alpha - beta, alpha - math.pi / 2)
        hi = np.where(left, alpha + beta, alpha + math.pi / 2)
        return np.maximum(lo, self.a0), np.minimum(hi, math.pi - self.a0)

    def eval(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """f_r of the Lambertian parts (the cylinders if Lambertian, and the base), 1/sr.

        Parameters
        ----------
        wi, wo : (..., 3) float

        Returns
        -------
        (..., 3) float
        """
        wi, wo, shape = flat_pairs(wi, wo)
        above = (wi[:, 2] > 0) & (wo[:, 2] > 0)
        ci, co = np.where(above, wi[:, 2], 1.0), np.where(above, wo[:, 2], 1.0)
        ai, ao = np.arctan2(wi[:, 2], wi[:, 0]), np.arctan2(wo[:, 2], wo[:, 0])
        f = np.zeros((len(wi), 3))
        if isinstance(self.facet, Lambertian):
            lo_i, hi_i = self._arc(np.where(above, ai, 1.0))
            lo_o, hi_o = self._arc(np.where(above, ao, 1.0))
            a, b = np.maximum(lo_i, lo_o), np.minimum(hi_i, hi_o)
            integral = np.where(b > a, 0.5 * ((b - a) * np.cos(ai - ao) + 0.5 * (
                np.sin(2 * b - ai - ao) - np.sin(2 * a - ai - ao))), 0.0)
            cos_l = np.hypot(wi[:, 0], wi[:, 2]) * np.hypot(wo[:, 0], wo[:, 2])
            scale = self.r / (math.pi * self.s) * cos_l * integral / (ci * co)
            f += scale[:, None] * rgb(self.facet.albedo, "facet albedo")
        if np.any(self.base_albedo > 0):
            # one cylinder (spacing ∞) covers none of the base: the limit of the share, 1
            share = self._base_share(wi, wo, above) if math.isfinite(self.s) else 1.0
            f += np.multiply.outer(share, self.base_albedo / math.pi)
        f[~above] = 0.0
        return f.reshape(*shape, 3)

    def _base_share(self, wi: np.ndarray, wo: np.ndarray, above: np.ndarray) -> np.ndarray:
        """Share of the base lit from ``wi`` and seen from ``wo``."""
        w = math.sqrt(max(self.r**2 - self.zc**2, 0.0))  # half the footprint
        starts, lengths = [np.full(len(wi), -w)], [np.full(len(wi), 2 * w)]
        for d in (wi, wo):
            # pairs not above the horizon are zeroed; (0, ±1, 0) has no projection
            proj = np.where(above, np.hypot(d[:, 0], d[:, 2]), 1.0)
            sin_a = np.where(above, d[:, 2], 1.0) / proj
            cot_a = d[:, 0] / np.where(above, d[:, 2], 1.0)
            half = self.r / sin_a
            starts.append(-self.zc * cot_a - half)
            lengths.append(np.minimum(2 * half, self.s))
        covered = _union_length(np.stack(starts, 1), np.stack(lengths, 1), self.s)
        return np.maximum(self.s - covered, 0.0) / self.s

    def singular(self, wi: np.ndarray, theta_edges: np.ndarray, phi_edges: np.ndarray,
                 phi_i: float = 0.0, impacts: int = IMPACTS) -> np.ndarray:
        """Bin averages of the specular cylinders' reflection (a delta on the cone).

        Parameters
        ----------
        wi : (3,) float
            Incident direction.
        theta_edges, phi_edges : (nt + 1,), (np + 1,) float
            The table's bin edges (φ relative to ``phi_i``).
        phi_i : float
            Azimuth the bins' φ is measured from.
        impacts : int
            Midpoint nodes over the impact parameter.

        Returns
        -------
        (nt, np, 3) float
            1/sr; zeros for Lambertian cylinders.
        """
        nt, nphi = len(theta_edges) - 1, len(phi_edges) - 1
        wi = np.asarray(wi, float)
        if isinstance(self.facet, Lambertian) or wi[2] <= 0:
            return np.zeros((nt, nphi, 3))
        cos_l = math.hypot(wi[0], wi[2])
        alpha = math.atan2(wi[2], wi[0])
        h = -1.0 + (np.arange(impacts) + 0.5) * (2.0 / impacts)
        psi = alpha + np.arcsin(h)
        lo, hi = self._arc(np.array([alpha]))
        n = np.column_stack([np.cos(psi), np.zeros(impacts), np.sin(psi)])
        cos_i = n @ wi
        wo = 2.0 * cos_i[:, None] * n - wi
        lo_o, hi_o = self._arc(np.arctan2(wo[:, 2], wo[:, 0]))
        seen = (psi >= lo) & (psi <= hi) & (wo[:, 2] > 0) & (psi >= lo_o) & (psi <= hi_o)
        share = self.r * (2.0 / impacts) * cos_l / (self.s * wi[2])
        weight = facet_reflectance(self.facet, cos_i) * (share * seen)[:, None]
        return bin_values(wo, weight, theta_edges, phi_edges, phi_i)
