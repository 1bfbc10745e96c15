"""The distribution of visible normals and its sampling, above and below the horizon.

Seen from a direction ω, the microfacet normals m are distributed as

    D_ω(m) = ⟨ω, m⟩⁺ D(m) / A(ω),    A(ω) = ∫ ⟨ω, m⟩⁺ D(m) dm

(Heitz & d'Eon 2014, "Importance sampling microfacet-based BSDFs using the distribution of
visible normals", EGSR, eq. 2). A(ω) is the projected area of the microsurface towards ω:
(1 + Λ(ω)) cos θ above the horizon (Heitz 2014, JCGT 3(2), sec. 5), and Λ(ω) |cos θ|
below it, since ∫ ⟨ω, m⟩ D dm = cos θ for every ω and Λ is even in cos θ. A random walk on
a Smith microsurface (Heitz, Hanika, d'Eon & Dachsbacher 2016, "Multiple-scattering
microfacet BSDFs with the Smith model", ACM TOG 35(4)) meets the surface from below its
mean plane too (a ray travelling upwards hits a facet above it), so both halves are needed.

Sampling stretches the configuration to α = 1 (the distributions here are
shape-invariant: Heitz 2014, sec. 5.4), samples the visible normals there and stretches
back: for GGX by the projected-hemisphere construction of Heitz 2018 ("Sampling the GGX
distribution of visible normals", JCGT 7(4), listing 1), which holds for any cos θ > −1;
for Beckmann by inverting the CDF of the visible slope along the view azimuth (Heitz &
d'Eon 2014, appendix; the safeguarded Newton iteration of Jakob 2014, "An improved
visible normal sampling routine for the Beckmann distribution") and drawing the
perpendicular slope from its Gaussian.

Directions are ``(n, 3)`` unit vectors in the local frame (macro normal +z).
"""

from __future__ import annotations

import math

import numpy as np
from scipy import special

from microsim.analytic.ndf import GGX, Beckmann

_SQRT_PI = math.sqrt(math.pi)
NEWTON_STEPS = 60
"""Most iterations of the Beckmann slope inversion (it stops when every slope moved by
less than 1e-12 (1 + |x|); 6 to 16 for 20 000 draws at one view)."""
SLOPE_RANGE = 10.0
"""The inversion brackets the α = 1 slope within this distance of its extremes: the
Beckmann slope density e^{−x²} beyond it is below 1e-43."""


def projected_area(ndf: object, w: np.ndarray) -> np.ndarray:
    """A(ω) = ∫ ⟨ω, m⟩⁺ D(m) dm of a Smith microsurface, for ω above or below the horizon.

    Parameters
    ----------
    ndf : NDF
        With ``Lambda`` (``microsim.analytic.ndf``).
    w : (n, 3) float
        Unit directions.

    Returns
    -------
    (n,) float
        (1 + Λ(ω)) cos θ for cos θ ≥ 0, Λ(ω) |cos θ| below; 0 exactly at the horizon
        (where Λ is returned finite), which callers treat as "no visible facet".
    """
    z = w[:, 2]
    lam = ndf.Lambda(w)
    return np.where(z >= 0, (1.0 + lam) * z, lam * -z)


def visible_pdf(ndf: object, w: np.ndarray, m: np.ndarray) -> np.ndarray:
    """D_ω(m) = ⟨ω, m⟩⁺ D(m) / A(ω), 1/sr (0 where A(ω) = 0).

    Parameters
    ----------
    ndf : NDF
    w, m : (n, 3) float
        Directions and microfacet normals.

    Returns
    -------
    (n,) float
    """
    area = projected_area(ndf, w)
    dot = np.maximum(np.sum(w * m, axis=-1), 0.0)
    return np.where(area > 0, dot * ndf.D(m) / np.where(area > 0, area, 1.0), 0.0)


def sample_visible(ndf: object, w: np.ndarray, u1: np.ndarray, u2: np.ndarray
                   ) -> np.ndarray:
    """Microfacet normals distributed as D_ω(m), for ω anywhere but straight down.

    Parameters
    ----------
    ndf : Beckmann or GGX
    w : (n, 3) float
        Unit directions (towards where the facets are seen from).
    u1, u2 : (n,) float
        Uniform numbers in [0, 1).

    Returns
    -------
    (n, 3) float
        Unit normals with m_z ≥ 0 and ⟨ω, m⟩ ≥ 0.

    Raises
    ------
    TypeError
        For a distribution without a sampler here.
    """
    if not isinstance(ndf, GGX | Beckmann):
        raise TypeError(f"no visible-normal sampler for {type(ndf).__name__}")
    ax, ay = ndf.alpha_x, ndf.alpha_y
    stretched = w * np.array([ax, ay, 1.0])
    stretched /= np.linalg.norm(stretched, axis=-1, keepdims=True)
    n = (_ggx_unit if isinstance(ndf, GGX) else _beckmann_unit)(stretched, u1, u2)
    m = n * np.array([ax, ay, 1.0])
    return m / np.linalg.norm(m, axis=-1, keepdims=True)


