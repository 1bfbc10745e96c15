"""Microfacet normal distributions D(m) and their Smith masking Λ, G1.

Every NDF is normalised so that ∫ D(m) cos θm dωm = 1 over the hemisphere (Walter et al.
2007, "Microfacet models for refraction through rough surfaces", EGSR, eq. 4). Smith's
masking of a direction ω is G1(ω) = χ⁺(ω·n) / (1 + Λ(ω)) (Smith 1967; Heitz 2014,
"Understanding the masking-shadowing function in microfacet-based BRDFs", JCGT 3(2),
eq. 43), which satisfies the consistency condition ∫ G1 ⟨ω, m⟩ D dm = cos θ.

Arguments are arrays of unit vectors ``(..., 3)`` in the local frame (macro normal +z).
Λ is even in ω_z (it depends on |cot θ|); G1 is 0 for directions at or below the horizon.
Λ at exactly θ = 90° is infinite in theory; it is returned as a large finite number
(≈ 1e299), so G1 = 0 there without overflow.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import integrate, special

_TINY = 1e-300
_SQRT_PI = math.sqrt(math.pi)


def _cot_and_inverse(w: np.ndarray, alpha_x: float, alpha_y: float) -> np.ndarray:
    """a = |ω_z| / √(αx² ω_x² + αy² ω_y²) = 1 / (α(φ) tan θ) (Heitz 2014, eq. 80), the
    argument of Λ for an anisotropic NDF stretched by (αx, αy); +inf at the pole."""
    w = np.asarray(w, float)
    proj = np.sqrt((alpha_x * w[..., 0]) ** 2 + (alpha_y * w[..., 1]) ** 2)
    z = np.maximum(np.abs(w[..., 2]), _TINY)
    return np.where(proj > 0, z / np.maximum(proj, _TINY), np.inf)


def lambda_beckmann(a: np.ndarray) -> np.ndarray:
    """Smith Λ of the Beckmann distribution as a function of a = 1/(α tan θ).

    Λ(a) = (erf(a) − 1)/2 + exp(−a²)/(2a√π) (Walter et al. 2007, eq. 27; Heitz 2014,
    eq. 83), evaluated without cancellation: with erfc(a) = exp(−a²) erfcx(a),
    Λ = exp(−a²)/2 · (1/(a√π) − erfcx(a)). For a > 8 the bracket is summed from its
    asymptotic series 1/(a√π) Σ_{n≥1} (−1)^{n+1} (2n−1)!! / (2a²)^n (Abramowitz & Stegun
    7.1.23), truncated after n = 12: it errs by about the next term, 4.2e-13 of the sum
    at a = 8 and less beyond (the direct form loses ~1e-14 to cancellation near a = 8).

    Parameters
    ----------
    a : (...) float
        ≥ 0; +inf gives 0.

    Returns
    -------
    (...) float
        Λ ≥ 0, finite (a = 0 is treated as a = 1e-300).
    """
    a = np.maximum(np.asarray(a, float), _TINY)
    finite = np.isfinite(a)
    a = np.where(finite, np.minimum(a, 1e100), 1.0)  # Λ < 1e-300 long before 1e100
    small = a <= 8.0
    direct = 1.0 / (a * _SQRT_PI) - special.erfcx(np.where(small, a, 8.0))
    big = np.maximum(a, 8.0)
    x = 1.0 / (2.0 * big * big)
    term, series = np.ones_like(a), np.zeros_like(a)
    for n in range(1, 13):
        term = term * (2 * n - 1) * x
        series += term if n % 2 else -term
    bracket = np.where(small, direct, series / (big * _SQRT_PI))
    lam = 0.5 * np.exp(-a * a) * bracket
    return np.where(finite, np.maximum(lam, 0.0), 0.0)


def lambda_ggx(a: np.ndarray) -> np.ndarray:
    """Smith Λ of the GGX (Trowbridge-Reitz) distribution, a = 1/(α tan θ).

    Λ = (−1 + √(1 + 1/a²))/2 (Walter et al. 2007, eq. 34; Heitz 2014, eq. 86), evaluated as
    s²/(2(√(1 + s²) + 1)) with s = 1/a to avoid cancellation for large a, and as s/2 where
    s² would overflow.
    """
    a = np.maximum(np.asarray(a, float), _TINY)
    s = 1.0 / a
    big = s > 1e150
    sb = np.where(big, 1.0, s)
    return np.where(big, 0.5 * s, sb * sb / (2.0 * (np.sqrt(1.0 + sb * sb) + 1.0)))


class _NDF:
    """Shared masking: G1 from Λ."""

    def Lambda(self, w: np.ndarray) -> np.ndarray:  # noqa: N802 - the literature's name
        raise NotImplementedError

    def G1(self, w: np.ndarray) -> np.ndarray:  # noqa: N802
        """Smith masking G1(ω) = χ⁺(ω_z) / (1 + Λ(ω)) (Heitz 2014, eq. 43).

        Parameters
        ----------
        w : (..., 3) float

        Returns
        -------
        (...) float
            In [0, 1]; 0 at or below the horizon.
        """
        w = np.asarray(w, float)
        return np.where(w[..., 2] > 0, 1.0 / (1.0 + self.Lambda(w)), 0.0)


class Beckmann(_NDF):
    """Beckmann distribution, isotropic or anisotropic.

    D(m) = exp(−tan²θm (cos²φm/αx² + sin²φm/αy²)) / (π αx αy cos⁴θm) (Beckmann &
    Spizzichino 1963; Walter et al. 2007, eq. 25; Heitz 2014, eq. 80).

    Parameters
    ----------
    alpha : float, optional
        Isotropic roughness (Walter's α = √2 × RMS slope per axis).
    alpha_x, alpha_y : float, optional
        Anisotropic roughness along x and y (give both instead of ``alpha``).
    """

    def __init__(self, alpha: float | None = None, *, alpha_x: float | None = None,
                 alpha_y: float | None = None) -> None:
        self.alpha_x, self.alpha_y = _alphas(alpha, alpha_x, alpha_y)
        self.alpha = math.sqrt(self.alpha_x * self.alpha_y)

    def D(self, m: np.ndarray) -> np.ndarray:  # noqa: N802
        """D(m), 1/sr; 0 for m at or below the horizon.

        Parameters
        ----------
        m : (..., 3) float
            Unit microfacet normals.

        Returns
        -------
        (...) float
        """
        m = np.asarray(m, float)
        z = m[..., 2]
        zs = np.where(z > 0, z, 1.0)
        e = ((m[..., 0] / self.alpha_x) ** 2 + (m[..., 1] / self.alpha_y) ** 2) / zs**2
        d = np.exp(-e) / (math.pi * self.alpha_x * self.alpha_y * zs**4)
        return np.where(z > 0, d, 0.0)

    def Lambda(self, w: np.ndarray) -> np.ndarray:  # noqa: N802
        """Smith Λ(ω) (see ``lambda_beckmann``).

        Parameters
        ----------
        w : (..., 3) float

        Returns
        -------
        (...) float
        """
        return lambda_beckmann(_cot_and_inverse(w, self.alpha_x, self.alpha_y))


class GGX(_NDF):
    """GGX / Trowbridge-Reitz distribution, isotropic or anisotropic.

    D(m) = 1 / (π αx αy (m_x²/αx² + m_y²/αy² + m_z²)²) (Trowbridge & Reitz 1975; Walter et
    al. 2007, eq. 33; Heitz 2014, eq. 85); isotropic: α² / (π ((α² − 1) cos²θm + 1)²).

    Parameters
    ----------
    alpha : float, optional
    alpha_x, alpha_y : float, optional
    """

    def __init__(self, alpha: float | None = None, *, alpha_x: float | None = None,
                 alpha_y: float | None = None) -> None:
        self.alpha_x, self.alpha_y = _alphas(alpha, alpha_x, alpha_y)
        self.alpha = math.sqrt(self.alpha_x * self.alpha_y)

    def D(self, m: np.ndarray) -> np.ndarray:  # noqa: N802
        """D(m), 1/sr; 0 at or below the horizon."""
        m = np.asarray(m, float)
        q = (m[..., 0] / self.alpha_x) ** 2 + (m[..., 1] / self.alpha_y) ** 2 + m[..., 2] ** 2
        d = 1.0 / (math.pi * self.alpha_x * self.alpha_y * np.maximum(q, _TINY) ** 2)
        return np.where(m[..., 2] > 0, d, 0.0)

    def Lambda(self, w: np.ndarray) -> np.ndarray:  # noqa: N802
        """Smith Λ(ω) (see ``lambda_ggx``)."""
        return lambda_ggx(_cot_and_inverse(w, self.alpha_x, self.alpha_y))


class _TabulatedIsotropic(_NDF):
    """An isotropic NDF given by a profile D(θm), normalised numerically, with Smith Λ by
    quadrature of the slope distribution (Heitz 2014, eq. 72):

    Λ(μ) = (1/μ) ∫_μ^∞ (q − μ) P2(q) dq,  μ = cot θ,  P2(q) = ∫ P22(p, q) dp,

    where P22(p, q) = D(θm) cos⁴θm with tan θm = √(p² + q²) is the slope density. Λ is
    tabulated once over u = θ/(π/2) and interpolated (cubic in u, tabulated at 129 nodes).
    """

    _nodes = 129

    def _profile(self, theta: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def _normalise(self) -> None:
        val, _ = integrate.quad(lambda t: float(self._profile(np.array(t)))
                                * math.cos(t) * math.sin(t), 0.0, math.pi / 2,
                                limit=200, points=self._points())
        self._scale = 1.0 / (2.0 * math.pi * val)
        self._table = None

    def _points(self) -> list[float]:
        return []

    def D(self, m: np.ndarray) -> np.ndarray:  # noqa: N802
        """D(m), 1/sr; 0 at or below the horizon."""
        m = np.asarray(m, float)
        z = np.clip(m[..., 2], -1.0, 1.0)
        theta = np.arccos(np.clip(z, 0.0, 1.0))
        return np.where(z > 0, self._scale * self._profile(theta), 0.0)

    def _lambda_at(self, theta: float) -> float:
        if theta <= 0.0:
            return 0.0
        mu = math.cos(theta) / math.sin(theta)
        val, _ = integrate.quad(lambda q: self._slope_marginal(q) * (q - mu), mu, np.inf,
                                limit=100)
        return val / mu

    def _slope_marginal(self, q: float) -> float:
        """P2(q) = ∫ P22(p, q) dp over every p, by quadrature."""
        def p22(p: float) -> float:
            t = math.atan(math.hypot(p, q))
            return self._scale * float(self._profile(np.array(t))) * math.cos(t) ** 4

        val, _ = integrate.quad(p22, 0.0, np.inf, limit=100)
        return 2.0 * val

    def Lambda(self, w: np.ndarray) -> np.ndarray:  # noqa: N802
        """Smith Λ(ω) by the tabulated slope integral."""
        from scipy.interpolate import CubicSpline

        if self._table is None:
            u = np.linspace(0.0, 1.0, self._nodes)[:-1]
            lam = np.array([self._lambda_at(x * math.pi / 2) for x in u])
            self._table = CubicSpline(u, np.log1p(lam))
        w = np.asarray(w, float)
        theta = np.arccos(np.clip(np.abs(w[..., 2]), 0.0, 1.0))
        u = theta / (math.pi / 2)
        last = 1.0 - 1.0 / self._nodes
        lam = np.expm1(self._table(np.minimum(u, last)))
        # beyond the last node Λ grows like cot θ → ∞: continue it as Λ ∝ 1/cot θ
        cot_last = math.tan(math.pi / 2 * (1 - last))
        scale = cot_last / np.maximum(np.cos(theta) / np.maximum(np.sin(theta), _TINY),
                                      1e-299)
        return np.where(u > last, np.expm1(self._table(last)) * scale, np.maximum(lam, 0.0))


class Blinn(_TabulatedIsotropic):
    """Normalised Blinn distribution D(m) = (n + 2)/(2π) cos^n θm (Blinn 1977; Walter et
    al. 2007, eq. 30). Λ by quadrature (no closed form)."""

    def __init__(self, n: float) -> None:
        if not n >= 0:
            raise ValueError("Blinn exponent n must be >= 0")
        self.n = float(n)
        self._scale = (self.n + 2.0) / (2.0 * math.pi)
        self._table = None

    def _profile(self, theta: np.ndarray) -> np.ndarray:
        return np.cos(theta) ** self.n

    def _slope_marginal(self, q: float) -> float:
        """P2(q) in closed form: with cos θm = (1 + p² + q²)^(−1/2) the slope density is
        P22 = s (1 + p² + q²)^(−(n+4)/2), and ∫ (a² + p²)^(−k) dp = √π Γ(k − ½)/Γ(k)
        a^(1−2k) (Gradshteyn & Ryzhik 3.251.2 with a² = 1 + q²). The quadrature of the
        general profile took minutes for n ≲ 2, whose slopes have heavy tails."""
        k = (self.n + 4.0) / 2.0
        ratio = math.exp(special.gammaln(k - 0.5) - special.gammaln(k))
        return self._scale * math.sqrt(math.pi) * ratio * (1.0 + q * q) ** (0.5 - k)


class TorranceSparrowGaussian(_TabulatedIsotropic):
    """The Gaussian in the half-angle of Torrance & Sparrow 1967, D ∝ exp(−(c θm)²) (the
    lecture's D(α) = e^{−(c₂α)²}), normalised numerically. Λ by quadrature."""

    def __init__(self, c: float) -> None:
        if not c > 0:
            raise ValueError("c must be > 0")
        self.c = float(c)
        self._normalise()

    def _profile(self, theta: np.ndarray) -> np.ndarray:
        return np.exp(-((self.c * theta) ** 2))

    def _points(self) -> list[float]:
        return [min(1.0 / self.c, math.pi / 2 * 0.999)]


def _alphas(alpha: float | None, alpha_x: float | None,
            alpha_y: float | None) -> tuple[float, float]:
    """(αx, αy) from an isotropic α or both anisotropic values; all must be > 0."""
    if alpha is not None and alpha_x is None and alpha_y is None:
        ax = ay = float(alpha)
    elif alpha is None and alpha_x is not None and alpha_y is not None:
        ax, ay = float(alpha_x), float(alpha_y)
    else:
        raise ValueError("give alpha, or both alpha_x and alpha_y")
    if not (ax > 0 and ay > 0 and math.isfinite(ax) and math.isfinite(ay)):
        raise ValueError("roughness must be finite and > 0")
    return ax, ay


def ndf_bin_average(ndf: _NDF, edges: np.ndarray, n: int = 16) -> np.ndarray:
    """Bin averages ∫_B D cos θ dω / ∫_B cos θ dω of an isotropic NDF over θ bins (what a
    histogram of area-weighted facet normals estimates), by Gauss-Legendre in θ.

    Parameters
    ----------
    ndf : NDF
        With ``D(m)``.
    edges : (k + 1,) float
        Bin edges in θ, radians.
    n : int
        Gauss-Legendre nodes per bin.

    Returns
    -------
    (k,) float
    """
    x, w = np.polynomial.legendre.leggauss(n)
    lo, hi = edges[:-1, None], edges[1:, None]
    t = lo + (hi - lo) * (x + 1) / 2
    weights = w * (hi - lo) / 2 * np.cos(t) * np.sin(t)
    m = np.stack([np.sin(t), np.zeros_like(t), np.cos(t)], axis=-1)
    return (ndf.D(m) * weights).sum(axis=1) / weights.sum(axis=1)

