"""Thin-film interference (``microsim.materials.thin_film``, the kernel's scalar functions,
and ``microsim.analytic.fresnel.fresnel_thin_film``, the vectorised one) against an
independent characteristic-matrix computation of a layered stack written here, against
the bare interfaces' Fresnel reflectances, and against closed forms (quarter-wave
anti-reflection coating, absent half-wave layer, energy conservation); and the coating's
record as a recipe gives it (``microsim.materials.coating``: parsing, JSON, columns)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from microsim.analytic import fresnel as analytic
from microsim.errors import InputError
from microsim.materials import optics, thin_film
from microsim.materials.coating import Coating
from microsim.spectra.channels import RGB, Channels
from microsim.spectra.spectrum import Spectrum

TOL = 1e-6
"""Agreement with the matrix reference: both are float64 evaluations of the same physics
(round-off ~1e-14 here), while a film changes R by 1e-3 to 1e-1 over this grid, so any
error of formula, branch or phase shows far above 1e-6."""
EXACT = 1e-12
"""Identities that hold to round-off (d = 0, half-wave layer, compiled against Python)."""

THICKNESSES = (0.0, 1.0, 50.0, 137.0, 350.0, 800.0, 2000.0)
THETAS_DEG = (0.0, 10.0, 30.0, 45.0, 60.0, 75.0, 85.0, 89.0)
FILMS = (1.3, 1.8, 2.5)
WAVELENGTHS = (450.0, 550.0, 650.0)
SUBSTRATES = {
    "gold": (0.2, 3.4),
    "silver": (0.05, 4.0),
    "glass": (1.5, 0.0),
    "below-film": (1.2, 0.0),  # η_s < η_f
    "tir": (0.7, 0.0),  # η_s < 1: evanescent in the substrate beyond asin 0.7 = 44.4°
}
DIELECTRICS = [name for name, (_, k) in SUBSTRATES.items() if k == 0.0]


def stack_reference(cos_i: float, layers: list[tuple[float, float]], n_sub: complex,
                    wavelength: float) -> tuple[float, float, float, float]:
    """(R_s, R_p, T_s, T_p) of a stack of homogeneous layers [(index, thickness), ...]
    (from the incident side, index 1) on a substrate ``n_sub``, by the product of the
    layers' characteristic matrices, M_j = [[cos δ, −i sin δ / p], [−i p sin δ, cos δ]],
    δ = 2π n d cos θ / λ, p = n cos θ (TE) or cos θ / n (TM) (Born & Wolf, Principles of
    Optics, 7th ed., sec. 1.6.2), and r = (B p_1 − C) / (B p_1 + C), t = 2 p_1 / (B p_1 + C)
    with (B, C) = M (1, p_l) (sec. 1.6.3); T = Re(p_l) / p_1 |t|² (t is the ratio of the
    tangential E for TE, of H for TM). cos θ = √(1 − sin²θ_i / n²), the root with
    Im(n cos θ) ≥ 0 (decaying waves, time factor e^{−iωt}). Independent of microsim."""
    sin2_i = 1.0 - cos_i**2

    def cos_theta(n: complex) -> complex:
        c = np.sqrt(1.0 - sin2_i / complex(n) ** 2 + 0j)
        return -c if (n * c).imag < 0 else c

    out = []
    for pol in ("TE", "TM"):
        def admittance(n: complex, c: complex, pol: str = pol) -> complex:
            return n * c if pol == "TE" else c / n

        m = np.eye(2, dtype=complex)
        for n, d in layers:
            c = cos_theta(n)
            delta = 2.0 * np.pi * n * d * c / wavelength
            p = admittance(n, c)
            m = m @ np.array([[np.cos(delta), -1j * np.sin(delta) / p],
                              [-1j * p * np.sin(delta), np.cos(delta)]])
        p1 = complex(cos_i)
        pl = admittance(n_sub, cos_theta(n_sub))
        b, c = m @ np.array([1.0, pl])
        r = (b * p1 - c) / (b * p1 + c)
        t = 2.0 * p1 / (b * p1 + c)
        out.append((abs(r) ** 2, pl.real / p1.real * abs(t) ** 2))
    (r_s, t_s), (r_p, t_p) = out
    return r_s, r_p, t_s, t_p


def grid() -> list[tuple[float, float, float, float, str]]:
    """(cos_i, η_f, d, λ, substrate) over the whole test grid."""
    return [(math.cos(math.radians(t)), f, d, lam, s) for t, f, d, lam, s in
            itertools.product(THETAS_DEG, FILMS, THICKNESSES, WAVELENGTHS, SUBSTRATES)]


def test_the_reference_is_a_stack() -> None:
    """The reference itself: with no layer it is the bare interface's Fresnel (complex
    closed form, Born & Wolf sec. 1.5.2), and a film split into two sublayers of the same
    index, or given an extra zero-thickness layer of another, reflects the same."""
    for cos_i, (eta, k) in itertools.product((1.0, 0.6, 0.1), SUBSTRATES.values()):
        n = complex(eta, k)
        ct = np.sqrt(1 - (1 - cos_i**2) / n**2)
        ct = -ct if (n * ct).imag < 0 else ct
        r_s = abs((cos_i - n * ct) / (cos_i + n * ct)) ** 2
        r_p = abs((n * cos_i - ct) / (n * cos_i + ct)) ** 2
        got = stack_reference(cos_i, [], n, 550.0)
        np.testing.assert_allclose(got[:2], (r_s, r_p), atol=EXACT)
        one = stack_reference(cos_i, [(1.8, 300.0)], n, 550.0)
        two = stack_reference(cos_i, [(1.8, 120.0), (2.3, 0.0), (1.8, 180.0)], n, 550.0)
        np.testing.assert_allclose(one, two, atol=EXACT)


@pytest.mark.parametrize("substrate", SUBSTRATES)
def test_kernel_matches_the_characteristic_matrix(substrate: str) -> None:
    """R_s, R_p (and T_s, T_p on dielectrics) of the kernel function, its unpolarised
    (R, T) and the vectorised reflectance agree with the matrix reference over thickness
    0-2000 nm, θi 0-89°, η_f 1.3-2.5 and three wavelengths; T = 0 on conductors."""
    eta, k = SUBSTRATES[substrate]
    cases = [g[:4] for g in grid() if g[4] == substrate]
    got_pol = np.array([thin_film.film_reflectance_polarised(c, f, d, lam, eta, k)
                        for c, f, d, lam in cases])
    got = np.array([thin_film.film_reflectance(c, f, d, lam, eta, k)
                    for c, f, d, lam in cases])
    want = np.array([stack_reference(c, [(f, d)], complex(eta, k), lam)
                     for c, f, d, lam in cases])
    c, f, d, lam = np.array(cases).T
    vectorised = analytic.fresnel_thin_film(c, f, d, lam, eta, k)
    np.testing.assert_allclose(got_pol[:, :2], want[:, :2], atol=TOL)
    np.testing.assert_allclose(got[:, 0], want[:, :2].mean(axis=1), atol=TOL)
    np.testing.assert_allclose(vectorised, want[:, :2].mean(axis=1), atol=TOL)
    if k == 0.0:
        np.testing.assert_allclose(got_pol[:, 2:], want[:, 2:], atol=TOL)
        np.testing.assert_allclose(got[:, 1], want[:, 2:].mean(axis=1), atol=TOL)
    else:
        assert np.all(got_pol[:, 2:] == 0.0) and np.all(got[:, 1] == 0.0)
    # the film matters on this grid: far from the bare substrate somewhere
    bare = np.array([optics.fresnel_conductor(ci, eta, k) for ci in c])
    assert np.max(np.abs(got[:, 0] - bare)) > 0.05


@pytest.mark.parametrize("substrate", DIELECTRICS)
def test_lossless_stacks_conserve_energy(substrate: str) -> None:
    """R + T = 1 per polarisation for a dielectric film on a dielectric substrate, and
    beyond the substrate's critical angle (η_s = 0.7) everything is reflected."""
    eta, _ = SUBSTRATES[substrate]
    for cos_i, f, d, lam, s in grid():
        if s != substrate:
            continue
        r_s, r_p, t_s, t_p = thin_film.film_reflectance_polarised(cos_i, f, d, lam, eta, 0.0)
        assert abs(r_s + t_s - 1.0) < EXACT and abs(r_p + t_p - 1.0) < EXACT
        if 1.0 - cos_i**2 > eta**2:
            assert t_s == t_p == 0.0 and r_s > 1.0 - EXACT and r_p > 1.0 - EXACT


