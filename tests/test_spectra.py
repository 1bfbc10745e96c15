"""Spectra: tabulated spectra and dispersion formulas against published numbers typed in
here from the sources (not read from the shipped files), interpolation against an
independent implementation, the shipped files' own rules, and the recipe parser's errors."""

from __future__ import annotations

import bisect
import json
import math
import subprocess
import sys
from importlib import resources

import numpy as np
import pytest
from scipy.special import wofz

from microsim.errors import InputError
from microsim.spectra.dispersion import Cauchy, Dispersion, Sellmeier, spectral_from_json
from microsim.spectra.measured import conductor, dielectric, names, reflectance
from microsim.spectra.spectrum import Spectrum, parse_spectrum

HC_EV_NM = 1239.84193
"""h c in eV nm (CODATA), to turn photon energies into wavelengths."""


# --- dispersion formulas against the glass makers' and Malitson's numbers ----------------

def test_bk7_d_line_is_schotts_nd():
    """SCHOTT's N-BK7 data sheet: n_d = 1.5168 at the helium d line, 587.56 nm. The
    datasheet quotes n_d to 4 decimals, hence the 1e-4 tolerance."""
    n = dielectric("BK7").at(np.array([587.56]))
    assert n.shape == (1,)
    assert abs(n[0] - 1.5168) < 1e-4


def test_fused_silica_at_587_6_is_malitsons():
    """Malitson 1965 (J. Opt. Soc. Am. 55, 1205), 20 °C: n = 1.4585 at 0.5876 µm (his
    table, 1.45846; the formula fits his measurements to about 1e-5)."""
    assert abs(float(dielectric("fused_silica").at(587.6)) - 1.4585) < 1e-4


def test_sellmeier_against_the_formula_written_out():
    """BK7 at 486.13 nm (F line) and 656.27 nm (C line) from the Sellmeier sum written out
    here with SCHOTT's coefficients, and the dispersion of the data sheet: Abbe number
    v_d = (n_d − 1)/(n_F − n_C) = 64.17 (datasheet, two decimals: tolerance 0.02)."""
    b = (1.03961212, 0.231792344, 1.01046945)
    c = (0.00600069867, 0.0200179144, 103.560653)

    def n(um):
        return math.sqrt(1 + sum(bi * um**2 / (um**2 - ci) for bi, ci in zip(b, c, strict=True)))

    bk7 = dielectric("bk7")
    n_f, n_c = bk7.at([486.13, 656.27])
    assert n_f == pytest.approx(n(0.48613), abs=1e-12)
    assert n_c == pytest.approx(n(0.65627), abs=1e-12)
    v_d = (float(bk7.at(587.56)) - 1) / (n_f - n_c)
    assert abs(v_d - 64.17) < 0.02


def test_cauchy_against_its_formula():
    """n = A + B/λ² + C/λ⁴ with λ in µm, by hand: at 0.5 µm, 1.5046 + 0.0042/0.25 + 1e-4/0.0625."""
    glass = Cauchy(1.5046, 0.0042, 1e-4, (400.0, 700.0), "test coefficients")
    assert float(glass.at(500.0)) == pytest.approx(1.5046 + 0.0168 + 0.0016, abs=1e-12)
    with pytest.raises(InputError, match=r"800 nm asked for, outside 400-700 nm.*test coeff"):
        glass.at([500.0, 800.0])


@pytest.mark.parametrize("name", ["BK7", "fused_silica"])
def test_dispersion_outside_its_range_names_range_and_source(name):
    lo, hi = dielectric(name).nm_range
    with pytest.raises(InputError, match=rf"{lo:g}-{hi:g} nm.*(SCHOTT|Malitson)"):
        dielectric(name).at([lo - 1.0])
    dielectric(name).at([lo, hi])  # the ends are inside


def test_sellmeier_rejects_a_resonance_inside_its_range():
    with pytest.raises(InputError, match="resonance at 500 nm lies inside"):
        Sellmeier((1.0,), (0.25,), (400.0, 700.0), "test")


# --- interpolation ----------------------------------------------------------------------

def _interp_reference(nm, value, x):
    """Linear interpolation written out: find the interval by bisection, blend its ends."""
    i = bisect.bisect_right(nm, x) - 1
    if i == len(nm) - 1:
        return value[-1]
    t = (x - nm[i]) / (nm[i + 1] - nm[i])
    return (1 - t) * value[i] + t * value[i + 1]


