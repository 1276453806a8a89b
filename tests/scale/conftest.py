"""Servers for the scale tests: one throw-away PostgreSQL cluster per session (bench/servers.py), skipped with the
reason where it cannot be started; a fresh database per test."""
from __future__ import annotations

import pytest

from bench.servers import LocalPostgres, postgres_missing


@pytest.fixture(scope="session")
def postgres():
    why = postgres_missing()
    if why:
        pytest.skip(f"no PostgreSQL here: {why}")
    try:
        pg = LocalPostgres().start()
    except Exception as e:  # noqa: BLE001 - a failed start is the machine's, reported as the skip reason
        pytest.skip(f"PostgreSQL could not be started: {type(e).__name__}: {str(e)[:300]}")
    yield pg
    pg.stop()


@pytest.fixture
def pg_url(postgres) -> str:
    """URL of a new empty database on the session's server."""
    return postgres.new_database()
