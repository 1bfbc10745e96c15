"""The transport kernel, compiled: every path of a chunk, from its start to its end.

``trace_chunk`` loads a chunk's rays into slots (origin, direction, weight, medium,
counts) and alternates two passes over the live paths until none is left: one Embree
query per path (``embree``: Embree's C API called from compiled code, no Python between
queries), then one step per path:

0. **Query.** Each segment is clipped at the first side of the tile's box the ray reaches
   (plus eps, so a face lying on the side is still found); Embree returns the face hit, if
   any. The faces hit are then gathered for all paths at once: independent loads the
   processor overlaps, where one path at a time would wait for each (the face table
   rarely fits a core's cache; this halves the step's cost).
1. **Hit point.** Embree's float32 distance is not used: the point is recomputed in float64
   on the plane of the face hit, n·x = c.
2. **Which side.** A ray in air can hit the front of a face; a ray inside a refracting
   part's medium the back of that part's faces. A hit on the other side whose plane the
   origin lies within 2 eps beyond is the artefact of an offset across a neighbour's plane
   at a concave edge: the ray goes on through it. Any other wrong-side hit ends the path
   (``BACKFACE``: numerical leakage).
3. **Absorption.** Inside an absorbing medium the weight falls by exp(−σ ℓ) over the
   segment's length ℓ (Beer-Lambert; PBR 4th ed., sec. 11.2), ℓ = |Δz| / |d_z| from the
   segment's start (x and y wrap, z does not).
4. **Scattering** by the face's material (``scatter.scatter_event``), with the refracting
   part's medium entered or left when the ray went through the face, unless the bounce
   limit is reached (the path ends, ``BOUNCES``). A face that approximates a curved tube
   scatters at the point where the ray entered the tube, about its normal there
   (``shading.shade_one``); the offset of step 5 follows that normal.
5. **Offset.** The next segment starts ``eps`` off the face on the side its direction
   goes, so it never re-hits the face through round-off.
6. **No hit: the box.** Through the top the path escapes (its direction, weight and order
   are recorded); through the bottom it is transmitted (after a refraction) or leaked;
   through a side it re-enters at the opposite side, unless its straight segment has used
   up its budget of side crossings (``TRAPPED``).
7. **Compaction.** The paths still alive are listed first in ``live`` for the next pass;
   a path's state stays in its slot.

Every ended path writes its outcome at its ray index (``O_*`` columns), so the results
depend on neither the chunking nor the thread that traced it.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from microsim.kernel.embree import INVALID, R_DIR_X, R_GEOM, R_MASK, R_PRIM, R_TFAR, call3
from microsim.kernel.scatter import (
    INLINE,
    JIT,
    MIRROR,
    P_ABSORPTION,
    REFRACTING,
    TABLE_COLUMNS,
    reflect,
    scatter_event,
)
from microsim.kernel.shading import shade_one

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
               tangents: np.ndarray | None) -> np.ndarray:
    """The per-face table the kernel reads (``F_*`` columns; 64 bytes a face, so a hit
    reads one cache line).

    Parameters
    ----------
    normals : (f, 3) float
    plane : (f,) float
    part : (f,) int
    tangents : (f, 3) float or None

    Returns
    -------
    (f, FACE_FLOATS) float
    """
    out = np.zeros((len(normals), FACE_FLOATS))
    out[:, F_NX:F_NZ + 1] = normals
    out[:, F_C] = plane
    out[:, F_PART] = part
    if tangents is not None:
        out[:, F_TX:F_TZ + 1] = tangents
    return out


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
def _aim(slots_f: np.ndarray, i: int, dx: float, dy: float, dz: float, box: np.ndarray
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
    ``_aim`` chose), and its axis (0, 1: a side, 2: the top or bottom)."""
    tx = max((slots_f[i, S_SX] - slots_f[i, S_PX]) * slots_f[i, S_IX], 0.0)
    ty = max((slots_f[i, S_SY] - slots_f[i, S_PY]) * slots_f[i, S_IY], 0.0)
    tz = max((slots_f[i, S_SZ] - slots_f[i, S_PZ]) * slots_f[i, S_IZ], 0.0)
    t = min(tx, ty, tz)
    return t, 0 if tx == t else (1 if ty == t else 2)


