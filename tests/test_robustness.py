"""Bad and extreme input as a new user gives it: one ``error:`` line and exit 2, never a
traceback, and no silently wrong output."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import numpy as np
import pytest
from figurelint import figure_layout_faults
from tablefixtures import changed

ROOT = Path(__file__).resolve().parent.parent
SURFACES = ROOT / "surfaces"
GAUSSIAN = str(SURFACES / "gaussian-0.3.toml")
SMALL = ["--set", "surface.resolution=32", "--set", "simulation.theta_i=[0, 60]",
         "--set", "table.theta_bins=8", "--set", "table.phi_bins=16",
         "--set", "table.sh_order=4"]
"""A small table: 32² tile, 2 incidences, 8 × 16 bins, harmonics to order 4."""


def one_error_line(code: int, err: str, *needles: str) -> str:
    """Assert exit 2 with exactly one ``error:`` line on stderr holding every needle."""
    lines = [line for line in err.strip().splitlines() if not line.startswith("warning:")]
    assert code == 2, err
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    return lines[0]


# --- recipes that are not recipes ---------------------------------------------------------
def test_binary_recipe_is_an_error_line(cli, tmp_path):
    path = tmp_path / "random.toml"
    path.write_bytes(np.random.default_rng(0).integers(0, 256, 300, np.uint8).tobytes())
    code, _, err = cli("check", str(path))
    one_error_line(code, err, str(path), "not UTF-8")


def test_oversized_recipe_is_refused_before_it_is_read_whole(cli, tmp_path):
    """An endless input (/dev/zero) or a huge file is refused after reading at most
    ``MAX_BYTES + 1`` bytes."""
    from microsim.recipe import MAX_BYTES

    path = tmp_path / "huge.toml"
    path.write_text("# comment\n" * (MAX_BYTES // 10 + 1), encoding="utf-8")
    code, _, err = cli("check", str(path))
    one_error_line(code, err, str(path), "larger than")
    if Path("/dev/zero").exists():
        code, _, err = cli("check", "/dev/zero")
        one_error_line(code, err, "/dev/zero", "larger than")


def test_folder_as_recipe_is_an_error_line(cli, tmp_path):
    code, _, err = cli("check", str(tmp_path))
    one_error_line(code, err, str(tmp_path), "cannot read")


# --- shipped recipes and what commands print about a tile -------------------------------
def test_mesh_recipe_simulates_and_reports_its_roughness_without_a_target(cli, tmp_path):
    """A mesh has a realised roughness but no target: the summary says so, and so does
    ``measure g1`` (no "target None")."""
    out_path = tmp_path / "mesh.exr"
    code, out, err = cli("simulate", str(SURFACES / "mesh-example.toml"), "--rays", "2000",
                         "--set", "table.sh_order=2", "-o", str(out_path))
    assert code == 0, err
    assert out_path.is_file()
    line = next(line for line in out.splitlines() if line.startswith("surface:"))
    assert "alpha realised" in line and "target" not in line
    code, out, err = cli("measure", "g1", str(SURFACES / "mesh-example.toml"), "--rays",
                         "2000", "--theta", "0,60")
    assert code == 0, err
    assert "None" not in out and "alpha realised" in out


def test_generate_prints_rounded_summaries_not_a_value_per_groove(cli, tmp_path):
    """A million grooves print one line of slope facts; numbers carry 4 significant
    figures in text (JSON keeps full precision)."""
    recipe = SURFACES / "vgroove-30.toml"
    code, out, err = cli("generate", str(recipe), "--set", "surface.grooves=1000000",
                         "-o", str(tmp_path / "v.ply"))
    assert code == 0, err
    assert len(out) < 2000, len(out)
    slopes = next(line for line in out.splitlines() if "slopes_deg" in line)
    assert "count 1000000" in slopes and "29.99999" not in slopes and "min 30," in slopes
    code, out, _ = cli("generate", GAUSSIAN, "-o", str(tmp_path / "g.ply"))
    realised = next(line for line in out.splitlines() if "alpha_realised" in line)
    assert len(realised.split(":")[1].strip()) <= 6, realised
    code, out, _ = cli("generate", GAUSSIAN, "-o", str(tmp_path / "g.ply"), "--json")
    assert len(str(json.loads(out)["alpha_realised"])) > 8  # full precision in JSON


# --- damaged tables -----------------------------------------------------------------------
def truncated(table: Path, folder: Path, fraction: float) -> Path:
    """A copy of ``table`` cut to ``fraction`` of its bytes."""
    data = table.read_bytes()
    path = folder / f"cut-{round(100 * fraction)}.exr"
    path.write_bytes(data[: int(len(data) * fraction)])
    return path


@pytest.mark.parametrize("fraction", [0.001, 0.1, 0.3, 0.46, 0.7, 0.95, 0.99])
def test_truncated_table_in_every_reading_command(cli, small_table, tmp_path, fraction):
    """Every command that reads a table exits 0 or 2 on a truncated copy, with one error
    line naming the file; ``sh`` names the damaged harmonics part when the bins survive."""
    cut = str(truncated(small_table, tmp_path, fraction))
    runs = {
        "compare": ["compare", cut, "--model", "beckmann", "--json"],
        "export": ["export", cut, "--format", "npz", "-o", str(tmp_path / "t.npz")],
        "fit": ["fit", cut, "--model", "beckmann", "--json"],
        "view": ["view", cut, "--screenshot", str(tmp_path / "v.png")],
        "sh": ["sh", cut, "--json"],
    }
    codes = {}
    for name, argv in runs.items():
        code, out, err = cli(*argv)
        codes[name] = code
        if code == 2:
            one_error_line(code, err, cut)
        else:
            assert code == 0, (name, err)
            if "--json" in argv:
                assert out.lstrip().startswith("{"), (name, out[:300], err)
                json.loads(out)
    if codes["compare"] == 0:  # the bins survived: only the harmonics may be lost
        if codes["sh"] == 2:
            code, _, err = cli(*runs["sh"])
            one_error_line(code, err, "spherical-harmonics part cannot be read")
            code, _, err = cli(*runs["compare"])
            assert "warning:" in err and "spherical-harmonics" in err
    else:
        code, _, err = cli(*runs["compare"])
        one_error_line(code, err, "damaged")


def test_damaged_harmonics_keep_stdout_clean_json(small_table, tmp_path):
    """OpenEXR's core prints its complaint about a damaged part on the C stdout: run as a
    separate process, ``compare --json`` still prints nothing but JSON there."""
    import subprocess
    import sys

    cut = truncated(small_table, tmp_path, 0.99)
    run = subprocess.run([sys.executable, "-m", "microsim.cli", "compare", str(cut),
                          "--model", "beckmann", "--json"], capture_output=True, text=True,
                         check=False)
    assert run.returncode == 0, run.stderr
    json.loads(run.stdout)
    assert run.stderr.strip().splitlines() == [line for line in run.stderr.strip().splitlines()
                                               if line.startswith("warning:")]
    assert "spherical-harmonics part cannot be read" in run.stderr


# --- outputs that cannot be written -------------------------------------------------------
def _no_work(*args, **kwargs):
    raise AssertionError("the work started before the output was checked")


@pytest.mark.parametrize(
    ("argv", "flag", "patch"),
    [
        (["simulate", GAUSSIAN, "-o", "{file}/t.exr"], "--output", "microsim.measurement.simulation.simulate_recipe"),
        (["simulate", GAUSSIAN, "-o", "{folder}"], "--output", "microsim.measurement.simulation.simulate_recipe"),
        (["demo", "-o", "{file}/t.exr"], "--output", "microsim.measurement.simulation.simulate_recipe"),
        (["demo", "-o", "{tmp}/d.exr", "--plot", "{file}/p.png"], "--plot", "microsim.measurement.simulation.simulate_recipe"),
        (["generate", GAUSSIAN, "-o", "{file}/t.ply"], "--output", "microsim.surfaces.build_tile"),
        (["export", "{table}", "--format", "npz", "-o", "{file}/t.npz"], "--output", "microsim.tables.export.write_npz"),
        (["compare", "{table}", "--model", "beckmann", "--out", "{file}"], "--out", "microsim.comparison.metrics.compare_table"),
        (["compare", "{table}", "--model", "beckmann", "--out", "{file}/r"], "--out", "microsim.comparison.metrics.compare_table"),
        (["bench", "--quick", "--out", "{file}/b"], "--out", "microsim.bench.sweep"),
        (["fit", "{table}", "--model", "ggx", "--plot", "{file}/f.png"], "--plot", "microsim.comparison.fit.fit_table"),
        (["sh", "{table}", "--plot", "{file}/s.png"], "--plot", "microsim.tables.sh_error.order_errors"),
        (["sh", "{table}", "--matrix", "{folder}"], "--matrix", "microsim.tables.sh_error.order_errors"),
        (["measure", "ndf", GAUSSIAN, "--plot", "{file}/n.png"], "--plot", "microsim.measurement.facets.measure_ndf_recipe"),
        (["view", GAUSSIAN, "--screenshot", "{file}/v.png"], "--screenshot", "microsim.surfaces.build_tile"),
        (["batch", str(ROOT / "scripts" / "sweep-roughness.toml"), "-o", "{file}"], "--output", "microsim.batch.run_batch"),
        (["render", "{table}", "-o", "{file}/r.png"], "--output", "microsim.render.scene.render"),
    ],
)
def test_unwritable_output_is_refused_before_the_work(cli, small_table, tmp_path, monkeypatch,
                                                      argv, flag, patch):
    """A path under a file, or a folder where a file is wanted: one error line naming the
    flag, before anything is computed (the work is replaced by a trap)."""
    (tmp_path / "a-file").write_text("x")
    (tmp_path / "a-folder.exr").mkdir()
    names = {"file": str(tmp_path / "a-file"), "folder": str(tmp_path / "a-folder.exr"),
             "tmp": str(tmp_path), "table": str(small_table)}
    monkeypatch.setattr(patch, _no_work)
    code, _, err = cli(*[a.format(**names) for a in argv])
    one_error_line(code, err, flag)


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_read_only_folder_is_refused_before_the_work(cli, tmp_path, monkeypatch):
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o500)
    monkeypatch.setattr("microsim.measurement.simulation.simulate_recipe", _no_work)
    code, _, err = cli("simulate", GAUSSIAN, "-o", str(locked / "t.exr"))
    one_error_line(code, err, "--output", "cannot write")


def test_stale_temporaries_of_the_target_are_removed(tmp_path):
    """A writer killed during a write leaves ``.<name>.<pid>.<hex>.tmp``: the next write of
    the same target removes it; a live writer's file and other targets' files stay."""
    import subprocess
    import sys

    from microsim.files import atomic_path

    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone.wait()
    stale = tmp_path / f".t.exr.{gone.pid}.0123abcd.tmp"
    live = tmp_path / f".t.exr.{os.getpid()}.4567abcd.tmp"
    other = tmp_path / f".u.exr.{gone.pid}.89abcdef.tmp"
    for path in (stale, live, other):
        path.write_bytes(b"partial")
    with atomic_path(tmp_path / "t.exr") as tmp:
        tmp.write_bytes(b"whole")
    assert not stale.exists() and live.exists() and other.exists()
    assert (tmp_path / "t.exr").read_bytes() == b"whole"


# --- the memory guard ---------------------------------------------------------------------
SWEEP = str(ROOT / "scripts" / "sweep-roughness.toml")


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["export", "{table}", "--format", "rgl", "--resolution", "1000000", "-o", "{tmp}/x.bsdf"], "--resolution 1000000"),
        (["view", GAUSSIAN, "--rays", "1000000000", "--screenshot", "{tmp}/v.png"], "--rays 1000000000"),
        (["measure", "g1", GAUSSIAN, "--rays", "1000000000"], "--rays 1000000000"),
        (["generate", str(SURFACES / "velvet.toml"), "--set", "surface.density=1e300", "-o", "{tmp}/v.ply"], "surface: this tile"),
        (["simulate", GAUSSIAN, "--memory-limit", "0.01", "-o", "{tmp}/t.exr"], "0.01 GiB limit"),
        (["measure", "g1", GAUSSIAN, "--memory-limit", "0.01"], "0.01 GiB limit"),
        (["measure", "ndf", GAUSSIAN, "--memory-limit", "0.01"], "0.01 GiB limit"),
        (["batch", SWEEP, "-o", "{tmp}/b", "--memory-limit", "0.01"], "point alpha=0.1_kind=mirror: surface: this tile"),
        (["measure", "ndf", GAUSSIAN, "--set", "surface.resolution=32", "--bins", "100000000"], "--bins 100000000"),
        (["view", GAUSSIAN, "--set", "surface.resolution=32", "--tiles", "1000", "--screenshot", "{tmp}/v.png"], "--tiles 1000"),
        (["export", "{table}", "--format", "merl", "--memory-limit", "0.1", "-o", "{tmp}/x.binary"], "--format merl"),
    ],
)
def test_memory_guard_refuses_before_the_work(cli, capsys, small_table, tmp_path, monkeypatch,
                                              argv, needle):
    """Work over the budget is refused before it starts (the tracers and the cluster are
    traps), with the estimate in 3 significant figures and a flag the command has."""
    # the tracers where the commands use them (modules that import them by name hold their
    # own reference), the cluster and the exporter
    for trap in ("microsim.measurement.scene.PeriodicScene", "microsim.measurement.masking.PeriodicScene",
                 "microsim.measurement.simulation.PeriodicScene", "microsim.commands.batch.dask_client",
                 "microsim.tables.export.write_rgl", "microsim.tables.export.write_merl",
                 "microsim.view.show_tile"):
        monkeypatch.setattr(trap, _no_work)
    code, _, err = cli(*[a.format(table=small_table, tmp=tmp_path) for a in argv])
    line = one_error_line(code, err, needle, "--memory-limit")
    estimate = line.split("needs about ")[1].split(" GiB")[0]
    assert len(estimate) <= 9, line  # e.g. 1.34e+295
    # the flag the message names is one the command takes
    command = argv[:2] if argv[0] == "measure" else argv[:1]
    with pytest.raises(SystemExit):
        cli(*command, "--help")
    assert "--memory-limit" in capsys.readouterr().out


def test_memory_guard_bounds_the_walks_of_a_monte_carlo_model(cli, small_table):
    """beckmann-ms with 10^7 walks per bin (the most a spec takes) asks for tens of GiB;
    refused before a walk."""
    code, _, err = cli("compare", str(small_table), "--model",
                       "beckmann-ms:samples=10000000")
    line = one_error_line(code, err, "samples = 10000000", "lower the model's samples",
                          "$MICROSIM_MEMORY_LIMIT")
    assert "needs about" in line


def test_second_batch_on_a_locked_folder_stops_before_a_cluster(cli, tmp_path, monkeypatch):
    """Another process holds the folder's lock: exit 2 at once, no cluster started."""
    import subprocess
    import sys

    folder = tmp_path / "out"
    folder.mkdir()
    holder = subprocess.Popen(
        [sys.executable, "-c", "import fcntl, sys, time\n"
         f"f = open({str(folder / '.batch.lock')!r}, 'a')\n"
         "fcntl.flock(f, fcntl.LOCK_EX)\nprint('locked', flush=True)\ntime.sleep(60)"],
        stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "locked"
        monkeypatch.setattr("microsim.commands.batch.dask_client", _no_work)
        code, _, err = cli("batch", SWEEP, "-o", str(folder))
        one_error_line(code, err, "another batch is writing this folder")
    finally:
        holder.kill()
        holder.wait()


# --- extreme geometry ---------------------------------------------------------------------
SIGMA = """
[surface]
kind = "gaussian"
sigma = 0.005
correlation_length = 0.03
resolution = 32
"""


@pytest.mark.parametrize(
    ("sets", "needle"),
    [
        (["surface.size=1e300"], "surface.size = 1e+300"),
        (["surface.size=1e-300"], "surface.size = 1e-300"),
        (["surface.sigma=1e300"], "surface.sigma = 1e+300"),
        (["surface.sigma=1e-6"], "surface.sigma = 1e-06: gives alpha"),
        (["surface.sigma=1"], "surface.sigma = 1.0: gives alpha"),
        (["surface.correlation_length=1e-300"], "surface.correlation_length = 1e-300"),
        (["surface.correlation_length=1e-5"], "gives alpha = 2 sigma / correlation_length = 1e+03"),
        (["surface.correlation_length=5"], "surface.correlation_length = 5.0: gives a correlation length"),
        (["surface.size=1e9"], "surface.correlation_length = 0.03"),
    ],
)
def test_extreme_gaussian_geometry_is_an_error_line(cli, tmp_path, sets, needle):
    recipe = tmp_path / "sigma.toml"
    recipe.write_text(SIGMA, encoding="utf-8")
    code, _, err = cli("check", str(recipe), *[a for s in sets for a in ("--set", s)])
    one_error_line(code, err, needle)


@pytest.mark.parametrize(
    ("recipe", "sets", "needle"),
    [
        ("gaussian-0.3.toml", ["surface.alpha=1e-300"], "surface.alpha = 1e-300: must be a number >= 0.001"),
        ("gaussian-0.3.toml", ["surface.alpha_x=0.5", "surface.alpha_y=0.001", "surface.alpha=nan"], "surface.alpha = nan"),
        ("gaussian-0.3.toml", ["surface.resolution=4"], "surface.resolution = 4"),
        ("cylinders.toml", ["surface.length=1e9"], "at most 10000 times smaller than surface.length"),
        ("velvet.toml", ["surface.size=1e-300"], "surface.size = 1e-300"),
        ("paint.toml", ["surface.top_alpha=1e-9"], "surface.top_alpha = 1e-09"),
        ("vgroove-rough-facets.toml", ["surface.micro_correlation=1e-7"], "surface.micro_correlation"),
    ],
)
def test_extreme_values_of_other_surfaces_are_error_lines(cli, recipe, sets, needle):
    code, _, err = cli("check", str(SURFACES / recipe), *[a for s in sets for a in ("--set", s)])
    one_error_line(code, err, needle)


@pytest.mark.parametrize("size", [1e-9, 1e9])
def test_lengths_at_the_bounds_give_finite_tables(cli, tmp_path, size):
    """The scale-free tracer at the ends of the length range: every value finite, the
    albedo of a closed mirror surface within 1e-3 of 1 (16 bounces lose less)."""
    import microsim

    out = tmp_path / "t.exr"
    code, _, err = cli("simulate", GAUSSIAN, *SMALL, "--set", f"surface.size={size}",
                       "--rays", "2000", "-o", str(out), "--json")
    assert code == 0, err
    table = microsim.read_table(out)
    for c in ("total", "single"):
        assert np.isfinite(table[c].values).all()
    assert np.abs(table.albedo - 1).max() < 1e-3


# --- silent wrongs ------------------------------------------------------------------------
def test_dielectric_of_index_one_is_refused(cli):
    """eta = 1 is no interface: nothing reflects, so a table of zeros with NaN errors."""
    code, _, err = cli("check", GAUSSIAN, "--set", "material.kind=dielectric",
                       "--set", "material.eta=1")
    one_error_line(code, err, "material.eta = 1", "> 1")


def test_nothing_escaping_prints_no_nan(cli, tmp_path):
    """A black material: albedo 0, its standard error and the median relative standard
    error undefined, printed as n/a (never "nan")."""
    code, out, err = cli("simulate", GAUSSIAN, *SMALL, "--rays", "500", "--set",
                         "material.kind=lambertian", "--set", "material.albedo=0",
                         "-o", str(tmp_path / "black.exr"))
    assert code == 0, err
    assert "nan" not in out.lower() and "n/a" in out


def leaky_mesh(folder: Path, keep: float = 0.3, seed: int = 0) -> Path:
    """The shipped 64² tile with most faces removed: rays leak through the holes."""
    import trimesh

    mesh = trimesh.load(SURFACES / "tile-gaussian-64.ply", process=False, force="mesh")
    rng = np.random.default_rng(seed)
    faces = mesh.faces[rng.random(len(mesh.faces)) < keep]
    recipe = folder / "leaky.toml"
    trimesh.Trimesh(mesh.vertices, faces, process=False).export(folder / "leaky.ply")
    recipe.write_text('[surface]\nkind = "mesh"\npath = "leaky.ply"\nperiod = [1.0, 1.0]\n'
                      "[simulation]\ntheta_i = [0, 60]\n[table]\ntheta_bins = 8\n"
                      "phi_bins = 16\nsh_order = 0\n", encoding="utf-8")
    return recipe


def test_lost_energy_is_warned_and_recorded_in_the_table(cli, tmp_path):
    """A mesh that keeps 30% of its faces leaks most rays: simulate warns on stderr, the
    table's metadata carries the warning and compare repeats it; a closed surface (the
    small Gaussian tile) carries none."""
    import microsim
    from microsim.measurement.goniometer import LOST_WARNING

    recipe = leaky_mesh(tmp_path)
    out = tmp_path / "leaky.exr"
    code, _, err = cli("simulate", str(recipe), "--rays", "3000", "-o", str(out))
    assert code == 0, err
    warned = [line for line in err.splitlines() if line.startswith("warning: lost energy")]
    assert len(warned) == 1 and "underside" in warned[0], err
    table = microsim.read_table(out)
    assert table.meta.warnings and "lost energy" in table.meta.warnings[0]
    assert max(max(d.lost) for d in table.meta.directions) > LOST_WARNING
    code, _, err = cli("compare", str(out), "--model", "lambertian")
    assert code == 0 and "warning:" in err and "lost energy" in err
    closed = tmp_path / "closed.exr"
    code, _, err = cli("simulate", GAUSSIAN, *SMALL, "--rays", "3000", "-o", str(closed))
    assert code == 0 and "lost energy" not in err
    assert microsim.read_table(closed).meta.warnings == ()


# --- output a user can read ---------------------------------------------------------------
def test_the_two_relative_errors_have_different_names(cli, small_table, tmp_path):
    """simulate reports the median relative *standard* error (its own noise); compare,
    fit and demo the median relative error *against the model*."""
    code, out, _ = cli("simulate", GAUSSIAN, *SMALL, "--rays", "2000", "-o",
                       str(tmp_path / "t.exr"))
    assert "median relative standard error" in out and "against the model" not in out
    code, out, _ = cli("simulate", GAUSSIAN, *SMALL, "--rays", "2000", "-o",
                       str(tmp_path / "t.exr"), "--json")
    keys = json.loads(out)
    assert "median_rel_stderr" in keys and "median_rel_error" not in keys
    code, out, _ = cli("compare", str(small_table), "--model", "beckmann")
    assert "median relative error against the model" in out and "standard error" not in out


def test_verdict_follows_the_error_bars():
    """Tables of a model with Gaussian noise of 2% reported as their error agree with it
    (10 seeds; each check errs with probability about 2e-3); reported errors half the
    real noise (z spread 2) or a model 5% off disagree, and the verdict line says which.
    The spread bound equals the
    chi-square quantile: for N lobe bins it lies within 1% of Wilson-Hilferty's
    1 + z_(1-alpha) / sqrt(2N) (asymptotic; N > 500 here)."""
    from scipy.stats import norm

    from microsim.analytic.registry import parse_model_spec
    from microsim.comparison.agreement import agreement, verdict_text
    from microsim.comparison.metrics import compare_table
    from microsim.comparison.metrics import model_table as analytic_table
    from microsim.tables.binning import HemisphereBins

    _, _, model = parse_model_spec("beckmann:alpha=0.3")
    theta = np.radians([0.0, 40.0, 70.0])
    bins = HemisphereBins(16, 32)
    for seed in range(10):
        table = analytic_table(model, theta, bins, 0.02, np.random.default_rng(seed))
        check = agreement(compare_table(table, model))
        assert check.agrees, (seed, check)
    n = check.lobe_bins
    assert n > 500
    approx = 1 + norm.ppf(1 - check.significance) / np.sqrt(2 * n)
    assert check.z_std_max == pytest.approx(approx, rel=0.01)
    result = compare_table(table, model)
    assert verdict_text(result, agreement(result)).startswith("verdict: agrees")
    half = analytic_table(model, theta, bins, 0.02, np.random.default_rng(0))
    half = changed(half, errors=lambda e: e.errors / 2)
    result = compare_table(half, model)
    assert not agreement(result).agrees
    assert verdict_text(result, agreement(result), "x").startswith("verdict (x): differs")
    _, _, off = parse_model_spec("beckmann:alpha=0.315")
    assert not agreement(compare_table(analytic_table(model, theta, bins, 0.02,
                                                      np.random.default_rng(0)), off)).agrees


VERDICT = re.compile(
    r"^verdict \((?P<what>[^)]*)\): (?P<word>agrees|differs) .*has mean (?P<mean>-?[\d.]+) "
    r"and spread (?P<std>[\d.]+) over (?P<n>\d+) lobe bins; noise alone gives a mean "
    r"within ±(?P<mean_max>[\d.]+) and a spread up to (?P<std_max>[\d.]+) at "
    r"significance 0.001")


def test_demo_ends_with_a_verdict_line_per_model(cli, tmp_path):
    """One line per comparison (single scattering against Torrance-Sparrow, all orders
    against the multiple-scattering model), each saying agrees or differs — and saying
    it because of its numbers: "agrees" exactly when |z mean| and the spread it prints
    are within the bounds it prints, and those numbers are the comparison of the table
    it wrote (recomputed from the file, to the printed two decimals; the file holds
    float32 values, so 0.006)."""
    import microsim
    from microsim.commands.demo import comparison, total_comparison
    from microsim.comparison.agreement import agreement

    out_table = tmp_path / "d.exr"
    code, out, err = cli("demo", "--rays", "3000", "-o", str(out_table))
    assert code == 0, err
    verdicts = [VERDICT.match(line) for line in out.splitlines()
                if line.startswith("verdict (")]
    assert len(verdicts) == 2 and all(verdicts), out
    table = microsim.read_table(out_table)
    _, _, single, _ = comparison(table)
    _, _, total, _ = total_comparison(table)
    for m, result in zip(verdicts, (single, total), strict=True):
        mean, std = float(m["mean"]), float(m["std"])
        inside = abs(mean) <= float(m["mean_max"]) and std <= float(m["std_max"])
        assert (m["word"] == "agrees") == inside, m.group(0)
        check = agreement(result)
        assert int(m["n"]) == check.lobe_bins
        assert abs(result.z_mean - mean) < 0.006 and abs(result.z_std - std) < 0.006
        assert abs(check.z_mean_max - float(m["mean_max"])) < 0.006
        assert abs(check.z_std_max - float(m["std_max"])) < 0.006


def test_fit_reports_progress_and_rounds_to_its_uncertainty(small_table):
    """The fit calls back after every model evaluation (counting up); parameters print
    to the decimal place of their uncertainty's second significant figure."""
    import microsim
    from microsim.commands.common import with_error
    from microsim.comparison.fit import fit_table

    seen = []
    result = fit_table(microsim.read_table(small_table), "beckmann", progress=seen.append)
    assert [s.evaluations for s in seen] == list(range(1, len(seen) + 1))
    assert len(seen) >= result.nfev
    assert with_error(0.29117715, 0.0012345) == "0.2912 ± 0.0012"
    assert with_error(12345.6, 230.0) == "12350 ± 230"
    assert with_error(3.14159, 0.5) == "3.14 ± 0.50"


def test_fit_json_is_the_records_json_then_the_tables_keys(cli, small_table):
    """``microsim fit --json`` prints ``FitResult.to_json()`` (the keys docs/compare.md
    lists, in that order) followed by the table's error model, realisations and realised
    alpha; the fit is deterministic, so the command's values equal a second fit's."""
    import microsim
    from microsim.comparison.fit import fit_table

    code, out, err = cli("fit", str(small_table), "--model", "beckmann", "--json")
    assert code == 0, err
    printed = json.loads(out)
    assert list(printed) == ["model", "params", "uncertainty", "held", "held_sources",
                             "chi2_dof", "median_rel_error", "per_theta_i", "nfev",
                             "error_model", "realisations", "alpha_realised", "units"]
    record = fit_table(microsim.read_table(small_table), "beckmann").to_json()
    assert json.loads(json.dumps(record)) == {k: printed[k] for k in record}
    assert [list(row) for row in printed["per_theta_i"]] == [
        ["theta_i", "phi_i", "albedo_fit", "albedo_table"]] * len(printed["per_theta_i"])


def test_view_says_when_a_lobe_is_interpolated(cli, small_table, tmp_path, monkeypatch):
    """The small table holds theta_i 0 and 60: 30 is drawn interpolated and 75 as the
    nearest (60), both said in the title and on stderr; 60 is drawn as measured."""
    titles = []
    monkeypatch.setattr("microsim.view.show_lobe",
                        lambda *a, title="", **k: titles.append(title))
    notes = {}
    for theta in ("30", "75", "60"):
        code, _, err = cli("view", str(small_table), "--theta-i", theta, "--screenshot",
                           str(tmp_path / "l.png"))
        assert code == 0, err
        notes[theta] = err
    assert "interpolated between the table's theta_i 0 and 60" in titles[0]
    assert "interpolated" in notes["30"] and notes["30"].startswith("warning: --theta-i 30")
    assert "nearest theta_i, 60 deg" in titles[1] and "nearest" in notes["75"]
    assert "measured" not in titles[2] and notes["60"] == ""


def test_the_documented_models_import_from_the_package():
    """``from microsim.analytic import ...`` gives the modules' own objects, and importing
    the package alone loads neither numpy nor scipy (the CLI's --help stays fast)."""
    import subprocess
    import sys

    import microsim.analytic as analytic
    from microsim.analytic import (
        GGX,
        Beckmann,
        TorranceSparrow,
        brdf,
        fresnel,
        fresnel_conductor,
        ndf,
    )

    assert (Beckmann, GGX) == (ndf.Beckmann, ndf.GGX)
    assert TorranceSparrow is brdf.TorranceSparrow
    assert fresnel_conductor is fresnel.fresnel_conductor
    for name in analytic.__all__:
        assert getattr(analytic, name) is not None
    with pytest.raises(AttributeError):
        analytic.NoSuchModel  # noqa: B018
    out = subprocess.run([sys.executable, "-c", "import sys, microsim.analytic\n"
                          "print(sorted({'numpy', 'scipy'} & set(sys.modules)))"],
                         capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


# --- set-up as written --------------------------------------------------------------------
def readme_block(heading: str) -> list[str]:
    """The lines of the first ```sh block after ``heading`` in README.md."""
    lines = (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
    start = lines.index("```sh", lines.index(heading)) + 1
    return lines[start:lines.index("```", start)]


def test_ci_runs_the_readme_commands_word_for_word():
    import subprocess

    setup, tests = readme_block("## Set up and run"), readme_block("## Test")
    assert len(setup) == 2 and setup[1].endswith("microsim demo") and tests == ["pytest"]
    out = subprocess.run([str(ROOT / ".ci" / "run"), "--print"], capture_output=True,
                         text=True, check=True).stdout
    assert out.splitlines() == setup + tests


@pytest.mark.parametrize("with_sudo", [False, True])
def test_the_system_packages_line_works_with_and_without_sudo(tmp_path, with_sudo):
    """The README's first line, run by bash with stand-ins for apt-get (and sudo): in a
    root shell without sudo it calls apt-get directly; with sudo, through sudo. Both
    update the package lists, then install the three EGL libraries and the LLVM library
    Mitsuba's vectorised variant needs."""
    import subprocess

    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    log = tmp_path / "log"
    (bin_dir / "apt-get").write_text(f'#!/bin/sh\necho "apt-get $*" >> {log}\n')
    if with_sudo:
        (bin_dir / "sudo").write_text(f'#!/bin/sh\necho "sudo" >> {log}\nexec "$@"\n')
    for tool in bin_dir.iterdir():
        tool.chmod(0o755)
    line = readme_block("## Set up and run")[0]
    subprocess.run(["/bin/bash", "-euo", "pipefail", "-c", line], check=True,
                   env={"PATH": str(bin_dir)})
    calls = log.read_text().splitlines()
    apt = [c for c in calls if c.startswith("apt-get")]
    assert apt == ["apt-get update",
                   "apt-get install -y libegl1 libegl-mesa0 libgl1-mesa-dri libllvm19"]
    assert calls.count("sudo") == (2 if with_sudo else 0)


# --- figures (every figure command: tests/test_figures.py) ----------------------------------
def test_comparison_figures_keep_their_texts_apart(small_table, tmp_path, monkeypatch):
    """Every figure of ``compare --out`` and ``fit --plot``: no title clipped by the edge,
    no axis label on a neighbouring panel; the fit's curve is labelled as the fit."""
    import matplotlib.pyplot as plt

    import microsim
    from microsim.analytic.registry import parse_model_spec
    from microsim.commands.compare import title_of
    from microsim.comparison.metrics import compare_table
    from microsim.comparison.table_models import model_defaults
    from microsim.plots import albedo_plot, half_difference_slices, incidence_plane, z_maps

    faults, legends = {}, {}
    close = plt.close

    def inspect(fig=None):
        faults[len(faults)] = figure_layout_faults(fig)
        legends[len(legends)] = [t.get_text() for ax in fig.axes if ax.get_legend()
                                 for t in ax.get_legend().get_texts()]
        close(fig)

    monkeypatch.setattr(plt, "close", inspect)
    table = microsim.read_table(small_table)
    name, _, model = parse_model_spec("beckmann", model_defaults(table.meta))
    bins = compare_table(table, model, "single").model
    title = title_of(table, name, "single") + ", a long title that must wrap or fit"
    incidence_plane(table, bins, tmp_path / "a.png", "single", title)
    half_difference_slices(table, model, tmp_path / "b.png", "single", title)
    z_maps(table, bins, tmp_path / "c.png", "single", title)
    albedo_plot(table, bins, tmp_path / "d.png", title)
    incidence_plane(table, bins, tmp_path / "e.png", "single", title, model_label="fit: ggx")
    assert all(not f for f in faults.values()), faults
    assert "model" in legends[0] and "fit: ggx" in legends[4] and "model" not in legends[4]


def test_half_difference_ratio_covers_the_lobe_at_every_theta_d(small_table, tmp_path,
                                                                 monkeypatch):
    """The ratio panel's mask follows the model's peak per θd: every θd row of the
    image shows some of the lobe, not only the rows near the grazing peak."""
    import matplotlib.pyplot as plt

    import microsim
    from microsim.analytic.registry import parse_model_spec
    from microsim.comparison.table_models import model_defaults
    from microsim.plots import half_difference_slices

    images = []
    close = plt.close

    def grab(fig=None):
        images.append(fig.axes[2].get_images()[0].get_array())
        close(fig)

    monkeypatch.setattr(plt, "close", grab)
    table = microsim.read_table(small_table)
    _, _, model = parse_model_spec("beckmann", model_defaults(table.meta))
    half_difference_slices(table, model, tmp_path / "h.png", "single")
    ratio = np.ma.filled(images[0].astype(float), np.nan)  # (θd, θh): imshow of img.T
    rows_shown = np.isfinite(ratio).any(axis=1)
    assert rows_shown.mean() > 0.9, rows_shown.mean()


# --- what the property-based tests found --------------------------------------------------
@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["check", GAUSSIAN, "--set", "surface.kind=[]"], "surface.kind = []"),
        (["check", GAUSSIAN, "--set", "material.kind=[1]"], "material.kind = [1]"),
        (["check", str(SURFACES / "mesh-example.toml"), "--set", "surface.path=gone.ply"], "surfaces/gone.ply': no such file"),
        (["compare", "{table}", "--model", "beckmann:alpha=1e-300"], "alpha = 1e-300"),
        (["view", "{table}", "--screenshot", "{tmp}/v.txt"], "--screenshot"),
        (["fit", "{table}", "--model", "ggx", "--plot", "{tmp}/f.txt"], "--plot"),
        (["simulate", GAUSSIAN, "--set", "table.theta_bins=2048", "--set",
          "table.phi_bins=4096", "-o", "{tmp}/t.exr"], "table: 8,388,608 bins"),
    ],
)
def test_inputs_the_fuzzer_found(cli, small_table, tmp_path, monkeypatch, argv, needle):
    monkeypatch.setattr("microsim.measurement.simulation.simulate_recipe", _no_work)
    code, _, err = cli(*[a.format(table=small_table, tmp=tmp_path) for a in argv])
    one_error_line(code, err, needle)


