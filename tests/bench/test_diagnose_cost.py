"""``python -m bench.diagnose_cost``'s table: the stages of every log in one column each, a stage's parts right under
it, every number from the logs' report.json ``cost`` (no diagnosis is run here)."""
from __future__ import annotations

from bench.diagnose_cost import parse_log, table
from pipeline.diagnosis.cost import DiagnosisCost, StageCost


def _row(log: str, stages: tuple[StageCost, ...]) -> dict:
    return {"log": log, "system": "drill", "case": "control", "verdict": "nothing missing", "selected": None,
            "n_runs": 8, "cost": DiagnosisCost(stages, (2.0, 1.5, 1.0)).to_json()}


def test_logs_name_their_runs():
    assert parse_log("drill:outside:quadratic_damping") == ("drill", "outside:quadratic_damping", 8)
    assert parse_log("drill:control@16") == ("drill", "control", 16)


def test_a_stages_parts_stand_under_it_in_every_column():
    a = _row("a", (StageCost("calibration", 10, 2.0, 4.0), StageCost("base", 4, 1.0, 2.0, part_of="calibration"),
                   StageCost("pairs", 0, 0.0, 0.0), StageCost("figures: drawing", 0, 1.0, 1.0)))
    b = _row("b", (StageCost("calibration", 12, 3.0, 5.0), StageCost("base", 6, 1.0, 2.0, part_of="calibration"),
                   StageCost("pairs", 8, 4.0, 6.0), StageCost("mu+fc", 8, 4.0, 6.0, part_of="pairs"),
                   StageCost("figures: drawing", 0, 1.0, 1.0)))
    lines = table([a, b], 2).splitlines()
    names = [ln.split(" | ")[0].lstrip("| ") for ln in lines[2:7]]
    assert names == ["calibration", "↳ base", "pairs", "↳ mu+fc", "figures: drawing"]
    assert lines[5] == "| ↳ mu+fc | — | 8 / 4.0 / 6.0 |"
    assert lines[7] == "| **total** | **10 / 3.0 / 5.0** | **20 / 8.0 / 12.0** |"
    assert "| `a` | 8 | nothing missing | 1 | 0.4 | 2, 1.5, 1 |" in lines