@pytest.mark.parametrize("substrate", SUBSTRATES)
def test_zero_thickness_is_the_bare_interface(substrate: str) -> None:
    """d = 0: the substrate's own Fresnel reflectance (``optics.fresnel_conductor``,
    ``optics.fresnel_dielectric`` and the analytic conductor's), whatever the film."""
    eta, k = SUBSTRATES[substrate]
    for cos_i, f in itertools.product(np.linspace(0.0, 1.0, 21), FILMS):
        r, _ = thin_film.film_reflectance(cos_i, f, 0.0, 550.0, eta, k)
        assert abs(r - optics.fresnel_conductor(cos_i, eta, k)) < EXACT
        assert abs(r - float(analytic.fresnel_conductor(cos_i, eta, k))) < EXACT
        assert abs(float(analytic.fresnel_thin_film(cos_i, f, 0.0, 550.0, eta, k)) - r) < EXACT
        if k == 0.0:
            assert abs(r - optics.fresnel_dielectric(cos_i, eta)) < EXACT


@pytest.mark.parametrize("eta_s", [1.5, 2.25, 1.2])
def test_quarter_wave_coating_reflects_nothing_at_normal_incidence(eta_s: float) -> None:
    """η_f = √η_s, d = λ / (4 η_f): r01 = r12 and e^{2iβ} = −1, so R = 0 exactly at normal
    incidence and at the design wavelength only (Born & Wolf, sec. 1.6.4)."""
    eta_f = math.sqrt(eta_s)
    lam = 550.0
    d = lam / (4.0 * eta_f)
    r, t = thin_film.film_reflectance(1.0, eta_f, d, lam, eta_s, 0.0)
    assert r < 1e-14 and abs(t - 1.0) < 1e-14
    assert float(analytic.fresnel_thin_film(1.0, eta_f, d, lam, eta_s, 0.0)) < 1e-14
    bare = ((eta_s - 1.0) / (eta_s + 1.0)) ** 2
    off, _ = thin_film.film_reflectance(1.0, eta_f, d, 400.0, eta_s, 0.0)
    assert 0.1 * bare < off < bare


