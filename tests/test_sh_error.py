"""How much a truncated harmonic lobe loses against the binned table
(microsim/tables/sh_error.py): ``order_errors`` against its definitions written out here —
bin integrals by Gauss-Legendre in θ and φ with scipy's harmonics, the relative L2 errors,
noise floors and sizes by their formulas, the most negative value at the documented
sample points — on tables whose g = f_r cos θo is or is not the stored series."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import sph_harm_y
from tablefixtures import changed, table_of

from microsim.spectra.channels import Channels
from microsim.tables import sh
from microsim.tables.binning import HemisphereBins
from microsim.tables.components import components_for
from microsim.tables.meta import TableMeta
from microsim.tables.sh_error import order_errors
from microsim.tables.table import BRDFTable


def exact_ring_table(bins: HemisphereBins, c0: float, c1: float) -> BRDFTable:
    """An isotropic table (θi = 0) whose g = f_r cos θo is c₀ Y₀₀ + c₁ Y₁₀ exactly: each
    bin holds its projected-solid-angle average of f_r, ∫_bin g dω / Ω_proj with ∫ Y₀₀ dω =
    Δφ Δcos θ / √(4π) and ∫ Y₁₀ dω = √(3/4π) Δφ Δcos²θ / 2 (a folded bin and its mirror
    image have the same average, so one side is integrated); the two harmonics are stored
    (order 2, the rest 0)."""
    x = np.cos(bins.theta_edges)
    dphi = bins.phi_edges[1] - bins.phi_edges[0]
    ring = (c0 * -np.diff(x) / math.sqrt(4 * math.pi)
            + c1 * math.sqrt(3 / (4 * math.pi)) * -np.diff(x ** 2) / 2) * dphi
    f = ring / bins.projected_solid_angle[:, 0]
    values = np.broadcast_to(f[None, None, :, None, None],
                             (1, 1) + bins.shape + (3,)).copy()
    coefficients = np.zeros((1, 1, sh.size(2), 3))
    coefficients[..., 0, :], coefficients[..., 2, :] = c0, c1      # k = l² + l + m
    comps = components_for(2)
    flat = {c: np.ones((1, 1, 3)) for c in comps}
    return table_of(bins, np.zeros(1), np.zeros(1), True, dict.fromkeys(comps, values),
                     {c: 0.01 * values for c in comps}, np.full((1, 1), 1000), flat, flat,
                     np.zeros((1, 1, 3)), TableMeta(), sh=dict.fromkeys(comps, coefficients),
                     sh_err={c: np.zeros_like(coefficients) for c in comps})


@pytest.mark.parametrize("period", [2 * np.pi, np.pi], ids=["full", "folded"])
def test_exact_harmonics_match_their_bins_folded_or_not(period: float) -> None:
    """Harmonics that are the table's g exactly have no error from order 1 on (1e-12:
    round-off of the 8-node Gauss-Legendre rings, exact for these polynomials in cos θ),
    whether the azimuths span 2π or are folded to π; order 0 misses the c₁ Y₁₀ part."""
    rows = order_errors(exact_ring_table(HemisphereBins(8, 16, period), 1.0, 0.8), [0, 1, 2])
    assert rows[0]["rel_l2_error"] > 0.1
    for row in rows[1:]:
        assert row["rel_l2_error"] < 1e-12, (row["order"], row["rel_l2_error"])
        assert row["rel_l2_error_lobe"] < 1e-12, (row["order"], row["rel_l2_error_lobe"])


def real_y(l: int, m: int, theta: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Real harmonic from scipy's complex ``sph_harm_y`` (Condon-Shortley phase), the
    basis of ``microsim.tables.sh`` (tests/test_sh.py checks the two agree)."""
    y = sph_harm_y(l, abs(m), theta, phi)
    return y.real if m == 0 else math.sqrt(2.0) * (y.real if m > 0 else y.imag)


