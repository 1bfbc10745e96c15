"""Recipe validation: strict schema, defaults, overrides, error messages."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from microsim import recipe
from microsim.errors import InputError
from microsim.materials import Black, Conductor, Dielectric, Lambertian, material_from_json
from microsim.schema import Key, check_value
from microsim.spectra.channels import RGB
from microsim.spectra.spectrum import Spectrum
from microsim.surfaces import SURFACES

ROOT = Path(__file__).resolve().parent.parent
BASE = {"surface": {"kind": "gaussian", "alpha": 0.3}}


def resolve_with(**sections: dict) -> dict:
    raw = {"surface": dict(BASE["surface"])}
    raw.update(sections)
    return recipe.resolve(raw)


def error_of(raw: dict) -> str:
    with pytest.raises(InputError) as info:
        recipe.resolve(raw)
    return str(info.value)


def test_defaults_filled_in():
    r = recipe.resolve(BASE)
    assert r.surface.resolution == SURFACES["gaussian"].keys()["resolution"].default
    assert {p: m.to_json() for p, m in r.material.items()} == {"base": {"kind": "mirror"}}
    assert set(r.simulation.to_json()) >= {"theta_i", "phi_i", "rays", "bounces", "seed"}
    assert r.simulation.target_error is None  # optional without default stays unset
    assert r.table.to_json() == {"theta_bins": 32, "phi_bins": 64, "sh_order": 32, "orders": 3}


def test_every_shipped_recipe_is_valid():
    recipes = sorted((ROOT / "surfaces").glob("*.toml"))
    assert recipes, "no shipped recipes"
    for path in recipes:
        resolved = recipe.load(path)
        assert resolved.surface.kind in SURFACES


def test_resolved_recipe_round_trips_through_toml(tmp_path):
    r = resolve_with(material={"kind": "conductor"}, simulation={"theta_i": [0, 45]})
    path = tmp_path / "r.toml"
    path.write_text(recipe.to_toml(r))
    assert recipe.load(path) == r


@pytest.mark.parametrize(
    ("raw", "needle"),
    [
        ({"surface": {"kind": "gaussian", "alpah": 0.3}}, "surface.alpah: unknown key (did you mean 'alpha'?)"),
        ({"surface": {"kind": "gausian"}}, "did you mean 'gaussian'?"),
        ({"surface": {"kind": "gaussian", "alpha": -1.0}}, "surface.alpha = -1.0: must be a number >= 0.001"),
        ({"surface": {"kind": "gaussian", "alpha": math.nan}}, "surface.alpha = nan"),
        ({"surface": {"kind": "gaussian", "alpha": math.inf}}, "surface.alpha = inf"),
        ({"surface": {"kind": "gaussian", "alpha": "0.3"}}, "surface.alpha = '0.3': must be a number"),
        ({"surface": {"kind": "gaussian", "alpha": True}}, "surface.alpha = True"),
        ({"surface": {"kind": "gaussian", "alpha": 0.3, "resolution": 0}}, "surface.resolution = 0"),
        ({"surface": {"kind": "gaussian", "alpha": 0.3, "resolution": 10.5}}, "must be an integer"),
        ({"surface": {"kind": "gaussian"}}, "exactly one of"),
        ({"surface": {"kind": "gaussian", "alpha": 0.3, "alpha_x": 0.2}}, "exactly one of"),
        ({"surface": {"kind": "gaussian", "sigma": 0.1}}, "surface.correlation_length: missing"),
        ({}, "surface: missing"),
        ({"surface": 3}, "surface: must be a table"),
        ({"surface": {"kind": "flat"}, "simulaton": {}}, "simulaton: unknown key (did you mean 'simulation'?)"),
        ({"surface": {"kind": "flat"}, "simulation": {"rays": -5}}, "simulation.rays = -5"),
        ({"surface": {"kind": "flat"}, "simulation": {"theta_i": [0, 90]}}, "simulation.theta_i[1] = 90"),
        ({"surface": {"kind": "flat"}, "simulation": {"theta_i": []}}, "simulation.theta_i = []"),
        ({"surface": {"kind": "flat"}, "material": {"kind": "gold"}}, "material.kind = 'gold'"),
        ({"surface": {"kind": "flat"}, "material": {"kind": "conductor", "eta": [1, 2]}}, "material.eta"),
        ({"surface": {"kind": "flat"}, "material": {"kind": "lambertian", "albedo": 1.5}}, "material.albedo = 1.5"),
        ({"surface": {"kind": "flat"}, "material": {"kind": "lambertian", "albedo": {"nm": [400, 700], "value": [0.2, 0.4]}}},
         "material.albedo: a spectrum needs a spectral table"),
        ({"surface": {"kind": "flat"}, "material": {"kind": "lambertian", "data": "colorchecker_green"}},
         "material.data: a spectrum needs a spectral table"),
        ({"surface": {"kind": "velvet"}, "material": {"base": {"kind": "black"}, "fibre": {"kind": "lambertian", "data": "colorchecker_green"}}},
         "material.fibre.data: a spectrum needs a spectral table"),
        ({"surface": {"kind": "flat"}, "material": {"kind": "mirror", "eta": 1.5}}, "material.eta: unknown key"),
        ({"surface": {"kind": "velvet"}, "material": {"fibre": {"kind": "mirror"}}}, "material.base: missing"),
        ({"surface": {"kind": "velvet"}, "material": {"fiber": {"kind": "mirror"}}}, "did you mean 'fibre'?"),
        ({"surface": {"kind": "flat"}, "description": 3}, "description = 3: must be a string"),
    ],
)
def test_bad_recipes_name_the_key(raw, needle):
    message = error_of(raw)
    assert needle in message
    assert "\n" not in message


def test_per_part_materials():
    r = recipe.resolve({"surface": {"kind": "velvet"},
                        "material": {"base": {"kind": "lambertian", "albedo": 0.5},
                                     "fibre": {"kind": "dielectric"}}})
    assert r.material["base"].to_json() == {"kind": "lambertian", "albedo": [0.5, 0.5, 0.5]}
    assert r.material["fibre"].to_json() == {"kind": "dielectric", "eta": 1.5, "refract": False,
                                     "absorption": [0.0, 0.0, 0.0]}


def test_one_material_applies_to_every_part():
    r = recipe.resolve({"surface": {"kind": "velvet"}, "material": {"kind": "lambertian"}})
    assert set(r.material) == set(SURFACES["velvet"].parts)
    assert all(m.kind == "lambertian" for m in r.material.values())


def test_overrides_parse_toml_values_and_bare_words():
    raw = recipe.apply_overrides(BASE, ["surface.alpha=0.5", "simulation.theta_i=[0, 45]",
                                        "material.kind=lambertian", "material.albedo=0.2"])
    r = recipe.resolve(raw)
    assert r.surface.alpha == 0.5
    assert r.simulation.theta_i == (0.0, 45.0)
    assert r.material["base"].to_json() == {"kind": "lambertian", "albedo": [0.2] * 3}
    assert BASE == {"surface": {"kind": "gaussian", "alpha": 0.3}}  # input untouched


def test_override_of_material_kind_drops_old_parameters():
    raw = {"surface": {"kind": "flat"}, "material": {"kind": "conductor", "eta": 1.0, "k": 2.0}}
    r = recipe.resolve(recipe.apply_overrides(raw, ["material.kind=mirror"]))
    assert r.material["base"].to_json() == {"kind": "mirror"}


@pytest.mark.parametrize("text", ["surface", "surface.alpha", "=3", ".alpha=3", "surface..a=1"])
def test_malformed_overrides(text):
    with pytest.raises(InputError, match="must be section.key=value"):
        recipe.parse_override(text)


def test_override_into_a_value_is_an_error():
    with pytest.raises(InputError, match="surface.alpha is not a table"):
        recipe.apply_overrides(BASE, ["surface.alpha.x=1"])


def test_files(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        recipe.load(tmp_path / "missing.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[surface\nkind=")
    with pytest.raises(InputError, match="not valid TOML"):
        recipe.load(bad)


def test_relative_mesh_path_resolves_against_recipe_folder(tmp_path):
    (tmp_path / "sub").mkdir()
    path = tmp_path / "sub" / "r.toml"
    path.write_text('[surface]\nkind = "mesh"\npath = "tile.ply"\nperiod = [1, 2]\n')
    assert recipe.load(path).surface.path == str((tmp_path / "sub" / "tile.ply").resolve())


def test_recipe_docs_are_up_to_date():
    """docs/recipes.md holds the generated schema; regenerate with scripts/make_recipe_docs.py."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("make_recipe_docs",
                                                  ROOT / "scripts" / "make_recipe_docs.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    page = (ROOT / "docs" / "recipes.md").read_text(encoding="utf-8")
    assert module.render(page) == page, "run: python scripts/make_recipe_docs.py"


