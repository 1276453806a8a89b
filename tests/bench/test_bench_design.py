"""bench_design's plumbing without training: hidden points on both sides of the boundary, means over seeds, the table
and which targets a score meets."""
from __future__ import annotations

import numpy as np

from bench import bench_design as bd


def _row(design: str, seed: int, r2: float) -> dict:
    s = {"n": 10, "accuracy": 0.99, "rop_r2": r2, "power_r2": 0.995, "decel_r2": 0.98, "n_progressing": 9,
         "coverage": {"rop_m_s": 0.9, "power_w": 0.89, "peak_decel_g": 0.91}}
    return {"model": "lab", "design": design, "n": 256, "seed": seed, "train_s": 1.0,
            "scores": {"interior": s, "boundary": dict(s, rop_r2=r2 - 0.01)}}


def test_hidden_points_interior_and_on_the_boundary():
    pts = bd.hidden_points(bd.lab_sweep(), 16, 12)
    lo = {k: float(v["low"]) for k, v in bd.lab_sweep()["vary"].items()}
    hi = {k: float(v["high"]) for k, v in bd.lab_sweep()["vary"].items()}
    at_end = lambda df: np.column_stack([(df[k] == lo[k]) | (df[k] == hi[k]) for k in lo]).any(axis=1)  # noqa: E731
    assert len(pts["interior"]) == 16 and not at_end(pts["interior"]).any()
    assert len(pts["boundary"]) == 12 and at_end(pts["boundary"]).all()


def test_means_over_seeds_and_the_table():
    res = {"rows": [_row("sobol", 0, 0.99), _row("sobol", 1, 0.97), _row("sobol-boundary 0.25", 0, 0.995)],
           "test": {"interior": 16, "boundary": 12}, "regressors": ["gbt"], "classifiers": ["gbt"], "cv_folds": 5,
           "seconds": 3.0, "machine": {"cpus": 2, "load_avg_at_start": [1.5, 1, 1], "load_avg_at_end": [2.5, 1, 1]}}
    means = bd.mean_scores(res["rows"])
    assert [(m["design"], m["seeds"]) for m in means] == [("sobol", [0, 1]), ("sobol-boundary 0.25", [0])]
    assert abs(means[0]["scores"]["interior"]["rop_r2"] - 0.98) < 1e-12
    md = bd.table(res)
    assert "| lab | sobol | 256 | 0,1 | interior | 0.9800 |" in md
    assert "Load average 1.5 at the start, 2.5 at the end" in md
    ok = bd.met(means[1]["scores"]["interior"])
    assert ok == {"rop_r2": True, "accuracy": True, "coverage": True, "power_r2": True, "decel_r2": False}
