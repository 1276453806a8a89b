"""Report section 5 (pipeline.report.closed_loop): the two recommendations side by side, the worth, the warning."""
from __future__ import annotations

import json
from pathlib import Path

from pipeline.report.build import ReportInputs
from pipeline.report.closed_loop import section_closed_loop
from pipeline.report.doc import Document, Table, to_markdown


def _cmp(explained: bool) -> dict:
    pt = {"frequency_hz": 262.0, "amplitude_n": 2700.0, "static_force_n": 1790.0}
    return {"recommendations": {"uncorrected": {"point": pt, "rop_m_s_on_uncorrected": 8.0e-3, "rop_m_s_on_corrected": 5.0e-3},
                                "corrected": {"point": {**pt, "frequency_hz": 200.0}, "rop_m_s_on_uncorrected": 7.0e-3,
                                              "rop_m_s_on_corrected": 6.5e-3}},
            "worth_mm_s": 1.5, "corrected_rig": {"model": "drill", "source": "vibro diagnose d (drill): x"},
            "spread": {"n_samples": 32, "sampled": ["K1"], "median_rop_m_s": 6.4e-3, "p5_rop_m_s": 6.0e-3,
                       "p95_rop_m_s": 6.9e-3, "fraction_progressing": 1.0},
            "explained": explained, "warning": None if explained else "rests on a model known to be wrong"}


def test_section_shows_both_recommendations_and_the_worth(tmp_path: Path):
    (tmp_path / "results/closed-loop").mkdir(parents=True)
    (tmp_path / "results/closed-loop/report.json").write_text(json.dumps(_cmp(False)))
    doc, summary = Document("t"), {}
    section_closed_loop(doc, None, ReportInputs(root=tmp_path), summary)
    table = next(b for b in doc.blocks if isinstance(b, Table))
    assert [r[2:] for r in table.rows] == [[8.0, 5.0], [7.0, 6.5]]          # mm/s, each point on each model
    md = to_markdown(doc, tmp_path)
    assert "worth +1.5 mm/s" in md and "6–6.9 mm/s" in md and "known to be wrong" in md
    assert summary["closed_loop"]["worth_mm_s"] == 1.5 and summary["closed_loop"]["explained"] is False


def test_section_says_when_the_stage_has_not_run(tmp_path: Path):
    doc = Document("t")
    section_closed_loop(doc, None, ReportInputs(root=tmp_path), {})
    assert "has not run" in to_markdown(doc, tmp_path)
