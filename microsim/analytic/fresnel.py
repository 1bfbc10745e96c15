"""Fresnel reflectance of a smooth interface, unpolarised light.

``cos_i`` is the cosine between the incident direction (pointing away from the surface,
towards where the light comes from) and the interface normal on the light's side, so it
lies in [0, 1]. Negative values are clamped to 0 (grazing). ``eta`` is the relative index
n_t / n_i; for a dielectric, eta < 1 means the light is inside the denser medium and total
internal reflection (F = 1) occurs beyond the critical angle.
"""

from __future__ import annotations

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
