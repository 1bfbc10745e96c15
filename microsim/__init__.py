"""microsim: a microgeometry simulator that produces tabulated BRDFs.

Explicit microgeometry (Gaussian height fields, V-grooves, cylinders, velvet, weaves) is
built as periodic triangle meshes, ray traced with Embree as a virtual goniophotometer,
and turned into BRDF tables with per-bin error bars, compared with analytic models.
"""

from __future__ import annotations

__version__ = "0.1.0"


def read_table(path):  # noqa: ANN001, ANN201 - documented in microsim.tables.exr
    """Read a BRDF table file (OpenEXR); see ``microsim.tables.exr.read_table``."""
    from microsim.tables.exr import read_table as read

    return read(path)
