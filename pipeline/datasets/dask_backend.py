"""Run sweep chunks on a Dask distributed cluster; the results come back and are written locally.

Workers only compute (``pipeline.datasets.compute.compute_chunk``, one thread per task: a worker with
several threads runs several chunks at once); this process writes each chunk atomically as it
arrives, so resumability and results are the same as a local run.  Workers must have the
``vibro`` package importable (same environment); each worker process loads (or on first use
compiles) the numba kernel once.
"""
from __future__ import annotations

import contextlib
from dataclasses import dataclass
from typing import Callable, Iterable

import pandas as pd

from pipeline.core.errors import UserError
from pipeline.datasets.compute import compute_chunk


LOCAL_PER_CORE = 4
"""``local:N`` may start at most this many worker processes per core (more only thrash the machine)."""


def local_workers(address: str) -> int:
    """N of a ``local:N`` address: an integer in [1, LOCAL_PER_CORE x cores] (UserError otherwise)."""
    import os

    cap = LOCAL_PER_CORE * (os.cpu_count() or 1)
    try:
        n = int(address.split(":", 1)[1])
    except ValueError:
        raise UserError(f"--scheduler {address}: expected local:N with N an integer") from None
    if not 1 <= n <= cap:
        raise UserError(f"--scheduler {address}: N must be in [1, {cap}] ({LOCAL_PER_CORE} worker processes per core)")
    return n


@contextlib.contextmanager
def connect(address: str):
    """A ``distributed.Client`` for ``address`` (``tcp://host:port``), or ``local:N`` for a throw-away
    LocalCluster of N single-threaded worker processes.  UserError when it cannot be reached."""
    from distributed import Client, LocalCluster

    if address.startswith("local:"):
        n = local_workers(address)
        with LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
                Client(cluster) as client:
            yield client
        return
    _check_reachable(address)
    try:
        client = Client(address, timeout="30s")
    except (OSError, TimeoutError) as e:
        raise UserError(f"--scheduler {address}: cannot reach the Dask scheduler ({e})") from None
    try:
        yield client
    finally:
        client.close()


@dataclass(frozen=True)
class DaskBackend:
    """Chunks as tasks on the Dask scheduler at ``address`` (``tcp://host:port`` or ``local:N``)."""

    address: str
    extra_packages: tuple[str, ...] = ("dask", "distributed")

    def __post_init__(self) -> None:
        if self.address.startswith("local:"):
            local_workers(self.address)      # refuse a bad N before anything is written

    @property
    def description(self) -> str:
        return f"dask {self.address}"

    def run(self, spec, chunks: Iterable[tuple[int, pd.DataFrame]],
            write: Callable[[int, pd.DataFrame], None]) -> None:
        """Submit every ``(k, points)`` chunk of ``spec`` and call ``write(k, rows)`` as each finishes.

        On an exception (including KeyboardInterrupt) pending tasks are cancelled; chunks already
        written stay on disk for the next resume."""
        run_on_dask(self.address, spec, chunks, write)


def run_on_dask(address: str, spec, chunks: Iterable[tuple[int, pd.DataFrame]],
                write: Callable[[int, pd.DataFrame], None]) -> None:
    """See :meth:`DaskBackend.run`."""
    from distributed import as_completed

    with connect(address) as client:
        keys: dict[str, int] = {}
        futures = []
        for k, pts in chunks:
            fut = client.submit(compute_chunk, spec.model, spec.preset, spec.settings, spec.fixed, pts, 1,
                                key=f"vibro-sweep-{spec.fingerprint[:16]}-{k:05d}", pure=False)
            keys[fut.key] = k
            futures.append(fut)
        try:
            for fut in as_completed(futures):
                write(keys[fut.key], fut.result())
        except BaseException:
            client.cancel(futures)
            raise


def _check_reachable(address: str, timeout_s: float = 5.0) -> None:
    """Fail fast (one line) when nothing listens at a tcp:// scheduler address."""
    import socket
    from urllib.parse import urlsplit

    if "://" not in address:
        address = "tcp://" + address
    u = urlsplit(address)
    if u.scheme != "tcp" or not u.hostname or not u.port:
        return                                    # other protocols: let distributed try
    try:
        socket.create_connection((u.hostname, u.port), timeout=timeout_s).close()
    except OSError as e:
        raise UserError(f"--scheduler {address}: cannot reach the Dask scheduler ({e})") from None
