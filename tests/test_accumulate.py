"""The compiled accumulation of realisations (``microsim.tables.accumulate``) against the
numpy arithmetic it replaces, written out here with numpy's masked operations: every
running sum, shift, count and degree of freedom equal bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from microsim.tables.estimator import RunningEstimate, realisation_moments


class NumpyRunning:
    """The running sums as numpy's masked operations make them: the shift where a row is
    first present, Σ (m − c), Σ (m − c)², Σ v and its count where v is finite, per group
    r mod ``groups``."""

    def __init__(self, shape: tuple[int, ...], groups: int) -> None:
        self.shape, self.groups = shape, groups
        self.count = np.zeros(shape[:-2], np.int64)
        self.shift = np.full(shape, np.nan)
        self.known = np.zeros(shape, np.int64)
        self.dof_one = np.zeros(shape[:-2])
        self.sums: dict[int, tuple[np.ndarray, ...]] = {}

    def add(self, r: int, m: np.ndarray, v: np.ndarray | None, rays: object,
            at: tuple[int, ...]) -> None:
        ix = (*at, Ellipsis)
        present = ~np.isnan(m).all(axis=(-2, -1))
        keep = np.broadcast_to(present[..., None, None], m.shape)
        shift = self.shift[ix]
        np.copyto(shift, m, where=keep & (self.count[ix] == 0)[..., None, None])
        g = r % self.groups
        if g not in self.sums:
            self.sums[g] = (np.zeros(self.shape), np.zeros(self.shape),
                            np.zeros(self.shape), np.zeros(self.shape[:-2], np.int64))
        s1, s2, sv, n = (x[ix] for x in self.sums[g])
        d = m - shift
        np.add(s1, d, out=s1, where=keep)
        np.add(s2, np.square(d, out=d), out=s2, where=keep)
        if v is not None:
            known = keep & np.isfinite(v)
            np.add(sv, v, out=sv, where=known)
            self.known[ix] += known
        n += present
        self.count[ix] += present
        self.dof_one[ix] += np.where(present, rays, 0)


def realisation(rng: np.random.Generator, shape: tuple[int, ...]
                ) -> tuple[np.ndarray, np.ndarray]:
    """Sums Σx, Σx² of one realisation with the hard entries: zeros (Σx² = 0, the
    variance unknown), Σx² below Σx m (round-off: the variance clipped to 0), NaN and
    infinite sums."""
    s1 = rng.exponential(1.0, shape) * (rng.uniform(size=shape) < 0.7)
    s2 = s1 * s1 * rng.uniform(0.2, 3.0, shape)
    s2[rng.uniform(size=shape) < 0.05] *= 1e-3   # below Σx m: the clipped variance
    s1[rng.uniform(size=shape) < 0.01] = np.nan
    s2[rng.uniform(size=shape) < 0.01] = np.inf
    return s1, s2


def assert_same(running: RunningEstimate, reference: NumpyRunning) -> None:
    """Every array of the two running sums equal bit for bit (NaN where NaN)."""
    for name in ("count", "shift", "known", "dof_one"):
        np.testing.assert_array_equal(getattr(running, name), getattr(reference, name),
                                      strict=True, err_msg=name)
    assert sorted(running._sums) == sorted(reference.sums)
    for g, sums in reference.sums.items():
        for mine, theirs in zip(running._sums[g], sums, strict=True):
            assert mine.dtype == theirs.dtype
            assert np.array_equal(mine, theirs, equal_nan=True), g


@pytest.mark.parametrize("rays", [1, 2, 37])
def test_sums_added_in_one_pass_are_numpys_moments_then_masked_additions(rays: int) -> None:
    """``add_sums`` per direction (``at``) equals ``realisation_moments`` then numpy's
    masked additions, for one-ray (variance unknown), two-ray and many-ray realisations,
    over more realisations than groups."""
    rng = np.random.default_rng(rays)
    shape, groups = (3, 2, 4, 5, 3), 4
    running, reference = RunningEstimate(shape, groups), NumpyRunning(shape, groups)
    for r in range(9):
        for at in [(0, 0), (0, 1), (2, 1), (1, 0)][: 2 + r % 3]:
            s1, s2 = realisation(rng, shape[2:])
            running.add_sums(r, s1, s2, rays, at)
            m, v = realisation_moments(s1, s2, np.int64(rays))
            reference.add(r, m, v, rays, at)
        assert_same(running, reference)


def test_estimates_added_with_absent_rows_and_without_variances() -> None:
    """``add`` of estimates whose rows are absent (all NaN) in some realisations, over
    the whole shape and per direction; and the variance-free sums (v None), whose Σ v
    and counts of known variances stay zero."""
    rng = np.random.default_rng(7)
    shape = (2, 3, 6, 2)
    for ray_variance in (True, False):
        running = RunningEstimate(shape, 3, ray_variance=ray_variance)
        reference = NumpyRunning(shape, 3)
        for r in range(7):
            s1, s2 = realisation(rng, shape)
            m, v = realisation_moments(s1, s2, np.array([[5, 0, 2], [1, 3, 0]]))
            m[rng.uniform(size=shape[:2]) < 0.3] = np.nan   # absent rows
            rays = rng.integers(1, 9, shape[:2])
            at: tuple[int, ...] = (r % 2,) if r % 3 == 2 else ()
            vv = v if ray_variance else None
            running.add(r, m[at], None if vv is None else vv[at], rays[at], at)
            reference.add(r, m[at], None if vv is None else vv[at], rays[at], at)
            assert_same(running, reference)
        if not ray_variance:
            assert not running.known.any()
            assert all(not sums[2].any() for sums in running._sums.values())


def test_a_running_sum_without_leading_axes() -> None:
    """Sums of shape (m, c) alone (a 0-d leading shape) add as numpy's do."""
    rng = np.random.default_rng(3)
    running, reference = RunningEstimate((4, 2), 2), NumpyRunning((4, 2), 2)
    for r in range(5):
        s1, s2 = realisation(rng, (4, 2))
        running.add_sums(r, s1, s2, 3)
        m, v = realisation_moments(s1, s2, np.int64(3))
        reference.add(r, m, v, 3, ())
    assert_same(running, reference)


def test_sums_need_running_sums_with_ray_variances() -> None:
    """``add_sums`` brings ray variances; sums that keep none refuse them."""
    running = RunningEstimate((1, 2, 1), ray_variance=False)
    with pytest.raises(ValueError, match="keep none"):
        running.add_sums(0, np.ones((1, 2, 1)), np.ones((1, 2, 1)), 4)