def test_interpolation_exact_at_nodes_and_linear_between():
    rng = np.random.default_rng(20240611)
    nm = tuple(np.cumsum(rng.uniform(0.5, 20.0, 40)) + 300.0)
    value = tuple(rng.normal(size=40))
    s = Spectrum(nm, value, "random test spectrum")
    assert np.array_equal(s.at(np.array(nm)), np.array(value))  # bit-exact at the nodes
    x = rng.uniform(nm[0], nm[-1], 500)
    expected = [_interp_reference(nm, value, xi) for xi in x]
    np.testing.assert_allclose(s.at(x), expected, rtol=0, atol=1e-12)
    assert s.at(np.zeros((0,))).shape == (0,)
    assert s.at(np.array(nm).reshape(4, 10)).shape == (4, 10)


def test_one_point_spectrum_is_constant():
    s = Spectrum((550.0,), (0.3,), "constant")
    np.testing.assert_array_equal(s.at([200.0, 550.0, 2000.0]), [0.3, 0.3, 0.3])
    assert s.nm_range == (0.0, math.inf)


def test_outside_the_range_names_range_and_source():
    s = Spectrum((400.0, 500.0, 600.0), (1.0, 2.0, 3.0), "Some et al. 2001")
    with pytest.raises(InputError, match=r"^material\.eta: 650 nm asked for, outside "
                                         r"400-600 nm, the range of Some et al\. 2001"):
        s.at([450.0, 650.0], where="material.eta")
    with pytest.raises(InputError, match="finite"):
        s.at([float("nan")])


# --- the shipped conductors -------------------------------------------------------------

def _raw_file(name):
    """A shipped file read here, apart from the package's reader: its text's '# range:'
    line and its numbers."""
    text = resources.files("microsim.spectra").joinpath("data", name).read_text("utf-8")
    stated = [line for line in text.splitlines() if line.startswith("# range:")]
    assert len(stated) == 1, f"{name}: one '# range:' line"
    lo, hi = stated[0].removeprefix("# range:").removesuffix("nm").split("-")
    assert any(line.startswith("# source:") and len(line) > 40 for line in text.splitlines())
    assert any(line.startswith("# units:") for line in text.splitlines())
    lines = [line for line in text.splitlines() if line.strip() and not line.startswith("#")]
    header = lines[0].split(",")
    rows = np.array([[float(cell) for cell in line.split(",")] for line in lines[1:]])
    return float(lo), float(hi), header, rows


@pytest.mark.parametrize("name", ["Ag", "Al", "Au", "Cr", "Cu"])
def test_every_conductor_file(name):
    """Parses; covers its stated range and at least the CIE visible 360–830 nm; η > 0,
    k ≥ 0; strictly increasing wavelengths; the registry returns the file's numbers."""
    lo, hi, header, rows = _raw_file(f"{name}.csv")
    assert list(header) == ["nm", "eta", "k"]
    nm, eta, k = rows.T
    assert nm[0] == lo and nm[-1] == hi
    assert lo <= 360.0 and hi >= 830.0
    assert np.all(np.diff(nm) > 0)
    assert np.all(eta > 0) and np.all(k >= 0)
    s_eta, s_k = conductor(name)
    assert s_eta.nm == tuple(nm) and s_eta.value == tuple(eta) and s_k.value == tuple(k)
    assert s_eta.nm_range == (lo, hi)
    assert f"data/{name}.csv" in s_eta.source
    assert ("Johnson" in s_eta.source) or ("Rakic" in s_eta.source)
    visible = np.linspace(360.0, 830.0, 95)
    assert np.all(s_eta.at(visible) > 0) and np.all(s_k.at(visible) > 0)


# Johnson & Christy 1972, Phys. Rev. B 6, 4370, Table I (photon energy E in eV, n, k);
# the wavelength is h c / E. Typed in from the published table.
JOHNSON_CHRISTY = [
    ("Au", 2.01, 0.21, 3.272),
    ("Au", 2.50, 1.04, 1.833),
    ("Au", 1.64, 0.14, 4.542),
    ("Ag", 2.26, 0.06, 3.586),
    ("Ag", 1.64, 0.03, 5.242),
    ("Cu", 1.88, 0.22, 3.747),
    ("Cu", 2.26, 1.02, 2.577),
]


@pytest.mark.parametrize("metal, ev, n, k", JOHNSON_CHRISTY)
def test_johnson_christy_spot_values(metal, ev, n, k):
    """At the table's own points (wavelength h c / E rounded to 0.1 nm, as the shipped
    rows are): the printed n and k, exactly (to float round-off)."""
    eta_s, k_s = conductor(metal)
    nm = round(HC_EV_NM / ev, 1)
    assert abs(float(eta_s.at(nm)) - n) < 1e-12
    assert abs(float(k_s.at(nm)) - k) < 1e-12


