"""Throw-away local servers for the scale benchmark (bench/storage.py) and tests (tests/scale): a PostgreSQL
cluster in a temporary folder and an ``mlflow server`` backed by it.

PostgreSQL comes from Debian's ``postgresql`` package (``/usr/lib/postgresql/<version>/bin``); it refuses to run
as root, so as root the cluster belongs to the ``postgres`` user (or ``nobody``).  It listens on 127.0.0.1 at a
free port and on a unix socket in its folder, trusts local connections and is removed on stop.
"""
from __future__ import annotations

import glob
import os
import pwd
import shutil
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request
import uuid
from pathlib import Path

PG_GLOBS = ("/usr/lib/postgresql/*/bin", "/usr/local/pgsql/bin")
PG_USER = "vibro"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def postgres_bin() -> Path | None:
    """The folder of ``initdb`` and ``pg_ctl``: on PATH, else the newest Debian install; None when absent."""
    found = shutil.which("initdb")
    if found and shutil.which("pg_ctl"):
        return Path(found).parent
    dirs = sorted((Path(d) for p in PG_GLOBS for d in glob.glob(p) if (Path(d) / "initdb").exists()),
                  key=lambda d: [int(x) for x in d.parent.name.split(".") if x.isdigit()] or [0])
    return dirs[-1] if dirs else None


def postgres_missing() -> str | None:
    """Why a local PostgreSQL cannot be started here (None when it can)."""
    if postgres_bin() is None:
        return "PostgreSQL server binaries (initdb, pg_ctl) not found: apt-get install postgresql"
    try:
        import psycopg  # noqa: F401
    except ImportError:
        return "the PostgreSQL driver psycopg is not installed (pip install 'psycopg[binary]')"
    if os.getuid() == 0 and _run_as() is None:
        return "running as root and no unprivileged user (postgres, nobody) to run PostgreSQL as"
    return None


def _run_as() -> str | None:
    """The user to run PostgreSQL as when this process is root (it refuses root)."""
    for name in ("postgres", "nobody"):
        try:
            pwd.getpwnam(name)
            return name
        except KeyError:
            continue
    return None


class LocalPostgres:
    """A PostgreSQL cluster in a temporary folder: ``with LocalPostgres() as pg: pg.new_database()``.

    fsync is off (a throw-away cluster; the benchmark states it); connections as user ``vibro`` without password."""

    def __init__(self, fsync: bool = False) -> None:
        self.fsync = fsync
        self.port = free_port()
        self.dir = Path(tempfile.mkdtemp(prefix="vibro-pg-"))
        self.user = _run_as() if os.getuid() == 0 else None
        self.bin = postgres_bin()

    def _cmd(self, *args: str) -> list[str]:
        return (["runuser", "-u", self.user, "--"] if self.user else []) + list(args)

    def start(self) -> "LocalPostgres":
        if self.user:
            info = pwd.getpwnam(self.user)
            os.chown(self.dir, info.pw_uid, info.pw_gid)
        os.chmod(self.dir, 0o755)
        data, log = self.dir / "data", self.dir / "log"
        subprocess.run(self._cmd(str(self.bin / "initdb"), "-D", str(data), "-U", PG_USER, "--auth=trust",
                                 "-E", "UTF8", "--no-sync"), check=True, capture_output=True, timeout=120)
        opts = (f"-p {self.port} -k {self.dir} -c listen_addresses=127.0.0.1 -c max_connections=200 "
                f"-c fsync={'on' if self.fsync else 'off'}")
        subprocess.run(self._cmd(str(self.bin / "pg_ctl"), "-D", str(data), "-l", str(log), "-w", "-t", "60",
                                 "-o", opts, "start"), check=True, capture_output=True, timeout=90)
        return self

    def stop(self) -> None:
        data = self.dir / "data"
        if data.exists():
            subprocess.run(self._cmd(str(self.bin / "pg_ctl"), "-D", str(data), "-m", "immediate", "-w", "stop"),
                           capture_output=True, timeout=60)
        shutil.rmtree(self.dir, ignore_errors=True)

    def url(self, database: str = "postgres") -> str:
        return f"postgresql://{PG_USER}@127.0.0.1:{self.port}/{database}"

    def new_database(self, prefix: str = "t") -> str:
        """A new empty database; returns its URL."""
        import psycopg

        name = f"{prefix}_{uuid.uuid4().hex[:12]}"
        with psycopg.connect(self.url(), autocommit=True) as conn:
            conn.execute(f'CREATE DATABASE "{name}"')
        return self.url(name)

    def __enter__(self) -> "LocalPostgres":
        try:
            return self.start()
        except BaseException:
            self.stop()
            raise

    def __exit__(self, *exc) -> None:
        self.stop()


class LocalMlflowServer:
    """``mlflow server`` on a free local port with ``backend`` (a database URL) and artifacts under ``artifacts``
    (proxied: clients upload through the server).  ``uri`` is what MLFLOW_TRACKING_URI takes."""

    def __init__(self, backend: str, artifacts: Path, log: Path | None = None) -> None:
        self.backend, self.artifacts = backend, Path(artifacts)
        self.port = free_port()
        self.uri = f"http://127.0.0.1:{self.port}"
        self.log = Path(log) if log else self.artifacts.parent / "mlflow-server.log"
        self.proc: subprocess.Popen | None = None

    def start(self, timeout_s: float = 120.0) -> "LocalMlflowServer":
        self.artifacts.mkdir(parents=True, exist_ok=True)
        mlflow_bin = Path(sys.executable).with_name("mlflow")
        cmd = [str(mlflow_bin) if mlflow_bin.exists() else "mlflow", "server", "--backend-store-uri", self.backend,
               "--artifacts-destination", str(self.artifacts), "--host", "127.0.0.1", "--port", str(self.port),
               "--workers", "1"]
        self.proc = subprocess.Popen(cmd, stdout=self.log.open("w"), stderr=subprocess.STDOUT,
                                     start_new_session=True)
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise RuntimeError(f"mlflow server exited ({self.proc.returncode}): {self.log.read_text()[-800:]}")
            try:
                with urllib.request.urlopen(f"{self.uri}/health", timeout=2) as r:
                    if r.status == 200:
                        return self
            except OSError:
                time.sleep(0.5)
        self.stop()
        raise RuntimeError(f"mlflow server did not answer within {timeout_s:.0f} s: {self.log.read_text()[-800:]}")

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            os.killpg(self.proc.pid, 15)
            try:
                self.proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, 9)
                self.proc.wait()
        self.proc = None

    def __enter__(self) -> "LocalMlflowServer":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()
