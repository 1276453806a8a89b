"""Several workers on one optuna study, and interrupted workers: what keeps the trial count exact.

For a SQLite file storage (``sqlite:///path.db``) the workers of one machine coordinate through two
flock files next to the database (pipeline.core.integrity.DirLock; the kernel drops them when a worker dies):
- ``path.db.lock``: held while a worker creates the storage/study, counts the trials and asks
  for its next batch — so the count and the new RUNNING trials are one step (no over-run, no two
  workers proposing from the same state);
- ``path.db.workers``: every worker holds a shared lock for its lifetime; a worker that can take it
  exclusively is the only one alive, so every RUNNING trial it finds is stale (a killed or
  interrupted worker's) and is marked FAIL, then re-run.  With other workers alive, only RUNNING
  trials tagged with a dead pid of this host are failed.
Other storages (an RDB server, a journal file, shared by several machines) get no file locks:
:func:`guard_for` gives them a heartbeat.HeartbeatGuard (heartbeats, stale trials re-run, surplus withdrawn).
Both guards offer one interface to study.run_study: lock, fail_stale, sampler_key, ask, settle, beating,
fail_orphans, wait.
"""
from __future__ import annotations

import contextlib
import fcntl
import hashlib
import os
import socket
from pathlib import Path

from pipeline.core.integrity import DirLock

WORKER_ATTR = "vibro_worker"


def sqlite_path(url: str | None) -> Path | None:
    """The database file of a ``sqlite:///`` URL (None for other storages or in-memory SQLite)."""
    if not url or not url.startswith("sqlite:///"):
        return None
    p = url[len("sqlite:///"):]
    return Path(p) if p and p != ":memory:" else None


def worker_id() -> str:
    return f"{socket.gethostname()} {os.getpid()}"


def batch_seed(seed: int, n_done: int) -> int:
    """Seed of the sampler that proposes the batch starting at trial count ``n_done``: a function of
    (seed, n_done) only, so a resumed study draws what the uninterrupted one drew."""
    return int.from_bytes(hashlib.sha256(f"vibro:{seed}:{n_done}".encode()).digest()[:4], "little")


def guard_for(url: str | None):
    """The guard of the workers of storage ``url``: flock files for a SQLite file, heartbeats for the rest."""
    from pipeline.optimise.storages import is_sqlite

    if url and not is_sqlite(url):
        from pipeline.optimise.heartbeat import HeartbeatGuard

        return HeartbeatGuard()
    return StudyGuard.for_url(url)


class StudyGuard:
    """Locks for the workers of one SQLite storage (no-ops when ``db`` is None: an in-memory study)."""

    waits = False   # a worker stops when the rest of the study runs in other (live) workers

    def __init__(self, db: Path | None) -> None:
        self.db = db
        self._reg_fd: int | None = None

    @classmethod
    def for_url(cls, url: str | None) -> "StudyGuard":
        return cls(sqlite_path(url))

    def lock(self):
        """Context manager: the storage's exclusive lock (waits for the holder)."""
        if self.db is None:
            return contextlib.nullcontext()
        self.db.parent.mkdir(parents=True, exist_ok=True)
        return DirLock(self.db.with_name(self.db.name + ".lock"), what="optuna worker", blocking=True)

    def register(self) -> None:
        """Hold the shared worker lock until :meth:`close` (or until this process dies)."""
        if self.db is None or self._reg_fd is not None:
            return
        self.db.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(self.db.with_name(self.db.name + ".workers"), os.O_RDWR | os.O_CREAT, 0o644)
        fcntl.flock(fd, fcntl.LOCK_SH)
        self._reg_fd = fd

    def only_worker(self) -> bool:
        """True when no other process holds the worker lock (call with :meth:`lock` held)."""
        if self._reg_fd is None:
            return False
        try:     # a failed conversion drops our shared lock (flock(2)): take it back in both cases
            fcntl.flock(self._reg_fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            alone = True
        except BlockingIOError:
            alone = False
        fcntl.flock(self._reg_fd, fcntl.LOCK_SH)
        return alone

    def close(self) -> None:
        if self._reg_fd is not None:
            os.close(self._reg_fd)
            self._reg_fd = None

    def fail_stale(self, study) -> None:
        """Mark FAIL the trials of dead workers (call with :meth:`lock` held)."""
        fail_stale_trials(study, self)

    def ask(self, study, distributions: dict):
        """A new trial, tagged with this worker (before the lock is released) when the storage is a file."""
        trial = study.ask(distributions)
        if self.db is not None:
            trial.set_user_attr(WORKER_ATTR, worker_id())
        return trial

    def sampler_key(self, n_done: int) -> int:
        """What seeds the sampler of the batch starting at ``n_done``: ``n_done`` alone (the lock orders the
        workers), so a resumed study proposes what the uninterrupted one did."""
        return n_done

    @staticmethod
    def pending_retries(trials: list) -> int:
        """Failed trials whose retry is about to be queued: none (no heartbeat on a locked storage)."""
        return 0

    def settle(self, study, trials: list, n_trials: int) -> list:
        """The trials to evaluate: all of them (they were counted and asked under the lock)."""
        return trials

    def beating(self, study, trials: list):
        return contextlib.nullcontext()

    def fail_orphans(self, study) -> None:
        """After an interruption inside ``ask``: fail the trial no list holds (call with :meth:`lock` held)."""
        fail_orphan_trials(study, tagged=self.db is not None)

    def wait(self) -> None:
        pass


def _pid_dead(tag: str | None) -> bool:
    if not tag:
        return False
    host, _, pid = tag.partition(" ")
    if host != socket.gethostname() or not pid.isdigit():
        return False
    try:
        os.kill(int(pid), 0)
    except ProcessLookupError:
        return True
    except PermissionError:
        return False
    return False


def fail_stale_trials(study, guard: StudyGuard) -> int:
    """Mark RUNNING/WAITING trials of dead workers FAIL (call with ``guard.lock()`` held); returns how many."""
    import optuna

    if guard.db is None:
        return 0
    TS = optuna.trial.TrialState
    live = study.get_trials(deepcopy=False, states=(TS.RUNNING, TS.WAITING))
    if not live:
        return 0
    alone = guard.only_worker()
    me = worker_id()
    n = 0
    for t in live:
        tag = t.user_attrs.get(WORKER_ATTR)
        if tag == me or t.state == TS.WAITING and not alone:
            continue
        if alone or _pid_dead(tag):
            study._storage.set_trial_state_values(t._trial_id, TS.FAIL)
            n += 1
    return n


def fail_orphan_trials(study, tagged: bool) -> int:
    """Mark FAIL the RUNNING trials an interrupted ask left behind (call with ``guard.lock()`` held):
    with ``tagged`` (every worker tags its trials before it releases the lock) those without a
    worker tag, otherwise those without parameters."""
    import optuna

    TS = optuna.trial.TrialState
    n = 0
    for t in study.get_trials(deepcopy=False, states=(TS.RUNNING,)):
        if WORKER_ATTR not in t.user_attrs and (tagged or not t.params):
            study._storage.set_trial_state_values(t._trial_id, TS.FAIL)
            n += 1
    return n