def _ggx_unit(v: np.ndarray, u1: np.ndarray, u2: np.ndarray) -> np.ndarray:
    """Visible normals of the α = 1 GGX distribution (a hemisphere's normals) seen from
    unit ``v``: a uniform point of the hemisphere's projection along v, lifted onto it
    (Heitz 2018, listing 1). The projection is a half-disc and half an ellipse of minor
    axis |v_z|: added to the disc for v_z > 0, cut out of it for v_z < 0; the blend
    t2 ← (1 − s) √(1 − t1²) + s t2 with s = (1 + v_z)/2 covers exactly that region,
    uniformly, for every v_z > −1."""
    lensq = v[:, 0] ** 2 + v[:, 1] ** 2
    has_azimuth = lensq > 0
    inv = 1.0 / np.sqrt(np.where(has_azimuth, lensq, 1.0))
    t1_axis = np.where(has_azimuth[:, None],
                       np.stack([-v[:, 1] * inv, v[:, 0] * inv, np.zeros_like(inv)], -1),
                       np.array([1.0, 0.0, 0.0]))
    t2_axis = np.cross(v, t1_axis)
    r, phi = np.sqrt(u1), 2.0 * math.pi * u2
    t1, t2 = r * np.cos(phi), r * np.sin(phi)
    s = 0.5 * (1.0 + v[:, 2])
    t2 = (1.0 - s) * np.sqrt(np.maximum(1.0 - t1 * t1, 0.0)) + s * t2
    lift = np.sqrt(np.maximum(1.0 - t1 * t1 - t2 * t2, 0.0))
    n = t1[:, None] * t1_axis + t2[:, None] * t2_axis + lift[:, None] * v
    n[:, 2] = np.maximum(n[:, 2], 0.0)
    return n


def _beckmann_cdf(x: np.ndarray, cos_t: np.ndarray, sin_t: np.ndarray) -> np.ndarray:
    """Unnormalised CDF of the visible α = 1 Beckmann slope x along the view azimuth,
    ∫_{−∞}^x (cos θ − t sin θ) e^{−t²}/√π dt = cos θ erfc(−x)/2 + sin θ e^{−x²}/(2√π)
    (erfc keeps the first term accurate for x < 0)."""
    return 0.5 * cos_t * special.erfc(-x) + sin_t * np.exp(-x * x) / (2.0 * _SQRT_PI)


def _beckmann_unit(v: np.ndarray, u1: np.ndarray, u2: np.ndarray) -> np.ndarray:
    """Visible normals of the α = 1 Beckmann distribution seen from unit ``v``.

    With slopes (x, y) of the normal (−x, −y, 1)/√(1 + x² + y²) in a frame whose x axis is
    v's azimuth, the facet faces v where x < cot θ, and the visible slopes have density
    ∝ (cos θ − x sin θ) e^{−x² − y²}/π there: x is drawn by inverting its marginal CDF
    (``_beckmann_cdf``; safeguarded Newton: a bisection step whenever Newton leaves the
    bracket), y independently from e^{−y²}/√π.
    """
    cos_t = v[:, 2]
    sin_t = np.sqrt(v[:, 0] ** 2 + v[:, 1] ** 2)
    cot = np.where(sin_t > 0, cos_t / np.where(sin_t > 0, sin_t, 1.0), np.inf)
    hi = np.minimum(cot, SLOPE_RANGE)
    lo = np.minimum(hi, 0.0) - SLOPE_RANGE
    target = u1 * _beckmann_cdf(hi, cos_t, sin_t)
    x = np.clip(special.erfinv(2.0 * u1 - 1.0), lo, hi)
    for _ in range(NEWTON_STEPS):
        f = _beckmann_cdf(x, cos_t, sin_t) - target
        lo = np.where(f < 0, x, lo)
        hi = np.where(f > 0, x, hi)
        slope = (cos_t - x * sin_t) * np.exp(-x * x) / _SQRT_PI
        with np.errstate(divide="ignore", invalid="ignore"):
            step = x - f / slope
        step = np.where((step >= lo) & (step <= hi), step, 0.5 * (lo + hi))
        done = np.abs(step - x) <= 1e-12 * (1.0 + np.abs(x))
        x = step
        if done.all():
            break
    y = special.erfinv(np.clip(2.0 * u2 - 1.0, -1.0 + 2.0**-53, 1.0 - 2.0**-53))
    phi = np.arctan2(v[:, 1], v[:, 0])
    c, s = np.cos(phi), np.sin(phi)
    sx, sy = c * x - s * y, s * x + c * y
    n = np.stack([-sx, -sy, np.ones_like(sx)], -1)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)
