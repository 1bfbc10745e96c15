"""A comparison of a table with a model, as records: one incidence's metrics and the table's.

``microsim.compare.metrics`` measures one incidence's bins against a model's bin averages
(``IncidenceMetrics``); ``microsim.comparison.metrics.compare_table`` every incidence of a table and
the pooled numbers (``Comparison``). Their JSON form (``to_json``) is made here only: it is
what ``microsim compare --json`` and ``microsim demo --json`` print, with the keys that
docs/compare.md lists, in a fixed order.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class IncidenceMetrics:
    """Error metrics of one incidence's simulated bins against a model's bin averages.

    Attributes
    ----------
    median_rel_error, p90_rel_error : float
        Median and 90th percentile of |sim − model| / model over the lobe bins (model ≥
        10% of its peak, per channel); NaN without lobe bins.
    rms_error : float
        Root mean square of sim − model over every bin and channel, 1/sr.
    z_mean, z_std : float
        Mean and sample standard deviation of the z-scores
        (``microsim.comparison.metrics.lobe_residuals``) over lobe bins with a defined, non-zero
        error; NaN with too few of them (none, or one for ``z_std``).
    lobe_bins : int
        Lobe bins of the green channel.
    albedo_sim, albedo_model : (3,) float
        Σ f_r Ω_proj over every bin, per channel: of the simulation and of the model.
    albedo_difference : (3,) float
        ``albedo_sim`` − ``albedo_model``.
    albedo_model_err : (3,) float
        The model's standard error of ``albedo_model``: √Σ (σ Ω_proj)², bins being
        independent estimates (zeros for an analytic model).
    theta_i, phi_i : float or None
        The incident direction, degrees, for a table's incidence (``compare_table``);
        None for bins compared on their own.
    multiple_scattering_share : float or None
        For a table's incidence, (total − single albedo) / total albedo of the simulation:
        the share of the escaping energy scattered more than once, what a
        single-scattering model leaves out (NaN where nothing escapes); None for bins
        compared on their own.
    """

    median_rel_error: float
    p90_rel_error: float
    rms_error: float
    z_mean: float
    z_std: float
    lobe_bins: int
    albedo_sim: np.ndarray
    albedo_model: np.ndarray
    albedo_difference: np.ndarray
    albedo_model_err: np.ndarray
    theta_i: float | None = None
    phi_i: float | None = None
    multiple_scattering_share: float | None = None

    def to_json(self) -> dict[str, Any]:
        """The metrics as JSON: the per-channel albedos as lists, the incidence's keys
        (``theta_i``, ``phi_i``, ``multiple_scattering_share``) after the metrics and
        only where set."""
        out: dict[str, Any] = {
            "median_rel_error": self.median_rel_error,
            "p90_rel_error": self.p90_rel_error,
            "rms_error": self.rms_error,
            "z_mean": self.z_mean,
            "z_std": self.z_std,
            "lobe_bins": self.lobe_bins,
            "albedo_sim": self.albedo_sim.tolist(),
            "albedo_model": self.albedo_model.tolist(),
            "albedo_difference": self.albedo_difference.tolist(),
            "albedo_model_err": self.albedo_model_err.tolist(),
        }
        placed = {"theta_i": self.theta_i, "phi_i": self.phi_i,
                  "multiple_scattering_share": self.multiple_scattering_share}
        out.update((key, value) for key, value in placed.items() if value is not None)
        return out


@dataclass(frozen=True)
class Comparison:
    """Every incidence of a table against a model: per-incidence and pooled metrics.

    Attributes
    ----------
    median_rel_error, p90_rel_error : float
        Median and 90th percentile of |sim − model| / model over every incidence's lobe
        bins pooled; NaN without lobe bins.
    z_mean, z_std : float
        Mean and sample standard deviation of every incidence's lobe z-scores pooled (z
        against both errors, ``microsim.comparison.metrics.lobe_residuals``).
    error_model : str
        The table's (``BRDFTable.error_model``).
    realisations : int
        The most realisations of any incidence.
    dof : float
        The fewest degrees of freedom of a bin's error in the compared component.
    per_theta_i : tuple of IncidenceMetrics
        One per incident direction (θi outer, φi inner), with ``theta_i``, ``phi_i`` and
        ``multiple_scattering_share`` set.
    model, model_err : (a, b, nt, np, 3) float
        The model's bin averages per incidence (a θi, b φi), bin and colour, and their
        standard errors (zeros for an analytic model), 1/sr: for plots.
    """

    median_rel_error: float
    p90_rel_error: float
    z_mean: float
    z_std: float
    error_model: str
    realisations: int
    dof: float
    per_theta_i: tuple[IncidenceMetrics, ...]
    model: np.ndarray
    model_err: np.ndarray

    def to_json(self) -> dict[str, Any]:
        """The comparison as JSON: the pooled metrics, the table's error model and the
        per-incidence rows; the per-bin ``model`` and ``model_err`` are left out."""
        return {
            "median_rel_error": self.median_rel_error,
            "p90_rel_error": self.p90_rel_error,
            "z_mean": self.z_mean,
            "z_std": self.z_std,
            "error_model": self.error_model,
            "realisations": self.realisations,
            "dof": self.dof,
            "per_theta_i": [row.to_json() for row in self.per_theta_i],
        }
