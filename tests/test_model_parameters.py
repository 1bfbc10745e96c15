"""Every model parameter a command fills in is printed with its unit and where it came from,
one unit per parameter wherever it is printed or read, and a table's own measured quantity
is the default where one exists (docs/compare.md)."""

from __future__ import annotations

import json
import math
from dataclasses import astuple
from datetime import timedelta
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_robustness import GAUSSIAN, SMALL, one_error_line

import microsim
from microsim.analytic.brdf import OrenNayar
from microsim.analytic.registry import parameter_sources, parameters_text, parse_model_spec
from microsim.comparison.table_models import ModelDefaults, table_defaults
from microsim.errors import InputError


@pytest.fixture(scope="module")
def table_file(tmp_path_factory):
    from microsim.cli import main

    path = tmp_path_factory.mktemp("table") / "small.exr"
    assert main(["simulate", GAUSSIAN, *SMALL, "--rays", "2000", "-o", str(path)]) == 0
    return path


def test_compare_prints_each_parameter_with_its_unit_and_source(cli, table_file):
    table = microsim.read_table(table_file)
    alpha = table.meta.surface.alpha_realised.alpha
    code, out, err = cli("compare", str(table_file), "--model", "oren-nayar:albedo=0.5")
    assert code == 0, err
    first = out.splitlines()[0]
    assert "sigma 20° (default)" in first, first
    assert "albedo [0.5, 0.5, 0.5] (given)" in first and "model full (default)" in first
    code, out, err = cli("compare", str(table_file), "--model", "beckmann", "--json")
    result = json.loads(out)
    assert result["params"]["alpha"] == alpha
    assert result["param_sources"] == {"alpha": "the table's realised alpha",
                                       "shadowing": "default"}
    code, out, err = cli("compare", str(table_file), "--model", "beckmann")
    assert f"alpha {alpha:.4g} (the table's realised alpha)" in out.splitlines()[0]


@pytest.mark.parametrize("component", ["total", "order2"])
def test_a_lambertian_comparison_takes_the_tables_measured_albedo(cli, table_file, component):
    """Not the facets' material (mirror facets here: F = 1, no albedo; on the velvet the
    fibres' [0.6, 0.1, 0.1]): the table's own directional albedo of the component."""
    table = microsim.read_table(table_file)
    measured = table[component].albedo.mean(axis=(0, 1))
    code, out, err = cli("compare", str(table_file), "--model", "lambertian", "--component",
                         component, "--json")
    assert code == 0, err
    result = json.loads(out)
    np.testing.assert_allclose(result["params"]["albedo"], np.clip(measured, 0, 1), rtol=1e-12)
    assert result["param_sources"]["albedo"] == (f"the table's measured {component} albedo, "
                                                 "mean over its incidences")
    # only the Lambertian model takes it: Oren-Nayar's albedo is a facet albedo
    _, params, _ = parse_model_spec("oren-nayar", table_defaults(table, component))
    assert params["albedo"] == 0.8  # its default


def test_velvet_sparse_on_a_base_that_is_not_black_says_how_to_simulate_one(cli, table_file):
    defaults = ModelDefaults()
    defaults.put("base_albedo", [0.3] * 3, "the recipe's material.base (lambertian)")
    with pytest.raises(InputError, match="needs a black base.*material.base.kind=black"):
        parse_model_spec("velvet-sparse", defaults)
    code, _, err = cli("compare", str(table_file), "--model", "velvet-sparse:base_albedo=0.3")
    one_error_line(code, err, "velvet-sparse", "black base", "--set material.base.kind=black")


