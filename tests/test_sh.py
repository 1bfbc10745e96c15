"""Spherical harmonics: the basis, the projection of escaping rays, errors, storage, the
BRDF matrix and the ``microsim sh`` command."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import mpmath
import numpy as np
import pytest
from scipy.special import sph_harm_y
from tablefixtures import changed, table_of

import microsim
from microsim.commands.sh import MATRIX_MAX_ORDER as CLI_MATRIX_MAX_ORDER
from microsim.commands.sh import WINDOWS as CLI_WINDOWS
from microsim.measurement.goniometer import Energies, RunKey, Sums, fold
from microsim.measurement.paths import Paths
from microsim.measurement.simulation import simulate
from microsim.recipe import resolve
from microsim.tables import sh
from microsim.tables.assemble import EnsembleSums, from_ensemble, merge
from microsim.tables.binning import HemisphereBins
from microsim.tables.components import components_for
from microsim.tables.exr import write_table
from microsim.tables.meta import TableMeta
from microsim.tables.principal import principal
from microsim.tables.sh_error import bin_integrals, order_errors
from microsim.tables.sh_matrix import MAX_ORDER, brdf_matrix, matrix_eval, write_matrix
from microsim.tables.table import BRDFTable

Z_MAX = 4.2
"""Two-sided z bound per coefficient: with 81 coefficients (and two components, whose z
are strongly correlated) the chance of a false alarm is below 2 x 81 x 2.7e-5 < 0.5%."""


def real_y(l: int, m: int, theta: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Real harmonic from scipy's complex ``sph_harm_y`` (Condon-Shortley phase)."""
    y = sph_harm_y(l, abs(m), theta, phi)
    return y.real if m == 0 else math.sqrt(2.0) * (y.real if m > 0 else y.imag)


def unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def lobe_coefficients(f, theta_i: np.ndarray, order: int, nodes: int = 96) -> np.ndarray:
    """∫ f(ωi, ωo) cos θo Y_k(ωo) dωo per incidence (φi = 0) by Gauss-Legendre in cos θo
    times the midpoint rule in φo, with scipy's harmonics: (len(theta_i), (L + 1)²)."""
    x, wx = np.polynomial.legendre.leggauss(nodes)
    x, wx = 0.5 * (x + 1.0), 0.5 * wx
    nphi = 4 * order + 16
    phi = (np.arange(nphi) + 0.5) * 2.0 * np.pi / nphi
    xx, pp = np.meshgrid(x, phi, indexing="ij")
    weight = np.repeat(wx, nphi) * (2.0 * np.pi / nphi)
    theta, phi = np.arccos(xx.ravel()), pp.ravel()
    wo = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)],
                  -1)
    out = np.zeros((len(theta_i), sh.size(order)))
    for a, t in enumerate(theta_i):
        g = f(np.array([np.sin(t), 0.0, np.cos(t)]), wo) * wo[:, 2] * weight
        for l in range(order + 1):
            for m in range(-l, l + 1):
                out[a, l * l + l + m] = g @ real_y(l, m, theta, phi)
    return out


def phong(wi: np.ndarray, wo: np.ndarray, n: int = 8) -> np.ndarray:
    """A reciprocal lobe about the mirror direction, normalised Phong (n + 2)/(2π) cos^n."""
    mirror = wi * np.array([-1.0, -1.0, 1.0])
    return (n + 2) / (2 * np.pi) * np.maximum(wo @ mirror, 0.0) ** n


def harmonics_table(theta_i: np.ndarray, coefficients: np.ndarray) -> BRDFTable:
    """An isotropic table holding only the given harmonics, (a, n) grey or (a, n, 3) per
    channel, in every component."""
    a = len(theta_i)
    zeros = {c: np.zeros((a, 1, 2, 2, 3)) for c in components_for(3)}
    flat = {c: np.zeros((a, 1, 3)) for c in components_for(3)}
    grey = (np.repeat(coefficients[:, None, :, None], 3, axis=-1) if coefficients.ndim == 2
            else coefficients[:, None])
    return table_of(HemisphereBins(2, 2), theta_i, np.zeros(1), True, zeros, zeros,
                     np.ones((a, 1), np.int64), flat, flat, np.zeros((a, 1, 3)), TableMeta(),
                     sh={c: grey for c in components_for(3)},
                     sh_err={c: np.zeros_like(grey) for c in components_for(3)})


# --- the basis ----------------------------------------------------------------------------
def test_orthonormal_to_order_40_by_quadrature() -> None:
    """Gauss-Legendre in cos θ (L + 2 nodes) times 2L + 3 uniform azimuths integrates
    every product Y_k Y_k' of order ≤ 40 exactly: the Gram matrix is the identity."""
    order = 40
    x, wx = np.polynomial.legendre.leggauss(order + 2)
    nphi = 2 * order + 3
    xx, pp = np.meshgrid(x, np.arange(nphi) * 2.0 * np.pi / nphi, indexing="ij")
    y = sh.basis(order, xx.ravel(), pp.ravel())
    gram = (y * (np.repeat(wx, nphi) * 2.0 * np.pi / nphi)[:, None]).T @ y
    assert np.abs(gram - np.eye(sh.size(order))).max() < 1e-11


def test_basis_against_scipy_closed_forms_and_mpmath() -> None:
    rng = np.random.default_rng(5)
    theta, phi = np.arccos(rng.uniform(-1, 1, 50)), rng.uniform(0, 2 * np.pi, 50)
    order = 32
    y = sh.basis(order, np.cos(theta), phi)
    l, m = sh.degrees(order)
    scipy_y = np.stack([real_y(a, b, theta, phi) for a, b in zip(l, m, strict=True)], -1)
    assert np.abs(y - scipy_y).max() < 1e-10
    # closed forms, written out by hand (Condon-Shortley: Y_11 ∝ −x)
    s, c = np.sin(theta), np.cos(theta)
    assert np.allclose(y[:, 3], -math.sqrt(3 / (4 * np.pi)) * s * np.cos(phi))
    assert np.allclose(y[:, 1], -math.sqrt(3 / (4 * np.pi)) * s * np.sin(phi))
    assert np.allclose(y[:, 4], 0.25 * math.sqrt(15 / np.pi) * s * s * np.sin(2 * phi))
    assert np.allclose(y[:, 6], 0.25 * math.sqrt(5 / np.pi) * (3 * c * c - 1))
    # mpmath's complex Y_l^m (Condon-Shortley) at high order, 30 digits
    mpmath.mp.dps = 30
    for i, (a, b) in enumerate([(32, 7), (30, -29), (25, 0)]):
        z = complex(mpmath.spherharm(a, abs(b), theta[i], phi[i]))
        expected = z.real if b == 0 else math.sqrt(2) * (z.real if b > 0 else z.imag)
        assert abs(y[i, a * a + a + b] - expected) < 1e-12


