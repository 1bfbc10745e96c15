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
   limit is reached (the path ends, ``BOUNCES``). A path carries one weight per channel
   (R, G, B, or a spectral table's wavelengths), each multiplied by its own factor; where
   the event's direction depends on the wavelength (a dispersive or coated refracting
   part), the path follows its hero channel, ray mod C, alone from there
   (``_follow_hero``; docs/spectral.md). A face that approximates a curved tube
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

Every ended path writes its outcome at its ray's row (``O_*`` columns), and once every
path of the chunk has ended, the weight each transmitted and that ended at a dispersive
event is added to its run's sums of its block in beam order (``slots.add_energy``, blocks
of ``ENERGY_BLOCK`` rays, never split between chunks; what it absorbed is what it started
with, 1, less its weight at the end and those), so the results depend on neither the
chunking nor the thread that traced it. A ray's random numbers are keyed by
its run and counted by its index in the run, so a run's paths are the same whether it is
traced alone or in a beam with others.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from microsim.jit import INLINE, JIT
from microsim.kernel.embree import INVALID, R_DIR_X, R_GEOM, R_MASK, R_PRIM, R_TFAR, call3
from microsim.kernel.events import scatter_event
from microsim.kernel.shading import shade_one
from microsim.kernel.slots import (
    B_BOTTOM,
    B_EPS,
    B_LX,
    B_LY,
    B_TOP,
    BACKFACE,
    BOUNCES,
    ESCAPED,
    F_C,
    F_NX,
    F_NY,
    F_NZ,
    F_PART,
    F_TX,
    F_TY,
    F_TZ,
    I_AXIS,
    I_BOUNCE,
    I_BUDGET,
    I_COUNT,
    I_CROSSED,
    I_HERO,
    I_MEDIUM,
    I_RAY,
    I_RUN,
    I_SEG,
    LEAKED,
    O_FACE,
    S_DX,
    S_DY,
    S_DZ,
    S_EXIT,
    S_PX,
    S_PY,
    S_PZ,
    S_UX,
    S_UY,
    S_W,
    S_Z0,
    TRANSMITTED,
    TRAPPED,
    add_energy,
    aim,
    budget,
    end,
    queue,
    start,
    wrap_near,
)
from microsim.materials.base import (
    DISPERSION_ALWAYS,
    HERO,
    P_ABSORPTION,
    P_DISPERSIVE,
    P_MEDIUM,
    P_MIRROR,
    TRANSMITTING,
    WEIGHTED,
)
from microsim.materials.optics import reflect