FLOAT_KEY = Key("float", 1.0, low=0.0, low_open=True, high=10.0)


@given(st.floats(allow_nan=True, allow_infinity=True))
def test_float_keys_accept_exactly_their_range(x):
    inside = math.isfinite(x) and 0.0 < x <= 10.0
    if inside:
        assert check_value(x, "k", FLOAT_KEY) == x
    else:
        with pytest.raises(InputError, match="k = "):
            check_value(x, "k", FLOAT_KEY)


@given(st.one_of(st.text(), st.lists(st.integers()), st.none(), st.booleans(), st.dictionaries(st.text(), st.integers())))
def test_non_numbers_are_refused(value):
    with pytest.raises(InputError):
        check_value(value, "k", FLOAT_KEY)


def test_one_number_is_a_list_of_one():
    """``--set simulation.theta_i=85`` means ``[85]``; a list key of fixed length above one
    (``rgb`` of 3 is its own rule) and a boolean are still refused."""
    load = recipe.load
    root = Path(__file__).resolve().parent.parent / "surfaces"
    assert load(root / "gaussian-0.3.toml", ["simulation.theta_i=85"]).simulation.theta_i \
        == (85.0,)
    with pytest.raises(InputError, match="theta_i"):
        load(root / "gaussian-0.3.toml", ["simulation.theta_i=true"])
    with pytest.raises(InputError, match="theta_i"):
        load(root / "gaussian-0.3.toml", ["simulation.theta_i=95"])


