"""``BRDFTable`` on small hand-made tables: what the constructor stores (dtypes, defaults,
the optional fields), the component names (their order, aliases and refusals), the lobe
mask, the median relative error, the refusals of ``eval``, and the per-realisation
albedos of an estimate whose realisations skip a direction."""

from __future__ import annotations

import warnings
from dataclasses import FrozenInstanceError, replace

import numpy as np
import pytest
from tablefixtures import table_of

from microsim.tables.assemble import from_realisations
from microsim.tables.binning import HemisphereBins
from microsim.tables.meta import TableMeta
from microsim.tables.table import ComponentEstimate, by_component, components_of

COMPONENTS = ("total", "order1", "order2+")


def ints(shape, start=0):
    """Nested Python lists of consecutive integers from ``start`` (exactly representable
    as floats), of ``shape``."""
    return (np.arange(np.prod(shape), dtype=np.int64).reshape(shape) + start).tolist()


def small_table(values=None, errors=None, rays=((10,), (20,)), **kw):
    """A table of two incidences (θi = 0 and 1 rad), one φi, 2 × 2 outgoing bins, RGB and
    the components total, order1, order2+ (``single`` given for order1); every array a
    Python list of integers unless given."""
    a, b, nt, nph = 2, 1, 2, 2
    per_bin = (a, b, nt, nph, 3)
    if values is None:
        values = {c: ints(per_bin, k) for k, c in enumerate(("total", "single", "order2+"))}
    if errors is None:
        errors = {c: ints(per_bin, 10 * k) for k, c in enumerate(COMPONENTS)}
    albedo = {c: ints((a, b, 3), k) for k, c in enumerate(COMPONENTS)}
    albedo_err = {c: ints((a, b, 3), 5 + k) for k, c in enumerate(COMPONENTS)}
    return table_of(HemisphereBins(nt, nph), [0, 1], [0], True, values, errors,
                     [list(r) for r in rays], albedo, albedo_err, ints((a, b, 3)),
                     TableMeta(), **kw)


def test_table_stores_every_given_field_as_documented():
    """Integer lists become float64 arrays with the same (exact) values: the angles, the
    values, errors, albedos and their errors, the lost energy, the degrees of freedom,
    inflation, ray errors, harmonics and their errors and the per-realisation albedos; the
    ray and realisation counts given as floats become int64; the raw sums are kept as the
    very objects given; the per-component mappings are keyed by the stored names in the
    table's order (``single`` stored as ``order1``). Exact: integers are floats exactly."""
    shape = (2, 1, 3)
    raw = {name: {c: object() for c in COMPONENTS}
           for name in ("sums", "sums_sq", "sh_sums", "sh_sums_sq")}
    given = {
        "dof": {c: ints(shape, 1 + k) for k, c in enumerate(COMPONENTS)},
        "inflation": {c: ints(shape, 2 + k) for k, c in enumerate(COMPONENTS)},
        "ray_errors": {c: ints((2, 1, 2, 2, 3), 3 + k) for k, c in enumerate(COMPONENTS)},
        "sh": {c: ints((2, 1, 4, 3), 4 + k) for k, c in enumerate(COMPONENTS)},
        "sh_err": {c: ints((2, 1, 4, 3), 5 + k) for k, c in enumerate(COMPONENTS)},
        "realisation_albedo": {c: ints((3, 2, 1, 3), 6 + k)
                               for k, c in enumerate(COMPONENTS)},
    }
    realisation_rays, lost = object(), object()
    t = small_table(rays=((10.0,), (20.0,)), realisations=[[2.0], [3.0]],
                    realisation_rays=realisation_rays, lost=lost, **given, **raw)
    assert t.components == COMPONENTS

    def same_floats(got, expected):
        assert isinstance(got, np.ndarray) and got.dtype == np.float64
        np.testing.assert_array_equal(got, np.asarray(expected, np.int64))

    same_floats(t.theta_i, [0, 1])
    same_floats(t.phi_i, [0])
    same_floats(t.lost_energy, ints(shape))
    assert tuple(t.estimates) == COMPONENTS
    for field, start, per in (("values", 0, (2, 1, 2, 2, 3)), ("errors", None, None),
                              ("albedo", 0, shape), ("albedo_err", 5, shape)):
        for k, c in enumerate(COMPONENTS):
            expected = (ints((2, 1, 2, 2, 3), 10 * k) if field == "errors"
                        else ints(per, start + k))
            same_floats(getattr(t[c], field), expected)
    for field, data in given.items():
        for c in COMPONENTS:
            same_floats(getattr(t[c], field), data[c])
    for field, data in raw.items():
        assert all(getattr(t[c], field) is data[c] for c in COMPONENTS)
    assert t.realisation_rays is realisation_rays and t.lost is lost
    for got, expected in ((t.rays, [[10], [20]]), (t.realisations, [[2], [3]])):
        assert got.dtype == np.int64
        np.testing.assert_array_equal(got, expected)