def basis_at(order: int, theta: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """(P, (L + 1)²) scipy harmonics at the points, index k = l² + l + m."""
    return np.stack([real_y(l, m, theta, phi) for l in range(order + 1)
                     for m in range(-l, l + 1)], -1)


def reference_bin_integrals(order: int, bins: HemisphereBins
                            ) -> tuple[np.ndarray, np.ndarray]:
    """∫_bin Y_k dω and Ω_bin by a 16 × 16-node Gauss-Legendre rule in θ and φ per bin
    (dω = sin θ dθ dφ: Y_k sin θ is smooth in θ, pole included, and a trigonometric
    polynomial in φ, so the rule is exact to round-off for these low orders), a folded
    bin over its mirror image [−φ₁, −φ₀] as well."""
    t, wt = np.polynomial.legendre.leggauss(16)
    rows, omegas = [], []
    for it in range(bins.theta_bins):
        t0, t1 = bins.theta_edges[it], bins.theta_edges[it + 1]
        theta = 0.5 * (t1 - t0) * t + 0.5 * (t1 + t0)
        w_theta = 0.5 * (t1 - t0) * wt * np.sin(theta)
        for ip in range(bins.phi_bins):
            p0, p1 = bins.phi_edges[ip], bins.phi_edges[ip + 1]
            ranges = [(p0, p1), (-p1, -p0)] if bins.folded else [(p0, p1)]
            row, omega = 0.0, 0.0
            for a, b in ranges:
                phi = 0.5 * (b - a) * t + 0.5 * (b + a)
                w_phi = 0.5 * (b - a) * wt
                tt, pp = np.meshgrid(theta, phi, indexing="ij")
                w = np.outer(w_theta, w_phi).ravel()
                row = row + w @ basis_at(order, tt.ravel(), pp.ravel())
                omega += w.sum()
            rows.append(row)
            omegas.append(omega)
    return np.array(rows), np.array(omegas)


def hanning(order: int) -> np.ndarray:
    """½ (1 + cos(π l / (L + 1))) per coefficient (sh.window's docstring)."""
    return np.array([0.5 * (1.0 + math.cos(math.pi * l / (order + 1)))
                     for l in range(order + 1) for _ in range(2 * l + 1)])


def reference_rows(table: BRDFTable, orders: list[int], window: str) -> list[dict]:
    """``order_errors`` by its definitions (module docstring and its Returns), written
    out: G_table = f̄ Ω_proj / Ω (Ω_proj = ½ Δsin²θ Δφ, doubled with Ω when folded),
    G_sh = Σ_k w_l c_k ∫_bin Y_k dω / Ω, ‖G‖² = Σ Ω G², the noise floors from the
    standard errors, the most negative value of the windowed series at the 2 × 2 points
    per bin u = (i + ½) / (2 nt), φ = (j + ½) period / (2 np) (cos θ = √(1 − u)), and
    the float32 size."""
    bins = table.bins
    a, b = table.rays.shape
    count = table.channels.count
    mirror = 2.0 if bins.folded else 1.0
    sin2 = np.sin(bins.theta_edges) ** 2
    omega_proj = mirror * 0.5 * np.outer(np.diff(sin2), np.diff(bins.phi_edges)).ravel()
    integrals, omega = reference_bin_integrals(max(orders), bins)
    scale = (omega_proj / omega)[None, None, :, None]
    g_table = table["total"].values.reshape(a, b, -1, count) * scale
    e_table = np.nan_to_num(table["total"].errors.reshape(a, b, -1, count)) * scale
    lobe = table.lobe_mask("total").reshape(a, b, -1)
    w = omega[None, None, :, None]
    u = (np.arange(2 * bins.theta_bins) + 0.5) / (2 * bins.theta_bins)
    phi = (np.arange(2 * bins.phi_bins) + 0.5) * bins.phi_period / (2 * bins.phi_bins)
    uu, pp = np.meshgrid(u, phi, indexing="ij")
    y_points = basis_at(max(orders), np.arccos(np.sqrt(1.0 - uu.ravel())), pp.ravel())

    def rel(g, sel, channel=None):
        d2, g2 = w * (g - g_table) ** 2, w * g_table ** 2
        keep = np.broadcast_to(sel[..., None], g.shape).copy()
        if channel is not None:
            keep[..., [c for c in range(count) if c != channel]] = False
        num, den = d2[keep].sum(), g2[keep].sum()
        return math.sqrt(num / den) if den > 0 else math.nan

    everywhere = np.ones(lobe.shape, bool)
    norm = float((w * g_table ** 2).sum())
    rows = []
    for order in orders:
        n = (order + 1) ** 2
        factors = hanning(order) if window == "hanning" else np.ones(n)
        c = table["total"].sh[..., :n, :]
        sigma = table["total"].sh_err[..., :n, :]
        g_win = np.einsum("jk,abkc->abjc", integrals[:, :n] * factors, c) / omega[:, None]
        g_plain = np.einsum("jk,abkc->abjc", integrals[:, :n], c) / omega[:, None]
        values = np.einsum("pk,abkc->abpc", y_points[:, :n] * factors, c)
        low, high = float(values.min()), float(values.max())
        row = {"order": order, "window": window, "coefficients": n,
               "rel_l2_error": rel(g_win, everywhere),
               "rel_l2_error_lobe": rel(g_win, lobe),
               "rel_l2_error_unwindowed": rel(g_plain, everywhere),
               "rel_l2_error_lobe_unwindowed": rel(g_plain, lobe),
               "table_noise": math.sqrt(float((w * e_table ** 2).sum()) / norm),
               "sh_noise": math.sqrt(float(((sigma * factors[:, None]) ** 2).sum()) / norm),
               "min_value": min(low, 0.0),
               "min_relative": min(low, 0.0) / high,
               "bytes": n * a * b * count * 4}
        if table.channels.spectral:
            row["channels"] = list(table.channels.names)
            row["rel_l2_error_per_channel"] = [rel(g_win, everywhere, k)
                                               for k in range(count)]
            row["rel_l2_error_lobe_per_channel"] = [rel(g_win, lobe, k)
                                                    for k in range(count)]
        rows.append(row)
    return rows


def lobe_table(bins: HemisphereBins, theta_i: list[float], phi_i: list[float],
               isotropic: bool, channels: Channels, seed: int) -> BRDFTable:
    """A table of a lobe about each incidence's mirror direction over a floor (f_r ≈
    0.02 to 0.3 per sr, so ‖G‖² < 1), per channel scaled by 1, 0.6, 0.3, …, errors 5 %,
    10 %, … of the values, and order-2 harmonics and standard errors drawn at random: they
    are not the table's, so every error is well away from 0."""
    t, p = np.meshgrid(bins.theta_centers, bins.phi_centers, indexing="ij")
    wo = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1)
    count = channels.count
    tint = np.linspace(1.0, 0.3, count)
    f = np.array([[(0.02 + 0.3 * np.exp(6.0 * (wo @ np.array(
        [-math.sin(ti) * math.cos(pi), -math.sin(ti) * math.sin(pi), math.cos(ti)]) - 1.0))
        )[..., None] * tint for pi in phi_i] for ti in theta_i])
    a, b = len(theta_i), len(phi_i)
    rng = np.random.default_rng(seed)
    c = rng.normal(0.0, 0.08, (a, b, sh.size(2), count))
    c[..., 0, :] += 0.25
    errors = f * 0.05 * np.arange(1, count + 1)
    comps = components_for(2)
    flat = {k: np.ones((a, b, count)) for k in comps}
    return table_of(bins, np.array(theta_i), np.array(phi_i), isotropic,
                     dict.fromkeys(comps, f), dict.fromkeys(comps, errors),
                     np.full((a, b), 1000), flat, flat, np.zeros((a, b, count)), TableMeta(),
                     sh=dict.fromkeys(comps, c),
                     sh_err=dict.fromkeys(comps, rng.uniform(0.001, 0.01, c.shape)),
                     channels=channels)


