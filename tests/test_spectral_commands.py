"""The commands that read a table, on spectral tables (one channel per wavelength): each
runs, names the channels, keeps them apart, and shows colour as CIE colorimetry gives it.

Luminances are checked against colour-science's own single-spectrum integration
(``colour.sd_to_XYZ``, method "Integration", D65, CIE 1931 2°, of the piecewise-linear
spectrum on the 1 nm grid), not against ``microsim.spectra.colour``'s cached matrix which
the code uses; swatch colours against ``microsim.spectra.colour.to_srgb_display`` (the
conversion a spectral table's colour is defined by, tested in tests/test_colour.py) and,
for a flat gold mirror, against the exact Fresnel reflectance of its indices.
"""

from __future__ import annotations

import json
from pathlib import Path

import colour
import numpy as np
import pytest
from figurelint import figure_layout_faults

import microsim
from microsim.analytic.fresnel import fresnel_conductor
from microsim.geometry import direction
from microsim.spectra import colour as mc
from microsim.spectra import measured
from microsim.spectra.channels import RGB, Channels
from microsim.tables.table import BRDFTable, ComponentEstimate

NM = [400.0, 460.0, 520.0, 580.0, 640.0, 700.0]
"""Six wavelengths across the visible, nm."""
NAMES = ["400nm", "460nm", "520nm", "580nm", "640nm", "700nm"]
FLAT_THETA = [0.0, 30.0, 60.0]
ROUGH_THETA = [0.0, 40.0, 70.0]
CMFS = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
GRID = CMFS.wavelengths                                   # 360..830 nm, 1 nm
D65 = colour.SpectralDistribution(
    np.interp(GRID, colour.SDS_ILLUMINANTS["D65"].wavelengths,
              colour.SDS_ILLUMINANTS["D65"].values), GRID)
Y_TOLERANCE = 1e-4
"""Relative: the two integrations sum the same function on the same grid, so they differ
by round-off and colour-science's handling of the illuminant's table (tests/test_colour.py
finds ≤ 1e-4 absolute for Y ≤ 1)."""


def reference_y(nm: list[float], values: np.ndarray) -> float:
    """CIE Y (D65, 2°; a perfect white 1) of one spectrum sampled at ``nm``: linear
    between the samples, constant beyond, integrated by colour-science on its 1 nm grid."""
    sd = colour.SpectralDistribution(np.interp(GRID, nm, values), GRID)
    return float(colour.sd_to_XYZ(sd, cmfs=CMFS, illuminant=D65,
                                  method="Integration")[1] / 100.0)


def reference_y_weights(nm: list[float]) -> np.ndarray:
    """(C,) weights with Y = values @ w, each the ``reference_y`` of one channel alone
    (Y is linear in the samples: the hat spectrum of each channel)."""
    return np.array([reference_y(nm, e) for e in np.eye(len(nm))])


def _recipe(surface: dict, theta: list[float], rays: int, realisations: int = 1,
            seed: int = 0, wavelengths: list[float] | None = NM, **table: object) -> dict:
    material = ({"kind": "conductor", "data": "Au"} if wavelengths is not None
                else {"kind": "conductor", "eta": [0.2, 0.9, 1.1], "k": [3.9, 2.4, 2.1]})
    channels = {} if wavelengths is None else {"wavelengths": wavelengths}
    return {"surface": surface, "material": material,
            "table": {**channels, "theta_bins": 8, "phi_bins": 16, **table},
            "simulation": {"theta_i": theta, "rays": rays, "realisations": realisations,
                           "seed": seed}}


GAUSSIAN = {"kind": "gaussian", "alpha": 0.3, "resolution": 32}


def _simulate(recipe: dict) -> BRDFTable:
    return microsim.simulate(microsim.load_recipe(recipe), threads=1)


@pytest.fixture(scope="module")
def tables(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, BRDFTable]]:
    """A flat gold mirror (every ray reflected once with the Fresnel weight of each
    wavelength: an exact albedo) and a rough gold surface (α 0.3, two tiles, orders 1 and
    2+, harmonics to order 4), both of six wavelengths, written to files."""
    folder = tmp_path_factory.mktemp("spectral")
    made = {"flat": _simulate(_recipe({"kind": "flat"}, FLAT_THETA, 60, theta_bins=4,
                                      phi_bins=8, sh_order=2)),
            "rough": _simulate(_recipe(GAUSSIAN, ROUGH_THETA, 6000, 2, sh_order=4,
                                       orders=2))}
    out = {}
    for name, table in made.items():
        microsim.write_table(table, folder / f"{name}.exr")
        out[name] = (folder / f"{name}.exr", table)
    return out


