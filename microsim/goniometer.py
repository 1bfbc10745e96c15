"""The virtual goniophotometer's BRDF estimator: binned f_r with standard errors.

It samples the tile as a real instrument does and counts what the paths over the periodic
tracer (``microsim.paths``) return; docs/goniometer.md explains the sampling, the weights,
the error bars and the adaptive stop. (Masking G1 is measured by ``microsim.masking``.)

Rays -wi start at uniform points of the tile's top plane (uniform irradiance over
the projected area, as a collimated beam gives) and scatter until they escape; an escaping
ray of weight w lands in a bin B of projected solid angle Omega_B, and
f_r(wi, B) = E[w 1_B] / Omega_B (the estimator is the fraction of incident power per
projected solid angle: Nicodemus et al. 1977, NBS Monograph 160, eq. 4).
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

import microsim
from microsim.compare import direction
from microsim.kernel.tally import bin_escapes, in_blocks
from microsim.materials import FacetMaterials
from microsim.paths import Paths, trace_paths
from microsim.surfaces.tile import Tile
from microsim.tables import sh
from microsim.tables.binning import HemisphereBins
from microsim.tables.components import DEFAULT_ORDERS, components_for
from microsim.tables.table import BRDFTable
from microsim.trace import PeriodicScene

BATCH = 65536
"""Rays per batch: the unit of random streams, accumulation and the adaptive stop."""
LOST_WARNING = 0.01
"""Lost energy (paths cut at the bounce limit or leaving through the tile's underside) as
a fraction of the incident energy above which a table carries a warning: a closed surface
with enough bounces loses none (the shipped recipes lose under 0.1%, except the open
weave, whose gaps let about 5% through)."""


class _Sums:
    """Running per-bin sums of one incident direction, per component.

    Row 0 of every array holds every escaping ray (``"total"``); row k, 1 ≤ k < N, the rays
    that escaped after k scattering events; row N those after N or more
    (``components_for(N)``, N = ``orders``). The compiled tally adds each ray to row 0 and
    to the row of its order (``slot_of_order``), so the order rows add up to row 0.

    Attributes
    ----------
    rays : int
        Rays launched.
    orders : int
        N of the order components.
    slot_of_order : (N + 1,) int
        Row of scattering order k at index min(k, N) (``microsim.kernel.tally``; order 0,
        not escaped, has none: −1).
    sums, sums_sq : (N + 1, b, 3) float
        Per row and bin, the sum of exit weights w and of w**2.
    lost, transmitted, absorbed : (3,) float
        Summed weight of paths ended by the simulation (bounce limit, leaks), transmitted
        (1 - F at non-refracting dielectrics; refracted paths out through the bottom), and
        absorbed (by the other materials and inside absorbing media).
    fates : dict of str to int
        Paths per ending.
    sh_order : int
        Order L of the spherical-harmonic moments (0: none).
    sh_sums : (N + 1, (L + 1)², 3) float, or None
        Σ w Y_k(ωo) over the escaping rays the bins take, per row
        (``microsim.tables.sh``; ωo's azimuth relative to ``phi_ref`` of ``add``).
    sh_sums_sq : (N + 1, (2L + 1)², 3) float, or None
        Σ w² Y_K(ωo) to order 2L, from which ``sh.second_moments`` gives Σ (w Y_k)².
    """

    def __init__(self, bins: int, sh_order: int = 0, orders: int = DEFAULT_ORDERS) -> None:
        self.rays = 0
        self.orders = int(orders)
        self.slot_of_order = np.concatenate([[-1], np.arange(1, self.orders + 1)])
        rows = self.orders + 1
        self.sums = np.zeros((rows, bins, 3))
        self.sums_sq = np.zeros((rows, bins, 3))
        self.sh_order = int(sh_order)
        self.sh_sums = np.zeros((rows, sh.size(sh_order), 3)) if sh_order else None
        self.sh_sums_sq = np.zeros((rows, sh.size(2 * sh_order), 3)) if sh_order else None
        self.lost, self.transmitted, self.absorbed = np.zeros(3), np.zeros(3), np.zeros(3)
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
        n = len(paths.order)
        self.rays += n
        index = np.empty(n, np.int64)

        def block(a: int, b: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            sums = np.zeros_like(self.sums)
            sums_sq, unbinned = np.zeros_like(sums), np.zeros(3)
            bin_escapes(paths.direction[a:b], paths.weight[a:b], paths.order[a:b], phi_ref,
                        bins.theta_bins, bins.phi_bins, bins.folded, self.slot_of_order, sums,
                        sums_sq, index[a:b], unbinned)
            return sums, sums_sq, unbinned

        sums, sums_sq, unbinned = in_blocks(block, n, mapper)
        self.sums += sums
        self.sums_sq += sums_sq
        if self.sh_order:
            self._add_sh(paths, index >= 0, phi_ref, mapper)
        # an escaping ray the bins do not take (none for a closed surface) is lost, not hidden
        self.lost += paths.lost + unbinned
        self.transmitted += paths.transmitted
        self.absorbed += paths.absorbed
        for name, count in paths.fate_counts.items():
            self.fates[name] = self.fates.get(name, 0) + count

    def _add_sh(self, paths: Paths, binned: np.ndarray, phi_ref: float,
                mapper: sh.Mapper | None) -> None:
        """Moments of the escaping rays' exit weights against the real harmonics: one
        transform per order row over that row's rays alone, the total row their sum."""
        loc = sh.angles(paths.direction[binned], phi_ref)
        w = paths.weight[binned]
        row = self.slot_of_order[np.minimum(paths.order[binned], self.orders)]
        for k in range(1, self.orders + 1):
            mine = row == k
            if mine.any():
                s1, s2 = sh.moments(loc[mine], w[mine], self.sh_order, mapper)
                self.sh_sums[k] += s1
                self.sh_sums_sq[k] += s2
                self.sh_sums[0] += s1
                self.sh_sums_sq[0] += s2

    @property
    def lost_energy(self) -> np.ndarray:
        """(3,) summed weight a table reports as lost: simulation ends and transmission."""
        return self.lost + self.transmitted


def _table(bins: HemisphereBins, theta_deg: Sequence[float], phi_deg: Sequence[float],
           isotropic: bool, runs: Sequence[Sequence[_Sums]], meta: Mapping[str, Any]
           ) -> BRDFTable:
    """The table of the sums of every direction (``runs[l][k]``)."""

    def stacked(get: Callable[[_Sums], np.ndarray]) -> np.ndarray:
        return np.stack([np.stack([get(acc) for acc in row]) for row in runs])

    def by_component(get: Callable[[_Sums], np.ndarray]) -> dict[str, np.ndarray]:
        """Per component, the (a, b, ...) array of its row."""
        rows = stacked(get)                                  # (a, b, N + 1, ...)
        return {c: rows[:, :, k] for k, c in enumerate(runs[0][0].components)}

    rays = np.array([[acc.rays for acc in row] for row in runs], np.int64)
    sums = by_component(lambda a: a.sums)
    sums_sq = by_component(lambda a: a.sums_sq)
    harmonics = runs[0][0].sh_order > 0
    sh_sums = by_component(lambda a: a.sh_sums) if harmonics else None
    sh_sums_sq = by_component(lambda a: a.sh_sums_sq) if harmonics else None
    return BRDFTable.from_sums(bins, np.radians(theta_deg), np.radians(phi_deg), isotropic,
                               rays, sums, sums_sq, stacked(lambda a: a.lost_energy), meta,
                               sh_sums=sh_sums, sh_sums_sq=sh_sums_sq)


MAX_RAYS_FACTOR = 100
"""With ``target_error`` and no ``max_rays``, at most this many times ``rays`` are traced."""


def _measure_direction(scene: PeriodicScene, facets: FacetMaterials, bins: HemisphereBins,
                       simulation: Mapping[str, Any], theta: float, phi: float,
                       isotropic: bool, streams: tuple[int, int],
                       progress: Callable[[dict[str, Any]], None] | None, sh_order: int = 0,
                       orders: int = DEFAULT_ORDERS) -> tuple[_Sums, str, float]:
    """Run the batches of one incident direction (degrees); see ``simulate``.

    Outgoing azimuths are binned relative to ``phi`` for isotropic tables, absolute
    otherwise (the table's convention). Returns the sums, why the batches stopped
    (``"rays"``: the fixed count, ``"target_error"`` or ``"max_rays"``), and the median
    relative error over the lobe.
    """
    phi_ref = math.radians(phi) if isotropic else 0.0
    wi = direction(math.radians(theta), math.radians(phi))
    acc = _Sums(bins.size, sh_order, orders)
    planned = int(simulation["rays"])
    target = simulation.get("target_error")
    most = simulation.get("max_rays") or MAX_RAYS_FACTOR * planned
    batch = 0
    while True:
        n = min(BATCH, planned - acc.rays)
        seed = np.random.SeedSequence(int(simulation["seed"]), spawn_key=(*streams, batch))
        xy = np.random.default_rng(seed).random((n, 2)) * scene.period
        origins = np.column_stack([xy, np.full(n, scene.z_top)])
        paths = trace_paths(scene, facets, origins, np.broadcast_to(-wi, (n, 3)),
                            int(simulation["bounces"]), seed)
        acc.add(paths, bins, phi_ref, scene.map)
        batch += 1
        # the figure the table reports, for this direction alone
        error = _table(bins, [theta], [phi], isotropic, [[acc]], {}).median_rel_stderr()
        if progress is not None:
            progress({"theta_i": theta, "phi_i": phi, "rays": acc.rays, "rel_stderr": error})
        if acc.rays < planned:
            continue
        if target is None:
            return acc, "rays", error
        if error <= target:
            return acc, "target_error", error
        if acc.rays >= most:
            return acc, "max_rays", error
        planned = min(acc.rays + BATCH, most)


@dataclass
class Measurement:
    """What tracing some incident polar angles of one table gives; see ``measure_directions``.

    Attributes
    ----------
    rows : dict of int to list of (_Sums, str, float)
        For each measured index l of ``simulation["theta_i"]``, one entry per incident
        azimuth k: the direction's sums, why its batches stopped, and its median relative
        error over the lobe (``_measure_direction``).
    surface : dict
        The tile's ``info``.
    inputs : list of dict
        Provenance of the tables its facet materials read (``FacetMaterials.inputs``).
    isotropic : bool
        Whether one incident azimuth (0) was measured.
    segments : int
        Embree queries traced.
    offset : float
        The scene's ray offset (``PeriodicScene.eps``).
    scene_time, trace_time : float
        Wall-clock seconds to build the scene and to trace.
    """

    rows: dict[int, list[tuple[_Sums, str, float]]]
    surface: dict[str, Any]
    inputs: list[dict[str, Any]]
    isotropic: bool
    segments: int
    offset: float
    scene_time: float
    trace_time: float


def incident_azimuths(isotropic: bool, simulation: Mapping[str, Any]) -> list[float]:
    """Incident azimuths (degrees) a table measures: ``[0]`` when isotropic."""
    return [0.0] if isotropic else [float(p) for p in simulation["phi_i"]]


def measure_directions(tile: Tile, materials: Mapping[str, Mapping[str, Any]],
                       simulation: Mapping[str, Any], table: Mapping[str, Any],
                       thetas: Sequence[int] | None = None, *, threads: int | None = None,
                       progress: Callable[[dict[str, Any]], None] | None = None,
                       scene: PeriodicScene | None = None) -> Measurement:
    """Trace the incident directions of some polar angles of a table (see ``simulate``).

    Parameters
    ----------
    tile, materials, simulation, table, threads, progress
        As for ``simulate``.
    thetas : sequence of int or None
        Indices into ``simulation["theta_i"]`` to measure, every incident azimuth of each
        (default: all). Direction (l, k) draws the same random numbers whichever other
        directions are measured with it, so measurements of disjoint index sets merge
        (``assemble_table``) into exactly the table of one measurement of all of them.
    scene : PeriodicScene or None
        An open scene of ``tile`` to trace in (left open; ``threads`` is then unused), or
        None to build one for this call. The numbers do not depend on it.

    Returns
    -------
    Measurement
    """
    start = time.perf_counter()
    isotropic = bool(tile.info.get("isotropic", False))
    theta_deg = [float(t) for t in simulation["theta_i"]]
    phi_deg = incident_azimuths(isotropic, simulation)
    bins = HemisphereBins(int(table["theta_bins"]), int(table["phi_bins"]))
    facets = FacetMaterials(tile.material, tile.parts, materials, tile.tangents,
                            tile.curved)
    chosen = range(len(theta_deg)) if thetas is None else thetas
    with contextlib.ExitStack() as stack:
        if scene is None:
            scene = stack.enter_context(PeriodicScene(tile, threads))
        built, before = time.perf_counter(), scene.segments
        rows = {l: [_measure_direction(scene, facets, bins, simulation, theta_deg[l], phi,
                                       isotropic, (l, k), progress,
                                       int(table.get("sh_order", 0)),
                                       int(table.get("orders", DEFAULT_ORDERS)))
                    for k, phi in enumerate(phi_deg)] for l in chosen}
        segments, eps = scene.segments - before, scene.eps
    return Measurement(rows, dict(tile.info), facets.inputs, isotropic, segments, eps,
                       built - start, time.perf_counter() - built)


def lost_energy_warnings(directions: Sequence[Mapping[str, Any]]) -> list[str]:
    """The warning a table carries when an incidence lost more than ``LOST_WARNING`` of
    its energy: the worst incidence, and how its rays ended.

    Parameters
    ----------
    directions : sequence of dict
        ``meta["directions"]`` of a table: ``theta_i``, ``phi_i``, ``rays``, ``lost``
        (per channel, per unit incident energy) and ``fates`` (paths per ending).

    Returns
    -------
    list of str
        Empty, or one sentence.
    """
    over = [d for d in directions if max(d["lost"]) > LOST_WARNING]
    if not over:
        return []
    worst = max(over, key=lambda d: max(d["lost"]))
    share = {k: worst["fates"].get(k, 0) / worst["rays"] for k in ("leaked", "bounces")}
    return [f"lost energy: {100 * max(worst['lost']):.3g}% of the incident energy at "
            f"theta_i {worst['theta_i']:g}, phi_i {worst['phi_i']:g} deg "
            f"({len(over)} of {len(directions)} incidences over {100 * LOST_WARNING:g}%): "
            f"{100 * share['leaked']:.3g}% of the rays left through the tile's underside "
            f"(gaps, or holes in a mesh), {100 * share['bounces']:.3g}% reached the bounce "
            "limit; the table's albedo leaves it out (close the surface, or raise "
            "simulation.bounces)"]


def assemble_table(parts: Sequence[Measurement], materials: Mapping[str, Mapping[str, Any]],
                   simulation: Mapping[str, Any], table: Mapping[str, Any], *,
                   recipe: Mapping[str, Any] | None = None, wall_time: float | None = None
                   ) -> BRDFTable:
    """The table of measurements that together cover every incident polar angle once.

    Parameters
    ----------
    parts : sequence of Measurement
        Of the same tile, materials, simulation and table, in any order.
    materials, simulation, table, recipe
        As for ``simulate``.
    wall_time : float or None
        Seconds the whole measurement took. Given, the metadata holds the timings
        (``wall_time``, ``scene_time``, ``rays_per_second``, ``segments_per_second``);
        None leaves them out, so the table depends on nothing but the recipe.

    Returns
    -------
    BRDFTable
        As ``simulate`` returns it.

    Raises
    ------
    ValueError
        If the parts do not cover each polar angle exactly once.
    """
    rows = {l: row for part in parts for l, row in part.rows.items()}
    theta_deg = [float(t) for t in simulation["theta_i"]]
    if sorted(rows) != list(range(len(theta_deg))) or \
            sum(len(part.rows) for part in parts) != len(theta_deg):
        raise ValueError("the measurements do not cover every incident polar angle once")
    runs = [rows[l] for l in range(len(theta_deg))]
    first = parts[0]
    phi_deg = incident_azimuths(first.isotropic, simulation)
    bins = HemisphereBins(int(table["theta_bins"]), int(table["phi_bins"]))
    rays = sum(acc.rays for row in runs for acc, _, _ in row)
    segments = sum(part.segments for part in parts)
    meta = {
        "recipe": dict(recipe) if recipe is not None else
        {"material": dict(materials), "simulation": dict(simulation), "table": dict(table)},
        "microsim_version": microsim.__version__,
        "surface": dict(first.surface),
        "inputs": first.inputs,
        "seed": int(simulation["seed"]),
        "isotropic": first.isotropic,
        "directions": [{"theta_i": theta_deg[l], "phi_i": phi_deg[k], "rays": acc.rays,
                        "lost": (acc.lost / acc.rays).tolist(),
                        "transmitted": (acc.transmitted / acc.rays).tolist(),
                        "absorbed": (acc.absorbed / acc.rays).tolist(),
                        "fates": acc.fates, "stop": stop, "rel_stderr": error}
                       for l, row in enumerate(runs)
                       for k, (acc, stop, error) in enumerate(row)],
        "stop": sorted({stop for row in runs for _, stop, _ in row}),
        "segments": segments,
        "batch": BATCH,
        "offset": first.offset,
    }
    meta["warnings"] = lost_energy_warnings(meta["directions"])
    if wall_time is not None:
        traced = sum(part.trace_time for part in parts)
        meta.update(wall_time=wall_time, scene_time=sum(part.scene_time for part in parts),
                    rays_per_second=rays / traced, segments_per_second=segments / traced)
    result = _table(bins, theta_deg, phi_deg, first.isotropic,
                    [[acc for acc, _, _ in row] for row in runs], meta)
    for entry, albedo in zip(result.meta["directions"], result.albedo.reshape(-1, 3),
                             strict=True):
        entry["albedo"] = albedo.tolist()
    return result


def simulate(tile: Tile, materials: Mapping[str, Mapping[str, Any]],
             simulation: Mapping[str, Any], table: Mapping[str, Any], *,
             recipe: Mapping[str, Any] | None = None, threads: int | None = None,
             progress: Callable[[dict[str, Any]], None] | None = None) -> BRDFTable:
    """Measure the tile's BRDF table with the virtual goniophotometer.

    Parameters
    ----------
    tile : Tile
        The surface. ``tile.info["isotropic"]`` (default False) says whether one incident
        azimuth (0) suffices; otherwise every ``simulation["phi_i"]`` is measured.
    materials : mapping
        Resolved ``[material]``: one section per part of the tile.
    simulation : mapping
        Resolved ``[simulation]``: ``theta_i``, ``phi_i`` (degrees), ``rays``,
        ``bounces``, ``seed``, and optionally ``target_error`` and ``max_rays``.
    table : mapping
        Resolved ``[table]``: ``theta_bins``, ``phi_bins``, and optionally ``sh_order``
        (spherical-harmonic order of the escaping rays' moments; 0 or absent: none) and
        ``orders`` (N: the order components; default ``DEFAULT_ORDERS``).
    recipe : mapping or None
        The full resolved recipe, stored in the table's metadata (default: the three
        sections given).
    threads : int or None
        Tracing threads (default: every CPU). The result does not depend on it.
    progress : callable or None
        Called after every batch with a dict: ``theta_i``, ``phi_i`` (degrees),
        ``rays`` (so far, this direction), ``rel_stderr`` (median relative standard error
        over the lobe, or None without a target).

    Returns
    -------
    BRDFTable
        Sums per bin for the components ``"total"`` and ``"order1"``, …, ``"order{N}+"``
        (``components_for(N)``: escaped after 1, …, N − 1 and N or more scattering
        events, adding up to the total), with metadata (see docs/goniometer.md).

    Notes
    -----
    Direction (l, k) runs batches of ``BATCH`` rays (the last one of the planned rays may
    be shorter); batch b draws from ``SeedSequence(seed, spawn_key=(l, k, b))``, so the
    numbers depend on neither the thread count nor the chunking. With ``target_error``,
    batches are added after the first ``rays`` until the median relative error over the
    lobe is at most the target, or ``max_rays`` (default ``MAX_RAYS_FACTOR * rays``) is
    reached.
    """
    start = time.perf_counter()
    measured = measure_directions(tile, materials, simulation, table, threads=threads,
                                  progress=progress)
    return assemble_table([measured], materials, simulation, table, recipe=recipe,
                          wall_time=time.perf_counter() - start)


def simulate_recipe(recipe: Mapping[str, Any], progress: Callable[[dict[str, Any]], None]
                    | None = None, threads: int | None = None) -> BRDFTable:
    """Build a resolved recipe's surface and measure its BRDF table (see ``simulate``)."""
    from microsim.surfaces import build_tile

    tile = build_tile(dict(recipe["surface"]))
    return simulate(tile, recipe["material"], recipe["simulation"], recipe["table"],
                    recipe=recipe, threads=threads, progress=progress)
