"""The K-correlation ("ABC") height field: its spectrum, normalisation, band-limited
roughness and input rules (microsim.surfaces.kcorrelation).

Statistical tests use fixed seeds; each threshold says why it is what it is. A z-score
|z| < 4 has a false-alarm probability of 6e-5 under the null (normal by the central limit
theorem over the seeds), so a changed seed does not make it fail, while the errors it
guards against (a power not normalised to unit mean, P for √P, a wrong difference
stencil) move z by tens.
"""

from __future__ import annotations

import math

import mpmath
import numpy as np
import pytest
from scipy import stats

from microsim.errors import InputError
from microsim.surfaces import kcorrelation as abc
from microsim.surfaces.facts import TileFacts


def reference_power(n: int, size: float, b: float, c: float) -> np.ndarray:
    """S(f) = (1 + (B f)²)^(−(C+1)/2) at f = (kx, ky) / size, each k wrapped to
    [−n/2, n/2) index by index, scaled to mean 1: written out apart from abc.power."""
    k = np.array([i if i < n - n // 2 else i - n for i in range(n)], float)
    p = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            f2 = (k[i] ** 2 + k[j] ** 2) / size**2
            p[i, j] = (1.0 + b * b * f2) ** (-(c + 1.0) / 2.0)
    return p / p.mean()


# --- the continuum formulas of the module docstring, by quadrature --------------------
@pytest.fixture(autouse=True)
def thirty_digits():
    """mpmath's quadrature at 30 digits, restored after each test."""
    with mpmath.workdps(30):
        yield


@pytest.mark.parametrize("c", [1.3, 2.0, 3.5, 8.0])
def test_continuum_variance_is_2_pi_a_over_b2_c_minus_1(c):
    """∫ S(f) 2πf df = 2πA / (B²(C − 1)); mpmath's quadrature to 1e-12 (it reaches
    ~1e-15; a wrong power of B or C would be off by O(1)). Beyond the knee the integrand
    falls only as f^−C, so that part is integrated over u = ln f, where it decays
    exponentially."""
    a, b = 0.7, 0.13

    def density(f):
        return a * (1 + (b * f) ** 2) ** (-(c + 1) / 2) * 2 * mpmath.pi * f

    numeric = (mpmath.quad(density, [0, 1 / b])
               + mpmath.quad(lambda u: density(mpmath.exp(u)) * mpmath.exp(u),
                             [-mpmath.log(b), mpmath.inf]))
    assert float(numeric) == pytest.approx(2 * math.pi * a / (b * b * (c - 1)), rel=1e-12)


@pytest.mark.parametrize("c", [3.5, 5.0, 8.0])
def test_continuum_slopes_give_the_continuum_alpha(c):
    """Slope variance per axis ½ ∫ (2πf)² S 2πf df = 8π³A / (B⁴(C − 1)(C − 3)), and
    α/σ = √(2 · slopes / σ²) = continuum_alpha_per_sigma; quadrature to 1e-10."""
    a, b = 1.3, 0.05

    def s(f):
        return a * (1 + (b * f) ** 2) ** (-(c + 1) / 2)

    var = mpmath.quad(lambda f: s(f) * 2 * mpmath.pi * f, [0, 1 / b, mpmath.inf])
    slopes = mpmath.quad(lambda f: 0.5 * (2 * mpmath.pi * f) ** 2 * s(f) * 2 * mpmath.pi * f,
                         [0, 1 / b, mpmath.inf])
    assert float(slopes) == pytest.approx(8 * math.pi**3 * a / (b**4 * (c - 1) * (c - 3)),
                                          rel=1e-10)
    assert abc.continuum_alpha_per_sigma(b, c) == pytest.approx(
        math.sqrt(2 * float(slopes / var)), rel=1e-10)
    assert abc.continuum_alpha_per_sigma(b, 3.0) == math.inf


@pytest.mark.parametrize("c", [1.5, 2.5, 6.0])
def test_profile_spectrum_falls_with_exponent_c(c):
    """A profile's spectrum ∫ S(√(fx² + fy²)) dfy is ∝ (1 + (B fx)²)^(−C/2): C is the
    profile's power law (the ABC parameterisation), the 2-D form has (C + 1)/2; the
    ratio is the same at every fx to 1e-10."""
    b = 0.2
    ratios = []
    for fx in (0.0, 1.0, 7.0, 40.0):
        line = mpmath.quad(lambda fy, fx=fx: (1 + b * b * (fx * fx + fy * fy))
                           ** (-(c + 1) / 2), [-mpmath.inf, 0, mpmath.inf])
        ratios.append(float(line / (1 + (b * fx) ** 2) ** (-c / 2)))
    assert np.allclose(ratios, ratios[0], rtol=1e-10, atol=0)


# --- the discrete spectrum and its normalisation -------------------------------------
@pytest.mark.parametrize("n", [16, 15])
def test_power_is_the_sampled_spectrum_with_unit_mean(n):
    """On even and odd grids, kept read-only and reused."""
    p = abc.power(n, 2.0, 0.3, 2.2)
    assert np.allclose(p, reference_power(n, 2.0, 0.3, 2.2), rtol=1e-13, atol=0)
    assert p.mean() == pytest.approx(1.0, rel=1e-14)
    assert not p.flags.writeable and abc.power(n, 2.0, 0.3, 2.2) is p
    with pytest.raises(ValueError):
        p[0, 0] = 1.0


def test_heights_are_the_direct_synthesis():
    n, size, sigma, b, c = 32, 1.0, 0.02, 0.1, 1.8
    noise = np.random.default_rng(5).standard_normal((n, n))
    expected = sigma * np.fft.ifft2(np.fft.fft2(noise)
                                    * np.sqrt(reference_power(n, size, b, c))).real
    h = abc.heights(n, size, sigma, b, c, np.random.default_rng(5))
    assert h.shape == (n, n)
    assert np.allclose(h, expected, rtol=0, atol=1e-14 * sigma)


@pytest.mark.parametrize("c", [1.2, 2.0, 6.0])
def test_height_variance_is_sigma_squared(c):
    """Over 200 seeds of a 64² grid (B = 8 cells): the grid mean of h² has expectation σ²
    exactly (Var h = mean(P) = 1), and the sample variance about the grid mean
    σ²(1 − P₀/N) (the mean height has variance σ² P₀/N; here P₀/N ≈ 2e-4, below what 200
    seeds resolve, so it is written for exactness); z-tests at |z| < 4 against the
    standard error over seeds (0.2–0.7% of σ², so a normalisation error of 3% fails)."""
    n, size, sigma, seeds = 64, 1.0, 0.3, 200
    b = 8 * size / n
    squares, variances = [], []
    for seed in range(seeds):
        h = abc.heights(n, size, sigma, b, c, np.random.default_rng(seed))
        squares.append(np.mean(h**2))
        variances.append(h.var())
    p0 = abc.power(n, size, b, c)[0, 0]
    for sample, expected in ((squares, sigma**2), (variances, sigma**2 * (1 - p0 / n**2))):
        sample = np.asarray(sample)
        z = (sample.mean() - expected) / (sample.std(ddof=1) / math.sqrt(seeds))
        assert abs(z) < 4, (c, z)


def test_periodogram_matches_the_power():
    """|F h|² / (N σ²) has mean P_k; divided by the reference P it is Exp(1) at each
    frequency (one of each ±k pair; the 4 self-conjugate ones left out). Summed over the
    64 seeds and the frequencies of a radial shell of one cell's width it is Gamma(m, 1),
    so every shell's z = (sum − m)/√m satisfies |z| < 4 (33 shells: family-wise false
    alarm 2e-3), and the shells' Σ z² passes a chi-square test with p > 1e-3 (a shape
    error of a few percent in any shell fails it)."""
    n, size, sigma, b, c, seeds = 48, 1.0, 0.01, 6 / 48, 2.0, 64
    ref = reference_power(n, size, b, c)
    ratio = np.zeros((n, n))
    for seed in range(seeds):
        h = abc.heights(n, size, sigma, b, c, np.random.default_rng(seed))
        ratio += np.abs(np.fft.fft2(h)) ** 2 / (n * n * sigma**2) / ref
    k = np.fft.fftfreq(n) * n
    kx, ky = np.meshgrid(k, k, indexing="ij")
    half = (kx > 0) | ((kx == 0) & (ky > 0)) | ((kx == -n / 2) & (ky > 0))
    half &= ~((np.abs(kx) == n / 2) & ((ky == 0) | (np.abs(ky) == n / 2)))
    half &= ~((kx == 0) & (np.abs(ky) == n / 2))
    shell = np.floor(np.hypot(kx, ky)).astype(int)
    zs = []
    for r in np.unique(shell[half]):
        members = half & (shell == r)
        m = seeds * members.sum()
        zs.append((ratio[members].sum() - m) / math.sqrt(m))
    zs = np.asarray(zs)
    assert np.all(np.abs(zs) < 4), zs
    assert stats.chi2.sf(np.sum(zs**2), len(zs)) > 1e-3


# --- the roughness of the grid --------------------------------------------------------
def test_realised_alpha_is_the_forward_difference_mean():
    """Tile.realised_alpha of one tile is √(2 mean (Δh)²/δ²) along each axis, δ the grid
    step: the two triangles per cell carry forward differences at equal projected areas
    (to round-off, 1e-12)."""
    n, size = 32, 1.0
    tile = abc.abc_tile(n, size, 0.3, 4 * size / n, 2.0, seed=3)
    h = tile.vertices[:, 2].reshape(n + 1, n + 1)[:n, :n]
    delta = size / n
    ax = math.sqrt(2 * np.mean((np.roll(h, -1, 0) - h) ** 2) / delta**2)
    ay = math.sqrt(2 * np.mean((np.roll(h, -1, 1) - h) ** 2) / delta**2)
    assert tile.realised_alpha() == pytest.approx((ax, ay), rel=1e-12)


@pytest.mark.parametrize(("n", "b", "c"), [(16, 0.2, 2.0), (15, 0.1, 1.5), (24, 0.25, 7.0)])
def test_alpha_per_sigma_against_the_filter_kernel(n, b, c):
    """An independent route: h = g ⊛ w with the real kernel g = F⁻¹(√P), so
    Var(h_{i+1,j} − h_{i,j}) = Σ_ij (g_{i+1,j} − g_{i,j})², summed here cell by cell in
    real space (to 1e-10: round-off of the inverse FFT)."""
    size = 1.0
    g = np.fft.ifft2(np.sqrt(reference_power(n, size, b, c))).real
    sx = sy = 0.0
    for i in range(n):
        for j in range(n):
            sx += (g[(i + 1) % n, j] - g[i, j]) ** 2
            sy += (g[i, (j + 1) % n] - g[i, j]) ** 2
    delta = size / n
    expected = math.sqrt((2 * sx / delta**2 + 2 * sy / delta**2) / 2)
    assert abc.alpha_per_sigma(n, size, b, c) == pytest.approx(expected, rel=1e-10)
    assert sx == pytest.approx(sy, rel=1e-10)  # isotropic: both axes alike


@pytest.mark.parametrize("c", [1.5, 2.5, 6.0])
def test_realised_alpha_squared_has_the_target_as_mean(c):
    """Over 160 tiles of 32² (B = 4 cells, target 0.3), the mean of α_realised² along each
    axis and the facts' α_realised² equal α_target²: z-tests at |z| < 4 on the standard
    error over the tiles (0.4–0.5% of α², so a σ off by 1.5% fails)."""
    n, size, alpha, seeds = 32, 1.0, 0.3, 160
    b = 4 * size / n
    rx, ry, facts = [], [], []
    for seed in range(seeds):
        tile = abc.abc_tile(n, size, alpha, b, c, seed)
        x, y = tile.realised_alpha()
        rx.append(x * x)
        ry.append(y * y)
        facts.append(float(tile.facts.alpha_realised) ** 2)
    for sample in (rx, ry, facts):
        sample = np.asarray(sample)
        z = (sample.mean() - alpha**2) / (sample.std(ddof=1) / math.sqrt(seeds))
        assert abs(z) < 4, (c, z)


def test_roughness_per_sigma_grows_with_the_band_below_c_3_and_converges_above():
    """At fixed size and B (1/16 of the tile), doubling the resolution from 64² to 512²
    raises α/σ by over 30% per doubling for C ≤ 2.5 (the continuum slopes diverge; the
    asymptote is 2^((3 − C)/2) per doubling), logarithmically at C = 3 (over 15%), while
    at C = 8 the last doubling adds under 0.5% and 512² lies within 0.2% of the continuum
    2√2π / (B √(C − 3)). Deterministic: the margins are orders above round-off."""
    size, b = 1.0, 1 / 16
    grids = (64, 128, 256, 512)
    for c, low in ((1.5, 1.3), (2.0, 1.3), (2.5, 1.3), (3.0, 1.15)):
        values = [abc.alpha_per_sigma(n, size, b, c) for n in grids]
        growth = np.array(values[1:]) / values[:-1]
        assert np.all(growth > low), (c, growth)
    values = [abc.alpha_per_sigma(n, size, b, 8.0) for n in grids]
    growth = np.array(values[1:]) / values[:-1]
    assert np.all(np.diff(growth) < 0) and 1 < growth[-1] < 1.005
    assert values[-1] == pytest.approx(abc.continuum_alpha_per_sigma(b, 8.0), rel=2e-3)


# --- the tile and its facts -----------------------------------------------------------
def test_tile_is_seeded_periodic_and_reports_its_facts():
    n, size, alpha, b, c = 32, 2.0, 0.2, 0.25, 2.0
    tile = abc.abc_tile(n, size, alpha, b, c, seed=7)
    again = abc.abc_tile(n, size, alpha, b, c, seed=7)
    assert np.array_equal(tile.vertices, again.vertices) and tile.faces is again.faces
    assert len(tile.vertices) == (n + 1) ** 2 and len(tile.faces) == 2 * n * n
    assert tile.parts == ("base",) and tile.period == (size, size)
    z = tile.vertices[:, 2].reshape(n + 1, n + 1)
    assert np.array_equal(z[0], z[n]) and np.array_equal(z[:, 0], z[:, n])
    facts = tile.facts
    assert isinstance(facts, abc.ABCFacts) and facts.kind == "abc" and facts.isotropic
    assert facts.sigma == pytest.approx(alpha / abc.alpha_per_sigma(n, size, b, c))
    assert (facts.correlation_length, facts.exponent) == (b, c)
    assert facts.alpha_target.alpha == alpha
    rx, ry = tile.realised_alpha()
    assert facts.alpha_realised.alpha == pytest.approx(math.sqrt((rx**2 + ry**2) / 2))
    data = facts.to_json()
    assert {"kind", "sigma", "correlation_length", "exponent", "alpha_target",
            "alpha_realised"} <= set(data)


def test_facts_read_back_as_abc_facts():
    facts = abc.abc_tile(16, 1.0, 0.2, 0.25, 2.0, seed=1).facts
    assert TileFacts.from_json(facts.to_json()) == facts


# --- input rules ------------------------------------------------------------------------
@pytest.mark.parametrize(("args", "message"), [
    ((256, 1.0, 0.3, 0.03, 1.0), "surface.exponent = 1.0: must be in (1, 10] (at or below 1 the height variance is the grid's, not the surface's; above 10 use kind gaussian)"),
    ((256, 1.0, 0.3, 0.03, 10.5), "surface.exponent = 10.5: must be in (1, 10]"),
    ((256, 1.0, 0.3, 0.03, math.nan), "surface.exponent = nan: must be in (1, 10]"),
    ((256, 1.0, 0.3, 0.002, 2.0), "surface.correlation_length = 0.002: gives a correlation length of 0.002, which must lie between one grid cell (0.00391) and the tile (1)"),
    ((256, 1.0, 0.3, 1.5, 2.0), "surface.correlation_length = 1.5: gives a correlation length of 1.5, which must lie between one grid cell (0.00391) and the tile (1)"),
    ((256, 1.0, 0.0, 0.03, 2.0), "surface.alpha = 0.0: must be in [0.001, 10]"),
])
def test_bad_inputs_are_refused_in_one_line(args, message):
    with pytest.raises(InputError) as error:
        abc.check(*args)
    assert str(error.value).startswith(message) and "\n" not in str(error.value)
    with pytest.raises(InputError):
        abc.abc_tile(*args, seed=0)


def test_the_limits_themselves_are_allowed():
    for args in ((256, 1.0, 0.3, 1 / 256, 1.0001), (256, 1.0, 10.0, 1.0, 10.0),
                 (256, 1.0, 0.001, 0.5, 3.0)):
        abc.check(*args)


def test_the_facets_roughness_along_the_diagonals_is_reported_and_warned_of():
    """A triangle's slope along x = y is the cell's diagonal difference (checked against
    the heights) and across it the rest, so α_45² + α_135² = α_x² + α_y² exactly (the mean square slope summed over any
    two orthogonal axes is the same; to 1e-12, round-off). Rough at the grid's scale
    (C = 2, B = 8 cells) the two differ by 35% and the tile warns; smooth over a cell
    (C = 10, B = 12 cells: 1.4% for this seed, a few percent between seeds) it does not
    (``DIAGONAL_SPREAD`` 10%)."""
    rough = abc.abc_tile(128, 1.0, 0.2, 8 / 128, 2.0, seed=4)
    f = rough.facts
    rx, ry = rough.realised_alpha()
    # both triangles of a cell rise h[i+1, j+1] − h[i, j] over the diagonal's √2 δ:
    # α_45² = 2 · mean slope² = mean (h[i+1, j+1] − h[i, j])² / δ², written out here
    z = rough.vertices[:, 2].reshape(129, 129)
    diagonal = np.mean((z[1:, 1:] - z[:-1, :-1]) ** 2) / (1 / 128) ** 2
    assert f.alpha_realised_45 == pytest.approx(math.sqrt(diagonal), rel=1e-12)
    assert f.alpha_realised_45**2 + f.alpha_realised_135**2 == pytest.approx(
        rx**2 + ry**2, rel=1e-12)
    assert f.alpha_realised_135 > (1 + 2 * abc.DIAGONAL_SPREAD) * f.alpha_realised_45
    assert any("cell diagonals" in w for w in rough.warnings)
    smooth = abc.abc_tile(256, 1.0, 0.2, 12 / 256, 10.0, seed=4)
    s45, s135 = smooth.facts.alpha_realised_45, smooth.facts.alpha_realised_135
    assert abs(s135 - s45) < abc.DIAGONAL_SPREAD * s45 and not smooth.warnings


def test_a_default_correlation_length_out_of_range_names_the_resolution():
    """The default B is 8 grid cells, so on a 4² grid it is twice the tile: the error names
    ``resolution``, the key the user gave, not ``correlation_length``, which they did not."""
    from microsim.recipe import resolve

    with pytest.raises(InputError) as error:
        resolve({"surface": {"kind": "abc", "alpha": 0.2, "resolution": 4}})
    assert str(error.value).startswith("surface.resolution = 4: gives a correlation length")
