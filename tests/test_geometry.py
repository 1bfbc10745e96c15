"""Orthonormal frames about unit vectors, including the poles where bases break down."""

from __future__ import annotations

import numpy as np

from microsim.geometry import orthonormal_basis


def test_frames_are_orthonormal_and_right_handed_everywhere() -> None:
    rng = np.random.default_rng(3)
    n = rng.normal(size=(10_000, 3))
    # the poles and the equator, where a naive construction divides by zero
    n = np.vstack([n, [[0, 0, 1], [0, 0, -1], [1, 0, 0], [0, 1, 0], [1e-9, 0, -1]]])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    t, s = orthonormal_basis(n)
    frame = np.stack([t, s, n], axis=1)                                   # (k, 3, 3)
    # 1e-12: round-off of a few products of unit-range numbers
    assert np.abs(frame @ frame.transpose(0, 2, 1) - np.eye(3)).max() < 1e-12
    assert np.abs(np.cross(t, s) - n).max() < 1e-12
