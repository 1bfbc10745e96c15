"""Dispersion formulas of dielectrics, n(λ): ``Sellmeier`` and ``Cauchy``, with the
``at(wavelengths)`` of ``microsim.spectra.spectrum.Spectrum``.

Wavelengths are in nm, in vacuum; the formulas' coefficients are in their customary µm.
A formula is valid over the range its source states (``nm_range``) and nowhere else: asking
outside it is an ``InputError`` naming the range and the source. Every record round-trips
through JSON (``to_json`` / ``from_json``; ``spectral_from_json`` reads either kind of
record) so that a table's metadata can hold it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from microsim.errors import InputError
from microsim.spectra.spectrum import (
    Spectrum,
    check_range,
    check_source,
    finite_number,
    finite_numbers,
    show,
    wavelength_array,
)


def wavelength_range(raw: Any, where: str) -> tuple[float, float]:
    """A valid wavelength range (lo, hi): 0 < lo < hi, finite."""
    lo_hi = finite_numbers(raw, where)
    if len(lo_hi) != 2 or not 0.0 < lo_hi[0] < lo_hi[1]:
        raise InputError(f"{where} = {show(raw)}: must be [lo, hi] in nm with 0 < lo < hi")
    return lo_hi[0], lo_hi[1]


class Dispersion:
    """A refractive-index formula n(λ) of a dielectric, valid over ``nm_range`` (nm).

    Subclasses (``Sellmeier``, ``Cauchy``) are frozen records with the fields
    ``nm_range`` and ``source`` and implement ``_index(um)``.
    """

    kind: ClassVar[str]
    nm_range: tuple[float, float]
    source: str

    def _index(self, um: np.ndarray) -> np.ndarray:
        """n at wavelengths in µm (NaN where the formula gives no real index); see ``at``."""
        raise NotImplementedError

    def at(self, wavelengths: Any, *, where: str | None = None) -> np.ndarray:
        """The refractive index n at the given wavelengths.

        Parameters
        ----------
        wavelengths : (c,) float
            Wavelengths in nm, in vacuum, within ``nm_range``.
        where : str, optional
            The key path to start an error message with.

        Returns
        -------
        (c,) float
            n, the shape of ``wavelengths``.

        Raises
        ------
        InputError
            For a wavelength outside ``nm_range`` (naming the range and the source), not
            finite, or where the formula gives no positive index.
        """
        prefix = f"{where}: " if where else ""
        x = wavelength_array(wavelengths, prefix)
        check_range(x, self.nm_range[0], self.nm_range[1], self.source, prefix)
        n = self._index(x * 1e-3)
        if np.any(~(n > 0.0)):
            raise InputError(f"{prefix}the {self.kind} formula of {self.source} gives no "
                             "positive refractive index at some of the wavelengths asked for")
        return n

    def to_json(self) -> dict[str, Any]:
        """The formula as a JSON-ready dict, with its ``kind``."""
        raise NotImplementedError

    @staticmethod
    def from_json(data: Any, where: str = "dispersion") -> Dispersion:
        """Inverse of ``to_json`` for every kind (``sellmeier``, ``cauchy``).

        Raises
        ------
        InputError
            For data that are not such a formula, naming ``where``.
        """
        kinds: dict[str, type[Sellmeier] | type[Cauchy]] = {"sellmeier": Sellmeier,
                                                             "cauchy": Cauchy}
        if not isinstance(data, Mapping) or data.get("kind") not in kinds:
            raise InputError(f"{where} = {show(data)}: a dispersion formula is a table with "
                             f"kind = one of {', '.join(kinds)}")
        cls = kinds[data["kind"]]
        keys = cls._json_keys()
        for key in keys:
            if key not in data:
                raise InputError(f"{where}: missing key '{key}'; a {data['kind']} formula has "
                                 f"{', '.join(keys)}")
        for key in data:
            if key not in (*keys, "kind"):
                raise InputError(f"{where}.{key}: unknown key; a {data['kind']} formula has "
                                 f"{', '.join(keys)}")
        return cls._from_fields(data, where)


@dataclass(frozen=True)
class Sellmeier(Dispersion):
    """Sellmeier's dispersion formula, n²(λ) = 1 + Σᵢ Bᵢ λ² / (λ² − Cᵢ), λ in µm.

    The form of Malitson 1965 (J. Opt. Soc. Am. 55, 1205, with Cᵢ = λᵢ²) and of the SCHOTT
    optical-glass data sheets (SCHOTT Technical Information TIE-29, "Refractive index and
    dispersion").

    Parameters
    ----------
    b : tuple of float
        The dimensionless oscillator strengths Bᵢ.
    c : tuple of float
        The resonances Cᵢ in µm² (≥ 0; same length as ``b``), none inside ``nm_range``.
    nm_range : (float, float)
        The wavelengths in nm the formula is valid for (as its source states).
    source : str
        The citation of the coefficients.
    """

    kind: ClassVar[str] = "sellmeier"
    b: tuple[float, ...]
    c: tuple[float, ...]
    nm_range: tuple[float, float]
    source: str

    def __post_init__(self) -> None:
        source = check_source(self.source, "Sellmeier source")
        where = f"Sellmeier formula ({source})"
        b = finite_numbers(self.b, f"{where}.b")
        c = finite_numbers(self.c, f"{where}.c")
        if len(b) != len(c):
            raise InputError(f"{where}: {len(b)} B and {len(c)} C coefficients; give one C "
                             "per B")
        lo, hi = wavelength_range(self.nm_range, f"{where}.nm_range")
        for i, ci in enumerate(c):
            if ci < 0.0:
                raise InputError(f"{where}.c[{i}] = {ci:g}: resonances are λᵢ² in µm², ≥ 0")
            if lo <= 1e3 * math.sqrt(ci) <= hi:
                raise InputError(f"{where}.c[{i}] = {ci:g}: its resonance at "
                                 f"{1e3 * math.sqrt(ci):g} nm lies inside the range "
                                 f"{lo:g}-{hi:g} nm")
        object.__setattr__(self, "b", b)
        object.__setattr__(self, "c", c)
        object.__setattr__(self, "nm_range", (lo, hi))

    def _index(self, um: np.ndarray) -> np.ndarray:
        l2 = um * um
        n2 = np.ones_like(l2)
        for bi, ci in zip(self.b, self.c, strict=True):
            n2 = n2 + bi * l2 / (l2 - ci)
        return np.sqrt(np.where(n2 > 0.0, n2, np.nan))

    def to_json(self) -> dict[str, Any]:
        return {"kind": self.kind, "b": list(self.b), "c": list(self.c),
                "nm_range": list(self.nm_range), "source": self.source}

    @staticmethod
    def _json_keys() -> tuple[str, ...]:
        return ("b", "c", "nm_range", "source")

    @classmethod
    def _from_fields(cls, data: Mapping[str, Any], where: str) -> Sellmeier:
        return cls(finite_numbers(data["b"], f"{where}.b"), finite_numbers(data["c"], f"{where}.c"),
                   wavelength_range(data["nm_range"], f"{where}.nm_range"),
                   check_source(data["source"], f"{where}.source"))


@dataclass(frozen=True)
class Cauchy(Dispersion):
    """Cauchy's dispersion formula, n(λ) = A + B / λ² + C / λ⁴, λ in µm (A. L. Cauchy,
    Mémoire sur la dispersion de la lumière, 1836; the coefficients as commonly quoted,
    e.g. A ≈ 1.5046, B ≈ 0.00420 µm² for BK7 in the visible).

    Parameters
    ----------
    a : float
        A, dimensionless.
    b : float
        B in µm².
    c : float
        C in µm⁴.
    nm_range : (float, float)
        The wavelengths in nm the coefficients are valid for.
    source : str
        The citation of the coefficients.
    """

    kind: ClassVar[str] = "cauchy"
    a: float
    b: float
    c: float
    nm_range: tuple[float, float]
    source: str

    def __post_init__(self) -> None:
        source = check_source(self.source, "Cauchy source")
        where = f"Cauchy formula ({source})"
        for key in ("a", "b", "c"):
            object.__setattr__(self, key, finite_number(getattr(self, key), f"{where}.{key}"))
        object.__setattr__(self, "nm_range", wavelength_range(self.nm_range, f"{where}.nm_range"))

    def _index(self, um: np.ndarray) -> np.ndarray:
        inv2 = 1.0 / (um * um)
        return self.a + inv2 * (self.b + inv2 * self.c)

    def to_json(self) -> dict[str, Any]:
        return {"kind": self.kind, "a": self.a, "b": self.b, "c": self.c,
                "nm_range": list(self.nm_range), "source": self.source}

    @staticmethod
    def _json_keys() -> tuple[str, ...]:
        return ("a", "b", "c", "nm_range", "source")

    @classmethod
    def _from_fields(cls, data: Mapping[str, Any], where: str) -> Cauchy:
        a, b, c = (finite_number(data[key], f"{where}.{key}") for key in ("a", "b", "c"))
        return cls(a, b, c, wavelength_range(data["nm_range"], f"{where}.nm_range"),
                   check_source(data["source"], f"{where}.source"))


def spectral_from_json(data: Any, where: str = "spectrum") -> Spectrum | Dispersion:
    """A ``Spectrum`` or a ``Dispersion`` from its ``to_json`` dict, by its ``kind``.

    Raises
    ------
    InputError
        For data of no known kind, naming ``where``.
    """
    if isinstance(data, Mapping) and data.get("kind") == "tabulated":
        return Spectrum.from_json(data, where)
    if isinstance(data, Mapping) and data.get("kind") in ("sellmeier", "cauchy"):
        return Dispersion.from_json(data, where)
    raise InputError(f"{where} = {show(data)}: a spectral quantity has kind = tabulated, "
                     "sellmeier or cauchy")
