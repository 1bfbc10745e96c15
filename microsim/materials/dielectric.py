"""The ``dielectric`` facet: specular reflection with the dielectric Fresnel reflectance;
the refracted part leaves the simulation, or, with ``refract = true``, refracts into the
medium the part's faces enclose (absorbing per unit length) and out again."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from microsim.analytic.fresnel import CoatedFresnel, DielectricFresnel, Fresnel
from microsim.errors import InputError
from microsim.materials.base import (
    DISPERSION_ALWAYS,
    DISPERSION_NONE,
    DISPERSION_REFRACTED,
    HERO,
    KEPT,
    P_DISPERSIVE,
    P_WAVELENGTH,
    TRANSMITTING,
    WEIGHTED,
    Material,
    kernel,
)
from microsim.materials.coating import Coating
from microsim.materials.optics import fresnel_dielectric, reflect, refract
from microsim.materials.thin_film import film_reflectance
from microsim.schema import Value, key
from microsim.spectra import measured
from microsim.spectra.channels import RGB, Channels
from microsim.spectra.spectrum import Spectrum


@kernel
def scatter(params: np.ndarray, tab_int: np.ndarray, tab_f: np.ndarray, part: int,
            dx: float, dy: float, dz: float, nx: float, ny: float, nz: float, ex: float,
            ey: float, ez: float, u: tuple, hero: int, fac: np.ndarray
            ) -> tuple[float, float, float, int]:
    """Column 0: η per channel; column 1: 1 to refract; columns 2 and 3: a coating's index
    and thickness (nm; 0: none), whose reflectance and transmittance at the channel's
    wavelength replace the bare interface's (``thin_film``; from inside the medium every
    index relative to the medium's, and the wavelength in it, λ / η).

    Refracting: a Fresnel-weighted choice between reflection and refraction with u[0],
    weight 1 either way: an unbiased estimate of both (PBR 4th ed., sec. 9.5); from inside
    the medium the ray sees 1 / η about the flipped normal. No 1/η² on crossing: a path
    carries power (importance), not radiance (Veach 1997, thesis, sec. 5.2). The choice
    and the refracted direction are the ``hero`` channel's. Where η depends on the
    wavelength (``P_DISPERSIVE`` = ``DISPERSION_REFRACTED``) a refraction leaves the path
    its hero alone (``HERO``), and a reflection, whose direction is every wavelength's,
    keeps every channel with weight F_c / F_hero: the hero chose it with probability
    F_hero, so each channel's expected weight is its own F_c (unbiased for each channel,
    as pbrt-v4's termination at every event is, but a lobe of reflections keeps all its
    wavelengths). A coated part (``DISPERSION_ALWAYS``) has left the path its hero before
    the event. Otherwise a mirror reflection with weight F per channel; 1 − F is
    transmitted (reported as lost)."""
    if params[part, 1, 0] != 0.0:
        eta = params[part, 0, hero]
        inside = dx * nx + dy * ny + dz * nz >= 0.0
        if inside:
            nx, ny, nz, eta = -nx, -ny, -nz, 1.0 / eta
        c = -(dx * nx + dy * ny + dz * nz)
        f = _reflectance(params, part, hero, c, eta, inside)[0]
        dispersive = params[part, P_DISPERSIVE, 0] == DISPERSION_REFRACTED
        if u[0] >= f:
            tx, ty, tz, tir = refract(dx, dy, dz, nx, ny, nz, eta)
            if not tir:
                return tx, ty, tz, HERO if dispersive else KEPT
        ox, oy, oz = reflect(dx, dy, dz, nx, ny, nz)
        if not dispersive:
            return ox, oy, oz, KEPT
        for j in range(fac.shape[1]):
            own = params[part, 0, j]
            fac[0, j] = _reflectance(params, part, j, c, 1.0 / own if inside else own,
                                     inside)[0] / f
        return ox, oy, oz, WEIGHTED
    c = -(dx * nx + dy * ny + dz * nz)
    for j in range(fac.shape[1]):
        f, t = _reflectance(params, part, j, c, params[part, 0, j], False)
        fac[0, j] = f
        fac[1, j] = t
    ox, oy, oz = reflect(dx, dy, dz, nx, ny, nz)
    return ox, oy, oz, TRANSMITTING


@kernel
def _reflectance(params: np.ndarray, part: int, j: int, c: float, eta: float,
                 inside: bool) -> tuple[float, float]:
    """Channel j's reflectance and transmittance of the interface at incidence cosine c,
    relative index ``eta`` (1 / η from inside): a coating's film (thin_film, every index
    and the wavelength relative to the incident medium's) or the bare Fresnel's."""
    thickness = params[part, 3, j]
    if thickness > 0.0:
        scale = eta if inside else 1.0  # 1 / η inside: indices relative to the medium
        return film_reflectance(c, params[part, 2, j] * scale, thickness,
                                params[part, P_WAVELENGTH, j] * scale, eta, 0.0)
    f = fresnel_dielectric(c, eta)
    return f, 1.0 - f


@dataclass(frozen=True, kw_only=True)
class Dielectric(Material):
    """Specular reflection with dielectric Fresnel; optionally refraction into a medium."""

    kind: ClassVar[str] = "dielectric"
    doc: ClassVar[str] = (
        "Specular reflection with dielectric Fresnel; the refracted part is absorbed and "
        "reported as lost energy, or, with refract = true, refracted into the medium "
        "behind the faces (absorbing per unit length) and out again.")
    scatter: ClassVar = scatter
    replaced_by_data: ClassVar[tuple[str, ...]] = ("eta",)
    data_kind: ClassVar[str] = "dielectric"
    blocks: ClassVar[int] = 1
    eta: float | Spectrum = key(
        "index", 1.5, "Index of refraction relative to the medium in front of the faces "
        "(air; for particles inside a paint's binder, relative to the binder); 1 would be "
        "no interface at all. A spectrum { nm, value } in a spectral table (dispersion).",
        low=1.0, low_open=True, high=10.0)
    refract: bool = key("bool", False, "Refract as well as reflect: a Fresnel-weighted "
                        "choice, Snell's law, total internal reflection; the part's faces "
                        "enclose a medium behind them (docs/materials.md). false: reflect "
                        "with weight F, report 1 - F as transmitted.")
    data: str | None = key(
        "str", None, "A shipped glass's dispersion formula in place of eta (a spectral "
        "table only; docs/spectral.md gives the sources).",
        choices=measured.names("dielectric"))
    coating: Coating | None = key(
        "coating", None, "A thin dielectric film on the faces, thickness in nm and its "
        "index (a number or a spectrum) relative to the medium in front: reflectance and "
        "transmittance by the Airy summation per wavelength (a spectral table only; "
        "docs/spectral.md).")
    absorption: tuple[float, float, float] | Spectrum = key(
        "spectrum", 0.0, "Beer-Lambert absorption coefficient inside the medium, per tile "
        "unit of path length (R, G, B, or a spectrum in a spectral table); needs refract = "
        "true.", low=0.0)

    def check(self, where: str, given: frozenset[str]) -> None:
        """Absorption needs a medium: ``refract = true``."""
        values = (self.absorption.value if isinstance(self.absorption, Spectrum)
                  else self.absorption)
        if not self.refract and any(a > 0 for a in values):
            raise InputError(f"{where}absorption = {list(values)!r}: needs refract = true "
                             "(without refraction no light enters the medium)")

    def parameters(self, channels: Channels, where: str = "material."
                   ) -> tuple[tuple[float, ...], ...]:
        """η per channel, then 1 to refract."""
        eta = self.eta if self.data is None else measured.dielectric(self.data)
        columns = (channels.sample(eta, where + ("eta" if self.data is None else "data")),
                   channels.sample(1.0 if self.refract else 0.0, where + "refract"))
        if self.coating is None:
            return columns
        return columns + self.coating.columns(channels, where + "coating")

    def medium(self, channels: Channels, where: str = "material."
               ) -> tuple[float, ...] | None:
        """The absorption inside a refracting part, None for a reflecting one."""
        return channels.sample(self.absorption, where + "absorption") if self.refract \
            else None

    @property
    def encloses_medium(self) -> bool:
        """A refracting part's faces enclose its medium."""
        return self.refract

    @property
    def transmits(self) -> bool:
        """A part that does not refract transmits 1 − F (``TRANSMITTING``)."""
        return not self.refract

    def dispersion(self, channels: Channels) -> int:
        """A refracting part: coated (its reflectance's interference makes the choice
        between reflection and refraction the hero's at every event), or with η varying
        between channels (only its refractions' directions depend on the wavelength)."""
        if not self.refract or channels.count == 1:
            return DISPERSION_NONE
        if self.coating is not None:
            return DISPERSION_ALWAYS
        dispersive = len(set(self.parameters(channels)[0])) > 1
        return DISPERSION_REFRACTED if dispersive else DISPERSION_NONE

    def fresnel(self, channels: Channels = RGB) -> Fresnel | None:
        """``DielectricFresnel(eta)``: a number, or η per channel where it varies;
        coated, ``CoatedFresnel(eta_film, thickness, wavelength, eta, 0)``."""
        eta, _, *film = (np.asarray(x) for x in self.parameters(channels))
        if film:
            return CoatedFresnel(film[0], film[1], np.asarray(channels.wavelengths), eta,
                                 np.zeros_like(eta))
        return DielectricFresnel(eta[0] if len(set(eta)) == 1 else eta)

    def model_defaults(self, channels: Channels = RGB) -> dict[str, Value]:
        """``eta``: a number, or per channel where it varies."""
        eta = self.parameters(channels)[0]
        return {"eta": eta[0] if len(set(eta)) == 1 else list(eta)}
