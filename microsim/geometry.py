"""Directions and frames: the geometry every layer shares.

The local frame's macro-surface normal is +z; θ is measured from +z, φ from +x towards +y,
and directions point away from the surface (docs/conventions.md). Nothing here knows of
tables, models or the tracer.
"""

from __future__ import annotations

import numpy as np


def direction(theta: np.ndarray | float, phi: np.ndarray | float) -> np.ndarray:
    """Unit vectors from polar angles.

    Parameters
    ----------
    theta, phi : (...) float
        Polar angle from +z and azimuth from +x towards +y, radians.

    Returns
    -------
    (..., 3) float
    """
    theta, phi = np.broadcast_arrays(np.asarray(theta, float), np.asarray(phi, float))
    s = np.sin(theta)
    return np.stack([s * np.cos(phi), s * np.sin(phi), np.cos(theta)], axis=-1)


def half_difference(theta_h: np.ndarray, theta_d: np.ndarray, phi_d: np.ndarray | float
                    ) -> tuple[np.ndarray, np.ndarray]:
    """(ωi, ωo) from Rusinkiewicz's half/difference angles with φh = 0 (Rusinkiewicz
    1998, "A new change of variables for efficient BRDF representation", sec. 3): the
    difference vector d(θd, φd) in the half vector's frame, rotated by θh about y; ωo is
    d mirrored about h.

    Parameters
    ----------
    theta_h, theta_d, phi_d : (...) float
        Radians.

    Returns
    -------
    wi, wo : (..., 3) float
    """
    d = direction(theta_d, phi_d)
    e = d * np.array([-1.0, -1.0, 1.0])
    c, s = np.cos(theta_h)[..., None], np.sin(theta_h)[..., None]

    def rot(v: np.ndarray) -> np.ndarray:
        return np.stack([c[..., 0] * v[..., 0] + s[..., 0] * v[..., 2], v[..., 1],
                         -s[..., 0] * v[..., 0] + c[..., 0] * v[..., 2]], axis=-1)

    return rot(d), rot(e)


def orthonormal_basis(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing each unit vector to a right-handed orthonormal frame.

    Branch-free and continuous except across n_z = 0 (Duff et al. 2017, "Building an
    orthonormal basis, revisited", JCGT 6(1), listing 3; the kernel's scalar form is
    ``microsim.materials.optics.orthonormal_basis``).

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


FIBRE_MAX_TILT = 80.0
"""Largest tilt of a velvet fibre from +z, degrees: the generator clips sampled tilts to it,
so every fibre stands out of the base (``microsim.surfaces.velvet``), and the sparse-velvet
model integrates over the same range (``microsim.analytic.velvet``)."""


def section_axes(axes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors u, v with (u, v, axis) right-handed: a fibre's section plane, where
    its tip's corners lie, for the velvet generator and the sparse-velvet model alike (u
    from the axis crossed with +z, or with +x for fibres within 26° of +z).

    Parameters
    ----------
    axes : (n, 3) float
        Unit fibre axes.

    Returns
    -------
    u, v : (n, 3) float
    """
    helper = np.where(np.abs(axes[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
    u = np.cross(axes, helper)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    return u, np.cross(axes, u)
