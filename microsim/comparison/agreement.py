"""The verdict of a comparison: does a table agree with a model within its error bars?

``compare.compare_table`` gives z = (sim − model) / stderr over the lobe bins; if the
model were exact and the error bars calibrated, z would be standard normal. ``agreement``
tests that at a stated significance and ``verdict_text`` says the outcome in one line.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from microsim.comparison.records import Comparison

AGREEMENT_SIGNIFICANCE = 1e-3
"""Significance of the test whether a table agrees with a model within its error bars."""


@dataclass(frozen=True)
class Agreement:
    """The outcome of the test whether a comparison's z-scores are noise alone.

    Attributes
    ----------
    agrees : bool
        Both bounds hold (and there are at least two lobe bins).
    lobe_bins : int
        N, the lobe bins of every incidence.
    z_mean_max : float
        The bound on |z mean|: z_{1−α/2} / √N.
    z_std_max : float
        The bound on the spread: √(χ²_{1−α}(N − 1) / (N − 1)); NaN for N < 2.
    significance : float
        α.
    """

    agrees: bool
    lobe_bins: int
    z_mean_max: float
    z_std_max: float
    significance: float

    def to_json(self) -> dict[str, Any]:
        """The outcome as JSON (``agreement`` of ``microsim compare --json``)."""
        return {"agrees": self.agrees, "lobe_bins": self.lobe_bins,
                "z_mean_max": self.z_mean_max, "z_std_max": self.z_std_max,
                "significance": self.significance}


def agreement(result: Comparison) -> Agreement:
    """Whether a comparison's z = (sim − model) / stderr looks like noise alone.

    If the model were exact and the error bars calibrated, the z of the N lobe bins would
    be standard normal: their mean within z_{1−α/2} / √N of 0 and (N − 1) s² below the
    1 − α quantile of χ²(N − 1), at significance α = ``AGREEMENT_SIGNIFICANCE``. N counts
    lobe bins, not colour channels (the channels of a grey material repeat each other, so
    counting them would claim three times the evidence).

    Parameters
    ----------
    result : Comparison
        ``compare_table``'s result.

    Returns
    -------
    Agreement
    """
    from scipy.stats import chi2, norm

    n = sum(row.lobe_bins for row in result.per_theta_i)
    alpha = AGREEMENT_SIGNIFICANCE
    mean_max = float(norm.ppf(1 - alpha / 2) / np.sqrt(max(n, 1)))
    std_max = float(np.sqrt(chi2.ppf(1 - alpha, n - 1) / (n - 1))) if n > 1 else np.nan
    agrees = bool(n > 1 and abs(result.z_mean) <= mean_max and result.z_std <= std_max)
    return Agreement(agrees, n, mean_max, std_max, alpha)


def verdict_text(result: Comparison, check: Agreement, what: str = "") -> str:
    """One line: does the table agree with the model within its error bars, and what the
    numbers say (``result`` from ``compare_table``, ``check`` from ``agreement``; ``what``
    names the comparison when there are several)."""
    head = f"verdict ({what}):" if what else "verdict:"

    def z(x: float, spec: str = ".2f", unit: str = "") -> str:
        """NaN (no lobe bin with light; a spread over one) in words."""
        return format(x, spec) + unit if np.isfinite(x) else "undefined"

    numbers = (f"z = (sim − model) / stderr has mean {z(result.z_mean)} and spread "
               f"{z(result.z_std)} over {check.lobe_bins} lobe bins; noise alone "
               f"gives a mean within ±{z(check.z_mean_max)} and a spread up to "
               f"{z(check.z_std_max)} at significance {check.significance:g}")
    if check.agrees:
        return f"{head} agrees with the model within the error bars ({numbers})"
    return (f"{head} differs from the model by more than the error bars ({numbers}); the "
            f"median relative error against the model is "
            f"{z(100 * result.median_rel_error, '.1f', '%')}")
