"""No NaN written with exit 0: inputs whose numbers the simulation cannot carry are refused
where they are taken (the recipe's keys and their bounds), and what is accepted, up to its
bounds, simulates to a finite table."""

from __future__ import annotations

import math

import mpmath
import numpy as np
import pytest
from test_robustness import GAUSSIAN, SMALL, SURFACES, one_error_line

import microsim
from microsim.materials.conductor import ETA_MAX
from microsim.materials.optics import fresnel_conductor

TINY = SMALL[:-1] + ["table.sh_order=2"]


def assert_finite_table(path) -> microsim.BRDFTable:
    """The table at ``path``: values, albedos, dof finite; errors NaN only in empty bins."""
    table = microsim.read_table(path)  # refuses NaN values, albedos and harmonics
    for c in table.components:
        v, e = table[c].values, table[c].errors
        assert np.all(np.isfinite(v)) and np.all(np.isfinite(table[c].albedo))
        assert np.all(np.isfinite(e) | (v == 0))
        assert np.all(np.isfinite(table[c].dof))
    return table


def mp_conductor(cos_i: float, eta: float, k: float) -> float:
    """Unpolarised conductor Fresnel reflectance in 50-digit complex arithmetic (Born &
    Wolf sec. 14.2: the dielectric r_s, r_p with the complex index n = eta + i k)."""
    with mpmath.workdps(50):
        c = mpmath.mpf(cos_i)
        n = mpmath.mpc(eta, k)
        cos_t = mpmath.sqrt(1 - (1 - c * c) / (n * n))
        r_s = (c - n * cos_t) / (c + n * cos_t)
        r_p = (n * c - cos_t) / (n * c + cos_t)
        return float((abs(r_s) ** 2 + abs(r_p) ** 2) / 2)


@pytest.mark.parametrize("eta", [1e-9, 1.0, 7.0, ETA_MAX])
@pytest.mark.parametrize("k", [0.0, 1e-9, 3.0, ETA_MAX])
def test_the_kernels_conductor_fresnel_is_exact_up_to_the_bounds(eta, k):
    """Over the whole accepted range of eta and k, the kernel's real-arithmetic Fresnel
    agrees with 50-digit complex arithmetic to 1e-9 (float64 round-off of a handful of
    operations on numbers up to |n|^4 = 4e8) at normal, oblique and near-grazing
    incidence, and is 1 at grazing incidence (where the complex form is 0/0 for n = 1)."""
    for cos_i in (1.0, 0.7, 0.2, 1e-3):
        f = fresnel_conductor(cos_i, eta, k)
        assert math.isfinite(f)
        assert abs(f - mp_conductor(cos_i, eta, k)) < 1e-9, (cos_i, f)
    assert fresnel_conductor(0.0, eta, k) == 1.0


@pytest.mark.parametrize(("sets", "needle"), [
    (["material.eta=1e100", "material.k=0"], "material.eta = 1e+100"),
    (["material.k=1e150"], "material.k = 1e+150"),
    (["material.eta=[1, 2, 1e300]"], "material.eta[2] = 1e+300"),
])
def test_a_conductor_beyond_the_bounds_is_refused(cli, sets, needle):
    argv = ["check", GAUSSIAN, "--set", "material.kind=conductor"]
    for s in sets:
        argv += ["--set", s]
    code, _, err = cli(*argv)
    one_error_line(code, err, needle, "<= 100")


@pytest.mark.parametrize(("eta", "k"), [(ETA_MAX, 0.0), (ETA_MAX, ETA_MAX), (1e-9, ETA_MAX)])
def test_a_conductor_at_the_bounds_simulates_to_a_finite_table(cli, tmp_path, eta, k):
    path = tmp_path / "c.exr"
    code, _, err = cli("simulate", GAUSSIAN, *TINY, "--rays", "400", "--set",
                       "material.kind=conductor", "--set", f"material.eta={eta}",
                       "--set", f"material.k={k}", "-o", str(path))
    assert code == 0, err
    table = assert_finite_table(path)
    assert np.all(table.albedo > 0.9)  # |n| = 100: F > 0.96 at every angle but grazing


def test_fewer_rays_than_two_per_given_realisation_are_refused(cli, tmp_path):
    code, _, err = cli("simulate", GAUSSIAN, *TINY, "--rays", "32", "--realisations", "64",
                       "-o", str(tmp_path / "t.exr"))
    one_error_line(code, err, "simulation.rays = 32", ">= 128", "realisations = 64")
    assert not (tmp_path / "t.exr").exists()
    code, _, err = cli("check", str(SURFACES / "vgroove-30.toml"), "--set",
                       "simulation.rays=1")
    one_error_line(code, err, "simulation.rays = 1", ">= 2")


def test_fewer_rays_than_the_default_realisations_lower_them_with_a_warning(cli, tmp_path):
    """32 rays and the generator's default realisations (64 for a 32² tile): 16
    realisations of 2 rays, said in a warning; every error and dof is finite where a ray
    landed."""
    path = tmp_path / "t.exr"
    code, _, err = cli("simulate", GAUSSIAN, *TINY, "--rays", "32", "-o", str(path))
    assert code == 0, err
    assert "warning: simulation.realisations: 16 instead of the generator's default" in err
    table = assert_finite_table(path)
    assert np.all(table.realisations == 16)


@pytest.mark.parametrize("angles", ["[30, 30]", "[60, 30]", "[0, 0.0]"])
def test_a_repeated_or_unordered_incidence_is_refused(cli, angles):
    code, _, err = cli("check", GAUSSIAN, "--set", f"simulation.theta_i={angles}")
    one_error_line(code, err, "simulation.theta_i", "distinct and increasing")
    code, _, err = cli("check", str(SURFACES / "vgroove-30.toml"), "--set",
                       f"simulation.phi_i={angles}")
    one_error_line(code, err, "simulation.phi_i", "distinct and increasing")