def test_ducc0_projection_and_second_moments_equal_direct_sums() -> None:
    rng = np.random.default_rng(2)
    d = unit(rng.normal(size=(3000, 3)))
    loc = sh.angles(d, 0.7)
    w = rng.random((3000, 2))
    y = sh.basis(12, np.cos(loc[:, 0]), loc[:, 1])
    direct = y.T @ w
    assert np.abs(sh.project(loc, w, 12) - direct).max() < 1e-6 * np.abs(direct).max()
    square = (y * y).T @ (w * w)
    wide = sh.project(loc, w * w, 24)
    assert np.abs(sh.second_moments(wide, 12) - square).max() < 1e-6 * square.max()


def test_equal_weight_columns_share_one_transform_and_lookalikes_do_not() -> None:
    """``moments`` transforms each distinct weight column once: equal columns (a grey
    material's R, G, B) take the first's sums, and columns of equal sums but other values
    (a permutation of the same weights) keep their own, equal to the direct sums; a column
    equal to its square (mirror weights 0 or 1) gives its first moments from the order-2L
    transform, to ducc0's accuracy."""
    rng = np.random.default_rng(5)
    loc = sh.angles(unit(rng.normal(size=(2000, 3))), 0.0)
    a = rng.random(2000)
    mirror = (rng.random(2000) < 0.5).astype(float)
    w = np.column_stack([a, a, rng.permutation(a), mirror, a])
    assert sh._distinct(np.ascontiguousarray(w.T)) == ([0, 2, 3], [0, 0, 1, 2, 0])
    sums, wide = sh.moments(loc, w, 8)
    direct = sh.basis(8, np.cos(loc[:, 0]), loc[:, 1]).T @ w
    assert np.abs(sums - direct).max() < 1e-6 * np.abs(direct).max()
    assert np.array_equal(sums[:, 0], sums[:, 1]) and np.array_equal(sums[:, 0], sums[:, 4])
    wide_direct = sh.basis(16, np.cos(loc[:, 0]), loc[:, 1]).T @ (w * w)
    assert np.abs(wide - wide_direct).max() < 1e-6 * np.abs(wide_direct).max()


def spectral_weights(n: int, seed: int) -> np.ndarray:
    """(n, 32) exit weights of a gold-like conductor at 32 wavelengths: the Fresnel factor
    at one bounce for two thirds of the rays, the product of two for the rest, with
    η and k smooth in λ (Johnson & Christy's gold between 400 and 710 nm, roughly)."""
    from microsim.analytic.fresnel import ConductorFresnel

    rng = np.random.default_rng(seed)
    x = np.linspace(0.0, 1.0, 32)
    gold = ConductorFresnel(1.5 - 1.3 * x ** 0.5, 1.8 + 2.6 * x)
    w = gold.factor(rng.uniform(0.02, 1.0, n))
    second = rng.random(n) < 1 / 3
    w[second] *= gold.factor(rng.uniform(0.02, 1.0, int(second.sum())))
    return w


def test_spectral_weights_are_transformed_through_few_principal_components() -> None:
    """32 channels of conductor weights span few dimensions: ``principal`` keeps at most
    12 components (measured: 10) whose residual is within ``PRINCIPAL_TOLERANCE`` of the
    weights' norm, and ``moments`` through them equals its channel-by-channel transforms
    within the documented bound ``PRINCIPAL_TOLERANCE`` ‖w‖ ‖Y_k‖ plus ducc0's own error
    (``EPSILON`` of the coefficients' norm), and the direct sums within 1e-6 of their
    largest, for both moments."""
    rng = np.random.default_rng(8)
    n = 6000
    loc = sh.angles(unit(rng.normal(size=(n, 3))), 0.3)
    w = spectral_weights(n, 9)
    found = principal(w.T, sh.PRINCIPAL_TOLERANCE)
    assert found is not None
    basis, mix = found
    assert basis.shape[0] == mix.shape[1] <= 12 and mix.shape[0] == 32
    np.testing.assert_allclose(mix.T @ mix, np.eye(mix.shape[1]), atol=1e-12)
    assert np.linalg.norm(w.T - mix @ basis) <= sh.PRINCIPAL_TOLERANCE * np.linalg.norm(w)
    sums, wide = sh.moments(loc, w, 8)
    plain = sh.PRINCIPAL_CHANNELS
    try:
        sh.PRINCIPAL_CHANNELS = 32
        each, each_wide = sh.moments(loc, w, 8)
    finally:
        sh.PRINCIPAL_CHANNELS = plain
    for order, got, want, weights in ((8, sums, each, w), (16, wide, each_wide, w * w)):
        y = sh.basis(order, np.cos(loc[:, 0]), loc[:, 1])
        bound = (sh.PRINCIPAL_TOLERANCE * np.linalg.norm(weights)
                 * np.linalg.norm(y, axis=0)[:, None]
                 + 2 * sh.EPSILON * np.linalg.norm(want, axis=0))
        assert np.all(np.abs(got - want) <= bound)
        direct = y.T @ weights
        assert np.abs(got - direct).max() < 1e-6 * np.abs(direct).max()


def test_principal_components_of_a_row_slice_are_those_of_its_copy() -> None:
    """``moments`` hands ``principal`` a batch's order row as a slice of the channel-major
    weights (rows a whole batch apart in memory, not copied): its components, and the
    sums through them, are those of the same rows copied, bit for bit, since the products
    read the same numbers in the same order."""
    w = spectral_weights(5000, 3)
    wide = np.ascontiguousarray(w.T)                     # (32, 5000), as a batch's rows
    rows = wide[:, 1200:4100]
    assert not rows.flags.c_contiguous
    got, want = principal(rows, sh.PRINCIPAL_TOLERANCE), principal(
        np.ascontiguousarray(rows), sh.PRINCIPAL_TOLERANCE)
    assert got is not None and want is not None
    assert all(np.array_equal(a, b) for a, b in zip(got, want, strict=True))
    loc = sh.angles(unit(np.random.default_rng(5).normal(size=(2900, 3))), 0.0)
    assert np.array_equal(sh.moments(loc, rows.T, 8, second=False)[0],
                          sh.moments(loc, np.ascontiguousarray(rows.T), 8, second=False)[0])


def test_principal_components_missed_by_the_sampled_gram_matrix_are_found() -> None:
    """``principal`` tries the eigenvectors of every ``SAMPLE``-th sample's Gram matrix
    first and checks the residual of every sample: weights with a second spectral
    direction only in the samples that one skips fail that check, and the Gram matrix of
    every sample then finds both directions (two components, residual within the
    tolerance); the sampled rows alone would have needed one."""
    from microsim.tables import principal as pc

    rng = np.random.default_rng(2)
    n = pc.SAMPLED * 32 * 2
    spectra = np.linalg.qr(rng.normal(size=(32, 2)))[0]      # two orthonormal spectra
    amount = rng.uniform(0.5, 1.0, (2, n))
    amount[1, ::pc.SAMPLE] = 0.0                              # absent where sampled
    rows = spectra @ amount
    assert pc._leading(np.ascontiguousarray(rows[:, ::pc.SAMPLE]),
                       sh.PRINCIPAL_TOLERANCE).shape == (32, 1)
    found = principal(rows, sh.PRINCIPAL_TOLERANCE)
    assert found is not None and found[0].shape == (2, n)
    basis, mix = found
    assert (np.linalg.norm(rows - mix @ basis)
            <= sh.PRINCIPAL_TOLERANCE * np.linalg.norm(rows))


