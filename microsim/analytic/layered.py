"""A Lambertian substrate under a smooth dielectric layer (a clear coat without absorption).

Light enters through the smooth interface with probability 1 − F(θi, η), the substrate
reflects a fraction ρ diffusely, a fraction 1 − r_i of diffuse light inside leaves through
the interface and r_i is reflected back to the substrate (r_i the cosine-weighted
hemispherical Fresnel reflectance from inside, total internal reflection included). Summing
the bounces between substrate and interface (Kelemen & Szirmay-Kalos 2001, "A microfacet
based coupled specular-matte BRDF model with importance sampling", Eurographics short
papers; Weidlich & Wilkie 2007, "Arbitrarily layered micro-facet surfaces",
GRAPHITE) gives the diffuse BRDF

    f_r(ωi, ωo) = ρ (1 − F(θi, η)) (1 − F(θo, η)) / (π η² (1 − ρ r_i)),

where the 1/η² is the radiance compression on leaving the denser medium (Veach 1997,
thesis, sec. 5.2), and a specular (Dirac) reflection F(θi, η) in the mirror direction that
``eval`` does not contain. Its directional albedo is
F(θi) + (1 − F(θi)) ρ (1 − r_i) / (1 − ρ r_i), with 1 − r_i = (1 − r_e) / η².
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from microsim.analytic.fresnel import fresnel_dielectric

NODES = 64
"""Gauss-Legendre nodes for r_i (after the substitution that removes the square-root
behaviour at the critical angle, the error is below 1e-12 at η = 1.5)."""


def internal_reflectance(eta: float) -> float:
    """Cosine-weighted hemispherical reflectance r_i = ∫ F(μ, 1/η) 2μ dμ over μ = cos θ
    in [0, 1] from inside a medium of relative index η > 1.

    Below μc = √(1 − 1/η²) the light is totally reflected (that part integrates to μc²);
    above it F has a square-root behaviour at μc, removed by μ = μc + (1 − μc) s².

    Parameters
    ----------
    eta : float
        Relative index (> 1).

    Returns
    -------
    float
    """
    mu_c = math.sqrt(1.0 - 1.0 / eta**2)
    s, w = np.polynomial.legendre.leggauss(NODES)
    s, w = (s + 1) / 2, w / 2  # on [0, 1]
    mu = mu_c + (1 - mu_c) * s * s
    jac = 2 * (1 - mu_c) * s
    return mu_c**2 + float(np.sum(w * jac * 2 * mu * fresnel_dielectric(mu, 1 / eta)))


class CoatedLambertian:
    """Diffuse reflection of a Lambertian substrate under a smooth dielectric layer.

    Parameters
    ----------
    albedo : float or (3,) float
        Substrate albedo ρ.
    eta : float
        Index of the layer relative to air (> 1).
    """

    def __init__(self, albedo: float | Sequence[float], eta: float) -> None:
        self.albedo = np.asarray(albedo, float)
        self.eta = float(eta)
        self.r_i = internal_reflectance(self.eta)

    def eval(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """f_r of the diffuse part, 1/sr: ``(...)`` for a scalar albedo, ``(..., 3)`` for
        RGB (0 at or below the horizon)."""
        wi, wo = np.broadcast_arrays(np.asarray(wi, float), np.asarray(wo, float))
        above = (wi[..., 2] > 0) & (wo[..., 2] > 0)
        t = ((1 - fresnel_dielectric(wi[..., 2], self.eta))
             * (1 - fresnel_dielectric(wo[..., 2], self.eta)) * above)
        scale = self.albedo / (math.pi * self.eta**2 * (1 - self.albedo * self.r_i))
        return t[..., None] * scale if self.albedo.ndim else t * float(scale)

    def directional_albedo(self, cos_i: np.ndarray | float) -> np.ndarray:
        """∫ f_r cos θo dωo plus the specular F: the whole reflected fraction, ``(...)`` or
        ``(..., 3)``."""
        f = np.asarray(fresnel_dielectric(cos_i, self.eta))
        rho = self.albedo
        diffuse = rho * (1 - self.r_i) / (1 - rho * self.r_i)
        return (f[..., None] + (1 - f[..., None]) * diffuse if rho.ndim
                else f + (1 - f) * float(diffuse))