SPECTRAL = {"wavelengths": [450.0, 600.0]}
NEEDS_SPECTRAL = ("a spectrum needs a spectral table ([table] wavelengths); an RGB table "
                  "takes a number or three (R, G, B)")
NEEDS_REFRACT = "needs refract = true (without refraction no light enters the medium)"
GOLD_DEFAULT = ("its default is gold's R, G, B, which a spectral table has no channels for; "
                'give it as a number or a spectrum (or data = "Au" …)')


@pytest.mark.parametrize(("table", "material", "message"), [
    (SPECTRAL, {"kind": "conductor", "eta": 0.5}, f"material.k: {GOLD_DEFAULT}"),
    (SPECTRAL, {"kind": "conductor", "k": 2.0}, f"material.eta: {GOLD_DEFAULT}"),
    ({"wavelengths": [450.0, 750.0]},
     {"kind": "conductor", "eta": {"nm": [400, 700], "value": [0.5, 0.6]}, "k": 2.0},
     "material.eta: 750 nm asked for, outside 400-700 nm, the range of the spectrum given "
     "at material.eta"),
    ({}, {"kind": "conductor", "data": "Ag"}, "material.data: a spectrum needs a spectral "
     "table ([table] wavelengths); an RGB table takes a number or three (R, G, B)"),
    ({}, {"kind": "conductor", "eta": 0.5, "k": 2.0,
          "coating": {"thickness": 100.0, "eta": 1.45}},
     "material.coating: a coating needs a spectral table ([table] wavelengths): its "
     "interference depends on the wavelength"),
    ({}, {"kind": "dielectric", "eta": {"nm": [400, 700], "value": [1.5, 1.6]}},
     f"material.eta: {NEEDS_SPECTRAL}"),
    ({}, {"kind": "dielectric", "data": "BK7"}, f"material.data: {NEEDS_SPECTRAL}"),
    ({}, {"kind": "dielectric", "refract": True,
          "absorption": {"nm": [400, 700], "value": [0.1, 0.2]}},
     f"material.absorption: {NEEDS_SPECTRAL}"),
    ({}, {"kind": "dielectric", "coating": {"thickness": 100.0, "eta": 1.45}},
     "material.coating: a coating needs a spectral table ([table] wavelengths): its "
     "interference depends on the wavelength"),
    ({}, {"kind": "dielectric", "absorption": 0.5},
     f"material.absorption = [0.5, 0.5, 0.5]: {NEEDS_REFRACT}"),
    (SPECTRAL, {"kind": "dielectric", "absorption": {"nm": [400, 700], "value": [0.0, 0.2]}},
     f"material.absorption = [0.0, 0.2]: {NEEDS_REFRACT}"),
    (SPECTRAL, {"kind": "lambertian", "data": "colorchecker_green", "albedo": 0.5},
     "material.data = 'colorchecker_green': gives albedo; leave out albedo"),
    (SPECTRAL, {"kind": "conductor", "data": "Ag", "eta": 1.0, "k": 2.0},
     "material.data = 'Ag': gives eta and k; leave out eta and k"),
    (SPECTRAL, {"kind": "conductor", "data": "Ag", "k": 2.0},
     "material.data = 'Ag': gives eta and k; leave out k"),
    *[(SPECTRAL, {"kind": "lambertian", "albedo": {"nm": [400], "value": [0.1, 0.2], **cited}},
       "material.albedo: nm has 1 entries and value 2; give one value for each wavelength")
      for cited in ({}, {"source": "a reflectance of the test"})],
    (SPECTRAL, {"kind": "conductor", "data": "Ag", "coating": {"thickness": -1.0, "eta": 2.0}},
     "material.coating.thickness = -1.0: must be a number of nm >= 0 and <= 100000"),
])
def test_a_material_that_does_not_fit_the_tables_channels_is_refused_naming_its_key(
        table, material, message):
    """A conductor's default gold triple left in a spectral table (the other index given),
    a spectrum not covering the wavelengths, a spectrum, shipped data or a coating in an
    RGB table, a dielectric's absorption (a number or a spectrum) without refraction, a key
    that ``data`` stands in for given with it, a malformed spectrum (cited or not) or
    coating: one ``InputError``, its whole message naming the key."""
    assert error_of({"surface": {"kind": "flat"}, "table": table,
                     "material": material}) == message


