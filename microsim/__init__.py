"""microsim: a microgeometry simulator that produces tabulated BRDFs.

Explicit microgeometry (Gaussian height fields, V-grooves, cylinders, velvet, weaves) is
built as periodic triangle meshes, ray traced with Embree as a virtual goniophotometer,
and turned into BRDF tables with per-bin error bars, compared with analytic models.

The Python API (docs/python.md) is the functions of this module: ``load_recipe``,
``simulate``, ``read_table``, ``write_table``, ``model``, ``compare_model``,
``fit_model`` and ``export``; a table evaluates itself (``BRDFTable.eval``). Each imports
what it needs when first called, so ``import microsim`` stays light.
"""

from __future__ import annotations

import copy
import os
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from collections.abc import Callable, Iterable, Mapping
    from pathlib import Path
    from typing import Any

    from microsim.comparison.fit import FitResult
    from microsim.comparison.records import Comparison
    from microsim.measurement.goniometer import Progress
    from microsim.settings import Recipe
    from microsim.tables.table import BRDFTable

from microsim.version import __version__  # noqa: F401 (the package's version)


def read_table(path: str | Path, require_sh: bool = False) -> BRDFTable:
    """Read a BRDF table file (OpenEXR); see ``microsim.tables.exr.read_table``.

    OpenEXR is imported on the first call, so ``import microsim`` stays light.

    Parameters
    ----------
    path : str or Path
    require_sh : bool
        A damaged spherical-harmonics part is an error (False: a warning, and the table
        is read without harmonics).

    Returns
    -------
    BRDFTable

    Raises
    ------
    microsim.errors.InputError
        If the file is missing, not OpenEXR, damaged, or not a microsim table.
    """
    from microsim.tables.exr import read_table as read

    return read(path, require_sh)


def write_table(table: BRDFTable, path: str | Path) -> None:
    """Write a BRDF table file (OpenEXR), atomically; see ``microsim.tables.exr.write_table``.

    Parameters
    ----------
    table : BRDFTable
    path : str or Path
        Target file; its folder is created if missing.
    """
    from microsim.tables.exr import write_table as write

    write(table, path)


def load_recipe(source: str | Path | Mapping[str, Any], overrides: Iterable[str] = (),
                folder: str | Path = ".") -> Recipe:
    """A resolved recipe (every default filled in, every key checked), from a TOML file
    or from a dict shaped as the TOML is (docs/recipes.md).

    Parameters
    ----------
    source : str, Path or mapping
        A recipe file, or its parsed content (``{"surface": {...}, "material": {...},
        "simulation": {...}}``).
    overrides : iterable of str
        ``section.key=value`` strings applied in order, as ``--set`` takes them
        (``"simulation.rays=20000"``).
    folder : str or Path
        Where the relative paths of a dict recipe point from (a file's: its folder).

    Returns
    -------
    microsim.settings.Recipe

    Raises
    ------
    microsim.errors.InputError
        Naming the key and what is allowed.
    """
    from microsim import recipe

    if isinstance(source, str | os.PathLike):
        return recipe.load(source, overrides)
    return recipe.resolve_in(copy.deepcopy(dict(source)), folder, overrides)


def simulate(recipe: Recipe, threads: int | None = None,
             progress: Callable[[Progress], None] | None = None,
             memory_limit_gib: float | None = None) -> BRDFTable:
    """Simulate a resolved recipe: every realisation and incidence, as ``microsim
    simulate`` does (without writing the file).

    Parameters
    ----------
    recipe : Recipe
        From ``load_recipe``.
    threads : int or None
        Tracing threads (default: every core); the table is the same for any number.
    progress : callable or None
        Called after every batch with a ``microsim.measurement.goniometer.Progress``.
    memory_limit_gib : float or None
        The memory guard's budget (docs/recipes.md; default $MICROSIM_MEMORY_LIMIT or 2).

    Returns
    -------
    BRDFTable
        ``table[component].values`` (a, b, nt, np, 3) with its errors, the albedo, the
        harmonics and ``table.meta`` (the realised surface, the recipe).
    """
    from microsim.measurement.simulation import simulate_recipe

    return simulate_recipe(recipe, progress, threads, memory_limit_gib)


def model(spec: str, table: BRDFTable | None = None, component: str = "total") -> Any:
    """An analytic model from a spec (``microsim models`` lists them), the parameters it
    does not give filled in from ``table`` as ``compare`` fills them (its realised α, its
    facets' Fresnel, a Lambertian's albedo from the table's measured ``component``).

    Parameters
    ----------
    spec : str
        ``NAME[:key=value,...]``, e.g. ``"beckmann"`` or ``"oren-nayar:sigma=20"``.
    table : BRDFTable or None
    component : str
        The table's component the model stands for.

    Returns
    -------
    object
        With ``eval(wi, wo) -> (..., 3)`` f_r in 1/sr for (..., 3) unit directions.
    """
    from microsim.analytic.registry import parse_model_spec
    from microsim.comparison.table_models import table_defaults

    defaults = None if table is None else table_defaults(table, component)
    return parse_model_spec(spec, defaults)[2]


def compare_model(table: BRDFTable, spec: str, component: str = "total") -> Comparison:
    """A table against a model (``model(spec, table, component)``), as ``microsim
    compare`` does.

    Parameters
    ----------
    table : BRDFTable
    spec : str
    component : str
        ``"total"``, ``"single"``, ``"order2"``, … (docs/table-format.md).

    Returns
    -------
    microsim.comparison.records.Comparison
        Pooled and per-incidence metrics: relative error and z against both error bars
        over the lobe bins, the verdict's numbers.
    """
    from microsim.comparison.metrics import compare_table

    return compare_table(table, model(spec, table, component), component)


def fit_model(table: BRDFTable, spec: str, component: str = "total") -> FitResult:
    """Fit a model family to a table, as ``microsim fit`` does.

    Parameters
    ----------
    table : BRDFTable
    spec : str
        A family (``microsim fit --help``), e.g. ``"beckmann"``, ``"lafortune:lobes=2"``.
    component : str

    Returns
    -------
    microsim.comparison.fit.FitResult
        Parameters with 1σ uncertainties, χ²/dof, the fitted model.
    """
    from microsim.comparison.fit import fit_table

    return fit_table(table, spec, component)


def export(table: BRDFTable, path: str | Path, format: str = "rgl",
           component: str = "total", resolution: int = 32) -> None:
    """Write a table for a renderer, as ``microsim export`` does.

    Parameters
    ----------
    table : BRDFTable
    path : str or Path
        ``.bsdf`` (``rgl``: Mitsuba's and pbrt's measured format), ``.binary``
        (``merl``, isotropic tables) or ``.npz`` (``npz``: every array of the table).
    format : str
        ``"rgl"``, ``"merl"`` or ``"npz"``.
    component : str
    resolution : int
        ``rgl``: half-vector grid vertices per axis.

    Raises
    ------
    ValueError
        An unknown format.
    """
    from microsim.tables import export as formats

    if format == "npz":
        formats.write_npz(table, path)
    elif format == "merl":
        formats.write_merl(table, path, component)
    elif format == "rgl":
        formats.write_rgl(table, path, resolution, component)
    else:
        raise ValueError(f"format {format!r}: one of rgl, merl, npz")
