"""Orthonormal frames about unit vectors (facet normals, particle axes)."""

from __future__ import annotations

import numpy as np


def orthonormal_basis(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing each unit vector to a right-handed orthonormal frame.

    Branch-free and continuous except across n_z = 0 (Duff et al. 2017, "Building an
    orthonormal basis, revisited", JCGT 6(1), listing 3).

    Parameters
    ----------
    n : (k, 3) float
        Unit vectors.

    Returns
    -------
    t, s : (k, 3) float
        Unit vectors with t × s = n.
    """
    sign = np.copysign(1.0, n[:, 2])
    a = -1.0 / (sign + n[:, 2])
    b = n[:, 0] * n[:, 1] * a
    t = np.stack([1.0 + sign * n[:, 0] ** 2 * a, sign * b, -sign * n[:, 0]], axis=1)
    s = np.stack([b, sign + n[:, 1] ** 2 * a, -n[:, 1]], axis=1)
    return t, s
