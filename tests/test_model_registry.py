"""The model registry: what each spec builds, its refusals, and how parameters are printed.

Every check is exact: a built model's class and fields (or its values against the model
built directly with the documented arguments), whole error messages, whole parameter
texts and sources. No simulation: the defaults a table would give are small
``ModelDefaults`` written out here.
"""

from __future__ import annotations

import math
from dataclasses import astuple

import numpy as np
import pytest
from refusals import refused

from microsim.analytic.brdf import KayKajiya, Lambertian, TorranceSparrow
from microsim.analytic.cloth import MicrocylinderCloth
from microsim.analytic.cylinders import CylinderArray
from microsim.analytic.fresnel import ConductorFresnel, DielectricFresnel
from microsim.analytic.multiple_scattering import SmithMultipleScattering
from microsim.analytic.ndf import GGX, Beckmann, Blinn, TorranceSparrowGaussian
from microsim.analytic.registry import (
    parameter_sources,
    parameter_units,
    parameters_text,
    parse_model_spec,
    split_spec,
)
from microsim.analytic.velvet import SparseVelvet
from microsim.comparison.table_models import ModelDefaults
from microsim.errors import InputError


def assert_fresnel(fresnel, kind: type, *arrays: list[float]) -> None:
    """``fresnel`` is a ``kind`` record whose fields are arrays exactly as given."""
    assert type(fresnel) is kind
    fields = astuple(fresnel)
    assert len(fields) == len(arrays)
    for got, want in zip(fields, arrays, strict=True):
        assert isinstance(got, np.ndarray)
        np.testing.assert_array_equal(got, want)


# --- microfacet models: the NDF, the Fresnel argument, the shadowing ---------------------

@pytest.mark.parametrize(("spec", "cls", "field", "value"), [
    ("beckmann:alpha=0.2", Beckmann, "alpha", 0.2),
    ("ggx:alpha=0.2", GGX, "alpha", 0.2),
    ("blinn:n=30", Blinn, "n", 30.0),
    ("torrance-sparrow:alpha=0.2", Beckmann, "alpha", 0.2),
    ("torrance-sparrow:ndf=ggx,alpha=0.2", GGX, "alpha", 0.2),
    ("torrance-sparrow:ndf=blinn,n=30", Blinn, "n", 30.0),
    ("torrance-sparrow:ndf=gaussian,c=5", TorranceSparrowGaussian, "c", 5.0),
])
def test_a_microfacet_spec_builds_torrance_sparrow_with_the_ndf_it_names(spec, cls, field,
                                                                        value):
    """Each microfacet name (and ``torrance-sparrow``'s ``ndf``) gives its NDF class with
    the value given: exact, the value is passed through."""
    _, _, model = parse_model_spec(spec)
    assert type(model) is TorranceSparrow
    assert type(model.ndf) is cls
    assert getattr(model.ndf, field) == value
    assert model.fresnel is None and model.shadowing == "smith-correlated"


def test_an_anisotropic_spec_builds_the_ndf_with_both_alphas():
    """alpha_x and alpha_y reach the NDF as given, and the isotropic default alpha is dropped."""
    _, params, model = parse_model_spec("ggx:alpha_x=0.1,alpha_y=0.4")
    assert params == {"alpha_x": 0.1, "alpha_y": 0.4, "shadowing": "smith-correlated"}
    assert type(model.ndf) is GGX
    assert (model.ndf.alpha_x, model.ndf.alpha_y) == (0.1, 0.4)


def test_the_shadowing_given_is_the_models():
    """The masking-shadowing choice reaches the model (its default is the other tests')."""
    _, _, model = parse_model_spec("beckmann:shadowing=v-groove")
    assert model.shadowing == "v-groove"


@pytest.mark.parametrize(("spec", "kind", "arrays"), [
    ("beckmann:eta=[0.2,0.9,1.1],k=[3,2.5,2]", ConductorFresnel,
     ([0.2, 0.9, 1.1], [3.0, 2.5, 2.0])),
    # k alone: the conductor's eta is 1.5 in every channel of k
    ("beckmann:k=[3,2.5]", ConductorFresnel, ([1.5, 1.5], [3.0, 2.5])),
    ("beckmann:k=2", ConductorFresnel, ([1.5, 1.5, 1.5], [2.0, 2.0, 2.0])),
    ("ggx:eta=1.4", DielectricFresnel, ([1.4, 1.4, 1.4],)),
    ("ggx:eta=[1.4,1.5,1.6]", DielectricFresnel, ([1.4, 1.5, 1.6],)),
])
def test_eta_and_k_make_the_fresnel_argument(spec, kind, arrays):
    """k (with eta, or eta = 1.5) is a conductor, eta alone a dielectric; the arrays are
    the values given, a single number read as R, G, B."""
    _, _, model = parse_model_spec(spec)
    assert_fresnel(model.fresnel, kind, *arrays)


