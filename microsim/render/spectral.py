"""The channels a Mitsuba 3 variant renders, made from a table's or a model's.

A table or a model gives f_r per channel: R, G, B, or one per wavelength of a spectral
table (``microsim.spectra.channels``). A variant renders R, G, B (``*_rgb``) or
wavelengths it samples itself, four per ray (``*_spectral``: uniformly over Mitsuba's
CIE range, 360–830 nm, ``MI_CIE_MIN``/``MI_CIE_MAX``). The four combinations:

- RGB channels, RGB variant: as they are.
- Spectral channels, spectral variant: as they are, at the table's wavelengths; Mitsuba
  interpolates linearly between them and holds the end values beyond the first and last
  (``measured``'s lookup; ``at_wavelengths`` for a Python BSDF, ``spectrum_dict`` for a
  plugin parameter), as ``microsim.spectra.colour`` reads a spectrum.
- Spectral channels, RGB variant: their linear sRGB (``microsim.tables.export.
  srgb_linear``: CIE 1931 2°, D65, negative components 0).
- RGB channels, spectral variant: upsampled as Mitsuba upsamples every RGB input of a
  spectral render (Jakob & Hanika 2019, "A Low-Dimensional Function Space for Efficient
  Spectral Upsampling", Computer Graphics Forum 38(2), eqs. 2–3): each value's colour c
  becomes the smooth spectrum s · S(λ) with S(λ) = ½ + x / (2 √(1 + x²)),
  x = c₀ λ² + c₁ λ + c₂, the coefficients those Mitsuba's ``srgb_model_fetch`` gives for
  c / s and s = 2 max(c) (Mitsuba's own scaling of an unbounded colour, src/spectra/
  d65.cpp, since an f_r cos θ may exceed 1). Its sRGB under D65 is c again to the
  model's accuracy. A tabulated function is upsampled at ``UPSAMPLE_NM``, every 5 nm:
  over 2000 random colours of any brightness, the sRGB of the spectrum so sampled (linear
  between the samples, as Mitsuba reads it) came back within 0.08% of the brightest
  channel of c (0.4% with 10 nm, 2% with 20 nm).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from microsim.tables.export import srgb_linear

CIE_RANGE = (360.0, 830.0)
"""Mitsuba's spectral range (``MI_CIE_MIN``, ``MI_CIE_MAX``), nm."""
UPSAMPLE_NM = tuple(float(x) for x in np.arange(360.0, 831.0, 5.0))
"""Wavelengths at which an upsampled RGB function is tabulated, nm: the CIE range every
5 nm (95)."""

Function = Callable[[np.ndarray, np.ndarray], np.ndarray]


def spectral_variant(mi: Any) -> bool:
    """Whether Mitsuba's current variant renders wavelengths (``mi.is_spectral``)."""
    return bool(mi.is_spectral)


def per_channel(values: Any, shape: tuple[int, ...], count: int) -> np.ndarray:
    """A function's output as ``shape + (count,)``: a grey (channel-less) value is the
    same in every channel, and so are three equal ones where ``count`` is not 3 (a model
    spec's single number becomes R, G, B, ``microsim.analytic.registry``).

    Parameters
    ----------
    values : (...), (..., 3) or (..., count) float
    shape : tuple of int
        The direction pairs' broadcast shape.
    count : int
        C, the channels.

    Raises
    ------
    ValueError
        For three channels that differ where ``count`` is not 3, or any other count.
    """
    v = np.asarray(values, float)
    if v.shape == shape:
        v = v[..., None]
    elif v.shape[-1] == 3 != count:
        if not (np.array_equal(v[..., 0], v[..., 1]) and np.array_equal(v[..., 0],
                                                                          v[..., 2])):
            raise ValueError(f"three different channels (R, G, B) where {count} are "
                             "wavelengths")
        v = v[..., :1]
    return np.broadcast_to(v, shape + (count,))


