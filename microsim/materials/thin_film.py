"""Thin-film interference at a facet, in kernel language: a dielectric coating of real
index η_f and thickness d on a substrate of complex index η_s + i k_s (a conductor, or a
dielectric with k_s = 0), lit from a medium of index 1, at one vacuum wavelength λ — the
coating of Gondek, Meyer & Newman's pearlescent flakes (1994, "Wavelength dependent
reflectance functions", SIGGRAPH, sec. 4).

Indices are relative to the incident medium; thickness and wavelength share a unit (nm).
The angles enter through the normal components of the wave vectors over k₀ = 2π/λ,
q_j = n_j cos θ_j = √(n_j² − sin²θ_i) (Snell's law n_j sin θ_j = sin θ_i), taken with
Im q_j ≥ 0 (the principal root, Re q_j ≥ 0 too): the wave decays away from the interface
in an absorbing medium and beyond a critical angle (evanescent), with the time factor
e^{−iωt} of Born & Wolf. Each polarisation has its interface admittance a_j, q_j for s
(TE) and q_j / n_j² = cos θ_j / n_j for p (TM), and the single-interface coefficients
r_jk = (a_j − a_k) / (a_j + a_k), t_jk = 2 a_j / (a_j + a_k) — Born & Wolf, Principles of
Optics, 7th ed., sec. 1.5.2, eqs. 20-21 in terms of q (their r_∥ sign; for p, t_jk is the
ratio of the tangential magnetic amplitudes, so that T = Re(a_2) / a_0 |t|² holds for both
polarisations).

Every function works on one ray and is marked ``kernel``: the transport kernel can compile
it with numba (``numba.extending.register_jitable``, as ``microsim.kernel.events`` does for
every kernel function); called from Python it runs as plain Python. The vectorised
counterpart for the analytic models is ``microsim.analytic.fresnel.fresnel_thin_film``.
"""

from __future__ import annotations

import cmath
import math

from microsim.materials.base import kernel

TWO_PI = 2.0 * math.pi


@kernel
def normal_wavenumber(eta: float, k: float, sin2_i: float) -> complex:
    """q = n cos θ = √(n² − sin²θ_i) of a medium of index n = η + i k (k ≥ 0) for light
    incident from index 1 at sin²θ_i, on the branch with Im q ≥ 0 (decaying or evanescent
    waves; Born & Wolf, sec. 1.5.4 for total reflection, sec. 14.2 for conductors)."""
    q = cmath.sqrt(complex(eta * eta - k * k - sin2_i, 2.0 * eta * k))
    if q.imag < 0.0:  # a real radicand below 0 whose imaginary part is a signed zero
        q = -q
    return q


@kernel
def film_amplitudes(a0: complex, a1: complex, a2: complex, half_phase: complex,
                    g: float) -> tuple[complex, complex]:
    """Amplitude reflection and transmission coefficients of one film for one
    polarisation, by the Airy summation of its multiple reflections (Born & Wolf, sec.
    1.6.4, eqs. 57-58):

    r = (r01 + r12 e^{2iβ}) / (1 + r01 r12 e^{2iβ}),
    t = t01 t12 e^{iβ} / (1 + r01 r12 e^{2iβ}),

    with admittances a0 (incident medium), a1 (film), a2 (substrate) and
    ``half_phase`` = e^{iβ}, β = k₀ d q_1. Where the film is at its own critical angle
    (a1 = 0: η_f < 1 and sin θ_i = η_f) r and t are 0/0, and are their limit a1 → 0 from
    the film's characteristic matrix (Born & Wolf, sec. 1.6.2; cos β → 1, sin β / a1 → g,
    a1 sin β → 0, with g = k₀ d for s and k₀ d η_f² for p):
    r = (a0 − a2 − i g a0 a2) / (a0 + a2 − i g a0 a2), t = 2 a0 / (a0 + a2 − i g a0 a2).
    ``a0`` must not be 0 (grazing incidence: the caller's case); a1 + a2 = 0 otherwise
    only at the pole of a lossless surface wave, which no film of η_f ≥ 1 reaches."""
    if a1 == 0.0:
        den0 = a0 + a2 - 1j * g * a0 * a2
        return (a0 - a2 - 1j * g * a0 * a2) / den0, 2.0 * a0 / den0
    phase = half_phase * half_phase
    s01 = a0 + a1
    r01 = (a0 - a1) / s01
    s12 = a1 + a2
    r12 = (a1 - a2) / s12
    den = 1.0 + r01 * r12 * phase
    return (r01 + r12 * phase) / den, (2.0 * a0 / s01) * (2.0 * a1 / s12) * half_phase / den


