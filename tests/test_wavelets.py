"""Wavelets of a table's hemisphere: the equal-area square, the exact bin overlaps, the
orthonormal transform (round trip, Parseval in the weighted L2 norm, monotone error), the
comparison with the harmonics, the EXR part and ``microsim wavelets`` / ``microsim eval``."""

from __future__ import annotations

import json
import math
import re
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy import stats
from tablefixtures import changed, table_of

import microsim
from microsim.tables import compression, wavelets
from microsim.tables.binning import HemisphereBins
from microsim.tables.components import components_for
from microsim.tables.equal_area import (
    Resampling,
    overlaps,
    pixel_solid_angle,
    to_hemisphere,
    to_square,
)
from microsim.tables.evaluate import Axes
from microsim.tables.meta import TableMeta
from microsim.tables.sh import size
from microsim.tables.table import BRDFTable

SIGNIFICANCE = 1e-3
"""Chi-square tests fail below this p-value (a correct map fails one run in a thousand)."""


# --- the equal-area square ----------------------------------------------------------------
def test_the_map_is_equal_area_and_inverts() -> None:
    """The Jacobian |∂ω/∂a × ∂ω/∂b| of the composed map, by central differences (an
    independent derivative), is π/2 everywhere off the sector diagonals (1e-6 relative:
    the differences' truncation error at step 1e-6); to_square inverts it to 1e-12."""
    rng = np.random.default_rng(3)
    a, b = rng.uniform(-0.999, 0.999, (2, 2000))
    off = np.abs(np.abs(a) - np.abs(b)) > 1e-3
    a, b = a[off], b[off]
    h = 1e-6
    da = (to_hemisphere(a + h, b) - to_hemisphere(a - h, b)) / (2 * h)
    db = (to_hemisphere(a, b + h) - to_hemisphere(a, b - h)) / (2 * h)
    jacobian = np.linalg.norm(np.cross(da, db), axis=-1)
    np.testing.assert_allclose(jacobian, math.pi / 2, rtol=1e-6)
    w = to_hemisphere(a, b)
    np.testing.assert_allclose(np.linalg.norm(w, axis=-1), 1.0, atol=1e-14)
    assert (w[:, 2] >= 0).all()
    back = to_square(w)
    np.testing.assert_allclose(back[0], a, atol=1e-12)
    np.testing.assert_allclose(back[1], b, atol=1e-12)


def test_the_map_on_the_axes_the_diagonals_and_the_centre() -> None:
    """Shirley & Chiu's sectors at their seams, written out: (±½, 0) and (0, ±½) go to
    φ = 0, π, π/2, 3π/2 and (½, ½) to φ = π/4, each with z = 1 − r², sin θ = r √(2 − r²)
    (r = ½: z = ¾, sin θ = √7 / 4), and the centre to the pole, (0, 0, 1) exactly;
    without a RuntimeWarning (a division by a = 0 or 0/0 would raise one, the suite turns
    them into errors), to 1e-15."""
    s = math.sqrt(7.0) / 4.0
    a = np.array([0.5, 0.0, -0.5, 0.0, 0.5, 0.0])
    b = np.array([0.0, 0.5, 0.0, -0.5, 0.5, 0.0])
    r2 = math.sqrt(2.0) / 2.0
    want = np.array([[s, 0.0, 0.75], [0.0, s, 0.75], [-s, 0.0, 0.75], [0.0, -s, 0.75],
                     [s * r2, s * r2, 0.75], [0.0, 0.0, 1.0]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        w = to_hemisphere(a, b)
    np.testing.assert_allclose(w, want, rtol=0, atol=1e-15)
    assert np.array_equal(w[-1], [0.0, 0.0, 1.0])


def test_the_map_keeps_the_shape_and_computes_in_double_precision() -> None:
    """(2, 3) arrays of square points give (2, 3, 3) directions, those of the flattened
    points; a, b or w given as float32 (or ints) are converted first, so the result is
    that of the same values in float64 to 1e-15 (float32 arithmetic errs by ~1e-7)."""
    rng = np.random.default_rng(9)
    a, b = rng.uniform(-0.99, 0.99, (2, 2, 3))
    w = to_hemisphere(a, b)
    assert w.shape == (2, 3, 3)
    np.testing.assert_array_equal(w.reshape(-1, 3), to_hemisphere(a.ravel(), b.ravel()))
    a32, b32 = a.astype(np.float32), b.astype(np.float32)
    for x, y in ((a32, b), (a, b32)):
        np.testing.assert_allclose(to_hemisphere(x, y),
                                   to_hemisphere(x.astype(float), y.astype(float)),
                                   rtol=0, atol=1e-15)
    np.testing.assert_allclose(to_hemisphere(np.array([1, 0, -1]), np.array([0, 1, 0])),
                               [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]],
                               rtol=0, atol=1e-15)
    w32 = w.astype(np.float32)
    for got, want in zip(to_square(w32), to_square(w32.astype(float)), strict=True):
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-15)


def test_to_square_takes_phi_ref_off_and_clamps_rounded_directions() -> None:
    """A direction at azimuth φ_ref + ψ maps with ``phi_ref`` as the direction at ψ
    without it (1e-12), a scalar or one per direction; one at φ_ref itself lands on the
    +a axis at r = √(1 − z). z rounded past 1 gives the centre (0, 0) and z rounded below
    the horizon (−1e-12) the square's edge, max(|a|, |b|) = 1 exactly, both without a
    RuntimeWarning."""
    rng = np.random.default_rng(4)
    theta, psi = rng.uniform(0.1, 1.4, 50), rng.uniform(-math.pi, math.pi, 50)
    ref = rng.uniform(-math.pi, math.pi, 50)

    def direction(t, p):
        return np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1)

    for phi_ref in (ref, 0.7):
        got = to_square(direction(theta, psi + phi_ref), phi_ref)
        want = to_square(direction(theta, psi))
        np.testing.assert_allclose(got[0], want[0], rtol=0, atol=1e-12)
        np.testing.assert_allclose(got[1], want[1], rtol=0, atol=1e-12)
    a, b = to_square(direction(theta, ref), ref)
    np.testing.assert_allclose(a, np.sqrt(1.0 - np.cos(theta)), rtol=0, atol=1e-12)
    np.testing.assert_allclose(b, 0.0, rtol=0, atol=1e-12)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        a, b = to_square(np.array([[0.0, 0.0, np.nextafter(1.0, 2.0)],
                                   [0.6, 0.8, -1e-12]]))
    assert a[0] == 0.0 and b[0] == 0.0
    assert max(abs(a[1]), abs(b[1])) == 1.0


@pytest.mark.parametrize("period", [2 * math.pi, math.pi])
def test_overlaps_sum_to_the_pixels_and_the_bins_solid_angles(period: float) -> None:
    """Every pixel's overlaps add up to 2π/n², every bin's to Δcos θ Δφ (twice that when
    folded), computed here from the bin edges alone, to 1e-12. The cache is cleared first,
    so the overlaps are computed by this test, not kept from an earlier one."""
    bins = HemisphereBins(8, 12, period)
    overlaps.cache_clear()
    m = overlaps(16, 8, 12, period)
    np.testing.assert_allclose(np.asarray(m.sum(axis=1)).ravel(), pixel_solid_angle(16),
                               rtol=1e-12)
    omega = np.outer(-np.diff(np.cos(bins.theta_edges)), np.diff(bins.phi_edges)).ravel()
    np.testing.assert_allclose(np.asarray(m.sum(axis=0)).ravel(),
                               omega * (2.0 if bins.folded else 1.0), rtol=1e-12)


