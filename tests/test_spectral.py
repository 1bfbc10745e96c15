"""Spectral tables: one channel per wavelength, each material key sampled from its
spectrum there, checked against exact optics and independent runs (docs/spectral.md)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.stats import chi2

import microsim
from microsim.analytic.fresnel import fresnel_conductor, fresnel_thin_film
from microsim.comparison.agreement import agreement
from microsim.comparison.metrics import compare_table
from microsim.comparison.table_models import microfacet_model
from microsim.errors import InputError
from microsim.spectra import measured
from microsim.spectra.channels import Channels
from microsim.tables.table import BRDFTable

NM16 = [float(x) for x in np.linspace(400.0, 700.0, 16)]
"""Sixteen wavelengths across the visible, nm."""
FLAT_THETA = [0.0, 20.0, 45.0, 60.0, 75.0, 85.0]


def _flat(material: dict, nm: list[float], **table: object) -> BRDFTable:
    return microsim.simulate(microsim.load_recipe({
        "surface": {"kind": "flat"}, "material": material,
        "table": {"wavelengths": nm, "theta_bins": 4, "phi_bins": 4, "sh_order": 0,
                  **table},
        "simulation": {"theta_i": FLAT_THETA, "rays": 64}}), threads=1)


@pytest.mark.parametrize("metal", measured.names("conductor"))
def test_flat_conductor_albedo_is_the_exact_fresnel_of_its_measured_indices(
        metal: str) -> None:
    """A flat shipped metal reflects every ray once with weight F(θi, λ) per channel: its
    albedo is the exact Fresnel reflectance of the shipped η(λ), k(λ) at each wavelength,
    computed here by the complex Born & Wolf form (``microsim.analytic.fresnel``), not the
    kernel's real-arithmetic one; 1e-6 is far above their round-off (~1e-14) and far below
    any error of a sampled index (η at 550 instead of 560 nm moves F by ~1e-2)."""
    table = _flat({"kind": "conductor", "data": metal}, NM16)
    assert table.channels == Channels(tuple(NM16))
    eta, k = measured.conductor(metal)
    theta = np.radians(FLAT_THETA)[:, None]
    exact = fresnel_conductor(np.cos(theta), eta.at(NM16), k.at(NM16))
    np.testing.assert_allclose(table.albedo[:, 0], exact, rtol=0, atol=1e-6)
    np.testing.assert_allclose(table.lost_energy, 0.0, atol=1e-12)


def test_a_spectral_table_of_three_wavelengths_equals_the_rgb_table_bit_for_bit() -> None:
    """The channels are one axis whatever they are: a spectral table whose spectra take at
    its three wavelengths the RGB table's three numbers is that table, bit for bit (same
    rays, same random numbers, same sums), on a rough conductor with multiple bounces."""
    recipe = {"surface": {"kind": "gaussian", "alpha": 0.5, "resolution": 32},
              "simulation": {"theta_i": [0, 60], "rays": 4000, "realisations": 2},
              "table": {"theta_bins": 8, "phi_bins": 8, "sh_order": 4}}
    eta, k, nm = [0.2, 0.92, 1.1], [3.9, 2.45, 2.14], [450.0, 550.0, 650.0]
    rgb = microsim.simulate(microsim.load_recipe(
        {**recipe, "material": {"kind": "conductor", "eta": eta, "k": k}}), threads=1)
    spectral = microsim.simulate(microsim.load_recipe(
        {**recipe, "table": {**recipe["table"], "wavelengths": nm},
         "material": {"kind": "conductor", "eta": {"nm": nm, "value": eta},
                      "k": {"nm": nm, "value": k}}}), threads=1)
    for c in rgb.components:
        assert np.array_equal(rgb[c].values, spectral[c].values)
        assert np.array_equal(rgb[c].errors, spectral[c].errors, equal_nan=True)
        assert np.array_equal(rgb[c].sh, spectral[c].sh, equal_nan=True)
    assert rgb.channels.names == ("R", "G", "B")
    assert spectral.channels.names == ("450nm", "550nm", "650nm")


def test_spectral_gold_agrees_with_torrance_sparrow_per_wavelength() -> None:
    """A Gaussian gold surface (α 0.3, 16 wavelengths, an ensemble of 8 tiles) agrees with
    Torrance-Sparrow + height-correlated Smith at its realised roughness with the
    spectral Fresnel of the shipped indices at every wavelength: the agreement verdict
    (z mean and spread over the lobe bins at significance 0.001) on single scattering."""
    table = microsim.simulate(microsim.load_recipe({
        "surface": {"kind": "gaussian", "alpha": 0.3, "resolution": 128},
        "material": {"kind": "conductor", "data": "Au"},
        "table": {"wavelengths": NM16, "theta_bins": 16, "phi_bins": 32, "sh_order": 0},
        "simulation": {"theta_i": [0, 30, 60], "rays": 200_000, "realisations": 8}}))
    model = microfacet_model(table.meta)
    eta, k = measured.conductor("Au")
    np.testing.assert_array_equal(model.fresnel.eta, eta.at(NM16))
    np.testing.assert_array_equal(model.fresnel.k, k.at(NM16))
    result = compare_table(table, model, "single")
    assert agreement(result).agrees, (result.z_mean, result.z_std)
    # the wavelengths differ: gold's albedo at normal incidence rises from blue to red
    albedo = table["single"].albedo[0, 0]
    assert albedo[-1] > 2.0 * albedo[0]


def _dielectric(nm: list[float], seed: int, rays: int = 480_000) -> BRDFTable:
    """A rough refracting BK7 surface at 30°: about 5 % of the light escapes upwards
    (reflected, or refracted back out), so each wavelength's lobe needs many rays."""
    return microsim.simulate(microsim.load_recipe({
        "surface": {"kind": "gaussian", "alpha": 0.4, "resolution": 32, "seed": seed},
        "material": {"kind": "dielectric", "data": "BK7", "refract": True},
        "table": {"wavelengths": nm, "theta_bins": 4, "phi_bins": 6, "sh_order": 0},
        "simulation": {"theta_i": [30], "rays": rays, "realisations": 4,
                       "seed": seed}}), threads=1)