def test_fit_prints_angles_in_the_degrees_the_model_spec_reads(cli, tmp_path):
    """A fitted Oren-Nayar sigma is printed in degrees with its unit, and given back to
    the model spec it is the same model."""
    from microsim.comparison.metrics import model_table
    from microsim.tables.binning import HemisphereBins
    from microsim.tables.exr import write_table

    truth = OrenNayar(math.radians(25.0), [0.7, 0.5, 0.3])
    table = model_table(truth, np.radians([0.0, 40.0, 70.0]), HemisphereBins(16, 32))
    path = tmp_path / "on.exr"
    write_table(table, path)
    code, out, err = cli("fit", str(path), "--model", "oren-nayar", "--json")
    assert code == 0, err
    fitted = json.loads(out)
    assert fitted["units"] == {"sigma": "°"}
    assert fitted["params"]["sigma"] == pytest.approx(25.0, rel=0.01)
    code, out, err = cli("fit", str(path), "--model", "oren-nayar")
    line = next(line for line in out.splitlines() if line.strip().startswith("sigma"))
    assert line.rstrip().endswith("°"), line
    _, _, model = parse_model_spec(f"oren-nayar:sigma={fitted['params']['sigma']},"
                                   f"albedo=[0.7,0.5,0.3]")
    wi = np.array([0.5, 0.0, math.sqrt(0.75)])
    wo = np.array([-0.3, 0.2, math.sqrt(0.87)])
    np.testing.assert_allclose(model.eval(wi, wo), truth.eval(wi, wo), rtol=0.02)


def test_parameters_text_names_units_of_every_kind():
    _, params, _ = parse_model_spec("cylinders:radius=0.4,spacing=1")
    sources = parameter_sources("cylinders:radius=0.4,spacing=1", params)
    text = parameters_text("cylinders", params, sources)
    assert "radius 0.4 (tile units) (given)" in text and "kind mirror (default)" in text
    _, params, _ = parse_model_spec("kay-kajiya")
    assert "tangent_theta 90° (default)" in parameters_text(
        "kay-kajiya", params, parameter_sources("kay-kajiya", params))


def test_models_eval_prints_each_parameter_with_its_unit_and_source(cli):
    """``models eval oren-nayar`` printed ``sigma 20`` (degrees unsaid, the default unsaid);
    it prints the units and sources compare prints, and its JSON names the sources."""
    code, out, err = cli("models", "eval", "oren-nayar:albedo=0.5", "--wi", "30,0", "--wo",
                         "40,180")
    assert code == 0, err
    assert "sigma 20° (default)" in out and "albedo [0.5, 0.5, 0.5] (given)" in out, out
    code, out, err = cli("models", "eval", "oren-nayar:albedo=0.5", "--wi", "30,0", "--wo",
                         "40,180", "--json")
    assert code == 0, err
    result = json.loads(out)
    assert result["param_sources"] == {"sigma": "default", "albedo": "given",
                                       "model": "default"}
    assert result["units"] == {"sigma": "°"}


def test_fit_prints_the_parameters_it_holds_with_their_units_and_sources(cli, tmp_path,
                                                                       table_file):
    """fit printed only what it fitted: the Kay-Kajiya fibre tangent and coverage it
    takes from the table (the cylinders' axis, 2 radius / spacing), a microfacet fit's
    shadowing, were not said. It prints them held, as compare prints parameters (unit,
    source), and its JSON holds them with their sources; held from a cylinders table,
    they are ``model_defaults``'s values."""
    from microsim.comparison.table_models import model_defaults

    path = tmp_path / "cylinders.exr"
    code, _, err = cli("simulate", str(Path(GAUSSIAN).with_name("cylinders.toml")),
                       "--set", "simulation.theta_i=[0, 60]", "--set", "simulation.phi_i=[0]",
                       "--set", "table.theta_bins=8", "--set", "table.phi_bins=16",
                       "--set", "table.sh_order=2", "--rays", "4000", "-o", str(path))
    assert code == 0, err
    defaults = model_defaults(microsim.read_table(path).meta)
    code, out, err = cli("fit", str(path), "--model", "kay-kajiya")
    assert code == 0, err
    held = next(line for line in out.splitlines() if line.strip().startswith("held:"))
    theta, coverage = defaults["tangent_theta"], defaults["coverage"]
    assert f"tangent_theta {theta:.4g}° (the cylinders' axis)" in held, held
    assert f"coverage {coverage:.4g} (2 radius / spacing of the recipe's surface)" in held
    code, out, err = cli("fit", str(path), "--model", "kay-kajiya", "--json")
    result = json.loads(out)
    assert result["held"] == {k: defaults[k] for k in ("tangent_theta", "tangent_phi",
                                                       "coverage")}
    assert result["held_sources"]["tangent_phi"] == "the cylinders' axis"
    code, out, err = cli("fit", str(table_file), "--model", "beckmann")
    assert "  held: shadowing smith-correlated (default)" in out.splitlines(), out


