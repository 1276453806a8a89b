"""Exit codes: 2 and one line for what the user or the machine causes (read-only file system, full disk, file
size limit, quota, a corrupt database, not enough memory), 1 only for the project's own bugs; no warning lines
before the error line.  The disk errors are injected where every atomic write passes (its fsync), so the file a
command had written before must survive byte for byte."""
from __future__ import annotations

import errno
import json
import os
import resource
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from pipeline.core.errors import UserError, machine_error
from tests.reliability.test_bad_inputs import run_cli

REPO = Path(__file__).resolve().parents[2]

DISK_ERRORS = [errno.ENOSPC, errno.EROFS, errno.EFBIG, errno.EDQUOT, errno.EIO, errno.EACCES]


@pytest.mark.parametrize("code", DISK_ERRORS, ids=[errno.errorcode[c] for c in DISK_ERRORS])
def test_disk_error_while_writing_is_exit_2_and_loses_nothing(code, tmp_path, capsys, monkeypatch):
    from pipeline.cli import main
    import vibrobase.files as files          # where the atomic writes live

    plot = tmp_path / "p.png"
    assert main(["simulate", "pendulum", "--plot", str(plot)]) == 0       # a previous run's figure
    before = plot.read_bytes()
    capsys.readouterr()

    def failing_fsync(fd):
        raise OSError(code, os.strerror(code), str(plot))

    monkeypatch.setattr(files.os, "fsync", failing_fsync)
    rc, err = run_cli(["simulate", "pendulum", "--plot", str(plot)], capsys)
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert rc == 2, err
    assert len(lines) == 1 and "error:" in lines[0] and "internal error" not in lines[0], err
    assert str(plot) in lines[0], err
    assert plot.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir() if p.name.endswith(".tmp")] == []


def _raises(exc: BaseException):
    def run(args):
        raise exc
    return run


MACHINE_CASES = [
    ("enospc-no-filename", OSError(errno.ENOSPC, "No space left on device"), "no space left"),
    ("errno-only-in-text", OSError("[Errno 28] Error writing bytes to file. Detail: [errno 28] No space left"),
     "no space left"),
    ("memory", MemoryError("Unable to allocate 417. GiB for an array with shape (56000000000,)"), "417"),
    ("corrupt-sqlite", __import__("sqlite3").DatabaseError("file is not a database"), "not a database"),
    ("malformed-sqlite-wrapped", RuntimeError("storage failed"), "malformed"),
    ("connection-refused", ConnectionRefusedError(errno.ECONNREFUSED, "Connection refused"), "connection refused"),
]


@pytest.mark.parametrize("case", MACHINE_CASES, ids=[c[0] for c in MACHINE_CASES])
def test_machine_errors_are_exit_2_one_line(case, capsys, monkeypatch):
    import sqlite3

    import pipeline.cli.models as models_cmd

    name, exc, fragment = case
    if name == "malformed-sqlite-wrapped":
        try:
            try:
                raise sqlite3.DatabaseError("database disk image is malformed")
            except sqlite3.DatabaseError as inner:
                raise RuntimeError("storage failed") from inner
        except RuntimeError as outer:
            exc = outer
    monkeypatch.setattr(models_cmd, "run", _raises(exc))
    rc, err = run_cli(["models"], capsys)
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert rc == 2 and len(lines) == 1 and "internal error" not in lines[0], err
    assert fragment in lines[0], err


def test_a_bug_stays_exit_1():
    assert machine_error(RuntimeError("a bug")) is None
    assert machine_error(OSError(errno.EBADF, "Bad file descriptor")) is None
    assert machine_error(KeyError("x")) is None


def test_no_warning_lines_before_the_error_line(capsys, monkeypatch):
    import pipeline.cli.models as models_cmd

    def noisy(args):
        for i in range(13):
            warnings.warn(f"invalid value encountered in divide ({i})", RuntimeWarning)
        raise UserError("the real problem")

    monkeypatch.setattr(models_cmd, "run", noisy)
    rc, err = run_cli(["models"], capsys)
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert rc == 2 and lines == ["vibro models: error: the real problem"], err


def test_warnings_of_a_successful_command_are_still_shown_once(capsys, monkeypatch):
    import pipeline.cli.models as models_cmd

    def noisy(args):
        for _ in range(3):
            warnings.warn("degenerate fold", RuntimeWarning)
        return 0

    monkeypatch.setattr(models_cmd, "run", noisy)
    rc, err = run_cli(["models"], capsys)
    assert rc == 0 and err.count("RuntimeWarning: degenerate fold") == 1, err


def _limit_file_size():
    resource.setrlimit(resource.RLIMIT_FSIZE, (4096, 4096))


@pytest.mark.slow
def test_real_file_size_limit_is_exit_2_and_keeps_the_old_file(tmp_path):
    """``ulimit -f``: the kernel refuses the write (Python ignores SIGXFSZ, so it is EFBIG), in a real process."""
    plot = tmp_path / "p.png"
    env = {**os.environ, "VIBRO_NO_MLFLOW": "1"}
    vibro = [sys.executable, "-m", "pipeline.cli"]
    assert subprocess.run([*vibro, "simulate", "pendulum", "--plot", str(plot)], cwd=REPO, env=env,
                          capture_output=True).returncode == 0
    before = plot.read_bytes()
    assert len(before) > 4096
    r = subprocess.run([*vibro, "simulate", "pendulum", "--plot", str(plot)], cwd=REPO, env=env,
                       capture_output=True, text=True, preexec_fn=_limit_file_size)
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.returncode == 2 and len(lines) == 1 and "file too large" in lines[0], r.stderr
    assert plot.read_bytes() == before


def test_corrupt_optuna_database_is_exit_2_and_untouched(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    db = tmp_path / "s.db"
    db.write_bytes(b"SQLite format 3\x00" + b"\xff" * 2000)
    before = db.read_bytes()
    rc, err = run_cli(["optimise", "--simulator", "--n-trials", "2", "--storage", f"sqlite:///{db}",
                       "--out", str(tmp_path / "o"), "--no-mlflow", "--quiet"], capsys)
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert rc == 2 and len(lines) == 1 and "internal error" not in lines[0], err
    assert db.read_bytes() == before and not (tmp_path / "o").exists()


def test_failed_simulation_is_a_result_exit_0(capsys):
    """A point stopped by its work limit is labelled ``failed``: a result printed with exit 0 (exit 1 means a bug),
    as ``vibro simulate --help`` and docs/reliability.md say."""
    from pipeline.cli import build_parser, main

    rc = main(["simulate", "drill", "--preset", "lab", "--setting", "max_steps=1000", "--json"])
    out = capsys.readouterr().out
    assert rc == 0
    assert json.loads(out)["status"] == "failed"
    sub = next(a for a in build_parser()._actions if a.dest == "command")
    help_text = sub.choices["simulate"].format_help()
    assert "whatever its status" in help_text and "1 only for a bug" in help_text
    assert "exits 0 for every status" in (Path(__file__).resolve().parents[2] / "docs" / "reliability.md").read_text()
