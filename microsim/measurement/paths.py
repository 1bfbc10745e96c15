"""Multi-bounce paths over a periodic tile: the goniophotometer's light transport.

A path starts as a ray, is traced over the periodic tile (``microsim.measurement.scene``),
scatters at each face it hits by that face's material (``microsim.materials``), and goes on until it
escapes through the top of the slab, is lost (leaked, trapped, a back-face hit, or alive
after the bounce limit), or is absorbed. Each path remembers the medium it is in (air, or
the inside of a refracting part), which decides which faces it may hit from behind and the
Beer-Lambert absorption along its segments. All of it runs in the compiled transport
kernel (``microsim.kernel``); docs/goniometer.md explains the energy accounting.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Future
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np

from microsim.kernel.beam import Runs
from microsim.kernel.packing import FacetMaterials
from microsim.kernel.slots import FATES, O_ORDER, O_W, S_DX, S_DZ
from microsim.kernel.tally import in_blocks, summarise
from microsim.measurement.scene import Outcomes, PeriodicScene, Tracing

T = TypeVar("T")


@dataclass
class Paths:
    """Fates of rays traced with bounces.

    Attributes
    ----------
    direction : (n, 3) float
        Exit direction of escaped rays (zero rows for the others); like ``weight`` and
        ``order``, a view of the traced outcomes' columns (rows not adjacent).
    weight : (n, C) float
        Weight per channel of escaped rays (zero for the others).
    order : (n,) int
        Scattering order of escaped rays (bounces before escaping; 0: not escaped, or
        escaped without touching the surface, which a closed surface does not allow).
    lost : (C,) float
        Summed weight per channel of paths ended by the simulation: alive after the last bounce,
        leaked (without having refracted), trapped, or through a back face.
    transmitted : (C,) float
        Summed weight per channel transmitted: 1 - F at non-refracting dielectric facets, and paths
        that left through the bottom of the slab after refracting.
    absorbed : (C,) float
        Summed weight per channel absorbed by conductor and lambertian facets and inside
        absorbing media (Beer-Lambert).
    fate_counts : dict of str to int
        Paths per ending (``"escaped"``, ``"bounces"``, ``"transmitted"``, ``"leaked"``,
        ``"trapped"``, ``"backface"``).
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
    """Trace rays with up to ``bounces`` scattering events each and wait for them:
    ``start_paths(...).result()``, with the same parameters."""
    return start_paths(scene, materials, origins, dirs, bounces, seed).result()


def start_paths(scene: PeriodicScene, materials: FacetMaterials, origins: np.ndarray,
                dirs: np.ndarray, bounces: int, seed: np.random.SeedSequence | Runs
                ) -> PendingPaths:
    """Start tracing rays with up to ``bounces`` scattering events each on the scene's
    worker threads; returns at once (``PendingPaths.result`` waits).

    Ray i draws its random numbers from the counter (i, event, ...) under the key of
    ``seed`` (``microsim.kernel.rng``): the result depends on neither the number of
    threads nor the chunk size, bit for bit. A beam of several runs (``seed`` a
    ``Runs``) gives each run the paths it gives traced alone.

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
    seed : numpy.random.SeedSequence or Runs
        Key of the random numbers, or the runs of a beam (``PeriodicScene.start``).

    Returns
    -------
    PendingPaths
    """
    return PendingPaths(scene, scene.start(origins, dirs, materials, bounces, seed))


class PendingPaths:
    """Paths being traced (``start_paths``): ``result`` for a run's paths, summarised on
    the scene's worker threads, or ``then`` to have a function of them run there.

    Parameters
    ----------
    scene : PeriodicScene
    tracing : Tracing
        The scene's handle of the chunks.
    """

    def __init__(self, scene: PeriodicScene, tracing: Tracing) -> None:
        self._scene, self._tracing = scene, tracing

    def result(self, run: int = 0) -> Paths:
        """The paths of run ``run`` of the beam: exit directions, weights and orders, and
        the energy and fate sums (summarised on the scene's worker threads)."""
        return _summarise(self._tracing.result(), run, self._scene.map)

    def then(self, fn: Callable[[Paths], T], run: int = 0) -> Future[T]:
        """``fn(paths)`` of run ``run`` on one of the scene's worker threads once every
        path of the beam has ended (summarised there, the paths those of ``result``), so
        the caller's thread need not wait for the tracing (``Tracing.then``)."""
        return self._tracing.then(lambda out: fn(_summarise(out, run, None)))


def _summarise(out: Outcomes, run: int, mapper: Callable[..., list[Any]] | None) -> Paths:
    """The paths of run ``run`` of traced outcomes, summarised in blocks (``in_blocks``:
    the same sums whatever ``mapper`` runs them); their directions, weights and orders
    are views of the run's rows of the outcomes, which ``summarise`` zeroes for the rays
    that did not escape. What its events transmitted, and what ended at a dispersive
    event, are the sums of its blocks' (``slots.add_energy``)."""
    first, last = int(out.starts[run]), int(out.starts[run + 1])
    floats, ints = out.floats[first:last], out.ints[first:last]
    channels = floats.shape[1] - O_W

    def block(a: int, b: int) -> tuple[np.ndarray, np.ndarray]:
        energy, counts = np.zeros((3, channels)), np.zeros(len(FATES), np.int64)
        summarise(floats[a:b], ints[a:b], energy, counts)
        return energy, counts

    energy, counts = in_blocks(block, last - first, mapper)
    diverted, sent = out.energy[:, run].sum(axis=0)
    return Paths(floats[:, S_DX:S_DZ + 1], floats[:, O_W:], ints[:, O_ORDER],
                 energy[0], energy[1] + sent, energy[2] - diverted,
                 dict(zip(FATES, map(int, counts), strict=True)))
