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
import socket
import struct
import time
from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager
from pathlib import Path

from ..errors import ConfigError

__all__ = ["pool", "source_digest"]

CONNECT_TIMEOUT = 30.0     # seconds to reach the scheduler and for its first worker to join
PROBE_TIMEOUT = 5.0        # seconds for the scheduler's address to accept a connection and send its greeting
_GREETING_LIMIT = 65536    # bytes a Dask scheduler's greeting (its handshake frames) stays well under


def scheduler_address(address: str) -> tuple:
    """(scheme, host, port) of a ``--scheduler`` address: ``tcp://HOST:PORT`` (or ``HOST:PORT``) or
    ``tls://HOST:PORT`` with Dask's TLS settings (distributed.comm.tls.ca-file and a client certificate)
    configured. ConfigError in one line for anything else (another scheme, no host, no port or a port out of
    1-65535), before any connection."""
    scheme, sep, rest = address.partition("://")
    if not sep:
        scheme, rest = "tcp", address
    if scheme not in ("tcp", "tls"):
        raise ConfigError(f"--scheduler {address}: scheme {scheme}:// is not one a Dask scheduler is reached by "
                          "here (tcp://HOST:PORT, or tls://HOST:PORT with Dask's TLS settings)")
    host, colon, port = rest.rpartition(":")
    host = host[1:-1] if host.startswith("[") and host.endswith("]") else host
    if not colon or not host or "/" in rest or any(c.isspace() for c in rest):
        raise ConfigError(f"--scheduler {address}: expected {scheme}://HOST:PORT (e.g. tcp://10.0.0.5:8786)")
    if not port.isdigit() or not 1 <= int(port) <= 65535:
        raise ConfigError(f"--scheduler {address}: port {port!r} is not a number from 1 to 65535")
    if scheme == "tls" and not _tls_configured():
        raise ConfigError(f"--scheduler {address}: tls:// needs Dask's TLS settings (distributed.comm.tls.ca-file "
                          "and distributed.comm.tls.client.cert in the Dask configuration); none are set")
    return scheme, host, int(port)


def _tls_configured() -> bool:
    try:
        import dask
    except ImportError:
        return False
    return bool(dask.config.get("distributed.comm.tls.ca-file", None)
                and dask.config.get("distributed.comm.tls.client.cert", None))


def _tls_context():
    from distributed.security import Security
    return Security().get_connection_args("client")["ssl_context"]


def probe_scheduler(address: str, timeout: float = PROBE_TIMEOUT) -> None:
    """Check that a Dask scheduler answers at ``address`` before a client is made: connect within
    ``timeout`` s and read its greeting (a Dask server sends its handshake as soon as it accepts: an 8-byte
    length, then msgpack frames that name its Python and pickle protocol) within ``timeout`` s more.
    ConfigError in one line when nothing accepts, nothing is said (a port that accepts and never answers, an
    HTTP server waiting for a request), or what is said is not a Dask greeting."""
    scheme, host, port = scheduler_address(address)
    deadline = time.monotonic() + 2 * timeout
    try:
        sock = socket.create_connection((host, port), timeout=timeout)
    except OSError as error:
        raise ConfigError(f"--scheduler {address}: no Dask scheduler answers there ({error.strerror or error})") \
            from None
    try:
        if scheme == "tls":
            sock = _tls_context().wrap_socket(sock, server_hostname=host)
        head = _read(sock, 8, deadline)
        size = struct.unpack("<Q", head)[0] if len(head) == 8 else None
        if size is None or not 8 <= size <= _GREETING_LIMIT:
            raise ConfigError(f"--scheduler {address}: something answers there, but not a Dask scheduler (it "
                              f"began with {head[:8]!r})")
        body = _read(sock, min(size, _GREETING_LIMIT), deadline)
        if b"pickle-protocol" not in body and b"python" not in body:
            raise ConfigError(f"--scheduler {address}: something answers there, but not a Dask scheduler")
    except (OSError, TimeoutError) as error:
        raise ConfigError(f"--scheduler {address}: no Dask scheduler answers there ({error.strerror or error})") \
            from None
    finally:
        sock.close()


def _read(sock, n: int, deadline: float) -> bytes:
    """Up to ``n`` bytes from ``sock`` by ``deadline`` (ConfigError-free: short when the peer stops)."""
    data = b""
    while len(data) < n:
        left = deadline - time.monotonic()
        if left <= 0:
            raise TimeoutError(f"no Dask greeting within {PROBE_TIMEOUT * 2:g} s")
        sock.settimeout(left)
        try:
            chunk = sock.recv(n - len(data))
        except socket.timeout:
            raise TimeoutError(f"no Dask greeting within {PROBE_TIMEOUT * 2:g} s") from None
        if not chunk:
            break
        data += chunk
    return data


def source_digest() -> str:
    """SHA-256 of the package's Python source (every ``*.py`` under contouring_ros/, by relative path)."""
    root = Path(__file__).resolve().parents[1]
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        digest.update(str(path.relative_to(root)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def _worker_digest() -> str:
    """Run on a worker: its contouring_ros's :func:`source_digest`, or why it has none."""
    try:
        from contouring_ros.studies.executors import source_digest as digest
    except ImportError as error:
        return f"cannot import contouring_ros: {error}"
    return digest()


class _Cluster:
    """A Dask client's executor and its thread count, closed with the client."""

    def __init__(self, scheduler: str):
        scheduler_address(scheduler)        # the address first: one line before anything is imported or dialled
        try:
            from distributed import Client
        except ImportError:
            raise ConfigError(f"--scheduler {scheduler}: the Dask distributed package is not installed "
                              "(pip install distributed)") from None
        probe_scheduler(scheduler)
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
def pool(workers: int | None = None, scheduler: str | None = None, initializer=None, initargs: tuple = (),
         tasks: int | None = None):
    """(executor, workers): local processes (``workers``, default one per core, never more than ``tasks``
    where the number of tasks is known: a process with nothing to do is not started; each runs
    ``initializer(*initargs)`` first where given), or the Dask cluster whose scheduler is at ``scheduler``
    (then ``workers`` is the cluster's thread count, the argument and the initializer are ignored). Refused
    in one line (:class:`ConfigError`) when the cluster cannot be used."""
    if scheduler:
        cluster = _Cluster(scheduler)
        try:
            yield cluster.executor, cluster.workers
        finally:
            cluster.close()
        return
    workers = workers or os.cpu_count() or 1
    if tasks is not None:
        workers = max(1, min(workers, tasks))
    with ProcessPoolExecutor(max_workers=workers, initializer=initializer, initargs=initargs) as local:
        yield local, workers
