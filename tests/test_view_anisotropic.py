"""``view TABLE --phi-i``: the lobe of an anisotropic table at a chosen incident azimuth;
fibre models refused where a lobe cannot show them; compare's plane of incidence for
anisotropic tables."""

from __future__ import annotations

import matplotlib.image as mpimg
import numpy as np
import pytest

from microsim.recipe import resolve
from microsim.simulation import simulate
from microsim.surfaces import build_tile
from microsim.tables.exr import write_table


@pytest.fixture(scope="module")
def cylinders_table(tmp_path_factory):
    """Gold cylinders along y over a white base: a strongly anisotropic table."""
    r = resolve({"surface": {"kind": "cylinders", "radius": 0.4, "spacing": 1.0},
                 "material": {"base": {"kind": "lambertian", "albedo": 0.9},
                              "cylinder": {"kind": "conductor"}},
                 "simulation": {"theta_i": [50.0], "phi_i": [0.0, 90.0], "rays": 20000,
                                "bounces": 4},
                 "table": {"theta_bins": 8, "phi_bins": 16}})
    path = tmp_path_factory.mktemp("aniso") / "cyl.exr"
    write_table(simulate(build_tile(r.surface), r.material, r.simulation, r.table,
                         threads=1, recipe=r), path)
    return path


def test_view_lobe_follows_the_incident_azimuth(cli, cylinders_table, tmp_path):
    """Across the cylinders (φi = 0) the cone of reflections is a fan in the xz plane;
    along them (φi = 90°) it is a cone about y: the two screenshots differ, and each is
    a rendered image."""
    shots = []
    for phi in ("0", "90"):
        shot = tmp_path / f"lobe{phi}.png"
        code, out, err = cli("view", str(cylinders_table), "--theta-i", "50", "--phi-i",
                             phi, "--screenshot", str(shot))
        assert code == 0, err
        img = mpimg.imread(shot)[..., :3]
        assert img.std() * 255 > 10
        shots.append(img)
    assert np.abs(shots[0] - shots[1]).mean() * 255 > 1.0


def test_view_refuses_bad_azimuths_and_delta_models(cli, cylinders_table, tmp_path):
    code, _, err = cli("view", str(cylinders_table), "--phi-i", "400", "--screenshot",
                       str(tmp_path / "x.png"))
    assert code == 2 and err.startswith("error: --phi-i")
    code, _, err = cli("view", str(cylinders_table), "--model", "cylinders",
                       "--screenshot", str(tmp_path / "x.png"))
    assert code == 2 and "delta" in err and err.count("\n") == 1


def test_compare_draws_every_incident_azimuth_of_an_anisotropic_table(cli, cylinders_table,
                                                                      tmp_path):
    """``compare --out`` on an anisotropic table writes the plane-of-incidence figure
    (one row per φi) and reports the exact single-scattering model's fit."""
    code, out, err = cli("compare", str(cylinders_table), "--model", "cylinders",
                         "--component", "single", "--out", str(tmp_path), "--json")
    assert code == 0, err
    assert (tmp_path / "incidence-plane.png").stat().st_size > 5000
    assert not (tmp_path / "half-difference.png").exists()