def test_hero_wavelength_channels_equal_single_wavelength_runs() -> None:
    """A dispersive rough dielectric (BK7, refracting) traced with hero wavelengths: each
    channel's values equal an independent run at that wavelength alone (no dispersion
    there: one channel) within both error bars. χ² of (a − b)² / (σa² + σb²) over the
    lobe bins of each wavelength below its 0.999 quantile (the runs are independent:
    other seeds)."""
    nm = [420.0, 520.0, 620.0, 720.0]
    spectral = _dielectric(nm, 1)
    assert spectral.channels.count == 4
    for j, wavelength in enumerate(nm):
        single = _dielectric([wavelength], 2)
        a, sa = spectral["total"].values[..., j], spectral["total"].errors[..., j]
        b, sb = single["total"].values[..., 0], single["total"].errors[..., 0]
        lobe = b >= 0.1 * b.max()
        chi = ((a - b) ** 2 / (sa**2 + sb**2))[lobe]
        assert chi.sum() < chi2.ppf(0.999, lobe.sum()), (wavelength, chi.sum(), lobe.sum())


def test_hero_wavelength_furnace_closes_per_wavelength() -> None:
    """White furnace of a lossless dispersive dielectric per wavelength: what escapes, is
    transmitted and is lost adds up to 1 per channel in expectation. A refraction leaves
    a path its hero alone (weight × C); a reflection keeps every channel with weight
    F_c / F_hero, so no single run closes exactly: over 8 independent runs the mean of
    (albedo + lost + transmitted − 1) lies within 4.5 of its standard errors of 0 at
    every wavelength (two-sided, about 1e-5 per comparison), and the runs do scatter
    (the closure is statistical)."""
    nm = [420.0, 570.0, 720.0]
    sums = []
    for seed in range(8):
        record = _dielectric(nm, 10 + seed, 12_000).meta.directions[0]
        sums.append(np.asarray(record.albedo) + np.asarray(record.lost)
                    + np.asarray(record.transmitted) - 1.0)
    sums = np.array(sums)
    mean, se = sums.mean(axis=0), sums.std(axis=0, ddof=1) / np.sqrt(len(sums))
    assert np.all(np.abs(mean) <= 4.5 * se), (mean, se)
    assert np.all(se > 1e-6)


