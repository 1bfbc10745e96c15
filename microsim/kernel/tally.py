"""Escape records into sums, compiled and in ray order.

A run's outcomes are written per ray (``transport``); these loops read them in ray order,
in blocks of ``BLOCK`` rays whose sums are added in block order (``in_blocks``), so every
floating-point sum is added in the same order whatever the threads and chunks that traced
the rays, and whichever threads summed the blocks: a table is the same bit for bit.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
from numba import njit

from microsim.jit import INLINE, JIT
from microsim.kernel.slots import ESCAPED, O_FATE, O_ORDER, O_W, S_DX, TRANSMITTED
from microsim.materials.optics import TWO_PI

BLOCK = 32768
"""Rays per block of the sums: a fixed partition of a run, independent of the tracer's
chunks, so the blocks can be summed on any threads; a multiple of ``slots.ENERGY_BLOCK``."""
GATHER = 64
"""Rays per block of ``gather_rows``'s copies (a block's weights stay in a core's cache)."""


def in_blocks(fn: Callable[[int, int], tuple[np.ndarray, ...]], n: int,
              mapper: Callable[[Callable[[int], Any], range], list[Any]] | None = None
              ) -> tuple[np.ndarray, ...]:
    """Sums over rays [0, n) made block by block and added in block order.

    Parameters
    ----------
    fn : callable
        ``fn(a, b)`` returns a tuple of arrays summed over rays [a, b).
    n : int
        Rays.
    mapper : callable or None
        ``mapper(g, range(k))`` returns ``[g(0), …, g(k − 1)]`` in any schedule (e.g.
        ``PeriodicScene.map``); default: one block after the other.

    Returns
    -------
    tuple of arrays
        The element-wise sums, the blocks added in order.
    """
    starts = range(0, n, BLOCK)
    run = mapper or (lambda g, jobs: [g(j) for j in jobs])
    parts = run(lambda a: fn(a, min(a + BLOCK, n)), starts)
    total = [np.array(x, copy=True) for x in parts[0]]
    for part in parts[1:]:
        for acc, x in zip(total, part, strict=True):
            acc += x
    return tuple(total)


@njit(**JIT)
def summarise(out_f: np.ndarray, out_i: np.ndarray, energy: np.ndarray,
              counts: np.ndarray) -> None:
    """Split a run's outcomes into the escaping rays and the energy of the others, in
    place: every other ray's weight is added to the energy it ends as, and its direction,
    weights and order in the outcomes are set to zero, so that the outcomes' columns are
    the escaping rays' records as they stand (no copy of a ray's C weights).

    Parameters
    ----------
    out_f, out_i
        The run's outcomes (``transport``); rewritten for the rays that did not escape.
    energy : (3, C) float
        Running summed weight per channel lost (paths ended by the simulation),
        transmitted and absorbed; this adds the weight of the paths that ended lost, of
        those out through the bottom after a refraction, and 1 − the final weight of
        every path to the absorbed (less what its events transmitted and what ended at a
        dispersive event, the blocks' sums of ``slots.add_energy``, it is what the path
        absorbed).
    counts : (len(FATES),) int
        Running paths per fate.
    """
    channels = out_f.shape[1] - O_W
    for r in range(len(out_i)):
        fate = out_i[r, O_FATE]
        counts[fate] += 1
        for c in range(channels):
            energy[2, c] += 1.0 - out_f[r, O_W + c]
        if fate == ESCAPED:
            continue
        for c in range(3):
            out_f[r, S_DX + c] = 0.0
        row = 1 if fate == TRANSMITTED else 0
        for c in range(channels):
            energy[row, c] += out_f[r, O_W + c]
            out_f[r, O_W + c] = 0.0
        out_i[r, O_ORDER] = 0


@njit(**JIT)
def bin_of(x: float, y: float, z: float, phi_ref: float, theta_bins: int, phi_bins: int,
           folded: bool) -> int:
    """Flat bin ``it · phi_bins + ip`` of a unit direction in bins uniform in u = sin²θ
    and φ − φ_ref (folded: φ reflected into [0, π]), or -1 on or below the horizon
    (``microsim.tables.binning.HemisphereBins.index``; the azimuth is reduced modulo 2π
    with a floor instead of numpy's ``mod``, which may differ in the last bit)."""
    return bin_at(x, y, z, math.atan2(y, x) - phi_ref, theta_bins, phi_bins, folded)


@njit(**INLINE)
def bin_at(x: float, y: float, z: float, phi: float, theta_bins: int, phi_bins: int,
           folded: bool) -> int:
    """``bin_of`` with the azimuth difference φ − φ_ref = atan2(y, x) − φ_ref given."""
    if z <= 0.0:
        return -1
    u = min(max(x * x + y * y, 0.0), 1.0)
    it = min(int(u * theta_bins), theta_bins - 1)
    phi -= TWO_PI * math.floor(phi * (1.0 / TWO_PI))
    if folded:
        phi = min(phi, TWO_PI - phi)
        ip = int(phi * (phi_bins / math.pi))
    else:
        ip = int(phi * (phi_bins / TWO_PI))
    return it * phi_bins + min(ip, phi_bins - 1)