def test_multiple_scattering_gets_the_ndf_fresnel_samples_and_seed_given():
    """The random-walk models get the NDF named by the model, the Fresnel argument, and the
    samples and seed given (or their defaults 256 and 0); exact, all passed through."""
    _, _, model = parse_model_spec("ggx-ms:alpha=0.2,eta=1.4,samples=64,seed=7")
    assert type(model) is SmithMultipleScattering
    assert type(model.ndf) is GGX and model.ndf.alpha == 0.2
    assert_fresnel(model.fresnel, DielectricFresnel, [1.4, 1.4, 1.4])
    assert (model.samples, model.seed) == (64, 7)
    _, _, model = parse_model_spec("beckmann-ms:alpha_x=0.1,alpha_y=0.3,k=2")
    assert type(model.ndf) is Beckmann
    assert (model.ndf.alpha_x, model.ndf.alpha_y) == (0.1, 0.3)
    assert_fresnel(model.fresnel, ConductorFresnel, [1.5, 1.5, 1.5], [2.0, 2.0, 2.0])
    assert (model.samples, model.seed) == (256, 0)


# --- roughness: alpha against alpha_x/alpha_y ---------------------------------------------

def test_one_anisotropic_alpha_alone_is_refused():
    """The whole message of the refusal."""
    assert refused(InputError, parse_model_spec, "ggx:alpha_x=0.2") == (
        "model: give both alpha_x and alpha_y, or alpha")


@pytest.mark.parametrize(("spec", "table"), [
    ("ggx:alpha_x=0.1,alpha_y=0.2", {}),
    ("ggx:alpha_x=0.1", {"alpha_y": 0.2}),
    ("ggx:alpha_y=0.2", {"alpha_x": 0.1}),
])
def test_a_given_anisotropic_alpha_sets_aside_the_tables_alpha_unchecked(spec, table):
    """A table's realised alpha below the models' range (5e-5 < 1e-4) is not a parameter
    of a spec that gives alpha_x or alpha_y (the other may come from the table), so it is
    neither used nor refused."""
    _, params, model = parse_model_spec(spec, {"alpha": 5e-5, **table})
    assert params == {"alpha_x": 0.1, "alpha_y": 0.2, "shadowing": "smith-correlated"}
    assert (model.ndf.alpha_x, model.ndf.alpha_y) == (0.1, 0.2)


def test_the_tables_alpha_out_of_range_is_refused_for_an_isotropic_spec():
    """The other side: without alpha_x or alpha_y given, the table's alpha is the model's
    and is checked."""
    assert refused(InputError, parse_model_spec, "ggx", {"alpha": 5e-5}).startswith(
        "model ggx: alpha = 5e-05")


# --- colour parameters: one count of channels ---------------------------------------------

@pytest.mark.parametrize(("spec", "params"), [
    ("beckmann:eta=[1.5,1.4],k=2",
     {"alpha": 0.3, "shadowing": "smith-correlated", "eta": [1.5, 1.4], "k": [2.0, 2.0]}),
    ("beckmann:eta=1.2,k=[3,2.5]",
     {"alpha": 0.3, "shadowing": "smith-correlated", "eta": [1.2, 1.2], "k": [3.0, 2.5]}),
    ("beckmann:eta=[1.5,1.4],k=[3,2.5]",
     {"alpha": 0.3, "shadowing": "smith-correlated", "eta": [1.5, 1.4], "k": [3.0, 2.5]}),
    ("lambertian:albedo=[0.1,0.2,0.3,0.4]", {"albedo": [0.1, 0.2, 0.3, 0.4]}),
    # the model's own default albedo, a single number, beside a list
    ("cylinders:kind=lambertian,base_albedo=[0.1,0.2,0.3]",
     {"radius": 0.5, "spacing": 1.0, "sink": 0.0, "kind": "lambertian",
      "albedo": [0.8, 0.8, 0.8], "base_albedo": [0.1, 0.2, 0.3]}),
])
def test_a_single_number_takes_the_length_of_the_lists_beside_it(spec, params):
    """A number (given, read as R, G, B, or a model's own default) becomes as many copies
    as the lists given have values; the lists keep their values."""
    assert parse_model_spec(spec)[1] == params


