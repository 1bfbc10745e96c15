"""Fresnel reflectance of a smooth interface, unpolarised light.

``cos_i`` is the cosine between the incident direction (pointing away from the surface,
towards where the light comes from) and the interface normal on the light's side, so it
lies in [0, 1]. Negative values are clamped to 0 (grazing). ``eta`` is the relative index
n_t / n_i; for a dielectric, eta < 1 means the light is inside the denser medium and total
internal reflection (F = 1) occurs beyond the critical angle.

The records at the end (``ConductorFresnel``, ``DielectricFresnel``, ``SchlickFresnel``,
``CoatedFresnel``) are what a
microfacet model takes as its facets' Fresnel factor (``TorranceSparrow``'s ``fresnel``;
None is F = 1, a mirror): the materials give them (``Material.fresnel``), the model
registry and the fits build them, and each evaluates its own factor.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def fresnel_dielectric(cos_i: np.ndarray | float, eta: np.ndarray | float) -> np.ndarray:
    """Exact unpolarised Fresnel reflectance of a dielectric interface.

    F = ½ (r_s² + r_p²) with r_s = (cos_i − η cos_t)/(cos_i + η cos_t) and
    r_p = (η cos_i − cos_t)/(η cos_i + cos_t), cos_t from Snell's law
    sin_t = sin_i / η (Born & Wolf, Principles of Optics, 7th ed., sec. 1.5.2, eq. 21a-b;
    pbrt-v4 ``FrDielectric``).

    Parameters
    ----------
    cos_i : (...) float
        Cosine of the angle of incidence, clamped to [0, 1].
    eta : (...) float
        Relative index of refraction n_t / n_i (> 0). Broadcasts with ``cos_i``: an
        ``eta`` of shape (3,) with ``cos_i[..., None]`` gives RGB.

    Returns
    -------
    (...) float
        Reflectance in [0, 1]; 1 under total internal reflection.
    """
    cos_i = np.clip(np.asarray(cos_i, float), 0.0, 1.0)
    eta = np.asarray(eta, float)
    sin2_t = (1.0 - cos_i**2) / eta**2
    tir = sin2_t >= 1.0
    cos_t = np.sqrt(np.maximum(1.0 - sin2_t, 0.0))
    den_s = cos_i + eta * cos_t
    den_p = eta * cos_i + cos_t
    safe_s = np.where(den_s > 0, den_s, 1.0)
    safe_p = np.where(den_p > 0, den_p, 1.0)
    r_s = np.where(den_s > 0, (cos_i - eta * cos_t) / safe_s, 1.0)
    r_p = np.where(den_p > 0, (eta * cos_i - cos_t) / safe_p, 1.0)
    return np.where(tir, 1.0, 0.5 * (r_s**2 + r_p**2))


def fresnel_conductor(cos_i: np.ndarray | float, eta: np.ndarray | float,
                      k: np.ndarray | float) -> np.ndarray:
    """Exact unpolarised Fresnel reflectance of a conductor, complex index η + i k.

    With the complex index n = η + i k, cos_t = √(1 − sin²_i / n²) (principal branch) and
    the same r_s, r_p as for a dielectric with complex arithmetic (Born & Wolf, sec. 14.2;
    pbrt-v4 ``FrComplex``). With k = 0 this equals ``fresnel_dielectric``.

    Parameters
    ----------
    cos_i : (...) float
        Cosine of the angle of incidence, clamped to [0, 1].
    eta, k : (...) float
        Real and imaginary parts of the relative index (broadcast like
        ``fresnel_dielectric``: shape (3,) with ``cos_i[..., None]`` for RGB).

    Returns
    -------
    (...) float
        Reflectance in [0, 1].
    """
    cos_i = np.clip(np.asarray(cos_i, float), 0.0, 1.0)
    n = np.asarray(eta, float) + 1j * np.asarray(k, float)
    sin2_i = 1.0 - cos_i**2
    cos_t = np.sqrt(1.0 - sin2_i / n**2)
    r_s = (cos_i - n * cos_t) / (cos_i + n * cos_t)
    r_p = (n * cos_i - cos_t) / (n * cos_i + cos_t)
    return np.clip(0.5 * (np.abs(r_s) ** 2 + np.abs(r_p) ** 2), 0.0, 1.0)


def _normal_wavenumber(n_sq: np.ndarray, sin2_i: np.ndarray) -> np.ndarray:
    """q = n cos θ = √(n² − sin²θi) on the branch Im q ≥ 0 (decaying, or evanescent beyond
    a critical angle)."""
    q = np.sqrt(n_sq - sin2_i)
    return np.where(q.imag < 0, -q, q)


def fresnel_thin_film(cos_i: np.ndarray | float, eta_film: np.ndarray | float,
                      thickness_nm: np.ndarray | float, wavelength_nm: np.ndarray | float,
                      eta_sub: np.ndarray | float, k_sub: np.ndarray | float) -> np.ndarray:
    """Unpolarised reflectance of a substrate coated with one dielectric film, with
    interference: the Airy sum of the film's multiple reflections, per polarisation,

    r = (r01 + r12 e^{2iβ}) / (1 + r01 r12 e^{2iβ}), β = 2π d η_f cos θ_f / λ,

    R = ½ (|r_s|² + |r_p|²) (Born & Wolf, Principles of Optics, 7th ed., sec. 1.6.4,
    eqs. 57-58), with r_jk = (a_j − a_k)/(a_j + a_k) for admittances a = n cos θ (s) and
    cos θ / n (p), n cos θ = √(n² − sin²θi) with Im ≥ 0 (sec. 1.5.2, eq. 21a-b, complex for
    a conductor or beyond a critical angle). Light comes from index 1; all indices are
    relative to it. With d = 0 this is ``fresnel_conductor`` of the substrate.

    Parameters
    ----------
    cos_i : (...) float
        Cosine of the angle of incidence, clamped to [0, 1]; R = 1 at 0 (grazing).
    eta_film : (...) float
        Real index of the film (> 0).
    thickness_nm, wavelength_nm : (...) float
        Film thickness (≥ 0) and vacuum wavelength (> 0), in the same unit (nm).
    eta_sub, k_sub : (...) float
        Real and imaginary parts of the substrate's index (k_sub = 0: a dielectric).
        All arguments broadcast together.

    Returns
    -------
    (...) float
        Reflectance in [0, 1].
    """
    c, eta_f, d, lam, eta_s, k_s = np.broadcast_arrays(
        *(np.asarray(a, float) for a in (cos_i, eta_film, thickness_nm, wavelength_nm,
                                          eta_sub, k_sub)))
    c = np.clip(c, 0.0, 1.0)
    sin2_i = 1.0 - c**2
    n1_sq, n2_sq = eta_f**2 + 0j, (eta_s + 1j * k_s) ** 2
    q1, q2 = _normal_wavenumber(n1_sq, sin2_i), _normal_wavenumber(n2_sq, sin2_i)
    k0d = 2.0 * np.pi * d / lam
    phase = np.exp(2j * k0d * q1)  # e^{2iβ}
    graze = c <= 0.0
    a0 = np.where(graze, 1.0, c)  # any nonzero admittance: R = 1 is set below
    reflectance = np.zeros(c.shape)
    with np.errstate(invalid="ignore", divide="ignore"):
        for a1, a2, g in ((q1, q2, k0d), (q1 / n1_sq, q2 / n2_sq, k0d * n1_sq)):
            r01 = (a0 - a1) / (a0 + a1)
            r12 = (a1 - a2) / (a1 + a2)
            # a1 = 0 (η_f < 1 at its critical angle) makes r 0/0: the limit a1 → 0 of the
            # film's characteristic matrix (sec. 1.6.2), sin β / a1 → g
            limit = (a0 - a2 - 1j * g * a0 * a2) / (a0 + a2 - 1j * g * a0 * a2)
            r = np.where(a1 == 0, limit, (r01 + r12 * phase) / (1.0 + r01 * r12 * phase))
            reflectance += 0.5 * np.abs(r) ** 2
    return np.where(graze, 1.0, np.clip(reflectance, 0.0, 1.0))


@dataclass(frozen=True, eq=False)
class ConductorFresnel:
    """The Fresnel factor of a conductor of complex relative index η + ik
    (``fresnel_conductor``).

    Parameters
    ----------
    eta, k : float or (C,) float
        One number for every channel, or one per channel (RGB, or one per wavelength).
    """

    eta: np.ndarray | float
    k: np.ndarray | float

    def factor(self, cos: np.ndarray) -> np.ndarray:
        """F at ``cos`` (...,): (...) for numbers, (..., C) per channel."""
        if np.ndim(self.eta) or np.ndim(self.k):
            return fresnel_conductor(cos[..., None], self.eta, self.k)
        return fresnel_conductor(cos, self.eta, self.k)


@dataclass(frozen=True, eq=False)
class DielectricFresnel:
    """The Fresnel factor of reflection off a dielectric of relative index η
    (``fresnel_dielectric``).

    Parameters
    ----------
    eta : float or (C,) float
    """

    eta: np.ndarray | float

    def factor(self, cos: np.ndarray) -> np.ndarray:
        """F at ``cos`` (...,): (...) for a number, (..., C) per channel."""
        return fresnel_dielectric(cos[..., None] if np.ndim(self.eta) else cos, self.eta)


@dataclass(frozen=True, eq=False)
class SchlickFresnel:
    """Schlick's approximation F0 + (1 − F0)(1 − cos)⁵ (Schlick 1994, "An inexpensive BRDF
    model for physically-based rendering", Comput. Graph. Forum 13(3), eq. 15): what model
    fits use.

    Parameters
    ----------
    f0 : float or (C,) float
        Reflectance at normal incidence, per channel.
    """

    f0: np.ndarray | float

    def factor(self, cos: np.ndarray) -> np.ndarray:
        """F at ``cos`` (...,): (...) for a number, (..., C) per channel."""
        f0 = np.asarray(self.f0, float)
        c = cos[..., None] if f0.ndim else cos
        return f0 + (1.0 - f0) * (1.0 - c) ** 5


@dataclass(frozen=True, eq=False)
class CoatedFresnel:
    """The Fresnel factor of facets under a thin dielectric film, per wavelength
    (``fresnel_thin_film``).

    Parameters
    ----------
    eta_film : float or (C,) float
        The film's index.
    thickness_nm : float
    wavelength_nm : (C,) float
        The channels' wavelengths.
    eta, k : float or (C,) float
        The facet beneath (k = 0: a dielectric).
    """

    eta_film: np.ndarray | float
    thickness_nm: float
    wavelength_nm: np.ndarray
    eta: np.ndarray | float
    k: np.ndarray | float

    def factor(self, cos: np.ndarray) -> np.ndarray:
        """F at ``cos`` (...,): (..., C)."""
        return fresnel_thin_film(cos[..., None], self.eta_film, self.thickness_nm,
                                 self.wavelength_nm, self.eta, self.k)


Fresnel = ConductorFresnel | DielectricFresnel | SchlickFresnel | CoatedFresnel
"""A facet's Fresnel factor as the microfacet models take it (None besides: F = 1)."""