# Rakić 1995, Appl. Opt. 34, 4755: tabulated n, k of aluminium at photon energies (eV).
RAKIC_AL = [(2.0, 1.3660, 7.4052), (1.52, 2.7668, 8.2573), (3.0, 0.52135, 5.0008)]


@pytest.mark.parametrize("ev, n, k", RAKIC_AL)
def test_rakic_aluminium_spot_values(ev, n, k):
    """The table's rows (wavelength h c / E to the table's five digits in µm, so a 2e-5
    relative shift at most: tolerance 1e-3 relative, far below the 5-8 % steps between
    rows)."""
    eta_s, k_s = conductor("Al")
    nm = HC_EV_NM / ev
    assert float(eta_s.at(nm)) == pytest.approx(n, rel=1e-3)
    assert float(k_s.at(nm)) == pytest.approx(k, rel=1e-3)


def _brendel_bormann_cr(ev):
    """Rakić et al. 1998 (Appl. Opt. 37, 5271), eqs. 11-14 and Table 3 (Cr, BB model):
    ε(ω) = 1 − Ωp²/(ω(ω + iΓ0)) + Σ_j χ_j(ω), Ωp = √f0 ωp,
    χ_j = i √π f_j ωp² / (2√2 a_j σ_j) [w((a_j − ω_j)/(√2 σ_j)) + w((a_j + ω_j)/(√2 σ_j))],
    a_j = √(ω² + iωΓ_j), w the Faddeeva function; n + ik = √ε. Written here from the
    paper's parameters, independently of the shipped table."""
    wp, f0, g0 = 10.75, 0.154, 0.048
    oscillators = [(0.338, 4.256, 0.281, 0.115), (0.261, 3.957, 0.584, 0.252),
                   (0.817, 2.218, 1.919, 0.225), (0.105, 6.983, 6.997, 4.903)]
    eps = 1 - f0 * wp**2 / (ev * (ev + 1j * g0))
    for f, gamma, w0, sigma in oscillators:
        a = np.sqrt(ev**2 + 1j * ev * gamma)
        z = np.sqrt(2) * sigma
        eps = eps + (1j * np.sqrt(np.pi) * f * wp**2 / (2 * np.sqrt(2) * a * sigma)
                     * (wofz((a - w0) / z) + wofz((a + w0) / z)))
    return np.sqrt(eps)


def test_chromium_against_the_brendel_bormann_model():
    """Across 360–830 nm (also between the table's points, 2.8 % apart): the shipped table
    against the model evaluated here. Its rows carry five digits and linear interpolation
    between them errs by at most 2.6e-4 relative (measured); tolerance 1e-3 relative."""
    nm = np.linspace(360.0, 830.0, 95)
    ref = _brendel_bormann_cr(HC_EV_NM / nm)
    eta_s, k_s = conductor("Cr")
    np.testing.assert_allclose(eta_s.at(nm), ref.real, rtol=1e-3)
    np.testing.assert_allclose(k_s.at(nm), ref.imag, rtol=1e-3)


def test_gold_normal_incidence_reflectance_at_650nm():
    """R = ((η − 1)² + k²)/((η + 1)² + k²) at normal incidence (Born & Wolf, sec. 14.2).
    Published opaque gold at 650 nm lies near 0.95: from the gold n, k pbrt-v4 tabulates
    (src/pbrt/util/spectrum.cpp, 652.5 nm: 0.166, 3.15) R = 0.941; from Yakubovsky et al.
    2017 (Opt. Express 25, 25574; 117 nm film at 650 nm: 0.1433, 3.703) R = 0.962. Johnson
    & Christy must land inside that spread of samples: 0.95 ± 0.015."""
    eta_s, k_s = conductor("Au")
    n, k = float(eta_s.at(650.0)), float(k_s.at(650.0))
    r = ((n - 1) ** 2 + k**2) / ((n + 1) ** 2 + k**2)
    assert abs(r - 0.95) < 0.015
    # and gold is yellow: it reflects red far better than blue (J&C: R(450) ≈ 0.41)
    n4, k4 = float(eta_s.at(450.0)), float(k_s.at(450.0))
    assert ((n4 - 1) ** 2 + k4**2) / ((n4 + 1) ** 2 + k4**2) < 0.45


