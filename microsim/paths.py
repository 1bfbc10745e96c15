"""Multi-bounce paths over a periodic tile: the goniophotometer's light transport.

A path starts as a ray, is traced by ``PeriodicScene`` (``microsim.trace``) to the face it
hits, scatters there by that face's material (``microsim.materials``), and goes on until it
escapes through the top of the slab, is lost (leaked, trapped, a back-face hit, or alive
after the bounce limit), or is absorbed. Each path remembers the medium it is in (air, or
the inside of a refracting part), which decides which faces it may hit from behind and the
Beer-Lambert absorption along its segments. The loop is vectorised over the paths still
alive; docs/goniometer.md explains the energy accounting.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from microsim.refraction import attenuation, next_medium
from microsim.shading import shade
from microsim.trace import BACKFACE, ESCAPED, FATES, HIT, LEAKED, TRAPPED, Hits, PeriodicScene

if TYPE_CHECKING:
    from microsim.materials import FacetMaterials


@dataclass
class Paths:
    """Fates of rays traced with bounces.

    Attributes
    ----------
    direction : (n, 3) float
        Exit direction of escaped rays (zero rows for the others).
    weight : (n, 3) float
        RGB weight of escaped rays (zero for the others).
    order : (n,) int
        Scattering order of escaped rays (bounces before escaping; 0: not escaped, or
        escaped without touching the surface, which a closed surface does not allow).
    lost : (3,) float
        Summed RGB weight of paths ended by the simulation: alive after the last bounce,
        leaked (without having refracted), trapped, or through a back face.
    transmitted : (3,) float
        Summed RGB weight transmitted: 1 - F at non-refracting dielectric facets, and paths
        that left through the bottom of the slab after refracting.
    absorbed : (3,) float
        Summed RGB weight absorbed by conductor and lambertian facets and inside
        absorbing media (Beer-Lambert).
    fate_counts : dict of str to int
        Paths per ending (``"escaped"``, ``"bounces"``, ``"transmitted"``, and the
        ``FATES`` of lost paths).
    """

    direction: np.ndarray
    weight: np.ndarray
    order: np.ndarray
    lost: np.ndarray
    transmitted: np.ndarray
    absorbed: np.ndarray
    fate_counts: dict[str, int]


def trace_paths(scene: PeriodicScene, materials: FacetMaterials, origins: np.ndarray,
                dirs: np.ndarray, bounces: int, seed: np.random.SeedSequence) -> Paths:
    """Trace rays with up to ``bounces`` scattering events each.

    Chunks of ``scene.chunk`` rays are traced on the worker threads, chunk c drawing its
    random numbers from the child ``seed`` spawn key + (c,); the result depends on the
    chunk size but not on the number of threads.

    Parameters
    ----------
    scene : PeriodicScene
    materials : FacetMaterials
        Scattering per face material.
    origins : (n, 3) float
        Start points within the slab.
    dirs : (n, 3) float
        Unit directions of travel.
    bounces : int
        Maximum scattering order; paths still alive afterwards are lost.
    seed : numpy.random.SeedSequence
        Root of the random streams of the materials that need them.

    Returns
    -------
    Paths
    """
    c = scene.chunk

    def run(i: int) -> tuple[Paths, int]:
        rng = np.random.default_rng(np.random.SeedSequence(
            seed.entropy, spawn_key=(*seed.spawn_key, i // c)))
        return _trace_paths(scene, materials, origins[i:i + c], dirs[i:i + c], bounces, rng)

    parts = scene.map(run, range(0, len(origins), c))
    scene.segments += sum(seg for _, seg in parts)
    fates = {k: sum(p.fate_counts[k] for p, _ in parts) for k in parts[0][0].fate_counts}
    return Paths(*(np.concatenate([getattr(p, f) for p, _ in parts])
                   for f in ("direction", "weight", "order")),
                 *(sum(getattr(p, f) for p, _ in parts)
                   for f in ("lost", "transmitted", "absorbed")), fates)


def _trace_paths(scene: PeriodicScene, materials: FacetMaterials, origins: np.ndarray,
                 dirs: np.ndarray, bounces: int, rng: np.random.Generator
                 ) -> tuple[Paths, int]:
    """``trace_paths`` of one chunk in the calling thread, and the Embree queries made."""
    n = len(origins)
    direction = np.zeros((n, 3))
    weight = np.zeros((n, 3))
    order = np.zeros(n, np.int64)
    lost, transmitted, absorbed = np.zeros(3), np.zeros(3), np.zeros(3)
    counts = dict.fromkeys(("escaped", "bounces", "transmitted") + FATES[2:], 0)
    # the paths still alive: their rows, weights, origins and directions
    alive, w, o, d = np.arange(n), np.ones((n, 3)), origins, dirs
    # with refracting facets: the medium each path is in (its part, -1: air) and whether
    # it has refracted (then leaving through the bottom is transmission, not leakage)
    refracting = bool(materials.refracting.any())
    medium = np.full(n, -1, np.int64) if refracting else None
    crossed = np.zeros(n, bool)
    segments = 0
    for bounce in range(bounces + 1):
        if alive.size == 0:
            break
        hits, seg = scene._closest_hit(o, d, medium)
        segments += seg
        if medium is not None:
            w, lose = _absorb(scene, materials, hits, o, d, w, medium)
            absorbed += lose
        out = np.flatnonzero(hits.status == ESCAPED)
        direction[alive[out]] = np.take(d, out, axis=0)
        weight[alive[out]] = np.take(w, out, axis=0)
        order[alive[out]] = bounce
        counts["escaped"] += out.size
        hit = np.flatnonzero(hits.status == HIT)
        for code in (LEAKED, TRAPPED, BACKFACE) if out.size + hit.size < alive.size else ():
            ended = hits.status == code
            if code == LEAKED:  # through the bottom after refracting: transmitted
                through = ended & crossed
                transmitted += w[through].sum(axis=0)
                counts["transmitted"] += int(through.sum())
                ended &= ~crossed
            lost += w[ended].sum(axis=0)
            counts[FATES[code]] += int(ended.sum())
        alive, face, crossed, z0 = alive[hit], hits.face[hit], crossed[hit], o[hit, 2]
        w, d, point = (np.take(a, hit, axis=0) for a in (w, d, hits.point))
        if bounce == bounces:
            lost += w.sum(axis=0)
            counts["bounces"] += alive.size
            break
        n_f = np.take(scene.normals, face, axis=0)
        # curved faces scatter about the tube's normal where the ray entered it
        n_s, point, _ = shade(materials.curved, face, point, d, n_f, z0)
        d_in = d
        d, factor, into = materials.scatter(face, d, n_s, rng)
        transmitted += (w * into).sum(axis=0)
        absorbed += (w * (1.0 - factor - into)).sum(axis=0)
        w = w * factor
        o = scene.offset(point, n_s, d)
        if medium is not None:
            part = np.take(materials.face_material, face)
            medium, through = next_medium(part, np.take(materials.refracting, part), n_f,
                                          d_in, d, medium[hit])
            crossed |= through
    return Paths(direction, weight, order, lost, transmitted, absorbed, counts), segments


def _absorb(scene: PeriodicScene, materials: FacetMaterials, hits: Hits, o: np.ndarray,
            d: np.ndarray, w: np.ndarray, medium: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Beer-Lambert attenuation of one query's segments travelled inside a medium.

    A segment's length is its height change over |d_z| (``_closest_hit`` wraps x and y,
    not z), from the origin to the face hit, or to the top or bottom of the slab.

    Returns
    -------
    w : (k, 3) float
        Weights after the segment.
    absorbed : (3,) float
        Weight absorbed on the way.
    """
    sigma = np.take(materials.absorption, medium, axis=0)
    sel = np.flatnonzero((sigma > 0).any(axis=1) & (hits.status != TRAPPED))
    if sel.size == 0:
        return w, np.zeros(3)
    status = hits.status[sel]
    z_end = np.where(status == ESCAPED, scene.z_top,
                     np.where(status == LEAKED, scene.z_bottom, hits.point[sel, 2]))
    dz = np.abs(z_end - o[sel, 2])
    d_z = np.abs(d[sel, 2])
    # a segment exactly parallel to the slab has no length from heights: it is taken as
    # never leaving the medium (a set of measure zero)
    length = np.divide(dz, d_z, out=np.full(sel.size, np.inf), where=d_z > 0)
    before = w[sel]
    w = w.copy()
    w[sel] = before * attenuation(sigma[sel], length)
    return w, (before - w[sel]).sum(axis=0)