@njit(**INLINE)
def _wrap(x: float, period: float) -> float:
    """x moved by whole periods into [0, period)."""
    return x - math.floor(x / period) * period


@njit(**INLINE)
def _wrap_near(x: float, period: float) -> float:
    """x, within one period of [0, period), moved into it (an offset hit point: one
    comparison instead of ``_wrap``'s division)."""
    if x < 0.0:
        return x + period
    if x >= period:
        return x - period
    return x


@njit(**INLINE)
def _queue(slots_f: np.ndarray, slots_i: np.ndarray, live: np.ndarray, q: int, i: int
           ) -> None:
    """Make slot i's next segment query q: its distance to the box's first side and that
    side's axis."""
    t, axis = box_exit(slots_f, i)
    slots_f[i, S_EXIT] = t
    slots_i[i, I_AXIS] = axis
    live[q] = i


# the slots: float64 state (columns S_*) and integer state (columns I_*) per live path
(S_PX, S_PY, S_PZ, S_DX, S_DY, S_DZ, S_W0, S_W1, S_W2, S_A0, S_A1, S_A2, S_T0, S_T1, S_T2,
 S_Z0, S_EXIT, S_UX, S_UY, S_SX, S_SY, S_SZ, S_IX, S_IY, S_IZ) = range(25)
"""Float state of a slot: position (wrapped into the box), direction, weight, absorbed and
transmitted weight so far (RGB), z where the straight segment began, distance to the box's
side, the whole periods the path has been shifted by (for unwrapped path vertices), and
the box sides its direction runs towards with 1 / direction (``_aim``)."""
SLOT_FLOATS = 25
(I_RAY, I_MEDIUM, I_CROSSED, I_BOUNCE, I_SEG, I_BUDGET, I_AXIS) = range(7)
"""Integer state of a slot: the ray's index, its medium (a refracting part; -1: air),
whether it has refracted, its bounces, queries of its straight segment, their budget, and
the box side ``S_EXIT`` leads to."""
SLOT_INTS = 7


@njit(**INLINE)
def start(first: int, origins: np.ndarray, dirs: np.ndarray, media: np.ndarray,
          slots_f: np.ndarray, slots_i: np.ndarray, live: np.ndarray, box: np.ndarray) -> int:
    """Load rays ``first``, ``first + 1``, … into the slots, one per row of ``origins``.

    Parameters
    ----------
    first : int
        Index of the first ray in the run.
    origins, dirs : (k, 3) float
        Start points within the slab (x, y wrapped here) and unit directions of travel.
    media : (k,) int
        Medium each ray starts in (-1: air).
    slots_f, slots_i, live
        The chunk's slots and the slot of each query (at least k rows).
    box : (7,) float

    Returns
    -------
    int
        Slots filled (k).
    """
    k = len(origins)
    for j in range(k):
        px, py = _wrap(origins[j, 0], box[B_LX]), _wrap(origins[j, 1], box[B_LY])
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
            _aim(slots_f, j, dx, dy, dz, box)
            slots_i[j, I_BUDGET] = budget(dx, dy, dz, box)
        for c in range(3):
            slots_f[j, S_W0 + c] = 1.0
            slots_f[j, S_A0 + c] = 0.0
            slots_f[j, S_T0 + c] = 0.0
        slots_f[j, S_Z0] = origins[j, 2]
        slots_i[j, I_RAY] = first + j
        slots_i[j, I_MEDIUM] = media[j]
        slots_i[j, I_CROSSED] = 0
        slots_i[j, I_BOUNCE] = 0
        slots_i[j, I_SEG] = 0
        _queue(slots_f, slots_i, live, j, j)
    return k