def test_render_prints_its_models_parameters_with_units_and_sources(cli, table_file,
                                                                  tmp_path):
    """``render --model`` printed its models' parameters (``params_text``) without a test
    of their units and sources: Oren-Nayar's sigma in degrees and a default, a Lambertian's
    albedo the table's own measured one (not a facet material's), each said so."""
    pytest.importorskip("mitsuba")
    table = microsim.read_table(table_file)
    albedo = table_defaults(table, "total").for_model["lambertian"]["albedo"]
    code, out, err = cli("render", str(table_file), str(table_file), "-o",
                         str(tmp_path / "r.png"), "--size", "16x16", "--spp", "2",
                         "--model", "oren-nayar", "--model", "lambertian")
    assert code == 0, err
    first, second = out.splitlines()[:2]
    assert "oren-nayar (sigma 20° (default), albedo 0.8 (default), model full (default))" \
        in first, first
    listed = "[" + ", ".join(f"{a:.4g}" for a in albedo) + "]"
    assert (f"lambertian (albedo {listed} (the table's measured total albedo, mean over its "
            "incidences))") in second, second


def test_view_prints_its_wireframe_models_parameters_with_units_and_sources(cli, table_file,
                                                                           tmp_path):
    """``view --model`` filled the model's parameters in from the table and said nothing;
    it prints them as compare does."""
    alpha = microsim.read_table(table_file).meta.surface.alpha_realised.alpha
    code, out, err = cli("view", str(table_file), "--model", "beckmann", "--screenshot",
                         str(tmp_path / "lobe.png"))
    assert code == 0, err
    assert f"alpha {alpha:.4g} (the table's realised alpha)" in out, out


# --- model specs: property-based --------------------------------------------------------
SPEC_VALUES = st.one_of(
    st.sampled_from(["0", "-1", "1e-300", "1e300", "nan", "inf", "-inf", "0.5", "90", "1e6",
                     "true", '"x"', "[0.1, 0.2, 0.3]", "[1, 2]", "[]", "9" * 400, "x",
                     "[0.2,0.9,1.1]", "smith-separable", "qualitative", "black"]),
    st.floats(allow_nan=False, allow_infinity=False).map(repr),
    st.integers(-10**6, 10**9).map(str),
)


@st.composite
def model_specs(draw) -> str:
    """A model name (sometimes misspelt) and 0-4 of its keys (sometimes unknown or
    repeated) with values of every kind: in range, extreme, of another type."""
    from microsim.analytic.registry import MODELS

    name = draw(st.sampled_from(sorted(MODELS) + ["bekmann", ""]))
    keys = sorted(MODELS[name].params) + ["nosuchkey"] if name in MODELS else ["alpha"]
    items = [f"{draw(st.sampled_from(keys))}={draw(SPEC_VALUES)}"
             for _ in range(draw(st.integers(0, 4)))]
    return name + (":" + ",".join(items) if items else "")