def test_table_defaults_one_realisation_and_rays_minus_one_degrees_of_freedom():
    """Without them: one realisation per direction (int64 ones of the rays' shape), and
    per component rays − 1 degrees of freedom for every colour (float64, (a, b, 3)); the
    optional fields are None. Exact: small integers."""
    t = small_table(rays=((10,), (20,)))
    assert t.realisations.dtype == np.int64
    np.testing.assert_array_equal(t.realisations, [[1], [1]])
    for c in COMPONENTS:
        assert t[c].dof.dtype == np.float64
        np.testing.assert_array_equal(t[c].dof, [[[9.0] * 3], [[19.0] * 3]])
    for field in ("realisation_rays", "lost", "wavelets"):
        assert getattr(t, field) is None, field
    for field in ("inflation", "ray_errors", "sums", "sums_sq", "sh", "sh_err", "sh_sums",
                  "sh_sums_sq", "realisation_albedo"):
        assert all(getattr(t[c], field) is None for c in COMPONENTS), field


def test_components_are_ordered_by_their_lowest_order():
    """``total`` first, then by lowest scattering order as a number (order10 after
    order9, not after order1), a closed order before the open one from the same order;
    ``single`` is named ``order1``."""
    names = ["order11+", "order3", "order10", "total"] + [f"order{k}" for k in (9, 2, 8)]
    names += ["single", "order4", "order7", "order6", "order5"]
    assert components_of(dict.fromkeys(names)) == (
        "total", *(f"order{k}" for k in range(1, 11)), "order11+")
    assert components_of(dict.fromkeys(["order2+", "total", "order2", "order1"])) == (
        "total", "order1", "order2", "order2+")


@pytest.mark.parametrize("names", [["order1", "order2+"], ["total", "single", "order1"]])
def test_components_without_total_or_with_a_name_twice_are_refused(names):
    """The whole message, with the names as given: a mapping without ``total``, or with
    ``single`` and ``order1`` both (the same component)."""
    data = dict.fromkeys(names)
    with pytest.raises(ValueError) as info:
        components_of(data)
    assert str(info.value) == ("components must include 'total', each once; got "
                               f"{list(data)}")


def test_by_component_converts_to_the_dtype_asked_or_keeps_the_objects():
    """With a dtype, each entry is an array of it (integer lists to float64, floats to
    int64); without, the objects themselves; keys in the order of ``components``."""
    data = {"order2+": [1, 2], "single": [3], "total": [4.0, 5.0]}
    out = by_component(data, COMPONENTS, float)
    assert tuple(out) == COMPONENTS
    for c, expected in zip(COMPONENTS, ([4, 5], [3], [1, 2]), strict=True):
        assert out[c].dtype == np.float64
        np.testing.assert_array_equal(out[c], expected)
    out = by_component(data, COMPONENTS, np.int64)
    assert out["total"].dtype == np.int64
    np.testing.assert_array_equal(out["total"], [4, 5])
    out = by_component(data, COMPONENTS)
    assert tuple(out) == COMPONENTS
    assert out["total"] is data["total"] and out["order1"] is data["single"]