def coefficients(mi: Any, rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Jakob & Hanika 2019's coefficients of colours, by Mitsuba's ``srgb_model_fetch``.

    Parameters
    ----------
    mi : module
        Mitsuba, any variant.
    rgb : (n, 3) float
        Linear sRGB, ≥ 0 (negative components count as 0), any magnitude.

    Returns
    -------
    coeff : (n, 3) float
        c₀, c₁, c₂ of the colour scaled to a maximum of 1/2.
    scale : (n,) float
        s = 2 max(c) (0 for black, whose spectrum is 0).
    """
    c = np.maximum(np.asarray(rgb, float).reshape(-1, 3), 0.0)
    scale = 2.0 * c.max(axis=1)
    unit = c / np.where(scale > 0, scale, 1.0)[:, None]
    out = np.zeros_like(unit)
    rows, inverse = np.unique(unit, axis=0, return_inverse=True)
    fetched = np.array([tuple(mi.srgb_model_fetch(mi.ScalarColor3f(*row))) for row in rows],
                       dtype=float).reshape(-1, 3)
    out[:] = fetched[np.ravel(inverse)]
    return out, scale


def upsampled(coeff: np.ndarray, scale: np.ndarray, nm: np.ndarray) -> np.ndarray:
    """s · S(λ) of Jakob & Hanika 2019 (eqs. 2–3), as Mitsuba's ``srgb_model_eval``
    computes it (an infinite c₂ is a constant 0 or 1 spectrum).

    Parameters
    ----------
    coeff : (n, 3) float
    scale : (n,) float
    nm : (n, W) or (W,) float
        Wavelengths, nm.

    Returns
    -------
    (n, W) float
    """
    lam = np.asarray(nm, float)
    c0, c1, c2 = (coeff[:, i:i + 1] for i in range(3))
    with np.errstate(invalid="ignore"):
        x = (c0 * lam + c1) * lam + c2
        s = np.where(np.isinf(c2), np.where(c2 > 0, 1.0, 0.0),
                     np.maximum(0.0, 0.5 * x / np.sqrt(x * x + 1.0) + 0.5))
    return scale[:, None] * s


def upsample(mi: Any, rgb: np.ndarray, nm: Sequence[float] = UPSAMPLE_NM) -> np.ndarray:
    """Colours as Mitsuba's spectral variants would see them, sampled at ``nm``.

    Parameters
    ----------
    mi : module
    rgb : (..., 3) float
        Linear sRGB.
    nm : (W,) float

    Returns
    -------
    (..., W) float
    """
    rgb = np.asarray(rgb, float)
    coeff, scale = coefficients(mi, rgb)
    return upsampled(coeff, scale, np.asarray(nm, float)).reshape(rgb.shape[:-1] + (-1,))


def at_wavelengths(nm: Sequence[float], values: np.ndarray, lam: np.ndarray) -> np.ndarray:
    """Per-wavelength values read at other wavelengths: linear between the samples,
    constant beyond the first and last (``measured``'s lookup, ``np.interp``'s ends).

    Parameters
    ----------
    nm : (C,) float
        The values' wavelengths, increasing.
    values : (n, C) float
    lam : (n, W) float
        The wavelengths wanted per row.

    Returns
    -------
    (n, W) float
    """
    grid = np.asarray(nm, float)
    v = np.asarray(values, float)
    if len(grid) == 1:
        return np.broadcast_to(v[:, :1], lam.shape).copy()
    j = np.clip(np.searchsorted(grid, lam, side="right") - 1, 0, len(grid) - 2)
    t = np.clip((lam - grid[j]) / (grid[j + 1] - grid[j]), 0.0, 1.0)
    lo = np.take_along_axis(v, j, axis=1)
    hi = np.take_along_axis(v, j + 1, axis=1)
    return lo + t * (hi - lo)


def spectrum_dict(nm: Sequence[float], values: Sequence[float]) -> dict[str, Any]:
    """A Mitsuba ``irregular`` spectrum of per-wavelength values, their end values
    repeated at the ends of the CIE range so that it holds them constant beyond
    (``irregular`` alone is 0 outside its wavelengths)."""
    lam, v = [float(x) for x in nm], [float(x) for x in values]
    if lam[0] > CIE_RANGE[0]:
        lam, v = [CIE_RANGE[0], *lam], [v[0], *v]
    if lam[-1] < CIE_RANGE[1]:
        lam, v = [*lam, CIE_RANGE[1]], [*v, v[-1]]
    return {"type": "irregular", "wavelengths": ", ".join(f"{x:.9g}" for x in lam),
            "values": ", ".join(f"{x:.9g}" for x in v)}


def conversion(mi: Any, wavelengths: Sequence[float] | None) -> str:
    """What the current variant makes of channels ``wavelengths`` (None: R, G, B):
    ``"rgb"`` or ``"spectral"`` (as they are), ``"srgb"`` (spectra to linear sRGB) or
    ``"upsampled"`` (RGB to spectra)."""
    spectral = spectral_variant(mi)
    if wavelengths is None:
        return "upsampled" if spectral else "rgb"
    return "spectral" if spectral else "srgb"


def for_variant(mi: Any, f: Function, wavelengths: Sequence[float] | None
                ) -> tuple[Function, tuple[float, ...] | None, str]:
    """``f`` with the channels the current variant renders (module docstring).

    Parameters
    ----------
    mi : module
        Mitsuba, variant set.
    f : callable
        ``f(wi, wo) -> (...)`` (grey) or ``(..., C)`` f_r in 1/sr.
    wavelengths : (C,) float or None
        The channels of f: None for R, G, B.

    Returns
    -------
    g : callable
        ``g(wi, wo) -> (..., K)``.
    nm : tuple of float or None
        g's wavelengths (a spectral variant), or None (R, G, B).
    how : str
        ``conversion``'s word for it.
    """
    how = conversion(mi, wavelengths)
    count = 3 if wavelengths is None else len(wavelengths)

    def channels(wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        return per_channel(f(wi, wo), np.broadcast_shapes(wi.shape, wo.shape)[:-1], count)

    if how == "rgb":
        return channels, None, how
    if how == "upsampled":
        return (lambda wi, wo: upsample(mi, channels(wi, wo))), UPSAMPLE_NM, how
    nm = tuple(float(x) for x in wavelengths)
    if how == "spectral":
        return channels, nm, how
    return (lambda wi, wo: srgb_linear(nm, channels(wi, wo))), None, how
