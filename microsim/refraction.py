"""Reflection and refraction at a smooth interface: the mirror law, Snell's law, the
Fresnel choice, total internal reflection, and Beer-Lambert absorption inside the medium.

A refracting dielectric facet separates air (on the side its normal points to, the front)
from the medium (behind it). A ray arriving from the front sees the relative index
η = n_medium / n_air; a ray arriving from behind (inside the medium) sees 1 / η and is
totally reflected beyond the critical angle. The scattering event picks reflection with
probability F (the exact unpolarised Fresnel reflectance) and refraction otherwise, with
path weight 1 either way: an unbiased estimator of the reflected and the transmitted
energy (Pharr, Jakob & Humphreys, PBR 4th ed., sec. 9.5, the dielectric BSDF's sampling).
Radiance scaling by 1/η² on crossing is not applied: the goniophotometer carries power
(importance), for which the crossing is weight 1 (Veach 1997, thesis, sec. 5.2).
"""

from __future__ import annotations

import numpy as np

from microsim.analytic.fresnel import fresnel_dielectric


def reflect(d: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Mirror a direction of travel about a plane: d - 2 (d . n) n.

    Parameters
    ----------
    d : (k, 3) float
        Unit directions of travel (towards the surface).
    n : (k, 3) float
        Unit facet normals.

    Returns
    -------
    (k, 3) float
        Reflected directions (away from the surface).
    """
    return d - 2.0 * np.einsum("ij,ij->i", d, n)[:, None] * n


def refract(d: np.ndarray, n: np.ndarray, eta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Refracted directions by Snell's law, in vector form.

    With i = −d (pointing away from the interface), c = i · n and the relative index
    η = n_t / n_i: t = −i / η + (c / η − cos θt) n, cos θt = √(1 − (1 − c²) / η²)
    (Walter et al. 2007, "Microfacet models for refraction through rough surfaces",
    eq. 40 with their η = n_i / n_t; PBR 4th ed., sec. 9.3, ``Refract``).

    Parameters
    ----------
    d : (k, 3) float
        Unit directions of travel, ``d . n < 0``.
    n : (k, 3) float
        Unit normals on the side the rays come from.
    eta : (k,) float
        Relative index n_t / n_i (> 0).

    Returns
    -------
    t : (k, 3) float
        Unit refracted directions of travel (``t . n < 0``); undefined where ``tir``.
    tir : (k,) bool
        Total internal reflection: no refracted ray exists (sin θt > 1).
    """
    c = np.clip(-np.einsum("ij,ij->i", d, n), 0.0, 1.0)
    sin2_t = (1.0 - c * c) / (eta * eta)
    tir = sin2_t >= 1.0
    cos_t = np.sqrt(np.maximum(1.0 - sin2_t, 0.0))
    t = d / eta[:, None] + (c / eta - cos_t)[:, None] * n
    # the formula is unit length exactly; renormalise the round-off only
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    return t, tir


def fresnel_choice(d: np.ndarray, n: np.ndarray, eta: float,
                   u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Scatter rays at refracting dielectric facets hit from either side.

    A ray with ``d . n < 0`` arrives from the front (air) and sees η; one with
    ``d . n > 0`` arrives from inside and sees 1 / η about the flipped normal. It reflects
    with probability F(cos θi, η) (1 under total internal reflection) and refracts
    otherwise; the path weight is 1 in both cases (PBR 4th ed., sec. 9.5).

    Parameters
    ----------
    d : (k, 3) float
        Unit directions of travel.
    n : (k, 3) float
        Unit face normals (pointing to the air side).
    eta : float
        Index of the medium relative to air (> 1).
    u : (k,) float
        Uniform numbers in [0, 1).

    Returns
    -------
    out : (k, 3) float
        New unit directions of travel.
    refracted : (k,) bool
        The ray crossed the interface.
    """
    front = np.einsum("ij,ij->i", d, n) < 0
    n_in = np.where(front[:, None], n, -n)
    rel = np.where(front, eta, 1.0 / eta)
    f = fresnel_dielectric(-np.einsum("ij,ij->i", d, n_in), rel)
    t, tir = refract(d, n_in, rel)
    refracted = (u >= f) & ~tir
    out = np.where(refracted[:, None], t, reflect(d, n_in))
    return out, refracted


def attenuation(sigma: np.ndarray, length: np.ndarray) -> np.ndarray:
    """Beer-Lambert transmittance exp(−σ ℓ) over path lengths inside a medium (PBR 4th
    ed., sec. 11.2, transmittance of a homogeneous medium).

    Parameters
    ----------
    sigma : (k, 3) float
        Absorption coefficients per unit length (RGB), >= 0.
    length : (k,) float
        Path lengths, >= 0; ``inf`` for a path that never leaves (a ray exactly
        parallel to the slab).

    Returns
    -------
    (k, 3) float
        Transmittance in [0, 1]; 1 where sigma is 0, whatever the length.
    """
    product = np.multiply(sigma, length[:, None], out=np.zeros(sigma.shape),
                          where=sigma > 0)
    return np.exp(-product)


def next_medium(part: np.ndarray, refracts: np.ndarray, n: np.ndarray, d_in: np.ndarray,
                d_out: np.ndarray, medium: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The media of paths after scattering at faces: a path that went through a refracting
    face (its direction kept the sign of ``d . n``) enters the face's part when it now
    goes behind the face, and returns to air when it now goes in front; every other path
    stays where it was.

    Parameters
    ----------
    part : (k,) int
        Part (material id) of each face hit.
    refracts : (k,) bool
        That part refracts.
    n : (k, 3) float
        Unit face normals.
    d_in, d_out : (k, 3) float
        Directions of travel before and after the event.
    medium : (k,) int
        Part whose medium each path was in (-1: air).

    Returns
    -------
    medium : (k,) int
        Part whose medium each path is in now.
    through : (k,) bool
        The path went through a refracting face.
    """
    side_in = np.einsum("ij,ij->i", d_in, n)
    side_out = np.einsum("ij,ij->i", d_out, n)
    through = refracts & (side_in * side_out > 0)
    return np.where(through, np.where(side_out < 0, part, -1), medium), through
