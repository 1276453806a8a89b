"""The start-up benchmark's plumbing (bench/startup.py): a command's child CPU is measured, a failing command is
an error naming it, and the rows reach bench_precision's table.  No timing is asserted."""
from __future__ import annotations

import pytest

from bench import bench_precision as bp
from bench import startup


def test_run_once_measures_the_child():
    cpu, wall = startup.run_once(("--help",))
    assert cpu > 0 and wall > 0          # RUSAGE_CHILDREN saw the interpreter run


def test_a_failing_command_is_an_error_naming_it():
    with pytest.raises(RuntimeError, match="no-such-command"):
        startup.run_once(("no-such-command",))


def test_rows_reach_the_generated_table():
    st = {"reps": 5, "load_avg_before": [2.0], "load_avg_after": [2.5],
          "rows": [{"command": "vibro simulate drill --preset lab", "cpu_s": 0.91, "wall_s": 0.95}]}
    md = startup.table(st)
    assert "| `vibro simulate drill --preset lab` | 0.91 | 0.95 |" in md
    res = {"machine": {"load_avg_at_start": [1.0]}, "repetitions": 1, "points": [], "startup": st}
    full = bp.table(res)
    assert "**Start-up**" in full and md.rstrip("\n") in full