@pytest.fixture
def figures(monkeypatch: pytest.MonkeyPatch) -> list[dict]:
    """What every figure closed during the test shows: its lint faults, texts, images
    (by the title of their panel) and lines (per panel title, their data). Files are
    written empty (the lint draws the figure itself)."""
    import matplotlib.figure
    import matplotlib.pyplot as plt

    monkeypatch.setattr(matplotlib.figure.Figure, "savefig",
                        lambda self, fname, **kw: Path(fname).write_bytes(b""))
    drawn: list[dict] = []
    close = plt.close

    def inspect(fig=None):
        drawn.append({
            "faults": figure_layout_faults(fig),
            "texts": " ".join(t.get_text() for t in fig.findobj(
                lambda a: hasattr(a, "get_text")) if t.get_text()),
            "images": {ax.get_title(): np.asarray(ax.images[0].get_array())
                       for ax in fig.axes if ax.images},
            "lines": {ax.get_title(): [np.asarray(line.get_ydata(), float)
                                       for line in ax.get_lines()] for ax in fig.axes}})
        close(fig)

    monkeypatch.setattr(plt, "close", inspect)
    return drawn


def strip_of(figure: dict) -> np.ndarray:
    """The (a, 3) colours of a figure's colour strip."""
    (image,) = [v for k, v in figure["images"].items() if k.startswith("colour of the table")]
    return image[0]


def test_compare_names_the_channels_and_draws_cie_luminance_and_colour(
        cli, tables, figures, tmp_path) -> None:
    """compare --out --json of a rough gold table: the JSON names the channels and
    wavelengths and gives six albedos per incidence, report.md names them and tabulates
    each wavelength's albedo; the four figures pass the lint; the albedo figure's
    luminance curve of all orders is CIE Y of the table's albedo spectrum per θi (by
    colour-science), its strip the sRGB of the spectrum of single scattering (the
    component compared), and its wavelength panel holds one curve per incidence."""
    path, table = tables["rough"]
    code, out, err = cli("compare", str(path), "--model", "beckmann", "--component",
                         "single", "--out", str(tmp_path / "out"), "--json")
    assert code == 0, err
    result = json.loads(out)
    assert result["channels"] == NAMES and result["wavelengths"] == NM
    assert all(len(row["albedo_sim"]) == len(row["albedo_model"]) == len(row["albedo_model_err"])
               == len(NM) for row in result["per_theta_i"])
    report = (tmp_path / "out" / "report.md").read_text(encoding="utf-8")
    assert "the 6 wavelengths (400-700 nm)" in report and "| 400nm | 460nm" in report
    assert "## Albedo per wavelength (order1): simulated / model" in report
    assert len(figures) == 4 and not any(f["faults"] for f in figures)
    assert all("luminance (CIE Y, D65)" in f["texts"] for f in figures)
    albedo = figures[3]
    want = [reference_y(NM, a) for a in table["total"].albedo[:, 0]]
    curves = albedo["lines"]["luminance (CIE Y, D65) against θi"]
    assert any(len(y) == len(want) and np.allclose(y, want, rtol=Y_TOLERANCE, atol=0)
               for y in curves), (want, curves)
    np.testing.assert_allclose(strip_of(albedo), mc.to_srgb_display(
        NM, table["single"].albedo.mean(axis=1)), rtol=0, atol=1e-12)
    spectra = albedo["lines"]["albedo per wavelength, single scattering"]
    # per incidence: the simulated curve, then the model's
    for k, a in enumerate(table["single"].albedo[:, 0]):
        np.testing.assert_array_equal(spectra[2 * k], a)
    # text: the albedo columns are means over the wavelengths, and say so
    code, out, _ = cli("compare", str(path), "--model", "beckmann")
    assert code == 0 and "channels: the 6 wavelengths (400-700 nm)" in out