def test_weights_the_sample_finds_of_full_rank_take_one_gram_matrix(monkeypatch) -> None:
    """Where every ``SAMPLE``-th sample already needs more than half the channels'
    components, ``principal`` gives none without the Gram matrix of every sample (which
    would need at least as many): one eigen-decomposition, of the sample's; weights whose
    sample is all zero still get the full one."""
    from microsim.tables import principal as pc

    calls: list[int] = []
    leading = pc._leading
    monkeypatch.setattr(pc, "_leading", lambda rows, tol: calls.append(rows.shape[1])
                        or leading(rows, tol))
    n = pc.SAMPLED * 32 * 2
    assert principal(np.random.default_rng(6).random((32, n)), 1e-7) is None
    assert calls == [len(range(0, n, pc.SAMPLE))]
    calls.clear()
    rows = np.zeros((32, n))
    rows[:, 1::pc.SAMPLE] = 1.0                                # one spectrum, unsampled
    found = principal(rows, 1e-7)
    assert found is not None and found[0].shape == (1, n) and calls[-1] == n


def test_a_measurement_keeps_the_blas_library_to_one_thread(monkeypatch) -> None:
    """Inside ``measure_ensemble`` the BLAS library (``principal``'s products) runs on one
    thread, so that it neither competes with the tracer's threads nor splits its sums
    differently from one run to the next; after it, the threads it had before."""
    from threadpoolctl import threadpool_info, threadpool_limits

    from microsim.measurement import simulation

    seen: list[int] = []

    class Stop(Exception):
        pass

    def opener(*args: object) -> None:
        seen.extend(info["num_threads"] for info in threadpool_info()
                    if info["user_api"] == "blas")
        raise Stop

    monkeypatch.setattr(simulation, "Opener", opener)
    recipe = resolve({"surface": {"kind": "flat"}, "material": {"kind": "mirror"}})
    with threadpool_limits(limits=2, user_api="blas"):
        with pytest.raises(Stop):
            simulation.measure_ensemble(None, recipe.material, recipe.simulation,
                                        recipe.table)
        after = [info["num_threads"] for info in threadpool_info()
                 if info["user_api"] == "blas"]
    assert seen and set(seen) == {1}
    assert set(after) == {2}


def test_weights_without_few_principal_components_are_transformed_as_they_are() -> None:
    """Independent random channels (full rank), zero weights, and a tolerance below what
    the Gram matrix's rounding allows give no principal components; ``moments`` then
    transforms the channels themselves, bit for bit as one at a time."""
    rng = np.random.default_rng(4)
    loc = sh.angles(unit(rng.normal(size=(3000, 3))), 0.0)
    w = rng.random((3000, 32))
    assert principal(w.T, sh.PRINCIPAL_TOLERANCE) is None
    assert principal(np.zeros((32, 100)), sh.PRINCIPAL_TOLERANCE) is None
    assert principal(spectral_weights(3000, 1).T, 1e-12) is None
    sums, _ = sh.moments(loc, w, 6, second=False)
    for c in (0, 17, 31):
        assert np.array_equal(sums[:, c], sh.moments(loc, w[:, c:c + 1], 6, second=False)[0][:, 0])


def test_windows() -> None:
    assert CLI_WINDOWS == sh.WINDOWS and CLI_MATRIX_MAX_ORDER == MAX_ORDER
    l, _ = sh.degrees(7)
    assert np.allclose(sh.window(7, "lanczos")[l == 4], 2 / np.pi)      # sinc(1/2)
    assert np.allclose(sh.window(7, "hanning")[l == 4], 0.5)
    assert np.all(sh.window(7, "none") == 1) and sh.window(7, "lanczos")[0] == 1
    with pytest.raises(ValueError, match="window"):
        sh.window(7, "gauss")


def test_hanning_window_angles_and_orders_are_their_formulas() -> None:
    """The Hanning factors ½ (1 + cos(πl/(L + 1))) at every l of order 7 (l = 4 alone, where
    cos vanishes, does not tell ½ (1 + c) from ½ (1 − c) or ½ / (1 + c)); ``angles`` of
    directions with known colatitude and azimuth, wrapped to [0, 2π) after subtracting
    ``phi_ref`` (default 0), z rounded past ±1 clipped (arccos would be NaN); ``order_of``
    of 0, 1, 2 and 16 coefficients, ``truncate`` past the stored order, and their
    messages."""
    l, _ = sh.degrees(7)
    assert np.allclose(sh.window(7, "hanning"), 0.5 * (1 + np.cos(np.pi * l / 8)),
                       rtol=1e-15, atol=0)
    theta, phi = np.radians([10.0, 80.0, 135.0]), np.radians([30.0, 200.0, 350.0])
    d = np.column_stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi),
                         np.cos(theta)])
    got = sh.angles(d)
    assert np.allclose(got, np.column_stack([theta, phi]), rtol=0, atol=1e-14)
    got = sh.angles(d, 0.7)
    assert np.allclose(got[:, 1], np.mod(phi - 0.7, 2 * np.pi), rtol=0, atol=1e-14)
    poles = sh.angles(np.array([[0.0, 0.0, 1.0 + 2e-16], [0.0, 0.0, -1.0 - 2e-16]]))
    assert np.array_equal(poles[:, 0], [0.0, np.pi])
    assert sh.order_of(1) == 0 and sh.order_of(16) == 3
    for n in (0, 2):
        with pytest.raises(ValueError, match=rf"^{n} coefficients is not \(L \+ 1\)\^2 "
                                              "for an order L$"):
            sh.order_of(n)
    with pytest.raises(ValueError, match=r"^order 4 exceeds the stored order 3$"):
        sh.truncate(np.zeros((16, 1)), 4)


def test_projection_of_one_direction_and_of_none() -> None:
    """``project`` of a single direction is its basis row times its weights (within 1e-6
    of the largest, ducc0's accuracy as in the other projections), and of no direction the
    zero coefficients of the order."""
    loc = sh.angles(np.array([[0.3, 0.4, math.sqrt(0.75)]]))
    w = np.array([[0.7, 1.3]])
    direct = sh.basis(3, np.cos(loc[:, 0]), loc[:, 1]).T @ w
    got = sh.project(loc, w, 3)
    assert got.shape == (16, 2) and np.abs(got - direct).max() < 1e-6 * np.abs(direct).max()
    assert np.array_equal(sh.project(np.zeros((0, 2)), np.zeros((0, 2)), 3), np.zeros((16, 2)))


