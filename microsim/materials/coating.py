"""A facet's dielectric coating as a recipe gives it: ``coating = { thickness, eta }``
(Gondek, Meyer & Newman 1994's pearlescent flakes: mica coated with a thin oxide), the
film whose interference ``microsim.materials.thin_film`` computes in the kernel."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from microsim.errors import InputError
from microsim.spectra.channels import Channels
from microsim.spectra.spectrum import Spectrum, parse_spectrum

THICKNESS_MAX = 100_000.0
"""nm: the thickest coating a recipe takes (100 µm; interference colours need < ~2 µm)."""


@dataclass(frozen=True)
class Coating:
    """A facet's dielectric coating (a recipe's ``coating = { thickness, eta }``).

    Parameters
    ----------
    thickness : float
        nm, in [0, ``THICKNESS_MAX``]; 0 is the bare facet.
    eta : float or Spectrum
        The film's real index relative to the medium in front of the facet, > 0 (a
        number, or a spectrum sampled at the table's wavelengths).
    """

    thickness: float
    eta: float | Spectrum

    @classmethod
    def parse(cls, raw: Any, where: str) -> Coating:
        """A coating from a recipe table ``{ thickness = nm, eta = n | spectrum }``.

        Raises
        ------
        InputError
            Naming ``where`` + the key for a value that is not a table, a missing or
            unknown key, a thickness outside [0, 100 000] nm, or an index ≤ 0.
        """
        form = "a table { thickness = <nm>, eta = <index or spectrum> }"
        if not isinstance(raw, Mapping):
            raise InputError(f"{where} = {raw!r}: must be {form}")
        for name in raw:
            if name not in ("thickness", "eta"):
                raise InputError(f"{where}.{name}: unknown key; a coating takes thickness "
                                 "(nm) and eta")
        for name in ("thickness", "eta"):
            if name not in raw:
                raise InputError(f"{where}.{name}: missing; a coating is {form}")
        thickness = raw["thickness"]
        if (isinstance(thickness, bool) or not isinstance(thickness, int | float)
                or not 0.0 <= thickness <= THICKNESS_MAX):
            raise InputError(f"{where}.thickness = {thickness!r}: must be a number of nm "
                             f">= 0 and <= {THICKNESS_MAX:g}")
        eta = raw["eta"]
        if isinstance(eta, Mapping):
            eta = (Spectrum.from_json(eta, f"{where}.eta") if "source" in eta
                   else parse_spectrum(eta, f"{where}.eta"))
            if min(eta.value) <= 0.0:
                raise InputError(f"{where}.eta: a film's index must be > 0")
        elif isinstance(eta, bool) or not isinstance(eta, int | float) or not (
                0.0 < eta < math.inf):
            raise InputError(f"{where}.eta = {eta!r}: must be a number > 0 or a spectrum "
                             "{ nm = [...], value = [...] }")
        return cls(float(thickness), eta if isinstance(eta, Spectrum) else float(eta))

    def to_json(self) -> dict[str, Any]:
        """As a recipe holds it."""
        eta = self.eta.to_json() if isinstance(self.eta, Spectrum) else self.eta
        return {"thickness": self.thickness, "eta": eta}

    def columns(self, channels: Channels, where: str) -> tuple[tuple[float, ...], ...]:
        """The film's index and thickness per channel (the kernel's parameter columns).

        Raises
        ------
        InputError
            In an RGB table: interference needs wavelengths.
        """
        if not channels.spectral:
            raise InputError(f"{where}: a coating needs a spectral table ([table] "
                             "wavelengths): its interference depends on the wavelength")
        return channels.sample(self.eta, where + ".eta"), (self.thickness,) * channels.count
