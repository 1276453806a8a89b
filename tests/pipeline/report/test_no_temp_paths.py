"""A report's results point at the files where the user asked for them, never into the command's temporary folder."""
from __future__ import annotations

import json
from pathlib import Path

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


def test_report_opens_with_the_answer(tmp_path: Path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("VIBRO_HOME", str(tmp_path))
    rec = {"params": {"frequency_hz": 210.0, "amplitude_n": 2700.0, "static_force_n": 1800.0}, "rop_m_s_sim": 7.19e-3}
    (tmp_path / "results/optimise/rop").mkdir(parents=True)
    (tmp_path / "results/optimise/rop/report.json").write_text(json.dumps({"recommendation": rec}))
    assert main(["report", "--out", "results/report", "--no-mlflow"]) == 0, capsys.readouterr().err
    md = (tmp_path / "results/report/report.md").read_text()
    assert md.index("## Answer") < md.index("## 1.") and "**Answer: f = 210 Hz" in md
