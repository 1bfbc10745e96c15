"""The ``black`` facet: it absorbs every ray that hits it."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from microsim.materials.base import WEIGHTED, Material, kernel
from microsim.materials.optics import reflect
from microsim.schema import Value
from microsim.spectra.channels import RGB, Channels


@kernel
def scatter(params: np.ndarray, tab_int: np.ndarray, tab_f: np.ndarray, part: int,
            dx: float, dy: float, dz: float, nx: float, ny: float, nz: float, ex: float,
            ey: float, ez: float, u: tuple, hero: int, fac: np.ndarray
            ) -> tuple[float, float, float, int]:
    """Factor 0: the whole weight is absorbed. The path goes on (mirrored, carrying
    nothing) to its end, as every path does, so its fate is counted as usual."""
    fac[0, :] = 0.0
    ox, oy, oz = reflect(dx, dy, dz, nx, ny, nz)
    return ox, oy, oz, WEIGHTED


@dataclass(frozen=True, kw_only=True)
class Black(Material):
    """A perfectly absorbing facet (a Lambertian facet of albedo 0 that draws nothing)."""

    kind: ClassVar[str] = "black"
    doc: ClassVar[str] = ("Absorbs every ray that hits it: a black base under fibres, "
                          "the reference of single-scattering models.")
    scatter: ClassVar = scatter

    def diffuse_albedo(self, channels: Channels = RGB) -> tuple[float, ...] | None:
        """Zero: a black facet is a diffuse facet that reflects nothing."""
        return (0.0,) * channels.count

    def model_defaults(self, channels: Channels = RGB) -> dict[str, Value]:
        """``albedo`` 0."""
        return {"albedo": [0.0] * channels.count}
