"""`vibro synth` as a job of its own (pipeline.synthesis.workflow): a §7 log from the simulator, reproducible."""
from __future__ import annotations

import numpy as np
import pytest

from pipeline.core.errors import UserError
from pipeline.synthesis.workflow import SynthConfig, resolve_effects, synthesize


def _small(seed: int) -> SynthConfig:
    return SynthConfig(system="pendulum", effects=resolve_effects("pendulum", {"rate_stiffening": None}),
                       frequencies_hz=(3.5, 4.0), levels=(0.9e-3,), cycles=4.0, summary_runs=1, seed=seed,
                       n_threads=1)


def test_a_log_has_every_run_once_and_the_same_seed_gives_the_same_log():
    a, truth = synthesize(_small(3))
    b, _ = synthesize(_small(3))
    assert len(a.runs) == 2 and set(a.series) | set(a.summary.index) == set(a.runs["run_id"])
    assert len(a.series) == 1 and len(a.summary) == 1                  # one run logged as a summary only
    for rid, df in a.series.items():
        assert np.isfinite(df.to_numpy()).all() and df["t_s"].is_monotonic_increasing
        assert df.equals(b.series[rid])
    assert truth["truth"]["alpha"] > 0 and "README.md" in a.extra_files


def test_an_effect_the_model_lacks_is_refused_by_name():
    with pytest.raises(UserError, match="tip_blunting"):
        resolve_effects("pendulum", {"tip_blunting": None})


def test_a_mistyped_system_gets_the_closest_name(tmp_path, capsys):
    from pipeline.cli import main

    assert main(["synth", "--out", str(tmp_path / "s"), "--system", "pendulm"]) == 2
    err = capsys.readouterr().err
    assert "--system pendulm: unknown (did you mean pendulum?)" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "s").exists()
