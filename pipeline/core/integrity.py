"""Storage integrity: an exclusive directory lock and per-file sha256 checksums.

``DirLock`` is an ``fcntl.flock`` on a lock file that is never deleted: the kernel drops the
lock when its holder exits (even after kill -9), so there is no stale lock to take over and no
race between two processes that both find one.  The file holds the holder's host and pid, for the
message only.

Checksums are sidecars in ``sha256sum`` format (``<file>.sha256``, one line ``<hex>  <name>``),
so ``sha256sum -c part-00000.parquet.sha256`` checks one by hand.  ``write_with_checksum`` writes
the sidecar *before* the data file is renamed into place: a data file never exists without its
checksum, and a crash between the two leaves only a sidecar, which the next run overwrites.
"""
from __future__ import annotations

import fcntl
import hashlib
import os
import socket
from pathlib import Path
from typing import Callable

from pipeline.core.errors import UserError
from vibrobase.files import atomic_write_text, atomic_write_with

CHECKSUM_SUFFIX = ".sha256"


class LockBusy(UserError):
    """Another live process holds the lock."""


class DirLock:
    """Exclusive, non-blocking lock on ``path`` (a file created if absent and never removed).

    ``with DirLock(path, what="sweep"):`` raises :class:`LockBusy` naming the holder when another
    process (or another open of the same file in this process) holds it."""

    def __init__(self, path: str | os.PathLike, what: str = "writer", blocking: bool = False) -> None:
        self.path = Path(path)
        self.what = what
        self.blocking = blocking        # True: wait for the holder instead of raising LockBusy
        self._fd: int | None = None

    def acquire(self) -> "DirLock":
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX if self.blocking else fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            try:
                holder = os.pread(fd, 200, 0).decode(errors="replace").strip() or "unknown"
            finally:
                os.close(fd)
            raise LockBusy(f"{self.path.parent}: another {self.what} (host/pid {holder}) is writing here; "
                           f"wait for it to finish") from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{socket.gethostname()} {os.getpid()}\n".encode(), 0)
        self._fd = fd
        return self

    def release(self) -> None:
        """Drop the lock (the file stays: deleting it would let a third process lock a new inode)."""
        if self._fd is not None:
            try:
                os.ftruncate(self._fd, 0)
                fcntl.flock(self._fd, fcntl.LOCK_UN)
            finally:
                os.close(self._fd)
                self._fd = None

    @property
    def held(self) -> bool:
        return self._fd is not None

    def __enter__(self) -> "DirLock":
        return self.acquire()

    def __exit__(self, *exc) -> None:
        self.release()


# ------------------------------------------------------------------------------- checksums
def sha256_file(path: str | os.PathLike, bufsize: int = 1 << 20) -> str:
    """Hex sha256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while chunk := fh.read(bufsize):
            h.update(chunk)
    return h.hexdigest()


def checksum_path(path: str | os.PathLike) -> Path:
    p = Path(path)
    return p.with_name(p.name + CHECKSUM_SUFFIX)


def write_with_checksum(path: str | os.PathLike, write: Callable[[str], None]) -> str:
    """Write ``path`` atomically through ``write(tmp_path)`` (vibrobase.files) with its sidecar
    checksum; returns the hex digest.  The sidecar is written (atomically) from the finished
    temporary file *before* that file is renamed into place."""
    path = Path(path)
    digest = ""

    def fill(tmp: str) -> None:
        nonlocal digest
        write(tmp)
        digest = sha256_file(tmp)
        atomic_write_text(checksum_path(path), f"{digest}  {path.name}\n")

    atomic_write_with(path, fill)
    return digest


def verify_checksum(path: str | os.PathLike) -> str | None:
    """None when ``path`` matches its sidecar; otherwise why not (missing / unreadable / mismatch)."""
    path = Path(path)
    side = checksum_path(path)
    try:
        recorded = side.read_text().split()[0].lower()
    except FileNotFoundError:
        return f"no checksum file {side.name}"
    except (OSError, IndexError, UnicodeDecodeError):
        return f"unreadable checksum file {side.name}"
    try:
        actual = sha256_file(path)
    except OSError as e:
        return f"unreadable ({e.strerror})"
    if actual != recorded:
        return f"sha256 {actual[:12]}… differs from the recorded {recorded[:12]}… (file damaged or edited)"
    return None
