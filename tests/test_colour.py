"""Colorimetry of spectral tables (microsim/spectra/colour.py): XYZ, luminance and sRGB
under CIE illuminants, checked against colour-science's own single-spectrum integration,
CIE's published white points, BabelColor's published ColorChecker colorimetry and the
published sRGB of the chart."""

from __future__ import annotations

import colour
import numpy as np
import pytest

from microsim.errors import InputError
from microsim.spectra import colour as mc

CMFS = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
GRID = CMFS.wavelengths                                   # 360..830 nm, 1 nm
BABEL = colour.SDS_COLOURCHECKERS["BabelColor Average"]   # 380..730 nm, 10 nm
BABEL_CCS = colour.CCS_COLOURCHECKERS["BabelColor Average"]  # xyY under ICC D50, 2°
SAMPLINGS = {
    "16 uniform": np.linspace(380.0, 780.0, 16),
    "32 uniform": np.linspace(380.0, 780.0, 32),
    # non-uniform, fractional, not spanning the CMFs' range: exercises the constant
    # extension at both ends and kinks between the 1 nm grid points
    "16 uneven": np.array([395.5, 410.0, 430.0, 445.2, 470.0, 490.0, 505.0, 520.0,
                           540.0, 555.5, 575.0, 600.0, 625.0, 650.0, 690.0, 735.0]),
}


def _spectra(nm: np.ndarray) -> dict[str, np.ndarray]:
    """Smooth test spectra sampled at ``nm``: a Gaussian bump at 550 nm, a ramp, and two
    measured ColorChecker patches (BabelColor's average, linearly resampled)."""
    out = {
        "gauss550": 0.05 + 0.9 * np.exp(-0.5 * ((nm - 550.0) / 30.0) ** 2),
        "ramp": (nm - 350.0) / 500.0,
    }
    for name in ("dark skin", "blue"):
        sd = BABEL[name]
        out[name] = np.interp(nm, sd.wavelengths, sd.values)
    return out


def _reference_xyz(nm: np.ndarray, values: np.ndarray, illuminant: str = "D65") -> np.ndarray:
    """colour-science's own integration (``sd_to_XYZ``, method "Integration") of the same
    function: the piecewise-linear spectrum (constant beyond its ends) evaluated on the
    1 nm grid by np.interp, with the illuminant brought onto the grid by np.interp as
    well (linear, constant beyond its table), one spectrum at a time; Y of white = 1."""
    sd = colour.SpectralDistribution(np.interp(GRID, nm, values), GRID)
    light_table = colour.SDS_ILLUMINANTS[illuminant]
    light = colour.SpectralDistribution(
        np.interp(GRID, light_table.wavelengths, light_table.values), GRID)
    return colour.sd_to_XYZ(sd, cmfs=CMFS, illuminant=light, method="Integration") / 100.0


@pytest.mark.parametrize("sampling", list(SAMPLINGS))
@pytest.mark.parametrize("illuminant", ["D65", "A"])
def test_xyz_matches_colour_science_on_the_same_piecewise_linear_spectrum(
        sampling: str, illuminant: str) -> None:
    """Both integrate the same function (the samples' linear interpolation, constant
    beyond the ends, times the illuminant and the CMFs) by the same 1 nm summation; the
    module through its (C, 3) hat-basis matrix, the reference one spectrum at a time. What
    is left is the integration rule's round-off (measured 6e-16); 1e-4 still catches a
    1 nm shift of the samples (6e-3 for the bump) or a wrong illuminant (2e-2, D50)."""
    nm = SAMPLINGS[sampling]
    for name, v in _spectra(nm).items():
        got = mc.to_xyz(nm, v, illuminant)
        want = _reference_xyz(nm, v, illuminant)
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-4, err_msg=name)
        assert abs(mc.luminance(nm, v, illuminant) - want[1]) <= 1e-4, name


# CIE 015's tabulated tristimulus values of the perfect white under the standard
# illuminants (2° observer, given in percent to 2 decimals; here Y = 1); E is equal-energy.
CIE_WHITES = {
    "D65": (0.9504, 1.0, 1.0888),
    "D50": (0.9642, 1.0, 0.8251),
    "A": (1.0985, 1.0, 0.3558),
    "E": (1.0, 1.0, 1.0),
}