@settings(max_examples=300, deadline=timedelta(seconds=30), derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(spec=model_specs())
def test_any_model_spec_is_refused_in_one_line_or_evaluates_finite(spec):
    """Whatever the spec, parse_model_spec raises InputError with one line, or builds a
    model whose f_r at a few direction pairs is finite and >= 0 (Lafortune lobes and
    truncated series aside, no model here is negative)."""
    try:
        name, params, model = parse_model_spec(spec)
    except InputError as exc:
        assert "\n" not in str(exc)
        return
    wi = np.array([[0.0, 0.0, 1.0], [0.5, 0.0, math.sqrt(0.75)], [0.1, 0.98, 0.17]])
    wo = np.array([[0.3, -0.2, math.sqrt(0.87)], [-0.5, 0.0, math.sqrt(0.75)],
                   [0.0, 0.0, 1.0]])
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    with np.errstate(invalid="raise", over="raise"):  # NaN or inf made, not underflow
        try:
            f = np.asarray(model.eval(wi, wo), float)
        except FloatingPointError as exc:
            raise AssertionError(f"{spec}: {exc}") from None
    assert np.all(np.isfinite(f)), (spec, f)
    text = parameters_text(name, params, parameter_sources(spec, params))
    assert "\n" not in text


# --- what the comparisons read from a table's materials -----------------------------------

def test_fibre_surfaces_give_their_models_the_keys_named_and_no_other():
    """Every key a fibre surface gives its models (its kind's ``model_keys``) is a
    ``[surface]`` key of that kind and a parameter of some model, so renaming either
    fails here instead of silently dropping a default; ``model_defaults`` of such a
    recipe takes exactly those keys from its surface, with their values and sources (a
    weave's ``sides``, a velvet-sparse parameter by name, is not one)."""
    from microsim.analytic.registry import MODELS
    from microsim.comparison.table_models import model_defaults
    from microsim.recipe import resolve
    from microsim.surfaces import SURFACES
    from microsim.tables.meta import TableMeta

    params = {name for spec in MODELS.values() for name in spec.params}
    parts = {"cylinders": ("base", "cylinder"), "velvet": ("base", "fibre"),
             "weave": ("warp", "weft")}
    assert {kind for kind, cls in SURFACES.items() if cls.model_keys} == set(parts)
    for kind in parts:
        keys = SURFACES[kind].model_keys
        assert set(keys) <= set(SURFACES[kind].keys()) and set(keys) <= params
        recipe = resolve({"surface": {"kind": kind},
                          "material": {p: {"kind": "lambertian", "albedo": 0.5}
                                       for p in parts[kind]}})
        defaults = model_defaults(TableMeta(recipe=recipe))
        from_surface = {k for k, v in defaults.sources.items()
                        if v.startswith("the recipe's surface.")}
        assert from_surface == set(keys), kind
        assert all(defaults[k] == recipe.surface.value(k)
                   and defaults.sources[k] == f"the recipe's surface.{k}" for k in keys)


def recipe_defaults(material: dict, table: dict | None = None) -> ModelDefaults:
    """``model_defaults`` of a flat tile's table of one material."""
    from microsim.comparison.table_models import model_defaults
    from microsim.recipe import resolve
    from microsim.tables.meta import TableMeta

    return model_defaults(TableMeta(recipe=resolve({"surface": {"kind": "flat"},
                                                    "material": material,
                                                    "table": table or {}})))


def test_a_diffuse_materials_albedo_is_the_lambertian_models_per_channel():
    """A black facet's albedo is 0 in every channel of the table (3 in RGB, one per
    wavelength), a Lambertian facet's its own albedo; both named as their source."""
    for table, count in (({}, 3), ({"wavelengths": [450.0, 550.0, 600.0, 650.0]}, 4)):
        defaults = recipe_defaults({"kind": "black"}, table)
        assert defaults == {"albedo": [0.0] * count}
        assert defaults.sources == {"albedo": "the recipe's material black"}
    defaults = recipe_defaults({"kind": "lambertian", "albedo": [0.2, 0.4, 0.6]})
    assert defaults == {"albedo": [0.2, 0.4, 0.6]}
    assert defaults.sources == {"albedo": "the recipe's material lambertian"}


def test_a_conductors_fresnel_and_model_defaults_are_its_indices_per_channel():
    """A conductor's Fresnel record is ``ConductorFresnel(eta, k)`` per channel and its
    model defaults the same η and k; coated (a spectral table), its record is the film's:
    ``CoatedFresnel(film index, thickness, wavelengths, eta, k)`` per channel, and its
    model defaults stay the facet's η and k."""
    from microsim.analytic.fresnel import CoatedFresnel, ConductorFresnel
    from microsim.materials import Conductor
    from microsim.materials.coating import Coating
    from microsim.spectra.channels import RGB, Channels

    bare = Conductor(eta=(0.2, 0.9, 1.1), k=(3.9, 2.4, 2.1))
    record = bare.fresnel(RGB)
    assert type(record) is ConductorFresnel
    assert record.eta.tolist() == [0.2, 0.9, 1.1] and record.k.tolist() == [3.9, 2.4, 2.1]
    assert bare.model_defaults(RGB) == {"eta": [0.2, 0.9, 1.1], "k": [3.9, 2.4, 2.1]}
    assert recipe_defaults({"kind": "conductor", "eta": [0.2, 0.9, 1.1],
                            "k": [3.9, 2.4, 2.1]}) == {"eta": [0.2, 0.9, 1.1],
                                                       "k": [3.9, 2.4, 2.1]}
    channels = Channels((450.0, 600.0))
    coated = Conductor(eta=0.5, k=2.0, coating=Coating(100.0, 1.45))
    record = coated.fresnel(channels)
    assert type(record) is CoatedFresnel
    assert [np.asarray(x).tolist() for x in astuple(record)] == [
        [1.45, 1.45], [100.0, 100.0], [450.0, 600.0], [0.5, 0.5], [2.0, 2.0]]
    assert coated.model_defaults(channels) == {"eta": [0.5, 0.5], "k": [2.0, 2.0]}


def test_a_dielectrics_fresnel_and_model_defaults_are_its_index():
    """A dielectric's Fresnel record is ``DielectricFresnel(eta)`` and its model default
    ``eta``: one number where η is the same in every channel (also a table of one
    wavelength), η per channel where it varies; coated, ``CoatedFresnel(film index,
    thickness, wavelengths, eta, 0)`` per channel."""
    from microsim.analytic.fresnel import CoatedFresnel, DielectricFresnel
    from microsim.materials import Dielectric
    from microsim.materials.coating import Coating
    from microsim.spectra.channels import RGB, Channels
    from microsim.spectra.spectrum import Spectrum

    glass = Dielectric(eta=1.6, refract=True)
    for channels in (RGB, Channels((550.0,))):
        record = glass.fresnel(channels)
        assert type(record) is DielectricFresnel
        assert record.eta == 1.6 and np.ndim(record.eta) == 0
        assert glass.model_defaults(channels) == {"eta": 1.6}
        assert np.ndim(glass.model_defaults(channels)["eta"]) == 0
    two = Channels((450.0, 600.0))
    dispersive = Dielectric(eta=Spectrum((400.0, 700.0), (1.6, 1.5), "an index of the test"))
    sampled = pytest.approx([1.6 - 0.1 / 6, 1.6 - 0.2 / 3], abs=1e-15)  # linear in nm
    record = dispersive.fresnel(two)
    assert type(record) is DielectricFresnel and record.eta.tolist() == sampled
    assert dispersive.model_defaults(two) == {"eta": sampled}
    assert isinstance(dispersive.model_defaults(two)["eta"], list)
    assert recipe_defaults({"kind": "dielectric", "eta": 1.6}) == {"eta": 1.6}
    record = Dielectric(eta=1.5, coating=Coating(100.0, 2.0)).fresnel(two)
    assert type(record) is CoatedFresnel
    assert [np.asarray(x).tolist() for x in astuple(record)] == [
        [2.0, 2.0], [100.0, 100.0], [450.0, 600.0], [1.5, 1.5], [0.0, 0.0]]