@pytest.mark.parametrize("substrate", SUBSTRATES)
def test_half_wave_layer_is_absent_at_normal_incidence(substrate: str) -> None:
    """d = λ / (2 η_f): e^{2iβ} = 1 and r = (r01 + r12) / (1 + r01 r12) = r02, the bare
    substrate's, for any film index."""
    eta, k = SUBSTRATES[substrate]
    for f, lam in itertools.product(FILMS, WAVELENGTHS):
        d = lam / (2.0 * f)
        r, _ = thin_film.film_reflectance(1.0, f, d, lam, eta, k)
        bare = optics.fresnel_conductor(1.0, eta, k)
        assert abs(r - bare) < EXACT
        assert abs(float(analytic.fresnel_thin_film(1.0, f, d, lam, eta, k)) - bare) < EXACT
        assert abs(thin_film.film_reflectance(1.0, f, 0.5 * d, lam, eta, k)[0] - bare) > 1e-3


def test_grazing_and_out_of_range_cosines_are_clamped() -> None:
    """cos_i ≤ 0 reflects everything (R = 1, T = 0); cos_i > 1 is normal incidence."""
    for cos_i, (eta, k) in itertools.product((0.0, -0.3), SUBSTRATES.values()):
        assert thin_film.film_reflectance_polarised(cos_i, 1.5, 137.0, 550.0, eta, k) == (
            1.0, 1.0, 0.0, 0.0)
        assert float(analytic.fresnel_thin_film(cos_i, 1.5, 137.0, 550.0, eta, k)) == 1.0
    for eta, k in SUBSTRATES.values():
        assert (thin_film.film_reflectance(1.3, 1.5, 137.0, 550.0, eta, k)
                == thin_film.film_reflectance(1.0, 1.5, 137.0, 550.0, eta, k))
        assert (float(analytic.fresnel_thin_film(1.3, 1.5, 137.0, 550.0, eta, k))
                == float(analytic.fresnel_thin_film(1.0, 1.5, 137.0, 550.0, eta, k)))


