"""Linear interpolation weights between a table's nodes (incidences, bin centres).

Shared by table evaluation, the spherical-harmonic series of a table, Westin's matrix and
tabulated facet materials, so all of them read a table as the same piecewise-linear
function of its axes.
"""

from __future__ import annotations

import numpy as np


def linear_weights(x: np.ndarray, nodes: np.ndarray,
                   period: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Indices and weights of linear interpolation of ``x`` between sorted ``nodes``.

    Clamped at the ends, or periodic with ``period``.

    Parameters
    ----------
    x : (...) float
        Where to interpolate.
    nodes : (m,) float
        Increasing node positions.
    period : float or None
        The period of a periodic axis (nodes within one period), or None.

    Returns
    -------
    i0, i1 : (...) int
    w1 : (...) float
        Value = (1 − w1) f[i0] + w1 f[i1].
    """
    m = len(nodes)
    if m == 1:
        zero = np.zeros(np.shape(x), np.int64)
        return zero, zero, np.zeros(np.shape(x))
    if period is None:
        x = np.clip(x, nodes[0], nodes[-1])
        i1 = np.clip(np.searchsorted(nodes, x, side="right"), 1, m - 1)
        i0 = i1 - 1
        w1 = (x - nodes[i0]) / (nodes[i1] - nodes[i0])
        return i0, i1, np.clip(w1, 0.0, 1.0)
    ext = np.concatenate([nodes, [nodes[0] + period]])
    x = nodes[0] + np.mod(x - nodes[0], period)
    i1 = np.clip(np.searchsorted(ext, x, side="right"), 1, m)
    i0 = i1 - 1
    w1 = np.clip((x - ext[i0]) / (ext[i1] - ext[i0]), 0.0, 1.0)
    return i0, np.mod(i1, m), w1
