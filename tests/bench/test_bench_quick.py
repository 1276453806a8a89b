"""The work-precision benchmark's quick path on one model, and its generated table (issue 16).

No timing is asserted (speed targets live in ``make bench``); what is checked is the plumbing that makes
the README figures trustworthy: every method is timed and scored, the summary picks methods that really
reach each error level, and the table lands between the markers and only there.
"""
from __future__ import annotations

import math

import pytest

from bench import bench_precision as bp


@pytest.fixture(scope="module")
def quick_result(tmp_path_factory):
    # indenter-metal: no optional peers and a small kernel, so the quick path stays well under 30 s
    out = tmp_path_factory.mktemp("bench")
    return bp.main(quick=True, write_readme=False, models=("indenter-metal",), scaling=False, out_dir=out), out


def test_quick_run_times_and_scores_every_method(quick_result):
    res, out = quick_result
    assert [(p["model"], p["point"]) for p in res["points"]] == [("indenter-metal", "table1-60hz")]
    rows = res["points"][0]["rows"]
    assert [r["method"] for r in rows] == ["sim dopri5 rtol 1e-06", "sim dopri5 rtol 1e-08", "sim dopri5 rtol 1e-10"]
    for r in rows:
        assert len(r["cpu_all"]) == res["repetitions"] and r["cpu_s"] > 0 and r["wall_s"] > 0
        # DOPRI5 at rtol <= 1e-6 agrees with the reference (DOP853 rtol 1e-10) far better than 1e-3
        assert math.isfinite(r["label_error"]) and r["label_error"] < 1e-3
        assert r["error_vs_exact"] is None               # no exact propagator for this model
    assert (out / "precision_quick.json").exists() and (out / "precision_quick.md").exists()


def test_summary_picks_only_methods_that_reach_the_level(quick_result):
    res, _ = quick_result
    pt = res["points"][0]
    levels = {s["target"] for s in res["summary"]}
    assert 1e-10 not in levels                          # below the reference's own accuracy: not claimed
    for s in res["summary"]:
        if s["sim"]:
            row = next(r for r in pt["rows"] if r["method"] == s["sim"])
            assert bp.effective_error(pt, row) <= s["target"]
            faster = [r for r in pt["rows"] if r["cpu_s"] < row["cpu_s"] and bp.effective_error(pt, r) <= s["target"]]
            assert not faster


def test_table_is_generated_and_written_between_the_markers_only(quick_result, tmp_path, monkeypatch):
    res, _ = quick_result
    md = bp.table(res)
    assert "| indenter-metal | table1-60hz | sim dopri5 rtol 1e-08 |" in md
    assert f"{res['machine']['load_avg_at_start'][0]:.1f} at the start" in md
    (tmp_path / "bench").mkdir()
    before, after = "# Title\nprose above\n", "\nprose below\n"
    for p in (tmp_path / "README.md", tmp_path / "bench" / "README.md"):
        p.write_text(f"{before}{bp.START}\nold figures\n{bp.END}{after}")
    monkeypatch.setattr(bp, "ROOT", tmp_path)
    assert sorted(bp.write_readmes(md)) == ["README.md", "bench/README.md"]
    text = (tmp_path / "README.md").read_text()
    assert text == f"{before}{bp.START}\n{md}{bp.END}{after}"
    assert "old figures" not in text
