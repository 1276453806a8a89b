"""``python -m bench.discovery``'s store: ``--fresh`` diagnoses the selected cases again and keeps every other stored
row (no diagnosis is run here: ``run_case`` is a stub)."""
from __future__ import annotations

import json

import bench.discovery as B


def _row(system: str, case: str, tag: str) -> dict:
    return {"system": system, "case": case, "noise": "rig", "seed": 0, "name": B.row_name(system, case, "rig", 0, 8),
            "verdict": tag, "selected": None, "accepted": None, "proposals": [], "base_nrms": 1.0, "final_nrms": 1.0,
            "noise_floor": 0.01, "correct": False, "wall_time_s": 1.0, "cpu_time_s": 1.0, "empirical": None}


def test_fresh_rediagnoses_the_selection_and_keeps_the_other_rows(tmp_path, monkeypatch):
    monkeypatch.setattr(B, "WORK", tmp_path / "work")
    monkeypatch.setattr(B, "RESULTS", tmp_path)
    monkeypatch.setattr(B, "cases", lambda system: ["pair:a+b", "pair:c+d"])
    calls = []

    def run_case(system, case, noise, seed, threads, n_runs, daq=None):
        calls.append((system, case))
        return _row(system, case, f"run {len(calls)}")

    monkeypatch.setattr(B, "run_case", run_case)
    assert B.main(["--systems", "drill", "pendulum", "--noise", "rig", "--no-doc"]) == 0
    assert len(calls) == 4
    assert B.main(["--systems", "drill", "--cases", "pair", "--noise", "rig", "--no-doc"]) == 0
    assert len(calls) == 4                          # stored: nothing diagnosed again
    assert B.main(["--systems", "pendulum", "--noise", "rig", "--fresh", "--no-doc"]) == 0
    assert calls[4:] == [("pendulum", "pair:a+b"), ("pendulum", "pair:c+d")]
    stored = {r["name"]: r["verdict"] for r in json.loads((tmp_path / "work" / "rows.json").read_text())}
    assert len(stored) == 4
    assert stored[B.row_name("drill", "pair:a+b", "rig", 0, 8)] == "run 1"
    assert stored[B.row_name("pendulum", "pair:c+d", "rig", 0, 8)] == "run 6"


def test_no_doc_writes_neither_the_doc_nor_the_results(tmp_path, monkeypatch):
    monkeypatch.setattr(B, "WORK", tmp_path / "work")
    monkeypatch.setattr(B, "RESULTS", tmp_path)
    monkeypatch.setattr(B, "DOC", tmp_path / "discovery.md")
    monkeypatch.setattr(B, "cases", lambda system: ["pair:a+b"])
    monkeypatch.setattr(B, "run_case", lambda system, case, *rest, **kw: _row(system, case, "run"))
    (tmp_path / "discovery.md").write_text("<!-- discovery:start -->\n<!-- discovery:end -->\n")
    assert B.main(["--systems", "drill", "--noise", "rig", "--no-doc"]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["discovery.md", "work"]
    assert (tmp_path / "discovery.md").read_text() == "<!-- discovery:start -->\n<!-- discovery:end -->\n"


def test_held_out_cases_and_a_daq_chain_select_and_name_their_logs(tmp_path, monkeypatch):
    """``--cases held-out`` picks the held-out kinds (tests/independent/kinds.py) among a system's cases and nothing
    else; ``--daq CHAIN`` reaches the log's generator and names its row apart from the lab-grade log's."""
    from tests.independent.kinds import KINDS_SYSTEMS

    monkeypatch.setattr(B, "WORK", tmp_path / "work")
    monkeypatch.setattr(B, "RESULTS", tmp_path)
    monkeypatch.setattr(B, "cases", lambda system: ["outside:drive_mode", "outside:contact_power", "pair:a+b"])
    calls = []

    def run_case(system, case, noise, seed, threads, n_runs, daq=None):
        calls.append((case, daq))
        return {**_row(system, case, "run"), "name": B.row_name(system, case, noise, seed, n_runs, daq)}

    monkeypatch.setattr(B, "run_case", run_case)
    assert "drive_mode" in KINDS_SYSTEMS and "contact_power" not in KINDS_SYSTEMS
    assert B.main(["--systems", "drill", "--cases", "held-out", "--noise", "rig", "--no-doc"]) == 0
    assert B.main(["--systems", "drill", "--cases", "held-out", "--noise", "rig", "--daq", "field", "--no-doc"]) == 0
    assert calls == [("outside:drive_mode", None), ("outside:drive_mode", "field")]
    stored = {r["name"] for r in json.loads((tmp_path / "work" / "rows.json").read_text())}
    assert stored == {"drill-outside-drive_mode-rig-s0-n8", "drill-outside-drive_mode-rig-field-s0-n8"}