def test_dispersive_reflections_keep_every_wavelength() -> None:
    """A reflection off a dispersive glass has every wavelength's direction, so it keeps
    every channel (weighted F_c / F_hero); only refractions leave a path its hero. A flat
    refracting BK7 surface reflects each ray at most once and refracts the rest out
    through the bottom: each ray adds F_c / F_h to channel c with probability F_h (h its
    hero, uniform over the C channels), a variance of F_c² (mean_h 1/F_h − 1) per ray, so
    every channel's albedo has the error of all N rays. χ² of the 12 z-scores (4
    wavelengths, 3 incidences) against the exact Fresnel reflectance of BK7 stays below
    its 0.999 quantile; ending the other channels at reflections too (pbrt-v4's way) has
    C = 4 times the variance and fails it."""
    nm = [400.0, 500.0, 600.0, 700.0]
    rays = 40_000
    table = microsim.simulate(microsim.load_recipe({
        "surface": {"kind": "flat"},
        "material": {"kind": "dielectric", "data": "BK7", "refract": True},
        "table": {"wavelengths": nm, "theta_bins": 4, "phi_bins": 4, "sh_order": 0},
        "simulation": {"theta_i": [0.0, 60.0, 80.0], "rays": rays}}), threads=1)
    cos = np.cos(np.radians([0.0, 60.0, 80.0]))[:, None]
    exact = fresnel_conductor(cos, measured.dielectric("BK7").at(nm), 0.0)
    spread = (1.0 / exact).mean(axis=1, keepdims=True) - 1.0
    z = (table.albedo[:, 0] - exact) / (exact * np.sqrt(spread / rays))
    assert (z**2).sum() < chi2.ppf(0.999, z.size), z


def test_spectral_table_round_trips_through_its_file(tmp_path) -> None:
    """A spectral table's file holds its wavelengths and one channel per wavelength
    (``total.552p5nm``, …); reading it gives the same channels and values."""
    nm = [450.0, 552.5, 650.0]
    table = _flat({"kind": "conductor", "data": "Cu"}, nm, sh_order=2)
    path = tmp_path / "cu.exr"
    microsim.write_table(table, path)
    back = microsim.read_table(path)
    assert back.channels == table.channels
    assert back.channels.names == ("450nm", "552p5nm", "650nm")
    for c in table.components:
        np.testing.assert_array_equal(back[c].values, table[c].values.astype(np.float32))
        np.testing.assert_array_equal(back[c].sh, table[c].sh.astype(np.float32))
    np.testing.assert_array_equal(back.albedo, table.albedo)


GAUSSIAN = {"surface": {"kind": "gaussian", "alpha": 0.3, "resolution": 32}}