def test_overlaps_match_points_thrown_on_the_square() -> None:
    """400 000 uniform points on the square, mapped and binned by ``HemisphereBins.index``
    (not by the overlap code), fall in each (pixel, bin) cell in proportion to its overlap:
    Pearson chi-square over the cells expecting >= 5 points, p > SIGNIFICANCE. (The
    overlaps' cache is cleared first: they are computed here.)"""
    n, bins = 8, HemisphereBins(4, 8)
    overlaps.cache_clear()
    rng = np.random.default_rng(11)
    a, b = rng.uniform(-1, 1, (2, 400_000))
    pixel = np.minimum(((b + 1) * n / 2).astype(int), n - 1) * n + np.minimum(
        ((a + 1) * n / 2).astype(int), n - 1)
    cell = pixel * bins.size + bins.index(to_hemisphere(a, b))
    counts = np.bincount(cell, minlength=n * n * bins.size)
    expected = overlaps(n, 4, 8, 2 * math.pi).toarray().ravel() * len(a) / (2 * math.pi)
    assert counts[expected == 0].sum() == 0
    big = expected >= 5
    chi2 = float(((counts[big] - expected[big]) ** 2 / expected[big]).sum())
    assert stats.chi2.sf(chi2, big.sum() - 1) > SIGNIFICANCE, (chi2, big.sum())


# --- the transform -----------------------------------------------------------------------
def lobe_values(theta_i: list[float], bins: HemisphereBins, sharpness: float = 40.0
                ) -> np.ndarray:
    """(a, 1, nt, np, 3) f_r of a smooth lobe about the mirror direction at bin centres,
    with a different scale per colour."""
    t, p = np.meshgrid(bins.theta_centers, bins.phi_centers, indexing="ij")
    wo = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1)
    out = []
    for ti in theta_i:
        mirror = np.array([-math.sin(ti), 0.0, math.cos(ti)])
        f = 0.1 + np.exp(sharpness * (wo @ mirror - 1.0))
        out.append(f[..., None] * np.array([1.0, 0.5, 0.25]))
    return np.array(out)[:, None]


def lobe_table(theta_i: list[float], bins: HemisphereBins, sh: dict | None = None
               ) -> BRDFTable:
    """An isotropic table of ``lobe_values`` in every component."""
    a = len(theta_i)
    values = {c: lobe_values(theta_i, bins) for c in components_for(2)}
    errors = {c: np.full_like(v, 0.01) for c, v in values.items()}
    flat = {c: np.ones((a, 1, 3)) for c in values}
    return table_of(bins, np.array(theta_i), np.zeros(1), True, values, errors,
                     np.full((a, 1), 1000), flat, flat, np.zeros((a, 1, 3)), TableMeta(),
                     sh=sh, sh_err=None if sh is None else {
                         c: np.zeros_like(v) for c, v in sh.items()})


@pytest.mark.parametrize("name", ["haar", "db2", "db4"])
def test_every_coefficient_kept_gives_the_resampled_table(name: str) -> None:
    """With all n² coefficients kept, the stored set's grid equals the table resampled onto
    the square to round-off (1e-12 of its largest value)."""
    bins = HemisphereBins(8, 16)
    table = lobe_table([0.0, 0.6], bins)
    stored = wavelets.encode({c: e.values for c, e in table.estimates.items()}, bins, 32,
                             name, keep=32 * 32)
    expected = wavelets.table_grids(table["total"].values, Resampling(32, bins))
    got = stored.grids("total")
    assert np.abs(got - expected).max() <= 1e-12 * expected.max()


@pytest.mark.parametrize("name", ["haar", "db2", "sym4"])
def test_dropped_energy_is_the_error_in_the_weighted_norm(name: str) -> None:
    """Parseval on the equal-area grid: for every kept count, the squared error of the
    reconstruction in the L2(dω) norm, Σ_p Ω_p (ĝ_p − g_p)² with Ω_p each pixel's solid
    angle from the overlaps (the pixels' areas, not the transform), equals
    (2π/n²) Σ_dropped c² to 1e-9 relative (or 1e-13 of the function's energy, round-off,
once nearly all is kept); keeping the largest is no worse than keeping the coarsest;
and the error never grows with the count."""
    n, bins = 32, HemisphereBins(8, 16)
    grid = wavelets.table_grids(lobe_values([0.5], bins), Resampling(n, bins))[0, 0, 0]
    omega_p = np.asarray(overlaps(n, 8, 16, 2 * math.pi).sum(axis=1)).reshape(n, n)
    c = wavelets.forward(grid, name)
    rank = wavelets.ranks(c)
    energy = float((omega_p * grid ** 2).sum())
    errors = []
    for k in compression.sweep(n * n, 4):
        kept = compression.keep_largest(c, rank, k)
        error2 = float((omega_p * (wavelets.inverse(kept, name) - grid) ** 2).sum())
        dropped = pixel_solid_angle(n) * float(((c - kept) ** 2).sum())
        assert error2 == pytest.approx(dropped, rel=1e-9, abs=1e-13 * energy)
        # the best k-term choice in that norm: no worse than the k coarsest coefficients
        coarsest = np.where(np.arange(n * n) < k, c, 0.0)
        assert dropped <= pixel_solid_angle(n) * float(((c - coarsest) ** 2).sum()) * (
            1 + 1e-12)
        errors.append(error2)
    assert all(later <= earlier * (1 + 1e-12) for earlier, later in
               zip(errors, errors[1:], strict=False))
    assert errors[-1] < 1e-20 * errors[0]


def test_kept_for_a_target_is_the_fewest_that_reach_it() -> None:
    """``kept_for``: its count reaches the target relative L2 error, one fewer does not."""
    c = np.random.default_rng(5).normal(size=(4, 256)) * np.geomspace(1, 1e-3, 256)
    rank = wavelets.ranks(c)

    def rel(row: int, count: int) -> float:
        kept = compression.keep_largest(c[row], rank[row], count)
        return math.sqrt(((c[row] - kept) ** 2).sum() / (c[row] ** 2).sum())

    for target in (0.3, 0.05, 0.001):
        k = wavelets.kept_for(c, target)
        for row in range(4):
            assert rel(row, k[row]) <= target < rel(row, k[row] - 1)


def test_a_constant_brdf_evaluates_exactly_from_its_wavelets() -> None:
    """A Lambertian table (f_r = 0.8/π in every bin) evaluated from its wavelets with every
    coefficient kept gives 0.8/π at random direction pairs to 1e-10: the pixels' mean
    cos θ is the bins' resampled like g."""
    bins = HemisphereBins(8, 16)
    a = 2
    values = {c: np.full((a, 1, 8, 16, 3), 0.8 / math.pi) for c in components_for(2)}
    flat = {c: np.ones((a, 1, 3)) for c in values}
    table = table_of(bins, np.array([0.0, 1.0]), np.zeros(1), True, values, values,
                      np.full((a, 1), 10), flat, flat, np.zeros((a, 1, 3)), TableMeta())
    table = replace(table, wavelets=wavelets.encode(values, bins, 32, "db2", keep=1024))
    rng = np.random.default_rng(2)
    wi, wo = (to_hemisphere(*rng.uniform(-0.99, 0.99, (2, 500))) for _ in range(2))
    np.testing.assert_allclose(table.eval(wi, wo, representation="wavelet"), 0.8 / math.pi,
                               rtol=1e-10)


