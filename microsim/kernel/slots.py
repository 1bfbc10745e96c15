"""A path's state in the transport kernel, compiled: the tile's box, the per-face table,
the slots that hold every live path, and the outcomes that record how each path ended.

A chunk's paths live in slots (``S_*`` float and ``I_*`` integer columns) that
``microsim.kernel.transport`` moves on after every Embree query; a path keeps its slot,
and ``queue`` lists the slots still alive for the next query. Every ended path writes its
outcome (``O_*`` columns) at its ray's row, and the weight it transmitted, and that ended
at a dispersive event, is added to its run's sums of its block of the beam in beam order
once the chunk's paths have ended (``add_energy``), so the results depend on neither the
chunking nor the thread that traced it.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from microsim.jit import INLINE, JIT
from microsim.materials.base import PARAMS
from microsim.materials.table import TABLE_COLUMNS

ESCAPED, BOUNCES, TRANSMITTED, LEAKED, TRAPPED, BACKFACE = range(6)
"""How a path ends: out through the top, alive after the bounce limit (for a query without
bounces: a face hit), out through the bottom after a refraction, out through the bottom
otherwise, out of side crossings, or a hit on the wrong side of a face."""
FATES = ("escaped", "bounces", "transmitted", "leaked", "trapped", "backface")
MAX_SEGMENTS = 10_000
"""Upper bound of queries of one straight segment: a direction so nearly horizontal that it
would need more side crossings to cross the slab is trapped."""
(B_LX, B_LY, B_BOTTOM, B_TOP, B_EPS, B_IX, B_IY) = range(7)
"""Entries of the ``box`` array: the periods, the bottom and top of the slab, the offset,
the inverse periods."""
NO_FACE = -1
(F_NX, F_NY, F_NZ, F_C, F_PART, F_TX, F_TY, F_TZ) = range(8)
"""Columns of the per-face table: unit normal, plane constant, part, tangent."""
FACE_FLOATS = 8


def face_table(normals: np.ndarray, plane: np.ndarray, part: np.ndarray,
               tangents: np.ndarray | None, out: np.ndarray | None = None) -> np.ndarray:
    """The per-face table the kernel reads (``F_*`` columns; 64 bytes a face, so a hit
    reads one cache line).

    Parameters
    ----------
    normals : (f, 3) float
    plane : (f,) float
    part : (f,) int
    tangents : (f, 3) float or None
    out : (f, FACE_FLOATS) float or None
        A table to overwrite (an earlier one of as many faces: no new memory to fault
        in); None or another shape: a new one.

    Returns
    -------
    (f, FACE_FLOATS) float
        Tangents 0 where ``tangents`` is None.
    """
    if out is None or out.shape != (len(normals), FACE_FLOATS):
        out = np.empty((len(normals), FACE_FLOATS))
    _fill_faces(out, normals, plane, part, np.zeros((0, 3)) if tangents is None else tangents)
    return out


@njit(**JIT)
def _fill_faces(out: np.ndarray, normals: np.ndarray, plane: np.ndarray, part: np.ndarray,
                tangents: np.ndarray) -> None:
    """``face_table``'s rows, one face at a time (a row is one cache line: 4 times faster
    than numpy's strided column copies); ``tangents`` (f, 3), or (0, 3) for none."""
    given = len(tangents) > 0
    for i in range(len(out)):
        out[i, F_NX] = normals[i, 0]
        out[i, F_NY] = normals[i, 1]
        out[i, F_NZ] = normals[i, 2]
        out[i, F_C] = plane[i]
        out[i, F_PART] = part[i]
        out[i, F_TX] = tangents[i, 0] if given else 0.0
        out[i, F_TY] = tangents[i, 1] if given else 0.0
        out[i, F_TZ] = tangents[i, 2] if given else 0.0


