"""A quantity tabulated against wavelength (``Spectrum``), evaluated by ``at(wavelengths)``,
and the checks every spectral record shares (``microsim.spectra.dispersion`` holds the
dispersion formulas of dielectrics, with the same ``at``).

Wavelengths are in nm, in vacuum (docs/conventions.md, "Spectra"). A spectrum is defined over its
tabulated wavelengths and nowhere else: asking outside them is an ``InputError`` that names
the range and the source, never an extrapolation. Every record carries its source (a
citation) and round-trips through JSON (``to_json`` / ``from_json``) so that a table's
metadata can hold it.

A recipe gives a spectrum as a TOML table ``{ nm = [...], value = [...] }`` (optionally
``source = "..."``); ``parse_spectrum`` checks it and names the key path in every message.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from microsim.errors import InputError

SPECTRUM_FORM = ("a table { nm = [...], value = [...] } (wavelengths in nm, > 0 and strictly "
                 "increasing, one value for each; optional source = \"citation\")")
"""What a recipe's spectrum looks like, for error messages."""

SPECTRUM_KEYS = ("nm", "value", "source")
"""The keys of a spectrum table (``source`` optional)."""


def show(raw: Any, limit: int = 60) -> str:
    """A short repr of a user's value for an error message."""
    text = repr(raw)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def finite_numbers(raw: Any, where: str) -> tuple[float, ...]:
    """A non-empty list of finite numbers (bools are not numbers), as floats.

    Raises
    ------
    InputError
        Naming ``where`` (and the index of a bad entry).
    """
    if isinstance(raw, np.ndarray):
        raw = raw.tolist()
    if not isinstance(raw, list | tuple):
        raise InputError(f"{where} = {show(raw)}: must be a list of numbers")
    if len(raw) == 0:
        raise InputError(f"{where}: empty list; give at least one number")
    return tuple(finite_number(x, f"{where}[{i}]") for i, x in enumerate(raw))


def finite_number(raw: Any, where: str) -> float:
    """One finite number (not a bool), as a float."""
    if isinstance(raw, bool) or not isinstance(raw, numbers.Real):
        raise InputError(f"{where} = {show(raw)}: not a number")
    x = float(raw)
    if not math.isfinite(x):
        raise InputError(f"{where} = {x}: must be finite (not NaN or infinite)")
    return x


def _check_nm(nm: tuple[float, ...], n_values: int, where: str) -> None:
    """Wavelengths > 0, strictly increasing, one per value."""
    if len(nm) != n_values:
        raise InputError(f"{where}: nm has {len(nm)} entries and value {n_values}; give one "
                         "value for each wavelength")
    for i, x in enumerate(nm):
        if x <= 0.0:
            raise InputError(f"{where}.nm[{i}] = {x:g}: wavelengths are in nm and must be > 0")
        if i > 0 and x <= nm[i - 1]:
            raise InputError(f"{where}.nm[{i}] = {x:g} follows nm[{i - 1}] = {nm[i - 1]:g}: "
                             "wavelengths must be strictly increasing")


def check_source(source: Any, where: str) -> str:
    """A citation: a non-empty string."""
    if not isinstance(source, str) or not source.strip():
        raise InputError(f"{where} = {show(source)}: must be a non-empty string (a citation)")
    return source


def wavelength_array(wavelengths: Any, prefix: str) -> np.ndarray:
    """The wavelengths asked for (nm, any shape), as a float array, all finite; ``prefix``
    starts an error message."""
    x = np.asarray(wavelengths, dtype=float)
    if not np.all(np.isfinite(x)):
        raise InputError(f"{prefix}wavelengths must be finite numbers of nm, not "
                         f"{show(np.asarray(wavelengths).tolist())}")
    return x


def check_range(x: np.ndarray, lo: float, hi: float, source: str, prefix: str) -> None:
    """Every wavelength within [lo, hi]; else an InputError naming the range and source."""
    if x.size == 0:
        return
    outside = (x < lo) | (x > hi)
    if np.any(outside):
        bad = x[outside]
        asked = (f"{bad.min():g} nm" if bad.min() == bad.max()
                 else f"{bad.min():g}-{bad.max():g} nm")
        raise InputError(f"{prefix}{asked} asked for, outside {lo:g}-{hi:g} nm, the range "
                         f"of {source}")


