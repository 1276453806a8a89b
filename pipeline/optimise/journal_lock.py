"""A journal file's lock that ages by the lock itself, so a stale lock is broken once, not twice.

optuna's :class:`~optuna.storages.journal.JournalFileSymlinkLock` judges a lock stale by ``os.stat`` of the
symbolic link, which follows the link to the journal file.  After a worker dies holding the lock, every waiter
sees the journal's unchanging mtime; the first to break the lock takes a fresh one, and a second waiter, still
reading the journal's old mtime, breaks that fresh lock too (its owner then fails with "did not possess lock").
Here the age is ``os.lstat`` of the link: a fresh lock is a new link with a new mtime, and every waiter restarts
its grace period when it sees one.
"""
from __future__ import annotations

import errno
import os
import time
import uuid

from optuna.storages.journal import JournalFileSymlinkLock

RENAME_SUFFIX = ".rename"


class LinkAgeLock(JournalFileSymlinkLock):
    """optuna's symbolic-link lock ``<journal>.lock`` (its paths and its ``release``), broken after
    ``grace_period_s`` [s] without a new link."""

    def __init__(self, journal_path: str, grace_period_s: float = 30.0) -> None:
        if grace_period_s <= 0:
            raise ValueError("grace_period_s must be positive")
        super().__init__(journal_path, grace_period=None)     # optuna's own ageing stays off
        self.grace_period_s = grace_period_s

    def acquire(self) -> bool:
        """Block until the link is created [True]; break a link that has not changed for the grace period."""
        sleep_s, seen, seen_since = 0.001, None, time.monotonic()
        while True:
            try:
                os.symlink(self._lock_target_file, self._lock_file)
                return True
            except OSError as err:
                if err.errno != errno.EEXIST:
                    raise
            try:
                identity = _identity(os.lstat(self._lock_file))
            except FileNotFoundError:
                continue
            if identity != seen:
                seen, seen_since = identity, time.monotonic()
            elif time.monotonic() - seen_since > self.grace_period_s:
                self._break(identity)
                seen, sleep_s = None, 0.001
                continue
            time.sleep(sleep_s)
            sleep_s = min(2 * sleep_s, 1.0)

    def _break(self, identity: tuple) -> None:
        """Remove the stale link, unless it was replaced since it was judged stale."""
        moved = self._lock_file + str(uuid.uuid4()) + RENAME_SUFFIX
        try:
            os.rename(self._lock_file, moved)
        except OSError:
            return
        if _identity(os.lstat(moved)) == identity or not _restore(moved, self._lock_file):
            os.unlink(moved)


def _identity(st: os.stat_result) -> tuple:
    """What tells one lock link from the next: inode and creation time of the link."""
    return (st.st_ino, st.st_mtime_ns)


def _restore(moved: str, lock_file: str) -> bool:
    """Put back a fresh lock taken by mistake (a hard link to the link itself); False if the name is taken."""
    try:
        os.link(moved, lock_file, follow_symlinks=False)
    except OSError:
        return False
    os.unlink(moved)
    return True