def test_a_flat_gold_swatch_is_the_srgb_of_its_fresnel_reflectance(cli, tables, figures,
                                                                    tmp_path) -> None:
    """A flat gold mirror's albedo is the exact Fresnel reflectance of the shipped gold
    indices at each wavelength (1e-6: far below any error of the channels, far above
    round-off), so the strip of every figure shows to_srgb_display of that spectrum per
    θi, within what 1e-6 in the albedo moves a colour (1e-5); gold is red above green
    above blue."""
    path, table = tables["flat"]
    code, _, err = cli("compare", str(path), "--model", "lambertian", "--out",
                       str(tmp_path / "out"))
    assert code == 0, err
    eta, k = measured.conductor("Au")
    exact = fresnel_conductor(np.cos(np.radians(FLAT_THETA))[:, None], eta.at(NM), k.at(NM))
    np.testing.assert_allclose(table.albedo[:, 0], exact, rtol=0, atol=1e-6)
    want = mc.to_srgb_display(NM, exact)
    strips = [strip_of(f) for f in figures if any(
        k.startswith("colour of the table") for k in f["images"])]
    assert len(strips) == 3                     # plane, half-difference, albedo
    for strip in strips:
        np.testing.assert_allclose(strip, want, rtol=0, atol=1e-5)
    assert np.all((want[:, 0] > want[:, 1]) & (want[:, 1] > want[:, 2]))


def test_sh_reports_each_wavelength_apart(cli, tables, tmp_path) -> None:
    """sh --json of a spectral table: every row names the six channels and gives each
    one's error against the bins; channel j's error over the hemisphere is the error sh
    reports for an RGB table whose three channels are all channel j (the pooled error of
    identical channels is each one's); the pooled errors (a weighted RMS of the
    channels') lie between the channels' least and largest, over the hemisphere and over
    the lobe (the bins of the mean over the channels, the same for every channel); the
    channels' errors are their own (they differ); the matrix file holds C channels and
    the wavelengths."""
    from microsim.tables.sh_error import order_errors

    path, _ = tables["rough"]
    table = microsim.read_table(path)
    code, out, err = cli("sh", str(path), "--json", "--matrix", str(tmp_path / "m.npz"))
    assert code == 0, err
    rows = json.loads(out)
    assert [r["order"] for r in rows] == [2, 4]
    for row in rows:
        assert row["channels"] == NAMES
        assert len(row["rel_l2_error_per_channel"]) == len(NM)
        assert len(row["rel_l2_error_lobe_per_channel"]) == len(NM)
        assert row["bytes"] == row["coefficients"] * 3 * len(NM) * 4
    for j in range(len(NM)):
        grey = BRDFTable(table.bins, table.theta_i, table.phi_i, table.isotropic,
                         {c: ComponentEstimate(e.values[..., [j] * 3], e.errors[..., [j] * 3],
                                               e.albedo[..., [j] * 3],
                                               e.albedo_err[..., [j] * 3],
                                               sh=e.sh[..., [j] * 3],
                                               sh_err=e.sh_err[..., [j] * 3])
                          for c, e in table.estimates.items()},
                         table.rays, table.lost_energy[..., [j] * 3], table.meta)
        assert grey.channels == RGB
        for row, alone in zip(rows, order_errors(grey, [2, 4]), strict=True):
            assert row["rel_l2_error_per_channel"][j] == pytest.approx(
                alone["rel_l2_error"], rel=1e-12)
    for row in rows:
        for pooled, each in (("rel_l2_error", "rel_l2_error_per_channel"),
                             ("rel_l2_error_lobe", "rel_l2_error_lobe_per_channel")):
            assert min(row[each]) <= row[pooled] <= max(row[each])
    assert len(set(rows[-1]["rel_l2_error_per_channel"])) == len(NM)
    matrix = np.load(tmp_path / "m.npz")
    assert matrix["matrix"].shape == (25, 25, len(NM)) and matrix["asymmetry"].shape == (6,)
    np.testing.assert_array_equal(matrix["wavelengths"], NM)
    code, out, _ = cli("sh", str(path))
    assert code == 0 and "per wavelength at order 4 (hemisphere, lobe): 400nm" in out