def test_film_at_its_critical_angle_is_the_limit() -> None:
    """A film of η_f < 1 exactly at its critical angle (η_f cos θ_f = 0, where the Airy
    quotient is 0/0) takes the limit: the reflectance at indices 1e-9 either side (the
    Airy form loses ~1e-16 / |η_f cos θ_f| ~ 1e-8 to cancellation there, hence 1e-6), and,
    when the substrate is the film's medium too, the bare interface's total reflection."""
    cos_i = 0.41
    eta_f = math.sqrt(1.0 - cos_i * cos_i)
    assert eta_f * eta_f == 1.0 - cos_i * cos_i  # η_f cos θ_f is exactly 0
    for eta, k in SUBSTRATES.values():
        at = thin_film.film_reflectance_polarised(cos_i, eta_f, 137.0, 550.0, eta, k)
        for side in (-1e-9, 1e-9):
            near = thin_film.film_reflectance_polarised(cos_i, eta_f + side, 137.0, 550.0,
                                                        eta, k)
            np.testing.assert_allclose(at, near, atol=TOL)
        vectorised = analytic.fresnel_thin_film(cos_i, eta_f, 137.0, 550.0, eta, k)
        assert abs(float(vectorised) - 0.5 * (at[0] + at[1])) < TOL
    r, t = thin_film.film_reflectance(cos_i, eta_f, 137.0, 550.0, eta_f, 0.0)
    assert abs(r - 1.0) < EXACT and t == 0.0
    assert abs(float(analytic.fresnel_thin_film(cos_i, eta_f, 137.0, 550.0, eta_f, 0.0))
               - 1.0) < EXACT


def test_vectorised_broadcasts_over_every_argument() -> None:
    """Shapes (4, 1, 1) x (3, 1) x (2,) of cos_i, thickness and wavelength, with the
    substrate per wavelength, give (4, 3, 2), each entry the kernel's."""
    cos_i = np.array([0.0, 0.3, 0.7, 1.0])[:, None, None]
    d = np.array([0.0, 137.0, 800.0])[:, None]
    lam = np.array([450.0, 650.0])
    eta_s, k_s = np.array([0.2, 1.5]), np.array([3.4, 0.0])
    out = analytic.fresnel_thin_film(cos_i, 1.8, d, lam, eta_s, k_s)
    assert out.shape == (4, 3, 2)
    for i, j, m in itertools.product(range(4), range(3), range(2)):
        want, _ = thin_film.film_reflectance(cos_i[i, 0, 0], 1.8, d[j, 0], lam[m],
                                             eta_s[m], k_s[m])
        assert abs(out[i, j, m] - want) < EXACT


