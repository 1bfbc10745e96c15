"""microsim.tables.evaluate against its interpolation written out pair by pair.

The table is piecewise linear in its axes (the module's docstring): linear in θi, clamped
outside the incidences, and periodically in φi; bilinear in (sin²θo, φo) between bin
centres, periodic in φo, clamped at the horizon; inside the first ring's centres blended
linearly in sin²θo towards the ring's mean. The references below redo that with scalar
loops and no shared code; agreement is to 1e-12 relative (round-off of a 16-term sum of
O(1) values is ~1e-15).
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from scipy.special import sph_harm_y

from microsim.tables import sh
from microsim.tables.binning import TWO_PI, HemisphereBins
from microsim.tables.evaluate import (
    Axes,
    from_harmonics,
    interpolate,
    interpolate_error,
    pole_share,
)

C = 2                                   # two channels: no default of 3 can stand in


def unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def direction(theta_deg: float, phi_deg: float) -> np.ndarray:
    t, p = math.radians(theta_deg), math.radians(phi_deg)
    return np.array([math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)])


def clamped(x: float, nodes: np.ndarray) -> list[tuple[int, float]]:
    """Linear interpolation weights of x between sorted nodes, constant outside."""
    if len(nodes) == 1 or x <= nodes[0]:
        return [(0, 1.0)]
    if x >= nodes[-1]:
        return [(len(nodes) - 1, 1.0)]
    j = max(k for k in range(len(nodes)) if nodes[k] <= x)
    w = (x - nodes[j]) / (nodes[j + 1] - nodes[j])
    return [(j, 1.0 - w), (j + 1, w)]


def periodic(x: float, nodes: np.ndarray, period: float) -> list[tuple[int, float]]:
    """Linear interpolation weights of x between nodes repeated with the period."""
    if len(nodes) == 1:
        return [(0, 1.0)]
    ext = list(nodes) + [nodes[0] + period]
    x = nodes[0] + (x - nodes[0]) % period
    j = max(k for k in range(len(nodes)) if ext[k] <= x)
    w = (x - ext[j]) / (ext[j + 1] - ext[j])
    return [(j, 1.0 - w), ((j + 1) % len(nodes), w)]


def incidence_weights(axes: Axes, wi: np.ndarray) -> list[tuple[int, int, float]]:
    theta = math.acos(min(1.0, wi[2]))
    phi = math.atan2(wi[1], wi[0]) % TWO_PI
    return [(t, p, wt * wp) for t, wt in clamped(theta, axes.theta_i)
            for p, wp in periodic(phi, axes.phi_i, TWO_PI)]


def outgoing_angles(axes: Axes, wi: np.ndarray, wo: np.ndarray) -> tuple[float, float]:
    """sin²θo and φo, relative to φi on isotropic tables, wrapped to [0, 2π)."""
    phi = math.atan2(wo[1], wo[0])
    if axes.isotropic:
        phi -= math.atan2(wi[1], wi[0])
    return min(1.0, wo[0] ** 2 + wo[1] ** 2), phi % TWO_PI


def reference_value(axes: Axes, values: np.ndarray, wi: np.ndarray, wo: np.ndarray
                    ) -> np.ndarray:
    if wi[2] <= 0 or wo[2] <= 0:
        return np.zeros(values.shape[-1])
    bins = axes.bins
    s, phi = outgoing_angles(axes, wi, wo)
    ring = np.sin(bins.theta_centers[0]) ** 2
    q = max(0.0, 1.0 - s / ring)
    out = np.zeros(values.shape[-1])
    for t, p, w_in in incidence_weights(axes, wi):
        for it, w_t in clamped(s, np.sin(bins.theta_centers) ** 2):
            for ip, w_p in periodic(phi, bins.phi_centers, bins.phi_period):
                v = values[t, p, it, ip]
                if q > 0:               # inside the first ring: towards the ring's mean
                    assert it == 0
                    v = v - q * (v - values[t, p, 0].mean(axis=0))
                out += w_in * w_t * w_p * v
    return out


def reference_error(axes: Axes, errors: np.ndarray, wi: np.ndarray, wo: np.ndarray
                    ) -> np.ndarray:
    """The 16 nodes' errors averaged with their weights over the finite ones, NaN where
    the node of largest weight is NaN (BRDFTable.stderr)."""
    if wi[2] <= 0 or wo[2] <= 0:
        return np.zeros(errors.shape[-1])
    bins = axes.bins
    s, phi = outgoing_angles(axes, wi, wo)
    nodes = [(w_in * w_t * w_p, errors[t, p, it, ip])
             for t, p, w_in in incidence_weights(axes, wi)
             for it, w_t in clamped(s, np.sin(bins.theta_centers) ** 2)
             for ip, w_p in periodic(phi, bins.phi_centers, bins.phi_period)]
    nearest = max(nodes, key=lambda n: n[0])[1]
    out = np.empty(errors.shape[-1])
    for c in range(errors.shape[-1]):
        known = [(w, e[c]) for w, e in nodes if np.isfinite(e[c])]
        out[c] = (np.nan if not np.isfinite(nearest[c])
                  else sum(w * e for w, e in known) / sum(w for w, _ in known))
    return out


def real_y(l: int, m: int, theta: float, phi: float) -> float:
    """Real harmonic from scipy's complex ``sph_harm_y`` (Condon-Shortley phase)."""
    y = complex(sph_harm_y(l, abs(m), theta, phi))
    return y.real if m == 0 else math.sqrt(2.0) * (y.real if m > 0 else y.imag)


