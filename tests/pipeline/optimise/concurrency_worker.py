"""A study worker for the reliability tests: run_study (or run_study_buffered) on an analytic
objective (no simulator), so kills and races are cheap to provoke.  Run as a script:
    python -m tests.pipeline.optimise.concurrency_worker DB N_TRIALS SEED DELAY_S [buffered]
The objective: rop = 1 - (x - 0.3)^2 - (y - 0.7)^2 on [0, 1]^2 (maximum 1 at (0.3, 0.7))."""
from __future__ import annotations

import sys
import time

import pandas as pd

from pipeline.optimise.constraints import Constraints
from pipeline.optimise.coordination import StudyGuard, batch_seed
from pipeline.optimise.space import Space
from pipeline.optimise.samplers import tpe_sampler
from pipeline.optimise.study import open_study, run_study, run_study_buffered

SPACE = Space({"x": (0.0, 1.0), "y": (0.0, 1.0)})
BATCH = 4


def evaluate_factory(delay_s: float):
    def evaluate(X: pd.DataFrame) -> pd.DataFrame:
        if delay_s:
            print("evaluating", flush=True)        # a test kills during the sleep that follows
        time.sleep(delay_s)
        rop = 1.0 - (X["x"] - 0.3) ** 2 - (X["y"] - 0.7) ** 2
        return pd.DataFrame({"status": "ok", "rop_m_s": rop})
    return evaluate


def run(db: str, n_trials: int, seed: int, delay_s: float, buffered: bool = False, progress: bool = False):
    url = f"sqlite:///{db}"
    n_start = 8

    def factory(n_done: int):
        return tpe_sampler(batch_seed(seed, n_done), 1, n_startup=n_start)

    study = open_study(url, "s", [("rop_m_s", "maximize")], factory(0), {"test": 1})
    print("opened", flush=True)
    guard = StudyGuard.for_url(url)
    ev = evaluate_factory(delay_s)
    if buffered:
        study, ran = run_study_buffered(study, factory(0), ev, SPACE, Constraints(), [("rop_m_s", "maximize")], n_trials, BATCH,
                                        checkpoint=8, progress=progress, sampler_factory=factory, guard=guard)
    else:
        ran = run_study(study, ev, SPACE, Constraints(), [("rop_m_s", "maximize")], n_trials, BATCH, progress=progress,
                        sampler_factory=factory, guard=guard)
    return study, ran


if __name__ == "__main__":
    db, n, seed, delay = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), float(sys.argv[4])
    _, ran = run(db, n, seed, delay, buffered=len(sys.argv) > 5 and sys.argv[5] == "buffered")
    print(f"ran {ran}", flush=True)
