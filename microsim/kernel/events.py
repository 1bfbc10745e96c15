"""The facet materials' scattering events, compiled behind one dispatch.

Every kind of ``microsim.materials`` brings its event in kernel language
(``Material.scatter``: scalar Python); this module compiles them with numba and chains
them by kind code (the kind's index in ``microsim.materials.KINDS``) into
``scatter_event``, which the transport kernel calls at every hit but a perfect mirror's
(``Material.mirror``: reflected inline): one compiled function whose if-chain over the
kinds is inlined, as fast as one written by hand. An event's random numbers come from
``rng.uniforms`` keyed by (ray, event), so they never depend on which thread traces the
ray; each kind draws only the blocks of four it reads (``Material.blocks``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numba import njit
from numba.extending import register_jitable

from microsim.jit import INLINE, JIT
from microsim.kernel.rng import uniforms
from microsim.materials import KINDS
from microsim.materials.base import KERNEL_FUNCTIONS, TRANSMITTING, WEIGHTED, Material

for _function in KERNEL_FUNCTIONS:
    if _function not in {kind.scatter for kind in KINDS}:
        register_jitable(_function)


@njit(**INLINE)
def draws(blocks: int, key: np.ndarray, ray: int, event: int) -> tuple[float, ...]:
    """Eight uniforms for one ray and event: ``blocks`` blocks of four drawn, the rest 0."""
    if blocks == 0:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    a, b, c, d = uniforms(key, ray, event, 0)
    if blocks == 1:
        return a, b, c, d, 0.0, 0.0, 0.0, 0.0
    e, f, g, h = uniforms(key, ray, event, 1)
    return a, b, c, d, e, f, g, h


@njit(**INLINE)
def _no_kind(kind: int, params: np.ndarray, tab_int: np.ndarray, tab_f: np.ndarray,
             part: int, dx: float, dy: float, dz: float, nx: float, ny: float, nz: float,
             ex: float, ey: float, ez: float, key: np.ndarray, ray: int, event: int,
             hero: int, fac: np.ndarray) -> tuple[float, float, float, int]:
    """The end of the chain, which no registered code reaches: everything absorbed."""
    fac[0, :] = 0.0
    return dx, dy, dz, WEIGHTED


def _link(code: int, kind: type[Material], rest: Callable[..., Any]) -> Callable[..., Any]:
    """``scatter_event`` for codes ≥ ``code``: kind ``code``'s event, else ``rest``."""
    event = njit(**INLINE)(kind.scatter)
    blocks = kind.blocks

    @njit(**INLINE)
    def link(k: int, params: np.ndarray, tab_int: np.ndarray, tab_f: np.ndarray, part: int,
             dx: float, dy: float, dz: float, nx: float, ny: float, nz: float, ex: float,
             ey: float, ez: float, key: np.ndarray, ray: int, bounce: int, hero: int,
             fac: np.ndarray) -> tuple[float, float, float, int]:
        if k == code:
            return event(params, tab_int, tab_f, part, dx, dy, dz, nx, ny, nz, ex, ey, ez,
                         draws(blocks, key, ray, bounce), hero, fac)
        return rest(k, params, tab_int, tab_f, part, dx, dy, dz, nx, ny, nz, ex, ey, ez,
                    key, ray, bounce, hero, fac)

    return link


_chain = _no_kind
for _code in reversed(range(len(KINDS))):
    _chain = _link(_code, KINDS[_code], _chain)


@njit(**JIT)
def scatter_event(kind: int, params: np.ndarray, tab_int: np.ndarray, tab_f: np.ndarray,
                  part: int, dx: float, dy: float, dz: float, nx: float, ny: float,
                  nz: float, ex: float, ey: float, ez: float, key: np.ndarray, ray: int,
                  event: int, hero: int, fac: np.ndarray
                  ) -> tuple[float, float, float, int]:
    """One scattering event at a facet of unit normal n (``d·n < 0``, except at a
    refracting facet, which is hit from either side): kind ``kind``'s event.

    Parameters
    ----------
    kind : int
        The material's kind code.
    params : (p, PARAMS, C) float
        Every part's parameter block (``microsim.materials.base``).
    tab_int : (p, TABLE_COLUMNS) int
        Every part's table layout (``table`` kinds).
    tab_f : (q,) float
        Packed table data.
    part : int
        The material's row.
    dx, dy, dz : float
        Unit direction of travel.
    nx, ny, nz : float
        Unit facet normal.
    ex, ey, ez : float
        The face's tangent.
    key : (2,) uint64
        The run's random key.
    ray, event : int
        The ray's index in its run and the event's number (its bounce, from 1).
    hero : int
        The path's hero channel (the one a dispersive event follows).
    fac : (2, C) float
        Filled with the factor per channel (row 0) and the transmitted fraction (row 1).

    Returns
    -------
    tuple of 3 float and an int
        New unit direction, and what the event did to the weight (``WEIGHTED``,
        ``TRANSMITTING``, ``KEPT`` or ``HERO``: ``microsim.materials.base``; ``fac``'s row 0
        is written for ``WEIGHTED`` and ``TRANSMITTING``, its row 1 for ``TRANSMITTING``
        only).
    """
    return _chain(kind, params, tab_int, tab_f, part, dx, dy, dz, nx, ny, nz, ex, ey, ez,
                  key, ray, event, hero, fac)


@njit(**JIT)
def scatter_all(faces: np.ndarray, d: np.ndarray, n: np.ndarray, face_material: np.ndarray,
                tangents: np.ndarray, kind: np.ndarray, params: np.ndarray,
                tab_int: np.ndarray, tab_f: np.ndarray, key: np.ndarray, event: int,
                out: np.ndarray, fac: np.ndarray) -> None:
    """``scatter_event`` for every ray r at face ``faces[r]``: its direction in row r of
    ``out`` ((k, 3)), its factor and transmitted fraction in ``fac[r]`` ((k, 2, C); hero
    channel r mod C), for tests and drawings."""
    channels = fac.shape[2]
    for r in range(len(faces)):
        f = faces[r]
        part = face_material[f]
        out[r, 0], out[r, 1], out[r, 2], outcome = scatter_event(
            kind[part], params, tab_int, tab_f, part, d[r, 0], d[r, 1], d[r, 2], n[r, 0],
            n[r, 1], n[r, 2], tangents[f, 0], tangents[f, 1], tangents[f, 2], key, r,
            event, r % channels, fac[r])
        if outcome != WEIGHTED and outcome != TRANSMITTING:
            fac[r, 0] = 1.0
        if outcome != TRANSMITTING:
            fac[r, 1] = 0.0