@pytest.mark.parametrize(("material", "table", "message"), [
    ({"kind": "conductor", "data": "Au"}, {}, "material.data: a spectrum needs a spectral "
     "table"),
    ({"kind": "conductor", "data": "Cr"}, {"wavelengths": [220.0, 500.0]},
     "material.data: 220 nm asked for, outside 247.97-2042.6 nm"),
    ({"kind": "conductor", "data": "Au"}, {"wavelengths": [2000.0]},
     "material.data: 2000 nm asked for, outside"),
    ({"kind": "conductor", "data": "Gold"}, {"wavelengths": [500.0]},
     "material.data = 'Gold': must be one of 'Ag', 'Al', 'Au', 'Cr', 'Cu'"),
    ({"kind": "conductor", "data": "Au", "k": 2.0}, {"wavelengths": [500.0]},
     "material.data = 'Au': gives eta and k; leave out k"),
    ({"kind": "lambertian", "data": "colorchecker_red", "albedo": 0.5},
     {"wavelengths": [500.0]},
     "material.data = 'colorchecker_red': gives albedo; leave out albedo"),
    ({"kind": "dielectric", "data": "BK7", "eta": 1.5}, {"wavelengths": [500.0]},
     "material.data = 'BK7': gives eta; leave out eta"),
    ({"kind": "conductor", "eta": 1.2}, {"wavelengths": [500.0]},
     "material.k: its default is gold's R, G, B"),
    ({"kind": "conductor"}, {"wavelengths": [500.0, 500.0]}, "table.wavelengths"),
    ({"kind": "conductor"}, {"wavelengths": [600.0, 500.0]}, "distinct and increasing"),
    ({"kind": "conductor"}, {"wavelengths": []}, "table.wavelengths"),
    ({"kind": "conductor", "eta": [1.0, 2.0, 3.0]}, {"wavelengths": [500.0, 600.0]},
     "material.eta = [1.0, 2.0, 3.0]: three numbers are R, G, B"),
    ({"kind": "conductor", "eta": {"nm": [400, 500], "value": [1.0]}},
     {"wavelengths": [450.0]}, "material.eta: nm has 2 entries and value 1"),
    ({"kind": "conductor", "eta": {"nm": [500, 400], "value": [1.0, 2.0]}},
     {"wavelengths": [450.0]}, "material.eta"),
    ({"kind": "conductor", "eta": {"nm": [400, 500], "value": [1.0, -1.0]}},
     {"wavelengths": [450.0]}, "material.eta.value[1] = -1.0"),
    ({"kind": "lambertian", "albedo": {"nm": [400, 700], "value": [0.5, 1.5]}},
     {"wavelengths": [450.0]}, "material.albedo.value[1] = 1.5"),
    ({"kind": "lambertian", "data": "colorchecker_red"}, {"wavelengths": [450.0, 750.0]},
     "material.data: 750 nm asked for, outside 380-730 nm"),
    ({"kind": "dielectric", "data": "BK7", "refract": True}, {"wavelengths": [250.0]},
     "material.data: 250 nm asked for, outside 300-2500 nm"),
    ({"kind": "dielectric", "data": "window"}, {"wavelengths": [500.0]},
     "material.data = 'window': must be one of"),
])
def test_bad_spectral_input_is_one_clear_error(material: dict, table: dict,
                                               message: str) -> None:
    """Each mistake is an ``InputError`` naming the key and what is allowed."""
    with pytest.raises(InputError) as caught:
        microsim.load_recipe({**GAUSSIAN, "material": material, "table": table})
    assert message in str(caught.value)


def test_bad_spectral_input_exits_2_with_one_error_line(cli, tmp_path) -> None:
    """From the command line: exit status 2, one line starting with ``error:``."""
    recipe = tmp_path / "gold.toml"
    recipe.write_text('[surface]\nkind = "flat"\n[material]\nkind = "conductor"\n'
                      'data = "Au"\n[table]\nwavelengths = [100, 500]\n')
    code, out, err = cli("simulate", str(recipe), "-o", str(tmp_path / "t.exr"))
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: table.wavelengths[0] = 100")


