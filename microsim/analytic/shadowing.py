"""Masking-shadowing: Smith's G2 (height-correlated and separable), V-groove models.

Directions are unit vectors ``(..., 3)`` pointing away from the surface; the macro normal
is +z.
"""

from __future__ import annotations

import numpy as np


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.sum(np.asarray(a, float) * np.asarray(b, float), axis=-1)


def smith_g2(ndf: object, wi: np.ndarray, wo: np.ndarray,
             correlated: bool = True) -> np.ndarray:
    """Smith's masking-shadowing of a direction pair.

    Height-correlated: G2 = χ⁺ / (1 + Λ(ωi) + Λ(ωo)) (Heitz 2014, "Understanding the
    masking-shadowing function", JCGT 3(2), eq. 99); separable: G1(ωi) G1(ωo) (eq. 98).

    Parameters
    ----------
    ndf : NDF
        Anything with ``Lambda(w)`` and ``G1(w)`` (``microsim.analytic.ndf``).
    wi, wo : (..., 3) float
    correlated : bool

    Returns
    -------
    (...) float
        In [0, 1]; 0 if either direction is at or below the horizon.
    """
    wi, wo = np.asarray(wi, float), np.asarray(wo, float)
    above = (wi[..., 2] > 0) & (wo[..., 2] > 0)
    if correlated:
        g = 1.0 / (1.0 + ndf.Lambda(wi) + ndf.Lambda(wo))
    else:
        g = ndf.G1(wi) * ndf.G1(wo)
    return np.where(above, g, 0.0)


def vgroove_G(wi: np.ndarray, wo: np.ndarray, wh: np.ndarray) -> np.ndarray:  # noqa: N802
    """Torrance-Sparrow V-groove attenuation for symmetric grooves with facet normal ωh.

    G = min(1, 2 (n·h)(n·ωo)/(ωo·h), 2 (n·h)(n·ωi)/(ωi·h)) (Torrance & Sparrow 1967,
    JOSA 57(9), eq. 21-23; Blinn 1977, eq. 4). The lecture's two cases are the second and
    third arguments; 1 is the unoccluded case.

    Parameters
    ----------
    wi, wo, wh : (..., 3) float

    Returns
    -------
    (...) float
        In [0, 1]; 0 where a direction is below the horizon or faces away from ωh.
    """
    wh = np.asarray(wh, float)
    nh = wh[..., 2]
    g = np.ones(np.broadcast_shapes(np.shape(wi)[:-1], np.shape(wo)[:-1], nh.shape))
    valid = np.ones_like(g, bool)
    for w in (np.asarray(wi, float), np.asarray(wo, float)):
        wm = _dot(w, wh)
        valid &= (wm > 0) & (w[..., 2] > 0) & (nh > 0)
        g = np.minimum(g, 2.0 * nh * w[..., 2] / np.where(wm > 0, wm, 1.0))
    return np.where(valid, np.clip(g, 0.0, 1.0), 0.0)


def vcavity_G1(w: np.ndarray, wm: np.ndarray) -> np.ndarray:  # noqa: N802
    """Masking of one facet of a symmetric V-cavity with normal ωm seen from ω.

    G1(ω, ωm) = χ⁺(ω·ωm) min(1, 2 (n·ωm)(n·ω)/(ω·ωm)) (Heitz 2014, sec. 4.1, eq. 56;
    the V-cavity model of Torrance & Sparrow 1967 as a masking function).

    Parameters
    ----------
    w, wm : (..., 3) float

    Returns
    -------
    (...) float
        In [0, 1].
    """
    w, wm = np.asarray(w, float), np.asarray(wm, float)
    d = _dot(w, wm)
    ok = (d > 0) & (w[..., 2] > 0) & (wm[..., 2] > 0)
    g = 2.0 * wm[..., 2] * w[..., 2] / np.where(ok, d, 1.0)
    return np.where(ok, np.minimum(1.0, g), 0.0)
