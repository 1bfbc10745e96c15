"""The virtual goniophotometer on one tile: per incident direction, binned exit weights.

It samples the tile as a real instrument does and counts what the paths over the periodic
tracer (``microsim.measurement.paths``) return, into per-direction sums from which
``microsim.tables.table.BRDFTable`` makes f_r and its errors; ``microsim.measurement.simulation``
runs it over the realisations of a surface, with the adaptive stop, and assembles the
table. docs/goniometer.md explains the sampling, the weights and the error bars. (Masking
G1 is measured by ``microsim.measurement.masking``.)

Rays -wi start at uniform points of the tile's top plane (uniform irradiance over
the projected area, as a collimated beam gives) and scatter until they escape; an escaping
ray of weight w lands in a bin B of projected solid angle Omega_B, and
f_r(wi, B) = E[w 1_B] / Omega_B (the estimator is the fraction of incident power per
projected solid angle: Nicodemus et al. 1977, NBS Monograph 160, eq. 4).
"""

from __future__ import annotations

import contextlib
import itertools
import math
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from concurrent.futures import Future
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from microsim.geometry import direction
from microsim.kernel.beam import CELLS, Runs, beam_origins
from microsim.kernel.packing import FacetMaterials
from microsim.kernel.rng import key_of
from microsim.kernel.tally import bin_escapes, gather_rows, in_blocks
from microsim.materials import Material
from microsim.measurement.paths import Paths, start_paths
from microsim.measurement.scene import PeriodicScene
from microsim.settings import DEFAULT_ORDERS, Simulation, TableSettings
from microsim.surfaces.facts import TileFacts
from microsim.surfaces.tile import Tile
from microsim.tables import sh
from microsim.tables.assemble import EnsembleSums
from microsim.tables.binning import HemisphereBins
from microsim.tables.components import components_for
from microsim.tables.meta import DirectionRecord, TableInput

BATCH = 65536
"""Rays per batch: the unit of random streams, accumulation and the adaptive stop."""
BEAM = 2 * BATCH
"""Rays per beam at most: consecutive batches of a tile traced together (``_beams``), so
that a realisation's few rays per direction on a large tile share the BVH's nodes and
the face table's rows in the kernel's chunks as a full batch's do (docs/performance.md,
"Rays per batch and the kernel")."""
DEPTH = 2
"""Beams under way on the worker threads (traced, or their batches summarised, binned and
projected on the harmonics there), the one whose sums are being added among them: the
workers always have the next beam's chunks to trace while they tally a beam's batches.
A third beam was no faster (the demo, a 32-wavelength table and the 1% run the same
within their noise, the tile-heavy ensemble 2–4% slower) and, where a beam is a whole
realisation, kept a fourth scene to build and hold."""
_ROWS = threading.local()
"""Each tallying thread's arrays of a batch's rays grouped by order row (``Sums.
_harmonics``), kept from batch to batch: a spectral batch's are 16 MB, whose pages the
system would zero anew for every batch."""
LOST_WARNING = 0.01
"""Lost energy (paths cut at the bounce limit or leaving through the tile's underside) as
a fraction of the incident energy above which a table carries a warning: a closed surface
with enough bounces loses none (the shipped recipes lose under 0.1%, except the open
weave, whose gaps let about 5% through)."""


