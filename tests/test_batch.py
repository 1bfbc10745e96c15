"""Batch runs: sweep files, exact merging of jobs, clusters, interruption, failures."""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from tilefixtures import random_tile

from microsim.measurement.goniometer import measure_directions
from microsim.measurement.scene import PeriodicScene
from microsim.measurement.simulation import assemble_table, simulate, simulate_recipe
from microsim.recipe import resolve
from microsim.sweep import load_sweep, point_seed
from microsim.tables.exr import read_table

BASE = """
[base.surface]
kind = "gaussian"
resolution = 32
correlation_length = 0.25
seed = 5

[base.simulation]
theta_i = [0, 40, 70]
rays = {rays}
realisations = 2
bounces = 8

[base.table]
theta_bins = 6
phi_bins = 12
"""
AXES = """
[sweep]
"surface.alpha" = [0.2, 0.5]
"material.kind" = ["mirror", "lambertian"]
"""
NAMES = ["alpha=0.2_kind=mirror", "alpha=0.2_kind=lambertian", "alpha=0.5_kind=mirror",
         "alpha=0.5_kind=lambertian"]


def write_sweep(folder: Path, head: str = "seed = 3", axes: str = AXES, rays: int = 2000,
                name: str = "sweep.toml") -> Path:
    """A sweep file of the small base recipe with the given top lines and axes."""
    path = folder / name
    path.write_text(head + "\n" + BASE.format(rays=rays) + axes, encoding="utf-8")
    return path


