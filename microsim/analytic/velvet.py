"""Sparse velvet: single scattering of Lambertian fibres standing on a black base, no
fibre shadowing another (the low-density limit of Westin, Arvo & Torrance 1992's velvet).

Each fibre is the ``velvet`` generator's, its side made smooth as the tracer shades it: a
cylinder of radius r whose axis t rises from a root on the base (z = 0) to length L,
capped by a pyramid of ``sides`` flat faces of height r. With the base black and no fibre
in another's way, the surface's single scattering is the sum of every fibre's own, and the
base hides nothing a fibre shows (a ray from a point above the base towards the sky or the
light never meets it again). So

    f_r(ω_i, ω_o) = N_A E_t[ ρ / (π cos θ_i cos θ_o) ∫_fibre (ω_i·n)⁺ (ω_o·n)⁺ dA ],

N_A fibres per unit area, the expectation over the fibre axes the generator draws (tilt
from +z ~ N(tilt, spread) clipped to [0, 80]°, so with atoms at 0 and 80°; azimuth uniform,
or N(azimuth, spread)), and the integral over the fibre's lit and seen surface: each
element's irradiance (ω_i·n) times its Lambertian radiance ρ/π times its projected area
(ω_o·n), over the unit areas of the macro-surface's projections (cos θ_i cos θ_o).

**Side.** With (u, v, t) orthonormal, a side point at angle ψ has n = u cos ψ + v sin ψ,
and ω·n = A cos(ψ − α) with A = |ω − (ω·t) t| = sin(t, ω) and α its angle in (u, v). The
side above the base along the generator at ψ has length ℓ(ψ) = L + (r / t_z)(u_z cos ψ +
v_z sin ψ) (the base cuts the tube through the root, obliquely when tilted), and
dA = ℓ(ψ) r dψ; the integral is in closed form (``_fibre``). Without the ℓ term it is
A_i A_o r L ½ [(π − Φ) cos Φ + sin Φ], Φ the angle between the projections: the
Lambertian cylinder's phase function. **Tip.** Its flat faces, each area × the two
cosines, with the generator's corners (``section_axes``).

The expectation is a quadrature: Gauss-Legendre in tilt over (0°, 80°) weighted by the
normal density plus the two atoms; azimuth by the periodic trapezoid rule (uniform) or
Gauss-Hermite (normal); 12 tilt and 32 azimuth nodes keep the quadrature within 0.15% of
a 64 × 256 one (measured at tilt 30 ± 10°). Or, with ``axes``, the fibres of one tile.
The kernel is compiled with numba: a table's comparison takes the model at ~10⁵ direction
pairs times ~400 fibre axes. What the simulated tile adds: its sides are prisms (shaded
as cylinders, ``microsim.kernel.shading``, but with the prism's silhouette, k sin(π/k)/π of the
circle's width on average: 0.955 at 6 sides, 0.997 at 24), and at any density fibres
shadow and light each other: the departure this model measures (docs/surfaces.md).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from scipy.special import ndtr

from microsim.analytic.brdf import flat_pairs, rgb
from microsim.geometry import FIBRE_MAX_TILT, section_axes
from microsim.jit import JIT


@njit(**JIT)
def _fibre(w_i: np.ndarray, w_o: np.ndarray, k: int, u: np.ndarray, v: np.ndarray,
           t: np.ndarray, tip_n: np.ndarray, tip_len: np.ndarray, m: int, r: float,
           length: float) -> float:
    """∫ (ω_i·n)⁺ (ω_o·n)⁺ dA over one fibre (side and tip; the module docstring), for
    the unit directions w_i[k], w_o[k] and the fibre frame m, (u, v, t)[m] (the
    generator's ``section_axes``, which also places the tip's corners).

    **Side.** With (x, y) = (ω·u, ω·v) = A (cos α, sin α) and Φ ∈ [0, π] the angle
    between the two projections: ∫ A_i cos(ψ − α_i) A_o cos(ψ − α_o) ℓ(ψ) r dψ over the
    arc where both are positive, of half-length H = (π − Φ)/2 about the bisector μ of
    α_i and α_o. With x = ψ − μ the product is ½ [cos Φ + cos 2x] and
    ℓ = L + B cos(x + μ − β), B cos(μ − β) = (r / t_z)(ẑ·b̂), b̂ the unit bisector; odd
    terms vanish, leaving A_i A_o r {L ½ [(π − Φ) cos Φ + sin Φ] + B cos(μ − β)
    ½ [2 cos Φ cos(Φ/2) + cos(Φ/2) − cos(3Φ/2)/3]}. **Tip**: its flat faces
    (``tip_faces``: outward normals n_k of length 2 area_k / r², and those lengths),
    Σ area_k (ω_i·n̂_k)⁺ (ω_o·n̂_k)⁺.
    """
    xi = w_i[k, 0] * u[m, 0] + w_i[k, 1] * u[m, 1] + w_i[k, 2] * u[m, 2]
    yi = w_i[k, 0] * v[m, 0] + w_i[k, 1] * v[m, 1] + w_i[k, 2] * v[m, 2]
    xo = w_o[k, 0] * u[m, 0] + w_o[k, 1] * u[m, 1] + w_o[k, 2] * u[m, 2]
    yo = w_o[k, 0] * v[m, 0] + w_o[k, 1] * v[m, 1] + w_o[k, 2] * v[m, 2]
    ai, ao = math.sqrt(xi * xi + yi * yi), math.sqrt(xo * xo + yo * yo)
    side = 0.0
    if ai > 0.0 and ao > 0.0:
        cosd = min(1.0, max(-1.0, (xi * xo + yi * yo) / (ai * ao)))
        phi = math.acos(cosd)
        half = math.sqrt(0.5 * (1.0 + cosd))  # cos(Φ/2)
        side = length * 0.5 * ((math.pi - phi) * cosd + math.sqrt(1.0 - cosd * cosd))
        bx, by = xi / ai + xo / ao, yi / ai + yo / ao
        nb = math.sqrt(bx * bx + by * by)
        if nb > 0.0:
            lean = r / t[m, 2] * (bx * u[m, 2] + by * v[m, 2]) / nb
            side += lean * 0.5 * (2 * cosd * half + half - (4 * half**3 - 3 * half) / 3)
        side *= ai * ao
    tip = 0.0
    for j in range(tip_n.shape[1]):
        n = tip_n[m, j]
        di = n[0] * w_i[k, 0] + n[1] * w_i[k, 1] + n[2] * w_i[k, 2]
        do = n[0] * w_o[k, 0] + n[1] * w_o[k, 1] + n[2] * w_o[k, 2]
        if di > 0 and do > 0:
            # a face's area is r² |n| / 2; times its unit normal's two cosines
            tip += 0.5 * di * do / tip_len[m, j]
    return r * side + r * r * tip


@njit(**JIT)
def _fibre_average(wi: np.ndarray, wo: np.ndarray, u: np.ndarray, v: np.ndarray,
                   t: np.ndarray, tip_n: np.ndarray, tip_len: np.ndarray,
                   weights: np.ndarray, r: float, length: float) -> np.ndarray:
    """Σ_m weights[m] ``_fibre``(wi[k], wo[k], frame m) for every row k."""
    out = np.zeros(len(wi))
    for k in range(len(wi)):
        if wi[k, 2] <= 0 or wo[k, 2] <= 0:
            continue
        acc = 0.0
        for m in range(len(weights)):
            acc += weights[m] * _fibre(wi, wo, k, u, v, t, tip_n, tip_len, m, r, length)
        out[k] = acc
    return out


def tilt_nodes(tilt: float, spread: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Nodes (radians) and weights of the clipped normal tilt distribution: Gauss-Legendre
    over (0°, 80°) times the density, plus the atoms at 0° and 80°."""
    if spread <= 0:
        return np.radians([min(max(tilt, 0.0), FIBRE_MAX_TILT)]), np.ones(1)
    x, w = np.polynomial.legendre.leggauss(n)
    t = 0.5 * FIBRE_MAX_TILT * (x + 1)
    dens = np.exp(-0.5 * ((t - tilt) / spread) ** 2) / (spread * math.sqrt(2 * math.pi))
    nodes = np.concatenate([[0.0], t, [FIBRE_MAX_TILT]])
    weights = np.concatenate([[ndtr(-tilt / spread)], w * 0.5 * FIBRE_MAX_TILT * dens,
                              [1.0 - ndtr((FIBRE_MAX_TILT - tilt) / spread)]])
    return np.radians(nodes), weights