def test_fit_gives_one_f0_per_wavelength(cli, tables) -> None:
    """fit --json: Beckmann's Schlick F0 is fitted per wavelength and named by it; on
    rough gold's single scattering each lies within 0.03 of the exact normal-incidence
    Fresnel reflectance of the gold indices, ((n − 1)² + k²) / ((n + 1)² + k²) (Schlick's
    F0 is F at normal incidence; 0.03 is over ten times the fit's uncertainty and far
    below gold's spread from 0.39 at 400 nm to 0.97 at 700 nm); a grey model (Lafortune)
    fits every channel alike."""
    path, table = tables["rough"]
    code, out, err = cli("fit", str(path), "--model", "beckmann", "--component",
                         "single", "--json")
    assert code == 0, err
    fitted = json.loads(out)
    assert list(fitted["params"]) == ["alpha", *(f"F0_{n}" for n in NAMES)]
    assert fitted["channels"] == NAMES and fitted["wavelengths"] == NM
    eta, k = (np.asarray(x.at(NM)) for x in measured.conductor("Au"))
    normal = ((eta - 1) ** 2 + k**2) / ((eta + 1) ** 2 + k**2)
    f0 = np.array([fitted["params"][f"F0_{n}"] for n in NAMES])
    np.testing.assert_allclose(f0, normal, rtol=0, atol=0.03)
    assert all(len(row["albedo_fit"]) == len(NM) for row in fitted["per_theta_i"])
    code, out, err = cli("fit", str(path), "--model", "lafortune", "--json")
    assert code == 0, err
    code, out, err = cli("fit", str(path), "--model", "beckmann")
    assert code == 0 and "F0_700nm" in out and "means over the 6 wavelengths" in out


def test_the_cloth_model_in_any_channels_is_the_rgb_one() -> None:
    """The microcylinder fit's model for channels other than R, G, B is built from three
    evaluations of the RGB cloth model (its f_r is affine in the volume scales): with the
    scales of an RGB cloth model it gives that model's f_r (1e-12: round-off)."""
    from microsim.analytic.cloth import MicrocylinderCloth
    from microsim.comparison.fit import _ClothPerChannel

    parts = np.array([0.7, 0.5, 1.45, 0.3, 0.6, 0.4])
    albedo = np.array([[0.2, 0.5, 0.9], [1.3, 0.1, 0.7]])
    rng = np.random.default_rng(4)
    wi = direction(rng.uniform(0, 1.4, 50), rng.uniform(0, 6.3, 50))
    wo = direction(rng.uniform(0, 1.4, 50), rng.uniform(0, 6.3, 50))
    rgb = MicrocylinderCloth(parts[:2], *parts[2:], albedo, 0.3, 0.2).eval(wi, wo)
    per = _ClothPerChannel(parts, albedo, 0.3, 0.2).eval(wi, wo)
    assert np.abs(rgb).max() > 0
    np.testing.assert_allclose(per, rgb, rtol=1e-12, atol=1e-14)


def test_eval_and_wavelets_keep_the_channels(cli, tables, tmp_path) -> None:
    """eval gives six values: at a table incidence and a bin centre (away from the pole)
    the bins' own values, channel by channel; its luminance is CIE Y of them
    (colour-science); wavelets --store keeps them by their names and eval reads them back
    from the stored wavelets near the bins' values (every coefficient of a smooth lobe's
    square kept to 1%)."""
    path, _ = tables["rough"]
    table = microsim.read_table(path)               # float32 values, as eval reads them
    it, ip = 3, 9
    wi = f"{ROUGH_THETA[1]},0"
    wo = (f"{np.degrees(table.bins.theta_centers[it])!r},"
          f"{np.degrees(table.bins.phi_centers[ip])!r}")
    bins = table["total"].values[1, 0, it, ip]
    for basis in ("table", "sh"):
        code, out, err = cli("eval", str(path), "--wi", wi, "--wo", wo, "--basis", basis,
                             "--json")
        assert code == 0, err
        got = json.loads(out)
        assert got["channels"] == NAMES and len(got["f_r"]) == len(NM)
        assert got["luminance"] == pytest.approx(reference_y(NM, got["f_r"]),
                                                 rel=Y_TOLERANCE)
        if basis == "table":
            np.testing.assert_allclose(got["f_r"], bins, rtol=1e-9)
    store = tmp_path / "w.exr"
    code, out, err = cli("wavelets", str(path), "--resolution", "32", "--store",
                         str(store), "--json")
    assert code == 0, err
    report = json.loads(out)
    assert report["channels"] == NAMES
    assert np.shape(report["stored"]["kept"]["total"]) == (3, 1, len(NM))
    assert microsim.read_table(store).wavelets.channels == tuple(NAMES)
    code, out, err = cli("eval", str(store), "--wi", wi, "--wo", wo, "--basis", "wavelet",
                         "--json")
    assert code == 0, err
    np.testing.assert_allclose(json.loads(out)["f_r"], bins, rtol=0.2)
    code, out, _ = cli("eval", str(path), "--wi", wi, "--wo", wo)
    assert code == 0 and "at the 6 wavelengths (400-700 nm); luminance (CIE Y, D65)" in out


