"""Counter-based random numbers: Philox4x64-10.

A uniform number is a pure function of (key, counter): the key comes from the run's seed,
the counter names the ray, the scattering event and the dimension, so a path draws the same
numbers whichever thread traces it and however the rays are chunked (Salmon, Moraes, Dror &
Shaw 2011, "Parallel random numbers: as easy as 1, 2, 3", SC '11, sec. 4: the Philox
bijection, 10 rounds, with their multipliers and Weyl key increments; the same generator as
``numpy.random.Philox``, against which the tests check it).
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import njit, types, uint64
from numba.extending import intrinsic

from microsim.jit import INLINE, JIT

M0 = np.uint64(0xD2E7470EE14C6C93)
M1 = np.uint64(0xCA5A826395121157)
W0 = np.uint64(0x9E3779B97F4A7C15)
W1 = np.uint64(0xBB67AE8584CAA73B)
S11 = np.uint64(11)
TO_UNIT = 1.0 / 9007199254740992.0
"""2^-53: a 53-bit integer to a double in [0, 1)."""


@intrinsic
def _mulhi(typingctx, a, b):  # noqa: ANN001, ANN201 (numba intrinsic signature)
    """High 64-bit word of the 128-bit product a·b of two uint64 (one machine multiply)."""
    sig = types.uint64(types.uint64, types.uint64)

    def codegen(context, builder, signature, args):  # noqa: ANN001, ANN202
        wide = ir.IntType(128)
        product = builder.mul(builder.zext(args[0], wide), builder.zext(args[1], wide))
        return builder.trunc(builder.lshr(product, ir.Constant(wide, 64)), ir.IntType(64))

    return sig, codegen


@njit(**JIT)
def philox(c0: uint64, c1: uint64, c2: uint64, c3: uint64, k0: uint64, k1: uint64
           ) -> tuple[uint64, uint64, uint64, uint64]:
    """Philox4x64-10 of the counter (c0, c1, c2, c3) under the key (k0, k1).

    Each round: (hi0, lo0) = M0·c0, (hi1, lo1) = M1·c2, then
    c = (hi1 ^ c1 ^ k0, lo1, hi0 ^ c3 ^ k1, lo0), and the key moves by the Weyl constants.
    """
    for _ in range(10):
        hi0, lo0 = _mulhi(M0, c0), M0 * c0
        hi1, lo1 = _mulhi(M1, c2), M1 * c2
        c0, c1, c2, c3 = hi1 ^ c1 ^ k0, lo1, hi0 ^ c3 ^ k1, lo0
        k0 += W0
        k1 += W1
    return c0, c1, c2, c3


@njit(**INLINE)
def unit(x: uint64) -> float:
    """The top 53 bits of a 64-bit word as a double in [0, 1) (numpy's ``next_double``)."""
    return float(x >> S11) * TO_UNIT


@njit(**INLINE)
def uniforms(key: np.ndarray, ray: int, event: int, block: int
             ) -> tuple[float, float, float, float]:
    """Four uniform numbers in [0, 1) for one ray and event.

    Parameters
    ----------
    key : (2,) uint64
        The run's key.
    ray : int
        Index of the ray in its run (>= 0).
    event : int
        Scattering event (0: the ray's start, k: the k-th hit).
    block : int
        Which four numbers of the event (0, 1, ...).
    """
    c0, c1, c2, c3 = philox(uint64(ray), uint64(event), uint64(block), uint64(0),
                            key[0], key[1])
    return unit(c0), unit(c1), unit(c2), unit(c3)


def key_of(seed: np.random.SeedSequence) -> np.ndarray:
    """(2,) uint64 Philox key of a seed sequence (its first two 64-bit state words)."""
    return seed.generate_state(2, np.uint64)
