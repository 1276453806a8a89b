"""Report section 5 (pipeline.report.closed_loop): the two recommendations side by side, the worth, the warning."""
from __future__ import annotations

import json
from pathlib import Path

import re

import pytest

from pipeline.report.answer import answer_line, headline
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


SPREAD_WORDS = re.compile(r"parameter spread ±([0-9.e+-]+), model error ±([0-9.e+-]+) \(held-out rms ([0-9.e+-]+) %\), "
                          r"combined ±([0-9.e+-]+) mm/s")


def test_the_answer_prints_the_spread_fields_of_report_json(tmp_path: Path):
    """The parameter spread, model error and their combination printed in report.md, the report and the answer are
    report.json's structured fields (mm/s to the printed 3 digits), and the headline carries the same numbers."""
    from pipeline.comparison.workflow import markdown

    cmp = _cmp(True)
    a, e, nominal = 0.45e-3, 0.05, 6.5e-3
    b = 1.6448536269514722 * e * nominal
    cmp["spread"].update(parameter_half_width_m_s=a, model_error_rel=e, model_error_half_width_m_s=b,
                         combined_half_width_m_s=(a * a + b * b) ** 0.5, model_error_basis="held-out ROP",
                         nominal_rop_m_s=nominal)
    (tmp_path / "results/closed-loop").mkdir(parents=True)
    (tmp_path / "results/closed-loop/report.json").write_text(json.dumps(cmp))
    doc, summary = Document("t"), {}
    section_closed_loop(doc, None, ReportInputs(root=tmp_path), summary)
    s = json.loads((tmp_path / "results/closed-loop/report.json").read_text())["spread"]
    want = [s["parameter_half_width_m_s"] * 1e3, s["model_error_half_width_m_s"] * 1e3, 100 * s["model_error_rel"],
            s["combined_half_width_m_s"] * 1e3]
    for text in (answer_line(summary), to_markdown(doc, tmp_path), markdown(cmp)):
        got = [float(x) for x in SPREAD_WORDS.search(text).groups()]
        assert got == pytest.approx(want, rel=5e-3), text
    assert headline(summary)["rop_m_s_combined_half_width"] == s["combined_half_width_m_s"]


def test_without_a_model_error_the_answer_says_it_is_not_given(tmp_path: Path):
    cmp = _cmp(True)
    cmp["spread"].update(parameter_half_width_m_s=0.45e-3, model_error_rel=None, model_error_half_width_m_s=None,
                         combined_half_width_m_s=None, model_error_basis="")
    (tmp_path / "results/closed-loop").mkdir(parents=True)
    (tmp_path / "results/closed-loop/report.json").write_text(json.dumps(cmp))
    summary = {}
    section_closed_loop(Document("t"), None, ReportInputs(root=tmp_path), summary)
    answer = answer_line(summary)
    assert "parameter spread ±0.45 mm/s, 5-95 %; model error not given" in answer and "combined ±" not in answer
    assert "rop_m_s_combined_half_width" not in headline(summary)