def test_the_mapper_runs_every_transform_once() -> None:
    """``project`` and ``moments`` hand their transforms to the given mapper in one call
    over range(jobs), and return what they return without one, bit for bit (the mapper
    here runs the jobs in reverse; each transform is single-threaded): ``project`` runs
    one order-L transform per distinct weight column; ``moments`` one order-2L transform
    of w² per distinct column and one order-L transform per distinct column other than
    its own square (0/1 weights take theirs from the order-2L one), and without
    ``second`` the order-L ones alone."""
    rng = np.random.default_rng(9)
    loc = sh.angles(unit(rng.normal(size=(500, 3))))
    a = rng.random(500)
    mirror = (rng.random(500) < 0.5).astype(float)
    w = np.column_stack([a, mirror, a, rng.random(500)])      # 3 distinct, 1 its square
    calls = []

    def mapper(fn, jobs):
        calls.append(len(jobs))
        return [fn(j) for j in reversed(jobs)][::-1]

    assert np.array_equal(sh.project(loc, w, 6, mapper), sh.project(loc, w, 6))
    assert calls == [3]
    calls.clear()
    sums, wide = sh.moments(loc, w, 6, mapper)
    ref_sums, ref_wide = sh.moments(loc, w, 6)
    assert calls == [2 + 3]
    assert np.array_equal(sums, ref_sums) and np.array_equal(wide, ref_wide)
    calls.clear()
    sums, wide = sh.moments(loc, w, 6, mapper, second=False)
    assert calls == [3] and wide is None
    assert np.array_equal(sums, sh.moments(loc, w, 6, second=False)[0])


def test_single_precision_inputs_are_computed_in_double_precision() -> None:
    """float32 cos θ (``legendre``, ``basis``) and float32 weights (``moments``) are taken
    as the float64 numbers they are and worked on in double precision: the results equal,
    bit for bit, those of the same values given as float64 (each transform is
    single-threaded, so equal inputs give equal sums). Worked in single precision, the
    recurrence and the squares of the weights would round to float32's 6e-8 at each step,
    differences of 1e-8 to 1e-6 here."""
    rng = np.random.default_rng(11)
    x = rng.uniform(-1.0, 1.0, 40).astype(np.float32)
    phi = rng.uniform(0.0, 2.0 * np.pi, 40)
    for order in (1, 5, 12):
        got = sh.legendre(order, x)
        assert got.dtype == np.float64
        assert np.array_equal(got, sh.legendre(order, x.astype(np.float64)))
        assert np.array_equal(sh.basis(order, x, phi),
                              sh.basis(order, x.astype(np.float64), phi))
    loc = sh.angles(unit(rng.normal(size=(300, 3))))
    w = rng.random((300, 2)).astype(np.float32)
    for order in (0, 2, 6):
        sums, wide = sh.moments(loc, w, order)
        ref_sums, ref_wide = sh.moments(loc, w.astype(np.float64), order)
        assert np.array_equal(sums, ref_sums) and np.array_equal(wide, ref_wide)


# --- projection of rays -------------------------------------------------------------------
def test_projection_of_rays_is_unbiased_with_honest_errors() -> None:
    """Rays leave cosine-distributed (pdf cos θo / π) with weight π f(ωo) per colour, so
    E[w Y_k] = ∫ f cos θo Y_k dωo for the Phong lobe about the mirror of θi = 40°; a third
    of the rays are second order (weight kept), so "order1" holds 2/3 of the lobe and
    "order2" 1/3. The
    goniometer's accumulator and estimator give coefficients whose z-scores against the
    exact values (quadrature with scipy's harmonics) stay within Z_MAX, and whose mean z²
    is near 1 (81 nearly independent z²: the mean has sd ≈ 0.16; bounds 0.5–1.6 are
    > 3.5 sd), so the standard errors are neither too small nor too large."""
    order, n = 8, 50_000
    wi = np.array([np.sin(np.radians(40)), 0.0, np.cos(np.radians(40))])
    rng = np.random.default_rng(11)
    bins = HemisphereBins(4, 8)
    acc = Sums(bins.size, order)
    for _ in range(4):
        u, phi = rng.random(n), rng.uniform(0, 2 * np.pi, n)
        wo = np.stack([np.sqrt(u) * np.cos(phi), np.sqrt(u) * np.sin(phi), np.sqrt(1 - u)],
                      -1)
        weight = np.pi * phong(wi, wo)[:, None] * np.array([1.0, 0.5, 0.25])
        orders = np.where(rng.random(n) < 1 / 3, 2, 1)
        paths = Paths(wo, weight, orders, np.zeros(3), np.zeros(3), np.zeros(3), {})
        acc.add(paths, bins)
    ensemble = EnsembleSums((1, 1), acc.components, bins.size, order)
    fold(ensemble, Energies(), RunKey(0, 0, 0), acc)
    table = from_ensemble(bins, np.radians([40.0]), np.zeros(1), True, ensemble, TableMeta())
    exact = lobe_coefficients(phong, np.radians([40.0]), order)[0]
    for comp, share in (("total", 1.0), ("order1", 2 / 3), ("order2", 1 / 3)):
        z = (table[comp].sh[0, 0] - share * exact[:, None] * [1.0, 0.5, 0.25]) / table[
            comp].sh_err[0, 0]
        assert np.abs(z).max() < Z_MAX, comp
        assert 0.5 < np.mean(z[:, 0] ** 2) < 1.6, comp
    # the constant harmonic is the albedo: the same rays, the same sums
    assert np.allclose(table["total"].sh[0, 0, 0] * math.sqrt(4 * np.pi), table.albedo[0, 0],
                       rtol=1e-6)


@pytest.fixture(scope="module")
def rough() -> BRDFTable:
    """Gaussian α = 0.5, mirror facets, 256² tile, θi = 0 and 45°, 2 x 65 536 rays, order
    16. (A 64² tile has too few facets: its mirror-reflected lobe is a spiky sum of a few
    thousand directions that no order-16 series follows; a 256² tile still has a speckle of
    its own NDF realisation, which scripts/sh_error_vs_order.py avoids with 1024².)"""
    from microsim.surfaces import build_tile

    recipe = resolve({"surface": {"kind": "gaussian", "alpha": 0.5, "resolution": 256,
                                  "seed": 3},
                      "simulation": {"theta_i": [0.0, 45.0], "rays": 131_072, "seed": 4},
                      "table": {"theta_bins": 16, "phi_bins": 32, "sh_order": 16}})
    return simulate(build_tile(recipe.surface), recipe.material, recipe.simulation,
                    recipe.table, recipe=recipe)