def test_per_component_mappings_answer_to_both_names():
    """``in`` and ``get`` take ``single`` for ``order1`` and the stored names as they are;
    a component the table lacks, or a key that is no string, is not in it, and ``get``
    gives the default then (None unless given)."""
    v = small_table().estimates
    for key in ("total", "order1", "single", "order2+"):
        assert key in v, key
        assert v.get(key) is v[key]
    assert v.get("single", 0) is v["order1"]
    for key in ("order2", "order1+", 1, None):
        assert key not in v, key
        assert v.get(key) is None
        assert v.get(key, "absent") == "absent"
    alone = by_component({"total": 1}, ("total",))
    assert "single" not in alone and "order1" not in alone and "total" in alone
    assert alone.get("single", 2) == 2 and alone.get("total") == 1


def test_component_names_and_refuses_what_the_table_lacks():
    """``single`` is ``order1``; a component the table does not hold is refused with the
    whole message listing what it holds."""
    t = small_table()
    assert t.component("single") == "order1" and t.component("order2+") == "order2+"
    with pytest.raises(ValueError) as info:
        t.component("order3")
    assert str(info.value) == "component 'order3': this table holds total, order1, order2+"


def lobe_table():
    """Two incidences of 2 × 2 bins, grey (the same f_r in R, G and B), errors likewise:
    incidence 0 has f_r 4, 2, 1, 0.3 and errors 1, NaN, 0.5, 0.1; incidence 1 is
    nothing landed (f_r 0, errors NaN) for ``total`` and ``order1`` alike."""
    f = np.zeros((2, 1, 2, 2, 3))
    f[0, 0] = np.array([[4.0, 2.0], [1.0, 0.3]])[..., None]
    e = np.full((2, 1, 2, 2, 3), np.nan)
    e[0, 0] = np.array([[1.0, np.nan], [0.5, 0.1]])[..., None]
    values = {"total": f, "order1": f / 2}
    errors = {"total": e, "order1": e / 2}
    return table_of(HemisphereBins(2, 2), [0.0, 1.0], [0.0], True, values, errors,
                     [[10], [10]], {c: np.zeros((2, 1, 3)) for c in values},
                     {c: np.zeros((2, 1, 3)) for c in values}, np.zeros((2, 1, 3)),
                     TableMeta())


def test_lobe_mask_is_the_bins_above_the_fraction_of_their_peak():
    """The total by default; with the default fraction 0.1 every bin of f_r ≥ 0.4 at
    incidence 0 (4, 2, 1, not 0.3); with 0.5 those ≥ 2; none where nothing landed."""
    t = lobe_table()
    ten = [[[[True, True], [True, False]]], [[[False, False], [False, False]]]]
    half = [[[[True, True], [False, False]]], [[[False, False], [False, False]]]]
    np.testing.assert_array_equal(t.lobe_mask(), ten)
    np.testing.assert_array_equal(t.lobe_mask("single"), ten)
    np.testing.assert_array_equal(t.lobe_mask(threshold=0.5), half)
    np.testing.assert_array_equal(t.lobe_mask("total", 0.5), half)


