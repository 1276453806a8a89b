"""A shared MLflow tracking server (``mlflow server`` on PostgreSQL with a proxied artifact folder): the commands
and the ``make run`` driver log to ``MLFLOW_TRACKING_URI=http://...`` the same runs, names, tags, params,
artifacts and logged models as to the embedded SQLite default."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from bench.servers import LocalMlflowServer

REPO = Path(__file__).resolve().parents[2]
EXPERIMENT = "vibro-scale"
COMMANDS = (
    ["sweep", "--n-points", "48", "--out", "data/sweep", "--quiet"],
    ["train", "data/sweep", "--out", "models/surrogate", "--regressors", "gbt", "--classifiers", "trees",
     "--cv-folds", "2", "--quiet"],
)
"""What the test logs: a sweep (metrics, metadata and figure artifacts) and a training run (params, figures, the
bundle as artifacts and a logged pyfunc model)."""


@pytest.fixture(scope="module")
def mlflow_server(postgres, tmp_path_factory):
    root = tmp_path_factory.mktemp("mlflow-server")
    try:
        server = LocalMlflowServer(postgres.new_database("mlflow"), root / "artifacts").start()
    except RuntimeError as e:
        pytest.skip(f"mlflow server could not be started: {str(e)[:300]}")
    yield server
    server.stop()


def _env(home: Path, uri: str | None) -> dict:
    env = {k: v for k, v in os.environ.items()
           if k not in ("MLFLOW_TRACKING_URI", "VIBRO_PARENT_RUN_ID", "VIBRO_NO_MLFLOW", "MLFLOW_RUN_ID")}
    env.update(VIBRO_HOME=str(home), VIBRO_EXPERIMENT=EXPERIMENT, PYTHONPATH=str(REPO), DVC_NO_ANALYTICS="1",
               PATH=str(Path(sys.executable).parent) + os.pathsep + env.get("PATH", ""))
    if uri:
        env["MLFLOW_TRACKING_URI"] = uri
    return env


def _log_commands(home: Path, uri: str | None) -> str:
    """Run COMMANDS in project folder ``home`` logging to ``uri`` (None: the default SQLite file); returns the URI."""
    home.mkdir(parents=True, exist_ok=True)
    for cmd in COMMANDS:
        p = subprocess.run([sys.executable, "-m", "pipeline.cli", *cmd], cwd=home, env=_env(home, uri),
                           capture_output=True, text=True, timeout=300)
        assert p.returncode == 0, f"vibro {cmd[0]}: {p.stderr[-2000:]}"
    return uri or f"sqlite:///{home / 'mlflow.db'}"


def _artifacts(list_fn, path: str | None = None) -> list[str]:
    out = []
    for a in list_fn(path):
        out += _artifacts(list_fn, a.path) if a.is_dir else [a.path]
    return out


def snapshot(uri: str, experiment: str = EXPERIMENT) -> dict:
    """Run name -> its status, tag keys (and vibro.* values), param keys, metric keys and artifact paths; plus the
    logged models (name, the run that logged it, its files)."""
    from mlflow.tracking import MlflowClient

    client = MlflowClient(tracking_uri=uri)
    exp = client.get_experiment_by_name(experiment)
    assert exp is not None, f"no experiment {experiment} at {uri}"
    runs = client.search_runs([exp.experiment_id], max_results=1000)
    names = {r.info.run_id: r.info.run_name for r in runs}
    out = {"runs": {}, "models": []}
    for r in runs:
        out["runs"][r.info.run_name] = {
            "status": r.info.status, "tags": sorted(r.data.tags), "params": sorted(r.data.params),
            "vibro_tags": {k: v for k, v in r.data.tags.items() if k.startswith("vibro.") or k == "dvc_exp"},
            "metrics": sorted(r.data.metrics),
            "artifacts": sorted(_artifacts(lambda p, rid=r.info.run_id: client.list_artifacts(rid, p)))}
    for m in client.search_logged_models(experiment_ids=[exp.experiment_id]):
        files = sorted(_artifacts(lambda p, mid=m.model_id: client.list_logged_model_artifacts(mid, p)))
        out["models"].append((m.name, names.get(m.source_run_id), files))
    out["models"].sort()
    return out


@pytest.mark.slow     # two sweeps and two trainings: about 80 s on the shared 2-core machine
def test_commands_log_the_same_runs_models_and_artifacts_to_a_server_as_to_sqlite(mlflow_server, tmp_path):
    local = snapshot(_log_commands(tmp_path / "embedded", None))
    shared = snapshot(_log_commands(tmp_path / "shared", mlflow_server.uri))
    assert sorted(shared["runs"]) == sorted(local["runs"]) == ["sweep", "train"]
    assert shared == local
    train = shared["runs"]["train"]
    assert any(a.startswith("surrogate/") for a in train["artifacts"]) and train["params"]
    assert [(name, run) for name, run, _ in shared["models"]] == [("drill-surrogate-lab", "train")]
    assert "MLmodel" in shared["models"][0][2] and "artifacts/surrogate/bundle.json" in shared["models"][0][2]
    # the server stored the files in its artifact folder (proxied uploads), the client wrote none locally
    stored = {p.name for p in mlflow_server.artifacts.rglob("*") if p.is_file()}
    assert {"metadata.json", "MLmodel"} <= stored
    assert not (tmp_path / "shared" / "mlartifacts").exists() and not (tmp_path / "shared" / "mlflow.db").exists()


@pytest.mark.slow     # a server, dvc and the driver: 40-90 s; a server in the default suite: test_pipeline.py
def test_the_pipeline_driver_logs_its_parent_and_stage_runs_to_the_server(mlflow_server, tmp_path):
    from tests.pipeline.tracking.test_pipeline import _TOY_DVC, _TOY_STAGE, DVC

    root = tmp_path / "toy"
    root.mkdir()
    (root / "stage.py").write_text(_TOY_STAGE)
    (root / "dvc.yaml").write_text(_TOY_DVC)
    (root / "params.yaml").write_text("a: {x: 1.0}\nb: {x: 10.0}\n")
    env = {**_env(root, mlflow_server.uri), "VIBRO_EXPERIMENT": "vibro-scale-pipeline"}
    subprocess.run([DVC, "init", "--no-scm", "-q"], cwd=root, check=True, env=env)
    p = subprocess.run([sys.executable, "-m", "pipeline.tracking.repro", "--root", str(root)], cwd=root, env=env,
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stdout[-2000:] + p.stderr[-2000:]
    assert mlflow_server.uri in p.stdout and not (root / "mlflow.db").exists()
    runs = snapshot(mlflow_server.uri, "vibro-scale-pipeline")["runs"]
    assert sorted(runs) == ["a", "b", "pipeline"]
    assert runs["pipeline"]["vibro_tags"]["vibro.stages_ran"] == "a,b"
    assert {"params.yaml", "dvc.lock"} <= set(runs["pipeline"]["artifacts"])
    assert runs["b"]["artifacts"] == ["b.txt"] and all(r["status"] == "FINISHED" for r in runs.values())