def test_view_draws_the_lobe_of_cie_y(cli, tables, tmp_path, monkeypatch) -> None:
    """view of a spectral table's lobe: the drawn scalar is CIE Y (colour-science's
    weights) of the table's f_r at each grid direction, and the title says so."""
    import pyvista as pv

    path, table = tables["rough"]
    drawn, texts = [], []
    add_mesh, add_text = pv.Plotter.add_mesh, pv.Plotter.add_text

    def record(self, mesh, **kw):
        if kw.get("scalars"):
            drawn.append((kw["scalars"], np.asarray(mesh.point_data[kw["scalars"]])))
        return add_mesh(self, mesh, **kw)

    def text(self, words, **kw):
        texts.append(words)
        return add_text(self, words, **kw)

    monkeypatch.setattr(pv.Plotter, "add_mesh", record)
    monkeypatch.setattr(pv.Plotter, "add_text", text)
    code, _, err = cli("view", str(path), "--theta-i", "40", "--screenshot",
                       str(tmp_path / "v.png"))
    assert code == 0, err
    assert (tmp_path / "v.png").stat().st_size > 0
    (name, values), = drawn
    assert name == "f_r (1/sr), CIE Y"
    n = 64
    theta = np.radians(np.linspace(0.0, 89.5, n))
    phi = np.linspace(0.0, 2 * np.pi, 2 * n + 1)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    f = table.eval(direction(np.radians(40.0), 0.0), direction(t, p))
    want = (f @ reference_y_weights(NM)).ravel(order="F")
    np.testing.assert_allclose(values, want, rtol=Y_TOLERANCE, atol=1e-12)
    assert "luminance (CIE Y, D65) of 6 wavelengths, 400-700 nm" in texts[0]


def test_simulate_reports_each_incidence_over_its_wavelengths(cli, tmp_path) -> None:
    """simulate's summary of a flat gold mirror: --json gives per incidence the six
    albedos (the exact Fresnel reflectances, 1e-6), names the wavelengths, and the text's
    albedo is their mean, said to be over the six wavelengths."""
    recipe = tmp_path / "gold.toml"
    recipe.write_text('[surface]\nkind = "flat"\n[material]\nkind = "conductor"\n'
                      f'data = "Au"\n[table]\nwavelengths = {NM}\ntheta_bins = 4\n'
                      'phi_bins = 8\nsh_order = 0\n[simulation]\n'
                      f'theta_i = {FLAT_THETA}\nrays = 60\n')
    code, out, err = cli("simulate", str(recipe), "-o", str(tmp_path / "t.exr"), "--json",
                         "--threads", "1")
    assert code == 0, err
    summary = json.loads(out)
    eta, k = measured.conductor("Au")
    exact = fresnel_conductor(np.cos(np.radians(FLAT_THETA))[:, None], eta.at(NM), k.at(NM))
    np.testing.assert_allclose(summary["albedo"], exact, rtol=0, atol=1e-6)
    assert np.shape(summary["lost_energy"]) == (3, len(NM))
    assert summary["channels"] == NAMES and summary["wavelengths"] == NM
    code, out, err = cli("simulate", str(recipe), "-o", str(tmp_path / "t.exr"),
                         "--threads", "1")
    assert code == 0, err
    assert "means over the 6 wavelengths (400-700 nm)" in out
    first = next(line for line in out.splitlines() if line.split()[:2] == ["60.0", "0.0"])
    assert f"{exact[2].mean():9.5f}" in first


def test_merge_and_difference_keep_the_channels_and_refuse_others() -> None:
    """Two one-tile spectral tables of independent rays merge into their ray-weighted
    mean per channel (1e-12) and stay spectral; table_difference gives each channel's
    albedo difference; both refuse an RGB table of the same axes."""
    from microsim.comparison.difference import table_difference
    from microsim.tables.assemble import merge

    a, b = (_simulate(_recipe(GAUSSIAN, [30.0], 1500, seed=s, sh_order=2)) for s in (1, 2))
    merged = merge(a, b)
    assert merged.channels == a.channels == Channels(tuple(NM))
    n_a, n_b = a.rays[0, 0], b.rays[0, 0]
    np.testing.assert_allclose(merged["total"].values,
                               (n_a * a["total"].values + n_b * b["total"].values)
                               / (n_a + n_b), rtol=1e-12, atol=1e-15)
    (row,) = table_difference(a, b)
    np.testing.assert_allclose(row["albedo_difference"], (a.albedo - b.albedo)[0, 0],
                               rtol=1e-12)
    rgb = _simulate(_recipe(GAUSSIAN, [30.0], 1500, seed=1, wavelengths=None, sh_order=2))
    with pytest.raises(ValueError, match="different channels do not merge"):
        merge(a, rgb)
    with pytest.raises(ValueError, match="different channels do not compare"):
        table_difference(a, rgb)


