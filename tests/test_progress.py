"""Progress of a simulation: every batch reported, counted against the batches planned,
which an adaptive stop raises as it plans more."""

from __future__ import annotations

import math
import os
import subprocess
import sys

from microsim import load_recipe, simulate
from microsim.commands.simulate import progress_bar
from microsim.measurement.goniometer import BATCH

RAW = {"surface": {"kind": "gaussian", "alpha": 0.3, "resolution": 32, "seed": 1},
       "material": {"kind": "mirror"},
       "simulation": {"theta_i": [0, 40], "rays": 3 * (BATCH + 1000), "realisations": 3,
                      "seed": 1},
       "table": {"theta_bins": 8, "phi_bins": 16, "sh_order": 0}}


def test_every_batch_is_counted_against_the_plan():
    """2 incidences × 3 realisations × ⌈(BATCH + 1000) / BATCH⌉ = 12 batches, each
    reported once, in order, against a plan of 12 from the first report on."""
    seen = []
    simulate(load_recipe(RAW), threads=2, progress=seen.append)
    planned = 2 * 3 * math.ceil((BATCH + 1000) / BATCH)
    assert [s.batches_done for s in seen] == list(range(1, planned + 1))
    assert {s.batches_planned for s in seen} == {planned}
    assert {s.realisations for s in seen} == {3}


def test_an_adaptive_plan_grows_and_ends_done():
    """With a target error the plan grows round by round; done never passes planned and
    equals it at the end."""
    seen = []
    simulate(load_recipe(RAW, ["simulation.target_error=0.03",
                               "simulation.rays=40000"]), threads=2, progress=seen.append)
    done = [s.batches_done for s in seen]
    planned = [s.batches_planned for s in seen]
    assert done == list(range(1, len(seen) + 1))
    assert all(d <= p for d, p in zip(done, planned, strict=True))
    assert planned == sorted(planned) and planned[-1] > planned[0]
    assert done[-1] == planned[-1]


def test_the_bar_is_off_without_a_terminal():
    with progress_bar(False) as show:
        assert show is None


def test_compare_reports_every_incidence():
    """``compare_table`` calls back once per incidence, counting up to all of them."""
    import numpy as np

    from microsim.analytic.brdf import Lambertian
    from microsim.comparison.metrics import compare_table, model_table
    from microsim.tables.binning import HemisphereBins

    model = Lambertian([0.5, 0.5, 0.5])
    table = model_table(model, np.radians([0.0, 30.0, 60.0]), HemisphereBins(8, 16))
    seen = []
    compare_table(table, model, "total", lambda done, total: seen.append((done, total)))
    assert seen == [(1, 3), (2, 3), (3, 3)]


def test_step_progress_shows_only_on_a_terminal_without_json(monkeypatch, capsys):
    """``progress_steps`` gives a callback on a terminal, and None for a pipe or with
    ``--json`` (whose stdout is read by programs), so a log gets no progress lines."""
    from microsim.commands.common import progress_steps

    for tty, json_output, shown in ((False, False, False), (True, True, False),
                                    (True, False, True)):
        monkeypatch.setattr("sys.stderr.isatty", lambda tty=tty: tty)
        with progress_steps("steps", json_output) as show:
            assert (show is not None) == shown
            if show is not None:
                show(1, 2)
                show(2, 2)
    assert "steps" in capsys.readouterr().err


def test_bench_prints_no_progress_into_a_pipe(tmp_path):
    """``microsim bench --quick`` into pipes, at a hundredth of the work: nothing on stderr
    but the ``warning:`` line of the reduced effort (it printed "resolution N done" lines,
    which a log or a script reading stderr takes for warnings or errors), the summary on
    stdout."""
    env = {**os.environ, "MICROSIM_EFFORT": "0.01"}
    run = subprocess.run([sys.executable, "-m", "microsim.cli", "bench", "--quick", "--out",
                          str(tmp_path)], capture_output=True, text=True, env=env,
                         timeout=300)
    assert run.returncode == 0, run.stderr
    assert [line for line in run.stderr.splitlines() if not line.startswith("warning:")] == []
    assert "wrote" in run.stdout and (tmp_path / "bench.csv").is_file()
