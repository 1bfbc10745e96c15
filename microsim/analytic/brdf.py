"""Analytic BRDFs: ``eval(wi, wo)`` returns f_r in 1/sr (never times cos θo).

``wi`` points towards the light and ``wo`` towards the viewer, both away from the surface,
as ``(..., 3)`` unit vectors in the local frame (macro normal +z). Every model returns 0
where either direction is at or below the horizon. Models with an RGB parameter (albedo,
conductor Fresnel) return ``(..., 3)``; the others ``(...)``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from microsim.analytic.fresnel import Fresnel
from microsim.analytic.shadowing import smith_g2, vgroove_G

SHADOWING = ("smith-correlated", "smith-separable", "v-groove", "none")


def _above(wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    return (wi[..., 2] > 0) & (wo[..., 2] > 0)


def _arrays(wi: np.ndarray, wo: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    wi, wo = np.broadcast_arrays(np.asarray(wi, float), np.asarray(wo, float))
    return wi, wo


def as_rgb(values: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """Broadcast a model's output to ``shape + (C,)``: a scalar (grey) model's to three
    equal channels, a per-channel one's (RGB, or one per wavelength) as it is."""
    values = np.asarray(values, float)
    if values.shape == shape:
        values = values[..., None]
    channels = values.shape[-1] if values.ndim > len(shape) and values.shape[-1] > 1 else 3
    return np.broadcast_to(values, shape + (channels,))


def rgb(value: object, name: str, rows: int = 0) -> np.ndarray:
    """A parameter of an RGB-only model as (3,) channels (or (rows, 3) with ``rows``): one
    number for all channels, or three values (per row, or one set for every row).

    Raises
    ------
    ValueError
        If ``value`` has another number of values, naming ``name``.
    """
    shape = (rows, 3) if rows else (3,)
    values = np.asarray(value, float)
    try:
        return np.broadcast_to(values, shape)
    except ValueError:
        raise ValueError(f"{name} takes one number or 3 values (RGB) per "
                         f"{'row' if rows else 'model'}: this model has no other channels; "
                         f"got shape {values.shape}") from None


def flat_pairs(wi: np.ndarray, wo: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, tuple[int, ...]]:
    """Direction pairs broadcast together and flattened: ((n, 3), (n, 3), the broadcast
    shape without the last axis, to reshape results to)."""
    wi, wo = _arrays(wi, wo)
    return wi.reshape(-1, 3), wo.reshape(-1, 3), wi.shape[:-1]


def mirror(w: np.ndarray) -> np.ndarray:
    """Mirror direction about the macro normal: R(ω) = (−ω_x, −ω_y, ω_z)."""
    return np.asarray(w, float) * np.array([-1.0, -1.0, 1.0])


