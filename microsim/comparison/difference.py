"""Two tables of the same set-up against each other, bin by bin, with both errors.

Neither is the truth: both are estimates with standard errors (e.g. a two-level hierarchy
of scale and the same surface simulated in one level, docs/materials.md).
"""

from __future__ import annotations

from typing import Any

import numpy as np


def table_difference(a: Any, b: Any, component: str = "total") -> list[dict[str, Any]]:
    """Two tables of the same axes against each other, incidence by incidence.

    Parameters
    ----------
    a, b : BRDFTable
        Same incident directions, bins and channels (R, G, B, or the same wavelengths).
    component : str
        A component of the table (``"total"``, ``"single"``, ``"order2"``, …).

    Returns
    -------
    list of dict
        Per incident direction: ``theta_i``, ``phi_i`` (degrees); ``albedo_a``,
        ``albedo_b``, ``albedo_difference`` (a − b) and ``albedo_difference_err`` (C,
        each: one per channel); ``l1`` = Σ |f_a − f_b| Ω / Σ f_b Ω, the share of b's
        reflected energy that a places differently (mean over the channels);
        ``l1_noise``, the L1 noise alone gives in expectation (Σ √(2/π) √(σ_a² + σ_b²) Ω
        over the same sum: E|N(0, σ²)| = σ √(2/π)); ``z_rms``, the RMS of
        (f_a − f_b) / √(σ_a² + σ_b²) over bins with a defined error (1 for noise
        alone).

    Raises
    ------
    ValueError
        If the axes, bins or channels differ.
    """
    same = (a.bins.shape == b.bins.shape and a.isotropic == b.isotropic
            and np.allclose(a.theta_i, b.theta_i) and np.allclose(a.phi_i, b.phi_i))
    if not same:
        raise ValueError("tables with different incidences or bins do not compare")
    if a.channels != b.channels:
        raise ValueError(f"tables of different channels do not compare: "
                         f"{', '.join(a.channels.names)} and {', '.join(b.channels.names)}")
    omega = a.bins.projected_solid_angle[..., None]
    rows = []
    for i, theta in enumerate(a.theta_i):
        for j, phi in enumerate(a.phi_i):
            fa, fb = a[component].values[i, j], b[component].values[i, j]
            ea, eb = a[component].errors[i, j], b[component].errors[i, j]
            sigma = np.hypot(np.nan_to_num(ea), np.nan_to_num(eb))
            reflected = (fb * omega).sum(axis=(0, 1))
            with np.errstate(divide="ignore", invalid="ignore"):
                l1 = (np.abs(fa - fb) * omega).sum(axis=(0, 1)) / reflected
                noise = (np.sqrt(2 / np.pi) * sigma * omega).sum(axis=(0, 1)) / reflected
            defined = sigma > 0
            z = (fa - fb)[defined] / sigma[defined]
            da, db = a[component].albedo[i, j], b[component].albedo[i, j]
            rows.append({
                "theta_i": float(np.degrees(theta)), "phi_i": float(np.degrees(phi)),
                "albedo_a": da.tolist(), "albedo_b": db.tolist(),
                "albedo_difference": (da - db).tolist(),
                "albedo_difference_err": np.hypot(a[component].albedo_err[i, j],
                                                  b[component].albedo_err[i, j]).tolist(),
                "l1": float(l1.mean()), "l1_noise": float(noise.mean()),
                "z_rms": float(np.sqrt(np.mean(z**2))) if z.size else float("nan"),
            })
    return rows