@njit(**INLINE)
def budget(dx: float, dy: float, dz: float, box: np.ndarray) -> int:
    """Most queries a straight segment may need: across the slab (length at most
    height / |d_z|) it crosses each pair of sides at most length |d_axis| / L + 1 times;
    doubled for slack, capped at ``MAX_SEGMENTS``."""
    reach = (abs(dx) * box[B_IX] + abs(dy) * box[B_IY]) * (box[B_TOP] - box[B_BOTTOM])
    crossings = reach / max(abs(dz), 1e-300)
    return int(min(2.0 * math.ceil(crossings) + 8.0, float(MAX_SEGMENTS)))


@njit(**INLINE)
def _target(d: float, low: float, high: float) -> tuple[float, float]:
    """The side of [low, high] a ray of direction component d runs towards, and 1 / d, so
    that its distance from o is (side − o) / d; for d = 0, (inf, 1): never reached."""
    side = high if d > 0.0 else (low if d < 0.0 else math.inf)
    return side, (1.0 / d if d != 0.0 else 1.0)


@njit(**INLINE)
def aim(slots_f: np.ndarray, i: int, dx: float, dy: float, dz: float, box: np.ndarray
         ) -> None:
    """Set slot i's direction, and the box sides it runs towards with 1 / direction
    (``box_exit`` then needs no branch and no division)."""
    slots_f[i, S_DX], slots_f[i, S_DY], slots_f[i, S_DZ] = dx, dy, dz
    slots_f[i, S_SX], slots_f[i, S_IX] = _target(dx, 0.0, box[B_LX])
    slots_f[i, S_SY], slots_f[i, S_IY] = _target(dy, 0.0, box[B_LY])
    slots_f[i, S_SZ], slots_f[i, S_IZ] = _target(dz, box[B_BOTTOM], box[B_TOP])


@njit(**INLINE)
def box_exit(slots_f: np.ndarray, i: int) -> tuple[float, int]:
    """Distance to the first side of the tile's box along slot i's ray (from the sides
    ``aim`` chose), and its axis (0, 1: a side, 2: the top or bottom)."""
    tx = max((slots_f[i, S_SX] - slots_f[i, S_PX]) * slots_f[i, S_IX], 0.0)
    ty = max((slots_f[i, S_SY] - slots_f[i, S_PY]) * slots_f[i, S_IY], 0.0)
    tz = max((slots_f[i, S_SZ] - slots_f[i, S_PZ]) * slots_f[i, S_IZ], 0.0)
    t = min(tx, ty, tz)
    return t, 0 if tx == t else (1 if ty == t else 2)


@njit(**INLINE)
def wrap(x: float, period: float) -> float:
    """x moved by whole periods into [0, period)."""
    return x - math.floor(x / period) * period


@njit(**INLINE)
def wrap_near(x: float, period: float) -> float:
    """x, within one period of [0, period), moved into it (an offset hit point: one
    comparison instead of ``_wrap``'s division)."""
    if x < 0.0:
        return x + period
    if x >= period:
        return x - period
    return x


@njit(**INLINE)
def queue(slots_f: np.ndarray, slots_i: np.ndarray, live: np.ndarray, q: int, i: int
           ) -> None:
    """Make slot i's next segment query q: its distance to the box's first side and that
    side's axis."""
    t, axis = box_exit(slots_f, i)
    slots_f[i, S_EXIT] = t
    slots_i[i, I_AXIS] = axis
    live[q] = i


# the slots: float64 state (columns S_*) and integer state (columns I_*) per live path
(S_PX, S_PY, S_PZ, S_DX, S_DY, S_DZ, S_Z0, S_EXIT, S_UX, S_UY, S_SX, S_SY, S_SZ, S_IX, S_IY,
 S_IZ, S_W) = range(17)
"""Float state of a slot: position (wrapped into the box), direction, z where the straight
segment began, distance to the box's side, the whole periods the path has been shifted by
(for unwrapped path vertices), the box sides its direction runs towards with
1 / direction (``aim``), and from ``S_W`` on, per channel c of C, the weight (column
S_W + c), the weight ended so far without being absorbed or transmitted (S_W + C + c: at
a dispersive event, the other channels' weights, and the hero's gain, negative) and the
weight transmitted so far (S_W + 2C + c). What a path absorbs is not kept: it is what
its weight lost otherwise (``add_energy``)."""


