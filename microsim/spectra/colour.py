"""CIE colorimetry of spectral tables: XYZ, luminance and sRGB of values sampled at C
wavelengths.

A spectral table holds values of shape (..., C) at C wavelengths ``nm`` (in vacuum,
strictly increasing, not necessarily uniform). They are read as a reflectance-like
quantity (a BRDF, an albedo: the illuminant is applied here, not in the values) whose
spectrum is

- between two samples, the linear interpolation of the two;
- below the first and above the last sample, constant (the end sample's value),

evaluated on the colour-matching functions' own 1 nm grid (360–830 nm for the CIE 1931
2° observer) and summed there with the illuminant: CIE's standard method, summation at
1 nm over 360–830 nm (CIE 015:2018, *Colorimetry*, 4th ed., sec. 7.1:
X = k Σ S(λ) R(λ) x̄(λ) Δλ, and Y, Z with ȳ, z̄). The whole computation is linear in the
values, so it is one (C, 3) matrix per (wavelengths, illuminant, observer), computed once
with colour-science (``colour.msds_to_XYZ``, method "Integration", on the C "hat" basis
spectra) and cached.
Its normalisation is CIE's k (sec. 7.1), here 1 / Σ S(λ) ȳ(λ) Δλ rather than 100 / …: a
perfect white (all ones) has Y = 1, i.e. XYZ is relative, not in percent.

The illuminants are colour-science's CIE tables (``colour.SDS_ILLUMINANTS``), brought onto
the 1 nm grid by colour-science's own alignment (linear interpolation; beyond a table's
last wavelength, e.g. D65 above 780 nm, its end value held constant: ȳ is below 1e-4 of its
peak there).

sRGB (IEC 61966-2-1:1999, *Default RGB colour space – sRGB*, sec. 5.2) is
colour-science's ``RGB_COLOURSPACES["sRGB"]``: its XYZ→RGB matrix (the standard's
four-decimal one) and its encoding transfer function. The sRGB white is D65: under D65 the
XYZ go through the matrix as they are; under any other illuminant they are first adapted
from that illuminant's white (the XYZ of a perfect white under it) to sRGB's D65 white by
a von Kries transform in CAT02 space (CIE 159:2004; ``colour.adaptation``), so a perfect
white is neutral whatever the illuminant, as the sRGB viewing condition assumes an
observer adapted to the scene's white.

This module imports colour-science (and through it SciPy): about a second. Nothing on the
path of ``microsim check`` (recipes, schema, materials) may import it. colour-science
switches numpy to its 1.13 printing when imported; this module puts the caller's printing
back (tests/test_colour.py).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from microsim.errors import InputError

_PRINTING = np.get_printoptions()
import colour  # noqa: E402 (colour-science sets numpy's 1.13 printing on import: undone)

np.set_printoptions(**_PRINTING)

ILLUMINANTS = ("D65", "D50", "D55", "D75", "A", "E")
"""The accepted illuminant names (CIE standard illuminants, colour-science's tables)."""

_OBSERVERS = ("CIE 1931 2 Degree Standard Observer", "CIE 1964 10 Degree Standard Observer")
_SRGB_OBSERVER = "CIE 1931 2 Degree Standard Observer"


def _check_nm(nm: np.ndarray | tuple[float, ...] | list[float]) -> tuple[float, ...]:
    """The wavelengths as a tuple of floats, after checking them.

    Parameters
    ----------
    nm : (C,) float
        Wavelengths in nm.

    Returns
    -------
    tuple of float
        The C wavelengths (a hashable cache key).
    """
    try:
        a = np.asarray(nm, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"wavelengths = {nm!r}: must be numbers in nm") from None
    if a.ndim != 1 or a.size == 0:
        raise InputError(f"wavelengths of shape {a.shape}: must be a non-empty 1-D list "
                         f"of nm")
    if not np.all(np.isfinite(a)) or np.any(a <= 0.0):
        raise InputError(f"wavelengths = {a.tolist()}: must be finite and > 0 nm")
    if np.any(np.diff(a) <= 0.0):
        raise InputError(f"wavelengths = {a.tolist()}: must be strictly increasing")
    return tuple(float(w) for w in a)


def _check_illuminant(illuminant: str) -> str:
    """``illuminant`` if it is one of ``ILLUMINANTS``; InputError otherwise."""
    if not isinstance(illuminant, str) or illuminant not in ILLUMINANTS:
        raise InputError(f"illuminant = {illuminant!r}: must be one of "
                         f"{', '.join(ILLUMINANTS)}")
    return illuminant


def _check_observer(cmfs: str) -> str:
    """``cmfs`` if it is one of the accepted observers; InputError otherwise."""
    if not isinstance(cmfs, str) or cmfs not in _OBSERVERS:
        raise InputError(f"cmfs = {cmfs!r}: must be one of {', '.join(_OBSERVERS)}")
    return cmfs


@lru_cache(maxsize=64)
def _weights(nm: tuple[float, ...], illuminant: str, cmfs: str) -> np.ndarray:
    """The cached, read-only (C, 3) XYZ weights; arguments already checked."""
    observer = colour.MSDS_CMFS[cmfs]
    grid = observer.wavelengths
    # Hat basis: spectrum i is 1 at nm[i], 0 at the other samples, linear in between and
    # constant beyond the ends (np.interp's extension), sampled on the CMFs' grid.
    eye = np.eye(len(nm))
    hats = np.stack([np.interp(grid, nm, e) for e in eye])           # (C, n_grid)
    light = colour.colorimetry.reshape_sd(colour.SDS_ILLUMINANTS[illuminant],
                                          observer.shape, copy=True)
    xyz = colour.msds_to_XYZ(hats, cmfs=observer, illuminant=light,
                             method="Integration", shape=observer.shape)
    w = np.asarray(xyz, dtype=float).reshape(len(nm), 3)
    # The hats sum to 1 on the grid, so the column sum of Y is a perfect white's Y:
    # normalise it to 1 (CIE 015:2018 sec. 7.1's k, whatever colour's range scale).
    w = w / w[:, 1].sum()
    w.setflags(write=False)
    return w


def xyz_weights(nm: np.ndarray, illuminant: str = "D65",
                cmfs: str = "CIE 1931 2 Degree Standard Observer") -> np.ndarray:
    """The linear map from spectral values to CIE XYZ: ``XYZ = values @ W``.

    The spectrum of values sampled at ``nm`` is their linear interpolation, constant
    beyond the first and last sample; it is weighted by the illuminant and the CMFs on the
    CMFs' 1 nm grid and summed (CIE 015:2018, sec. 7.1), with k such that a
    perfect white (all ones) has Y = 1. Computed with colour-science
    (``colour.msds_to_XYZ``, method "Integration") on the C hat basis spectra, and cached
    per (wavelengths, illuminant, observer).

    Parameters
    ----------
    nm : (C,) float
        Wavelengths in nm, finite, > 0, strictly increasing.
    illuminant : str
        One of ``ILLUMINANTS``.
    cmfs : str
        The observer: "CIE 1931 2 Degree Standard Observer" or
        "CIE 1964 10 Degree Standard Observer".

    Returns
    -------
    (C, 3) float
        W, read-only (shared by the cache); its column Y sums to 1.

    Raises
    ------
    InputError
        Bad wavelengths, an unknown illuminant or observer.
    """
    return _weights(_check_nm(nm), _check_illuminant(illuminant), _check_observer(cmfs))


def _values(nm: tuple[float, ...], values: np.ndarray) -> np.ndarray:
    """``values`` as floats, after checking that its last axis has one entry per
    wavelength."""
    v = np.asarray(values, dtype=float)
    if v.ndim == 0 or v.shape[-1] != len(nm):
        raise InputError(f"values of shape {v.shape}: the last axis must have one entry "
                         f"per wavelength ({len(nm)})")
    return v


def to_xyz(nm: np.ndarray, values: np.ndarray, illuminant: str = "D65") -> np.ndarray:
    """CIE 1931 XYZ of spectral values under an illuminant (``values @ xyz_weights``).

    Parameters
    ----------
    nm : (C,) float
        Wavelengths in nm, strictly increasing.
    values : (..., C) float
        A reflectance-like quantity at those wavelengths.
    illuminant : str
        One of ``ILLUMINANTS``.

    Returns
    -------
    (..., 3) float
        XYZ, relative: a perfect white (all ones) has Y = 1.
    """
    key = _check_nm(nm)
    w = _weights(key, _check_illuminant(illuminant), _SRGB_OBSERVER)
    return _values(key, values) @ w


def luminance(nm: np.ndarray, values: np.ndarray, illuminant: str = "D65") -> np.ndarray:
    """Relative luminance Y of spectral values under an illuminant.

    Parameters
    ----------
    nm : (C,) float
        Wavelengths in nm, strictly increasing.
    values : (..., C) float
        A reflectance-like quantity at those wavelengths.
    illuminant : str
        One of ``ILLUMINANTS``.

    Returns
    -------
    (...) float
        Y; 1 for a perfect white.
    """
    key = _check_nm(nm)
    w = _weights(key, _check_illuminant(illuminant), _SRGB_OBSERVER)
    return _values(key, values) @ w[:, 1]


@lru_cache(maxsize=16)
def _xyz_to_srgb(illuminant: str) -> np.ndarray:
    """The (3, 3) matrix from XYZ under ``illuminant`` to linear sRGB, read-only.

    IEC 61966-2-1's (sec. 5.2) XYZ→RGB matrix (colour-science's
    ``RGB_COLOURSPACES["sRGB"]``), after, unless the illuminant is D65, a CAT02 von Kries
    adaptation from the illuminant's integrated white to sRGB's white (CIE 159:2004).
    """
    space = colour.RGB_COLOURSPACES["sRGB"]
    m = np.asarray(space.matrix_XYZ_to_RGB, dtype=float)
    if illuminant != "D65":
        # The white of this illuminant as this module integrates it (a one-sample
        # constant spectrum), so a perfect white maps exactly to sRGB's white.
        white = _weights((550.0,), illuminant, _SRGB_OBSERVER)[0]
        target = colour.xy_to_XYZ(space.whitepoint)
        cat = colour.adaptation.matrix_chromatic_adaptation_VonKries(
            white, target, transform="CAT02")
        m = m @ np.asarray(cat, dtype=float)
    m.setflags(write=False)
    return m


def to_srgb_linear(nm: np.ndarray, values: np.ndarray,
                   illuminant: str = "D65") -> np.ndarray:
    """Linear sRGB of spectral values under an illuminant, not clipped.

    XYZ (``to_xyz``) through IEC 61966-2-1's XYZ→RGB matrix; under an illuminant other
    than D65, first adapted to D65 (CAT02 von Kries, from the illuminant's white), so a
    perfect white gives (1, 1, 1) (under D65 to within 2e-4, the standard's matrix being
    rounded to 4 decimals).

    Parameters
    ----------
    nm : (C,) float
        Wavelengths in nm, strictly increasing.
    values : (..., C) float
        A reflectance-like quantity at those wavelengths.
    illuminant : str
        One of ``ILLUMINANTS``.

    Returns
    -------
    (..., 3) float
        Linear R, G, B; out-of-gamut colours have components < 0 or > 1.
    """
    m = _xyz_to_srgb(_check_illuminant(illuminant))
    return to_xyz(nm, values, illuminant) @ m.T


def to_srgb_display(nm: np.ndarray, values: np.ndarray,
                    illuminant: str = "D65") -> np.ndarray:
    """Display-encoded sRGB of spectral values: linear sRGB clipped to [0, 1], then
    IEC 61966-2-1's encoding (sec. 5.2: 12.92 x up to 0.0031308, 1.055 x^(1/2.4) − 0.055
    above; colour-science's ``eotf_inverse_sRGB``).

    Each component is clipped on its own (no gamut mapping): an out-of-gamut colour
    changes hue a little.

    Parameters
    ----------
    nm : (C,) float
        Wavelengths in nm, strictly increasing.
    values : (..., C) float
        A reflectance-like quantity at those wavelengths.
    illuminant : str
        One of ``ILLUMINANTS``.

    Returns
    -------
    (..., 3) float
        Encoded R', G', B' in [0, 1] (multiply by 255 and round for 8 bits).
    """
    rgb = np.clip(to_srgb_linear(nm, values, illuminant), 0.0, 1.0)
    return np.asarray(colour.models.eotf_inverse_sRGB(rgb), dtype=float)