def test_rough_gaussian_error_falls_with_order(rough: BRDFTable) -> None:
    """Measured: 21.9%, 12.1%, 9.0%, 7.7% at orders 2, 4, 8, 16 over the hemisphere
    (pooled over both incidences), with the table's own noise at 5.3%: at this ray count
    the table's noise, not the truncation, dominates from order 8 on. Each order must beat
    the previous one (over the hemisphere and over the lobe), and order 16 must come within
    twice the table's noise. Lanczos σ-factors at order 8 must make the most negative
    value less negative, and cost error.

    With 4 M rays on a 1024² tile (scripts/sh_error_vs_order.py, docs/performance.md),
    5% over the hemisphere takes order 11 at α = 0.5 and order 26 at α = 0.2."""
    rows = order_errors(rough, [2, 4, 8, 16])
    errors = [r["rel_l2_error"] for r in rows]
    assert all(b < a for a, b in zip(errors, errors[1:], strict=False)), errors
    lobe = [r["rel_l2_error_lobe"] for r in rows]
    assert all(b < a for a, b in zip(lobe, lobe[1:], strict=False)), lobe
    assert errors[-1] < 2.0 * rows[-1]["table_noise"], (errors, rows[-1]["table_noise"])
    assert [r["bytes"] for r in rows] == [(o + 1) ** 2 * 2 * 3 * 4 for o in (2, 4, 8, 16)]
    lanczos = order_errors(rough, [8], "lanczos")[0]
    assert lanczos["min_value"] > rows[2]["min_value"]        # the window damps ringing
    assert lanczos["rel_l2_error"] > rows[2]["rel_l2_error"]  # at a cost in error


def test_sh_eval_is_the_series_over_cos_theta(rough: BRDFTable) -> None:
    """At a tabulated incidence, eval(representation="sh") is Σ c_k Y_k(ωo) / cos θo with
    ωo's azimuth relative to φi (scipy's harmonics), whatever φi is."""
    rng = np.random.default_rng(3)
    wo = unit(rng.normal(size=(20, 3)) * [1, 1, 0.1] + [0, 0, 0.5])
    phi_i = 1.1
    wi = np.array([np.sin(np.radians(45)) * np.cos(phi_i),
                   np.sin(np.radians(45)) * np.sin(phi_i), np.cos(np.radians(45))])
    theta, phi = np.arccos(wo[:, 2]), np.arctan2(wo[:, 1], wo[:, 0]) - phi_i
    l, m = sh.degrees(16)
    y = np.stack([real_y(a, b, theta, phi) for a, b in zip(l, m, strict=True)], -1)
    expected = y @ rough["total"].sh[1, 0] / wo[:, 2:]
    assert np.allclose(rough.eval(wi, wo, representation="sh"), expected, rtol=1e-9,
                       atol=1e-12)
    with pytest.raises(ValueError, match="representation"):
        rough.eval(wi, wo, representation="bins")


def test_sums_pickle_and_same_seed_gives_same_harmonics_whatever_the_threads() -> None:
    """Batch runners ship ``Sums`` between processes; the harmonics travel with them."""
    import pickle

    from tilefixtures import random_tile

    recipe = resolve({"surface": {"kind": "flat"},
                      "simulation": {"theta_i": [30.0], "rays": 2000, "seed": 1},
                      "table": {"theta_bins": 4, "phi_bins": 8, "sh_order": 6}})
    tile = random_tile()
    one = simulate(tile, recipe.material, recipe.simulation, recipe.table, threads=1)
    two = simulate(tile, recipe.material, recipe.simulation, recipe.table, threads=2)
    for c in one.components:
        assert np.array_equal(one[c].sh, two[c].sh) and np.array_equal(one[c].sh_err,
                                                                       two[c].sh_err)
    acc = Sums(8, 6)
    acc.add(Paths(np.array([[0.0, 0.6, 0.8]]), np.ones((1, 3)),
                                         np.ones(1, np.int64), np.zeros(3), np.zeros(3),
                                         np.zeros(3), {}), HemisphereBins(2, 4))
    back = pickle.loads(pickle.dumps(acc))
    assert back.sh_order == 6
    assert np.array_equal(back.sh_sums, acc.sh_sums)
    assert np.array_equal(back.sh_sums_sq, acc.sh_sums_sq)


def test_merged_tables_merge_their_harmonics() -> None:
    """Two runs with other seeds: the merged coefficients are the ray-weighted mean."""
    from tilefixtures import random_tile

    recipe = resolve({"surface": {"kind": "flat"},
                      "simulation": {"theta_i": [30.0], "rays": 3000, "seed": 1},
                      "table": {"theta_bins": 4, "phi_bins": 8, "sh_order": 4}})
    tile = random_tile()
    a = simulate(tile, recipe.material, recipe.simulation, recipe.table)
    b = simulate(tile, recipe.material, replace(recipe.simulation, seed=2, rays=5000), recipe.table)
    merged = merge(a, b)
    assert np.allclose(merged["total"].sh, (3 * a["total"].sh + 5 * b["total"].sh) / 8)
    assert np.all(merged["total"].sh_err < np.maximum(a["total"].sh_err, b["total"].sh_err))


# --- storage ------------------------------------------------------------------------------
def test_exr_round_trip_and_tables_without_harmonics(rough: BRDFTable, tmp_path) -> None:
    write_table(rough, tmp_path / "t.exr")
    back = microsim.read_table(tmp_path / "t.exr")
    assert back.sh_order == 16
    assert back.components == rough.components == components_for(3)
    for c in rough.components:
        assert np.allclose(back[c].sh, rough[c].sh, rtol=1e-6, atol=1e-9)
        assert np.allclose(back[c].sh_err, rough[c].sh_err, rtol=1e-6, atol=1e-12)
        assert np.allclose(back[c].values, rough[c].values, rtol=1e-6, atol=1e-9)
    plain = replace(rough, estimates={c: replace(e, sh=None, sh_err=None)
                                      for c, e in rough.estimates.items()})
    write_table(plain, tmp_path / "plain.exr")
    old = microsim.read_table(tmp_path / "plain.exr")
    assert not old.has_sh and old.sh_order == 0
    assert np.allclose(old["total"].values, rough["total"].values, rtol=1e-6, atol=1e-9)
    with pytest.raises(ValueError, match="no spherical harmonics"):
        old.eval([0, 0, 1.0], [0, 0, 1.0], representation="sh")


# --- Westin's matrix ----------------------------------------------------------------------
def test_lambertian_matrix_is_the_outer_product_of_cosine_moments() -> None:
    """f = ρ/π: b_ij = ρ/π c_i c_j with c_l0 = 2π ∫_0^1 x P̄_l(x) dx (mpmath, 20 digits) and
    c_lm = 0 for m ≠ 0."""
    theta_i = np.radians([0.0, 30.0, 60.0, 80.0])
    order = 4
    coefficients = lobe_coefficients(lambda wi, wo: np.full(len(wo), 0.8 / np.pi), theta_i,
                                     order)
    matrix, asymmetry = brdf_matrix(harmonics_table(theta_i, coefficients))
    mpmath.mp.dps = 20
    c = np.zeros(sh.size(order))
    for l in range(order + 1):
        norm = mpmath.sqrt((2 * l + 1) / (4 * mpmath.pi))
        c[l * l + l] = float(2 * mpmath.pi * norm * mpmath.quad(
            lambda x, l=l: x * mpmath.legendre(l, x), [0, 1]))
    assert np.abs(matrix[..., 0] - 0.8 / np.pi * np.outer(c, c)).max() < 1e-12
    assert asymmetry.max() < 1e-12


