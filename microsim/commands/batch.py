"""``microsim batch SWEEP -o DIR``: run a sweep of tables on a Dask cluster."""

from __future__ import annotations

import argparse
import contextlib
import logging
import os
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from microsim.commands.common import add_json_arg, add_memory_arg, positive_int, print_json
from microsim.errors import InputError
from microsim.files import folder_possible, writable_folder

if TYPE_CHECKING:
    from microsim.batch import BatchProgress, BatchSummary

CONNECT_TIMEOUT = 20
"""Seconds to wait for ``--scheduler`` before giving up."""
CONNECT_GRACE = 5
"""Seconds past ``CONNECT_TIMEOUT`` that Dask's own connect may take to report its
failure before the wait ends without it."""


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``batch`` command."""
    p = sub.add_parser(
        "batch",
        help="run a sweep of recipes (one BRDF table each) on a local or remote Dask cluster",
        description="Trace every point of a sweep file (a base recipe and axes over its "
                    "keys, docs/batch.md) as jobs on Dask workers and write one OpenEXR "
                    "table per point to DIR, with DIR/manifest.json. Re-running resumes: "
                    "tables done with an unchanged recipe and input files are skipped. "
                    "Exit status 1 when a table failed (the summary and the manifest name "
                    "it).",
    )
    p.add_argument("sweep", metavar="SWEEP", type=Path, help="sweep file (TOML)")
    p.add_argument("-o", "--output", type=Path, required=True, metavar="DIR",
                   help="output folder (created if missing)")
    p.add_argument("--workers", type=positive_int, default=None,
                   help="worker processes of the local cluster (default: every CPU)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="use a running Dask cluster: its address (tcp://host:port) or a "
                        "scheduler file, instead of a local cluster")
    p.add_argument("--threads", type=positive_int, default=1,
                   help="tracing threads per job (default 1: one job per worker thread)")
    p.add_argument("--resume", action=argparse.BooleanOptionalAction, default=True,
                   help="skip tables already done with the same recipe (default); "
                        "--no-resume recomputes every table")
    add_memory_arg(p)
    add_json_arg(p)
    p.set_defaults(func=run)


LOCAL_WORKERS_PER_CPU = 4
"""At most this many workers of the local cluster per CPU: each is a process of its own
(an interpreter, numpy, the compiled kernel), and beyond the CPUs they only wait for them."""


def check_workers(workers: int | None) -> None:
    """Refuse (``InputError``) more local workers than ``LOCAL_WORKERS_PER_CPU`` per CPU,
    before a cluster starts them (``--workers 100000`` started processes until the run was
    stopped)."""
    cpus = os.cpu_count() or 1
    most = LOCAL_WORKERS_PER_CPU * cpus
    if workers is not None and workers > most:
        raise InputError(f"--workers: at most {most} on this machine ({LOCAL_WORKERS_PER_CPU}"
                         f" per CPU, {cpus} CPUs), not {workers:,}: the local cluster's "
                         "workers are processes, and more of them than CPUs only wait")


@contextlib.contextmanager
def dask_client(workers: int | None, scheduler: str | None) -> Iterator[Any]:
    """A client of a new local cluster (processes, one thread each) or of ``scheduler``."""
    import dask
    from distributed import Client, LocalCluster

    from microsim.batch import RETRIES

    if scheduler is None:
        n = workers or os.cpu_count() or 1
        # a job whose worker dies is run once more, as one that raised (Dask's default is 3);
        # a worker holds only the job it runs (no queue of its own), so its death is
        # charged to that job alone and not to jobs merely waiting there
        with dask.config.set({"distributed.scheduler.allowed-failures": RETRIES,
                              "distributed.scheduler.worker-saturation": 1.0}), \
                LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                             dashboard_address=None, silence_logs=logging.CRITICAL) as cluster, \
                Client(cluster) as client:
            yield client
        return
    if workers is not None:
        raise InputError("--workers: only for the local cluster; the cluster of "
                         "--scheduler has its own workers")
    with connected_client(scheduler) as client:
        yield client


@contextlib.contextmanager
def connected_client(scheduler: str) -> Iterator[Any]:
    """A client of the Dask scheduler at ``scheduler`` (an address or a scheduler file),
    or an ``InputError`` within ``CONNECT_TIMEOUT`` seconds and a few more.

    The client connects on a thread of its own, waited for at most that long: a port that
    accepts connections but never speaks Dask holds Dask's own connect past its timeout.
    A client that connects after the wait is closed by that thread.
    """
    import json

    from distributed import Client

    where = f"--scheduler {scheduler!r}"
    if "://" in scheduler:
        target: dict[str, Any] = {"address": scheduler}
    elif Path(scheduler).is_file():
        try:
            info = json.loads(Path(scheduler).read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, ValueError, RecursionError):
            info = None
        if not isinstance(info, dict) or not isinstance(info.get("address"), str):
            raise InputError(f"{where}: not a Dask scheduler file (JSON with an "
                             "'address', as dask scheduler --scheduler-file writes it)")
        target = {"scheduler_file": scheduler}
    else:
        raise InputError(f"{where}: neither an address (tcp://host:port) nor an existing "
                         "scheduler file")
    outcome: dict[str, Any] = {}
    abandoned = threading.Event()

    def connect() -> None:
        try:
            client = Client(**target, timeout=CONNECT_TIMEOUT)
        except Exception as exc:  # reported below, as the error line of this input
            outcome["error"] = exc
            return
        if abandoned.is_set():
            client.close()
        outcome["client"] = client

    thread = threading.Thread(target=connect, name="microsim-connect", daemon=True)
    thread.start()
    thread.join(CONNECT_TIMEOUT + CONNECT_GRACE)
    if thread.is_alive():
        abandoned.set()
        raise InputError(f"{where}: no answer within {CONNECT_TIMEOUT:g} s (is it a Dask "
                         "scheduler?)")
    if "error" in outcome:
        exc = outcome["error"]
        raise InputError(f"{where}: cannot connect: {type(exc).__name__}: "
                         f"{str(exc).splitlines()[0] if str(exc) else 'no reason given'}"
                         ) from None
    with outcome["client"] as client:
        yield client


@contextlib.contextmanager
def progress_bar(enabled: bool) -> Iterator[Any]:
    """A rich progress bar on stderr and its callback for ``run_batch``, or None."""
    if not enabled:
        yield None
        return
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    with Progress(TextColumn("tables {task.fields[tables]}"), BarColumn(),
                  TextColumn("jobs"), MofNCompleteColumn(), TextColumn("{task.fields[rate]}"),
                  TimeElapsedColumn(), TextColumn("ETA"), TimeRemainingColumn(),
                  console=Console(stderr=True)) as bar:
        task = bar.add_task("batch", total=None, tables="", rate="")

        def show(state: BatchProgress) -> None:
            rate = state.rays / max(state.elapsed, 1e-9)
            bar.update(task, total=state.jobs, completed=state.jobs_done,
                       tables=f"{state.tables_done}/{state.tables}",
                       rate=f"{rate:,.0f} rays/s")

        yield show


def print_summary(s: BatchSummary) -> None:
    """Text for people."""
    print(f"{s.tables} tables in {s.output}: {len(s.computed)} computed, "
          f"{len(s.skipped)} already done, {len(s.failed)} failed; {s.jobs} jobs, "
          f"{s.rays:,} rays in {s.wall_s:.1f} s")
    for table, error in s.failed.items():
        print(f"failed: {table}: {error}")


def run(args: argparse.Namespace) -> int:
    """Load and check the whole sweep, run it, print the summary; 1 if a table failed."""
    from microsim.batch import check_folder, output_lock, run_batch
    from microsim.commands.simulate import check_table_memory
    from microsim.surfaces import check_tile_memory
    from microsim.sweep import load_sweep

    check_workers(args.workers)
    folder_possible(args.output, "--output")  # before the points, which may be many
    sweep = load_sweep(args.sweep)
    for point in sweep.points:  # before a cluster starts (isotropy unknown: every phi_i)
        check_tile_memory(point.recipe.surface, args.memory_limit, f"point {point.name}: ")
        check_table_memory(point.recipe, False, args.memory_limit, f"point {point.name}: ")
    writable_folder(args.output, "--output")
    check_folder(args.output, sweep, args.resume)
    # the lock before the cluster: a second batch on the folder stops at once
    # the command line hands --memory-limit to the local cluster's workers (flag_limit)
    with output_lock(args.output), dask_client(args.workers, args.scheduler) as client, \
            progress_bar(sys.stderr.isatty() and not args.json) as show:
        summary = run_batch(sweep, args.output, client, resume=args.resume,
                            threads=args.threads, progress=show)
    print_json(summary.to_json()) if args.json else print_summary(summary)
    return 1 if summary.failed else 0
