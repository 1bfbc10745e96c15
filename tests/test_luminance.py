"""A table's luminance and display colour (microsim/tables/luminance.py), RGB and spectral:
ITU-R BT.709-6's luminance weights and IEC 61966-2-1:1999's sRGB encoding written out
here, the CIE Y column integrated with colour-science one hat spectrum at a time, the
standard error Σ_c w_c σ_c, and the refusal of values that do not fit the channels."""

from __future__ import annotations

import colour
import numpy as np
import pytest

from microsim.spectra import colour as mc
from microsim.spectra.channels import RGB, Channels
from microsim.tables import luminance as lum

BT709 = np.array([0.2126, 0.7152, 0.0722])
"""ITU-R BT.709-6, item 3.2: Y = 0.2126 R + 0.7152 G + 0.0722 B."""
NM = (400.0, 450.0, 500.0, 550.0, 600.0, 650.0, 700.0)
"""Seven wavelengths across the visible, nm."""
SPECTRAL = Channels(NM)
CMFS = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
GRID = CMFS.wavelengths                                   # 360..830 nm, 1 nm


def _srgb_curve(x: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1:1999, sec. 5.2, of x already in [0, 1]: 12.92 x for x ≤ 0.0031308,
    1.055 x^(1/2.4) − 0.055 above; written out element by element."""
    return np.array([12.92 * t if t <= 0.0031308 else 1.055 * t ** (1 / 2.4) - 0.055
                     for t in np.ravel(x)]).reshape(np.shape(x))


def _cie_y_weights(nm: tuple[float, ...]) -> np.ndarray:
    """The CIE 1931 Y under D65 of each hat spectrum (1 at one sample, 0 at the others,
    linear in between, constant beyond the ends) by colour-science's own single-spectrum
    integration (``sd_to_XYZ``, method "Integration", 1 nm), D65 brought onto the grid by
    np.interp, divided by a perfect white's Y."""
    table = colour.SDS_ILLUMINANTS["D65"]
    light = colour.SpectralDistribution(np.interp(GRID, table.wavelengths, table.values),
                                        GRID)

    def y(values: np.ndarray) -> float:
        sd = colour.SpectralDistribution(np.interp(GRID, nm, values), GRID)
        return float(colour.sd_to_XYZ(sd, cmfs=CMFS, illuminant=light,
                                      method="Integration")[1])

    white = y(np.ones(len(nm)))
    return np.array([y(e) for e in np.eye(len(nm))]) / white


def test_rgb_weights_are_bt709_and_luminance_is_their_sum() -> None:
    """RGB: the weights are BT.709's (exactly: they are the standard's decimals), they
    sum to 1, and Y of (..., 3) values is 0.2126 R + 0.7152 G + 0.0722 B to 1e-15 (one
    dot product's rounding), for one triple and for a (2, 2, 3) stack."""
    np.testing.assert_array_equal(lum.weights(RGB), BT709)
    np.testing.assert_array_equal(lum.weights(), BT709)
    assert abs(lum.weights(RGB).sum() - 1.0) <= 1e-15
    rng = np.random.default_rng(7)
    v = rng.uniform(0.0, 2.0, (2, 2, 3))
    want = 0.2126 * v[..., 0] + 0.7152 * v[..., 1] + 0.0722 * v[..., 2]
    np.testing.assert_allclose(lum.luminance(v, RGB), want, rtol=0, atol=1e-15)
    np.testing.assert_allclose(lum.luminance(v), want, rtol=0, atol=1e-15)
    assert lum.luminance([0.1, 0.5, 0.9]) == pytest.approx(
        0.2126 * 0.1 + 0.7152 * 0.5 + 0.0722 * 0.9, abs=1e-15)


def test_spectral_weights_are_the_cie_y_of_each_hat_spectrum() -> None:
    """Spectral: the weights are the CIE 1931 Y under D65 of each channel's hat spectrum,
    integrated here by colour-science one spectrum at a time (``_cie_y_weights``); both
    are the same 1 nm summation (measured 1.1e-16 apart), so 1e-12 leaves room for
    rounding only, far below the gap to the X or Z column (0.22 and 0.67). They are
    non-negative, sum to 1 and peak at 550 nm (ȳ peaks at 555 nm)."""
    w = lum.weights(SPECTRAL)
    assert w.shape == (len(NM),)
    want = _cie_y_weights(NM)
    np.testing.assert_allclose(w, want, rtol=0, atol=1e-12)
    np.testing.assert_allclose(w, mc.xyz_weights(np.array(NM))[:, 1], rtol=0, atol=1e-15)
    assert np.all(w >= 0.0)
    assert abs(w.sum() - 1.0) <= 1e-12
    assert int(np.argmax(w)) == NM.index(550.0)
    # the Z column differs from Y by far more than the tolerance
    assert np.max(np.abs(mc.xyz_weights(np.array(NM))[:, 2] - want)) > 0.05


def test_spectral_luminance_is_the_weighted_sum_of_the_samples() -> None:
    """Y of (..., C) spectral values is values @ (CIE Y weights) to 1e-12 (weights
    below 1 and values below 2: a few roundings), for one spectrum and a stack."""
    want_w = _cie_y_weights(NM)
    rng = np.random.default_rng(11)
    v = rng.uniform(0.0, 2.0, (4, len(NM)))
    np.testing.assert_allclose(lum.luminance(v, SPECTRAL), v @ lum.weights(SPECTRAL),
                               rtol=0, atol=1e-12)
    np.testing.assert_allclose(lum.luminance(v, SPECTRAL), v @ want_w, rtol=0, atol=1e-12)
    assert lum.luminance(v[0], SPECTRAL) == pytest.approx(float(v[0] @ want_w), abs=1e-12)


@pytest.mark.parametrize("channels", [RGB, SPECTRAL], ids=["rgb", "spectral"])
def test_a_grey_table_has_y_equal_to_its_value(channels: Channels) -> None:
    """The weights are ≥ 0 and sum to 1, so the same value g in every channel has Y = g
    (to 1e-12 for g up to 3: the weights' sum is 1 to 1e-15)."""
    g = np.array([0.0, 0.02, 0.5, 1.0, 3.0])
    grey = g[:, None] * np.ones((1, channels.count))
    np.testing.assert_allclose(lum.luminance(grey, channels), g, rtol=0, atol=1e-12)
    assert np.all(lum.weights(channels) >= 0.0)


@pytest.mark.parametrize("channels", [RGB, SPECTRAL], ids=["rgb", "spectral"])
def test_luminance_error_is_the_weighted_sum_of_the_channel_errors(
        channels: Channels) -> None:
    """σ_Y = Σ_c w_c σ_c (the module docstring's bound), with the weights written out
    (BT.709's or the CIE Y column above), to 1e-12 (a few roundings of errors below
    0.1), and against ``weights`` to 1e-15; a NaN channel error makes σ_Y NaN. For
    errors equal in every channel σ_Y is that error (the weights sum to 1)."""
    w = BT709 if not channels.spectral else _cie_y_weights(NM)
    rng = np.random.default_rng(3)
    err = rng.uniform(0.0, 0.1, (5, channels.count))
    want = np.array([sum(w[c] * row[c] for c in range(channels.count)) for row in err])
    np.testing.assert_allclose(lum.luminance_err(err, channels), want, rtol=0, atol=1e-12)
    np.testing.assert_allclose(lum.luminance_err(err, channels),
                               err @ lum.weights(channels), rtol=0, atol=1e-15)
    same = np.full(channels.count, 0.03)
    assert lum.luminance_err(same, channels) == pytest.approx(0.03, abs=1e-12)
    bad = err[0].copy()
    bad[1] = np.nan
    assert np.isnan(lum.luminance_err(bad, channels))


def test_encode_srgb_is_the_iec_curve_after_clipping() -> None:
    """``encode_srgb`` clips to [0, 1] and applies IEC 61966-2-1's curve (``_srgb_curve``,
    written out per element) to 1e-12 (a power's rounding is ~1e-16): values below 0 give
    0, values above 1 (a BRDF can exceed 1) give 1, both pieces are sampled, and at the
    threshold x = 0.0031308 itself it is the linear piece 12.92 x (the power piece is
    2.9e-8 lower there, far above the tolerance)."""
    x = np.array([-0.5, -1e-3, 0.0, 1e-4, 0.002, 0.0031308, 0.00314, 0.01, 0.18, 0.5,
                  0.9, 1.0, 1.5, 2.5])
    got = lum.encode_srgb(x)
    np.testing.assert_allclose(got, _srgb_curve(np.clip(x, 0.0, 1.0)), rtol=0, atol=1e-12)
    np.testing.assert_allclose(got[:3], 0.0, rtol=0, atol=0)
    np.testing.assert_allclose(got[-3:], 1.0, rtol=0, atol=1e-15)
    assert got[5] == pytest.approx(12.92 * 0.0031308, rel=0, abs=1e-12)
    # mid-grey 18 % encodes to about 0.46 (IEC 61966-2-1's curve)
    assert got[8] == pytest.approx(1.055 * 0.18 ** (1 / 2.4) - 0.055, abs=1e-12)
    assert 0.46 < got[8] < 0.47


def test_display_srgb_of_rgb_clips_and_encodes_each_channel() -> None:
    """RGB: ``display_srgb`` is the IEC curve of each channel clipped to [0, 1], for
    (..., 3) values, to 1e-12; one out-of-range channel does not touch the others."""
    v = np.array([[[-0.2, 0.18, 3.0], [0.001, 0.5, 1.0]]])
    got = lum.display_srgb(v, RGB)
    assert got.shape == v.shape
    np.testing.assert_allclose(got, _srgb_curve(np.clip(v, 0.0, 1.0)), rtol=0, atol=1e-12)
    np.testing.assert_allclose(lum.display_srgb(v), got, rtol=0, atol=0)
    np.testing.assert_allclose(got[0, 0], [0.0, _srgb_curve(np.array([0.18]))[0], 1.0],
                               rtol=0, atol=1e-12)


def test_display_srgb_computes_in_double_precision_whatever_the_input_type() -> None:
    """Values arrive as float16 or float32 (an EXR's half and float channels) and as int:
    they are converted to float64 first, so the display colour is that of the same
    values in double precision to 1e-15 (float16 arithmetic would err by ~1e-3)."""
    v = np.array([[0.002, 0.18, 0.7], [0.05, 0.33, 0.95]])
    for dtype in (np.float16, np.float32):
        low = v.astype(dtype)
        got = lum.display_srgb(low, RGB)
        assert got.dtype == np.float64, dtype
        np.testing.assert_allclose(got, _srgb_curve(low.astype(np.float64)), rtol=0,
                                   atol=1e-15, err_msg=str(dtype))
    np.testing.assert_allclose(lum.display_srgb(np.array([0, 1, 2]), RGB), [0.0, 1.0, 1.0],
                               rtol=0, atol=1e-15)


def test_display_srgb_of_a_spectrum_is_the_colour_modules_display() -> None:
    """Spectral: ``display_srgb`` is ``microsim.spectra.colour.to_srgb_display`` (D65) of
    the values, to 1e-15 (the same computation), (..., 3) for (..., C); a grey spectrum of
    value g displays as the IEC curve of g in every component, to 2e-4 (D65's white
    through the standard's four-decimal matrix is (1, 1, 1) to 2e-4, test_colour.py)."""
    rng = np.random.default_rng(5)
    v = rng.uniform(0.0, 1.0, (2, 3, len(NM)))
    got = lum.display_srgb(v, SPECTRAL)
    assert got.shape == (2, 3, 3)
    np.testing.assert_allclose(got, mc.to_srgb_display(np.array(NM), v), rtol=0, atol=1e-15)
    g = np.array([0.0, 0.1, 0.5, 0.9])
    grey = lum.display_srgb(g[:, None] * np.ones((1, len(NM))), SPECTRAL)
    np.testing.assert_allclose(grey, np.repeat(_srgb_curve(g)[:, None], 3, axis=1),
                               rtol=0, atol=2e-4)


@pytest.mark.parametrize("call", [lum.luminance, lum.luminance_err, lum.display_srgb],
                         ids=["luminance", "luminance_err", "display_srgb"])
def test_values_that_do_not_fit_the_channels_are_refused_naming_them(call) -> None:
    """A last axis other than one per channel (as the first or the last of several
    axes), and a scalar, are a ValueError naming the shape, the count and the channels."""
    with pytest.raises(ValueError, match=r"^values of shape \(4,\): the last axis must "
                                         r"hold the 3 channels \(R, G, B\)$"):
        call(np.ones(4), RGB)
    with pytest.raises(ValueError, match=r"^values of shape \(3, 2\): the last axis must "
                                         r"hold the 3 channels \(R, G, B\)$"):
        call(np.ones((3, 2)), RGB)
    with pytest.raises(ValueError, match=r"^values of shape \(\): the last axis must "
                                         r"hold the 3 channels \(R, G, B\)$"):
        call(0.5, RGB)
    with pytest.raises(ValueError, match=r"^values of shape \(2, 3\): the last axis must "
                       r"hold the 7 channels \(400nm, 450nm, 500nm, 550nm, 600nm, 650nm, "
                       r"700nm\)$"):
        call(np.ones((2, 3)), SPECTRAL)


def test_note_names_what_the_luminance_is() -> None:
    """BT.709's Y for RGB, CIE Y under D65 for wavelengths (the figures' notes)."""
    assert lum.note(RGB) == "luminance Y (Rec. 709)"
    assert lum.note() == "luminance Y (Rec. 709)"
    assert lum.note(SPECTRAL) == "luminance (CIE Y, D65)"