@njit(**INLINE)
def _end(slots_f: np.ndarray, slots_i: np.ndarray, i: int, fate: int, out_f: np.ndarray,
         out_i: np.ndarray) -> None:
    """Record how slot i's path ended at its ray's row of the outcomes."""
    r = slots_i[i, I_RAY]
    for c in range(O_FLOATS):
        out_f[r, c] = slots_f[i, c]
    out_i[r, O_FATE] = fate
    out_i[r, O_ORDER] = slots_i[i, I_BOUNCE]


# the outcomes: per ray, the first O_FLOATS float columns of its slot at its end, and
O_FLOATS = S_T2 + 1
"""Float columns of an outcome: the slot's position, direction, weight, absorbed and
transmitted weight (``S_PX`` … ``S_T2``) when the path ended."""
(O_FATE, O_ORDER, O_FACE) = range(3)
"""Integer columns of an outcome: its fate, its bounces, the last face it hit."""
OUT_INTS = 3


@njit(**INLINE)
def advance(prim: np.ndarray, m: int, slots_f: np.ndarray, slots_i: np.ndarray,
            live: np.ndarray, near: np.ndarray, box: np.ndarray, faces: np.ndarray,
            kind: np.ndarray, params: np.ndarray, tab_int: np.ndarray, tab_f: np.ndarray,
            bounces: int, key: np.ndarray, out_f: np.ndarray, out_i: np.ndarray,
            vertices: np.ndarray, curved: np.ndarray) -> int:
    """Move every live path on after one query; see the module's steps 1 to 7.

    Parameters
    ----------
    prim : (m,) int
        The face each of the m queries hit (-1: none).
    m : int
        Queries (live paths).
    slots_f : (w, SLOT_FLOATS) float
    slots_i : (w, SLOT_INTS) int
        The paths' state (a path keeps its slot).
    live : (w,) int
        The slot of each query, rewritten for the paths still alive.
    near : (w, 5) float
        Scratch: the first five ``faces`` columns of each query's face.
    box : (7,) float
        ``B_*`` entries.
    faces : (f, FACE_FLOATS) float
        Per face (one cache line): its unit normal (away from the material), c of its
        plane n·x = c, its part, its unit tangent (zeros when the tile gives none).
    kind : (p,) int
        Material kind per part.
    params : (p, 12) float
        Material parameters per part.
    tab_int : (p, TABLE_COLUMNS) int
        Table layout per part (table materials).
    tab_f : (q,) float
        Packed table data.
    bounces : int
        Scattering events before a path is ended.
    key : (2,) uint64
        The run's random key.
    out_f : (n, O_FLOATS) float
    out_i : (n, OUT_INTS) int
        Outcomes per ray of the run.
    vertices : (n, v, 3) float
        Unwrapped hit points per ray and bounce (v = 0: not recorded).
    curved : (f, 9) or (0, 9) float
        The faces' tubes for shading normals (``shading.curved_table``; no rows: every
        face flat).

    Returns
    -------
    int
        Queries of the paths still alive (compacted to the first ones).
    """
    eps = box[B_EPS]
    lx, ly = box[B_LX], box[B_LY]
    keep = vertices.shape[1]
    # the faces hit, gathered first: independent loads the processor overlaps, where one
    # path at a time would wait for each (the face table rarely fits a core's cache)
    for q in range(m):
        f = prim[q]
        if f >= 0:
            for c in range(5):
                near[q, c] = faces[f, c]
    alive = 0
    for q in range(m):
        f = prim[q]
        i = live[q]
        px, py, pz = slots_f[i, S_PX], slots_f[i, S_PY], slots_f[i, S_PZ]
        dx, dy, dz = slots_f[i, S_DX], slots_f[i, S_DY], slots_f[i, S_DZ]
        medium = slots_i[i, I_MEDIUM]
        slots_i[i, I_SEG] += 1
        go_on = True
        fate = -1
        if f >= 0:
            # 1. the hit point in float64 on the face's plane
            nx, ny, nz = near[q, F_NX], near[q, F_NY], near[q, F_NZ]
            den = dx * nx + dy * ny + dz * nz
            num = near[q, F_C] - (px * nx + py * ny + pz * nz)
            t = max(num / den, 0.0) if den != 0.0 else 0.0
            hx, hy, hz = px + t * dx, py + t * dy, pz + t * dz
            # 2. the side hit: the back of the ray's own medium's faces, else the front
            back = den >= 0.0
            part = int(near[q, F_PART])
            real = back == (part == medium)
            if not real and (num if back else -num) <= 2.0 * eps:
                # an offset's artefact (the origin lies just beyond the plane): go on
                s = eps if back else -eps
                px, py, pz = hx + s * nx, hy + s * ny, hz + s * nz
            elif not real:
                go_on = False
                fate = BACKFACE
                out_i[slots_i[i, I_RAY], O_FACE] = f
                if medium >= 0:
                    _absorb(slots_f, i, params, medium, hz, dz)
                px, py, pz = hx, hy, hz
            else:
                # 3. absorption along the segment inside a medium
                if medium >= 0:
                    _absorb(slots_f, i, params, medium, hz, dz)
                if curved.shape[0] > 0:
                    # a curved face scatters at the tube's entry point, about its normal
                    nx, ny, nz, hx, hy, hz, _ = shade_one(curved, f, hx, hy, hz, dx, dy,
                                                          dz, nx, ny, nz, slots_f[i, S_Z0])
                bounce = slots_i[i, I_BOUNCE]
                if bounce < keep:
                    r = slots_i[i, I_RAY]
                    vertices[r, bounce, 0] = hx + slots_f[i, S_UX]
                    vertices[r, bounce, 1] = hy + slots_f[i, S_UY]
                    vertices[r, bounce, 2] = hz
                if bounce >= bounces:
                    go_on = False
                    fate = BOUNCES
                    out_i[slots_i[i, I_RAY], O_FACE] = f
                    px, py, pz = hx, hy, hz
                    ox, oy, oz = dx, dy, dz
                elif kind[part] == MIRROR:
                    # 4. scattering: a mirror, the commonest event, keeps the weight
                    ox, oy, oz = reflect(dx, dy, dz, nx, ny, nz)
                else:
                    # 4. scattering: the weight takes the factor, the rest is absorbed or
                    # transmitted
                    ox, oy, oz, f0, f1, f2, i0, i1, i2 = scatter_event(
                        kind[part], params, tab_int, part, tab_f, dx, dy, dz, nx, ny, nz,
                        faces[f, F_TX], faces[f, F_TY], faces[f, F_TZ], key,
                        slots_i[i, I_RAY], bounce + 1)
                    w0, w1, w2 = slots_f[i, S_W0], slots_f[i, S_W1], slots_f[i, S_W2]
                    slots_f[i, S_T0] += w0 * i0
                    slots_f[i, S_T1] += w1 * i1
                    slots_f[i, S_T2] += w2 * i2
                    slots_f[i, S_A0] += w0 * (1.0 - f0 - i0)
                    slots_f[i, S_A1] += w1 * (1.0 - f1 - i1)
                    slots_f[i, S_A2] += w2 * (1.0 - f2 - i2)
                    slots_f[i, S_W0], slots_f[i, S_W1], slots_f[i, S_W2] = (w0 * f0, w1 * f1,
                                                                            w2 * f2)
                    if kind[part] == REFRACTING:
                        # through the face (the direction kept the side of d·n): into the
                        # part's medium when it now goes behind the face, else out to air
                        side_out = ox * nx + oy * ny + oz * nz
                        if den * side_out > 0.0:
                            slots_i[i, I_MEDIUM] = part if side_out < 0.0 else -1
                            slots_i[i, I_CROSSED] = 1
                if go_on:
                    dx, dy, dz = ox, oy, oz
                    _aim(slots_f, i, dx, dy, dz, box)
                    slots_i[i, I_BOUNCE] = bounce + 1
                    # 5. the offset off the face, on the side the new direction goes
                    s = eps if dx * nx + dy * ny + dz * nz >= 0.0 else -eps
                    px, py, pz = hx + s * nx, hy + s * ny, hz + s * nz
                    slots_f[i, S_Z0] = pz
                    slots_i[i, I_SEG] = 0
                    slots_i[i, I_BUDGET] = budget(dx, dy, dz, box)
            if go_on:
                # the next origin (a hit point offset by eps), wrapped into the box
                wx, wy = _wrap_near(px, lx), _wrap_near(py, ly)
                slots_f[i, S_UX] += px - wx
                slots_f[i, S_UY] += py - wy
                px, py = wx, wy
        else:
            # 6. no face before the box's side
            t = slots_f[i, S_EXIT]
            axis = slots_i[i, I_AXIS]
            if axis == 2:
                go_on = False
                if medium >= 0:
                    _absorb(slots_f, i, params, medium,
                            box[B_TOP] if dz > 0.0 else box[B_BOTTOM], dz)
                if dz > 0.0:
                    fate = ESCAPED
                else:
                    fate = TRANSMITTED if slots_i[i, I_CROSSED] else LEAKED
            else:
                # on into the neighbouring tile: enter at the opposite side exactly
                px = min(max(px + t * dx, 0.0), lx)
                py = min(max(py + t * dy, 0.0), ly)
                pz = pz + t * dz
                if axis == 0:
                    slots_f[i, S_UX] += lx if dx > 0.0 else -lx
                    px = 0.0 if dx > 0.0 else lx
                else:
                    slots_f[i, S_UY] += ly if dy > 0.0 else -ly
                    py = 0.0 if dy > 0.0 else ly
        if go_on and slots_i[i, I_SEG] >= slots_i[i, I_BUDGET]:
            go_on = False
            fate = TRAPPED
        slots_f[i, S_PX], slots_f[i, S_PY], slots_f[i, S_PZ] = px, py, pz
        if not go_on:
            _end(slots_f, slots_i, i, fate, out_f, out_i)
            continue
        # 7. compaction: the path's next query is number `alive` (never above q)
        _queue(slots_f, slots_i, live, alive, i)
        alive += 1
    return alive


