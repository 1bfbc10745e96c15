"""`microsim compare`: tables made from analytic models, with and without known noise."""

from __future__ import annotations

import json

import numpy as np
import pytest

from microsim.analytic.fresnel import ConductorFresnel
from microsim.analytic.registry import parse_model_spec
from microsim.comparison.metrics import compare_table
from microsim.comparison.metrics import model_table as analytic_table
from microsim.comparison.table_models import model_defaults
from microsim.tables.binning import HemisphereBins
from microsim.tables.exr import write_table
from microsim.tables.meta import TableMeta

THETA_I = np.radians([0.0, 40.0, 70.0])


def model_table(spec, sigma_rel=0.0, seed=0, meta=None):
    """A table whose bins hold the model's exact bin averages, plus Gaussian noise of a
    known relative standard deviation reported as the bins' standard error."""
    _, _, model = parse_model_spec(spec)
    return analytic_table(model, THETA_I, HemisphereBins(12, 24), sigma_rel,
                          np.random.default_rng(seed), TableMeta.from_json(meta or {"surface": {"kind": "test"}}))


def test_same_model_gives_zero_error():
    _, _, model = parse_model_spec("ggx:alpha=0.4")
    r = compare_table(model_table("ggx:alpha=0.4"), model)
    assert r.median_rel_error < 1e-12 and abs(r.z_mean) < 1e-6
    for row in r.per_theta_i:
        np.testing.assert_allclose(row.albedo_difference, 0.0, atol=1e-12)


def test_known_noise_gives_unit_z_spread():
    """Noise of relative σ 2% reported as the error: z is standard normal; over the lobe
    bins of 3 incidences × 3 channels (several hundred values) its mean lies within
    4/√N of 0 and its spread within 4/√(2N) of 1."""
    _, _, model = parse_model_spec("beckmann:alpha=0.3")
    r = compare_table(model_table("beckmann:alpha=0.3", 0.02, seed=3), model)
    n = 3 * sum(row.lobe_bins for row in r.per_theta_i)
    assert n > 200
    assert abs(r.z_mean) < 4 / np.sqrt(n) and abs(r.z_std - 1) < 4 / np.sqrt(2 * n)
    assert 0.01 < r.median_rel_error < 0.02  # median |N(0, 0.02)| = 0.0135


METRIC_KEYS = ["median_rel_error", "p90_rel_error", "rms_error", "z_mean", "z_std",
               "lobe_bins", "albedo_sim", "albedo_model", "albedo_difference",
               "albedo_model_err"]


def test_json_of_a_comparison_has_the_documented_keys_in_order():
    """The JSON of a comparison (what ``compare --json`` prints beside the model): the
    pooled keys, then one row per incidence whose metrics come before θi, φi and the
    multiple-scattering share; bins compared on their own have no incidence keys; the
    verdict's keys. Every value is plain JSON (no numpy scalars or arrays), and NaN
    stays NaN (``print_json`` prints it as null)."""
    from microsim.comparison.agreement import agreement
    from microsim.comparison.metrics import metrics

    _, _, model = parse_model_spec("beckmann:alpha=0.3")
    table = model_table("beckmann:alpha=0.3", 0.02, seed=3)
    result = compare_table(table, model)
    data = result.to_json()
    assert list(data) == ["median_rel_error", "p90_rel_error", "z_mean", "z_std",
                          "error_model", "realisations", "dof", "per_theta_i"]
    assert len(data["per_theta_i"]) == len(THETA_I)
    for row, record in zip(data["per_theta_i"], result.per_theta_i, strict=True):
        assert list(row) == [*METRIC_KEYS, "theta_i", "phi_i", "multiple_scattering_share"]
        assert row["albedo_sim"] == record.albedo_sim.tolist()
    assert [row["theta_i"] for row in data["per_theta_i"]] == pytest.approx([0, 40, 70])
    assert json.loads(json.dumps(data)) == data
    assert list(agreement(result).to_json()) == ["agrees", "lobe_bins", "z_mean_max",
                                                 "z_std_max", "significance"]
    flat = np.ones((2, 2, 3))
    alone = metrics(flat, np.full_like(flat, np.nan), flat, np.ones((2, 2))).to_json()
    assert list(alone) == METRIC_KEYS and np.isnan(alone["z_mean"])


