"""A report's results point at the files where the user asked for them, never into the command's temporary folder."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from pipeline.cli import main
from pipeline.report.answer import answer_from_report


def _strings(obj) -> list[str]:
    if isinstance(obj, dict):
        return [s for v in obj.values() for s in _strings(v)]
    if isinstance(obj, list):
        return [s for v in obj for s in _strings(v)]
    return [obj] if isinstance(obj, str) else []


def test_summary_answer_names_the_final_report_not_the_temporary_folder(tmp_path: Path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("VIBRO_HOME", str(tmp_path))
    rec = {"params": {"frequency_hz": 210.0, "amplitude_n": 2700.0, "static_force_n": 1800.0},
           "rop_m_s_sim": 7.19e-3, "power_w_sim": 17.9}
    (tmp_path / "results/optimise/rop").mkdir(parents=True)
    (tmp_path / "results/optimise/rop/report.json").write_text(json.dumps({"recommendation": rec}))
    assert main(["report", "--out", "results/report", "--no-mlflow"]) == 0, capsys.readouterr().err
    summary = json.loads((tmp_path / "results/report/summary.json").read_text())
    assert summary["answer"].startswith("Answer: f = 210 Hz") and summary["answer"].endswith("report: report.html")
    leaked = [s for s in _strings(summary) if ".tmp" in s or ".report." in s or str(tmp_path) in s]
    assert leaked == []
    assert not [p for p in (tmp_path / "results").iterdir() if p.name.startswith(".")]    # no temp folder left
    line = answer_from_report(tmp_path / "results/report")       # what make run prints: the real path
    assert line.endswith(f"report: {tmp_path / 'results/report/report.html'}")


REC = {"params": {"frequency_hz": 210.0, "amplitude_n": 2700.0, "static_force_n": 1800.0}, "rop_m_s_sim": 7.19e-3}


@pytest.fixture()
def project(tmp_path: Path, monkeypatch) -> Path:
    """A project folder holding only the lab optimisation's report.json (recommendation REC)."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("VIBRO_HOME", str(tmp_path))
    (tmp_path / "results/optimise/rop").mkdir(parents=True)
    (tmp_path / "results/optimise/rop/report.json").write_text(json.dumps({"recommendation": REC}))
    return tmp_path


def test_report_opens_with_the_answer(project: Path, capsys):
    tmp_path = project
    assert main(["report", "--out", "results/report", "--no-mlflow"]) == 0, capsys.readouterr().err
    md = (tmp_path / "results/report/report.md").read_text()
    assert md.index("## Answer") < md.index("## 1.") and "**Answer: f = 210 Hz" in md


def test_report_metrics_is_the_answer_in_a_few_flat_numbers(project: Path, capsys):
    """``--metrics``: the pipeline's one dvc metric, flat and small so ``dvc metrics show`` fits a terminal."""
    tmp_path, rec = project, REC
    assert main(["report", "--out", "results/report", "--no-mlflow", "--metrics", "results/answer.json"]) == 0, \
        capsys.readouterr().err
    m = json.loads((tmp_path / "results/answer.json").read_text())
    assert m == {"frequency_hz": 210.0, "amplitude_n": 2700.0, "static_force_n": 1800.0, "rop_m_s": 7.19e-3,
                 "lab_rop_m_s": 7.19e-3}
    from pipeline.report.answer import headline

    cl = {"corrected_point": {"frequency_hz": 307.0, "amplitude_n": 2700.0, "static_force_n": 1575.0},
          "corrected_rop_mm_s": 3.6, "spread_mm_s": [3.5, 3.7], "worth_mm_s": 1.45, "explained": True,
          "fallback": "the surrogate was wrong at 12 of 12 verified points"}
    h = headline({"optimise": {"recommended": rec, "verified_rop_m_s": 7.19e-3}, "closed_loop": cl})
    assert h["frequency_hz"] == 307.0 and h["rop_m_s"] == pytest.approx(3.6e-3) and h["worth_m_s"] == pytest.approx(1.45e-3)
    assert h["surrogate_fallback"] == 1.0 and h["explained"] == 1.0 and len(h) <= 12
    assert all(isinstance(v, float) for v in h.values())