# --- against the harmonics ---------------------------------------------------------------
def test_exact_harmonics_have_no_error_and_the_curves_fall() -> None:
    """A table whose f_r cos θo is c₀ Y₀₀ + c₁ Y₁₀ exactly, with its bins computed here in
    closed form (∫ Y₀₀ dω = Δφ Δcos θ / √(4π), ∫ Y₁₀ dω = √(3/4π) Δφ Δcos²θ / 2): its two
    stored harmonics reproduce every lobe bin to 1e-9, both curves end below where they
    start, and the wavelets' last point (every coefficient) is their resampling floor,
    below 5 % for this slowly varying lobe."""
    bins = HemisphereBins(8, 16)
    c0, c1 = 1.0, 0.8
    x = np.cos(bins.theta_edges)
    ring = (c0 * -np.diff(x) / math.sqrt(4 * math.pi)
            + c1 * math.sqrt(3 / (4 * math.pi)) * -np.diff(x ** 2) / 2) * bins.phi_edges[1]
    f = ring / bins.projected_solid_angle[:, 0]                    # per projected sr
    values = np.broadcast_to(f[None, None, :, None, None], (1, 1, 8, 16, 3)).copy()
    coefficients = np.zeros((1, 1, size(4), 3))
    coefficients[..., 0, :], coefficients[..., 2, :] = c0, c1      # k = l² + l + m
    table = lobe_table([0.0], bins, sh={c: coefficients for c in components_for(2)})
    table = changed(table, values=lambda e: values)
    result = compression.curves(table, resolution=32, wavelet="haar")
    by_count = dict(map(tuple, result["sh"]))
    assert by_count[2] < 1e-9 and by_count[size(4)] < 1e-9
    assert by_count[1] > 0.01
    assert result["wavelet"][-1][0] == 32 * 32
    assert result["wavelet"][-1][1] < 0.05 < result["wavelet"][0][1]
    assert result["bytes"]["sh"][1] == 2 * 6 * 3                    # 2 kept, 3 colours


def test_the_lobe_error_falls_with_the_largest_kept_first() -> None:
    """The median relative error on the lobe bins is not monotone in the count (only the
    L2 error is: at a few coefficients the coarse mean can sit closer to most lobe bins
    than a partial lobe does), but with the largest coefficients kept first a smooth lobe
    (64² pixels, 16 × 32 bins) is within 5 % at 1/16 of the coefficients, where the 256
    smallest would leave almost all of it out, and at all of them the error is the
    resampling floor, below 1 %."""
    bins = HemisphereBins(16, 32)
    table = lobe_table([0.0, 0.5, 1.0], bins, sh={c: np.zeros((3, 1, size(2), 3))
                                                  for c in components_for(2)})
    curve = dict(map(tuple, compression.curves(table, resolution=64, wavelet="haar",
                                               steps_per_octave=2)["wavelet"]))
    assert curve[256] < 0.05
    assert curve[64 * 64] < 0.01


def test_needed_ignores_a_first_crossing_that_does_not_last() -> None:
    curve = [[1, 0.2], [2, 0.04], [4, 0.06], [8, 0.03], [16, 0.01]]
    assert compression.needed(curve, 0.05) == 8
    assert compression.needed(curve, 0.005) is None


def test_needed_counts_a_point_at_the_target_as_reaching_it() -> None:
    """"At or below the target": an error equal to it (here exactly 0.05) reaches it."""
    assert compression.needed([[1, 0.2], [2, 0.05], [4, 0.05]], 0.05) == 2
    assert compression.needed([[1, 0.2], [2, 0.05], [4, 0.06]], 0.05) is None


def test_sweep_is_the_rounded_powers_of_the_root_of_two_below_the_total() -> None:
    """Two steps per octave: round(2^(i/2)) (written out: 2^6.5 = 90.51 → 91, 2^9.5 =
    724.08 → 724), once each, below the total, then the total; one and two
    coefficients; four steps per octave for nine."""
    powers = [1, 2, 3, 4, 6, 8, 11, 16, 23, 32, 45, 64, 91, 128, 181, 256, 362, 512, 724]
    assert compression.sweep(1024) == powers + [1024]
    assert compression.sweep(1024, 2) == powers + [1024]
    assert compression.sweep(1000, 2) == powers + [1000]
    assert compression.sweep(9, 2) == [1, 2, 3, 4, 6, 8, 9]
    assert compression.sweep(9, 4) == [1, 2, 3, 4, 5, 6, 7, 8, 9]
    assert compression.sweep(1) == [1]
    assert compression.sweep(2) == [1, 2]


def test_median_errors_by_hand() -> None:
    """|g − g_table| / g_table over the lobe bins and channels where g_table > 0, its
    median per incidence and over all, against values chosen here: incidence 0 has the
    relative errors 0.5, 0.1, 0.25, 0.2, 0 on its five counted entries (median 0.2), a lobe
    entry with g_table = 0 (left out, though g = 5 there) and a bin outside the lobe
    (error 1, left out); incidence 1 has no lobe bin (NaN, without a warning: the
    RuntimeWarnings of an empty median are errors here); incidence 2 has 0.1, …, 0.8
    (median 0.45); pooled, the 13 counted errors have median 0.3. To 1e-12 (round-off of
    the quotients)."""
    g_table = np.zeros((3, 1, 4, 2))
    g = np.zeros((3, 1, 4, 2))
    lobe = np.zeros((3, 1, 4), bool)
    g_table[0, 0] = [[1.0, 2.0], [4.0, 0.0], [2.0, 2.0], [8.0, 8.0]]
    g[0, 0] = [[1.5, 2.2], [3.0, 5.0], [2.4, 2.0], [0.0, 0.0]]
    lobe[0, 0] = [True, True, True, False]
    g_table[1, 0], g[1, 0] = 1.0, 3.0
    g_table[2, 0] = 0.5
    g[2, 0] = 0.5 * (1.0 + np.arange(1, 9).reshape(4, 2) / 10.0)
    lobe[2, 0] = True
    per, pooled = compression.median_errors(g, g_table, lobe)
    assert per.shape == (3, 1)
    assert per[0, 0] == pytest.approx(0.2, abs=1e-12)
    assert math.isnan(per[1, 0])
    assert per[2, 0] == pytest.approx(0.45, abs=1e-12)
    assert pooled == pytest.approx(0.3, abs=1e-12)
    per, pooled = compression.median_errors(g, g_table, np.zeros_like(lobe))
    assert np.isnan(per).all() and math.isnan(pooled)


def test_curves_of_a_table_without_harmonics_are_refused() -> None:
    with pytest.raises(ValueError, match=r"^the table holds no spherical harmonics$"):
        compression.curves(lobe_table([0.0], HemisphereBins(8, 16)))


