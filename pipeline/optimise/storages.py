"""Optuna storages by URL: SQLite file (default), an RDB server, or a journal file; heartbeats for the shared ones.

- ``sqlite:///path.db``: one machine; workers coordinate through flock files (coordination.StudyGuard).
  Never on a network file system: SQLite's locking is not reliable there.
- ``postgresql://user@host/db`` (any SQLAlchemy RDB URL): workers on several machines; optuna's heartbeat
  (:class:`optuna.storages.RDBStorage`) marks the trials of a lost worker FAIL and a retry callback re-queues them.
- ``journal:///path/study.log``: optuna's :class:`~optuna.storages.JournalStorage` on a file, no server; the
  file may sit on a shared file system (NFS) that every worker mounts.  :class:`JournalHeartbeatStorage`
  adds the heartbeat optuna gives only to RDBStorage, timed by the workers' clocks.
"""
from __future__ import annotations

import contextlib
import math
import time
import warnings
from pathlib import Path

import optuna
from optuna.storages import JournalStorage
from optuna.storages._heartbeat import BaseHeartbeat
from optuna.storages.journal import JournalFileBackend

from pipeline.core.errors import UserError
from pipeline.optimise.journal_lock import LinkAgeLock

JOURNAL_SCHEME = "journal://"
DEFAULT_HEARTBEAT_S = 10
"""Seconds between two heartbeats of a running trial on a shared storage."""
GRACE_FACTOR = 3
"""A running trial with no heartbeat for GRACE_FACTOR × heartbeat is stale: marked FAIL and re-queued."""
MAX_RETRY = 3
"""Re-runs of one stale trial; after that its point is dropped (a point that kills its worker) and a new one is asked."""
HEARTBEAT_ATTR = "vibro:heartbeat"
"""Journal trials: system attribute holding the epoch time [s] of the last heartbeat."""


def is_sqlite(url: str) -> bool:
    return url.startswith("sqlite:")


def journal_path(url: str) -> str | None:
    """The log file of a ``journal://PATH`` URL (``journal:///shared/s.log`` is ``/shared/s.log``), None for
    other URLs."""
    if not url.startswith(JOURNAL_SCHEME):
        return None
    path = url[len(JOURNAL_SCHEME):]
    if not path.strip("/"):
        raise UserError(f"--storage '{url}': name the journal file, e.g. journal:///shared/optuna/study.log")
    return path


def open_storage(url: str, heartbeat_s: int = DEFAULT_HEARTBEAT_S):
    """Optuna storage for ``url``, checked first with :func:`check_storage_target`.  A SQLite file is opened in WAL
    mode with synchronous=NORMAL (several times fewer fsyncs per trial); a server or journal storage with a heartbeat
    every ``heartbeat_s`` seconds, a grace period of GRACE_FACTOR heartbeats and up to MAX_RETRY re-runs of a stale
    trial."""
    if is_sqlite(url):
        return _open_sqlite(url)
    if heartbeat_s is None or int(heartbeat_s) < 1:
        raise UserError(f"--heartbeat-s must be a whole number of seconds >= 1, got {heartbeat_s}")
    with warnings.catch_warnings():     # optuna's heartbeat API is marked experimental since v2.8
        warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
        retry = optuna.storages.RetryHeartbeatStaleTrialCallback(max_retry=MAX_RETRY)
    hb = {"heartbeat_interval": int(heartbeat_s), "grace_period": GRACE_FACTOR * int(heartbeat_s),
          "heartbeat_stale_trial_callback": retry}
    journal = journal_path(url)
    if journal is not None:
        return _open_journal(url, journal, hb)
    return _open_rdb(url, {**hb, "engine_kwargs": {"pool_pre_ping": True}})


def _open_rdb(url: str, kwargs: dict):
    """RDBStorage; another worker creating the schema at the same moment is waited for, not an error."""
    for attempt in range(5):
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
                return optuna.storages.RDBStorage(url, **kwargs)
        except ImportError as e:
            raise UserError(f"--storage '{url}': its database driver is not installed ({e})") from None
        except Exception as e:  # noqa: BLE001 - bad URL, refused connection, not a database
            text = str(e)
            racing = any(s in text for s in ("already exists", "UNIQUE constraint", "duplicate key"))
            if attempt < 4 and racing:
                time.sleep(0.2 * (attempt + 1))
                continue
            raise UserError(f"--storage '{url}': {text.splitlines()[0] if text else type(e).__name__}") from None
    raise AssertionError("unreachable")