@njit(**INLINE)
def advance(prim: np.ndarray, m: int, slots_f: np.ndarray, slots_i: np.ndarray,
            live: np.ndarray, near: np.ndarray, box: np.ndarray, faces: np.ndarray,
            kind: np.ndarray, params: np.ndarray, tab_int: np.ndarray, tab_f: np.ndarray,
            bounces: int, keys: np.ndarray, out_f: np.ndarray, out_i: np.ndarray,
            vertices: np.ndarray, curved: np.ndarray, fac: np.ndarray) -> int:
    """Move every live path on after one query; see the module's steps 1 to 7.

    Parameters
    ----------
    prim : (m,) int
        The face each of the m queries hit (-1: none).
    m : int
        Queries (live paths).
    slots_f : (w, slot_floats(C)) float
    slots_i : (w, SLOT_INTS) int
        The paths' state (a path keeps its slot).
    live : (w,) int
        The slot of each query, rewritten for the paths still alive.
    near : (w, 5) float
        Scratch: the first five ``faces`` columns of each query's face.
    box, faces, kind, params, tab_int, tab_f, bounces, keys, out_f, out_i, vertices, curved
        As for ``trace_chunk``.
    fac : (2, C) float
        Scratch: an event's factors (``scatter_event``).

    Returns
    -------
    int
        Queries of the paths still alive (compacted to the first ones).
    """
    eps = box[B_EPS]
    lx, ly = box[B_LX], box[B_LY]
    keep = vertices.shape[1]
    channels = fac.shape[1]
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
                elif params[part, P_MIRROR, 0] != 0.0:
                    # 4. scattering: a perfect mirror, the commonest event, keeps the weight
                    ox, oy, oz = reflect(dx, dy, dz, nx, ny, nz)
                else:
                    # 4. scattering: the weight takes the factor, the rest is absorbed or
                    # transmitted
                    if (params[part, P_DISPERSIVE, 0] == DISPERSION_ALWAYS
                            and slots_i[i, I_HERO] < 0):
                        _follow_hero(slots_f, slots_i, i, channels)
                    hero = slots_i[i, I_HERO]
                    ox, oy, oz, outcome = scatter_event(
                        kind[part], params, tab_int, tab_f, part, dx, dy, dz, nx, ny, nz,
                        faces[f, F_TX], faces[f, F_TY], faces[f, F_TZ],
                        keys[slots_i[i, I_RUN]], slots_i[i, I_COUNT], bounce + 1,
                        hero if hero >= 0 else slots_i[i, I_COUNT] % channels, fac)
                    if outcome == HERO and hero < 0:
                        _follow_hero(slots_f, slots_i, i, channels)
                    # (what the weight loses otherwise is absorbed: ``add_energy``)
                    for c in range(channels if outcome == TRANSMITTING else 0):
                        slots_f[i, S_W + 2 * channels + c] += slots_f[i, S_W + c] * fac[1, c]
                    for c in range(channels if outcome == WEIGHTED or outcome == TRANSMITTING
                                   else 0):
                        slots_f[i, S_W + c] = slots_f[i, S_W + c] * fac[0, c]
                    if params[part, P_MEDIUM, 0] != 0.0:
                        # through a refracting face (the direction kept the side of d·n):
                        # into the part's medium when it now goes behind the face, else out
                        # to air
                        side_out = ox * nx + oy * ny + oz * nz
                        if den * side_out > 0.0:
                            slots_i[i, I_MEDIUM] = part if side_out < 0.0 else -1
                            slots_i[i, I_CROSSED] = 1
                if go_on:
                    dx, dy, dz = ox, oy, oz
                    aim(slots_f, i, dx, dy, dz, box)
                    slots_i[i, I_BOUNCE] = bounce + 1
                    # 5. the offset off the face, on the side the new direction goes
                    s = eps if dx * nx + dy * ny + dz * nz >= 0.0 else -eps
                    px, py, pz = hx + s * nx, hy + s * ny, hz + s * nz
                    slots_f[i, S_Z0] = pz
                    slots_i[i, I_SEG] = 0
                    slots_i[i, I_BUDGET] = budget(dx, dy, dz, box)
            if go_on:
                # the next origin (a hit point offset by eps), wrapped into the box
                wx, wy = wrap_near(px, lx), wrap_near(py, ly)
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
            end(slots_f, slots_i, i, fate, out_f, out_i)
            continue
        # 7. compaction: the path's next query is number `alive` (never above q)
        queue(slots_f, slots_i, live, alive, i)
        alive += 1
    return alive