class Sums:
    """Running per-bin sums of one incident direction, per component.

    Row 0 of every array holds every escaping ray (``"total"``); row k, 1 ≤ k < N, the rays
    that escaped after k scattering events; row N those after N or more
    (``components_for(N)``, N = ``orders``). The compiled tally adds each ray to row 0 and
    to row min(k, N) of its order k, so the order rows add up to row 0.

    Attributes
    ----------
    rays : int
        Rays launched.
    orders : int
        N of the order components.
    channels : int
        C, the colour channels (3 for RGB, one per wavelength).
    sums, sums_sq : (N + 1, b, C) float
        Per row and bin, the sum of exit weights w and of w**2.
    lost, transmitted, absorbed : (C,) float
        Summed weight of paths ended by the simulation (bounce limit, leaks), transmitted
        (1 - F at non-refracting dielectrics; refracted paths out through the bottom), and
        absorbed (by the other materials and inside absorbing media).
    fates : dict of str to int
        Paths per ending.
    sh_order : int
        Order L of the spherical-harmonic moments (0: none).
    sh_sums : (N + 1, (L + 1)², C) float, or None
        Σ w Y_k(ωo) over the escaping rays the bins take, per row
        (``microsim.tables.sh``; ωo's azimuth relative to ``phi_ref`` of ``add``).
    sh_sums_sq : (N + 1, (2L + 1)², C) float, or None
        Σ w² Y_K(ωo) to order 2L, from which ``sh.second_moments`` gives Σ (w Y_k)²;
        None without ``sh_ray_variance``.
    sh_ray_variance : bool
        Whether ``sh_sums_sq`` is kept (``harmonic_ray_variance``).
    """

    def __init__(self, bins: int, sh_order: int = 0, orders: int = DEFAULT_ORDERS,
                 channels: int = 3, sh_ray_variance: bool = True) -> None:
        self.rays = 0
        self.orders = int(orders)
        self.channels = c = int(channels)
        rows = self.orders + 1
        self.sums = np.zeros((rows, bins, c))
        self.sums_sq = np.zeros((rows, bins, c))
        self.sh_order = int(sh_order)
        self.sh_sums = np.zeros((rows, sh.size(sh_order), c)) if sh_order else None
        self.sh_ray_variance = bool(sh_ray_variance)
        self.sh_sums_sq = np.zeros((rows, sh.size(2 * sh_order), c)) if (
            sh_order and sh_ray_variance) else None
        self.lost, self.transmitted, self.absorbed = np.zeros(c), np.zeros(c), np.zeros(c)
        self.fates: dict[str, int] = {}

    @property
    def components(self) -> tuple[str, ...]:
        """Component names of the rows (``components_for``)."""
        return components_for(self.orders)

    def add(self, paths: Paths, bins: HemisphereBins, phi_ref: float = 0.0,
            mapper: sh.Mapper | None = None) -> None:
        """Add one batch: the traced ``paths``, binned in ``bins`` with φo measured from the
        azimuth ``phi_ref`` (radians), which the harmonics use too; ``mapper`` runs the
        binning's blocks and the harmonic transforms (``sh.Mapper``: e.g. on the tracer's
        threads; the sums do not depend on it: ``microsim.kernel.tally.in_blocks``)."""
        self.add_tally(self.tally(paths, bins, phi_ref, mapper))

    def tally(self, paths: Paths, bins: HemisphereBins, phi_ref: float = 0.0,
              mapper: sh.Mapper | None = None) -> Tally:
        """One batch's sums, to be added with ``add_tally`` (``add`` does both); reads only
        the settings of these sums, so batches are tallied on any thread."""
        n = len(paths.order)
        index = np.empty(n, np.int64)
        loc = np.empty((n if self.sh_order else 0, 2))

        def block(a: int, b: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            sums = np.zeros_like(self.sums)
            sums_sq, unbinned = np.zeros_like(sums), np.zeros(self.channels)
            bin_escapes(paths.direction[a:b], paths.weight[a:b], paths.order[a:b], phi_ref,
                        bins.theta_bins, bins.phi_bins, bins.folded, self.orders, sums,
                        sums_sq, index[a:b], unbinned, loc[a:b])
            return sums, sums_sq, unbinned

        sums, sums_sq, unbinned = in_blocks(block, n, mapper)
        harmonics = self._harmonics(paths, index, loc, mapper) if self.sh_order else []
        # an escaping ray the bins do not take (none for a closed surface) is lost, not hidden
        return Tally(n, sums, sums_sq, harmonics, paths.lost + unbinned, paths.transmitted,
                     paths.absorbed, paths.fate_counts)

    def add_tally(self, tally: Tally) -> None:
        """Add one batch's sums (``tally``)."""
        self.rays += tally.rays
        self.sums += tally.sums
        self.sums_sq += tally.sums_sq
        for k, s1, s2 in tally.harmonics:
            self.sh_sums[k] += s1
            self.sh_sums[0] += s1
            if s2 is not None:
                self.sh_sums_sq[k] += s2
                self.sh_sums_sq[0] += s2
        self.lost += tally.lost
        self.transmitted += tally.transmitted
        self.absorbed += tally.absorbed
        for name, count in tally.fates.items():
            self.fates[name] = self.fates.get(name, 0) + count

    def _harmonics(self, paths: Paths, index: np.ndarray, loc: np.ndarray,
                   mapper: sh.Mapper | None
                   ) -> list[tuple[int, np.ndarray, np.ndarray | None]]:
        """Moments of the escaping rays' exit weights against the real harmonics: one
        transform per order row over that row's binned rays alone (``index`` their bins,
        ``loc`` their angles), (row, Σ w Y_k, Σ w² Y_K or None without
        ``sh_ray_variance``) in row order (the total row is their sum). The rays are
        grouped by row in one compiled pass (``microsim.kernel.tally.gather_rows``); a
        row's rays are then one slice, its weights one slice of each channel's row
        (channel-major, so the transforms take them without a transposing copy)."""
        n = len(index)
        loc_rows, w = _row_arrays(n, self.channels)
        ends = np.empty(self.orders + 1, np.int64)
        gather_rows(loc, paths.weight, paths.order, index, self.orders, loc_rows, w, ends)
        out = []
        for k in range(1, self.orders + 1):
            a, b = ends[k - 1], ends[k]
            if b > a:
                out.append((k, *sh.moments(loc_rows[a:b], w[:, a:b].T, self.sh_order,
                                           mapper, second=self.sh_ray_variance)))
        return out

    @property
    def lost_energy(self) -> np.ndarray:
        """(C,) summed weight a table reports as lost: simulation ends and transmission."""
        return self.lost + self.transmitted


def _row_arrays(n: int, channels: int) -> tuple[np.ndarray, np.ndarray]:
    """The calling thread's (n, 2) angles and (channels, n) weights for ``gather_rows``:
    views of arrays it keeps (``_ROWS``; valid until its next call), grown when n is
    larger than before."""
    held = getattr(_ROWS, "arrays", None)
    if held is None or held[1].shape[0] != channels or len(held[0]) < n:
        held = _ROWS.arrays = (np.empty((n, 2)), np.empty((channels, n)))
    return held[0][:n], held[1][:, :n]


class Tally(NamedTuple):
    """One batch's sums (``Sums.tally``): its rays; per row and bin Σw and Σw²; per order
    row with rays, (row, Σ w Y_k, Σ w² Y_K); the lost (unbinned escapes included),
    transmitted and absorbed weight; the paths per ending."""

    rays: int
    sums: np.ndarray
    sums_sq: np.ndarray
    harmonics: list[tuple[int, np.ndarray, np.ndarray | None]]
    lost: np.ndarray
    transmitted: np.ndarray
    absorbed: np.ndarray
    fates: dict[str, int]


class _Batch(NamedTuple):
    """One batch of one direction's rays: what the pipeline needs to trace and add it
    (``travel``: its rays' direction of travel, −ωi, (3,) float)."""

    run: Run
    number: int
    rays: int
    travel: np.ndarray
    phi_ref: float
    seed: np.random.SeedSequence
    report: Callable[[int], None] | None
    realisation: int
    scene: PeriodicScene | None = None
    facets: FacetMaterials | None = None


def _batches(work: Mapping[Direction, int], runs: dict[RunKey, Run], new_run: Callable[[], Run],
             seed: int, axes: Incidences, realisation: int,
             progress: Callable[[Progress], None] | None) -> Iterator[_Batch]:
    """The batches of every direction of ``work`` in order, each direction's continuing its
    run in ``runs`` (``new_run()`` where there is none yet).

    Batches of ``BATCH`` rays (the last one of a direction may be shorter) are numbered
    from the run's ``batches``; batch b of direction (l, k) draws from
    ``SeedSequence(seed, spawn_key=(l, k, realisation, b))``. Outgoing azimuths are binned
    relative to the incident azimuth for isotropic tables, absolute otherwise (the
    table's convention).
    """
    for (l, k), rays in work.items():
        key = RunKey(l, k, realisation)
        run = runs[key] = runs.get(key) or new_run()
        phi_ref = axes.phi_ref(k)
        travel = -axes.incident(l, k)
        report = None if progress is None else _reporter(
            progress, axes.theta_deg[l], axes.phi_deg[k], realisation, run.sums)
        first = run.batches  # grows as the batches are added, while later ones are made
        for index, start in enumerate(range(0, rays, BATCH)):
            number = first + index
            stream = np.random.SeedSequence(seed, spawn_key=(*key, number))
            count = min(BATCH, rays - start)
            yield _Batch(run, number, count, travel, phi_ref, stream, report, realisation)


def _beams(batches: Iterable[_Batch], limit: int) -> Iterator[list[_Batch]]:
    """Consecutive batches (of one realisation's tile) in beams of at most ``limit`` rays
    (a batch is never split; 0: each batch alone)."""
    beam: list[_Batch] = []
    rays = 0
    for batch in batches:
        if beam and rays + batch.rays > limit:
            yield beam
            beam, rays = [], 0
        beam.append(batch)
        rays += batch.rays
    if beam:
        yield beam


def _pipeline(beams: Iterator[list[_Batch]], bounces: int, bins: HemisphereBins
              ) -> Iterator[tuple[_Batch, Tally]]:
    """The tally of each batch, in order, with ``DEPTH`` beams under way.

    A beam's batches share one tile (``_beams``). Each batch's origins are drawn
    uniformly over the tile's top from its own stream; the beam's are traced together in
    cell order (``microsim.kernel.beam``), each batch in its own rows with its own random
    numbers, and its chunks queued on the scene's worker threads; when they have ended,
    each batch is summarised, binned and projected on the harmonics there too
    (``Sums.tally``, one batch on one thread, its blocks in order), so this thread only
    queues beams and adds their batches' sums, and the workers never wait for it, not
    even where one realisation's batches end and the next one's begin. What comes out
    is what tracing and tallying the batches one after the other gives, bit for bit.
    """
    pending: deque[tuple[_Batch, Future[Tally], bool]] = deque()  # its beam's last?

    def queue_next() -> None:
        for beam in itertools.islice(beams, 1):
            scene = beam[0].scene
            starts = np.cumsum([0] + [batch.rays for batch in beam])
            u = np.concatenate([np.random.default_rng(batch.seed).random((batch.rays, 2))
                                for batch in beam])
            origins, rows, run = beam_origins(u, starts, scene.period, scene.z_top, CELLS)
            dirs = np.stack([batch.travel for batch in beam])[run]
            runs = Runs(rows, run, starts, np.stack([key_of(batch.seed) for batch in beam]))
            paths = start_paths(scene, beam[0].facets, origins, dirs, bounces, runs)
            for r, batch in enumerate(beam):
                sums, phi_ref = batch.run.sums, batch.phi_ref
                pending.append((batch, paths.then(
                    lambda traced, sums=sums, phi_ref=phi_ref: sums.tally(traced, bins,
                                                                          phi_ref), r),
                    r == len(beam) - 1))

    for _ in range(DEPTH):
        queue_next()
    while pending:
        batch, tally, last = pending.popleft()
        yield batch, tally.result()
        if last:  # once its batches are added (a realisation then lets go of its scene)
            queue_next()


@dataclass
class Run:
    """One incident direction of one realisation: its sums and the batches they took."""

    sums: Sums
    batches: int = 0


Direction = tuple[int, int]
"""An incident direction (l, k): polar angle index l, azimuth index k."""


@dataclass(frozen=True)
class Incidences:
    """The axes of a measurement: its incident directions, the outgoing bins, scattering
    orders, harmonics and channels it tallies into, made once from the recipe's sections
    and carried by the measurement, so that its sums and the table are made from it
    (``microsim.measurement.simulation.assemble_table``).

    Attributes
    ----------
    theta_deg, phi_deg : tuple of float
        Every incident polar angle of the simulation (index l) and the incident azimuths
        measured (index k; ``(0,)`` for an isotropic surface), degrees as the recipe
        gives them (the table's records keep these).
    isotropic : bool
        One incident azimuth, and outgoing azimuths binned relative to it.
    bins : HemisphereBins
        The outgoing bins.
    orders : int
        N: the components are ``components_for(N)``.
    sh_order : int
        Order L of the harmonics tallied (0: none).
    channels : int
        C, the colour channels (3: RGB; one per wavelength).
    sh_ray_variance : bool
        Whether the harmonics' ray variances are tallied (``harmonic_ray_variance``).
    """

    theta_deg: tuple[float, ...]
    phi_deg: tuple[float, ...]
    isotropic: bool
    bins: HemisphereBins
    orders: int
    sh_order: int
    channels: int
    sh_ray_variance: bool

    @classmethod
    def of(cls, simulation: Simulation, table: TableSettings, isotropic: bool
           ) -> Incidences:
        """The axes of ``simulation`` and ``table`` for a surface of that symmetry."""
        phi = (0.0,) if isotropic else tuple(float(p) for p in simulation.phi_i)
        return cls(tuple(float(t) for t in simulation.theta_i), phi, bool(isotropic),
                   HemisphereBins(table.theta_bins, table.phi_bins), table.orders,
                   table.sh_order, table.channels.count, harmonic_ray_variance(simulation))

    def new_sums(self) -> Sums:
        """Empty sums of one run (one direction of one realisation)."""
        return Sums(self.bins.size, self.sh_order, self.orders, self.channels,
                    self.sh_ray_variance)

    def new_ensemble(self) -> EnsembleSums:
        """Empty running sums over realisations for every incident direction."""
        return EnsembleSums((len(self.theta_deg), len(self.phi_deg)),
                            components_for(self.orders), self.bins.size, self.sh_order,
                            self.channels, self.sh_ray_variance)

    @property
    def theta_i(self) -> np.ndarray:
        """(a,) float: the incident polar angles, radians."""
        return np.radians(self.theta_deg)

    @property
    def phi_i(self) -> np.ndarray:
        """(b,) float: the incident azimuths, radians."""
        return np.radians(self.phi_deg)

    def incident(self, l: int, k: int) -> np.ndarray:
        """(3,) float: the unit direction ωi towards the light of direction (l, k)."""
        return direction(math.radians(self.theta_deg[l]), math.radians(self.phi_deg[k]))

    def phi_ref(self, k: int) -> float:
        """The azimuth (radians) outgoing azimuths are binned from: the incident one for
        an isotropic table, 0 (absolute) otherwise."""
        return math.radians(self.phi_deg[k]) if self.isotropic else 0.0


class RunKey(NamedTuple):
    """The run of incident direction (``theta``, ``phi``) of realisation ``realisation``
    (indices into the simulation's angles and the realisations)."""

    theta: int
    phi: int
    realisation: int


@dataclass(frozen=True)
class Progress:
    """Where a measurement is, reported after every batch: the direction (degrees), the
    realisation, the realisations planned so far, the rays traced of this direction
    and realisation, and the batches of the whole measurement done and planned so far
    (0 where the caller does not count them; an adaptive stop plans more as it goes)."""

    theta_i: float
    phi_i: float
    realisation: int
    realisations: int
    rays: int
    batches_done: int = 0
    batches_planned: int = 0


@dataclass
class Energies:
    """What the folded realisations of one incident direction leave for its record
    (``DirectionRecord``): Σ over realisations of each one's lost, transmitted and
    absorbed weight per ray ((3, C) float, rows in that order; None before the first) and
    the paths per ending."""

    energy: np.ndarray | None = None
    fates: dict[str, int] = field(default_factory=dict)

    def add(self, sums: Sums) -> None:
        """Add one realisation's run."""
        energy = np.stack([sums.lost, sums.transmitted, sums.absorbed]) / sums.rays
        self.energy = energy if self.energy is None else self.energy + energy
        for name, n in sums.fates.items():
            self.fates[name] = self.fates.get(name, 0) + n


@dataclass
class Measurement:
    """What tracing some incident directions of some realisations gives; the pieces a table
    is assembled from (``microsim.measurement.simulation.assemble_table``).

    Realisations a measurement will add no rays to are folded into running sums
    (``fold``), so its memory does not grow with their number; the others stay runs.

    Attributes
    ----------
    runs : dict of RunKey to Run
        Per traced (l, k, r) not folded: incident polar angle index l into
        ``simulation.theta_i``, azimuth index k, realisation r.
    surfaces : dict of int to TileFacts
        The facts of each realisation's tile.
    inputs : list of TableInput
        Provenance of the tables its facet materials read (``FacetMaterials.inputs``).
    axes : Incidences
        Its incident directions (the indices of ``runs``' keys), outgoing bins, orders,
        harmonics and channels.
    segments : int
        Embree queries traced.
    offset : float
        The scene's ray offset (``PeriodicScene.eps``; of realisation 0 when traced).
    scene_time, trace_time : float
        Wall-clock seconds to build the tiles and scenes, and to trace.
    tiles : int
        Tiles built (and their scenes) in ``scene_time``.
    stops : dict of (int, int) to str
        Why each direction's adaptive stop ended (``microsim.measurement.simulation``); directions
        traced with a fixed count are absent.
    warnings : list of str
        The tiles' warnings, each once.
    ensemble : EnsembleSums or None
        The folded realisations' sums, of every direction of the simulation's table
        (those of realisations 0, 1, ... of a direction, in order).
    energies : dict of (int, int) to Energies
        The folded realisations' energies and fates, per direction.
    """

    runs: dict[RunKey, Run]
    surfaces: dict[int, TileFacts]
    inputs: list[TableInput]
    axes: Incidences
    segments: int = 0
    offset: float = math.nan
    scene_time: float = 0.0
    trace_time: float = 0.0
    tiles: int = 0
    stops: dict[Direction, str] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    ensemble: EnsembleSums | None = None
    energies: dict[Direction, Energies] = field(default_factory=dict)

    @property
    def isotropic(self) -> bool:
        """Whether one incident azimuth (0) was measured."""
        return self.axes.isotropic

    @property
    def rays(self) -> int:
        """Rays traced over every run, folded ones included."""
        folded = 0 if self.ensemble is None else int(self.ensemble.rays.sum())
        return folded + sum(run.sums.rays for run in self.runs.values())

    def fold(self, key: RunKey) -> None:
        """Move run ``key`` into the running sums (realisations of a direction in index
        order)."""
        if self.ensemble is None:
            self.ensemble = self.axes.new_ensemble()
        fold(self.ensemble, self.energies.setdefault(key[:2], Energies()), key,
             self.runs.pop(key).sums)


def fold(ensemble: EnsembleSums, energies: Energies, key: RunKey, sums: Sums) -> None:
    """Add one realisation's run of a direction to running sums: the table's
    (``EnsembleSums``) and the record's (``Energies``)."""
    ensemble.add((key.theta, key.phi), key.realisation, sums.rays, sums.sums, sums.sums_sq,
                 sums.lost_energy, sums.sh_sums, sums.sh_sums_sq)
    energies.add(sums)


def harmonic_ray_variance(simulation: Simulation) -> bool:
    """Whether a run's harmonics need their ray variances, the order-2L transforms of w²
    (``microsim.tables.sh.moments``): only a single realisation does, whose error they
    are. An ensemble's harmonics take batch means over its realisations (unbiased for
    the error of the mean whatever the rays, ``microsim.tables.estimator``); the ray
    variance would only floor them where realisations tie, which sums over thousands of
    directions do not, and its transforms at twice the order cost more than the
    harmonics themselves (docs/ensembles.md, "Error bars of the ensemble")."""
    return simulation.realisations_or_one == 1


class Part(NamedTuple):
    """One realisation's share of a measurement (``trace_realisations``): its index, an
    open scene of its tile (``scene.tile``; the part holds no tile of its own, so a scene
    set aside lets go of it), and the rays to add per direction."""

    realisation: int
    scene: PeriodicScene
    work: Mapping[Direction, int]


def trace_realisations(parts: Iterable[Part], materials: Mapping[str, Material],
                       simulation: Simulation, table: TableSettings, axes: Incidences,
                       runs: dict[RunKey, Run], *,
                       progress: Callable[[Progress], None] | None = None,
                       ended: Callable[[Part, int, list[TableInput]], None] | None = None
                       ) -> None:
    """Trace the parts one after the other through one pipeline of batches, so that the
    next realisation's batches are queued while the last ones of a realisation are
    traced and tallied.

    Parameters
    ----------
    parts : iterable of Part
        Taken one at a time, when the pipeline needs the next one's batches (a generator
        may open each realisation then).
    materials, simulation, table
        As for ``measure_directions``.
    axes : Incidences
        The measurement's directions, bins and tallies (of the parts' surface).
    runs : dict of RunKey to Run
        Runs to continue or start (their sums grow).
    progress : callable or None
        Called after every batch.
    ended : callable or None
        ``ended(part, segments, inputs)`` once every batch of a part has been added: the
        Embree queries it made and the provenance of the tables its facet materials read
        (its scene is free again).
    """
    bins = axes.bins
    left: dict[int, list] = {}  # per realisation: batches not added, part, segments, inputs

    def new_run() -> Run:
        return Run(axes.new_sums())

    def beams() -> Iterator[list[_Batch]]:
        for part in parts:
            scene = part.scene
            tile = scene.tile
            facets = FacetMaterials(tile.material, tile.parts, materials, tile.tangents,
                                    tile.curved, table.channels)
            items = [b._replace(scene=scene, facets=facets) for b in _batches(
                part.work, runs, new_run, int(simulation.seed), axes, part.realisation,
                progress)]
            state = left[part.realisation] = [len(items), part, scene.segments,
                                              facets.inputs]
            del tile
            if not items:
                finish(part.realisation, state)
            # a run's energy sums are the same in any beam only where no part divides the
            # weight (``FacetMaterials.divides_weight``): elsewhere each batch alone
            yield from _beams(items, 0 if facets.divides_weight else BEAM)

    def finish(r: int, state: list) -> None:
        del left[r]
        if ended is not None:
            ended(state[1], state[1].scene.segments - state[2], state[3])

    for batch, tally in _pipeline(beams(), int(simulation.bounces), bins):
        batch.run.sums.add_tally(tally)
        batch.run.batches = batch.number + 1
        if batch.report is not None:
            batch.report(batch.rays)
        state = left[batch.realisation]
        state[0] -= 1
        if state[0] == 0:
            finish(batch.realisation, state)


def measure_directions(tile: Tile, materials: Mapping[str, Material], simulation: Simulation,
                       table: TableSettings, thetas: Sequence[int] | None = None, *,
                       rays: int | Mapping[Direction, int] | None = None,
                       realisation: int = 0, runs: dict[RunKey, Run] | None = None,
                       threads: int | None = None,
                       progress: Callable[[Progress], None] | None = None,
                       scene: PeriodicScene | None = None) -> Measurement:
    """Trace incident directions of one realisation's tile.

    Parameters
    ----------
    tile : Tile
        Realisation ``realisation`` of the recipe's surface.
    materials : mapping of str to Material
        The material of every part of the tile.
    simulation, table : Simulation, TableSettings
        The recipe's sections (``microsim.settings``).
    thetas : sequence of int or None
        Indices into ``simulation.theta_i`` to trace, every incident azimuth of each
        (default: all).
    rays : int, mapping or None
        Rays to add per direction (default: ``simulation.rays_per_realisation``); a
        mapping of directions (l, k) (l as in ``thetas``, k indexing the incident
        azimuths) to rays traces exactly those directions, ``thetas`` unused.
    realisation : int
        Its index r: direction (l, k) draws its batches from
        ``SeedSequence(seed, spawn_key=(l, k, r, b))``, so the numbers do not depend on
        which other directions or realisations are traced with it, or where.
    runs : dict or None
        Runs to continue (their sums grow, batches keep their numbers); None: fresh ones.
    threads, progress
        As for ``microsim.measurement.simulation.simulate``.
    scene : PeriodicScene or None
        An open scene of ``tile`` to trace in (left open; ``threads`` is then unused), or
        None to build one for this call. The numbers do not depend on it.

    Returns
    -------
    Measurement
        With the runs of this realisation that were traced (continued ones included).
    """
    start = time.perf_counter()
    axes = Incidences.of(simulation, table, bool(tile.facts.isotropic))
    if isinstance(rays, Mapping):
        work = dict(rays)
    else:
        n = simulation.rays_per_realisation if rays is None else int(rays)
        work = {(l, k): n for l in (range(len(axes.theta_deg)) if thetas is None
                                    else thetas) for k in range(len(axes.phi_deg))}
    runs = {} if runs is None else runs
    done: dict[str, object] = {}

    def ended(_: Part, segments: int, inputs: list[TableInput]) -> None:
        done.update(segments=segments, inputs=inputs)

    with contextlib.ExitStack() as stack:
        if scene is None:
            scene = stack.enter_context(PeriodicScene(tile, threads))
        built = time.perf_counter()
        trace_realisations([Part(realisation, scene, work)], materials, simulation,
                           table, axes, runs, progress=progress, ended=ended)
        eps = scene.eps
    traced = {key: runs[key] for key in (RunKey(l, k, realisation) for l, k in work)}
    return Measurement(traced, {realisation: tile.facts}, done["inputs"], axes,
                       done["segments"], eps, built - start, time.perf_counter() - built,
                       warnings=list(dict.fromkeys(tile.warnings)))


def _reporter(progress: Callable[[Progress], None], theta: float, phi: float,
              realisation: int, acc: Sums) -> Callable[[int], None]:
    """The per-batch callback of one direction: ``progress`` with its state."""
    return lambda _: progress(Progress(theta, phi, realisation, realisation + 1, acc.rays))


def lost_energy_warnings(directions: Sequence[DirectionRecord]) -> list[str]:
    """The warning a table carries when an incidence lost more than ``LOST_WARNING`` of
    its energy: the worst incidence, and how its rays ended.

    Parameters
    ----------
    directions : sequence of DirectionRecord
        A table's directions (``meta.directions``).

    Returns
    -------
    list of str
        Empty, or one sentence.
    """
    over = [d for d in directions if max(d.lost) > LOST_WARNING]
    if not over:
        return []
    worst = max(over, key=lambda d: max(d.lost))
    share = {k: worst.fates.get(k, 0) / worst.rays for k in ("leaked", "bounces")}
    return [f"lost energy: {100 * max(worst.lost):.3g}% of the incident energy at "
            f"theta_i {worst.theta_i:g}, phi_i {worst.phi_i:g} deg "
            f"({len(over)} of {len(directions)} incidences over {100 * LOST_WARNING:g}%): "
            f"{100 * share['leaked']:.3g}% of the rays left through the tile's underside "
            f"(gaps, or holes in a mesh), {100 * share['bounces']:.3g}% reached the bounce "
            "limit; the table's albedo leaves it out (close the surface, or raise "
            "simulation.bounces)"]


