"""Several workers on one study in a shared storage (a real PostgreSQL server, a journal file), started
independently as on several machines: exactly --n-trials complete trials, none duplicated; a worker killed with
SIGKILL mid-trial has its trials failed by the heartbeat and re-run, and the study still ends with --n-trials."""
from __future__ import annotations

import datetime
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import optuna
import pytest

from pipeline.core.errors import UserError
from pipeline.optimise.heartbeat import SURPLUS_ATTR
from pipeline.optimise.storages import HEARTBEAT_ATTR, open_storage

REPO = Path(__file__).resolve().parents[2]
TS = optuna.trial.TrialState
RETRY = optuna.storages.RetryHeartbeatStaleTrialCallback
ENGINES = ["postgresql", "journal"]
pytestmark = [pytest.mark.filterwarnings("ignore::optuna.exceptions.ExperimentalWarning"),
              pytest.mark.filterwarnings("ignore:Heartbeat of storage is supposed to be used with Study.optimize")]


@pytest.fixture(params=ENGINES)
def storage_url(request, tmp_path) -> str:
    if request.param == "postgresql":
        return request.getfixturevalue("pg_url")
    return f"journal://{tmp_path / 'study.log'}"


def _env() -> dict:
    return {**os.environ, "PYTHONPATH": str(REPO), "MLFLOW_TRACKING_URI": "", "VIBRO_NO_MLFLOW": "1"}


def _trials(url: str, name: str):
    return optuna.load_study(study_name=name, storage=open_storage(url, 1)).get_trials(deepcopy=False)


def _key(t) -> tuple:
    return tuple(sorted(t.params.items()))


@pytest.fixture
def cpu_burner():
    """A loaded machine: busy-looping processes (twice the cores, at least 4) for at most 300 s, stopped at the
    end of the test.  A live but descheduled worker must not be declared dead."""
    n = max(4, 2 * (os.cpu_count() or 1))
    code = "import time\nend = time.monotonic() + 300\nwhile time.monotonic() < end:\n    pass\n"
    burners = [subprocess.Popen([sys.executable, "-c", code]) for _ in range(n)]
    yield burners
    for b in burners:
        b.kill()
        b.wait()


@pytest.mark.slow
def test_four_independent_optimise_workers_run_exactly_n_trials(storage_url, tmp_path, cpu_burner):
    """Under load (the failure this guards against: a 2 s heartbeat missed at load ~7 on 2 cores, a live worker's
    trial failed and re-run).  Slow: its busy loops hold both cores for a minute or two, whatever else runs; the
    heartbeat and exactly-n contracts stay in the default suite with the killed worker and test_concurrency."""
    assert all(b.poll() is None for b in cpu_burner)
    n = 24
    procs = [subprocess.Popen(
        [sys.executable, "-m", "pipeline.cli", "optimise", "--simulator", "--model", "drill", "--preset", "lab",
         "--n-trials", str(n), "--batch-size", "4", "--n-verify", "1", "--workers", "1", "--storage", storage_url,
         "--study-name", "four", "--heartbeat-s", "2", "--no-mlflow", "--quiet", "--out", str(tmp_path / f"w{i}")],
        cwd=REPO, env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for i in range(4)]
    for p in procs:
        out, err = p.communicate(timeout=240)
        assert p.returncode == 0, err[-2000:]
    trials = _trials(storage_url, "four")
    complete = [t for t in trials if t.state == TS.COMPLETE]
    assert len(complete) == n
    assert len({_key(t) for t in complete}) == n
    assert not [t for t in trials if t.state in (TS.RUNNING, TS.WAITING)]
    assert all("labels" in t.user_attrs for t in complete)
    # every withdrawn trial is a surplus one: two workers asked at once, none was evaluated twice
    assert all(t.user_attrs.get(SURPLUS_ATTR) for t in trials if t.state == TS.FAIL)
    for i in range(4):
        assert (tmp_path / f"w{i}" / "trials.csv").exists()


def _spawn(url: str, name: str, n: int, delay_s: float, heartbeat_s: int) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "tests.scale.worker", url, name, str(n), str(delay_s),
                             str(heartbeat_s)], cwd=REPO, env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)


