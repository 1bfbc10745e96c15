"""The ``conductor`` facet: specular reflection with the exact conductor Fresnel
reflectance per colour channel."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from microsim.errors import InputError
from microsim.materials.base import Material, kernel
from microsim.materials.optics import fresnel_conductor, reflect
from microsim.schema import key
from microsim.spectra import measured
from microsim.spectra.channels import RGB, Channels
from microsim.spectra.measured import CONDUCTORS
from microsim.spectra.spectrum import Spectrum

ETA_MAX = 100.0
"""Largest η and k a conductor takes, as the analytic models' (``microsim.analytic.
registry``): measured metals lie far below it in the visible and near infrared, and far
above it the Fresnel terms overflow float64 (η = 1e100 gave NaN reflectance)."""


@kernel
def scatter(params: np.ndarray, tab_int: np.ndarray, tab_f: np.ndarray, part: int,
            dx: float, dy: float, dz: float, nx: float, ny: float, nz: float, ex: float,
            ey: float, ez: float, u: tuple, hero: int, fac: np.ndarray
            ) -> tuple[float, float, float]:
    """Mirror reflection, the weight times F(θ) of η + ik per channel (column 0: η,
    1: k); the rest is absorbed."""
    c = -(dx * nx + dy * ny + dz * nz)
    for j in range(fac.shape[1]):
        fac[0, j] = fresnel_conductor(c, params[part, 0, j], params[part, 1, j])
        fac[1, j] = 0.0
    return reflect(dx, dy, dz, nx, ny, nz)


@dataclass(frozen=True, kw_only=True)
class Conductor(Material):
    """Specular reflection with exact conductor Fresnel per colour channel."""

    kind: ClassVar[str] = "conductor"
    doc: ClassVar[str] = ("Specular reflection with exact conductor Fresnel per colour "
                          "channel.")
    scatter: ClassVar = scatter
    eta: tuple[float, float, float] | Spectrum = key(
        "spectrum", [0.2, 0.92, 1.1], "Real part of the complex index of refraction (R, G, "
        "B, or a spectrum in a spectral table) relative to the medium in front of the faces "
        "(air, or a paint's binder: divide by its eta, as for k); default gold in air.",
        low=0.0, low_open=True, high=ETA_MAX)
    k: tuple[float, float, float] | Spectrum = key(
        "spectrum", [3.9, 2.45, 2.14], "Extinction coefficient (R, G, B, or a spectrum); "
        "default gold.", low=0.0, high=ETA_MAX)
    data: str | None = key(
        "str", None, "A shipped metal's measured eta and k, in place of those keys (a "
        "spectral table only; docs/spectral.md gives the sources).", choices=CONDUCTORS)

    def check(self, where: str, given: frozenset[str]) -> None:
        """``data`` replaces ``eta`` and ``k``: not both."""
        if self.data is not None and given & {"eta", "k"}:
            raise InputError(f"{where}data = {self.data!r}: gives eta and k; leave out "
                             f"{' and '.join(sorted(given & {'eta', 'k'}))}")

    def indices(self) -> tuple[Any, Any]:
        """η and k as given: triples, numbers or spectra (``data``'s measurements)."""
        return (self.eta, self.k) if self.data is None else measured.conductor(self.data)

    def parameters(self, channels: Channels, where: str = "material."
                   ) -> tuple[tuple[float, ...], ...]:
        """η, then k, per channel."""
        name = "data" if self.data is not None else None
        eta, k = self.indices()
        return (channels.sample(eta, where + (name or "eta")),
                channels.sample(k, where + (name or "k")))

    def fresnel(self, channels: Channels = RGB) -> tuple | None:
        """``("conductor", eta, k)``, per channel."""
        eta, k = self.parameters(channels)
        return ("conductor", np.asarray(eta), np.asarray(k))

    def model_defaults(self, channels: Channels = RGB) -> dict[str, Any]:
        """``eta`` and ``k``, per channel."""
        eta, k = self.parameters(channels)
        return {"eta": list(eta), "k": list(k)}
