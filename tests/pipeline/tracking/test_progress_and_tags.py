"""make run explains itself (stage lines with ETA, the one-line answer), dvc stage commands need no activated
venv, and every MLflow run carries a distinct name plus git_commit / dvc_exp tags."""
from __future__ import annotations

import io
import os
import shutil
import subprocess
import sys
from pathlib import Path

import yaml

from pipeline.report.answer import answer_line
from pipeline.tracking import repro, runs

REPO = Path(__file__).resolve().parents[3]


def test_stage_clock_prints_one_line_per_stage_with_an_estimate():
    out = io.StringIO()
    clock = repro.StageClock(["sweep", "train"], {"sweep": 60.0, "train": 120.0}, out=out)
    clock.start("sweep")
    clock.start("train")
    clock.finish()
    lines = out.getvalue().splitlines()
    assert lines[0].startswith("[1/2] sweep: started") and "about 3:00 left" in lines[0]   # 60 s + 120 s
    assert lines[1].strip().startswith("sweep: done in")
    assert lines[2].startswith("[2/2] train: started") and "about 2:00 left" in lines[2]
    assert lines[3].strip().startswith("train: done in") and set(clock.times) == {"sweep", "train"}


def test_stage_times_are_remembered_for_the_next_estimate(tmp_path):
    repro.write_stage_times(tmp_path, {"train": 90.0})
    repro.write_stage_times(tmp_path, {"sweep": 30.0})
    assert repro.read_stage_times(tmp_path) == {"train": 90.0, "sweep": 30.0}


def test_answer_line_has_point_rop_power_and_report():
    summary = {"optimise": {"recommended": {"params": {"frequency_hz": 262.2, "amplitude_n": 2699.6,
                                                       "static_force_n": 1789.7},
                                            "rop_m_s_sim": 0.00803, "power_w_sim": 1234.0},
                            "verified_rop_m_s": 0.00803}}
    line = answer_line(summary, "results/report/report.html")
    assert line == ("Answer: f = 262 Hz, F0 = 2.70 kN, Fs = 1.79 kN -> verified ROP 8.03 mm/s, power 1.23 kW; "
                    "report: results/report/report.html")
    summary["optimise"]["recommended"]["power_w_sim"] = 17.9      # the lab rig's answer: W, not "0.02 kW"
    assert answer_line(summary).endswith("power 17.9 W")
    del summary["optimise"]["recommended"]["power_w_sim"]
    assert "power" not in answer_line(summary)
    assert answer_line({}) is None


def test_run_names_and_tags(monkeypatch):
    monkeypatch.delenv("VIBRO_HOME", raising=False)
    assert runs.run_name("optimise", "rop") == "optimise-rop" and runs.run_name("train") == "train"
    monkeypatch.setenv("DVC_EXP_NAME", "tidal-bass")
    tags = runs.run_tags()
    assert tags["dvc_exp"] == "tidal-bass"
    head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=REPO, capture_output=True, text=True).stdout.strip()
    assert tags["git_commit"].split("+")[0] == (head or "unknown")
    monkeypatch.delenv("DVC_EXP_NAME")
    assert runs.run_tags()["dvc_exp"] == "workspace"


def test_git_commit_follows_the_project_root(tmp_path, monkeypatch):
    """A run under another $VIBRO_HOME (outside any repository) must not fix the commit every later run sees
    (CI failure of 81ec9aa: an earlier test's VIBRO_HOME cached 'unknown' for the whole worker)."""
    monkeypatch.setenv("VIBRO_HOME", str(tmp_path))
    assert runs.git_commit() == "unknown"
    monkeypatch.delenv("VIBRO_HOME")
    head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=REPO, capture_output=True, text=True).stdout.strip()
    assert runs.git_commit().split("+")[0] == (head or "unknown")


def test_every_run_is_named_and_tagged_and_the_experiment_is_classic_ml(tmp_path, monkeypatch):
    from mlflow.tracking import MlflowClient

    monkeypatch.setenv("MLFLOW_TRACKING_URI", f"sqlite:///{tmp_path / 'mlflow.db'}")
    monkeypatch.setenv("VIBRO_EXPERIMENT", "tags-test")
    monkeypatch.setenv("DVC_EXP_NAME", "exp-1")
    monkeypatch.delenv("VIBRO_PARENT_RUN_ID", raising=False)
    monkeypatch.delenv("VIBRO_NO_MLFLOW", raising=False)
    with runs.variant("rop"):
        with runs.run("optimise", {"a": 1}):
            pass
    with runs.run("optimise", {"a": 2}, variant="pareto"):
        pass
    client = MlflowClient()
    exp = client.get_experiment_by_name("tags-test")
    assert exp.tags.get("mlflow.experimentKind") == runs.EXPERIMENT_KIND
    found = client.search_runs([exp.experiment_id])
    assert sorted(r.info.run_name for r in found) == ["optimise-pareto", "optimise-rop"]
    for r in found:
        assert r.data.tags["dvc_exp"] == "exp-1" and r.data.tags["git_commit"]


def test_dvc_stage_commands_use_the_repository_wrapper():
    stages = yaml.safe_load((REPO / "dvc.yaml").read_text())["stages"]
    for name, st in stages.items():
        cmd = " ".join((st.get("do") or st)["cmd"].split())
        assert cmd.startswith("bin/vibro "), (name, cmd)           # no bare `vibro` needing an activated venv
        assert "--quiet" not in cmd and "--no-progress" not in cmd, name   # progress shows in make run
        assert "bin/vibro" in (st.get("do") or st)["deps"], name


