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
  are COMPLETE: a lost worker's trial is then re-run by whoever is still alive.  Such a worker takes only the
  queued retries (never a new point), and between a stale trial's FAIL and its retry's appearance (two storage
  writes by the worker that failed it) the trial still counts as live, so no worker asks a new point in its place.
"""
from __future__ import annotations

import contextlib
import datetime
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
INTERRUPTED_ATTR = "vibro_interrupted"
"""User attribute of a trial its own worker marked FAIL when interrupted (never retried by the heartbeat)."""
PENDING_RETRY_S = 60.0
"""A stale trial failed this recently whose retry is not stored yet counts as live; a worker that died between the
two writes holds the others back at most this long [s]."""
MAX_REASKS = 8
"""Times a worker asks again for a trial whose point an earlier trial holds."""
MAX_GRACE_STRETCH = 10
"""The grace grown from observed beat gaps is at most this many times the storage's."""


class HeartbeatGuard:
    """The study guard of a shared storage (same interface as coordination.StudyGuard, no locks).

    Heartbeats come from one background thread, independent of the objective, for every trial this worker holds
    from its ``ask`` to the end of its ``beating`` block (told by then), every half heartbeat interval.  The grace
    after which another worker's silent trial is failed grows with how late this worker's own beats ran
    (:meth:`grace_s`): a machine loaded enough to delay its beats delays the other workers' too, and a live but
    descheduled worker is not declared dead."""

    waits = True     # a worker waits for the other workers' trials before it stops

    def __init__(self, poll_s: float = 1.0) -> None:
        self.poll_s = poll_s        # seconds between two looks at a study whose last trials run elsewhere
        self.token = int.from_bytes(os.urandom(4), "little")
        self._held: set[int] = set()            # ids of the trials this worker holds RUNNING
        self._mutex = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.worst_gap_s = 0.0      # longest time between two of this worker's beat rounds [s]

    def sampler_key(self, n_done: int) -> int:
        """What seeds the sampler of the batch starting at ``n_done``: distinct per worker, since two workers that
        count the study at the same moment would otherwise propose the same points (no lock orders them)."""
        return n_done + (self.token << 32)

    def lock(self):
        return contextlib.nullcontext()

    def register(self) -> None:
        pass

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
            self._thread = None
        with self._mutex:
            self._held.clear()

    def grace_s(self, storage) -> float:
        """The grace period used to judge other workers' trials: the storage's, or GRACE_FACTOR times the longest
        gap between this worker's own beat rounds when that is longer (at most MAX_GRACE_STRETCH times the
        storage's: a suspended laptop must not keep a killed worker's trials from ever being re-run)."""
        from pipeline.optimise.storages import GRACE_FACTOR, grace_of

        grace = float(grace_of(storage))
        return min(max(grace, GRACE_FACTOR * self.worst_gap_s), MAX_GRACE_STRETCH * grace)

    def fail_stale(self, study) -> None:
        """Mark FAIL the running trials whose heartbeat stopped (optuna's callback re-queues each), with the grace
        of :meth:`grace_s`."""
        from pipeline.optimise.storages import grace_for

        with warnings.catch_warnings(), grace_for(study._storage, self.grace_s(study._storage)):
            warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
            optuna.storages.fail_stale_trials(study)

    def ask(self, study, distributions: dict):
        """A new trial (or a queued retry), with its first heartbeat recorded at once and beaten from then on.

        A trial whose point an earlier-numbered live trial already holds (two workers proposed from the same
        state) is withdrawn as surplus and asked again: the later number always yields, so one of the two runs."""
        for _ in range(MAX_REASKS):
            with warnings.catch_warnings():     # optuna warns that its heartbeat expects Study.optimize: we beat here
                warnings.filterwarnings("ignore",
                                        message="Heartbeat of storage is supposed to be used with Study.optimize")
                trial = study.ask(distributions)
            self._hold(study, trial._trial_id)
            if not self._duplicated(study, trial):
                return trial
            self._release([trial])
            with contextlib.suppress(optuna.exceptions.UpdateFinishedTrialError):
                trial.set_user_attr(SURPLUS_ATTR, True)
                study.tell(trial, state=TS.FAIL)
        return trial

    def ask_queued(self, study, distributions: dict):
        """A queued retry taken from the study (beaten from then on), or None when none is left: a worker with
        nothing left to ask never creates a new point where another worker took the last retry first."""
        trial_id = study._pop_waiting_trial_id()
        if trial_id is None:
            return None
        self._hold(study, trial_id)
        trial = optuna.Trial(study, trial_id)
        for name, dist in distributions.items():
            trial._suggest(name, dist)      # the queued parameters, as study.ask sets them
        return trial

    def _hold(self, study, trial_id: int) -> None:
        """A trial this worker now holds: its first heartbeat recorded at once, beaten from then on."""
        study._storage.record_heartbeat(trial_id)
        with self._mutex:
            self._held.add(trial_id)
        self._start(study)

    @staticmethod
    def pending_retries(trials: list) -> int:
        """Stale trials failed in the last PENDING_RETRY_S whose retry is not stored yet (the failing worker writes
        FAIL first, then the WAITING retry): counted as live so that nobody asks a new point in their place."""
        from pipeline.optimise.storages import MAX_RETRY

        retried = {t.system_attrs.get("failed_trial") for t in trials}
        now = datetime.datetime.now()
        n = 0
        for t in trials:
            if t.state != TS.FAIL or t.number in retried or t.datetime_complete is None:
                continue
            if t.user_attrs.get(SURPLUS_ATTR) or t.user_attrs.get(INTERRUPTED_ATTR):
                continue
            if len(t.system_attrs.get("retry_history", [])) >= MAX_RETRY:
                continue        # out of retries: none will come
            if 0.0 <= (now - t.datetime_complete).total_seconds() <= PENDING_RETRY_S:
                n += 1
        return n

    def _duplicated(self, study, trial, wait_s: float = 5.0) -> bool:
        """True when a live trial numbered below ``trial`` holds its point; an earlier trial still without
        parameters (asked at this moment elsewhere) is waited for, at most ``wait_s``."""
        names = set(trial.params)
        end = time.monotonic() + wait_s
        while True:
            earlier = [t for t in study.get_trials(deepcopy=False, states=(TS.RUNNING, TS.COMPLETE))
                       if t.number < trial.number]
            if any(t.params == trial.params for t in earlier):
                return True
            if time.monotonic() > end or all(names <= set(t.params) for t in earlier if t.state == TS.RUNNING):
                return False
            time.sleep(0.05)

    def settle(self, study, trials: list, n_trials: int) -> list:
        """Withdraw this worker's trials beyond ``n_trials`` live ones (another worker asked at the same moment);
        returns the trials to evaluate."""
        every = study.get_trials(deepcopy=False)
        excess = sum(t.state in LIVE for t in every) + self.pending_retries(every) - n_trials
        if excess <= 0 or not trials:
            return trials
        keep, drop = trials[:max(len(trials) - excess, 0)], trials[max(len(trials) - excess, 0):]
        for t in drop:
            self._release([t])
            with contextlib.suppress(optuna.exceptions.UpdateFinishedTrialError):
                t.set_user_attr(SURPLUS_ATTR, True)
                study.tell(t, state=TS.FAIL)
        time.sleep(random.uniform(0, self.poll_s))     # two workers that withdrew together ask apart next time
        return keep

    @contextlib.contextmanager
    def beating(self, study, trials: list):
        """Keep ``trials`` beating while the block runs (evaluated and told inside it); released at its end."""
        self._start(study)
        try:
            yield
        finally:
            self._release(trials)

    def _release(self, trials: list) -> None:
        with self._mutex:
            for t in trials:
                self._held.discard(t._trial_id)

    def _start(self, study) -> None:
        """The beat thread of this worker (one per guard), started on first use."""
        if self._thread is not None:
            return
        storage = study._storage
        period = max(float(storage.get_heartbeat_interval() or 1) / 2.0, 0.1)
        self._stop.clear()

        def beat() -> None:
            last = time.monotonic()
            while not self._stop.wait(period):
                with self._mutex:
                    held = list(self._held)
                for trial_id in held:
                    with contextlib.suppress(Exception):    # told or failed meanwhile: nothing to keep alive
                        storage.record_heartbeat(trial_id)
                now = time.monotonic()
                self.worst_gap_s = max(self.worst_gap_s, now - last)
                last = now

        self._thread = threading.Thread(target=beat, name="vibro-heartbeat", daemon=True)
        self._thread.start()

    def fail_orphans(self, study) -> None:
        """Stop beating: an interrupted worker's trials become stale and are re-run by the others."""
        with self._mutex:
            self._held.clear()

    def wait(self) -> None:
        time.sleep(self.poll_s)