def table_bytes(folder: Path) -> dict[str, bytes]:
    """Every table of a folder, by file name."""
    return {p.name: p.read_bytes() for p in sorted(folder.glob("*.exr"))}


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The 4-table sweep run on a local cluster of 2 workers, one angle per job."""
    from microsim.cli import main

    folder = tmp_path_factory.mktemp("reference")
    sweep = write_sweep(folder, "seed = 3\nthetas_per_job = 1")
    assert main(["batch", str(sweep), "-o", str(folder / "out"), "--workers", "2"]) == 0
    return sweep, folder / "out"


# --- the sweep file -----------------------------------------------------------------------
@pytest.mark.parametrize("head, axes, message", [
    ("", '[sweep]\n"surface.alpah" = [0.1]\n', "surface.alpah: unknown key"),
    ("", '[sweep]\n"surface.alpha" = []\n', "empty axis"),
    ('mode = "zip"', '[sweep]\n"surface.alpha" = [0.1, 0.2]\n"simulation.rays" = [10]\n',
     "unequal lengths"),
    ("", '[sweep]\n"surface.alpha" = [0.1, -1.0]\n', "point alpha=-1.0: surface.alpha"),
    ("", '[sweep]\n"surface.alpha" = [0.1, 0.1]\n', "every point must differ"),
    ("", '[sweep]\n"colour.alpha" = [0.1]\n', "section one of"),
    ('mode = "cross"', AXES, "mode = 'cross'"),
    ("sead = 1", AXES, "sead: unknown key (did you mean 'seed'?)"),
    ("", "", "sweep: missing or empty"),
    ("seed = 1", '[sweep]\n"simulation.seed" = [1, 2]\n', "seed: unused"),
])
def test_bad_sweep_exits_2_before_any_work(tmp_path: Path, cli: Callable, head: str,
                                           axes: str, message: str) -> None:
    sweep = write_sweep(tmp_path, head, axes)
    code, out, err = cli("batch", str(sweep), "-o", str(tmp_path / "out"))
    assert code == 2 and message in err and err.startswith("error: ") and err.count("\n") == 1
    assert not (tmp_path / "out").exists()


def test_bad_base_and_scheduler_exit_2(tmp_path: Path, cli: Callable) -> None:
    (tmp_path / "s.toml").write_text('base = "nowhere.toml"\n' + AXES, encoding="utf-8")
    code, _, err = cli("batch", str(tmp_path / "s.toml"), "-o", str(tmp_path / "out"))
    assert code == 2 and "nowhere.toml: no such file" in err
    sweep = write_sweep(tmp_path)
    code, _, err = cli("batch", str(sweep), "-o", str(tmp_path / "out"), "--scheduler", "x")
    assert code == 2 and "--scheduler 'x'" in err


def test_points_names_and_seeds(tmp_path: Path) -> None:
    """Product order, readable names, and the documented seed: SeedSequence(sweep seed,
    spawn_key = first 4 little-endian 32-bit words of SHA-256 of the point's canonical
    JSON), first 64-bit word shifted right by one. A swept simulation.seed is kept."""
    sweep = load_sweep(write_sweep(tmp_path))
    assert [p.name for p in sweep.points] == NAMES
    values = {"surface.alpha": 0.2, "material.kind": "mirror"}
    digest = hashlib.sha256(b'{"material.kind":"mirror","surface.alpha":0.2}').digest()
    key = [int.from_bytes(digest[4 * i:4 * i + 4], "little") for i in range(4)]
    word = np.random.SeedSequence(3, spawn_key=key).generate_state(1, np.uint64)[0]
    assert sweep.points[0].recipe.simulation.seed == int(word) >> 1
    assert point_seed(3, dict(reversed(values.items()))) == int(word) >> 1
    assert len({p.recipe.simulation.seed for p in sweep.points}) == 4
    zipped = load_sweep(write_sweep(tmp_path, 'mode = "zip"', '[sweep]\n'
                                    '"simulation.seed" = [11, 12]\n"surface.alpha" = [0.2, 0.3]\n'))
    assert [p.name for p in zipped.points] == ["seed=11_alpha=0.2", "seed=12_alpha=0.3"]
    assert [p.recipe.simulation.seed for p in zipped.points] == [11, 12]


# --- exactness -------------------------------------------------------------------------
def test_one_worker_gives_the_same_bytes_as_two(tmp_path: Path, cli: Callable,
                                                reference: tuple[Path, Path]) -> None:
    """1 worker with 3 angles per job against 2 workers with 1 angle per job (the
    reference), each job one of the 2 realisations: identical table bytes, and each table
    equals ``simulate_recipe`` of its point."""
    sweep_path, ref = reference
    sweep = write_sweep(tmp_path, "seed = 3\nthetas_per_job = 3")
    code, out, _ = cli("batch", str(sweep), "-o", str(tmp_path / "out"), "--workers", "1",
                       "--json")
    assert code == 0 and json.loads(out)["jobs"] == 4 * 2
    assert sorted(table_bytes(ref)) == sorted(f"{n}.exr" for n in NAMES)
    assert table_bytes(tmp_path / "out") == table_bytes(ref)
    manifest = json.loads((ref / "manifest.json").read_text())
    for entry in manifest["tables"].values():
        assert entry["status"] == "done" and entry["rays"] == 3 * 2000 and entry["jobs"] == 6
        assert entry["error_model"] == "ensemble" and entry["realisations"] == 2
        assert entry["wall_s"] >= entry["trace_s"] > 0
    point = load_sweep(sweep_path).points[1]
    alone = simulate_recipe(point.recipe, threads=1)
    merged = read_table(ref / f"{point.name}.exr")
    for c in ("total", "single"):
        assert np.array_equal(merged[c].values, alone[c].values.astype(np.float32))
        assert np.array_equal(merged[c].errors, alone[c].errors.astype(np.float32),
                              equal_nan=True)
    assert merged.meta.recipe == point.recipe and merged.meta.timing is None


def test_resume_skips_done_tables_and_redoes_changed_ones(tmp_path: Path, cli: Callable
                                                          ) -> None:
    sweep = write_sweep(tmp_path, axes='[sweep]\n"surface.alpha" = [0.2, 0.5]\n', rays=500)
    out = tmp_path / "out"
    assert cli("batch", str(sweep), "-o", str(out), "--workers", "1")[0] == 0
    code, text, _ = cli("batch", str(sweep), "-o", str(out), "--workers", "1", "--json")
    assert code == 0 and json.loads(text)["skipped"] == ["alpha=0.2", "alpha=0.5"]
    write_sweep(tmp_path, axes='[sweep]\n"surface.alpha" = [0.2, 0.5]\n', rays=600)
    code, text, _ = cli("batch", str(sweep), "-o", str(out), "--workers", "1", "--json")
    assert code == 0 and json.loads(text)["computed"] == ["alpha=0.2", "alpha=0.5"]
    assert read_table(out / "alpha=0.5.exr").rays.sum() == 3 * 600


def test_a_bad_output_is_refused_before_the_sweep_is_loaded(tmp_path: Path, cli: Callable,
                                                           monkeypatch) -> None:
    """Loading and checking a sweep of a million points took 110 s before a bad -o was
    reported: the output is checked first (without creating it), the loading is a trap."""
    def trap(path):
        raise AssertionError("the sweep was loaded")

    monkeypatch.setattr("microsim.sweep.load_sweep", trap)
    (tmp_path / "a-file").write_text("x")
    code, _, err = cli("batch", str(write_sweep(tmp_path)), "-o",
                       str(tmp_path / "a-file" / "out"))
    assert code == 2 and err.startswith("error: --output") and "is a file" in err, err


def test_resume_redoes_a_done_table_whose_file_was_truncated(tmp_path: Path, cli: Callable
                                                             ) -> None:
    """The manifest says done, the file is cut to half its bytes: it is made again (it
    was skipped, and the sweep's output was a file no command reads)."""
    sweep = write_sweep(tmp_path, axes='[sweep]\n"surface.alpha" = [0.2, 0.5]\n', rays=500)
    out = tmp_path / "out"
    assert cli("batch", str(sweep), "-o", str(out), "--workers", "1")[0] == 0
    whole = (out / "alpha=0.5.exr").read_bytes()
    (out / "alpha=0.5.exr").write_bytes(whole[:len(whole) // 2])
    code, text, _ = cli("batch", str(sweep), "-o", str(out), "--workers", "1", "--json")
    result = json.loads(text)
    assert code == 0 and result["skipped"] == ["alpha=0.2"], result
    assert result["computed"] == ["alpha=0.5"]
    assert read_table(out / "alpha=0.5.exr", require_sh=True).rays.sum() == 3 * 500


def test_resume_redoes_a_table_whose_input_file_changed(tmp_path: Path, cli: Callable
                                                         ) -> None:
    """The recipe hash covers the contents of the files a recipe names: a mesh edited in
    place (same path, same recipe) makes its table be recomputed."""
    ply = ("ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
           "property float z\nelement face 2\nproperty list uchar int vertex_indices\n"
           "end_header\n0 0 0\n1 0 0\n1 1 {z}\n0 1 {z}\n3 0 1 2\n3 0 2 3\n")
    mesh = tmp_path / "ramp.ply"
    mesh.write_text(ply.format(z=0), encoding="ascii")
    sweep = tmp_path / "s.toml"
    sweep.write_text('[base.surface]\nkind = "mesh"\npath = "ramp.ply"\nperiod = [1.0, 1.0]\n'
                     '[base.simulation]\ntheta_i = [30]\nrays = 300\n'
                     '[base.table]\ntheta_bins = 2\nphi_bins = 4\n'
                     '[sweep]\n"simulation.bounces" = [4]\n', encoding="utf-8")
    out = tmp_path / "out"
    assert cli("batch", str(sweep), "-o", str(out), "--workers", "1")[0] == 0
    code, text, _ = cli("batch", str(sweep), "-o", str(out), "--workers", "1", "--json")
    assert code == 0 and json.loads(text)["skipped"] == ["bounces=4"]
    mesh.write_text(ply.format(z=0.0), encoding="ascii")        # same numbers, other bytes
    code, text, _ = cli("batch", str(sweep), "-o", str(out), "--workers", "1", "--json")
    assert code == 0 and json.loads(text)["computed"] == ["bounces=4"]


# --- failures --------------------------------------------------------------------------
def test_one_failing_point_the_rest_complete(tmp_path: Path, cli: Callable) -> None:
    """A mesh file that is missing at run time fails its table (after the retry); the
    other table is written; exit status 1; the manifest and the summary name the error."""
    ply = ("ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
           "property float z\nelement face 2\nproperty list uchar int vertex_indices\n"
           "end_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2\n3 0 2 3\n")
    (tmp_path / "flat.ply").write_text(ply, encoding="ascii")
    sweep = tmp_path / "s.toml"
    sweep.write_text('[base.surface]\nkind = "mesh"\npath = "flat.ply"\nperiod = [1.0, 1.0]\n'
                     '[base.simulation]\ntheta_i = [30]\nrays = 300\n'
                     '[base.table]\ntheta_bins = 2\nphi_bins = 4\n'
                     '[sweep]\n"surface.path" = ["flat.ply", "gone.ply"]\n', encoding="utf-8")
    code, out, _ = cli("batch", str(sweep), "-o", str(tmp_path / "out"), "--workers", "1",
                       "--json")
    summary = json.loads(out)
    assert code == 1 and summary["computed"] == ["path=flat.ply"]
    assert [f["table"] for f in summary["failed"]] == ["path=gone.ply"]
    assert "gone.ply" in summary["failed"][0]["error"]
    tables = json.loads((tmp_path / "out" / "manifest.json").read_text())["tables"]
    assert tables["path=gone.ply"]["status"] == "failed"
    assert "no such file" in tables["path=gone.ply"]["error"]
    assert tables["path=flat.ply"]["status"] == "done"
    assert np.all(read_table(tmp_path / "out" / "path=flat.ply.exr").albedo == 1.0)
    assert not (tmp_path / "out" / "path=gone.ply.exr").exists()


# --- interruption ----------------------------------------------------------------------
def test_sigkill_then_resume_equals_an_uninterrupted_run(tmp_path: Path, cli: Callable
                                                         ) -> None:
    """Kill -9 the batch as soon as its first table is written; a
    stale temporary file of a dead writer is planted too; the re-run finishes the rest,
    leaves no temporary file, and gives the bytes of an uninterrupted run."""
    axes = '[sweep]\n"surface.alpha" = [0.2, 0.3, 0.4, 0.5, 0.6, 0.7]\n'
    sweep = write_sweep(tmp_path, axes=axes, rays=40_000)
    out = tmp_path / "out"
    process = subprocess.Popen([sys.executable, "-m", "microsim.cli", "batch", str(sweep),
                                "-o", str(out), "--workers", "1"], start_new_session=True,
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 60
        while not list(out.glob("*.exr")) and time.monotonic() < deadline:
            time.sleep(0.005)
        os.kill(process.pid, signal.SIGKILL)  # the batch alone; its workers follow it
        process.wait()
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGKILL)
        process.wait()
    written = len(list(out.glob("*.exr")))
    assert 1 <= written < 6, "the kill must come after the first table, before the last"
    (out / f".alpha=0.6.exr.{process.pid}.0badf00d.tmp").write_bytes(b"partial")
    assert cli("batch", str(sweep), "-o", str(out), "--workers", "1")[0] == 0
    assert cli("batch", str(sweep), "-o", str(tmp_path / "whole"), "--workers", "1")[0] == 0
    assert len(table_bytes(out)) == 6 and table_bytes(out) == table_bytes(tmp_path / "whole")
    assert not list(out.glob("*.tmp")) and not list(out.glob(".*.tmp"))
    for name in table_bytes(out):
        assert read_table(out / name).rays.sum() == 3 * 40_000


# --- a real cluster --------------------------------------------------------------------
def free_port() -> int:
    """A TCP port of 127.0.0.1 that nothing listens on right now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def dask_cluster(tmp_path: Path) -> Iterator[tuple[str, Path]]:
    """A ``dask scheduler`` and two ``dask worker`` processes on 127.0.0.1 (each ends by
    itself after 120 s at most; killed at teardown); yields the scheduler's address and
    its scheduler file."""
    from distributed import Client

    dask = str(Path(sys.executable).with_name("dask"))
    address = f"tcp://127.0.0.1:{free_port()}"
    scheduler_file = tmp_path / "scheduler.json"
    started = [subprocess.Popen(
        [dask, "scheduler", "--host", "127.0.0.1", "--port", address.rsplit(":", 1)[1],
         "--scheduler-file", str(scheduler_file), "--no-dashboard", "--idle-timeout",
         "120s"], start_new_session=True,
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        for _ in range(2):
            started.append(subprocess.Popen(
                [dask, "worker", address, "--nthreads", "1", "--no-nanny", "--no-dashboard",
                 "--lifetime", "120s", "--host", "127.0.0.1"], start_new_session=True,
                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        with Client(address, timeout=60) as client:
            client.wait_for_workers(2, timeout=60)
        yield address, scheduler_file
    finally:
        for p in started:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()


def test_a_real_cluster_gives_the_same_bytes(tmp_path: Path, cli: Callable,
                                             dask_cluster: tuple[str, Path],
                                             reference: tuple[Path, Path]) -> None:
    """Reached by address and by scheduler file, with 2 angles per job."""
    sweep = write_sweep(tmp_path, "seed = 3\nthetas_per_job = 2")
    for how, target in zip(("address", "file"), dask_cluster, strict=True):
        code, out, _ = cli("batch", str(sweep), "-o", str(tmp_path / how), "--scheduler",
                           str(target), "--json")
        assert code == 0 and json.loads(out)["jobs"] == 4 * 2 * 2
        assert table_bytes(tmp_path / how) == table_bytes(reference[1])


def test_the_shipped_example_sweep_loads() -> None:
    sweep = load_sweep(Path(__file__).parents[1] / "scripts" / "sweep-roughness.toml")
    assert len(sweep.points) == 12 and sweep.points[0].name == "alpha=0.1_kind=mirror"
    last = sweep.points[-1].recipe.material["base"]
    assert (last.kind, last.eta) == ("dielectric", 1.5)


def test_progress_reports_every_job(tmp_path: Path) -> None:
    """The callback sees every job and table; the rich bar renders its states."""
    from microsim.batch import BatchProgress, run_batch
    from microsim.commands.batch import dask_client, progress_bar

    sweep = load_sweep(write_sweep(tmp_path, axes='[sweep]\n"surface.alpha" = [0.2, 0.5]\n',
                                   rays=300))
    states: list[BatchProgress] = []
    with dask_client(1, None) as client:
        summary = run_batch(sweep, tmp_path / "out", client, progress=states.append)
    assert [s.jobs_done for s in states] == list(range(1, 13))
    assert states[-1].tables_done == states[-1].tables == 2
    assert states[-1].rays == summary.rays == 2 * 3 * 300
    with progress_bar(True) as show:
        for state in states:
            show(state)


def dying_job(recipe: dict, thetas: tuple[int, ...], threads: int = 1,
              realisation: int | None = 0) -> object:
    """``run_job``, except that the worker process of alpha = 0.5 dies (imported by the
    workers by name)."""
    from microsim.batch import run_job

    if recipe.surface.alpha == 0.5:
        os._exit(1)
    return run_job(recipe, thetas, threads, realisation)


def test_a_dying_worker_fails_its_table_alone(tmp_path: Path,
                                              monkeypatch: pytest.MonkeyPatch) -> None:
    """A job that kills its worker is tried twice (the nanny restarts the worker), then
    its table fails with KilledWorker; the other table completes."""
    from microsim import batch
    from microsim.commands.batch import dask_client

    sweep = load_sweep(write_sweep(tmp_path, "thetas_per_job = 3",
                                   '[sweep]\n"surface.alpha" = [0.2, 0.5]\n', rays=300))
    monkeypatch.setattr(batch, "run_job", dying_job)
    with dask_client(1, None) as client:
        summary = batch.run_batch(sweep, tmp_path / "out", client)
    assert summary.computed == ["alpha=0.2"]
    assert list(summary.failed) == ["alpha=0.5"]
    assert "KilledWorker" in summary.failed["alpha=0.5"]
    assert "2 different workers" in summary.failed["alpha=0.5"]


def test_a_raising_job_is_retried_once(tmp_path: Path, monkeypatch: pytest.MonkeyPatch
                                       ) -> None:
    """On an in-process cluster: a job that raises once succeeds on its retry; one that
    always raises is tried exactly twice and fails its table with the error (the jobs of
    realisation 0 raise; those of realisation 1 run, or are cancelled with their table)."""
    from distributed import Client, LocalCluster

    from microsim import batch

    log = tmp_path / "calls.txt"
    real = batch.run_job

    def flaky(recipe: dict, thetas: tuple[int, ...], threads: int = 1,
              realisation: int | None = 0) -> object:
        alpha = recipe.surface.alpha
        if realisation == 0:
            with open(log, "a", encoding="utf-8") as f:
                f.write(f"{alpha}\n")
            if alpha == 0.5 or log.read_text().split().count(str(alpha)) == 1:
                raise RuntimeError(f"boom {alpha}")
        return real(recipe, thetas, threads, realisation)

    sweep = load_sweep(write_sweep(tmp_path, "thetas_per_job = 3",
                                   '[sweep]\n"surface.alpha" = [0.2, 0.5]\n', rays=300))
    monkeypatch.setattr(batch, "run_job", flaky)
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                      dashboard_address=None) as cluster, Client(cluster) as client:
        summary = batch.run_batch(sweep, tmp_path / "out", client)
    assert sorted(log.read_text().split()) == ["0.2", "0.2", "0.5", "0.5"]
    assert summary.computed == ["alpha=0.2"]
    assert summary.failed == {"alpha=0.5": "RuntimeError: boom 0.5"}


def test_measurements_of_disjoint_angles_merge_into_simulate() -> None:
    """Angles traced apart (one in a shared scene, in another order) assemble into the
    sums of ``simulate``; a set of parts that misses or repeats an angle, or whose parts
    were binned differently, is refused."""
    tile = random_tile(16, rms_slope=0.4, cells=3.0, seed=2)
    recipe = resolve({"surface": {"kind": "flat"}, "material": {"kind": "lambertian"},
                      "simulation": {"theta_i": [0, 30, 60], "rays": 700, "seed": 9},
                      "table": {"theta_bins": 4, "phi_bins": 8}})
    sections = recipe.material, recipe.simulation, recipe.table
    whole = simulate(tile, *sections, threads=1)
    with PeriodicScene(tile, 1) as scene:
        last = measure_directions(tile, *sections, [2], scene=scene)
        first = measure_directions(tile, *sections, [1, 0], scene=scene)
    merged = assemble_table([last, first], *sections)
    for c in ("total", "single"):
        assert merged[c].values.tobytes() == whole[c].values.tobytes()
        assert merged[c].errors.tobytes() == whole[c].errors.tobytes()
    assert merged.meta.segments == whole.meta.segments
    assert merged.meta.directions == whole.meta.directions
    assert whole.meta.timing is not None and merged.meta.timing is None
    with pytest.raises(ValueError, match="every incident polar angle once"):
        assemble_table([first], *sections)
    with pytest.raises(ValueError, match="traced twice"):
        assemble_table([first, last, last], *sections)
    other = replace(recipe.table, phi_bins=16)
    with PeriodicScene(tile, 1) as scene:
        binned_apart = measure_directions(tile, recipe.material, recipe.simulation, other,
                                          [2], scene=scene)
    assert binned_apart.axes.bins.shape == (4, 16) and first.axes.bins.shape == (4, 8)
    with pytest.raises(ValueError, match="do not share their incident directions"):
        assemble_table([binned_apart, first], *sections)
