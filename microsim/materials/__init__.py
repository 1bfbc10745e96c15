"""Facet materials: one class per kind, in a module of its own, registered here once.

Each kind (``microsim.materials.base.Material``) holds its recipe keys, its scattering
event in kernel language (compiled by ``microsim.kernel.events``), and what comparisons
read from it (Fresnel, albedo, model defaults). A kind's kernel code is its position in
``KINDS``. Nothing here imports numba: ``microsim check`` validates recipes with it.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from microsim.materials.base import Material
from microsim.materials.black import Black
from microsim.materials.conductor import Conductor
from microsim.materials.dielectric import Dielectric
from microsim.materials.lambertian import Lambertian
from microsim.materials.mirror import Mirror
from microsim.materials.table import Table
from microsim.schema import kind_from_json, parse_kind

__all__ = ["KINDS", "MATERIALS", "Black", "Conductor", "Dielectric", "Lambertian", "Material",
           "Mirror", "Table", "code_of", "material_from_json", "parse_material"]

KINDS: tuple[type[Material], ...] = (Mirror, Conductor, Dielectric, Lambertian, Table, Black)
"""Every facet material kind; its index is its code in the transport kernel."""
MATERIALS: dict[str, type[Material]] = {cls.kind: cls for cls in KINDS}
"""The kinds by recipe name."""


def code_of(material: Material) -> int:
    """The kernel code of a material's kind (its index in ``KINDS``)."""
    return KINDS.index(type(material))


def parse_material(raw: Mapping[str, Any], where: str) -> Material:
    """A ``[material]`` section (``kind`` and its keys) validated into its kind's record.

    Parameters
    ----------
    raw : mapping
        The user's table.
    where : str
        Prefix of error messages, e.g. ``"material.base."``.

    Raises
    ------
    InputError
        For a missing or unknown kind, or a bad key of the kind.
    """
    return parse_kind(MATERIALS, raw, where)


def material_from_json(data: Mapping[str, Any]) -> Material:
    """A material from the recipe JSON a table file holds (``Material.to_json``)."""
    return kind_from_json(MATERIALS, data, "material")
