"""microsim: a microgeometry simulator that produces tabulated BRDFs.

Explicit microgeometry (Gaussian height fields, V-grooves, cylinders, velvet, weaves) is
built as periodic triangle meshes, ray traced with Embree as a virtual goniophotometer,
and turned into BRDF tables with per-bin error bars, compared with analytic models.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from pathlib import Path

    from microsim.tables.table import BRDFTable

__version__ = "0.1.0"


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