def anisotropic_lobe_table(theta_i: list[float], phi_i: list[float], bins: HemisphereBins
                           ) -> BRDFTable:
    """An anisotropic table: per incidence (θi, φi) a lobe about its mirror direction
    (``lobe_values`` turned by φi), every component alike, with nine harmonics drawn at
    random (seed 4): what is checked of it is the bookkeeping, not the harmonics' fit."""
    t, p = np.meshgrid(bins.theta_centers, bins.phi_centers, indexing="ij")
    wo = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1)
    f = np.array([[(0.1 + np.exp(40.0 * (wo @ np.array([
        -math.sin(ti) * math.cos(pi), -math.sin(ti) * math.sin(pi), math.cos(ti)]) - 1.0))
        )[..., None] * np.array([1.0, 0.5, 0.25]) for pi in phi_i] for ti in theta_i])
    a, b = len(theta_i), len(phi_i)
    rng = np.random.default_rng(4)
    sh = rng.normal(0.3, 0.1, (a, b, size(2), 3))
    values = {c: f for c in components_for(2)}
    errors = {c: np.full_like(f, 0.01) for c in values}
    flat = {c: np.ones((a, b, 3)) for c in values}
    return table_of(bins, np.array(theta_i), np.array(phi_i), False, values, errors,
                     np.full((a, b), 1000), flat, flat, np.zeros((a, b, 3)), TableMeta(),
                     sh={c: sh for c in values},
                     sh_err={c: np.zeros_like(sh) for c in values})


def test_curves_report_their_settings_sizes_and_each_incidence() -> None:
    """Two θi by two φi (an anisotropic table, so a ≠ 1 and b ≠ 1): the result names its
    component, order, wavelet, resolution and levels (log2 32 = 5 for Haar, whose filters
    have two taps), the table's own median relative error (0.01 over the lobe's mean f_r,
    computed here), each basis' total per incidence and channel (9 harmonics, 32² wavelet
    coefficients) and bytes per kept coefficient (a float32 and a 2-byte index: 6), the
    bytes of each count k over every incidence and colour (k × 6 × 3 × 2 × 2), the counts
    of the asked four steps per octave, and per incidence its angles in degrees and the
    curves of the table cut down to that incidence alone (its pooled curves are that
    incidence's own, to 1e-15)."""
    bins = HemisphereBins(8, 16)
    theta_i, phi_i = [0.2, 0.7], [0.0, 1.5]
    table = anisotropic_lobe_table(theta_i, phi_i, bins)
    result = compression.curves(table, resolution=32, wavelet="haar", steps_per_octave=4)
    assert result["component"] == "total"
    assert result["sh_order"] == 2
    assert result["wavelet_name"] == "haar"
    assert result["resolution"] == 32
    assert result["levels"] == 5
    f = table["total"].values.mean(axis=-1)
    lobe = table.lobe_mask("total")
    assert result["median_rel_stderr"] == pytest.approx(float(np.median(0.01 / f[lobe])),
                                                        rel=1e-12)
    assert result["coefficients"] == {"sh": 9, "wavelet": 1024}
    assert result["bytes_per_coefficient"] == {"sh": 6, "wavelet": 6}
    assert [k for k, _ in result["sh"]] == [1, 2, 3, 4, 5, 6, 7, 8, 9]
    assert [k for k, _ in result["wavelet"]] == compression.sweep(1024, 4)
    for name in ("sh", "wavelet"):
        assert result["bytes"][name] == [k * 6 * 3 * 2 * 2 for k, _ in result[name]]
    rows = result["per_incidence"]
    assert [(r["theta_i"], r["phi_i"]) for r in rows] == [
        (pytest.approx(math.degrees(t), abs=1e-12), pytest.approx(math.degrees(p), abs=1e-12))
        for t in theta_i for p in phi_i]
    for row, (i, j) in zip(rows, [(i, j) for i in range(2) for j in range(2)], strict=True):
        alone = anisotropic_lobe_table([theta_i[i]], [phi_i[j]], bins)
        alone = replace(alone, estimates={c: replace(e, sh=table[c].sh[i:i + 1, j:j + 1])
                                          for c, e in alone.estimates.items()})
        own = compression.curves(alone, resolution=32, wavelet="haar", steps_per_octave=4)
        for name in ("sh", "wavelet"):
            assert [k for k, _ in row[name]] == [k for k, _ in own[name]]
            np.testing.assert_allclose([e for _, e in row[name]],
                                       [e for _, e in own[name]], rtol=0, atol=1e-15)


# --- the file and the commands ------------------------------------------------------------
@pytest.fixture
def lobe_file(tmp_path: Path) -> Path:
    bins = HemisphereBins(8, 16)
    sh = {c: np.zeros((2, 1, size(3), 3)) for c in components_for(2)}
    for c in sh:
        sh[c][..., 0, :] = 1.0
    path = tmp_path / "lobe.exr"
    microsim.write_table(lobe_table([0.0, 0.6], bins, sh=sh), path)
    return path


def test_stored_wavelets_survive_the_file_and_eval_reads_them(cli, lobe_file: Path,
                                                              tmp_path: Path) -> None:
    """--store writes every component's wavelets; read back, they evaluate as the ones
    kept in memory (to float32 round-off), and eval --basis wavelet reads them."""
    out = tmp_path / "stored.exr"
    code, text, err = cli("wavelets", str(lobe_file), "--resolution", "32", "--store",
                          str(out), "--target-error", "0.001", "--json")
    assert code == 0, err
    report = json.loads(text)
    assert set(report) >= {"sh", "wavelet", "per_incidence", "bytes"}
    assert all(len(point) == 2 for point in report["sh"] + report["wavelet"])
    table = microsim.read_table(out)
    assert table.wavelets is not None and table.wavelets.target_error == 0.001
    original = microsim.read_table(lobe_file)
    memory = wavelets.encode({c: e.values for c, e in original.estimates.items()},
                             original.bins, 32, "haar", target_error=0.001)
    for c in table.components:
        np.testing.assert_allclose(table.wavelets.grids(c), memory.grids(c), rtol=1e-6,
                                   atol=1e-6 * memory.grids(c).max())
    wi = np.array([math.sin(0.3), 0.0, math.cos(0.3)])
    wo = np.array([-math.sin(0.3), 0.0, math.cos(0.3)])
    code, text, err = cli("eval", str(out), "--wi", "17.19,0", "--wo", "17.19,180",
                          "--basis", "wavelet", "--json")
    assert code == 0, err
    f = json.loads(text)["f_r"]
    # the CLI's angles are rounded to 0.01°
    np.testing.assert_allclose(f, table.eval(wi, wo, representation="wavelet"), rtol=1e-3)


@pytest.mark.parametrize("argv, message", [
    (["wavelets", "{t}", "--store", "{o}", "--target-error", "0"], "--target-error 0.0: must be > 0"),
    (["wavelets", "{t}", "--store", "{o}", "--target-error", "-0.5"], "--target-error -0.5: must be > 0"),
    (["wavelets", "{t}", "--target-error", "0.1"], "give --store EXR"),
    (["wavelets", "{t}", "--wavelet", "bior2.2"], "--wavelet 'bior2.2': not of the orthogonal families"),
    (["wavelets", "{t}", "--wavelet", "nope"], "--wavelet 'nope': not a discrete wavelet"),
    (["wavelets", "{t}", "--resolution", "100"], "--resolution 100: must be a power of two"),
    (["eval", "{t}", "--wi", "0,0", "--wo", "10,0", "--basis", "wavelet"], "--basis wavelet: "),
    (["eval", "{t}", "--wi", "0,0", "--wo", "10,0", "--basis", "haar"], "--basis"),
])
def test_bad_input_is_one_error_line(cli, lobe_file: Path, tmp_path: Path, argv: list[str],
                                     message: str) -> None:
    args = [a.format(t=lobe_file, o=tmp_path / "o.exr") for a in argv]
    code, out, err = cli(*args)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:") and message in lines[0], err
    assert not (tmp_path / "o.exr").exists()


