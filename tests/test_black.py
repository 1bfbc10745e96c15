"""The black facet: a kind of its own module (microsim/materials/black.py) that absorbs
everything, in recipes, in the kernel and in comparisons."""

from __future__ import annotations

import numpy as np
import pytest
from tilefixtures import flat_tile, sections, simulate_sections

from microsim.comparison.table_models import model_defaults
from microsim.errors import InputError
from microsim.kernel.packing import FacetMaterials
from microsim.materials import Black, parse_material
from microsim.recipe import resolve
from microsim.tables.meta import TableMeta


def test_black_takes_no_keys() -> None:
    assert parse_material({"kind": "black"}, "material.") == Black()
    with pytest.raises(InputError, match=r"material\.albedo: unknown key; allowed: none"):
        parse_material({"kind": "black", "albedo": 0.5}, "material.")


def test_black_floor_absorbs_every_ray_and_the_energy_balance_closes() -> None:
    """A flat black tile: no escaping weight in any bin (f_r = 0, albedo 0 exactly), every
    ray's weight absorbed (absorbed = 1 per channel, nothing lost or transmitted), and the
    paths' fates still counted: mirrored once, they escape carrying nothing."""
    rays = 4000
    table = simulate_sections(flat_tile(), {"base": {"kind": "black"}},
                              {"theta_i": [0.0, 60.0], "rays": rays, "bounces": 4},
                              {"theta_bins": 4, "phi_bins": 8})
    assert np.all(table["total"].values == 0.0) and np.all(table.albedo == 0.0)
    for d in table.meta.directions:
        assert d.absorbed == (1.0, 1.0, 1.0)
        assert d.lost == d.transmitted == (0.0, 0.0, 0.0)
        assert d.fates["escaped"] == rays


def test_black_scatters_with_factor_zero_and_draws_nothing() -> None:
    """The kernel's event: the weight goes to zero, nothing is transmitted, the direction
    is the mirror direction (no random numbers are needed)."""
    materials, _, _ = sections({"base": {"kind": "black"}}, {}, {})
    facets = FacetMaterials(np.zeros(2, np.int64), ("base",), materials)
    d = np.array([[0.6, 0.0, -0.8], [0.0, 0.0, -1.0]])
    n = np.tile([0.0, 0.0, 1.0], (2, 1))
    out, factor, transmitted = facets.scatter(np.zeros(2, np.int64), d, n,
                                              np.random.SeedSequence(1))
    assert np.array_equal(out, d * [1, 1, -1])
    assert not factor.any() and not transmitted.any()


def test_black_base_is_the_black_base_of_single_scattering_fibre_models() -> None:
    """A black base gives the models of fibres on a black base (velvet-sparse) their
    base albedo 0; a black facet has no microfacet (Fresnel) model."""
    recipe = resolve({"surface": {"kind": "velvet"},
                      "material": {"base": {"kind": "black"},
                                   "fibre": {"kind": "lambertian", "albedo": 0.8}}})
    defaults = model_defaults(TableMeta(recipe=recipe))
    assert defaults["base_albedo"] == [0.0, 0.0, 0.0] and defaults["kind"] == "lambertian"
    with pytest.raises(ValueError, match="no microfacet model"):
        Black().fresnel()
