"""The luminance and the display colour of a table's channels, RGB or spectral.

What a figure or a report collapses a table's C channels into:

- an RGB table's channels are linear sRGB (ITU-R BT.709 primaries, D65 white): its
  luminance is Y = 0.2126 R + 0.7152 G + 0.0722 B (ITU-R BT.709-6, item 3.2;
  ``LUMINANCE``) and its display colour the sRGB encoding of
  the linear values clipped to [0, 1] (IEC 61966-2-1:1999, sec. 5.2);
- a spectral table's channels are samples of a spectrum at its wavelengths: its
  luminance is CIE 1931 Y under D65 (CIE 015:2018, sec. 7.1; ``microsim.spectra.colour``,
  piecewise-linear between the samples, normalised so a perfect white has Y = 1) and its
  display colour ``microsim.spectra.colour.to_srgb_display`` (XYZ through the sRGB
  matrix, clipped per component, encoded).

Both luminances are linear maps Y = Σ_c w_c v_c with w_c ≥ 0 (BT.709's weights; the hat
spectra weighted by D65 and ȳ, both non-negative) summing to 1, so a grey table (the same
value in every channel) has Y equal to that value.

Y's standard error is taken as Σ_c w_c σ_c: the channels of a bin are estimated from the
same rays, so their errors are positively correlated; the sum is exact when the channels
are proportional (grey facets) and an upper bound otherwise (the triangle inequality of
the standard deviation), so a z-score of Y never overstates a difference.

colour-science (behind ``microsim.spectra.colour``) takes about a second to import: it is
imported inside the functions, and only for spectral channels.
"""

from __future__ import annotations

import numpy as np

from microsim.spectra.channels import RGB, Channels

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
"""BT.709 luminance weights of linear R, G, B (ITU-R BT.709-6, item 3.2; those of
``microsim.tables.export.LUMINANCE`` too)."""

RGB_NOTE = "luminance Y (Rec. 709)"
"""What an RGB table's luminance is, in words (figure notes)."""
SPECTRAL_NOTE = "luminance (CIE Y, D65)"
"""What a spectral table's luminance is, in words."""


def note(channels: Channels = RGB) -> str:
    """``RGB_NOTE`` or ``SPECTRAL_NOTE``: what ``luminance`` of these channels is."""
    return SPECTRAL_NOTE if channels.spectral else RGB_NOTE


def weights(channels: Channels = RGB) -> np.ndarray:
    """The (C,) weights w of Y = Σ_c w_c v_c: BT.709's for RGB, the CIE Y column of
    ``microsim.spectra.colour.xyz_weights`` (D65, CIE 1931 2°) for wavelengths."""
    if not channels.spectral:
        return LUMINANCE
    from microsim.spectra import colour

    return colour.xyz_weights(np.asarray(channels.wavelengths))[:, 1]


def _check(values: np.ndarray, channels: Channels) -> np.ndarray:
    """``values`` as floats, after checking that the last axis is one per channel."""
    v = np.asarray(values, float)
    if v.ndim == 0 or v.shape[-1] != channels.count:
        raise ValueError(f"values of shape {v.shape}: the last axis must hold the "
                         f"{channels.count} channels ({', '.join(channels.names)})")
    return v


def luminance(values: np.ndarray, channels: Channels = RGB) -> np.ndarray:
    """Y of per-channel values.

    Parameters
    ----------
    values : (..., C) float
        Linear values (f_r, albedo) in the table's channels.
    channels : Channels
        The table's (``BRDFTable.channels``).

    Returns
    -------
    (...) float
        BT.709 Y of linear RGB, or CIE Y (D65) of a spectrum
        (``microsim.spectra.colour.luminance``).
    """
    v = _check(values, channels)
    if not channels.spectral:
        return v @ LUMINANCE
    from microsim.spectra import colour

    return colour.luminance(np.asarray(channels.wavelengths), v)


def luminance_err(err: np.ndarray, channels: Channels = RGB) -> np.ndarray:
    """Standard error of Y from the channels' errors: Σ_c w_c σ_c (module docstring; NaN
    where a channel's error is undefined).

    Parameters
    ----------
    err : (..., C) float
    channels : Channels

    Returns
    -------
    (...) float
    """
    return _check(err, channels) @ weights(channels)


def encode_srgb(linear: np.ndarray) -> np.ndarray:
    """The sRGB transfer curve of linear values, clipped to [0, 1] first (IEC 61966-2-1,
    sec. 5.2: 12.92 x up to 0.0031308, 1.055 x^(1/2.4) − 0.055 above)."""
    x = np.clip(linear, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)


def display_srgb(values: np.ndarray, channels: Channels = RGB) -> np.ndarray:
    """Display-encoded sRGB in [0, 1] of per-channel values (reflectance-like: an albedo).

    Parameters
    ----------
    values : (..., C) float
    channels : Channels

    Returns
    -------
    (..., 3) float
        ``encode_srgb`` of linear RGB, or ``microsim.spectra.colour.to_srgb_display`` of
        a spectrum (D65).
    """
    v = _check(values, channels)
    if not channels.spectral:
        return encode_srgb(v)
    from microsim.spectra import colour

    return colour.to_srgb_display(np.asarray(channels.wavelengths), v)