def test_eval_without_harmonics_is_an_error(cli, tmp_path: Path) -> None:
    path = tmp_path / "plain.exr"
    microsim.write_table(lobe_table([0.0], HemisphereBins(4, 8)), path)
    code, _, err = cli("eval", str(path), "--wi", "0,0", "--wo", "10,0", "--basis", "sh")
    assert code == 2 and err.startswith("error: --basis sh:")
    code, _, err = cli("wavelets", str(path))
    assert code == 2 and "holds no spherical harmonics" in err


def test_a_damaged_wavelet_part_is_refused_by_name() -> None:
    """``from_part`` (what ``read_table`` hands the part to) names what is wrong: an index
    past n², a wavelet that is not orthogonal, levels or shape that do not match, a
    missing channel."""
    bins = HemisphereBins(4, 8)
    stored = wavelets.encode({"total": lobe_values([0.0], bins)}, bins, 8, "haar", keep=4)
    header = wavelets.part_header(stored, (1, 1))
    pixels = wavelets.part_channels(stored)
    assert wavelets.from_part(header, pixels, ("total",), (1, 1)).keep == 4
    bad_index = dict(pixels, **{"total_index.G": pixels["total_index.G"] + 64})
    cases = [
        (header, bad_index, "must be below 64"),
        (dict(header, wavelet="bior2.2"), pixels, "not of the orthogonal families"),
        (dict(header, levels=1), pixels, "levels 1"),
        (dict(header, shape=[2, 1]), pixels, "shape [2, 1]"),
        (header, {k: v for k, v in pixels.items() if k != "total.B"}, "total.R/G/B"),
    ]
    for info, data, message in cases:
        with pytest.raises(ValueError, match=re.escape(message)):
            wavelets.from_part(info, data, ("total",), (1, 1))


# --- exact outputs: counts, orders, refusals, the part and evaluation by hand -------------
def test_an_index_takes_two_bytes_up_to_65536_coefficients_then_four() -> None:
    """``index_bytes``: 2 bytes for up to 2¹⁶ = 65 536 coefficients (the default 256²
    grid), 4 from one more, and for 2¹⁷ and 512²."""
    assert wavelets.index_bytes(16) == 2
    assert wavelets.index_bytes(65_535) == 2
    assert wavelets.index_bytes(65_536) == 2
    assert wavelets.index_bytes(65_537) == 4
    assert wavelets.index_bytes(1 << 17) == 4
    assert wavelets.index_bytes(512 * 512) == 4


def test_wavelets_and_resolutions_are_refused_by_their_whole_message() -> None:
    """``wavelet_of`` gives PyWavelets' wavelet for the orthogonal families and refuses an
    unknown name, a biorthogonal wavelet and the discrete Meyer one (orthogonal, but not of
    the families named) by their whole messages; ``check_resolution`` takes the powers of
    two 4 and 1024 at its ends and refuses the others by its whole message."""
    for name in ("haar", "db2", "sym4", "coif1"):
        assert wavelets.wavelet_of(name).name == name
    unknown = ("wavelet 'nope': not a discrete wavelet PyWavelets knows; use an orthogonal "
               "one: haar, db1..db38, sym2..sym20, coif1..coif17")
    with pytest.raises(ValueError, match=f"^{re.escape(unknown)}$"):
        wavelets.wavelet_of("nope")
    for name in ("bior2.2", "dmey"):
        other = (f"wavelet {name!r}: not of the orthogonal families haar, db<N>, sym<N>, "
                 "coif<N> (a biorthogonal transform is not orthonormal)")
        with pytest.raises(ValueError, match=f"^{re.escape(other)}$"):
            wavelets.wavelet_of(name)
    for n in (4, 8, 512, 1024):
        assert wavelets.check_resolution(n) == n
    for n in (1, 2, 3, 6, 100, 1023, 2048):
        with pytest.raises(ValueError, match=f"^resolution {n}: must be a power of two "
                                             "from 4 to 1024$"):
            wavelets.check_resolution(n)


def test_ranks_are_by_magnitude_with_ties_in_index_order() -> None:
    """``ranks`` of rows with many equal magnitudes (integers −3…3, seed 6) are each index's
    place in Python's ``sorted`` by (−|c|, index), a stable order written out here."""
    c = np.random.default_rng(6).integers(-3, 4, (3, 200)).astype(float)
    got = wavelets.ranks(c)
    for row in range(3):
        order = sorted(range(200), key=lambda k: (-abs(c[row, k]), k))
        want = np.empty(200, int)
        want[order] = np.arange(200)
        np.testing.assert_array_equal(got[row], want)


def test_kept_for_counts_each_row_of_a_stack() -> None:
    """``kept_for`` along the last axis of a (2, 3, 16) stack of integer coefficients
    (seed 8; exact energies, so the comparison has no rounding) is, row by row, the fewest
    largest whose dropped energy is at most target² of the total, found here by a loop
    over the counts; a row of zeros keeps 0; a row of small coefficients (total energy
    0.328 < 1, exact binary fractions) keeps its count; a target met exactly (four equal
    coefficients, target ½: dropping one leaves a quarter of the energy) is reached."""
    c = np.random.default_rng(8).integers(-9, 10, (2, 3, 16)).astype(float)
    c[1, 2] = 0.0
    for target in (0.6, 0.3, 0.1, 0.01):
        got = wavelets.kept_for(c, target)
        assert got.shape == (2, 3) and got.dtype.kind == "i"
        for i in range(2):
            for j in range(3):
                energy = sorted((x * x for x in c[i, j]), reverse=True)
                total = sum(energy)
                want = 0 if total == 0 else next(
                    k for k in range(1, 17) if sum(energy[k:]) <= target ** 2 * total)
                assert got[i, j] == want, (target, i, j)
    assert wavelets.kept_for(np.array([0.5, -0.25, 0.125, 0.0]), 0.5) == 1
    assert wavelets.kept_for(np.array([0.5, -0.25, 0.125, 0.0]), 0.25) == 2
    assert wavelets.kept_for(np.ones(4), 0.5) == 3
    assert wavelets.kept_for(np.array([[1.0, -1.0, 1.0, 1.0], [0.0, 0.0, 0.0, 0.0]]),
                             0.5).tolist() == [3, 0]


def test_grid_bins_of_a_constant_grid_are_its_value_over_each_bins_mean_cosine() -> None:
    """A grid constant per incidence and channel reads back into the bins as that value
    over the bin's mean cos θ, ½ (sin²θ₁ − sin²θ₀) / (cos θ₀ − cos θ₁), written out from
    the bin edges, in the table's (a, b, nt, np, C) shape, to 1e-12."""
    bins = HemisphereBins(4, 8)
    grids = np.array([1.0, 2.0, 3.0])[None, None, :, None, None] * np.array(
        [1.0, 0.5])[:, None, None, None, None] * np.ones((2, 1, 3, 8, 8))
    got = wavelets.grid_bins(grids, Resampling(8, bins))
    assert got.shape == (2, 1, 4, 8, 3)
    t = bins.theta_edges
    ring = 0.5 * (np.sin(t[1:]) ** 2 - np.sin(t[:-1]) ** 2) / (np.cos(t[:-1]) - np.cos(t[1:]))
    for i in range(2):
        for k in range(3):
            want = grids[i, 0, k, 0, 0] / ring[:, None] * np.ones((4, 8))
            np.testing.assert_allclose(got[i, 0, :, :, k], want, rtol=1e-12)


