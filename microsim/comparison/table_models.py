"""The analytic models a table's metadata implies: the microfacet reference of a Gaussian
surface, and the parameters every model spec takes from a table when it does not give
them (the realised roughness, the facets' Fresnel or albedo, the fibres' geometry).
"""

from __future__ import annotations

import numpy as np

from microsim.analytic.brdf import TorranceSparrow
from microsim.analytic.ndf import Beckmann
from microsim.schema import Value
from microsim.spectra.channels import RGB
from microsim.surfaces.facts import CylinderFacts, WeaveFacts
from microsim.tables.meta import TableMeta
from microsim.tables.table import BRDFTable


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
    return TorranceSparrow(ndf, fresnel=material.fresnel(meta.recipe.table.channels),
                           shadowing="smith-correlated")


FIBRE_PARTS = ("cylinder", "fibre")
"""Parts whose material a fibre model describes (the rest is the base)."""


class ModelDefaults(dict[str, Value]):
    """Model parameters a table implies, by key (a ``dict`` of ``Value``, as a model spec's
    checked parameters), with where each came from.

    Attributes
    ----------
    sources : dict of str to str
        Per key, its source in words, e.g. ``"the table's realised alpha"``.
    for_model : dict of str to dict of str to Value
        Keys that apply to one model only, by model name (the table's measured albedo is
        a Lambertian model's albedo, not an Oren-Nayar facet albedo).
    """

    def __init__(self) -> None:
        super().__init__()
        self.sources: dict[str, str] = {}
        self.for_model: dict[str, dict[str, Value]] = {}

    def put(self, key: str, value: Value, source: str) -> None:
        """Set ``key`` to ``value``, from ``source``."""
        self[key] = value
        self.sources[key] = source


def model_defaults(meta: TableMeta) -> ModelDefaults:
    """Model parameters a table's metadata implies. A spec's own values override these.

    - ``alpha`` (or ``alpha_x``/``alpha_y``): the realised roughness.
    - Fresnel (``eta``, ``k``) or Lambertian ``albedo``: the material every part shares;
      on a fibre surface (a part ``cylinder`` or ``fibre``), that part's, with its
      ``kind``, and a diffuse (Lambertian or black) base's albedo as ``base_albedo``.
    - On cylinders, velvet and weaves, the recipe's ``[surface]`` keys that models of
      that geometry take (its kind's ``model_keys``: ``radius``, ``spacing``, ``sink``,
      ``fibre_radius``, ``density``, …).
    - Kay-Kajiya on cylinders: the tangent of the surface's axis (``tangent_theta``,
      ``tangent_phi``, degrees), ``coverage`` = 2 radius / spacing, and for Lambertian
      fibres ``kd`` = albedo / π² (the energy-exact value: ``KayKajiya``).
    - Weaves: the yarns' tangent curves (``slope`` = π crimp amplitude / spacing, ``flat``
      = 1 − 2 / repeat) and Lambertian yarns' ``albedo_warp``, ``albedo_weft``.

    Each value's source is in the result's ``sources``.
    """
    out = ModelDefaults()
    recipe, facts = meta.recipe, meta.surface
    surface = None if recipe is None else recipe.surface
    for k in () if surface is None else surface.model_keys:
        out.put(k, surface.value(k), f"the recipe's surface.{k}")
    if facts is not None and facts.alpha_realised is not None:
        for k, v in facts.alpha_realised.params().items():
            out.put(k, v, "the table's realised alpha")
    materials = {} if recipe is None else dict(recipe.material)
    channels = RGB if recipe is None else recipe.table.channels
    listed = list(materials.values())
    if listed and all(m == listed[0] for m in listed):
        for k, v in listed[0].model_defaults(channels).items():
            out.put(k, v, f"the recipe's material {listed[0].kind}")
    fibre_part = next((p for p in FIBRE_PARTS if p in materials), None)
    if fibre_part is not None:
        fibre = materials[fibre_part]
        where = f"the recipe's material.{fibre_part}"
        out.put("kind", fibre.kind, where)
        for k, v in fibre.model_defaults(channels).items():
            out.put(k, v, where)
        base = materials.get("base")
        base_albedo = None if base is None else base.diffuse_albedo(channels)
        if base_albedo is not None:
            out.put("base_albedo", list(base_albedo),
                    f"the recipe's material.base ({base.kind})")
        fibre_albedo = fibre.diffuse_albedo(channels)
        if fibre_albedo is not None:
            out.put("kd", float(np.mean(fibre_albedo)) / np.pi**2,
                    f"albedo / pi^2 of {where}")
    tile = None if facts is None else facts.tile
    if isinstance(tile, WeaveFacts) and "spacing" in out:
        # the yarns' tangent curves (microsim.analytic.cloth.tangents)
        out.put("slope", np.pi * tile.crimp_amplitude / out["spacing"],
                "pi crimp amplitude / spacing of the weave")
        out.put("flat", 1.0 - 2.0 / tile.repeat, "1 - 2 / repeat of the weave")
        for part in ("warp", "weft"):
            albedo = materials[part].diffuse_albedo(channels) if part in materials else None
            if albedo is not None:
                out.put(f"albedo_{part}", list(albedo), f"the recipe's material.{part}")
    if isinstance(tile, CylinderFacts) and tile.axis is not None:
        t = np.asarray(tile.axis, float)
        out.put("tangent_theta", float(np.degrees(np.arccos(np.clip(t[2], -1.0, 1.0)))),
                "the cylinders' axis")
        out.put("tangent_phi", float(np.degrees(np.arctan2(t[1], t[0]))),
                "the cylinders' axis")
        if "radius" in out and "spacing" in out:
            out.put("coverage", min(2.0 * out["radius"] / out["spacing"], 1.0),
                    "2 radius / spacing of the recipe's surface")
    return out


def table_defaults(table: BRDFTable, component: str = "total") -> ModelDefaults:
    """``model_defaults`` of a table's metadata, and what the table itself measured: a
    Lambertian model's ``albedo`` is the table's directional albedo of ``component``
    (mean over its incidences, per colour, at most 1), not a facet material's.

    Parameters
    ----------
    table : BRDFTable
    component : str
        A component the table holds.
    """
    out = model_defaults(table.meta)
    albedo = np.clip(table[component].albedo.mean(axis=(0, 1)), 0.0, 1.0)
    out.for_model["lambertian"] = {"albedo": [float(a) for a in albedo]}
    out.sources["lambertian.albedo"] = (f"the table's measured {component} albedo, mean "
                                        "over its incidences")
    return out