def test_a_conductors_indices_in_a_spectral_table_are_its_measured_metals():
    """In a spectral table a conductor left at its default (gold's R, G, B) is the shipped
    measured gold, ``data`` names another shipped metal, and given numbers are the same in
    every channel; each column is the spectrum sampled at the table's wavelengths. In an
    RGB table the default is gold's triple."""
    from microsim.materials import Conductor
    from microsim.spectra.channels import RGB, Channels

    nm = (450.0, 600.0, 650.0)
    channels = Channels(nm)
    for material, metal in ((Conductor(), "Au"), (Conductor(data="Ag"), "Ag"),
                            (Conductor(data="cu"), "Cu")):
        eta, k = material.parameters(channels)
        eta_s, k_s = conductor(metal)
        assert eta == tuple(eta_s.at(nm)) and k == tuple(k_s.at(nm)), metal
    assert Conductor(eta=0.5, k=2.0).parameters(channels) == ((0.5,) * 3, (2.0,) * 3)
    assert Conductor().parameters(RGB) == ((0.2, 0.92, 1.1), (3.9, 2.45, 2.14))


def test_a_materials_sources_cite_each_spectrum_it_samples():
    """``sources`` names, by key, the citation of every spectrum a material samples: its
    shipped ``data`` (Johnson & Christy's gold, SCHOTT's BK7, BabelColor's ColorChecker),
    a given spectrum's ``source``, a coating's index as ``coating.eta``; nothing for
    numbers, a number's coating, or a kind without keys."""
    from microsim.materials import Black, Conductor, Dielectric, Lambertian, Mirror
    from microsim.materials.coating import Coating

    film = Spectrum((400.0, 700.0), (2.0, 2.1), "a film of the test")
    albedo = Spectrum((400.0, 700.0), (0.2, 0.4), "an albedo of the test")
    gold = Conductor(data="Au", coating=Coating(90.0, film)).sources()
    assert set(gold) == {"data", "coating.eta"} and gold["coating.eta"] == "a film of the test"
    assert "Johnson and R. W. Christy" in gold["data"]
    glass = Dielectric(data="BK7", absorption=albedo).sources()
    assert set(glass) == {"data", "absorption"} and "SCHOTT" in glass["data"]
    assert glass["absorption"] == "an albedo of the test"
    patch = Lambertian(data="colorchecker_green").sources()
    assert set(patch) == {"data"} and "BabelColor" in patch["data"]
    assert Lambertian(albedo=albedo).sources() == {"albedo": "an albedo of the test"}
    for bare in (Lambertian(), Conductor(eta=0.5, k=2.0, coating=Coating(90.0, 1.45)),
                 Dielectric(), Black(), Mirror()):
        assert bare.sources() == {}, bare


# --- reflectances -----------------------------------------------------------------------

def test_colorchecker_patches():
    """BabelColor's average (typed in from colour-science's copy): red at 380 and 730 nm,
    white 9.5 at 550 nm, blue at 450 nm; every patch a fraction in [0, 1] on 380–730 nm."""
    assert len(names("reflectance")) == 10
    red = reflectance("colorchecker_red")
    assert float(red.at(380.0)) == 0.050 and float(red.at(730.0)) == 0.738
    assert float(reflectance("colorchecker_white_9_5").at(550.0)) == 0.914
    assert float(reflectance("colorchecker_blue").at(450.0)) == 0.309
    lo, hi, header, rows = _raw_file("colorchecker.csv")
    assert (lo, hi) == (380.0, 730.0) and list(header[1:]) == list(names("reflectance"))
    for name in names("reflectance"):
        v = reflectance(name).at(np.arange(380.0, 731.0, 5.0))
        assert np.all((v >= 0) & (v <= 1)), name
    assert "BabelColor" in red.source and "Pascale" in red.source


# --- the registry -----------------------------------------------------------------------

@pytest.mark.parametrize("lookup, kind", [(conductor, "conductor"), (dielectric, "dielectric"),
                                          (reflectance, "reflectance")])
def test_unknown_name_lists_the_shipped_ones(lookup, kind):
    with pytest.raises(InputError) as info:
        lookup("unobtainium", where="material.name")
    message = str(info.value)
    assert message.startswith("material.name = 'unobtainium'")
    for shipped in names(kind):
        assert shipped in message


def test_names_and_case():
    assert names("conductor") == ("Ag", "Al", "Au", "Cr", "Cu")
    assert names("dielectric") == ("fused_silica", "BK7")
    assert conductor("au") is conductor("Au")  # cached, case-insensitive
    with pytest.raises(InputError, match="conductor, dielectric, reflectance"):
        names("metal")


