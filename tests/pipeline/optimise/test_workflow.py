"""The optimise driver is thin: config and strategies in, a frozen ``OptimiseResult`` out, no file written;
``optimise`` (``pipeline/optimise/outcome.py``) writes report.json with the keys it always had."""
from __future__ import annotations

import dataclasses
import json

import pytest

from pipeline.core.errors import UserError
from pipeline.optimise.config import MODES, OptimiseConfig, check_numbers
from pipeline.optimise.outcome import OptimiseOutcome, optimise
from pipeline.optimise.strategies import BUILDERS, SAMPLER_FACTORIES, build_strategies
from pipeline.optimise.study import SAMPLERS
from pipeline.optimise.workflow import OptimiseResult, plan_optimise, run_optimise

from .test_optimise import SMALL, ToyBundle

REPORT_KEYS = ["study_name", "inputs", "created", "tried", "recommendation", "feedback_rows", "feedback_file",
               "surrogate_note", "infill", "fallback", "outcome", "pareto_verified", "objectives", "figures", "metrics"]
TRIED_KEYS = ["mode", "objective", "objectives", "sampler", "seed", "model", "preset", "fixed", "space", "constraints",
              "n_trials", "n_trials_run_now", "n_feasible", "status_counts", "storage", "simulator_calls_study",
              "n_verified", "simulator_calls"]
METRIC_KEYS = ["feasible", "n_trials", "n_feasible_trials", "simulator_calls", "n_verified", "n_surrogate_wrong",
               "n_pareto_verified", "best_rop_m_s", "best_rop_m_s_predicted", "best_rop_rel_error", "best_power_w",
               "best_peak_decel_g", "best_n_on_bounds", "best_frequency_hz", "best_amplitude_n", "best_static_force_n",
               "surrogate_fallback"]
REC_KEYS = ["params", "rop_m_s_sim", "rop_m_s_pred", "rop_m_s_lo", "rop_m_s_hi", "peak_force_n_sim",
            "specific_energy_j_m_sim", "impacts_per_cycle_sim", "power_w_sim", "power_w_pred", "peak_decel_g_sim",
            "peak_decel_g_pred", "rop_rel_error", "status_sim", "surrogate_wrong", "on_bounds", "binding"]


@pytest.fixture()
def dirs(tmp_path, monkeypatch):
    """An empty current folder, a project root and a folder for the optuna storage, apart."""
    cwd, home, db = tmp_path / "cwd", tmp_path / "home", tmp_path / "db"
    for d in (cwd, home, db):
        d.mkdir()
    monkeypatch.chdir(cwd)
    monkeypatch.setenv("VIBRO_HOME", str(home))
    monkeypatch.setenv("MLFLOW_TRACKING_URI", f"sqlite:///{tmp_path / 'mlflow.db'}")
    return tmp_path


def test_lookup_tables_cover_every_name_the_config_accepts():
    assert set(SAMPLER_FACTORIES) == set(SAMPLERS) and set(BUILDERS) == set(MODES)


def test_config_validates_itself():
    with pytest.raises(UserError, match="mode must be one of"):
        OptimiseConfig(mode="annealing")
    with pytest.raises(UserError, match="sampler must be one of"):
        OptimiseConfig(sampler="cmaes")
    with pytest.raises(UserError, match="at least two"):
        OptimiseConfig(objective="pareto", objectives=["rop_m_s"])
    # one table of bounds (config.BOUNDS) for the params.yaml section and the built config, with one message
    with pytest.raises(UserError, match=r"^optimise\.rel_tol: must be > 0, got 0$"):
        OptimiseConfig(rel_tol=0)
    with pytest.raises(UserError, match=r"^p\.yaml: optimise\.n_trials: must be >= 1, got 0$"):
        check_numbers({"n_trials": 0}, "p.yaml: optimise")
    assert check_numbers({"seed": 3.0, "fixed": {"K1": "3e8"}}) == {"seed": 3, "fixed": {"K1": 3e8}}


@pytest.mark.parametrize("mode", ["simulator", "surrogate"])
def test_run_optimise_returns_a_frozen_result_and_writes_nothing(dirs, mode):
    fb = dirs / "cwd" / "feedback.parquet"
    cfg = OptimiseConfig(mode=mode, surrogate=str(dirs / "home"), preset="lab", ranges=SMALL, n_trials=8, n_verify=2,
                         batch_size=4, storage=f"sqlite:///{dirs / 'db' / 'optuna.db'}", study_name=f"t-{mode}",
                         feedback=str(fb))
    plan = plan_optimise(cfg, build_strategies(cfg, ToyBundle() if mode == "surrogate" else None))
    res = run_optimise(plan, progress=False)
    assert isinstance(res, OptimiseResult)
    with pytest.raises(dataclasses.FrozenInstanceError):
        res.outcome = "changed"
    assert res.recommendation is not None and res.outcome.startswith("recommended point verified")
    assert len(res.trials) == 8 and res.n_verified == 2 and len(res.verified) == 2
    assert res.simulator_calls == res.simulator_calls_study + 2 == (8 if mode == "simulator" else 0) + 2
    assert res.metrics()["best_rop_m_s"] == res.recommendation["rop_m_s_sim"]
    # nothing written but the study's storage: no report, figure, feedback file or MLflow store
    assert list((dirs / "cwd").iterdir()) == [] and list((dirs / "home").iterdir()) == []
    assert not (dirs / "mlflow.db").exists()
    assert {p.name for p in (dirs / "db").iterdir()} <= {"optuna.db", "optuna.db.lock", "optuna.db.workers",
                                                        "optuna.db-wal", "optuna.db-shm"}