def test_matrix_reciprocity_improves_with_incidences() -> None:
    """A reciprocal Phong lobe tabulated at 4, 8 and 16 incidences: the asymmetry of the
    matrix before symmetrisation (the θi interpolation error) measured 9.5%, 1.5% and
    0.34% at order 8: it must fall by 3x per doubling; the result is symmetric and
    reproduces the per-incidence series to 2% at 16 incidences."""
    order = 8
    asym = []
    for count in (4, 8, 16):
        theta_i = np.radians(np.linspace(0.0, 89.0, count))
        table = harmonics_table(theta_i, lobe_coefficients(phong, theta_i, order, 64))
        matrix, asymmetry = brdf_matrix(table)
        asym.append(asymmetry[0])
    assert asym[1] < asym[0] / 3 and asym[2] < asym[1] / 3, asym
    assert np.array_equal(matrix, matrix.transpose(1, 0, 2))
    l, m = sh.degrees(order)
    assert np.all(matrix[np.abs(m[:, None]) != np.abs(m[None, :])] == 0)
    rng = np.random.default_rng(8)
    wi = unit(rng.normal(size=(200, 3)) * [1, 1, 0] + [0, 0, 1.2])
    wo = unit(rng.normal(size=(200, 3)) * [1, 1, 0] + [0, 0, 1.2])
    h_matrix = matrix_eval(matrix, wi, wo) * (wi[:, 2] * wo[:, 2])[:, None]
    h_series = table.eval(wi, wo, representation="sh") * (wi[:, 2] * wo[:, 2])[:, None]
    assert np.sqrt(np.mean((h_matrix - h_series) ** 2) / np.mean(h_series ** 2)) < 0.02


def definition_matrix(theta_i: np.ndarray, a: np.ndarray, order: int,
                      nodes: int = 24) -> np.ndarray:
    """Westin's b_ij = ∫ cos θi Y_i(ωi) C_j(ωi) dωi over the upper hemisphere, written out
    with scipy's harmonics and no block structure: the lobe at (θi, φi) is
    g(ωo) = Σ_k a_k(θi) Y_k(θo, φo − φi), a_k linear in θi between the incidences
    (``np.interp``, clamped outside), and C_j(ωi) = ∫ Y_j g dωo over the sphere. The
    quadratures: Gauss-Legendre with ``nodes`` nodes in θi on each interval between 0, the
    incidences and π/2; 4L + 4 uniform φi and 2L + 2 uniform φo (exact for the
    trigonometric polynomials of degree ≤ 2L in either); L + 2 Gauss-Legendre nodes in
    cos θo (exact for the products Y_j Y_k, polynomials of degree ≤ 2L in cos θo once the
    azimuths are integrated). ``a`` is (len(theta_i), (L + 1)², C); the result is B before
    symmetrisation, ((L + 1)², (L + 1)², C)."""
    l, m = sh.degrees(order)
    breaks = np.unique(np.concatenate([[0.0], theta_i, [np.pi / 2]]))
    t, wt = np.polynomial.legendre.leggauss(nodes)
    half = 0.5 * np.diff(breaks)[:, None]
    theta = ((t + 1.0) * half + breaks[:-1, None]).ravel()
    w_theta = (wt * half).ravel()
    n_phi_i = 4 * order + 4
    phi_i = np.arange(n_phi_i) * 2 * np.pi / n_phi_i
    x, wx = np.polynomial.legendre.leggauss(order + 2)
    n_phi_o = 2 * order + 2
    xo, po = np.meshgrid(x, np.arange(n_phi_o) * 2 * np.pi / n_phi_o, indexing="ij")
    theta_o, phi_o = np.arccos(xo.ravel()), po.ravel()
    w_o = np.repeat(wx, n_phi_o) * 2 * np.pi / n_phi_o
    y_o = np.stack([real_y(a_, b_, theta_o, phi_o) for a_, b_ in zip(l, m, strict=True)], -1)
    # R[p, j, k] = ∫ Y_j(θo, φo) Y_k(θo, φo − φi_p) dωo
    rotated = np.stack([np.stack([real_y(a_, b_, theta_o, phi_o - p) for a_, b_ in
                                  zip(l, m, strict=True)], -1) for p in phi_i])
    rot = np.einsum("oj,pok,o->pjk", y_o, rotated, w_o)
    coefficients = np.stack([[np.interp(theta, theta_i, a[:, k, c]) for k in range(len(l))]
                             for c in range(a.shape[-1])], -1)   # (k, θ, C)
    c_j = np.einsum("pjk,ktc->tpjc", rot, coefficients)
    tt, pp = np.meshgrid(theta, phi_i, indexing="ij")
    y_i = np.stack([real_y(a_, b_, tt, pp) for a_, b_ in zip(l, m, strict=True)], -1)
    weight = (w_theta * np.cos(theta) * np.sin(theta))[:, None] * 2 * np.pi / n_phi_i
    return np.einsum("tp,tpi,tpjc->ijc", weight, y_i, c_j)


def test_matrix_is_its_definition_for_any_coefficients() -> None:
    """Random coefficients, their odd-in-azimuth a_{l,−μ} too (which a lobe symmetric
    about the plane of incidence leaves 0, and with them the entries of sign −π), per
    channel, at incidences 20, 45, 70° (so a_k is clamped below the first): the matrix is
    the symmetrised definition written out (``definition_matrix``), and its asymmetry
    ‖B − Bᵀ‖_F / ‖B‖_F per channel that of the definition's B, both within 1e-12
    relative (the quadratures are exact up to round-off). A channel of zeros has
    asymmetry 0; channel 0 is scaled so that its norm is below 1. With ``nodes=2`` the θi
    integral takes 2 Gauss-Legendre nodes per interval, as the definition with 2 does,
    which differs from the converged one by more than 1e-6."""
    order = 3
    theta_i = np.radians([20.0, 45.0, 70.0])
    rng = np.random.default_rng(12)
    a = rng.normal(size=(3, sh.size(order), 3)) * [0.05, 3.0, 0.0]
    table = harmonics_table(theta_i, a)
    matrix, asymmetry = brdf_matrix(table)
    exact = definition_matrix(theta_i, a, order)
    scale = np.abs(exact).max(axis=(0, 1))
    assert np.all(np.abs(matrix - 0.5 * (exact + exact.transpose(1, 0, 2)))[..., :2]
                  < 1e-12 * scale[:2])
    assert np.all(matrix[..., 2] == 0)
    skew = np.sqrt(((exact - exact.transpose(1, 0, 2)) ** 2).sum(axis=(0, 1)))[:2]
    norm = np.sqrt((exact ** 2).sum(axis=(0, 1)))[:2]
    assert norm[0] < 1 < norm[1] and np.all(skew > 0.1 * norm)
    assert np.allclose(asymmetry[:2], skew / norm, rtol=1e-12, atol=0)
    assert asymmetry.dtype == np.float64 and asymmetry[2] == 0
    coarse, coarse_asymmetry = brdf_matrix(table, nodes=2)
    two = definition_matrix(theta_i, a, order, nodes=2)
    assert np.all(np.abs(coarse - 0.5 * (two + two.transpose(1, 0, 2)))[..., :2]
                  < 1e-12 * scale[:2])
    assert np.abs(coarse - matrix)[..., 1].max() > 1e-6 * scale[1]


