"""Connecting to a Dask distributed scheduler: an address ``tcp://host:port``, or ``local:N`` for a throw-away
LocalCluster of N single-threaded worker processes on this machine (``vibro sweep`` and ``vibro diagnose``)."""
from __future__ import annotations

import contextlib
import os
from typing import Iterator

from pipeline.core.errors import UserError

LOCAL_PER_CORE = 4
"""``local:N`` may start at most this many worker processes per core (more only thrash the machine)."""


def local_workers(address: str) -> int:
    """N of a ``local:N`` address: an integer in [1, LOCAL_PER_CORE x cores] (UserError otherwise)."""
    cap = LOCAL_PER_CORE * (os.cpu_count() or 1)
    try:
        n = int(address.split(":", 1)[1])
    except ValueError:
        raise UserError(f"--scheduler {address}: expected local:N with N an integer") from None
    if not 1 <= n <= cap:
        raise UserError(f"--scheduler {address}: N must be in [1, {cap}] ({LOCAL_PER_CORE} worker processes per core)")
    return n


def check_address(address: str) -> str:
    """``address`` when it can name a scheduler: a ``local:N`` with N in range, or a non-empty address (UserError)."""
    if not isinstance(address, str) or not address.strip():
        raise UserError(f"--scheduler {address!r}: expected tcp://host:port or local:N")
    if address.startswith("local:"):
        local_workers(address)
    return address


@contextlib.contextmanager
def connect(address: str) -> Iterator:
    """A ``distributed.Client`` for ``address`` (``tcp://host:port``), or ``local:N`` for a throw-away
    LocalCluster of N single-threaded worker processes.  UserError when it cannot be reached."""
    from distributed import Client, LocalCluster

    check_address(address)
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