def test_colour_lists_of_different_lengths_are_refused():
    """The whole message, naming each list's length."""
    assert refused(InputError, parse_model_spec, "beckmann:eta=[1.5,1.4],k=[1,2,3]") == (
        "model beckmann: eta has 2 values, k has 3 values; give each colour parameter one "
        "number or one per channel, as many for each")


# --- names and spec syntax -------------------------------------------------------------------

def test_an_unknown_model_is_refused_with_the_list_of_models():
    """The whole message: the suggestion and every model's name, in the registry's order."""
    assert refused(InputError, parse_model_spec, "beckman") == (
        "model 'beckman': unknown (did you mean 'beckmann'?); models: beckmann, ggx, "
        "beckmann-ms, ggx-ms, torrance-sparrow, blinn, phong, blinn-phong, lambertian, "
        "coated-lambertian, oren-nayar, lafortune, kay-kajiya, cylinders, velvet-sparse, "
        "microcylinder")


@pytest.mark.parametrize(("spec", "message"), [
    ("ggx:alpha", "model ggx: 'alpha' must be key=value"),
    ("beckmann:alpha=0.1,alpha=0.2", "model beckmann: alpha given twice; give each key once"),
    ("beckmann:alpha=" + "1" * 5000,
     "model beckmann: alpha = 11111111111111111111…: cannot be read: nested too deeply or "
     "holding an integer of more than 4300 digits (Python's limit)"),
])
def test_a_malformed_spec_is_refused_naming_the_model_and_key(spec, message):
    """Whole messages: no '=', a key twice, a value past Python's limits."""
    assert refused(InputError, parse_model_spec, spec) == message


def test_split_spec_keeps_what_follows_the_first_equals_sign_and_names_its_flag():
    """A value holding '=' is kept whole; the refusal names the flag it was given for."""
    assert split_spec('point:name="a=b", power = [1, 2]', "--light") == (
        "point", {"name": "a=b", "power": [1, 2]})
    with pytest.raises(InputError) as caught:
        split_spec("point:power=1,power=2", "--light")
    assert str(caught.value) == "--light point: power given twice; give each key once"


# --- defaults from a table -------------------------------------------------------------------

def table_defaults() -> ModelDefaults:
    """Defaults as a table gives them: alpha and albedo with named sources, eta without
    one, and for one model only a Lambertian albedo (named) and a cylinders base albedo
    (unnamed)."""
    d = ModelDefaults()
    d.put("alpha", 0.25, "the table's realised alpha")
    d.put("albedo", 0.6, "the facets' albedo")
    d["eta"] = 1.3
    d.for_model["lambertian"] = {"albedo": 0.4}
    d.sources["lambertian.albedo"] = "the table's measured albedo"
    d.for_model["cylinders"] = {"base_albedo": 0.1}
    return d


def test_a_models_own_table_values_override_the_shared_ones():
    """``for_model`` values win over the table's shared ones for that model only; a given
    value wins over both."""
    d = table_defaults()
    assert parse_model_spec("lambertian", d)[1] == {"albedo": [0.4, 0.4, 0.4]}
    assert parse_model_spec("oren-nayar", d)[1] == {
        "sigma": 20.0, "albedo": [0.6, 0.6, 0.6], "model": "full"}
    assert parse_model_spec("lambertian:albedo=0.7", d)[1] == {"albedo": [0.7, 0.7, 0.7]}


def test_sources_name_the_spec_the_tables_words_or_the_models_default():
    """Each parameter's source: given, the table's own words for a shared or a one-model
    value, "from the table" where it has none, or the model's default."""
    d = table_defaults()
    spec = "beckmann:shadowing=v-groove"
    _, params, _ = parse_model_spec(spec, d)
    assert parameter_sources(spec, params, d) == {
        "alpha": "the table's realised alpha", "shadowing": "given", "eta": "from the table"}
    _, params, _ = parse_model_spec("lambertian", d)
    assert parameter_sources("lambertian", params, d) == {
        "albedo": "the table's measured albedo"}
    spec = "cylinders:kind=lambertian,radius=0.4"
    _, params, _ = parse_model_spec(spec, d)
    assert parameter_sources(spec, params, d) == {
        "radius": "given", "spacing": "default", "sink": "default", "kind": "given",
        "eta": "from the table", "albedo": "the facets' albedo",
        "base_albedo": "from the table"}


