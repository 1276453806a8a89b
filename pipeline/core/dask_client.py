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


SCHEMES = ("tcp", "tls")
"""Transports a scheduler address may name (``host:port`` alone means tcp)."""
GREETING_S = 5.0
"""Seconds a scheduler has to send its handshake when probed."""
MAX_GREETING_BYTES = 2**24
"""A Dask handshake frame is a few hundred bytes; a larger announced size means something else answered."""


def check_address(address, what: str = "--scheduler") -> str:
    """The scheduler address ``address`` names: ``local:N`` with N in range, or ``tcp://host:port`` (``tls://``,
    or ``host:port`` meaning tcp) with a host and a port in 1..65535, IPv6 hosts in brackets.  UserError naming
    ``what`` and the address otherwise; nothing is contacted."""
    if not isinstance(address, str) or not address.strip() or len(address) > 300:
        raise UserError(f"{what} {str(address)[:60]!r}: expected tcp://host:port or local:N")
    address = address.strip()
    if address.startswith("local:"):
        local_workers(address)
        return address
    scheme, sep, rest = address.partition("://")
    if not sep:
        scheme, rest = "tcp", address
    if scheme not in SCHEMES:
        raise UserError(f"{what} {address}: unknown protocol '{scheme}://' (expected tcp://host:port or local:N)")
    if rest.startswith("["):
        host, close, tail = rest[1:].partition("]")
        if not close or not host or not tail.startswith(":"):
            raise UserError(f"{what} {address}: an IPv6 host is written [addr]:port, e.g. tcp://[::1]:8786")
        port_s = tail[1:]
        import ipaddress

        try:
            ipaddress.IPv6Address(host)
        except ValueError:
            raise UserError(f"{what} {address}: '{host}' is not an IPv6 address") from None
    else:
        host, colon, port_s = rest.rpartition(":")
        if not colon or not host or "/" in rest or "[" in rest or "]" in rest or ":" in host:
            raise UserError(f"{what} {address}: expected tcp://host:port (e.g. tcp://10.0.0.5:8786) or local:N")
    if not port_s.isdigit() or not 1 <= int(port_s[:6]) <= 65535:
        raise UserError(f"{what} {address}: the port must be a number in 1..65535, got '{port_s[:20]}'")
    return address if sep else f"tcp://{address}"


def probe(address: str, what: str = "--scheduler", timeout_s: float = GREETING_S) -> None:
    """UserError unless a Dask scheduler answers at the tcp:// ``address``: something must listen and send a
    Dask handshake frame (an HTTP server or another service is named as such, never read as a frame size)."""
    import socket
    import struct

    address = check_address(address, what)
    scheme, _, rest = address.partition("://")
    if scheme != "tcp":
        return
    host, _, port = rest.rpartition(":")
    host = host.strip("[]")
    try:
        with socket.create_connection((host, int(port)), timeout=timeout_s) as sock:
            head = b""
            while len(head) < 8:
                chunk = sock.recv(8 - len(head))
                if not chunk:
                    break
                head += chunk
    except socket.timeout:
        raise UserError(f"{what} {address}: not a Dask scheduler (something listens there but sent no Dask "
                        f"handshake within {timeout_s:g} s); the scheduler's port is usually 8786, the dashboard's "
                        "8787") from None
    except OSError as e:
        raise UserError(f"{what} {address}: cannot reach the Dask scheduler ({e.strerror or e})") from None
    if len(head) < 8 or head[:4] in (b"HTTP", b"SSH-", b"<htm") or struct.unpack("<Q", head)[0] > MAX_GREETING_BYTES:
        kind = "an HTTP server" if head.startswith(b"HTTP") else "not a Dask scheduler"
        raise UserError(f"{what} {address}: {kind} answered; the scheduler's port is usually 8786, the "
                        "dashboard's 8787")


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
    address = check_address(address)
    probe(address)
    try:
        client = Client(address, timeout="30s")
    except (OSError, TimeoutError) as e:
        raise UserError(f"--scheduler {address}: cannot reach the Dask scheduler ({e})") from None
    try:
        yield client
    finally:
        client.close()
