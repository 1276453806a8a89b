"""The dvc pipeline + MLflow tracking.

Fast tests: ``run_main`` on a two-stage toy pipeline (parent/child runs, no-op repro, partial rerun),
the report on hand-made stage outputs, and an ``mlflow server`` on loopback queried over HTTP.
Slow test (``-m slow``): the project's real ``dvc.yaml`` end to end on a tiny ``params.yaml`` override.
"""
from __future__ import annotations

import json
import os
import shutil
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import pytest
import yaml

REPO = Path(__file__).resolve().parents[3]
BIN = Path(sys.executable).parent
DVC = str(BIN / "dvc")


def _env(root: Path, experiment: str = "vibro-test") -> dict[str, str]:
    env = dict(os.environ)
    for key in ("MLFLOW_TRACKING_URI", "VIBRO_PARENT_RUN_ID", "VIBRO_NO_MLFLOW", "MLFLOW_RUN_ID"):
        env.pop(key, None)
    env.update(VIBRO_HOME=str(root), VIBRO_EXPERIMENT=experiment, DVC_NO_ANALYTICS="1",
               PATH=str(BIN) + os.pathsep + env.get("PATH", ""),
               # the suite's kernels (a copied project's stages would otherwise compile every one again)
               VIBRO_KERNEL_DIR=env.get("VIBRO_KERNEL_DIR") or str(REPO / ".numba_cache"))
    env.pop("NUMBA_CACHE_DIR", None)
    return env


def _run_main(root: Path, env: dict, *extra: str, timeout: float = 600) -> subprocess.CompletedProcess:
    proc = subprocess.run([sys.executable, "-m", "pipeline.tracking.repro", "--root", str(root), *extra], cwd=root,
                          env=env, capture_output=True, text=True, timeout=timeout)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return proc


def _client(root: Path):
    from mlflow.tracking import MlflowClient

    return MlflowClient(tracking_uri=f"sqlite:///{root / 'mlflow.db'}")


def _runs(root: Path, experiment: str = "vibro-test") -> list:
    client = _client(root)
    exp = client.get_experiment_by_name(experiment)
    assert exp is not None, f"experiment {experiment} missing"
    return client.search_runs([exp.experiment_id], max_results=1000)


# ------------------------------------------------------------------------------------- toy pipeline
_TOY_STAGE = '''
import json, sys
from pathlib import Path
import yaml
from pipeline import tracking
name, out = sys.argv[1], Path(sys.argv[2])
params = yaml.safe_load(open("params.yaml"))[name]
out.parent.mkdir(parents=True, exist_ok=True)
prev = float(Path("out/a.txt").read_text()) if name == "b" else 0.0
value = prev + params["x"]
out.write_text(str(value))
Path("metrics").mkdir(exist_ok=True)
Path(f"metrics/{name}.json").write_text(json.dumps({"value": value}))
with tracking.run(name, params) as mlflow:
    mlflow.log_metric(f"{name}.value", value)
    mlflow.log_artifact(str(out))
'''

_TOY_DVC = '''
stages:
  a:
    cmd: python stage.py a out/a.txt
    deps: [stage.py]
    params: [a]
    outs: [out/a.txt]
    metrics: [{metrics/a.json: {cache: false}}]
  b:
    cmd: python stage.py b out/b.txt
    deps: [stage.py, out/a.txt]
    params: [b]
    outs: [out/b.txt]
    metrics: [{metrics/b.json: {cache: false}}]
'''


@pytest.fixture
def toy(tmp_path: Path) -> Path:
    root = tmp_path / "toy"
    root.mkdir()
    (root / "stage.py").write_text(_TOY_STAGE)
    (root / "dvc.yaml").write_text(_TOY_DVC)
    (root / "params.yaml").write_text("a: {x: 1.0}\nb: {x: 10.0}\n")
    subprocess.run([DVC, "init", "--no-scm", "-q"], cwd=root, check=True, env=_env(root))
    return root