def test_matrix_refuses_what_it_cannot_build_with_its_messages() -> None:
    """Anisotropic tables, tables without harmonics and orders past ``MAX_ORDER`` (32)
    are refused with their messages; order 32 itself is built."""
    table = harmonics_table(np.zeros(1), np.zeros((1, 4)))
    table = replace(table, isotropic=False)
    with pytest.raises(ValueError, match="^Westin's matrix is built for isotropic tables "
                                         "only$"):
        brdf_matrix(table)
    table = changed(harmonics_table(np.zeros(1), np.zeros((1, 4))), sh=lambda e: None)
    with pytest.raises(ValueError, match="^the table holds no spherical harmonics$"):
        brdf_matrix(table)
    with pytest.raises(ValueError, match="^order 33: the dense matrix is built up to "
                                         "order 32$"):
        brdf_matrix(harmonics_table(np.zeros(1), np.zeros((1, 4))), 33)
    assert MAX_ORDER == 32
    top = harmonics_table(np.radians([30.0]), np.ones((1, sh.size(32))))
    matrix, _ = brdf_matrix(top, 32)
    assert matrix.shape == (sh.size(32), sh.size(32), 3)


def test_matrix_eval_is_the_double_series_and_zero_off_the_hemisphere() -> None:
    """f_r = Σ_ij b_ij Y_i(ωi) Y_j(ωo) / (cos θi cos θo) with scipy's harmonics for pairs
    above the horizon (within 1e-12 relative), and exactly 0, as floats, where either
    direction is on the horizon (z = 0) or below it."""
    order = 2
    rng = np.random.default_rng(4)
    b = rng.normal(size=(sh.size(order), sh.size(order), 2))
    b = b + b.transpose(1, 0, 2)
    wi = unit(np.array([[0.3, 0.1, 0.9], [0.5, -0.4, 0.2], [0.2, 0.6, 0.7], [0.6, 0.0, 0.8],
                        [0.3, 0.4, -0.5], [1.0, 0.0, 0.0], [0.1, 0.2, 0.9]]))
    wo = unit(np.array([[-0.2, 0.5, 0.6], [0.1, 0.1, 0.95], [0.7, -0.1, 0.1], [0.0, 1.0, 0.0],
                        [0.2, 0.1, 0.9], [0.3, 0.3, 0.8], [0.4, 0.0, -0.2]]))
    got = matrix_eval(b, wi, wo)
    assert got.shape == (7, 2) and got.dtype == np.float64
    l, m = sh.degrees(order)

    def y(d):
        theta, phi = np.arccos(d[:, 2]), np.arctan2(d[:, 1], d[:, 0])
        return np.stack([real_y(a_, b_, theta, phi) for a_, b_ in zip(l, m, strict=True)], -1)

    expected = np.einsum("ki,ijc,kj->kc", y(wi[:3]), b, y(wo[:3])) / (
        wi[:3, 2] * wo[:3, 2])[:, None]
    assert np.allclose(got[:3], expected, rtol=1e-12, atol=0)
    assert np.array_equal(got[3:], np.zeros((4, 2)))


def test_write_matrix_stores_its_keys_and_the_wavelengths_of_spectral_tables(
        tmp_path) -> None:
    """The ``.npz`` holds exactly ``matrix``, ``order``, ``asymmetry`` and ``convention``
    (the string docs/table-format.md describes) for RGB, and ``wavelengths`` as float64 nm
    besides (given as ints here) for a spectral table."""
    rng = np.random.default_rng(6)
    matrix, asymmetry = rng.normal(size=(9, 9, 3)), np.array([0.1, 0.2, 0.3])
    write_matrix(tmp_path / "rgb.npz", matrix, asymmetry)
    convention = ("f_r cos(theta_i) cos(theta_o) = sum_ij b_ij Y_i(wi) Y_j(wo); real "
                  "orthonormal spherical harmonics, Condon-Shortley phase, index l*l + l + m "
                  "(docs/table-format.md)")
    with np.load(tmp_path / "rgb.npz") as data:
        assert sorted(data.files) == ["asymmetry", "convention", "matrix", "order"]
        assert np.array_equal(data["matrix"], matrix) and int(data["order"]) == 2
        assert np.array_equal(data["asymmetry"], asymmetry)
        assert str(data["convention"]) == convention
    write_matrix(tmp_path / "spectral.npz", matrix, asymmetry, (450, 550, 650))
    with np.load(tmp_path / "spectral.npz") as data:
        assert sorted(data.files) == ["asymmetry", "convention", "matrix", "order",
                                      "wavelengths"]
        assert data["wavelengths"].dtype == np.float64
        assert np.array_equal(data["wavelengths"], [450.0, 550.0, 650.0])


# --- the command --------------------------------------------------------------------------
def test_cli_reports_error_against_order(rough: BRDFTable, tmp_path, cli) -> None:
    write_table(rough, tmp_path / "t.exr")
    code, out, err = cli("sh", str(tmp_path / "t.exr"), "--orders", "2,4,8", "--json",
                         "--window", "hanning", "--plot", str(tmp_path / "e.png"))
    assert code == 0, err
    rows = json.loads(out)
    assert [r["order"] for r in rows] == [2, 4, 8]
    for key in ("order", "rel_l2_error", "rel_l2_error_lobe", "min_value", "bytes",
                "rel_l2_error_unwindowed", "table_noise", "sh_noise"):
        assert all(key in r for r in rows)
    assert rows[0]["window"] == "hanning" and (tmp_path / "e.png").stat().st_size > 1000
    code, out, _ = cli("sh", str(tmp_path / "t.exr"), "--json")        # stored order 16
    assert code == 0 and [r["order"] for r in json.loads(out)] == [2, 4, 8, 16]
    code, out, _ = cli("sh", str(tmp_path / "t.exr"), "--orders", "4")
    assert code == 0 and "hemisphere" in out and len(out.strip().splitlines()) == 3