@pytest.mark.parametrize("thickness", [0.0, 120.0, 350.0, 2000.0])
@pytest.mark.parametrize("material", [
    {"kind": "conductor", "data": "Ag"},
    {"kind": "conductor", "eta": 0.2, "k": 3.4},
    {"kind": "dielectric", "eta": 1.5},
])
def test_coated_flat_facets_reflect_the_films_airy_reflectance(material: dict,
                                                              thickness: float) -> None:
    """A flat coated facet reflects every ray once with the film's reflectance at the
    channel's wavelength: the albedo equals ``analytic.fresnel_thin_film`` (a vectorised
    implementation independent of the kernel's, itself checked against a characteristic-
    matrix stack in tests/test_thin_film.py) to 1e-6, over θi 0-85° and 16 wavelengths;
    a film of 0 nm is the bare facet."""
    film = {"thickness": thickness, "eta": {"nm": [380.0, 720.0], "value": [2.45, 2.25]}}
    table = _flat({**material, "coating": film}, NM16)
    nm = np.asarray(NM16)
    film_eta = np.interp(nm, [380.0, 720.0], [2.45, 2.25])
    if material.get("data"):
        eta, k = (s.at(NM16) for s in measured.conductor(material["data"]))
    else:
        eta, k = material["eta"], material.get("k", 0.0)
    cos = np.cos(np.radians(FLAT_THETA))[:, None]
    exact = fresnel_thin_film(cos, film_eta, thickness, nm, eta, k)
    np.testing.assert_allclose(table.albedo[:, 0], exact, rtol=0, atol=1e-6)
    if thickness == 0.0:
        bare = _flat(material, NM16)
        np.testing.assert_allclose(table.albedo, bare.albedo, rtol=0, atol=1e-12)


def test_coated_refracting_dielectric_reflects_the_film_on_average() -> None:
    """A flat refracting glass under a 350 nm film: each path's choice between reflection
    and refraction is its hero wavelength's (the film makes it wavelength-dependent), so
    each channel's albedo is a binomial estimate, C × (hero paths reflected) / N, of the
    film's reflectance: within 4.5 binomial standard errors of ``fresnel_thin_film`` at
    every wavelength and incidence (two-sided, about 1e-5 per comparison), and the
    estimates differ from it (they are not exact)."""
    nm = [420.0, 500.0, 580.0, 660.0]
    film = {"thickness": 350.0, "eta": 2.0}
    rays = 40_000
    table = microsim.simulate(microsim.load_recipe({
        "surface": {"kind": "flat"},
        "material": {"kind": "dielectric", "eta": 1.5, "refract": True, "coating": film},
        "table": {"wavelengths": nm, "theta_bins": 4, "phi_bins": 4, "sh_order": 0},
        "simulation": {"theta_i": [0.0, 45.0, 70.0], "rays": rays}}), threads=1)
    cos = np.cos(np.radians([0.0, 45.0, 70.0]))[:, None]
    exact = fresnel_thin_film(cos, 2.0, 350.0, np.asarray(nm), 1.5, 0.0)
    per_channel = rays / len(nm)
    se = len(nm) * np.sqrt(per_channel * exact * (1 - exact)) / rays
    z = (table.albedo[:, 0] - exact) / se
    assert np.all(np.abs(z) < 4.5), z
    assert np.any(np.abs(table.albedo[:, 0] - exact) > 1e-6)


@pytest.mark.parametrize(("coating", "table", "message"), [
    ({"thickness": 100.0, "eta": 2.0}, {}, "material.coating: a coating needs a spectral "
     "table"),
    ({"thickness": -1.0, "eta": 2.0}, {"wavelengths": [500.0]},
     "material.coating.thickness = -1.0: must be a number of nm >= 0"),
    ({"thickness": 100.0}, {"wavelengths": [500.0]}, "material.coating.eta: missing"),
    ({"thickness": 100.0, "eta": 2.0, "n": 1}, {"wavelengths": [500.0]},
     "material.coating.n: unknown key"),
    ({"thickness": 100.0, "eta": 0.0}, {"wavelengths": [500.0]},
     "material.coating.eta = 0.0: must be a number > 0"),
    ({"thickness": 100.0, "eta": {"nm": [400.0, 600.0], "value": [2.0, 2.1]}},
     {"wavelengths": [500.0, 700.0]}, "material.coating.eta: 700 nm asked for"),
    (350.0, {"wavelengths": [500.0]}, "material.coating = 350.0: must be a table"),
])
def test_bad_coating_is_one_clear_error(coating: object, table: dict, message: str) -> None:
    """Each mistake in a coating is an ``InputError`` naming its key."""
    with pytest.raises(InputError) as caught:
        microsim.load_recipe({**GAUSSIAN, "material": {"kind": "conductor",
                                                       "coating": coating},
                              "table": table})
    assert message in str(caught.value)


