"""Hemisphere bins: exact projected solid angles, indexing, sampling."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import integrate, stats

from microsim.geometry import direction
from microsim.tables.binning import HemisphereBins


def test_projected_solid_angle_matches_quadrature():
    bins = HemisphereBins(7, 5)
    for i, j in [(0, 0), (3, 2), (6, 4)]:
        val, _ = integrate.dblquad(lambda t, p: np.cos(t) * np.sin(t),
                                   bins.phi_edges[j], bins.phi_edges[j + 1],
                                   bins.theta_edges[i], bins.theta_edges[i + 1],
                                   epsabs=1e-14, epsrel=1e-12)
        assert bins.projected_solid_angle[i, j] == pytest.approx(val, rel=1e-10)
    assert bins.projected_solid_angle.sum() == pytest.approx(np.pi, rel=1e-14)
    assert np.ptp(bins.projected_solid_angle) < 1e-15  # all bins equal


def test_cosine_weighted_directions_fill_bins_equally():
    """Cosine-weighted samples spread uniformly over equal-projected-solid-angle bins:
    chi-square goodness of fit at significance 0.001 (fixed seed)."""
    rng = np.random.default_rng(3)
    n = 200_000
    u1, u2 = rng.random(n), rng.random(n)
    wo = direction(np.arcsin(np.sqrt(u1)), 2 * np.pi * u2)
    bins = HemisphereBins(6, 8)
    counts = np.bincount(bins.index(wo), minlength=bins.size)
    assert counts.sum() == n
    assert stats.chisquare(counts).pvalue > 1e-3


def test_index_edge_cases():
    bins = HemisphereBins(4, 8)
    eps = 1e-12
    wo = np.array([
        [0.0, 0.0, 1.0],                       # the pole: first theta bin, phi 0
        [1.0, 0.0, 0.0],                       # on the horizon: not in the hemisphere
        [0.6, 0.0, -0.8],                      # below
        [np.cos(-eps), np.sin(-eps), 1e-9],    # phi = 2 pi - eps, almost grazing
        [1e-20, -1e-20, 1.0],                  # rounding at the pole
    ])
    idx = bins.index(wo / np.linalg.norm(wo, axis=1, keepdims=True))
    assert idx[0] == 0 and idx[1] == -1 and idx[2] == -1
    assert idx[3] == 3 * 8 + 7
    assert 0 <= idx[4] < 8


def test_relative_azimuth_and_folding():
    full, folded = HemisphereBins(2, 8), HemisphereBins(2, 4, np.pi)
    w = direction(np.full(3, 1.0), np.array([0.3, -0.3, 0.3 + 2 * np.pi]))
    assert full.index(w[:1], 0.3)[0] == full.index(direction(1.0, 0.0)[None])[0]
    i = folded.index(w)
    assert i[0] == i[1] == i[2]  # phi and -phi share a bin when folded
    assert folded.to_dict()["phi_o"]["folded"]
    back = HemisphereBins.from_dict(folded.to_dict())
    np.testing.assert_array_equal(back.phi_edges, folded.phi_edges)


def test_sample_lands_in_its_bin_and_is_uniform_in_projected_solid_angle():
    rng = np.random.default_rng(5)
    bins = HemisphereBins(5, 6)
    k = np.full(50_000, 13)
    wo = bins.sample(k, rng.random(k.size), rng.random(k.size))
    np.testing.assert_allclose(np.linalg.norm(wo, axis=1), 1, atol=1e-12)
    assert np.all(bins.index(wo) == 13)
    # within the bin, u = sin^2 theta is uniform: Kolmogorov-Smirnov at significance 0.001
    u = 1 - wo[:, 2] ** 2
    lo, hi = bins.u_edges[2], bins.u_edges[3]
    assert stats.kstest((u - lo) / (hi - lo), "uniform").pvalue > 1e-3


def test_bins_are_described_and_refused_as_documented():
    """Edges and centres as the docstring writes them (φ centres mid-way between edges);
    one bin each way is allowed, fewer refused with the message, as is a period other
    than 2π or π; ``to_dict`` is the table file's description (docs/table-format.md) and
    ``from_dict`` its inverse."""
    one = HemisphereBins(1, 1)
    assert one.size == 1 and one.index(np.array([[0.0, 0.0, 1.0]]))[0] == 0
    for bad in ((0, 4), (4, 0)):
        with pytest.raises(ValueError, match="^theta_bins and phi_bins must be >= 1$"):
            HemisphereBins(*bad)
    with pytest.raises(ValueError, match="^phi_period must be 2 pi or pi$"):
        HemisphereBins(4, 4, 3.0)
    bins = HemisphereBins(4, 6, np.pi)
    edges = np.linspace(0.0, np.pi, 7)
    np.testing.assert_allclose(bins.phi_centers, (edges[:-1] + edges[1:]) / 2, rtol=1e-15)
    np.testing.assert_allclose(bins.theta_edges, np.arcsin(np.sqrt(np.arange(5) / 4)))
    assert bins.to_dict() == {
        "theta_o": {"edges": bins.theta_edges.tolist(), "unit": "rad",
                    "spacing": "uniform in sin^2(theta_o)"},
        "phi_o": {"edges": edges.tolist(), "unit": "rad", "folded": True}}
    back = HemisphereBins.from_dict(bins.to_dict())
    assert back.shape == (4, 6) and back.folded


def test_index_takes_the_reference_azimuth_off_and_keeps_the_last_bin():
    """``index(wo, phi_ref)`` bins the azimuth relative to ``phi_ref`` (a direction at
    φref + 0.1 lands in the first φ bin, one at φref − 0.1 in the last); an azimuth a hair
    below 2π, which wraps to 2π itself in floating point, stays in the last bin of its
    row."""
    bins = HemisphereBins(4, 16)
    ref = 1.0
    got = bins.index(direction(np.array([0.5, 0.5]), ref + np.array([0.1, -0.1])), ref)
    it = int(np.sin(0.5) ** 2 * 4)
    assert got.tolist() == [it * 16, it * 16 + 15]
    assert bins.index(direction(np.array([0.5]), np.array([-1e-17])))[0] == it * 16 + 15


def test_sample_is_uniform_in_azimuth_within_its_bin():
    """u2 = 0, ½ and → 1 put the sampled azimuth at the bin's start, centre and end (the
    azimuth is linear in u2 across the bin), for narrow bins too."""
    bins = HemisphereBins(4, 16)
    flat = np.full(3, 2 * 16 + 5)
    wo = bins.sample(flat, np.full(3, 0.5), np.array([0.0, 0.5, 1 - 1e-12]))
    phi = np.arctan2(wo[:, 1], wo[:, 0])
    np.testing.assert_allclose(phi, bins.phi_edges[5] + np.array([0.0, 0.5, 1.0])
                               * (bins.phi_edges[6] - bins.phi_edges[5]), atol=1e-9)