def reference_series(axes: Axes, coefficients: np.ndarray, wi: np.ndarray,
                     wo: np.ndarray) -> np.ndarray:
    """Σ_k c_k(θi, φi) Y_k(ωo) / cos θo, c linear between the incidences as above."""
    if wi[2] <= 0 or wo[2] <= 0:
        return np.zeros(coefficients.shape[-1])
    order = math.isqrt(coefficients.shape[2]) - 1
    phi = math.atan2(wo[1], wo[0])
    if axes.isotropic:
        phi -= math.atan2(wi[1], wi[0])
    theta = math.acos(wo[2])
    y = np.array([real_y(l, m, theta, phi) for l in range(order + 1)
                  for m in range(-l, l + 1)])
    return sum(w * (y @ coefficients[t, p]) for t, p, w in incidence_weights(axes, wi)
               ) / wo[2]


ANISOTROPIC = Axes(HemisphereBins(4, 6), np.radians([10.0, 40.0, 70.0]),
                   np.radians([30.0, 150.0, 270.0]), False)
ISOTROPIC = Axes(HemisphereBins(5, 8), np.radians([0.0, 45.0]), np.zeros(1), True)


def pairs(seed: int, n: int = 60) -> tuple[np.ndarray, np.ndarray]:
    """Random pairs over the upper hemisphere, with directions beyond the incidences
    (θi < 10°, > 70°), at every φi (between the last φi and the first one + 2π) and
    outgoing directions inside the first ring's centres (near the pole)."""
    rng = np.random.default_rng(seed)
    wi = unit(rng.normal(size=(n, 3)) * [1, 1, 0.6] + [0, 0, 0.7])
    wo = unit(rng.normal(size=(n, 3)) * [1, 1, 0.6] + [0, 0, 0.7])
    wo[: n // 4] = unit(rng.normal(size=(n // 4, 3)) * [0.15, 0.15, 0] + [0, 0, 1])
    wi[:4] = [direction(3.0, 300.0), direction(85.0, 10.0), direction(55.0, 200.0),
              direction(25.0, 350.0)]
    return wi, wo


@pytest.mark.parametrize("axes", [ANISOTROPIC, ISOTROPIC], ids=["anisotropic", "isotropic"])
def test_interpolate_is_the_interpolation_written_out(axes: Axes) -> None:
    rng = np.random.default_rng(1)
    values = rng.uniform(0.5, 2.0, (len(axes.theta_i), len(axes.phi_i)) + axes.bins.shape
                         + (C,))
    wi, wo = pairs(2)
    assert (pole_share(axes.bins, wo) > 0).sum() >= 10      # the pole blend is exercised
    got = interpolate(axes, values, wi, wo)
    expected = np.array([reference_value(axes, values, a, b) for a, b in zip(wi, wo,
                                                                              strict=True)])
    assert got.shape == (len(wi), C)
    assert np.allclose(got, expected, rtol=1e-12, atol=0), np.abs(got - expected).max()


@pytest.mark.parametrize("axes", [ANISOTROPIC, ISOTROPIC], ids=["anisotropic", "isotropic"])
def test_interpolate_error_is_the_mean_over_known_nodes_written_out(axes: Axes) -> None:
    """A third of the errors undefined (NaN): the result is NaN exactly where the nearest
    node's is, else the weighted mean of the finite ones."""
    rng = np.random.default_rng(3)
    shape = (len(axes.theta_i), len(axes.phi_i)) + axes.bins.shape + (C,)
    errors = rng.uniform(0.1, 1.0, shape)
    errors[rng.uniform(size=shape) < 0.3] = np.nan
    wi, wo = pairs(4)
    got = interpolate_error(axes, errors, wi, wo)
    expected = np.array([reference_error(axes, errors, a, b) for a, b in zip(wi, wo,
                                                                             strict=True)])
    assert got.shape == (len(wi), C)
    assert np.array_equal(np.isnan(got), np.isnan(expected))
    assert 0 < np.isnan(got).sum() < got.size
    known = ~np.isnan(expected)
    assert np.allclose(got[known], expected[known], rtol=1e-12, atol=0)


@pytest.mark.parametrize("axes", [ANISOTROPIC, ISOTROPIC], ids=["anisotropic", "isotropic"])
def test_from_harmonics_is_the_series_written_out(axes: Axes) -> None:
    """Order 3 with random coefficients, blended between incidences as the bins are."""
    rng = np.random.default_rng(5)
    coefficients = rng.normal(size=(len(axes.theta_i), len(axes.phi_i), sh.size(3), C))
    wi, wo = pairs(6)
    got = from_harmonics(axes, coefficients, wi, wo)
    expected = np.array([reference_series(axes, coefficients, a, b)
                         for a, b in zip(wi, wo, strict=True)])
    assert got.shape == (len(wi), C)
    assert np.allclose(got, expected, rtol=1e-10, atol=1e-12), np.abs(got - expected).max()


def evaluations(axes: Axes):
    rng = np.random.default_rng(7)
    values = rng.uniform(0.5, 2.0, (len(axes.theta_i), len(axes.phi_i)) + axes.bins.shape
                         + (C,))
    coefficients = rng.normal(size=(len(axes.theta_i), len(axes.phi_i), sh.size(2), C))
    return {"interpolate": lambda wi, wo: interpolate(axes, values, wi, wo),
            "interpolate_error": lambda wi, wo: interpolate_error(axes, values, wi, wo),
            "from_harmonics": lambda wi, wo: from_harmonics(axes, coefficients, wi, wo)}


@pytest.mark.parametrize("name", ["interpolate", "interpolate_error", "from_harmonics"])
def test_zero_on_the_horizon_and_at_z_rounded_past_one(name: str) -> None:
    """0 where either direction is on the horizon (z = 0 exactly) or below; an incident z
    rounded past ±1 by a normalisation (1 ± 2⁻⁵²) is the normal (or 0 below) without a
    RuntimeWarning from arccos."""
    f = evaluations(ANISOTROPIC)[name]
    up = direction(30.0, 40.0)
    flat = np.array([0.8, 0.6, 0.0])
    assert np.all(f(flat, up) == 0) and np.all(f(up, flat) == 0)
    assert np.all(f(up, up) != 0)
    past = np.array([0.0, 0.0, 1.0 + 2.0 ** -52])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert np.array_equal(f(past, up), f(np.array([0.0, 0.0, 1.0]), up))
        assert np.all(f(-past, up) == 0)


@pytest.mark.parametrize("name", ["interpolate", "interpolate_error", "from_harmonics"])
def test_single_precision_directions_are_evaluated_in_double(name: str) -> None:
    """float32 directions give exactly the result of the same values in float64."""
    f = evaluations(ISOTROPIC)[name]
    wi, wo = pairs(8)
    wi32, wo32 = wi.astype(np.float32), wo.astype(np.float32)
    exact = f(wi32.astype(float), wo32.astype(float))
    assert np.array_equal(f(wi32, wo32), exact)
    assert np.array_equal(f(wi32, wo32.astype(float)), exact)
    assert np.array_equal(f(wi32.astype(float), wo32), exact)


def test_pole_share_is_one_minus_the_ring_fraction_of_sin2() -> None:
    """1 − sin²θo / sin²θ₁ inside the first ring's centres, 1 at the pole, 0 on and beyond
    the ring's centres (never negative)."""
    bins = HemisphereBins(5, 8)
    theta_1 = bins.theta_centers[0]
    theta = np.array([0.0, 0.3 * theta_1, 0.9 * theta_1, theta_1, 1.5 * theta_1, 1.2])
    wo = np.stack([np.sin(theta) * np.cos(0.4), np.sin(theta) * np.sin(0.4),
                   np.cos(theta)], -1)
    expected = np.maximum(0.0, 1.0 - np.sin(theta) ** 2 / np.sin(theta_1) ** 2)
    got = pole_share(bins, wo)
    assert got[0] == 1.0 and np.all(got[3:] == 0.0)
    assert np.allclose(got, expected, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("name", ["interpolate", "interpolate_error", "from_harmonics"])
def test_directions_broadcast_and_the_result_keeps_their_shape(name: str) -> None:
    """One pair gives (C,), a (2, 5) grid of outgoing directions under one incident
    direction (2, 5, C), each the value of its pair evaluated alone."""
    f = evaluations(ANISOTROPIC)[name]
    wi, wo = pairs(9, 10)
    one = f(wi[0], wo[0])
    assert one.shape == (C,)
    grid = f(wi[0], wo.reshape(2, 5, 3))
    assert grid.shape == (2, 5, C)
    alone = np.array([f(wi[0], b) for b in wo]).reshape(2, 5, C)
    assert np.allclose(grid, alone, rtol=1e-14, atol=0)
    assert np.allclose(one, alone[0, 0], rtol=1e-14, atol=0)
