"""`microsim generate`, the mesh importer and the memory guard."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh

from microsim.recipe import resolve
from microsim.surfaces import build_tile

ROOT = Path(__file__).resolve().parent.parent
GAUSS = str(ROOT / "surfaces" / "gaussian-0.3.toml")



def test_generate_ply_round_trips_through_the_mesh_importer(cli, tmp_path):
    out = tmp_path / "tile.ply"
    code, text, _ = cli("generate", GAUSS, "--set", "surface.resolution=64", "-o",
                        str(out), "--json")
    assert code == 0
    facts = json.loads(text)
    assert facts["triangles"] == 2 * 64**2 and facts["period"] == [1.0, 1.0]
    assert facts["alpha_target"] == 0.3 and 0.2 < facts["alpha_realised"] < 0.33
    assert any("correlation lengths" in w for w in facts["warnings"])
    ply = trimesh.load(out, process=False)
    assert len(ply.faces) == facts["triangles"]
    assert ply.metadata["_ply_raw"]["face"]["data"]["material"].max() == 0
    tile = build_tile(resolve({"surface": {"kind": "mesh", "path": str(out),
                                           "period": [1.0, 1.0]}}).surface)
    # PLY stores float32: the imported slopes equal the generated ones to float32 precision
    rx, ry = tile.realised_alpha()
    assert np.sqrt((rx**2 + ry**2) / 2) == pytest.approx(facts["alpha_realised"], rel=1e-3)
    assert not list(tmp_path.glob(".*tmp"))
    assert out.stat().st_mode & 0o044  # readable by others under the usual umask, not 0600


def test_generate_obj(cli, tmp_path):
    out = tmp_path / "tile.obj"
    code, _, _ = cli("generate", str(ROOT / "surfaces" / "vgroove-30.toml"), "-o",
                     str(out))
    assert code == 0 and len(trimesh.load(out, process=False).faces) == 4 * 64


def mesh_recipe(tmp_path, vertices, faces, period=(1.0, 1.0)):
    path = tmp_path / "m.ply"
    trimesh.Trimesh(np.asarray(vertices, float), np.asarray(faces), process=False).export(path)
    recipe = tmp_path / "m.toml"
    recipe.write_text(f'[surface]\nkind = "mesh"\npath = "m.ply"\nperiod = {list(period)}\n')
    return str(recipe)


def test_mesh_drops_zero_area_faces_with_a_warning(tmp_path):
    v = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0.5, 0]]
    f = [[0, 1, 2], [0, 2, 3], [0, 4, 2]]  # the last one is degenerate (collinear)
    from microsim.recipe import load
    tile = build_tile(load(mesh_recipe(tmp_path, v, f)).surface)
    assert len(tile.faces) == 2 and "zero-area" in tile.warnings[0]


@pytest.mark.parametrize(("case", "needle"), [
    ("outside", "outside [0, 1]"),
    ("missing", "no such file"),
    ("garbage", "cannot read it as a mesh"),
])
def test_bad_meshes_exit_2(cli, tmp_path, case, needle):
    if case == "outside":
        recipe = mesh_recipe(tmp_path, [[0, 0, 0], [1.5, 0, 0], [1, 1, 0]], [[0, 1, 2]])
    else:
        recipe = tmp_path / "m.toml"
        recipe.write_text('[surface]\nkind = "mesh"\npath = "m.ply"\nperiod = [1, 1]\n')
        if case == "garbage":
            (tmp_path / "m.ply").write_text("this is not a mesh")
        recipe = str(recipe)
    code, _, err = cli("generate", recipe, "-o", str(tmp_path / "o.ply"))
    assert code == 2 and err.startswith("error: surface.") and needle in err


@pytest.mark.parametrize(("argv", "needle"), [
    (["--set", "surface.resolution=8192"], "over the 2 GiB limit"),
    (["--set", "surface.resolution=1024", "--memory-limit", "0.1"], "over the 0.1 GiB limit"),
    (["--memory-limit", "-1"], "--memory-limit"),
    (["--set", "surface.resolution=0"], "surface.resolution = 0"),
    (["--set", "surface.alpha=nan"], "surface.alpha = nan"),
])
def test_bad_generate_input(cli, tmp_path, argv, needle):
    code, _, err = cli("generate", GAUSS, "-o", str(tmp_path / "t.ply"), *argv)
    assert code == 2 and err.startswith("error: ") and needle in err
    assert not (tmp_path / "t.ply").exists()


def test_memory_limit_from_the_environment(cli, tmp_path, monkeypatch):
    monkeypatch.setenv("MICROSIM_MEMORY_LIMIT", "0.01")
    code, _, err = cli("generate", GAUSS, "-o", str(tmp_path / "t.ply"))
    assert code == 2 and "0.01 GiB limit" in err
    monkeypatch.setenv("MICROSIM_MEMORY_LIMIT", "lots")
    code, _, err = cli("generate", GAUSS, "-o", str(tmp_path / "t.ply"))
    assert code == 2 and "MICROSIM_MEMORY_LIMIT" in err


def test_output_suffix_checked(cli, tmp_path):
    code, _, err = cli("generate", GAUSS, "-o", str(tmp_path / "t.stl"))
    assert code == 2 and "--output" in err


def test_seed_flag_overrides_the_surface_seed(cli, tmp_path):
    runs = [json.loads(cli("generate", GAUSS, "--set", "surface.resolution=32", "-o",
                           str(tmp_path / "t.ply"), "--seed", s, "--json")[1])
            for s in ("5", "5", "6")]
    assert runs[0]["alpha_realised"] == runs[1]["alpha_realised"] != runs[2]["alpha_realised"]