@pytest.mark.parametrize("illuminant", list(CIE_WHITES))
def test_white_gives_the_cie_white_point_and_srgb_white(illuminant: str) -> None:
    """A perfect white sampled densely (1 nm, 380–780) gives CIE's published white point
    to 1e-3 (the published values are rounded to 1e-4 and come from 5 nm tables summed
    over 380–780 nm against 1 nm over 360–830 here: a few 1e-4); linear sRGB (1, 1, 1) to 2e-3 (sRGB's
    matrix is rounded to 4 decimals, IEC 61966-2-1; the D65 white is not adapted, the
    others are adapted to D65 and so map to white by construction)."""
    nm = np.arange(380.0, 781.0)
    white = np.ones_like(nm)
    np.testing.assert_allclose(mc.to_xyz(nm, white, illuminant), CIE_WHITES[illuminant],
                               rtol=0, atol=1e-3)
    np.testing.assert_allclose(mc.to_srgb_linear(nm, white, illuminant), 1.0,
                               rtol=0, atol=2e-3)
    np.testing.assert_allclose(mc.to_srgb_display(nm, white, illuminant), 1.0,
                               rtol=0, atol=2e-3)


def test_colorchecker_xyz_under_d50_matches_babelcolor_published_colorimetry() -> None:
    """BabelColor's published xyY of its average ColorChecker (ICC D50, 2°; colour-science's
    CCS_COLOURCHECKERS) are computed from the same average spectra (380–730 nm, 10 nm),
    given to 4 decimals. At the spectra's own sampling all 24 patches agree to 1.5e-3 in
    x, y and Y (measured max 1.2e-3): the residual is the rounding and BabelColor's
    integration rule (10 nm weighting tables against 1 nm linear interpolation here)."""
    worst = 0.0
    for name, sd in BABEL.items():
        xyy = colour.XYZ_to_xyY(mc.to_xyz(sd.wavelengths, sd.values, "D50"))
        worst = max(worst, float(np.abs(xyy - BABEL_CCS.data[name]).max()))
    assert worst <= 1.5e-3


def test_colorchecker_srgb_under_d50_matches_its_published_colorimetry_in_srgb() -> None:
    """The same patches' display sRGB under D50 against BabelColor's published xyY taken to
    sRGB by colour-science's own XYZ_to_sRGB (CAT02 from ICC D50 to D65, clipped): 8e-3
    covers the xyY residual of the test above after the encoding's slope (measured max
    4.5e-3, the yellow patch, whose linear blue is near 0 where the encoding is steep)."""
    for name, sd in BABEL.items():
        got = mc.to_srgb_display(sd.wavelengths, sd.values, "D50")
        xyz = colour.xyY_to_XYZ(BABEL_CCS.data[name])
        want = np.clip(colour.XYZ_to_sRGB(xyz, illuminant=BABEL_CCS.illuminant,
                                          chromatic_adaptation_transform="CAT02"), 0, 1)
        np.testing.assert_allclose(got, want, rtol=0, atol=8e-3, err_msg=name)


# The published 8-bit sRGB of the ColorChecker Classic (Pascale, "RGB coordinates of the
# Macbeth ColorChecker", BabelColor, 2006; X-Rite quotes the same numbers): low-chroma
# patches only, see the test.
PUBLISHED_SRGB8 = {
    "dark skin": (115, 82, 68),
    "light skin": (194, 150, 130),
    "white 9.5 (.05 D)": (243, 243, 242),
    "neutral 8 (.23 D)": (200, 200, 200),
    "neutral 6.5 (.44 D)": (160, 160, 160),
    "neutral 5 (.70 D)": (122, 122, 121),
    "neutral 3.5 (1.05 D)": (85, 85, 85),
    "black 2 (1.5 D)": (52, 52, 52),
}


@pytest.mark.parametrize("name", list(PUBLISHED_SRGB8))
def test_colorchecker_srgb_under_d65_matches_the_published_srgb(name: str) -> None:
    """Display sRGB under D65 of BabelColor's average spectra against the published 8-bit
    sRGB of the chart within 0.02 (5/255): 8-bit rounding (0.002), the published values
    come from an earlier average of other charts (2006, against the 2012 spectra here) and
    from D50 colorimetry adapted to D65 (Bradford) rather than D65 spectral integration.
    Measured: at most 0.014 on these patches. Saturated patches differ more (up to 0.055,
    the blue patch's red, a linear 0.023 against 0.040 where the encoding is steep), so
    they are checked through the D50 colorimetry above instead."""
    sd = BABEL[name]
    got = mc.to_srgb_display(sd.wavelengths, sd.values)
    np.testing.assert_allclose(got, np.array(PUBLISHED_SRGB8[name]) / 255.0, rtol=0,
                               atol=0.02)


