"""The read-only check of a storage file before optuna opens it (pipeline/optimise/storage_files.py)."""
from __future__ import annotations

import sqlite3

import pytest
from optuna.storages._rdb import models

from pipeline.core.errors import UserError
from pipeline.optimise.storage_files import OPTUNA_SCHEMA, check_sqlite_file


def _db(path, tables):
    con = sqlite3.connect(path)
    for t in tables:
        con.execute(f"CREATE TABLE {t} (id INTEGER)")
    con.commit()
    con.close()
    return path


def test_schema_names_every_table_optuna_creates():
    assert set(models.BaseModel.metadata.tables) <= OPTUNA_SCHEMA


def test_a_store_half_created_by_another_worker_is_accepted(tmp_path):
    """Workers creating one new store at once: one of them sees only the first tables."""
    check_sqlite_file(_db(tmp_path / "half.db", ["studies"]), "--storage")
    check_sqlite_file(_db(tmp_path / "some.db", ["studies", "trials", "alembic_version"]), "--storage")


def test_another_applications_database_is_refused(tmp_path):
    with pytest.raises(UserError, match="another application's database"):
        check_sqlite_file(_db(tmp_path / "app.db", ["studies", "notes"]), "--storage")