def test_order_residuals_of_a_spectral_table(tables) -> None:
    """The orders study (microsim.comparison.orders) runs on a spectral table's orders;
    its albedos are the means over the wavelengths."""
    from microsim.comparison.orders import compare_orders

    _, table = tables["rough"]
    rows, _ = compare_orders(table, "gold", 8, 500, 1, 4)
    assert len(rows) == len(ROUGH_THETA) * len(table.components)
    for row in rows:
        a = ROUGH_THETA.index(row["theta_i"])
        assert row["albedo_sim"] == pytest.approx(
            table[row["component"]].albedo[a, 0].mean(), rel=1e-12)


def test_an_rgb_only_model_is_refused_with_one_error_line(cli, tmp_path) -> None:
    """The cylinders model computes R, G, B only: compared with a spectral table whose
    recipe gives per-wavelength albedos (ColorChecker patches), compare and view exit 2
    with one error line naming the flag, the keys and what is allowed; with those keys
    given as one number each, it compares; models eval refuses four values alike."""
    table = microsim.simulate(microsim.load_recipe({
        "surface": {"kind": "cylinders", "radius": 0.5, "spacing": 1.2, "sink": 0.25},
        "material": {"base": {"kind": "lambertian", "data": "colorchecker_red"},
                     "cylinder": {"kind": "lambertian", "data": "colorchecker_blue"}},
        "table": {"wavelengths": NM, "theta_bins": 4, "phi_bins": 8, "sh_order": 0},
        "simulation": {"theta_i": [0, 40], "rays": 400}}), threads=1)
    path = tmp_path / "cylinders.exr"
    microsim.write_table(table, path)
    for command in (["compare", str(path), "--model", "cylinders"],
                    ["view", str(path), "--model", "cylinders", "--screenshot",
                     str(tmp_path / "v.png")]):
        code, _, err = cli(*command)
        assert code == 2
        (line,) = err.strip().splitlines()
        assert line.startswith("error: --model cylinders: the cylinders model computes R, "
                               "G and B only, and albedo, base_albedo differ between this "
                               "table's 6 wavelengths; give each one number")
    code, _, err = cli("compare", str(path), "--model",
                       "cylinders:albedo=0.3,base_albedo=0.4", "--json")
    assert code == 0, err
    # without a table: one or three values (four is neither R, G, B nor grey)
    code, _, err = cli("models", "eval", "cylinders:albedo=[0.1,0.2,0.3,0.4]", "--wi",
                       "30,0", "--wo", "30,180")
    assert code == 2
    (line,) = err.strip().splitlines()
    assert line.endswith("the cylinders model computes R, G and B only; albedo must be "
                         "one number or three (R, G, B)")


def test_rgb_tables_do_not_import_colour_science(tmp_path) -> None:
    """colour-science takes about a second to import: the commands import it for spectral
    tables only. compare --out, sh --plot, fit, eval and view's lobe of an RGB table, in a
    fresh interpreter, leave it unimported."""
    import subprocess
    import sys

    from microsim.analytic.registry import parse_model_spec
    from microsim.comparison.metrics import model_table
    from microsim.tables.binning import HemisphereBins

    _, _, model = parse_model_spec("beckmann:alpha=0.3,eta=[0.2,0.9,1.1],k=[3.9,2.4,2.1]")
    table = model_table(model, np.radians([0.0, 45.0]), HemisphereBins(4, 8), 0.05,
                        np.random.default_rng(0))
    path = tmp_path / "rgb.exr"
    microsim.write_table(table, path)
    out = tmp_path / "out"
    script = f"""
import contextlib, io, sys
from microsim.cli import main
with contextlib.redirect_stdout(io.StringIO()):
    for args in (["compare", {str(path)!r}, "--model", "beckmann", "--out", {str(out)!r}],
                 ["fit", {str(path)!r}, "--model", "beckmann"],
                 ["eval", {str(path)!r}, "--wi", "30,0", "--wo", "20,180"],
                 ["view", {str(path)!r}, "--screenshot", {str(tmp_path / "v.png")!r}]):
        assert main(args) == 0, args
print("colour" in sys.modules)
"""
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          timeout=120, check=False)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip().splitlines()[-1] == "False"