def test_a_lossless_coated_interface_reflects_alike_from_both_sides() -> None:
    """From inside a coated glass the kernel takes every index and the wavelength relative
    to the glass. Stokes' relations for a lossless stack (Born & Wolf, sec. 1.6.4):
    |r| is the same from both sides at angles related by Snell's law, so the reflectance
    seen from inside at θs equals that from air at θ0, sin θ0 = η sin θs, at every
    wavelength and thickness (to round-off, 1e-12)."""
    from microsim.materials.base import P_WAVELENGTH, PARAMS
    from microsim.materials.dielectric import _reflectance

    eta, film = 1.5, 2.1
    for thickness in (0.0, 90.0, 350.0, 1500.0):
        for nm in (420.0, 555.0, 690.0):
            params = np.zeros((1, PARAMS, 1))
            params[0, 0], params[0, 2], params[0, 3] = eta, film, thickness
            params[0, P_WAVELENGTH] = nm
            for theta_s in np.radians([0.0, 15.0, 30.0, 41.0]):
                sin_0 = eta * np.sin(theta_s)
                outside = _reflectance(params, 0, 0, np.sqrt(1 - sin_0**2), eta, False)
                inside = _reflectance(params, 0, 0, np.cos(theta_s), 1.0 / eta, True)
                assert abs(inside[0] - outside[0]) < 1e-12, (thickness, nm, theta_s)
                assert abs(inside[0] + inside[1] - 1.0) < 1e-12


@pytest.mark.parametrize("material", [
    {"kind": "conductor", "data": "Au", "coating": {"thickness": 90.0, "eta": 1.45}},
    {"kind": "conductor", "eta": {"nm": [400.0, 700.0], "value": [1.0, 2.0]}, "k": 3.0,
     "coating": {"thickness": 100.0, "eta": {"nm": [400.0, 700.0], "value": [2.0, 2.1]}}},
    {"kind": "lambertian", "data": "colorchecker_green"},
    {"kind": "dielectric", "data": "fused_silica", "refract": True},
])
def test_a_spectral_recipe_round_trips_through_its_toml(material: dict) -> None:
    """``microsim check`` writes spectra and coatings as inline tables and leaves out the
    keys ``data`` stands in for, so what it prints resolves to the same recipe."""
    import tomllib

    from microsim.recipe import resolve, to_toml

    recipe = microsim.load_recipe({"surface": {"kind": "flat"}, "material": material,
                                   "table": {"wavelengths": [450.0, 600.0]}})
    text = to_toml(recipe)
    assert resolve(tomllib.loads(text)) == recipe
    if "data" in material:
        assert f'data = "{material["data"]}"' in text
        assert "\nalbedo =" not in text and "\nk =" not in text


def test_a_dielectric_index_spectrum_gives_the_fresnel_of_each_wavelength() -> None:
    """A flat glass whose index is a spectrum (or the shipped BK7 formula) reflects
    F(θi, η(λ)) at each wavelength: its albedo equals the exact Fresnel reflectance of the
    index sampled there (the complex-form ``analytic.fresnel_conductor`` with k = 0) to
    1e-6."""
    nm = [400.0, 500.0, 600.0, 700.0]
    cos = np.cos(np.radians(FLAT_THETA))[:, None]
    for material, eta in (
            ({"kind": "dielectric", "eta": {"nm": [380.0, 720.0], "value": [1.9, 1.7]}},
             np.interp(nm, [380.0, 720.0], [1.9, 1.7])),
            ({"kind": "dielectric", "data": "BK7"}, measured.dielectric("BK7").at(nm))):
        table = _flat(material, nm)
        exact = fresnel_conductor(cos, eta, 0.0)
        np.testing.assert_allclose(table.albedo[:, 0], exact, rtol=0, atol=1e-6)