def test_different_model_reports_the_known_difference():
    """Lambertian 0.8 against Lambertian 0.6: every bin is off by exactly 1/3 and the
    albedo by 0.2."""
    _, _, model = parse_model_spec("lambertian:albedo=0.6")
    r = compare_table(model_table("lambertian:albedo=0.8"), model)
    assert r.median_rel_error == pytest.approx(1 / 3, rel=1e-9)
    for row in r.per_theta_i:
        np.testing.assert_allclose(row.albedo_difference, 0.2, rtol=1e-6)


def test_defaults_come_from_the_table():
    meta = {"surface": {"alpha_realised": 0.27},
            "recipe": {"material": {"base": {"kind": "conductor", "eta": [0.2, 0.9, 1.1],
                                             "k": [3.9, 2.4, 2.1]}}}}
    d = model_defaults(TableMeta.from_json(meta))
    assert d == {"alpha": 0.27, "eta": [0.2, 0.9, 1.1], "k": [3.9, 2.4, 2.1]}
    _, params, model = parse_model_spec("beckmann", d)
    assert params["alpha"] == 0.27 and isinstance(model.fresnel, ConductorFresnel)
    assert model_defaults(TableMeta.from_json({"surface": {"alpha_realised": [0.1, 0.2]}})) == {
        "alpha_x": 0.1, "alpha_y": 0.2}


@pytest.fixture
def table_file(tmp_path):
    path = tmp_path / "t.exr"
    meta = {"surface": {"kind": "gaussian", "alpha_realised": 0.3},
            "recipe": {"material": {"base": {"kind": "mirror"}}}}
    write_table(model_table("beckmann:alpha=0.3", 0.02, meta=meta), path)
    return path


def test_cli_json_plots_and_report(cli, table_file, tmp_path):
    out = tmp_path / "cmp"
    code, text, _ = cli("compare", str(table_file), "--model", "beckmann", "--out", str(out),
                        "--json")
    assert code == 0
    r = json.loads(text)
    assert set(r) >= {"median_rel_error", "p90_rel_error", "z_mean", "z_std",
                      "per_theta_i", "model", "params", "report"}
    assert r["params"]["alpha"] == 0.3  # from the table
    row = r["per_theta_i"][0]
    assert set(row) >= {"theta_i", "phi_i", "median_rel_error", "p90_rel_error", "rms_error",
                        "z_mean", "z_std", "albedo_sim", "albedo_model",
                        "albedo_difference", "multiple_scattering_share"}
    report = (out / "report.md").read_text()
    assert "alpha 0.3 (the table's realised alpha), shadowing smith-correlated (default)" \
        in report  # each parameter with its source, as compare prints them
    for name in ("incidence-plane.png", "half-difference.png", "z-maps.png", "albedo.png"):
        image = out / name
        assert image.stat().st_size > 20_000, name  # a drawn figure, not an empty canvas
        assert f"]({name})" in report


@pytest.mark.parametrize(("spec", "needle"), [
    ("beckman", "models: beckmann, ggx"),           # the list of valid names
    ("beckmann:alpha=-2", "alpha = -2: must be a number >= 0.0001"),
    ("ggx:roughness=0.3", "allowed: alpha, alpha_x"),
])
def test_bad_spec_exits_2(cli, table_file, spec, needle):
    code, _, err = cli("compare", str(table_file), "--model", spec)
    assert code == 2 and err.startswith("error: ") and needle in err


def test_missing_table_exits_2(cli, tmp_path):
    code, _, err = cli("compare", str(tmp_path / "none.exr"), "--model", "ggx")
    assert code == 2 and "no such file" in err


