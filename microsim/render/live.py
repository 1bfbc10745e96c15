"""Simulation at render time: a Mitsuba 3 BSDF that traces the recipe's microgeometry.

The seed lecture's fourth way from microgeometry to a renderer is to "just do simulation
at render time": each time the path tracer asks the surface for a scattered direction,
a ray is traced through the recipe's periodic tile by the compiled kernel, as
``microsim simulate`` traces its beam (docs/goniometer.md), and the direction it escapes
in and its weight are the sample. No table, no binning, no interpolation and no model
stand between the microgeometry and the image, so the render of a table made from the
same recipe must agree with it within the two renders' noise: a test of the whole table
pipeline (binning, interpolation, the RGL export, Mitsuba's ``measured``) that needs no
model (docs/render.md, "Simulation at render time").

**The sample.** A ray arriving from ωi (towards the viewer, in the surface's local frame:
+z the normal, +x the tile's x, the object's tangent) starts at a uniform random point of
the top of the tile's slab, travelling along −ωi, scatters by the facets' materials and
escapes along ωo with throughput w (RGB). Over the beam, E[w δ(ω − ωo)] = f_r(ωi, ωo)
cos θo (the goniometer's estimator of f_r cos θo, Cook & Torrance 1982's definition of
f_r as reflected radiance over incident irradiance; docs/goniometer.md), so ωo with
weight w is a BSDF sample whose weight f_r cos θo / pdf is w, without the pdf ever being
known. Paths the simulation ends (bounce limit, trapped, through the tile's underside)
are samples of weight 0, as the table leaves that energy out of f_r. The path is traced
from the viewer's side: it samples f_r(ωo ← ωi), which for the reciprocal facet
materials (mirror, conductor, Lambertian, dielectric reflection) is f_r(ωi ← ωo), the
function a table holds (Helmholtz reciprocity; tests/test_orders.py and tests/test_
reciprocity.py check it of the simulated tables).

**What it cannot do.** It has no ``eval``: f_r at a given pair of directions is not
known, only sampled. So the BSDF is declared a delta lobe: Mitsuba's path tracer then
does no next-event estimation at it and counts a sampled ray that reaches a light in full.
Lights must be reachable by sampling: an environment (``sky``, ``envmap``) or a sun of
finite size (``sun:radius=…``, a far disc); a directional light (radius 0) would be
black. Each realisation is an open Embree scene, so every realisation the table averages
is in memory at once (``memory_bytes``).

**Which tile.** A sample picks realisation ⌊u K⌋ of the K opened (the first of its three
uniform numbers u), so the render averages the same ensemble as a table of those K
realisations. The random numbers of the kernel are keyed by a hash of the sample's own
uniform numbers and the seed, so a pixel's samples do not depend on the order in which
Mitsuba's threads ask for them.
"""

from __future__ import annotations

import hashlib
import math
from typing import TYPE_CHECKING, Any

import numpy as np

from microsim.errors import InputError
from microsim.kernel import slots as ks
from microsim.kernel.packing import FacetMaterials
from microsim.measurement.scene import PeriodicScene
from microsim.memory import check_memory
from microsim.render.bsdfs import rotation_z
from microsim.settings import Recipe

if TYPE_CHECKING:
    from microsim.render.scene import Light

SCENE_BYTES_PER_FACE = 400
"""Memory the guard counts for one open realisation per face of its tile: the tile's
arrays, the face table and Embree's BVH (measured: 29 MiB resident a realisation of the
shipped 256² Gaussian tile's 131,072 faces, 235 bytes a face; the rest is a margin for
the tracing buffers and for tiles whose faces cost more)."""


def memory_bytes(faces: int, realisations: int) -> float:
    """Estimated memory of ``realisations`` open scenes of a tile of ``faces`` faces."""
    return float(SCENE_BYTES_PER_FACE) * faces * realisations