def test_cli_writes_westin_matrix_and_npz_carries_harmonics(rough: BRDFTable, tmp_path,
                                                           cli) -> None:
    write_table(rough, tmp_path / "t.exr")
    code, out, err = cli("sh", str(tmp_path / "t.exr"), "--orders", "2,6", "--json",
                         "--matrix", str(tmp_path / "m.npz"))
    assert code == 0, err
    rows = json.loads(out)
    data = np.load(tmp_path / "m.npz")
    matrix, asymmetry = brdf_matrix(microsim.read_table(tmp_path / "t.exr"), 6)
    assert int(data["order"]) == 6 and np.allclose(data["matrix"], matrix)
    assert rows[-1]["matrix_asymmetry"] == pytest.approx(asymmetry.tolist())
    assert "matrix_asymmetry" not in rows[0]
    code, _, err = cli("sh", str(tmp_path / "t.exr"), "--orders", "4", "--matrix",
                       str(tmp_path / "m.txt"))
    assert code == 2 and "--matrix" in err
    assert cli("export", str(tmp_path / "t.exr"), "--format", "npz", "-o",
               str(tmp_path / "t.npz"))[0] == 0
    arrays = np.load(tmp_path / "t.npz")
    assert int(arrays["sh_order"]) == 16
    assert np.allclose(arrays["sh_total"], rough["total"].sh, rtol=1e-6, atol=1e-9)
    assert arrays["sh_order2_err"].shape == rough["order2"].sh_err.shape


@pytest.mark.parametrize("args, words", [
    (["--orders", "2,17"], "--orders 17"),
    (["--orders", "two"], "--orders"),
    (["--orders", "-1"], "--orders"),
    (["--window", "gauss"], "--window"),
])
def test_cli_bad_flags(rough: BRDFTable, tmp_path, cli, args, words) -> None:
    write_table(rough, tmp_path / "t.exr")
    code, out, err = cli("sh", str(tmp_path / "t.exr"), *args)
    assert code == 2 and err.startswith("error:") and words in err and out == ""
    assert len(err.strip().splitlines()) == 1


def test_cli_table_without_harmonics(tmp_path, cli) -> None:
    recipe = resolve({"surface": {"kind": "flat"},
                      "simulation": {"theta_i": [10.0], "rays": 500},
                      "table": {"theta_bins": 4, "phi_bins": 8, "sh_order": 0}})
    from tilefixtures import flat_tile

    write_table(simulate(flat_tile(), recipe.material, recipe.simulation,
                         recipe.table), tmp_path / "p.exr")
    code, _, err = cli("sh", str(tmp_path / "p.exr"))
    assert code == 2 and "no spherical harmonics" in err and "sh_order" in err
    code, _, err = cli("sh", str(tmp_path / "missing.exr"))
    assert code == 2 and err.startswith("error:")


def test_bin_integrals_sum_to_hemisphere_integrals() -> None:
    """Σ over bins of ∫_bin Y_k dω is ∫ over the hemisphere (by scipy quadrature), for
    full and folded azimuths; bin by bin, the integrals match a fine midpoint rule."""
    order = 6
    hemisphere = lobe_coefficients(lambda wi, wo: 1.0 / wo[:, 2], np.zeros(1), order)[0]
    for bins in (HemisphereBins(8, 16), HemisphereBins(8, 8, np.pi)):
        integrals, omega = bin_integrals(order, bins)
        assert np.allclose(integrals.sum(axis=0), hemisphere, atol=1e-12)
        assert np.isclose(omega.sum(), 2 * np.pi)
    bins = HemisphereBins(3, 4)
    integrals, _ = bin_integrals(order, bins)
    x, phi = np.meshgrid((np.arange(600) + 0.5) / 600, (np.arange(800) + 0.5) * np.pi / 400,
                         indexing="ij")
    cos, sin = x.ravel(), np.sqrt(1 - x.ravel() ** 2)
    weights = np.full(len(cos), (1 / 600) * (np.pi / 400))          # dω = d(cos θ) dφ
    wo = np.stack([sin * np.cos(phi.ravel()), sin * np.sin(phi.ravel()), cos], -1)
    index = bins.index(wo)
    y = sh.basis(order, cos, phi.ravel()) * weights[:, None]
    fine = np.stack([y[index == b].sum(axis=0) for b in range(bins.size)])
    assert np.abs(fine - integrals).max() < 2e-3


def test_anisotropic_table_evaluates_a_lambertian_floor() -> None:
    """A flat Lambertian tile that does not say it is isotropic is measured at φi = 0 and
    90° with absolute azimuths; between and at the incidences, eval(representation="sh")
    must equal the exact order-8 series of ρ/π cos θo (scipy quadrature) within 4 standard
    errors of the estimated series (propagated from the coefficients' errors as if
    independent) plus 1e-9."""
    from tilefixtures import height_field_tile

    recipe = resolve({"surface": {"kind": "flat"},
                      "material": {"kind": "lambertian", "albedo": 0.6},
                      "simulation": {"theta_i": [20.0, 50.0], "phi_i": [0.0, 90.0],
                                     "rays": 20_000, "seed": 5},
                      "table": {"theta_bins": 4, "phi_bins": 8, "sh_order": 8}})
    tile = height_field_tile(np.zeros((4, 4)))              # says nothing: anisotropic
    table = simulate(tile, recipe.material, recipe.simulation, recipe.table)
    assert not table.isotropic and table["total"].sh.shape == (2, 2, 81, 3)
    exact = lobe_coefficients(lambda wi, wo: np.full(len(wo), 0.6 / np.pi), np.zeros(1), 8)[0]
    rng = np.random.default_rng(1)
    wo = unit(rng.normal(size=(30, 3)) * [1, 1, 0.3] + [0, 0, 0.8])
    l, m = sh.degrees(8)
    theta, phi = np.arccos(wo[:, 2]), np.arctan2(wo[:, 1], wo[:, 0])
    y = np.stack([real_y(a, b, theta, phi) for a, b in zip(l, m, strict=True)], -1)
    for k, phi_i in ((0, 0.0), (1, np.pi / 2)):
        wi = np.array([np.sin(np.radians(20)) * np.cos(phi_i),
                       np.sin(np.radians(20)) * np.sin(phi_i), np.cos(np.radians(20))])
        got = table.eval(wi, wo, representation="sh")[:, 0]
        sigma = np.sqrt((y ** 2) @ table["total"].sh_err[0, k, :, 0] ** 2) / wo[:, 2]
        assert np.all(np.abs(got - y @ exact / wo[:, 2]) < 4 * sigma + 1e-9)


def test_black_table_reports_nan_not_a_traceback(tmp_path, cli) -> None:
    """A black Lambertian floor reflects nothing: the relative errors are undefined (null
    in JSON), the rest is 0."""
    from tilefixtures import flat_tile

    recipe = resolve({"surface": {"kind": "flat"},
                      "material": {"kind": "lambertian", "albedo": 0.0},
                      "simulation": {"theta_i": [10.0], "rays": 500},
                      "table": {"theta_bins": 4, "phi_bins": 8, "sh_order": 4}})
    write_table(simulate(flat_tile(), recipe.material, recipe.simulation,
                         recipe.table), tmp_path / "black.exr")
    code, out, err = cli("sh", str(tmp_path / "black.exr"), "--orders", "2,4", "--json")
    assert code == 0, err
    row = json.loads(out)[0]
    assert row["rel_l2_error"] is None and row["min_value"] == 0 and row["bytes"] == 108