def azimuth_nodes(azimuth: float, spread: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Nodes (radians) and weights of the azimuth: uniform (spread ≥ 360°: the periodic
    trapezoid rule), a point (spread 0) or normal (Gauss-Hermite)."""
    if spread >= 360.0:
        return 2 * math.pi * (np.arange(n) + 0.5) / n, np.full(n, 1.0 / n)
    if spread <= 0:
        return np.radians([azimuth]), np.ones(1)
    x, w = np.polynomial.hermite_e.hermegauss(n)
    return np.radians(azimuth + spread * x), w / w.sum()


class SparseVelvet:
    """The sparse-fibre model of the module docstring.

    Parameters
    ----------
    fibre_radius, fibre_length, density : float
        As the ``velvet`` generator's (density: fibres per unit area).
    tilt, tilt_spread, azimuth, azimuth_spread : float
        Degrees, as the generator's.
    albedo : float or (3,) float
        Of the fibres' Lambertian facets.
    tilt_count, azimuth_count : int
        Quadrature nodes (tilt: Gauss-Legendre; uniform azimuth: trapezoid).
    axes : (n, 3) float or None
        Instead of the distribution, these unit axes with equal weights (the fibres of one
        tile: the model of that realisation; the angles are then unused).
    sides : int
        Faces of the tip (the generator's ``sides``).
    """

    def __init__(self, fibre_radius: float, fibre_length: float, density: float,
                 tilt: float, tilt_spread: float, azimuth: float, azimuth_spread: float,
                 albedo: float | np.ndarray, tilt_count: int = 12,
                 azimuth_count: int = 32, axes: np.ndarray | None = None,
                 sides: int = 6) -> None:
        self.r, self.length, self.density = float(fibre_radius), float(fibre_length), float(
            density)
        self.sides = int(sides)
        self.albedo = rgb(albedo, "albedo")
        if axes is not None:
            self.axes = np.ascontiguousarray(axes, float)
            self.weights = np.full(len(self.axes), 1.0 / len(self.axes))
        else:
            theta, wt = tilt_nodes(tilt, tilt_spread, tilt_count)
            phi, wp = azimuth_nodes(azimuth, azimuth_spread, azimuth_count)
            th, ph = np.meshgrid(theta, phi, indexing="ij")
            self.weights = np.outer(wt, wp).ravel()
            s = np.sin(th).ravel()
            self.axes = np.column_stack([s * np.cos(ph).ravel(), s * np.sin(ph).ravel(),
                                         np.cos(th).ravel()])
        self.u, self.v = section_axes(self.axes)
        self.tip_n, self.tip_len = tip_faces(self.u, self.v, self.axes, self.sides)

    def fibre_integral(self, t: np.ndarray, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """∫ (ω_i·n)⁺ (ω_o·n)⁺ dA over one fibre's side and tip, per (axis, ω_i, ω_o) row.

        Parameters
        ----------
        t, wi, wo : (n, 3) float
            Unit axes and directions (above the horizon).

        Returns
        -------
        (n,) float
        """
        u, v = section_axes(t)
        n, lengths = tip_faces(u, v, t, self.sides)
        wi, wo = np.ascontiguousarray(wi, float), np.ascontiguousarray(wo, float)
        return np.array([_fibre(wi, wo, k, u, v, t, n, lengths, k, self.r, self.length)
                         for k in range(len(t))])

    def eval(self, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """f_r, 1/sr: (..., 3)."""
        wi, wo, shape = flat_pairs(wi, wo)
        wi, wo = np.ascontiguousarray(wi), np.ascontiguousarray(wo)
        total = _fibre_average(wi, wo, self.u, self.v, self.axes, self.tip_n, self.tip_len,
                               self.weights, self.r, self.length)
        above = (wi[:, 2] > 0) & (wo[:, 2] > 0)
        den = np.where(above, wi[:, 2] * wo[:, 2], 1.0)
        f = np.where(above, self.density * total / (math.pi * den), 0.0)
        return (f[:, None] * self.albedo).reshape(*shape, 3)


def tip_faces(u: np.ndarray, v: np.ndarray, t: np.ndarray, sides: int
              ) -> tuple[np.ndarray, np.ndarray]:
    """The tip's faces in units of r: from ring corners p_k = u cos a_k + v sin a_k,
    a_k = 2πk/sides, to the apex t; outward normals (p_(k+1) − p_k) × (t − p_k) (length
    twice the face's area over r²) and their lengths.

    Returns
    -------
    normals : (m, sides, 3) float
    lengths : (m, sides) float
    """
    a = 2 * np.pi * np.arange(sides + 1) / sides
    p = np.cos(a)[None, :, None] * u[:, None] + np.sin(a)[None, :, None] * v[:, None]
    n = np.cross(p[:, 1:] - p[:, :-1], t[:, None] - p[:, :-1])
    n *= np.where(np.einsum("mkj,mkj->mk", n, p[:, 1:] + p[:, :-1]) < 0, -1.0, 1.0)[..., None]
    return np.ascontiguousarray(n), np.linalg.norm(n, axis=2)