def test_run_main_parent_child_noop_and_partial_rerun(toy: Path):
    env = _env(toy)
    first = _run_main(toy, env)
    assert "mlflow ui --backend-store-uri sqlite:///" in first.stdout
    assert str(toy / "mlflow.db") in first.stdout
    runs = _runs(toy)
    parents = [r for r in runs if r.data.tags.get("vibro.stage") == "pipeline"]
    assert len(parents) == 1
    parent = parents[0]
    assert parent.info.status == "FINISHED"
    assert parent.data.tags["vibro.status"] == "ok"
    assert parent.data.tags["vibro.stages_ran"] == "a,b"
    assert parent.data.params["a.x"] == "1.0" and parent.data.params["b.x"] == "10.0"
    assert parent.data.metrics["b.value"] == pytest.approx(11.0)       # metrics/b.json summarised
    children = [r for r in runs if r.data.tags.get("mlflow.parentRunId") == parent.info.run_id]
    assert sorted(r.data.tags["vibro.stage"] for r in children) == ["a", "b"]
    child_b = next(r for r in children if r.data.tags["vibro.stage"] == "b")
    assert child_b.data.metrics["b.value"] == pytest.approx(11.0)
    assert [a.path for a in _client(toy).list_artifacts(child_b.info.run_id)] == ["b.txt"]
    assert {a.path for a in _client(toy).list_artifacts(parent.info.run_id)} >= {"params.yaml", "dvc.lock", "pipeline.dvc.yaml"}

    # nothing changed: no stage runs and no new MLflow run appears
    second = _run_main(toy, env)
    assert "up to date" in second.stdout
    assert "Running stage" not in second.stdout
    assert len(_runs(toy)) == len(runs)

    # a change in b's params reruns b only
    (toy / "params.yaml").write_text("a: {x: 1.0}\nb: {x: 20.0}\n")
    third = _run_main(toy, env)
    assert "Running stage 'b'" in third.stdout and "Running stage 'a'" not in third.stdout
    new_parent = [r for r in _runs(toy) if r.data.tags.get("vibro.stage") == "pipeline"
                  and r.info.run_id != parent.info.run_id]
    assert len(new_parent) == 1 and new_parent[0].data.tags["vibro.stages_ran"] == "b"
    assert json.loads((toy / "metrics/b.json").read_text())["value"] == pytest.approx(21.0)


