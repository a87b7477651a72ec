"""Sweeps on a Dask distributed cluster: a scheduler and two workers started as separate processes on
loopback give the same CSV, byte for byte, as the same sweep on two local processes."""
import json
import subprocess
import sys
import time

import pytest

from contouring_ros.errors import ConfigError
from contouring_ros.studies.executors import pool, source_digest
from contouring_ros.studies.sweep import run_sweep, write_sweep_csv
from contouring_ros.experiment.settings import parse_grid
from conftest import DEFAULT, shortened

pytest.importorskip("distributed")


def _dask(*args, **kwargs):
    return subprocess.Popen([sys.executable, "-m", "dask", *args], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, **kwargs)


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    """(scheduler address, processes): a scheduler on 127.0.0.1 and two single-thread workers."""
    folder = tmp_path_factory.mktemp("cluster")
    file = folder / "scheduler.json"
    scheduler = _dask("scheduler", "--host", "127.0.0.1", "--port", "0", "--dashboard-address", ":0",
                      "--scheduler-file", str(file))
    processes = [scheduler]
    try:
        deadline = time.monotonic() + 60
        while not file.exists() or not file.read_text().strip():
            assert time.monotonic() < deadline, "the Dask scheduler did not start"
            assert scheduler.poll() is None, "the Dask scheduler exited"
            time.sleep(0.2)
        address = json.loads(file.read_text())["address"]
        for i in range(2):
            processes.append(_dask("worker", address, "--nthreads", "1", "--nworkers", "1", "--no-nanny",
                                   "--host", "127.0.0.1", "--dashboard-address", ":0", "--name", f"w{i}",
                                   cwd=folder))
        from distributed import Client
        with Client(address, timeout=30) as client:
            client.wait_for_workers(2, timeout=60)
        yield address, processes
    finally:
        for process in reversed(processes):
            process.terminate()
        for process in processes:
            try:
                process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                process.kill()


def test_a_sweep_on_the_cluster_writes_the_same_csv_as_a_local_one(cluster, tmp_path):
    address, _ = cluster
    text = shortened(DEFAULT, 0.2)
    # six combinations in three vectorised chunks, two of which diverge at once
    grid = parse_grid(["ccc.kp=0.5,4,1e9", "x/servo.kappa=0.2985,0.5"])
    local = run_sweep(text, grid, workers=2)
    remote = run_sweep(text, grid, scheduler=address)
    write_sweep_csv(local, tmp_path / "local.csv")
    write_sweep_csv(remote, tmp_path / "cluster.csv")
    assert (tmp_path / "local.csv").read_bytes() == (tmp_path / "cluster.csv").read_bytes()
    assert len(local) == 6 and sum(r.scores is None for r in local) == 2
    with pool(scheduler=address) as (_, workers):
        assert workers == 2                       # two single-thread workers


def test_the_cluster_is_refused_in_one_line_when_it_cannot_be_used(cluster, monkeypatch):
    from contouring_ros.studies import executors
    with pytest.raises(ConfigError, match=r"--scheduler tcp://127.0.0.1:9: no Dask scheduler answers there"):
        monkeypatch.setattr(executors, "CONNECT_TIMEOUT", 2.0)
        with pool(scheduler="tcp://127.0.0.1:9"):
            pass
    # a worker with other source than the client's: named, and nothing runs
    address, _ = cluster
    monkeypatch.setattr(executors, "source_digest", lambda: "another checkout")
    with pytest.raises(ConfigError, match=r"worker tcp://127\.0\.0\.1:\d+: it runs other contouring_ros source"):
        with pool(scheduler=address):
            pass
    assert len(source_digest()) == 64