def test_ndf_of_a_tile_with_empty_sub_tiles(cli):
    """A flat tile of two triangles leaves most of the 4 x 4 error sub-tiles empty: the
    histogram stays finite (no warning), and undefined errors print as n/a."""
    code, out, err = cli("measure", "ndf", str(SURFACES / "flat-lambertian.toml"))
    assert code == 0, err
    assert "nan" not in out and "n/a" in out


def test_plots_take_the_format_of_their_suffix(cli, small_table, tmp_path):
    code, _, err = cli("sh", str(small_table), "--plot", str(tmp_path / "s.pdf"))
    assert code == 0, err
    assert (tmp_path / "s.pdf").read_bytes().startswith(b"%PDF")


def test_control_characters_stay_on_one_line(cli, tmp_path):
    """A value with a control character (here the record separator, a line boundary to
    str.splitlines) is escaped in the error line."""
    code, _, err = cli("check", str(SURFACES / "cylinders.toml"), "--set",
                       "material.kind=table", "--set", 'material.path="a\\u001eb\\nc"')
    line = one_error_line(code, err, "material.path")
    assert "\\x1e" in line and "\\n" in line


def test_agreement_bounds_are_the_documented_quantiles():
    """The bounds are z_{1−α/2}/√N and √(χ²_{1−α}(N − 1)/(N − 1)) at α = 0.001
    (docs/compare.md; z_0.9995 = 3.2905 from the normal table), also for few bins: one
    bin cannot agree (no spread) and reports no spread bound; two can. The verdict line
    prints the numbers, and a differing one the median relative error in %; ``to_json``
    holds the bounds under their documented keys."""
    from types import SimpleNamespace

    from scipy.stats import chi2

    from microsim.comparison.agreement import agreement, verdict_text

    def comparison(n: int, z_mean: float, z_std: float) -> SimpleNamespace:
        return SimpleNamespace(per_theta_i=[SimpleNamespace(lobe_bins=n)], z_mean=z_mean,
                               z_std=z_std, median_rel_error=0.1234)

    for n in (2, 7, 900):
        check = agreement(comparison(n, 0.0, 1.0))
        assert check.z_mean_max == pytest.approx(3.2905267 / np.sqrt(n), rel=1e-7)
        assert check.z_std_max == pytest.approx(np.sqrt(chi2.ppf(0.999, n - 1) / (n - 1)),
                                                rel=1e-12)
        assert check.agrees and check.lobe_bins == n and check.significance == 1e-3
    one = agreement(comparison(1, 0.0, float("nan")))
    assert not one.agrees and np.isnan(one.z_std_max)
    assert one.z_mean_max == pytest.approx(3.2905267, rel=1e-7)
    assert one.to_json() == {"agrees": False, "lobe_bins": 1,
                             "z_mean_max": one.z_mean_max, "z_std_max": one.z_std_max,
                             "significance": 1e-3}
    result = comparison(900, 0.5, 1.0)
    check = agreement(result)
    text = verdict_text(result, check)
    assert not check.agrees and text.startswith("verdict: differs")
    assert "has mean 0.50 and spread 1.00 over 900 lobe bins" in text
    assert f"within ±{check.z_mean_max:.2f} and a spread up to {check.z_std_max:.2f}" in text
    assert text.endswith("the median relative error against the model is 12.3%")