def test_sources_of_plain_defaults_and_of_none():
    """A plain mapping has no words for its values ("from the table"); without defaults,
    a parameter is given or the model's default."""
    _, params, _ = parse_model_spec("beckmann", {"alpha": 0.25})
    assert parameter_sources("beckmann", params, {"alpha": 0.25}) == {
        "alpha": "from the table", "shadowing": "default"}
    _, params, _ = parse_model_spec("beckmann:alpha=0.2")
    assert parameter_sources("beckmann:alpha=0.2", params, None) == {
        "alpha": "given", "shadowing": "default"}
    with pytest.raises(InputError) as caught:
        parameter_sources("ggx:alpha", {})
    assert str(caught.value) == "model ggx: 'alpha' must be key=value"


# --- how parameters are printed ----------------------------------------------------------

def test_parameter_units_are_those_the_spec_reads():
    """Degrees and tile units as printed; none for a dimensionless model or an unknown name."""
    assert parameter_units("oren-nayar") == {"sigma": "°"}
    assert parameter_units("cylinders") == {
        "radius": " (tile units)", "spacing": " (tile units)", "sink": " (tile units)"}
    assert parameter_units("beckmann") == {}
    assert parameter_units("no-such-model") == {}


def test_parameters_text_prints_each_value_with_its_unit_and_source():
    """Floats and list entries to 4 significant figures, ints and strings as they are,
    units after the value, a missing source as "default"; a key the model does not have
    (a fit's held value) has no unit."""
    params = {"sigma": 20.0, "albedo": [0.123456, 2, 0.5], "model": "full"}
    assert parameters_text("oren-nayar", params, {"albedo": "given"}) == (
        "sigma 20° (default), albedo [0.1235, 2, 0.5] (given), model full (default)")
    params = {"radius": 0.123456, "sides": 6, "extra": 1.5}
    sources = {"radius": "the table's radius", "sides": "given", "extra": "held"}
    assert parameters_text("cylinders", params, sources) == (
        "radius 0.1235 (tile units) (the table's radius), sides 6 (given), extra 1.5 (held)")
    _, params, _ = parse_model_spec("beckmann-ms:samples=64")
    assert parameters_text("beckmann-ms", params, {"samples": "given"}) == (
        "alpha 0.3 (default), samples 64 (given), seed 0 (default)")


# --- fibre and cloth models ---------------------------------------------------------------

def test_cylinders_get_the_geometry_facet_and_base_given():
    """Radius, spacing, the axes' height r - sink, the facet constants and the base albedo
    as given (0.4 - 0.1 written as the same float operation: exact)."""
    _, _, model = parse_model_spec(
        "cylinders:radius=0.4,spacing=1.2,sink=0.1,kind=conductor,eta=0.2,k=3,"
        "base_albedo=0.3")
    assert type(model) is CylinderArray
    assert (model.r, model.s, model.zc) == (0.4, 1.2, 0.4 - 0.1)
    assert_fresnel(model.facet, ConductorFresnel, [0.2] * 3, [3.0] * 3)
    np.testing.assert_array_equal(model.base_albedo, [0.3, 0.3, 0.3])
    _, _, model = parse_model_spec("cylinders:kind=dielectric,eta=1.5")
    assert_fresnel(model.facet, DielectricFresnel, [1.5] * 3)
    assert parse_model_spec("cylinders")[2].facet is None  # a mirror
    _, _, model = parse_model_spec("cylinders:kind=lambertian,albedo=0.3")
    assert type(model.facet) is Lambertian and model.facet.albedo.tolist() == [0.3] * 3


@pytest.mark.parametrize(("spec", "missing"), [
    ("cylinders:kind=conductor", "eta and k"),
    ("cylinders:kind=conductor,eta=1.2", "k"),
    ("cylinders:kind=conductor,k=3", "eta"),
    ("cylinders:kind=dielectric", "eta"),
    ("cylinders:kind=dielectric,k=3", "eta"),
])
def test_cylinders_refuse_a_material_without_its_constants(spec, missing):
    """The whole message names each missing constant of the kind."""
    kind = spec.split("kind=")[1].split(",")[0]
    assert refused(InputError, parse_model_spec, spec) == (
        f"model cylinders: kind = {kind} needs {missing}")