def test_srgb_linear_is_the_iec_matrix_and_the_cat02_adaptation_of_colour_science() -> None:
    """Under A, linear sRGB equals colour-science's XYZ_to_RGB of the module's XYZ with
    CAT02 from A's white (as integrated) to sRGB's D65 white; under D65, the bare IEC
    61966-2-1 matrix (written out here). Same arithmetic, another code path: 1e-12."""
    nm = SAMPLINGS["16 uneven"]
    v = np.stack(list(_spectra(nm).values()))                          # (4, 16)
    xyz_a = mc.to_xyz(nm, v, "A")
    white_a = mc.to_xyz(nm, np.ones_like(nm), "A")
    want = colour.XYZ_to_RGB(xyz_a, colour.RGB_COLOURSPACES["sRGB"],
                             illuminant=colour.XYZ_to_xy(white_a),
                             chromatic_adaptation_transform="CAT02")
    np.testing.assert_allclose(mc.to_srgb_linear(nm, v, "A"), want, rtol=0, atol=1e-12)
    iec = np.array([[3.2406, -1.5372, -0.4986],
                    [-0.9689, 1.8758, 0.0415],
                    [0.0557, -0.2040, 1.0570]])
    np.testing.assert_allclose(mc.to_srgb_linear(nm, v), mc.to_xyz(nm, v) @ iec.T,
                               rtol=0, atol=1e-12)


def test_display_encoding_clips_then_applies_the_srgb_curve() -> None:
    """Grey spectra of constant value g: linear sRGB ≈ g (white is ≈ 1, to 2e-4 for
    D65's rounded matrix), display = the IEC 61966-2-1 curve written out here, after
    clipping: g = 2 (a BRDF can exceed 1) gives 1, g = −0.1 gives 0."""
    nm = SAMPLINGS["32 uniform"]
    g = np.array([-0.1, 0.0, 0.002, 0.2, 0.5, 0.9, 2.0])
    greys = g[:, None] * np.ones((1, nm.size))
    lin = mc.to_srgb_linear(nm, greys)
    np.testing.assert_allclose(lin, g[:, None] * np.ones((1, 3)), rtol=3e-4, atol=1e-12)
    x = np.clip(lin, 0.0, 1.0)
    curve = np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)
    np.testing.assert_allclose(mc.to_srgb_display(nm, greys), curve, rtol=0, atol=1e-12)
    np.testing.assert_allclose(mc.to_srgb_display(nm, greys)[[0, -1]], [[0.0] * 3, [1.0] * 3],
                               rtol=0, atol=1e-12)


def test_linear_in_the_values_and_broadcasts_over_leading_axes() -> None:
    """to_xyz(a + b) = to_xyz(a) + to_xyz(b), to_xyz(s a) = s to_xyz(a), for tables of
    shape (2, 3, C); luminance is the Y column; round-off only (1e-12)."""
    rng = np.random.default_rng(1)
    nm = SAMPLINGS["16 uneven"]
    a = rng.uniform(0.0, 1.0, (2, 3, nm.size))
    b = rng.uniform(0.0, 1.0, (2, 3, nm.size))
    xa, xb = mc.to_xyz(nm, a), mc.to_xyz(nm, b)
    assert xa.shape == (2, 3, 3)
    np.testing.assert_allclose(mc.to_xyz(nm, a + b), xa + xb, rtol=0, atol=1e-12)
    np.testing.assert_allclose(mc.to_xyz(nm, 2.5 * a), 2.5 * xa, rtol=0, atol=1e-12)
    y = mc.luminance(nm, a)
    assert y.shape == (2, 3)
    np.testing.assert_allclose(y, xa[..., 1], rtol=0, atol=1e-15)
    assert mc.to_srgb_linear(nm, a).shape == mc.to_srgb_display(nm, a).shape == (2, 3, 3)