def test_every_kernel_function_is_marked_for_the_transport_kernel() -> None:
    """The transport kernel compiles what ``materials.base.kernel`` marked
    (``KERNEL_FUNCTIONS``, registered by ``microsim.kernel.events``): the film's and the
    optics' helpers and every kind's event are in it, and marking returns the function."""
    from microsim.materials import KINDS, conductor, dielectric
    from microsim.materials.base import KERNEL_FUNCTIONS, kernel

    helpers = [thin_film.normal_wavenumber, thin_film.film_amplitudes,
               thin_film.film_reflectance_polarised, thin_film.film_reflectance,
               optics.reflect, optics.refract, optics.fresnel_dielectric,
               optics.fresnel_conductor, optics.orthonormal_basis, optics.cosine_about,
               conductor.coated, dielectric._reflectance]
    for fn in helpers + [kind.scatter for kind in KINDS]:
        assert any(marked is fn for marked in KERNEL_FUNCTIONS), fn.__qualname__
    assert kernel(thin_film.film_reflectance) is thin_film.film_reflectance
    assert KERNEL_FUNCTIONS.pop() is thin_film.film_reflectance


def test_compiled_kernel_equals_python() -> None:
    """Compiled with numba as the transport kernel compiles kernel functions (the helpers
    registered with ``register_jitable``, ``microsim.kernel.events``), the unpolarised and
    polarised functions return the Python values to 1e-12 over the grid and the edge
    cases (grazing, a film at its critical angle)."""
    numba = pytest.importorskip("numba")
    from numba.extending import register_jitable

    for fn in (thin_film.normal_wavenumber, thin_film.film_amplitudes,
               thin_film.film_reflectance_polarised):
        register_jitable(fn)
    compiled = numba.njit(thin_film.film_reflectance)
    compiled_pol = numba.njit(thin_film.film_reflectance_polarised)
    cases = [(c, f, d, lam, *SUBSTRATES[s]) for c, f, d, lam, s in grid()[::7]]
    cases += [(0.0, 1.5, 137.0, 550.0, 0.2, 3.4), (-0.2, 1.5, 137.0, 550.0, 1.5, 0.0),
              (0.41, math.sqrt(1.0 - 0.41**2), 137.0, 550.0, 1.5, 0.0)]
    for case in cases:
        np.testing.assert_allclose(compiled(*case), thin_film.film_reflectance(*case),
                                   rtol=0.0, atol=EXACT)
        np.testing.assert_allclose(compiled_pol(*case),
                                   thin_film.film_reflectance_polarised(*case),
                                   rtol=0.0, atol=EXACT)


# --- the coating as a recipe gives it (microsim.materials.coating) --------------------

FILM_WHERE = "material.coating"
FILM_FORM = "a table { thickness = <nm>, eta = <index or spectrum> }"


@pytest.mark.parametrize(("raw", "thickness", "eta"), [
    ({"thickness": 0, "eta": 2}, 0.0, 2.0),
    ({"thickness": 0.5, "eta": 0.5}, 0.5, 0.5),
    ({"thickness": 100_000.0, "eta": 1e300}, 100_000.0, 1e300),
])
def test_coating_takes_0_to_100000_nm_and_any_finite_positive_index(
        raw: dict, thickness: float, eta: float) -> None:
    """The documented ranges' ends (thickness 0, the bare facet, and 100 000 nm; any index
    > 0, also below 1) are taken, and the record holds floats, as its fields say."""
    coating = Coating.parse(raw, FILM_WHERE)
    assert coating == Coating(thickness, eta)
    assert type(coating.thickness) is float and type(coating.eta) is float
    assert coating.to_json() == {"thickness": thickness, "eta": eta}


