"""The ``conductor`` facet: specular reflection with the exact conductor Fresnel
reflectance per colour channel."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from microsim.analytic.fresnel import CoatedFresnel, ConductorFresnel, Fresnel
from microsim.errors import InputError
from microsim.materials.base import P_WAVELENGTH, WEIGHTED, Material, kernel
from microsim.materials.coating import Coating
from microsim.materials.optics import fresnel_conductor, reflect
from microsim.materials.thin_film import film_reflectance
from microsim.schema import Value, key
from microsim.spectra import measured
from microsim.spectra.channels import RGB, Channels
from microsim.spectra.measured import CONDUCTORS
from microsim.spectra.spectrum import Spectrum

GOLD_RGB = ((0.2, 0.92, 1.1), (3.9, 2.45, 2.14))
"""The default η and k of an RGB table (R, G, B): gold in air."""
ETA_MAX = 100.0
"""Largest η and k a conductor takes, as the analytic models' (``microsim.analytic.
registry``): measured metals lie far below it in the visible and near infrared, and far
above it the Fresnel terms overflow float64 (η = 1e100 gave NaN reflectance)."""


@kernel
def coated(params: np.ndarray, part: int, c: float, fac: np.ndarray) -> None:
    """The factors of a coated conductor: the film's reflectance at each channel's
    wavelength (``thin_film``), nothing transmitted. Compiled as a function of its own
    (``microsim.kernel.events``), called, not inlined: the film's complex arithmetic kept
    out of the transport's loop costs the uncoated events nothing."""
    for j in range(fac.shape[1]):
        fac[0, j] = film_reflectance(c, params[part, 2, j], params[part, 3, j],
                                     params[part, P_WAVELENGTH, j], params[part, 0, j],
                                     params[part, 1, j])[0]


@kernel
def scatter(params: np.ndarray, tab_int: np.ndarray, tab_f: np.ndarray, part: int,
            dx: float, dy: float, dz: float, nx: float, ny: float, nz: float, ex: float,
            ey: float, ez: float, u: tuple, hero: int, fac: np.ndarray
            ) -> tuple[float, float, float, int]:
    """Mirror reflection, the weight times F(θ) of η + ik per channel (column 0: η,
    1: k), or, under a coating (column 3: its thickness, > 0; 2: its index), the film's
    reflectance at the channel's wavelength; the rest is absorbed."""
    c = -(dx * nx + dy * ny + dz * nz)
    if params[part, 3, 0] > 0.0:
        coated(params, part, c, fac)
    else:
        for j in range(fac.shape[1]):
            fac[0, j] = fresnel_conductor(c, params[part, 0, j], params[part, 1, j])
    ox, oy, oz = reflect(dx, dy, dz, nx, ny, nz)
    return ox, oy, oz, WEIGHTED


@dataclass(frozen=True, kw_only=True)
class Conductor(Material):
    """Specular reflection with exact conductor Fresnel per colour channel."""

    kind: ClassVar[str] = "conductor"
    doc: ClassVar[str] = ("Specular reflection with exact conductor Fresnel per colour "
                          "channel.")
    scatter: ClassVar = scatter
    replaced_by_data: ClassVar[tuple[str, ...]] = ("eta", "k")
    data_kind: ClassVar[str] = "conductor"
    eta: tuple[float, float, float] | Spectrum = key(
        "spectrum", list(GOLD_RGB[0]), "Real part of the complex index of refraction (R, G, "
        "B, or a spectrum in a spectral table) relative to the medium in front of the faces "
        "(air, or a paint's binder: divide by its eta, as for k); default gold in air (in "
        "a spectral table, the shipped measured gold, data = \"Au\").", low=0.0,
        low_open=True, high=ETA_MAX)
    k: tuple[float, float, float] | Spectrum = key(
        "spectrum", list(GOLD_RGB[1]), "Extinction coefficient (R, G, B, or a spectrum); "
        "default gold.", low=0.0, high=ETA_MAX)
    data: str | None = key(
        "str", None, "A shipped metal's measured eta and k, in place of those keys (a "
        "spectral table only; docs/spectral.md gives the sources).", choices=CONDUCTORS)
    coating: Coating | None = key(
        "coating", None, "A thin dielectric film on the facets, thickness in nm and its "
        "index (a number or a spectrum) relative to the medium in front: reflectance by "
        "the Airy summation per wavelength (a spectral table only; docs/spectral.md).")

    def indices(self, channels: Channels) -> tuple[Any, Any]:
        """η and k as given: triples, numbers or spectra (``data``'s measurements); the
        default gold's in a spectral table is the measured gold's."""
        if self.data is None and channels.spectral and (self.eta, self.k) == GOLD_RGB:
            return measured.conductor("Au")
        return (self.eta, self.k) if self.data is None else measured.conductor(self.data)

    def parameters(self, channels: Channels, where: str = "material."
                   ) -> tuple[tuple[float, ...], ...]:
        """η, then k, per channel."""
        given = self.indices(channels)
        columns = []
        for name, value, default in zip(("eta", "k"), given, GOLD_RGB, strict=True):
            if self.data is not None:
                name = "data"
            elif channels.spectral and value == default:
                raise InputError(f"{where}{name}: its default is gold's R, G, B, which a "
                                 "spectral table has no channels for; give it as a number "
                                 "or a spectrum (or data = \"Au\" …)")
            columns.append(channels.sample(value, where + name))
        if self.coating is None:
            return tuple(columns)
        return (*columns, *self.coating.columns(channels, where + "coating"))

    def fresnel(self, channels: Channels = RGB) -> Fresnel | None:
        """``ConductorFresnel(eta, k)`` per channel; coated, ``CoatedFresnel(eta_film,
        thickness, wavelength, eta, k)``."""
        eta, k, *film = (np.asarray(x) for x in self.parameters(channels))
        if film:
            return CoatedFresnel(film[0], film[1], np.asarray(channels.wavelengths), eta,
                                 k)
        return ConductorFresnel(eta, k)

    def model_defaults(self, channels: Channels = RGB) -> dict[str, Value]:
        """``eta`` and ``k``, per channel (a coated conductor has no model parameters of
        its own: its Fresnel is the film's)."""
        eta, k = self.parameters(channels)[:2]
        return {"eta": list(eta), "k": list(k)}