def _wait_for_line(p: subprocess.Popen, text: str, timeout_s: float) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        line = p.stdout.readline()
        if text in line:
            return
        if not line and p.poll() is not None:
            raise AssertionError(f"worker exited before '{text}': {p.stderr.read()[-2000:]}")
    raise AssertionError(f"no '{text}' from the worker within {timeout_s} s")


def test_a_worker_killed_mid_trial_is_failed_by_the_heartbeat_and_rerun(storage_url):
    n, heartbeat_s = 16, 1
    victim = _spawn(storage_url, "kill", n, 30.0, heartbeat_s)      # its first batch would take 30 s
    _wait_for_line(victim, "evaluating", 60)
    held = [t for t in _trials(storage_url, "kill") if t.state == TS.RUNNING]
    assert held, "the victim holds no running trial"
    others = [_spawn(storage_url, "kill", n, 0.3, heartbeat_s) for _ in range(2)]
    time.sleep(0.5)
    victim.send_signal(signal.SIGKILL)
    victim.wait(timeout=30)
    for p in others:
        out, err = p.communicate(timeout=120)
        assert p.returncode == 0, err[-2000:]
    trials = _trials(storage_url, "kill")
    by_number = {t.number: t for t in trials}
    complete = [t for t in trials if t.state == TS.COMPLETE]
    assert len(complete) == n
    assert not [t for t in trials if t.state in (TS.RUNNING, TS.WAITING)]
    retries = {RETRY.retried_trial_number(t): t for t in trials if RETRY.retried_trial_number(t) is not None}
    for t in held:
        assert by_number[t.number].state == TS.FAIL, f"trial {t.number} of the killed worker was not failed"
        assert t.number in retries, f"trial {t.number} of the killed worker was not queued again"
        retry = retries[t.number]
        assert _key(retry) == _key(t)
        # re-run, unless a worker had asked the study's last trial at the moment it was queued (then withdrawn)
        assert retry.state == TS.COMPLETE or retry.user_attrs.get(SURPLUS_ATTR)
    assert any(r.state == TS.COMPLETE for r in retries.values())
    # distinct points, except a retry and its original (the killed trial never completed)
    assert len({_key(t) for t in complete}) == n


def test_concurrent_asks_beyond_n_trials_are_withdrawn(tmp_path):
    """Two workers that counted the study at the same moment both ask: the one that counts again after both
    stored their trials sees the surplus and withdraws its own; together they keep exactly n live trials."""
    from pipeline.optimise.heartbeat import HeartbeatGuard

    url = f"journal://{tmp_path / 's.log'}"
    a = optuna.create_study(storage=open_storage(url, 1), study_name="s")
    b = optuna.load_study(storage=open_storage(url, 1), study_name="s")
    dist = {"x": optuna.distributions.FloatDistribution(0, 1)}
    guard = HeartbeatGuard(poll_s=0.01)
    mine_a = [guard.ask(a, dist) for _ in range(3)]
    mine_b = [guard.ask(b, dist) for _ in range(3)]
    kept_a = guard.settle(a, mine_a, 4)
    kept_b = guard.settle(b, mine_b, 4)
    guard.close()
    assert len(kept_a) + len(kept_b) == 4
    states = [t.state for t in a.get_trials(deepcopy=False)]
    assert states.count(TS.RUNNING) == 4 and states.count(TS.FAIL) == 2
    assert all(t.user_attrs.get(SURPLUS_ATTR) for t in a.get_trials(deepcopy=False) if t.state == TS.FAIL)


class _RepeatingSampler(optuna.samplers.RandomSampler):
    """Proposes x = 0.5 for trials 0 and 1 (two workers that proposed from the same state), then 0.9."""

    def sample_independent(self, study, trial, name, dist):
        return 0.5 if trial.number < 2 else 0.9