def test_gold_srgb_equals_colour_sciences_own_conversion() -> None:
    """The sRGB (linear, D65) of a flat spectral gold table's normal-incidence albedo
    (81 wavelengths, 380-780 nm every 5 nm; the product's path: kernel, table,
    ``microsim.spectra.colour``) equals colour-science's own conversion of gold's
    normal-incidence reflectance computed here from the shipped η, k at every nm
    (``colour.sd_to_XYZ`` under D65 with the CIE 1931 2° observer, ``colour.XYZ_to_sRGB``,
    no product code) within 0.002 per channel: the tolerance covers sampling the
    reflectance every 5 nm instead of every 1 nm (gold's reflectance bends around its
    500 nm edge; the measured difference is below 1e-3)."""
    import colour as cs

    from microsim.spectra import colour as ours

    nm = [float(x) for x in np.arange(380.0, 781.0, 5.0)]
    table = _flat({"kind": "conductor", "data": "Au"}, nm)
    product = ours.to_srgb_linear(np.asarray(nm), table.albedo[0, 0])
    dense = np.arange(380.0, 781.0, 1.0)
    eta, k = measured.conductor("Au")
    reflectance = fresnel_conductor(1.0, eta.at(dense), k.at(dense))
    sd = cs.SpectralDistribution(dict(zip(dense, reflectance, strict=True)))
    cmfs = cs.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    with warnings.catch_warnings():
        # colour-science says it aligns the spectrum and D65 to the observer's range
        # (constant beyond the data, as microsim.spectra.colour does): expected here
        warnings.simplefilter("ignore", cs.utilities.ColourRuntimeWarning)
        xyz = cs.sd_to_XYZ(sd, cmfs, cs.SDS_ILLUMINANTS["D65"]) / 100.0
    reference = cs.XYZ_to_sRGB(xyz, apply_cctf_encoding=False)
    np.testing.assert_allclose(product, reference, rtol=0, atol=2e-3)
    assert product[0] > product[1] > product[2]  # gold: red over green over blue


def test_an_absorption_spectrum_is_each_wavelengths_own_absorption() -> None:
    """A paint binder whose Beer-Lambert absorption is a spectrum σ(λ), over a white
    Lambertian base: the paths do not depend on the wavelength (the binder's index is one
    number), so each channel of the spectral table is, bit for bit, the table of that
    wavelength alone with σ as a number (same rays, same random numbers, each channel's
    weight its own); and the absorbed share grows with σ."""
    nm = [450.0, 550.0, 650.0]
    sigma = {"nm": [400.0, 700.0], "value": [0.0, 6.0]}

    def paint(absorption: object, wavelengths: list[float]) -> BRDFTable:
        return microsim.simulate(microsim.load_recipe({
            "surface": {"kind": "paint", "binder_thickness": 0.2, "top_alpha": 0.0,
                        "pigment_fraction": 0.0, "resolution": 32},
            "material": {"binder": {"kind": "dielectric", "eta": 1.5, "refract": True,
                                    "absorption": absorption},
                         "pigment": {"kind": "lambertian", "albedo": 0.5},
                         "substrate": {"kind": "lambertian", "albedo": 0.9}},
            "table": {"wavelengths": wavelengths, "theta_bins": 4, "phi_bins": 4,
                      "sh_order": 0},
            "simulation": {"theta_i": [0.0, 50.0], "rays": 4000}}), threads=1)

    spectral = paint(sigma, nm)
    for j, wavelength in enumerate(nm):
        value = float(np.interp(wavelength, sigma["nm"], sigma["value"]))
        alone = paint(value, [wavelength])
        assert np.array_equal(spectral["total"].values[..., j],
                              alone["total"].values[..., 0])
    absorbed = np.asarray(spectral.meta.directions[0].absorbed)
    assert absorbed[0] < absorbed[1] < absorbed[2]