def test_dvc_repro_runs_a_stage_from_a_plain_shell(tmp_path):
    """A shell without the venv on PATH: dvc runs `bin/vibro`, which finds .venv/bin/python by itself."""
    dvc = Path(sys.executable).with_name("dvc")
    root = tmp_path / "repo"
    for d in ("bin", "pipeline", "sim"):
        shutil.copytree(REPO / d, root / d, ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(REPO / "pyproject.toml", root / "pyproject.toml")
    venv_python = root / ".venv" / "bin" / "python"
    venv_python.parent.mkdir(parents=True)
    venv_python.write_text(f"#!/bin/sh\nexec {sys.executable} \"$@\"\n")     # stands for `make install`'s venv
    venv_python.chmod(0o755)
    (root / "dvc.yaml").write_text("stages:\n  models:\n    cmd: bin/vibro models drill > models.txt\n"
                                   "    deps: [bin/vibro]\n    outs: [models.txt]\n")
    env = {"PATH": "/usr/bin:/bin", "HOME": str(tmp_path), "DVC_NO_ANALYTICS": "1"}
    for cmd in (["git", "init", "-q"], [str(dvc), "init", "-q"], [str(dvc), "stage", "list"],
                [str(dvc), "repro", "--dry"], [str(dvc), "repro"]):
        p = subprocess.run(cmd, cwd=root, env=env, capture_output=True, text=True, timeout=300)
        assert p.returncode == 0, (cmd, p.stdout[-2000:], p.stderr[-2000:])
    assert "lab" in (root / "models.txt").read_text()


def test_answer_leads_with_the_corrected_rig_when_the_loop_was_closed():
    """After a diagnosis the corrected rig's recommendation comes first; the lab model's second, named as such."""
    summary = {"optimise": {"recommended": {"params": {"frequency_hz": 210.0, "amplitude_n": 2700.0,
                                                       "static_force_n": 1800.0}},
                            "verified_rop_m_s": 0.00719},
               "closed_loop": {"corrected_point": {"frequency_hz": 305.0, "amplitude_n": 2700.0, "static_force_n": 1570.0},
                               "corrected_rop_mm_s": 3.61, "uncorrected_rop_on_corrected_mm_s": 2.15,
                               "worth_mm_s": 1.46, "spread_mm_s": [3.2, 3.9], "explained": True,
                               "limits": {"power_w_sim": 17.78, "peak_decel_g_sim": 3.976,
                                          "binding": ["power_w 17.78 of its limit 18"],
                                          "on_bounds": [{"name": "amplitude_n", "side": "high", "bound": 2700.0}]},
                               "surrogate_wrong": 12, "rig_name": "drill-rig"}}
    first, second = answer_line(summary, "r.html").split("\n")
    assert first.startswith("Answer (corrected rig 'drill-rig'): f = 305 Hz, F0 = 2.70 kN, Fs = 1.57 kN -> ROP 3.61 mm/s")
    assert "on the edge of the search space: F0 at its upper bound 2.70 kN" in first
    assert "5-95 %: 3.20-3.90), power 17.8 W, peak deceleration 3.98 g (binding: power 17.8 W of its 18 W limit)" in first
    assert "gives 2.15 mm/s there (+1.46 mm/s)" in first
    assert "wrong at 12 verified point(s)" in first and "CAUTION" not in first
    assert second.startswith("Lab model's answer (before the diagnosis): f = 210 Hz") and second.endswith("r.html")
    summary["closed_loop"].update(explained=False, model_error_ratio=25.5, surrogate_wrong=0)
    first = answer_line(summary).split("\n")[0]
    assert "unexplained (held-out error 25.5x the noise floor)" in first and "known to be wrong" in first
    assert "surrogate" not in first
    summary["closed_loop"]["fallback"] = "the surrogate was wrong at 12 of 12 verified points: the recommendation comes"
    assert "Corrected-rig surrogate: the surrogate was wrong at 12 of 12" in answer_line(summary)


def test_summary_box_names_binding_limits_and_each_diagnosis_in_engineering_words():
    from pipeline.report.answer import summary_lines

    summary = {"optimise": {"recommended": {"params": {"frequency_hz": 210.0}, "binding": [
                   "power_w 17.68 of its limit 18", "peak_decel_g 3.851 of its limit 4"]}, "verified_rop_m_s": 0.00719},
               "diagnose": [{"dataset": "drill-rig", "system": "drill", "base_error": 0.1806, "final_error": 0.0214,
                             "noise_floor": 0.044, "selected": "shaker_coil", "explained": True},
                            {"dataset": "seed000", "system": "indenter-metal", "base_error": 0.465,
                             "final_error": 0.465, "noise_floor": 0.0965, "selected": "none", "explained": False}]}
    lines = summary_lines(summary)
    assert lines[0].startswith("Answer: f = 210 Hz")
    assert lines[1] == ("Limits that bind at the lab model's point: power 17.7 W of its 18 W limit; "
                        "peak deceleration 3.85 g of its 4 g limit")
    assert lines[2] == ("Diagnosis of drill-rig (drill): shaker_coil selected; held-out feature error of the calibrated "
                        "model 18.1% -> 2.1% with shaker_coil (noise floor 4.4%)")
    assert lines[3].startswith("Diagnosis of seed000 (indenter-metal): UNEXPLAINED") and "46.5%" in lines[3]