def _image_ok(path):
    """A rendered figure, not a blank canvas: pixel std > 10 and many colours."""
    import matplotlib.image as mpimg

    img = mpimg.imread(path)[..., :3]
    return img.std() * 255 > 10 and len(np.unique(img.reshape(-1, 3), axis=0)) > 50


def test_view_table_lobe_against_model(cli, table_file, tmp_path):
    shot = tmp_path / "lobe.png"
    code, _, err = cli("view", str(table_file), "--theta-i", "40", "--model", "beckmann",
                       "--screenshot", str(shot))
    assert code == 0, err
    assert _image_ok(shot)


def test_view_recipe_with_ray_paths(cli, tmp_path):
    from pathlib import Path
    recipe = Path(__file__).resolve().parent.parent / "surfaces" / "gaussian-0.3.toml"
    shot = tmp_path / "paths.png"
    code, _, err = cli("view", str(recipe), "--set", "surface.resolution=32", "--rays", "20",
                       "--tiles", "1", "--screenshot", str(shot))
    assert code == 0, err
    assert _image_ok(shot)


def test_ray_paths_escape_with_their_order():
    """On a flat mirror every path is entry → one hit → escape: order 1, 4 vertices, and
    the escaping leg is the mirror image of the incoming one (to 1e-4: the leg starts at
    the secondary-ray origin, offset ~1e-6 of the scene off the face, over a 0.26 leg)."""
    from microsim.recipe import resolve
    from microsim.surfaces import build_tile
    from microsim.view import ray_paths
    r = resolve({"surface": {"kind": "flat"}})
    paths = ray_paths(build_tile(r.surface), r.material, 0.5, 10, 4, 0)
    for points, order in paths:
        assert order == 1 and len(points) == 4
        incoming, outgoing = points[2] - points[1], points[3] - points[2]
        np.testing.assert_allclose(outgoing / np.linalg.norm(outgoing),
                                   incoming / np.linalg.norm(incoming) * [1, 1, -1], atol=1e-4)


@pytest.mark.parametrize(("argv", "needle"), [
    (["--theta-i", "95"], "--theta-i"),
    (["--model", "nosuch"], "models:"),
])
def test_view_table_bad_flags(cli, table_file, argv, needle):
    code, _, err = cli("view", str(table_file), *argv, "--screenshot", "/tmp/x.png")
    assert code == 2 and err.startswith("error: ") and needle in err


def test_view_without_display_asks_for_a_screenshot(cli, table_file, monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    code, _, err = cli("view", str(table_file))
    assert code == 2 and "--screenshot" in err


def test_the_text_and_the_report_name_the_channels_the_albedos_average(cli, tmp_path):
    """An RGB table of three different channels (Lambertian 0.8, 0.4, 0.1): the text
    report's albedo columns are the mean over R, G and B of the JSON's per-channel
    albedos, and both the text and report.md say so (an RGB table's said nothing, so a
    reader could take the column for one channel)."""
    path = tmp_path / "t.exr"
    write_table(model_table("lambertian:albedo=[0.8,0.4,0.1]"), path)
    code, text, err = cli("compare", str(path), "--model", "lambertian", "--out",
                          str(tmp_path / "cmp"))
    assert code == 0, err
    assert "channels: R, G and B; the albedos are means over them (--json gives each)" \
        in text
    assert "the albedo columns are means over them" in (tmp_path / "cmp" / "report.md") \
        .read_text(encoding="utf-8")
    code, out, _ = cli("compare", str(path), "--model", "lambertian", "--json")
    rows = json.loads(out)["per_theta_i"]
    printed = [float(line.split()[6]) for line in text.splitlines()
               if line.split()[:1] in (["0.0"], ["40.0"], ["70.0"])]
    assert printed == pytest.approx([np.mean(r["albedo_sim"]) for r in rows], abs=6e-5)
    assert len(printed) == 3 and max(printed) < 0.5  # the mean, not R's 0.8
