"""The colour channels of a simulation and its table: red, green and blue, or one per
wavelength.

Every per-channel quantity of a run (a path's weight, a material's parameters, a table's
values) carries a trailing axis of ``Channels.count`` entries. An RGB run has three
channels, named R, G, B, whose materials give three numbers per key; a spectral run has one
channel per wavelength (nm, in vacuum, strictly increasing), whose materials give their
spectra sampled there (``Channels.sample``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from microsim.errors import InputError

RGB_NAMES = ("R", "G", "B")
"""The channel names of an RGB table (its EXR channels ``{component}.R`` …)."""


@dataclass(frozen=True)
class Channels:
    """The channels of a run: RGB (``wavelengths`` None) or one per wavelength.

    Parameters
    ----------
    wavelengths : tuple of float or None
        Strictly increasing wavelengths in nm; None for RGB.
    """

    wavelengths: tuple[float, ...] | None = None

    @property
    def spectral(self) -> bool:
        """Whether the channels are wavelengths."""
        return self.wavelengths is not None

    @property
    def count(self) -> int:
        """C, the number of channels."""
        return 3 if self.wavelengths is None else len(self.wavelengths)

    @property
    def names(self) -> tuple[str, ...]:
        """The channels' names: R, G, B, or the wavelengths as ``550nm`` (a decimal point
        written ``p``: ``552p5nm``, so names hold no dot, the separator of EXR layers)."""
        if self.wavelengths is None:
            return RGB_NAMES
        return tuple(f"{nm:g}nm".replace(".", "p") for nm in self.wavelengths)

    def sample(self, value: Any, where: str) -> tuple[float, ...]:
        """A per-channel quantity as C floats: a number is the same in every channel; three
        numbers are R, G, B (RGB channels only); a spectrum (an object with ``at``) is
        sampled at the wavelengths (spectral channels only).

        Raises
        ------
        InputError
            For a value that does not fit the channels, naming ``where``.
        """
        if isinstance(value, int | float):
            return (float(value),) * self.count
        if hasattr(value, "at"):
            if self.wavelengths is None:
                raise InputError(f"{where}: a spectrum needs a spectral table "
                                 "([table] wavelengths); an RGB table takes a number or "
                                 "three (R, G, B)")
            return tuple(float(v) for v in value.at(self.wavelengths, where=where))
        values = tuple(float(v) for v in value)
        if self.wavelengths is not None and len(set(values)) > 1:
            raise InputError(f"{where} = {list(values)!r}: three numbers are R, G, B, "
                             "which a spectral table has no channels for; give a number or "
                             "a spectrum { nm = [...], value = [...] }")
        if len(values) != 3 and self.wavelengths is None:
            raise InputError(f"{where}: {len(values)} numbers; an RGB table takes three")
        return values if self.wavelengths is None else (values[0],) * self.count

    def to_json(self) -> list[float] | None:
        """The wavelengths as a table's metadata holds them (None for RGB)."""
        return None if self.wavelengths is None else list(self.wavelengths)

    @classmethod
    def from_json(cls, data: Sequence[float] | None) -> Channels:
        """Inverse of ``to_json``."""
        return cls(None if data is None else tuple(float(x) for x in data))


RGB = Channels()
"""The channels of an RGB run."""