def test_kept_counts_the_non_zero_values_of_each_incidence_and_channel() -> None:
    """``Wavelets.kept`` of hand-made (2, 3, 4, 2) values is, per (incidence, channel), the
    number of non-zero entries among the four columns, counted here by a loop."""
    values = np.random.default_rng(12).normal(size=(2, 3, 4, 2))
    values[np.random.default_rng(13).random((2, 3, 4, 2)) < 0.4] = 0.0
    stored = wavelets.Wavelets("haar", 4, {"total": values},
                               {"total": np.zeros(values.shape, int)}, keep=4)
    got = stored.kept("total")
    assert got.shape == (2, 3, 2)
    for i in range(2):
        for j in range(3):
            for k in range(2):
                assert got[i, j, k] == sum(values[i, j, m, k] != 0 for m in range(4))


@pytest.mark.parametrize("kwargs, message", [
    ({}, "give one of target_error and keep"),
    ({"target_error": 0.1, "keep": 3}, "give one of target_error and keep"),
    ({"target_error": 0.0}, "target error 0.0: must be > 0"),
    ({"target_error": -0.5}, "target error -0.5: must be > 0"),
    ({"target_error": math.nan}, "target error nan: must be > 0"),
    ({"keep": 0}, "keep 0: must be >= 1"),
    ({"keep": 3, "channels": ("550nm", "650nm")},
     "values['total'] have 3 channels, the names 2"),
])
def test_encode_refuses_by_the_whole_message(kwargs: dict, message: str) -> None:
    """Each refusal of ``encode``, by its whole message (the values' channel count is the
    last axis': here 3 of (1, 2, 4, 8, 3), against two names)."""
    bins = HemisphereBins(4, 8)
    values = {"total": np.ones((1, 2, 4, 8, 3))}
    with pytest.raises(ValueError, match=f"^{re.escape(message)}$"):
        wavelets.encode(values, bins, 8, "haar", **kwargs)


def reference_coefficients(grid: np.ndarray, name: str) -> np.ndarray:
    """PyWavelets' own 2-D transform of one n × n grid, its arrays laid out by
    ``coeffs_to_array`` and flattened row by row (the documented index)."""
    import pywt

    level = pywt.dwt_max_level(grid.shape[-1], pywt.Wavelet(name).dec_len)
    coeffs = pywt.wavedec2(grid, name, mode="periodization", level=level)
    return pywt.coeffs_to_array(coeffs)[0].ravel()


def test_encode_keeps_the_largest_first_with_ties_by_index_and_pads_with_zero() -> None:
    """Per incidence and channel, the kept values and indices are those of PyWavelets' own
    transform of the resampled grid sorted by (−|c|, index) in Python: for ``keep`` 1 and
    5 (the lobe at normal incidence is symmetric, so its coefficients tie in magnitude in
    groups of four and eight, and the fifth cuts one), one column and five, exactly; for a
    target error, each row's count is the fewest whose dropped energy is at most target² of
    the total (a loop over the counts), the rest of the row value 0 at index 0, in the
    documented (a, b, K, C) shape; the names of a spectral table's channels are kept."""
    bins = HemisphereBins(8, 16)
    values = lobe_values([0.0, 0.6], bins)
    grids = wavelets.table_grids(values, Resampling(8, bins))

    def by_magnitude(i: int, k: int) -> tuple[np.ndarray, list[int]]:
        c = reference_coefficients(grids[i, 0, k], "haar")
        return c, sorted(range(64), key=lambda m: (-abs(c[m]), m))

    for keep in (1, 5):
        stored = wavelets.encode({"total": values}, bins, 8, "haar", keep=keep)
        assert stored.values["total"].shape == (2, 1, keep, 3)
        assert stored.indices["total"].shape == (2, 1, keep, 3)
        assert stored.keep == keep and stored.target_error is None
        for i in range(2):
            for k in range(3):
                c, order = by_magnitude(i, k)
                assert stored.indices["total"][i, 0, :, k].tolist() == order[:keep]
                np.testing.assert_array_equal(stored.values["total"][i, 0, :, k],
                                              c[order[:keep]])
    target = 0.05
    stored = wavelets.encode({"total": values}, bins, 8, "haar", target_error=target)
    assert stored.target_error == target and stored.keep is None
    counts = {}
    for i in range(2):
        for k in range(3):
            c, order = by_magnitude(i, k)
            energy = [c[m] ** 2 for m in order]
            counts[i, k] = next(n for n in range(1, 65)
                                if sum(energy[n:]) <= target ** 2 * sum(energy))
    width = max(counts.values())
    assert len(set(counts.values())) > 1
    assert stored.values["total"].shape == (2, 1, width, 3)
    for (i, k), count in counts.items():
        c, order = by_magnitude(i, k)
        got_values = stored.values["total"][i, 0, :, k]
        got_indices = stored.indices["total"][i, 0, :, k]
        np.testing.assert_array_equal(got_values[:count], c[order[:count]])
        assert got_indices[:count].tolist() == order[:count]
        assert (got_values[count:] == 0).all() and (got_indices[count:] == 0).all()
    np.testing.assert_array_equal(stored.kept("total"),
                                  [[[counts[i, k] for k in range(3)]] for i in range(2)])
    spectral = wavelets.encode({"total": values[..., :2]}, bins, 8, "haar", keep=2,
                               channels=("550nm", "650nm"))
    assert spectral.channels == ("550nm", "650nm")


