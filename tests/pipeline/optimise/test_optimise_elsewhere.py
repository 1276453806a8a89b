"""`vibro optimise` run from another folder keeps its optuna storage and its feedback file together (the project
root, the documented default) and writes nothing into the current folder but its --out."""
from __future__ import annotations

import numpy as np
import pandas as pd

import sim
from pipeline.cli import main

LAB = {"frequency_hz": (100.0, 450.0), "amplitude_n": (1800.0, 2700.0), "static_force_n": (600.0, 1800.0)}


def test_optimise_from_another_folder_writes_storage_and_feedback_beside_each_other(tmp_path, monkeypatch, capsys):
    import surrogate

    home, elsewhere = tmp_path / "project", tmp_path / "elsewhere"
    home.mkdir()
    elsewhere.mkdir()
    u = np.random.default_rng(0).random((48, 3))
    X = pd.DataFrame({n: lo + u[:, i] * (hi - lo) for i, (n, (lo, hi)) in enumerate(LAB.items())})
    df = sim.simulate_batch("drill", X, preset="lab").assign(point_id=np.arange(len(X)))
    bundle = surrogate.train_bundle(df, list(LAB), LAB, "drill", "lab",
                                    config={"regressors": ["krr"], "classifiers": ["trees"], "learning_curve": [],
                                            "cv_folds": 2, "workers": 1})
    bundle.save(tmp_path / "sur")
    monkeypatch.setenv("VIBRO_HOME", str(home))
    monkeypatch.chdir(elsewhere)
    rc = main(["optimise", "--surrogate", str(tmp_path / "sur"), "--out", "res", "--n-trials", "16",
               "--batch-size", "8", "--n-verify", "2", "--no-mlflow", "--quiet"])
    assert rc == 0, capsys.readouterr().err
    assert (home / "optuna.db").is_file() and (home / "feedback" / "optimise.parquet").is_file()
    assert sorted(p.name for p in elsewhere.iterdir()) == ["res"]
    assert len(pd.read_parquet(home / "feedback" / "optimise.parquet")) == 2
