"""The journal lock: a stale lock is broken once; a fresh lock that replaced it is never broken."""
from __future__ import annotations

import os
import threading
import time

import pytest

from pipeline.optimise.journal_lock import LinkAgeLock, _identity


def _stale_link(journal: str) -> None:
    """A lock left by a killed worker: the link exists and nobody will remove it."""
    open(journal, "ab").close()
    os.symlink(journal, journal + ".lock")


def test_a_free_lock_is_taken_and_given_back(tmp_path):
    journal = str(tmp_path / "s.log")
    lock = LinkAgeLock(journal, 5.0)
    assert lock.acquire()
    assert os.path.islink(journal + ".lock")
    lock.release()
    assert not os.path.lexists(journal + ".lock")
    with pytest.raises(RuntimeError, match="did not possess"):
        lock.release()


def test_a_stale_lock_is_broken_after_the_grace_period(tmp_path):
    journal = str(tmp_path / "s.log")
    _stale_link(journal)
    start = time.monotonic()
    lock = LinkAgeLock(journal, 0.3)
    assert lock.acquire()
    assert time.monotonic() - start >= 0.3
    lock.release()


def test_breaking_a_lock_that_was_replaced_since_leaves_the_new_one(tmp_path):
    # the race optuna's own lock loses: a waiter judged the old link stale, another broke it and took a new one
    journal = str(tmp_path / "s.log")
    _stale_link(journal)
    old = _identity(os.lstat(journal + ".lock"))
    os.unlink(journal + ".lock")
    time.sleep(0.01)
    os.symlink(journal, journal + ".lock")
    new = _identity(os.lstat(journal + ".lock"))
    assert new != old
    LinkAgeLock(journal, 0.3)._break(old)
    assert _identity(os.lstat(journal + ".lock")) == new
    assert [p.name for p in tmp_path.iterdir() if p.name.endswith(".rename")] == []


def test_waiters_on_a_stale_lock_take_it_in_turn_and_each_releases_its_own(tmp_path):
    journal = str(tmp_path / "s.log")
    _stale_link(journal)
    holding, most, errors = [0], [0], []
    guard = threading.Lock()

    def worker() -> None:
        lock = LinkAgeLock(journal, 0.3)
        for _ in range(3):
            lock.acquire()
            with guard:
                holding[0] += 1
                most[0] = max(most[0], holding[0])
            time.sleep(0.05)
            with guard:
                holding[0] -= 1
            try:
                lock.release()
            except RuntimeError as e:
                errors.append(e)

    threads = [threading.Thread(target=worker) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(30)
    assert errors == [] and most[0] == 1


def test_a_non_positive_grace_is_refused(tmp_path):
    with pytest.raises(ValueError, match="grace_period_s"):
        LinkAgeLock(str(tmp_path / "s.log"), 0)