def test_weights_are_cached_read_only_and_white_has_y_one() -> None:
    nm = SAMPLINGS["16 uniform"]
    w = mc.xyz_weights(nm)
    assert w.shape == (16, 3)
    assert mc.xyz_weights(list(nm)) is w        # one matrix per (wavelengths, illuminant)
    assert mc.xyz_weights(nm, "D50") is not w
    assert not w.flags.writeable
    assert abs(w[:, 1].sum() - 1.0) <= 1e-12
    w10 = mc.xyz_weights(nm, cmfs="CIE 1964 10 Degree Standard Observer")
    assert abs(w10[:, 1].sum() - 1.0) <= 1e-12 and np.abs(w10 - w).max() > 1e-3


def test_weights_do_not_depend_on_colour_sciences_domain_range_scale() -> None:
    """colour-science returns XYZ in 0–100 or 0–1 depending on a global setting; the
    weights are normalised by the white's Y, so either gives Y = 1 for white. (Fresh
    wavelengths, so the cache is cold.)"""
    nm = np.array([401.0, 503.0, 607.0, 709.0])
    with colour.domain_range_scale("1"):
        w = mc.xyz_weights(nm)
    assert abs(w[:, 1].sum() - 1.0) <= 1e-12
    np.testing.assert_allclose(w.sum(axis=0), CIE_WHITES["D65"], rtol=0, atol=1e-3)


def test_the_module_imports_colour_science_not_itself() -> None:
    """``import colour`` inside microsim/spectra/colour.py is the colour-science package
    (absolute imports), not the module itself."""
    assert mc.colour is colour and mc.colour is not mc
    assert set(mc.ILLUMINANTS) >= {"D65", "D50", "A", "E"}


NM = np.linspace(400.0, 700.0, 4)


@pytest.mark.parametrize(("call", "message"), [
    (lambda: mc.xyz_weights([]), r"wavelengths of shape \(0,\): must be a non-empty 1-D"),
    (lambda: mc.xyz_weights([[400.0, 500.0]]), r"wavelengths of shape \(1, 2\): must be a non-empty 1-D"),
    (lambda: mc.xyz_weights([500.0, 400.0]), r"wavelengths = \[500.0, 400.0\]: must be strictly increasing"),
    (lambda: mc.xyz_weights([400.0, 400.0]), r"must be strictly increasing"),
    (lambda: mc.xyz_weights([0.0, 400.0]), r"wavelengths = \[0.0, 400.0\]: must be finite and > 0 nm"),
    (lambda: mc.xyz_weights([-5.0, 400.0]), r"must be finite and > 0 nm"),
    (lambda: mc.xyz_weights([400.0, np.nan]), r"must be finite and > 0 nm"),
    (lambda: mc.xyz_weights(["red", "blue"]), r"wavelengths = \['red', 'blue'\]: must be numbers in nm"),
    (lambda: mc.xyz_weights(NM, "D63"), r"illuminant = 'D63': must be one of D65, D50, D55, D75, A, E"),
    (lambda: mc.to_xyz(NM, np.ones(4), "F2"), r"illuminant = 'F2': must be one of D65, D50"),
    (lambda: mc.to_srgb_linear(NM, np.ones(4), "d65"), r"illuminant = 'd65': must be one of"),
    (lambda: mc.xyz_weights(NM, cmfs="CIE 2015 2 Degree"), r"cmfs = 'CIE 2015 2 Degree': must be one of CIE 1931 2 Degree"),
    (lambda: mc.to_xyz(NM, np.ones(5)), r"values of shape \(5,\): the last axis must have one entry per wavelength \(4\)"),
    (lambda: mc.luminance(NM, 1.0), r"values of shape \(\): the last axis must have one entry per wavelength"),
    (lambda: mc.to_srgb_display([], np.ones(0)), r"wavelengths of shape \(0,\)"),
])
def test_bad_input_is_an_input_error_naming_the_key(call, message: str) -> None:
    with pytest.raises(InputError, match=message):
        call()


def test_importing_leaves_numpys_printing_as_it_was() -> None:
    """colour-science sets numpy's legacy (1.13) printing when imported; importing
    ``microsim.spectra.colour`` in a fresh interpreter leaves the caller's printing alone
    (an array prints as numpy prints it, without legacy's sign padding)."""
    import subprocess
    import sys

    code = ("import numpy as np; before = np.get_printoptions(); "
            "import microsim.spectra.colour; print(np.get_printoptions() == before, "
            "repr(str(np.array([0.5, 1.0]))))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "True '[0.5 1. ]'"
