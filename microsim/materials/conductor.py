"""The ``conductor`` facet: specular reflection with the exact conductor Fresnel
reflectance per colour channel."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from microsim.materials.base import Material, kernel
from microsim.materials.optics import fresnel_conductor, reflect
from microsim.schema import key

ETA_MAX = 100.0
"""Largest η and k a conductor takes, as the analytic models' (``microsim.analytic.
registry``): measured metals lie far below it in the visible and near infrared, and far
above it the Fresnel terms overflow float64 (η = 1e100 gave NaN reflectance)."""


@kernel
def scatter(params: np.ndarray, tab_int: np.ndarray, tab_f: np.ndarray, part: int,
            dx: float, dy: float, dz: float, nx: float, ny: float, nz: float, ex: float,
            ey: float, ez: float, u: tuple) -> tuple[float, ...]:
    """Mirror reflection, the weight times F(θ) of η + ik per channel (columns 0-2: η,
    3-5: k); the rest is absorbed."""
    ox, oy, oz = reflect(dx, dy, dz, nx, ny, nz)
    c = -(dx * nx + dy * ny + dz * nz)
    return (ox, oy, oz, fresnel_conductor(c, params[part, 0], params[part, 3]),
            fresnel_conductor(c, params[part, 1], params[part, 4]),
            fresnel_conductor(c, params[part, 2], params[part, 5]), 0.0, 0.0, 0.0)


@dataclass(frozen=True, kw_only=True)
class Conductor(Material):
    """Specular reflection with exact conductor Fresnel per colour channel."""

    kind: ClassVar[str] = "conductor"
    doc: ClassVar[str] = ("Specular reflection with exact conductor Fresnel per colour "
                          "channel.")
    scatter: ClassVar = scatter
    eta: tuple[float, float, float] = key(
        "rgb", [0.2, 0.92, 1.1], "Real part of the complex index of refraction (R, G, B) "
        "relative to the medium in front of the faces (air, or a paint's binder: divide by "
        "its eta, as for k); default gold in air.", low=0.0, low_open=True, high=ETA_MAX)
    k: tuple[float, float, float] = key("rgb", [3.9, 2.45, 2.14],
                                        "Extinction coefficient (R, G, B); default gold.",
                                        low=0.0, high=ETA_MAX)

    def parameters(self) -> tuple[float, ...]:
        """η (R, G, B), then k (R, G, B)."""
        return (*self.eta, *self.k)

    def fresnel(self) -> tuple | None:
        """``("conductor", eta, k)``."""
        return ("conductor", np.asarray(self.eta), np.asarray(self.k))

    def model_defaults(self) -> dict[str, Any]:
        """``eta`` and ``k``."""
        return {"eta": list(self.eta), "k": list(self.k)}