@njit(**JIT)
def trace_chunk(first: int, origins: np.ndarray, dirs: np.ndarray, media: np.ndarray,
                scene: int, intersect: int, rayhit: np.ndarray, slots_f: np.ndarray,
                slots_i: np.ndarray, live: np.ndarray, near: np.ndarray, prim: np.ndarray,
                box: np.ndarray, faces: np.ndarray, kind: np.ndarray,
                params: np.ndarray, tab_int: np.ndarray, tab_f: np.ndarray, bounces: int,
                key: np.ndarray, out_f: np.ndarray, out_i: np.ndarray,
                vertices: np.ndarray, curved: np.ndarray) -> int:
    """Trace rays ``first``, ``first + 1``, … (one per row of ``origins``) to their ends.

    Parameters
    ----------
    first : int
        Index of the first ray in the run (its row of the outcomes, its random numbers).
    origins, dirs : (k, 3) float
        Start points within the slab (x, y wrapped here) and unit directions of travel.
    media : (k,) int
        Medium each ray starts in (-1: air).
    scene, intersect : int
        The ``RTCScene`` and the address of ``rtcIntersect1`` (``embree.Scene``).
    rayhit : (RAYHIT_WORDS,) float32
        A 16-byte-aligned ``RTCRayHit`` record of the calling thread (``embree``).
    slots_f : (w, SLOT_FLOATS) float
    slots_i : (w, SLOT_INTS) int
    live, prim : (w,) int
    near : (w, 5) float
        The calling thread's path state, its queries and their answers, w ≥ k.
    box : (7,) float
        ``B_*`` entries.
    faces : (f, FACE_FLOATS) float
        Per face (one cache line): its unit normal (away from the material), c of its
        plane n·x = c, its part, its unit tangent (zeros when the tile gives none).
    kind : (p,) int
        Material kind per part.
    params : (p, 12) float
        Material parameters per part.
    tab_int : (p, TABLE_COLUMNS) int
        Table layout per part (table materials).
    tab_f : (q,) float
        Packed table data.
    bounces : int
        Scattering events before a path is ended.
    key : (2,) uint64
        The run's random key.
    out_f : (n, O_FLOATS) float
    out_i : (n, OUT_INTS) int
        Outcomes per ray of the run.
    vertices : (n, v, 3) float
        Unwrapped hit points per ray and bounce (v = 0: not recorded).
    curved : (f, 9) or (0, 9) float
        The faces' tubes for shading normals (``shading.curved_table``; no rows: every
        face flat).

    Returns
    -------
    int
        Embree queries made.
    """
    segments = 0
    m = start(first, origins, dirs, media, slots_f, slots_i, live, box)
    while m:
        _query(m, live, slots_f, rayhit, scene, intersect, prim, box[B_EPS])
        segments += m
        m = advance(prim, m, slots_f, slots_i, live, near, box, faces, kind, params,
                    tab_int, tab_f, bounces, key, out_f, out_i, vertices, curved)
    return segments