def f_r_by_hand(stored: wavelets.Wavelets, bins: HemisphereBins, theta_i: list[float],
                phi_i: list[float], isotropic: bool, wi: np.ndarray, wo: np.ndarray
                ) -> np.ndarray:
    """f_r of each pair from the ``total`` coefficients, worked out pair by pair: each
    grid by PyWavelets' own inverse of the dense coefficients, divided by the pixels' mean
    cos θ (the bins' ½ Δsin²θ / Δcos θ spread by the overlaps, over 2π/n²), read
    bilinearly between pixel centres a_j = −1 + (2j + 1)/n found by a loop (the nearest
    centre past the outer ones), at the square point of ωo turned by −φi when isotropic,
    then linear in θi (clamped) and in φi (periodic); 0 unless both z > 0."""
    import pywt

    n, name = stored.resolution, stored.wavelet
    level = pywt.dwt_max_level(n, pywt.Wavelet(name).dec_len)
    slices = pywt.coeffs_to_array(pywt.wavedec2(np.zeros((n, n)), name,
                                                mode="periodization", level=level))[1]
    values, indices = stored.values["total"], stored.indices["total"]
    a, b, kept, count = values.shape
    t = bins.theta_edges
    ring = 0.5 * (np.sin(t[1:]) ** 2 - np.sin(t[:-1]) ** 2) / (np.cos(t[:-1]) - np.cos(t[1:]))
    matrix = overlaps(n, bins.theta_bins, bins.phi_bins, bins.phi_period)
    cos = (matrix @ np.repeat(ring, bins.phi_bins)).reshape(n, n) / (2 * math.pi / n ** 2)
    f = np.zeros((a, b, n, n, count))
    for i in range(a):
        for j in range(b):
            for k in range(count):
                dense = np.zeros(n * n)
                for m in range(kept):
                    dense[indices[i, j, m, k]] += values[i, j, m, k]
                coeffs = pywt.array_to_coeffs(dense.reshape(n, n), slices,
                                              output_format="wavedec2")
                f[i, j, :, :, k] = pywt.waverec2(coeffs, name, mode="periodization") / cos
    centres = [-1.0 + (2 * j + 1) / n for j in range(n)]

    def bracket(x: float, nodes: list[float]) -> tuple[int, int, float]:
        if x <= nodes[0]:
            return 0, 0, 0.0
        if x >= nodes[-1]:
            return len(nodes) - 1, len(nodes) - 1, 0.0
        j = max(j for j in range(len(nodes) - 1) if nodes[j] <= x)
        return j, j + 1, (x - nodes[j]) / (nodes[j + 1] - nodes[j])

    out = np.zeros((len(wi), count))
    for p, (i, o) in enumerate(zip(wi, wo, strict=True)):
        if i[2] <= 0 or o[2] <= 0:
            continue
        phi = math.atan2(i[1], i[0])
        if isotropic:
            o = np.array([math.cos(phi) * o[0] + math.sin(phi) * o[1],
                          -math.sin(phi) * o[0] + math.cos(phi) * o[1], o[2]])
        x, y = (float(s[0]) for s in to_square(o[None]))
        j0, j1, wx = bracket(x, centres)
        i0, i1, wy = bracket(y, centres)
        pixel = ((1 - wy) * ((1 - wx) * f[:, :, i0, j0] + wx * f[:, :, i0, j1])
                 + wy * ((1 - wx) * f[:, :, i1, j0] + wx * f[:, :, i1, j1]))
        t0, t1, wt = bracket(math.acos(i[2]), theta_i)
        if b == 1:
            p0 = p1 = 0
            wp = 0.0
        else:
            az = phi % (2 * math.pi)
            below = [q for q in range(b) if phi_i[q] <= az]
            p0 = max(below) if below else b - 1
            p1 = (p0 + 1) % b
            span = (phi_i[p1] - phi_i[p0]) % (2 * math.pi)
            wp = ((az - phi_i[p0]) % (2 * math.pi)) / span
        out[p] = ((1 - wt) * ((1 - wp) * pixel[t0, p0] + wp * pixel[t0, p1])
                  + wt * ((1 - wp) * pixel[t1, p0] + wp * pixel[t1, p1]))
    return out


