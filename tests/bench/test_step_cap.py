"""bench.step_cap (label error against one simulator setting over a model's grid: the pendulum's step cap, the
RIMD's hybrid method)."""
from __future__ import annotations

import math

import pytest

import bench.step_cap as sc


def test_label_error_is_the_largest_relative_deviation_of_the_compared_labels():
    ref = {"peak_force_n": 100.0, "peak_decel_g": 50.0, "energy_per_cycle_j": 2.0, "power_w": None, "period": 1}
    row = {"peak_force_n": 100.1, "peak_decel_g": 50.0, "energy_per_cycle_j": 2.02, "power_w": 3.0, "period": 2}
    assert math.isclose(sc.label_error(row, ref), 0.01)        # energy 1 %; force 0.1 %; power: no yardstick
    assert sc.label_error(ref, ref) == 0.0


@pytest.mark.parametrize("args, needle", [
    (["--values", "abc"], "--values abc: max_step_frac takes numbers, got 'abc'"),
    (["--values", "0.02,0"], "--values 0.02,0: setting 'max_step_frac' has an invalid value 0.0"),
    (["--values", "1.5"], "--values 1.5: setting 'max_step_frac' has an invalid value 1.5"),
    (["--values", ","], "--values ,: expected comma-separated values of max_step_frac"),
    (["--model", "rimd", "--setting", "method", "--values", "rk4"], "--values rk4: setting 'method' has an invalid "
                                                                    "value 'rk4'"),
    (["--setting", "step"], "--setting step: not a simulator setting; known: rtol, min_transient"),
    (["--model", "oscillator"], "--model oscillator: no grid for it here; known: pendulum, rimd, drill, indenter-metal, "
                                "indenter-sandstone"),
])
def test_bad_arguments_get_one_line(args, needle):
    with pytest.raises(SystemExit) as e:
        sc.main(args)
    assert str(e.value).startswith(needle) and "\n" not in str(e.value)


def test_a_small_grid_counts_settled_points_and_the_larger_cap_takes_fewer_steps(monkeypatch):
    """Two of the seed's impact resonances at gap 0 (MODELS.md §3: z = 1/1 at 3.75 Hz, z = 1/2 at 7.25 Hz): both
    settle on a period, so both count; the pendulum's free flight is cap-limited, so a larger cap takes fewer steps,
    and at the default rtol 1e-7 every label stays within 1e-5 of the rtol-1e-11 yardstick at either cap."""
    monkeypatch.setitem(sc.GRIDS, "pendulum", {"gap_m": (0.0,), "frequency_hz": (3.75, 7.25), "amplitude_m": (0.89e-3,)})
    rows = sc.study("pendulum", [0.02, 0.03])
    assert [r["points"] for r in rows] == [2, 2] and all(r["grid"] == 2 for r in rows)
    assert 0 < rows[1]["steps"] < rows[0]["steps"]
    assert all(0.0 <= r["median"] <= r["p90"] <= r["max"] < 1e-5 for r in rows)
    text = sc.render("pendulum", rows, "python -m bench.step_cap --values 0.02,0.03")
    assert "| max_step_frac |" in text and "| 0.03 |" in text and f"| {rows[0]['steps']} (1.00) |" in text


def test_the_rimd_grid_compares_its_hybrid_with_dopri5(monkeypatch):
    """The same study over a setting that is a word: the RIMD's method, on two points of its gap-0 resonance
    (MODELS.md §4: 8.0 Hz, impacting from rest); the hybrid takes fewer steps, both stay within 1e-4 of the
    rtol-1e-11 DOPRI5 yardstick at the default rtol 1e-7."""
    monkeypatch.setitem(sc.GRIDS, "rimd", {"gap_m": (0.0,), "frequency_hz": (7.5, 8.0), "amplitude_n": (1.0,)})
    rows = sc.study("rimd", ["dopri5", "exact"], "method")
    assert [r["points"] for r in rows] == [2, 2]
    assert 0 < rows[1]["steps"] < rows[0]["steps"]
    assert all(r["max"] < 1e-4 for r in rows)
    assert "| method |" in sc.render("rimd", rows, "cmd", "method")