@pytest.mark.parametrize("spec", [
    "cylinders:radius=0.5,spacing=0.99",
    "cylinders:radius=0.5,sink=1.0",
    "cylinders:radius=0.5,spacing=0.9,sink=1.2",
])
def test_cylinders_refuse_overlapping_or_buried_cylinders(spec):
    """At the bounds themselves: sink = 2 radius is refused (the cylinder would be
    buried), and spacing = 2 radius (touching) is the next test's."""
    assert refused(InputError, parse_model_spec, spec) == (
        "model cylinders: need spacing >= 2 radius and sink < 2 radius")


def test_cylinders_that_touch_or_are_almost_buried_are_built():
    """The other side of the bounds: spacing = 2 radius and sink just below 2 radius."""
    _, _, model = parse_model_spec("cylinders:radius=0.5,spacing=1.0,sink=0.99")
    assert (model.r, model.s) == (0.5, 1.0)
    assert model.zc == pytest.approx(-0.49, abs=1e-15)  # 0.5 - 0.99, one rounding


def test_kay_kajiya_tangent_from_its_angles():
    """The unit tangent (sin t cos f, sin t sin f, cos t) at t = 60°, f = 30°: (3/4,
    sqrt(3)/4, 1/2), to rounding (1e-15)."""
    _, _, model = parse_model_spec("kay-kajiya:tangent_theta=60,tangent_phi=30")
    assert type(model) is KayKajiya
    np.testing.assert_allclose(model.tangent, [0.75, math.sqrt(3) / 4, 0.5], atol=1e-15)


def test_velvet_is_the_model_built_directly_with_the_values_given():
    """Fields and quadrature nodes equal (exact: the same arguments) to the model built
    directly with the spec's values in their documented order."""
    _, _, model = parse_model_spec(
        "velvet-sparse:azimuth=45,azimuth_spread=30,sides=4,albedo=0.5")
    direct = SparseVelvet(0.01, 0.15, 400.0, 10.0, 5.0, 45.0, 30.0, 0.5, sides=4)
    assert type(model) is SparseVelvet
    assert (model.r, model.length, model.density, model.sides) == (0.01, 0.15, 400.0, 4)
    np.testing.assert_array_equal(model.albedo, [0.5, 0.5, 0.5])
    np.testing.assert_array_equal(model.axes, direct.axes)
    np.testing.assert_array_equal(model.weights, direct.weights)


@pytest.mark.parametrize("base", ["0.2", "[0, 0, 1]"])
def test_velvet_refuses_a_base_that_is_not_black(base):
    """The whole message, a number given shown as its R, G, B; a single lit channel is
    enough to refuse."""
    shown = {"0.2": "[0.2, 0.2, 0.2]", "[0, 0, 1]": "[0.0, 0.0, 1.0]"}[base]
    assert refused(InputError, parse_model_spec, f"velvet-sparse:base_albedo={base}") == (
        f"model velvet-sparse: base_albedo = {shown}: the model needs a black base "
        "(base_albedo = 0); simulate the velvet on one with --set material.base.kind=black")


def test_cloth_is_the_model_built_directly_with_the_values_given():
    """Fields and tangent families equal (exact: the same arguments) to the model built
    directly, widths in radians and the albedos as one row per thread family."""
    _, _, model = parse_model_spec(
        "microcylinder:a_warp=0.7,a_weft=0.6,gamma_s=12,gamma_v=24,kd=0.3,"
        "albedo_warp=[0.1,0.2,0.3],albedo_weft=0.4,slope=0.5,flat=0.25")
    direct = MicrocylinderCloth([0.7, 0.6], 1.5, math.radians(12), math.radians(24), 0.3,
                                [[0.1, 0.2, 0.3], [0.4, 0.4, 0.4]], 0.5, 0.25)
    assert type(model) is MicrocylinderCloth
    np.testing.assert_array_equal(model.coverage, [0.7, 0.6])
    assert (model.eta, model.gamma_s, model.gamma_v, model.kd) == (
        direct.eta, direct.gamma_s, direct.gamma_v, 0.3)
    np.testing.assert_array_equal(model.albedo, [[0.1, 0.2, 0.3], [0.4, 0.4, 0.4]])
    for (t, w), (t0, w0) in zip(model.families, direct.families, strict=True):
        np.testing.assert_array_equal(t, t0)
        np.testing.assert_array_equal(w, w0)
