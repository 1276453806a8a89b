"""What an optuna storage file may be before optuna opens it: absent, empty, or optuna's own.

optuna appends to any journal file and adds its tables to any SQLite database it is given; these checks read
(never write) the file first, so a user's text, another application's database or a device is refused untouched.
"""
from __future__ import annotations

import json
import os
import stat
from pathlib import Path
from typing import BinaryIO, Callable
from urllib.parse import quote

from pipeline.core.errors import UserError

SQLITE_MAGIC = b"SQLite format 3\x00"
OPTUNA_TABLES = frozenset({"studies", "version_info"})
"""Tables every optuna RDB schema has (optuna/storages/_rdb/models.py)."""
OPTUNA_SCHEMA = frozenset({"studies", "study_directions", "study_system_attributes", "study_user_attributes",
                           "trial_heartbeats", "trial_intermediate_values", "trial_params", "trial_system_attributes",
                           "trial_user_attributes", "trial_values", "trials", "version_info", "alembic_version",
                           "sqlite_sequence"})
"""Every table optuna's RDB storage creates: a file holding only some of them is one another worker is
creating at this moment, not another application's."""
MAX_JOURNAL_LINE = 2**20
"""Bytes read to find a journal's first record."""


def sqlite_file(url: str) -> Path | None:
    """The database file of a ``sqlite:`` URL (query string dropped), None for ``:memory:``; UserError when the
    URL names no file (``sqlite:///`` would be a throw-away in-memory database)."""
    rest = url[len("sqlite:"):].split("?", 1)[0]
    path = rest[3:] if rest.startswith("///") else ""
    if path == ":memory:":
        return None
    if not path:
        raise UserError(f"--storage '{url}': name the database file, e.g. sqlite:///optuna.db "
                        "(sqlite:////abs/path.db for an absolute path)")
    return Path(path)


def _existing_regular(path: Path, label: str, kind: str) -> int | None:
    """Size of ``path`` when it is a regular file, None when absent; UserError for a folder, device or FIFO."""
    try:
        st = path.stat()
    except FileNotFoundError:
        return None
    except OSError as e:
        raise UserError(f"{label}: {path}: {e.strerror or e}") from None
    if stat.S_ISDIR(st.st_mode):
        raise UserError(f"{label}: {path} is a folder, not {kind}")
    if not stat.S_ISREG(st.st_mode):
        raise UserError(f"{label}: {path} is a device or pipe, not {kind}")
    return st.st_size


def _head(path: Path, label: str, kind: str, read: Callable[[BinaryIO], bytes]) -> bytes | None:
    """``read`` of the start of ``path`` (opened for binary reading), None when it is absent or empty; UserError
    for a folder, a device or pipe, or a file that cannot be read."""
    if not _existing_regular(path, label, kind):
        return None
    try:
        with open(path, "rb") as fh:
            return read(fh)
    except OSError as e:
        raise UserError(f"{label}: {path}: {e.strerror or e}") from None


def check_journal_file(path: Path, label: str) -> None:
    """UserError unless ``path`` is absent, empty or an optuna journal (its first line a journal record)."""
    first = _head(path, label, "an optuna journal file", lambda fh: fh.readline(MAX_JOURNAL_LINE))
    if first is None:
        return
    try:
        rec = json.loads(first.decode("utf-8")) if first.endswith(b"\n") else None
    except (UnicodeDecodeError, ValueError):
        rec = None
    if not (isinstance(rec, dict) and isinstance(rec.get("op_code"), int) and "worker_id" in rec):
        raise UserError(f"{label}: {path} exists and is not an optuna journal; it was left unchanged "
                        "(name a new or empty file)")


def _tables(path: Path, label: str, attempts: int = 5) -> set[str]:
    """The table names of the SQLite file ``path``, read without locking it.  An immutable read of a file
    another worker is writing may see a torn page: read again a few times (0.2 s apart) before refusing it."""
    import sqlite3
    import time

    for i in range(attempts):
        try:      # immutable: no lock, journal or WAL file is created next to a file that may not be ours
            con = sqlite3.connect(f"file:{quote(os.fspath(path.resolve()))}?mode=ro&immutable=1", uri=True)
            try:
                return {r[0] for r in con.execute("SELECT name FROM sqlite_master WHERE type='table'")}
            finally:
                con.close()
        except sqlite3.Error as e:
            if i == attempts - 1:
                raise UserError(f"{label}: {path}: not a readable SQLite database ({e})") from None
            time.sleep(0.2)
    return set()


def check_sqlite_file(path: Path, label: str) -> None:
    """UserError unless ``path`` is absent, empty, or an SQLite database that is empty or has optuna's schema."""
    magic = _head(path, label, "an SQLite database file", lambda fh: fh.read(len(SQLITE_MAGIC)))
    if magic is None:
        return
    if magic != SQLITE_MAGIC:
        raise UserError(f"{label}: {path} exists and is not an SQLite database; it was left unchanged "
                        "(name a new file)")
    tables = _tables(path, label)
    if tables and not (OPTUNA_TABLES <= tables or tables <= OPTUNA_SCHEMA):
        shown = ", ".join(sorted(tables)[:4]) + (", ..." if len(tables) > 4 else "")
        raise UserError(f"{label}: {path} is another application's database (tables {shown}), not an optuna "
                        "storage; it was left unchanged (name a new file)")