@njit(**JIT)
def bin_escapes(direction: np.ndarray, weight: np.ndarray, order: np.ndarray,
                phi_ref: float, theta_bins: int, phi_bins: int, folded: bool,
                orders: int, sums: np.ndarray, sums_sq: np.ndarray,
                index: np.ndarray, unbinned: np.ndarray, loc: np.ndarray) -> None:
    """Add escaping rays' weights w and w² to their bins, per component, and keep the
    binned rays' angles for their harmonics.

    Parameters
    ----------
    direction : (n, 3) float
    weight : (n, C) float
    order : (n,) int
        Scattering order (0: not escaped or never scattered, not binned).
    phi_ref : float
        Azimuth the bins' φ is measured from, radians.
    theta_bins, phi_bins : int
    folded : bool
    orders : int
        N ≥ 1: a ray of order k adds to component min(k, N) besides component 0 (all
        orders).
    sums, sums_sq : (N + 1, theta_bins · phi_bins, C) float
        Running Σw and Σw² per component, bin and channel.
    index : (n,) int
        Filled with each ray's bin (-1: none).
    unbinned : (C,) float
        Running summed weight of scattered rays no bin takes (escaping on the horizon).
    loc : (n, 2) float, or (0, 2) for none
        Filled, for each binned ray, with its colatitude and its azimuth relative to
        φ_ref in [0, 2π) (``microsim.tables.sh.angles``: θ = acos z, and φ reduced as
        numpy's ``mod`` reduces it; φ_ref in [0, 2π)).
    """
    angles = len(loc) > 0
    channels = weight.shape[1]
    for r in range(len(order)):
        k = order[r]
        b = -1
        if k > 0:
            x, y, z = direction[r, 0], direction[r, 1], direction[r, 2]
            phi = math.atan2(y, x) - phi_ref
            b = bin_at(x, y, z, phi, theta_bins, phi_bins, folded)
            if b < 0:
                for c in range(channels):
                    unbinned[c] += weight[r, c]
            elif angles:
                # numpy's mod: fmod (exact), then + 2π if negative; the difference lies
                # in (−3π, π], where fmod is one exact addition of 2π below −2π
                if phi <= -TWO_PI:
                    phi += TWO_PI
                if phi < 0.0:
                    phi += TWO_PI
                loc[r, 0] = math.acos(min(max(z, -1.0), 1.0))
                loc[r, 1] = phi
        index[r] = b
        if b < 0:
            continue
        slot = min(k, orders)
        for c in range(channels):
            w = weight[r, c]
            sums[0, b, c] += w
            sums_sq[0, b, c] += w * w
            sums[slot, b, c] += w
            sums_sq[slot, b, c] += w * w


@njit(**JIT)
def gather_rows(loc: np.ndarray, weight: np.ndarray, order: np.ndarray, index: np.ndarray,
                orders: int, loc_rows: np.ndarray, weight_rows: np.ndarray,
                ends: np.ndarray) -> int:
    """The binned rays grouped by order row, for their harmonic transforms: a counting
    sort on the row min(k, N) (stable: each row's rays keep their ray order).

    Parameters
    ----------
    loc : (n, 2) float
        The rays' angles (``bin_escapes``).
    weight : (n, C) float
    order : (n,) int
    index : (n,) int
        Each ray's bin (``bin_escapes``; -1: not binned, left out).
    orders : int
        N.
    loc_rows, weight_rows : (n, 2) and (C, n) float
        Filled, in their first entries, with the binned rays' angles and (channel by
        channel) weights, order row by order row.
    ends : (N + 1,) int
        Filled with the end of each row's rays (row 0, the total, holds none).

    Returns
    -------
    int
        The binned rays.
    """
    ends[:] = 0
    for r in range(len(order)):
        if index[r] >= 0:
            ends[min(order[r], orders)] += 1
    for k in range(1, orders + 1):
        ends[k] += ends[k - 1]
    fill = np.empty(orders + 1, np.int64)
    fill[0] = 0
    for k in range(1, orders + 1):
        fill[k] = ends[k - 1]
    # in blocks of GATHER rays: their destinations, then each channel's weights (a
    # channel's row written in order, the block's weights read from cache): at 32
    # channels, twice as fast as writing every channel of one ray at a time
    dest = np.empty(GATHER, np.int64)
    for start in range(0, len(order), GATHER):
        stop = min(start + GATHER, len(order))
        for r in range(start, stop):
            if index[r] < 0:
                dest[r - start] = -1
                continue
            row = min(order[r], orders)
            j = fill[row]
            fill[row] += 1
            dest[r - start] = j
            loc_rows[j, 0] = loc[r, 0]
            loc_rows[j, 1] = loc[r, 1]
        for c in range(weight.shape[1]):
            for r in range(start, stop):
                j = dest[r - start]
                if j >= 0:
                    weight_rows[c, j] = weight[r, c]
    return ends[orders]
