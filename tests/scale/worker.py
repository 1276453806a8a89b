"""A study worker for the shared-storage tests: run_study on storage URL with an analytic objective that sleeps
DELAY_S per batch (announcing "evaluating" first), so a test can kill it mid-trial.  Run as a script:
    python -m tests.scale.worker URL STUDY N_TRIALS DELAY_S HEARTBEAT_S"""
from __future__ import annotations

import sys

from pipeline.optimise.constraints import Constraints
from pipeline.optimise.coordination import batch_seed, guard_for
from pipeline.optimise.samplers import tpe_sampler
from pipeline.optimise.study import open_study, run_study
from tests.pipeline.optimise.concurrency_worker import BATCH, SPACE, evaluate_factory


def run(url: str, study_name: str, n_trials: int, delay_s: float, heartbeat_s: int) -> int:
    def factory(n_done: int):
        return tpe_sampler(batch_seed(0, n_done), 1, n_startup=8)

    study = open_study(url, study_name, [("rop_m_s", "maximize")], factory(0), {"test": 1}, heartbeat_s=heartbeat_s)
    print("opened", flush=True)
    return run_study(study, evaluate_factory(delay_s), SPACE, Constraints(), [("rop_m_s", "maximize")], n_trials,
                     BATCH, progress=False, sampler_factory=factory, guard=guard_for(url))


if __name__ == "__main__":
    url, name, n, delay, hb = sys.argv[1], sys.argv[2], int(sys.argv[3]), float(sys.argv[4]), int(sys.argv[5])
    print(f"ran {run(url, name, n, delay, hb)}", flush=True)
