"""Where the in-process runs of sweeps, the claims' maps and the benchmark execute: local processes (one per
core by default), or the workers of a Dask distributed cluster (``--scheduler ADDRESS``).

Both are a :class:`concurrent.futures.Executor` (``submit``, ``map``): the local one is a
ProcessPoolExecutor, the cluster's is ``distributed.Client.get_executor`` (Dask's concurrent.futures
interface). The work is cut into the same tasks either way and the results are gathered in the order they
were submitted, so a cluster gives the same rows as a local run with as many workers, byte for byte in the
CSV (tested with a scheduler and two workers on loopback).

A cluster is set up with Dask's own commands (https://distributed.dask.org/en/stable/quickstart.html)::

    dask scheduler                                   # on one machine: prints tcp://HOST:8786
    dask worker tcp://HOST:8786 --nworkers 8 --nthreads 1   # on each machine with contouring_ros installed
    contouring-ros sweep CONFIG --grid ... --scheduler tcp://HOST:8786

One thread per worker process: a run is Python and numpy, held by the GIL. Every worker must run the same
contouring_ros as the client: before any work the client compares a digest of the package's source on
every worker with its own and refuses, naming the worker, where they differ or where a worker cannot import
it at all.
"""
from __future__ import annotations

import hashlib
import os
from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager
from pathlib import Path

from .errors import ConfigError

__all__ = ["pool", "source_digest"]

CONNECT_TIMEOUT = 30.0     # seconds to reach the scheduler and for its first worker to join


def source_digest() -> str:
    """SHA-256 of the package's Python source (every ``*.py`` under contouring_ros/, by relative path)."""
    root = Path(__file__).resolve().parent
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        digest.update(str(path.relative_to(root)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def _worker_digest() -> str:
    """Run on a worker: its contouring_ros's :func:`source_digest`, or why it has none."""
    try:
        from contouring_ros.executors import source_digest as digest
    except ImportError as error:
        return f"cannot import contouring_ros: {error}"
    return digest()


class _Cluster:
    """A Dask client's executor and its thread count, closed with the client."""

    def __init__(self, scheduler: str):
        try:
            from distributed import Client
        except ImportError:
            raise ConfigError(f"--scheduler {scheduler}: the Dask distributed package is not installed "
                              "(pip install distributed)") from None
        try:
            self.client = Client(scheduler, timeout=CONNECT_TIMEOUT, set_as_default=False)
        except (OSError, TimeoutError) as error:
            raise ConfigError(f"--scheduler {scheduler}: no Dask scheduler answers there ({error})") from None
        try:
            self.client.wait_for_workers(1, timeout=CONNECT_TIMEOUT)
        except TimeoutError:
            self.client.close()
            raise ConfigError(f"--scheduler {scheduler}: the scheduler has no worker after "
                              f"{CONNECT_TIMEOUT:g} s (start one: dask worker {scheduler} --nthreads 1)") from None
        mine = source_digest()
        for worker, theirs in sorted(self.client.run(_worker_digest).items()):
            if theirs != mine:
                self.client.close()
                why = theirs if theirs.startswith("cannot") else "it runs other contouring_ros source than this one"
                raise ConfigError(f"--scheduler {scheduler}: worker {worker}: {why} (install the same "
                                  "checkout on every worker: pip install -e .)")
        self.workers = max(1, sum(self.client.nthreads().values()))
        self.executor = self.client.get_executor(pure=False)

    def close(self):
        self.client.close()


@contextmanager
def pool(workers: int | None = None, scheduler: str | None = None, initializer=None, initargs: tuple = ()):
    """(executor, workers): local processes (``workers``, default one per core; each runs ``initializer(*initargs)``
    first where given), or the Dask cluster whose scheduler is at ``scheduler`` (then ``workers`` is the
    cluster's thread count, the argument and the initializer are ignored). Refused in one line
    (:class:`ConfigError`) when the cluster cannot be used."""
    if scheduler:
        cluster = _Cluster(scheduler)
        try:
            yield cluster.executor, cluster.workers
        finally:
            cluster.close()
        return
    workers = workers or os.cpu_count() or 1
    with ProcessPoolExecutor(max_workers=workers, initializer=initializer, initargs=initargs) as local:
        yield local, workers