def _open_sqlite(url: str):
    from sqlalchemy import event

    storage = _open_rdb(url, {"engine_kwargs": {"connect_args": {"timeout": 60}}})

    @event.listens_for(storage.engine, "connect")
    def _pragmas(dbapi_conn, _record):  # noqa: ANN001
        cur = dbapi_conn.cursor()
        cur.execute("PRAGMA journal_mode=WAL")
        cur.execute("PRAGMA synchronous=NORMAL")
        cur.close()

    storage.engine.dispose()   # reconnect with the pragmas
    return storage


def _open_journal(url: str, path: str, hb: dict):
    parent = Path(path).parent
    if not parent.is_dir():
        raise UserError(f"--storage '{url}': folder {parent} does not exist")
    try:
        backend = JournalFileBackend(path, LinkAgeLock(path))
        return JournalHeartbeatStorage(backend, hb["heartbeat_interval"], hb["grace_period"],
                                       hb["heartbeat_stale_trial_callback"])
    except OSError as e:
        raise UserError(f"--storage '{url}': {e.strerror or e}") from None


def grace_of(storage) -> float:
    """The grace period [s] of a heartbeat storage (an RDB server's or a journal's)."""
    if isinstance(storage, JournalHeartbeatStorage):
        return storage.grace_s
    grace = getattr(storage, "grace_period", None)
    return float(grace if grace is not None else 2 * (storage.get_heartbeat_interval() or 0))


@contextlib.contextmanager
def grace_for(storage, seconds: float):
    """``storage`` judging stale trials with a grace of ``seconds`` (whole, rounded up) inside the block."""
    attr = "grace_s" if isinstance(storage, JournalHeartbeatStorage) else "grace_period"
    old = getattr(storage, attr, None)
    setattr(storage, attr, int(math.ceil(seconds)))
    try:
        yield
    finally:
        setattr(storage, attr, old)


def check_storage_target(url: str) -> None:
    """UserError unless the file behind a ``sqlite:///`` or ``journal:///`` URL is absent, empty or optuna's own
    (an SQLite database with optuna's tables, an optuna journal); device files, folders and FIFOs are refused.
    Runs before optuna or the worker locks touch anything, so another application's file is never written."""
    from pipeline.optimise.storage_files import check_journal_file, check_sqlite_file, sqlite_file

    journal = journal_path(url)
    if journal is not None:
        check_journal_file(Path(journal), f"--storage '{url}'")
    elif is_sqlite(url):
        db = sqlite_file(url)
        if db is not None:
            check_sqlite_file(db, f"--storage '{url}'")


class JournalHeartbeatStorage(JournalStorage, BaseHeartbeat):
    """A :class:`optuna.storages.JournalStorage` whose running trials carry a heartbeat (system attribute
    HEARTBEAT_ATTR, epoch seconds) every ``heartbeat_s`` seconds, so ``optuna.storages.fail_stale_trials`` fails
    those silent for ``grace_s`` seconds (a lost worker's) and calls ``stale_callback(study, trial)``.

    The times are the workers' clocks: keep them synchronised (NTP) to well within the grace period."""

    def __init__(self, backend, heartbeat_s: int, grace_s: int, stale_callback=None) -> None:
        super().__init__(backend)
        self.heartbeat_s, self.grace_s, self.stale_callback = int(heartbeat_s), int(grace_s), stale_callback

    def record_heartbeat(self, trial_id: int) -> None:
        self.set_trial_system_attr(trial_id, HEARTBEAT_ATTR, time.time())

    def _get_stale_trial_ids(self, study_id: int) -> list[int]:
        now = time.time()
        stale = []
        for t in self.get_all_trials(study_id, deepcopy=False, states=(optuna.trial.TrialState.RUNNING,)):
            # a retry copies its original's attributes: its own start is its first sign of life
            alive = max(float(t.system_attrs.get(HEARTBEAT_ATTR, 0.0)),
                        t.datetime_start.timestamp() if t.datetime_start else 0.0)
            if now - alive > self.grace_s:
                stale.append(t._trial_id)
        return stale

    def get_heartbeat_interval(self) -> int | None:
        return self.heartbeat_s

    def get_heartbeat_stale_trial_callback(self):
        return self.stale_callback
