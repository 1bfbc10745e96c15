"""Optics of one ray at a facet, in kernel language: the scalar functions the material
kinds' scattering events are made of (reflection, Fresnel reflectance, refraction,
cosine-weighted directions).

Every function works on one ray, with vectors as scalar triples, and is marked ``kernel``:
the transport kernel compiles it with numba, inlined into its callers
(``microsim.kernel.events``); called from Python it runs as plain Python (the tests check
both against ``microsim.analytic``).
"""

from __future__ import annotations

import math

from microsim.materials.base import kernel

TWO_PI = 2.0 * math.pi


@kernel
def reflect(dx: float, dy: float, dz: float, nx: float, ny: float, nz: float
            ) -> tuple[float, float, float]:
    """Mirror a direction of travel about a plane: d − 2 (d·n) n."""
    s = 2.0 * (dx * nx + dy * ny + dz * nz)
    return dx - s * nx, dy - s * ny, dz - s * nz


@kernel
def fresnel_dielectric(cos_i: float, eta: float) -> float:
    """Exact unpolarised Fresnel reflectance of a dielectric interface, relative index η.

    F = ½ (r_s² + r_p²), r_s = (c_i − η c_t)/(c_i + η c_t), r_p = (η c_i − c_t)/(η c_i + c_t),
    sin θt = sin θi / η; F = 1 under total internal reflection (Born & Wolf, Principles of
    Optics, 7th ed., sec. 1.5.2, eq. 21a-b; ``microsim.analytic.fresnel``)."""
    c = min(max(cos_i, 0.0), 1.0)
    sin2_t = (1.0 - c * c) / (eta * eta)
    if sin2_t >= 1.0:
        return 1.0
    cos_t = math.sqrt(1.0 - sin2_t)
    den_s = c + eta * cos_t
    den_p = eta * c + cos_t
    r_s = (c - eta * cos_t) / den_s if den_s > 0.0 else 1.0
    r_p = (eta * c - cos_t) / den_p if den_p > 0.0 else 1.0
    return 0.5 * (r_s * r_s + r_p * r_p)


@kernel
def fresnel_conductor(cos_i: float, eta: float, k: float) -> float:
    """Exact unpolarised Fresnel reflectance of a conductor of complex index η + ik, in
    real arithmetic: with a² + b² = √((η² − k² − sin²θ)² + 4η²k²) and
    a = √((a² + b² + η² − k² − sin²θ) / 2),
    R_s = (a² + b² + cos²θ − 2a cos θ) / (a² + b² + cos²θ + 2a cos θ),
    R_p = R_s (cos²θ (a² + b²) + sin⁴θ − 2a cos θ sin²θ)
            / (cos²θ (a² + b²) + sin⁴θ + 2a cos θ sin²θ), F = (R_s + R_p) / 2
    (pbrt-v3, sec. 8.2.1, ``FrConductor``; the same function as Born & Wolf's complex form,
    sec. 14.2, which ``microsim.analytic.fresnel`` evaluates and the tests compare)."""
    c = min(max(cos_i, 0.0), 1.0)
    c2 = c * c
    s2 = 1.0 - c2
    e2, k2 = eta * eta, k * k
    t0 = e2 - k2 - s2
    a2b2 = math.sqrt(t0 * t0 + 4.0 * e2 * k2)
    a = math.sqrt(max(0.5 * (a2b2 + t0), 0.0))
    t1 = a2b2 + c2
    t2 = 2.0 * c * a
    # t1 + t2 = 0 only at grazing incidence on a non-interface (eta = 1, k = 0): F = 1 there
    # as at every other grazing incidence
    r_s = (t1 - t2) / (t1 + t2) if t1 + t2 > 0.0 else 1.0
    t3 = c2 * a2b2 + s2 * s2
    t4 = t2 * s2
    r_p = r_s * (t3 - t4) / (t3 + t4)
    return min(max(0.5 * (r_s + r_p), 0.0), 1.0)


@kernel
def refract(dx: float, dy: float, dz: float, nx: float, ny: float, nz: float, eta: float
            ) -> tuple[float, float, float, bool]:
    """Snell's law in vector form for d·n < 0, relative index η = n_t / n_i:
    t = d / η + (c / η − cos θt) n with c = −d·n, cos θt = √(1 − (1 − c²) / η²) (Walter et
    al. 2007, "Microfacet models for refraction through rough surfaces", eq. 40 with their
    η = n_i / n_t; PBR 4th ed., sec. 9.3). Returns the unit direction and whether total
    internal reflection forbids it."""
    c = min(max(-(dx * nx + dy * ny + dz * nz), 0.0), 1.0)
    sin2_t = (1.0 - c * c) / (eta * eta)
    if sin2_t >= 1.0:
        return dx, dy, dz, True
    cos_t = math.sqrt(1.0 - sin2_t)
    s = c / eta - cos_t
    tx, ty, tz = dx / eta + s * nx, dy / eta + s * ny, dz / eta + s * nz
    norm = math.sqrt(tx * tx + ty * ty + tz * tz)  # unit exactly; this is round-off only
    return tx / norm, ty / norm, tz / norm, False


@kernel
def orthonormal_basis(nx: float, ny: float, nz: float
                      ) -> tuple[float, float, float, float, float, float]:
    """Unit t, s with t × s = n (Duff et al. 2017, "Building an orthonormal basis,
    revisited", JCGT 6(1), listing 3; ``microsim.geometry``)."""
    sign = math.copysign(1.0, nz)
    a = -1.0 / (sign + nz)
    b = nx * ny * a
    return (1.0 + sign * nx * nx * a, sign * b, -sign * nx,
            b, sign + ny * ny * a, -ny)


@kernel
def cosine_about(nx: float, ny: float, nz: float, u1: float, u2: float
                 ) -> tuple[float, float, float]:
    """A direction with pdf cos θ / π about n: Malley's method, a uniform point of the unit
    disc lifted to the hemisphere (PBR 4th ed., sec. A.5.3)."""
    tx, ty, tz, sx, sy, sz = orthonormal_basis(nx, ny, nz)
    r = math.sqrt(u1)
    phi = TWO_PI * u2
    a, b = r * math.cos(phi), r * math.sin(phi)
    z = math.sqrt(max(1.0 - u1, 0.0))
    return a * tx + b * sx + z * nx, a * ty + b * sy + z * ny, a * tz + b * sz + z * nz