def test_median_rel_stderr_counts_empty_bins_as_infinitely_uncertain():
    """Over the lobe bins (f_r 4, 2, 1; errors 1, NaN, 0.5) the relative errors are 0.25,
    ∞, 0.5: median 0.5 exactly (dropping the NaN would give 0.375, keeping it NaN), for
    the total by default and for order1 (f_r and errors both halved); a table whose lobe
    is empty gives NaN without a warning."""
    t = lobe_table()
    assert t.median_rel_stderr() == 0.5
    assert t.median_rel_stderr("single") == 0.5
    empty = table_of(HemisphereBins(2, 2), [0.0], [0.0], True,
                      {"total": np.zeros((1, 1, 2, 2, 3))},
                      {"total": np.full((1, 1, 2, 2, 3), np.nan)}, [[10]],
                      {"total": np.zeros((1, 1, 3))}, {"total": np.zeros((1, 1, 3))},
                      np.zeros((1, 1, 3)), TableMeta())
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert np.isnan(empty.median_rel_stderr())


def test_eval_refuses_representations_the_table_lacks():
    """The whole messages: no wavelets, no harmonics, an unknown representation."""
    t = small_table()
    wi = wo = np.array([0.0, 0.0, 1.0])
    for representation, message in (
            ("wavelet", "this table holds no wavelets (store them with microsim wavelets "
                        "TABLE --store)"),
            ("sh", "this table holds no spherical harmonics (simulate it with [table] "
                   "sh_order > 0)"),
            ("bins", "representation must be one of ('table', 'sh', 'wavelet'), got "
                     "'bins'")):
        with pytest.raises(ValueError) as info:
            t.eval(wi, wo, representation=representation)
        assert str(info.value) == message


def test_realisation_albedos_are_stored_in_the_order_the_realisations_traced():
    """Realisation 0 traces direction 0 only, realisation 1 both (4 rays each, one bin,
    weights 0 or 1): direction 0 holds realisation 0's albedo then realisation 1's,
    direction 1 realisation 1's in the first slot and NaN in the second; the first axis
    is the most realisations of any direction (2). Exact: albedo = Σw / 4 of small
    integers."""
    rays = np.array([[[4], [0]], [[4], [4]]])
    s = np.zeros((2, 2, 1, 1, 3))
    s[0, 0] = 2.0
    s[1, 0] = 3.0
    s[1, 1] = 1.0
    t = from_realisations(HemisphereBins(1, 1), np.array([0.0, 0.5]), np.zeros(1), True,
                          rays, {"total": s}, {"total": s}, np.zeros((2, 2, 1, 3)),
                          TableMeta())
    np.testing.assert_array_equal(t.realisations, [[2], [1]])
    np.testing.assert_array_equal(
        t["total"].realisation_albedo[..., 0],
        [[[0.5], [0.25]], [[0.75], [np.nan]]])


def test_a_table_is_one_frozen_estimate_per_component():
    """``table[c]`` is the component's ``ComponentEstimate`` by either name; neither the
    table nor an estimate can be assigned to; ``with_estimate`` changes the named fields
    of one component in a copy and nothing else; ``dataclasses.replace`` of the table
    keeps the estimates and recomputes the derived names."""
    t = small_table()
    assert t["single"] is t["order1"] is t.estimates["order1"]
    assert isinstance(t["total"], ComponentEstimate)
    with pytest.raises(FrozenInstanceError):
        t.meta = TableMeta(seed=1)
    with pytest.raises(FrozenInstanceError):
        t["total"].values = np.zeros(1)
    with pytest.raises(ValueError, match="component 'order3': this table holds total, "
                       "order1, order2[+]"):
        t["order3"]
    halved = t.with_estimate("single", errors=t["order1"].errors / 2, albedo=[[[0.0] * 3]] * 2)
    np.testing.assert_array_equal(halved["order1"].errors, t["order1"].errors / 2)
    assert halved["order1"].albedo.dtype == np.float64 and not halved["order1"].albedo.any()
    assert halved["order1"].values is t["order1"].values
    assert halved["total"] is t["total"] and halved["order2+"] is t["order2+"]
    assert t["order1"].albedo.any()
    other = replace(t, meta=TableMeta(seed=5))
    assert other.meta.seed == 5 and other.components == t.components
    assert all(other[c] is t[c] for c in COMPONENTS)
