"""The cost of a diagnosis (``pipeline.diagnosis.cost``): a stage counts the simulations asked for within it, a
stage inside another and a stage's per-model parts are not counted twice in the total, and report.md's table and
the command's line take every number from report.json ``cost``."""
from __future__ import annotations

import time

from pipeline.diagnosis.cost import CostRecorder, DiagnosisCost, StageCost


class _Sims:
    """A simulation counter a fake stage adds to."""

    def __init__(self) -> None:
        self.n = 0

    def __call__(self) -> int:
        return self.n


def _busy(seconds: float) -> None:
    end = time.process_time() + seconds
    while time.process_time() < end:
        pass


def test_a_stage_counts_its_simulations_cpu_and_wall_time():
    sims = _Sims()
    rec = CostRecorder("drill", sims)
    sims.n = 5                                  # before the stage: not its own
    with rec.stage("calibration"):
        sims.n += 7
        _busy(0.05)
    with rec.stage("held-out"):
        sims.n += 3
        time.sleep(0.05)                        # wall time, no CPU
    [cal, held] = rec.rows()
    assert (cal.stage, cal.simulations, cal.system, cal.part_of) == ("calibration", 7, "drill", None)
    assert cal.cpu_s >= 0.045 and cal.wall_s >= cal.cpu_s * 0.5
    assert held.simulations == 3 and held.wall_s >= 0.045 and held.cpu_s < held.wall_s


def test_nested_stages_and_task_parts_are_not_counted_twice():
    sims = _Sims()
    rec = CostRecorder("drill", sims)
    with rec.stage("calibration"):
        sims.n += 10
        rec.tasks(["base", "mu", "base"], [2, 5, 3], [0.1, 0.2, 0.3], [0.2, 0.4, 0.6])
        with rec.stage("inner"):
            sims.n += 4
    with rec.stage("pairs"):
        sims.n += 6
    rec.tasks(["base"], [1], [1.0], [1.0])      # outside a stage: nobody's part
    rows = rec.rows()
    assert [(r.stage, r.part_of) for r in rows] == [("calibration", None), ("base", "calibration"),
                                                     ("mu", "calibration"), ("inner", "calibration"), ("pairs", None)]
    by = {r.stage: r for r in rows}
    assert by["calibration"].simulations == 14 and by["inner"].simulations == 4
    assert (by["base"].simulations, by["base"].cpu_s, by["base"].wall_s) == (5, 0.4, 0.8)
    cost = DiagnosisCost(rows)
    top = [r for r in rows if r.part_of is None]
    assert cost.total.simulations == 20 == sum(r.simulations for r in top)
    assert cost.total.cpu_s == sum(r.cpu_s for r in top) and cost.total.wall_s == sum(r.wall_s for r in top)


def test_the_json_field_round_trips_and_report_md_and_the_command_read_it():
    from pipeline.cli.diagnose import cost_line
    from pipeline.diagnosis.report import cost_lines

    cost = DiagnosisCost((StageCost("calibration", 12, 3.0, 4.5, "drill"),
                          StageCost("mu", 8, 2.0, 2.5, "drill", "calibration"),
                          StageCost("figures: drawing", 0, 1.0, 1.5, "drill")), (1.5, 1.25, 1.0))
    d = cost.to_json()
    assert d["total"] == {"simulations": 12, "cpu_s": 4.0, "wall_s": 6.0} and d["load_avg"] == [1.5, 1.25, 1.0]
    assert DiagnosisCost.from_json(d) == cost
    md = "\n".join(cost_lines(d))
    assert "| stage | simulations | CPU time [s] | wall time [s] |" in md      # units from pipeline.core.units
    assert "| calibration | 12 | 3 | 4.5 |" in md and "| ↳ mu | 8 | 2 | 2.5 |" in md.replace("  ↳", "↳")
    assert "| **total** | 12 | 4 | 6 |" in md and "1.5, 1.25, 1" in md
    assert cost_line(d).startswith("cost: 12 simulations, 4.0 s CPU, 6.0 s wall")
