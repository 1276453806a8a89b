"""Optimisation that holds under concurrency and interruption: several workers run
exactly --n-trials between them with no duplicates, a new SQLite store can be created by two
workers at once, trials of a killed or interrupted worker are failed and re-run, and a resumed
study reaches the same best point as an uninterrupted one with the same seed.

The worker (tests/pipeline/optimise/concurrency_worker.py) optimises an analytic function, not the simulator."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import optuna
import pytest

from tests.pipeline.optimise import concurrency_worker as W

REPO = Path(__file__).resolve().parents[3]
TS = optuna.trial.TrialState


def _trials(db: Path):
    st = optuna.load_study(study_name="s", storage=f"sqlite:///{db}")
    return st.get_trials(deepcopy=False)


def _as_from_a_terminal() -> None:
    """In the child: Ctrl-C delivered and handled as in a shell (the pytest worker may have SIGINT blocked or ignored
    by a library it ran earlier, and a child inherits both; the full suite failed the Ctrl-C case that way)."""
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _spawn(db: Path, n: int, seed: int, delay: float, *extra: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "tests.pipeline.optimise.concurrency_worker", str(db), str(n), str(seed), str(delay),
                             *extra], cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": str(REPO)}, preexec_fn=_as_from_a_terminal)


def _complete_params(db: Path) -> list[tuple]:
    return [tuple(sorted(t.params.items())) for t in _trials(db) if t.state == TS.COMPLETE]


def _best(trials) -> tuple[float, dict]:
    best = max((t for t in trials if t.state == TS.COMPLETE), key=lambda t: t.values[0])
    return best.values[0], best.params


@pytest.mark.parametrize("mode", ["direct", "buffered"])
def test_two_workers_run_exactly_n_trials_without_duplicates(tmp_path, mode):
    """Issue 15: two workers with --n-trials 40 ran 76 trials, 17 duplicated (surrogate mode: 200 -> 392)."""
    db = tmp_path / "s.db"
    extra = ("buffered",) if mode == "buffered" else ()
    procs = [_spawn(db, 40, 0, 0.02, *extra) for _ in range(2)]
    for p in procs:
        out, err = p.communicate(timeout=120)
        assert p.returncode == 0, err
    params = _complete_params(db)
    assert len(params) == 40
    assert len(set(params)) == 40
    assert not [t for t in _trials(db) if t.state in (TS.RUNNING, TS.WAITING)]


def test_concurrent_creation_of_a_new_store(tmp_path):
    """Issue 15: two workers creating a new SQLite store at once: one failed with IntegrityError."""
    for i in range(3):
        db = tmp_path / f"new{i}.db"
        procs = [_spawn(db, 4, 0, 0.0) for _ in range(3)]
        for p in procs:
            out, err = p.communicate(timeout=120)
            assert p.returncode == 0, err
        assert len(_complete_params(db)) == 4


def _kill_after(db: Path, n_seen: int, sig: int, seed: int = 0, n: int = 24) -> None:
    """Start a worker and send ``sig`` while it evaluates a batch, once ``n_seen`` trials are complete (the
    worker announces each evaluation and then sleeps 3 s, so the signal lands with trials in flight)."""
    p = _spawn(db, n, seed, 3.0)
    assert p.stdout.readline().strip() == "opened", p.stderr.read()    # never read a store being created
    ready = False     # the store is read between evaluations, so the signal follows an "evaluating" line at once
    for line in p.stdout:   # (reading it after that line took > 1 s on a loaded CI machine: nothing was in flight)
        assert p.poll() is None, p.stderr.read()
        if line.strip() == "evaluating":
            if ready:
                break
            ready = sum(t.state == TS.COMPLETE for t in _trials(db)) >= n_seen
    else:
        raise AssertionError(f"worker ended before {n_seen} trials: {p.stderr.read()}")
    p.send_signal(sig)
    p.communicate(timeout=60)


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGINT], ids=["kill-9", "ctrl-c"])
def test_interrupted_study_resumes_to_the_uninterrupted_result(tmp_path, sig):
    """kill -9 / Ctrl-C mid-study: the trials in flight end FAIL (at the latest when the study is
    resumed), the resumed study runs exactly the missing trials and proposes exactly what the
    uninterrupted study with the same seed proposed."""
    ref_db = tmp_path / "ref.db"
    W.run(str(ref_db), 24, 0, 0.0)
    ref = _trials(ref_db)

    db = tmp_path / "s.db"
    _kill_after(db, 6, sig)
    left = _trials(db)
    assert any(t.state != TS.COMPLETE for t in left)                          # trials were in flight
    if sig == signal.SIGINT:
        assert not [t for t in left if t.state == TS.RUNNING]                 # Ctrl-C fails its own trials
    W.run(str(db), 24, 0, 0.0)
    after = _trials(db)
    assert not [t for t in after if t.state in (TS.RUNNING, TS.WAITING)]     # stale ones were failed
    done = [t for t in after if t.state == TS.COMPLETE]
    assert len(done) == 24
    assert [t.params for t in done] == [t.params for t in ref]
    assert _best(after) == _best(ref)


def test_buffered_resume_is_deterministic(tmp_path):
    ref_db, db = tmp_path / "ref.db", tmp_path / "s.db"
    W.run(str(ref_db), 20, 3, 0.0, buffered=True)
    W.run(str(db), 12, 3, 0.0, buffered=True)          # an earlier, shorter run (same seed): resumed to 20
    W.run(str(db), 20, 3, 0.0, buffered=True)
    assert _complete_params(db) == _complete_params(ref_db)


@pytest.mark.slow
def test_many_kills_then_resume(tmp_path):
    ref_db = tmp_path / "ref.db"
    W.run(str(ref_db), 40, 1, 0.0)
    db = tmp_path / "s.db"
    for k in (5, 13, 22, 31):
        _kill_after(db, k, signal.SIGKILL, seed=1, n=40)
    W.run(str(db), 40, 1, 0.0)
    assert _complete_params(db) == _complete_params(ref_db)
