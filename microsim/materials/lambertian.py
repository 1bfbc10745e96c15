"""The ``lambertian`` facet: cosine-weighted diffuse reflection with an albedo."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from microsim.materials.base import WEIGHTED, Material, kernel
from microsim.materials.optics import cosine_about
from microsim.schema import Value, key
from microsim.spectra import measured
from microsim.spectra.channels import RGB, Channels
from microsim.spectra.spectrum import Spectrum


@kernel
def scatter(params: np.ndarray, tab_int: np.ndarray, tab_f: np.ndarray, part: int,
            dx: float, dy: float, dz: float, nx: float, ny: float, nz: float, ex: float,
            ey: float, ez: float, u: tuple, hero: int, fac: np.ndarray
            ) -> tuple[float, float, float, int]:
    """A cosine-distributed direction about n (u[0], u[1]); the cosine pdf cancels the
    BRDF's cosine, so the weight is the albedo (column 0; PBR 4th ed., sec. 13.6.3
    and 4.5.1)."""
    for j in range(fac.shape[1]):
        fac[0, j] = params[part, 0, j]
    ox, oy, oz = cosine_about(nx, ny, nz, u[0], u[1])
    return ox, oy, oz, WEIGHTED


@dataclass(frozen=True, kw_only=True)
class Lambertian(Material):
    """Cosine-weighted diffuse reflection with the given albedo."""

    kind: ClassVar[str] = "lambertian"
    doc: ClassVar[str] = "Cosine-weighted diffuse reflection with the given albedo."
    scatter: ClassVar = scatter
    replaced_by_data: ClassVar[tuple[str, ...]] = ("albedo",)
    data_kind: ClassVar[str] = "reflectance"
    blocks: ClassVar[int] = 1
    albedo: tuple[float, float, float] | Spectrum = key(
        "spectrum", 0.8, "Diffuse reflectance (R, G, B, or a spectrum in a spectral table).",
        low=0.0, high=1.0)
    data: str | None = key(
        "str", None, "A shipped measured reflectance spectrum in place of albedo (a "
        "spectral table only; docs/spectral.md lists them).",
        choices=measured.names("reflectance"))

    def parameters(self, channels: Channels, where: str = "material."
                   ) -> tuple[tuple[float, ...], ...]:
        """The albedo per channel."""
        if self.data is not None:
            return (channels.sample(measured.reflectance(self.data), where + "data"),)
        return (channels.sample(self.albedo, where + "albedo"),)

    def diffuse_albedo(self, channels: Channels = RGB) -> tuple[float, ...] | None:
        """The albedo per channel."""
        return self.parameters(channels)[0]

    def model_defaults(self, channels: Channels = RGB) -> dict[str, Value]:
        """``albedo``, per channel."""
        return {"albedo": list(self.parameters(channels)[0])}
