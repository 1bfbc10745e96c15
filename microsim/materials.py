"""Facet scattering: what a ray does where it hits a face of a given material.

Each face carries a material id (an index into the tile's parts); each part has a resolved
``[material.<part>]`` section of the recipe, which ``FacetMaterials`` packs into the arrays
the compiled transport kernel reads (``microsim.kernel.scatter`` has the events).
Scattering returns the new direction, the factor (RGB) by which the path weight is
multiplied, and the fraction transmitted into the material (a non-refracting dielectric's
1 - F, reported as lost energy); the rest, ``1 - factor - transmitted``, is absorbed (by a
conductor or a diffuse facet).

- ``mirror``: specular reflection, factor 1.
- ``conductor``: specular reflection, factor the exact conductor Fresnel reflectance per
  channel at the facet's incidence angle.
- ``dielectric``: specular reflection, factor the dielectric Fresnel reflectance; the
  refracted part is absorbed inside and reported as lost. With ``refract = true``: a
  Fresnel-weighted choice between reflection and refraction from either side, factor 1
  (``microsim.kernel.scatter.scatter_event``); the tracer keeps track of which paths are
  inside the medium and applies its ``absorption`` (docs/materials.md).
- ``lambertian``: cosine-weighted direction about the facet normal, factor the albedo (the
  cosine-weighted pdf cancels the BRDF's cosine: Pharr, Jakob & Humphreys, PBR 4th ed.,
  sec. 13.6.3 and 4.5.1).
- ``table``: a direction importance-sampled from a simulated BRDF table in the facet's
  frame, factor f_r cos / pdf (``microsim.tabulated``; hierarchies of scale).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numba import njit

from microsim.errors import InputError
from microsim.kernel import scatter as events
from microsim.kernel.rng import key_of
from microsim.kernel.shading import curved_table
from microsim.tabulated import TabulatedMaterial

KINDS = {"mirror": events.MIRROR, "conductor": events.CONDUCTOR,
         "dielectric": events.DIELECTRIC, "lambertian": events.LAMBERTIAN,
         "table": events.TABLE}
"""Kernel code of each recipe kind (a dielectric with ``refract = true`` is ``REFRACTING``)."""


class FacetMaterials:
    """The materials of one tile's faces, packed for the transport kernel.

    Parameters
    ----------
    face_material : (m,) int
        Material id per face (index into ``parts``).
    parts : sequence of str
        Part names.
    materials : mapping of str to dict
        A resolved ``[material.<part>]`` section per part (``kind`` and its keys).
    tangents : (m, 3) float or None
        Unit tangent per face from the generator (``Tile.tangents``), for table materials
        with ``axis = "tangent"``.
    curved : (m, 3, 3) float or None
        The tube each face approximates (``Tile.curved``), for shading normals.

    Attributes
    ----------
    tables : dict of int to TabulatedMaterial
        The loaded table of each part of kind ``table`` (by material id).
    inputs : list of dict
        Provenance of those tables: ``part``, ``path``, ``sha256``, ``component``.
    kind : (p,) int
        Kernel code per part (``microsim.kernel.scatter``).
    params : (p, 12) float
        Per part: η and k per RGB channel, the Lambertian albedo, the Beer-Lambert
        absorption per unit length inside a refracting part (``P_*`` offsets).
    tab_int : (p, TABLE_COLUMNS) int
        Per table part, its layout in ``tab_f`` (zeros for the others).
    tab_f : (q,) float
        The tables' nodes, bin edges, cumulative probabilities and weights.
    tangents : (m, 3) float
        The faces' tangents (zeros when the tile gives none).
    curved : (m, 9) or (0, 9) float
        The faces' tubes for the kernel (``microsim.kernel.shading.curved_table``:
        refracting parts flat; no rows when no face is curved).

    Raises
    ------
    InputError
        If a table file is missing or unusable (naming ``material.<part>.path``).
    """

    def __init__(self, face_material: np.ndarray, parts: Sequence[str],
                 materials: Mapping[str, Mapping[str, Any]],
                 tangents: np.ndarray | None = None,
                 curved: np.ndarray | None = None) -> None:
        self.face_material = np.ascontiguousarray(face_material, np.int64)
        specs = [dict(materials[p]) for p in parts]
        self.tables = {m: TabulatedMaterial.load(spec["path"], spec["component"],
                                                 f"material.{parts[m]}.path", spec["axis"])
                       for m, spec in enumerate(specs) if spec["kind"] == "table"}
        for m, table in self.tables.items():
            if table.uses_tangents and tangents is None:
                raise InputError(f"material.{parts[m]}.axis = 'tangent': this surface gives "
                                 "its faces no tangents (velvet does); use 'x' or 'y'")
        self.inputs = [{"part": parts[m], **t.source} for m, t in self.tables.items()]
        self.tangents = np.zeros((len(self.face_material), 3)) if tangents is None else \
            np.ascontiguousarray(tangents, float)
        self.kind = np.array([events.REFRACTING if s["kind"] == "dielectric" and
                              s.get("refract") else KINDS[s["kind"]] for s in specs], np.int64)
        self.params = np.zeros((len(specs), 12))
        for m, spec in enumerate(specs):
            for at, name in ((events.P_ETA, "eta"), (events.P_K, "k"),
                             (events.P_ALBEDO, "albedo"), (events.P_ABSORPTION, "absorption")):
                if name in spec:
                    self.params[m, at:at + 3] = spec[name]
        self.tab_int = np.zeros((len(specs), events.TABLE_COLUMNS), np.int64)
        chunks: list[np.ndarray] = [np.zeros(1)]
        used = 1
        for m, table in self.tables.items():
            self.tab_int[m], data = table.packed(used)
            chunks.append(data)
            used += len(data)
        self.tab_f = np.concatenate(chunks)
        self.curved = curved_table(curved, self.kind[self.face_material] == events.REFRACTING)

    def scatter(self, faces: np.ndarray, d: np.ndarray, n: np.ndarray,
                seed: np.random.SeedSequence, event: int = 1
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Scatter rays at the faces they hit, with the kernel's own events.

        Parameters
        ----------
        faces : (k,) int
            Faces hit.
        d : (k, 3) float
            Unit directions of travel (``d . n < 0``, except at refracting faces, which
            are hit from either side).
        n : (k, 3) float
            Unit normals of the faces.
        seed : numpy.random.SeedSequence
            Key of the random numbers; ray i draws those of ray i, event ``event``.
        event : int
            The events' number (a path's bounce, from 1).

        Returns
        -------
        out : (k, 3) float
            New unit directions.
        factor : (k, 3) float
            RGB weight factor, in [0, 1] (one ray's channel of a ``table`` may exceed 1;
            its mean does not).
        transmitted : (k, 3) float
            Fraction of the weight refracted into the material (dielectrics), in [0, 1].
        """
        out = np.empty((len(faces), 9))
        _scatter_all(np.ascontiguousarray(faces, np.int64), np.ascontiguousarray(d, float),
                     np.ascontiguousarray(n, float), self.face_material, self.tangents,
                     self.kind, self.params, self.tab_int, self.tab_f, key_of(seed), event,
                     out)
        return out[:, :3], out[:, 3:6], out[:, 6:]


@njit(**events.JIT)
def _scatter_all(faces: np.ndarray, d: np.ndarray, n: np.ndarray, face_material: np.ndarray,
                 tangents: np.ndarray, kind: np.ndarray, params: np.ndarray,
                 tab_int: np.ndarray, tab_f: np.ndarray, key: np.ndarray, event: int,
                 out: np.ndarray) -> None:
    """``scatter_event`` for every ray: rows of ``out`` (direction, factor, transmitted)."""
    for r in range(len(faces)):
        f = faces[r]
        part = face_material[f]
        result = events.scatter_event(kind[part], params, tab_int, part, tab_f, d[r, 0],
                                      d[r, 1], d[r, 2], n[r, 0], n[r, 1], n[r, 2],
                                      tangents[f, 0], tangents[f, 1], tangents[f, 2], key,
                                      r, event)
        for c in range(9):
            out[r, c] = result[c]