def test_no_heavy_imports_and_lazy_reading():
    """microsim check imports materials, which import the spectra: only numpy may come, and
    no data file is read until asked for."""
    code = ("import sys, microsim.spectra.measured as m; print(m._read.cache_info().currsize); "
            "m.conductor('Au'); m.reflectance('colorchecker_red'); "
            "print(m._read.cache_info().currsize); "
            "print(','.join(x for x in ('scipy', 'colour', 'numba', 'matplotlib') "
            "if x in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.split("\n")[:3] == ["0", "2", ""]


# --- the recipe parser and JSON ---------------------------------------------------------

def test_parse_spectrum_good():
    s = parse_spectrum({"nm": [400, 500.5], "value": [1, 2.5]}, "material.eta")
    assert s.nm == (400.0, 500.5) and s.value == (1.0, 2.5)
    assert "material.eta" in s.source
    s = parse_spectrum({"nm": [550], "value": [0.4], "source": "me"}, "x")
    assert s.source == "me"


BAD = [
    ([400, 500], "a spectrum is a table"),
    ("gold", "a spectrum is a table"),
    ({"value": [1]}, "missing key 'nm'"),
    ({"nm": [400]}, "missing key 'value'"),
    ({"nm": [400], "value": [1], "values": [1]}, r"\.values: unknown key"),
    ({"nm": [], "value": []}, r"\.nm: empty list"),
    ({"nm": 400, "value": [1]}, r"\.nm = 400: must be a list"),
    ({"nm": [400, "500"], "value": [1, 2]}, r"\.nm\[1\] = '500': not a number"),
    ({"nm": [400, True], "value": [1, 2]}, r"\.nm\[1\] = True: not a number"),
    ({"nm": [400, 500], "value": [1, float("nan")]}, r"\.value\[1\] = nan: must be finite"),
    ({"nm": [400, float("inf")], "value": [1, 2]}, r"\.nm\[1\] = inf: must be finite"),
    ({"nm": [500, 400], "value": [1, 2]}, r"\.nm\[1\] = 400 follows nm\[0\] = 500: .*"
                                          "strictly increasing"),
    ({"nm": [400, 400], "value": [1, 2]}, "strictly increasing"),
    ({"nm": [400, 500], "value": [1]}, "nm has 2 entries and value 1"),
    ({"nm": [0, 500], "value": [1, 2]}, r"\.nm\[0\] = 0: .*must be > 0"),
    ({"nm": [-5], "value": [1]}, r"\.nm\[0\] = -5: .*must be > 0"),
    ({"nm": [400], "value": [1], "source": ""}, r"\.source = '': must be a non-empty"),
]


@pytest.mark.parametrize("raw, message", BAD)
def test_parse_spectrum_bad(raw, message):
    """Every message starts with the key path and says what is allowed."""
    with pytest.raises(InputError, match=message) as info:
        parse_spectrum(raw, "material.eta")
    assert str(info.value).startswith("material.eta")


def test_json_round_trips():
    eta, _ = conductor("Cu")
    for thing in (eta, dielectric("BK7"), dielectric("fused_silica"),
                  Cauchy(1.45, 0.0036, 0.0, (380.0, 780.0), "test")):
        data = thing.to_json()
        back = spectral_from_json(json.loads(json.dumps(data)))
        assert back == thing
        assert type(back).from_json(data) == thing
    assert isinstance(Dispersion.from_json(dielectric("BK7").to_json()), Sellmeier)


@pytest.mark.parametrize("data, message", [
    ({"kind": "tabulated", "nm": [1], "value": [1]}, "missing key 'source'"),
    ({"kind": "spline"}, "kind = tabulated, sellmeier or cauchy"),
    ({"kind": "sellmeier", "b": [1], "c": [0.01], "source": "s"}, "missing key 'nm_range'"),
    ({"kind": "cauchy", "a": 1.5, "b": 0, "c": 0, "nm_range": [700, 400], "source": "s"},
     r"nm_range = \[700, 400\]: must be \[lo, hi\]"),
    ({"kind": "cauchy", "a": "x", "b": 0, "c": 0, "nm_range": [400, 700], "source": "s"},
     r"\.a = 'x': not a number"),
    ({"kind": "sellmeier", "b": [1], "c": [0.01], "nm_range": [400, 700], "source": "s",
      "d": 1}, r"\.d: unknown key"),
])
def test_from_json_bad(data, message):
    with pytest.raises(InputError, match=message) as info:
        spectral_from_json(data, "table.metadata.eta")
    assert str(info.value).startswith("table.metadata.eta")
