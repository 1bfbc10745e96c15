"""The ``lambertian`` facet: cosine-weighted diffuse reflection with an albedo."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from microsim.materials.base import Material, kernel
from microsim.materials.optics import cosine_about
from microsim.schema import key


@kernel
def scatter(params: np.ndarray, tab_int: np.ndarray, tab_f: np.ndarray, part: int,
            dx: float, dy: float, dz: float, nx: float, ny: float, nz: float, ex: float,
            ey: float, ez: float, u: tuple) -> tuple[float, ...]:
    """A cosine-distributed direction about n (u[0], u[1]); the cosine pdf cancels the
    BRDF's cosine, so the weight is the albedo (columns 0-2; PBR 4th ed., sec. 13.6.3
    and 4.5.1)."""
    ox, oy, oz = cosine_about(nx, ny, nz, u[0], u[1])
    return (ox, oy, oz, params[part, 0], params[part, 1], params[part, 2], 0.0, 0.0, 0.0)


@dataclass(frozen=True, kw_only=True)
class Lambertian(Material):
    """Cosine-weighted diffuse reflection with the given albedo."""

    kind: ClassVar[str] = "lambertian"
    doc: ClassVar[str] = "Cosine-weighted diffuse reflection with the given albedo."
    scatter: ClassVar = scatter
    blocks: ClassVar[int] = 1
    albedo: tuple[float, float, float] = key("rgb", 0.8, "Diffuse reflectance (R, G, B).",
                                             low=0.0, high=1.0)

    def parameters(self) -> tuple[float, ...]:
        """The albedo (R, G, B)."""
        return self.albedo

    def diffuse_albedo(self) -> tuple[float, float, float] | None:
        """The albedo."""
        return self.albedo

    def model_defaults(self) -> dict[str, Any]:
        """``albedo``."""
        return {"albedo": list(self.albedo)}
