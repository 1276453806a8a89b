"""Several workers on one shared storage (an RDB server, a journal file): exact trial count with no lock.

The workers may run on several machines, so no file lock spans them.  What keeps ``n_trials`` exact:
- every running trial gets a heartbeat (storages.open_storage sets the interval); before each batch a worker
  marks FAIL the running trials silent for longer than the grace period (a killed or lost worker's) and optuna's
  retry callback queues each again as a WAITING trial with the same parameters, which the next ``ask`` takes;
- a worker asks only the trials missing from ``n_trials`` (complete + running + waiting), then counts again
  once its new trials are stored: two workers that asked at once see each other and each withdraws its own
  trials beyond ``n_trials`` (marked FAIL with user attribute SURPLUS_ATTR) before evaluating them.  The last
  to store its trials sees all the others, so at most ``n_trials`` live trials remain (argued in docs/scale.md);
- a worker with nothing left to ask waits while other workers' trials run, and stops only when ``n_trials``
  are COMPLETE: a lost worker's trial is then re-run by whoever is still alive.
"""
from __future__ import annotations

import contextlib
import os
import random
import threading
import time
import warnings

import optuna

TS = optuna.trial.TrialState
LIVE = (TS.COMPLETE, TS.RUNNING, TS.WAITING)
SURPLUS_ATTR = "vibro_surplus"
"""User attribute of a trial withdrawn (FAIL) because other workers had already asked the study's last trials."""


class HeartbeatGuard:
    """The study guard of a shared storage (same interface as coordination.StudyGuard, no locks)."""

    waits = True     # a worker waits for the other workers' trials before it stops

    def __init__(self, poll_s: float = 1.0) -> None:
        self.poll_s = poll_s        # seconds between two looks at a study whose last trials run elsewhere
        self.token = int.from_bytes(os.urandom(4), "little")

    def sampler_key(self, n_done: int) -> int:
        """What seeds the sampler of the batch starting at ``n_done``: distinct per worker, since two workers that
        count the study at the same moment would otherwise propose the same points (no lock orders them)."""
        return n_done + (self.token << 32)

    def lock(self):
        return contextlib.nullcontext()

    def register(self) -> None:
        pass

    def close(self) -> None:
        pass

    def fail_stale(self, study) -> None:
        """Mark FAIL the running trials whose heartbeat stopped (optuna's callback re-queues each)."""
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
            optuna.storages.fail_stale_trials(study)

    def ask(self, study, distributions: dict):
        """A new trial (or a queued retry), with its first heartbeat recorded at once."""
        with warnings.catch_warnings():     # optuna warns that its heartbeat expects Study.optimize: we beat here
            warnings.filterwarnings("ignore", message="Heartbeat of storage is supposed to be used with Study.optimize")
            trial = study.ask(distributions)
        study._storage.record_heartbeat(trial._trial_id)
        return trial

    def settle(self, study, trials: list, n_trials: int) -> list:
        """Withdraw this worker's trials beyond ``n_trials`` live ones (another worker asked at the same moment);
        returns the trials to evaluate."""
        excess = len(study.get_trials(deepcopy=False, states=LIVE)) - n_trials
        if excess <= 0 or not trials:
            return trials
        keep, drop = trials[:max(len(trials) - excess, 0)], trials[max(len(trials) - excess, 0):]
        for t in drop:
            with contextlib.suppress(optuna.exceptions.UpdateFinishedTrialError):
                t.set_user_attr(SURPLUS_ATTR, True)
                study.tell(t, state=TS.FAIL)
        time.sleep(random.uniform(0, self.poll_s))     # two workers that withdrew together ask apart next time
        return keep

    @contextlib.contextmanager
    def beating(self, study, trials: list):
        """Record a heartbeat of each of ``trials`` every heartbeat interval while the block runs."""
        interval = study._storage.get_heartbeat_interval()
        stop = threading.Event()

        def beat() -> None:
            while not stop.wait(interval):
                for t in trials:
                    with contextlib.suppress(Exception):    # told or failed meanwhile: nothing to keep alive
                        study._storage.record_heartbeat(t._trial_id)

        thread = threading.Thread(target=beat, name="vibro-heartbeat", daemon=True)
        thread.start()
        try:
            yield
        finally:
            stop.set()
            thread.join()

    def fail_orphans(self, study) -> None:
        """Nothing to do: an interrupted worker's trials stop beating and become stale."""

    def wait(self) -> None:
        time.sleep(self.poll_s)