def slot_floats(channels: int) -> int:
    """Float columns of a slot of a run of ``channels`` channels."""
    return S_W + 3 * channels


(I_RAY, I_MEDIUM, I_CROSSED, I_BOUNCE, I_SEG, I_BUDGET, I_AXIS, I_HERO, I_RUN,
 I_COUNT) = range(10)
"""Integer state of a slot: the ray's row of the outcomes, its medium (a refracting
part; -1: air), whether it has refracted, its bounces, queries of its straight segment,
their budget, the box side ``S_EXIT`` leads to, its hero channel once a dispersive event
has left it only that one (-1 before: every channel follows the path), the run it belongs
to, and its index in that run (the counter of its random numbers)."""
SLOT_INTS = 10


@njit(**INLINE)
def start(origins: np.ndarray, dirs: np.ndarray, media: np.ndarray, rows: np.ndarray,
          runs: np.ndarray, run_rows: np.ndarray, slots_f: np.ndarray, slots_i: np.ndarray,
          live: np.ndarray, box: np.ndarray) -> int:
    """Load a chunk's rays into the slots, one per row of ``origins``.

    Parameters
    ----------
    origins, dirs : (k, 3) float
        Start points within the slab (x, y wrapped here) and unit directions of travel.
    media : (k,) int
        Medium each ray starts in (-1: air).
    rows, runs : (k,) int
        Each ray's row of the outcomes and its run.
    run_rows : (b,) int
        The first row of each run: a ray's index in its run is its row less its run's.
    slots_f, slots_i, live
        The chunk's slots and the slot of each query (at least k rows).
    box : (7,) float

    Returns
    -------
    int
        Slots filled (k).
    """
    k = len(origins)
    channels = (slots_f.shape[1] - S_W) // 3
    for j in range(k):
        px, py = wrap(origins[j, 0], box[B_LX]), wrap(origins[j, 1], box[B_LY])
        slots_f[j, S_PX], slots_f[j, S_PY], slots_f[j, S_PZ] = px, py, origins[j, 2]
        slots_f[j, S_UX], slots_f[j, S_UY] = origins[j, 0] - px, origins[j, 1] - py
        dx, dy, dz = dirs[j, 0], dirs[j, 1], dirs[j, 2]
        if j > 0 and dx == dirs[j - 1, 0] and dy == dirs[j - 1, 1] and dz == dirs[j - 1, 2]:
            # a beam: the previous ray's sides, reciprocals and budget
            for c in range(S_DX, S_DZ + 1):
                slots_f[j, c] = slots_f[j - 1, c]
            for c in range(S_SX, S_IZ + 1):
                slots_f[j, c] = slots_f[j - 1, c]
            slots_i[j, I_BUDGET] = slots_i[j - 1, I_BUDGET]
        else:
            aim(slots_f, j, dx, dy, dz, box)
            slots_i[j, I_BUDGET] = budget(dx, dy, dz, box)
        for c in range(S_W, S_W + channels):
            slots_f[j, c] = 1.0
        for c in range(S_W + channels, S_W + 3 * channels):
            slots_f[j, c] = 0.0
        slots_f[j, S_Z0] = origins[j, 2]
        slots_i[j, I_RAY] = rows[j]
        slots_i[j, I_RUN] = runs[j]
        slots_i[j, I_COUNT] = rows[j] - run_rows[runs[j]]
        slots_i[j, I_MEDIUM] = media[j]
        slots_i[j, I_CROSSED] = 0
        slots_i[j, I_BOUNCE] = 0
        slots_i[j, I_SEG] = 0
        slots_i[j, I_HERO] = -1
        queue(slots_f, slots_i, live, j, j)
    return k