def test_optimise_writes_the_report_keys_it_always_wrote(dirs):
    fb = dirs / "fb.parquet"
    cfg = OptimiseConfig(mode="surrogate", surrogate=str(dirs / "home"), objective="pareto", ranges=SMALL,
                         n_trials=40, n_verify=4, storage=f"sqlite:///{dirs / 'db' / 'optuna.db'}", feedback=str(fb),
                         fallback_trials=0, infill_rounds=0)
    rep = optimise(cfg, dirs / "out", bundle=ToyBundle(), progress=False).report
    on_disk = json.loads((dirs / "out" / "report.json").read_text())
    keys = [k for k in REPORT_KEYS if k not in ("infill", "fallback")]
    assert list(on_disk) == keys and list(rep) == keys
    assert list(on_disk["tried"]) == TRIED_KEYS and list(on_disk["metrics"]) == METRIC_KEYS
    assert list(on_disk["recommendation"]) == REC_KEYS
    assert on_disk["feedback_file"] == str(fb) and on_disk["feedback_rows"] == 4 and fb.exists()
    assert on_disk["objectives"] == ["rop_m_s", "power_w"] and on_disk["pareto_verified"]
    assert {p.name for p in (dirs / "out").iterdir()} == {"report.json", "report.md", "verified.csv", "trials.csv",
                                                          "history.png", "importances.png", "verification.png",
                                                          "pareto.png"}
    # a ROP study on the simulator: no feedback, no surrogate note, no front
    cfg = OptimiseConfig(mode="simulator", preset="lab", ranges=SMALL, n_trials=4, n_verify=1, batch_size=4,
                         storage=f"sqlite:///{dirs / 'db' / 'optuna.db'}")
    rep = optimise(cfg, dirs / "sim", progress=False).report
    want = [k for k in REPORT_KEYS if k not in ("feedback_rows", "feedback_file", "surrogate_note", "infill", "fallback",
                                                "pareto_verified", "objectives")]
    assert list(json.loads((dirs / "sim" / "report.json").read_text())) == want == list(rep)
    assert list(rep["metrics"]) == [k for k in METRIC_KEYS if k != "n_pareto_verified"]


def test_a_surrogate_the_simulator_contradicts_never_makes_the_recommendation(dirs):
    """A surrogate 3x too optimistic is wrong at every verified point: optimise runs a study straight on the
    simulator over the same space and recommends from it, and the report and metrics say so."""
    store = f"sqlite:///{dirs / 'db' / 'optuna.db'}"
    cfg = OptimiseConfig(mode="surrogate", surrogate=str(dirs / "home"), ranges=SMALL, n_trials=16, n_verify=3,
                         batch_size=4, storage=store, fallback_trials=8)
    said = []
    out = optimise(cfg, dirs / "out", bundle=ToyBundle(rop_scale=3.0), progress=False, notify=said.append)
    rep = out.report
    assert said == [f"{rep['fallback']['reason']}; running 8 trials straight on the simulator"]
    assert isinstance(out, OptimiseOutcome) and out.fell_back and out.failed.config.mode == "surrogate"
    assert out.verification_failed == rep["fallback"]["reason"] and out.result.study_name == rep["study_name"]
    assert list(rep) == [k for k in REPORT_KEYS if k not in ("pareto_verified", "objectives")]
    fb = rep["fallback"]
    assert fb["reason"].startswith("the surrogate was wrong at 3 of 3 verified points") and fb["n_trials"] == 8
    assert rep["tried"]["mode"] == "simulator" and rep["study_name"] == fb["simulator_study"] != fb["surrogate_study"]
    assert rep["metrics"]["surrogate_fallback"] is True and rep["recommendation"]["surrogate_wrong"] is False
    assert "The surrogate was wrong at 3 of 3" in rep["surrogate_note"]
    md = (dirs / "out" / "report.md").read_text()
    assert "Surrogate failed its verification" in md
    # the simulator study starts from the 3 points the surrogate study verified, so it is never worse than them
    trials = json.loads((dirs / "out" / "report.json").read_text())["tried"]
    assert trials["simulator_calls_study"] == 8
    import pandas as pd

    study = pd.read_csv(dirs / "out" / "trials.csv")
    surrogate_verified = pd.read_parquet(dirs / "home" / "feedback.parquet")
    assert rep["recommendation"]["rop_m_s_sim"] >= surrogate_verified["rop_m_s"].max() - 1e-15
    assert set(surrogate_verified["frequency_hz"].round(9)) <= set(study["frequency_hz"].round(9))