def test_run_main_failed_stage_marks_parent_failed(toy: Path):
    (toy / "params.yaml").write_text("a: {x: 1.0}\nb: {}\n")             # b's key x missing → stage b fails
    env = _env(toy)
    proc = subprocess.run([sys.executable, "-m", "pipeline.tracking.repro", "--root", str(toy)], cwd=toy, env=env,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode != 0
    parent = next(r for r in _runs(toy) if r.data.tags.get("vibro.stage") == "pipeline")
    assert parent.info.status == "FAILED"
    assert parent.data.tags["vibro.status"] == "failed"


def test_run_main_without_dvc_yaml_is_a_one_line_error(tmp_path: Path):
    proc = subprocess.run([sys.executable, "-m", "pipeline.tracking.repro", "--root", str(tmp_path)], env=_env(tmp_path),
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert "no dvc.yaml" in proc.stderr and "Traceback" not in proc.stderr


# ------------------------------------------------------------------------------------------ report
def _diagnosis(systems: dict):
    """The stored two-system diagnosis (tests/pipeline/diagnosis/data) with, per system, these (default, base, final)
    errors, selected effects and explained (noise floor 0.1)."""
    from dataclasses import replace

    from pipeline.diagnosis.report_types import DiagnoseReport

    stored = Path(__file__).parents[1] / "diagnosis" / "data" / "report_systems.json"
    rep = DiagnoseReport.from_json(json.loads(stored.read_text()))
    out = []
    for s in rep.systems:
        (d, b, f), selected, explained = systems[s.system]
        e = s.errors
        errors = replace(e, default=replace(e.default, error=d), base=replace(e.base, error=b),
                         final=replace(e.final, error=f), noise_floor=0.1)
        out.append(replace(s, errors=errors, selected=selected, explained=explained))
    return replace(rep, systems=tuple(out))


def _fake_outputs(root: Path) -> None:
    import numpy as np
    import pandas as pd

    sweep = root / "data/sweep"
    sweep.mkdir(parents=True)
    rng = np.random.default_rng(0)
    n = 40
    df = pd.DataFrame({"point_id": np.arange(n), "frequency_hz": rng.uniform(10, 400, n),
                       "amplitude_n": rng.uniform(0, 3000, n), "static_force_n": rng.uniform(75, 1425, n),
                       "rop_m_s": rng.uniform(0, 2e-3, n), "peak_force_n": rng.uniform(100, 1500, n),
                       "status": ["ok"] * 35 + ["runaway"] * 5, "reason": [""] * n})
    df.to_parquet(sweep / "part-00000.parquet")
    (sweep / "metadata.json").write_text(json.dumps({"model": "drill", "preset": "lab", "n_points": n,
                                                          "complete": True}))
    sur = root / "models/surrogate"
    sur.mkdir(parents=True)
    (sur / "report.json").write_text(json.dumps({"rop_m_s": {"r2": 0.93, "mae": 1e-4},
                                                 "peak_force_n": {"r2": 0.97, "mae": 12.0}}))
    opt = root / "results/optimise"                     # the layout of `vibro optimise` report.json
    (opt / "rop").mkdir(parents=True)
    (opt / "pareto").mkdir(parents=True)
    (opt / "rop/report.json").write_text(json.dumps({"recommendation": {
        "params": {"frequency_hz": 205.0, "amplitude_n": 2500.0, "static_force_n": 900.0},
        "rop_m_s_sim": 1.8e-3, "rop_m_s_pred": 1.9e-3, "status_sim": "ok", "power_w_sim": 16.8,
        "on_bounds": [{"name": "amplitude_n", "side": "high", "bound": 2700.0, "value": 2690.0}]}}))
    (opt / "pareto/report.json").write_text(json.dumps({"recommendation": {"rop_m_s_sim": 1.5e-3}, "pareto_verified": [
        {"rop_m_s": r, "specific_energy_j_m": e, "params": {"frequency_hz": f}}
        for r, e, f in ((1e-3, 1e4, 150.0), (1.5e-3, 2e4, 200.0), (1.9e-3, 4e4, 250.0))]}))
    (root / "metrics").mkdir()
    diag = root / "results/diagnose/seed000-published"      # the layout of `vibro diagnose` report.json
    diag.mkdir(parents=True)
    (diag / "report.json").write_text(json.dumps(_diagnosis({
        "indenter-metal": ((0.5, 0.3, 0.12), ("shaker_coil",), True),
        "indenter-sandstone": ((0.6, 0.4, 0.4), None, False)}).to_json()))
    (root / "params.yaml").write_text("sweep: {model: drill, preset: lab}\nreport: {title: Test report}\n")


def test_report_is_self_contained_and_shows_every_section(tmp_path: Path):
    _fake_outputs(tmp_path)
    env = _env(tmp_path)
    env["VIBRO_NO_MLFLOW"] = "1"
    proc = subprocess.run([str(BIN / "vibro"), "report", "--out", "results/report"], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    out = tmp_path / "results/report"
    page = (out / "report.html").read_text()
    md = (out / "report.md").read_text()
    assert page.startswith("<!DOCTYPE html>") and "<h1>Test report</h1>" in page
    assert page.count("src='data:image/png;base64,") >= 3          # sweep map, Pareto front, diagnosis
    assert "src='http" not in page and "src='figures" not in page  # nothing external
    assert "1.8 mm/s" in md                                        # verified ROP of the recommended point
    assert "On the edge of the search space:** amplitude_n at its upper bound 2700" in md
    assert "| force amplitude F0 [kN] | 2.5 |" in md and "| power (sim) [W] | 16.8 |" in md   # engineering units (pipeline.core.units)
    assert "| seed000-published | indenter-metal | 0.5 | 0.3 | 0.12 | 0.1 | shaker_coil | True |" in md
    assert "| seed000-published | indenter-sandstone | 0.6 | 0.4 | 0.4 | 0.1 | none | False |" in md
    assert "| ROP [mm/s] | 0.93 |" in md                          # surrogate accuracy table, engineering units
    assert "40** simulated points" in md and "runaway: 5" in md
    for line in md.splitlines():                                   # every figure the .md links exists
        if line.startswith("!["):
            assert (out / line.split("](")[1].rstrip(")")).exists()
    summary = json.loads((out / "summary.json").read_text())
    assert summary["optimise"]["verified_rop_m_s"] == pytest.approx(1.8e-3)
    assert summary["optimise"]["pareto_size"] == 3
    assert summary["answer"].startswith("Answer: ") and "verified ROP 1.80 mm/s" in summary["answer"]


def test_report_bad_params_is_one_line_error(tmp_path: Path):
    (tmp_path / "params.yaml").write_text("report: {colour: red}\n")
    proc = subprocess.run([str(BIN / "vibro"), "report", "--out", "rep", "--no-mlflow"], cwd=tmp_path,
                          env=_env(tmp_path), capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2
    assert "report.colour" in proc.stderr and "params.yaml" in proc.stderr
    assert "Traceback" not in proc.stderr and not (tmp_path / "rep/report.html").exists()


# ------------------------------------------------------------------------------------ mlflow server
def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.slow      # starts a server, like tests/scale/test_mlflow_server.py
def test_mlflow_server_on_loopback_lists_the_runs(tmp_path: Path):
    env = _env(tmp_path, "vibro-server-test")
    code = ("from pipeline import tracking\n"
            "import pathlib\npathlib.Path('fig.png').write_bytes(b'\\x89PNG-test')\n"
            "with tracking.run('pipeline') as m:\n    m.log_metric('x', 1.5)\n    m.log_artifact('fig.png')\n"
            "    print(m.active_run().info.run_id)\n")
    made = subprocess.run([sys.executable, "-c", code], env=env, cwd=tmp_path, capture_output=True, text=True, timeout=300,
                          check=True).stdout.split()[-1]
    port = _free_port()
    server = subprocess.Popen([str(BIN / "mlflow"), "server", "--backend-store-uri", f"sqlite:///{tmp_path / 'mlflow.db'}",
                               "--host", "127.0.0.1", "--port", str(port), "--workers", "1"],
                              env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    base = f"http://127.0.0.1:{port}"
    try:
        deadline = time.time() + 120
        while True:
            try:
                with urllib.request.urlopen(f"{base}/health", timeout=2) as r:
                    if r.status == 200:
                        break
            except OSError:
                pass
            assert server.poll() is None, "mlflow server exited"
            assert time.time() < deadline, "mlflow server did not come up within 120 s"
            time.sleep(0.5)
        with urllib.request.urlopen(f"{base}/api/2.0/mlflow/experiments/get-by-name?experiment_name=vibro-server-test",
                                    timeout=10) as r:
            exp_id = json.load(r)["experiment"]["experiment_id"]
        req = urllib.request.Request(f"{base}/api/2.0/mlflow/runs/search", method="POST",
                                     data=json.dumps({"experiment_ids": [exp_id]}).encode(),
                                     headers={"Content-Type": "application/json"})
        with urllib.request.urlopen(req, timeout=10) as r:
            runs = json.load(r)["runs"]
        assert [r["info"]["run_id"] for r in runs] == [made]
        assert {m["key"]: m["value"] for m in runs[0]["data"]["metrics"]} == {"x": 1.5}
        with urllib.request.urlopen(f"{base}/get-artifact?path=fig.png&run_uuid={made}", timeout=10) as r:
            assert r.read() == b"\x89PNG-test"                    # figures are served to the UI
    finally:
        os.killpg(server.pid, 15)
        try:
            server.wait(timeout=20)
        except subprocess.TimeoutExpired:
            os.killpg(server.pid, 9)
            server.wait(timeout=10)


# ------------------------------------------------------------------------------ real pipeline (slow)
TINY = {
    "sweep": {"n_points": 48, "chunk_size": 16},
    "train": {"regressors": ["gbt"], "classifiers": ["gbt"], "cv_folds": 3, "learning_curve": [0.5, 1.0]},
    "optimise": {"n_trials": 24, "n_verify": 2},
    "diagnose": {"n_starts": 1, "max_nfev": 2, "grid": 2, "effects": ["shaker_coil"]},
}
# Files/folders the pipeline needs in a fresh project directory (the code runs from the editable install,
# but dvc hashes these as stage deps).
COPY = ("dvc.yaml", "params.yaml", ".dvcignore", "vibrobase", "sim", "surrogate", "pipeline", "measured")


def _merge(base: dict, over: dict) -> dict:
    out = dict(base)
    for k, v in over.items():
        out[k] = _merge(base.get(k) or {}, v) if isinstance(v, dict) else v
    return out


def _copy_project(dst: Path) -> None:
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc")
    for name in COPY:
        src = REPO / name
        if src.is_dir():
            shutil.copytree(src, dst / name, ignore=ignore)
        elif src.exists():
            shutil.copy2(src, dst / name)


@pytest.mark.slow
def test_real_pipeline_end_to_end(tmp_path: Path):
    from pipeline.tracking.repro import stale_stages

    root = tmp_path / "proj"
    root.mkdir()
    _copy_project(root)
    params = _merge(yaml.safe_load((REPO / "params.yaml").read_text()), TINY)
    (root / "params.yaml").write_text(yaml.safe_dump(params, sort_keys=False))
    env = _env(root, "vibro-e2e")
    subprocess.run([DVC, "init", "--no-scm", "-q"], cwd=root, check=True, env=env)
    stages = list(yaml.safe_load((root / "dvc.yaml").read_text())["stages"])

    first = _run_main(root, env, timeout=1500)
    for st in stages:
        assert f"Running stage '{st}" in first.stdout, f"stage {st} did not run"
    report = root / "results/report/report.html"
    assert report.exists() and "data:image/png;base64," in report.read_text()

    runs = _runs(root, "vibro-e2e")
    parent = next(r for r in runs if r.data.tags.get("vibro.stage") == "pipeline")
    assert parent.info.status == "FINISHED" and parent.data.tags["vibro.status"] == "ok"
    assert parent.data.params["sweep.n_points"] == "48"
    children = {r.data.tags.get("vibro.stage"): r for r in runs
                if r.data.tags.get("mlflow.parentRunId") == parent.info.run_id}
    for st in ("sweep", "train", "optimise", "report"):
        assert st in children, f"no child run for stage {st}: {sorted(children)}"
        assert children[st].info.status == "FINISHED"
    assert any(k.startswith("diagnose") for k in children)
    assert children["sweep"].data.params, "sweep child run logged no params"
    assert children["train"].data.metrics, "train child run logged no metrics"
    client = _client(root)
    assert client.list_artifacts(children["train"].info.run_id), "train child run logged no artifacts (model)"
    rep_art = [a.path for a in client.list_artifacts(children["report"].info.run_id, "report")]
    assert "report/report.html" in rep_art
    assert any(k.startswith("train.") for k in parent.data.metrics)    # stage metrics summarised on the parent

    # second repro: nothing to do, no new run
    second = _run_main(root, env)
    assert "up to date" in second.stdout and "Running stage" not in second.stdout
    assert stale_stages(root, DVC) == {}
    assert len(_runs(root, "vibro-e2e")) == len(runs)

    # a training parameter change reruns train and what follows, not the sweep
    train_sec = params.get("train") or {}
    params["train"] = {**train_sec, "seed": int(train_sec.get("seed") or 0) + 1}
    (root / "params.yaml").write_text(yaml.safe_dump(params, sort_keys=False))
    stale = stale_stages(root, DVC)
    assert "train" in stale and "sweep" not in stale
    third = _run_main(root, env, timeout=1500)
    assert "Running stage 'train'" in third.stdout and "Running stage 'sweep'" not in third.stdout
    assert "Running stage 'report'" in third.stdout