@pytest.mark.parametrize(("wavelengths", "expected"), [
    ({"start": 400, "stop": 700, "step": 100}, [400.0, 500.0, 600.0, 700.0]),
    ({"start": 400, "stop": 650, "step": 100}, [400.0, 500.0, 600.0]),
    ({"start": 550, "stop": 550, "step": 10}, [550.0]),
    ({"start": 400, "stop": 700, "step": 0}, "table.wavelengths.step = 0: must be a number"),
    ({"start": 400, "stop": 300, "step": 10}, "table.wavelengths.stop = 300: must be >= "),
    ({"start": 400, "stop": 700}, "table.wavelengths = {'start': 400, 'stop': 700}: a range"),
    ({"start": 400, "stop": 4000, "step": 1}, "3601 wavelengths; at most 1000"),
    ({"start": 100, "stop": 700, "step": 100}, "table.wavelengths[0] = 100.0: must be"),
])
def test_wavelengths_as_a_range(wavelengths: dict, expected: object) -> None:
    """``wavelengths = { start, stop, step }`` is the list start, start + step, … up to
    stop; a bad range is one error naming its key."""
    recipe = {"surface": {"kind": "flat"}, "table": {"wavelengths": wavelengths}}
    if isinstance(expected, list):
        assert list(microsim.load_recipe(recipe).table.wavelengths) == expected
        return
    with pytest.raises(InputError) as caught:
        microsim.load_recipe(recipe)
    assert expected in str(caught.value)


def test_a_spectral_table_records_where_its_spectra_come_from(tmp_path) -> None:
    """The table's metadata names the source of every spectrum it sampled: a shipped
    data set's citation (the measured gold's paper) and a given spectrum's own
    ``source``, by key, through its file; an RGB table records none."""
    table = _flat({"kind": "conductor", "data": "Au",
                   "coating": {"thickness": 100.0,
                               "eta": {"nm": [380.0, 720.0], "value": [2.4, 2.2],
                                       "source": "a film index of the test"}}},
                  [450.0, 600.0])
    sources = table.meta.sources
    assert "Johnson and R. W. Christy" in sources["material.base.data"]
    assert sources["material.base.coating.eta"] == "a film index of the test"
    microsim.write_table(table, tmp_path / "t.exr")
    assert microsim.read_table(tmp_path / "t.exr").meta.sources == sources
    rgb = microsim.simulate(microsim.load_recipe({
        "surface": {"kind": "flat"}, "material": {"kind": "conductor"},
        "table": {"theta_bins": 4, "phi_bins": 4, "sh_order": 0},
        "simulation": {"theta_i": [0.0], "rays": 64}}), threads=1)
    assert rgb.meta.sources == {} and "sources" not in rgb.meta.to_json()


def test_hero_wavelength_error_bars_are_calibrated() -> None:
    """The error bars of a dispersive glass's spectral table (hero paths weighted × C,
    reflections weighted F_c / F_hero) are what independent repeats show: 12 runs with
    other seeds (other tiles, other rays), and per lobe bin and wavelength the empirical
    variance of the value over the runs against the mean of the reported variances. Their
    ratio averaged over the lobe bins (60 bin-wavelengths; measured 0.95) is 1 for
    calibrated errors, with a spread of about √(2/11) / √60 ≈ 0.055 if the bins were
    independent; they are correlated (shared rays and tiles), so the bound is [0.7, 1.4],
    about ±6 such spreads: errors 1.5 times too large (checked by hand) fail it, as do
    errors off by √2 either way."""
    nm = [420.0, 560.0, 700.0]
    runs = [_dielectric(nm, 100 + seed, 48_000) for seed in range(12)]
    values = np.stack([t["total"].values for t in runs])
    errors = np.stack([t["total"].errors for t in runs])
    lobe = values.mean(axis=0) >= 0.1 * values.mean(axis=0).max(axis=(0, 1, 2, 3))
    empirical = values.var(axis=0, ddof=1)[lobe]
    reported = np.nanmean(errors**2, axis=0)[lobe]
    ratio = float(np.mean(empirical / reported))
    assert lobe.sum() >= 50, lobe.sum()
    assert 0.7 <= ratio <= 1.4, ratio