def test_a_trial_repeating_an_earlier_live_point_is_withdrawn_and_asked_again(tmp_path):
    from pipeline.optimise.heartbeat import HeartbeatGuard

    study = optuna.create_study(storage=open_storage(f"journal://{tmp_path / 's.log'}", 1), study_name="s",
                                sampler=_RepeatingSampler())
    dist = {"x": optuna.distributions.FloatDistribution(0, 1)}
    guard = HeartbeatGuard(poll_s=0.01)
    try:
        first, second = guard.ask(study, dist), guard.ask(study, dist)
    finally:
        guard.close()
    assert (first.number, first.params) == (0, {"x": 0.5})
    assert (second.number, second.params) == (2, {"x": 0.9})
    withdrawn = study.get_trials(deepcopy=False)[1]
    assert withdrawn.state == TS.FAIL and withdrawn.user_attrs.get(SURPLUS_ATTR)


def test_a_worker_waiting_for_retries_never_asks_a_new_point(tmp_path):
    """The last queued retry taken by another worker first: ask_queued returns None and stores nothing, where
    study.ask would have created a new trial that one of the two workers then withdraws (maybe the retry)."""
    from pipeline.optimise.heartbeat import HeartbeatGuard

    url = f"journal://{tmp_path / 's.log'}"
    study = optuna.create_study(storage=open_storage(url, 1), study_name="s")
    dist = {"x": optuna.distributions.FloatDistribution(0, 1)}
    study.enqueue_trial({"x": 0.25})
    guard = HeartbeatGuard(poll_s=0.01)
    try:
        taken, none_left = guard.ask_queued(study, dist), guard.ask_queued(study, dist)
    finally:
        guard.close()
    assert taken.params == {"x": 0.25} and none_left is None
    assert [t.state for t in study.get_trials(deepcopy=False)] == [TS.RUNNING]


def test_a_stale_trial_counts_as_live_until_its_retry_is_stored(tmp_path):
    """fail_stale_trials writes FAIL, then the retry: in between a counting worker must not see a free slot.  A
    withdrawn or interrupted trial, one out of retries and one failed long ago are not pending."""
    from pipeline.optimise.heartbeat import INTERRUPTED_ATTR, PENDING_RETRY_S, HeartbeatGuard
    from pipeline.optimise.storages import MAX_RETRY

    url = f"journal://{tmp_path / 's.log'}"
    storage = open_storage(url, 1)
    study = optuna.create_study(storage=storage, study_name="s")
    dist = {"x": optuna.distributions.FloatDistribution(0, 1)}
    stale, surplus, interrupted = study.ask(dist), study.ask(dist), study.ask(dist)
    storage.set_trial_state_values(stale._trial_id, TS.FAIL)        # the first of the failing worker's writes
    surplus.set_user_attr(SURPLUS_ATTR, True)
    study.tell(surplus, state=TS.FAIL)
    interrupted.set_user_attr(INTERRUPTED_ATTR, True)
    study.tell(interrupted, state=TS.FAIL)
    trials = study.get_trials(deepcopy=False)
    assert HeartbeatGuard.pending_retries(trials) == 1
    RETRY(max_retry=MAX_RETRY)(study, trials[0])                     # the second write
    assert HeartbeatGuard.pending_retries(study.get_trials(deepcopy=False)) == 0
    exhausted = study.get_trials(deepcopy=True)[0]
    exhausted.system_attrs["retry_history"] = list(range(MAX_RETRY))
    assert HeartbeatGuard.pending_retries([exhausted]) == 0
    old = study.get_trials(deepcopy=True)[0]
    old.datetime_complete -= datetime.timedelta(seconds=PENDING_RETRY_S + 1)
    assert HeartbeatGuard.pending_retries([old]) == 0


