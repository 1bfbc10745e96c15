"""Hand-made tables for tests: a ``BRDFTable`` from per-component mappings of each field."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import replace
from typing import Any

import numpy as np

from microsim.tables.table import BRDFTable, ComponentEstimate, by_component, components_of


def table_of(bins: Any, theta_i: Any, phi_i: Any, isotropic: bool,
             values: Mapping[str, Any], errors: Mapping[str, Any], rays: Any,
             albedo: Mapping[str, Any], albedo_err: Mapping[str, Any], lost_energy: Any,
             meta: Any, **fields: Any) -> BRDFTable:
    """A table whose components are the keys of ``values``: ``values``, ``errors``,
    ``albedo``, ``albedo_err`` and any ``ComponentEstimate`` field in ``fields`` are
    mappings of component to array (None: absent); the other ``fields`` go to
    ``BRDFTable`` as they are."""
    names = {"dof", "inflation", "ray_errors", "sh", "sh_err", "sums", "sums_sq",
             "sh_sums", "sh_sums_sq", "realisation_albedo"}
    components = components_of(values)
    per = {k: by_component(v, components) for k, v in fields.items()
           if k in names and v is not None}
    rest = {k: v for k, v in fields.items() if k not in names}
    values, errors, albedo, albedo_err = (by_component(x, components)
                                          for x in (values, errors, albedo, albedo_err))
    estimates = {c: ComponentEstimate(values[c], errors[c], albedo[c], albedo_err[c],
                                      **{k: v[c] for k, v in per.items()})
                 for c in components}
    return BRDFTable(bins, np.asarray(theta_i, float), phi_i, isotropic, estimates, rays,
                     lost_energy, meta, **rest)


def changed(table: BRDFTable, **fields: Callable[[ComponentEstimate], Any]) -> BRDFTable:
    """A copy of ``table`` with fields of every component's estimate replaced by what each
    function makes of that component's estimate, e.g. ``errors=lambda e: e.errors / 2``."""
    return replace(table, estimates={
        c: replace(e, **{name: make(e) for name, make in fields.items()})
        for c, e in table.estimates.items()})