@kernel
def film_reflectance_polarised(cos_i: float, eta_film: float, thickness_nm: float,
                               wavelength_nm: float, eta_sub: float, k_sub: float
                               ) -> tuple[float, float, float, float]:
    """Power reflectances and transmittances (R_s, R_p, T_s, T_p) of a film of real index
    ``eta_film`` and thickness ``thickness_nm`` on a substrate ``eta_sub`` + i ``k_sub``,
    lit from index 1 at incidence cosine ``cos_i`` (clamped to [0, 1]) and vacuum
    wavelength ``wavelength_nm``.

    R = |r|², T = Re(a_2) / a_0 |t|² (the transmissivity: Born & Wolf, sec. 1.5.3, and
    sec. 1.6.4 for the film) with r, t of ``film_amplitudes``: T is the power that enters
    a dielectric substrate (``k_sub`` == 0), 0 beyond its critical angle; for an
    absorbing substrate (``k_sub`` > 0) the power not reflected is absorbed and T is
    reported as 0. For lossless media R + T = 1. With ``thickness_nm`` = 0 these are the
    bare substrate's Fresnel reflectances; at grazing incidence (``cos_i`` ≤ 0) R = 1,
    T = 0. Each value is clipped to [0, 1] (round-off only)."""
    c = min(max(cos_i, 0.0), 1.0)
    if c <= 0.0:
        return 1.0, 1.0, 0.0, 0.0
    sin2_i = 1.0 - c * c
    q0 = complex(c, 0.0)
    q1 = normal_wavenumber(eta_film, 0.0, sin2_i)
    q2 = normal_wavenumber(eta_sub, k_sub, sin2_i)
    k0d = TWO_PI * thickness_nm / wavelength_nm
    half_phase = cmath.exp(1j * k0d * q1)  # e^{iβ}, β = 2π d η_f cos θ_f / λ
    n1_sq = eta_film * eta_film
    n2_sq = complex(eta_sub * eta_sub - k_sub * k_sub, 2.0 * eta_sub * k_sub)
    p2 = q2 / n2_sq
    r_s, t_s = film_amplitudes(q0, q1, q2, half_phase, k0d)
    r_p, t_p = film_amplitudes(q0, q1 / n1_sq, p2, half_phase, k0d * n1_sq)
    big_r_s = min(max(abs(r_s) ** 2, 0.0), 1.0)
    big_r_p = min(max(abs(r_p) ** 2, 0.0), 1.0)
    if k_sub != 0.0:
        return big_r_s, big_r_p, 0.0, 0.0
    big_t_s = min(max(q2.real / c * abs(t_s) ** 2, 0.0), 1.0)
    big_t_p = min(max(p2.real / c * abs(t_p) ** 2, 0.0), 1.0)
    return big_r_s, big_r_p, big_t_s, big_t_p


@kernel
def film_reflectance(cos_i: float, eta_film: float, thickness_nm: float,
                     wavelength_nm: float, eta_sub: float, k_sub: float
                     ) -> tuple[float, float]:
    """Unpolarised (R, T) of a coated facet: the means of the s and p values of
    ``film_reflectance_polarised`` (same arguments and conventions: T is the power entering
    a dielectric substrate, 0 for ``k_sub`` > 0; R + T = 1 for lossless media)."""
    r_s, r_p, t_s, t_p = film_reflectance_polarised(cos_i, eta_film, thickness_nm,
                                                    wavelength_nm, eta_sub, k_sub)
    return 0.5 * (r_s + r_p), 0.5 * (t_s + t_p)

