"""A --scheduler that is not a reachable Dask scheduler is one line, within 30 s, with no traceback: an address
Dask is not reached by here, a port that accepts and never answers, an HTTP server, a server that answers
something else."""
import http.server
import socket
import subprocess
import sys
import threading
import time

import pytest

from contouring_ros.studies import executors
from contouring_ros.errors import ConfigError

from conftest import DEFAULT, ROOT


@pytest.mark.parametrize("address, message", [
    ("inproc://scheduler", "scheme inproc:// is not one"),
    ("ws://127.0.0.1:8786", "scheme ws:// is not one"),
    ("ucx://127.0.0.1:8786", "scheme ucx:// is not one"),
    ("tcp://127.0.0.1", "expected tcp://HOST:PORT"),
    ("tcp://:8786", "expected tcp://HOST:PORT"),
    ("127.0.0.1:99999", "port '99999' is not a number from 1 to 65535"),
    ("tcp://127.0.0.1:http", "port 'http' is not a number"),
    ("tls://127.0.0.1:8786", "tls:// needs Dask's TLS settings"),
])
def test_an_address_dask_is_not_reached_by_is_refused_before_any_connection(address, message, monkeypatch):
    monkeypatch.setattr(socket, "create_connection", lambda *a, **k: pytest.fail("connected"))
    started = time.monotonic()
    with pytest.raises(ConfigError, match=f"^--scheduler {address}: .*{message}"):
        with executors.pool(scheduler=address):
            pass
    assert time.monotonic() - started < 1.0


@pytest.fixture
def server():
    """A listening socket on loopback and its address; ``serve(answer)`` accepts connections in a thread
    and sends ``answer`` (None: never a byte) on each."""
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen(8)
    held = []

    def serve(answer):
        def loop():
            while True:
                try:
                    conn, _ = listener.accept()
                except OSError:
                    return
                held.append(conn)
                if answer is not None:
                    conn.sendall(answer)
        threading.Thread(target=loop, daemon=True).start()
        return f"tcp://127.0.0.1:{listener.getsockname()[1]}"
    yield serve
    listener.close()
    for conn in held:
        conn.close()


def test_a_port_that_accepts_and_never_answers_is_refused_by_the_deadline(server, monkeypatch):
    assert 2 * executors.PROBE_TIMEOUT < 30.0            # the stated bound, connect and greeting together
    monkeypatch.setattr(executors, "PROBE_TIMEOUT", 0.5)
    address = server(None)
    started = time.monotonic()
    with pytest.raises(ConfigError, match=f"^--scheduler {address}: no Dask scheduler answers there"):
        executors.probe_scheduler(address, timeout=0.5)
    assert time.monotonic() - started < 3.0


def test_an_http_server_is_not_taken_for_a_scheduler(monkeypatch):
    httpd = http.server.HTTPServer(("127.0.0.1", 0), http.server.SimpleHTTPRequestHandler)
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    try:
        address = f"tcp://127.0.0.1:{httpd.server_address[1]}"
        with pytest.raises(ConfigError, match=f"^--scheduler {address}: no Dask scheduler answers there"):
            executors.probe_scheduler(address, timeout=0.5)
    finally:
        httpd.shutdown()
        httpd.server_close()


def test_a_server_that_answers_something_else_is_one_line_and_no_traceback(server, tmp_path):
    """The command itself, as a user runs it: one line, exit 2, nothing more on the way out."""
    address = server(b"HTTP/1.0 400 Bad Request\r\n\r\n")
    started = time.monotonic()
    done = subprocess.run([sys.executable, "-m", "contouring_ros.cli", "sweep", str(DEFAULT), "--grid",
                           "ccc.kp=1,2", "--scheduler", address, "--out", str(tmp_path / "s.csv")],
                          cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert done.returncode == 2
    assert done.stderr.strip() == f"error: --scheduler {address}: something answers there, but not a Dask " \
                                  "scheduler (it began with b'HTTP/1.0')", done.stderr
    assert time.monotonic() - started < 30.0 and not (tmp_path / "s.csv").exists()


def test_a_local_pool_never_starts_more_processes_than_it_has_tasks(monkeypatch):
    started = []

    class Recorded(executors.ProcessPoolExecutor):
        def __init__(self, max_workers=None, **kw):
            started.append(max_workers)
            super().__init__(max_workers=max_workers, **kw)
    monkeypatch.setattr(executors, "ProcessPoolExecutor", Recorded)
    from contouring_ros.experiment.files import load_experiment
    from contouring_ros.studies.sweep import run_sweep
    text = load_experiment(DEFAULT).text.replace("    sample_time: 0.001\n",
                                                 "    sample_time: 0.001\n    duration: 0.02\n", 1)
    rows = run_sweep(text, {"ccc.kp": [1.0, 2.0]}, workers=32)
    assert started == [2] and len(rows) == 2
