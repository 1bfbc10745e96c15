"""The measured spectra shipped with microsim, by name: conductors' optical constants
(η, k), dielectrics' dispersion formulas, and reflectance spectra of real surfaces.

The tables are the text files ``microsim/spectra/data/*.csv``: ``#`` comment lines (the
description, a ``# source:`` line with the full citation, ``# range:`` and ``# units:``),
then a header row (``nm`` and the quantities' names) and one row per wavelength. They are
read lazily through ``importlib.resources`` and cached; nothing is downloaded.

Shipped (see each file's header for the details):

- conductors, η and k: Ag, Au, Cu (Johnson & Christy 1972, 187.9–1937 nm), Al (Rakić 1995,
  206.6–2066 nm), Cr (Rakić et al. 1998, Brendel-Bormann model, 248.0–2043 nm);
- dielectrics: ``fused_silica`` (Malitson 1965 Sellmeier, 210–3710 nm), ``BK7`` (SCHOTT
  N-BK7 Sellmeier, 300–2500 nm);
- reflectances: ten ColorChecker Classic patches, ``colorchecker_<patch>`` (BabelColor's
  average of 30 charts, 380–730 nm).
"""

from __future__ import annotations

import functools
from importlib import resources

from microsim.errors import InputError
from microsim.spectra.dispersion import Dispersion, Sellmeier
from microsim.spectra.spectrum import Spectrum

KINDS = ("conductor", "dielectric", "reflectance")
"""The kinds of shipped data ``names`` lists."""

CONDUCTORS = ("Ag", "Al", "Au", "Cr", "Cu")
"""The conductors shipped, each a file ``<name>.csv`` with columns nm, eta, k."""

REFLECTANCE_FILES = ("colorchecker.csv",)
"""The files of reflectance spectra: columns nm, then one column per named spectrum."""

_MALITSON = ('I. H. Malitson, "Interspecimen comparison of the refractive index of fused '
             'silica", J. Opt. Soc. Am. 55, 1205-1208 (1965), doi:10.1364/JOSA.55.001205 '
             "(Sellmeier formula, 20 °C)")
_SCHOTT = ("SCHOTT AG, optical glass data sheet N-BK7 517642.251 (Sellmeier coefficients of "
           "the SCHOTT Zemax catalogue 2017-01-20; n_d = 1.5168, v_d = 64.17)")

DIELECTRICS: dict[str, Dispersion] = {
    # Malitson 1965's coefficients: B_i and resonance wavelengths λ_i in µm, so
    # C_i = λ_i²; the formula is stated for 0.21–3.71 µm.
    "fused_silica": Sellmeier(
        b=(0.6961663, 0.4079426, 0.8974794),
        c=(0.0684043**2, 0.1162414**2, 9.896161**2),
        nm_range=(210.0, 3710.0), source=_MALITSON),
    # SCHOTT's B_i and C_i (µm²); the catalogue states the formula for 0.3–2.5 µm.
    "BK7": Sellmeier(
        b=(1.03961212, 0.231792344, 1.01046945),
        c=(0.00600069867, 0.0200179144, 103.560653),
        nm_range=(300.0, 2500.0), source=_SCHOTT),
}
"""The dielectrics' dispersion formulas, by name."""


@functools.cache
def _read(filename: str) -> tuple[str, dict[str, tuple[float, ...]]]:
    """A shipped data file: its ``# source:`` citation and its columns by header name.

    A malformed shipped file is a defect of the package (RuntimeError), not bad input.
    """
    text = resources.files("microsim.spectra").joinpath("data", filename).read_text("utf-8")
    source = None
    header: list[str] | None = None
    rows: list[tuple[float, ...]] = []
    for number, line in enumerate(text.splitlines(), start=1):
        line = line.strip()
        if not line:
            continue
        if line.startswith("#"):
            body = line[1:].strip()
            if body.startswith("source:"):
                source = body[len("source:"):].strip()
            continue
        cells = [cell.strip() for cell in line.split(",")]
        if header is None:
            header = cells
            continue
        if len(cells) != len(header):
            raise RuntimeError(f"shipped data file {filename}, line {number}: {len(cells)} "
                               f"cells under a header of {len(header)}")
        rows.append(tuple(float(cell) for cell in cells))
    if source is None or header is None or header[0] != "nm" or not rows:
        raise RuntimeError(f"shipped data file {filename}: needs a '# source:' line, a header "
                           "starting with nm, and rows")
    columns = {name: tuple(row[i] for row in rows) for i, name in enumerate(header)}
    return source, columns


