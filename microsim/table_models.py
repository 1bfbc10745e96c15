"""The analytic models a table's metadata implies: the microfacet reference of a Gaussian
surface, and the parameters every model spec takes from a table when it does not give
them (the realised roughness, the facets' Fresnel or albedo, the fibres' geometry).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from microsim.analytic.brdf import TorranceSparrow
from microsim.analytic.ndf import Beckmann
from microsim.surfaces.facts import CylinderFacts, WeaveFacts
from microsim.tables.meta import TableMeta


def microfacet_model(meta: TableMeta) -> TorranceSparrow:
    """Torrance-Sparrow with a Beckmann NDF at the surface's realised roughness and
    height-correlated Smith masking: the model a Gaussian surface's single scattering is
    meant to follow (Walter et al. 2007, eq. 20; Heitz 2014, eq. 99).

    Parameters
    ----------
    meta : TableMeta
        A table's metadata: its surface's realised roughness and the recipe's material
        of the part ``base``.
    """
    ndf = Beckmann(**meta.surface.alpha_realised.params())
    material = meta.recipe.material["base"]
    return TorranceSparrow(ndf, fresnel=material.fresnel(), shadowing="smith-correlated")


FIBRE_PARTS = ("cylinder", "fibre")
"""Parts whose material a fibre model describes (the rest is the base)."""
FIBRE_SURFACES = ("cylinders", "velvet", "weave")
"""Surfaces whose ``[surface]`` keys models of their geometry take as defaults."""


def model_defaults(meta: TableMeta) -> dict[str, Any]:
    """Model parameters a table's metadata implies. A spec's own values override these.

    - ``alpha`` (or ``alpha_x``/``alpha_y``): the realised roughness.
    - Fresnel (``eta``, ``k``) or Lambertian ``albedo``: the material every part shares;
      on a fibre surface (a part ``cylinder`` or ``fibre``), that part's, with its
      ``kind``, and a diffuse (Lambertian or black) base's albedo as ``base_albedo``.
    - On cylinders, velvet and weaves, the recipe's ``[surface]`` keys (``radius``,
      ``spacing``, ``sink``, ``fibre_radius``, ``density``, …) for models of that
      geometry.
    - Kay-Kajiya on cylinders: the tangent of the surface's axis (``tangent_theta``,
      ``tangent_phi``, degrees), ``coverage`` = 2 radius / spacing, and for Lambertian
      fibres ``kd`` = albedo / π² (the energy-exact value: ``KayKajiya``).
    - Weaves: the yarns' tangent curves (``slope`` = π crimp amplitude / spacing, ``flat``
      = 1 − 2 / repeat) and Lambertian yarns' ``albedo_warp``, ``albedo_weft``.
    """
    out: dict[str, Any] = {}
    recipe, facts = meta.recipe, meta.surface
    surface = None if recipe is None else recipe.surface
    if surface is not None and surface.kind in FIBRE_SURFACES:
        out.update({k: v for k, v in surface.items() if k not in ("kind", "seed", "size")})
    if facts is not None and facts.alpha_realised is not None:
        out.update(facts.alpha_realised.params())
    materials = {} if recipe is None else dict(recipe.material)
    listed = list(materials.values())
    if listed and all(m == listed[0] for m in listed):
        out.update(listed[0].model_defaults())
    fibre = next((materials[p] for p in FIBRE_PARTS if p in materials), None)
    if fibre is not None:
        out.update(kind=fibre.kind, **fibre.model_defaults())
        base = materials.get("base")
        base_albedo = None if base is None else base.diffuse_albedo()
        if base_albedo is not None:
            out["base_albedo"] = list(base_albedo)
        fibre_albedo = fibre.diffuse_albedo()
        if fibre_albedo is not None:
            out["kd"] = float(np.mean(fibre_albedo)) / np.pi**2
    tile = None if facts is None else facts.tile
    if isinstance(tile, WeaveFacts) and "spacing" in out:
        # the yarns' tangent curves (microsim.analytic.cloth.tangents)
        out["slope"] = np.pi * tile.crimp_amplitude / out["spacing"]
        out["flat"] = 1.0 - 2.0 / tile.repeat
        for part in ("warp", "weft"):
            albedo = materials[part].diffuse_albedo() if part in materials else None
            if albedo is not None:
                out[f"albedo_{part}"] = list(albedo)
    if isinstance(tile, CylinderFacts) and tile.axis is not None:
        t = np.asarray(tile.axis, float)
        out["tangent_theta"] = float(np.degrees(np.arccos(np.clip(t[2], -1.0, 1.0))))
        out["tangent_phi"] = float(np.degrees(np.arctan2(t[1], t[0])))
        if "radius" in out and "spacing" in out:
            out["coverage"] = min(2.0 * out["radius"] / out["spacing"], 1.0)
    return out
