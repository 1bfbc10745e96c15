"""How much a truncated harmonic lobe loses against the binned table
(microsim/tables/sh_error.py): ``order_errors`` against its definitions written out here —
bin integrals by Gauss-Legendre in θ and φ with scipy's harmonics, the relative L2 errors,
noise floors and sizes by their formulas, the most negative value at the documented
sample points — on tables whose g = f_r cos θo is or is not the stored series."""

from __future__ import annotations

import math

import numpy as np
import pytest

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
    return BRDFTable(bins, np.zeros(1), np.zeros(1), True, dict.fromkeys(comps, values),
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