@njit(**INLINE)
def _query(m: int, live: np.ndarray, slots_f: np.ndarray, rayhit: np.ndarray, scene: int,
           intersect: int, prim: np.ndarray, eps: float) -> None:
    """Step 0: Embree's closest hit of every live path's segment (``rtcIntersect1``), its
    face in ``prim`` (-1: none)."""
    words = rayhit.view(np.uint32)
    record = rayhit.ctypes.data
    rayhit[3] = 0.0  # tnear
    rayhit[7] = 0.0  # time
    words[R_MASK + 1] = 0  # id
    words[R_MASK + 2] = 0  # flags
    for q in range(m):
        i = live[q]
        for c in range(3):
            rayhit[c] = slots_f[i, S_PX + c]
            rayhit[R_DIR_X + c] = slots_f[i, S_DX + c]
        rayhit[R_TFAR] = slots_f[i, S_EXIT] + eps
        words[R_MASK] = INVALID
        words[R_GEOM] = INVALID
        call3(intersect, scene, record, 0)
        prim[q] = -1 if words[R_GEOM] == INVALID else int(words[R_PRIM])


@njit(**INLINE)
def _absorb(slots_f: np.ndarray, i: int, params: np.ndarray, medium: int, z_end: float,
            dz: float) -> None:
    """Beer-Lambert attenuation exp(−σ ℓ) of slot i's weight over its straight segment in
    the medium of part ``medium``, ℓ = |z_end − z_start| / |d_z| (a segment parallel to the
    slab never leaves: ℓ = ∞)."""
    length = abs(z_end - slots_f[i, S_Z0]) / abs(dz) if dz != 0.0 else math.inf
    for c in range(3):
        sigma = params[medium, P_ABSORPTION + c]
        if sigma > 0.0:
            before = slots_f[i, S_W0 + c]
            after = before * math.exp(-sigma * length)
            slots_f[i, S_W0 + c] = after
            slots_f[i, S_A0 + c] += before - after


def empty_tables(parts: int) -> tuple[np.ndarray, np.ndarray]:
    """``tab_int`` and ``tab_f`` of ``parts`` materials without tables."""
    return np.zeros((parts, TABLE_COLUMNS), np.int64), np.zeros(1)