def assert_rows_match(got: list[dict], want: list[dict]) -> None:
    """The same keys; the relative L2 errors within 5e-5 relative, the other numbers
    within 1e-10 (sums of a few hundred terms, measured 3e-16). The errors go through the
    bin integrals, where ``bin_integrals``' 8-node Gauss-Legendre rule in cos θ is exact
    for every ring but the pole's m = ±1 harmonics (sin θ = √(1 − x²) is not a
    polynomial in x, with an infinite slope at x = 1): measured 9e-6 there against the
    reference's rule in θ, 1.1e-5 in the errors."""
    assert len(got) == len(want)
    for g, w in zip(got, want, strict=True):
        assert set(g) == set(w), sorted(set(g) ^ set(w))
        for key, value in w.items():
            if isinstance(value, str) or key in ("channels", "order", "coefficients",
                                                 "bytes"):
                assert g[key] == value, key
            else:
                rtol = 5e-5 if key.startswith("rel_l2_error") else 1e-10
                np.testing.assert_allclose(g[key], value, rtol=rtol, atol=1e-14,
                                           err_msg=f"order {w['order']}: {key}")


@pytest.mark.parametrize("window", ["none", "hanning"])
def test_spectral_anisotropic_rows_are_their_definitions(window: str) -> None:
    """Two θi by two φi (anisotropic, so a ≠ 1 and b ≠ 1), three wavelengths: every field
    of every order 0, 1, 2, with and without the window, per channel too, against
    ``reference_rows``. The lobe is a strict part of the bins (so the lobe errors are not
    the hemisphere's), and the series dips below 0 (so min_value is a value)."""
    table = lobe_table(HemisphereBins(4, 8), [0.3, 0.8], [0.0, 1.2], False,
                       Channels((450.0, 550.0, 650.0)), seed=6)
    lobe = table.lobe_mask("total")
    assert 0 < lobe.sum() < lobe.size
    want = reference_rows(table, [0, 1, 2], window)
    assert want[-1]["min_value"] < 0
    assert_rows_match(order_errors(table, [0, 1, 2], window), want)
    assert want[0]["channels"] == ["450nm", "550nm", "650nm"]