def test_coating_index_spectrum_with_or_without_its_source_reads_back() -> None:
    """An index spectrum without ``source`` is cited by its key path; one with a source
    (as a table file's recipe holds it, with ``kind``) keeps it; ``to_json`` writes the
    spectrum's JSON, which reads back to the same coating. A film's index may be below 1
    (relative to the medium in front)."""
    nm, value = [400.0, 700.0], [0.8, 2.0]
    given = Coating.parse({"thickness": 100.0, "eta": {"nm": nm, "value": value}}, FILM_WHERE)
    assert given == Coating(100.0, Spectrum(tuple(nm), tuple(value),
                                            "the spectrum given at material.coating.eta"))
    cited = Coating.parse({"thickness": 100.0,
                           "eta": {"nm": nm, "value": value, "source": "a film of the test"}},
                          FILM_WHERE)
    assert cited == Coating(100.0, Spectrum(tuple(nm), tuple(value), "a film of the test"))
    text = cited.to_json()
    assert text == {"thickness": 100.0, "eta": {"kind": "tabulated", "nm": nm,
                                                "value": value, "source": "a film of the test"}}
    assert Coating.parse(text, FILM_WHERE) == cited


@pytest.mark.parametrize(("raw", "message"), [
    (350.0, f"material.coating = 350.0: must be {FILM_FORM}"),
    ({"thickness": 1.0, "eta": 2.0, "n": 1},
     "material.coating.n: unknown key; a coating takes thickness (nm) and eta"),
    ({"eta": 2.0}, f"material.coating.thickness: missing; a coating is {FILM_FORM}"),
    ({"thickness": 1.0}, f"material.coating.eta: missing; a coating is {FILM_FORM}"),
    *[({"thickness": t, "eta": 2.0}, f"material.coating.thickness = {t!r}: must be a "
       "number of nm >= 0 and <= 100000") for t in (-1.0, 100_000.5, math.nan, True, "100")],
    *[({"thickness": 1.0, "eta": e}, f"material.coating.eta = {e!r}: must be a number > 0 "
       "or a spectrum { nm = [...], value = [...] }") for e in (0.0, -1.0, math.inf, True, "2")],
    ({"thickness": 1.0, "eta": {"nm": [400.0, 700.0], "value": [0.0, 2.0]}},
     "material.coating.eta: a film's index must be > 0"),
    ({"thickness": 1.0, "eta": {"nm": [400.0], "value": [1.0, 2.0]}},
     "material.coating.eta: nm has 1 entries and value 2; give one value for each wavelength"),
    ({"thickness": 1.0, "eta": {"nm": [400.0], "value": [1.0, 2.0], "source": "s"}},
     "material.coating.eta: nm has 1 entries and value 2; give one value for each wavelength"),
])
def test_a_bad_coating_is_one_error_naming_its_key(raw: object, message: str) -> None:
    """Each mistake is an ``InputError`` whose whole message names the key and what it
    takes (a number out of range, a boolean, a string; an index spectrum with a value
    ≤ 0 or malformed, cited or not)."""
    with pytest.raises(InputError) as info:
        Coating.parse(raw, FILM_WHERE)
    assert str(info.value) == message


def test_coating_columns_are_its_index_and_thickness_per_wavelength() -> None:
    """The kernel's columns: the index spectrum sampled (linear between its points) at
    each wavelength and the thickness in every channel; an RGB table, or a wavelength
    outside the spectrum, is refused naming the key."""
    coating = Coating(120.0, Spectrum((400.0, 700.0), (2.0, 2.3), "a film of the test"))
    eta, thickness = coating.columns(Channels((450.0, 600.0)), FILM_WHERE)
    assert eta == pytest.approx((2.0 + 0.3 * 50 / 300, 2.0 + 0.3 * 200 / 300), abs=1e-15)
    assert thickness == (120.0, 120.0)
    with pytest.raises(InputError) as info:
        coating.columns(RGB, FILM_WHERE)
    assert str(info.value) == ("material.coating: a coating needs a spectral table ([table] "
                               "wavelengths): its interference depends on the wavelength")
    with pytest.raises(InputError) as info:
        coating.columns(Channels((450.0, 750.0)), FILM_WHERE)
    assert str(info.value).startswith("material.coating.eta: 750 nm asked for, outside "
                                      "400-700 nm")
