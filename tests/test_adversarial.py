"""What the adversarial campaign (scripts/adversarial_inputs.py) found, each cause pinned by
a test, and a fixed sample of the campaign's own cases run as the campaign runs them (each
in a process of its own, judged by its rule)."""

from __future__ import annotations

import tracemalloc
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent


# --- causes the campaign found -------------------------------------------------------------
@pytest.mark.parametrize("spec", ["beckmann-ms:samples=1000,seed=3",
                                  "ggx-ms:samples=70001,eta=[0.2,0.9,1.1],k=[3.9,2.4,2.1]"])
def test_a_monte_carlo_models_walks_per_pair_are_the_two_pass_estimate(spec):
    """``estimate`` runs its walks a chunk at a time and merges the chunks' means and
    squared deviations: the same walks as all at once (the random stream is consumed in
    the same chunks), so the mean equals the two-pass one to 1e-12 and the error to 1e-12
    of f_r (rounding; where every walk gives the same value the error is 0 to rounding)."""
    from microsim.analytic import multiple_scattering as ms
    from microsim.analytic.registry import parse_model_spec

    wi = np.array([[0.5, 0, np.sqrt(0.75)], [0, 0, 1], [0, 0, -1], [0.1, 0.2, np.sqrt(0.95)]])
    wo = np.array([[-0.5, 0, np.sqrt(0.75)], [0.3, 0, np.sqrt(0.91)], [0, 0, 1], [0, 0, 1]])
    _, _, chunked = parse_model_spec(spec)
    _, _, whole = parse_model_spec(spec)
    f, e = (a.reshape(len(wi), -1) for a in chunked.estimate(wi, wo))
    up = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    k = whole.samples
    x = whole._per_walk(np.repeat(wi[up], k, axis=0), np.repeat(wo[up], k, axis=0))
    mean, err = ms._mean_error(x.reshape(-1, k, x.shape[-1]), axis=1)
    assert np.allclose(f[up], mean / wo[up, 2:3], rtol=1e-12, atol=0)
    assert np.allclose(e[up], err / wo[up, 2:3], rtol=0, atol=1e-12 * f[up].max())
    assert np.all(f[~up] == 0) and np.all(e[~up] == 0)


def test_a_monte_carlo_models_walks_per_pair_take_bounded_memory():
    """``models eval beckmann-ms:samples=100000000`` held every walk of a pair at once
    (228 B each: 23 GB, unguarded); run a chunk of 65 536 walks at a time, 10^6 walks
    peak at 27 MB (were 228 MB). Bound 64 MB: one chunk of RGB walks is 24 MB."""
    from microsim.analytic.registry import parse_model_spec

    _, _, model = parse_model_spec("beckmann-ms:samples=1000000")
    tracemalloc.start()
    try:
        model.estimate(np.array([0.5, 0, np.sqrt(0.75)]), np.array([-0.5, 0, np.sqrt(0.75)]))
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 64e6, peak

