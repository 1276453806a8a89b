"""The lab chain and the corrected chain are told apart in MLflow: run names, the vibro.chain tag, model names;
the experiment is created as a classic machine-learning experiment (MLflow 3's experiment kind)."""
from __future__ import annotations

import json

import pytest

from pipeline.cli import main
from pipeline.cli.train import model_name
from pipeline.tracking import runs
from pipeline.tracking.bundles import surrogate_chain, surrogate_rig


@pytest.fixture
def store(tmp_path, monkeypatch):
    monkeypatch.setenv("MLFLOW_TRACKING_URI", f"sqlite:///{tmp_path / 'mlflow.db'}")
    monkeypatch.setenv("VIBRO_EXPERIMENT", "chains-test")
    monkeypatch.setenv("VIBRO_HOME", str(tmp_path))
    for var in ("VIBRO_PARENT_RUN_ID", "VIBRO_NO_MLFLOW", "DVC_EXP_NAME"):
        monkeypatch.delenv(var, raising=False)
    return tmp_path


def _runs():
    from mlflow.tracking import MlflowClient

    client = MlflowClient()
    exp = client.get_experiment_by_name("chains-test")
    return exp, {r.info.run_name: r.data.tags for r in client.search_runs([exp.experiment_id])}


def test_the_two_chains_get_distinct_run_names_and_chain_tags(store):
    for chain in ("lab", "corrected"):
        with runs.chain(chain):
            with runs.run("train", {"a": 1}):
                pass
            with runs.variant("rop"), runs.run("optimise"):
                pass
    exp, found = _runs()
    assert sorted(found) == ["optimise-rop", "optimise-rop-corrected", "train", "train-corrected"]
    assert {n: t["vibro.chain"] for n, t in found.items()} == {
        "train": "lab", "optimise-rop": "lab", "train-corrected": "corrected", "optimise-rop-corrected": "corrected"}
    assert exp.tags["mlflow.experimentKind"] == "custom_model_development"
    with pytest.raises(ValueError):
        with runs.chain("rig"):
            pass


def test_a_sweep_on_a_rig_file_is_the_corrected_chain_named_for_the_rig(store, capsys):
    rig = store / "my-rig.yaml"
    rig.write_text("model: drill\npreset: lab\nparameters: {K1: 6.2e8}\n")
    common = ["--n-points", "4", "--vary", "frequency_hz=200:300", "--quiet"]
    assert main(["sweep", "--out", str(store / "lab"), *common]) == 0, capsys.readouterr().err
    assert main(["sweep", "--rig", str(rig), "--out", str(store / "rig"), *common]) == 0, capsys.readouterr().err
    _, found = _runs()
    assert found["sweep"]["vibro.chain"] == "lab" and "vibro.rig" not in found["sweep"]
    assert found["sweep-my-rig"]["vibro.chain"] == "corrected" and found["sweep-my-rig"]["vibro.rig"] == "my-rig"
    # train names the rig, and refuses a rig file the sweep did not run on
    from pipeline.cli.train import check_rig_matches, describe
    from pipeline.core.errors import UserError
    from pipeline.core.rigfile import read_rig
    from pipeline.training.workflow import load_training_data

    data = load_training_data(str(store / "rig"))
    check_rig_matches(read_rig(rig), data.meta, str(rig), "rig")
    other = store / "other.yaml"
    other.write_text("model: drill\npreset: lab\nparameters: {K1: 5.0e8}\n")
    with pytest.raises(UserError, match="K1 = 5e\\+08, but dataset 'rig' was simulated with K1 = 6.2e\\+08"):
        check_rig_matches(read_rig(other), data.meta, str(other), "rig")
    with pytest.raises(UserError, match="K1 = 6.2e\\+08, but dataset 'lab' was simulated with K1 = its preset"):
        check_rig_matches(read_rig(rig), load_training_data(str(store / "lab")).meta, str(rig), "lab")
    text = describe({"model": "drill", "preset": "lab", "rig": str(rig), "rig_name": "my-rig"})
    assert text.startswith("rig 'my-rig' (model 'drill', preset 'lab'")


def test_rig_names():
    from pipeline.core.rigfile import rig_name

    assert rig_name("rigs/my-rig.yaml") == "my-rig" and rig_name(None) is None
    assert rig_name("results/diagnose/drill-rig/rig.yaml") == "drill-rig"
    assert rig_name("results/diagnose/seed000-published/rig-metal.yaml") == "seed000-published-metal"
    assert runs.run_name("optimise", "rop", "corrected", "drill-rig") == "optimise-rop-drill-rig"
    assert runs.run_name("optimise", "rop", "corrected") == "optimise-rop-corrected"


def test_model_names_and_the_surrogates_chain(tmp_path):
    assert model_name("drill", "lab") != model_name("drill", "corrected")
    assert model_name("drill", "corrected") == "drill-surrogate-corrected"
    (tmp_path / "report.json").write_text(json.dumps({"chain": "corrected"}))
    assert surrogate_chain(tmp_path) == "corrected"             # optimise inherits the chain it was trained in
    assert surrogate_chain(tmp_path / "missing") is None
    assert surrogate_rig(tmp_path) is None
    (tmp_path / "report.json").write_text(json.dumps({"chain": "corrected", "rig_name": "drill-rig"}))
    assert surrogate_rig(tmp_path) == "drill-rig"                # and the rig's name