def random_pairs(count: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Pairs over the hemisphere: wi at θ up to 69° (past the last incidence, so θi is
    clamped too) and any azimuth, wo from uniform points of the whole square (so some lie
    beyond the outer pixel centres)."""
    rng = np.random.default_rng(seed)
    theta, phi = rng.uniform(0.0, 1.2, count), rng.uniform(-math.pi, math.pi, count)
    wi = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi),
                   np.cos(theta)], -1)
    return wi, to_hemisphere(*rng.uniform(-1.0, 1.0, (2, count)))


@pytest.mark.parametrize("isotropic", [True, False])
def test_evaluate_reads_the_grid_bilinearly_then_blends_the_incidences(isotropic: bool
                                                                       ) -> None:
    """``evaluate`` of a truncated set (20 of 256 coefficients per incidence and channel,
    db2 on 16² pixels, 8 × 16 bins) at 300 random pairs is ``f_r_by_hand``'s, to 1e-12 of
    the largest value (round-off of the reconstruction and of the weights): an isotropic
    table (θi 0 and 0.6, ωo's azimuth taken relative to φi) and an anisotropic one (θi 0.2
    and 0.7 by φi 0 and 1.5, absolute azimuths, periodic in φi)."""
    bins = HemisphereBins(8, 16)
    if isotropic:
        theta_i, phi_i = [0.0, 0.6], [0.0]
        values = lobe_values(theta_i, bins)
    else:
        theta_i, phi_i = [0.2, 0.7], [0.0, 1.5]
        values = anisotropic_lobe_table(theta_i, phi_i, bins)["total"].values
    stored = wavelets.encode({"total": values}, bins, 16, "db2", keep=20)
    axes = Axes(bins, np.array(theta_i), np.array(phi_i), isotropic)
    wi, wo = random_pairs(300, 21)
    got = wavelets.evaluate(axes, stored, "total", wi, wo)
    want = f_r_by_hand(stored, bins, theta_i, phi_i, isotropic, wi, wo)
    assert got.shape == (300, 3)
    assert np.abs(got - want).max() <= 1e-12 * np.abs(want).max()
    assert np.ptp(want[:, 0]) > 0.5 * np.abs(want[:, 0]).max()     # not a constant


def test_evaluate_is_zero_off_the_hemisphere_keeps_the_shape_and_works_in_double() -> None:
    """Pairs with ωi or ωo on the horizon (z = 0) or below it give exactly 0, beside a pair
    above it that does not; (2, 3, 3) directions broadcast against one give (2, 3, C), the
    values of the flattened pairs; float32 directions give the values of the same
    directions in float64, to 1e-15 (float32 arithmetic would err by ~1e-7)."""
    bins = HemisphereBins(8, 16)
    theta_i = [0.0, 0.6]
    stored = wavelets.encode({"total": lobe_values(theta_i, bins)}, bins, 16, "haar",
                             keep=30)
    axes = Axes(bins, np.array(theta_i), np.zeros(1), True)
    up = np.array([0.0, 0.6, 0.8])
    wi = np.array([[1.0, 0.0, 0.0], [0.6, 0.0, -0.8], up, up, up])
    wo = np.array([up, up, [0.0, 1.0, 0.0], [0.0, 0.6, -0.8], [0.6, 0.0, 0.8]])
    got = wavelets.evaluate(axes, stored, "total", wi, wo)
    assert (got[:4] == 0.0).all()
    assert (got[4] > 0.0).all()
    wi, wo = random_pairs(6, 5)
    got = wavelets.evaluate(axes, stored, "total", wi.reshape(2, 3, 3), wo[0])
    assert got.shape == (2, 3, 3)
    np.testing.assert_array_equal(
        got.reshape(6, 3), wavelets.evaluate(axes, stored, "total", wi,
                                             np.broadcast_to(wo[0], (6, 3))))
    wi32, wo32 = (w.astype(np.float32) for w in random_pairs(50, 6))
    np.testing.assert_allclose(
        wavelets.evaluate(axes, stored, "total", wi32, wo32),
        wavelets.evaluate(axes, stored, "total", wi32.astype(float), wo32.astype(float)),
        rtol=1e-15, atol=0)


HEADER_TEXT = {
    "function": "f_r(wi, wo) cos(theta_o) averaged over each pixel of the square",
    "map": "Shirley-Chiu concentric map of [-1, 1]^2 to the disk, then z = 1 - r^2, "
           "sin(theta) = r sqrt(2 - r^2); pixel (i, j) centred at a = -1 + (2j+1)/n "
           "(along +x), b = -1 + (2i+1)/n (along +y); each pixel 2 pi / n^2 sr",
    "azimuth": "as the table's: phi_o - phi_i when isotropic, else phi_o",
    "index": "flat (row-major) index into pywt.coeffs_to_array(pywt.wavedec2(grid, "
             "wavelet, mode, levels)) of the n x n grid",
    "rows": "i_theta_i * n_phi_i + i_phi_i",
    "columns": "kept coefficients, largest first; value 0 (index 0) pads a row",
}
"""The descriptions the ``microsim_wavelet`` attribute carries (docs/table-format.md, "The
part ``wavelet``": the function, the map, the index, the rows and the channels)."""


def test_the_part_header_is_the_documented_attribute_key_by_key() -> None:
    """``part_header`` of a spectral table's two components: the wavelet, the resolution,
    mode ``periodization``, the levels (the most with no filter longer than the data,
    ⌊log2(n / (filter length − 1))⌋: 3 for Haar on 8², 2 for db2 on 16²), the target or the
    count (the other null), the descriptions, the shape, and the channels, each
    component's values then its indices, one per channel name, as ``part_channels`` names
    them; it is JSON and reads back the same."""
    bins = HemisphereBins(4, 8)
    v = lobe_values([0.0, 0.6], bins)[..., :2]
    values = {"total": v, "specular": 0.5 * v}
    channels = ("550nm", "650nm")
    names = ["total.550nm", "total.650nm", "total_index.550nm", "total_index.650nm",
             "specular.550nm", "specular.650nm", "specular_index.550nm",
             "specular_index.650nm"]
    for resolution, name, target, keep, levels in ((8, "haar", None, 3, 3),
                                                   (16, "db2", 0.05, None, 2)):
        stored = wavelets.encode(values, bins, resolution, name, target_error=target,
                                 keep=keep, channels=channels)
        header = wavelets.part_header(stored, (2, 1))
        assert header == {"wavelet": name, "resolution": resolution,
                          "mode": "periodization", "levels": levels,
                          "target_error": target, "keep": keep, **HEADER_TEXT,
                          "shape": [2, 1], "channels": names}
        assert list(header) == ["wavelet", "resolution", "mode", "levels", "target_error",
                                "keep", "function", "map", "azimuth", "index", "rows",
                                "shape", "columns", "channels"]
        assert json.loads(json.dumps(header)) == header
        assert sorted(wavelets.part_channels(stored)) == sorted(names)


def valid_part() -> tuple[dict, dict]:
    """The header and channels of two incidences (shape (2, 1)), Haar on 8², 4 kept."""
    bins = HemisphereBins(4, 8)
    stored = wavelets.encode({"total": lobe_values([0.0, 0.6], bins)}, bins, 8, "haar",
                             keep=4)
    return wavelets.part_header(stored, (2, 1)), wavelets.part_channels(stored)


ROWS = "channels total.R/G/B: missing, or not 2 rows of one width"
TYPES = "channels total.R/G/B must be finite floats and total_index.R/G/B unsigned integers"


def _without(d: dict, key: str) -> dict:
    return {k: v for k, v in d.items() if k != key}


def _each(pixels: dict, prefix: str, change) -> dict:
    return {k: change(v) if k.startswith(prefix) else v for k, v in pixels.items()}


def _nan_at_first(v: np.ndarray) -> np.ndarray:
    v = v.copy()
    v[0, 0] = np.nan
    return v


def _index_at_first(v: np.ndarray, index: int) -> np.ndarray:
    v = v.copy()
    v[1, 2] = index
    return v


@pytest.mark.parametrize("header_change, pixels_change, message", [
    (lambda h: [h], None, "the wavelet attribute is not a JSON object"),
    (lambda h: dict(h, wavelet=3), None,
     "wavelet 3: must be the name of an orthogonal wavelet"),
    (lambda h: dict(h, resolution=8.0), None,
     "resolution 8.0: must be a power of two from 4 to 1024"),
    (lambda h: dict(h, resolution="8"), None,
     "resolution '8': must be a power of two from 4 to 1024"),
    (lambda h: dict(h, resolution=True), None,
     "resolution True: must be a power of two from 4 to 1024"),
    (lambda h: dict(h, levels=1), None,
     "mode 'periodization', levels 1: this microsim reads mode 'periodization' with 3 "
     "levels"),
    (lambda h: dict(h, mode="zero"), None,
     "mode 'zero', levels 3: this microsim reads mode 'periodization' with 3 levels"),
    (lambda h: _without(h, "shape"), None,
     "shape None: must be the table's incidences [2, 1]"),
    (None, lambda p: _without(p, "total.G"), ROWS),
    (None, lambda p: _each(p, "total.", lambda v: np.vstack([v, v[:1]])), ROWS),
    (None, lambda p: _each(p, "total.", lambda v: v[:, 0]), ROWS),
    (None, lambda p: dict(p, **{"total.B": p["total.B"][:, :3]}), ROWS),
    (None, lambda p: _each(p, "total_index.", lambda v: v.astype(np.float32)), TYPES),
    (None, lambda p: dict(p, **{"total.R": _nan_at_first(p["total.R"])}), TYPES),
    (None, lambda p: dict(p, **{"total_index.G": _index_at_first(p["total_index.G"], 64)}),
     "channel total_index: holds 64, must be below 64 (n² coefficients)"),
])
def test_a_damaged_part_is_refused_by_the_whole_message(header_change, pixels_change,
                                                        message: str) -> None:
    """Each refusal of ``from_part``, by its whole message: an attribute that is not an
    object, a wavelet name that is not a string, a resolution that is not an int (a float,
    a string, a bool), levels or mode not as written, no shape, a missing channel (the
    middle one), planes with a row too many, 1-D planes, planes of different widths,
    float indices, a NaN value, an index of n² (one past the last)."""
    header, pixels = valid_part()
    info = header if header_change is None else header_change(header)
    data = pixels if pixels_change is None else pixels_change(pixels)
    with pytest.raises(ValueError, match=f"^{re.escape(message)}$"):
        wavelets.from_part(info, data, ("total",), (2, 1))


def test_a_part_read_back_is_what_was_written() -> None:
    """A spectral table's part (two wavelengths, 2 × 2 incidences, two components, kept to
    a target) read by ``from_part`` from its JSON and its channels gives the wavelet,
    resolution, target, count and channel names written, the values rounded to float32
    and the indices as integers, each as written."""
    bins = HemisphereBins(4, 8)
    f = anisotropic_lobe_table([0.2, 0.7], [0.0, 1.5], bins)["total"].values[..., :2]
    channels = ("550nm", "650nm")
    stored = wavelets.encode({"total": f, "diffuse": 0.3 * f}, bins, 8, "haar",
                             target_error=0.1, channels=channels)
    info = json.loads(json.dumps(wavelets.part_header(stored, (2, 2))))
    back = wavelets.from_part(info, wavelets.part_channels(stored), ("total", "diffuse"),
                              (2, 2), channels)
    assert (back.wavelet, back.resolution, back.target_error, back.keep) == (
        "haar", 8, 0.1, None)
    assert back.channels == channels
    for c in ("total", "diffuse"):
        assert back.values[c].dtype == np.float64
        np.testing.assert_array_equal(back.values[c],
                                      stored.values[c].astype(np.float32).astype(float))
        assert back.indices[c].dtype.kind == "i"
        np.testing.assert_array_equal(back.indices[c], stored.indices[c])
