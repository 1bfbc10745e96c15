"""The ``mirror`` facet: perfect specular reflection, F = 1."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from microsim.analytic.fresnel import Fresnel
from microsim.materials.base import KEPT, Material, kernel
from microsim.materials.optics import reflect
from microsim.schema import Value
from microsim.spectra.channels import RGB, Channels


@kernel
def scatter(params: np.ndarray, tab_int: np.ndarray, tab_f: np.ndarray, part: int,
            dx: float, dy: float, dz: float, nx: float, ny: float, nz: float, ex: float,
            ey: float, ez: float, u: tuple, hero: int, fac: np.ndarray
            ) -> tuple[float, float, float, int]:
    """Mirror reflection about n; the weight is kept."""
    ox, oy, oz = reflect(dx, dy, dz, nx, ny, nz)
    return ox, oy, oz, KEPT


@dataclass(frozen=True, kw_only=True)
class Mirror(Material):
    """Perfect specular reflection, F = 1."""

    kind: ClassVar[str] = "mirror"
    doc: ClassVar[str] = "Perfect specular reflection, F = 1."
    scatter: ClassVar = scatter
    mirror: ClassVar[bool] = True

    def fresnel(self, channels: Channels = RGB) -> Fresnel | None:
        """F = 1: no Fresnel factor."""
        return None

    def model_defaults(self, channels: Channels = RGB) -> dict[str, Value]:
        """A mirror implies no model parameter."""
        return {}