@njit(**INLINE)
def end(slots_f: np.ndarray, slots_i: np.ndarray, i: int, fate: int, out_f: np.ndarray,
         out_i: np.ndarray) -> None:
    """Record how slot i's path ended at its ray's row of the outcomes (the weight it lost
    on the way stays in its slot: ``add_energy``)."""
    r = slots_i[i, I_RAY]
    for c in range(O_W):
        out_f[r, c] = slots_f[i, c]
    for c in range(out_f.shape[1] - O_W):
        out_f[r, O_W + c] = slots_f[i, S_W + c]
    out_i[r, O_FATE] = fate
    out_i[r, O_ORDER] = slots_i[i, I_BOUNCE]


@njit(**INLINE)
def add_energy(first: int, k: int, slots_f: np.ndarray, slots_i: np.ndarray,
               out: np.ndarray) -> None:
    """Add the weight the paths of slots 0 … k − 1 (the rays at places ``first`` … of the
    beam, all ended) transmitted, and that ended at a dispersive event, to the sums of
    their block of the beam and their run, ray by ray in beam order (``ENERGY_BLOCK``;
    ``out`` (blocks, runs, 2, C): transmitted and ended, transmitted). A path starts with
    weight 1 per channel and keeps what it has at its end (escaped or lost), so what it
    absorbed is
    1 − its weight − what it transmitted − what ended at a dispersive event: the sum of
    its events' losses w (1 − F − T) and its media's w (1 − e^(−σℓ)) in exact arithmetic,
    without adding them event by event; 1 − its weight is summed from its outcome
    (``tally.summarise``), the rest here. Where no part transmits or disperses, these
    sums are zero whatever rays share a block (``FacetMaterials.divides_weight``)."""
    channels = out.shape[3]
    for j in range(k):
        b, run = (first + j) // ENERGY_BLOCK, slots_i[j, I_RUN]
        for c in range(channels):
            sent = slots_f[j, S_W + 2 * channels + c]
            out[b, run, 0, c] += sent + slots_f[j, S_W + channels + c]
            out[b, run, 1, c] += sent


# the outcomes: per ray, its slot's position, direction and weights at its end, and
O_W = S_DZ + 1
"""Float columns of an outcome: the slot's position and direction (``S_PX`` … ``S_DZ``)
when the path ended, then from ``O_W`` on its weight per channel (O_W + c)."""
ENERGY_BLOCK = 64
"""Rays per block of the beam of a run's sums of transmitted and ended weight
(``add_energy``), which are kept per block, not per ray: two fewer floats of outcome per
ray and channel to write and read back (two thirds of the outcomes' memory traffic at 32
channels). A block's sums add its rays in beam order, so they depend on neither the thread
nor the chunking, as long as every chunk holds whole blocks (``PeriodicScene`` asks for a
chunk that is a multiple of this)."""


def out_floats(channels: int) -> int:
    """Float columns of an outcome of a run of ``channels`` channels."""
    return O_W + channels


def energy_blocks(rays: int) -> int:
    """Blocks of the energy sums of a beam of ``rays`` rays (``ENERGY_BLOCK``)."""
    return -(-rays // ENERGY_BLOCK)


(O_FATE, O_ORDER, O_FACE) = range(3)
"""Integer columns of an outcome: its fate, its bounces, the last face it hit."""
OUT_INTS = 3


def empty_tables(parts: int) -> tuple[np.ndarray, np.ndarray]:
    """``tab_int`` and ``tab_f`` of ``parts`` materials without tables."""
    return np.zeros((parts, TABLE_COLUMNS), np.int64), np.zeros(1)


def empty_params(parts: int) -> tuple[np.ndarray, np.ndarray]:
    """``kind`` and ``params`` of ``parts`` materials of kind code 0 that enclose no
    medium, with three channels (for queries without scattering)."""
    return np.zeros(parts, np.int64), np.zeros((parts, PARAMS, 3))
