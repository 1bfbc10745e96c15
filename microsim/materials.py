"""Facet scattering: what a ray does where it hits a face of a given material.

Each face carries a material id (an index into the tile's parts); each part has a resolved
``[material.<part>]`` section of the recipe. Scattering returns the new direction, the
factor (RGB) by which the path weight is multiplied, and the fraction transmitted into the
material (a non-refracting dielectric's 1 - F, reported as lost energy); the rest,
``1 - factor - transmitted``, is absorbed (by a conductor or a diffuse facet).

- ``mirror``: specular reflection, factor 1.
- ``conductor``: specular reflection, factor the exact conductor Fresnel reflectance per
  channel at the facet's incidence angle.
- ``dielectric``: specular reflection, factor the dielectric Fresnel reflectance; the
  refracted part is absorbed inside and reported as lost. With ``refract = true``: a
  Fresnel-weighted choice between reflection and refraction from either side, factor 1
  (``microsim.refraction.fresnel_choice``); the tracer keeps track of which paths are
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

from microsim.analytic.fresnel import fresnel_conductor, fresnel_dielectric
from microsim.errors import InputError
from microsim.frames import orthonormal_basis
from microsim.refraction import fresnel_choice, reflect
from microsim.tabulated import TabulatedMaterial


def cosine_about(n: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Cosine-weighted directions about each normal.

    Malley's method (a uniform point on the unit disc lifted to the hemisphere; PBR 4th
    ed., sec. A.5.3) in the orthonormal basis of Duff et al. 2017, "Building an
    orthonormal basis, revisited", JCGT 6(1), listing 3.

    Parameters
    ----------
    n : (k, 3) float
        Unit normals.
    u : (k, 2) float
        Uniform numbers in [0, 1).

    Returns
    -------
    (k, 3) float
        Unit directions with pdf cos(theta) / pi about ``n``.
    """
    t, s = orthonormal_basis(n)
    r = np.sqrt(u[:, 0])
    phi = 2.0 * np.pi * u[:, 1]
    z = np.sqrt(np.maximum(1.0 - u[:, 0], 0.0))
    return (r * np.cos(phi))[:, None] * t + (r * np.sin(phi))[:, None] * s + z[:, None] * n


class FacetMaterials:
    """The materials of one tile's faces.

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
    refracting : (parts + 1,) bool
        Which parts refract (the last entry, for part -1 = air, is False).
    absorption : (parts + 1, 3) float
        Beer-Lambert coefficient per unit length inside each refracting part (0 elsewhere;
        the last row, for part -1 = air, is 0).
    curved : (m, 3, 3) float or None
        ``curved`` with the faces of refracting parts made flat: a ray inside a medium
        meets its faces from behind, where the entry-point construction of
        ``microsim.shading`` does not apply, so refracting tubes keep their facets.

    Raises
    ------
    InputError
        If a table file is missing or unusable (naming ``material.<part>.path``).
    """

    def __init__(self, face_material: np.ndarray, parts: Sequence[str],
                 materials: Mapping[str, Mapping[str, Any]],
                 tangents: np.ndarray | None = None,
                 curved: np.ndarray | None = None) -> None:
        self.face_material = np.asarray(face_material, np.int64)
        self.specs = [dict(materials[p]) for p in parts]
        self.tangents = tangents
        self.tables = {m: TabulatedMaterial.load(spec["path"], spec["component"],
                                                 f"material.{parts[m]}.path", spec["axis"])
                       for m, spec in enumerate(self.specs) if spec["kind"] == "table"}
        for m, table in self.tables.items():
            if table.uses_tangents and tangents is None:
                raise InputError(f"material.{parts[m]}.axis = 'tangent': this surface gives "
                                 "its faces no tangents (velvet does); use 'x' or 'y'")
        self.inputs = [{"part": parts[m], **t.source} for m, t in self.tables.items()]
        self.refracting = np.array([s["kind"] == "dielectric" and bool(s.get("refract"))
                                    for s in self.specs] + [False])
        self.absorption = np.zeros((len(self.specs) + 1, 3))
        for m in np.flatnonzero(self.refracting):
            self.absorption[m] = self.specs[m].get("absorption", 0.0)
        self.curved = None if curved is None else np.where(
            self.refracting[self.face_material][:, None, None], 0.0, curved)

    def scatter(self, faces: np.ndarray, d: np.ndarray, n: np.ndarray,
                rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Scatter rays at the faces they hit.

        Parameters
        ----------
        faces : (k,) int
            Faces hit.
        d : (k, 3) float
            Unit directions of travel (``d . n < 0``, except at refracting faces, which
            are hit from either side).
        n : (k, 3) float
            Unit normals of the faces.
        rng : numpy.random.Generator
            Source of the random numbers (drawn part by part, in part order).

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
        out = np.empty_like(d)
        factor = np.empty((len(d), 3))
        transmitted = np.zeros((len(d), 3))
        mat = self.face_material[faces]
        for m, spec in enumerate(self.specs):
            sel = np.flatnonzero(mat == m)
            if sel.size == 0:
                continue
            if sel.size == len(d):  # one material for every ray: no gathering
                sel = slice(None)
                ds, ns = d, n
            else:
                ds, ns = np.take(d, sel, axis=0), np.take(n, sel, axis=0)
            count = len(ds)
            kind = spec["kind"]
            if kind == "lambertian":
                out[sel] = cosine_about(ns, rng.random((count, 2)))
                factor[sel] = np.broadcast_to(spec["albedo"], (count, 3))
                continue
            if kind == "table":
                table = self.tables[m]
                along = (np.take(self.tangents, faces[sel], axis=0)
                         if table.uses_tangents else None)
                out[sel], factor[sel] = table.scatter(ds, ns, rng, along)
                continue
            if self.refracting[m]:
                out[sel] = fresnel_choice(ds, ns, spec["eta"], rng.random(count))[0]
                factor[sel] = 1.0
                continue
            out[sel] = reflect(ds, ns)
            if kind == "mirror":
                factor[sel] = 1.0
                continue
            cos = np.clip(-np.einsum("ij,ij->i", ds, ns), 0.0, 1.0)
            if kind == "conductor":
                factor[sel] = fresnel_conductor(cos[:, None], np.asarray(spec["eta"]),
                                                np.asarray(spec["k"]))
            else:
                factor[sel] = fresnel_dielectric(cos, spec["eta"])[:, None]
                transmitted[sel] = 1.0 - factor[sel]
        return out, factor, transmitted
