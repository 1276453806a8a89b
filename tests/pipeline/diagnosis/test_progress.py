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


def test_a_diverged_simulation_has_no_features_and_no_overflow_warning():
    """A history whose signals blew up (1e200 m/s²) is a run the model could not simulate: no features, and no
    'overflow encountered in matmul' from fitting harmonics to it."""
    import warnings
    from types import SimpleNamespace

    import numpy as np
    import pandas as pd

    from pipeline.diagnosis.features import _operators, simulated_features

    t = np.arange(400) / 4000.0
    ok = pd.DataFrame({"t_s": t, "accel_m_s2": np.sin(2 * np.pi * 50.0 * t)})
    blown = ok.assign(accel_m_s2=1e160 * (np.sin(2 * np.pi * 50.0 * t) + t))     # squares overflow a float
    series = SimpleNamespace(kind="series", signals=("accel_m_s2",), pinv=_operators(t, 50.0, 3), record_start_s=None,
                             t_rec=t, fs_hz=4000.0, frequency_hz=50.0, halves=[],
                             pairs=(), pair_at=np.array([], dtype=int), filter_gain=None, nuisance=None,  # no DAQ chain
                             antialias=False, saturation={})
    summary = SimpleNamespace(kind="summary", names=["spectral_ratio"], record_start_s=None, t_rec=None,
                              frequency_hz=50.0, k_max=3, ratio_ref_hz=50.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        assert simulated_features(series, SimpleNamespace(history=ok)).size == 6
        assert simulated_features(summary, SimpleNamespace(history=ok, labels={})).size == 1
        assert simulated_features(series, SimpleNamespace(history=blown)) is None
        assert simulated_features(summary, SimpleNamespace(history=blown, labels={})) is None