@njit(**JIT)
def trace_chunk(first: int, origins: np.ndarray, dirs: np.ndarray, media: np.ndarray,
                rows: np.ndarray, runs: np.ndarray, run_rows: np.ndarray, scene: int,
                intersect: int, rayhit: np.ndarray, slots_f: np.ndarray, slots_i: np.ndarray,
                live: np.ndarray, near: np.ndarray, prim: np.ndarray, box: np.ndarray,
                faces: np.ndarray, kind: np.ndarray, params: np.ndarray, tab_int: np.ndarray,
                tab_f: np.ndarray, bounces: int, keys: np.ndarray, out_f: np.ndarray,
                out_i: np.ndarray, energy: np.ndarray, vertices: np.ndarray,
                curved: np.ndarray) -> int:
    """Trace the rays at places ``first``, ``first + 1``, … of a beam (one per row of
    ``origins``) to their ends, each carrying a weight per channel (C of them:
    ``params``' last axis). A beam holds the rays of one run or of several (a
    realisation's incident directions, traced together); each ray writes its run's rows
    of the outcomes and draws from its run's key with its index in the run as counter,
    so its path is the one it follows when its run is traced alone.

    Parameters
    ----------
    first : int
        Place of the chunk's first ray in the beam (a multiple of ``ENERGY_BLOCK``).
    origins, dirs : (k, 3) float
        Start points within the slab (x, y wrapped here) and unit directions of travel.
    media : (k,) int
        Medium each ray starts in (-1: air).
    rows, runs : (k,) int
        Each ray's row of the outcomes and its run.
    run_rows : (b,) int
        The first row of each run (``slots.start``).
    scene, intersect : int
        The ``RTCScene`` and the address of ``rtcIntersect1`` (``embree.Scene``).
    rayhit : (RAYHIT_WORDS,) float32
        A 16-byte-aligned ``RTCRayHit`` record of the calling thread (``embree``).
    slots_f : (w, slot_floats(C)) float
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
    params : (p, PARAMS, C) float
        Material parameters per part and channel.
    tab_int : (p, TABLE_COLUMNS) int
        Table layout per part (table materials).
    tab_f : (q,) float
        Packed table data.
    bounces : int
        Scattering events before a path is ended.
    keys : (b, 2) uint64
        Each run's random key.
    out_f : (n, out_floats(C)) float
    out_i : (n, OUT_INTS) int
        Outcomes per ray of the beam, by row.
    energy : (energy_blocks(n), b, 2, C) float
        Each run's transmitted and ended weight, and its transmitted weight
        (``slots.add_energy``), per block of ``ENERGY_BLOCK`` places
        of the beam, added to once every path has ended.
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
    fac = np.empty((2, params.shape[2]))
    k = m = start(origins, dirs, media, rows, runs, run_rows, slots_f, slots_i, live, box)
    while m:
        _query(m, live, slots_f, rayhit, scene, intersect, prim, box[B_EPS])
        segments += m
        m = advance(prim, m, slots_f, slots_i, live, near, box, faces, kind, params,
                    tab_int, tab_f, bounces, keys, out_f, out_i, vertices, curved, fac)
    add_energy(first, k, slots_f, slots_i, energy)
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
    slab never leaves: ℓ = ∞); what it loses is absorbed (``add_energy``)."""
    length = abs(z_end - slots_f[i, S_Z0]) / abs(dz) if dz != 0.0 else math.inf
    channels = params.shape[2]
    for c in range(channels):
        sigma = params[medium, P_ABSORPTION, c]
        if sigma > 0.0:
            slots_f[i, S_W + c] = slots_f[i, S_W + c] * math.exp(-sigma * length)


@njit(**INLINE)
def _follow_hero(slots_f: np.ndarray, slots_i: np.ndarray, i: int, channels: int) -> None:
    """Leave slot i's path one channel, its hero h = ray mod C (the ray's index in its
    run), at its first event whose direction depends on the wavelength: the other
    channels' weights end there and the hero's is multiplied by C (hero-wavelength
    sampling, Wilkie et al. 2014, "Hero wavelength spectral sampling", sec. 4; pbrt-v4's
    ``TerminateSecondary``). Each
    channel is the hero of every C-th ray, so each channel's expected weight is unchanged;
    the ended weights are neither absorbed nor transmitted: they are kept as the slot's
    ended weight, and so is the hero's gain, (C − 1) times its weight, negative
    (``add_energy``)."""
    hero = slots_i[i, I_COUNT] % channels
    slots_i[i, I_HERO] = hero
    for c in range(channels):
        w = slots_f[i, S_W + c]
        if c == hero:
            slots_f[i, S_W + channels + c] -= w * (channels - 1)
            slots_f[i, S_W + c] = w * channels
        else:
            slots_f[i, S_W + channels + c] += w
            slots_f[i, S_W + c] = 0.0