class LiveSurface:
    """The realisations of a recipe's surface, open for tracing render-time samples.

    Parameters
    ----------
    recipe : Recipe
        A resolved recipe; its ``simulation.bounces`` limits the paths.
    realisations : int
        K, the realisations 0 … K − 1 opened (those a table of K realisations averages).
    tiles : callable
        Realisation index → its tile (``microsim.measurement.simulation.Tiles``).
    seed : int
        Mixed into every sample's key.
    threads : int
        Tracing threads per call (1 where the renderer's own threads call concurrently).
    memory_limit_gib : float or None
        The memory guard's budget (``microsim.memory``).

    Raises
    ------
    InputError
        If the K open scenes would exceed the memory guard.
    """

    def __init__(self, recipe: Recipe, realisations: int, tiles: Any, seed: int = 0,
                 threads: int | None = 1, memory_limit_gib: float | None = None) -> None:
        first = tiles(0)
        check_memory(memory_bytes(len(first.faces), realisations),
                     f"render --live: {realisations} open realisations of this tile "
                     f"({len(first.faces):,} faces)",
                     "lower --realisations or the surface's resolution", memory_limit_gib)
        self.bounces = int(recipe.simulation.bounces)
        self.seed = int(seed)
        self.scenes: list[PeriodicScene] = []
        self.facets: list[FacetMaterials] = []
        for r in range(realisations):
            tile = first if r == 0 else tiles(r)
            self.scenes.append(PeriodicScene(tile, threads=threads))
            self.facets.append(FacetMaterials(tile.material, tile.parts, recipe.material,
                                              tile.tangents, tile.curved))
        self.samples = 0
        self.segments = 0

    def close(self) -> None:
        """Release the scenes."""
        for scene in self.scenes:
            scene.close()
        self.scenes = []

    def __enter__(self) -> LiveSurface:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def entropy(self, u: np.ndarray) -> int:
        """The entropy of the kernel's keys for the samples ``u``: a hash of their bits
        and the seed (realisation r's key is ``SeedSequence(entropy, spawn_key=(r,))``)."""
        digest = hashlib.blake2b(np.ascontiguousarray(u).tobytes(), digest_size=16,
                                 key=self.seed.to_bytes(8, "little")).digest()
        return int.from_bytes(digest, "little")

    def sample(self, wi: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Scattered directions and weights of rays arriving from ``wi``.

        Parameters
        ----------
        wi : (n, 3) float
            Unit directions towards where the rays come from, local frame (z > 0).
        u : (n, 3) float
            Uniform numbers in [0, 1): the realisation (``u[:, 0]``) and the start point
            over the tile (``u[:, 1:]``).

        Returns
        -------
        wo : (n, 3) float
            Escape directions (zero where the path did not escape).
        weight : (n, 3) float
            Throughput w, RGB (zero where the path did not escape, or ``wi`` is below the
            horizon).
        """
        wi = np.asarray(wi, float).reshape(-1, 3)
        u = np.asarray(u, float).reshape(-1, 3)
        n = len(wi)
        wo, weight = np.zeros((n, 3)), np.zeros((n, 3))
        k = len(self.scenes)
        which = np.minimum((u[:, 0] * k).astype(np.int64), k - 1)
        which[wi[:, 2] <= 0] = k  # below the horizon: no path
        order = np.argsort(which, kind="stable")
        ends = np.searchsorted(which[order], np.arange(k + 1))
        entropy = self.entropy(u)
        for r in np.flatnonzero(np.diff(ends)):
            rows = order[ends[r]:ends[r + 1]]
            scene = self.scenes[r]
            origins = np.empty((len(rows), 3))
            origins[:, 0] = u[rows, 1] * scene.period[0]
            origins[:, 1] = u[rows, 2] * scene.period[1]
            origins[:, 2] = scene.z_top
            out = scene.run(origins, -wi[rows], self.facets[r], self.bounces,
                            np.random.SeedSequence(entropy, spawn_key=(int(r),)))
            self.segments += out.segments
            escaped = (out.ints[:, ks.O_FATE] == ks.ESCAPED) & (out.ints[:, ks.O_ORDER] > 0)
            hit = rows[escaped]
            wo[hit] = out.floats[escaped, ks.S_DX:ks.S_DZ + 1]
            weight[hit] = out.floats[escaped, ks.O_W:ks.O_W + 3]
        self.samples += n
        return wo, weight


def live_bsdf(mi: Any, surface: LiveSurface, rotation: float = 0.0) -> Any:
    """``surface`` as a Mitsuba BSDF whose ``sample`` traces the microgeometry.

    A delta lobe for Mitsuba (no ``eval``, no next-event estimation; module docstring):
    ``sample`` returns the traced escape direction with ``pdf`` 1 and the throughput as
    its weight, or ``pdf`` 0 (an invalid sample, which ends the path) where the path did
    not escape. Works in every variant: one sample per call in ``scalar_rgb``, whole
    wavefronts in ``llvm_ad_rgb``.

    Parameters
    ----------
    mi : module
        Mitsuba, variant set.
    surface : LiveSurface
    rotation : float
        Degrees about the normal: the material's +x axis turns from the tangent towards
        the bitangent (as ``render --rotate`` turns a table).
    """
    import drjit as dr

    from microsim.render.bsdfs import _numpy

    to_tile, from_tile = rotation_z(-rotation), rotation_z(rotation)
    flags = mi.BSDFFlags.DeltaReflection | mi.BSDFFlags.FrontSide

    class LiveBSDF(mi.BSDF):
        def __init__(self, props: Any) -> None:
            mi.BSDF.__init__(self, props)
            self.m_flags = flags
            self.m_components = [flags]

        def sample(self, ctx: Any, si: Any, sample1: Any, sample2: Any,
                   active: Any = True) -> Any:
            wi = _numpy(si.wi)
            u = np.column_stack([np.ravel(np.array(sample1, dtype=float)),
                                 np.atleast_2d(_numpy(sample2))])
            scalar = wi.ndim == 1
            wo, weight = surface.sample(wi.reshape(-1, 3) @ to_tile.T, u)
            wo = wo @ from_tile.T
            ok = (weight > 0).any(axis=1)
            bs = dr.zeros(mi.BSDFSample3f)
            if scalar:
                bs.wo = mi.Vector3f(*wo[0])
                bs.pdf = 1.0 if ok[0] else 0.0
                value = mi.Color3f(*weight[0])
            else:
                bs.wo = mi.Vector3f(np.ascontiguousarray(wo.T, dtype=np.float32))
                bs.pdf = mi.Float(ok.astype(np.float32))
                value = mi.Color3f(np.ascontiguousarray(weight.T, dtype=np.float32))
            bs.eta = 1.0
            bs.sampled_type = mi.UInt32(+mi.BSDFFlags.DeltaReflection)
            bs.sampled_component = 0
            return bs, dr.select(active, value, 0.0)

        def eval(self, ctx: Any, si: Any, wo: Any, active: Any = True) -> Any:
            return mi.Color3f(0.0)

        def pdf(self, ctx: Any, si: Any, wo: Any, active: Any = True) -> Any:
            return mi.Float(0.0)

        def eval_pdf(self, ctx: Any, si: Any, wo: Any, active: Any = True) -> Any:
            return self.eval(ctx, si, wo, active), self.pdf(ctx, si, wo, active)

        def to_string(self) -> str:
            return f"microsim live simulation ({len(surface.scenes)} realisations)"

    return LiveBSDF(mi.Properties())


def check_lights(lights: list[Light]) -> None:
    """Refuse lights a sampled-only BSDF cannot see: a sun of radius 0 (directional).

    Raises
    ------
    InputError
    """
    for light in lights:
        if light.kind == "sun" and not light.params.get("radius", 0.0) > 0.0:
            raise InputError("--light sun: --live needs a sun of finite size (radius=DEG "
                             "> 0; the live surface is sampled only, so a directional "
                             "light would not reach it), or sky / envmap lights")


def disc_radiance(irradiance: np.ndarray, radius_deg: float) -> np.ndarray:
    """Radiance of a uniform disc of angular radius ρ that gives ``irradiance`` on a
    surface facing it: E = L π sin²ρ (the projected solid angle of a cone of half-angle
    ρ about the normal)."""
    return np.asarray(irradiance, float) / (math.pi * math.sin(math.radians(radius_deg)) ** 2)
