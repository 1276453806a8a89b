"""One chunk of a sweep simulated: the function a backend runs (locally or on a Dask worker)."""
from __future__ import annotations

import numpy as np
import pandas as pd

from pipeline.datasets.store import columns


def compute_chunk(model: str, preset: str | None, settings: dict, fixed: dict[str, float],
                  points: pd.DataFrame, n_threads: int | None = None) -> pd.DataFrame:
    """Simulate the rows of ``points`` (``point_id`` + varied parameters); runs locally or on a Dask
    worker.  Returns the dataset rows (columns of :func:`columns`), ordered by point_id."""
    import sim

    table = points.drop(columns=["point_id"]).copy()
    for k, v in fixed.items():
        table[k] = v
    res = sim.simulate_batch(model, table, preset=preset, settings=settings, n_threads=n_threads)
    res.insert(0, "point_id", points["point_id"].to_numpy(dtype=np.int64))
    return res[columns(model)]
