"""Every place that reports a surrogate's verification says the same: a corrected-rig surrogate that the simulator
contradicts (a fallback study makes the recommendation) is reported with one wrong count, one fallback and one set
of bounds by optimise's report.json, its metrics file, its report.md, MLflow, compare, the pipeline report's tables
and the answer line; the answer names the rig, not a study."""
from __future__ import annotations

import json
import re

from pipeline.cli.optimise import run_tracked
from pipeline.comparison.workflow import compare
from pipeline.optimise.config import OptimiseConfig
from pipeline.report.answer import answer_line
from pipeline.report.build import ReportInputs, build_report
from sim import Rig

from tests.pipeline.optimise.test_optimise import SMALL, ToyBundle


def test_a_fallback_case_says_the_same_everywhere(tmp_path, monkeypatch):
    monkeypatch.setenv("MLFLOW_TRACKING_URI", f"sqlite:///{tmp_path / 'mlflow.db'}")
    monkeypatch.setenv("VIBRO_HOME", str(tmp_path))
    monkeypatch.setenv("VIBRO_EXPERIMENT", "one-source")
    for var in ("VIBRO_PARENT_RUN_ID", "VIBRO_NO_MLFLOW", "DVC_EXP_NAME"):
        monkeypatch.delenv(var, raising=False)
    root, store = tmp_path / "root", f"sqlite:///{tmp_path / 'optuna.db'}"
    (root / "metrics").mkdir(parents=True)
    lab = OptimiseConfig(mode="simulator", preset="lab", ranges=SMALL, n_trials=4, n_verify=1, batch_size=4,
                         storage=store, max_power_w=1e6)
    unc = run_tracked(lab, root / "results/optimise/rop", metrics_path=str(root / "metrics/optimise-rop.json"),
                      progress=False).report
    toy = OptimiseConfig(mode="surrogate", surrogate=str(tmp_path), ranges=SMALL, n_trials=16, n_verify=3,
                         batch_size=4, storage=store, fallback_trials=8, max_power_w=1e6)
    cor = run_tracked(toy, root / "results/optimise-rig/rop", bundle=ToyBundle(rop_scale=3.0),
                      metrics_path=str(root / "metrics/optimise-rig.json"), progress=False).report
    fb = cor["fallback"]
    n_wrong, n_verified = fb["surrogate_n_wrong"], fb["surrogate_n_verified"]
    assert n_wrong == 3 == n_verified                              # the surrogate 3x off: wrong everywhere
    assert cor["metrics"]["n_surrogate_wrong"] == n_wrong and cor["metrics"]["surrogate_fallback"] is True
    assert json.loads((root / "metrics/optimise-rig.json").read_text())["n_surrogate_wrong"] == n_wrong
    assert f"wrong at {n_wrong} of {n_verified}" in fb["text"] and fb["simulator_study"] not in fb["text"]
    md = (root / "results/optimise-rig/rop/report.md").read_text()
    assert "said:" not in md                                          # no second copy of the fallback's outcome
    pred, simulated = fb["surrogate_best_rop_m_s_pred"], fb["surrogate_best_rop_m_s_sim"]
    assert pred > 2 * simulated and f"predicted {pred * 1e3:.4g} mm/s" in md and f"gave {simulated * 1e3:.4g}" in md
    # MLflow holds the same count
    from mlflow.tracking import MlflowClient

    client = MlflowClient()
    exp = client.get_experiment_by_name("one-source")
    logged = [r.data.metrics for r in client.search_runs([exp.experiment_id])
              if r.data.metrics.get("surrogate_fallback") == 1.0]
    assert [m["n_surrogate_wrong"] for m in logged] == [n_wrong]
    # compare and the pipeline report
    cmp = compare(unc, cor, Rig("drill", "lab"), n_samples=2, settings={"window": 8}, rig_name="my-rig")
    assert cmp["corrected_surrogate_wrong"] == n_wrong and cmp["corrected_fallback"] == fb["text"]
    assert cmp["corrected_limits"]["on_bounds"] == cor["recommendation"]["on_bounds"]
    assert cmp["recommendations"]["corrected"]["breaks_on_uncorrected"] == {}     # both within 1 MW
    (root / "results/closed-loop").mkdir(parents=True)
    (root / "results/closed-loop/report.json").write_text(json.dumps(cmp))
    res = build_report(ReportInputs(root=root), root / "report")
    report_md = res.markdown.read_text()
    lines = report_md.splitlines()
    i = next(i for i, ln in enumerate(lines) if ln.startswith("| n_surrogate_wrong"))
    head = next(ln for ln in reversed(lines[:i]) if ln.startswith("| quantity"))
    cells = lambda ln: [c.strip() for c in ln.strip().strip("|").split("|")]      # noqa: E731
    assert dict(zip(cells(head), cells(lines[i])))["optimise-rig"] == str(n_wrong)
    assert "within that model's limits" in report_md
    answer = answer_line(res.summary)
    assert answer.startswith("Answer (corrected rig 'my-rig')") and f"wrong at {n_wrong} of {n_verified}" in answer
    assert "simulator-" not in answer and fb["simulator_study"] not in answer
    for hit in cor["recommendation"]["on_bounds"]:
        sym = {"frequency_hz": "f", "amplitude_n": "F0", "static_force_n": "Fs"}[hit["name"]]
        assert re.search(rf"{sym} at its (upper|lower) bound", answer)
