"""Model bin averages and comparison metrics, checked by independent quadrature."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import integrate

from microsim.compare import bin_average, metrics
from microsim.geometry import direction


class Lobe:
    """A smooth test lobe f = (1 + 3 x_o^2) z_o^2 exp(-2 (1 - wi.r)) — not a model of
    anything, just a function with structure in both θ and φ."""

    def eval(self, wi, wo):
        r = wo * np.array([-1.0, -1.0, 1.0])
        return (1 + 3 * wo[..., 0] ** 2) * wo[..., 2] ** 2 * np.exp(
            -2 * (1 - np.sum(wi * r, axis=-1)))


def edges(nt, nph):
    theta = np.arcsin(np.sqrt(np.linspace(0, 1, nt + 1)))
    return theta, np.linspace(0, 2 * np.pi, nph + 1)


def test_direction_is_unit_and_follows_the_frame():
    w = direction(np.array([0.0, np.pi / 2, np.pi / 2]), np.array([1.0, 0.0, np.pi / 2]))
    np.testing.assert_allclose(w, [[0, 0, 1], [1, 0, 0], [0, 1, 0]], atol=1e-15)


def test_constant_lobe_averages_to_itself():
    class Const:
        def eval(self, wi, wo):
            return np.full(wo.shape[:-1], 1 / np.pi)

    te, pe = edges(5, 7)
    avg = bin_average(Const(), direction(0.3, 0.0), te, pe)
    np.testing.assert_allclose(avg, 1 / np.pi, rtol=1e-14)


@pytest.mark.parametrize("bin_index", [(0, 0), (2, 3), (4, 6)])
def test_bin_average_equals_quadrature(bin_index):
    """Midpoint rule with n = 64 against scipy dblquad of f cos θ sin θ over the bin. In
    u = sin²θ the integrand is smooth except for a √u term at the pole, so the midpoint
    error falls as n^-1.5: 2.3e-4 relative at n = 24 in the pole bin, ~5e-5 at n = 64."""
    te, pe = edges(5, 7)
    wi = direction(0.5, 0.2)
    model = Lobe()
    avg = bin_average(model, wi, te, pe, phi_i=0.2, n=64)
    i, j = bin_index

    def integrand(theta, phi):
        wo = direction(theta, 0.2 + phi)
        return model.eval(wi, wo) * np.cos(theta) * np.sin(theta)

    val, _ = integrate.dblquad(integrand, pe[j], pe[j + 1], te[i], te[i + 1],
                               epsabs=1e-12, epsrel=1e-10)
    proj = 0.5 * (np.sin(te[i + 1]) ** 2 - np.sin(te[i]) ** 2) * (pe[j + 1] - pe[j])
    assert avg[i, j, 0] == pytest.approx(val / proj, rel=1e-4)


def test_metrics_of_a_perfect_match_and_of_a_known_bias():
    rng = np.random.default_rng(7)
    te, pe = edges(8, 16)
    proj = 0.5 * np.diff(np.sin(te) ** 2)[:, None] * np.diff(pe)[None, :]
    model = bin_average(Lobe(), direction(0.4, 0.0), te, pe)
    sigma = 0.01 * model + 1e-3
    sim = model + sigma * rng.standard_normal(model.shape)
    m = metrics(sim, sigma, model, proj)
    # z of pure Gaussian noise of known sigma: mean 0 ± 1/sqrt(N), std 1 ± 1/sqrt(2N);
    # 4-sigma bounds over N = 3 x lobe bins samples
    n = 3 * m.lobe_bins
    assert abs(m.z_mean) < 4 / np.sqrt(n)
    assert abs(m.z_std - 1) < 4 / np.sqrt(2 * n)
    biased = metrics(1.05 * model, sigma, model, proj)
    assert biased.median_rel_error == pytest.approx(0.05, rel=1e-12)
    np.testing.assert_allclose(biased.albedo_difference,
                               0.05 * np.array(biased.albedo_model), rtol=1e-12)


def test_metrics_skip_undefined_errors():
    te, pe = edges(4, 4)
    proj = 0.5 * np.diff(np.sin(te) ** 2)[:, None] * np.diff(pe)[None, :]
    model = np.ones((4, 4, 3))
    err = np.full_like(model, np.nan)
    m = metrics(model, err, model, proj)
    assert np.isnan(m.z_mean) and m.median_rel_error == 0.0