def test_folded_rgb_rows_are_their_definitions() -> None:
    """An isotropic RGB table folded to φ ∈ [0, π]: the fields of orders 1 and 2 against
    ``reference_rows`` (its sample points at φ = (j + ½) π / 12, which a shift by a whole
    step would move off the half-plane), and no per-channel fields."""
    table = lobe_table(HemisphereBins(4, 6, np.pi), [0.4], [0.0], True, Channels(),
                       seed=8)
    got = order_errors(table, [1, 2])
    assert_rows_match(got, reference_rows(table, [1, 2], "none"))
    assert "rel_l2_error_per_channel" not in got[0] and "channels" not in got[0]


def test_min_value_is_sought_at_every_sample_point() -> None:
    """g = Y₀₀ + 0.1 Y₁₋₁ − 0.9 Y₁₀ + 0.3 Y₁₁ on 2 × 4 bins has its most negative sample
    at the first point (u = 1/8, φ = π/8, the next 0.013 above): min_value is that value
    and min_relative it over the largest, to 1e-12; a series positive at every point
    (Y₀₀ alone) gives exactly 0 for both."""
    bins = HemisphereBins(2, 4)
    c = np.array([1.0, 0.1, -0.9, 0.3])
    u = (np.arange(4) + 0.5) / 4
    phi = (np.arange(8) + 0.5) * 2 * np.pi / 8
    uu, pp = np.meshgrid(u, phi, indexing="ij")
    g = basis_at(1, np.arccos(np.sqrt(1.0 - uu.ravel())), pp.ravel()) @ c
    assert int(np.argmin(g)) == 0 and np.sort(g)[1] - g[0] > 0.01
    for coefficients, low in ((c, g.min()), (np.array([1.0, 0.0, 0.0, 0.0]), 0.0)):
        table = exact_ring_table(bins, 1.0, 0.0)
        table = changed(table, sh=lambda e, c=coefficients: np.broadcast_to(
            c[None, None, :, None], (1, 1, 4, 3)).copy(), sh_err=lambda e: np.zeros((1, 1, 4, 3)))
        row = order_errors(table, [1])[0]
        high = (basis_at(1, np.arccos(np.sqrt(1.0 - uu.ravel())), pp.ravel())
                @ coefficients).max()
        assert row["min_value"] == pytest.approx(low, abs=1e-12)
        assert row["min_relative"] == pytest.approx(low / high, abs=1e-12)
        if low == 0.0:
            assert row["min_value"] == 0.0 and row["min_relative"] == 0.0


@pytest.mark.parametrize("missing", ["sh", "sh_err"])
def test_a_table_without_harmonics_or_their_errors_is_refused(missing: str) -> None:
    table = exact_ring_table(HemisphereBins(2, 4), 1.0, 0.0)
    table = changed(table, **{missing: lambda e: None})
    with pytest.raises(ValueError, match=r"^the table holds no spherical harmonics$"):
        order_errors(table, [1])
