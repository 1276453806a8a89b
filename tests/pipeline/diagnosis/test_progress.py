"""A diagnosis reports its progress per stage and per fit task, so a terminal can show what is left."""
from __future__ import annotations

from pipeline.core.executors import InlineExecutor
from pipeline.diagnosis.progress import fit_tasks


def _square(shared, item):
    return shared * item * item


def test_the_executor_reports_every_finished_task():
    done = []
    ex = InlineExecutor(on_task_done=lambda: done.append(len(done)))
    assert ex.map(_square, 2, [1, 2, 3]) == [2, 8, 18] and done == [0, 1, 2]
    assert ex.stats.n_batches == 1


def test_expected_fit_tasks_follow_the_fit_plan():
    # one fold, base from 2 starts (+ polish), 3 candidates from a 1-start grid (grid, start, polish), refits (4)
    assert fit_tasks(1, 3, n_starts=2, candidate_starts=1, warm=False) == 3 + 3 * 3 + 4
    # warm-started folds: one start and a polish per model, no grid
    assert fit_tasks(4, 3, n_starts=2, candidate_starts=2, warm=True) == 4 * (2 + 3 * 2 + 4)