class TorranceSparrow:
    """Microfacet specular reflection f = D(h) G(ωi, ωo) F(ωi·h) / (4 cos θi cos θo).

    Torrance & Sparrow 1967, JOSA 57(9), eq. 32 with the 1/4 of Walter et al. 2007, eq. 20
    (the lecture's form, whose Jacobian 1/(4 ωo·h) and projected-area terms combine into
    1/(4 cos θi cos θo)).

    Parameters
    ----------
    ndf : NDF
        ``microsim.analytic.ndf`` distribution (``D``, ``Lambda``, ``G1``).
    fresnel : Fresnel or None
        The facets' Fresnel factor (``microsim.analytic.fresnel``): ``ConductorFresnel``,
        ``DielectricFresnel``, ``SchlickFresnel`` (what model fits use) or ``CoatedFresnel``
        (a thin dielectric film on the facets, per wavelength); None: F = 1 (a mirror
        facet).
    shadowing : str
        ``"smith-correlated"`` (default, Heitz 2014 eq. 99), ``"smith-separable"``,
        ``"v-groove"`` (Torrance-Sparrow's), or ``"none"`` (G = 1).
    """

    def __init__(self, ndf: object, fresnel: Fresnel | None = None,
                 shadowing: str = "smith-correlated") -> None:
        if shadowing not in SHADOWING:
            raise ValueError(f"shadowing must be one of {SHADOWING}")
        if fresnel is not None and not isinstance(fresnel, Fresnel):
            raise ValueError("fresnel must be None (F = 1) or a record of "
                             "microsim.analytic.fresnel (ConductorFresnel, DielectricFresnel, "
                             f"SchlickFresnel, CoatedFresnel), not {type(fresnel).__name__}")
        self.ndf, self.fresnel, self.shadowing = ndf, fresnel, shadowing

    def F(self, cos_d: np.ndarray) -> np.ndarray:  # noqa: N802
        """Fresnel factor at ⟨ωi, h⟩: ``(...)`` or ``(..., C)``."""
        if self.fresnel is None:
            return np.ones_like(cos_d)
        return self.fresnel.factor(cos_d)

    def G(self, wi: np.ndarray, wo: np.ndarray, h: np.ndarray) -> np.ndarray:  # noqa: N802
        """Masking-shadowing of the chosen model."""
        if self.shadowing == "smith-correlated":
            return smith_g2(self.ndf, wi, wo, correlated=True)
        if self.shadowing == "smith-separable":
            return smith_g2(self.ndf, wi, wo, correlated=False)
        if self.shadowing == "v-groove":
            return vgroove_G(wi, wo, h)
        return np.where(_above(wi, wo), 1.0, 0.0)

    def eval(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """f_r(ωi, ωo), 1/sr."""
        wi, wo = _arrays(wi, wo)
        s = wi + wo
        norm = np.linalg.norm(s, axis=-1, keepdims=True)
        h = s / np.where(norm > 0, norm, 1.0)
        above = _above(wi, wo) & (norm[..., 0] > 0)
        ci, co = np.where(above, wi[..., 2], 1.0), np.where(above, wo[..., 2], 1.0)
        base = self.ndf.D(h) * self.G(wi, wo, h) / (4.0 * ci * co)
        f = self.F(np.clip(np.sum(wi * h, axis=-1), 0.0, 1.0))
        base = np.where(above, base, 0.0)
        return base[..., None] * f if f.ndim > base.ndim else base * f


class Phong:
    """Phong's lobe about the mirror direction, f = cos^n α with cos α = ωi · R(ωo).

    Phong 1975 (the lecture's (ωi · R(N, ωo))^n). ``normalized=True`` gives the
    energy-conserving form (n + 2)/(2π) cos^n α (Lewis 1994, "Making shaders more
    physically plausible", eq. 7), whose lobe integrates to 1 with cos θo at normal
    incidence and to less elsewhere.

    Parameters
    ----------
    n : float
        Exponent, ≥ 0.
    normalized : bool
    """

    def __init__(self, n: float, normalized: bool = False) -> None:
        self.n, self.normalized = float(n), bool(normalized)

    def eval(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """f_r, 1/sr."""
        wi, wo = _arrays(wi, wo)
        c = np.clip(np.sum(wi * mirror(wo), axis=-1), 0.0, 1.0)
        scale = (self.n + 2.0) / (2.0 * math.pi) if self.normalized else 1.0
        return np.where(_above(wi, wo), scale * c**self.n, 0.0)


class BlinnPhong:
    """Blinn's half-vector lobe, f = (n + 2)/(8π) cos^n θh (Blinn 1977 with the
    normalisation of Akenine-Möller et al., Real-Time Rendering 3rd ed., eq. 7.49 in its
    (n + 2)/(8π) form, which keeps the albedo below 1 at every incidence: tested).

    Parameters
    ----------
    n : float
        Exponent, ≥ 0.
    """

    def __init__(self, n: float) -> None:
        self.n = float(n)

    def eval(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """f_r, 1/sr."""
        wi, wo = _arrays(wi, wo)
        s = wi + wo
        norm = np.linalg.norm(s, axis=-1)
        cos_h = np.where(norm > 0, s[..., 2] / np.where(norm > 0, norm, 1.0), 0.0)
        f = (self.n + 2.0) / (8.0 * math.pi) * np.clip(cos_h, 0.0, 1.0) ** self.n
        return np.where(_above(wi, wo), f, 0.0)


class Lambertian:
    """f = ρ/π (Lambert 1760).

    Parameters
    ----------
    albedo : float or (3,) float
    """

    def __init__(self, albedo: float | Sequence[float]) -> None:
        self.albedo = np.asarray(albedo, float)

    def eval(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """f_r, 1/sr: ``(...)`` for a scalar albedo, ``(..., 3)`` for RGB."""
        wi, wo = _arrays(wi, wo)
        above = _above(wi, wo).astype(float)
        if self.albedo.ndim:
            return above[..., None] * self.albedo / math.pi
        return above * float(self.albedo) / math.pi


class OrenNayar:
    """Oren & Nayar 1994, "Generalization of Lambert's reflectance model", SIGGRAPH.

    Lambertian V-cavities with a Gaussian slope distribution of standard deviation σ
    (radians). ``model="full"``: the functional approximation of eq. 30 (direct term with
    C1, C2, C3) plus the interreflection term of eq. 39; ``model="qualitative"``: the
    simplified A + B model of eq. 47. With α = max(θi, θo), β = min(θi, θo) and
    cos Δφ the cosine of the azimuth difference,

    - C1 = 1 − 0.5 σ²/(σ² + 0.33);
    - C2 = 0.45 σ²/(σ² + 0.09) sin α if cos Δφ ≥ 0, else
      0.45 σ²/(σ² + 0.09) (sin α − (2β/π)³);
    - C3 = 0.125 σ²/(σ² + 0.09) (4αβ/π²)²;
    - f1 = ρ/π [C1 + cos Δφ C2 tan β + (1 − |cos Δφ|) C3 tan((α + β)/2)];
    - f2 = 0.17 ρ²/π σ²/(σ² + 0.13) [1 − cos Δφ (2β/π)²];
    - qualitative: ρ/π [A + B max(0, cos Δφ) sin α tan β], A = C1, B = 0.45 σ²/(σ²+0.09).

    Parameters
    ----------
    sigma : float
        Slope standard deviation, radians.
    albedo : float or (3,) float
        Facet albedo ρ.
    model : str
        ``"full"`` or ``"qualitative"``.
    """

    def __init__(self, sigma: float, albedo: float | Sequence[float] = 1.0,
                 model: str = "full") -> None:
        if model not in ("full", "qualitative"):
            raise ValueError("model must be 'full' or 'qualitative'")
        self.sigma, self.albedo, self.model = float(sigma), np.asarray(albedo, float), model

    def eval(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """f_r, 1/sr."""
        wi, wo = _arrays(wi, wo)
        above = _above(wi, wo)
        ti = np.arccos(np.clip(wi[..., 2], 0.0, 1.0))
        to = np.arccos(np.clip(wo[..., 2], 0.0, 1.0))
        si, so = np.sin(ti), np.sin(to)
        den = si * so
        cos_dphi = np.where(den > 1e-12, (wi[..., 0] * wo[..., 0] + wi[..., 1] * wo[..., 1])
                            / np.where(den > 1e-12, den, 1.0), 0.0)
        cos_dphi = np.clip(cos_dphi, -1.0, 1.0)
        a, b = np.maximum(ti, to), np.minimum(ti, to)
        tan_b = np.tan(np.minimum(b, math.pi / 2 - 1e-12))
        s2 = self.sigma**2
        c1 = 1.0 - 0.5 * s2 / (s2 + 0.33)
        bcoef = 0.45 * s2 / (s2 + 0.09)
        if self.model == "qualitative":
            shape = (c1 + bcoef * np.maximum(cos_dphi, 0.0) * np.sin(a) * tan_b) / math.pi
            f = self._scale(shape, 1)
        else:
            c2 = np.where(cos_dphi >= 0, bcoef * np.sin(a),
                          bcoef * (np.sin(a) - (2 * b / math.pi) ** 3))
            c3 = 0.125 * s2 / (s2 + 0.09) * (4 * a * b / math.pi**2) ** 2
            tan_ab = np.tan(np.minimum((a + b) / 2, math.pi / 2 - 1e-12))
            direct = (c1 + cos_dphi * c2 * tan_b + (1 - np.abs(cos_dphi)) * c3 * tan_ab)
            inter = 0.17 * s2 / (s2 + 0.13) * (1 - cos_dphi * (2 * b / math.pi) ** 2)
            f = self._scale(direct / math.pi, 1) + self._scale(inter / math.pi, 2)
        mask = above[..., None] if f.ndim > above.ndim else above
        return np.where(mask, f, 0.0)

    def _scale(self, shape: np.ndarray, power: int) -> np.ndarray:
        rho = self.albedo**power
        return shape[..., None] * rho if rho.ndim else shape * float(rho)


class Lafortune:
    """Lafortune et al. 1997, "Non-linear approximation of reflectance functions",
    SIGGRAPH, eq. 5-6: f = Σ_k (Cx ωi_x ωo_x + Cy ωi_y ωo_y + Cz ωi_z ωo_z)^{n_k} (a
    component-wise product; the lecture's cross products are a typo), each term clamped at
    0. With directions pointing away from the surface, Cx = Cy = −1, Cz = 1 is a lobe
    about the mirror direction (Phong's); Cx = Cy > 0 is retro-reflective.

    Parameters
    ----------
    lobes : sequence of (Cx, Cy, Cz, n)
        Lobe coefficients (their magnitude carries the lobe's albedo).
    """

    def __init__(self, lobes: Sequence[Sequence[float]]) -> None:
        self.lobes = np.asarray(lobes, float).reshape(-1, 4)

    def eval(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """f_r, 1/sr."""
        wi, wo = _arrays(wi, wo)
        f = np.zeros(wi.shape[:-1])
        for cx, cy, cz, n in self.lobes:
            d = cx * wi[..., 0] * wo[..., 0] + cy * wi[..., 1] * wo[..., 1] + \
                cz * wi[..., 2] * wo[..., 2]
            f = f + np.maximum(d, 0.0) ** n
        return np.where(_above(wi, wo), f, 0.0)


class KayKajiya:
    """Kay & Kajiya 1989, "Rendering fur with three dimensional textures", SIGGRAPH,
    sec. 2.3: the reflection of a thin fibre with unit tangent t.

    Diffuse kd sin(t, ωi) (Lambertian cylinder integrated over its circumference);
    specular ks (cos θi cos θo + sin θi sin θo)^n = ks cos^n(θi − θo), a PRODUCT form
    (the lecture's "+ sin θi + sin θo" is a typo), where θi is the angle between t and the
    direction the light travels (−ωi) and θo the angle between t and ωo, so the peak lies
    on the cone of mirror directions about the fibre. The specular term is reciprocal;
    the diffuse term, a shading heuristic, is not (it depends on ωi alone).

    What the two terms claim: the radiance of the fibre, per unit irradiance normal to
    the light, seen from ωo. The diffuse term is the Lambertian cylinder's reflected
    power spread evenly over the directions around the fibre (it ignores which part of
    the lit half the viewer sees): with kd = ρ/π² it is exact in energy, and it is the
    exact Lambertian cylinder's radiance averaged over the azimuth around the fibre
    (tested). The specular term is a lobe of arbitrary width about the cone, constant
    around it.

    As a BRDF (``coverage`` given): a layer of parallel fibres of diameter D at spacing s,
    coverage c = D/s, nothing shadowing: a fibre intercepts D sin(t, ωi) per unit length
    and unit irradiance normal to the beam and is seen over a width D sin(t, ωo), so
    f_r = c L(ωi, ωo) sin(t, ωo) / (cos θ_i cos θ_o), L = kd sin(t, ωi) + ks cos^n.
    Without ``coverage``, ``eval`` returns L itself (the shading model).

    Parameters
    ----------
    tangent : (3,) float
        Fibre direction (normalised here).
    kd, ks : float
        Diffuse and specular coefficients, 1/sr.
    n : float
        Specular exponent.
    coverage : float or None
        Projected fibre area per unit area of the layer (D/s), or None (shading form).
    """

    def __init__(self, tangent: Sequence[float], kd: float, ks: float, n: float,
                 coverage: float | None = None) -> None:
        t = np.asarray(tangent, float)
        self.tangent = t / np.linalg.norm(t)
        self.kd, self.ks, self.n = float(kd), float(ks), float(n)
        self.coverage = None if coverage is None else float(coverage)

    def specular(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """ks cos^n(θi − θo), clamped at 0."""
        wi, wo = _arrays(wi, wo)
        ci, co = -(wi @ self.tangent), wo @ self.tangent
        si = np.sqrt(np.maximum(1.0 - ci * ci, 0.0))
        so = np.sqrt(np.maximum(1.0 - co * co, 0.0))
        return self.ks * np.maximum(ci * co + si * so, 0.0) ** self.n

    def eval(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """f_r, 1/sr (the layer BRDF with ``coverage``, else the fibre's L)."""
        wi, wo = _arrays(wi, wo)
        ci = wi @ self.tangent
        diffuse = self.kd * np.sqrt(np.maximum(1.0 - ci * ci, 0.0))
        f = diffuse + self.specular(wi, wo)
        above = _above(wi, wo)
        if self.coverage is not None:
            co = wo @ self.tangent
            seen = np.sqrt(np.maximum(1.0 - co * co, 0.0))
            den = np.where(above, wi[..., 2] * wo[..., 2], 1.0)
            f = self.coverage * f * seen / den
        return np.where(above, f, 0.0)