@dataclass(frozen=True)
class Spectrum:
    """A quantity tabulated against wavelength, linear between the points.

    Parameters
    ----------
    nm : tuple of float
        Wavelengths in nm (vacuum), > 0 and strictly increasing; at least one.
    value : tuple of float
        The quantity at each wavelength (finite), same length as ``nm``.
    source : str
        Where the numbers come from (a citation).

    Raises
    ------
    InputError
        For values that break the rules above.

    Notes
    -----
    A one-point spectrum is a constant, valid at every wavelength; otherwise the spectrum
    is defined on [nm[0], nm[-1]] only.
    """

    nm: tuple[float, ...]
    value: tuple[float, ...]
    source: str

    def __post_init__(self) -> None:
        source = check_source(self.source, "spectrum source")
        where = f"spectrum ({source})"
        nm = finite_numbers(self.nm, f"{where}.nm")
        value = finite_numbers(self.value, f"{where}.value")
        _check_nm(nm, len(value), where)
        object.__setattr__(self, "nm", nm)
        object.__setattr__(self, "value", value)

    @property
    def nm_range(self) -> tuple[float, float]:
        """The wavelengths ``at`` accepts: (nm[0], nm[-1]), or (0, inf) for a constant."""
        if len(self.nm) == 1:
            return 0.0, math.inf
        return self.nm[0], self.nm[-1]

    def at(self, wavelengths: Any, *, where: str | None = None) -> np.ndarray:
        """The quantity at the given wavelengths, by linear interpolation between the
        tabulated points (exact at them).

        Parameters
        ----------
        wavelengths : (c,) float
            Wavelengths in nm (any shape; a number gives a 0-d array).
        where : str, optional
            The key path to start an error message with.

        Returns
        -------
        (c,) float
            The interpolated values, the shape of ``wavelengths``.

        Raises
        ------
        InputError
            For a wavelength outside [nm[0], nm[-1]] (naming the range and the source) or
            not finite.
        """
        prefix = f"{where}: " if where else ""
        x = wavelength_array(wavelengths, prefix)
        if len(self.nm) == 1:
            return np.full(x.shape, self.value[0])
        check_range(x, self.nm[0], self.nm[-1], self.source, prefix)
        return np.interp(x, np.asarray(self.nm), np.asarray(self.value))

    def to_json(self) -> dict[str, Any]:
        """The spectrum as a JSON-ready dict (``kind`` = ``"tabulated"``)."""
        return {"kind": "tabulated", "nm": list(self.nm), "value": list(self.value),
                "source": self.source}

    @classmethod
    def from_json(cls, data: Any, where: str = "spectrum") -> Spectrum:
        """Inverse of ``to_json`` (the ``kind`` key may be left out).

        Raises
        ------
        InputError
            For data that are not a spectrum, naming ``where``.
        """
        if not isinstance(data, Mapping):
            raise InputError(f"{where} = {show(data)}: a spectrum is {SPECTRUM_FORM}")
        data = dict(data)
        kind = data.pop("kind", "tabulated")
        if kind != "tabulated":
            raise InputError(f"{where}.kind = {show(kind)}: a spectrum's kind is 'tabulated'")
        if "source" not in data:
            raise InputError(f"{where}: missing key 'source' (the citation of the numbers)")
        return parse_spectrum(data, where)


def parse_spectrum(raw: Any, where: str) -> Spectrum:
    """A spectrum from a recipe's value, a table ``{ nm = [...], value = [...] }``.

    Parameters
    ----------
    raw : Any
        The value as the TOML parser gives it: a table with ``nm`` (wavelengths in nm, > 0,
        strictly increasing) and ``value`` (one finite number per wavelength), optionally
        ``source`` (a citation; default: the key path in the recipe).
    where : str
        The key path of the value, e.g. ``"material.eta"``; every message starts with it.

    Returns
    -------
    Spectrum

    Raises
    ------
    InputError
        For a value that is not a table, a missing or unknown key, an empty list, an entry
        that is not a finite number, wavelengths ≤ 0 or not strictly increasing, or lists
        of different lengths.
    """
    if not isinstance(raw, Mapping):
        raise InputError(f"{where} = {show(raw)}: a spectrum is {SPECTRUM_FORM}")
    for key in ("nm", "value"):
        if key not in raw:
            raise InputError(f"{where}: missing key '{key}'; a spectrum is {SPECTRUM_FORM}")
    for key in raw:
        if key not in SPECTRUM_KEYS:
            raise InputError(f"{where}.{key}: unknown key; a spectrum takes nm, value and "
                             "(optional) source")
    source = (check_source(raw["source"], f"{where}.source") if "source" in raw
              else f"the spectrum given at {where}")
    nm = finite_numbers(raw["nm"], f"{where}.nm")
    value = finite_numbers(raw["value"], f"{where}.value")
    _check_nm(nm, len(value), where)
    return Spectrum(nm, value, source)