def test_journal_heartbeat_fails_a_silent_trial_and_queues_it_again(tmp_path):
    url = f"journal://{tmp_path / 's.log'}"
    storage = open_storage(url, 1)
    study = optuna.create_study(storage=storage, study_name="s")
    dist = {"x": optuna.distributions.FloatDistribution(0, 1)}
    silent, alive = study.ask(dist), study.ask(dist)
    storage.record_heartbeat(silent._trial_id)
    assert HEARTBEAT_ATTR in study.get_trials(deepcopy=False)[0].system_attrs
    time.sleep(3.5)                     # grace period: 3 heartbeats of 1 s
    storage.record_heartbeat(alive._trial_id)
    optuna.storages.fail_stale_trials(study)
    trials = study.get_trials(deepcopy=False)
    assert [t.state for t in trials] == [TS.FAIL, TS.RUNNING, TS.WAITING]
    assert trials[2].params == trials[0].params and RETRY.retried_trial_number(trials[2]) == 0


def _beat_age(study, trial) -> float:
    t = next(x for x in study.get_trials(deepcopy=False) if x._trial_id == trial._trial_id)
    return time.time() - float(t.system_attrs[HEARTBEAT_ATTR])


def test_a_held_trial_beats_from_ask_until_released(tmp_path):
    """Heartbeats come from the guard's own thread from the ask on (not only while the objective runs): the
    time spent asking the rest of a batch, settling and telling is covered; a released trial stops beating."""
    from pipeline.optimise.heartbeat import HeartbeatGuard

    storage = open_storage(f"journal://{tmp_path / 's.log'}", 1)
    study = optuna.create_study(storage=storage, study_name="s")
    guard = HeartbeatGuard(poll_s=0.01)
    try:
        trial = guard.ask(study, {"x": optuna.distributions.FloatDistribution(0, 1)})
        time.sleep(2.2)                 # no beating block yet: still beaten every half interval
        assert _beat_age(study, trial) < 1.0
        with guard.beating(study, [trial]):
            time.sleep(1.2)
            assert _beat_age(study, trial) < 1.0
        time.sleep(2.2)
        assert _beat_age(study, trial) > 1.5
        assert guard.worst_gap_s >= 0.5
    finally:
        guard.close()


def test_grace_grows_with_the_observed_beat_gap(tmp_path):
    """A worker whose own beats ran 5 s apart (a loaded machine) gives other workers' trials 3 x 5 s, not the
    storage's 3 s; the storage's grace is restored afterwards."""
    from pipeline.optimise.heartbeat import HeartbeatGuard
    from pipeline.optimise.storages import grace_of

    storage = open_storage(f"journal://{tmp_path / 's.log'}", 1)
    study = optuna.create_study(storage=storage, study_name="s")
    quiet = study.ask({"x": optuna.distributions.FloatDistribution(0, 1)})
    storage.record_heartbeat(quiet._trial_id)
    time.sleep(3.5)
    guard = HeartbeatGuard(poll_s=0.01)
    guard.worst_gap_s = 5.0
    assert guard.grace_s(storage) == 15.0
    guard.fail_stale(study)
    assert study.get_trials(deepcopy=False)[0].state == TS.RUNNING
    assert grace_of(storage) == 3
    guard.worst_gap_s = 1e6             # a suspended machine: the stretch is capped
    assert guard.grace_s(storage) == 30.0
    guard.worst_gap_s = 0.0
    guard.fail_stale(study)
    assert study.get_trials(deepcopy=False)[0].state == TS.FAIL


@pytest.mark.parametrize("url, words", [("journal://", "name the journal file"),
                                         ("journal:///no/such/folder/s.log", "does not exist"),
                                         ("nosuchdialect://host/db", "--storage 'nosuchdialect://host/db'")])
def test_a_bad_storage_url_is_one_line_naming_the_option(url, words):
    with pytest.raises(UserError, match=words):
        open_storage(url, 1)


def test_heartbeat_must_be_a_positive_whole_second(tmp_path):
    with pytest.raises(UserError, match="--heartbeat-s"):
        open_storage(f"journal://{tmp_path / 's.log'}", 0)