def test_a_materials_own_errors_name_its_key_as_one_material_section():
    """Outside a recipe (the Python API, a table file's recipe read back) a material's
    parameters name its keys as a single ``[material]`` section's, ``material.<key>``."""
    with pytest.raises(InputError) as info:
        Lambertian(albedo=(0.1, 0.2)).parameters(RGB)
    assert str(info.value) == "material.albedo: 2 numbers; an RGB table takes three"
    with pytest.raises(InputError) as info:
        Conductor(eta=(1.0, 2.0)).parameters(RGB)
    assert str(info.value) == "material.eta: 2 numbers; an RGB table takes three"
    index = Spectrum((400.0, 700.0), (1.5, 1.6), "an index of the test")
    with pytest.raises(InputError) as info:
        Dielectric(eta=index).parameters(RGB)
    assert str(info.value) == f"material.eta: {NEEDS_SPECTRAL}"
    with pytest.raises(InputError) as info:
        Dielectric(refract=True, absorption=index).medium(RGB)
    assert str(info.value) == f"material.absorption: {NEEDS_SPECTRAL}"


def test_material_from_json_refuses_an_unknown_kind_and_lists_the_known_ones():
    """A table file's recipe with a kind this microsim lacks (a newer one's) is one
    ``InputError`` that names the kind and every kind known, in ``KINDS``' order; each
    known kind's JSON reads back to the same material."""
    with pytest.raises(InputError) as info:
        material_from_json({"kind": "gold", "eta": 1.0})
    assert str(info.value) == ("material kind 'gold': this microsim knows mirror, "
                               "conductor, dielectric, lambertian, table, black")
    with pytest.raises(InputError, match=r"^material kind None: "):
        material_from_json({})
    r = recipe.resolve({"surface": {"kind": "velvet"},
                        "material": {"base": {"kind": "conductor", "eta": 0.5, "k": 2.0},
                                     "fibre": {"kind": "dielectric", "refract": True}}})
    for material in (*r.material.values(), Lambertian(albedo=(0.1, 0.2, 0.3)), Black()):
        assert material_from_json(material.to_json()) == material


def test_a_spectral_materials_json_leaves_out_what_data_gives_and_reads_back():
    """A material's JSON (a table file's recipe) holds a spectrum with its source (an
    uncited one cited by its key path) and leaves out the keys ``data`` stands in for;
    it reads back to the same material, spectra and coatings as records; a malformed
    section in a table file is refused naming its key."""
    nm = [450.0, 600.0]
    spectrum = {"nm": [400.0, 700.0], "value": [1.6, 1.5]}
    r = recipe.resolve({"surface": {"kind": "velvet"}, "table": {"wavelengths": nm},
                        "material": {"base": {"kind": "lambertian", "albedo": {
                                         "nm": [400.0, 700.0], "value": [0.1, 0.2]}},
                                     "fibre": {"kind": "dielectric", "eta": spectrum}}})
    base, fibre = r.material["base"], r.material["fibre"]
    assert base.albedo == Spectrum((400.0, 700.0), (0.1, 0.2),
                                   "the spectrum given at material.base.albedo")
    assert fibre.eta == Spectrum((400.0, 700.0), (1.6, 1.5),
                                 "the spectrum given at material.fibre.eta")
    r = recipe.resolve({"surface": {"kind": "flat"}, "table": {"wavelengths": nm},
                        "material": {"kind": "conductor", "data": "Ag", "coating": {
                            "thickness": 90.0, "eta": {**spectrum, "source": "a film"}}}})
    metal = r.material["base"]
    assert metal.to_json() == {"kind": "conductor", "data": "Ag", "coating": {
        "thickness": 90.0, "eta": {"kind": "tabulated", **spectrum, "source": "a film"}}}
    assert Lambertian(data="colorchecker_green").to_json() == {
        "kind": "lambertian", "data": "colorchecker_green"}
    for material in (base, fibre, metal):
        assert material_from_json(material.to_json()) == material
    with pytest.raises(InputError) as info:
        material_from_json({"kind": "conductor", "coating": {"thickness": -1, "eta": 2.0}})
    assert str(info.value) == ("material.coating.thickness = -1: must be a number of nm >= 0 "
                               "and <= 100000")
    with pytest.raises(InputError) as info:
        material_from_json({"kind": "lambertian",
                            "albedo": {"nm": [400.0], "value": [0.1, 0.2], "source": "s"}})
    assert str(info.value) == ("material.albedo: nm has 1 entries and value 2; give one value "
                               "for each wavelength")
