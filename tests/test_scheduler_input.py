"""``batch --scheduler`` given something that is no Dask scheduler: one ``error:`` line and
exit 2 within the connect timeout (docs/batch.md), never a hang or a traceback: a port that
accepts connections but never speaks, a malformed scheduler file, an unknown address
scheme, a folder."""

from __future__ import annotations

import socket
import threading
import time

import pytest
from test_batch import write_sweep
from test_robustness import one_error_line

from microsim.commands import batch


@pytest.fixture
def silent_port():
    """A server on 127.0.0.1 that accepts connections and never answers (closed at
    teardown; it serves nothing but this test)."""
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(8)
    accepted = []
    stop = threading.Event()

    def accept() -> None:
        server.settimeout(0.2)
        while not stop.is_set():
            try:
                accepted.append(server.accept()[0])
            except OSError:
                continue

    thread = threading.Thread(target=accept, daemon=True)
    thread.start()
    yield f"tcp://127.0.0.1:{server.getsockname()[1]}"
    stop.set()
    thread.join(2)
    for conn in accepted:
        conn.close()
    server.close()


def test_a_port_that_never_speaks_is_an_error_within_the_timeout(cli, tmp_path, silent_port,
                                                                 monkeypatch):
    monkeypatch.setattr(batch, "CONNECT_TIMEOUT", 2)
    sweep = write_sweep(tmp_path)
    start = time.perf_counter()
    code, _, err = cli("batch", str(sweep), "-o", str(tmp_path / "out"), "--scheduler",
                       silent_port)
    assert time.perf_counter() - start < 2 + 10  # the timeout, and the CLI's start
    one_error_line(code, err, f"--scheduler {silent_port!r}", "no answer within 2 s")


@pytest.mark.parametrize(("make", "needle"), [
    (lambda p: p.write_text("{not json"), "not a Dask scheduler file"),
    (lambda p: p.write_text('{"addres": "tcp://127.0.0.1:1"}'), "not a Dask scheduler file"),
    (lambda p: p.write_text("[1, 2]"), "not a Dask scheduler file"),
    (lambda p: p.mkdir(), "neither an address"),
])
def test_a_malformed_scheduler_file_is_one_error_line(cli, tmp_path, make, needle):
    path = tmp_path / "scheduler.json"
    make(path)
    code, _, err = cli("batch", str(write_sweep(tmp_path)), "-o", str(tmp_path / "out"),
                       "--scheduler", str(path))
    one_error_line(code, err, "--scheduler", needle)


@pytest.mark.parametrize("address", ["foo://127.0.0.1:1", "tcp://", "tcp://127.0.0.1:99999"])
def test_an_address_of_an_unknown_scheme_or_port_is_one_error_line(cli, tmp_path, address,
                                                                   monkeypatch):
    monkeypatch.setattr(batch, "CONNECT_TIMEOUT", 2)
    code, _, err = cli("batch", str(write_sweep(tmp_path)), "-o", str(tmp_path / "out"),
                       "--scheduler", address)
    one_error_line(code, err, f"--scheduler {address!r}")