def _spectrum(filename: str, column: str) -> Spectrum:
    """One column of a shipped file as a Spectrum, citing the file's source."""
    source, columns = _read(filename)
    return Spectrum(columns["nm"], columns[column],
                    f"{source} [microsim/spectra/data/{filename}, column {column}]")


def _lookup(name: str, shipped: tuple[str, ...], kind: str, where: str) -> str:
    """The shipped name matching ``name`` (case-insensitively), else an InputError."""
    if isinstance(name, str):
        for candidate in shipped:
            if candidate.lower() == name.strip().lower():
                return candidate
    raise InputError(f"{where} = {name!r}: no shipped {kind} of that name; the shipped "
                     f"{kind}s are {', '.join(shipped)}")


@functools.cache
def _conductor(name: str) -> tuple[Spectrum, Spectrum]:
    return _spectrum(f"{name}.csv", "eta"), _spectrum(f"{name}.csv", "k")


def conductor(name: str, *, where: str = "conductor") -> tuple[Spectrum, Spectrum]:
    """The measured optical constants of a shipped conductor.

    Parameters
    ----------
    name : str
        One of ``names("conductor")`` (case-insensitive).
    where : str
        The key path to name in an error message.

    Returns
    -------
    (Spectrum, Spectrum)
        η and k, the real and imaginary parts of the complex refractive index η + i k.

    Raises
    ------
    InputError
        For an unknown name, listing the shipped ones.
    """
    return _conductor(_lookup(name, CONDUCTORS, "conductor", where))


def dielectric(name: str, *, where: str = "dielectric") -> Dispersion:
    """The dispersion formula of a shipped dielectric.

    Parameters
    ----------
    name : str
        One of ``names("dielectric")`` (case-insensitive).
    where : str
        The key path to name in an error message.

    Returns
    -------
    Dispersion
        Its refractive index n(λ), ``at(nm)``.

    Raises
    ------
    InputError
        For an unknown name, listing the shipped ones.
    """
    return DIELECTRICS[_lookup(name, tuple(DIELECTRICS), "dielectric", where)]


@functools.cache
def _reflectances() -> dict[str, str]:
    """Every shipped reflectance spectrum's name, with the file that holds it."""
    out: dict[str, str] = {}
    for filename in REFLECTANCE_FILES:
        for column in _read(filename)[1]:
            if column != "nm":
                out[column] = filename
    return out


def reflectance(name: str, *, where: str = "reflectance") -> Spectrum:
    """A shipped reflectance spectrum (a fraction, 0–1, against wavelength).

    Parameters
    ----------
    name : str
        One of ``names("reflectance")`` (case-insensitive), e.g. ``"colorchecker_red"``.
    where : str
        The key path to name in an error message.

    Returns
    -------
    Spectrum

    Raises
    ------
    InputError
        For an unknown name, listing the shipped ones.
    """
    shipped = _reflectances()
    name = _lookup(name, tuple(shipped), "reflectance", where)
    return _spectrum(shipped[name], name)


def names(kind: str) -> tuple[str, ...]:
    """The names of the shipped data of one kind.

    Parameters
    ----------
    kind : str
        ``"conductor"``, ``"dielectric"`` or ``"reflectance"``.

    Returns
    -------
    tuple of str
        The names ``conductor``, ``dielectric`` or ``reflectance`` accept.

    Raises
    ------
    InputError
        For an unknown kind, listing the kinds.
    """
    if kind == "conductor":
        return CONDUCTORS
    if kind == "dielectric":
        return tuple(DIELECTRICS)
    if kind == "reflectance":
        return tuple(_reflectances())
    raise InputError(f"kind = {kind!r}: the kinds of shipped spectra are {', '.join(KINDS)}")


def source(kind: str, name: str) -> str:
    """The citation of a shipped data set (``kind`` as ``names``): a conductor's η and k
    share their file's."""
    if kind == "conductor":
        return conductor(name)[0].source
    if kind == "dielectric":
        return dielectric(name).source
    return reflectance(name).source
